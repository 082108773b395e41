#!/usr/bin/env bash
# Install SpaceMesh with every extra into a fresh virtual environment and run the tests.
# torch==2.13.0 is installed first (a local CPU build on these machines); any other torch
# requirement would download several GB of CUDA packages.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${SPACEMESH_TEST_VENV:-.venv-test}"
PYTHON="${PYTHON:-python3}"
[ -x "$VENV/bin/python" ] || "$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q "torch==2.13.0"
"$VENV/bin/python" -m pip install -q -e "model[geometry,train,test]" -e service -e client
exec "$VENV/bin/python" -m pytest -q "$@"
