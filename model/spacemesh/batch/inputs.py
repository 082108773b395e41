"""The inputs of a batch: folders, globs and lists of files, local or at any fsspec URL.

Each argument of ``spacemesh batch INPUTS...`` is one of:

- ``@LIST``: a text file (itself local or at a URL) naming one input per line, a path or a
  URL; blank lines and lines starting with ``#`` are skipped, and a relative path is read
  relative to the list's own folder;
- a glob (``scans/*.ply``, ``s3://bucket/scans/**.xyz``): every file it matches;
- a folder: every file under it, at any depth, whose extension is one the operation
  reads (:data:`GENERATE_SUFFIXES`, or :data:`REPAIR_SUFFIXES` for ``--repair``);
- a file.

An input listed twice is meshed once. Every input gets an output *name*: its path
relative to the folder given (without the extension) for a folder's files, else its
file name's stem; inputs whose names would collide get ``-`` and 8 hex digits of their
source's SHA-1 appended, so that names are a function of the set of inputs.
"""

from __future__ import annotations

import hashlib
import posixpath
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import fsspec

from spacemesh.io.points import SUPPORTED_POINTS_READ
from spacemesh.io.surface import SURFACE_FORMATS

#: Extensions a folder's files are generated from (every point-cloud and mesh format).
GENERATE_SUFFIXES: tuple[str, ...] = SUPPORTED_POINTS_READ
#: Extensions a folder's files are repaired from (the mesh formats).
REPAIR_SUFFIXES: tuple[str, ...] = SURFACE_FORMATS
#: Characters that make an argument a glob.
GLOB_CHARACTERS = ("*", "?", "[")
#: The prefix of a list of inputs.
LIST_PREFIX = "@"


class InputError(ValueError):
    """An argument that names no input (a missing file, an empty glob or folder)."""


@dataclass(frozen=True)
class BatchInput:
    """One input file of a batch.

    Attributes
    ----------
    source : str
        A local path, or a URL with its protocol (``s3://bucket/a.ply``).
    name : str
        The output's name relative to the output folder, without extension
        (``a``, ``sub/b``).
    """

    source: str
    name: str


def split_url(source: str) -> tuple[Any, str]:
    """The fsspec filesystem of a path or URL, and the path within it.

    Parameters
    ----------
    source : str

    Returns
    -------
    fs : fsspec.AbstractFileSystem
    path : str
    """
    return fsspec.core.url_to_fs(source)


def is_local(fs: Any) -> bool:
    """Whether an fsspec filesystem is the local one."""
    protocol = fs.protocol
    protocols = (protocol,) if isinstance(protocol, str) else tuple(protocol)
    return "file" in protocols or "local" in protocols


def full_source(fs: Any, path: str) -> str:
    """A path within ``fs`` as a source: the plain path when local, else its URL."""
    return path if is_local(fs) else fs.unstrip_protocol(path)


def _suffix(path: str) -> str:
    return posixpath.splitext(path)[1].lower().lstrip(".")


def _stem(path: str) -> str:
    return posixpath.splitext(posixpath.basename(path.rstrip("/")))[0]


def _list_entries(argument: str) -> list[str]:
    """The inputs a ``@LIST`` names, relative ones joined to the list's folder."""
    location = argument[len(LIST_PREFIX):]
    fs, path = split_url(location)
    try:
        with fs.open(path, "rt", encoding="utf-8") as handle:
            lines = handle.read().splitlines()
    except (OSError, UnicodeDecodeError) as error:
        raise InputError(f"{location}: cannot read the list of inputs ({error})") from None
    folder = posixpath.dirname(path)
    entries = []
    for line in lines:
        entry = line.strip()
        if not entry or entry.startswith("#"):
            continue
        if "://" not in entry and not posixpath.isabs(entry):
            entry = full_source(fs, posixpath.join(folder, entry))
        entries.append(entry)
    return entries


def _expand(argument: str, suffixes: Sequence[str], *,
            from_list: bool = False) -> list[tuple[str, str]]:
    """(source, name) of every file one argument names."""
    fs, path = split_url(argument)
    if any(c in path for c in GLOB_CHARACTERS):
        found = [p for p in sorted(fs.glob(path)) if fs.isfile(p)]
        if not found:
            raise InputError(f"{argument}: the pattern matches no file")
        return [(full_source(fs, p), _stem(p)) for p in found]
    if fs.isdir(path):
        root = path.rstrip("/")
        found = [p for p in sorted(fs.find(root)) if _suffix(p) in suffixes]
        if not found:
            raise InputError(f"{argument}: the folder holds no file of a type read here "
                             f"({', '.join(suffixes)})")
        return [(full_source(fs, p), posixpath.splitext(posixpath.relpath(p, root))[0])
                for p in found]
    if fs.isfile(path):
        return [(full_source(fs, path), _stem(path))]
    where = " (listed)" if from_list else ""
    raise InputError(f"{argument}{where}: no such file or folder")


def _unique_names(found: Iterable[tuple[str, str]]) -> list[BatchInput]:
    """Drop repeated sources; disambiguate colliding names by a hash of the source."""
    seen: dict[str, str] = {}
    for source, name in found:
        seen.setdefault(source, name)
    counts: dict[str, int] = {}
    for name in seen.values():
        counts[name.lower()] = counts.get(name.lower(), 0) + 1
    out = []
    for source, name in seen.items():
        if counts[name.lower()] > 1:
            name = f"{name}-{hashlib.sha1(source.encode()).hexdigest()[:8]}"
        out.append(BatchInput(source, name))
    return out


def expand_inputs(arguments: Sequence[str], *, repair: bool = False) -> list[BatchInput]:
    """Every input file the command-line arguments name, in order, each once.

    Parameters
    ----------
    arguments : sequence of str
        Files, folders, globs and ``@LIST`` files, local paths or fsspec URLs.
    repair : bool
        Folders contribute their mesh files only (:data:`REPAIR_SUFFIXES`).

    Returns
    -------
    list of BatchInput

    Raises
    ------
    InputError
        An argument that names no file.
    """
    suffixes = REPAIR_SUFFIXES if repair else GENERATE_SUFFIXES
    found: list[tuple[str, str]] = []
    for argument in arguments:
        if argument.startswith(LIST_PREFIX):
            for entry in _list_entries(argument):
                found.extend(_expand(entry, suffixes, from_list=True))
        else:
            found.extend(_expand(argument, suffixes))
    if not found:
        raise InputError("no inputs given")
    return _unique_names(found)


__all__ = ["GENERATE_SUFFIXES", "LIST_PREFIX", "REPAIR_SUFFIXES", "BatchInput", "InputError",
           "expand_inputs", "full_source", "is_local", "split_url"]
