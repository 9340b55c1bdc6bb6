#!/usr/bin/env bash
# The main job on the bundled sample: installs dependencies, builds, and runs the offline runner
# over six KITTI frames (data/kitti_seq06_sample). Outputs go to out/demo (or $1).
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export PATH="/usr/bin:/bin:$PATH"
OUT="${1:-$REPO/out/demo}"
bash "$REPO/scripts/install_deps.sh"
bash "$REPO/scripts/build.sh"
WS="${SGD_WS:-$REPO/.catkin_ws}"
"$WS/devel/lib/stereo_ground_dem/dem_offline" --sequence "$REPO/data/kitti_seq06_sample" --out "$OUT" \
  --config "$REPO/config/kitti.yaml"
echo
echo "Outputs in $OUT:"
echo "  dem.tif + dem.yaml        the DEM (float32 GeoTIFF, NaN unknown) and its grid"
echo "  dem_height.png            shaded height map with the camera trajectory"
echo "  traversability.png/.tif   traversability 0..1"
echo "  dem_disparity_overlay.png the disparity the DEM implies, over the first left image"
echo "  trajectory_kitti.txt      camera poses (KITTI format), also trajectory_tum.txt"
echo "  mesh.ply                  the surface for a 3-D viewer"
echo "  obstacles.tif             obstacle layer (1 obstacle, 0 ground, NaN unknown), obstacle_height.tif"
