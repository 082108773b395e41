"""Python SDK for the SpaceMesh service: point cloud in, oriented manifold polygon mesh out.

>>> from spacemesh_client import Client
>>> with Client("http://localhost:8000") as client:  # doctest: +SKIP
...     mesh = client.generate("points.ply", seed=7)
...     mesh.save("mesh.glb")

- :class:`Client`, :class:`AsyncClient`: ``generate``, ``repair``, ``health``,
  ``model_info``, over REST (``http://``) or gRPC (``grpc://``).
- :class:`Mesh`: vertices, polygon faces, statistics, ``save``, ``to_trimesh``.
- :mod:`spacemesh_client.errors`: one exception per problem type of the service.
- :class:`RetryPolicy`: retries on connection errors, 503 and 429 (``Retry-After``).

Depends on httpx and numpy; trimesh and grpcio are optional extras.
"""

from spacemesh_client._http import Health
from spacemesh_client.client import DEFAULT_FORMAT, DEFAULT_URL, AsyncClient, Client
from spacemesh_client.errors import (
    ClientTimeout,
    ConnectionFailed,
    InvalidRequest,
    NoSurface,
    ServerError,
    SpaceMeshError,
    Unavailable,
)
from spacemesh_client.mesh import Mesh, MeshStats
from spacemesh_client.retry import RetryPolicy

try:
    from importlib.metadata import version

    __version__ = version("spacemesh-client")
except Exception:  # pragma: no cover - running from a source tree
    __version__ = "0.0.0"

__all__ = [
    "DEFAULT_FORMAT",
    "DEFAULT_URL",
    "AsyncClient",
    "Client",
    "ClientTimeout",
    "ConnectionFailed",
    "Health",
    "InvalidRequest",
    "Mesh",
    "MeshStats",
    "NoSurface",
    "RetryPolicy",
    "ServerError",
    "SpaceMeshError",
    "Unavailable",
    "__version__",
]
