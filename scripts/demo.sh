#!/usr/bin/env bash
# Seed the demo building and run the server on 127.0.0.1:8000 with simulated robots.
# Variables (README, "Two commands"): HOST, PORT, ROBOTS, PEOPLE, PEOPLE_SEED, CLOUDNAV_PUBLIC_URL,
# CLOUDNAV_DEMO_PASSWORD, and the settings' own (DATABASE_URL, REDIS_URL, ...).
# Ctrl-C stops everything.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=.venv/bin/python
HOST=${HOST:-127.0.0.1}
PORT=${PORT:-8000}
ROBOTS=${ROBOTS:-3}
PEOPLE=${PEOPLE:-0}
PEOPLE_SEED=${PEOPLE_SEED:-0}
export CLOUDNAV_PUBLIC_URL=${CLOUDNAV_PUBLIC_URL:-http://$HOST:$PORT}
# The demo may run with the public default SECRET_KEY; nothing else may (README, Production).
export CLOUDNAV_DEMO=1

$PY manage.py seed_demo --robots "$ROBOTS"

pids=()
cleanup() { kill "${pids[@]}" 2>/dev/null || true; wait 2>/dev/null || true; }
trap cleanup EXIT INT TERM

.venv/bin/daphne --websocket_timeout -1 -b "$HOST" -p "$PORT" cloudnav_web.asgi:application &
pids+=($!)

for _ in $(seq 1 100); do
  (exec 3<>"/dev/tcp/$HOST/$PORT") 2>/dev/null && break
  sleep 0.1
done

if [ -f robots/agent/__main__.py ]; then
  $PY -m robots.agent --server "$CLOUDNAV_PUBLIC_URL" --tokens-file var/demo_tokens.json \
    --count "$ROBOTS" --people "$PEOPLE" --people-seed "$PEOPLE_SEED" &
  pids+=($!)
fi

echo "CloudNav is running at $CLOUDNAV_PUBLIC_URL (sign in as admin / ${CLOUDNAV_DEMO_PASSWORD:-admin-demo}, or the password you gave admin since). Ctrl-C stops it."
wait -n "${pids[@]}"
