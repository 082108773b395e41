"""The SDK stands alone: httpx and numpy only (no SpaceMesh package, no torch, no gRPC
until a grpc:// URL), and its generated gRPC code matches proto/spacemesh.proto."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

ISOLATED = textwrap.dedent('''
    import sys

    class Block:
        blocked = ("spacemesh", "spacemesh_service", "torch", "trimesh", "grpc", "google")

        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in self.blocked:
                raise ModuleNotFoundError(f"No module named {name!r} (blocked)", name=name)
            return None

    sys.meta_path.insert(0, Block())
    import spacemesh_client
    from spacemesh_client import Client, errors
    from spacemesh_client.cli import build_parser
    with Client("http://127.0.0.1:9") as client:
        try:
            client.generate([[0.0, 0.0, 0.0]] * 20)
        except errors.ConnectionFailed:
            pass
    try:
        Client("grpc://127.0.0.1:9")
    except ModuleNotFoundError as error:
        assert "spacemesh-client[grpc]" in str(error), error
    else:
        raise AssertionError("grpc:// without grpcio")
    mods = sorted(m for m in sys.modules if m.split(".")[0] in Block.blocked)
    assert not mods, mods
    print("ok")
''')


def test_the_sdk_needs_no_other_spacemesh_package():
    done = subprocess.run([sys.executable, "-c", ISOLATED], capture_output=True, text=True,
                          timeout=60, cwd=ROOT / "client")
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-3000:]


def test_generated_code_matches_the_proto(tmp_path):
    protoc = pytest.importorskip("grpc_tools.protoc")
    pytest.importorskip("google.protobuf")
    from google.protobuf import descriptor_pb2

    from spacemesh_client.pb import spacemesh_pb2

    args = ["protoc", "-I", str(ROOT / "proto"), f"--descriptor_set_out={tmp_path / 'set.pb'}",
            str(ROOT / "proto" / "spacemesh.proto")]
    assert protoc.main(args) == 0
    wanted = descriptor_pb2.FileDescriptorSet.FromString((tmp_path / "set.pb").read_bytes())
    have = descriptor_pb2.FileDescriptorProto()
    spacemesh_pb2.DESCRIPTOR.CopyToProto(have)
    for message in [*wanted.file[0].message_type, *have.message_type]:
        drop_json_names(message)  # the descriptor set adds them; generated code does not
    assert have == wanted.file[0], "client/spacemesh_client/pb is stale: run client/gen_proto.sh"


def drop_json_names(message) -> None:
    for field in message.field:
        field.ClearField("json_name")
    for nested in message.nested_type:
        drop_json_names(nested)


def test_pyproject_declares_the_console_script_and_extras():
    import tomllib

    project = tomllib.loads((ROOT / "client" / "pyproject.toml").read_text())["project"]
    assert project["scripts"]["spacemesh-client"] == "spacemesh_client.cli:main"
    assert sorted(d.split(">")[0] for d in project["dependencies"]) == ["httpx", "numpy"]
    assert set(project["optional-dependencies"]) >= {"trimesh", "grpc"}


def test_the_service_and_the_sdk_commit_the_same_generated_code():
    """Both copies come from scripts/gen_proto.sh; the SDK's is checked against the proto
    above, so the service's is too."""
    for name in ("spacemesh_pb2.py", "spacemesh_pb2.pyi", "spacemesh_pb2_grpc.py"):
        service = ROOT / "service" / "spacemesh_service" / "pb" / name
        client = ROOT / "client" / "spacemesh_client" / "pb" / name
        assert service.read_bytes() == client.read_bytes(), f"{name}: run scripts/gen_proto.sh"
