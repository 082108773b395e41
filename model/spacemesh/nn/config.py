"""Model configurations as data, and the one factory that builds networks from them.

Three named configurations, and two variants with the local-point denoiser
(``tiny-local``, ``small-local``: :attr:`DenoiserConfig.local_points`):

``tiny``
    For tests: trains in seconds, exports in seconds (width 32, one block, 64 vertices).
``small``
    The shipped default: trainable on a 2-core CPU in about an hour, fast at inference
    (denoiser width 128, connectivity width 128 with nearest-neighbour offsets and
    geometric attention, volumes 16/8, 256 vertices).
``paper``
    The sizes of the paper's Supplement C: embeddings 32 and 12, ten blocks of width 256,
    PVConv resolutions 32/16/8 with 64/128/256 channels, 1024 timesteps, 512 vertices.

A :class:`ModelConfig` round-trips through JSON (:meth:`ModelConfig.to_dict`,
:meth:`ModelConfig.from_dict`); checkpoints and model repositories store it that way.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any


@dataclass(frozen=True)
class EncoderConfig:
    """The PVCNN point-cloud encoder.

    Attributes
    ----------
    n_points : int
        Conditioning points fed to the encoder (inputs are subsampled or padded to it).
    normals : bool
        Whether the encoder also reads unit normals (input channels 6 instead of 3).
    stem : int
        Width of the per-point MLP before the first PVConv.
    resolutions, channels : tuple of int
        One PVConv per entry: voxel grid resolution and feature channels. Each PVConv's
        voxel-branch output is one of the feature volumes the other networks sample.
    """

    n_points: int = 2048
    normals: bool = False
    stem: int = 32
    resolutions: tuple[int, ...] = (16, 8)
    channels: tuple[int, ...] = (64, 128)


@dataclass(frozen=True)
class DenoiserConfig:
    """The Point-E-style vertex diffusion transformer.

    Attributes
    ----------
    width, layers, heads : int
        Transformer size.
    point_voxel : tuple of (resolution, channels)
        Optional PVConv layers on the vertex tokens after the input projection (the
        paper uses the encoder's sizes; CPU configs leave them out).
    local_points : int
        ``K`` of the local-point attention (0: none, the volumes only): before every
        block each vertex token attends to the ``K`` input points nearest its current
        position (their offsets, and their normals when the encoder reads normals; see
        :mod:`spacemesh.nn.local_points`). The denoiser then also takes the points.
    local_width : int
        Hidden width of the neighbour features of the local-point attention.
    """

    width: int = 128
    layers: int = 4
    heads: int = 4
    point_voxel: tuple[tuple[int, int], ...] = ()
    local_points: int = 0
    local_width: int = 32


@dataclass(frozen=True)
class ConnectivityConfig:
    """The connectivity transformer and the embedding sizes it predicts.

    Attributes
    ----------
    width, layers, heads : int
        Transformer size (no positional embedding).
    adjacency_dim : int
        Size ``k`` of the adjacency embedding ``x``.
    n_space : int
        Space coordinates of ``x`` under the spacetime distance (the rest are time).
    permutation_dim : int
        Size ``kp`` of each of ``y_root``, ``y_prev``, ``y_next``.
    distance, reduction : str
        Read by the decode; see :class:`spacemesh.decode.DecodeOptions`.
    distance_bias : bool
        Add ``-s_h |p_i - p_j|^2`` (one learned ``s_h`` per head) to the attention logits:
        a relative, permutation-equivariant locality prior (no positional embedding).
    fourier : int
        Octaves of sine/cosine features of each vertex's coordinates added to its input
        (a coordinate encoding, not a positional embedding: tokens remain a set).
    position_prior : bool
        Add ``c p_i`` (learned ``c``) to the first three space coordinates of ``x_i``, and
        start with small outputs: training then starts from the graph of Euclidean
        distance below a threshold instead of a random graph.
    point_voxel : tuple of (resolution, channels)
        Optional PVConv layers on the vertex tokens, as in the paper.
    neighbours : int
        Offsets to each vertex's ``K`` nearest vertices added to its input (0: none; see
        :mod:`spacemesh.nn.geometry`).
    geometric_attention : bool
        Each attention head also returns the mean and covariance of the offsets to the
        vertices it attends to.
    """

    width: int = 128
    layers: int = 4
    heads: int = 4
    adjacency_dim: int = 32
    n_space: int = 16
    permutation_dim: int = 12
    distance: str = "spacetime"
    reduction: str = "product"
    distance_bias: bool = True
    fourier: int = 0
    position_prior: bool = False
    point_voxel: tuple[tuple[int, int], ...] = ()
    neighbours: int = 0
    geometric_attention: bool = False


@dataclass(frozen=True)
class DiffusionConfig:
    """The noise process and the default inference sampler.

    Attributes
    ----------
    timesteps : int
        Training timesteps ``T``.
    schedule : {"cosine", "linear"}
        Beta schedule (see :mod:`spacemesh.runtime.schedule`).
    sampler : {"ddim", "ddpm"}
        Default inference sampler.
    steps : int
        Default inference steps (respaced).
    """

    timesteps: int = 1024
    schedule: str = "cosine"
    sampler: str = "ddim"
    steps: int = 50


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation settings (see :mod:`spacemesh.train.loop`).

    Attributes
    ----------
    batch_size : int
        Meshes per step, per process.
    lr : float
        Adam learning rate (after a linear warm-up of ``warmup`` steps).
    final_lr_ratio : float
        The rate decays along a half cosine from ``lr`` to ``lr * final_lr_ratio`` at
        ``steps`` (1.0 keeps it constant).
    steps : int
        Diffusion steps; each is followed by ``connectivity_steps`` connectivity steps.
    connectivity_steps : int
        Connectivity steps per diffusion step (the paper trains it 10 times as often).
    edge_weight, permutation_weight, epsilon_weight, mask_weight : float
        Loss weights: Eq. 3 (as a mean over vertex pairs) times 200, plus Eq. 5, plus the
        epsilon loss on positions and on the mask channel, as in the paper.
    scale_range : (float, float)
        Random per-axis scaling of each shape (then renormalised to [-1, 1]).
    connectivity_jitter : float
        Standard deviation of Gaussian noise added to the vertex positions that the
        connectivity network sees in training (the targets are unchanged), in the
        [-1, 1] frame; 0 trains on exact ground-truth positions as the paper does. At
        inference the network sees sampled vertices, which lie about 0.05 off the surface
        (median, ``small`` model), so some noise makes it robust to them.
    false_positive_weight : float, optional
        Weight of the non-edges that are currently below the threshold (hard negatives:
        mostly next-ring pairs) in the edge loss, instead of the paper's ``lambda``
        (:func:`spacemesh.nn.losses.edge_loss_dense`); None keeps the paper's loss.
    false_positive_margin : float
        Non-edges count as hard up to ``d < tau + margin``.
    grad_clip : float
        Gradient norm clip (0 disables).
    connectivity_trains_encoder : bool
        Backpropagate the connectivity loss into the encoder (the paper trains all
        networks together; CPU configs train the encoder by the diffusion loss only and
        skip the encoder's backward pass in connectivity steps).
    diffusion_only : bool
        Train the denoiser alone: the encoder is frozen (a base model's, or an
        ``--init-from`` run's) and no connectivity step is taken.
    encoder_cache : int
        In a diffusion-only run, augmented variants per training shape whose frozen
        encoder volumes are cached (each computed once, when first drawn; see
        :mod:`spacemesh.train.encoder_cache`); 0 runs the frozen encoder on freshly
        augmented shapes every step.
    val_every, checkpoint_every : int
        In diffusion steps.
    checkpoint_minutes : float
        Also write ``last.pt`` when this much wall time has passed since the last
        checkpoint (0: only every ``checkpoint_every`` steps), so that a killed run loses
        at most that much.
    val_shapes : int
        Validation shapes evaluated each time.
    augment : str
        Conditioning-cloud augmentation preset (:data:`spacemesh.data.augment.PRESETS`):
        ``none`` (the clean samples) or ``realistic`` (noise, uneven density, missing
        regions and outliers); the ground-truth mesh stays the clean one.
    warm_start : bool
        In a diffusion-only run on a base model, start the new denoiser from the base's
        (read back from its ``denoiser.onnx``; a local-point denoiser gets the shared
        weights and local attention that starts silent, see
        :func:`spacemesh.nn.denoiser.graft_denoiser`) instead of fresh weights.
    """

    batch_size: int = 8
    lr: float = 3e-4
    warmup: int = 100
    final_lr_ratio: float = 1.0
    steps: int = 2000
    connectivity_steps: int = 10
    edge_weight: float = 200.0
    permutation_weight: float = 1.0
    epsilon_weight: float = 1.0
    mask_weight: float = 1.0
    scale_range: tuple[float, float] = (0.75, 1.25)
    connectivity_jitter: float = 0.0
    false_positive_weight: float | None = None
    false_positive_margin: float = 0.5
    grad_clip: float = 1.0
    connectivity_trains_encoder: bool = True
    diffusion_only: bool = False
    encoder_cache: int = 4
    val_every: int = 100
    checkpoint_every: int = 100
    checkpoint_minutes: float = 0.0
    val_shapes: int = 32
    augment: str = "none"
    warm_start: bool = False


