#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# POST /jobs: queue a scene and print the job (its id, status and links).
# Usage: submit_job.sh [SCENE.json] [IDEMPOTENCY-KEY]
SCENE="${1:-$(dirname "$0")/../hanging_cloth.json}"
if [ -n "${2:-}" ]; then
  curl -sS --fail-with-body -H 'Content-Type: application/json' -H "Idempotency-Key: $2" \
    --data-binary "@$SCENE" "$DRAPE/jobs"
else
  curl -sS --fail-with-body -H 'Content-Type: application/json' --data-binary "@$SCENE" "$DRAPE/jobs"
fi
echo
