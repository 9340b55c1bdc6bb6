#pragma once
/// \file FarGroundSeeds.hpp
/// Starting heights for ground the surface hypothesis does not reach: the far side of a crest.
///
/// Climbing towards a crest, the mesh continues the climb past it; the ground beyond, falling
/// away, comes into view 20-65 m ahead while the hypothesis places those pixels 10-20 m away, 8-19
/// px of disparity off, far outside any alignment's basin. ObstacleDetector sees that such pixels
/// look past the surface (far_depth_ratio) and excludes them, so they never correct the mesh: the
/// far side stays unmapped until the camera is over the crest (the rendered `rolling` scene lost
/// 10-15 % of its coverage within 20 m that way). Their best fronto-parallel window's disparity
/// gives a rough 3-D point each; the unknown vertices under enough of them start at those points'
/// median height (seeds()), and any vertex, known or not, standing above one of their rays starts
/// at the ray (ceilings(): the climb the map continued past the crest and fused from afar). The
/// hidden band between the crest and them follows by the harmonic extension
/// (MapView::initialHeights), and the obstacle test runs again on that surface: the far side's
/// pixels then fit it and the joint alignment refines it like any other new ground.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"

namespace stereo_ground_dem {

struct FarGroundSeedsOptions {
  bool enabled = true;
  /// Seeds are sought only when at least this many pixels (at the obstacle test's level) look past
  /// the surface: a crest's far side, not the few pixels over a bump's top.
  int min_far_pixels = 200;
  /// A vertex is seeded from the points within one grid spacing of it (its bilinear support), when
  /// there are at least this many.
  int min_points = 3;
  /// ... and only where their median lies at least this far below the surface hypothesis (the
  /// pixels looked past it, so their ground is lower) [m].
  double min_drop_m = 0.2;
  /// The share of each far ray, from the camera, that bounds the ground (ceilings()) [-].
  double ray_share = 0.8;
  /// A vertex whose height stands more than this above its ceiling starts at the ceiling (known
  /// or not: the map's climb continued past the crest and fused from afar) [m].
  double ceiling_margin_m = 0.1;

  bool isValid(std::string* why) const;
};

/// What FarGroundSeeds::starts() gives the frame: starting heights and how they came about.
struct FarGroundStarts {
  /// Starting height [m] per vertex of the window; NaN where the map's own start stands.
  Eigen::VectorXd heights;
  int seeded_vertices = 0;  ///< finite entries of `heights` (seeds and ceilings together)
  int carved_vertices = 0;  ///< of which a ceiling (a far ray passing under the vertex's height)
  /// ceilings() of the frame [m] (+infinity where no far ray passed): the map heights above them
  /// that the frame does not measure again are refuted (ElevationMap::markRefuted).
  Eigen::VectorXd ceilings;
};

class FarGroundSeeds {
 public:
  /// Throws std::invalid_argument on invalid options.
  explicit FarGroundSeeds(const FarGroundSeedsOptions& options = FarGroundSeedsOptions());

  /// Heights [m] for the vertices of `grid` that are unknown (`information` 0) from `points` (ground
  /// frame [m], seen past the surface `heights`): the median height of the points within one
  /// spacing of the vertex, where there are min_points and the median is min_drop_m below the
  /// vertex's height. NaN for every other vertex.
  Eigen::VectorXd seeds(const GroundGrid& grid, const Eigen::VectorXd& heights, const Eigen::VectorXd& information,
                        const std::vector<Eigen::Vector3d>& points) const;

  /// Upper bounds [m] on the ground at the vertices of `grid` from the rays of the pixels that saw
  /// past the surface: the ray from `camera` (ground frame) to each of `points` passes above the
  /// ground, so a vertex it passes over (nearest vertex of samples every half spacing) lies no
  /// higher than the ray there. Only the first ray_share of each ray counts (the point's depth is
  /// rough). The lowest bound per vertex; +infinity where no ray passes.
  Eigen::VectorXd ceilings(const GroundGrid& grid, const Eigen::Vector3d& camera,
                           const std::vector<Eigen::Vector3d>& points) const;

  /// The starts for one frame: seeds() where an unknown vertex has them; elsewhere, a vertex
  /// (known or not) whose height stands more than ceiling_margin_m above its ceilings() starts at
  /// the ceiling. `camera` is the camera centre in the ground frame.
  FarGroundStarts starts(const GroundGrid& grid, const Eigen::VectorXd& heights, const Eigen::VectorXd& information,
                         const Eigen::Vector3d& camera, const std::vector<Eigen::Vector3d>& points) const;

  const FarGroundSeedsOptions& options() const { return options_; }

 private:
  FarGroundSeedsOptions options_;
};

}  // namespace stereo_ground_dem
