"""Record a model version's golden outputs in its manifest (see :mod:`spacemesh.runtime.golden`).

``spacemesh export`` records them for every version it writes; for a version exported
before the section existed (its graphs unchanged, byte for byte)::

    python -m spacemesh.export.golden models/spacemesh-small/7 [more version folders]
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from spacemesh.export.manifest import update_manifest
from spacemesh.runtime.golden import SECTION, golden_section
from spacemesh.runtime.repository import ModelRepository, ModelRepositoryError


def record_golden(directory: str | Path, *, threads: int = 1) -> dict[str, Any]:
    """Run the golden input through a version's graphs and write the ``golden`` section
    into its manifest; nothing else in the folder changes.

    Parameters
    ----------
    directory : path
        A model version folder; its files must match the manifest's sha256.
    threads : int
        onnxruntime intra-op threads.

    Returns
    -------
    dict
        The new manifest.

    Raises
    ------
    spacemesh.runtime.ModelRepositoryError
        A missing file or a sha256 mismatch.
    """
    repository = ModelRepository.load(directory, threads=threads, golden=False)
    section = golden_section(repository.backend, repository.manifest)
    return update_manifest(repository.path, **{SECTION: section})


def main(argv: list[str] | None = None) -> int:
    """``python -m spacemesh.export.golden VERSION_DIR...``: record each, print its path."""
    folders = sys.argv[1:] if argv is None else argv
    if not folders:
        print("usage: python -m spacemesh.export.golden VERSION_DIR...", file=sys.stderr)
        return 2
    for folder in folders:
        try:
            record_golden(folder)
        except (ModelRepositoryError, OSError, ValueError) as error:
            print(f"spacemesh.export.golden: error: {folder}: {error}", file=sys.stderr)
            return 2
        print(folder)
    return 0


if __name__ == "__main__":
    sys.exit(main())
