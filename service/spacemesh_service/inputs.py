"""Where a request becomes a point cloud: file uploads, JSON points, options, validation.

Used by both the REST app and the gRPC server, so both accept and reject exactly the
same inputs. Every rejection is a :class:`~spacemesh_service.problems.Problem`:

- unreadable file or JSON: 400 ``malformed-input``; unknown format: 415;
- too many points: 413; too few, NaN/Inf, or degenerate geometry (all points identical,
  collinear or coplanar, from the singular values of the centred points): 422, by
  :func:`spacemesh.runtime.cloud.validate_cloud`, which ``spacemesh generate`` calls too;
- request options are read and checked by :mod:`spacemesh_service.options` (a JSON
  field that is not an option of ``/generate``: 422 ``invalid-option``).

Every reader is bounded before it allocates: the counts and decoded sizes a file or
JSON body declares are checked against :func:`read_limits` (this server's
``max_points``, ``max_mesh_vertices``, ``max_mesh_faces`` and ``max_upload_bytes``)
while it is read, and anything over them is refused with 413 (``too-many-points`` for
point rows, ``payload-too-large`` otherwise) by :func:`~spacemesh.io.limits.ReadLimits`.
Parsing runs in :class:`ParseSlots`, at most ``max_parallel_parses`` at once, so the
memory uploads take is bounded (docs/SERVICE.md, "Memory bound").

Repair requests (:func:`read_mesh_upload`, :func:`read_region`): an unreadable mesh
file, a file without faces, or a region that is not JSON: 400 ``malformed-input``;
NaN/Inf vertices: 422 ``non-finite``; a region that is JSON but not a region: 422
``invalid-region`` (see :func:`~spacemesh_service.problems.region_problem`).
"""

from __future__ import annotations

import asyncio
import contextvars
import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import PurePath
from typing import Any, TypeVar

import numpy as np

from spacemesh.io import SUPPORTED_MESH_READ
from spacemesh.io.errors import (
    MeshFormatError,
    TooLargeError,
    is_blank,
)
from spacemesh.io.limits import ReadLimits, load_json
from spacemesh.io.points import SUPPORTED_POINTS_READ, is_binary_cloud
from spacemesh.io.surface import input_kind, load_cloud_input
from spacemesh.mesh import PolygonMesh
from spacemesh.repair.region import Region, RegionError, parse_region
from spacemesh.runtime.cloud import CloudError
from spacemesh.runtime.cloud import validate_cloud as check_cloud
from spacemesh_service import problems as P
from spacemesh_service.options import GENERATE_ROUTE_OPTIONS, refuse_unknown
from spacemesh_service.problems import Problem
from spacemesh_service.settings import Settings

#: Point-cloud upload formats (also reported by the model metadata).
INPUT_FORMATS: tuple[str, ...] = SUPPORTED_POINTS_READ
#: Mesh upload formats of a repair (also reported by the model metadata).
MESH_FORMATS: tuple[str, ...] = SUPPORTED_MESH_READ
#: The fields of a JSON body that are not options.
JSON_BODY_FIELDS = ("points", "normals")

T = TypeVar("T")


def read_limits(settings: Settings) -> ReadLimits:
    """What one upload may declare or hold: this server's request limits.

    Parameters
    ----------
    settings : Settings

    Returns
    -------
    ReadLimits
        Points: ``max_points``; mesh vertices and faces: ``max_mesh_vertices`` and
        ``max_mesh_faces``; decoded bytes (a zip member, a base64 buffer, a JSON
        document): ``max_upload_bytes``.
    """
    return ReadLimits(max_points=settings.max_points, max_vertices=settings.max_mesh_vertices,
                      max_faces=settings.max_mesh_faces, max_bytes=settings.max_upload_bytes,
                      max_text_points=settings.max_text_points)


@dataclass(frozen=True)
class UploadRules:
    """How an upload is read besides its :class:`ReadLimits`.

    Attributes
    ----------
    max_text_bytes : int, optional
        Largest file other than a binary PLY, NPY, NPZ, LAS or LAZ cloud (413 above); None: no
        limit beyond the body's.
    working_points : int, optional
        A cloud of more points is reduced to this many
        (:func:`spacemesh.io.points.read_points`); None: all kept.
    """

    max_text_bytes: int | None = None
    working_points: int | None = None

    @classmethod
    def from_settings(cls, settings: Settings) -> UploadRules:
        """This server's ``max_text_bytes`` and ``working_points``."""
        return cls(settings.max_text_bytes, settings.working_points)

    def check_text_bytes(self, size: int, what: str) -> None:
        """413 ``payload-too-large`` when ``size`` bytes of ``what`` exceed
        ``max_text_bytes``."""
        if self.max_text_bytes is not None and size > self.max_text_bytes:
            raise Problem(P.PAYLOAD_TOO_LARGE, f"{what} has {size} bytes; this server takes "
                          f"at most {self.max_text_bytes} but for binary PLY, NPY, NPZ, LAS "
                          "and LAZ point clouds", limit=self.max_text_bytes)


