#pragma once
/// \file RisingGroundSeeds.hpp
/// Starting heights for ground that rises out of the surface hypothesis: a hill ahead that the
/// mesh has not climbed yet.
///
/// The obstacle test (ObstacleDetector) explains a pixel by the mesh raised or lowered by up to
/// ground_band_m, or by an upright surface. Ground that climbs more than that above the mesh is
/// explained better by the upright surface: its pixels are excluded, so the mesh never climbs it,
/// and it stays an "obstacle" (the rendered rolling scene, seed 2, kept 10 % of its free ground
/// flagged that way and drifted 1.25 %). The flagged pixels' own window disparities
/// (ObstacleMask::uprightPoints()) tell the two apart: an upright thing's points stack up at one
/// place (a wall, a car's back, a pole: heights from its foot to its top), ground's lie on a plane
/// no steeper than max_slope_deg around each vertex; and ground rises from the ground whose pixels
/// fit the hypothesis, while a car's roof stands off its face. Rising ground found so grows from
/// there, vertex by vertex, and its vertices start at their plane's height; the obstacle test then
/// runs again on that surface (IncrementalEstimator), its pixels fit it and the joint alignment
/// refines it. Steeper banks (the off-road scene's 35 deg embankment) stay excluded: seeded
/// (max_slope_deg 40), their starts were 7.6 cm off (median) but the joint alignment mapped them
/// 30 cm and more off, and the off-road scene's 95th percentile doubled (docs/results.md).

#include <Eigen/Core>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

struct RisingGroundSeedsOptions {
  bool enabled = true;
  /// A vertex is a candidate with at least this many points within one spacing of it (its
  /// bilinear support), spread over it (rms a quarter spacing across, in every direction) ...
  int min_points = 6;
  /// ... lying on one plane (least squares) to a median |residual| of at most this [m] ...
  double max_spread_m = 0.1;
  /// ... that stands at least this far above the surface hypothesis at the vertex [m].
  double min_rise_m = 0.15;
  /// ... and is no steeper than this; a candidate joins the rising ground next to a vertex of it,
  /// or of the surface's ground, at most this steeply above or below that neighbour [deg].
  double max_slope_deg = 20.0;
  /// A grown region with fewer vertices is dropped (a few rough points on a car's side) [-].
  int min_region_vertices = 12;
  /// Points farther than this from the camera (horizontally) are not used: a window's disparity
  /// at the test level is whole pixels, 25 % of the depth at 15 m [m].
  double max_range_m = 15.0;

  bool isValid(std::string* why) const;
};

class RisingGroundSeeds {
 public:
  /// Throws std::invalid_argument on invalid options.
  explicit RisingGroundSeeds(const RisingGroundSeedsOptions& options = RisingGroundSeedsOptions());

  /// Heights [m] for the unknown vertices (`information` 0) of `grid` under rising ground, from
  /// `points` (ground frame [m], the flagged pixels' own points) over the surface `heights`: the
  /// candidates (see the options) connected, each to the next no steeper than max_slope_deg, to
  /// the surface's ground: a vertex that is no candidate and has fewer than min_points points (its
  /// pixels fit the hypothesis), at the hypothesis' height. A wall's face, or a car's, has points
  /// and is no candidate: nothing grows across it. Regions of at least min_region_vertices; NaN
  /// for every other vertex. `camera`: the camera centre, ground frame (max_range_m).
  Eigen::VectorXd seeds(const GroundGrid& grid, const Eigen::VectorXd& heights, const Eigen::VectorXd& information,
                        const Eigen::Vector3d& camera, const std::vector<Eigen::Vector3d>& points) const;

  const RisingGroundSeedsOptions& options() const { return options_; }

 private:
  RisingGroundSeedsOptions options_;
};

}  // namespace stereo_ground_dem
