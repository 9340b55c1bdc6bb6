#pragma once
/// \file HeightSystemSolver.hpp
/// The Gauss-Newton step of an AlignmentLevel from an Evaluation: assembles the normal equations
/// of the data term (per triangle, from the evaluation's sums), the smoothness (IRLS weights), the
/// prior and the update constraint, projects the height block onto the level's basis, and solves
/// it with the motion and photometric unknowns as a dense border: preconditioned conjugate
/// gradients on the whole system, or the Schur complement on the globals with a sparse Cholesky
/// factorization of the height block (small systems, a CG that did not converge, and when the
/// motion's marginal information is wanted). Internal to SurfaceAligner.

#include <Eigen/Core>
#include <Eigen/SparseCholesky>

#include "stereo_ground_dem/aligner/AlignmentLevel.hpp"
#include "stereo_ground_dem/aligner/Evaluation.hpp"

namespace stereo_ground_dem {
namespace aligner {

class HeightSystemSolver {
 public:
  explicit HeightSystemSolver(const AlignmentLevel& level) : level_(level), hzz_(level.heightPattern()) {}

  /// The step at state s evaluated as `ev` (linearized with ev's own planes, whatever was
  /// evaluated since). Fills the
  /// report's vertex_information (the data term's diagonal) and, with need_schur or a motion-only
  /// problem, its motion_information; report->degenerate when the system cannot be solved.
  Step solve(const SurfaceState& s, const Evaluation& ev, AlignmentReport* report, bool need_schur = false);

 private:
  /// Preconditioned conjugate gradients for [a b; b^T d] [x; y] = [r; q] with a sparse SPD,
  /// preconditioner blockdiag(diag(a), d). Returns false if it did not converge.
  bool augmentedCg(const SpMat& a, const Eigen::MatrixXd& b, const Eigen::MatrixXd& d, const Eigen::VectorXd& r,
                   const Eigen::VectorXd& q, Eigen::VectorXd* x, Eigen::VectorXd* y) const;

  const AlignmentLevel& level_;
  SpMat hzz_, hcc_;  ///< the height block on the fixed pattern; projected onto the basis
  Eigen::SimplicialLDLT<SpMat> chol_;
  bool analyzed_ = false;
  Eigen::Index analyzed_nnz_ = 0;
};

}  // namespace aligner
}  // namespace stereo_ground_dem
