#!/usr/bin/env bash
# Builds the package in a catkin workspace kept inside the repository (.catkin_ws, git-ignored).
# Usage: scripts/build.sh [extra catkin_make arguments, e.g. a target name]
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# catkin's CMake and pluginlib's helpers need Debian's python3 (a pyenv python lacks catkin_pkg).
export PATH="/usr/bin:/bin:$PATH"
WS="${SGD_WS:-$REPO/.catkin_ws}"
mkdir -p "$WS/src"
if [ ! -e "$WS/src/stereo_ground_dem" ]; then ln -s "$REPO" "$WS/src/stereo_ground_dem"; fi
JOBS="${SGD_JOBS:-$(nproc)}"
cd "$WS"
catkin_make -DCMAKE_BUILD_TYPE="${SGD_BUILD_TYPE:-Release}" -DCATKIN_ENABLE_TESTING=ON -j"$JOBS" "$@" \
  > "$WS/build.log" 2>&1 || { tail -n 60 "$WS/build.log"; echo "build failed (full log: $WS/build.log)"; exit 1; }
echo "build: ok ($WS)"