class ParseSlots:
    """At most ``count`` request parses at once, each in a worker thread.

    A slot is held until the worker thread ends, even when the request that started
    it is cancelled (a client that disconnects cannot free its slot while its parse
    still runs), so the parses alive at any moment never exceed ``count``.

    Parameters
    ----------
    count : int
        Slots (the ``max_parallel_parses`` setting).
    """

    def __init__(self, count: int) -> None:
        self.count = count
        self._slots = asyncio.Semaphore(count)
        self._running = 0

    @property
    def running(self) -> int:
        """Parses running now (holding a slot)."""
        return self._running

    async def run(self, work: Callable[..., T], *args: Any) -> T:
        """``work(*args)`` in a worker thread once a slot is free.

        Parameters
        ----------
        work : callable
        *args
            Its arguments.

        Returns
        -------
        object
            What ``work`` returns (its exceptions are raised here).
        """
        await self._slots.acquire()
        loop = asyncio.get_running_loop()
        self._running += 1

        def release() -> None:
            self._running -= 1
            self._slots.release()

        def in_thread() -> T:
            try:
                return work(*args)
            finally:
                try:
                    loop.call_soon_threadsafe(release)
                except RuntimeError:  # pragma: no cover - the loop closed meanwhile
                    pass

        call = functools.partial(contextvars.copy_context().run, in_thread)
        try:
            future = loop.run_in_executor(None, call)
        except BaseException:  # pragma: no cover - the executor is shut down
            release()
            raise
        # shielded: a cancelled request leaves the thread to finish and free its slot
        return await asyncio.shield(future)


@dataclass(frozen=True)
class PointCloud:
    """A validated request input.

    Attributes
    ----------
    points : (P, 3) float64
    normals : (P, 3) float64 or None
    source : str
        ``json``, ``points`` (gRPC numbers) or the file format read (``obj-surface``:
        points sampled on a mesh's faces).
    points_read : int, optional
        Points in the upload when it was reduced to ``points``; None when they are all
        of them.
    """

    points: np.ndarray
    normals: np.ndarray | None
    source: str
    points_read: int | None = None

    @property
    def reduction(self) -> dict[str, int] | None:
        """``{"read": N, "used": M}`` when the upload's N points were reduced to M
        (``X-SpaceMesh-Points-Read`` and ``-Used``), else None."""
        if self.points_read is None:
            return None
        return {"read": int(self.points_read), "used": len(self.points)}

    @property
    def input_kind(self) -> str:
        """``mesh`` (a mesh's surface sampled) or ``points`` (``X-SpaceMesh-Input``)."""
        return input_kind(self.source)


# ---------------------------------------------------------------------- reading
def _file_type(filename: str | None, formats: tuple[str, ...] = INPUT_FORMATS) -> str | None:
    """The format named by a file name's extension, when it is one we read."""
    if not filename:
        return None
    suffix = PurePath(filename).suffix.lower().lstrip(".")
    return suffix if suffix in formats else None


def read_upload(data: bytes, filename: str | None, limits: ReadLimits | None = None
                ) -> tuple[np.ndarray, np.ndarray | None, str]:
    """Points (and normals) of an uploaded file, all of them
    (:func:`read_cloud_upload` without a reduction).

    Parameters
    ----------
    data : bytes
    filename : str, optional
    limits : ReadLimits, optional

    Returns
    -------
    points : (P, 3) float64
    normals : (P, 3) float64 or None
    source : str
    """
    points, normals, source, _ = read_cloud_upload(data, filename, limits)
    return points, normals, source


