#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /openapi.json: the API description.
curl -sS --fail-with-body "$DRAPE/openapi.json"
echo
