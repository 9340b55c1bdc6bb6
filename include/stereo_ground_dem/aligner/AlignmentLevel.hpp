#pragma once
/// \file AlignmentLevel.hpp
/// Everything about one pyramid level of a SurfaceAligner problem that stays fixed while
/// Gauss-Newton iterates: the working set of triangles and vertices, the basis of the height
/// increment and its update weights, the smoothness stencils, the sparsity pattern of the height
/// block, and where each image pair's unknowns sit. Internal to SurfaceAligner: the
/// PhotometricEvaluator reads it to evaluate a state, the HeightSystemSolver to build a step, and
/// apply() turns a step into the next state.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <array>
#include <opencv2/core.hpp>
#include <vector>

#include "stereo_ground_dem/SurfaceAligner.hpp"
#include "stereo_ground_dem/aligner/Evaluation.hpp"

namespace stereo_ground_dem {
namespace aligner {

using SpMat = Eigen::SparseMatrix<double>;

/// One working triangle of the fine grid.
struct TriangleGeometry {
  std::array<int, 3> vertex{};       ///< fine vertex indices
  std::array<int, 3> local{};        ///< compact active indices
  std::array<int, 9> value_index{};  ///< positions of its 3x3 block in the height matrix' values
  Eigen::Matrix3d heights_to_plane;
  // written by each evaluation, for its own use (the solve reads Evaluation::slot_m, slot_dm_dz):
  Eigen::Vector3d m = Eigen::Vector3d::Zero();  ///< the plane in the reference camera (m^T X = 1)
  bool drawn = false;
};

/// How a pair's warps map reference pixels: along rows only (a rectified stereo partner), by an
/// affine map (no perspective division), or by a general homography.
enum WarpKind { kWarpHorizontal = 0, kWarpAffine = 1, kWarpProjective = 2 };

/// One image pair at a state: its pose relative to the reference, warp kind, photometry, masks.
struct PairContext {
  Eigen::Isometry3d target_T_reference;
  Eigen::Vector3d t_prime;  ///< R_j^T t_j
  WarpKind kind;
  bool row_shift = false;         ///< the target has a row shift (AlignerTarget::row_shift_px)
  std::array<float, 6> shift{};   ///< its coefficients in this level's pixels
  const cv::Mat* target_excluded = nullptr;     ///< the target's excluded pixels at this level
  const cv::Mat* reference_excluded = nullptr;  ///< reference pixels this pair skips at this level
  bool world;               ///< world-fixed pair with motion estimated: accumulate Jm
  bool checkerboard;        ///< use every other pixel only
  int photo_index = -1;     ///< first global index of (dg, db), -1 when fixed
  PhotometricParams photometric;
  const cv::Mat* image;
};

/// Three collinear vertices of a second difference of the smoothness term.
struct Stencil {
  std::array<int, 3> v{};    ///< compact indices of the three collinear vertices
  double w = 0.0;            ///< sqrt(lambda) / h-scaled weight of the second difference
  std::array<int, 9> idx{};  ///< positions of its 3x3 block in the height matrix' values
};

/// A Gauss-Newton step in the level's unknowns.
struct Step {
  Eigen::VectorXd dtheta;   ///< basis coefficients (compact controls)
  Eigen::VectorXd dglobal;  ///< [motion (6)][photometric (2 per estimated pair)]
  bool ok = false;
};

class AlignmentLevel {
 public:
  /// Throws std::invalid_argument when the problem does not fit (masks, basis, heights).
  AlignmentLevel(const SurfaceAlignerOptions& options, const AlignmentProblem& problem, const SurfaceState& state);

