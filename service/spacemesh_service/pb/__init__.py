"""Code generated from ``proto/spacemesh.proto`` by ``scripts/gen_proto.sh`` (do not edit)."""

from spacemesh_service.pb import spacemesh_pb2, spacemesh_pb2_grpc

__all__ = ["spacemesh_pb2", "spacemesh_pb2_grpc"]
