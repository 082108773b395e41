"""The OpenAPI description of the REST API: schemas and examples (served at ``/docs``).

``POST /generate`` and ``POST /repair`` read their bodies and options by hand (a
multipart upload or JSON), so their parameters, request bodies, responses and headers are
described here rather than inferred by FastAPI. Every option (query parameter, form and
JSON field, reported header) comes from the table of :mod:`spacemesh_service.options`.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, create_model

from spacemesh.examples import icosphere
from spacemesh.geometry.report import FitReport
from spacemesh.io import export_mesh
from spacemesh_service import problems as P
from spacemesh_service.options import (
    GENERATE_OPTIONS,
    GENERATE_ROUTE_OPTIONS,
    REPAIR_ROUTE_OPTIONS,
    RequestOption,
)
from spacemesh_service.outputs import HEADER_PREFIX, MEDIA_TYPES, header_name
from spacemesh_service.problems import problem_response

DESCRIPTION = """\
Point cloud in, oriented manifold polygon mesh out (SpaceMesh).

* `POST /generate`: upload a point cloud (multipart field `file`: PLY, XYZ/PTS/TXT/CSV,
  NPY/NPZ, LAS/LAZ, or the vertices of an OBJ/OFF/STL/GLB) or send JSON
  `{"points": [[x, y, z], ...]}`.
  Options `format`, `seed`, `steps`, `sampler`, `start`, `start_time`,
  `target_vertices`, `tolerance`, `samples`, `raw` as query parameters or form/JSON
  fields; every response reports how well the mesh fits the points (`X-SpaceMesh-Fit-*`).
* `POST /repair`: upload a mesh (multipart field `file`: OBJ, OFF, PLY, STL, GLB, glTF) and
  a region as JSON (field `region`: `{"faces": [...]}`, `{"vertices": [...]}`,
  `{"sphere": {"center": [x, y, z], "radius": r}}`, `{"box": {"min": [...], "max": [...]}}`,
  or `{"auto": "holes" | "defects" | "all"}`: every hole and/or defect found, each with the
  faces around it); the region is generated again, every other face comes back unchanged.
* Health and metadata in the KServe v2 shape under `/v2`; Prometheus metrics at `/metrics`.
* Options parse one way everywhere: integer options take only integers (`1e3`, `1.0`
  are refused, not converted). Every option error (an unknown name, one the route does
  not take, a wrong type, a value out of range) is 422 `invalid-option` naming it.
* Each generate and repair is costed before any work starts: one estimated over this
  server's budget (seconds and MB per request) is 422 `too-expensive`, whose `option`
  names the option to lower.
* Every error is RFC 9457 `application/problem+json` with a stable `type`.
"""

_TETRA = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]


def _sphere_points(count: int = 48) -> list[list[float]]:
    """``count`` points spread on an ellipsoid (Fibonacci spiral), 4 decimals: the
    examples' point cloud, one the server accepts."""
    i = np.arange(count) + 0.5
    z = 1 - 2 * i / count
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5**0.5) * i
    points = np.stack([1.5 * r * np.cos(phi), r * np.sin(phi), 0.75 * z], axis=1)
    return np.round(points, 4).tolist()


#: The examples' point cloud (JSON) and the same points as an XYZ file.
_CLOUD = _sphere_points()
_CLOUD_XYZ = "".join(f"{x} {y} {z}\n" for x, y, z in _CLOUD)
#: The repair examples' mesh (an icosphere: 42 vertices, 80 triangles) as OBJ, PLY and OFF
#: text, and the same mesh with a hole (the star of vertex 0 removed) for ``auto``.
_MESH = icosphere(1)
_MESH_FILES = {fmt: export_mesh(_MESH, fmt, **({"encoding": "ascii"} if fmt == "ply" else {}))
               .decode() for fmt in ("obj", "ply", "off")}
_HOLED_OBJ = export_mesh(
    _MESH.__class__.from_faces(_MESH.vertices, [f for f in _MESH.faces if 0 not in f]), "obj"
).decode()
_NEAR = _MESH.vertices[7]


def _option_fields(table: tuple[RequestOption, ...]) -> dict[str, Any]:
    """pydantic fields (all optional) of the options of ``table``."""
    return {o.name: (o.kind | None, Field(None, description=o.description)) for o in table}


class _PointsBody(BaseModel):
    model_config = ConfigDict(extra="forbid")  # a field that is not an option: 422

    points: list[list[float]] = Field(
        description="Point positions, one [x, y, z] per point, any frame and scale.",
        examples=[_TETRA])
    normals: list[list[float]] | None = Field(
        None, description="Optional normals, one per point (used when the model reads them).")


