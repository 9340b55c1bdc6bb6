#pragma once
/// \file SurfaceAligner.hpp
/// One pyramid level of the direct ground-surface estimation (METHOD.md sections 2-4): Gauss-Newton
/// with the inverse compositional formulation over the reference image and one or more other
/// images, jointly for the mesh heights, the reference camera's motion and per-image gain/bias.
///
/// The heights live on a fine GroundGrid. A level estimates an increment z = z0 + B theta in the
/// span of a basis B (the piecewise-linear prolongation from a coarser mesh for hierarchical
/// meshing, a plane for the start-up plane fit, or the identity). The surface is always rendered
/// with the fine mesh, so the objective is the same at every level; only its subspace and the
/// image resolution change.
///
/// Cost (all terms are sums of squares, in chi^2-like units):
///   C = C_D + C_S + C_P, and each step adds the update constraint C_U = sum_c mu_c dtheta_c^2;
///   C_D = 4^level / sigma^2 * sum_pairs sum_pixels rho(I0[u] - a_j Ij[H_j u] - b_j), rho Cauchy;
///   C_S = sum_stencils rho_s(sqrt(lambda_s) s / h^2 (z_a - 2 z_b + z_c)) over the fine grid's rows,
///         columns and diagonals (h = s or s sqrt 2): approximately lambda_s * integral of squared
///         curvature where the surface bends gently, and a Cauchy rho_s beyond a bend of
///         smoothness_robust_scale_m, so that steps and curbs are not smeared;
///   C_P = sum_v info_v (z_v - prior_v)^2.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <string>
#include <vector>

#include "stereo_ground_dem/GroundGrid.hpp"
#include "stereo_ground_dem/ImagePyramid.hpp"
#include "stereo_ground_dem/PhotometricParams.hpp"
#include "stereo_ground_dem/Se3.hpp"
#include "stereo_ground_dem/StereoRig.hpp"
#include "stereo_ground_dem/VerticalMisalignment.hpp"

namespace stereo_ground_dem {

struct SurfaceAlignerOptions {
  int max_iterations = 8;                  ///< Gauss-Newton iterations per level
  int max_step_halvings = 2;               ///< a step that raises the cost is halved this often, then rejected
  double robust_scale_grey = 6.0;          ///< Cauchy scale [grey levels]; <= 0: plain least squares
  double image_noise_std_grey = 2.0;       ///< sigma of the photometric residual [grey levels]
  double smoothness_weight = 200.0;        ///< lambda_s [m^2]
  /// Cauchy scale of the second differences [m]; <= 0: quadratic smoothness. Bends much larger
  /// than this (a curb, a step) cost little more than this, so the surface can break there.
  double smoothness_robust_scale_m = 0.1;
  double min_depth_m = 3.0;                ///< triangles need all vertices at camera depth >= this [m]
  double max_depth_m = 40.0;               ///< ... and <= this [m]
  double max_lateral_m = 25.0;             ///< ... and |camera x| <= this [m]
  double converged_height_step_m = 5e-4;   ///< stop when the largest height update is below [m]
  double converged_translation_m = 1e-4;   ///< ... and the motion update below [m]
  double converged_rotation_rad = 1e-5;    ///< ... and [rad]
  double converged_relative_decrease = 2e-4;  ///< or when a step lowers the cost by less than this fraction
  int border_margin_px = 2;                ///< reference pixels this close to the border are unused
  double dark_level_grey = 1.5;            ///< reference / target values at or below: not used
  double saturated_level_grey = 253.5;     ///< values at or above: not used
  /// A used reference pixel counts as textured (AlignmentReport::vertex_textured_pixels) when its
  /// image gradient is at least this [grey/px at the level]: blank sky, glare or an untextured
  /// wall modelled as ground tell nothing about the heights there.
  double textured_gradient_grey_per_px = 1.0;
  double outside_penalty_factor = 3.0;     ///< a pixel warped outside its target costs rho(factor * scale)
  bool estimate_motion = false;            ///< 6-DoF twist of the reference camera
  /// After the iterations, one more step with the update constraint scaled by
  /// final_step_damping_scale: the damping then shapes the path, not the result (far vertices,
  /// where data is weak, otherwise stay near their starting heights).
  bool final_undamped_step = false;
  double final_step_damping_scale = 0.01;
  /// ... for the controls whose data information is at least this share of their update weight
  /// (the far edges, seen by a handful of pixels, keep their damping).
  double undamped_min_information_ratio = 1.0;
  int num_threads = 2;                     ///< threads for the pixel loop
  /// The height block of the normal equations is solved by conjugate gradients with a Jacobi
  /// preconditioner (measured on a KITTI frame, 4580 heights: 0.4 ms to 1e-4 relative error
  /// against 23 ms for Eigen's sparse LDLT), falling back to the sparse Cholesky factorization
  /// when CG does not converge; kCholesky always factorizes.
  enum class LinearSolver { kConjugateGradient, kCholesky };
  LinearSolver linear_solver = LinearSolver::kConjugateGradient;
  /// Relative residual of the CG solves. 1e-3 rather than 1e-4: a step needs no more, and the
  /// looser solve leaves the weakly determined directions (far ground, held by smoothness and
  /// damping) less resolved, which the zoo measured as equal or better everywhere (off-road 95th
  /// 9.3 -> 6.1 cm, shadows 1.12 -> 0.93 deg, rolling 8.3 -> 7.7 %; 3e-3 was worse again) and
  /// as less sensitive to rounding (docs/results.md, speed section).
  double cg_tolerance = 1e-3;
  int cg_max_iterations = 400;
  int cg_min_unknowns = 400;               ///< smaller systems are factorized (faster there)

