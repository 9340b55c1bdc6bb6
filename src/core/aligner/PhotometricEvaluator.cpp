#include "stereo_ground_dem/aligner/PhotometricEvaluator.hpp"

#include <algorithm>
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
  std::uint32_t bits;
  std::memcpy(&bits, &y, sizeof(bits));
  const int exponent = static_cast<int>((bits >> 23) & 0xff) - 126;  // y = mant * 2^e, mant in [0.5, 1)
  bits = (bits & 0x007fffffu) | 0x3f000000u;
  float mant;
  std::memcpy(&mant, &bits, sizeof(mant));
  const float t = (mant - 0.70710678f) / (mant + 0.70710678f);
  const float t2 = t * t;
  // ln(mant) = ln(sqrt(1/2)) + 2 atanh(t), |t| < 0.172
  const float ln_m = -0.34657359f + 2.0f * t * (1.0f + t2 * (0.33333333f + t2 * (0.2f + t2 * 0.14285714f)));
  return ln_m + 0.69314718f * static_cast<float>(exponent);
}

}  // namespace

/// Rasterizes the current surface and accumulates the normal-equation pieces and the cost.
void PhotometricEvaluator::evaluate(const SurfaceState& s, Evaluation* ev) {
  const SurfaceAlignerOptions& opt = level_.options();
  const AlignmentProblem& prob = level_.problem();
  const StereoRig& rig = level_.rig();
  std::vector<TriangleGeometry>& tris = level_.triangles();
  const int width = level_.width(), height = level_.height(), threads = level_.threads();
  const std::vector<PairContext> pc = level_.pairs(s);
  const size_t np = pc.size();
  const size_t nt = tris.size();
  // Per-triangle planes and, per pair, homographies.
  const Eigen::Isometry3d& ctg = s.camera_T_ground;
  const Eigen::Vector3d cam_pos = -(ctg.linear().transpose() * ctg.translation());
  const Eigen::Matrix3d k = rig.K();
  const Eigen::Matrix3d kinv = k.inverse();
  auto& hom = ws_->homographies;
  TriangleRasterizer& raster = ws_->raster;
  raster.reset(width, height, opt.border_margin_px);
  for (size_t i = 0; i < nt; ++i) {
    TriangleGeometry& t = tris[i];
    t.drawn = false;
    const Eigen::Vector3d z(s.heights[t.vertex[0]], s.heights[t.vertex[1]], s.heights[t.vertex[2]]);
    const Eigen::Vector3d pqc = t.heights_to_plane * z;
    // front-facing: the camera is above the triangle's plane
    if (!(cam_pos.z() - (pqc.x() * cam_pos.x() + pqc.y() * cam_pos.y() + pqc.z()) > 1e-3)) continue;
    if (!PlaneGeometry::cameraPlane(ctg, pqc, &t.m)) continue;
    TriangleRasterizer::Triangle rt;
    bool ok = true;
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector2d xy = prob.grid->position(t.vertex[static_cast<size_t>(a)]);
      const Eigen::Vector3d xc = ctg * Eigen::Vector3d(xy.x(), xy.y(), z[a]);
      if (!(xc.z() > 0.1)) {
        ok = false;
        break;
      }
      rt.u[a] = rig.fx * xc.x() / xc.z() + rig.cx;
      rt.v[a] = rig.fy * xc.y() / xc.z() + rig.cy;
    }
    if (!ok) continue;
    rt.rho_a = t.m.x() / rig.fx;
    rt.rho_b = t.m.y() / rig.fy;
    rt.rho_c = t.m.z() - t.m.x() * rig.cx / rig.fx - t.m.y() * rig.cy / rig.fy;
    rt.id = static_cast<int>(i);
    t.drawn = true;
    raster.draw(rt);
  }
  // Slots for the triangles that won pixels; their Jacobian pieces and homographies.
  ev->slot_of.assign(nt, -1);
  ev->slot_tri.clear();
  const cv::Mat& labels = raster.labels();
  for (int v = 0; v < height; ++v) {
    const int* lab = labels.ptr<int>(v);
    for (int u = raster.rowBegin(v); u <= raster.rowEnd(v); ++u) {
      const int ti = lab[u];
      if (ti >= 0 && ev->slot_of[static_cast<size_t>(ti)] < 0) {
        ev->slot_of[static_cast<size_t>(ti)] = static_cast<int>(ev->slot_tri.size());
        ev->slot_tri.push_back(ti);
      }
    }
  }
  const size_t ns = ev->slot_tri.size();
  hom.resize(np * ns);
  for (size_t k2 = 0; k2 < ns; ++k2) {
    TriangleGeometry& t = tris[static_cast<size_t>(ev->slot_tri[k2])];
    const Eigen::Vector3d z(s.heights[t.vertex[0]], s.heights[t.vertex[1]], s.heights[t.vertex[2]]);
    t.dm_dz = PlaneGeometry::cameraPlaneJacobian(ctg, t.heights_to_plane * z) * t.heights_to_plane;
    for (size_t j = 0; j < np; ++j) {
      const Eigen::Matrix3d h = k *
                                (pc[j].target_T_reference.linear() +
                                 pc[j].target_T_reference.translation() * t.m.transpose()) *
                                kinv;
      auto& hh = hom[j * ns + k2];
      for (int a = 0; a < 9; ++a) hh[static_cast<size_t>(a)] = static_cast<float>(h(a / 3, a % 3));
    }
  }
  // Rows split into chunks of about equal pixel counts, one per thread.
  std::vector<int> bounds{0};
  {
    long total = 0;
    for (int v = 0; v < height; ++v) total += std::max(0, raster.rowEnd(v) - raster.rowBegin(v) + 1);
    long acc = 0;
    int next = 1;
    for (int v = 0; v < height && next < threads; ++v) {
      acc += std::max(0, raster.rowEnd(v) - raster.rowBegin(v) + 1);
      if (acc * threads >= total * next) {
        bounds.push_back(v + 1);
        ++next;
      }
    }
    while (static_cast<int>(bounds.size()) <= threads) bounds.push_back(height);
    bounds.back() = height;
  }
  ev->chunks.resize(static_cast<size_t>(threads));
  auto work = [&](int c) {
    Chunk& ch = ev->chunks[static_cast<size_t>(c)];
    ch.reset(level_.strides(), ns);
    accumulateRows(pc, *ev, bounds[static_cast<size_t>(c)], bounds[static_cast<size_t>(c) + 1], &ch);
  };
  if (threads > 1) {
    tbb::task_arena arena(threads);
    arena.execute([&] { tbb::parallel_for(0, threads, work); });
  } else {
    work(0);
  }
  Chunk& sum = ev->chunks[0];
  for (int c = 1; c < threads; ++c) {
    const Chunk& o = ev->chunks[static_cast<size_t>(c)];
    for (size_t j = 0; j < np; ++j) {
      double* dst = sum.tri[j].data();
      const double* src = o.tri[j].data();
      const size_t n = sum.tri[j].size();
      for (size_t i = 0; i < n; ++i) dst[i] += src[i];
      sum.pair[j].add(o.pair[j]);
    }
    for (size_t i = 0; i < ns; ++i) {
      sum.tri_pixels[i] += o.tri_pixels[i];
      sum.tri_excluded[i] += o.tri_excluded[i];
      sum.tri_textured[i] += o.tri_textured[i];
    }
    sum.abs_residuals.insert(sum.abs_residuals.end(), o.abs_residuals.begin(), o.abs_residuals.end());
    for (size_t j = 0; j < np; ++j) {
      sum.pair_abs_residuals[j].insert(sum.pair_abs_residuals[j].end(), o.pair_abs_residuals[j].begin(),
                                       o.pair_abs_residuals[j].end());
    }
  }
  ev->data_cost = 0.0;
  for (const auto& pa : sum.pair) ev->data_cost += level_.dataScale() * pa.cost;
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

