#!/usr/bin/env bash
# Installs every Debian package that building, testing and running stereo_ground_dem needs.
# Debian bookworm ships ROS 1 (Noetic-era) under /usr; on Ubuntu + ROS Noetic use
# `rosdep install --from-paths . --ignore-src -y` instead (package.xml lists the same dependencies).
set -euo pipefail
PKGS=(
  build-essential cmake pkg-config
  catkin ros-core-dev libroscpp-dev libnodeletlib-dev libnodelet-dev libnodeletlib-tools
  libimage-transport-dev image-transport-tools libcv-bridge-dev libtf2-ros-dev libtf2-dev
  libtf2-geometry-msgs-dev libmessage-filters-dev ros-message-generation ros-message-runtime
  ros-std-msgs ros-sensor-msgs ros-geometry-msgs ros-nav-msgs ros-visualization-msgs
  librostest-dev python3-rostest python3-roslaunch python3-rosnode python3-rostopic
  python3-rosservice python3-rosbag librosbag-dev python3-dynamic-reconfigure
  libdynamic-reconfigure-config-init-mutex-dev pluginlib-dev libdiagnostic-updater-dev
  libopencv-dev libeigen3-dev libgdal-dev libgtest-dev libgmock-dev libbenchmark-dev
  python3-numpy python3-opencv python3-yaml
  # ROS layer: headers of the remaining message packages, the Python side of the rostests, the
  # live-camera launch file (stereo_image_proc) and the viewer
  libstd-srvs-dev libdiagnostic-msgs-dev libtf2-msgs-dev libtf2-eigen-dev python3-tf2-ros
  python3-std-srvs python3-genmsg python3-diagnostic-msgs python3-nav-msgs python3-roslib
  ros-stereo-image-proc libtbb-dev rviz
  # stereo_image_proc's and image_proc's package.xml, launch files and nodelet plugin lists (the
  # ros-* packages hold only the executables: without these the live-camera launch file fails
  # with "Resource not found: stereo_image_proc")
  libstereo-image-proc-dev ros-image-proc libimage-proc-dev
  # the README's ROS commands on a fresh machine: rosrun (rosbash), roslaunch, rosbag play; rviz
  # headless for the screenshot (docs/ros.md): Xvfb, xauth and imagemagick's import
  rosbash xvfb xauth imagemagick
  # scripts/ros_realtime_check.py subscribes to sensor_msgs/Image
  python3-sensor-msgs
  # the zoo test and scripts/evaluate_zoo.py score the real clip with ../shared/tools/lidar_dem_eval.py
  python3-scipy python3-matplotlib
)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PKGS[@]} packages present"
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install_deps: installing ${#missing[@]} packages: ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install_deps: done"
