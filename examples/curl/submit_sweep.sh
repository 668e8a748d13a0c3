#!/bin/sh
# See README.md ("Sweeps over HTTP"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# POST /sweeps: queue every variant of a sweep as jobs. Usage: submit_sweep.sh [SWEEP.json]
SWEEP="${1:-$(dirname "$0")/../sweeps/tiny.json}"
curl -sS --fail-with-body -H 'Content-Type: application/json' --data-binary "@$SWEEP" "$DRAPE/sweeps"
echo
