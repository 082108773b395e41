"""The image's HEALTHCHECK: exit 0 when ``GET /v2/health/ready`` answers 200, else 1.

Standard library only (the runtime image has no curl). The port is ``$SPACEMESH_PORT``
(default 8000), the same variable ``spacemesh serve`` reads.
"""

import os
import sys
import urllib.error
import urllib.request

port = os.environ.get("SPACEMESH_PORT") or "8000"
url = f"http://127.0.0.1:{port}/v2/health/ready"
try:
    with urllib.request.urlopen(url, timeout=float(os.environ.get("HEALTHCHECK_TIMEOUT", 4))):
        sys.exit(0)
except (urllib.error.URLError, OSError) as error:
    print(f"not ready: {url}: {error}", file=sys.stderr)
    sys.exit(1)
