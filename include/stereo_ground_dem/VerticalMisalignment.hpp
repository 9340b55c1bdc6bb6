#pragma once
/// \file VerticalMisalignment.hpp
/// The residual vertical misalignment of a rectified stereo pair: where a left pixel with
/// disparity d really appears in the right image,
///
///     v_right = v + row_shift(x, y) + per_disparity * d,
///     row_shift = c0 + c1 x + c2 y + c3 x y + c4 x^2 + c5 y^2     [px at level 0],
///
/// with (x, y) = ((u_right - cx) / fx, (v - cy) / fy) the right pixel's normalized coordinates.
///
/// Real rigs are never rectified perfectly. Both KITTI rigs in ../shared/data show the same
/// pattern (sparse matches over 6-8 frames each): -0.15 to -0.3 px of offset and a saddle
/// c3 x y with c3 = +6.5 to +7 px, i.e. up to 1.4 px at the image corners, of opposite signs at
/// the top and the bottom. The direct method models the stereo pair as a pure horizontal shift, so
/// an unmodelled vertical error biases the disparity of slanted texture (lane markings) with
/// opposite signs on the two sides of the image: a tilted ground (docs/method.md, section 2).
/// The polynomial is a fixed map of right-image pixels; per_disparity is a vertical baseline
/// component (a right camera displaced by ty: per_disparity = -(fy / fx) ty / baseline).

#include <Eigen/Core>
#include <array>

#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

struct VerticalMisalignment {
  static constexpr int kTerms = 6;
  std::array<double, kTerms> row_shift_px{};  ///< c0..c5 [px at level 0]
  double per_disparity = 0.0;                 ///< [px/px of disparity]

  /// The basis functions (1, x, y, xy, x^2, y^2) at normalized coordinates (x, y).
  static std::array<double, kTerms> basis(double x, double y) { return {1.0, x, y, x * y, x * x, y * y}; }

  /// The row shift [px at level 0] at right-image pixel (u, v) of the level-0 rig.
  double rowShift(const StereoRig& rig, double u, double v) const;

  /// The largest |vertical offset| [px] over an image of the rig's size (the principal point as
  /// its centre when the size is unknown), with disparities up to max_disparity_px.
  double maxAbsPx(const StereoRig& rig, double max_disparity_px) const;

  /// The right camera's y offset [m] (in the left camera frame) that produces per_disparity.
  double rightCameraOffsetY(const StereoRig& rig) const { return -per_disparity * rig.baseline_m * rig.fx / rig.fy; }

  bool hasRowShift() const {
    for (double c : row_shift_px)
      if (c != 0.0) return true;
    return false;
  }
  bool isZero() const { return !hasRowShift() && per_disparity == 0.0; }
};

}  // namespace stereo_ground_dem
