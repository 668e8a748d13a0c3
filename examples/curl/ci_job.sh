#!/bin/sh
# See README.md ("Using the service"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# A CI step: submit a scene as a job, wait for it, save the result, and fail unless it succeeded.
# Usage: ci_job.sh SCENE.json RESULT.json
SCENE="${1:-$(dirname "$0")/../hanging_cloth.json}"
OUT="${2:-result.json}"
KEY="ci-${CI_JOB_ID:-$$}-$(basename "$SCENE")"
# On a refusal, curl fails and the problem body (which names each field at fault) goes to stderr.
JOB=$(curl -sS --fail-with-body -H 'Content-Type: application/json' -H "Idempotency-Key: $KEY" \
  --data-binary "@$SCENE" "$DRAPE/jobs") || { printf '%s\n' "$JOB" >&2; exit 2; }
ID=$(printf '%s' "$JOB" | sed -n 's/.*"id":"\([0-9a-f]*\)".*/\1/p')
echo "job $ID"
# The event stream ends with one end event; its data is the job.
END=$(curl -sS -N --fail-with-body "$DRAPE/jobs/$ID/events" | sed -n '/^event: end/{n;s/^data: //p;}')
STATUS=$(printf '%s' "$END" | sed -n 's/.*"status":"\([a-z]*\)".*/\1/p')
echo "status $STATUS"
curl -sS --fail-with-body --compressed -o "$OUT" "$DRAPE/jobs/$ID/result" || true
[ "$STATUS" = succeeded ]
