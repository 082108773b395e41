"""The manifest of a batch: one row per input, as JSON lines (and Parquet) in the output folder.

A row (:data:`ROW_FIELDS`) says where an input's mesh went, how many points were read
and used (a cloud of more than the working size is reduced to it, as ``spacemesh
generate`` and the service reduce it), the mesh's fit report, and,
for an input that failed, the error's stable ``kind`` (the service's problem slugs:
``malformed-input``, ``degenerate-geometry`` ...) and message. The driver appends each
row to ``manifest.jsonl`` as its input finishes (a local folder; at a URL the file is
rewritten every :data:`REMOTE_FLUSH_SECONDS`), so a run that is stopped keeps the rows
of the inputs it finished; at the end the file is rewritten with one row per input
(the last one wins), and, where pyarrow is installed, ``manifest.parquet`` holds the
same rows with ``fit`` and ``repair`` as JSON text. :func:`finished` tells a rerun which
inputs it may skip: those with a row without error whose output file exists, and those
whose error was the input's own (a corrupt file fails the same way again);
:func:`check_settings` refuses a rerun with other settings.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterable, Mapping
from typing import Any

from spacemesh.batch.inputs import is_local

#: The manifest's file name in the output folder.
MANIFEST_NAME = "manifest.jsonl"
#: The Parquet copy's file name (written only where pyarrow is installed).
PARQUET_NAME = "manifest.parquet"
#: The fields of a row, in order.
ROW_FIELDS = ("input", "output", "operation", "points_read", "points_used", "vertices",
              "faces", "fit", "repair", "error_kind", "error", "seconds")
#: Fields written to Parquet as JSON text (nested dictionaries whose keys vary by row).
JSON_FIELDS = ("fit", "repair")
#: The file in the output folder recording the settings of the batch it holds.
SETTINGS_NAME = "batch.json"
#: Error kinds a rerun tries again (a file that could not be opened, an internal error);
#: other errors are the input's own and come back the same (``--retry-errors`` retries
#: them too).
RETRIED_KINDS = ("unreadable-input", "internal-error")
#: How often a manifest at a URL (where files cannot be appended to) is rewritten.
REMOTE_FLUSH_SECONDS = 30.0


def read_rows(fs: Any, path: str) -> dict[str, dict[str, Any]]:
    """The rows of an existing manifest by input (the last row of an input wins).

    Lines that are not a JSON object with an ``input`` (a line cut short when a run was
    killed) are skipped.

    Parameters
    ----------
    fs : fsspec.AbstractFileSystem
    path : str
        The manifest within ``fs``.

    Returns
    -------
    dict
        Rows by input; empty when there is no manifest.
    """
    if not fs.exists(path):
        return {}
    rows: dict[str, dict[str, Any]] = {}
    with fs.open(path, "rt", encoding="utf-8") as handle:
        for line in handle:
            try:
                row = json.loads(line)
            except ValueError:
                continue
            if isinstance(row, dict) and isinstance(row.get("input"), str):
                rows[row["input"]] = row
    return rows


def finished(rows: Mapping[str, Mapping[str, Any]], existing: set[str], *,
             retry_errors: bool = False) -> set[str]:
    """The inputs a rerun skips: a row without error whose output is in ``existing``,
    and a row whose error the same input would meet again (any kind but
    :data:`RETRIED_KINDS`) unless ``retry_errors``.

    Parameters
    ----------
    rows : mapping
        :func:`read_rows`.
    existing : set of str
        The files in the output folder (as rows name them).
    retry_errors : bool
        Run every input with an error row again.

    Returns
    -------
    set of str
    """
    done = set()
    for source, row in rows.items():
        kind = row.get("error_kind")
        if kind is None:
            if row.get("output") in existing:
                done.add(source)
        elif not retry_errors and kind not in RETRIED_KINDS:
            done.add(source)
    return done


def check_settings(fs: Any, root: str, settings: Mapping[str, Any]) -> None:
    """Record a run's settings in the output folder (:data:`SETTINGS_NAME`), or check
    them against the ones recorded there: a rerun must mesh with the same options,
    format, operation and model, or its outputs would not match the ones it skips.

    Parameters
    ----------
    fs : fsspec.AbstractFileSystem
    root : str
        The output folder within ``fs``.
    settings : mapping
        JSON values.

    Raises
    ------
    SettingsMismatch
        The folder holds a batch made with other settings.
    """
    path = f"{root}/{SETTINGS_NAME}"
    current = json.loads(json.dumps(dict(settings)))
    if fs.exists(path):
        with fs.open(path, "rt", encoding="utf-8") as handle:
            try:
                recorded = json.load(handle)
            except ValueError:
                recorded = None
        if recorded is not None and recorded != current:
            changed = sorted(k for k in set(recorded) | set(current)
                             if recorded.get(k) != current.get(k))
            raise SettingsMismatch(
                f"{root} holds a batch made with other settings ({', '.join(changed)}); "
                "give the same ones, or another output folder")
    write_bytes(fs, path, (json.dumps(current, indent=1) + "\n").encode())


class SettingsMismatch(ValueError):
    """An output folder holding a batch made with other settings."""


class ManifestWriter:
    """Appends rows as inputs finish and writes the final manifest.

    Parameters
    ----------
    fs : fsspec.AbstractFileSystem
        The output folder's filesystem.
    root : str
        The output folder within ``fs``.
    previous : mapping
        The rows already there (:func:`read_rows`); kept unless an input's new row
        replaces its row.
    """

    def __init__(self, fs: Any, root: str, previous: Mapping[str, dict[str, Any]]) -> None:
        self.fs = fs
        self.root = root.rstrip("/")
        self.path = f"{self.root}/{MANIFEST_NAME}"
        self.rows: dict[str, dict[str, Any]] = dict(previous)
        self.local = is_local(fs)
        self._flushed = time.monotonic()
        self._handle = open(self.path, "a", encoding="utf-8") if self.local else None

    def add(self, row: Mapping[str, Any]) -> None:
        """Record one finished input's row (appended at once to a local manifest)."""
        clean = {name: row.get(name) for name in ROW_FIELDS}
        self.rows[str(clean["input"])] = clean
        if self._handle is not None:
            self._handle.write(json.dumps(clean) + "\n")
            self._handle.flush()
        elif time.monotonic() - self._flushed > REMOTE_FLUSH_SECONDS:
            self._rewrite(self.rows.values())

    def close(self, order: Iterable[str]) -> list[dict[str, Any]]:
        """Write the manifest with one row per input: ``order`` first, then any other
        input an earlier run recorded; and its Parquet copy where pyarrow is installed.

        Parameters
        ----------
        order : iterable of str
            This run's inputs, in order.

        Returns
        -------
        list of dict
            The rows written.
        """
        if self._handle is not None:
            self._handle.close()
            self._handle = None
        ordered = [self.rows[s] for s in order if s in self.rows]
        listed = {row["input"] for row in ordered}
        ordered += [row for source, row in self.rows.items() if source not in listed]
        self._rewrite(ordered)
        write_parquet(self.fs, f"{self.root}/{PARQUET_NAME}", ordered)
        return ordered

    def _rewrite(self, rows: Iterable[Mapping[str, Any]]) -> None:
        data = "".join(json.dumps(dict(row)) + "\n" for row in rows).encode()
        write_bytes(self.fs, self.path, data)
        self._flushed = time.monotonic()


