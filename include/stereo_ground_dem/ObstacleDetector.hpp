#pragma once
/// \file ObstacleDetector.hpp
/// Occlusion reasoning for the ground estimators: which reference pixels see something standing on
/// the ground (a car, a pole, a wall, a pedestrian) rather than the ground itself.
///
/// Each pixel is explained by one of two surface models, compared photometrically over a small
/// window between the left and the right image of the current frame:
///  - the ground: the current estimate of the ground mesh (a slanted surface: its disparity grows
///    by baseline/camera-height pixels per image row);
///  - an upright obstacle: a fronto-parallel surface (constant disparity over the window) closer to
///    the camera than the ground seen through the pixel by at least `min_obstacle_height_m` worth
///    of disparity.
/// A pixel goes to the obstacle when the best upright surface explains its window clearly better
/// than the ground does. The ground model is a family: the mesh's surface raised or lowered by up
/// to `ground_band_m` (each a slanted window), so raised ground (a curb top, a terrace above a
/// step, a verge) is explained as ground before the mesh has risen to it; the test is about the
/// orientation of the surface (slanted like the ground, or upright) more than about its height.
/// A third model catches ground the surface does not hold: a fronto-parallel surface at least
/// `far_depth_ratio` times farther than the ground hypothesis (the far side of a crest that the mesh
/// continued upwards, ground down a drop-off). Such pixels are excluded too, but are no obstacle.
/// Excluded pixels take no part in the ground data term (so the mesh cannot climb onto the
/// obstacle and ground hidden behind it stays unobserved); their disparity gives the obstacle's
/// position and height for the obstacle layer.

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/PhotometricParams.hpp"
#include "stereo_ground_dem/StereoRig.hpp"

namespace stereo_ground_dem {

struct ObstacleDetectorOptions {
  bool enabled = true;
  int level = 2;                       ///< pyramid level of the test
  int window_width_px = 3;             ///< window at that level [px]
  int window_height_px = 7;            ///< [px]; taller than wide: the slant of the ground shows
  double min_obstacle_height_m = 0.25; ///< upright surfaces must stand at least this high
  double camera_height_m = 1.65;       ///< nominal camera height, converts the above to disparity
  double margin_px = 0.5;              ///< extra disparity margin at the test level [px]
  double cost_ratio = 0.7;             ///< obstacle if its cost < ratio * ground cost
  double min_ground_cost_grey = 3.0;   ///< mean |residual| of the ground below this: ground [grey]
  double min_range_m = 2.0;            ///< nearest obstacle searched [m]
  double ground_band_m = 0.4;          ///< ground raised/lowered by up to this is still ground [m]
  int dilation_px = 1;                 ///< grow the mask at the test level [px]
  /// Hidden ground this close to a cell where the thing stands is its body (a car's footprint
  /// seen from behind); farther hidden ground is its occlusion shadow and stays unknown [m].
  double hidden_body_depth_m = 1.5;
  /// The body only behind its visible face, along the camera's rays (false: in every direction,
  /// so that hidden ground beside a thing's end is its body too). Along the rays: fewer marks on
  /// free ground, fewer obstacle cells found (docs/results.md, "The obstacle layer").
  bool hidden_body_along_ray = false;
  /// An obstacle pixel's depth is that of its column's foot (the ground's just below the lowest
  /// obstacle pixel of its run, or the foot of the run below it in the column), unless the run's
  /// own median disparity and the foot's differ by more than a factor 1 / foot_min_ratio: then its
  /// windows' own disparities (detect()).
  bool foot_depth = true;
  double foot_min_ratio = 0.67;
  /// Left of column d + half a window the right image does not see what the left one sees at
  /// disparity d: an obstacle whose leftmost pixels lie at that limit over at least two windows'
  /// height of rows (a car entering the view from the left) continues to the image's border in
  /// those rows (detect()). Without it, the part of an overtaking car left of the limit entered
  /// the temporal pairs (the shadows scene's yaw drift while a car passes).
  bool continue_at_left_border = true;
  /// Ground seen beyond the mesh's surface: a pixel whose window a fronto-parallel surface at
  /// least this many times farther than the ground hypothesis explains clearly better (the same
  /// `cost_ratio`, and better than any upright surface) sees past the surface the mesh holds (over
  /// a crest whose far side the mesh continues too high, down a drop-off): it is excluded from the
  /// ground data term but is no obstacle (no obstacle point, not counted in `pixels`). 0 disables.
  double far_depth_ratio = 2.0;
  /// Threads of the plane sweeps (the ground bands and the upright disparities are split between
  /// them; the result is the same for any number).
  int num_threads = 1;