#: JSON body of ``POST /generate``: points, normals and the route's options.
PointsRequest = create_model("PointsRequest", __base__=_PointsBody,
                             **_option_fields(GENERATE_ROUTE_OPTIONS))
PointsRequest.__doc__ = "JSON body of ``POST /generate``."

#: :class:`~spacemesh.geometry.report.FitReport` as JSON.
_FIT_FIELDS: dict[str, Any] = {f: (float | int | None, ...) for f in FitReport.__dataclass_fields__}
FitReportModel = create_model("FitReportModel", **_FIT_FIELDS)
FitReportModel.__doc__ = ("How well the mesh fits the uploaded points "
                          "(`spacemesh.geometry.report.FitReport`).")


class MeshStatsModel(BaseModel):
    vertices: int
    faces: int
    edges: int
    face_degrees: dict[str, int] = Field(description="Face degree -> number of faces.")
    manifold: bool
    closed: bool
    oriented: bool
    components: int
    genus: int
    # FitReportModel is a class, made at import by create_model (mypy sees a variable)
    fit: FitReportModel | None = Field(  # type: ignore[valid-type]
        None, description="The fit report (generated meshes).")


class SampleScoreModel(BaseModel):
    seed: int
    score: float | None = Field(description="Fit score (lower is better).")


class ModelRef(BaseModel):
    name: str
    version: str


class _MeshBody(BaseModel):
    vertices: list[list[float]]
    faces: list[list[int]] = Field(description="Polygons, counter-clockwise seen from outside.")
    stats: MeshStatsModel
    model: ModelRef
    sample_scores: list[SampleScoreModel] | None = Field(
        None, description="Every seed tried and its fit score (`POST /generate`).")
    repair: dict[str, Any] | None = Field(
        None, description="What the repair did (`POST /repair` only): the `X-SpaceMesh-Repair` "
        "header's object.")


#: The ``json`` output format: the mesh, its statistics and the resolved options.
MeshJSON = create_model("MeshJSON", __base__=_MeshBody, **_option_fields(GENERATE_OPTIONS))
MeshJSON.__doc__ = "The ``json`` output format."


class ProblemModel(BaseModel):
    """RFC 9457 problem details."""

    type: str = Field(description="Stable URI of the error kind.")
    title: str
    status: int
    detail: str
    instance: str | None = None


class LiveModel(BaseModel):
    live: bool


class ReadyModel(BaseModel):
    ready: bool


class ModelReadyModel(BaseModel):
    name: str
    ready: bool


class ServerMetadata(BaseModel):
    name: str
    version: str
    extensions: list[str]


_MESH_EXAMPLE = {
    "vertices": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    "stats": {"vertices": 4, "faces": 4, "edges": 6, "face_degrees": {"3": 4},
              "manifold": True, "closed": True, "oriented": True, "components": 1,
              "genus": 0},
    "seed": 7, "steps": 50, "sampler": "ddim", "start": "points", "start_time": 0.0,
    "samples": 1, "raw": False, "sample_scores": [{"seed": 7, "score": 0.012}],
    "model": {"name": "spacemesh-small", "version": "1"},
}

_HEADERS = {
    "Vertices": ("integer", "Vertex count."),
    "Faces": ("integer", "Face count."),
    "Edges": ("integer", "Edge count."),
    "Face-Degrees": ("string", "Face degree counts, e.g. `3:120,4:8`."),
    "Manifold": ("boolean", "Every edge has two faces and every vertex one fan."),
    "Closed": ("boolean", "No boundary edges."),
    "Oriented": ("boolean", "Neighbouring faces agree on orientation."),
    "Components": ("integer", "Connected components."),
    "Genus": ("integer", "Sum of the components' genera."),
    "Model": ("string", "Model name/version."),
    "Batch-Size": ("integer", "Requests that shared this request's onnxruntime batch."),
    "Sample-Scores": ("string", "`seed:score` of every seed tried (`samples`), e.g. "
                      "`5:0.0099,6:0.0098`; the mesh is the lowest score's."),
    # the resolved options
    **{header_name(o.name): (o.schema()["type"], "Resolved: " + o.description)
       for o in GENERATE_OPTIONS},
    # the fit report
    **{"Fit-" + header_name(name): ("number", f"Fit report: `{name}` "
                                    "(`spacemesh.geometry.report.FitReport`).")
       for name in FitReport.__dataclass_fields__},
}


