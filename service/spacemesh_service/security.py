"""Who may call the service, and how often: API keys, rate limits, client addresses.

Everything here is off by default and one setting away (``--api-keys FILE``,
``--rate-limit``, ``--trusted-proxies``), and shared by both servers: the REST app checks
requests in :class:`RestGuard` (ASGI middleware), the gRPC server in
:class:`spacemesh_service.grpc_guard.GrpcGuard` (a server interceptor); both ask one
:class:`Guard`, so the two transports answer the same problems (401 ``unauthorized``,
429 ``rate-limited``).

* **API keys**: one per line in a file, blank and ``#`` lines ignored. Only their SHA-256
  digests are kept; a presented key is hashed and compared with every digest by
  :func:`hmac.compare_digest` (constant time, and every digest is compared, so the time
  does not say which one matched). A key is known in logs by its *key id*, the first 12
  hex digits of its digest, never by the key.
* **Open paths**: the health routes (``/v2/health/live``, ``/v2/health/ready``), the web
  page (``/``) and its assets (``/static/...``) need no key, so that load balancers and
  browsers reach them; ``/metrics`` needs one unless ``--public-metrics``. Over gRPC,
  ``grpc.health.v1`` is open.
* **Rate limits**: a token bucket per key id (when keys are on) or per client address,
  ``rate_limit`` tokens a second up to ``rate_burst``; open paths are not counted.
* **Client address**: the peer's address, or, when the peer is one of
  ``--trusted-proxies``, the right-most ``X-Forwarded-For`` address that is not a trusted
  proxy (a client cannot forge its way past the proxy that appended the real address).
"""

from __future__ import annotations

import hashlib
import hmac
import ipaddress
import math
import threading
import time
from collections import OrderedDict
from collections.abc import Awaitable, Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from spacemesh_service import problems as P
from spacemesh_service.networks import ConfigError, Network, parse_networks
from spacemesh_service.problems import Problem, problem_response

#: Hex digits of a key's SHA-256 digest that name it in logs and rate limits.
KEY_ID_LENGTH = 12
#: REST paths open without a key (exact), and path prefixes open without a key.
OPEN_PATHS = frozenset({"/", "/v2/health/live", "/v2/health/ready", "/favicon.ico"})
OPEN_PREFIXES = ("/static/",)
#: gRPC methods open without a key.
OPEN_GRPC_PREFIXES = ("/grpc.health.v1.Health/",)
#: Most clients whose buckets are kept (the least recently seen are forgotten first).
MAX_BUCKETS = 10_000

# ---------------------------------------------------------------------- keys
def digest(key: str) -> bytes:
    """The SHA-256 digest of a key (UTF-8)."""
    return hashlib.sha256(key.encode("utf-8")).digest()


def key_id(key_digest: bytes) -> str:
    """How a key is named in logs: the first :data:`KEY_ID_LENGTH` hex digits of its
    digest."""
    return key_digest.hex()[:KEY_ID_LENGTH]


