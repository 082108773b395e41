"""Helpers of the service tests: inputs in every upload format, a gated generator."""

from __future__ import annotations

import io
import re
import threading
import time
from dataclasses import dataclass

import numpy as np

from spacemesh.cancel import cancelled


def metric(url: str, name: str) -> float:
    """The value of the unlabelled metric ``name`` on the server at ``url`` (0 when absent)."""
    import httpx

    text = httpx.get(url + "/metrics").text
    match = re.search(rf"^{re.escape(name)} (\S+)$", text, re.M)
    return float(match.group(1)) if match else 0.0


def wait_for(condition, what: str, timeout: float = 30.0) -> None:
    """Wait until ``condition()`` is true (failing after ``timeout`` s, never measuring)."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


class HeldStage:
    """``function`` whose first call waits until the work of its thread is abandoned
    (:func:`spacemesh.cancel.cancelled`), counting its calls and those begun after."""

    def __init__(self, function) -> None:
        self.function = function
        self.calls = 0
        self.after = 0
        self.held = threading.Event()

    def __call__(self, *args, **kwargs):
        self.calls += 1
        if not self.held.is_set():
            self.held.set()
            wait_for(cancelled, "the request's deadline", timeout=60)
        elif cancelled():
            self.after += 1
        return self.function(*args, **kwargs)


#: Seeds tried to find one that gives a surface (and one that gives none).
SEEDS_TO_TRY = 40


def make_cloud(count: int = 300, seed: int = 0) -> np.ndarray:
    """Points on an ellipsoid, exactly representable in float32 (so every file format,
    text or binary, single or double precision, reads back the same numbers)."""
    rng = np.random.default_rng(seed)
    d = rng.standard_normal((count, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    points = d * np.array([1.5, 1.0, 0.75]) + np.array([10.0, -4.0, 2.0])
    return points.astype(np.float32).astype(np.float64)


# ---------------------------------------------------------------------- encoders
def as_ply(points: np.ndarray, binary: bool = True) -> bytes:
    header = (f"ply\nformat {'binary_little_endian' if binary else 'ascii'} 1.0\n"
              f"element vertex {len(points)}\nproperty float x\nproperty float y\n"
              "property float z\nend_header\n").encode()
    if binary:
        return header + points.astype("<f4").tobytes()
    return header + "".join(f"{x!r} {y!r} {z!r}\n" for x, y, z in points.tolist()).encode()


def as_text(points: np.ndarray, count_line: bool = False) -> bytes:
    rows = [f"{x!r} {y!r} {z!r}" for x, y, z in points.tolist()]
    if count_line:
        rows.insert(0, str(len(points)))
    return ("\n".join(rows) + "\n").encode()


def as_obj(points: np.ndarray) -> bytes:
    return ("# cloud\n" + "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in points.tolist())
            ).encode()


def as_npy(points: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, points)
    return buffer.getvalue()


def as_npz(points: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, points=points)
    return buffer.getvalue()


#: The LAS scale :func:`as_las` stores with: every float32 value of magnitude below 128
#: (those of :func:`make_cloud`) is a whole multiple of it, so LAS holds them exactly.
LAS_SCALE = 2.0**-24


def as_las(points: np.ndarray, compressed: bool = False) -> bytes:
    """The points as a LAS 1.4 file (LAZ when ``compressed``) that reads back exactly."""
    import laspy

    points = np.asarray(points, dtype=np.float64)
    assert np.array_equal(np.round(points / LAS_SCALE) * LAS_SCALE, points), \
        "the points are not whole multiples of LAS_SCALE"
    header = laspy.LasHeader(point_format=0, version="1.4")
    header.scales = np.full(3, LAS_SCALE)
    header.offsets = np.zeros(3)
    las = laspy.LasData(header)
    las.X, las.Y, las.Z = np.round(points / LAS_SCALE).astype(np.int32).T
    buffer = io.BytesIO()
    las.write(buffer, do_compress=compressed)
    return buffer.getvalue()


#: Upload format -> (file name, encoder).
UPLOADS = {
    "ply": ("cloud.ply", as_ply),
    "ply-ascii": ("cloud.ply", lambda p: as_ply(p, binary=False)),
    "xyz": ("cloud.xyz", as_text),
    "txt": ("cloud.txt", as_text),
    "pts": ("cloud.pts", lambda p: as_text(p, count_line=True)),
    "npy": ("cloud.npy", as_npy),
    "npz": ("cloud.npz", as_npz),
    "las": ("cloud.las", as_las),
    "laz": ("cloud.laz", lambda p: as_las(p, compressed=True)),
    "obj": ("cloud.obj", as_obj),
    "sniffed-ply": ("upload", as_ply),
    "sniffed-laz": ("upload", lambda p: as_las(p, compressed=True)),
}



#: Options with which the tiny model makes no surface from the test cloud whatever the
#: seed: one diffusion step from noise leaves its vertices unjoined.
NO_SURFACE_OPTIONS = {"start": "noise", "steps": 1}


@dataclass(frozen=True)
class Case:
    """The test input and seeds the tiny model turns into a surface, or into nothing.

    ``no_surface`` always holds request options (``seed`` and, unless ``empty_seed`` was
    found, :data:`NO_SURFACE_OPTIONS`) that the fixture checked give no surface, so
    the ``no-surface`` tests never need to skip.
    """

    points: np.ndarray
    good_seed: int
    empty_seed: int | None
    no_surface: dict


class WrappedGenerator:
    """A real generator seen through a wrapper (subclasses change ``generate_batch``)."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.spec = inner.spec
        self.name = inner.name
        self.repository = inner.repository

    def generate_batch(self, requests, *, progress=None, stage=None):
        return self.inner.generate_batch(requests, progress=progress, stage=stage)


