#include "stereo_ground_dem/SurfaceAligner.hpp"

#include <Eigen/Cholesky>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <type_traits>

#include "stereo_ground_dem/PlaneGeometry.hpp"
#include "stereo_ground_dem/TriangleRasterizer.hpp"

namespace stereo_ground_dem {

bool SurfaceAlignerOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (max_iterations < 0) return bad("max_iterations must be >= 0");
  if (max_step_halvings < 0) return bad("max_step_halvings must be >= 0");
  if (!(image_noise_std_grey > 0.0)) return bad("image_noise_std_grey must be > 0");
  if (!(smoothness_weight >= 0.0)) return bad("smoothness_weight must be >= 0");
  if (!(min_depth_m > 0.0) || !(max_depth_m > min_depth_m)) {
    return bad("need 0 < min_depth_m < max_depth_m");
  }
  if (!(max_lateral_m > 0.0)) return bad("max_lateral_m must be > 0");
  if (border_margin_px < 1) return bad("border_margin_px must be >= 1");
  if (!(saturated_level_grey > dark_level_grey)) return bad("saturated_level_grey must exceed dark_level_grey");
  if (!(textured_gradient_grey_per_px >= 0.0) || !std::isfinite(textured_gradient_grey_per_px)) {
    return bad("textured_gradient_grey_per_px must be finite and >= 0");
  }
  if (!(outside_penalty_factor >= 0.0)) return bad("outside_penalty_factor must be >= 0");
  if (num_threads < 1) return bad("num_threads must be >= 1");
  if (!(cg_tolerance > 0.0 && cg_tolerance < 1.0)) return bad("cg_tolerance must be in (0, 1)");
  if (cg_max_iterations < 1) return bad("cg_max_iterations must be >= 1");
  return true;
}

namespace {

using Matrix32d = Eigen::Matrix<double, 3, 2>;
using Matrix36d = Eigen::Matrix<double, 3, 6>;
using Matrix62d = Eigen::Matrix<double, 6, 2>;
using SpMat = Eigen::SparseMatrix<double>;

// Per working triangle and pair, the sums over its pixels of the inverse compositional Jacobian
// in the plane-increment space (delta, 3) with the residual, the photometric part (I0, 1) and,
// for world-fixed pairs, the motion part. Flat layout per triangle:
//   [0..5]   sum w Jd^T Jd   (xx, xy, xz, yy, yz, zz)
//   [6..8]   sum w Jd^T e
//   [9..14]  sum w Jd^T (I0, 1)  (row-major 3x2)
//   [15..32] sum w Jd^T Jm       (row-major 3x6, world-fixed pairs only)
constexpr int kStrideRig = 15;
constexpr int kStrideWorld = 33;

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

/// One thread's share of an evaluation.
struct Chunk {
  std::vector<std::vector<double>> tri;  ///< [pair] stride * triangles
  std::vector<PairAccumulator> pair;
  std::vector<int> tri_pixels;
  std::vector<int> tri_excluded;  ///< pixels of the triangle masked out as obstacles
  std::vector<int> tri_textured;  ///< its used pixels with a gradient of at least textured_gradient
  std::vector<float> abs_residuals;
  std::vector<std::vector<float>> pair_abs_residuals;  ///< [pair] the same samples, per pair
  void reset(const std::vector<int>& strides, size_t nt) {
    tri.resize(strides.size());
    for (size_t j = 0; j < strides.size(); ++j) tri[j].assign(static_cast<size_t>(strides[j]) * nt, 0.0);
    pair.assign(strides.size(), PairAccumulator());
    tri_pixels.assign(nt, 0);
    tri_excluded.assign(nt, 0);
    tri_textured.assign(nt, 0);
    abs_residuals.clear();
    pair_abs_residuals.assign(strides.size(), {});
  }
};

struct Evaluation {
  std::vector<Chunk> chunks;  ///< chunks[0] holds the merged sums after evaluate()
  /// Triangles that own at least one pixel get a slot; accumulators are per slot.
  std::vector<int> slot_of;   ///< triangle -> slot or -1
  std::vector<int> slot_tri;  ///< slot -> triangle
  std::vector<double> smooth_residual;  ///< per stencil: w (z_a - 2 z_b + z_d)
  std::vector<double> smooth_weight;    ///< per stencil: robust (IRLS) weight
  double data_cost = 0.0, smoothness_cost = 0.0, prior_cost = 0.0;
  double total() const { return data_cost + smoothness_cost + prior_cost; }
  const Chunk& sums() const { return chunks[0]; }
};

struct TriangleGeometry {
  std::array<int, 3> vertex{};     ///< fine vertex indices
  std::array<int, 3> local{};      ///< compact active indices
  std::array<int, 9> value_index{};  ///< positions of its 3x3 block in the height matrix' values
  Eigen::Matrix3d heights_to_plane;
  // per evaluation:
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  Eigen::Matrix3d dm_dz = Eigen::Matrix3d::Zero();
  bool drawn = false;
};

/// How a pair's warps map reference pixels: along rows only (a rectified stereo partner), by an
/// affine map (no perspective division), or by a general homography.
enum WarpKind { kWarpHorizontal = 0, kWarpAffine = 1, kWarpProjective = 2 };

struct PairContext {
  Eigen::Isometry3d target_T_reference;
  Eigen::Vector3d t_prime;  ///< R_j^T t_j
  WarpKind kind;
  bool row_shift = false;         ///< the target has a row shift (AlignerTarget::row_shift_px)
  std::array<float, 6> shift{};   ///< its coefficients in this level's pixels
  const cv::Mat* target_excluded = nullptr;  ///< the target's excluded pixels at this level
  const cv::Mat* reference_excluded = nullptr;  ///< reference pixels this pair skips at this level
  bool world;               ///< world-fixed pair with motion estimated: accumulate Jm
  bool checkerboard;        ///< use every other pixel only
  int photo_index = -1;     ///< first global index of (dg, db), -1 when fixed
  PhotometricParams photometric;
  const cv::Mat* image;
};

/// Buffers reused across iterations, levels and frames (one per thread).
struct Workspace {
  TriangleRasterizer raster;
  Evaluation eval[2];
  std::vector<std::array<float, 9>> homographies;
};

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

/// Everything about one level that stays fixed while it iterates.
class LevelSolver {
 public:
  LevelSolver(const SurfaceAlignerOptions& o, const AlignmentProblem& p, const SurfaceState& s, Workspace* ws)
      : opt_(o), prob_(p), ws_(ws) {
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
      strides_.push_back(o.estimate_motion && !p.targets[j].rig_fixed ? kStrideWorld : kStrideRig);
    }
    threads_ = std::max(1, o.num_threads);
  }

