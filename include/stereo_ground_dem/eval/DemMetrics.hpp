#pragma once
/// \file DemMetrics.hpp
/// A DEM against the exact terrain of a synthetic scene.
///
/// The estimated DEM lives in the estimated ground frame; it is brought into the true ground frame
/// through the first camera: true_T_est = true ground_T_camera0 * (estimated ground_T_camera0)^-1.
/// A vertex's error is its height there minus the terrain height at its (x, y). Vertices are
/// grouped by the smallest camera depth at which any frame saw them inside the image's
/// horizontal field of view ("seen within d m").

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/sim/SyntheticScene.hpp"

namespace stereo_ground_dem {

struct HeightErrorStats {
  double min_depth_m = 0.0, max_depth_m = 0.0;  ///< the bin: seen within [min, max)
  int count = 0;
  double median_m = 0.0, rmse_m = 0.0, p95_m = 0.0;  ///< of |error|
  /// Known vertices / vertices a camera saw in this bin (terrain, no obstacle, in the horizontal
  /// field of view with a line of sight clear of the terrain: ground behind a crest is not counted).
  double coverage = 0.0;
};

struct DemMetrics {
  std::vector<HeightErrorStats> bins;  ///< 0-10, 10-20, 20-30, 30-40 m
  HeightErrorStats within_20m;         ///< everything seen within 20 m
  int known_vertices = 0;
  int obstacle_vertices = 0;           ///< known vertices inside an obstacle footprint (excluded)
  // traversability: "blocked" = traversability < 0.5 (or an obstacle footprint in the truth)
  int trav_compared = 0;
  double trav_precision = 0.0;  ///< of the blocked class
  double trav_recall = 0.0;
  double trav_accuracy = 0.0;
  // The obstacle layer (obstacles.tif: >= 0.5 marked) against the scene's footprints at the
  // processed frames' times; "near" a footprint = within 0.5 m of it (the mask's dilation).
  int obs_free_known = 0;     ///< cells with a value that no footprint came near, ever
  int obs_free_flagged = 0;   ///< ... of them marked (false alarms on free ground)
  /// cells a moving obstacle came near and left, then seen by a later frame (4-30 m ahead, in the
  /// image, the line of sight free of obstacles at that frame's time and of terrain)
  int obs_path_seen = 0;
  int obs_path_ghost = 0;     ///< ... of them still marked at the end (ghosts)
  int obs_static_known = 0;   ///< cells with a value inside a static footprint
  int obs_static_marked = 0;  ///< ... of them marked
  int obs_static_in_view = 0;         ///< cells inside a static footprint that a frame had in view (4-30 m)
  int obs_static_in_view_marked = 0;  ///< ... of them marked (recall: the rest unknown or ground)
  /// Per cell of the obstacle layer, which of the above it is (CV_8U): 0 no value or none of them,
  /// 1 free ground unmarked, 2 free ground marked, 3 left by a mover and cleared, 4 a ghost,
  /// 5 static footprint marked, 6 static footprint unmarked.
  cv::Mat obstacle_class;
  cv::Mat signed_error;  ///< per vertex of the estimated grid: estimate - truth [m], NaN unknown/obstacle

  /// `camera0_T_camera` are the true poses of the frames (poses.txt), `times_s` their stamps.
  static DemMetrics compute(const GroundGrid& grid, const cv::Mat& elevation, const cv::Mat& traversability,
                            const Eigen::Isometry3d& est_ground_T_camera0, const sim::SyntheticScene& scene,
                            const Eigen::Isometry3d& true_ground_T_camera0,
                            const std::vector<Eigen::Isometry3d>& camera0_T_camera, const std::vector<double>& times_s,
                            const StereoRig& rig, const cv::Mat& true_traversability = cv::Mat(),
                            const cv::Mat& obstacles = cv::Mat());
};

}  // namespace stereo_ground_dem
