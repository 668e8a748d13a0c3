#!/bin/sh
# See README.md ("Meshes from files"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /assets: every uploaded mesh, newest first.
curl -sS --fail-with-body "$DRAPE/assets"
echo
