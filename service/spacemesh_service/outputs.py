"""Where a generated mesh becomes a response: validation, bytes, media type, statistics.

Formats: GLB and glTF (triangulated), OBJ, PLY and OFF (polygons kept) through
:func:`spacemesh.io.export_mesh`, and ``json`` (vertices, polygon faces, statistics).
The bytes depend only on the mesh, the options and the model, so REST and gRPC
answer byte-identical meshes for the same input and seed.

The fit report of a generated mesh (:class:`spacemesh.geometry.report.FitReport`) is
``MeshStats.fit``, :meth:`FitReport.to_dict` as it is: the ``stats.fit`` object of the
JSON format, ``MeshStats.fit`` of gRPC (the same field names) and one
``X-SpaceMesh-Fit-<Name>`` header per field (:func:`value_headers`).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, replace
from typing import Any

from spacemesh.cancel import checkpoint
from spacemesh.io import export_mesh
from spacemesh.mesh import PolygonMesh
from spacemesh.topology import check_topology, surface_topology
from spacemesh_service import problems as P
from spacemesh_service.problems import Problem

#: Output format -> media type.
MEDIA_TYPES: dict[str, str] = {
    "glb": "model/gltf-binary",
    "gltf": "model/gltf+json",
    "obj": "model/obj",
    "ply": "model/x-ply",
    "off": "model/x-off",
    "json": "application/json",
}
#: Output formats, the default first.
OUTPUT_FORMATS: tuple[str, ...] = tuple(MEDIA_TYPES)
#: Prefix of the statistics headers.
HEADER_PREFIX = "X-SpaceMesh-"


@dataclass(frozen=True)
class MeshStats:
    """What the response headers (and the JSON body) say about a mesh."""

    vertices: int
    faces: int
    edges: int
    face_degrees: dict[int, int]
    manifold: bool
    closed: bool
    oriented: bool
    components: int
    genus: int
    #: :meth:`FitReport.to_dict` of a generated mesh (None for a repair).
    fit: dict[str, float | int] | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (face degrees keyed by strings, non-finite fit values None)."""
        data = asdict(self)
        data["face_degrees"] = {str(k): v for k, v in self.face_degrees.items()}
        if self.fit is None:
            del data["fit"]
        else:
            data["fit"] = {k: finite_or_none(v) for k, v in self.fit.items()}
        return data


@dataclass(frozen=True)
class EncodedMesh:
    """A mesh ready to send.

    Attributes
    ----------
    body : bytes
    format : str
    media_type : str
    stats : MeshStats
    """

    body: bytes
    format: str
    media_type: str
    stats: MeshStats


def validate_mesh(mesh: PolygonMesh, open_surface: bool = False
                  ) -> tuple[PolygonMesh, MeshStats]:
    """Check a generated mesh before it is sent.

    Parameters
    ----------
    mesh : PolygonMesh
    open_surface : bool
        The fit report says the surface is open: boundary edges are allowed
        (:meth:`spacemesh.topology.TopologyReport.is_valid`).

    Returns
    -------
    mesh : PolygonMesh
        Without unreferenced vertices.
    stats : MeshStats

    Raises
    ------
    Problem
        ``no-surface`` (422) for an empty mesh, ``invalid-output`` (500) when the mesh is
        not valid: an oriented manifold, closed unless ``open_surface``.
    """
    if mesh.n_faces == 0:
        raise Problem(P.NO_SURFACE, "the model produced no faces for this input and seed; "
                      "try another seed or more steps")
    report = check_topology(mesh)
    if report.n_unreferenced_vertices:
        mesh, _ = mesh.remove_unreferenced_vertices()
        report = check_topology(mesh)
    if not report.is_valid(open_surface):
        raise Problem(P.INVALID_OUTPUT, "the generated mesh has "
                      + ", ".join(report.defects(open_surface)))
    genus = report.genus if report.is_closed else surface_topology(mesh).genus
    stats = MeshStats(
        vertices=mesh.n_vertices, faces=mesh.n_faces, edges=report.n_edges,
        face_degrees=mesh.degree_histogram(), manifold=report.is_manifold,
        closed=report.is_closed, oriented=report.is_oriented,
        components=report.n_components, genus=int(genus or 0),
    )
    return mesh, stats