  const SurfaceAlignerOptions& options() const { return opt_; }
  const AlignmentProblem& problem() const { return prob_; }
  const StereoRig& rig() const { return rig_; }            ///< intrinsics at this level
  const ImagePyramid::Level& reference() const { return *ref_; }
  const cv::Mat* excluded() const { return excluded_; }     ///< reference pixels not used (obstacles)
  int width() const { return width_; }
  int height() const { return height_; }
  double dataScale() const { return data_scale_; }          ///< 4^level / sigma^2
  float texturedGradient2() const { return gtex2_; }        ///< textured_gradient^2 [(grey/px)^2]
  int threads() const { return threads_; }

  std::vector<TriangleGeometry>& triangles() { return tris_; }
  const std::vector<TriangleGeometry>& triangles() const { return tris_; }
  bool empty() const { return tris_.empty(); }
  int activeCount() const { return static_cast<int>(active_.size()); }
  const std::vector<int>& active() const { return active_; }  ///< compact index -> fine vertex
  bool identityBasis() const { return identity_basis_; }
  int controlCount() const { return control_count_; }
  const std::vector<int>& controls() const { return control_; }  ///< compact control -> basis column
  const SpMat& basis() const { return basis_; }              ///< active rows x compact controls
  const SpMat& basisTransposed() const { return basis_t_; }
  const Eigen::VectorXd& updateWeights() const { return mu_; }
  const std::vector<Stencil>& stencils() const { return stencils_; }
  double smoothnessC2() const { return smooth_c2_; }         ///< robust scale^2 of the smoothness [m^2]
  const SpMat& heightPattern() const { return hzz_pattern_; }
  const std::vector<int>& diagonalIndex() const { return diag_index_; }
  int globalCount() const { return global_count_; }          ///< motion (6 if estimated) + 2 per photometric pair
  const std::vector<int>& photoIndex() const { return photo_index_; }
  const std::vector<int>& strides() const { return strides_; }

  /// The damping of control c given its data information: reduced (setDampingScale) only where
  /// that information exceeds its update weight, so the far edges seen by a few pixels keep it.
  double dampingScale(double data_information, int c) const {
    return damping_scale_ < 1.0 && data_information >= opt_.undamped_min_information_ratio * mu_[c] ? damping_scale_
                                                                                                      : 1.0;
  }
  void setDampingScale(double s) { damping_scale_ = s; }

  /// The image pairs at state s.
  std::vector<PairContext> pairs(const SurfaceState& s) const;
  /// The heights of the active vertices.
  Eigen::VectorXd activeHeights(const SurfaceState& s) const;
  /// from + alpha * step into *to; returns the largest fine height change [m].
  double apply(const Step& step, double alpha, const SurfaceState& from, SurfaceState* to) const;
  /// Per fine vertex: the pixels, excluded pixels and textured pixels of its triangles.
  void fillPixels(const Evaluation& ev, AlignmentReport* report) const;

 private:
  void selectWorkingSet(const GroundGrid& g, const SurfaceState& s);
  void buildBasis();
  void buildSmoothness(const GroundGrid& g);
  void buildPattern();

  const SurfaceAlignerOptions& opt_;
  const AlignmentProblem& prob_;
  StereoRig rig_;
  const ImagePyramid::Level* ref_ = nullptr;
  const cv::Mat* excluded_ = nullptr;
  int width_ = 0, height_ = 0;
  double data_scale_ = 1.0;
  float gtex2_ = 0.0f;
  int threads_ = 1;
  std::vector<TriangleGeometry> tris_;
  std::vector<int> active_;
  std::vector<int> local_;    ///< fine vertex -> compact index or -1
  bool identity_basis_ = true;
  std::vector<int> control_;
  int control_count_ = 0;
  SpMat basis_, basis_t_;
  Eigen::VectorXd mu_;
  double damping_scale_ = 1.0;  ///< scales mu_ (the final undamped step uses a small share)
  std::vector<Stencil> stencils_;
  double smooth_c2_ = 0.0;
  SpMat hzz_pattern_;
  std::vector<int> diag_index_;
  int global_count_ = 0;
  std::vector<int> photo_index_;
  std::vector<int> strides_;
};

}  // namespace aligner
}  // namespace stereo_ground_dem
