"""The protected deployment: deploy/compose.protected.yml, deploy/nginx-tls.conf,
deploy/prometheus-tls.yml and deploy/make-secrets.sh.

The override validates against the compose-spec schema and names only real settings; the
TLS nginx file is nginx.conf plus TLS lines; and the secrets that make-secrets.sh makes
start a real server (keys + TLS) behind a real nginx running nginx-tls.conf, reached over
https and gRPC with TLS with and without a key.
"""

from __future__ import annotations

import json
import logging
import re
import shutil
import subprocess
import textwrap
import time

import pytest
from deploy_testing import ROOT, executable, free_port, missing
from test_deploy_compose import errors, validator  # noqa: F401  (fixture)
from test_deploy_nginx import wait_for_port

pytestmark = pytest.mark.slow

DEPLOY = ROOT / "deploy"
NGINX = (DEPLOY / "nginx.conf").read_text()
NGINX_TLS = (DEPLOY / "nginx-tls.conf").read_text()
#: The lines nginx-tls.conf adds to nginx.conf.
TLS_LINE = re.compile(r"^\s*(ssl_|proxy_ssl_|grpc_ssl_)")


@pytest.fixture(scope="module")
def protected(yaml) -> dict:
    return yaml.safe_load((DEPLOY / "compose.protected.yml").read_text())


def directives(conf: str) -> list[str]:
    """The configuration without comments and blank lines, TLS spellings made plain."""
    out = []
    for line in conf.splitlines():
        line = line.split("#", 1)[0].rstrip()
        if not line.strip() or TLS_LINE.match(line):
            continue
        line = line.replace(" ssl;", ";").replace(" ssl http2;", " http2;")
        out.append(line.replace("https://", "http://").replace("grpcs://", "grpc://"))
    return out


def test_the_tls_nginx_file_is_nginx_conf_with_tls(protected):
    assert directives(NGINX_TLS) == directives(NGINX)
    assert "proxy_pass https://" in NGINX_TLS and "grpc_pass grpcs://" in NGINX_TLS
    assert "proxy_ssl_verify on;" in NGINX_TLS and "grpc_ssl_verify on;" in NGINX_TLS
    assert "location = /metrics" in NGINX  # never shown through the edge


def test_the_override_is_valid_and_names_real_settings(validator, protected, compose,  # noqa: F811
                                                       yaml):
    from spacemesh_service.settings import Settings

    assert errors(validator, protected) == []
    known = {Settings.env_name(name) for name in Settings.model_fields}
    for document in (compose, protected):
        for name, service in document["services"].items():
            env = service.get("environment") or {}
            unknown = {k for k in env if k.startswith("SPACEMESH_")} - known
            assert not unknown, (name, unknown)
    for service in ("spacemesh", "spacemesh-gpu"):
        env = protected["services"][service]["environment"]
        assert env["SPACEMESH_API_KEYS"] == "/run/secrets/api-keys"
        assert {env["SPACEMESH_TLS_CERT"], env["SPACEMESH_TLS_KEY"]} == {
            "/run/secrets/tls-cert", "/run/secrets/tls-key"}
    for secret in protected["secrets"].values():  # relative to the project (the root)
        assert secret["file"].startswith("./deploy/secrets/")
    assert "/deploy/secrets/" in (ROOT / ".gitignore").read_text().splitlines()
    for mount in (v for s in protected["services"].values() for v in s.get("volumes", ())):
        assert (ROOT / mount.split(":")[0]).is_file(), mount
    prometheus = yaml.safe_load((DEPLOY / "prometheus-tls.yml").read_text())
    jobs = {job["job_name"]: job for job in prometheus["scrape_configs"]}
    for job in ("spacemesh", "spacemesh-gpu"):
        assert jobs[job]["scheme"] == "https"
        assert jobs[job]["authorization"]["credentials_file"] == "/run/secrets/metrics-key"


