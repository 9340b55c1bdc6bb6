#include "stereo_ground_dem/aligner/AlignmentLevel.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "stereo_ground_dem/PlaneGeometry.hpp"

namespace stereo_ground_dem {
namespace aligner {

AlignmentLevel::AlignmentLevel(const SurfaceAlignerOptions& o, const AlignmentProblem& p, const SurfaceState& s)
    : opt_(o), prob_(p) {
  const GroundGrid& g = *p.grid;
  rig_ = p.rig->atLevel(p.level);
  ref_ = &p.reference->level(p.level);
  width_ = ref_->image.cols;
  height_ = ref_->image.rows;
  if (p.excluded && static_cast<int>(p.excluded->size()) > p.level) {
    excluded_ = &(*p.excluded)[static_cast<size_t>(p.level)];
    if (excluded_->size() != ref_->image.size() || excluded_->type() != CV_8U) {
      throw std::invalid_argument("SurfaceAligner: excluded mask does not match the pyramid level");
    }
  }
  data_scale_ = std::ldexp(1.0, 2 * p.level) / (o.image_noise_std_grey * o.image_noise_std_grey);
  gtex2_ = static_cast<float>(o.textured_gradient_grey_per_px * o.textured_gradient_grey_per_px);
  selectWorkingSet(g, s);
  buildBasis();
  if (p.estimate_heights) {  // motion/photometry only: no height block to build
    buildSmoothness(g);
    buildPattern();
  }
  global_count_ = o.estimate_motion ? 6 : 0;
  photo_index_.assign(p.targets.size(), -1);
  for (size_t j = 0; j < p.targets.size(); ++j) {
    if (p.targets[j].estimate_photometric) {
      photo_index_[j] = global_count_;
      global_count_ += 2;
    }
    // A world-fixed pair's motion block is summed per pair; per triangle only what the heights
    // need (nothing when they are fixed). A rig pair's motion block comes from its triangles.
    const bool world = o.estimate_motion && !p.targets[j].rig_fixed;
    strides_.push_back(world ? (p.estimate_heights ? kStrideWorld : 0) : kStrideRig);
  }
  threads_ = std::max(1, o.num_threads);
}

std::vector<PairContext> AlignmentLevel::pairs(const SurfaceState& s) const {
  std::vector<PairContext> out(prob_.targets.size());
  for (size_t j = 0; j < out.size(); ++j) {
    const AlignerTarget& t = prob_.targets[j];
    PairContext& c = out[j];
    c.target_T_reference = t.rig_fixed ? t.target_T_reference : t.target_T_ground * s.camera_T_ground.inverse();
    const Eigen::Matrix3d& r = c.target_T_reference.linear();
    const Eigen::Vector3d& tt = c.target_T_reference.translation();
    c.t_prime = r.transpose() * tt;
    const bool no_rotation = (r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12;
    if (no_rotation && std::abs(tt.z()) < 1e-12) {
      c.kind = std::abs(tt.y()) < 1e-12 ? kWarpHorizontal : kWarpAffine;
    } else {
      c.kind = kWarpProjective;
    }
    const double level_scale = std::ldexp(1.0, -prob_.level);  // level-0 px -> this level's px
    for (size_t a = 0; a < c.shift.size(); ++a) {
      c.shift[a] = static_cast<float>(level_scale * t.row_shift_px[a]);
      c.row_shift = c.row_shift || t.row_shift_px[a] != 0.0;
    }
    c.world = opt_.estimate_motion && !t.rig_fixed;
    c.checkerboard = t.checkerboard;
    c.photo_index = photo_index_[j];
    c.photometric = s.photometric[j];
    c.image = &t.pyramid->level(prob_.level).image;
    if (t.reference_excluded && static_cast<int>(t.reference_excluded->size()) > prob_.level &&
        !(*t.reference_excluded)[static_cast<size_t>(prob_.level)].empty()) {
      c.reference_excluded = &(*t.reference_excluded)[static_cast<size_t>(prob_.level)];
      if (c.reference_excluded->size() != ref_->image.size() || c.reference_excluded->type() != CV_8U) {
        throw std::invalid_argument("SurfaceAligner: a target's reference mask does not match the pyramid level");
      }
    }
    if (t.excluded && static_cast<int>(t.excluded->size()) > prob_.level &&
        !(*t.excluded)[static_cast<size_t>(prob_.level)].empty()) {
      c.target_excluded = &(*t.excluded)[static_cast<size_t>(prob_.level)];
      if (c.target_excluded->size() != c.image->size() || c.target_excluded->type() != CV_8U) {
        throw std::invalid_argument("SurfaceAligner: a target's excluded mask does not match its pyramid level");
      }
    }
  }
  return out;
}

Eigen::VectorXd AlignmentLevel::activeHeights(const SurfaceState& s) const {
  Eigen::VectorXd za(activeCount());
  for (size_t a = 0; a < active_.size(); ++a) za[static_cast<Eigen::Index>(a)] = s.heights[active_[a]];
  return za;
}

double AlignmentLevel::apply(const Step& st, double alpha, const SurfaceState& from, SurfaceState* to) const {
  *to = from;
  double max_dz = 0.0;
  if (prob_.estimate_heights && st.dtheta.size() > 0) {
    if (identity_basis_) {
      for (size_t a = 0; a < active_.size(); ++a) {
        const double d = alpha * st.dtheta[static_cast<Eigen::Index>(a)];
        to->heights[active_[a]] += d;
        max_dz = std::max(max_dz, std::abs(d));
      }
    } else {
      Eigen::VectorXd full = Eigen::VectorXd::Zero(prob_.basis->cols());
      for (int c = 0; c < control_count_; ++c) full[control_[static_cast<size_t>(c)]] = alpha * st.dtheta[c];
      const Eigen::VectorXd dz = (*prob_.basis) * full;
      for (Eigen::Index v = 0; v < dz.size(); ++v) {
        if (std::isfinite(to->heights[v]) && dz[v] != 0.0) {
          to->heights[v] += dz[v];
          max_dz = std::max(max_dz, std::abs(dz[v]));
        }
      }
    }
  }
  if (opt_.estimate_motion) {
    to->camera_T_ground = Se3::exp(alpha * st.dglobal.head<6>()) * from.camera_T_ground;
  }
  for (size_t j = 0; j < prob_.targets.size(); ++j) {
    const int pi = photo_index_[j];
    if (pi < 0) continue;
    to->photometric[j] = from.photometric[j].composedWithInverse(alpha * st.dglobal[pi], alpha * st.dglobal[pi + 1]);
  }
  return max_dz;
}

void AlignmentLevel::fillPixels(const Evaluation& ev, AlignmentReport* report) const {
  report->vertex_pixels = Eigen::VectorXi::Zero(prob_.grid->vertexCount());
  report->vertex_excluded_pixels = Eigen::VectorXi::Zero(prob_.grid->vertexCount());
  report->vertex_textured_pixels = Eigen::VectorXi::Zero(prob_.grid->vertexCount());
  for (size_t k2 = 0; k2 < ev.slot_tri.size(); ++k2) {
    const TriangleGeometry& t = tris_[static_cast<size_t>(ev.slot_tri[k2])];
    for (int a = 0; a < 3; ++a) {
      report->vertex_pixels[t.vertex[static_cast<size_t>(a)]] += ev.tri_pixels[k2];
      report->vertex_excluded_pixels[t.vertex[static_cast<size_t>(a)]] += ev.tri_excluded[k2];
      report->vertex_textured_pixels[t.vertex[static_cast<size_t>(a)]] += ev.tri_textured[k2];
    }
  }
}

void AlignmentLevel::selectWorkingSet(const GroundGrid& g, const SurfaceState& s) {
  const int nv = g.vertexCount();
  if (s.heights.size() != nv) throw std::invalid_argument("SurfaceAligner: heights do not match the grid");
  // vertex eligibility: finite height, enabled, within the depth / lateral range
  std::vector<uint8_t> ok(static_cast<size_t>(nv), 0);
  std::vector<Eigen::Vector2d> pix(static_cast<size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    if (!std::isfinite(s.heights[v])) continue;
    if (!prob_.vertex_mask.empty() && !prob_.vertex_mask[static_cast<size_t>(v)]) continue;
    const Eigen::Vector2d xy = g.position(v);
    const Eigen::Vector3d xc = s.camera_T_ground * Eigen::Vector3d(xy.x(), xy.y(), s.heights[v]);
    if (xc.z() < opt_.min_depth_m || xc.z() > opt_.max_depth_m || std::abs(xc.x()) > opt_.max_lateral_m) continue;
    ok[static_cast<size_t>(v)] = 1;
    pix[static_cast<size_t>(v)] = {rig_.fx * xc.x() / xc.z() + rig_.cx, rig_.fy * xc.y() / xc.z() + rig_.cy};
  }
  std::vector<int> local(static_cast<size_t>(nv), -1);
  // The triangles in GroundGrid order (t = 2 (r (cols - 1) + c) + {0, 1}: GroundGrid::triangle)
  // whose vertices are eligible and whose image bounding box meets the image; counted first.
  std::vector<std::array<int, 3>> kept;
  kept.reserve(static_cast<size_t>(g.triangleCount()));
  for (int r = 0; r + 1 < g.rows; ++r) {
    for (int c = 0; c + 1 < g.cols; ++c) {
      const int v00 = g.index(r, c), v11 = v00 + g.cols + 1;
      for (const std::array<int, 3>& tv : {std::array<int, 3>{v00, v00 + 1, v11}, std::array<int, 3>{v00, v11, v00 + g.cols}}) {
        if (!ok[static_cast<size_t>(tv[0])] || !ok[static_cast<size_t>(tv[1])] || !ok[static_cast<size_t>(tv[2])]) continue;
        double umin = 1e30, umax = -1e30, vmin = 1e30, vmax = -1e30;
        for (int a : tv) {
          const auto& p = pix[static_cast<size_t>(a)];
          umin = std::min(umin, p.x());
          umax = std::max(umax, p.x());
          vmin = std::min(vmin, p.y());
          vmax = std::max(vmax, p.y());
        }
        if (umax < 0 || vmax < 0 || umin > width_ - 1 || vmin > height_ - 1) continue;
        kept.push_back(tv);
      }
    }
  }
  tris_.reserve(kept.size());
  active_.reserve(std::min(kept.size(), static_cast<size_t>(nv)));
  for (const std::array<int, 3>& tv : kept) {
    TriangleGeometry tg;
    tg.vertex = tv;
    std::array<Eigen::Vector2d, 3> xy;
    for (int a = 0; a < 3; ++a) {
      const int v = tv[static_cast<size_t>(a)];
      xy[static_cast<size_t>(a)] = g.position(v);
      if (local[static_cast<size_t>(v)] < 0) {
        local[static_cast<size_t>(v)] = static_cast<int>(active_.size());
        active_.push_back(v);
      }
      tg.local[static_cast<size_t>(a)] = local[static_cast<size_t>(v)];
    }
    tg.heights_to_plane = PlaneGeometry::heightsToPlane(xy);
    tris_.push_back(tg);
  }
  local_ = std::move(local);
}

void AlignmentLevel::buildBasis() {
  const int na = activeCount();
  if (prob_.basis == nullptr) {
    identity_basis_ = true;
    control_count_ = prob_.estimate_heights ? na : 0;
    mu_.resize(control_count_);
    for (int a = 0; a < control_count_; ++a) {
      mu_[a] = prob_.update_weight.size() > 0 ? prob_.update_weight[active_[static_cast<size_t>(a)]] : 0.0;
    }
    return;
  }
  identity_basis_ = false;
  const auto& b = *prob_.basis;
  if (b.rows() != prob_.grid->vertexCount()) throw std::invalid_argument("SurfaceAligner: basis rows != grid vertices");
  std::vector<int> col_local(static_cast<size_t>(b.cols()), -1);
  std::vector<Eigen::Triplet<double>> trip;
  for (int a = 0; a < na; ++a) {
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(b, active_[static_cast<size_t>(a)]); it; ++it) {
      if (it.value() == 0.0) continue;
      int& cl = col_local[static_cast<size_t>(it.col())];
      if (cl < 0) {
        cl = static_cast<int>(control_.size());
        control_.push_back(static_cast<int>(it.col()));
      }
      trip.emplace_back(a, cl, it.value());
    }
  }
  control_count_ = prob_.estimate_heights ? static_cast<int>(control_.size()) : 0;
  basis_.resize(na, static_cast<int>(control_.size()));
  basis_.setFromTriplets(trip.begin(), trip.end());
  basis_t_ = basis_.transpose();
  mu_.resize(static_cast<Eigen::Index>(control_.size()));
  for (size_t c = 0; c < control_.size(); ++c) {
    mu_[static_cast<Eigen::Index>(c)] = prob_.update_weight.size() > 0 ? prob_.update_weight[control_[c]] : 0.0;
  }
}

void AlignmentLevel::buildSmoothness(const GroundGrid& g) {
  const double s = g.resolution_m;
  const double w_axis = std::sqrt(opt_.smoothness_weight) / s;
  const double w_diag = std::sqrt(opt_.smoothness_weight) / (2.0 * s);
  stencils_.clear();
  auto add = [&](int r, int c, int dr, int dc, double w) {
    if (!g.contains(r - dr, c - dc) || !g.contains(r + dr, c + dc)) return;
    const int a = local_[static_cast<size_t>(g.index(r - dr, c - dc))];
    const int b = local_[static_cast<size_t>(g.index(r, c))];
    const int d = local_[static_cast<size_t>(g.index(r + dr, c + dc))];
    if (a < 0 || b < 0 || d < 0) return;
    Stencil st;
    st.v = {a, b, d};
    st.w = w;
    stencils_.push_back(st);
  };
  if (opt_.smoothness_weight > 0.0) {
    for (int v : active_) {
      const int r = g.rowOf(v), c = g.colOf(v);
      add(r, c, 0, 1, w_axis);
      add(r, c, 1, 0, w_axis);
      add(r, c, 1, 1, w_diag);
    }
  }
  // Robust scale of a stencil's second difference [m]: larger bends (a curb, a step) are
  // down-weighted (Cauchy), so the surface may break there instead of smearing the step.
  smooth_c2_ = opt_.smoothness_robust_scale_m > 0.0 ? opt_.smoothness_robust_scale_m * opt_.smoothness_robust_scale_m
                                                    : 0.0;
}

void AlignmentLevel::buildPattern() {
  // Column a's rows are the vertices sharing a triangle or a stencil with a, and a itself. Built
  // column by column from each vertex's incident triangles and stencils (counting sort), with a
  // marker array against duplicates; each column's rows sorted; then every triangle's and
  // stencil's 3x3 block is located through the column's row positions.
  const int na = activeCount();
  const size_t nt = tris_.size(), nst = stencils_.size();
  // incidence: element e = triangle t (e = t) or stencil s (e = nt + s), per vertex
  std::vector<int> start(static_cast<size_t>(na) + 1, 0);
  for (const auto& t : tris_)
    for (int v : t.local) ++start[static_cast<size_t>(v) + 1];
  for (const auto& st : stencils_)
    for (int v : st.v) ++start[static_cast<size_t>(v) + 1];
  for (int a = 0; a < na; ++a) start[static_cast<size_t>(a) + 1] += start[static_cast<size_t>(a)];
  std::vector<int> incident(static_cast<size_t>(start.back()));
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (size_t t = 0; t < nt; ++t)
    for (int v : tris_[t].local) incident[static_cast<size_t>(fill[static_cast<size_t>(v)]++)] = static_cast<int>(t);
  for (size_t s = 0; s < nst; ++s)
    for (int v : stencils_[s].v) incident[static_cast<size_t>(fill[static_cast<size_t>(v)]++)] = static_cast<int>(nt + s);
  auto vertices = [&](int e) -> const std::array<int, 3>& {
    return e < static_cast<int>(nt) ? tris_[static_cast<size_t>(e)].local : stencils_[static_cast<size_t>(e) - nt].v;
  };
  std::vector<int> mark(static_cast<size_t>(na), -1), pos(static_cast<size_t>(na), 0);
  std::vector<int> outer(static_cast<size_t>(na) + 1, 0), inner;
  inner.reserve(static_cast<size_t>(na) * 20);
  std::vector<int> col;
  diag_index_.resize(static_cast<size_t>(na));
  for (int a = 0; a < na; ++a) {
    col.clear();
    col.push_back(a);
    mark[static_cast<size_t>(a)] = a;
    for (int k = start[static_cast<size_t>(a)]; k < start[static_cast<size_t>(a) + 1]; ++k)
      for (int r : vertices(incident[static_cast<size_t>(k)]))
        if (mark[static_cast<size_t>(r)] != a) {
          mark[static_cast<size_t>(r)] = a;
          col.push_back(r);
        }
    std::sort(col.begin(), col.end());
    const int base = static_cast<int>(inner.size());
    for (size_t k = 0; k < col.size(); ++k) pos[static_cast<size_t>(col[k])] = base + static_cast<int>(k);
    inner.insert(inner.end(), col.begin(), col.end());
    outer[static_cast<size_t>(a) + 1] = static_cast<int>(inner.size());
    diag_index_[static_cast<size_t>(a)] = pos[static_cast<size_t>(a)];
    // the blocks' entries in this column
    for (int k = start[static_cast<size_t>(a)]; k < start[static_cast<size_t>(a) + 1]; ++k) {
      const int e = incident[static_cast<size_t>(k)];
      const std::array<int, 3>& ev = vertices(e);
      std::array<int, 9>& idx = e < static_cast<int>(nt) ? tris_[static_cast<size_t>(e)].value_index
                                                         : stencils_[static_cast<size_t>(e) - nt].idx;
      for (int cc = 0; cc < 3; ++cc) {
        if (ev[static_cast<size_t>(cc)] != a) continue;
        for (int rr = 0; rr < 3; ++rr) idx[static_cast<size_t>(rr * 3 + cc)] = pos[static_cast<size_t>(ev[static_cast<size_t>(rr)])];
      }
    }
  }
  hzz_pattern_.resize(na, na);
  hzz_pattern_.resizeNonZeros(static_cast<Eigen::Index>(inner.size()));
  std::copy(outer.begin(), outer.end(), hzz_pattern_.outerIndexPtr());
  std::copy(inner.begin(), inner.end(), hzz_pattern_.innerIndexPtr());
  std::fill(hzz_pattern_.valuePtr(), hzz_pattern_.valuePtr() + inner.size(), 0.0);
}

}  // namespace aligner
}  // namespace stereo_ground_dem
