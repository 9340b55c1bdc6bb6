#include "stereo_ground_dem/aligner/PhotometricEvaluator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <type_traits>

#include "stereo_ground_dem/PlaneGeometry.hpp"

namespace stereo_ground_dem {
namespace aligner {

namespace {

/// Eight floats as one vector (GCC / Clang vector extension: one AVX or two SSE registers).
typedef float Float8 __attribute__((vector_size(32)));
/// Four floats / ints: one SSE register (the x86-64 baseline), no AVX argument-passing ABI.
typedef float Float4 __attribute__((vector_size(16)));
typedef int Int4 __attribute__((vector_size(16)));

inline float bilinear(const cv::Mat& img, float u, float v) {
  const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
  const float fu = u - static_cast<float>(u0), fv = v - static_cast<float>(v0);
  const float* r0 = img.ptr<float>(v0) + u0;
  const float* r1 = img.ptr<float>(v0 + 1) + u0;
  return (1.0f - fv) * ((1.0f - fu) * r0[0] + fu * r0[1]) + fv * ((1.0f - fu) * r1[0] + fu * r1[1]);
}

/// log(1 + x) for x >= 0 to ~1e-6 relative accuracy, much cheaper than std::log1p: the robust cost
/// only decides whether a step is accepted, and both sides of that comparison use this function.
inline float fastLog1p(float x) {
  const float y = 1.0f + x;
  // bit casts without a memory round trip (std::memcpy through a local stops the vectorizer)
  std::uint32_t bits = __builtin_bit_cast(std::uint32_t, y);
  const int exponent = static_cast<int>((bits >> 23) & 0xff) - 126;  // y = mant * 2^e, mant in [0.5, 1)
  bits = (bits & 0x007fffffu) | 0x3f000000u;
  const float mant = __builtin_bit_cast(float, bits);
  const float t = (mant - 0.70710678f) / (mant + 0.70710678f);
  const float t2 = t * t;
  // ln(mant) = ln(sqrt(1/2)) + 2 atanh(t), |t| < 0.172
  const float ln_m = -0.34657359f + 2.0f * t * (1.0f + t2 * (0.33333333f + t2 * (0.2f + t2 * 0.14285714f)));
  return ln_m + 0.69314718f * static_cast<float>(exponent);
}

/// fastLog1p on four lanes, operation for operation (each lane's result equals fastLog1p's).
inline Float4 fastLog1p4(Float4 x) {
  const Float4 y = 1.0f + x;
  Int4 bits = __builtin_bit_cast(Int4, y);
  const Int4 exponent = ((bits >> 23) & 0xff) - 126;
  bits = (bits & 0x007fffff) | 0x3f000000;
  const Float4 mant = __builtin_bit_cast(Float4, bits);
  const Float4 t = (mant - 0.70710678f) / (mant + 0.70710678f);
  const Float4 t2 = t * t;
  const Float4 ln_m = -0.34657359f + 2.0f * t * (1.0f + t2 * (0.33333333f + t2 * (0.2f + t2 * 0.14285714f)));
  return ln_m + 0.69314718f * __builtin_convertvector(exponent, Float4);
}

}  // namespace

void PhotometricEvaluator::rasterize(const SurfaceState& s) {
  const SurfaceAlignerOptions& opt = level_.options();
  const StereoRig& rig = level_.rig();
  std::vector<TriangleGeometry>& tris = level_.triangles();
  const Eigen::Isometry3d& ctg = s.camera_T_ground;
  const Eigen::Vector3d cam_pos = -(ctg.linear().transpose() * ctg.translation());
  TriangleRasterizer& raster = ws_->raster;
  raster.reset(level_.width(), level_.height(), opt.border_margin_px);
  std::vector<TriangleRasterizer::Triangle>& projected = ws_->projected;
  projected.clear();
  const size_t nt = tris.size();
  // The pixel centres a triangle can cover (TriangleRasterizer::draw's bounds): none, and it is
  // not drawn, before its plane is computed (most triangles of the coarse levels).
  const int margin = opt.border_margin_px;
  const int row_max = level_.height() - 1 - margin, col_max = level_.width() - 1 - margin;
  // Two threads draw two bands of rows, split where about half of the drawing's work lies above.
  // The work of drawing a triangle (TriangleRasterizer::draw, then the band's scan of the labels):
  // a set-up, a few edge tests per row and its pixels, spread evenly over its rows (a difference
  // array over the rows). The costs of a set-up and of a row in pixels are rough, measured once
  // (KITTI 06, perf): the far ground's many small triangles are mostly set-up and rows, and
  // balancing by area alone gave the upper band 2.7x the lower one's drawing.
  constexpr double kSetupPx = 12.0, kRowPx = 5.0;
  // Two bands only with a second thread and enough triangles to share (checked again below on the
  // triangles drawn); the work is counted only then.
  constexpr size_t kMinTrianglesToSplit = 64;
  const bool balance = level_.threads() > 1 && tris.size() > kMinTrianglesToSplit;
  std::vector<double>& rate_change = ws_->row_work_change;  // the work per row from this row on
  std::vector<double>& setups = ws_->row_work_setups;       // the set-ups of the triangles starting here
  double total_work = 0.0;
  if (balance) {
    rate_change.assign(static_cast<size_t>(level_.height()) + 1, 0.0);
    setups.assign(static_cast<size_t>(level_.height()), 0.0);
  }
  for (size_t i = 0; i < nt; ++i) {
    TriangleGeometry& t = tris[i];
    t.drawn = false;
    const size_t l0 = static_cast<size_t>(t.local[0]), l1 = static_cast<size_t>(t.local[1]),
                 l2 = static_cast<size_t>(t.local[2]);
    if (!vertex_ok_[l0] || !vertex_ok_[l1] || !vertex_ok_[l2]) continue;
    const double row_first = std::max(static_cast<double>(margin), std::ceil(std::min({vertex_v_[l0], vertex_v_[l1], vertex_v_[l2]})));
    const double row_last = std::min(static_cast<double>(row_max), std::floor(std::max({vertex_v_[l0], vertex_v_[l1], vertex_v_[l2]})));
    {
      const double umin = std::min({vertex_u_[l0], vertex_u_[l1], vertex_u_[l2]});
      const double umax = std::max({vertex_u_[l0], vertex_u_[l1], vertex_u_[l2]});
      if (row_first > row_last ||
          std::max(static_cast<double>(margin), std::ceil(umin)) > std::min(static_cast<double>(col_max), std::floor(umax)))
        continue;
    }
    const Eigen::Vector3d z(s.heights[t.vertex[0]], s.heights[t.vertex[1]], s.heights[t.vertex[2]]);
    const Eigen::Vector3d pqc = t.heights_to_plane * z;
    // front-facing: the camera is above the triangle's plane
    if (!(cam_pos.z() - (pqc.x() * cam_pos.x() + pqc.y() * cam_pos.y() + pqc.z()) > 1e-3)) continue;
    if (!PlaneGeometry::cameraPlane(ctg, pqc, &t.m)) continue;
    TriangleRasterizer::Triangle rt;
    for (int a = 0; a < 3; ++a) {
      rt.u[a] = vertex_u_[static_cast<size_t>(t.local[static_cast<size_t>(a)])];
      rt.v[a] = vertex_v_[static_cast<size_t>(t.local[static_cast<size_t>(a)])];
    }
    rt.rho_a = t.m.x() / rig.fx;
    rt.rho_b = t.m.y() / rig.fy;
    rt.rho_c = t.m.z() - t.m.x() * rig.cx / rig.fx - t.m.y() * rig.cy / rig.fy;
    rt.id = static_cast<int>(i);
    t.drawn = true;
    projected.push_back(rt);
    if (balance) {
      const int r0 = static_cast<int>(row_first), r1 = static_cast<int>(row_last);
      const double area = 0.5 * std::abs((rt.u[1] - rt.u[0]) * (rt.v[2] - rt.v[0]) - (rt.v[1] - rt.v[0]) * (rt.u[2] - rt.u[0]));
      const double per_row = kRowPx + area / (r1 - r0 + 1);
      rate_change[static_cast<size_t>(r0)] += per_row;
      rate_change[static_cast<size_t>(r1) + 1] -= per_row;
      setups[static_cast<size_t>(r0)] += kSetupPx;
      total_work += kSetupPx + per_row * (r1 - r0 + 1);
    }
  }
  // The two bands: a triangle across the split is drawn by both, clipped. Within a band the
  // triangles are drawn in the same order as by one thread, so every pixel gets the same winner
  // (the split moves only the work, never a result). Each band then lists the triangles that won
  // pixels in it, in raster order, with their first and last rows.
  const int height = level_.height();
  const cv::Mat& labels = raster.labels();
  ++generation_;
  for (BandSlots& b : band_) {
    b.tri.clear();
    b.first_row.clear();
    if (b.stamp.size() != nt) {
      b.stamp.assign(nt, 0);
      b.last_row.assign(nt, -1);
    }
  }
  auto scan = [&](int b, int first, int last) {
    BandSlots& bs = band_[static_cast<size_t>(b)];
    for (int v = first; v <= last; ++v) {
      const int* lab = labels.ptr<int>(v);
      for (int u = raster.rowBegin(v); u <= raster.rowEnd(v); ++u) {
        const int ti = lab[u];
        if (ti < 0) continue;
        const size_t t = static_cast<size_t>(ti);
        if (bs.stamp[t] != generation_) {
          bs.stamp[t] = generation_;
          bs.tri.push_back(ti);
          bs.first_row.push_back(v);
        }
        bs.last_row[t] = v;
      }
    }
  };
  int split = height;  // band 0: rows [0, split), band 1: [split, height)
  if (balance && projected.size() > kMinTrianglesToSplit) {
    split = 0;
    double rate = 0.0;  // the work per row: the running sum of the changes
    for (double acc = 0.0; split < height && acc < 0.5 * total_work; ++split) {
      rate += rate_change[static_cast<size_t>(split)];
      acc += rate + setups[static_cast<size_t>(split)];
    }
    auto band = [&](int b) {
      const int first = b == 0 ? 0 : split, last = b == 0 ? split - 1 : height - 1;
      for (const TriangleRasterizer::Triangle& rt : projected) {
        if (std::max({rt.v[0], rt.v[1], rt.v[2]}) < first || std::min({rt.v[0], rt.v[1], rt.v[2]}) > last) continue;
        raster.draw(rt, first, last);
      }
      scan(b, first, last);
    };
    arena().execute([&] { tbb::parallel_for(0, 2, band); });
  } else {
    for (const TriangleRasterizer::Triangle& rt : projected) raster.draw(rt);
    scan(0, 0, height - 1);
  }
  // Slots for the triangles that won pixels, numbered in raster order: band 0's, then band 1's
  // not already in band 0 (the order one scan of the whole image gives).
  slot_of_.assign(nt, -1);
  slot_tri_.clear();
  slot_last_row_.clear();
  slots_before_row_.assign(static_cast<size_t>(height) + 1, 0);
  size_t next = 0;  // rows up to the first row of the next new slot get the count so far
  int row = 0;
  auto newSlot = [&](int ti, int first_row, int last_row) {
    for (; row <= first_row; ++row) slots_before_row_[static_cast<size_t>(row)] = static_cast<int>(next);
    slot_of_[static_cast<size_t>(ti)] = static_cast<int>(next++);
    slot_tri_.push_back(ti);
    slot_last_row_.push_back(last_row);
  };
  for (int b = 0; b < 2; ++b) {
    const BandSlots& bs = band_[static_cast<size_t>(b)];
    for (size_t i = 0; i < bs.tri.size(); ++i) {
      const int ti = bs.tri[i];
      const int last_row = bs.last_row[static_cast<size_t>(ti)];
      const int slot = slot_of_[static_cast<size_t>(ti)];
      if (slot < 0) newSlot(ti, bs.first_row[i], last_row);
      else slot_last_row_[static_cast<size_t>(slot)] = std::max(slot_last_row_[static_cast<size_t>(slot)], last_row);
    }
  }
  for (; row <= height; ++row) slots_before_row_[static_cast<size_t>(row)] = static_cast<int>(next);
}

/// Rasterizes the current surface and accumulates the normal-equation pieces and the cost.
void PhotometricEvaluator::evaluate(const SurfaceState& s, Evaluation* ev, bool sums) {
  sums_ = sums;
  ev->sums = sums;
  const AlignmentProblem& prob = level_.problem();
  const StereoRig& rig = level_.rig();
  std::vector<TriangleGeometry>& tris = level_.triangles();
  const int height = level_.height(), threads = level_.threads();
  const std::vector<PairContext> pc = level_.pairs(s);
  const size_t np = pc.size();
  const Eigen::Isometry3d& ctg = s.camera_T_ground;
  const Eigen::Matrix3d k = rig.K();
  const Eigen::Matrix3d kinv = k.inverse();
  auto& hom = ws_->homographies;
  TriangleRasterizer& raster = ws_->raster;
  const auto t_raster = std::chrono::steady_clock::now();
  // The active vertices in the image.
  const std::vector<int>& active = level_.active();
  const size_t na = active.size();
  vertex_u_.resize(na);
  vertex_v_.resize(na);
  vertex_ok_.resize(na);
  for (size_t a = 0; a < na; ++a) {
    const Eigen::Vector2d xy = prob.grid->position(active[a]);
    const Eigen::Vector3d xc = ctg * Eigen::Vector3d(xy.x(), xy.y(), s.heights[active[a]]);
    const bool ok = xc.z() > 0.1;
    vertex_ok_[a] = ok;
    vertex_u_[a] = ok ? rig.fx * xc.x() / xc.z() + rig.cx : 0.0;
    vertex_v_[a] = ok ? rig.fy * xc.y() / xc.z() + rig.cy : 0.0;
  }
  rasterize(s);
  ev->slot_of = slot_of_;
  ev->slot_tri = slot_tri_;
  // The planes of the triangles that own pixels, their Jacobians and, per pair, homographies.
  std::vector<Eigen::Matrix3d> krk(np);
  std::vector<Eigen::Vector3d> kt(np);
  for (size_t j = 0; j < np; ++j) {
    krk[j] = k * pc[j].target_T_reference.linear() * kinv;
    kt[j] = k * pc[j].target_T_reference.translation();
  }
  const size_t ns = ev->slot_tri.size();
  hom.resize(np * ns);
  ev->slot_m.resize(ns);
  ev->slot_dm_dz.resize(ns);
  auto geometry = [&](size_t begin, size_t end) {
    for (size_t k2 = begin; k2 < end; ++k2) {
      TriangleGeometry& t = tris[static_cast<size_t>(ev->slot_tri[k2])];
      const Eigen::Vector3d z(s.heights[t.vertex[0]], s.heights[t.vertex[1]], s.heights[t.vertex[2]]);
      const Eigen::Vector3d pqc = t.heights_to_plane * z;
      ev->slot_m[k2] = t.m;
      if (sums) ev->slot_dm_dz[k2] = PlaneGeometry::cameraPlaneJacobian(ctg, pqc) * t.heights_to_plane;
      // H_j = K (R_j + t_j m^T) K^-1 = K R_j K^-1 + (K t_j) (K^-T m)^T
      const Eigen::Vector3d mk = kinv.transpose() * t.m;
      for (size_t j = 0; j < np; ++j) {
        auto& hh = hom[j * ns + k2];
        for (int a = 0; a < 9; ++a)
          hh[static_cast<size_t>(a)] = static_cast<float>(krk[j](a / 3, a % 3) + kt[j][a / 3] * mk[a % 3]);
      }
    }
  };
  if (threads > 1 && ns > 512) {
    arena().execute([&] {
      tbb::parallel_for(0, threads, [&](int c) { geometry(ns * static_cast<size_t>(c) / static_cast<size_t>(threads), ns * static_cast<size_t>(c + 1) / static_cast<size_t>(threads)); });
    });
  } else {
    geometry(0, ns);
  }
  raster_ms_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t_raster).count();
  // The threads take the slots in ranges of about equal pixel counts: thread c the slots first
  // seen from row split[c] on (raster order), over the rows where they lie. Each writes only its
  // own slots' sums, so nothing per slot is merged.
  std::vector<int> split{0};
  {
    long total = 0;
    for (int v = 0; v < height; ++v) total += std::max(0, raster.rowEnd(v) - raster.rowBegin(v) + 1);
    long acc = 0;
    for (int v = 0; v < height && static_cast<int>(split.size()) < threads; ++v) {
      acc += std::max(0, raster.rowEnd(v) - raster.rowBegin(v) + 1);
      if (acc * threads >= total * static_cast<long>(split.size())) split.push_back(v + 1);
    }
    while (static_cast<int>(split.size()) < threads) split.push_back(height);
    split.push_back(height);
  }
  const std::vector<int>& strides = level_.strides();
  ev->tri.resize(np);
  for (size_t j = 0; j < np; ++j) ev->tri[j].resize(static_cast<size_t>(strides[j]) * ns);
  ev->tri_pixels.resize(ns);
  ev->tri_excluded.resize(ns);
  ev->tri_textured.resize(ns);
  ev->parts.resize(static_cast<size_t>(threads));
  auto work = [&](int c) {
    const int first_row = split[static_cast<size_t>(c)];
    const int slot_begin = slots_before_row_[static_cast<size_t>(first_row)];
    const int slot_end = slots_before_row_[static_cast<size_t>(split[static_cast<size_t>(c) + 1])];
    int last_row = first_row - 1;
    for (int k2 = slot_begin; k2 < slot_end; ++k2) last_row = std::max(last_row, slot_last_row_[static_cast<size_t>(k2)]);
    for (size_t j = 0; j < np && sums; ++j) {
      std::fill(ev->tri[j].begin() + static_cast<std::ptrdiff_t>(strides[j]) * slot_begin,
                ev->tri[j].begin() + static_cast<std::ptrdiff_t>(strides[j]) * slot_end, 0.0);
    }
    for (auto* counts : {&ev->tri_pixels, &ev->tri_excluded, &ev->tri_textured})
      std::fill(counts->begin() + slot_begin, counts->begin() + slot_end, 0);
    ThreadPart& part = ev->parts[static_cast<size_t>(c)];
    part.reset(np);
    accumulateRows(pc, ev, first_row, last_row + 1, slot_begin, slot_end, &part);
  };
  if (threads > 1) {
    arena().execute([&] { tbb::parallel_for(0, threads, work); });
  } else {
    work(0);
  }
  ev->pair = ev->parts[0].pair;
  ev->abs_residuals = ev->parts[0].abs_residuals;
  ev->pair_abs_residuals = ev->parts[0].pair_abs_residuals;
  for (int c = 1; c < threads; ++c) {
    const ThreadPart& o = ev->parts[static_cast<size_t>(c)];
    for (size_t j = 0; j < np; ++j) {
      ev->pair[j].add(o.pair[j]);
      ev->pair_abs_residuals[j].insert(ev->pair_abs_residuals[j].end(), o.pair_abs_residuals[j].begin(),
                                       o.pair_abs_residuals[j].end());
    }
    ev->abs_residuals.insert(ev->abs_residuals.end(), o.abs_residuals.begin(), o.abs_residuals.end());
  }
  for (auto& pa : ev->pair) {
    pa.pp(1, 0) = pa.pp(0, 1);
    for (int r = 0; r < 6; ++r)
      for (int col = 0; col < r; ++col) pa.mm(r, col) = pa.mm(col, r);
  }
  ev->data_cost = 0.0;
  for (const auto& pa : ev->pair) ev->data_cost += level_.dataScale() * pa.cost;
  const Eigen::VectorXd za = level_.activeHeights(s);
  ev->smoothness_cost = 0.0;
  ev->smooth_residual.resize(level_.stencils().size());
  ev->smooth_weight.resize(level_.stencils().size());
  for (size_t k = 0; k < level_.stencils().size(); ++k) {
    const Stencil& st = level_.stencils()[k];
    const double r = st.w * (za[st.v[0]] - 2.0 * za[st.v[1]] + za[st.v[2]]);
    ev->smooth_residual[k] = r;
    if (level_.smoothnessC2() > 0.0) {
      const double c2 = level_.smoothnessC2() * st.w * st.w;
      ev->smoothness_cost += c2 * std::log1p(r * r / c2);
      ev->smooth_weight[k] = 1.0 / (1.0 + r * r / c2);
    } else {
      ev->smoothness_cost += r * r;
      ev->smooth_weight[k] = 1.0;
    }
  }
  ev->prior_cost = 0.0;
  if (prob.prior) {
    for (const int v : level_.active()) {
      const double info = prob.prior->information[v];
      if (info > 0.0) {
        const double d = s.heights[v] - prob.prior->mean[v];
        ev->prior_cost += info * d * d;
      }
    }
  }
}

/// The reference pixels of one row that take part (SoA): column, slot, triangle and the per-pixel
/// constants of the inverse compositional Jacobian, in runs of one slot; and, per pair, the
/// robust weight w and w * residual of each (0 where the sample is not used).
struct PhotometricEvaluator::RowPixels {
  int n = 0;
  std::vector<int> u, slot, tri;
  std::vector<float> i0, c0, c1, x;
  std::vector<int> run_begin;  ///< first pixel of each run of one slot; n closes the last
  std::vector<float> w, we;
  // per pair, scratch: the sample position in the target, its value, and what became of it
  std::vector<float> uj, vj, ij, cost;
  std::vector<uint8_t> use;  ///< kUsed, kSkipped (no cost) or kOutside (the outside penalty)
  explicit RowPixels(int width) {
    const size_t s = static_cast<size_t>(width) + 1;
    for (auto* a : {&u, &slot, &tri, &run_begin}) a->resize(s);
    for (auto* a : {&i0, &c0, &c1, &x, &w, &we, &uj, &vj, &ij, &cost}) a->resize(s);
    use.resize(s);
  }
};

/// The pixel loop over rows [v0, v1): residuals, robust weights and the inverse compositional
/// Jacobians accumulated per triangle and pair. Sums run in float over the pixels of one run (one
/// triangle in one row), with x relative to the run's first pixel so that the nearly
/// rank-deficient 3x3 block of a triangle (its pixels' rays are nearly parallel) keeps its
/// precision, and are flushed into the double accumulators at the end of each run.
void PhotometricEvaluator::accumulateRows(const std::vector<PairContext>& pc, Evaluation* ev, int v0, int v1,
                                          int slot_begin, int slot_end, ThreadPart* part) const {
  const SurfaceAlignerOptions& opt = level_.options();
  const StereoRig& rig = level_.rig();
  const ImagePyramid::Level* ref = &level_.reference();
  const cv::Mat* excluded = level_.excluded();
  const float gtex2 = level_.texturedGradient2();
  const size_t np = pc.size();
  const size_t ns = ev->slot_tri.size();
  const int* slot_of = ev->slot_of.data();
  const TriangleRasterizer& raster = ws_->raster;
  const float dark = static_cast<float>(opt.dark_level_grey);
  const float sat = static_cast<float>(opt.saturated_level_grey);
  const float fx = static_cast<float>(rig.fx), fy = static_cast<float>(rig.fy);
  const float cx = static_cast<float>(rig.cx), cy = static_cast<float>(rig.cy);
  const cv::Mat& labels = raster.labels();
  RowPixels px(level_.width());
  // Raw pointers: stores through the vectors would otherwise make the compiler reload every
  // vector's data pointer per pixel.
  int* const tri_pixels = ev->tri_pixels.data();
  int* const tri_excluded = ev->tri_excluded.data();
  int* const tri_textured = ev->tri_textured.data();
  int* const pu = px.u.data();
  int* const pslot = px.slot.data();
  int* const ptri = px.tri.data();
  int* const prun = px.run_begin.data();
  float* const pi0 = px.i0.data();
  float* const pc0 = px.c0.data();
  float* const pc1 = px.c1.data();
  float* const pxn = px.x.data();
  for (int v = v0; v < v1; ++v) {
    const int b = raster.rowBegin(v), e_col = raster.rowEnd(v);
    if (b > e_col) continue;
    const int* lab = labels.ptr<int>(v);
    const float* i0row = ref->image.ptr<float>(v);
    const float* gurow = ref->grad_u.ptr<float>(v);
    const float* gvrow = ref->grad_v.ptr<float>(v);
    const uint8_t* exrow = excluded ? excluded->ptr<uint8_t>(v) : nullptr;
    const float y = (static_cast<float>(v) - cy) / fy;
    int n = 0, runs = 0, last_slot = -1;
    for (int u = b; u <= e_col; ++u) {
      const int tl = lab[u];
      if (tl < 0) continue;
      const int ti = slot_of[tl];
      if (ti < slot_begin || ti >= slot_end) continue;  // another thread's
      if (exrow && exrow[u]) {
        tri_excluded[ti]++;
        continue;
      }
      const float i0 = i0row[u];
      if (i0 <= dark || i0 >= sat) continue;
      const float gu = gurow[u], gv = gvrow[u];
      tri_pixels[ti]++;
      tri_textured[ti] += gu * gu + gv * gv >= gtex2;
      if (ti != last_slot) {
        prun[runs++] = n;
        last_slot = ti;
      }
      const int k = n++;
      pu[k] = u;
      pslot[k] = ti;
      ptri[k] = tl;
      pi0[k] = i0;
      pc0[k] = gu * fx;
      pc1[k] = gv * fy;
      pxn[k] = (static_cast<float>(u) - cx) / fx;
    }
    if (n == 0) continue;
    px.n = n;
    px.run_begin[static_cast<size_t>(runs)] = n;
    for (size_t j = 0; j < np; ++j) {
      const PairContext& p = pc[j];
      dispatchRow(p, j, ns, v, y, px, ev, part, runs);
    }
  }
}

/// One instantiation of pairRow per warp kind and row shift, then of accumulateRuns world-fixed or not.
void PhotometricEvaluator::dispatchRow(const PairContext& p, size_t j, size_t ns, int v, float y, RowPixels& px,
                                       Evaluation* ev, ThreadPart* part, int runs) const {
  switch (p.kind) {
    case kWarpHorizontal:
      p.row_shift ? pairRow<kWarpHorizontal, true>(p, j, ns, v, px, part) : pairRow<kWarpHorizontal, false>(p, j, ns, v, px, part);
      break;
    case kWarpAffine:
      p.row_shift ? pairRow<kWarpAffine, true>(p, j, ns, v, px, part) : pairRow<kWarpAffine, false>(p, j, ns, v, px, part);
      break;
    case kWarpProjective:
      p.row_shift ? pairRow<kWarpProjective, true>(p, j, ns, v, px, part)
                  : pairRow<kWarpProjective, false>(p, j, ns, v, px, part);
      break;
  }
  if (!sums_) return;
  if (!p.world) accumulateRuns<false, true>(p, j, y, px, runs, ev, part);
  else if (level_.strides()[j] > 0) accumulateRuns<true, true>(p, j, y, px, runs, ev, part);
  else accumulateRuns<true, false>(p, j, y, px, runs, ev, part);
}

template <int kKind, bool kShift>
void PhotometricEvaluator::pairRow(const PairContext& p, size_t j, size_t ns, int v, RowPixels& px,
                                   ThreadPart* part) const {
  enum : uint8_t { kUsed = 0, kSkipped = 1, kOutside = 2 };
  const SurfaceAlignerOptions& opt = level_.options();
  const StereoRig& rig = level_.rig();
  const auto& hom = ws_->homographies;
  const cv::Mat& img = *p.image;
  const float wmax = static_cast<float>(img.cols - 1), hmax = static_cast<float>(img.rows - 1);
  const bool robust = opt.robust_scale_grey > 0.0;
  const float c2r = static_cast<float>(opt.robust_scale_grey * opt.robust_scale_grey);
  const float inv_c2 = robust ? 1.0f / c2r : 0.0f;
  auto rho = [&](float e) { return robust ? c2r * fastLog1p(e * e * inv_c2) : e * e; };
  const float outside_cost = rho(static_cast<float>(
      opt.outside_penalty_factor * (robust ? opt.robust_scale_grey : opt.image_noise_std_grey)));
  const float dark = static_cast<float>(opt.dark_level_grey);
  const float sat = static_cast<float>(opt.saturated_level_grey);
  const float gain = static_cast<float>(p.photometric.gain), bias = static_cast<float>(p.photometric.bias_grey);
  const float vf = static_cast<float>(v);
  const float cx = static_cast<float>(rig.cx), cy = static_cast<float>(rig.cy);
  const float ifx = static_cast<float>(1.0 / rig.fx), ify = static_cast<float>(1.0 / rig.fy);
  const std::array<float, 6>& sh = p.shift;
  const cv::Mat* tex = p.target_excluded;
  const uint8_t* rex = p.reference_excluded ? p.reference_excluded->ptr<uint8_t>(v) : nullptr;
  PairAccumulator& pa = part->pair[j];
  const int n = px.n;
  const int* uk = px.u.data();
  float* ujk = px.uj.data();
  float* vjk = px.vj.data();
  float* ijk = px.ij.data();
  uint8_t* use = px.use.data();
  // 1. where each pixel lands in the target (one homography per run)
  for (int r = 0; px.run_begin[static_cast<size_t>(r)] < n; ++r) {
    const int a = px.run_begin[static_cast<size_t>(r)], b = px.run_begin[static_cast<size_t>(r) + 1];
    const auto& h = hom[j * ns + static_cast<size_t>(px.slot[static_cast<size_t>(a)])];
    for (int k = a; k < b; ++k) {
      const float uf = static_cast<float>(uk[k]);
      float uj, vj;
      uint8_t state = kUsed;
      if (kKind == kWarpHorizontal) {
        uj = h[0] * uf + h[1] * vf + h[2];
        vj = vf;
      } else if (kKind == kWarpAffine) {
        uj = h[0] * uf + h[1] * vf + h[2];
        vj = h[3] * uf + h[4] * vf + h[5];
      } else {
        const float wz = h[6] * uf + h[7] * vf + h[8];
        state = wz > 1e-6f ? kUsed : kOutside;
        const float iw = 1.0f / (state == kUsed ? wz : 1.0f);
        uj = (h[0] * uf + h[1] * vf + h[2]) * iw;
        vj = (h[3] * uf + h[4] * vf + h[5]) * iw;
      }
      if (kShift) {  // the target's rectification error (AlignerTarget::row_shift_px)
        const float xn = (uj - cx) * ifx, yn = (vj - cy) * ify;
        vj += sh[0] + xn * (sh[1] + sh[3] * yn + sh[4] * xn) + yn * (sh[2] + sh[5] * yn);
      }
      if (!(uj >= 0.0f && vj >= 0.0f && uj < wmax && vj < hmax)) state = kOutside;
      ujk[k] = uj;
      vjk[k] = vj;
      use[k] = state;
    }
  }
  // 2. the samples (pixels this pair skips: no cost)
  const bool odd_row = (v & 1) != 0;
  for (int k = 0; k < n; ++k) {
    const int u = uk[k];
    if ((p.checkerboard && (((u & 1) != 0) != odd_row)) || (rex && rex[u])) {
      use[k] = kSkipped;
      continue;
    }
    if (use[k] != kUsed) continue;
    if (tex && tex->at<uint8_t>(static_cast<int>(vjk[k] + 0.5f), static_cast<int>(ujk[k] + 0.5f))) {
      use[k] = kSkipped;
      continue;
    }
    const float ij = bilinear(img, ujk[k], vjk[k]);
    ijk[k] = ij;
    if (ij <= dark || ij >= sat) use[k] = kSkipped;
  }
  // 3. residuals, robust weights and the cost (branch-free), four samples at a time: written
  // with vector types because the compiler keeps the division and the logarithm of a plain loop
  // scalar; every lane computes what the scalar tail below computes for one sample.
  const float* i0k = px.i0.data();
  float* wk = px.w.data();
  float* wek = px.we.data();
  float* ck = px.cost.data();
  int valid = 0, outside = 0;
  int k3 = 0;
  {
    Int4 valid4 = {}, outside4 = {};
    for (; k3 + 4 <= n; k3 += 4) {
      Float4 i0v, ijv;
      std::memcpy(&i0v, i0k + k3, sizeof(i0v));
      std::memcpy(&ijv, ijk + k3, sizeof(ijv));
      Int4 usev;
      for (int l = 0; l < 4; ++l) usev[l] = use[k3 + l];
      const Int4 used = usev == static_cast<int>(kUsed), out = usev == static_cast<int>(kOutside);  // -1 where true
      const Float4 zero = {};
      const Float4 e = used ? i0v - (gain * ijv + bias) : zero;
      const Float4 w = 1.0f / (1.0f + e * e * inv_c2);
      const Float4 r = robust ? c2r * fastLog1p4(e * e * inv_c2) : e * e;
      const Float4 c = used ? r : (out ? zero + outside_cost : zero);
      const Float4 wu = used ? w : zero, weu = used ? w * e : zero;
      valid4 -= used;
      outside4 -= out;
      std::memcpy(ck + k3, &c, sizeof(c));
      std::memcpy(wk + k3, &wu, sizeof(wu));
      std::memcpy(wek + k3, &weu, sizeof(weu));
    }
    for (int l = 0; l < 4; ++l) {
      valid += valid4[l];
      outside += outside4[l];
    }
  }
  for (int k = k3; k < n; ++k) {
    const bool used = use[k] == kUsed;
    const float e = used ? i0k[k] - (gain * ijk[k] + bias) : 0.0f;
    const float w = 1.0f / (1.0f + e * e * inv_c2);  // 1 exactly without the robust cost (inv_c2 = 0)
    ck[k] = used ? rho(e) : (use[k] == kOutside ? outside_cost : 0.0f);
    valid += used;
    outside += use[k] == kOutside;
    wk[k] = used ? w : 0.0f;
    wek[k] = used ? w * e : 0.0f;
  }
  // summed in pixel order, apart from the loop above: the cost does not depend on how the
  // compiler splits that loop into vector lanes
  float cost = 0.0f;
  for (int k = 0; k < n; ++k) cost += ck[k];
  pa.cost += cost;
  pa.valid += valid;
  pa.outside += outside;
  // 4. every 8th used sample's |residual|, for the medians
  for (int k = 0, count = 0; k < n; ++k) {
    if (use[k] != kUsed || (++count & 7) != 0) continue;
    const float e = std::abs(i0k[k] - (gain * ijk[k] + bias));
    part->abs_residuals.push_back(e);
    part->pair_abs_residuals[j].push_back(e);
  }
}

template <bool kWorld, bool kTriangles>
void PhotometricEvaluator::accumulateRuns(const PairContext& p, size_t j, float y, const RowPixels& px, int runs,
                                          Evaluation* ev, ThreadPart* part) const {
  constexpr int kStride = kWorld ? kStrideWorld : kStrideRig;
  static_assert(kWorld || kTriangles, "a rig pair's motion comes from its triangles");
  const std::vector<TriangleGeometry>& tris = level_.triangles();
  const float tx = static_cast<float>(p.t_prime.x()), ty = static_cast<float>(p.t_prime.y()),
              tz = static_cast<float>(p.t_prime.z());
  const double yd = y;
  PairAccumulator& pa = part->pair[j];
  double* tri_acc = ev->tri[j].data();
  const float* wk = px.w.data();
  const float* wek = px.we.data();
  const float* c0k = px.c0.data();
  const float* c1k = px.c1.data();
  const float* xk = px.x.data();
  const float* i0k = px.i0.data();
  for (int r = 0; r < runs; ++r) {
    const int a = px.run_begin[static_cast<size_t>(r)], b = px.run_begin[static_cast<size_t>(r) + 1];
    const float xr = xk[a];
    // plane-increment block: sc = c . t' (c2 = -(c0 x + c1 y)), J = sc (x, y, 1); y is constant in
    // the row, so its sums are multiples of those without it
    float s0 = 0, s1 = 0, s2 = 0, e0 = 0, e1 = 0, p0 = 0, p1 = 0, q0 = 0, q1 = 0;
    float g0 = 0, g1 = 0, g2 = 0, h0 = 0, h1 = 0;
    if (!kTriangles) {
#pragma omp simd reduction(+ : g0, g1, g2, h0, h1)
      for (int k = a; k < b; ++k) {
        const float w = wk[k], we = wek[k], i0 = i0k[k];
        g0 += w * i0 * i0;
        g1 += w * i0;
        g2 += w;
        h0 += we * i0;
        h1 += we;
      }
    } else {
#pragma omp simd reduction(+ : s0, s1, s2, e0, e1, p0, p1, q0, q1, g0, g1, g2, h0, h1)
    for (int k = a; k < b; ++k) {
      const float w = wk[k], we = wek[k], i0 = i0k[k], dx = xk[k] - xr;
      const float c0 = c0k[k], c1 = c1k[k];
      const float sc = c0 * tx + c1 * ty - (c0 * xk[k] + c1 * y) * tz;
      const float ws = w * sc, wes = we * sc;
      s0 += ws * sc;
      s1 += ws * sc * dx;
      s2 += ws * sc * dx * dx;
      e0 += wes;
      e1 += wes * dx;
      p0 += ws * i0;
      p1 += ws * i0 * dx;
      q0 += ws;
      q1 += ws * dx;
      g0 += w * i0 * i0;
      g1 += w * i0;
      g2 += w;
      h0 += we * i0;
      h1 += we;
    }
    }
    if (g2 == 0.0f) continue;  // no sample of this run was used
    const double x0 = xr;
    double* acc = kTriangles ? tri_acc + static_cast<size_t>(px.slot[static_cast<size_t>(a)]) * kStride : nullptr;
    if (kTriangles) {
    const double S1 = s1 + x0 * s0, S2 = s2 + 2.0 * x0 * s1 + x0 * x0 * s0;
    acc[0] += S2;
    acc[1] += yd * S1;
    acc[2] += S1;
    acc[3] += yd * yd * s0;
    acc[4] += yd * s0;
    acc[5] += s0;
    acc[6] += e1 + x0 * e0;
    acc[7] += yd * e0;
    acc[8] += e0;
    acc[9] += p1 + x0 * p0;
    acc[10] += q1 + x0 * q0;
    acc[11] += yd * p0;
    acc[12] += yd * q0;
    acc[13] += p0;
    acc[14] += q0;
    }
    pa.pp(0, 0) += g0;
    pa.pp(0, 1) += g1;
    pa.pp(1, 1) += g2;
    pa.pe(0) += h0;
    pa.pe(1) += h1;
    if (kWorld) {
      // motion: Jm = (rho c0, rho c1, rho c2, y c2 - c1, c0 - x c2, x c1 - y c0), rho the run's plane
      const Eigen::Vector3d& m = tris[static_cast<size_t>(px.tri[static_cast<size_t>(a)])].m;
      const float mx = static_cast<float>(m.x()), mr = static_cast<float>(m.y() * y + m.z());
      // Jm as one 8-lane vector per pixel (lanes 6, 7 zero); the sums are its outer products
      Float8 hm[6] = {}, me = {}, mp = {}, mq = {}, f = {}, fx = {};
      for (int k = a; k < b; ++k) {
        const float w = wk[k], we = wek[k], x = xk[k], c0 = c0k[k], c1 = c1k[k];
        const float c2 = -(c0 * x + c1 * y);
        const float rho = mx * x + mr;
        const Float8 jm = {rho * c0, rho * c1, rho * c2, y * c2 - c1, c0 - x * c2, x * c1 - y * c0, 0.0f, 0.0f};
        const float ws = w * (c0 * tx + c1 * ty + c2 * tz);
        const Float8 wj = w * jm;
        for (int r2 = 0; r2 < 6; ++r2) hm[r2] += wj[r2] * jm;
        me += we * jm;
        mp += i0k[k] * wj;
        mq += wj;
        if (kTriangles) {
          f += ws * jm;
          fx += (ws * (x - xr)) * jm;
        }
      }
      for (int r2 = 0; r2 < 6; ++r2) {
        if (kTriangles) {
          double* am = acc + 15;
          am[r2] += fx[r2] + x0 * f[r2];
          am[6 + r2] += yd * f[r2];
          am[12 + r2] += f[r2];
        }
        for (int c3 = r2; c3 < 6; ++c3) pa.mm(r2, c3) += hm[r2][c3];
        pa.me(r2) += me[r2];
        pa.mp(r2, 0) += mp[r2];
        pa.mp(r2, 1) += mq[r2];
      }
    }
  }
}

}  // namespace aligner
}  // namespace stereo_ground_dem
