#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /metrics: Prometheus metrics (drape_*).
curl -sS --fail-with-body "$DRAPE/metrics"