/// The reference pixels of one row that take part: column, slot and per-pixel constants.
struct PhotometricEvaluator::RowPixels {
  std::vector<int> u, slot, tri;
  std::vector<float> i0, c0, c1, c2, x;
  void clear() {
    u.clear();
    slot.clear();
    tri.clear();
    i0.clear();
    c0.clear();
    c1.clear();
    c2.clear();
    x.clear();
  }
};

/// The pixel loop over rows [v0, v1): residuals, robust weights and the inverse compositional
/// Jacobians accumulated per triangle and pair. Sums run in float over the pixels of one
/// triangle in a row and are flushed into the double accumulators when the triangle changes.
void PhotometricEvaluator::accumulateRows(const std::vector<PairContext>& pc, const Evaluation& ev, int v0, int v1,
                                          Chunk* ch) const {
  const SurfaceAlignerOptions& opt = level_.options();
  const StereoRig& rig = level_.rig();
  const ImagePyramid::Level* ref = &level_.reference();
  const cv::Mat* excluded = level_.excluded();
  const float gtex2 = level_.texturedGradient2();
  const size_t np = pc.size();
  const size_t ns = ev.slot_tri.size();
  const int* slot_of = ev.slot_of.data();
  const TriangleRasterizer& raster = ws_->raster;
  const float dark = static_cast<float>(opt.dark_level_grey);
  const float sat = static_cast<float>(opt.saturated_level_grey);
  const float fx = static_cast<float>(rig.fx), fy = static_cast<float>(rig.fy);
  const float cx = static_cast<float>(rig.cx), cy = static_cast<float>(rig.cy);
  const cv::Mat& labels = raster.labels();
  RowPixels px;
  for (int v = v0; v < v1; ++v) {
    const int b = raster.rowBegin(v), e_col = raster.rowEnd(v);
    if (b > e_col) continue;
    const int* lab = labels.ptr<int>(v);
    const float* i0row = ref->image.ptr<float>(v);
    const float* gurow = ref->grad_u.ptr<float>(v);
    const float* gvrow = ref->grad_v.ptr<float>(v);
    const uint8_t* exrow = excluded ? excluded->ptr<uint8_t>(v) : nullptr;
    const float y = (static_cast<float>(v) - cy) / fy;
    px.clear();
    for (int u = b; u <= e_col; ++u) {
      const int tl = lab[u];
      if (tl < 0) continue;
      const int ti = slot_of[tl];
      if (exrow && exrow[u]) {
        ch->tri_excluded[static_cast<size_t>(ti)]++;
        continue;
      }
      const float i0 = i0row[u];
      if (i0 <= dark || i0 >= sat) continue;
      ch->tri_pixels[static_cast<size_t>(ti)]++;
      ch->tri_textured[static_cast<size_t>(ti)] += gurow[u] * gurow[u] + gvrow[u] * gvrow[u] >= gtex2;
      const float x = (static_cast<float>(u) - cx) / fx;
      const float gfu = gurow[u] * fx, gfv = gvrow[u] * fy;
      px.u.push_back(u);
      px.slot.push_back(ti);
      px.tri.push_back(tl);
      px.i0.push_back(i0);
      px.c0.push_back(gfu);
      px.c1.push_back(gfv);
      px.c2.push_back(-(gfu * x + gfv * y));
      px.x.push_back(x);
    }
    if (px.u.empty()) continue;
    for (size_t j = 0; j < np; ++j) {
      const PairContext& p = pc[j];
      const bool photo = p.photo_index >= 0;
      dispatchRow(p, j, ns, v, y, px, ch, photo);
    }
  }
  for (auto& pa : ch->pair) {
    pa.pp(1, 0) = pa.pp(0, 1);
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < r; ++c) pa.mm(r, c) = pa.mm(c, r);
  }
}

