"""One meaning of ``--threads`` for every command: how many CPU threads the libraries use.

``threads >= 1`` means exactly that many threads for torch's intra-op pool, for the
BLAS/OpenMP pools of numpy and scipy (limited through threadpoolctl, so that libraries
loaded before the limit obey it too) and for the served networks, whose onnxruntime
sessions run one batch item per call on one thread each and run up to that many items at
once (:class:`spacemesh.runtime.backend.OnnxBackend`: the meshes do not depend on the
count); ``0`` or ``None`` means one per core this process may run on
(:func:`default_threads`). Waiting threads sleep instead of spinning: OpenMP gets
``OMP_WAIT_POLICY=PASSIVE`` (unless set) and onnxruntime sessions are built with
spinning off (:func:`spacemesh.runtime.repository.create_session`), so that a loaded
machine is shared instead of fought over. torch's inter-op pool is one thread: nothing
here runs independent torch operators in parallel.

This module imports neither torch nor onnxruntime; it configures torch only when torch is
already loaded, and otherwise through the environment that torch reads when it loads.
"""

from __future__ import annotations

import os
import sys

#: Environment variables that BLAS/OpenMP libraries read when they load.
THREAD_VARIABLES = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
)
#: torch's inter-op pool (parallel independent operators): deliberately one thread.
INTEROP_THREADS = 1


def default_threads() -> int:
    """The thread count that ``0`` stands for: the cores this process may run on.

    Returns
    -------
    int
        ``len(os.sched_getaffinity(0))`` where the platform has it (it honours CPU
        affinity and container cpusets), else ``os.cpu_count()``; at least 1.
    """
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # macOS, Windows
        return max(os.cpu_count() or 1, 1)


def resolve_threads(threads: int | None) -> int:
    """``threads`` itself when at least 1, else :func:`default_threads`.

    Parameters
    ----------
    threads : int or None
        A ``--threads`` value: ``None`` or ``0`` for the default.

    Returns
    -------
    int
        At least 1.

    Raises
    ------
    ValueError
        For a negative count.
    """
    if threads is not None and threads < 0:
        raise ValueError(f"threads must be 0 (one per core) or more (got {threads})")
    return threads if threads else default_threads()


def limit_threads(threads: int | None) -> int:
    """Use exactly :func:`resolve_threads` ``(threads)`` CPU threads from now on.

    Sets :data:`THREAD_VARIABLES` (read by libraries that load later), limits the pools of
    libraries already loaded (threadpoolctl), and sets torch's intra-op threads (and its
    inter-op pool to :data:`INTEROP_THREADS`, where torch still allows it) when torch is
    loaded. Pass the result on as a model's ``threads``
    (:meth:`spacemesh.runtime.MeshGenerator.from_repository`).

    Parameters
    ----------
    threads : int or None
        ``0`` or ``None``: one per core.

    Returns
    -------
    int
        The thread count in force.
    """
    n = resolve_threads(threads)
    for name in THREAD_VARIABLES:
        os.environ[name] = str(n)
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # sleep, do not spin, when idle
    from threadpoolctl import threadpool_limits  # a dependency: every pool, loaded or not

    threadpool_limits(n)
    torch = sys.modules.get("torch")
    if torch is not None:
        torch.set_num_threads(n)
        if torch.get_num_interop_threads() != INTEROP_THREADS:
            try:
                torch.set_num_interop_threads(INTEROP_THREADS)
            except RuntimeError:  # inter-op work already started: torch keeps its pool
                pass
    return n