class SlowGenerator(WrappedGenerator):
    """The real generator, ``step_seconds`` slower per sampler step (the step report is
    where the batcher stops work nobody waits for)."""

    def __init__(self, inner, step_seconds: float) -> None:
        super().__init__(inner)
        self.step_seconds = step_seconds

    def generate_batch(self, requests, *, progress=None, stage=None):
        def slow(done: int, total: int) -> None:
            time.sleep(self.step_seconds)
            if progress is not None:
                progress(done, total)

        return self.inner.generate_batch(requests, progress=slow, stage=stage)


class FailingGenerator(WrappedGenerator):
    """A generator whose batches raise an unexpected error (a bug, not a bad input)."""

    def generate_batch(self, requests, *, progress=None, stage=None):
        raise RuntimeError("a bug in the generator")


class GatedGenerator(WrappedGenerator):
    """A generator whose batches wait for :attr:`gate`; records what each batch did."""

    def __init__(self, inner) -> None:
        super().__init__(inner)
        self.gate = threading.Event()
        self.entered = threading.Event()
        self.batches: list[int] = []
        self.errors: list[str] = []

    def generate_batch(self, requests, *, progress=None, stage=None):
        self.entered.set()
        self.gate.wait(60)
        self.batches.append(len(requests))
        try:
            return self.inner.generate_batch(requests, progress=progress, stage=stage)
        except Exception as error:
            self.errors.append(type(error).__name__)
            raise


#: Settings of a server whose tiny deadline (``request_timeout_s``) is the point of a test:
#: a budget that admits everything, since the default one (twice the deadline) would
#: refuse the request as too expensive before it ran (tests/service/test_service_cost.py).
ADMIT_ALL = {"request_budget_s": 3600.0}


def server_settings(repository, **changes):
    from spacemesh_service.settings import Settings

    values = dict(model=repository, host="127.0.0.1", port=0, grpc_port=0, ort_threads=1,
                  min_points=16, max_points=5000, max_upload_bytes=2_000_000,
                  max_batch_delay_ms=2, log_level="warning", drain_notice_s=0)
    values.update(changes)
    return Settings(**values)


# ---------------------------------------------------------------------- repair
#: Steps of every repair in the tests (the tiny model's default is 8).
REPAIR_STEPS = 4


def repair_mesh_cases() -> dict:
    """Closed meshes of ``spacemesh.examples`` and a region of each form on them:
    ``name -> (mesh, region)`` (triangles for two forms, quads for the others)."""
    from spacemesh.examples import icosphere, torus_grid

    sphere = icosphere(1)  # 42 vertices, 80 triangles
    torus = torus_grid(12, 8)  # 96 vertices, 96 quads (more than the 64 tokens: a patch)
    star = [i for i, face in enumerate(sphere.faces) if 0 in face]
    corner = torus.vertices[5]
    return {
        "faces": (sphere, {"faces": star}),
        "vertices": (torus, {"vertices": [30]}),
        "sphere": (sphere, {"sphere": {"center": sphere.vertices[7].tolist(), "radius": 0.3}}),
        "box": (torus, {"box": {"min": (corner - 0.2).tolist(),
                                "max": (corner + 0.2).tolist()}}),
    }


def mesh_file(mesh, fmt: str = "obj") -> bytes:
    """``mesh`` as a file the server reads."""
    from spacemesh.io import export_mesh

    return export_mesh(mesh, fmt)


def face_keys(reference: np.ndarray, vertices: np.ndarray, faces, tol: float = 1e-5) -> set:
    """Faces as rotation-normalised tuples of the reference vertices they sit on (-1 for a
    vertex on none), so faces of two files compare by position whatever their numbering."""
    from scipy.spatial import cKDTree

    distance, nearest = cKDTree(reference).query(np.asarray(vertices, dtype=np.float64))
    nearest[distance > tol] = -1
    keys = set()
    for face in faces:
        ids = [int(nearest[v]) for v in face]
        start = ids.index(min(ids))
        keys.add(tuple(ids[start:] + ids[:start]))
    return keys


