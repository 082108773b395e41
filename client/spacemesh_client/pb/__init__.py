"""The gRPC contract, ``proto/spacemesh.proto``, as generated Python (do not edit).

For raw gRPC use (``examples/grpc_generate.py``); ``Client("grpc://...")`` wraps it.
Regenerate with ``client/gen_proto.sh``; tests/client/test_client_package.py checks that
it matches the proto. The SDK keeps its own copy so that it depends on no other
SpaceMesh package. Importing the modules needs the ``grpc`` extra.
"""
