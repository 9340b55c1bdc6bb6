#pragma once
/// \file RectificationMonitor.hpp
/// Sparse feature matches between the left and the right image of a pair (the strongest
/// minimum-eigenvalue corner per cell, pyramidal Lucas-Kanade with a forward-backward check, all
/// OpenCV), used for two things the direct method
/// cannot see by itself:
///  - the residual vertical misalignment of the rectification (VerticalMisalignment), fitted
///    robustly per pair and accumulated over pairs, so that the estimators can model it;
///  - a sanity test of the pair: swapped cameras (most matches with negative disparity), images
///    without common content (random noise, a covered lens: few consistent matches), a pair that
///    is not rectified at all.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/VerticalMisalignment.hpp"

namespace stereo_ground_dem {

struct RectificationMonitorOptions {
  int match_level = 1;                 ///< pyramid level of the matching (1 = half resolution)
  /// A corner's minimum eigenvalue must exceed this share of the image's strongest.
  double min_corner_strength = 2e-3;
  int cell_px = 8;                     ///< one corner (the strongest) per cell [px at match_level]
  int border_px = 8;                   ///< no corners this close to the border [px at match_level]
  int lk_window_px = 9;                ///< Lucas-Kanade window side [px]
  int lk_levels = 4;                   ///< Lucas-Kanade pyramid levels above match_level
  double max_forward_backward_px = 0.15;  ///< forward-backward error of a kept match [px at match_level]
  int min_matches = 25;                ///< fewer consistent matches: the pair shares no content
  double min_disparity_px = 1.0;       ///< |disparity| below this counts neither way [px at level 0]
  double max_misalignment_px = 6.0;    ///< larger vertical misalignment: not a rectified pair [px]
  double max_disparity_px = 200.0;     ///< disparity range over which the misalignment is bounded [px]
  double huber_k = 1.5;                ///< robust fit: Huber threshold in robust standard deviations
  /// Refine each Lucas-Kanade match with a window that may shear horizontally (see
  /// refineWithShear): without it the ground's shear biases the vertical offsets.
  bool refine_shear = true;
  /// Accumulation over pairs: the information of earlier pairs is multiplied by this per pair.
  double forgetting = 0.9;
  /// Prior standard deviation of the row shift's non-constant terms [px]: keeps them bounded
  /// where corners are few (one side of the image in a tunnel, the sky).
  double shape_prior_std_px = 5.0;
  /// Fit the terms that vary with the row only (y, y^2). Off by default: on the ground, where
  /// the disparity changes along the columns of a window (shear), Lucas-Kanade's translation-only
  /// windows bias the vertical offset by a function of the row (measured on rendered pairs with a
  /// perfect rig: up to 0.2 px at the bottom rows); with them off those terms stay 0.
  bool fit_row_terms = true;
  /// The prior standard deviation of term c (1..5) [px].
  double termPriorStd(int c) const { return (!fit_row_terms && (c == 2 || c == 5)) ? 1e-4 : shape_prior_std_px; }

  bool isValid(std::string* why) const;
};

/// What one pair says.
struct StereoPairCheck {
  int features = 0;               ///< corners tried
  int matches = 0;                ///< consistent forward-backward
  int positive = 0;               ///< matches with disparity > min_disparity_px
  int negative = 0;               ///< ... < -min_disparity_px (a right image left of the left one)
  double median_disparity_px = 0.0;
  VerticalMisalignment fit;       ///< this pair alone (zero when it could not be fitted)
  /// Information of the fit's row shift coefficients c0..c5 [1/px^2]. The fit leaves
  /// per_disparity at 0: on rendered pairs with a perfect rig, Lucas-Kanade's translation-only
  /// windows on the sheared ground give a spurious 0.001 px/px, as large as what it would measure.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  double residual_std_px = 0.0;   ///< robust spread of the vertical offsets about the fit [px]
  /// The consistent matches: (u, v) of the left pixel and the disparity [px at level 0].
  std::vector<Eigen::Vector3f> points;
  double time_ms = 0.0;
  std::string problem;            ///< empty when the pair looks like a rectified stereo pair
  bool ok() const { return problem.empty(); }
};

class RectificationMonitor {
 public:
  explicit RectificationMonitor(const RectificationMonitorOptions& options = RectificationMonitorOptions());

  /// Matches `left` into `right` (single-channel CV_32F grey images at pyramid level
  /// options.match_level of the same size) and fits the misalignment. `rig` is at level 0.
  /// `row_disparity` (optional, px at the match level, one per row; rows beyond it 0): the
  /// disparity expected on each row, by which the right image's rows are shifted before matching,
  /// so that windows on ground of that disparity gradient need no shear (a low camera's near ground
  /// changes by baseline / height px per row, too fast for the translation-only Lucas-Kanade:
  /// docs/results.md, "A low camera's start-up matches"). Matches are reported unshifted.
  StereoPairCheck measure(const cv::Mat& left, const cv::Mat& right, const StereoRig& rig,
                          const std::vector<float>* row_disparity = nullptr) const;

  /// Adds a pair's fit to the running estimate (ignored when !check.ok()).
  void accumulate(const StereoPairCheck& check);
  /// Adds a fit measured otherwise (RowShiftEstimator) with the information of its c0..c5.
  void accumulate(const VerticalMisalignment& fit, const Eigen::Matrix<double, 6, 6>& information);
  /// The running estimate (zero before any pair).
  VerticalMisalignment estimate() const;
  int pairs() const { return pairs_; }
  void reset();
  /// The accumulated normal equations of c0..c5 (what estimate() solves), to save and restore().
  const Eigen::Matrix<double, 6, 6>& information() const { return information_; }
  const Eigen::Matrix<double, 6, 1>& informationVector() const { return information_vector_; }
  void restore(const Eigen::Matrix<double, 6, 6>& information, const Eigen::Matrix<double, 6, 1>& information_vector,
               int pairs) {
    information_ = information;
    information_vector_ = information_vector;
    pairs_ = pairs;
  }

  const RectificationMonitorOptions& options() const { return options_; }

 private:
  bool refineWithShear(const cv::Mat& left, const cv::Mat& right, const cv::Mat& right_gu, const cv::Mat& right_gv,
                       const cv::Point2f& p, cv::Point2f* q) const;

  RectificationMonitorOptions options_;
  Eigen::Matrix<double, 6, 6> information_ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> information_vector_ = Eigen::Matrix<double, 6, 1>::Zero();
  int pairs_ = 0;
};

}  // namespace stereo_ground_dem
