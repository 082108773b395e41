"""Settings of the collection fit (:func:`spacemesh.fitting.collection.fit_collection`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from spacemesh.fitting.collection_losses import PairSampling
from spacemesh.fitting.collection_model import DecoderShape
from spacemesh.permutation import SINKHORN_ITERS


@dataclass(frozen=True)
class CollectionConfig:
    """Settings of :func:`fit_collection` (see docs/fitting/collection.md).

    The decoder's sizes are :class:`DecoderShape`'s; ``lr`` 1e-3 is the paper's.
    """

    latent_dim: int = 512
    width: int = 128
    layers: int = 2
    heads: int = 4
    feedforward: int = 512
    adjacency_dim: int = 16
    permutation_dim: int = 6
    reduction: str = "product"
    position_skip: bool = False
    distance: str = "spacetime"
    sinkhorn_iters: int = SINKHORN_ITERS
    lr: float = 3e-3
    code_lr: float | None = 3e-2  # of latent codes and positional embedding (None: lr)
    latent_std: float = 1.0
    warmup: int = 20  # steps of linear learning-rate warm-up
    clip: float | None = 1.0  # gradient norm clipping (None: off)
    position_weight: float = 1.0  # of the position + mask L2 against the connectivity losses
    # the position L2 of each mesh over its own vertices (False: over all N slots, where the
    # padding dilutes a small mesh's positions; the runs before 3 December 2026)
    per_vertex_positions: bool = True
    embedding_scale: float = 1.0
    false_positive_weight: float | None = 1.0
    false_positive_margin: float = 0.5
    sampling: PairSampling = field(default_factory=PairSampling)
    batch_size: int = 16  # meshes per step (all of them when the collection is smaller)
    seed: int = 0
    max_steps: int | None = None
    max_seconds: float | None = None  # of this call (a resumed run gets a new budget)
    checkpoint_seconds: float = 120.0
    check_every: int = 25  # steps between exactness checks when the cheap scores are 1
    l2_target: float = 5e-4  # stop early once every mesh is exact and this close
    threads: int | None = None  # None: as the process is; else spacemesh.threads
    device: str = "cpu"

    def shape(self, n_meshes: int, n_tokens: int) -> DecoderShape:
        """The decoder's sizes for a collection."""
        return DecoderShape(
            n_meshes, n_tokens, self.latent_dim, self.width, self.layers, self.heads,
            self.feedforward, self.adjacency_dim, self.permutation_dim, self.reduction,
            self.position_skip,
        )


#: Settings a resumed run takes from its checkpoint (the rest may change).
FIXED_SETTINGS = (
    "latent_dim", "width", "layers", "heads", "feedforward", "adjacency_dim",
    "permutation_dim", "reduction", "position_skip", "distance", "sinkhorn_iters",
)
