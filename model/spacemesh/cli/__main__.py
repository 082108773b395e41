"""``python -m spacemesh.cli``: the same as the ``spacemesh`` command (used by torchrun)."""

from spacemesh.cli import main

main()
