#!/bin/sh
# Build the runtime virtual environment, in two phases (two Docker layers):
#
#   deploy/install.sh deps VENV [cpu|gpu]   pinned requirements (deploy/requirements-*.txt)
#   deploy/install.sh app  VENV             the model and service packages (./model,
#                                           ./service) without dependencies, then remove
#                                           the build tools (setuptools, wheel) from VENV
#
# The Dockerfile runs exactly this, and so does tests/deploy/test_deploy_runtime.py in a
# fresh virtual environment; run it from the repository root. PIP_* variables apply
# (the image sets PIP_NO_CACHE_DIR=1; the test keeps pip's cache).
set -eu
phase="${1:?usage: deploy/install.sh deps|app VENV [cpu|gpu]}"
venv="${2:?usage: deploy/install.sh deps|app VENV [cpu|gpu]}"
onnxruntime="${3:-cpu}"
python="${PYTHON:-python3}"
case "$phase" in
  deps)
    [ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install --disable-pip-version-check \
        -r deploy/requirements-runtime.txt \
        -r "deploy/requirements-onnxruntime-$onnxruntime.txt"
    ;;
  app)
    "$venv/bin/python" -m pip install --disable-pip-version-check --no-deps \
        ./model ./service
    "$venv/bin/python" -m pip uninstall --disable-pip-version-check -y setuptools wheel \
        >/dev/null 2>&1 || true
    ;;
  *)
    echo "deploy/install.sh: unknown phase $phase (deps or app)" >&2
    exit 2
    ;;
esac