def read_cloud_upload(data: bytes, filename: str | None, limits: ReadLimits | None = None,
                      rules: UploadRules | None = None
                      ) -> tuple[np.ndarray, np.ndarray | None, str, int | None]:
    """Points (and normals) of an uploaded file.

    The extension picks the format when it is one we read; otherwise the content is
    sniffed (PLY, NPY, NPZ, OBJ, number columns...). A file whose reader finds faces (a
    mesh) is sampled area-uniformly on its surface, with face normals
    (:func:`spacemesh.io.surface.load_cloud_input`; ``source`` is then e.g.
    ``obj-surface``).

    Parameters
    ----------
    data : bytes
    filename : str, optional
    limits : ReadLimits, optional
        Checked while reading (:func:`read_limits`); 413 beyond.
    rules : UploadRules, optional
        The size of anything but a binary cloud, and the points a cloud is reduced to.

    Returns
    -------
    points : (P, 3) float64
    normals : (P, 3) float64 or None
    source : str
        The format read.
    points_read : int or None
        The upload's points when it was reduced to ``points``, else None.
    """
    from spacemesh.io import sniff_file_type

    rules = rules or UploadRules()
    file_type = _file_type(filename)
    if is_blank(data):
        raise Problem(P.MALFORMED_INPUT, "the uploaded file is empty")
    source = file_type or sniff_file_type(data)
    if source not in INPUT_FORMATS:
        named = PurePath(filename).suffix if filename else ""
        what = f"'{named}' files" if named else "this file (its content was not recognised)"
        raise Problem(P.UNSUPPORTED_FORMAT,
                      f"cannot read {what}; supported: {', '.join(INPUT_FORMATS)}",
                      supported=list(INPUT_FORMATS))
    if not is_binary_cloud(data, source):
        rules.check_text_bytes(len(data), f"the {source.upper()} file")
    try:
        cloud = load_cloud_input(data, file_type=source, limits=limits,
                                 keep=rules.working_points)
    except MeshFormatError as error:
        raise P.read_problem(error) from None
    return cloud.points, cloud.normals, cloud.source, cloud.count


def read_mesh_upload(data: bytes, filename: str | None, limits: ReadLimits | None = None,
                     rules: UploadRules | None = None) -> tuple[PolygonMesh, str]:
    """The polygon mesh of an uploaded file (a repair request).

    The extension picks the format when it is one we read (OBJ, OFF, PLY, STL, GLB,
    glTF); otherwise the content is sniffed. Faces and vertices keep the file's order,
    so face and vertex indices of a region refer to the file.

    Parameters
    ----------
    data : bytes
    filename : str, optional
    limits : ReadLimits, optional
        Checked while reading (:func:`read_limits`); 413 beyond.
    rules : UploadRules, optional
        Its ``max_text_bytes`` limits the file's size (a mesh, whatever its format).

    Returns
    -------
    mesh : PolygonMesh
    source : str
        The format read.
    """
    from spacemesh.io import load_mesh, sniff_file_type

    if is_blank(data):
        raise Problem(P.MALFORMED_INPUT, "the uploaded mesh file is empty")
    (rules or UploadRules()).check_text_bytes(len(data), "the mesh file")
    source = _file_type(filename, MESH_FORMATS) or sniff_file_type(data)
    if source not in MESH_FORMATS:
        named = PurePath(filename).suffix if filename else ""
        what = f"'{named}' files" if named else "this file (its content was not recognised)"
        raise Problem(P.UNSUPPORTED_FORMAT,
                      f"cannot read {what} as a mesh; supported: {', '.join(MESH_FORMATS)}",
                      supported=list(MESH_FORMATS))
    try:
        mesh = load_mesh(data, file_type=source, limits=limits)
    except MeshFormatError as error:
        raise P.read_problem(error) from None
    except (ValueError, IndexError, KeyError, TypeError, OverflowError) as error:
        # a reader's or PolygonMesh's own check
        raise Problem(P.MALFORMED_INPUT, str(error) or type(error).__name__) from None
    if mesh.n_faces == 0:
        raise Problem(P.MALFORMED_INPUT, f"the {source.upper()} file has no faces; repair "
                      "needs a polygon mesh")
    return mesh, source


def read_region(raw: Any, limits: ReadLimits | None = None) -> Region:
    """A repair region from its JSON text (REST) or its JSON form (gRPC).

    Parameters
    ----------
    raw : str, bytes or dict
        ``{"faces": [...]}``, ``{"vertices": [...]}``,
        ``{"sphere": {"center": [x, y, z], "radius": r}}`` or
        ``{"box": {"min": [x, y, z], "max": [x, y, z]}}``.
    limits : ReadLimits, optional
        The JSON text's length and values are checked before it is parsed.

    Returns
    -------
    Region
    """
    data = raw
    if isinstance(raw, (str, bytes, bytearray)):
        if not raw.strip():
            raise Problem(P.MALFORMED_INPUT, "the region is empty; send it as JSON, e.g. "
                          '{"faces": [0, 1]}')
        try:
            data = load_json(raw, "the region", limits)
        except TooLargeError as error:
            raise P.too_large_problem(error) from None
        except MeshFormatError as error:
            raise Problem(P.MALFORMED_INPUT, str(error)) from None
    try:
        return parse_region(data)
    except RegionError as error:
        raise P.region_problem(error) from None
    except (ValueError, TypeError, OverflowError, RecursionError) as error:  # pragma: no cover
        raise Problem(P.INVALID_REGION, f"the region cannot be read ({error})") from None


