"""Point cloud in, mesh out, over gRPC with the stubs of proto/spacemesh.proto
(pip install -e 'client[grpc]'), streaming one progress event per stage of the work
(and per diffusion step, where the model's default has any).

Run from the repository root:  python examples/grpc_generate.py [POINTS]
"""

import os
import sys
from pathlib import Path

import grpc

from spacemesh_client.pb import spacemesh_pb2 as pb
from spacemesh_client.pb import spacemesh_pb2_grpc as pb_grpc

target = os.environ.get("SPACEMESH_GRPC_TARGET", "localhost:8001")
path = Path(sys.argv[1] if len(sys.argv) > 1 else "examples/points.ply")
request = pb.GenerateRequest(file=pb.PointCloudFile(data=path.read_bytes(), filename=path.name),
                             format="glb", seed=int(os.environ.get("SEED", 0)),
                             stages=True)

with grpc.insecure_channel(target) as channel:
    stub = pb_grpc.SpaceMeshStub(channel)
    try:
        for event in stub.GenerateStream(request, timeout=300):
            if event.HasField("progress"):
                progress = event.progress
                print(f"{progress.stage:<13} {progress.step}/{progress.total}", end="\r")
            else:
                reply = event.mesh
    except grpc.RpcError as error:  # the problem type is in the trailing metadata
        problem = dict(error.trailing_metadata() or ())
        sys.exit(f"{error.code().name}: {error.details()} [{problem.get('problem-type')}]")
Path("mesh.glb").write_bytes(reply.mesh)
print(f"mesh.glb: {reply.stats.vertices} vertices, {reply.stats.faces} faces, "
      f"closed={reply.stats.closed}, seed {reply.seed}, model {reply.model_name}, "
      f"start {reply.start}, fit coverage {reply.stats.fit.coverage:.3f}")
