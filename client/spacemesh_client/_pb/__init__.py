"""Code generated from ``proto/spacemesh.proto`` (do not edit; ``client/gen_proto.sh``).

The client keeps its own copy so that it depends on no other SpaceMesh package;
tests/client/test_client_proto.py checks that it matches the proto. The modules are
imported only by the gRPC transport (the ``grpc`` extra).
"""
