#!/usr/bin/env bash
# Set up everything CloudNav needs on a fresh Debian machine; quick when already done.
#   Debian packages (chromium, redis-server, nginx, postgresql, ROS 1, cmake and g++ for the ROS 2
#   interface packages) with apt-get where absent,
#   the Python virtualenv from requirements.txt, Node packages from package-lock.json,
#   and the database schema.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
VENV=.venv

as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
    echo "setup: need root to run: $*" >&2; return 1; fi
}

apt_packages() {
  local missing=()
  command -v chromium >/dev/null || missing+=(chromium)
  command -v redis-server >/dev/null || missing+=(redis-server)
  # The scaled demo's front (make demo-scaled), run as the user with its own config.
  [ -x /usr/sbin/nginx ] || command -v nginx >/dev/null || missing+=(nginx)
  ls /usr/lib/postgresql/*/bin/postgres >/dev/null 2>&1 || missing+=(postgresql)
  command -v node >/dev/null || missing+=(nodejs npm)
  "$PYTHON" -c "import venv, ensurepip" 2>/dev/null || missing+=(python3-venv)
  # ROS 1 (Debian's own packages) for the agent's ROS backend and its tests.
  command -v roscore >/dev/null || missing+=(ros-core)
  local ros
  for ros in rospy actionlib tf2-ros rostopic move-base-msgs nav-msgs sensor-msgs \
    geometry-msgs map-msgs; do
    dpkg -s "python3-$ros" >/dev/null 2>&1 || missing+=("python3-$ros")
  done
  # The ROS 2 robot side's interface packages (scripts/ros2_env.sh) build with these.
  command -v cmake >/dev/null || missing+=(cmake)
  dpkg -s build-essential >/dev/null 2>&1 || missing+=(build-essential)
  # Open3D (bench visual-slam's peer) loads libusb at import
  dpkg -s libusb-1.0-0 >/dev/null 2>&1 || missing+=(libusb-1.0-0)
  "$PYTHON" -c 'import os, sysconfig; assert os.path.exists(sysconfig.get_paths()["include"] + "/Python.h")' \
    2>/dev/null || missing+=(python3-dev)
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing Debian packages: ${missing[*]}"
    as_root apt-get update -q
    DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -q --no-install-recommends "${missing[@]}"
  fi
}

python_packages() {
  [ -x "$VENV/bin/python" ] || "$PYTHON" -m venv "$VENV"
  local stamp="$VENV/.requirements.sha256"
  local want
  want=$(sha256sum requirements.txt | cut -d' ' -f1)
  if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    echo "setup: installing Python packages from requirements.txt"
    "$VENV/bin/pip" install -q --disable-pip-version-check -r requirements.txt
    echo "$want" > "$stamp"
  fi
}

node_packages() {
  [ -f package-lock.json ] || return 0
  local stamp=node_modules/.package-lock.sha256
  local want
  want=$(sha256sum package-lock.json | cut -d' ' -f1)
  if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    echo "setup: installing Node packages from package-lock.json"
    npm ci --no-audit --no-fund --loglevel=error
    echo "$want" > "$stamp"
  fi
}

apt_packages
python_packages
node_packages
bash scripts/build_static.sh
"$VENV/bin/python" manage.py migrate --noinput -v 0
