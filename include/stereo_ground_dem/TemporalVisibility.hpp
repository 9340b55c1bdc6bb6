#pragma once
/// \file TemporalVisibility.hpp
/// Reference pixels whose ground the previous camera did not see: hidden from it by the surface
/// itself (the near side of a crest or a ridge, the rim of a ditch, a rut's wall).
///
/// The temporal pairs warp a reference pixel to where its ground point projects in the previous
/// image. Where that point was hidden from the previous viewpoint, the previous image holds the
/// occluder there, not the point, and the pair fits the occluding contour's motion instead of the
/// ground's. Climbing towards a crest whose far side comes into view (the rendered `rolling`
/// scene, frames 28-39), about 8 % of the ground pixels are such newly revealed ground, in a strip
/// right behind the ridge across the whole image, and the attitude walked off by 0.1-0.3 deg per
/// frame even from the true pose. SkylineMask handles the same effect where the occluder stands
/// against a blank sky; this test needs the surface, not a blank background: the current surface
/// is rendered into the previous view (its z-buffer) and a pixel is hidden when that view holds a
/// nearer surface where the pixel's point projects.

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

struct TemporalVisibilityOptions {
  bool enabled = true;
  /// Hidden when the previous view's surface at the projection is nearer than the point by more
  /// than this share of the point's inverse depth (a point on the visible surface meets itself).
  double inverse_depth_tolerance = 0.05;
  int dilation_px = 1;  ///< grow the hidden area [px at the test level]
  /// The tracker runs the level once more without the hidden ground when it is more than this
  /// share of the level's samples (0.02: a crest's revealed strip, not the few pixels behind small
  /// bumps, which cost a pass on every off-road frame for nothing measurable).
  double min_repeat_share = 0.02;

  bool isValid(std::string* why) const;
};

class TemporalVisibility {
 public:
  /// Throws std::invalid_argument on invalid options.
  explicit TemporalVisibility(const TemporalVisibilityOptions& options = TemporalVisibilityOptions());

  /// The pixels of the reference view (inverse depth `reference_rho`, CV_32F [1/m], 0 = no surface)
  /// whose points the target view (the same surface rendered from there, `target_rho`, the same
  /// size) sees behind a nearer surface: CV_8U, 255 = hidden. `rig` is at the images' level;
  /// `target_T_reference` maps reference camera coordinates into the target camera's. Points
  /// projecting outside the target image, or where it has no surface, are not hidden.
  cv::Mat hidden(const cv::Mat& reference_rho, const cv::Mat& target_rho, const StereoRig& rig,
                 const Eigen::Isometry3d& target_T_reference) const;

  const TemporalVisibilityOptions& options() const { return options_; }

 private:
  TemporalVisibilityOptions options_;
};

}  // namespace stereo_ground_dem
