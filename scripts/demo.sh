#!/usr/bin/env bash
# Seed the demo building and run the server on 127.0.0.1:8000 with simulated robots.
# Variables (README, "Two commands"): HOST, PORT, ROBOTS, PEOPLE, PEOPLE_SEED, CLOUDNAV_PUBLIC_URL,
# CLOUDNAV_DEMO_PASSWORD, and the settings' own (DATABASE_URL, REDIS_URL, ...).
# PROCESSES=N (N > 1, `make demo-scaled`): N daphne processes on PORT+1..PORT+N behind nginx
# on PORT, sharing Redis and PostgreSQL (started where none answers; README, "A real front").
# Ctrl-C stops everything.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=.venv/bin/python
HOST=${HOST:-127.0.0.1}
PORT=${PORT:-8000}
ROBOTS=${ROBOTS:-3}
PEOPLE=${PEOPLE:-0}
PEOPLE_SEED=${PEOPLE_SEED:-0}
PROCESSES=${PROCESSES:-1}
export CLOUDNAV_PUBLIC_URL=${CLOUDNAV_PUBLIC_URL:-http://$HOST:$PORT}
# The demo may run with the public default SECRET_KEY; nothing else may (README, Production).
export CLOUDNAV_DEMO=1

pids=()
cleanup() { kill "${pids[@]}" 2>/dev/null || true; wait 2>/dev/null || true; }
trap cleanup EXIT INT TERM

wait_for() {
  for _ in $(seq 1 900); do
    (exec 3<>"/dev/tcp/$1/$2") 2>/dev/null && return 0
    sleep 0.1
  done
  echo "demo: nothing answers on $1:$2" >&2
  return 1
}

daphne() {
  .venv/bin/daphne --websocket_timeout -1 "$@" cloudnav_web.asgi:application &
  pids+=($!)
}

# The scaled mode's shared parts: Redis, and a PostgreSQL database made once and migrated.
shared_services() {
  export REDIS_URL=${REDIS_URL:-redis://127.0.0.1:6379/0}
  export DATABASE_URL=${DATABASE_URL:-postgres://postgres:postgres@127.0.0.1:5432/cloudnav_demo}
  bash scripts/services.sh
  local name=${DATABASE_URL##*/} admin=${DATABASE_URL%/*}/postgres
  psql "$admin" -tAc "SELECT 1 FROM pg_database WHERE datname = '$name'" | grep -q 1 \
    || psql "$admin" -qc "CREATE DATABASE \"$name\""
  $PY manage.py migrate --noinput -v 0
}

# N daphne processes on loopback, and nginx on HOST:PORT in front of them (var/nginx).
scaled_servers() {
  local upstreams=() nginx
  nginx=$(command -v nginx || echo /usr/sbin/nginx)
  for i in $(seq 1 "$PROCESSES"); do
    # --proxy-headers: sign-in limits count the client's address, not nginx's.
    daphne --proxy-headers -b 127.0.0.1 -p $((PORT + i))
    upstreams+=("127.0.0.1:$((PORT + i))")
  done
  for upstream in "${upstreams[@]}"; do wait_for 127.0.0.1 "${upstream#*:}"; done
  $PY -m cloudnav_web.front --listen "$HOST:$PORT" --dir var/nginx "${upstreams[@]}" >/dev/null
  "$nginx" -p "$PWD/var/nginx" -c "$PWD/var/nginx/nginx.conf" &
  pids+=($!)
}

if [ "$PROCESSES" -gt 1 ]; then shared_services; fi
$PY manage.py seed_demo --robots "$ROBOTS"

if [ "$PROCESSES" -gt 1 ]; then scaled_servers; else daphne -b "$HOST" -p "$PORT"; fi
wait_for "$HOST" "$PORT"

# Through the front, nginx gives each robot's WebSocket to the process holding the fewest.
if [ -f robots/agent/__main__.py ]; then
  $PY -m robots.agent --server "$CLOUDNAV_PUBLIC_URL" --tokens-file var/demo_tokens.json \
    --count "$ROBOTS" --people "$PEOPLE" --people-seed "$PEOPLE_SEED" &
  pids+=($!)
fi

echo "CloudNav is running at $CLOUDNAV_PUBLIC_URL ($PROCESSES server process(es)); sign in as admin / ${CLOUDNAV_DEMO_PASSWORD:-admin-demo}, or the password you gave admin since. Ctrl-C stops it."
wait -n "${pids[@]}"
