"""Decoding: per-vertex embeddings to an oriented manifold polygon mesh (paper Sec. 3).

* :mod:`~spacemesh.decode.decoder`: the decode and its guarantee (:func:`decode`);
* :mod:`~spacemesh.decode.crossing`: the weaker of two crossing quad diagonals dropped;
* :mod:`~spacemesh.decode.splitting`: long faces cut along their strongest diagonals;
* :mod:`~spacemesh.decode.refinement`: removed vertices put back, diagonals flipped;
* :mod:`~spacemesh.decode.quad_fit`: which diagonal of a quad lies closer to the points.

The decode sits below :mod:`spacemesh.geometry` (the stage after it) and imports nothing
above the representation core and :mod:`spacemesh.primitives`.
"""

from spacemesh.decode.decoder import (
    EDGE_ROUNDS,
    MAX_DEGREE,
    DecodeOptions,
    DecodeResult,
    Embeddings,
    decode,
    pinched_face_edges,
    repeated_in_faces,
    unpinch_candidates,
)

__all__ = [
    "EDGE_ROUNDS",
    "MAX_DEGREE",
    "DecodeOptions",
    "DecodeResult",
    "Embeddings",
    "decode",
    "pinched_face_edges",
    "repeated_in_faces",
    "unpinch_candidates",
]