@dataclass(frozen=True)
class ModelConfig:
    """Everything needed to build, train and export one SpaceMesh model.

    Attributes
    ----------
    name : str
    max_vertices : int
        Vertex tokens of the diffusion (meshes are padded to it; a mask channel marks
        the real ones). Training shapes with more vertices are skipped.
    """

    name: str = "small"
    max_vertices: int = 256
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    denoiser: DenoiserConfig = field(default_factory=DenoiserConfig)
    connectivity: ConnectivityConfig = field(default_factory=ConnectivityConfig)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)
    train: TrainConfig = field(default_factory=TrainConfig)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready nested dict (tuples become lists)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ModelConfig:
        """Inverse of :meth:`to_dict` (unknown keys are an error)."""
        parts = {
            "encoder": EncoderConfig,
            "denoiser": DenoiserConfig,
            "connectivity": ConnectivityConfig,
            "diffusion": DiffusionConfig,
            "train": TrainConfig,
        }
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if key in parts:
                kwargs[key] = _dataclass_from_dict(parts[key], value)
            else:
                kwargs[key] = value
        return cls(**kwargs)

    def with_train(self, **changes: Any) -> ModelConfig:
        """A copy with some :class:`TrainConfig` fields replaced."""
        return replace(self, train=replace(self.train, **changes))


