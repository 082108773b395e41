"""API keys and TLS for both transports.

* ``api_key`` (default ``$SPACEMESH_API_KEY``) is sent as ``Authorization: Bearer KEY``
  (REST header, gRPC metadata ``authorization``), unless the caller's own headers already
  carry an authorization.
* ``verify`` says how the server's certificate is checked on ``https://`` and
  ``grpcs://`` URLs: True (the system's CAs), a path to a PEM file of CA certificates
  (e.g. a self-signed server certificate; used by REST and gRPC alike), or False (REST
  only: no check).
"""

from __future__ import annotations

import os
import ssl
from collections.abc import Mapping
from pathlib import Path

#: Where the client takes its API key from unless given one.
API_KEY_ENV = "SPACEMESH_API_KEY"

Verify = bool | str | Path


def auth_headers(headers: Mapping[str, str] | None, api_key: str | None) -> dict[str, str]:
    """``headers`` with ``Authorization: Bearer KEY`` added.

    Parameters
    ----------
    headers : mapping, optional
        The caller's headers; an ``Authorization`` among them wins.
    api_key : str, optional
        Default ``$SPACEMESH_API_KEY``; no header without either, or with ``""``.

    Raises
    ------
    ValueError
        A key with spaces or line breaks inside (it could not be sent as one header).
    """
    out = dict(headers or {})
    key = (api_key if api_key is not None else os.environ.get(API_KEY_ENV) or "").strip()
    if not key or any(k.lower() == "authorization" for k in out):
        return out
    if any(c.isspace() for c in key):
        raise ValueError("an API key cannot contain spaces or line breaks")
    out["Authorization"] = f"Bearer {key}"
    return out


def _check(verify: Verify) -> None:
    if not isinstance(verify, (bool, str, Path)):
        raise TypeError(f"verify must be True, False or a CA file path, not {verify!r}")


def http_verify(verify: Verify) -> bool | ssl.SSLContext:
    """httpx's ``verify``: True/False, or an SSL context trusting the CA file."""
    _check(verify)
    if isinstance(verify, bool):
        return verify
    return ssl.create_default_context(cafile=str(verify))


def grpc_root_certificates(verify: Verify) -> bytes | None:
    """``root_certificates`` of ``grpc.ssl_channel_credentials`` (None: the defaults).

    Raises
    ------
    ValueError
        ``verify=False``: gRPC always checks the server's certificate.
    """
    _check(verify)
    if verify is False:
        raise ValueError("gRPC cannot skip the certificate check: pass verify=PATH of the "
                         "server's CA certificate instead of verify=False")
    return None if verify is True else Path(verify).read_bytes()
