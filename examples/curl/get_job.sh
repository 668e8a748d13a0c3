#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /jobs/{id}: a job's status, progress and stats. Usage: get_job.sh ID
curl -sS --fail-with-body "$DRAPE/jobs/$1"
echo
