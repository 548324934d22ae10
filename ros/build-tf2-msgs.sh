#!/bin/sh
# Build tf2_msgs/TFMessage into a virtual environment that has the ROS 2 wheels from PyPI
# (the [ros] and [ros-build] extras), where no tf2_msgs exists: tf2_msgs is not on PyPI.
# docs/ros.md explains the route. Usage: ros/build-tf2-msgs.sh VENV
# Does nothing when tf2_msgs can already be imported (a sourced ROS 2, or an earlier build).
set -eu
VENV=$(cd "$1" && pwd)
HERE=$(cd "$(dirname "$0")" && pwd)
PY="$VENV/bin/python"
if "$PY" -c "from tf2_msgs.msg import TFMessage; TFMessage.__class__.__import_type_support__(); assert TFMessage.__class__._TYPE_SUPPORT" 2>/dev/null; then
    exit 0
fi
mkdir -p "$VENV/.build"
BUILD="$VENV/.build/tf2_msgs"
rm -rf "$BUILD"
# The generators find their type supports through the ament index of the venv.
export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
cmake -S "$HERE/tf2_msgs" -B "$BUILD" -DCMAKE_PREFIX_PATH="$VENV" -DCMAKE_INSTALL_PREFIX="$VENV" \
    -DPython3_EXECUTABLE="$PY" -DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release \
    > "$BUILD.log" 2>&1 || { cat "$BUILD.log"; exit 1; }
cmake --build "$BUILD" -j2 --target install >> "$BUILD.log" 2>&1 || { tail -50 "$BUILD.log"; exit 1; }
rm -rf "$BUILD"
"$PY" -c "from tf2_msgs.msg import TFMessage; TFMessage.__class__.__import_type_support__(); assert TFMessage.__class__._TYPE_SUPPORT" \
    || { echo "tf2_msgs built but cannot be imported; see $BUILD.log" >&2; exit 1; }
echo "built tf2_msgs/TFMessage into $VENV"