GENERATE_RESPONSES: dict[int | str, dict[str, Any]] = {
    200: {
        "description": "The mesh, in the requested format. Statistics in the headers.",
        "content": {
            media: ({"schema": {"$ref": "#/components/schemas/MeshJSON"},
                     "example": _MESH_EXAMPLE}
                    if fmt == "json" else {"schema": {"type": "string", "format": "binary"}})
            for fmt, media in MEDIA_TYPES.items()
        },
        "headers": {
            **{HEADER_PREFIX + name: {"description": text, "schema": {"type": kind}}
               for name, (kind, text) in _HEADERS.items()},
            "Server-Timing": {"description": "Milliseconds per stage.",
                              "schema": {"type": "string"}},
        },
    },
    400: problem_response("Unreadable input", {
        "malformed": (P.MALFORMED_INPUT, "PLY: the header ends before 'end_header'"),
    }),
    413: problem_response("Too many points or bytes", {
        "points": (P.TOO_MANY_POINTS, "250000 points; this server takes at most 200000"),
        "bytes": (P.PAYLOAD_TOO_LARGE, "the body exceeds 33554432 bytes"),
    }),
    415: problem_response("Unsupported format", {
        "format": (P.UNSUPPORTED_FORMAT, "cannot read '.docx' files; supported: ..."),
    }),
    422: problem_response("An option that is unknown, of the wrong type or out of range, "
                          "a request estimated over this server's budget, or unusable "
                          "geometry", {
        "option": (P.INVALID_OPTION, "target_vertices must be in 4..10000, not 20000"),
        "integer": (P.INVALID_OPTION, "seed must be an integer (digits only, no fraction or "
                                      "exponent), not '1e3'"),
        "start_time": (P.INVALID_OPTION, "start_time applies to start=points only"),
        "format": (P.INVALID_OPTION, "format must be one of glb, gltf, obj, ply, off, json, "
                                     "not 'stl'"),
        "unknown": (P.INVALID_OPTION, "unknown option 'colour': this route takes format, "
                                      "seed, steps, sampler, start, start_time, "
                                      "target_vertices, tolerance, samples, raw"),
        "expensive": (P.TOO_EXPENSIVE, "this generate is estimated at 111 s and 958 MB, over "
                      "the budget of 60 s and 2048 MB per request; lower "
                      "target_vertices: target_vertices=6357 fits. Each option at its "
                      "default would save: target_vertices 109 s"),
        "few": (P.TOO_FEW_POINTS, "3 points; this server needs at least 16"),
        "nan": (P.NON_FINITE, "point 12 has a NaN or infinite coordinate"),
        "flat": (P.DEGENERATE_GEOMETRY, "the points are coplanar; a surface needs a 3D "
                                        "point cloud"),
        "empty": (P.NO_SURFACE, "the model produced no faces for this input and seed"),
    }),
    503: problem_response("Queue full, loading or draining", {
        "busy": (P.QUEUE_FULL, "32 requests are waiting already"),
        "loading": (P.NOT_READY, "the model is loading"),
    }, retry_after=True),
    504: problem_response("Timed out", {"timeout": (P.TIMEOUT, "no result within 30.0 s")}),
}

_REPAIR_HEADERS = {
    "Repair": ("string", "What the repair did, as compact JSON: `requested_faces`, "
               "`region_faces` (after growth), `grown_faces`, `removed_vertices`, "
               "`boundary_vertices`, `loops`, `new_vertices`, `new_faces`, "
               "`new_face_degrees`, `patch_faces`, `patch_rings`, `known_vertices`, "
               "`tokens`, `candidates`, `fallback`, `fill`, `inpaint`, "
               "`flipped_orientation`, `welded_vertices`."),
    "Region-Faces": ("integer", "Faces re-generated (the region after growth)."),
    "Grown-Faces": ("integer", "Faces added to the region so that no hole is pinched."),
    "New-Vertices": ("integer", "Vertices generated."),
    "New-Faces": ("integer", "Faces generated."),
    "Fallback": ("string", "`none`, `removed-new-vertices` or `polygon`."),
    "Welded-Vertices": ("integer", "Vertices merged into another at the same position "
                        "(`weld=true`; 0 without)."),
}

_REPAIR_200 = {
    "description": "The repaired mesh in the requested format: kept faces first, unchanged "
                   "and in input order, then the new faces. Statistics in the headers.",
    "content": GENERATE_RESPONSES[200]["content"],
    "headers": {
        **GENERATE_RESPONSES[200]["headers"],
        **{HEADER_PREFIX + name: {"description": text, "schema": {"type": kind}}
           for name, (kind, text) in _REPAIR_HEADERS.items()},
    },
}

