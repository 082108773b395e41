"""Export trained networks to ONNX model repositories (needs torch and onnxscript).

- :mod:`~spacemesh.export.onnx_export`: the three graphs via the dynamo exporter.
- :mod:`~spacemesh.export.repository`: ``NAME/VERSION/*.onnx + manifest.json``.
"""
