#!/usr/bin/env bash
# The ROS 2 robot side's own virtualenv for DISTRO (jazzy or kilted), built once and cached:
#   scripts/ros2_env.sh jazzy     # prints the virtualenv's path
# It holds the pinned wheels of stock rclpy and the messages
# (robots/agent/ros2/requirements-DISTRO.txt), the robot side's own packages
# (robots/agent/requirements.txt: no Django) and the small interface packages of
# robots/agent/ros2/interfaces (Nav2's NavigateToPose and LoadMap, tf2's TFMessage), built
# with the rosidl generators, Debian's cmake and g++. The wheels install a bootstrapper
# that re-launches every Python process started in their virtualenv: never install them
# into the server's .venv. The cache is $CLOUDNAV_CACHE (default ~/.cache/cloudnav)/
# ros2-DISTRO-HASH, HASH of the pins, the interface sources and this script; a build that
# fails exits non-zero and leaves nothing that looks finished.
set -euo pipefail
cd "$(dirname "$0")/.."

DISTRO=${1:?usage: scripts/ros2_env.sh jazzy|kilted}
PINS=robots/agent/ros2/requirements-$DISTRO.txt
[ -f "$PINS" ] || { echo "ros2_env: no $PINS" >&2; exit 2; }
PYTHON=${PYTHON:-python3}
CACHE=${CLOUDNAV_CACHE:-$HOME/.cache/cloudnav}

HASH=$(cat "$0" "$PINS" robots/agent/requirements.txt \
  $(find robots/agent/ros2/interfaces -type f | LC_ALL=C sort) | sha256sum | cut -c1-12)
VENV=$CACHE/ros2-$DISTRO-$HASH
DONE=$VENV/.cloudnav-complete

build_interfaces() {
  local site include numpy_include package build
  site=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
  include=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  numpy_include=$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')
  # The wheels' exported CMake files name their build machine's Python: point them here.
  { grep -rlZ /opt/python/ --include='*.cmake' "$VENV/share" || true; } | xargs -0 -r sed -i \
    -e "s#/opt/python/cp[0-9]*-cp[0-9]*/lib/python[0-9.]*/site-packages/numpy/_core/include#$numpy_include#g" \
    -e "s#/opt/python/cp[0-9]*-cp[0-9]*/include/python[0-9.]*#$include#g"
  local libs
  libs=$(find "$site" -maxdepth 1 -name 'ros_*.libs' -type d | tr '\n' ':')
  mkdir -p "$VENV/build"
  for package in tf2_msgs nav2_msgs; do
    build=$VENV/build/$package
    echo "ros2_env: building $package for $DISTRO" >&2
    AMENT_PREFIX_PATH=$VENV CMAKE_PREFIX_PATH=$VENV LD_LIBRARY_PATH=$VENV/lib:$libs \
      PATH=$VENV/bin:$PATH \
      cmake -S "robots/agent/ros2/interfaces/$package" -B "$build" \
        -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$VENV" -DBUILD_TESTING=OFF \
        -DPython3_EXECUTABLE="$VENV/bin/python" -DPYTHON_EXECUTABLE="$VENV/bin/python" \
        -DPython3_FIND_VIRTUALENV=ONLY \
        -DCMAKE_INSTALL_RPATH="$VENV/lib:${libs%:}" -DCMAKE_BUILD_WITH_INSTALL_RPATH=ON \
        >"$build.log" 2>&1 \
      && LD_LIBRARY_PATH=$VENV/lib:$libs PATH=$VENV/bin:$PATH \
        cmake --build "$build" -j "$(nproc)" >>"$build.log" 2>&1 \
      && cmake --install "$build" >>"$build.log" 2>&1 \
      || { tail -n 40 "$build.log" >&2; echo "ros2_env: $package failed ($build.log)" >&2; return 1; }
  done
}

check() {
  "$VENV/bin/python" -c '
import rclpy, numpy, cv2, httpx, websockets
from nav2_msgs.action import NavigateToPose
from nav2_msgs.srv import LoadMap
from tf2_msgs.msg import TFMessage
NavigateToPose.Result(error_code=0, error_msg="")
' >&2
}

build() {
  rm -rf "$VENV"
  mkdir -p "$CACHE"
  "$PYTHON" -m venv "$VENV"
  echo "ros2_env: installing $PINS into $VENV" >&2
  "$VENV/bin/pip" install -q --disable-pip-version-check -r "$PINS" \
    -r robots/agent/requirements.txt >&2
  build_interfaces
  check
  touch "$DONE"
}

mkdir -p "$CACHE"
exec 9>"$CACHE/ros2-$DISTRO.lock"
flock 9  # one build at a time; a second caller finds the first's result
[ -f "$DONE" ] || build
echo "$VENV"
