"""What the pipeline needs from a model: three functions on numpy arrays.

:class:`OnnxBackend` runs the exported graphs in onnxruntime; the torch networks offer
the same interface (:class:`spacemesh.nn.model.TorchBackend`), which is how the torch
and onnxruntime pipelines are compared.

Graph interface (names of the ONNX inputs and outputs):

``encoder``
    ``points`` (B, P, 3 or 6) float32 -> ``volume_0`` ... ``volume_{L-1}``
    (B, C_r, R_r, R_r, R_r) float32.
``denoiser``
    ``x_t`` (B, N, 4) float32, ``t`` (B,) int64, ``volume_*`` -> ``eps`` (B, N, 4);
    a local-point denoiser (``config.denoiser.local_points > 0``) also takes ``points``
    (B, P, 3 or 6) float32, the encoder's input.
``connectivity``
    ``vertices`` (B, N, 3) float32, ``valid`` (B, N) bool, ``volume_*`` ->
    ``x`` (B, N, k), ``root``, ``prev``, ``next`` (B, N, kp), ``tau`` (1,).

Reproducible to the bit: :class:`OnnxBackend` runs every graph call on one batch item
with onnxruntime on one thread (``intra_op_num_threads = 1``), and runs the items of a
batch at once on its own pool of ``workers`` threads. onnxruntime's parallel kernels do
not sum in a fixed order, so a multi-threaded operator can change the last bits of an
output from one run to the next, and the decode's thresholds turn those bits into
different meshes; one item on one thread always sums in the same order. An item's
outputs therefore depend on neither the thread count, nor the other items of its batch,
nor the process.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from spacemesh.typed import FloatArray

ENCODER_INPUTS = ("points",)
DENOISER_INPUTS = ("x_t", "t")
#: The extra input of a local-point denoiser graph (after the volumes).
DENOISER_POINTS = "points"
CONNECTIVITY_INPUTS = ("vertices", "valid")
CONNECTIVITY_OUTPUTS = ("x", "root", "prev", "next", "tau")


def volume_names(count: int) -> list[str]:
    """``["volume_0", ..., "volume_{count-1}"]``."""
    return [f"volume_{i}" for i in range(count)]


@dataclass(frozen=True)
class ConnectivityOutputs:
    """Per-vertex embeddings of a batch.

    Attributes
    ----------
    x : (B, N, k) float32
    root, prev, next : (B, N, kp) float32
    tau : float
    """

    x: FloatArray
    root: FloatArray
    prev: FloatArray
    next: FloatArray
    tau: float


class Backend(Protocol):
    """The three networks, numpy in and numpy out."""

    def encode(self, points: np.ndarray) -> list[np.ndarray]:
        """Feature volumes of ``points`` ``(B, P, 3 or 6)``."""
        ...

    def denoise(self, x_t: np.ndarray, t: np.ndarray, volumes: list[np.ndarray]) -> np.ndarray:
        """Predicted noise ``(B, N, 4)`` (a local-point model's backend also takes
        ``points``, see :func:`denoiser_fn`)."""
        ...

    def connect(
        self, vertices: np.ndarray, valid: np.ndarray, volumes: list[np.ndarray]
    ) -> ConnectivityOutputs:
        """Per-vertex embeddings."""
        ...


class OnnxBackend:
    """The three exported graphs in onnxruntime sessions, one batch item per call.

    Parameters
    ----------
    encoder, denoiser, connectivity : onnxruntime.InferenceSession
        Sessions with one intra-op thread
        (:func:`spacemesh.runtime.repository.create_session`), so that an item's outputs
        are the same in every run.
    workers : int
        Threads that run the items of a batch at once (each item one graph call); one
        pool, shared by the threads that call the backend (the service's two lanes).
    """

    def __init__(self, *, encoder, denoiser, connectivity, workers: int = 1) -> None:
        self.encoder = encoder
        self.denoiser = denoiser
        self.connectivity = connectivity
        self.workers = max(int(workers), 1)
        self.n_volumes = len(encoder.get_outputs())
        self._volumes = volume_names(self.n_volumes)
        self._pool: ThreadPoolExecutor | None = None
        self._pool_lock = threading.Lock()

    def _run(self, session, outputs: Sequence[str], feeds: dict[str, np.ndarray]
             ) -> list[np.ndarray]:
        """``session.run(outputs, feeds)`` one batch item at a time, the items on
        :attr:`workers` threads; the outputs of the items concatenated along the batch
        axis (an output without one, such as ``tau`` with fewer than two axes, is the
        first item's).

        Parameters
        ----------
        session : onnxruntime.InferenceSession
        outputs : sequence of str
        feeds : dict of str to array
            Every input with the batch axis first (B, ...).

        Returns
        -------
        list of arrays
            One per name of ``outputs``.
        """
        size = len(next(iter(feeds.values())))

        def item(b: int) -> list[np.ndarray]:
            return session.run(list(outputs), {k: v[b:b + 1] for k, v in feeds.items()})

        if size <= 1 or self.workers == 1:
            runs = [item(b) for b in range(size)]
        else:
            with self._pool_lock:
                if self._pool is None:
                    self._pool = ThreadPoolExecutor(self.workers,
                                                    thread_name_prefix="onnx-item")
            runs = list(self._pool.map(item, range(size)))
        if size == 1:
            return runs[0]
        # every batched output is (1, ...) with at least two axes; tau is (1,) or ()
        return [np.concatenate(parts) if np.ndim(parts[0]) >= 2 else parts[0]
                for parts in zip(*runs, strict=True)]

    def encode(self, points: np.ndarray) -> list[np.ndarray]:
        """Feature volumes of ``points`` ``(B, P, 3 or 6)``."""
        return self._run(self.encoder, self._volumes,
                         {"points": np.ascontiguousarray(points, np.float32)})

    def denoise(self, x_t: np.ndarray, t: np.ndarray, volumes: list[np.ndarray],
                points: np.ndarray | None = None) -> np.ndarray:
        """Predicted noise ``(B, N, 4)`` (``points``: the encoder's input, for a
        local-point denoiser graph)."""
        feeds: dict[str, np.ndarray] = {"x_t": np.ascontiguousarray(x_t, np.float32),
                                        "t": np.asarray(t, np.int64)}
        feeds.update(zip(self._volumes, volumes, strict=True))
        if points is not None:
            feeds[DENOISER_POINTS] = np.ascontiguousarray(points, np.float32)
        return self._run(self.denoiser, ["eps"], feeds)[0]

    def connect(
        self, vertices: np.ndarray, valid: np.ndarray, volumes: list[np.ndarray]
    ) -> ConnectivityOutputs:
        """Per-vertex embeddings."""
        feeds = {
            "vertices": np.ascontiguousarray(vertices, np.float32),
            "valid": np.asarray(valid, dtype=bool),
        }
        feeds.update(zip(self._volumes, volumes, strict=True))
        x, root, prev, nxt, tau = self._run(self.connectivity, CONNECTIVITY_OUTPUTS, feeds)
        return ConnectivityOutputs(x, root, prev, nxt, tau=float(np.asarray(tau).reshape(-1)[0]))


def denoiser_fn(backend: Backend, volumes: list[np.ndarray], points: np.ndarray | None = None):
    """``denoise(x_t, t) -> eps`` of one batch for the sampler loop.

    Parameters
    ----------
    backend : Backend
    volumes : list of arrays
        The batch's encoder volumes.
    points : (B, P, 3 or 6) array, optional
        The encoder's input, passed on only for a local-point denoiser (None otherwise,
        so that backends without local points keep their three-argument ``denoise``).

    Returns
    -------
    callable
    """
    if points is None:
        return lambda x_t, t: backend.denoise(x_t, t, volumes)
    local: Any = backend  # a local-point backend: its denoise also takes the points
    return lambda x_t, t: local.denoise(x_t, t, volumes, points)
