#include "stereo_ground_dem/VerticalMisalignment.hpp"

#include <algorithm>
#include <cmath>

namespace stereo_ground_dem {

double VerticalMisalignment::rowShift(const StereoRig& rig, double u, double v) const {
  const auto b = basis((u - rig.cx) / rig.fx, (v - rig.cy) / rig.fy);
  double s = 0.0;
  for (int k = 0; k < kTerms; ++k) s += row_shift_px[static_cast<size_t>(k)] * b[static_cast<size_t>(k)];
  return s;
}

double VerticalMisalignment::maxAbsPx(const StereoRig& rig, double max_disparity_px) const {
  const double w = rig.width > 0 ? rig.width - 1.0 : 2.0 * rig.cx;
  const double h = rig.height > 0 ? rig.height - 1.0 : 2.0 * rig.cy;
  double worst = 0.0;
  // The polynomial is quadratic: its extremes over the image lie on a fine enough lattice.
  constexpr int kSteps = 16;
  for (int i = 0; i <= kSteps; ++i) {
    for (int j = 0; j <= kSteps; ++j) {
      const double s = rowShift(rig, w * i / kSteps, h * j / kSteps);
      worst = std::max({worst, std::abs(s), std::abs(s + per_disparity * max_disparity_px)});
    }
  }
  return worst;
}

}  // namespace stereo_ground_dem