def _number_array(value: Any, name: str) -> np.ndarray:
    """A float64 (P, 3) array from nested lists of numbers (400 otherwise)."""
    try:
        array = np.asarray(value)
    except (ValueError, TypeError):
        array = None
    if array is not None and array.size == 0:
        return np.zeros((0, 3))
    if array is None or array.dtype.kind not in "iuf" or array.ndim != 2 or (
        array.size and array.shape[1] != 3
    ):
        raise Problem(P.MALFORMED_INPUT, f"'{name}' must be a list of [x, y, z] number triples")
    return array.astype(np.float64).reshape(-1, 3)


def read_json(body: bytes, limits: ReadLimits | None = None
              ) -> tuple[np.ndarray, np.ndarray | None, dict[str, Any]]:
    """Points, normals and options of a JSON body ``{"points": [[x, y, z], ...], ...}``.

    Parameters
    ----------
    body : bytes
    limits : ReadLimits, optional
        The body's length and values are checked before it is parsed
        (:func:`spacemesh.io.limits.load_json`), the points after; 413 beyond.

    Returns
    -------
    points : (P, 3) float64
    normals : (P, 3) float64 or None
    options : dict
        Every other field of the body, by name (values as sent): options, whose names
        and values :func:`~spacemesh_service.options.resolve_request` checks (a name
        ``/generate`` does not take is a 422 ``invalid-option``).
    """
    try:
        data = load_json(body, "the JSON body", limits and limits.for_text().for_points())
    except TooLargeError as error:
        raise P.too_large_problem(error) from None
    except MeshFormatError as error:
        raise Problem(P.MALFORMED_INPUT, str(error)) from None
    if not isinstance(data, dict) or "points" not in data:
        raise Problem(P.MALFORMED_INPUT, "the JSON body must be an object with 'points'")
    options = {k: v for k, v in data.items() if k not in JSON_BODY_FIELDS}
    refuse_unknown(options, GENERATE_ROUTE_OPTIONS)  # before the points are converted
    points = _number_array(data["points"], "points")
    normals = None if data.get("normals") is None else _number_array(data["normals"], "normals")
    return points, normals, options


def points_from_flat(xyz: Any, normals: Any, limits: ReadLimits | None = None
                     ) -> tuple[np.ndarray, np.ndarray | None]:
    """Points (and normals) from flat ``x0 y0 z0 x1 ...`` sequences (the gRPC form),
    their count checked against ``limits`` before they are copied."""
    if limits is not None:
        try:
            limits.for_text().check_points("points", max(len(xyz), len(normals)) // 3)
        except TooLargeError as error:
            raise P.too_large_problem(error) from None
    p = np.asarray(xyz, dtype=np.float64)
    if p.size % 3:
        raise Problem(P.MALFORMED_INPUT, f"xyz has {p.size} numbers, not a multiple of 3")
    n = np.asarray(normals, dtype=np.float64) if len(normals) else None
    if n is not None and n.size % 3:
        raise Problem(P.MALFORMED_INPUT, f"normals has {n.size} numbers, not a multiple of 3")
    return p.reshape(-1, 3), None if n is None else n.reshape(-1, 3)


# ---------------------------------------------------------------------- validation
def validate_cloud(
    points: np.ndarray, normals: np.ndarray | None, settings: Settings, *,
    source: str, needs_normals: bool = False, points_read: int | None = None,
) -> PointCloud:
    """Apply the limits and geometry checks to parsed points.

    The checks are :func:`spacemesh.runtime.cloud.validate_cloud`, the ones
    ``spacemesh generate`` makes, with this server's ``min_points`` and ``max_points``.

    Parameters
    ----------
    points : (P, 3) float64
    normals : (P, 3) float64 or None
    settings : Settings
    source : str
    needs_normals : bool
        The model's encoder reads normals.
    points_read : int, optional
        The upload's points when ``points`` are a reduction of them.

    Returns
    -------
    PointCloud

    Raises
    ------
    Problem
        The :class:`~spacemesh.runtime.cloud.CloudError`'s kind (413 or 422).
    """
    try:
        points, normals = check_cloud(points, normals, min_points=settings.min_points,
                                      max_points=settings.max_points,
                                      needs_normals=needs_normals)
    except CloudError as error:
        raise P.cloud_problem(error) from None
    return PointCloud(points, normals, source, points_read)
