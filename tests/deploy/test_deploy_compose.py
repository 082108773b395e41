"""docker-compose.yml validates against the compose-spec JSON schema (vendored from the
check-jsonschema package, deploy/schema/), and wires what the issue asks: replicas
behind nginx for REST and gRPC, Prometheus scraping /metrics, an optional GPU profile."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import re

import pytest
from deploy_testing import ROOT, missing

SCHEMA = ROOT / "deploy" / "schema" / "compose-spec.json"
#: sha256 of compose-spec.json as check-jsonschema 0.39.0 ships it
#: (check_jsonschema/builtin_schemas/vendor/compose-spec.json, and its sha256/ file).
SCHEMA_SHA256 = "d549057ebc2925f39f62799eab0db7b9e2c18b35b6c00595199116da3ed10e64"
NGINX = (ROOT / "deploy" / "nginx.conf").read_text()


@pytest.fixture(scope="module")
def validator():
    if importlib.util.find_spec("jsonschema") is None:
        missing("jsonschema")
    import jsonschema

    schema = json.loads(SCHEMA.read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def errors(validator, document) -> list[str]:
    return sorted(f"{'/'.join(map(str, e.absolute_path))}: {e.message}"
                  for e in validator.iter_errors(document))


def test_the_vendored_schema_is_the_published_one():
    assert hashlib.sha256(SCHEMA.read_bytes()).hexdigest() == SCHEMA_SHA256
    assert (ROOT / "deploy" / "schema" / "LICENSE.compose-spec").is_file()


def test_compose_file_validates(validator, compose):
    assert errors(validator, compose) == []


def test_the_schema_would_catch_mistakes(validator, compose):
    broken = json.loads(json.dumps(compose))
    broken["services"]["nginx"]["portz"] = ["8000:8000"]  # a typo
    broken["services"]["nginx"]["depends_on"]["spacemesh"]["condition"] = "service_sleepy"
    found = errors(validator, broken)
    assert any("portz" in e for e in found) and any("sleepy" in e for e in found), found


def test_replicas_behind_nginx(compose):
    services = compose["services"]
    assert services["spacemesh"]["deploy"]["replicas"] >= 2
    assert services["spacemesh"]["build"]["target"] == "runtime"
    assert set(services["spacemesh"]["expose"]) == {"8000", "8001"}
    assert "ports" not in services["spacemesh"]  # reached through nginx only
    nginx = services["nginx"]
    assert nginx["depends_on"]["spacemesh"]["condition"] == "service_healthy"
    assert set(nginx["ports"]) == {"8000:8000", "8001:8001"}
    assert "./deploy/nginx.conf:/etc/nginx/nginx.conf:ro" in nginx["volumes"]


def test_nginx_balances_rest_and_grpc_over_http2():
    upstreams = dict(re.findall(r"upstream (\w+) \{(.*?)\}", NGINX, re.S))
    assert "server spacemesh:8000" in upstreams["spacemesh_rest"]
    assert "server spacemesh:8001" in upstreams["spacemesh_grpc"]
    assert "proxy_pass http://spacemesh_rest;" in NGINX
    assert "grpc_pass grpc://spacemesh_grpc;" in NGINX
    assert re.search(r"listen 8001 http2;", NGINX)
    assert "client_max_body_size 32m;" in NGINX


def test_prometheus_scrapes_every_replica(compose, yaml):
    prometheus = compose["services"]["prometheus"]
    assert "./deploy/prometheus.yml:/etc/prometheus/prometheus.yml:ro" in prometheus["volumes"]
    config = yaml.safe_load((ROOT / "deploy" / "prometheus.yml").read_text())
    jobs = {job["job_name"]: job for job in config["scrape_configs"]}
    for name in ("spacemesh", "spacemesh-gpu"):
        job = jobs[name]
        assert job["metrics_path"] == "/metrics"
        sd = job["dns_sd_configs"][0]
        assert sd["names"] == [name] and sd["port"] == 8000 and sd["type"] == "A"


def test_the_gpu_profile(compose):
    gpu = compose["services"]["spacemesh-gpu"]
    assert gpu["profiles"] == ["gpu"] and gpu["build"]["args"]["ONNXRUNTIME"] == "gpu"
    device = gpu["deploy"]["resources"]["reservations"]["devices"][0]
    assert device["driver"] == "nvidia" and "gpu" in device["capabilities"]
    assert all("profiles" not in s for n, s in compose["services"].items() if s is not gpu)
