"""SpaceMesh inference service (REST and gRPC over onnxruntime; never imports torch)."""