  bool isValid(std::string* why) const;
};

struct ObstacleMask {
  std::vector<cv::Mat> excluded;  ///< per pyramid level, CV_8U, 255 = obstacle pixel or seeing past the surface
  cv::Mat disparity;              ///< at the test level: obstacle disparity in level-0 pixels, 0 = none
  int level = 2;                  ///< the test level
  int pixels = 0;                 ///< obstacle pixels at the test level
  int far_pixels = 0;             ///< pixels seeing past the surface (far_depth_ratio), not obstacles
  cv::Mat far_disparity;          ///< at the test level: their best window's disparity in level-0 pixels, 0 = none
  /// At the test level: each pixel the upright test flagged, its own best window's disparity in
  /// level-0 pixels (`disparity` gives runs their foot's instead), 0 = none.
  cv::Mat upright_disparity;

  /// The 3-D points [m] of the obstacle pixels (from their disparity) in the ground frame.
  std::vector<Eigen::Vector3d> groundPoints(const StereoRig& rig, const Eigen::Isometry3d& ground_T_camera) const;
  /// The 3-D points [m] of the pixels seeing past the surface (from far_disparity), ground frame.
  std::vector<Eigen::Vector3d> farPoints(const StereoRig& rig, const Eigen::Isometry3d& ground_T_camera) const;
  /// The 3-D points [m] of the flagged pixels from their own windows' disparity (upright_disparity),
  /// ground frame: where they lie, not where a thing would stand (RisingGroundSeeds).
  std::vector<Eigen::Vector3d> uprightPoints(const StereoRig& rig, const Eigen::Isometry3d& ground_T_camera) const;
};

/// Per-vertex obstacle evidence of one frame on a grid.
struct ObstacleEvidence {
  std::vector<uint8_t> hit;     ///< vertex under an obstacle (its points fall into the cell)
  std::vector<uint8_t> hidden;  ///< vertex seen mostly through obstacle pixels: its ground is not seen
  std::vector<uint8_t> ground;  ///< vertex seen as ground (its pixels fit the surface)
  Eigen::VectorXd height;       ///< obstacle height above the surface [m], NaN where no 3-D point
};

class ObstacleDetector {
 public:
  /// Evidence on `grid` (surface `heights`): a vertex is hit when at least `min_points` obstacle
  /// points at least `min_obstacle_height_m` above the surface fall into its cell and some of its
  /// triangles' pixels are obstacle pixels (the thing stands there). It is hidden when its
  /// triangles' pixels were mostly excluded as obstacle pixels (more than `hidden_ratio` times its
  /// ground pixels: the ground behind the thing is not seen); a hidden vertex within
  /// `body_depth_m` of a hit vertex is hit too (the thing's body), the others are neither hit nor
  /// ground (its occlusion shadow: unknown). It is ground when it had `min_ground_pixels` ground
  /// pixels and is neither hit nor hidden. With `camera_position` (ground frame), the body reaches
  /// only behind a hit vertex along the ray from the camera (hidden_body_along_ray).
  static ObstacleEvidence evidence(const GroundGrid& grid, const Eigen::VectorXd& heights,
                                   const Eigen::VectorXi& ground_pixels, const Eigen::VectorXi& excluded_pixels,
                                   const std::vector<Eigen::Vector3d>& points, double hidden_ratio,
                                   int min_ground_pixels, double min_obstacle_height_m, double body_depth_m,
                                   int min_points = 2, const Eigen::Vector3d* camera_position = nullptr);

  explicit ObstacleDetector(const ObstacleDetectorOptions& options);

  /// `ground_inverse_depth` is the current ground surface's inverse depth [1/m] at the test level
  /// (0 where there is no surface); `photometric` relates left = gain * right + bias.
  ObstacleMask detect(const ImagePyramid& left, const ImagePyramid& right, const StereoRig& rig,
                      const PhotometricParams& photometric, const cv::Mat& ground_inverse_depth) const;

  const ObstacleDetectorOptions& options() const { return options_; }

 private:
  ObstacleDetectorOptions options_;
};

}  // namespace stereo_ground_dem
