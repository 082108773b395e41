"""One batch worker's work: a loaded model that meshes one input at a time.

:class:`Mesher` holds one :class:`~spacemesh.runtime.MeshGenerator` for its life (Ray Data
builds one per worker) and turns an input row into a manifest row. It reads the input
exactly as ``spacemesh generate`` does (:func:`~spacemesh.runtime.cloud.read_generate_input`:
a cloud of more than the working size reduced to it, a mesh's surface sampled to the
model's point count, the points checked), runs
:meth:`MeshGenerator.generate` with the same options and writes
:func:`~spacemesh.io.export_mesh`'s bytes, so its files are byte-identical to the
command's for the same seed, format, options and thread count. With ``repair`` set it
runs the repair's automatic region instead, as ``spacemesh repair --auto`` (``--holes``,
``--defects``) does, and writes the repair only when :func:`~spacemesh.repair.verify_repair`
finds nothing changed outside the region.

Memory is bounded per worker: one input at a time, read within :attr:`BatchSettings.limits`
(the service's default limits) after its size is checked against
:attr:`BatchSettings.max_input_bytes`; the mesh goes to its file from the worker, and
only the manifest row (a few hundred bytes) goes back to the driver.
"""

from __future__ import annotations

import json
import posixpath
import time
from dataclasses import dataclass, field
from typing import Any

from spacemesh.batch.inputs import full_source, is_local, split_url
from spacemesh.batch.manifest import write_bytes
from spacemesh.errors import KindedError
from spacemesh.io import MeshFormatError, ReadLimits
from spacemesh.io.errors import read_error_kind
from spacemesh.io.reduce import DEFAULT_MAX_BINARY_POINTS
from spacemesh.runtime.cloud import read_generate_input
from spacemesh.runtime.options import GenerateOptions, OptionError
from spacemesh.threads import limit_threads

#: ``--repair`` values and the automatic region each one asks for.
REPAIR_MODES = {"auto": "all", "holes": "holes", "defects": "defects"}
#: Output formats (the extension of each output file).
OUTPUT_FORMATS = ("obj", "ply", "off", "glb", "gltf")
#: The largest input file read (bytes).
MAX_INPUT_BYTES = 512 * 1024 * 1024
#: The read limits of a batch input: the service's defaults (points in a file, before a
#: bigger cloud is reduced to the working size as ``spacemesh generate`` and the service
#: reduce it; mesh vertices and faces; decoded bytes).
BATCH_LIMITS = ReadLimits(max_points=DEFAULT_MAX_BINARY_POINTS, max_vertices=1_000_000,
                          max_faces=2_000_000, max_bytes=MAX_INPUT_BYTES)