REPAIR_RESPONSES: dict[int | str, dict[str, Any]] = {
    200: _REPAIR_200,
    400: problem_response("Unreadable mesh or region, or a missing field", {
        "malformed": (P.MALFORMED_INPUT, "OFF: face 12 refers to vertex 900 but the file "
                                         "has 100 vertices"),
        "region": (P.MALFORMED_INPUT, "the region is not valid JSON (Expecting value: line "
                                      "1 column 1 (char 0))"),
        "missing": (P.MALFORMED_INPUT, "the multipart body has no field 'region'"),
    }, instance="/repair"),
    413: problem_response("Body too large", {
        "bytes": (P.PAYLOAD_TOO_LARGE, "the body exceeds 33554432 bytes"),
    }, instance="/repair"),
    415: problem_response("Unsupported format", {
        "format": (P.UNSUPPORTED_FORMAT, "cannot read '.docx' files as a mesh; supported: "
                                         "..."),
    }, instance="/repair"),
    422: problem_response("A region the server cannot use (the kind is the type), an "
                          "option that is unknown, of the wrong type or out of range, or a "
                          "repair estimated over this server's budget", {
        "option": (P.INVALID_OPTION, "steps must be in 1..1024, not 0"),
        "expensive": (P.TOO_EXPENSIVE, "this repair is estimated at 121 s and 50 MB, over "
                      "the budget of 60 s and 2048 MB per request; lower steps: "
                      "steps=497 fits. Each option at its default would save: steps 112 s, "
                      "region 91 s, mesh 0.1 s"),
        "weld": (P.INVALID_OPTION, "weld must be true or false, not 'maybe'"),
        "generate-only": (P.INVALID_OPTION, "unknown option target_vertices (an option of "
                                            "/generate only): this route takes format, seed, "
                                            "steps, sampler, weld, max_growth"),
        "invalid": (P.INVALID_REGION, "the sphere's radius must be a positive finite number"),
        "empty": (P.EMPTY_REGION, "the region selects no face of the mesh"),
        "whole": (P.WHOLE_MESH_REGION, "the region covers the whole mesh; repair needs faces "
                                       "outside the region to keep"),
        "defects": (P.DEFECTS_OUTSIDE_REGION, "the mesh has defects outside the region; "
                    "extend the region to cover them: 4 open boundary edges (e.g. vertices 0, "
                    "42, 43, 46)"),
        "seams": (P.DEFECTS_OUTSIDE_REGION, "the mesh has defects outside the region; "
                  "extend the region to cover them: 2592 open boundary edges (e.g. vertices "
                  "96, 97, 98, 99, 100). 2238 vertices share their exact position with another "
                  "vertex (a mesh split at UV seams or hard edges looks open there): the "
                  "repair option weld=true (--weld) merges them first"),
        "large": (P.REGION_TOO_LARGE, "the region's boundary has 300 vertices; the model "
                                      "holds at most 248"),
        "growth": (P.REGION_GROWTH_EXCEEDED, "the region of 101 faces grows to 160 faces (84% "
                   "of the mesh's 190; at most 25% allowed) because the vertices around it "
                   "are pinched: mark a region without pinched corners, or allow more with "
                   "max_growth"),
        "moebius": (P.NON_ORIENTABLE, "the mesh is not orientable (like a Moebius strip): its "
                    "faces around face 0 cannot all face the same way, so no closed oriented "
                    "surface can be made from them"),
        "nan": (P.NON_FINITE, "OBJ: vertex 3 has a NaN or infinite coordinate"),
    }, instance="/repair"),
    503: GENERATE_RESPONSES[503],
    504: GENERATE_RESPONSES[504],
}

#: The error responses of ``POST /ui/preview`` (the web page's file preview).
UI_PREVIEW_RESPONSES: dict[int | str, dict[str, Any]] = {
    400: problem_response("The file could not be read, or `kind` is not points or mesh", {
        "file": (P.MALFORMED_INPUT, "the multipart body has no file field 'file'"),
        "kind": (P.INVALID_PARAMETER, "kind is one of points, mesh, not 'x'"),
    }, instance="/ui/preview"),
    413: problem_response("The file is larger than this server's limits", {
        "bytes": (P.PAYLOAD_TOO_LARGE, "the body exceeds 33554432 bytes"),
        "points": (P.TOO_MANY_POINTS, "XYZ: the file has 200001 points or more; the limit "
                                      "is 200000"),
    }, instance="/ui/preview"),
    415: problem_response("Unsupported format", {
        "format": (P.UNSUPPORTED_FORMAT, "cannot read '.docx' files; supported: ..."),
    }, instance="/ui/preview"),
    422: problem_response("NaN or infinite coordinates", {
        "nan": (P.NON_FINITE, "XYZ: point 3 has a NaN or infinite coordinate"),
    }, instance="/ui/preview"),
}

