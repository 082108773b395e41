"""Importing a folder of mesh files: kept shapes, skipped files and their reasons."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

import spacemesh.cli.data  # noqa: F401  (registers the ``data`` commands)
from spacemesh.cli.common import app
from spacemesh.data.importer import flip_caps, import_folder, weld_close_vertices
from spacemesh.data.shards import open_dataset
from spacemesh.data.validate import validate_mesh
from spacemesh.io import save_mesh
from spacemesh.mesh import PolygonMesh

trimesh = pytest.importorskip("trimesh")

CUBE_V = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=float,
)
CUBE_Q = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]


def torus() -> PolygonMesh:
    tm = trimesh.creation.torus(
        major_radius=1.0, minor_radius=0.35, major_sections=24, minor_sections=12
    )
    return PolygonMesh.from_faces(tm.vertices * [2.0, 1.0, 0.5], tm.faces)


def fin_cube() -> PolygonMesh:
    """A cube with a fin on one edge: three faces at that edge (non-manifold)."""
    vertices = np.vstack([CUBE_V, [[0, -1, -1], [1, -1, -1]]])
    return PolygonMesh.from_faces(vertices, [*CUBE_Q, [0, 1, 9, 8], [8, 9, 1, 0]])


@pytest.fixture(scope="module")
def mesh_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("meshes")
    save_mesh(PolygonMesh.from_faces(CUBE_V * 3.0 + 5.0, CUBE_Q), folder / "cube.obj")
    save_mesh(torus(), folder / "torus.stl")
    (folder / "sub").mkdir()
    save_mesh(torus(), folder / "sub" / "torus.ply")
    save_mesh(fin_cube(), folder / "fin.off")
    open_box = PolygonMesh.from_faces(CUBE_V, CUBE_Q[1:])
    save_mesh(open_box, folder / "open.glb")
    (folder / "broken.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    (folder / "notes.txt").write_text("not a mesh")
    return folder


def test_import_keeps_good_and_explains_skipped(mesh_folder, tmp_path):
    manifest = import_folder(mesh_folder, tmp_path / "out", points=32, progress=False)
    dataset = open_dataset(tmp_path / "out")
    kept = {r.shape_id: r for r in dataset}
    assert set(kept) == {"cube.obj", "torus.stl", "sub/torus.ply"}
    assert kept["cube.obj"].mesh.degree_histogram() == {4: 6}  # polygons stay polygons
    assert kept["torus.stl"].genus == 1
    for record in kept.values():
        assert validate_mesh(record.mesh) == []
        assert np.isclose(np.abs(record.mesh.vertices).max(), 1.0)
    skipped = {s["file"]: s["reasons"] for s in manifest["skipped"]}
    assert set(skipped) == {"fin.off", "open.glb", "broken.off"}
    assert "non_manifold_edge" in skipped["fin.off"]
    assert "open_boundary" in skipped["open.glb"]
    assert skipped["broken.off"][0].startswith("unreadable:")
    assert manifest["rejections"]["non_manifold_edge"] == 1


def test_import_decimates(mesh_folder, tmp_path):
    import_folder(mesh_folder, tmp_path / "dec", decimate_to=100, points=16, progress=False)
    torus_record = next(r for r in open_dataset(tmp_path / "dec") if r.shape_id == "torus.stl")
    assert torus_record.mesh.n_vertices <= 100 and torus_record.genus == 1


def test_import_cli_reports_skips(mesh_folder, tmp_path):
    result = CliRunner().invoke(
        app, ["data", "import", str(mesh_folder), "--out", str(tmp_path / "c"), "--no-progress"]
    )
    assert result.exit_code == 0, result.output
    assert "imported 3 of 6 files" in result.output
    assert "skipped fin.off: non_manifold_edge" in result.output
    manifest = json.loads((tmp_path / "c" / "manifest.json").read_text())
    assert manifest["counts"]["stored"] == 3


def test_import_cli_missing_folder(tmp_path):
    result = CliRunner().invoke(app, ["data", "import", str(tmp_path / "nope"), "--out", "x"])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and "is not a folder" in result.output


def test_cleanups_repair_cad_defects():
    # A collinear cap: vertex 8 on the edge (0, 1) of a triangulated cube.
    vertices = np.vstack([CUBE_V, [[0.5, 0.0, 0.0]]])
    polygons = [[0, 3, 2, 1, 8], CUBE_Q[1], [0, 8, 1, 5, 4], *CUBE_Q[3:]]
    capped = PolygonMesh.from_faces(
        vertices, [[p[0], p[i], p[i + 1]] for p in polygons for i in range(1, len(p) - 1)]
    )
    assert "zero_area_face" in validate_mesh(capped)
    assert validate_mesh(flip_caps(capped)) == []
    # A crack: the top face uses a copy of vertex 6 that is 1e-7 away.
    vertices = np.vstack([CUBE_V, [[1.0, 1.0, 1.0 + 1e-7]]])
    faces = [list(f) for f in CUBE_Q]
    faces[1] = [4, 5, 8, 7]
    cracked = PolygonMesh.from_faces(vertices, faces)
    assert "open_boundary" in validate_mesh(cracked)
    assert validate_mesh(weld_close_vertices(cracked)) == []


def test_self_intersecting_meshes_are_skipped_or_kept_flagged(tmp_path):
    """A closed manifold whose faces cross: skipped by default, kept with the flag."""
    from spacemesh.examples import icosphere

    sphere = icosphere(1)
    vertices = sphere.vertices.copy()
    vertices[0] *= -1.6  # pushed through the far side of the sphere
    folder = tmp_path / "in"
    folder.mkdir()
    save_mesh(PolygonMesh.from_faces(vertices, [f.tolist() for f in sphere.faces]),
              folder / "crossed.obj")
    save_mesh(PolygonMesh.from_faces(CUBE_V, CUBE_Q), folder / "cube.obj")

    strict = import_folder(folder, tmp_path / "strict", points=16, progress=False)
    assert strict["skipped"] == [{"file": "crossed.obj", "reasons": ["self_intersection"]}]

    result = CliRunner().invoke(app, ["data", "import", str(folder), "--out",
                                      str(tmp_path / "kept"), "--keep-self-intersecting",
                                      "--no-progress"])
    assert result.exit_code == 0 and "imported 2 of 2 files" in result.output, result.output
    kept = {r.shape_id: r for r in open_dataset(tmp_path / "kept")}
    assert kept["crossed.obj"].tolerated == ("self_intersection",)
    assert kept["cube.obj"].tolerated == ()
    assert validate_mesh(kept["crossed.obj"].mesh) == ["self_intersection"]  # only that
    manifest = json.loads((tmp_path / "kept" / "manifest.json").read_text())
    assert manifest["tolerated"] == ["self_intersection"]
