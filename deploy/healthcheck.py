"""The image's HEALTHCHECK: exit 0 when ``GET /v2/health/ready`` answers 200, else 1.

Standard library only (the runtime image has no curl). The port is ``$SPACEMESH_PORT``
(default 8000), the same variable ``spacemesh serve`` reads. With ``$SPACEMESH_TLS_CERT``
set the server speaks TLS: the check uses https to 127.0.0.1 without checking the
certificate (it names the public host, and the check never leaves the container).
"""

import os
import ssl
import sys
import urllib.error
import urllib.request

port = os.environ.get("SPACEMESH_PORT") or "8000"
context = None
if os.environ.get("SPACEMESH_TLS_CERT"):
    context = ssl.create_default_context()
    context.check_hostname = False
    context.verify_mode = ssl.CERT_NONE
url = f"{'https' if context else 'http'}://127.0.0.1:{port}/v2/health/ready"
try:
    with urllib.request.urlopen(url, timeout=float(os.environ.get("HEALTHCHECK_TIMEOUT", 4)),
                                context=context):
        sys.exit(0)
except (urllib.error.URLError, OSError) as error:
    print(f"not ready: {url}: {error}", file=sys.stderr)
    sys.exit(1)
