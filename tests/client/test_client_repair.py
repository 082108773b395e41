"""``Client.repair``, ``AsyncClient.repair`` and ``spacemesh-client repair`` against a real
server (REST and gRPC): every region form and format byte-identical to the raw API, every
input form, the region errors as typed exceptions, and one-line CLI errors."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys

import httpx
import pytest
from service_testing import REPAIR_STEPS, check_repair, mesh_file, repair_mesh_cases

from spacemesh_client import AsyncClient, Client, Mesh, RetryPolicy
from spacemesh_client import errors as E
from spacemesh_client.cli import main
from spacemesh_client.mesh import repair_summary
from tests.repair.repair_testing import flat_shaded
from tests.repair.test_repair_cut import open_icosphere

pytestmark = pytest.mark.slow

CASES = repair_mesh_cases()
SEED = 5
FORMATS = ("glb", "gltf", "obj", "ply", "off", "json")
#: The installed console script's code path, without relying on PATH.
CLI = [sys.executable, "-c", "from spacemesh_client.cli import main; main()"]


def raw_repair(rest_url: str, mesh, region: dict, **params) -> httpx.Response:
    """The same request without the SDK (the reference)."""
    response = httpx.post(rest_url + "/repair", params={"steps": REPAIR_STEPS, **params},
                          files={"file": ("mesh.obj", mesh_file(mesh))},
                          data={"region": json.dumps(region)}, timeout=60)
    assert response.status_code == 200, response.text
    return response


@pytest.mark.parametrize("form", sorted(CASES))
def test_every_region_form_matches_the_raw_api(client, rest_url, form):
    mesh, region = CASES[form]
    repaired = client.repair(mesh_file(mesh), region, filename="mesh.obj", format="obj",
                             seed=SEED, steps=REPAIR_STEPS)
    reference = raw_repair(rest_url, mesh, region, format="obj", seed=SEED)
    assert repaired.data == reference.content  # REST and gRPC: byte-identical to curl
    assert repaired.repair == repair_summary(json.loads(reference.headers["x-spacemesh-repair"]))
    assert repaired.seed == SEED and repaired.steps == REPAIR_STEPS and repaired.batch_size == 1
    assert repaired.stats.closed and repaired.stats.manifold and repaired.stats.oriented
    assert {"cut", "sampler", "splice"} <= set(repaired.timings)
    check_repair(mesh, region, repaired.vertices, repaired.faces, repaired.repair)


@pytest.mark.parametrize("fmt", FORMATS)
def test_every_format(client, fmt):
    mesh, region = CASES["sphere"]  # triangles: GLB and glTF keep the kept faces
    repaired = client.repair(mesh_file(mesh, "ply"), region, filename="m.ply", format=fmt,
                             seed=SEED, steps=REPAIR_STEPS)
    assert repaired.format == fmt
    check_repair(mesh, region, repaired.vertices, repaired.faces, repaired.repair,
                 polygons=fmt not in ("glb", "gltf"))


def test_every_input_form_and_seed_replay(rest_url, grpc_url, tmp_path):
    trimesh = pytest.importorskip("trimesh")
    mesh, region = CASES["faces"]
    path = tmp_path / "mesh.off"
    path.write_bytes(mesh_file(mesh, "off"))
    with Client(rest_url, retry=RetryPolicy.never()) as client:
        first = client.repair(path, region, steps=REPAIR_STEPS)  # a seed picked by the server
        same = [
            client.repair(str(path), region, seed=first.seed, steps=REPAIR_STEPS),
            client.repair(path.read_bytes(), region, filename="m.off", seed=first.seed,
                          steps=REPAIR_STEPS),
            client.repair(path.read_bytes(), region, seed=first.seed, steps=REPAIR_STEPS),
            client.repair(path, region["faces"], seed=first.seed, steps=REPAIR_STEPS),
        ]
        assert all(m.data == first.data for m in same)
        as_json = client.repair(path, region, seed=first.seed, steps=REPAIR_STEPS,
                                format="json")
        # A Mesh (a JSON one is sent as PLY) or a trimesh object goes back in as it is.
        star = {"vertices": [1]}
        again = [client.repair(m, star, seed=1, steps=REPAIR_STEPS, format="obj")
                 for m in (as_json, first)]
        assert again[0].data == again[1].data
        tri = trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.face_indices.reshape(-1, 3),
                              process=False)  # sent as trimesh writes it (float32 PLY)
        by_trimesh = client.repair(tri, region, seed=first.seed, steps=REPAIR_STEPS)
        check_repair(mesh, region, by_trimesh.vertices, by_trimesh.faces, by_trimesh.repair)
    with Client(grpc_url, retry=RetryPolicy.never()) as client:
        assert client.repair(path, region, seed=first.seed, steps=REPAIR_STEPS).data == (
            first.data)


def test_region_errors_are_typed(client):
    mesh = mesh_file(CASES["faces"][0])

    def expect(cls, region, data=mesh):
        with pytest.raises(cls) as caught:
            client.repair(data, region, filename="m.obj", steps=REPAIR_STEPS)
        error = caught.value
        assert type(error) is cls and error.status == cls_status(cls), repr(error)
        assert error.type == E.TYPE_BASE + cls.slug and error.detail
        return error

    expect(E.EmptyRegion, {"sphere": {"center": [9, 9, 9], "radius": 0.1}})
    expect(E.WholeMeshRegion, {"box": {"min": [-2, -2, -2], "max": [2, 2, 2]}})
    expect(E.InvalidRegion, {"sphere": {"center": [0, 0], "radius": 1}})
    expect(E.InvalidRegion, {"faces": [1000]})
    expect(E.InvalidRegion, {"cylinder": {"radius": 1}})  # gRPC: refused by the client
    expect(E.InvalidRegion, {"sphere": {"centre": [0, 0, 1], "radius": 1}})
    opened, _ = open_icosphere()  # open edges around vertex 0
    far = int((opened.vertices @ opened.vertices[0]).argmin())
    defects = expect(E.DefectsOutsideRegion, {"vertices": [far]}, mesh_file(opened))
    assert defects.extra["defects"][0]["kind"] == "open-boundary"  # over gRPC too
    expect(E.MalformedInput, {"faces": [0]}, b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n")
    assert isinstance(defects, E.RegionError) and isinstance(defects, E.InvalidRequest)


def cls_status(cls) -> int:
    return 400 if cls is E.MalformedInput else 422


def test_async_client_repairs_concurrently(url, rest_url):
    mesh, region = CASES["box"]

    async def run() -> list[Mesh]:
        async with AsyncClient(url, retry=RetryPolicy.never()) as client:
            jobs = [client.repair(mesh_file(mesh), region, filename="m.obj", format="obj",
                                  seed=SEED, steps=REPAIR_STEPS) for _ in range(3)]
            done = await asyncio.gather(*jobs)
            with pytest.raises(E.EmptyRegion):
                await client.repair(mesh_file(mesh), {"faces": []}, filename="m.obj")
            return done

    meshes = asyncio.run(run())
    reference = raw_repair(rest_url, mesh, region, format="obj", seed=SEED)
    assert {m.data for m in meshes} == {reference.content}
    assert meshes[0].repair["region_faces"] == int(reference.headers["x-spacemesh-region-faces"])


def test_cli_repair(rest_url, grpc_url, tmp_path, capsys):
    mesh, region = CASES["sphere"]
    source = tmp_path / "mesh.obj"
    source.write_bytes(mesh_file(mesh))
    center, radius = region["sphere"]["center"], region["sphere"]["radius"]
    sphere = ",".join(map(repr, [*center, radius]))
    out = tmp_path / "fixed.obj"
    done = subprocess.run([*CLI, "repair", str(source), "-o", str(out), "--sphere", sphere,
                           "--seed", str(SEED), "--steps", str(REPAIR_STEPS), "--url", rest_url],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "faces re-generated" in done.stdout and "closed oriented manifold" in done.stdout
    reference = raw_repair(rest_url, mesh, region, format="obj", seed=SEED)
    assert out.read_bytes() == reference.content  # OBJ asked from the extension

    grpc_out = tmp_path / "fixed.ply"
    main(["repair", str(source), "-o", str(grpc_out), "--region", json.dumps(region),
          "--seed", str(SEED), "--steps", str(REPAIR_STEPS), "--url", grpc_url, "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert summary["format"] == "ply" and summary["closed"] and summary["seed"] == SEED
    expected = json.loads(reference.headers["x-spacemesh-repair"])
    assert summary["repair"] == expected

    for args, message in (
        (["--faces", "", "--url", rest_url], "(422): the region selects no face"),
        (["--sphere", "9,9,9,0.1", "--url", grpc_url], "(422): the region selects no face"),
        (["--box", "-2,-2,-2,2,2,2", "--url", rest_url], "whole mesh"),
        (["--region", '{"faces": [1000]}', "--url", rest_url], "out of range"),
    ):
        with pytest.raises(SystemExit) as caught:
            main(["repair", str(source), "-o", str(out), "--steps", str(REPAIR_STEPS), *args])
        assert caught.value.code == 2, args
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("spacemesh-client: error: "), lines
        assert message in lines[0], (args, lines[0])
    with pytest.raises(SystemExit) as caught:  # a usage mistake: one line too
        main(["repair", str(source), "--faces", "1"])
    lines = capsys.readouterr().err.strip().splitlines()
    assert caught.value.code == 2 and len(lines) == 1 and "-o/--output" in lines[0], lines


# ---------------------------------------------------------------------- weld
SMOOTH, BALL = CASES["sphere"]
FLAT_GLB = mesh_file(flat_shaded(SMOOTH), "glb")  # every triangle on vertices of its own
MERGED = 3 * SMOOTH.n_faces - SMOOTH.n_vertices


def test_weld_repairs_a_split_glb(client, rest_url):
    with pytest.raises(E.DefectsOutsideRegion) as caught:
        client.repair(FLAT_GLB, BALL, filename="flat.glb", seed=SEED, steps=REPAIR_STEPS)
    assert caught.value.extra["coincident_vertices"] == MERGED
    assert "weld=true" in caught.value.detail
    repaired = client.repair(FLAT_GLB, BALL, filename="flat.glb", format="obj", seed=SEED,
                             steps=REPAIR_STEPS, weld=True)
    response = httpx.post(rest_url + "/repair", params={"steps": REPAIR_STEPS, "seed": SEED,
                                                        "format": "obj", "weld": "true"},
                          files={"file": ("flat.glb", FLAT_GLB)},
                          data={"region": json.dumps(BALL)}, timeout=60)
    assert response.status_code == 200, response.text
    assert repaired.data == response.content
    assert repaired.repair["welded_vertices"] == MERGED == int(
        response.headers["x-spacemesh-welded-vertices"])
    assert repaired.stats.closed and repaired.stats.manifold and repaired.stats.oriented
    check_repair(SMOOTH, BALL, repaired.vertices, repaired.faces, repaired.repair)


def test_async_client_welds(url):
    async def run() -> Mesh:
        async with AsyncClient(url, retry=RetryPolicy.never()) as client:
            with pytest.raises(E.DefectsOutsideRegion):
                await client.repair(FLAT_GLB, BALL, filename="flat.glb", steps=REPAIR_STEPS)
            return await client.repair(FLAT_GLB, BALL, filename="flat.glb", seed=SEED,
                                       steps=REPAIR_STEPS, weld=True)

    repaired = asyncio.run(run())
    assert repaired.repair["welded_vertices"] == MERGED and repaired.stats.closed


def test_cli_repair_weld(rest_url, grpc_url, tmp_path, capsys):
    source = tmp_path / "flat.glb"
    source.write_bytes(FLAT_GLB)
    center, radius = BALL["sphere"]["center"], BALL["sphere"]["radius"]
    args = ["repair", str(source), "-o", str(tmp_path / "fixed.obj"), "--sphere",
            ",".join(map(repr, [*center, radius])), "--seed", str(SEED), "--steps",
            str(REPAIR_STEPS)]
    with pytest.raises(SystemExit) as caught:
        main([*args, "--url", rest_url])
    lines = capsys.readouterr().err.strip().splitlines()
    assert caught.value.code == 2 and len(lines) == 1 and "weld=true" in lines[0], lines
    for url in (rest_url, grpc_url):
        main([*args, "--url", url, "--weld"])
        out = capsys.readouterr().out
        assert f"{MERGED} vertices welded" in out and "closed oriented manifold" in out, out