@pytest.fixture(scope="module")
def secrets(tmp_path_factory):
    """What deploy/make-secrets.sh makes (run in a copy of deploy/)."""
    if shutil.which("openssl") is None:
        missing("openssl")
    folder = tmp_path_factory.mktemp("deploy")
    shutil.copy(DEPLOY / "make-secrets.sh", folder)
    done = subprocess.run(["bash", str(folder / "make-secrets.sh"), "mesh.example.com"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return folder / "secrets"


def render(conf: str, folder, secrets, rest: str, grpc: str, rest_port: int,
           grpc_port: int) -> str:
    """nginx-tls.conf with a loopback replica, free ports, temporary paths and the
    secrets' files."""
    conf = re.sub(r"server spacemesh:8000 ([^;]*);", rf"server {rest} \1;", conf)
    conf = re.sub(r"server spacemesh:8001 ([^;]*);", rf"server {grpc} \1;", conf)
    conf = conf.replace("listen 8000 ssl;", f"listen 127.0.0.1:{rest_port} ssl;")
    conf = conf.replace("listen 8001 ssl http2;", f"listen 127.0.0.1:{grpc_port} ssl http2;")
    conf = conf.replace("pid /tmp/nginx.pid;", f"pid {folder}/nginx.pid;")
    conf = conf.replace("access_log /dev/stdout combined;", f"access_log {folder}/access.log;")
    conf = conf.replace("/run/secrets/tls-cert", str(secrets / "tls.crt"))
    conf = conf.replace("/run/secrets/tls-key", str(secrets / "tls.key"))
    temp = "".join(f"    {kind}_temp_path {folder}/{kind};\n" for kind in
                   ("client_body", "proxy", "fastcgi", "uwsgi", "scgi"))
    return conf.replace("http {\n", "http {\n" + temp, 1)


def test_tls_and_keys_end_to_end_behind_nginx(secrets, start_server, generator, case,
                                              tmp_path, caplog):
    from spacemesh_client import Client, RetryPolicy
    from spacemesh_client.errors import Unauthorized

    binary = executable("nginx")
    if binary is None:
        pytest.skip("no nginx binary (apt-get install nginx)")
    replica = start_server(generator, api_keys=secrets / "api-keys",
                           tls_cert=secrets / "tls.crt", tls_key=secrets / "tls.key",
                           trusted_proxies="127.0.0.1/32")
    rest_port, grpc_port = free_port(), free_port()
    conf = tmp_path / "nginx.conf"
    conf.write_text(render(NGINX_TLS, tmp_path, secrets, replica.url.split("//")[1],
                           replica.grpc_target, rest_port, grpc_port))
    check = subprocess.run([binary, "-t", "-p", str(tmp_path), "-c", str(conf)],
                           capture_output=True, text=True)
    assert check.returncode == 0, check.stderr
    process = subprocess.Popen([binary, "-p", str(tmp_path), "-c", str(conf), "-g",
                                "daemon off;"], stderr=subprocess.PIPE, text=True)
    caplog.set_level(logging.INFO, logger="spacemesh.access")
    try:
        wait_for_port(rest_port, process)
        wait_for_port(grpc_port, process)
        key = (secrets / "client-key").read_text().strip()
        for url in (f"https://127.0.0.1:{rest_port}", f"grpcs://127.0.0.1:{grpc_port}"):
            with Client(url, verify=secrets / "tls.crt", retry=RetryPolicy.never(),
                        api_key="") as client:
                with pytest.raises(Unauthorized):
                    client.generate(case.points, seed=case.good_seed)
            with Client(url, verify=secrets / "tls.crt", api_key=key) as client:
                assert client.generate(case.points, seed=case.good_seed).stats.faces > 0
        with Client(f"https://127.0.0.1:{rest_port}", verify=secrets / "tls.crt",
                    api_key=key) as client:
            with pytest.raises(Exception, match="404"):
                client.request("GET", "/metrics")
            answer = client.request("GET", "/v2")
        request_id = answer.headers["x-request-id"]
        assert re.fullmatch(r"[0-9a-f]{32}", request_id)  # nginx's $request_id
        deadline = time.monotonic() + 20
        while True:
            lines = [json.loads(r.getMessage()) for r in caplog.records
                     if r.name == "spacemesh.access"]
            mine = [line for line in lines if line["request_id"] == request_id]
            if mine or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        assert mine and mine[0]["client"] == "127.0.0.1" and mine[0]["route"] == "/v2"
    finally:
        process.terminate()
        process.wait(30)


def test_the_kubernetes_notes_name_real_settings_and_open_probes(yaml):
    from spacemesh_service.security import Guard
    from spacemesh_service.settings import Settings

    text = (ROOT / "docs" / "DEPLOY.md").read_text()
    kubernetes = text[text.index("## Kubernetes"):text.index("## Training")]
    documents = [d for block in re.findall(r"```yaml\n(.*?)```", kubernetes, re.S)
                 for d in yaml.safe_load_all(textwrap.dedent(block)) if d]
    [deployment] = [d for d in documents if d.get("kind") == "Deployment"]
    [container] = deployment["spec"]["template"]["spec"]["containers"]
    names = {e["name"] for e in container["env"]}
    known = {Settings.env_name(name) for name in Settings.model_fields}
    assert names <= known, names - known
    assert {"SPACEMESH_API_KEYS", "SPACEMESH_TLS_CERT", "SPACEMESH_TLS_KEY",
            "SPACEMESH_RATE_LIMIT", "SPACEMESH_TRUSTED_PROXIES"} <= names
    mounts = {m["mountPath"] for m in container["volumeMounts"]}
    for env in container["env"]:
        if env["name"] in ("SPACEMESH_API_KEYS", "SPACEMESH_TLS_CERT", "SPACEMESH_TLS_KEY"):
            assert any(env["value"].startswith(m + "/") for m in mounts), env
    guard = Guard()
    for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
        get = container[probe]["httpGet"]
        assert guard.is_open(get["path"]) and get["scheme"] == "HTTPS", probe
