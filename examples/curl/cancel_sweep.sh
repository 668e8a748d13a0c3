#!/bin/sh
# See README.md ("Sweeps over HTTP"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# DELETE /sweeps/{id}: cancel every job of a sweep. Usage: cancel_sweep.sh ID
curl -sS --fail-with-body -X DELETE "$DRAPE/sweeps/$1"
echo
