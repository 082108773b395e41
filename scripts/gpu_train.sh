#!/usr/bin/env bash
# Train a local-point denoiser on the shipped model's frozen encoder and export it, in
# about 12 minutes on one GPU, on a machine without a package registry.
#
#   OUT=/path bash scripts/gpu_train.sh --data data/qem-gpu [--minutes 11] [--batch 128]
#       [--lr 1e-3] [--config small-local] [--base models/spacemesh-small/7] [--resume --run DIR]
#
# - The dataset travels with the working tree: data/ is ignored, so name it in the call's
#   carry (about 30 KB a shape: some 1,000 shapes fit beside the tree in 64 MiB).
# - Python packages the machine lacks travel as wheels in .whl/ (ignored too; carry it):
#   they are installed into /tmp/site without a registry. The session lists what is missing
#   and stops before training (exit 2) if anything is.
# - Results go to $OUT: run/last.pt (for --resume), run/weights.pt, run/metrics.csv,
#   run/curves.png, model/denoiser.onnx, model/manifest.json, summary.json
#   (python -m spacemesh.export.session --help).
# - CPU smoke test with a tiny budget:
#   OUT=/tmp/gpu-out PYTHON=.venv/bin/python bash scripts/gpu_train.sh --data DATA \
#       --device cpu --minutes 3 --batch 6 --export-reserve 100
set -euo pipefail
cd "$(dirname "$0")/.."
fail() { echo "gpu_train: cannot start: $*" >&2; exit 2; }
[ -n "${OUT:-}" ] || fail "set OUT to the folder the results go to"
PY="${PYTHON:-python3}"
command -v "$PY" >/dev/null 2>&1 || fail "no Python interpreter $PY (set PYTHON)"
if compgen -G ".whl/*.whl" >/dev/null; then
    "$PY" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || fail "the wheels in .whl/ did not install"
    export PYTHONPATH="/tmp/site${PYTHONPATH:+:$PYTHONPATH}"
fi
export PYTHONPATH="$PWD/model${PYTHONPATH:+:$PYTHONPATH}"
export PYTHONUNBUFFERED=1
exec "$PY" -m spacemesh.export.session --out "$OUT" "$@"