  int activeCount() const { return static_cast<int>(active_.size()); }
  void setDampingScale(double s) { damping_scale_ = s; }
  /// The damping of control c: reduced (damping_scale_) only where its data information exceeds
  /// its update weight, so the far edges seen by a few pixels keep their damping.
  double dampingScale(double data_information, int c) const {
    return damping_scale_ < 1.0 && data_information >= opt_.undamped_min_information_ratio * mu_[c] ? damping_scale_ : 1.0;
  }
  int workingTriangles() const { return static_cast<int>(tris_.size()); }
  bool empty() const { return tris_.empty(); }

  std::vector<PairContext> pairs(const SurfaceState& s) const {
    std::vector<PairContext> out(prob_.targets.size());
    for (size_t j = 0; j < out.size(); ++j) {
      const AlignerTarget& t = prob_.targets[j];
      PairContext& c = out[j];
      c.target_T_reference =
          t.rig_fixed ? t.target_T_reference : t.target_T_ground * s.camera_T_ground.inverse();
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

  /// Rasterizes the current surface and accumulates the normal-equation pieces and the cost.
  void evaluate(const SurfaceState& s, Evaluation* ev) {
    const std::vector<PairContext> pc = pairs(s);
    const size_t np = pc.size();
    const size_t nt = tris_.size();
    // Per-triangle planes and, per pair, homographies.
    const Eigen::Isometry3d& ctg = s.camera_T_ground;
    const Eigen::Vector3d cam_pos = -(ctg.linear().transpose() * ctg.translation());
    const Eigen::Matrix3d k = rig_.K();
    const Eigen::Matrix3d kinv = k.inverse();
    auto& hom = ws_->homographies;
    TriangleRasterizer& raster = ws_->raster;
    raster.reset(width_, height_, opt_.border_margin_px);
    for (size_t i = 0; i < nt; ++i) {
      TriangleGeometry& t = tris_[i];
      t.drawn = false;
      const Eigen::Vector3d z(s.heights[t.vertex[0]], s.heights[t.vertex[1]], s.heights[t.vertex[2]]);
      const Eigen::Vector3d pqc = t.heights_to_plane * z;
      // front-facing: the camera is above the triangle's plane
      if (!(cam_pos.z() - (pqc.x() * cam_pos.x() + pqc.y() * cam_pos.y() + pqc.z()) > 1e-3)) continue;
      if (!PlaneGeometry::cameraPlane(ctg, pqc, &t.m)) continue;
      TriangleRasterizer::Triangle rt;
      bool ok = true;
      for (int a = 0; a < 3; ++a) {
        const Eigen::Vector2d xy = prob_.grid->position(t.vertex[static_cast<size_t>(a)]);
        const Eigen::Vector3d xc = ctg * Eigen::Vector3d(xy.x(), xy.y(), z[a]);
        if (!(xc.z() > 0.1)) {
          ok = false;
          break;
        }
        rt.u[a] = rig_.fx * xc.x() / xc.z() + rig_.cx;
        rt.v[a] = rig_.fy * xc.y() / xc.z() + rig_.cy;
      }
      if (!ok) continue;
      rt.rho_a = t.m.x() / rig_.fx;
      rt.rho_b = t.m.y() / rig_.fy;
      rt.rho_c = t.m.z() - t.m.x() * rig_.cx / rig_.fx - t.m.y() * rig_.cy / rig_.fy;
      rt.id = static_cast<int>(i);
      t.drawn = true;
      raster.draw(rt);
    }
    // Slots for the triangles that won pixels; their Jacobian pieces and homographies.
    ev->slot_of.assign(nt, -1);
    ev->slot_tri.clear();
    const cv::Mat& labels = raster.labels();
    for (int v = 0; v < height_; ++v) {
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
      TriangleGeometry& t = tris_[static_cast<size_t>(ev->slot_tri[k2])];
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
      for (int v = 0; v < height_; ++v) total += std::max(0, raster.rowEnd(v) - raster.rowBegin(v) + 1);
      long acc = 0;
      int next = 1;
      for (int v = 0; v < height_ && next < threads_; ++v) {
        acc += std::max(0, raster.rowEnd(v) - raster.rowBegin(v) + 1);
        if (acc * threads_ >= total * next) {
          bounds.push_back(v + 1);
          ++next;
        }
      }
      while (static_cast<int>(bounds.size()) <= threads_) bounds.push_back(height_);
      bounds.back() = height_;
    }
    ev->chunks.resize(static_cast<size_t>(threads_));
    auto work = [&](int c) {
      Chunk& ch = ev->chunks[static_cast<size_t>(c)];
      ch.reset(strides_, ns);
      accumulateRows(pc, *ev, bounds[static_cast<size_t>(c)], bounds[static_cast<size_t>(c) + 1], &ch);
    };
    if (threads_ > 1) {
      tbb::task_arena arena(threads_);
      arena.execute([&] { tbb::parallel_for(0, threads_, work); });
    } else {
      work(0);
    }
    Chunk& sum = ev->chunks[0];
    for (int c = 1; c < threads_; ++c) {
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
    for (const auto& pa : sum.pair) ev->data_cost += data_scale_ * pa.cost;
    const Eigen::VectorXd za = activeHeights(s);
    ev->smoothness_cost = 0.0;
    ev->smooth_residual.resize(stencils_.size());
    ev->smooth_weight.resize(stencils_.size());
    for (size_t k = 0; k < stencils_.size(); ++k) {
      const Stencil& st = stencils_[k];
      const double r = st.w * (za[st.v[0]] - 2.0 * za[st.v[1]] + za[st.v[2]]);
      ev->smooth_residual[k] = r;
      if (smooth_c2_ > 0.0) {
        const double c2 = smooth_c2_ * st.w * st.w;
        ev->smoothness_cost += c2 * std::log1p(r * r / c2);
        ev->smooth_weight[k] = 1.0 / (1.0 + r * r / c2);
      } else {
        ev->smoothness_cost += r * r;
        ev->smooth_weight[k] = 1.0;
      }
    }
    ev->prior_cost = 0.0;
    if (prob_.prior) {
      for (size_t a = 0; a < active_.size(); ++a) {
        const int v = active_[a];
        const double info = prob_.prior->information[v];
        if (info > 0.0) {
          const double d = s.heights[v] - prob_.prior->mean[v];
          ev->prior_cost += info * d * d;
        }
      }
    }
  }

  /// The pixel loop over rows [v0, v1): residuals, robust weights and the inverse compositional
  /// Jacobians accumulated per triangle and pair.
  /// The reference pixels of one row that take part: column, slot and per-pixel constants.
  struct RowPixels {
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
  void accumulateRows(const std::vector<PairContext>& pc, const Evaluation& ev, int v0, int v1, Chunk* ch) const {
    const size_t np = pc.size();
    const size_t ns = ev.slot_tri.size();
    const int* slot_of = ev.slot_of.data();
    const TriangleRasterizer& raster = ws_->raster;
    const float dark = static_cast<float>(opt_.dark_level_grey);
    const float sat = static_cast<float>(opt_.saturated_level_grey);
    const float fx = static_cast<float>(rig_.fx), fy = static_cast<float>(rig_.fy);
    const float cx = static_cast<float>(rig_.cx), cy = static_cast<float>(rig_.cy);
    const cv::Mat& labels = raster.labels();
    RowPixels px;
    for (int v = v0; v < v1; ++v) {
      const int b = raster.rowBegin(v), e_col = raster.rowEnd(v);
      if (b > e_col) continue;
      const int* lab = labels.ptr<int>(v);
      const float* i0row = ref_->image.ptr<float>(v);
      const float* gurow = ref_->grad_u.ptr<float>(v);
      const float* gvrow = ref_->grad_v.ptr<float>(v);
      const uint8_t* exrow = excluded_ ? excluded_->ptr<uint8_t>(v) : nullptr;
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
        ch->tri_textured[static_cast<size_t>(ti)] += gurow[u] * gurow[u] + gvrow[u] * gvrow[u] >= gtex2_;
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
  void dispatchRow(const PairContext& p, size_t j, size_t ns, int v, float y, const RowPixels& px, Chunk* ch,
                   bool photo) const {
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
  void pairRow(const PairContext& p, size_t j, size_t ns, int v, float y, const RowPixels& px, Chunk* ch,
               bool photo) const {
    constexpr int kStride = kWorld ? kStrideWorld : kStrideRig;
    const auto& hom = ws_->homographies;
    const cv::Mat& img = *p.image;
    const float wmax = static_cast<float>(img.cols - 1), hmax = static_cast<float>(img.rows - 1);
    const bool robust = opt_.robust_scale_grey > 0.0;
    const float c2r = static_cast<float>(opt_.robust_scale_grey * opt_.robust_scale_grey);
    const float inv_c2 = robust ? 1.0f / c2r : 0.0f;
    auto rho = [&](float e) { return robust ? c2r * fastLog1p(e * e * inv_c2) : e * e; };
    const float outside_cost = rho(static_cast<float>(
        opt_.outside_penalty_factor * (robust ? opt_.robust_scale_grey : opt_.image_noise_std_grey)));
    const float dark = static_cast<float>(opt_.dark_level_grey);
    const float sat = static_cast<float>(opt_.saturated_level_grey);
    const float gain = static_cast<float>(p.photometric.gain), bias = static_cast<float>(p.photometric.bias_grey);
    const float tx = static_cast<float>(p.t_prime.x()), ty = static_cast<float>(p.t_prime.y()),
                tz = static_cast<float>(p.t_prime.z());
    const float vf = static_cast<float>(v);
    const float cx = static_cast<float>(rig_.cx), cy = static_cast<float>(rig_.cy);
    const float ifx = static_cast<float>(1.0 / rig_.fx), ify = static_cast<float>(1.0 / rig_.fy);
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
        const Eigen::Vector3d& m = tris_[static_cast<size_t>(px.tri[k])].m;
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

  struct Step {
    Eigen::VectorXd dtheta;  ///< basis coefficients (compact controls)
    Eigen::VectorXd dglobal; ///< [motion (6)][photometric (2 per estimated pair)]
    bool ok = false;
  };

  /// Builds and solves the normal equations of the Gauss-Newton step at the evaluated state.
  /// Preconditioned conjugate gradients for [a b; b^T d] [x; y] = [r; q] with a sparse SPD,
  /// preconditioner blockdiag(diag(a), d). Returns false if it did not converge.
  bool augmentedCg(const SpMat& a, const Eigen::MatrixXd& b, const Eigen::MatrixXd& d, const Eigen::VectorXd& r,
                   const Eigen::VectorXd& q, Eigen::VectorXd* x, Eigen::VectorXd* y) const {
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
    for (int it = 0; it < opt_.cg_max_iterations; ++it) {
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
      if (std::sqrt(rc.squaredNorm() + rg.squaredNorm()) < opt_.cg_tolerance * b_norm) return true;
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

  Step solve(const SurfaceState& s, const Evaluation& ev, AlignmentReport* report, bool need_schur = false) {
    const Chunk& sum = ev.sums();
    const std::vector<PairContext> pc = pairs(s);
    const int na = activeCount();
    const int ng = global_count_;
    // Height block on the fixed pattern: smoothness (constant) + data + prior.
    SpMat& hzz = hzz_;
    Eigen::Map<Eigen::VectorXd> values(hzz.valuePtr(), hzz.nonZeros());
    values.setZero();
    Eigen::VectorXd gz = Eigen::VectorXd::Zero(na);
    static constexpr double kCoef[3] = {1.0, -2.0, 1.0};
    for (size_t k = 0; k < stencils_.size(); ++k) {
      const Stencil& st = stencils_[k];
      const double om = ev.smooth_weight[k];
      const double ww = om * st.w * st.w;
      for (int a = 0; a < 3; ++a) {
        gz[st.v[a]] += om * ev.smooth_residual[k] * st.w * kCoef[a];
        for (int b = 0; b < 3; ++b) values[st.idx[a * 3 + b]] += ww * kCoef[a] * kCoef[b];
      }
    }
    Eigen::MatrixXd hzg = Eigen::MatrixXd::Zero(na, ng);
    Eigen::MatrixXd hgg = Eigen::MatrixXd::Zero(ng, ng);
    Eigen::VectorXd gg = Eigen::VectorXd::Zero(ng);
    Eigen::VectorXd data_diag = Eigen::VectorXd::Zero(na);
    const double ks = data_scale_;
    for (size_t j = 0; j < pc.size(); ++j) {
      const PairContext& p = pc[j];
      const bool rig = prob_.targets[j].rig_fixed;
      const int pi = p.photo_index;
      const PairAccumulator& pa = sum.pair[j];
      const int stride = strides_[j];
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
      for (size_t k2 = 0; k2 < ev.slot_tri.size(); ++k2) {
        const TriangleGeometry& t = tris_[static_cast<size_t>(ev.slot_tri[k2])];
        if (sum.tri_pixels[k2] == 0) continue;
        const double* acc = sum.tri[j].data() + k2 * static_cast<size_t>(stride);
        Eigen::Matrix3d dd;
        dd << acc[0], acc[1], acc[2], acc[1], acc[3], acc[4], acc[2], acc[4], acc[5];
        const Eigen::Vector3d de(acc[6], acc[7], acc[8]);
        Matrix32d dp;
        dp << acc[9], acc[10], acc[11], acc[12], acc[13], acc[14];
        const double scale = PlaneGeometry::deltaScale(t.m, p.t_prime);
        const Eigen::Matrix3d a = scale * t.dm_dz;  // delta = a * dz
        if (prob_.estimate_heights) {
          const Eigen::Matrix3d hz = ks * a.transpose() * dd * a;
          const Eigen::Vector3d g3 = ks * a.transpose() * de;
          for (int r = 0; r < 3; ++r) {
            gz[t.local[static_cast<size_t>(r)]] += g3[r];
            data_diag[t.local[static_cast<size_t>(r)]] += hz(r, r);
            for (int c = 0; c < 3; ++c) values[t.value_index[static_cast<size_t>(r * 3 + c)]] += hz(r, c);
          }
          if (pi >= 0) {
            const Matrix32d hzp = ks * a.transpose() * dp;
            for (int r = 0; r < 3; ++r) hzg.block<1, 2>(t.local[static_cast<size_t>(r)], pi) += hzp.row(r);
          }
        }
        if (opt_.estimate_motion) {
          Matrix36d hzm;
          if (rig) {
            const Matrix36d bm = scale * PlaneGeometry::cameraPlaneMotionJacobian(t.m);
            hzm = ks * a.transpose() * dd * bm;
            hgg.topLeftCorner<6, 6>() += ks * bm.transpose() * dd * bm;
            gg.head<6>() += ks * bm.transpose() * de;
            if (pi >= 0) {
              const Matrix62d hmp = ks * bm.transpose() * dp;
              hgg.block<6, 2>(0, pi) += hmp;
              hgg.block<2, 6>(pi, 0) += hmp.transpose();
            }
          } else {
            const Eigen::Map<const Eigen::Matrix<double, 3, 6, Eigen::RowMajor>> dm(acc + 15);
            hzm = ks * a.transpose() * dm;
          }
          if (prob_.estimate_heights) {
            for (int r = 0; r < 3; ++r) hzg.block<1, 6>(t.local[static_cast<size_t>(r)], 0) += hzm.row(r);
          }
        }
      }
    }
    // A pair whose pixels are all masked or outside leaves its photometric block empty; a tiny
    // Levenberg damping keeps the global block invertible (the step for it is then ~0).
    for (int k = 0; k < ng; ++k) hgg(k, k) += 1e-9 * (1.0 + hgg(k, k)) + (hgg(k, k) == 0.0 ? 1.0 : 0.0);
    report->vertex_information = Eigen::VectorXd::Zero(prob_.grid->vertexCount());
    for (int a = 0; a < na; ++a) report->vertex_information[active_[static_cast<size_t>(a)]] = data_diag[a];

    Step step;
    step.dglobal = Eigen::VectorXd::Zero(ng);
    if (!prob_.estimate_heights || control_count_ == 0) {
      step.dtheta = Eigen::VectorXd::Zero(control_count_);
      if (ng == 0) return step;
      const Eigen::LDLT<Eigen::MatrixXd> ldlt(hgg);
      if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) {
        report->degenerate = true;
        return step;
      }
      step.dglobal = ldlt.solve(-gg);
      step.ok = step.dglobal.allFinite();
      if (opt_.estimate_motion) report->motion_information = hgg.topLeftCorner<6, 6>();
      return step;
    }
    // Smoothness and prior gradients on the fine active heights.
    if (prob_.prior) {
      for (int a = 0; a < na; ++a) {
        const int v = active_[static_cast<size_t>(a)];
        const double info = prob_.prior->information[v];
        if (info > 0.0) {
          values[diag_index_[static_cast<size_t>(a)]] += info;
          gz[a] += info * (s.heights[v] - prob_.prior->mean[v]);
        }
      }
    }
    // Project onto the basis; the update constraint on the controls.
    Eigen::VectorXd gc;
    Eigen::MatrixXd hcg;
    const SpMat* hcc = nullptr;
    if (identity_basis_) {
      for (int c = 0; c < control_count_; ++c) values[diag_index_[static_cast<size_t>(c)]] += dampingScale(data_diag[c], c) * mu_[c];
      hcc = &hzz;
      gc = gz;
      hcg = hzg;
    } else {
      hcc_ = basis_t_ * hzz * basis_;
      const Eigen::VectorXd control_data = basis_t_ * data_diag;
      for (int c = 0; c < control_count_; ++c) hcc_.coeffRef(c, c) += dampingScale(control_data[c], c) * mu_[c];
      hcc = &hcc_;
      gc = basis_t_ * gz;
      hcg = basis_t_ * hzg;
    }
    // Conjugate gradients on the whole system [hcc hcg; hcg^T hgg] (one run, block-Jacobi
    // preconditioner), or the Schur complement on the globals with the sparse Cholesky
    // factorization of hcc (small systems, fallback, and when the marginal information of the
    // motion is wanted).
    const bool use_cg = opt_.linear_solver == SurfaceAlignerOptions::LinearSolver::kConjugateGradient &&
                        hcc->rows() >= opt_.cg_min_unknowns && !need_schur;
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
      if (opt_.estimate_motion) {
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

  /// state + alpha * step; returns the largest fine height change [m].
  double apply(const Step& st, double alpha, const SurfaceState& from, SurfaceState* to) const {
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
      to->photometric[j] = from.photometric[j].composedWithInverse(alpha * st.dglobal[pi],
                                                                   alpha * st.dglobal[pi + 1]);
    }
    return max_dz;
  }

  void fillPixels(const Evaluation& ev, AlignmentReport* report) const {
    report->vertex_pixels = Eigen::VectorXi::Zero(prob_.grid->vertexCount());
    report->vertex_excluded_pixels = Eigen::VectorXi::Zero(prob_.grid->vertexCount());
    report->vertex_textured_pixels = Eigen::VectorXi::Zero(prob_.grid->vertexCount());
    for (size_t k2 = 0; k2 < ev.slot_tri.size(); ++k2) {
      const TriangleGeometry& t = tris_[static_cast<size_t>(ev.slot_tri[k2])];
      for (int a = 0; a < 3; ++a) {
        report->vertex_pixels[t.vertex[static_cast<size_t>(a)]] += ev.sums().tri_pixels[k2];
        report->vertex_excluded_pixels[t.vertex[static_cast<size_t>(a)]] += ev.sums().tri_excluded[k2];
        report->vertex_textured_pixels[t.vertex[static_cast<size_t>(a)]] += ev.sums().tri_textured[k2];
      }
    }
  }

 private:
  Eigen::VectorXd activeHeights(const SurfaceState& s) const {
    Eigen::VectorXd za(activeCount());
    for (size_t a = 0; a < active_.size(); ++a) za[static_cast<Eigen::Index>(a)] = s.heights[active_[a]];
    return za;
  }

  void selectWorkingSet(const GroundGrid& g, const SurfaceState& s) {
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
    for (int t = 0; t < g.triangleCount(); ++t) {
      const auto tv = g.triangle(t);
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

  void buildBasis() {
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

  void buildSmoothness(const GroundGrid& g) {
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
    smooth_c2_ = opt_.smoothness_robust_scale_m > 0.0
                     ? opt_.smoothness_robust_scale_m * opt_.smoothness_robust_scale_m
                     : 0.0;
  }

  /// The fixed sparsity pattern of the height block (triangles, smoothness, diagonal) and where
  /// each triangle's 3x3 block lives in its value array.
  void buildPattern() {
    const int na = activeCount();
    std::vector<Eigen::Triplet<double>> trip;
    trip.reserve(tris_.size() * 9 + static_cast<size_t>(na) + stencils_.size() * 9);
    for (const auto& t : tris_)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) trip.emplace_back(t.local[static_cast<size_t>(r)], t.local[static_cast<size_t>(c)], 0.0);
    for (int a = 0; a < na; ++a) trip.emplace_back(a, a, 0.0);
    for (const auto& st : stencils_)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) trip.emplace_back(st.v[static_cast<size_t>(a)], st.v[static_cast<size_t>(b)], 0.0);
    hzz_.resize(na, na);
    hzz_.setFromTriplets(trip.begin(), trip.end());
    hzz_.makeCompressed();
    auto index = [this](int r, int c) {
      const int* begin = hzz_.innerIndexPtr() + hzz_.outerIndexPtr()[c];
      const int* end = hzz_.innerIndexPtr() + hzz_.outerIndexPtr()[c + 1];
      const int* it = std::lower_bound(begin, end, r);
      return static_cast<int>(it - hzz_.innerIndexPtr());
    };
    for (auto& t : tris_)
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          t.value_index[static_cast<size_t>(r * 3 + c)] = index(t.local[static_cast<size_t>(r)], t.local[static_cast<size_t>(c)]);
    diag_index_.resize(static_cast<size_t>(na));
    for (int a = 0; a < na; ++a) diag_index_[static_cast<size_t>(a)] = index(a, a);
    for (auto& st : stencils_)
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) st.idx[static_cast<size_t>(a * 3 + b)] = index(st.v[static_cast<size_t>(a)], st.v[static_cast<size_t>(b)]);
  }

  const SurfaceAlignerOptions& opt_;
  const AlignmentProblem& prob_;
  Workspace* ws_;
  StereoRig rig_;
  const ImagePyramid::Level* ref_ = nullptr;
  const cv::Mat* excluded_ = nullptr;
  int width_ = 0, height_ = 0;
  double data_scale_ = 1.0;
  float gtex2_ = 0.0f;
  int threads_ = 1;
  std::vector<TriangleGeometry> tris_;
  std::vector<int> active_;   ///< compact index -> fine vertex
  std::vector<int> local_;    ///< fine vertex -> compact index or -1
  bool identity_basis_ = true;
  std::vector<int> control_;  ///< compact control -> basis column
  int control_count_ = 0;
  SpMat basis_, basis_t_;     ///< active rows x compact controls
  Eigen::VectorXd mu_;
  double damping_scale_ = 1.0;  ///< scales mu_ (the final undamped step uses a small share)
  struct Stencil {
    std::array<int, 3> v{};    ///< compact indices of the three collinear vertices
    double w = 0.0;            ///< sqrt(lambda) / h-scaled weight of the second difference
    std::array<int, 9> idx{};  ///< positions of its 3x3 block in the height matrix' values
  };
  std::vector<Stencil> stencils_;
  double smooth_c2_ = 0.0;
  SpMat hzz_, hcc_;
  std::vector<int> diag_index_;
  Eigen::SimplicialLDLT<SpMat> chol_;
  bool analyzed_ = false;
  Eigen::Index analyzed_nnz_ = 0;
  int global_count_ = 0;
  std::vector<int> photo_index_;
  std::vector<int> strides_;
};

double median(std::vector<float> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

void checkProblem(const AlignmentProblem& p, const SurfaceState& s) {
  if (!p.reference || !p.rig || !p.grid) throw std::invalid_argument("SurfaceAligner: reference, rig and grid are required");
  if (p.level < 0 || p.level >= p.reference->levels()) throw std::invalid_argument("SurfaceAligner: no such pyramid level");
  if (s.photometric.size() != p.targets.size()) {
    throw std::invalid_argument("SurfaceAligner: one PhotometricParams per target is required");
  }
  for (const auto& t : p.targets) {
    if (!t.pyramid || t.pyramid->levels() <= p.level) throw std::invalid_argument("SurfaceAligner: target pyramid missing or too shallow");
  }
  if (p.prior && (p.prior->mean.size() != p.grid->vertexCount() || p.prior->information.size() != p.grid->vertexCount())) {
    throw std::invalid_argument("SurfaceAligner: prior does not match the grid");
  }
  if (!p.vertex_mask.empty() && static_cast<int>(p.vertex_mask.size()) != p.grid->vertexCount()) {
    throw std::invalid_argument("SurfaceAligner: vertex mask does not match the grid");
  }
}

}  // namespace

SurfaceAligner::SurfaceAligner(const SurfaceAlignerOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("SurfaceAlignerOptions: " + why);
}

AlignmentReport SurfaceAligner::align(const AlignmentProblem& problem, SurfaceState& state) const {
  checkProblem(problem, state);
  thread_local Workspace ws;
  AlignmentReport report;
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
  auto t0 = Clock::now();
  LevelSolver solver(options_, problem, state, &ws);
  report.setup_ms = ms(t0, Clock::now());
  report.working_triangles = solver.workingTriangles();
  report.active_vertices = solver.activeCount();
  if (solver.empty()) {
    report.vertex_information = Eigen::VectorXd::Zero(problem.grid->vertexCount());
    report.vertex_pixels = Eigen::VectorXi::Zero(problem.grid->vertexCount());
    report.vertex_excluded_pixels = Eigen::VectorXi::Zero(problem.grid->vertexCount());
    report.vertex_textured_pixels = Eigen::VectorXi::Zero(problem.grid->vertexCount());
    return report;
  }
  Evaluation* ev = &ws.eval[0];
  Evaluation* trial_ev = &ws.eval[1];
  t0 = Clock::now();
  solver.evaluate(state, ev);
  report.evaluate_ms += ms(t0, Clock::now());
  report.evaluations++;
  report.initial_cost = ev->total();
  SurfaceState trial;
  for (int it = 0; it < options_.max_iterations; ++it) {
    report.iterations = it + 1;
    t0 = Clock::now();
    const auto step = solver.solve(state, *ev, &report);
    report.solve_ms += ms(t0, Clock::now());
    if (!step.ok) break;
    double alpha = 1.0;
    bool accepted = false;
    double max_dz = 0.0;
    for (int h = 0; h <= options_.max_step_halvings; ++h, alpha *= 0.5) {
      max_dz = solver.apply(step, alpha, state, &trial);
      t0 = Clock::now();
      solver.evaluate(trial, trial_ev);
      report.evaluate_ms += ms(t0, Clock::now());
      report.evaluations++;
      if (trial_ev->total() <= ev->total() * (1.0 + 1e-9)) {
        accepted = true;
        break;
      }
    }
    if (!accepted) break;
    const double decrease = ev->total() - trial_ev->total();
    state = trial;
    std::swap(ev, trial_ev);
    report.accepted_steps++;
    if (decrease < options_.converged_relative_decrease * ev->total()) {
      report.converged = true;
      break;
    }
    bool small = max_dz < options_.converged_height_step_m;
    if (options_.estimate_motion) {
      small = small && alpha * step.dglobal.head<3>().norm() < options_.converged_translation_m &&
              alpha * step.dglobal.segment<3>(3).norm() < options_.converged_rotation_rad;
    }
    if (small) {
      report.converged = true;
      break;
    }
  }
  // The update constraint damps every step by mu (most where data is weak, far away): with a few
  // iterations, far vertices stay near their starting heights. A last step with almost no
  // damping moves them to where data, smoothness and prior put them.
  if (options_.final_undamped_step && problem.estimate_heights) {
    solver.setDampingScale(options_.final_step_damping_scale);
    t0 = Clock::now();
    const auto step = solver.solve(state, *ev, &report);
    report.solve_ms += ms(t0, Clock::now());
    if (step.ok) {
      double alpha = 1.0;
      for (int h = 0; h <= options_.max_step_halvings; ++h, alpha *= 0.5) {
        solver.apply(step, alpha, state, &trial);
        t0 = Clock::now();
        solver.evaluate(trial, trial_ev);
        report.evaluate_ms += ms(t0, Clock::now());
        report.evaluations++;
        if (trial_ev->total() <= ev->total() * (1.0 + 1e-9)) {
          state = trial;
          std::swap(ev, trial_ev);
          report.accepted_steps++;
          break;
        }
      }
    }
    solver.setDampingScale(1.0);
  }
  if (options_.estimate_motion && problem.want_motion_information) {
    t0 = Clock::now();
    AlignmentReport tmp;
    solver.solve(state, *ev, &tmp, true);  // the Schur complement at the final state
    report.motion_information = tmp.motion_information;
    report.solve_ms += ms(t0, Clock::now());
  }
  // ev holds the evaluation at the final state; vertex_information comes from the last
  // linearization (the state before the last accepted step), which differs only to second order.
  solver.fillPixels(*ev, &report);
  report.final_cost = ev->total();
  report.data_cost = ev->data_cost;
  report.smoothness_cost = ev->smoothness_cost;
  report.prior_cost = ev->prior_cost;
  report.valid_pixels = 0;
  report.outside_pixels = 0;
  for (const auto& pa : ev->sums().pair) {
    report.valid_pixels += pa.valid;
    report.outside_pixels += pa.outside;
  }
  report.median_abs_residual_grey = median(ev->sums().abs_residuals);
  for (const auto& r : ev->sums().pair_abs_residuals) report.target_median_abs_residual_grey.push_back(median(r));
  return report;
}

cv::Mat SurfaceAligner::renderInverseDepth(const AlignmentProblem& problem, const SurfaceState& state,
                                           cv::Mat* labels) const {
  checkProblem(problem, state);
  SurfaceAlignerOptions o = options_;
  o.estimate_motion = false;
  o.num_threads = 1;
  AlignmentProblem p = problem;
  p.targets.clear();
  SurfaceState s = state;
  s.photometric.clear();
  Workspace ws;
  LevelSolver bare(o, p, s, &ws);
  bare.evaluate(s, &ws.eval[0]);
  if (labels) *labels = ws.raster.labels().clone();
  return ws.raster.inverseDepth().clone();
}

}  // namespace stereo_ground_dem
