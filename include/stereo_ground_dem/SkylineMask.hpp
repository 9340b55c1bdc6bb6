#pragma once
/// \file SkylineMask.hpp
/// The reference pixels along the outline of the ground against a blank background (sky, glare,
/// a white wall): the temporal pairs leave them out.
///
/// Where terrain ends against a textureless background (the top of a climb, a crest seen against
/// the sky) its outline is the strongest edge in the image, and it is an occluding contour: from
/// the next viewpoint a different line of the surface forms it, so it does not move as the ground
/// under it does. On the rendered `rolling` scene, climbing towards a crest, the band from 3 px
/// above to 8 px below that outline holds 42-48 % of the squared image gradient of the ground's
/// pixels (frames 26-36); the temporal alignment fits the outline's motion instead of the
/// ground's, and the attitude walks off by 0.3-0.6 deg per frame. The stereo pair keeps these
/// pixels (the outline has the crest's disparity from both cameras at once).
///
/// Per column, a run of at least `min_blank_rows` blank rows from the image's top edge down (mean
/// |gradient| over a `window_px` box below `blank_gradient_grey_per_px`) ending at a textured row
/// marks the rows from `rows_above` above to `rows_below` + `reveal_rows` / 2^level below that
/// transition. Only that first outline: a blank patch lower down is smooth ground (low-texture
/// asphalt), not a background (on the `shadows` scene, marking every blank-to-textured
/// transition broke the tracking). Every level is tested on its own gradients, the window and
/// rows_above / rows_below in its own pixels (the pyramid's blur widens the edge by about one
/// pixel of the level), the blank run and reveal_rows scaled by 1 / 2^level (the run >= 3).
/// Sizes chosen on the whole zoo (docs/results.md, "The outline against the sky").

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/ImagePyramid.hpp"

namespace stereo_ground_dem {

struct SkylineMaskOptions {
  bool enabled = true;
  /// Blank: the mean gradient magnitude over the window is below this [grey/px] (the rendered
  /// sky's noise: ~0.6; ground, even weakly textured asphalt: 3-9).
  double blank_gradient_grey_per_px = 1.5;
  int window_px = 9;          ///< the box the mean is taken over (odd) [px]
  int min_blank_rows = 20;    ///< a blank run from the top at least this tall [px at level 0]
  int rows_above = 2;         ///< marked above the first textured row [px]
  int rows_below = 8;         ///< ... and below it [px] (the window reaches ~window_px / 2 past the edge) ...
  /// ... plus this [px at level 0, so reveal_rows / 2^level at a level]: the ground just below
  /// the outline that the previous frame did not see yet (the crest recedes as the camera nears it)
  int reveal_rows = 12;

  bool isValid(std::string* why) const;
};

class SkylineMask {
 public:
  /// Throws std::invalid_argument on invalid options.
  explicit SkylineMask(const SkylineMaskOptions& options);
  /// One CV_8U mask per level of `pyramid` (nonzero = along a blank background's outline), left
  /// empty (not computed) below `first_level`; no masks at all when disabled.
  std::vector<cv::Mat> compute(const ImagePyramid& pyramid, int first_level = 0) const;
  /// The mask of pyramid level `l` from its gradient images (CV_32F [grey/px]).
  cv::Mat level(const cv::Mat& grad_u, const cv::Mat& grad_v, int l) const;
  const SkylineMaskOptions& options() const { return options_; }

 private:
  SkylineMaskOptions options_;
};

}  // namespace stereo_ground_dem
