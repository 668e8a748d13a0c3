#!/bin/sh
# See README.md ("Meshes from files"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# DELETE /assets/{id}: delete an uploaded mesh (jobs already accepted with it still run).
# Usage: delete_asset.sh ID
curl -sS --fail-with-body -X DELETE "$DRAPE/assets/$1"
