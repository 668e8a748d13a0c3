#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# GET /jobs: recent jobs, newest first. Usage: list_jobs.sh [OFFSET] [LIMIT]
curl -sS --fail-with-body "$DRAPE/jobs?offset=${1:-0}&limit=${2:-20}"
echo