def check_repair(original, region: dict, vertices: np.ndarray, faces, repair: dict,
                 polygons: bool = True) -> None:
    """A repaired mesh is closed, oriented and manifold, and every face outside the region
    comes back with the same positions and the same polygon (faces the cut added to the
    region, ``repair["grown_faces"]`` of them, may change)."""
    from spacemesh.mesh import PolygonMesh
    from spacemesh.repair import parse_region
    from tests.validity import assert_valid_mesh

    out = PolygonMesh.from_faces(np.asarray(vertices, dtype=np.float64),
                                 [np.asarray(f) for f in faces])
    assert_valid_mesh(out)
    requested = parse_region(region).face_mask(original)
    assert repair["requested_faces"] == int(requested.sum()) > 0
    assert repair["region_faces"] == repair["requested_faces"] + repair["grown_faces"]
    outside = [f for f, inside in zip(original.faces, requested, strict=True) if not inside]
    expected = face_keys(original.vertices, original.vertices, outside)
    got = face_keys(original.vertices, out.vertices, out.faces)
    assert len(expected - got) <= repair["grown_faces"], expected - got
    if repair["grown_faces"] == 0:
        assert expected <= got
    if polygons:  # kept faces, then the new ones
        assert out.n_faces == original.n_faces - repair["region_faces"] + repair["new_faces"]


def faulty_repair(repair_mesh, fault: str = "moved"):
    """``repair_mesh`` with a bug outside the region, which the server's check
    (:func:`spacemesh.repair.verify_repair`) must refuse: ``"moved"`` moves a corner of
    the first kept face, ``"dropped"`` re-generates the first kept face as well (it is
    left out of the kept faces and added back as a new one)."""
    from dataclasses import replace

    from spacemesh.mesh import PolygonMesh

    def repair(*args, **kwargs):
        result = repair_mesh(*args, **kwargs)
        mesh, source = result.mesh, result.face_source
        first = int(np.flatnonzero(source >= 0)[0])
        corners = mesh.face_indices[mesh.face_offsets[first]: mesh.face_offsets[first + 1]]
        if fault == "moved":
            vertices = mesh.vertices.copy()
            vertices[corners[0]] += 0.01 * (np.ptp(mesh.vertices, axis=0).max() or 1.0)
            return replace(result, mesh=PolygonMesh(vertices, mesh.face_indices,
                                                    mesh.face_offsets))
        faces = [mesh.face_indices[mesh.face_offsets[f]: mesh.face_offsets[f + 1]]
                 for f in range(mesh.n_faces)]
        order = [f for f in range(mesh.n_faces) if f != first] + [first]
        moved = PolygonMesh.from_faces(mesh.vertices, [faces[f] for f in order])
        return replace(result, mesh=moved, face_source=np.append(np.delete(source, first), -1))

    return repair


#: Requests that must answer 422 invalid-option, and the option each names (REST, gRPC
#: and the SDK's tests send them all).
BAD_OPTIONS = [
    ({"start": "bogus"}, "start"),
    ({"start": "noise", "start_time": 0.5}, "start_time"),
    ({"start": "points", "start_time": 2}, "start_time"),
    ({"start": "points", "target_vertices": 3}, "target_vertices"),
    ({"start": "points", "target_vertices": 20000}, "target_vertices"),
    ({"samples": 0}, "samples"),
    ({"samples": 17}, "samples"),
    ({"raw": "maybe"}, "raw"),
    ({"start": "points", "tolerance": 0.9}, "tolerance"),
    ({"start": "points", "tolerance": 0.01, "target_vertices": 60}, "tolerance"),
    ({"start": "noise", "tolerance": 0.01}, "tolerance"),
    ({"surface": "half"}, "surface"),
    ({"raw": True, "surface": "open"}, "surface"),
    ({"face_type": "hexagons"}, "face_type"),
    ({"face_type": "quads"}, "face_type"),
    ({"raw": True, "face_type": "triangles"}, "face_type"),  # the tiny model makes polygons
]


def region_pb(region: dict):
    """The gRPC ``Region`` of a region in its JSON form (every form, ``auto`` included)."""
    from spacemesh_service.pb import spacemesh_pb2 as pb

    (kind, value), = region.items()
    if kind in ("faces", "vertices"):
        return pb.Region(**{kind: pb.Indices(indices=value)})
    if kind == "sphere":
        return pb.Region(sphere=pb.Sphere(center=value["center"], radius=value["radius"]))
    if kind == "auto":
        return pb.Region(auto_region=value)
    return pb.Region(box=pb.Box(min=value["min"], max=value["max"]))