class KeyRing:
    """The accepted API keys, as SHA-256 digests.

    Parameters
    ----------
    keys : iterable of str
        The keys (at least one).

    Raises
    ------
    ConfigError
        No key.
    """

    def __init__(self, keys: Iterable[str]) -> None:
        self._digests = tuple(dict.fromkeys(digest(k) for k in keys))
        if not self._digests:
            raise ConfigError("no API key given")

    @classmethod
    def from_file(cls, path: Path | str) -> KeyRing:
        """Keys from a file: one a line, blank lines and ``#`` comments ignored.

        Raises
        ------
        ConfigError
            The file cannot be read, or holds no key (the message names the file).
        """
        try:
            text = Path(path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as error:
            raise ConfigError(f"cannot read the API key file {path}: "
                              f"{getattr(error, 'strerror', None) or error}") from None
        keys = [line.strip() for line in text.splitlines()]
        keys = [k for k in keys if k and not k.startswith("#")]
        if not keys:
            raise ConfigError(f"the API key file {path} has no key (one key a line; blank "
                              "and # lines are ignored)")
        return cls(keys)

    def __len__(self) -> int:
        return len(self._digests)

    def match(self, key: str) -> str | None:
        """The key id of ``key`` if it is one of the ring's, else None (constant time in
        the key and over the ring)."""
        presented = digest(key)
        found = None
        for known in self._digests:
            if hmac.compare_digest(presented, known):
                found = known
        return key_id(found) if found is not None else None


def bearer_token(authorization: str | None) -> str | None:
    """``Bearer KEY`` -> ``KEY`` (None when absent or another scheme)."""
    if not authorization:
        return None
    scheme, _, token = authorization.strip().partition(" ")
    token = token.strip()
    return token if scheme.lower() == "bearer" and token else None


# ---------------------------------------------------------------------- rate limits
class RateLimiter:
    """Token buckets by client: ``rate`` tokens a second, at most ``burst`` saved.

    Parameters
    ----------
    rate : float
        Requests a second each client may make in the long run (> 0).
    burst : int
        Requests a client may make at once (>= 1).
    max_clients : int
        Buckets kept; the least recently seen client is forgotten first (it then starts
        with a full bucket), so memory stays bounded whatever the number of clients.
    clock : callable
        Seconds (monotonic); tests may pass their own.
    """

    def __init__(self, rate: float, burst: int, *, max_clients: int = MAX_BUCKETS,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if rate <= 0 or burst < 1:
            raise ConfigError("a rate limit needs rate > 0 and burst >= 1")
        self.rate = rate
        self.burst = burst
        self.max_clients = max_clients
        self._clock = clock
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()
        self._lock = threading.Lock()  # the gRPC and REST servers share one loop; cheap

    def take(self, client: str) -> float:
        """Take a token for ``client``.

        Returns
        -------
        float
            0 when allowed; otherwise the seconds until a token is available.
        """
        now = self._clock()
        with self._lock:
            tokens, then = self._buckets.pop(client, (float(self.burst), now))
            tokens = min(float(self.burst), tokens + (now - then) * self.rate)
            wait = 0.0
            if tokens >= 1.0:
                tokens -= 1.0
            else:
                wait = (1.0 - tokens) / self.rate
            self._buckets[client] = (tokens, now)
            while len(self._buckets) > self.max_clients:
                self._buckets.popitem(last=False)
        return wait


# ---------------------------------------------------------------------- addresses
def _address(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        address = ipaddress.ip_address(text.strip().strip("[]"))
    except ValueError:
        return None
    mapped = getattr(address, "ipv4_mapped", None)
    return mapped or address


def client_address(peer: str | None, forwarded_for: str | None,
                   trusted: tuple[Network, ...]) -> str:
    """The address a request is counted under.

    Parameters
    ----------
    peer : str or None
        The connection's remote address.
    forwarded_for : str or None
        The ``X-Forwarded-For`` header (``client, proxy1, proxy2``).
    trusted : tuple of networks
        The trusted proxies; without one, the header is ignored.

    Returns
    -------
    str
        ``peer`` unless it is a trusted proxy and the header names an address: then the
        right-most address of the header that is not itself a trusted proxy.
    """
    peer = peer or "unknown"
    if not trusted or not forwarded_for:
        return peer
    peer_address = _address(peer)
    if peer_address is None or not any(peer_address in n for n in trusted):
        return peer
    hops = [h.strip() for h in forwarded_for.split(",") if h.strip()]
    for hop in reversed(hops):
        address = _address(hop)
        if address is None:
            return peer  # garbage from the client side: do not trust the rest
        if not any(address in n for n in trusted):
            return str(address)
    return str(_address(hops[0])) if hops else peer


def grpc_peer_address(peer: str | None) -> str | None:
    """``ipv4:127.0.0.1:5000`` / ``ipv6:[::1]:5000`` -> the address."""
    if not peer:
        return None
    kind, _, rest = peer.partition(":")
    if kind == "ipv6":
        return rest.rpartition(":")[0].strip("[]").replace("%5B", "").replace("%5D", "")
    if kind == "ipv4":
        return rest.rpartition(":")[0]
    return peer


# ---------------------------------------------------------------------- the guard
@dataclass(frozen=True)
class Caller:
    """Who made a request: its client address and key id (None without keys)."""

    address: str
    key: str | None = None

    @property
    def bucket(self) -> str:
        """What its rate limit is counted under: the key id, else the address."""
        return f"key:{self.key}" if self.key else f"addr:{self.address}"


class Guard:
    """The protection settings, applied to one request at a time (both transports).

    Parameters
    ----------
    keys : KeyRing, optional
        Without one, every request is let in.
    limiter : RateLimiter, optional
        Without one, no request is limited.
    trusted_proxies : tuple of networks
    public_metrics : bool
        ``/metrics`` open without a key.
    """

    def __init__(self, keys: KeyRing | None = None, limiter: RateLimiter | None = None,
                 trusted_proxies: tuple[Network, ...] = (), public_metrics: bool = False
                 ) -> None:
        self.keys = keys
        self.limiter = limiter
        self.trusted_proxies = trusted_proxies
        self.public_metrics = public_metrics

    @classmethod
    def from_settings(cls, settings: Any) -> Guard:
        """The guard of a :class:`~spacemesh_service.settings.Settings`.

        Raises
        ------
        ConfigError
            The key file is unreadable or empty, or a trusted proxy is not a CIDR.
        """
        keys = KeyRing.from_file(settings.api_keys) if settings.api_keys else None
        limiter = (RateLimiter(settings.rate_limit, settings.rate_burst)
                   if settings.rate_limit > 0 else None)
        return cls(keys, limiter, parse_networks(settings.trusted_proxies),
                   settings.public_metrics)

    @property
    def active(self) -> bool:
        """Whether anything is checked (keys or rate limits)."""
        return self.keys is not None or self.limiter is not None

    def is_open(self, path: str) -> bool:
        """Whether a REST path or gRPC method needs neither key nor token."""
        if path in OPEN_PATHS or path.startswith(OPEN_PREFIXES + OPEN_GRPC_PREFIXES):
            return True
        return self.public_metrics and path == "/metrics"

    def caller(self, peer: str | None, forwarded_for: str | None,
               authorization: str | None) -> Caller:
        """Who calls (the key id only when the key is right)."""
        address = client_address(peer, forwarded_for, self.trusted_proxies)
        token = bearer_token(authorization)
        key = self.keys.match(token) if self.keys is not None and token else None
        return Caller(address, key)

    def check(self, path: str, caller: Caller, authorization: str | None) -> None:
        """Let the request in, or raise its problem.

        Raises
        ------
        Problem
            ``unauthorized`` (401): keys are on and none, or a wrong one, was sent.
            ``rate-limited`` (429, with ``retry_after``): the caller's bucket is empty.
        """
        if self.is_open(path):
            return
        if self.keys is not None and caller.key is None:
            detail = ("this server needs an API key: send 'Authorization: Bearer KEY'"
                      if bearer_token(authorization) is None else "the API key is not valid")
            raise Problem(P.UNAUTHORIZED, detail)
        if self.limiter is not None:
            wait = self.limiter.take(caller.bucket)
            if wait > 0:
                seconds = max(1, math.ceil(wait))
                raise Problem(P.RATE_LIMITED, f"too many requests; retry in {seconds} s "
                              f"(at most {self.limiter.rate:g} a second, bursts of "
                              f"{self.limiter.burst})", retry_after=seconds)


#: The challenge of a 401 (RFC 6750), and the one for a key that was sent but is wrong.
WWW_AUTHENTICATE = 'Bearer realm="spacemesh"'
WWW_AUTHENTICATE_INVALID = 'Bearer realm="spacemesh", error="invalid_token"'


def asgi_header(scope: dict[str, Any], name: bytes) -> str | None:
    """Header ``name`` (lower case) of an ASGI scope, its lines joined by ``", "`` as
    RFC 9110 combines them (a proxy may add its own ``X-Forwarded-For`` line); None when
    absent."""
    values = [value.decode("latin-1") for key, value in scope.get("headers", ())
              if key == name]
    return ", ".join(values) if values else None


ASGIApp = Callable[[dict[str, Any], Callable, Callable], Awaitable[None]]
#: Renders a problem as an ASGI response: ``(problem, scope, send, extra_headers)``.
ProblemSender = Callable[[Problem, dict[str, Any], Callable, dict[str, str]], Awaitable[None]]


class RestGuard:
    """ASGI middleware: the :class:`Guard` in front of the REST app.

    It runs before the body is read, so refused requests cost no parsing. The caller is
    left in ``scope["state"]["caller"]`` for the access log.

    Parameters
    ----------
    app : ASGI app
    guard : Guard
    send_problem : callable
        Renders a problem as problem+json (the app's renderer).
    """

    def __init__(self, app: ASGIApp, guard: Guard, send_problem: ProblemSender) -> None:
        self.app = app
        self.guard = guard
        self.send_problem = send_problem

    async def __call__(self, scope: dict[str, Any], receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        client = scope.get("client")
        authorization = asgi_header(scope, b"authorization")
        caller = self.guard.caller(client[0] if client else None,
                                   asgi_header(scope, b"x-forwarded-for"), authorization)
        scope.setdefault("state", {})["caller"] = caller
        try:
            self.guard.check(scope["path"], caller, authorization)
        except Problem as problem:
            extra = {}
            if problem.kind is P.UNAUTHORIZED:
                extra["WWW-Authenticate"] = (WWW_AUTHENTICATE if bearer_token(authorization)
                                             is None else WWW_AUTHENTICATE_INVALID)
            await self.send_problem(problem, scope, send, extra)
            return
        await self.app(scope, receive, send)


# ---------------------------------------------------------------------- metadata
#: Suffixes of the files a path in a manifest names (checkpoints, data, configs).
_FILE_SUFFIXES = (".pt", ".pth", ".ckpt", ".onnx", ".npz", ".npy", ".json", ".yaml", ".yml",
                  ".toml", ".txt", ".csv", ".ply", ".obj", ".h5", ".safetensors", ".tar",
                  ".gz", ".zip", ".log")


def looks_like_path(text: str) -> bool:
    """Whether a string names a file or folder (``/abs/...``, ``runs/x/last.pt``,
    ``C:\\data``), as opposed to a media type (``model/gltf-binary``) or a URL."""
    if not text or any(c.isspace() for c in text) or "://" in text:
        return False
    if text.startswith(("/", "~", "./", "../", "\\\\")) or (
            len(text) > 2 and text[1] == ":" and text[2] in "/\\"):
        return True
    separators = text.count("/") + text.count("\\")
    return separators >= 2 or (separators == 1 and text.lower().endswith(_FILE_SUFFIXES))


def without_paths(value: Any) -> Any:
    """``value`` (JSON-like) without the strings that are file-system paths: members and
    items whose value is one are left out (the model metadata shows no server paths)."""
    if isinstance(value, dict):
        return {k: without_paths(v) for k, v in value.items()
                if not (isinstance(v, str) and looks_like_path(v))}
    if isinstance(value, list):
        return [without_paths(v) for v in value if not (isinstance(v, str) and looks_like_path(v))]
    return value


# ---------------------------------------------------------------------- OpenAPI
#: Name of the bearer scheme in the OpenAPI document.
SECURITY_SCHEME = "apiKey"


def document_protection(spec: dict[str, Any], guard: Guard) -> dict[str, Any]:
    """The OpenAPI document with what protection adds: 408 on routes that read a body;
    with keys, the bearer scheme on every route but the open ones and their 401; with
    rate limits, their 429.

    Parameters
    ----------
    spec : dict
        The OpenAPI document (changed in place).
    guard : Guard

    Returns
    -------
    dict
        ``spec``.
    """
    if guard.keys is not None:
        schemes = spec.setdefault("components", {}).setdefault("securitySchemes", {})
        schemes[SECURITY_SCHEME] = {
            "type": "http", "scheme": "bearer",
            "description": "An API key of the server's --api-keys file."}
    for path, operations in spec.get("paths", {}).items():
        for method, operation in operations.items():
            if not isinstance(operation, dict) or "responses" not in operation:
                continue
            responses = operation["responses"]
            if method in ("post", "put", "patch"):
                responses.setdefault("408", problem_response("The body arrived too slowly", {
                    "slow": (P.REQUEST_TIMEOUT, "the request body did not arrive within "
                             "60 s")}, instance=path))
            if guard.is_open(path):
                continue
            if guard.keys is not None:
                operation["security"] = [{SECURITY_SCHEME: []}]
                responses.setdefault("401", problem_response("No or a wrong API key", {
                    "missing": (P.UNAUTHORIZED, "this server needs an API key: send "
                                "'Authorization: Bearer KEY'")}, instance=path))
            if guard.limiter is not None:
                responses.setdefault("429", problem_response("Rate limit reached", {
                    "limited": (P.RATE_LIMITED, "too many requests; retry in 1 s")},
                    retry_after=True, instance=path))
    return spec
