#!/usr/bin/env bash
# Point cloud in, mesh out, with curl: upload examples/points.ply, get mesh.glb back.
# The mesh's statistics, its fit report (X-SpaceMesh-Fit-*) and the options used come
# back as X-SpaceMesh-* headers; errors as problem+json. More options: &start=points
# &target_vertices=500 &samples=4 &raw=true (docs/SERVICE.md).
# Run from the repository root:  bash examples/curl_generate.sh [POINTS]
set -euo pipefail
URL="${SPACEMESH_URL:-http://localhost:8000}"
POINTS="${1:-examples/points.ply}"

curl -sS --fail-with-body "$URL/v2/health/ready"; echo
curl -sS --fail-with-body -X POST "$URL/generate?format=glb&seed=${SEED:-0}" \
     -F "file=@$POINTS" -o mesh.glb -D headers.txt
grep -i '^x-spacemesh-' headers.txt