def _tupled(value: Any) -> Any:
    if isinstance(value, list):
        return tuple(_tupled(v) for v in value)
    return value


def _dataclass_from_dict(kind: type, data: dict[str, Any]) -> Any:
    names = {f.name for f in fields(kind)}
    unknown = set(data) - names
    if unknown:
        raise ValueError(f"unknown {kind.__name__} keys: {', '.join(sorted(unknown))}")
    return kind(**{k: _tupled(v) for k, v in data.items()})


TINY = ModelConfig(
    name="tiny",
    max_vertices=64,
    encoder=EncoderConfig(n_points=256, stem=16, resolutions=(8, 4), channels=(16, 32)),
    denoiser=DenoiserConfig(width=32, layers=1, heads=2),
    connectivity=ConnectivityConfig(
        width=32, layers=2, heads=2, adjacency_dim=16, n_space=8, permutation_dim=6, fourier=2,
        position_prior=True, neighbours=4, geometric_attention=True,
    ),
    diffusion=DiffusionConfig(timesteps=64, steps=8),
    train=TrainConfig(
        batch_size=4, lr=1e-3, warmup=0, steps=20, connectivity_steps=2,
        val_every=10, checkpoint_every=10, val_shapes=4,
    ),
)

SMALL = ModelConfig(
    name="small",
    max_vertices=256,
    encoder=EncoderConfig(n_points=2048, stem=32, resolutions=(16, 8), channels=(32, 64)),
    denoiser=DenoiserConfig(width=128, layers=4, heads=4),
    connectivity=ConnectivityConfig(
        width=128, layers=4, heads=4, adjacency_dim=32, n_space=16, permutation_dim=12,
        fourier=4, position_prior=True, neighbours=16, geometric_attention=True,
    ),
    diffusion=DiffusionConfig(timesteps=1024, schedule="cosine", sampler="ddim", steps=50),
    train=TrainConfig(batch_size=6, lr=7e-4, warmup=20, final_lr_ratio=0.1, steps=2000,
                      connectivity_steps=10,
                      connectivity_trains_encoder=False, val_every=100, checkpoint_every=100,
                      val_shapes=24),
)

PAPER = ModelConfig(
    name="paper",
    max_vertices=512,
    encoder=EncoderConfig(n_points=2048, stem=64, resolutions=(32, 16, 8), channels=(64, 128, 256)),
    denoiser=DenoiserConfig(
        width=256, layers=10, heads=8, point_voxel=((32, 64), (16, 128), (8, 256))
    ),
    connectivity=ConnectivityConfig(
        width=256, layers=10, heads=8, adjacency_dim=32, n_space=16, permutation_dim=12,
        point_voxel=((32, 64), (16, 128), (8, 256)),
    ),
    diffusion=DiffusionConfig(timesteps=1024, schedule="cosine", sampler="ddpm", steps=1024),
    train=TrainConfig(batch_size=32, lr=1e-4, warmup=1000, steps=800_000, connectivity_steps=10,
                      val_every=5000, checkpoint_every=5000, val_shapes=256),
)

#: ``tiny`` with the local-point denoiser (tests).
TINY_LOCAL = replace(TINY, name="tiny-local",
                     denoiser=replace(TINY.denoiser, local_points=8, local_width=16))

#: ``small`` with the local-point denoiser: each vertex token reads its 16 nearest input
#: points before every block.
SMALL_LOCAL = replace(SMALL, name="small-local",
                      denoiser=replace(SMALL.denoiser, local_points=16))

#: The named configurations.
CONFIGS: dict[str, ModelConfig] = {
    c.name: c for c in (TINY, SMALL, PAPER, TINY_LOCAL, SMALL_LOCAL)
}


def get_config(name: str) -> ModelConfig:
    """The named configuration (``tiny``, ``small``, ``paper``, ``tiny-local`` or
    ``small-local``).

    Parameters
    ----------
    name : str

    Returns
    -------
    ModelConfig
    """
    try:
        return CONFIGS[name]
    except KeyError:
        raise ValueError(f"unknown config {name!r}; choose from {', '.join(CONFIGS)}") from None
