"""The batch on Ray Data: inputs as rows, a pool of :class:`~.work.Mesher` workers, the
manifest written as rows come back. The only module of the package that imports ray.

:func:`run_batch` joins a Ray cluster (``address``; ``auto`` for the cluster this process
runs in) or starts a local one, skips the inputs an earlier run finished
(:func:`~spacemesh.batch.manifest.finished`), maps the others over an actor pool of
``workers`` actors of ``threads`` CPUs each (each actor loads the model once), and
appends each row to the manifest as it arrives.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import ray

from spacemesh.batch.inputs import BatchInput, full_source, split_url
from spacemesh.batch.manifest import (
    MANIFEST_NAME,
    ManifestWriter,
    check_settings,
    finished,
    read_rows,
)
from spacemesh.batch.work import BatchSettings, Mesher
from spacemesh.threads import default_threads

#: Most Ray Data blocks of one run (more inputs share blocks; fewer give one per block,
#: so that the workers take inputs one at a time and stay balanced).
MAX_BLOCKS = 10_000

#: ``progress(row, done, total)`` after each finished input.
ProgressFn = Callable[[dict[str, Any], int, int], None]


@dataclass(frozen=True)
class BatchReport:
    """What a run did.

    Attributes
    ----------
    total : int
        Inputs named.
    skipped : int
        Inputs an earlier run had finished.
    succeeded, failed : int
        Inputs of this run that got an output / an error row.
    workers : int
        Workers of this run (0 when every input was skipped).
    seconds : float
        Wall time of the run.
    manifest : str
        The manifest's path or URL.
    rows : list of dict
        The manifest's rows after the run (this run's inputs first, in order).
    """

    total: int
    skipped: int
    succeeded: int
    failed: int
    workers: int
    seconds: float
    manifest: str
    rows: list[dict[str, Any]]


@contextmanager
def ray_session(address: str | None, cpus: int) -> Iterator[None]:
    """Ray for the run: the one this process already started, the cluster at
    ``address``, or a local one of ``cpus`` CPUs (shut down again afterwards).

    Raises
    ------
    ConnectionError
        No cluster at ``address``.
    """
    if ray.is_initialized():
        yield
        return
    if address is None:
        ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False,
                 logging_level=logging.ERROR, configure_logging=True)
    else:
        ray.init(address=address, logging_level=logging.ERROR, log_to_driver=False)
    try:
        yield
    finally:
        ray.shutdown()


def cluster_cpus() -> int:
    """CPUs of the Ray cluster this process is connected to (at least 1)."""
    return max(int(ray.cluster_resources().get("CPU", 1)), 1)


def run_batch(items: Sequence[BatchInput], settings: BatchSettings, *,
              workers: int | None = None, address: str | None = None,
              retry_errors: bool = False, progress: ProgressFn | None = None) -> BatchReport:
    """Mesh every input not finished yet and write the manifest.

    Parameters
    ----------
    items : sequence of BatchInput
        :func:`~spacemesh.batch.inputs.expand_inputs`.
    settings : BatchSettings
    workers : int, optional
        Workers (actors) of ``settings.threads`` CPUs each; default as many as the
        cluster's CPUs allow.
    address : str, optional
        A Ray cluster to join (``auto``: the one this process runs in); default a local
        Ray (or the one this process already started).
    retry_errors : bool
        Run inputs with any error row again (by default only errors that may pass:
        :data:`~spacemesh.batch.manifest.RETRIED_KINDS`).
    progress : callable, optional
        ``progress(row, done, total)`` after each finished input.

    Returns
    -------
    BatchReport

    Raises
    ------
    SettingsMismatch
        The output folder holds a batch made with other settings.
    ConnectionError
        No Ray cluster at ``address``.
    """
    started = time.perf_counter()
    fs, root = split_url(settings.out)
    root = root.rstrip("/")
    fs.makedirs(root, exist_ok=True)
    check_settings(fs, root, settings.record())
    previous = read_rows(fs, f"{root}/{MANIFEST_NAME}")
    existing = {full_source(fs, p) for p in fs.find(root)} if previous else set()
    done = finished(previous, existing, retry_errors=retry_errors)
    todo = [item for item in items if item.source not in done]
    writer = ManifestWriter(fs, root, previous)
    counts = {"succeeded": 0, "failed": 0}
    pool = 0
    try:
        if todo:
            local_cpus = max(default_threads(), (workers or 1) * settings.threads)
            with ray_session(address, local_cpus):
                pool = workers or max(cluster_cpus() // settings.threads, 1)
                for row in _rows(todo, settings, pool):
                    writer.add(row)
                    counts["failed" if row.get("error_kind") else "succeeded"] += 1
                    if progress is not None:
                        progress(row, counts["succeeded"] + counts["failed"], len(todo))
    finally:
        rows = writer.close(item.source for item in items)
    return BatchReport(total=len(items), skipped=len(items) - len(todo),
                       succeeded=counts["succeeded"], failed=counts["failed"], workers=pool,
                       seconds=time.perf_counter() - started,
                       manifest=full_source(fs, writer.path), rows=rows)


def _rows(todo: Sequence[BatchInput], settings: BatchSettings,
          workers: int) -> Iterator[dict[str, Any]]:
    """The manifest rows of ``todo`` as the workers finish them (in any order)."""
    for name in ("ray", "ray.data"):  # our progress lines instead of Ray's
        logging.getLogger(name).setLevel(logging.ERROR)
    context = ray.data.DataContext.get_current()
    context.enable_progress_bars = False
    context.print_on_execution_start = False
    context.execution_options.preserve_order = False
    dataset = ray.data.from_items([{"input": item.source, "name": item.name} for item in todo],
                                  override_num_blocks=min(len(todo), MAX_BLOCKS))
    worker: Any = Mesher  # a callable class: Ray Data builds one per actor
    mapped = dataset.map(worker, fn_constructor_kwargs={"settings": settings},
                         compute=ray.data.ActorPoolStrategy(size=min(workers, len(todo))),
                         num_cpus=settings.threads)
    for out in mapped.iter_rows():
        yield json.loads(out["row"])


__all__ = ["MAX_BLOCKS", "BatchReport", "cluster_cpus", "ray_session", "run_batch"]