class RowError(Exception):
    """A failed input of a known kind (see :func:`error_kind`)."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind


@dataclass(frozen=True)
class BatchSettings:
    """What every input of a batch gets.

    Attributes
    ----------
    out : str
        The output folder, a local path or an fsspec URL.
    options : GenerateOptions
        As parsed from the flags (not resolved; the generator resolves them, as for
        ``spacemesh generate``). With ``repair``, only ``seed``, ``steps`` and
        ``sampler`` apply.
    file_format : str
        One of :data:`OUTPUT_FORMATS`.
    repair : str, optional
        One of :data:`REPAIR_MODES`: repair mesh inputs instead of generating.
    model : str, optional
        The model repository (default: the shipped model or ``$SPACEMESH_MODEL``), as
        every worker sees it.
    threads : int
        CPU threads of each worker (:func:`spacemesh.threads.limit_threads`).
    limits : ReadLimits
        Read limits of an input.
    max_input_bytes : int
        Largest input file.
    """

    out: str
    options: GenerateOptions = field(default_factory=GenerateOptions)
    file_format: str = "obj"
    repair: str | None = None
    model: str | None = None
    threads: int = 1
    limits: ReadLimits = BATCH_LIMITS
    max_input_bytes: int = MAX_INPUT_BYTES

    @property
    def operation(self) -> str:
        """``generate`` or ``repair``."""
        return "generate" if self.repair is None else "repair"

    def record(self) -> dict[str, Any]:
        """What decides the outputs' bytes (the output folder's ``batch.json``): the
        operation, options, format and model."""
        return {"operation": self.operation, "repair": self.repair,
                "options": self.options.to_dict(), "format": self.file_format,
                "model": self.model}


def output_source(settings: BatchSettings, name: str) -> str:
    """Where the output of the input named ``name`` goes (path or URL)."""
    fs, root = split_url(settings.out)
    return full_source(fs, f"{root.rstrip('/')}/{name}.{settings.file_format}")


def error_kind(error: BaseException) -> tuple[str, str]:
    """The manifest's ``error_kind`` and ``error`` of an exception.

    The kinds are the service's problem slugs: a :class:`~spacemesh.errors.KindedError`'s
    own kind (a point cloud's or a repair region's), ``too-many-points`` or
    ``payload-too-large``, ``unsupported-format``, ``non-finite``, ``malformed-input``,
    ``invalid-option``, ``unreadable-input`` (a file that cannot be opened), and
    ``internal-error`` for anything else (its message names the exception's type).

    Returns
    -------
    kind : str
    message : str
    """
    message = str(error)
    if isinstance(error, RowError):
        return error.kind, message
    if isinstance(error, OptionError):
        return "invalid-option", f"{error.option}: {message}"
    if isinstance(error, KindedError):
        return error.kind, message
    if isinstance(error, MeshFormatError):
        return read_error_kind(error), message
    if isinstance(error, OSError):
        return "unreadable-input", f"{type(error).__name__}: {message}"
    return "internal-error", f"{type(error).__name__}: {message}"


class Mesher:
    """A batch worker: one model loaded once, one input meshed per call.

    Parameters
    ----------
    settings : BatchSettings
    """

    def __init__(self, settings: BatchSettings) -> None:
        from spacemesh.runtime import MeshGenerator

        self.settings = settings
        threads = limit_threads(settings.threads)
        self.generator = MeshGenerator.from_repository(settings.model, threads=threads)

    def __call__(self, item: dict[str, Any]) -> dict[str, str]:
        """Mesh one input.

        Parameters
        ----------
        item : dict
            ``{"input": source, "name": output name}`` (:class:`~.inputs.BatchInput`).

        Returns
        -------
        dict
            ``{"row": the manifest row as JSON}`` (one text column, whatever the row
            holds, so that Ray Data's blocks keep one schema).
        """
        return {"row": json.dumps(self.mesh(item["input"], item["name"]))}

    def mesh(self, source: str, name: str) -> dict[str, Any]:
        """The manifest row of one input, its output written when it succeeded.

        Parameters
        ----------
        source : str
            The input's path or URL.
        name : str
            The output's name in the output folder, without extension.

        Returns
        -------
        dict
            :data:`~spacemesh.batch.manifest.ROW_FIELDS`; an error becomes ``error_kind``
            and ``error`` (never raised).
        """
        started = time.perf_counter()
        row: dict[str, Any] = {"input": source, "output": None,
                               "operation": self.settings.operation, "points_read": None,
                               "points_used": None, "vertices": None, "faces": None,
                               "fit": None, "repair": None, "error_kind": None,
                               "error": None}
        try:
            row.update(self._mesh(source, name))
        except Exception as error:  # every failure becomes an error row
            row["error_kind"], row["error"] = error_kind(error)
        row["seconds"] = round(time.perf_counter() - started, 4)
        return row

    def _read(self, source: str) -> tuple[Any, str | None]:
        """What the readers take: a local path as it is (as ``spacemesh generate`` reads
        it), or a URL's bytes and its extension as the file type."""
        fs, path = split_url(source)
        size = fs.size(path)
        if size is not None and size > self.settings.max_input_bytes:
            raise RowError("payload-too-large", f"{size} bytes; at most "
                           f"{self.settings.max_input_bytes} are read")
        if is_local(fs):
            return path, None
        return fs.cat_file(path), posixpath.splitext(path)[1].lstrip(".") or None

    def _mesh(self, source: str, name: str) -> dict[str, Any]:
        from spacemesh.io import export_mesh

        data, file_type = self._read(source)
        if self.settings.repair is None:
            mesh, extra = self._generate(data, file_type)
        else:
            mesh, extra = self._repair(data, file_type)
        output = output_source(self.settings, name)
        fs, path = split_url(output)
        fs.makedirs(posixpath.dirname(path), exist_ok=True)
        write_bytes(fs, path, export_mesh(mesh, self.settings.file_format))
        return {"output": output, "vertices": mesh.n_vertices, "faces": mesh.n_faces, **extra}

    def _generate(self, data: Any, file_type: str | None) -> tuple[Any, dict[str, Any]]:
        spec = self.generator.spec
        cloud = read_generate_input(data, file_type=file_type, limits=self.settings.limits,
                                    n_points=spec.n_points, needs_normals=spec.normals)
        result = self.generator.generate(cloud.points, cloud.normals, self.settings.options)
        return result.mesh, {"fit": result.fit.to_dict() if result.fit is not None else None,
                             "points_read": cloud.points_read,
                             "points_used": len(cloud.points)}

    def _repair(self, data: Any, file_type: str | None) -> tuple[Any, dict[str, Any]]:
        from spacemesh.io import load_mesh
        from spacemesh.repair import plan_repair, repair_mesh, verify_repair

        assert self.settings.repair is not None  # _mesh calls it for repairs only
        region = {"auto": REPAIR_MODES[self.settings.repair]}
        mesh = load_mesh(data, file_type=file_type, limits=self.settings.limits)
        if mesh.n_faces == 0:
            raise RowError("malformed-input", "the file has no faces to repair")
        chosen = self.settings.options.resolve(self.generator.spec)
        plan = plan_repair(mesh, region, self.generator.spec.max_vertices)
        result = repair_mesh(mesh, region, self.generator, seed=chosen.seed,
                             steps=chosen.steps, method=chosen.sampler, plan=plan)
        issues = verify_repair(plan, result)
        if issues:  # the service's check: a faulty repair is never written
            raise RowError("internal-error", "the repair changed the mesh outside the "
                           "grown region: " + "; ".join(issues))
        return result.mesh, {"repair": result.stats.to_dict()}


__all__ = ["BATCH_LIMITS", "MAX_INPUT_BYTES", "OUTPUT_FORMATS", "REPAIR_MODES",
           "BatchSettings", "Mesher", "RowError", "error_kind", "output_source"]
