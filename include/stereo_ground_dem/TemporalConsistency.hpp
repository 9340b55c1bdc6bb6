#pragma once
/// \file TemporalConsistency.hpp
/// Ground whose texture moved between two frames: a moving car's shadow, a moving object the
/// obstacle test missed, reflections. Its pixels fit the stereo pair (the left and right images
/// are taken at the same time) but not the previous frame under the camera's own motion, and
/// they pull that motion toward their own (METHOD.md section 6). Per pixel of a coarse level
/// with a surface, the photometric residual of the stereo pair and of the (current, previous
/// left) pair under the estimated surface and motion are compared in small windows; where the
/// temporal one stands far above the stereo one (relative to the frame's usual ratio of the two)
/// the pixel is flagged, and the temporal pairs skip it (AlignerTarget::reference_excluded).

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/PhotometricParams.hpp"
#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/VerticalMisalignment.hpp"

namespace stereo_ground_dem {

struct TemporalConsistencyOptions {
  bool enabled = true;
  int level = 2;                 ///< pyramid level of the test
  int window_px = 2;             ///< half side of the averaging window at that level [px]
  /// Flagged when the local temporal residual exceeds ratio * (the frame's median temporal /
  /// stereo ratio) * the local stereo residual + margin_grey, and share_of_median * the
  /// frame's median temporal residual.
  double ratio = 2.5;
  double margin_grey = 2.0;
  double share_of_median = 3.0;
  int dilation_px = 1;           ///< grow the flagged area [px at the level]
  double min_flagged_share = 0.003;  ///< fewer flagged surface pixels: nothing to do

  bool isValid(std::string* why) const;
};

struct TemporalInconsistency {
  std::vector<cv::Mat> masks;  ///< per pyramid level (CV_8U, 255 flagged); empty when nothing flagged
  int pixels = 0;              ///< flagged pixels at the test level
  int surface_pixels = 0;      ///< pixels with a surface at the test level
};

class TemporalConsistency {
 public:
  explicit TemporalConsistency(const TemporalConsistencyOptions& options = TemporalConsistencyOptions());

  /// `inverse_depth`: the surface at options.level of `left` [1/m] (0: none); `excluded`
  /// (optional, same size): pixels already excluded (obstacles). prev_T_current maps current
  /// camera coordinates into the previous left camera's. The photometric pairs relate
  /// left = gain * other + bias; `rectification` is the stereo pair's row shift.
  TemporalInconsistency detect(const ImagePyramid& left, const ImagePyramid& right, const ImagePyramid& previous_left,
                               const StereoRig& rig, const cv::Mat& inverse_depth, const cv::Mat& excluded,
                               const Eigen::Isometry3d& prev_T_current, const PhotometricParams& stereo,
                               const PhotometricParams& temporal, const VerticalMisalignment& rectification) const;

  const TemporalConsistencyOptions& options() const { return options_; }

 private:
  TemporalConsistencyOptions options_;
};

}  // namespace stereo_ground_dem
