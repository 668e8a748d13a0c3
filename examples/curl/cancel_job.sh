#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# DELETE /jobs/{id}: cancel a job. Usage: cancel_job.sh ID
curl -sS --fail-with-body -X DELETE "$DRAPE/jobs/$1"
echo
