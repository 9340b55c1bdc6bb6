#pragma once
/// \file Evaluation.hpp
/// What one evaluation of the photometric objective at a state produces (PhotometricEvaluator)
/// and the Gauss-Newton step consumes (HeightSystemSolver): the normal-equation pieces of the data
/// term per working triangle and per image pair, the costs, and the pixel counts. Internal to
/// SurfaceAligner.

#include <Eigen/Core>
#include <vector>

#include "stereo_ground_dem/Se3.hpp"

namespace stereo_ground_dem {
namespace aligner {

using Matrix62d = Eigen::Matrix<double, 6, 2>;

/// Per working triangle and pair, the sums over its pixels of the inverse compositional Jacobian
/// in the plane-increment space (delta, 3) with the residual, the photometric part (I0, 1) and,
/// for world-fixed pairs, the motion part. Flat layout per triangle:
///   [0..5]   sum w Jd^T Jd   (xx, xy, xz, yy, yz, zz)
///   [6..8]   sum w Jd^T e
///   [9..14]  sum w Jd^T (I0, 1)  (row-major 3x2)
///   [15..32] sum w Jd^T Jm       (row-major 3x6, world-fixed pairs only)
/// A world-fixed pair of a motion-only problem has no per-triangle sums (stride 0): its motion
/// block is summed per pair.
constexpr int kStrideRig = 15;
constexpr int kStrideWorld = 33;

/// Sums of one image pair over all of its pixels: photometric and motion blocks, cost, counts.
struct PairAccumulator {
  Eigen::Matrix2d pp = Eigen::Matrix2d::Zero();
  Eigen::Vector2d pe = Eigen::Vector2d::Zero();
  Matrix6d mm = Matrix6d::Zero();
  Matrix62d mp = Matrix62d::Zero();
  Vector6d me = Vector6d::Zero();
  double cost = 0.0;  ///< sum rho(e) incl. outside penalties (unscaled)
  int valid = 0;
  int outside = 0;
  void add(const PairAccumulator& o) {
    pp += o.pp;
    pe += o.pe;
    mm += o.mm;
    mp += o.mp;
    me += o.me;
    cost += o.cost;
    valid += o.valid;
    outside += o.outside;
  }
};

/// One thread's share of an evaluation: its pairs' sums and residual samples.
struct ThreadPart {
  std::vector<PairAccumulator> pair;
  std::vector<float> abs_residuals;
  std::vector<std::vector<float>> pair_abs_residuals;  ///< [pair] the same samples, per pair
  void reset(size_t pairs) {
    pair.assign(pairs, PairAccumulator());
    abs_residuals.clear();
    pair_abs_residuals.assign(pairs, {});
  }
};

struct Evaluation {
  /// The normal-equation pieces (tri, slot_dm_dz, the pairs' blocks) were accumulated; false for
  /// an evaluation that only decides whether a step is taken and is never solved from (costs,
  /// counts and residual samples only).
  bool sums = true;
  /// Triangles that own at least one pixel get a slot; accumulators are per slot.
  std::vector<int> slot_of;   ///< triangle -> slot or -1
  std::vector<int> slot_tri;  ///< slot -> triangle
  // Per slot, the triangle's plane at this evaluation's state and its Jacobian: the step solved
  // from these sums must linearize at the same state (the level's TriangleGeometry holds the
  // last evaluation's, which after a rejected trial is not the state's).
  std::vector<Eigen::Vector3d> slot_m;    ///< m (m^T X = 1 in the reference camera)
  std::vector<Eigen::Matrix3d> slot_dm_dz;  ///< d m / d (its three heights)
  // Per slot (each thread writes the slots of its own range):
  std::vector<std::vector<double>> tri;  ///< [pair] stride * slots
  std::vector<int> tri_pixels;
  std::vector<int> tri_excluded;  ///< pixels of the triangle masked out as obstacles
  std::vector<int> tri_textured;  ///< its used pixels with a gradient of at least textured_gradient
  // Per pair, merged over the threads:
  std::vector<PairAccumulator> pair;
  std::vector<float> abs_residuals;  ///< every 8th used sample's |residual|, all pairs
  std::vector<std::vector<float>> pair_abs_residuals;  ///< [pair] the same samples, per pair
  std::vector<ThreadPart> parts;  ///< per thread, before the merge
  std::vector<double> smooth_residual;  ///< per stencil: w (z_a - 2 z_b + z_d)
  std::vector<double> smooth_weight;    ///< per stencil: robust (IRLS) weight
  double data_cost = 0.0, smoothness_cost = 0.0, prior_cost = 0.0;
  double total() const { return data_cost + smoothness_cost + prior_cost; }
};

}  // namespace aligner
}  // namespace stereo_ground_dem
