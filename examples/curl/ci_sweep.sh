#!/bin/sh
# See README.md ("Sweeps over HTTP"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# A CI step: submit a sweep, wait for every run, save the table as CSV and the plot, and fail
# unless every run succeeded. Usage: ci_sweep.sh [SWEEP.json] [OUT_DIR]
SWEEP="${1:-$(dirname "$0")/../sweeps/tiny.json}"
OUT="${2:-.}"
# On a refusal, curl fails and the problem body (which names each field at fault) goes to stderr.
ANSWER=$(curl -sS --fail-with-body -H 'Content-Type: application/json' --data-binary "@$SWEEP" "$DRAPE/sweeps") \
  || { printf '%s\n' "$ANSWER" >&2; exit 2; }
ID=$(printf '%s' "$ANSWER" | sed -n 's/.*"id":"\([0-9a-f]*\)".*/\1/p')
echo "sweep $ID"
TRIES=0
until curl -sS --fail-with-body "$DRAPE/sweeps/$ID" | grep -q '"complete":true'; do
  TRIES=$((TRIES + 1)); [ "$TRIES" -lt "${MAX_WAIT_S:-3600}" ] || { echo "sweep $ID not done"; exit 1; }
  sleep 1
done
curl -sS --fail-with-body -o "$OUT/sweep.csv" "$DRAPE/sweeps/$ID?format=csv"
curl -sS --fail-with-body -o "$OUT/plot.svg" "$DRAPE/sweeps/$ID/plot.svg"
# The CSV's status column: every row must say succeeded.
FAILED=$(tail -n +2 "$OUT/sweep.csv" | grep -vc ',succeeded,' || true)
echo "runs not succeeded: $FAILED"
[ "$FAILED" = 0 ]