def mesh_json(mesh: PolygonMesh, stats: MeshStats, info: dict[str, Any]) -> bytes:
    """The ``json`` format: ``vertices``, polygon ``faces``, ``stats`` and ``info`` keys
    (``seed``, ``steps``, ``sampler``, ``model``; ``repair`` for a repair)."""
    body = {
        "vertices": mesh.vertices.tolist(),
        "faces": [face.tolist() for face in mesh.faces],
        "stats": stats.to_dict(),
        **info,
    }
    return json.dumps(body, separators=(",", ":")).encode("utf-8")


def finite_or_none(value: Any) -> Any:
    """``value``, or None for a NaN or infinite float (JSON has no such numbers)."""
    return None if isinstance(value, float) and not math.isfinite(value) else value


def encode_mesh(mesh: PolygonMesh, fmt: str, info: dict[str, Any],
                fit: dict[str, float | int] | None = None) -> EncodedMesh:
    """Validate and serialise a mesh (in a cancellation scope, abandoned work stops
    between the two: :func:`spacemesh.cancel.checkpoint`).

    Parameters
    ----------
    mesh : PolygonMesh
    fmt : str
        One of :data:`OUTPUT_FORMATS`.
    info : dict
        The reported options (``seed``, ``steps``, ``sampler``...), ``model``, and
        ``sample_scores`` or ``repair`` (added to the JSON body).
    fit : dict, optional
        The fit report (:meth:`FitReport.to_dict`), as :attr:`MeshStats.fit`.

    Returns
    -------
    EncodedMesh
    """
    mesh, stats = validate_mesh(mesh, open_surface=bool(fit and fit.get("open_surface")))
    checkpoint()  # a request abandoned while the mesh was checked is not written
    stats = replace(stats, fit=fit)
    body = mesh_json(mesh, stats, info) if fmt == "json" else export_mesh(mesh, fmt)
    return EncodedMesh(body, fmt, MEDIA_TYPES[fmt], stats)


#: The repair statistics that also get a header of their own (all are in ``Repair``).
REPAIR_HEADERS = {"Region-Faces": "region_faces", "Grown-Faces": "grown_faces",
                  "New-Vertices": "new_vertices", "New-Faces": "new_faces",
                  "Fallback": "fallback", "Welded-Vertices": "welded_vertices"}
#: Keys of ``RepairStats.to_dict()`` reported elsewhere (seed, steps, sampler, timings).
_REPORTED_ELSEWHERE = ("seed", "steps", "method", "timings")


def repair_summary(stats: Any) -> dict[str, Any]:
    """What a repair did: :meth:`spacemesh.repair.RepairStats.to_dict` without the seed,
    steps, sampler and timings (the reply carries those for every request)."""
    return {k: v for k, v in stats.to_dict().items() if k not in _REPORTED_ELSEWHERE}


def repair_headers(summary: dict[str, Any]) -> dict[str, str]:
    """``X-SpaceMesh-Repair`` (the summary as compact JSON) and one header per count of
    :data:`REPAIR_HEADERS`."""
    headers = {HEADER_PREFIX + "Repair": json.dumps(summary, separators=(",", ":"))}
    headers.update({HEADER_PREFIX + name: str(summary[key])
                    for name, key in REPAIR_HEADERS.items() if key in summary})
    return headers


def header_name(name: str) -> str:
    """``start_time`` -> ``Start-Time`` (the part of an ``X-SpaceMesh-*`` header)."""
    return "-".join(part.capitalize() for part in name.split("_"))


def value_headers(values: dict[str, Any], prefix: str = "") -> dict[str, str]:
    """``X-SpaceMesh-<prefix><Name>`` headers of named values (booleans as
    ``true``/``false``; None values left out)."""
    return {HEADER_PREFIX + prefix + header_name(k): str(v).lower() if isinstance(v, bool)
            else str(v) for k, v in values.items() if v is not None}


def stats_headers(stats: MeshStats) -> dict[str, str]:
    """``X-SpaceMesh-*`` headers of a mesh's statistics (``X-SpaceMesh-Fit-*`` of its fit
    report)."""
    values = {k: v for k, v in asdict(stats).items() if k != "fit"}
    values["face_degrees"] = ",".join(f"{k}:{v}" for k, v in sorted(stats.face_degrees.items()))
    headers = value_headers(values)
    headers.update(value_headers(stats.fit or {}, prefix="Fit-"))
    return headers


def sample_scores_header(scores: list[tuple[int, float]]) -> str:
    """``X-SpaceMesh-Sample-Scores``: ``seed:score`` of every seed tried, e.g.
    ``5:0.0099,6:0.0098`` (scores written exactly, as the fit headers are)."""
    return ",".join(f"{seed}:{float(score)!r}" for seed, score in scores)
