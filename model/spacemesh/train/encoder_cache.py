"""A frozen encoder's volumes, computed once per augmented training shape.

In a diffusion-only run (``TrainConfig.diffusion_only``) the encoder does not train, so
its output for a shape depends only on the shape's augmentation (the per-axis scaling,
the subset of conditioning points and, with ``TrainConfig.augment``, the realistic
cloud of :mod:`spacemesh.data.augment`: noise, drops, outliers). A cache variant is one
such augmentation: each training shape gets ``variants`` fixed augmentations, drawn
from a generator seeded by ``(seed, shape, variant)``; a variant's volumes are computed
the first time a batch draws it and kept (float16, on the training device), so the
encoder's forward pass, about half of a diffusion step on a CPU, is paid once per
variant instead of once per step.

Memory: ``shapes * variants * sum(C_r R_r^3) * 2`` bytes, 0.33 MB per variant for the
``small`` encoder (4,000 shapes with 4 variants: 5.2 GB); the positions and points of a
variant are recomputed from its seed each time (cheap), not stored.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch
from torch import Tensor

from spacemesh.data.augment import AugmentConfig
from spacemesh.train.batching import Batch, Sample, collate


def variant_seed(seed: int, shape: int, variant: int) -> np.random.Generator:
    """The generator of one augmentation variant of one shape."""
    return np.random.default_rng([seed, shape, variant])


def collate_variants(
    samples: Sequence[Sample], keys: Sequence[tuple[int, int]], *, seed: int, n_points: int,
    normals: bool, pad_to: int, scale_range: tuple[float, float] | None,
    augment: AugmentConfig | None = None,
) -> Batch:
    """A diffusion batch of fixed augmentation variants (no connectivity).

    Parameters
    ----------
    samples : sequence of Sample
        All training shapes.
    keys : sequence of (shape index, variant)
    seed : int
    n_points, normals, pad_to, scale_range, augment
        As in :func:`spacemesh.train.batching.collate`.

    Returns
    -------
    Batch
        Row ``j`` is variant ``keys[j][1]`` of shape ``keys[j][0]``, the same every time.
    """
    rows = [
        collate([samples[i]], n_points=n_points, normals=normals, pad_to=pad_to,
                connectivity=False, rng=variant_seed(seed, i, v), scale_range=scale_range,
                augment=augment)
        for i, v in keys
    ]
    return Batch(torch.cat([r.points for r in rows]), torch.cat([r.positions for r in rows]),
                 torch.cat([r.valid for r in rows]), None, None,
                 [s for r in rows for s in r.samples])


class EncoderCache:
    """Volumes of a frozen encoder per (shape, variant), filled on first use.

    Parameters
    ----------
    encoder : callable
        ``points (B, P, C) -> list of (B, C_r, R_r, R_r, R_r)``, frozen.
    samples : sequence of Sample
        The training shapes.
    variants : int
        Augmentation variants per shape.
    seed : int
    n_points, normals, pad_to, scale_range, augment
        How batches are made (see :func:`collate_variants`); the cached volumes are
        those of the augmented clouds, so a cache serves one augmentation setting.
    device : torch.device
        Where volumes are computed and stored.
    """

    def __init__(
        self, encoder: Callable[[Tensor], list[Tensor]], samples: Sequence[Sample], *,
        variants: int, seed: int, n_points: int, normals: bool, pad_to: int,
        scale_range: tuple[float, float] | None, device: torch.device,
        augment: AugmentConfig | None = None,
    ) -> None:
        if variants < 1:
            raise ValueError("the encoder cache needs at least one variant per shape")
        self.encoder = encoder
        self.samples = samples
        self.variants = variants
        self.seed = seed
        self.device = device
        self.batch_options = {"n_points": n_points, "normals": normals, "pad_to": pad_to,
                              "scale_range": scale_range, "augment": augment}
        self.store: dict[tuple[int, int], list[Tensor]] = {}
        self.misses = 0

    def __len__(self) -> int:
        return len(self.store)

    @property
    def nbytes(self) -> int:
        """Bytes held."""
        return sum(v.numel() * v.element_size() for vols in self.store.values() for v in vols)

    def batch(self, indices: Sequence[int], rng: np.random.Generator
              ) -> tuple[Batch, list[Tensor]]:
        """A batch of the shapes ``indices`` (a random variant each) and its volumes.

        Parameters
        ----------
        indices : sequence of int
        rng : numpy.random.Generator
            Draws the variants.

        Returns
        -------
        batch : Batch
            On the cache's device.
        volumes : list of (B, C_r, R_r, R_r, R_r) float32 tensors
        """
        drawn = rng.integers(0, self.variants, size=len(indices))
        keys = [(int(i), int(v)) for i, v in zip(indices, drawn, strict=True)]
        batch = collate_variants(self.samples, keys, seed=self.seed,
                                 **self.batch_options).to(self.device)
        self.fill(keys, batch.points)
        volumes = [torch.stack([self.store[key][level] for key in keys]).float()
                   for level in range(len(self.store[keys[0]]))]
        return batch, volumes

    def fill(self, keys: Sequence[tuple[int, int]], points: Tensor | None = None) -> int:
        """Compute the volumes of the variants ``keys`` not cached yet.

        Parameters
        ----------
        keys : sequence of (shape index, variant)
        points : (len(keys), P, C) tensor, optional
            Their encoder input, if already collated.

        Returns
        -------
        int
            Variants computed.
        """
        missing = [key for key in dict.fromkeys(keys) if key not in self.store]
        if not missing:
            return 0
        if points is None:
            points = collate_variants(self.samples, missing, seed=self.seed,
                                      **self.batch_options).points.to(self.device)
        else:
            points = points[[list(keys).index(key) for key in missing]]
        with torch.no_grad():
            computed = self.encoder(points)
        for n, key in enumerate(missing):
            self.store[key] = [v[n].detach().to(torch.float16) for v in computed]
        self.misses += len(missing)
        return len(missing)
