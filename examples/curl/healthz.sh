#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /healthz: is the server up?
curl -sS --fail-with-body "$DRAPE/healthz"
echo
