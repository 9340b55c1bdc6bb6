#include "stereo_ground_dem/aligner/HeightSystemSolver.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <stdexcept>

#include "stereo_ground_dem/PlaneGeometry.hpp"

namespace stereo_ground_dem {
namespace aligner {

namespace {
using Matrix32d = Eigen::Matrix<double, 3, 2>;
using Matrix36d = Eigen::Matrix<double, 3, 6>;
}  // namespace

bool HeightSystemSolver::augmentedCg(const SpMat& a, const Eigen::MatrixXd& b, const Eigen::MatrixXd& d,
                                     const Eigen::VectorXd& r, const Eigen::VectorXd& q, Eigen::VectorXd* x,
                                     Eigen::VectorXd* y) const {
  const SurfaceAlignerOptions& opt = level_.options();
  const Eigen::Index n = a.rows(), m = d.rows();
  const Eigen::VectorXd inv_diag = a.diagonal().cwiseMax(1e-300).cwiseInverse();
  const Eigen::LDLT<Eigen::MatrixXd> dinv(d);
  if (m > 0 && (dinv.info() != Eigen::Success || !dinv.isPositive())) return false;
  auto apply = [&](const Eigen::VectorXd& pc, const Eigen::VectorXd& pg, Eigen::VectorXd* oc, Eigen::VectorXd* og) {
    *oc = a * pc;
    if (m > 0) {
      *oc += b * pg;
      *og = b.transpose() * pc + d * pg;
    }
  };
  x->setZero(n);
  y->setZero(m);
  Eigen::VectorXd rc = r, rg = q, zc = inv_diag.cwiseProduct(rc), zg = m > 0 ? Eigen::VectorXd(dinv.solve(rg)) : rg;
  Eigen::VectorXd pc = zc, pg = zg, ac, ag(m);
  double rz = rc.dot(zc) + rg.dot(zg);
  const double b_norm = std::sqrt(r.squaredNorm() + q.squaredNorm());
  if (b_norm == 0.0) return true;
  for (int it = 0; it < opt.cg_max_iterations; ++it) {
    apply(pc, pg, &ac, &ag);
    const double pap = pc.dot(ac) + (m > 0 ? pg.dot(ag) : 0.0);
    if (!(pap > 0.0)) return false;
    const double alpha = rz / pap;
    *x += alpha * pc;
    rc -= alpha * ac;
    if (m > 0) {
      *y += alpha * pg;
      rg -= alpha * ag;
    }
    if (std::sqrt(rc.squaredNorm() + rg.squaredNorm()) < opt.cg_tolerance * b_norm) return true;
    zc = inv_diag.cwiseProduct(rc);
    if (m > 0) zg = dinv.solve(rg);
    const double rz_new = rc.dot(zc) + (m > 0 ? rg.dot(zg) : 0.0);
    const double beta = rz_new / rz;
    rz = rz_new;
    pc = zc + beta * pc;
    if (m > 0) pg = zg + beta * pg;
  }
  // Not at the tolerance: an inexact Newton step is still a descent direction worth trying
  // (the step is accepted only if the cost drops) when the residual fell by 100x.
  return std::sqrt(rc.squaredNorm() + rg.squaredNorm()) < 1e-2 * b_norm;
}

Step HeightSystemSolver::solve(const SurfaceState& s, const Evaluation& ev, AlignmentReport* report, bool need_schur) {
  const SurfaceAlignerOptions& opt = level_.options();
  const AlignmentProblem& prob = level_.problem();
  const std::vector<TriangleGeometry>& tris = level_.triangles();
  const std::vector<int>& active = level_.active();
  const int control_count = level_.controlCount();
  const Evaluation& sum = ev;
  const std::vector<PairContext> pc = level_.pairs(s);
  const int na = level_.activeCount();
  const int ng = level_.globalCount();
  if (!ev.sums) throw std::logic_error("HeightSystemSolver: the evaluation has no normal-equation sums");
  // Height block on the fixed pattern: smoothness + data + prior.
  SpMat& hzz = hzz_;
  Eigen::Map<Eigen::VectorXd> values(hzz.valuePtr(), hzz.nonZeros());
  values.setZero();
  Eigen::VectorXd gz = Eigen::VectorXd::Zero(na);
  Eigen::VectorXd data_diag = Eigen::VectorXd::Zero(na);
  // rows: heights (row-major: a triangle's rows are written together)
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> hzg_rows =
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>::Zero(prob.estimate_heights ? na : 0, ng);
  Eigen::MatrixXd hgg = Eigen::MatrixXd::Zero(ng, ng);
  Eigen::VectorXd gg = Eigen::VectorXd::Zero(ng);
  const double ks = level_.dataScale();
  static constexpr double kCoef[3] = {1.0, -2.0, 1.0};
  for (size_t k = 0; k < level_.stencils().size(); ++k) {
    const Stencil& st = level_.stencils()[k];
    const double om = ev.smooth_weight[k];
    const double ww = om * st.w * st.w;
    for (int a = 0; a < 3; ++a) {
      gz[st.v[a]] += om * ev.smooth_residual[k] * st.w * kCoef[a];
      for (int b = 0; b < 3; ++b) values[st.idx[a * 3 + b]] += ww * kCoef[a] * kCoef[b];
    }
  }
  for (size_t j = 0; j < pc.size(); ++j) {
    const PairContext& p = pc[j];
    const bool rig = prob.targets[j].rig_fixed;
    const int pi = p.photo_index;
    const int stride = level_.strides()[j];
    // a rig pair's motion blocks, summed over its slots (the upper triangle of the 6x6)
    Matrix6d rig_mm = Matrix6d::Zero();
    Vector6d rig_me = Vector6d::Zero();
    Matrix62d rig_mp = Matrix62d::Zero();
    // per triangle: what the heights need, and a rig pair's motion (nothing else when the heights
    // are fixed: a world-fixed pair then has no per-triangle sums)
    const size_t slots = stride > 0 && (prob.estimate_heights || (rig && opt.estimate_motion)) ? ev.slot_tri.size() : 0;
    for (size_t k2 = 0; k2 < slots; ++k2) {
      const TriangleGeometry& t = tris[static_cast<size_t>(ev.slot_tri[k2])];
      if (sum.tri_pixels[k2] == 0) continue;
      const double* acc = sum.tri[j].data() + k2 * static_cast<size_t>(stride);
      Eigen::Matrix3d dd;
      dd << acc[0], acc[1], acc[2], acc[1], acc[3], acc[4], acc[2], acc[4], acc[5];
      const Eigen::Vector3d de(acc[6], acc[7], acc[8]);
      Matrix32d dp;
      dp << acc[9], acc[10], acc[11], acc[12], acc[13], acc[14];
      // the plane and its Jacobian at the evaluation's state (not the level's last evaluation)
      const Eigen::Vector3d& m = ev.slot_m[k2];
      const double scale = PlaneGeometry::deltaScale(m, p.t_prime);
      const Eigen::Matrix3d a = scale * ev.slot_dm_dz[k2];  // delta = a * dz
      if (prob.estimate_heights) {
        const Eigen::Matrix3d atd = ks * a.transpose() * dd;
        const Eigen::Matrix3d hz = atd * a;
        const Eigen::Vector3d g3 = ks * a.transpose() * de;
        for (int r = 0; r < 3; ++r) {
          gz[t.local[static_cast<size_t>(r)]] += g3[r];
          data_diag[t.local[static_cast<size_t>(r)]] += hz(r, r);
          for (int c = 0; c < 3; ++c) values[t.value_index[static_cast<size_t>(r * 3 + c)]] += hz(r, c);
        }
        if (pi >= 0) {
          const Matrix32d hzp = ks * a.transpose() * dp;
          for (int r = 0; r < 3; ++r) hzg_rows.block<1, 2>(t.local[static_cast<size_t>(r)], pi) += hzp.row(r);
        }
      }
      if (opt.estimate_motion) {
        Matrix36d hzm;
        if (rig) {
          // bm = d delta / d xi = scale [-m m^T, -[m]_x] (PlaneGeometry::cameraPlaneMotionJacobian)
          const Matrix36d bm = scale * PlaneGeometry::cameraPlaneMotionJacobian(m);
          const Matrix36d dbm = ks * (dd * bm);  // ks dd bm, shared by three blocks
          if (prob.estimate_heights) hzm.noalias() = a.transpose() * dbm;
          for (int r = 0; r < 6; ++r) {
            for (int q = r; q < 6; ++q)
              rig_mm(r, q) += bm(0, r) * dbm(0, q) + bm(1, r) * dbm(1, q) + bm(2, r) * dbm(2, q);
            rig_me[r] += ks * (bm(0, r) * de[0] + bm(1, r) * de[1] + bm(2, r) * de[2]);
            if (pi >= 0) {
              rig_mp(r, 0) += ks * (bm(0, r) * dp(0, 0) + bm(1, r) * dp(1, 0) + bm(2, r) * dp(2, 0));
              rig_mp(r, 1) += ks * (bm(0, r) * dp(0, 1) + bm(1, r) * dp(1, 1) + bm(2, r) * dp(2, 1));
            }
          }
        } else if (prob.estimate_heights) {
          const Eigen::Map<const Eigen::Matrix<double, 3, 6, Eigen::RowMajor>> dm(acc + 15);
          hzm = ks * a.transpose() * dm;
        }
        if (prob.estimate_heights) {
          for (int r = 0; r < 3; ++r) hzg_rows.block<1, 6>(t.local[static_cast<size_t>(r)], 0) += hzm.row(r);
        }
      }
    }
    if (rig && opt.estimate_motion) {
      hgg.topLeftCorner<6, 6>() += rig_mm.selfadjointView<Eigen::Upper>().toDenseMatrix();
      gg.head<6>() += rig_me;
      if (pi >= 0) {
        hgg.block<6, 2>(0, pi) += rig_mp;
        hgg.block<2, 6>(pi, 0) += rig_mp.transpose();
      }
    }
  }
  const Eigen::MatrixXd hzg = hzg_rows;
  // the pairs' own photometric and motion blocks
  for (size_t j = 0; j < pc.size(); ++j) {
    const PairContext& p = pc[j];
    const int pi = p.photo_index;
    const PairAccumulator& pa = sum.pair[j];
    if (pi >= 0) {
      hgg.block<2, 2>(pi, pi) += ks * pa.pp;
      gg.segment<2>(pi) += ks * pa.pe;
    }
    if (p.world) {
      hgg.topLeftCorner<6, 6>() += ks * pa.mm;
      gg.head<6>() += ks * pa.me;
      if (pi >= 0) {
        hgg.block<6, 2>(0, pi) += ks * pa.mp;
        hgg.block<2, 6>(pi, 0) += ks * pa.mp.transpose();
      }
    }
  }
  // A pair whose pixels are all masked or outside leaves its photometric block empty; a tiny
  // Levenberg damping keeps the global block invertible (the step for it is then ~0).
  for (int k = 0; k < ng; ++k) hgg(k, k) += 1e-9 * (1.0 + hgg(k, k)) + (hgg(k, k) == 0.0 ? 1.0 : 0.0);
  report->vertex_information = Eigen::VectorXd::Zero(prob.grid->vertexCount());
  for (int a = 0; a < na; ++a) report->vertex_information[active[static_cast<size_t>(a)]] = data_diag[a];

  Step step;
  step.dglobal = Eigen::VectorXd::Zero(ng);
  if (!prob.estimate_heights || control_count == 0) {
    step.dtheta = Eigen::VectorXd::Zero(control_count);
    if (ng == 0) return step;
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(hgg);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) {
      report->degenerate = true;
      return step;
    }
    step.dglobal = ldlt.solve(-gg);
    step.ok = step.dglobal.allFinite();
    if (opt.estimate_motion) report->motion_information = hgg.topLeftCorner<6, 6>();
    return step;
  }
  // Smoothness and prior gradients on the fine active heights.
  if (prob.prior) {
    for (int a = 0; a < na; ++a) {
      const int v = active[static_cast<size_t>(a)];
      const double info = prob.prior->information[v];
      if (info > 0.0) {
        values[level_.diagonalIndex()[static_cast<size_t>(a)]] += info;
        gz[a] += info * (s.heights[v] - prob.prior->mean[v]);
      }
    }
  }
  // Project onto the basis; the update constraint on the controls.
  Eigen::VectorXd gc;
  Eigen::MatrixXd hcg;
  const SpMat* hcc = nullptr;
  if (level_.identityBasis()) {
    for (int c = 0; c < control_count; ++c)
      values[level_.diagonalIndex()[static_cast<size_t>(c)]] += level_.dampingScale(data_diag[c], c) * level_.updateWeights()[c];
    hcc = &hzz;
    gc = gz;
    hcg = hzg;
  } else {
    hcc_ = level_.basisTransposed() * hzz * level_.basis();
    const Eigen::VectorXd control_data = level_.basisTransposed() * data_diag;
    for (int c = 0; c < control_count; ++c)
      hcc_.coeffRef(c, c) += level_.dampingScale(control_data[c], c) * level_.updateWeights()[c];
    hcc = &hcc_;
    gc = level_.basisTransposed() * gz;
    hcg = level_.basisTransposed() * hzg;
  }
  // Conjugate gradients on the whole system [hcc hcg; hcg^T hgg] (one run, block-Jacobi
  // preconditioner), or the Schur complement on the globals with the sparse Cholesky
  // factorization of hcc (small systems, fallback, and when the marginal information of the
  // motion is wanted).
  const bool use_cg = opt.linear_solver == SurfaceAlignerOptions::LinearSolver::kConjugateGradient &&
                      hcc->rows() >= opt.cg_min_unknowns && !need_schur;
  if (use_cg) {
    Eigen::VectorXd xc, xg;
    if (augmentedCg(*hcc, hcg, hgg, gc, gg, &xc, &xg)) {
      step.dtheta = -xc;
      step.dglobal = -xg;
      step.ok = step.dtheta.allFinite() && step.dglobal.allFinite();
      if (step.ok) return step;
    }
    report->cg_fallbacks++;
  }
  if (!analyzed_ || analyzed_nnz_ != hcc->nonZeros()) {
    chol_.analyzePattern(*hcc);
    analyzed_ = true;
    analyzed_nnz_ = hcc->nonZeros();
  }
  chol_.factorize(*hcc);
  if (chol_.info() != Eigen::Success) {
    report->degenerate = true;
    return step;
  }
  if (ng > 0) {
    const Eigen::MatrixXd hinv_hcg = chol_.solve(hcg);
    const Eigen::VectorXd hinv_gc = chol_.solve(gc);
    const Eigen::MatrixXd schur = hgg - hcg.transpose() * hinv_hcg;
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(schur);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) {
      report->degenerate = true;
      return step;
    }
    step.dglobal = ldlt.solve(-gg + hcg.transpose() * hinv_gc);
    step.dtheta = -(hinv_gc + hinv_hcg * step.dglobal);
    if (opt.estimate_motion) {
      // Motion information with the heights marginalized (data + regularizers).
      report->motion_information = schur.topLeftCorner<6, 6>();
    }
  } else {
    step.dtheta = chol_.solve(-gc);
  }
  step.ok = step.dtheta.allFinite() && step.dglobal.allFinite();
  if (!step.ok) report->degenerate = true;
  return step;
}

}  // namespace aligner
}  // namespace stereo_ground_dem
