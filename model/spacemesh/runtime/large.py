"""Meshes larger than the model's token count: how many vertices the networks place.

With ``start=points`` and a ``target_vertices`` above the model's ``max_vertices`` (256
for ``small``), the pipeline can make the extra vertices in one of two ways
(:attr:`spacemesh.runtime.spec.ModelSpec.large_meshes`, manifest
``sampler.large_meshes``):

``split``
    the networks read ``max_vertices`` farthest-point vertices and the geometry stage
    splits the longest edges up to the target (the behaviour before large meshes: the
    extra vertices and their edges never come from the model);
``tokens`` (default)
    every target vertex is a token of the connectivity network, up to
    :data:`MAX_NETWORK_TOKENS`; the geometry stage then fits them (and splits edges only
    beyond that cap). The connectivity network has no positional embedding and reads
    relative features (distance bias, nearest-vertex offsets), so it runs on any token
    count; at four times its training count (spacing halved) its thresholded graph has
    a mean degree of about 8 instead of 6 and the decode removes the extra edges
    (docs/model/large_meshes.md has the measurements).

The cap bounds the cost: the network's attention is quadratic in the tokens and the
decode's crossing and pinch rounds grow faster still (on one core, about 3 s each for
2,048 tokens and 12 s and 27 s for 4,096). ``raw`` requests are not capped: they give every
target vertex to the networks, as before.

On thin shapes the full-token graph can fall apart (on one dev mesh the decode kept 118
of 1,024 vertices, and the fit could not undo the folds: 47% of the faces intersect). A
``tokens`` decode that keeps fewer than :data:`MIN_KEPT_SHARE` of its vertices is
therefore replaced by the ``split`` one: the connectivity network runs again on the
first ``max_vertices`` tokens (farthest-point sampling is greedy, so they are exactly the
``split`` tokens), and ``decode_stats["large_meshes"]`` says ``"split"``.
"""

from __future__ import annotations

#: How the pipeline makes more vertices than the model's token count.
LARGE_MESH_MODES = ("split", "tokens")
#: The default of models whose manifest does not choose.
DEFAULT_LARGE_MESHES = "tokens"
#: Most vertex tokens the connectivity network reads outside ``raw`` (the geometry
#: stage splits edges beyond it).
MAX_NETWORK_TOKENS = 2048
#: A full-token decode that keeps fewer than this share of its vertices is replaced by
#: the ``split`` decode (the first ``max_vertices`` farthest-point tokens).
MIN_KEPT_SHARE = 0.9


def check_large_meshes(mode: str) -> str:
    """``mode`` if it is one of :data:`LARGE_MESH_MODES`.

    Raises
    ------
    ValueError
        Any other value.
    """
    if mode not in LARGE_MESH_MODES:
        raise ValueError(f"large_meshes must be one of {', '.join(LARGE_MESH_MODES)}, "
                         f"not {mode!r}")
    return mode


def network_vertices(wanted: int, max_vertices: int, mode: str, *, raw: bool) -> int:
    """Vertices the networks place for a request that wants ``wanted`` of them.

    Parameters
    ----------
    wanted : int
        The request's vertex count (its target, else the model's default).
    max_vertices : int
        The model's token count.
    mode : {"split", "tokens"}
        See the module docstring.
    raw : bool
        ``raw`` requests give every vertex to the networks.

    Returns
    -------
    int
        At most ``wanted``; the geometry stage splits edges up to ``wanted``.
    """
    if raw:
        return wanted
    if check_large_meshes(mode) == "split":
        return min(wanted, max_vertices)
    return min(wanted, max(max_vertices, MAX_NETWORK_TOKENS))


def needs_split(n_tokens: int, n_kept: int, max_vertices: int) -> bool:
    """Whether a decode of ``n_tokens`` tokens that kept ``n_kept`` vertices falls back
    to the ``split`` decode (see the module docstring)."""
    return n_tokens > max_vertices and n_kept < MIN_KEPT_SHARE * n_tokens