  bool isValid(std::string* why) const;
};

/// One image paired with the reference image.
struct AlignerTarget {
  const ImagePyramid* pyramid = nullptr;
  /// true: the camera moves with the reference (stereo partner), its pose relative to the
  /// reference is target_T_reference; false: its pose in the ground frame, target_T_ground, is known.
  bool rig_fixed = true;
  Eigen::Isometry3d target_T_reference = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d target_T_ground = Eigen::Isometry3d::Identity();
  bool estimate_photometric = true;
  /// Use every other reference pixel (a checkerboard) for this pair: half the cost, for pairs
  /// whose information is mostly about the six motion parameters.
  bool checkerboard = false;
  /// The target's pixels sit this much lower than the geometry says: the row shift polynomial of
  /// VerticalMisalignment (coefficients c0..c5 [px at level 0] of (1, x, y, xy, x^2, y^2) in the
  /// target's normalized coordinates), a real rig's residual rectification error. All zero: none.
  std::array<double, VerticalMisalignment::kTerms> row_shift_px{};
  /// Optional per pyramid level: pixels of THIS target image not to sample (CV_8U, nonzero =
  /// excluded), e.g. the previous frame's obstacle pixels for a temporal pair: ground seen now
  /// where a car stood (or moved away from) is not compared with the car.
  const std::vector<cv::Mat>* excluded = nullptr;
  /// Optional per pyramid level: REFERENCE pixels this pair alone skips (CV_8U, nonzero =
  /// skipped), e.g. ground whose texture moved between the frames (a moving shadow) for a
  /// temporal pair, while the stereo pair still uses it.
  const std::vector<cv::Mat>* reference_excluded = nullptr;
};

/// What is estimated; updated in place by align().
struct SurfaceState {
  Eigen::Isometry3d camera_T_ground = Eigen::Isometry3d::Identity();  ///< the reference camera
  Eigen::VectorXd heights;                     ///< one per fine grid vertex [m]; NaN = not a surface
  std::vector<PhotometricParams> photometric;  ///< one per target
};

/// A Gaussian prior on the fine heights (incremental mode).
struct HeightPrior {
  Eigen::VectorXd mean;         ///< [m]
  Eigen::VectorXd information;  ///< [1/m^2]; 0 = no prior for this vertex
};

struct AlignmentProblem {
  const ImagePyramid* reference = nullptr;
  int level = 0;                         ///< pyramid level used for all images
  const StereoRig* rig = nullptr;        ///< intrinsics at level 0
  const GroundGrid* grid = nullptr;      ///< the fine grid the heights live on
  std::vector<AlignerTarget> targets;
  /// z = z0 + basis * theta; nullptr: the identity (every fine height is free).
  const Eigen::SparseMatrix<double, Eigen::RowMajor>* basis = nullptr;
  /// mu per basis column (or per fine vertex with the identity basis) [1/m^2 for heights].
  Eigen::VectorXd update_weight;
  const HeightPrior* prior = nullptr;    ///< optional
  /// Optional per-vertex mask (fine grid, 1 = may be used); empty: all vertices may be used.
  std::vector<uint8_t> vertex_mask;
  bool estimate_heights = true;
  /// Optional per pyramid level: reference pixels not to use (CV_8U, nonzero = excluded), e.g.
  /// obstacles found by the ObstacleDetector.
  const std::vector<cv::Mat>* excluded = nullptr;
  /// Compute AlignmentReport::motion_information at the final state (one extra factorization).
  bool want_motion_information = false;
  /// Optional other starting pose of the reference camera: evaluated with the state's own (one more
  /// evaluation, the same working set) and taken when its cost per sample is
  /// below alternative_win_ratio times the state's (AlignmentReport::started_from_alternative).
  const Eigen::Isometry3d* alternative_start = nullptr;
  double alternative_win_ratio = 1.0;
};

struct AlignmentReport {
  int level = -1;                    ///< the pyramid level aligned
  int pairs = 0;                     ///< image pairs in the data term
  bool motion = false;               ///< the motion was estimated
  bool heights = false;              ///< the heights were estimated
  int iterations = 0;
  int accepted_steps = 0;
  bool converged = false;
  /// The last Gauss-Newton step raised the cost at every halving: the iterations stopped there and
  /// the final undamped step, solved from the same linearization, was not tried.
  bool stalled = false;
  int final_step_evaluations = 0;    ///< evaluations of the final undamped step's trials
  bool degenerate = false;           ///< the normal equations could not be solved
  double initial_cost = 0.0;         ///< at the start taken (the alternative's, if it won)
  bool started_from_alternative = false;  ///< AlignmentProblem::alternative_start won
  double final_cost = 0.0;
  double data_cost = 0.0, smoothness_cost = 0.0, prior_cost = 0.0;
  int valid_pixels = 0;              ///< pixel-pair samples in the data term at the end
  int outside_pixels = 0;            ///< samples warped outside their target image
  double median_abs_residual_grey = 0.0;
  std::vector<double> target_median_abs_residual_grey;  ///< the same per target, in problem order
  int working_triangles = 0;
  int active_vertices = 0;
  int evaluations = 0;               ///< rasterize + residual passes
  double setup_ms = 0.0;             ///< working set, basis, pattern
  double evaluate_ms = 0.0;          ///< rasterization and pixel loops
  double raster_ms = 0.0;            ///< ... of which rasterization, slots and homographies
  double solve_ms = 0.0;             ///< normal equations and their solution
  int cg_fallbacks = 0;              ///< CG solves that did not converge (Cholesky used)
  /// Per fine vertex, from the final linearization: diagonal of the data term's normal matrix
  /// (information about the height) [1/m^2], and the number of pixels in its triangles.
  Eigen::VectorXd vertex_information;
  Eigen::VectorXi vertex_pixels;
  /// Per fine vertex: pixels of its triangles excluded by AlignmentProblem::excluded (obstacles).
  Eigen::VectorXi vertex_excluded_pixels;
  /// Per fine vertex: the used pixels of its triangles that are textured
  /// (SurfaceAlignerOptions::textured_gradient_grey_per_px).
  Eigen::VectorXi vertex_textured_pixels;
  /// Information of the motion (6x6, heights marginalized) if motion was estimated and
  /// AlignmentProblem::want_motion_information was set.
  Matrix6d motion_information = Matrix6d::Zero();
};

/// Not thread-safe per thread: each thread keeps one reusable workspace (buffers that would
/// otherwise be reallocated every iteration), so concurrent align() calls must come from
/// different threads.
class SurfaceAligner {
 public:
  explicit SurfaceAligner(const SurfaceAlignerOptions& options);

  /// Runs Gauss-Newton at problem.level and updates `state`. Throws std::invalid_argument on an
  /// inconsistent problem (missing images, sizes that do not match the grid, ...).
  AlignmentReport align(const AlignmentProblem& problem, SurfaceState& state) const;

  /// The surface's inverse depth [1/m] at every reference pixel of `level` (0 = no surface), and
  /// optionally the triangle label of each pixel (-1 none); z-buffered like the estimation.
  cv::Mat renderInverseDepth(const AlignmentProblem& problem, const SurfaceState& state,
                             cv::Mat* labels = nullptr) const;

  const SurfaceAlignerOptions& options() const { return options_; }

 private:
  SurfaceAlignerOptions options_;
};

}  // namespace stereo_ground_dem
