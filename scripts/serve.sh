#!/usr/bin/env bash
# Install the model core and the service into .venv and start `spacemesh serve`
# (REST on :8000, gRPC on :8001, the shipped models/spacemesh-small).
#
#   scripts/serve.sh [spacemesh serve flags...]      e.g. --host 0.0.0.0 --port 9000
#
# Serving needs no torch: the service runs the exported ONNX graphs with onnxruntime.
# Every flag also reads an environment variable (SPACEMESH_PORT, SPACEMESH_MODEL, ...).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${SPACEMESH_VENV:-.venv}"
PYTHON="${PYTHON:-python3}"
[ -x "$VENV/bin/python" ] || "$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q -e model -e service
exec "$VENV/bin/spacemesh" serve "$@"
