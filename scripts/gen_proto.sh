#!/usr/bin/env bash
# Regenerate the service's gRPC code from proto/spacemesh.proto (needs grpcio-tools).
# The generated modules are committed; run this after every change to the proto.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-.venv/bin/python}"
OUT=service/spacemesh_service/pb
"$PYTHON" -m grpc_tools.protoc -I proto --python_out="$OUT" --pyi_out="$OUT" \
    --grpc_python_out="$OUT" proto/spacemesh.proto
# protoc writes a top-level import; make it relative to the package.
sed -i 's/^import spacemesh_pb2 as /from . import spacemesh_pb2 as /' "$OUT/spacemesh_pb2_grpc.py"
echo "wrote $OUT/spacemesh_pb2.py, spacemesh_pb2.pyi, spacemesh_pb2_grpc.py"
bash client/gen_proto.sh
