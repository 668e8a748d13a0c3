#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /jobs/{id}/events: follow a job (progress events, then one end event). Usage: follow_events.sh ID
curl -sS -N --fail-with-body "$DRAPE/jobs/$1/events"
