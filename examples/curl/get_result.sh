#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /jobs/{id}/result: the result of an ended job (gzip if large). Usage: get_result.sh ID [FILE]
curl -sS --fail-with-body --compressed -o "${2:-/dev/stdout}" "$DRAPE/jobs/$1/result"
