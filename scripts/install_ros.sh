#!/usr/bin/env bash
# Installs ROS 1 (Noetic-era) from Debian's own archive and lets the project's virtualenv import
# it: Debian's rospy & co. live in /usr/lib/python3/dist-packages, built for Python 3.11, and a
# .pth file appends that folder to the venv's sys.path (after the venv's own packages).
#   scripts/install_ros.sh [VENV]        (default VENV: .venv)
# Needs root (or sudo) for apt-get. Without either it says so and exits 0: the ROS tests then
# skip with that reason, and everything else runs.
set -euo pipefail
VENV=${1:-.venv}
PKGS="ros-core python3-rospy python3-rosbag python3-roslaunch python3-message-filters \
python3-std-msgs python3-sensor-msgs python3-geometry-msgs python3-trajectory-msgs \
python3-rosgraph-msgs python3-tf2-msgs python3-actionlib python3-actionlib-msgs python3-genpy"

if /usr/bin/python3 -c "import rospy, rosbag, message_filters, sensor_msgs.msg, trajectory_msgs.msg, tf2_msgs.msg, actionlib, actionlib_msgs.msg, genpy" 2>/dev/null \
   && command -v roslaunch >/dev/null && command -v roscore >/dev/null; then
  echo "ROS 1 already installed"
else
  if [ "$(id -u)" = 0 ]; then SUDO=""; elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then SUDO="sudo"; else
    echo "install_ros.sh: not root and no sudo: ROS 1 not installed; the ROS tests will skip" >&2
    exit 0
  fi
  echo "installing ROS 1 from Debian (apt-get)…"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends $PKGS >/dev/null
fi

if [ -d "$VENV" ]; then
  site=$("$VENV/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
  echo "/usr/lib/python3/dist-packages" > "$site/foldbot-ros-debian.pth"
  "$VENV/bin/python" -c "import rospy, rosbag" && echo "ROS 1 importable from $VENV"
fi
