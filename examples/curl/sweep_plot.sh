#!/bin/sh
# See README.md ("Sweeps over HTTP"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /sweeps/{id}/plot.svg: error against wall time, log-log. Usage: sweep_plot.sh ID [OUT.svg]
curl -sS --fail-with-body -o "${2:-plot.svg}" "$DRAPE/sweeps/$1/plot.svg"
