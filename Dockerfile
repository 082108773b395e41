# syntax=docker/dockerfile:1
#
# SpaceMesh inference service: REST on :8000, gRPC on :8001, the shipped model inside.
#
#   docker build -t spacemesh .                                  # CPU (onnxruntime)
#   docker build -t spacemesh:gpu --build-arg ONNXRUNTIME=gpu .  # NVIDIA (onnxruntime-gpu)
#   docker run --rm -p 8000:8000 -p 8001:8001 spacemesh
#
# Two stages: `builder` makes a virtual environment with deploy/install.sh (the same
# script tests/deploy/test_deploy_runtime.py runs in a fresh venv); `runtime` copies
# only that environment and the model repository onto a clean Python image: no torch,
# no compilers, no setuptools, no pip cache, a non-root user. See docs/DEPLOY.md.

ARG PYTHON_VERSION=3.11

# ---------------------------------------------------------------------- builder
FROM python:${PYTHON_VERSION}-slim-bookworm AS builder
# cpu: onnxruntime; gpu: onnxruntime-gpu with the CUDA/cuDNN wheels
ARG ONNXRUNTIME=cpu
ENV PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PYTHONDONTWRITEBYTECODE=1
WORKDIR /src
# Dependencies first: this layer is rebuilt only when a requirements file changes.
COPY deploy/install.sh deploy/requirements-runtime.txt deploy/requirements-onnxruntime-${ONNXRUNTIME}.txt deploy/
RUN sh deploy/install.sh deps /opt/venv "${ONNXRUNTIME}"
COPY model/ model/
COPY service/ service/
RUN sh deploy/install.sh app /opt/venv

# ---------------------------------------------------------------------- runtime
FROM python:${PYTHON_VERSION}-slim-bookworm AS runtime
ARG ONNXRUNTIME=cpu
LABEL org.opencontainers.image.title="spacemesh" \
      org.opencontainers.image.description="SpaceMesh: point cloud in, oriented manifold polygon mesh out (REST :8000, gRPC :8001)" \
      org.opencontainers.image.licenses="Apache-2.0" \
      dev.spacemesh.onnxruntime="${ONNXRUNTIME}"
RUN groupadd --system --gid 10001 spacemesh \
    && useradd --system --uid 10001 --gid spacemesh --no-create-home \
       --home-dir /nonexistent --shell /usr/sbin/nologin spacemesh
COPY --from=builder /opt/venv /opt/venv
# The shipped model repository (Triton layout: name/version/files + manifest.json with
# the sha256 of every file, checked at start-up). Read-only for the service's user.
COPY models/ /opt/spacemesh/models/
COPY deploy/healthcheck.py /opt/spacemesh/healthcheck.py
# Every `spacemesh serve` flag has a SPACEMESH_* variable; override them with -e.
ENV PATH=/opt/venv/bin:$PATH \
    PYTHONUNBUFFERED=1 \
    PYTHONDONTWRITEBYTECODE=1 \
    SPACEMESH_MODEL=/opt/spacemesh/models/spacemesh-small \
    SPACEMESH_HOST=0.0.0.0 \
    SPACEMESH_PORT=8000 \
    SPACEMESH_GRPC_PORT=8001
USER 10001:10001
WORKDIR /tmp
EXPOSE 8000 8001
# Ready = model loaded and warm, not draining (GET /v2/health/ready answers 200).
HEALTHCHECK --interval=10s --timeout=5s --start-period=60s --retries=3 \
    CMD ["python", "/opt/spacemesh/healthcheck.py"]
# SIGTERM drains: readiness turns false, in-flight requests finish (SPACEMESH_DRAIN_TIMEOUT_S).
STOPSIGNAL SIGTERM
ENTRYPOINT ["spacemesh", "serve"]
