#!/bin/sh
# See README.md ("Sweeps over HTTP"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /sweeps/{id}: the table as it stands, as JSON or CSV. Usage: get_sweep.sh ID [json|csv]
curl -sS --fail-with-body "$DRAPE/sweeps/$1?format=${2:-json}"
echo