#: The query parameters of each route.
GENERATE_PARAMETERS = [o.parameter() for o in GENERATE_ROUTE_OPTIONS]
REPAIR_PARAMETERS = [o.parameter() for o in REPAIR_ROUTE_OPTIONS]


def _form_properties(table: tuple[RequestOption, ...]) -> dict[str, Any]:
    return {o.name: o.schema() for o in table}

GENERATE_REQUEST_BODY: dict[str, Any] = {
    "required": True,
    "content": {
        "multipart/form-data": {
            "schema": {
                "type": "object", "required": ["file"], "additionalProperties": False,
                "properties": {
                    "file": {"type": "string", "format": "binary",
                             "description": "The point cloud file."},
                    **_form_properties(GENERATE_ROUTE_OPTIONS),
                },
            },
            "example": {"file": _CLOUD_XYZ, "format": "obj", "seed": 7},
        },
        "application/json": {
            "schema": {"$ref": "#/components/schemas/PointsRequest"},
            "examples": {
                "points": {"summary": "Points only",
                           "value": {"points": _CLOUD, "format": "obj", "seed": 7}},
                "normals": {"summary": "With normals",
                            "value": {"points": _CLOUD, "normals": _CLOUD, "steps": 25}},
                "options": {"summary": "A vertex budget, best of 4 seeds",
                            "value": {"points": _CLOUD, "start": "points",
                                      "target_vertices": 100, "samples": 4}},
            },
        },
    },
}

_REGION_SCHEMA = {
    "type": "string",
    "description": "The region as JSON (mesh coordinates; indices into the file's faces "
                   "and vertices): exactly one of `faces`, `vertices`, `sphere`, `box`, "
                   "or `{\"auto\": \"holes\" | \"defects\" | \"all\"}` (every hole "
                   "and/or defect found, each repaired with the ring of faces around it).",
}

REPAIR_REQUEST_BODY: dict[str, Any] = {
    "required": True,
    "content": {
        "multipart/form-data": {
            "schema": {
                "type": "object", "required": ["file", "region"], "additionalProperties": False,
                "properties": {
                    "file": {"type": "string", "format": "binary",
                             "description": "The mesh file (OBJ, OFF, PLY, STL, GLB, glTF)."},
                    "region": _REGION_SCHEMA,
                    **_form_properties(REPAIR_ROUTE_OPTIONS),
                },
            },
            "examples": {
                "faces": {"summary": "Face indices",
                          "value": {"file": _MESH_FILES["obj"], "region": '{"faces": [3, 4, 10]}',
                                    "format": "obj", "seed": 7}},
                "vertices": {"summary": "Every face using these vertices",
                             "value": {"file": _MESH_FILES["obj"],
                                       "region": '{"vertices": [5]}'}},
                "sphere": {"summary": "Every face with a vertex in a ball",
                           "value": {"file": _MESH_FILES["ply"], "region": json.dumps(
                               {"sphere": {"center": np.round(_NEAR, 4).tolist(),
                                           "radius": 0.3}})}},
                "box": {"summary": "Every face with a vertex in a box",
                        "value": {"file": _MESH_FILES["off"], "region": json.dumps(
                            {"box": {"min": np.round(_NEAR - 0.2, 4).tolist(),
                                     "max": np.round(_NEAR + 0.2, 4).tolist()}})}},
                "auto": {"summary": "Every hole, closed (the regions found automatically)",
                         "value": {"file": _HOLED_OBJ, "region": '{"auto": "holes"}'}},
            },
        },
    },
}

#: Models whose schemas /generate's hand-written spec refers to.
EXTRA_SCHEMAS = (PointsRequest, MeshJSON, ProblemModel)


def add_schemas(spec: dict[str, Any]) -> dict[str, Any]:
    """Put :data:`EXTRA_SCHEMAS` into an OpenAPI spec's components."""
    schemas = spec.setdefault("components", {}).setdefault("schemas", {})
    for model in EXTRA_SCHEMAS:
        schema = model.model_json_schema(ref_template="#/components/schemas/{model}")
        for name, sub in schema.pop("$defs", {}).items():
            schemas.setdefault(name, sub)
        schemas[model.__name__] = schema
    return spec
