#!/usr/bin/env bash
# The secrets of deploy/compose.protected.yml, in deploy/secrets/ (git-ignored):
#   api-keys     one API key per line (a client key, and the metrics key)
#   client-key   the client key alone:  export SPACEMESH_API_KEY=$(cat deploy/secrets/client-key)
#   metrics-key  Prometheus's key (also in api-keys)
#   tls.crt/.key a self-signed certificate for `spacemesh` (how nginx and Prometheus reach
#                the replicas), localhost and the host names given as arguments
#
#   bash deploy/make-secrets.sh mesh.example.com
#
# With a certificate of your own CA instead, put it in tls.crt/tls.key (it must also name
# `spacemesh`). Owners: the replicas run as uid 10001, Prometheus as 65534 (nobody); nginx
# reads as root. Needs openssl; run with sudo to set the owners.
set -euo pipefail
cd "$(dirname "$0")"
mkdir -p secrets
umask 077
names="DNS:spacemesh,DNS:localhost,IP:127.0.0.1"
for host in "$@"; do names="$names,DNS:$host"; done
openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 365 \
    -subj "/CN=spacemesh" -addext "subjectAltName=$names" \
    -keyout secrets/tls.key -out secrets/tls.crt 2>/dev/null
openssl rand -hex 32 > secrets/client-key
openssl rand -hex 32 > secrets/metrics-key
{ echo "# SpaceMesh API keys (deploy/make-secrets.sh, $(date -u +%F))"
  cat secrets/client-key secrets/metrics-key; } > secrets/api-keys
chmod 0444 secrets/tls.crt
chmod 0400 secrets/tls.key secrets/api-keys secrets/metrics-key secrets/client-key
if [ "$(id -u)" = 0 ]; then
    chown 10001 secrets/tls.key secrets/api-keys
    chown 65534 secrets/metrics-key
else
    echo "note: not root; give uid 10001 read access to secrets/tls.key and secrets/api-keys," \
         "and uid 65534 to secrets/metrics-key (sudo chown), or run this with sudo" >&2
fi
echo "deploy/secrets: api-keys, client-key, metrics-key, tls.crt, tls.key"
