#!/usr/bin/env bash
# Install SpaceMesh with every extra into a fresh virtual environment and run the tests.
# torch==2.13.0 is installed first (a local CPU build on these machines); any other torch
# requirement would download several GB of CUDA packages.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV="${SPACEMESH_TEST_VENV:-.venv-test}"
PYTHON="${PYTHON:-python3}"
# nginx lets tests/deploy check the compose load balancer for real (skipped without it)
if ! command -v nginx >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    (apt-get update -qq && apt-get install -y -qq nginx-light >/dev/null 2>&1) \
        || echo "note: nginx could not be installed; the nginx test will be skipped"
fi
# chromium and its driver let tests/browser drive the web page in a real headless browser
if ! command -v chromedriver >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    (apt-get update -qq && apt-get install -y -qq chromium chromium-driver >/dev/null 2>&1) \
        || echo "note: chromium could not be installed; the browser tests will be skipped"
fi
[ -x "$VENV/bin/python" ] || "$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q "torch==2.13.0"
"$VENV/bin/python" -m pip install -q -e "model[geometry,train,test]" -e service -e "client[trimesh,grpc]" \
    -r deploy/requirements-check.txt
# the tiny model most test folders share (tests/conftest.py) is built in the background
# while style, types and layers are checked: the tests would otherwise wait for it
TOY_TEMP=""
if [ -z "${SPACEMESH_TEST_TOY_DIR:-}" ]; then
    TOY_TEMP="$(mktemp -d)"
    export SPACEMESH_TEST_TOY_DIR="$TOY_TEMP/spacemesh-toy-model"
fi
mkdir -p "$(dirname "$SPACEMESH_TEST_TOY_DIR")"
"$VENV/bin/python" -m spacemesh.train.toy "$SPACEMESH_TEST_TOY_DIR" \
    > "$SPACEMESH_TEST_TOY_DIR.log" 2>&1 &
TOY_BUILD=$!
trap 'kill "$TOY_BUILD" 2>/dev/null || true; [ -z "$TOY_TEMP" ] || rm -rf "$TOY_TEMP"' EXIT
# style, types and layers first (ruff.toml, mypy.ini, .importlinter), then the tests
"$VENV/bin/ruff" check model service client tests bench experiments scripts examples
"$VENV/bin/lint-imports" --no-cache
"$VENV/bin/mypy"
# two workers (pytest-xdist; a test file stays on one worker, so its fixtures start once)
"$VENV/bin/python" -m pytest -q -n "${SPACEMESH_TEST_WORKERS:-2}" --dist loadfile "$@"
