#!/usr/bin/env bash
# Make sure a Redis and a PostgreSQL answer on 127.0.0.1 for the scaled-mode tests:
# use the ones the machine runs, else start Debian's (installed by setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."

answers() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }

wait_for() {
  local port=$1 name=$2
  for _ in $(seq 1 100); do answers "$port" && return 0; sleep 0.1; done
  echo "services: $name did not start on port $port" >&2; return 1
}

start_redis() {
  answers 6379 && return 0
  echo "services: starting redis-server on 127.0.0.1:6379"
  mkdir -p var
  redis-server --daemonize yes --bind 127.0.0.1 --port 6379 --save "" --appendonly no \
    --dir "$PWD/var" --logfile "$PWD/var/redis.log"
  wait_for 6379 redis
}

start_postgres() {
  answers 5432 && return 0
  if command -v pg_ctlcluster >/dev/null && [ -n "$(ls /etc/postgresql 2>/dev/null)" ]; then
    local version
    version=$(ls /etc/postgresql | sort -V | tail -n 1)
    echo "services: starting PostgreSQL $version (cluster main)"
    pg_ctlcluster --skip-systemctl-redirect "$version" main start || true
  fi
  answers 5432 || start_private_postgres
  wait_for 5432 postgresql
}

# A throwaway cluster with trust auth, when the machine has no cluster of its own.
start_private_postgres() {
  local bin data=/tmp/cloudnav-pgdata
  bin=$(dirname "$(ls /usr/lib/postgresql/*/bin/postgres | sort -V | tail -n 1)")
  echo "services: starting a private PostgreSQL in $data"
  local run=()
  [ "$(id -u)" = 0 ] && run=(runuser -u postgres --)
  if [ ! -f "$data/PG_VERSION" ]; then
    mkdir -p "$data" && chown "$( [ "$(id -u)" = 0 ] && echo postgres || id -un)" "$data"
    "${run[@]}" "$bin/initdb" -D "$data" -U postgres --auth=trust >/dev/null
  fi
  "${run[@]}" "$bin/pg_ctl" -D "$data" -l "$data/server.log" -o "-h 127.0.0.1 -p 5432 -k /tmp" start >/dev/null
}

# Debian's own cluster asks for a password over TCP: give the postgres role the one tests use.
ensure_postgres_login() {
  PGPASSWORD=postgres psql -h 127.0.0.1 -U postgres -d postgres -tAc "select 1" >/dev/null 2>&1 && return 0
  echo "services: setting the postgres role's password for TCP logins"
  local run=()
  [ "$(id -u)" = 0 ] && run=(runuser -u postgres --)
  "${run[@]}" psql -d postgres -c "ALTER ROLE postgres PASSWORD 'postgres'" >/dev/null
}

start_redis
start_postgres
ensure_postgres_login