def write_bytes(fs: Any, path: str, data: bytes) -> None:
    """Write a file whole: locally through a temporary file and a rename, so that a
    reader (or a rerun after a kill) never sees it cut short."""
    if is_local(fs):
        partial = f"{path}.part"
        with open(partial, "wb") as handle:
            handle.write(data)
        os.replace(partial, path)
    else:
        fs.pipe_file(path, data)


def write_parquet(fs: Any, path: str, rows: list[dict[str, Any]]) -> bool:
    """The rows as Parquet (``fit`` and ``repair`` as JSON text); False without pyarrow.

    Parameters
    ----------
    fs : fsspec.AbstractFileSystem
    path : str
    rows : list of dict

    Returns
    -------
    bool
        Whether the file was written.
    """
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return False
    columns: dict[str, list[Any]] = {name: [] for name in ROW_FIELDS}
    for row in rows:
        for name in ROW_FIELDS:
            value = row.get(name)
            if name in JSON_FIELDS and value is not None:
                value = json.dumps(value)
            columns[name].append(value)
    schema = pa.schema([("input", pa.string()), ("output", pa.string()),
                        ("operation", pa.string()), ("vertices", pa.int64()),
                        ("faces", pa.int64()), ("fit", pa.string()), ("repair", pa.string()),
                        ("error_kind", pa.string()), ("error", pa.string()),
                        ("seconds", pa.float64())])
    table = pa.table(columns, schema=schema)
    with fs.open(path, "wb") as handle:
        pq.write_table(table, handle)
    return True


__all__ = ["JSON_FIELDS", "MANIFEST_NAME", "PARQUET_NAME", "RETRIED_KINDS", "ROW_FIELDS",
           "SETTINGS_NAME", "ManifestWriter", "SettingsMismatch", "check_settings",
           "finished", "read_rows", "write_bytes", "write_parquet"]
