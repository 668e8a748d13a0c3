#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# POST /simulate: run a small scene and print its JSON result.
SCENE="${1:-$(dirname "$0")/../hanging_cloth.json}"
curl -sS --fail-with-body -H 'Content-Type: application/json' --data-binary "@$SCENE" "$DRAPE/simulate"
echo