/// One instantiation of pairRow per warp kind, world-fixed or not, row shift or not.
void PhotometricEvaluator::dispatchRow(const PairContext& p, size_t j, size_t ns, int v, float y, const RowPixels& px,
                                       Chunk* ch, bool photo) const {
  auto with = [&](auto kind, auto world) {
    if (p.row_shift) pairRow<decltype(kind)::value, decltype(world)::value, true>(p, j, ns, v, y, px, ch, photo);
    else pairRow<decltype(kind)::value, decltype(world)::value, false>(p, j, ns, v, y, px, ch, photo);
  };
  using H = std::integral_constant<int, kWarpHorizontal>;
  using A = std::integral_constant<int, kWarpAffine>;
  using P = std::integral_constant<int, kWarpProjective>;
  using W = std::true_type;
  using F = std::false_type;
  switch (p.kind) {
    case kWarpHorizontal: p.world ? with(H(), W()) : with(H(), F()); break;
    case kWarpAffine: p.world ? with(A(), W()) : with(A(), F()); break;
    case kWarpProjective: p.world ? with(P(), W()) : with(P(), F()); break;
  }
}

template <int kKind, bool kWorld, bool kShift>
void PhotometricEvaluator::pairRow(const PairContext& p, size_t j, size_t ns, int v, float y, const RowPixels& px,
                                   Chunk* ch, bool photo) const {
  const SurfaceAlignerOptions& opt = level_.options();
  const StereoRig& rig = level_.rig();
  const std::vector<TriangleGeometry>& tris = level_.triangles();
  constexpr int kStride = kWorld ? kStrideWorld : kStrideRig;
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
  const float tx = static_cast<float>(p.t_prime.x()), ty = static_cast<float>(p.t_prime.y()),
              tz = static_cast<float>(p.t_prime.z());
  const float vf = static_cast<float>(v);
  const float cx = static_cast<float>(rig.cx), cy = static_cast<float>(rig.cy);
  const float ifx = static_cast<float>(1.0 / rig.fx), ify = static_cast<float>(1.0 / rig.fy);
  const std::array<float, 6>& sh = p.shift;
  const cv::Mat* tex = p.target_excluded;
  const uint8_t* rex = p.reference_excluded ? p.reference_excluded->ptr<uint8_t>(v) : nullptr;
  PairAccumulator& pa = ch->pair[j];
  double* tri_acc = ch->tri[j].data();
  // Sums in double: a triangle's 3x3 block is nearly rank-deficient (its pixels' rays are
  // nearly parallel); float sums make it indefinite.
  double run[kStride];
  int run_slot = -1;
  auto flush = [&]() {
    if (run_slot < 0) return;
    double* a = tri_acc + static_cast<size_t>(run_slot) * kStride;
    for (int k = 0; k < kStride; ++k) a[k] += run[k];
  };
  // per-row global sums in float, flushed to double at the end of the row
  double gpp[3] = {0, 0, 0}, gpe[2] = {0, 0}, gmm[21] = {}, gme[6] = {}, gmp[12] = {};
  float cost = 0.0f;
  int valid = 0, outside = 0;
  const bool odd_row = (v & 1) != 0;
  const size_t n = px.u.size();
  for (size_t k = 0; k < n; ++k) {
    const int u = px.u[k];
    if (p.checkerboard && (((u & 1) != 0) != odd_row)) continue;
    if (rex && rex[u]) continue;
    const int slot = px.slot[k];
    const auto& h = hom[j * ns + static_cast<size_t>(slot)];
    const float uf = static_cast<float>(u);
    float uj, vj;
    if (kKind == kWarpHorizontal) {
      uj = h[0] * uf + h[1] * vf + h[2];
      vj = vf;
    } else if (kKind == kWarpAffine) {
      uj = h[0] * uf + h[1] * vf + h[2];
      vj = h[3] * uf + h[4] * vf + h[5];
    } else {
      const float wz = h[6] * uf + h[7] * vf + h[8];
      if (!(wz > 1e-6f)) {
        cost += outside_cost;
        ++outside;
        continue;
      }
      const float iw = 1.0f / wz;
      uj = (h[0] * uf + h[1] * vf + h[2]) * iw;
      vj = (h[3] * uf + h[4] * vf + h[5]) * iw;
    }
    if (kShift) {  // the target's rectification error (AlignerTarget::row_shift_px)
      const float xn = (uj - cx) * ifx, yn = (vj - cy) * ify;
      vj += sh[0] + xn * (sh[1] + sh[3] * yn + sh[4] * xn) + yn * (sh[2] + sh[5] * yn);
    }
    if (!(uj >= 0.0f && vj >= 0.0f && uj < wmax && vj < hmax)) {
      cost += outside_cost;
      ++outside;
      continue;
    }
    if (tex && tex->at<uint8_t>(static_cast<int>(vj + 0.5f), static_cast<int>(uj + 0.5f))) continue;
    const float ij = bilinear(img, uj, vj);
    if (ij <= dark || ij >= sat) continue;
    const float i0 = px.i0[k];
    const float e = i0 - (gain * ij + bias);
    const float w = robust ? 1.0f / (1.0f + e * e * inv_c2) : 1.0f;
    cost += rho(e);
    ++valid;
    if ((valid & 7) == 0) {
      ch->abs_residuals.push_back(std::abs(e));
      ch->pair_abs_residuals[j].push_back(std::abs(e));
    }
    if (slot != run_slot) {
      flush();
      run_slot = slot;
      std::fill(run, run + kStride, 0.0);
    }
    const double c0 = px.c0[k], c1 = px.c1[k], c2 = px.c2[k], x = px.x[k];
    const double sc = c0 * tx + c1 * ty + c2 * tz;
    const double j0 = sc * x, j1 = sc * y, j2 = sc;
    const double ew = e, w0 = w * j0, w1 = w * j1, w2 = w * j2;
    run[0] += w0 * j0;
    run[1] += w0 * j1;
    run[2] += w0 * j2;
    run[3] += w1 * j1;
    run[4] += w1 * j2;
    run[5] += w2 * j2;
    run[6] += w0 * ew;
    run[7] += w1 * ew;
    run[8] += w2 * ew;
    if (photo) {
      run[9] += w0 * i0;
      run[10] += w0;
      run[11] += w1 * i0;
      run[12] += w1;
      run[13] += w2 * i0;
      run[14] += w2;
      gpp[0] += static_cast<double>(w) * i0 * i0;
      gpp[1] += w * i0;
      gpp[2] += w;
      gpe[0] += w * ew * i0;
      gpe[1] += w * ew;
    }
    if (kWorld) {
      const Eigen::Vector3d& m = tris[static_cast<size_t>(px.tri[k])].m;
      const double rho_u = m.x() * x + m.y() * y + m.z();
      const double jm[6] = {rho_u * c0, rho_u * c1, rho_u * c2, y * c2 - c1, c0 - x * c2, x * c1 - y * c0};
      double* am = run + 15;
      for (int c = 0; c < 6; ++c) {
        am[c] += w0 * jm[c];
        am[6 + c] += w1 * jm[c];
        am[12 + c] += w2 * jm[c];
      }
      int q = 0;
      for (int r = 0; r < 6; ++r) {
        const double wr = w * jm[r];
        for (int c = r; c < 6; ++c) gmm[q++] += wr * jm[c];
        gme[r] += wr * ew;
        if (photo) {
          gmp[2 * r] += wr * i0;
          gmp[2 * r + 1] += wr;
        }
      }
    }
  }
  flush();
  pa.cost += cost;
  pa.valid += valid;
  pa.outside += outside;
  if (photo) {
    pa.pp(0, 0) += gpp[0];
    pa.pp(0, 1) += gpp[1];
    pa.pp(1, 1) += gpp[2];
    pa.pe(0) += gpe[0];
    pa.pe(1) += gpe[1];
  }
  if (kWorld) {
    int q = 0;
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) pa.mm(r, c) += gmm[q++];
      pa.me(r) += gme[r];
      pa.mp(r, 0) += gmp[2 * r];
      pa.mp(r, 1) += gmp[2 * r + 1];
    }
  }
}

}  // namespace aligner
}  // namespace stereo_ground_dem
