#include "stereo_ground_dem/ObstacleDetector.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <stdexcept>

namespace stereo_ground_dem {

bool ObstacleDetectorOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (level < 0 || level > 5) return bad("level must be in 0..5");
  if (window_width_px < 1 || window_height_px < 1) return bad("window sizes must be >= 1");
  if (!(min_obstacle_height_m > 0.0)) return bad("min_obstacle_height_m must be > 0");
  if (!(camera_height_m > min_obstacle_height_m)) return bad("camera_height_m must exceed min_obstacle_height_m");
  if (!(cost_ratio > 0.0 && cost_ratio <= 1.0)) return bad("cost_ratio must be in (0, 1]");
  if (!(min_ground_cost_grey >= 0.0)) return bad("min_ground_cost_grey must be >= 0");
  if (!(min_range_m > 0.0)) return bad("min_range_m must be > 0");
  if (!(ground_band_m >= 0.0) || !(ground_band_m < camera_height_m)) return bad("ground_band_m must be in [0, camera_height_m)");
  if (!(hidden_body_depth_m >= 0.0) || !(hidden_body_depth_m <= 10.0)) return bad("hidden_body_depth_m must be in [0, 10]");
  if (dilation_px < 0) return bad("dilation_px must be >= 0");
  if (num_threads < 1) return bad("num_threads must be >= 1");
  if (!(foot_min_ratio > 0.0 && foot_min_ratio <= 1.0)) return bad("foot_min_ratio must be in (0, 1]");
  if (!(far_depth_ratio == 0.0 || far_depth_ratio > 1.0)) return bad("far_depth_ratio must be 0 (off) or > 1");
  return true;
}

namespace {

// The 3-D points [m] in the ground frame of the pixels of `disparity` (level-0 pixels, 0 = none)
// at pyramid level `level`.
std::vector<Eigen::Vector3d> pointsOf(const cv::Mat& disparity, int level, const StereoRig& rig,
                                      const Eigen::Isometry3d& ground_T_camera) {
  std::vector<Eigen::Vector3d> pts;
  if (disparity.empty()) return pts;
  const double scale = std::ldexp(1.0, level);  // test-level pixel -> level-0 pixel
  for (int v = 0; v < disparity.rows; ++v) {
    const float* d = disparity.ptr<float>(v);
    for (int u = 0; u < disparity.cols; ++u) {
      if (!(d[u] > 0.0f)) continue;
      const double z = rig.disparityTimesDepth() / d[u];
      const Eigen::Vector3d xc((u * scale - rig.cx) * z / rig.fx, (v * scale - rig.cy) * z / rig.fy, z);
      pts.push_back(ground_T_camera * xc);
    }
  }
  return pts;
}

}  // namespace

std::vector<Eigen::Vector3d> ObstacleMask::groundPoints(const StereoRig& rig,
                                                        const Eigen::Isometry3d& ground_T_camera) const {
  return pointsOf(disparity, level, rig, ground_T_camera);
}

std::vector<Eigen::Vector3d> ObstacleMask::farPoints(const StereoRig& rig, const Eigen::Isometry3d& ground_T_camera) const {
  return pointsOf(far_disparity, level, rig, ground_T_camera);
}

std::vector<Eigen::Vector3d> ObstacleMask::uprightPoints(const StereoRig& rig,
                                                         const Eigen::Isometry3d& ground_T_camera) const {
  return pointsOf(upright_disparity, level, rig, ground_T_camera);
}

ObstacleEvidence ObstacleDetector::evidence(const GroundGrid& grid, const Eigen::VectorXd& heights,
                                            const Eigen::VectorXi& ground_pixels, const Eigen::VectorXi& excluded_pixels,
                                            const std::vector<Eigen::Vector3d>& points, double hidden_ratio,
                                            int min_ground_pixels, double min_height, double body_depth_m,
                                            int min_points, const Eigen::Vector3d* camera_position) {
  const int n = grid.vertexCount();
  ObstacleEvidence ev;
  ev.hit.assign(static_cast<size_t>(n), 0);
  ev.ground.assign(static_cast<size_t>(n), 0);
  ev.hidden.assign(static_cast<size_t>(n), 0);
  ev.height = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  std::vector<int> count(static_cast<size_t>(n), 0);
  for (const auto& p : points) {
    const int c = static_cast<int>(std::lround(p.x() / grid.resolution_m)) - grid.col0;
    const int r = static_cast<int>(std::lround(p.y() / grid.resolution_m)) - grid.row0;
    if (!grid.contains(r, c)) continue;
    const int v = grid.index(r, c);
    if (!std::isfinite(heights[v])) continue;
    const double above = p.z() - heights[v];
    if (above < min_height) continue;
    ++count[static_cast<size_t>(v)];
    ev.height[v] = std::isfinite(ev.height[v]) ? std::max(ev.height[v], above) : above;
  }
  for (int v = 0; v < n; ++v) {
    const bool hidden = ground_pixels.size() == n && excluded_pixels.size() == n && excluded_pixels[v] > 0 &&
                        excluded_pixels[v] > hidden_ratio * ground_pixels[v];
    // Obstacle points count only where obstacle pixels also cover part of the vertex's triangles:
    // a thing standing there hides some of its ground; a point from a wrong disparity far away
    // does not.
    const bool covered = excluded_pixels.size() == n && excluded_pixels[v] > 0;
    const bool points_here = covered && count[static_cast<size_t>(v)] >= min_points;
    if (!points_here) ev.height[v] = std::numeric_limits<double>::quiet_NaN();
    // Ground hidden behind something is not seen: neither obstacle nor ground (the occlusion shadow
    // of a car stays unknown instead of becoming a long lethal streak behind it).
    ev.hit[static_cast<size_t>(v)] = points_here;
    ev.hidden[static_cast<size_t>(v)] = hidden;
    ev.ground[static_cast<size_t>(v)] =
        !points_here && !hidden && ground_pixels.size() == n && ground_pixels[v] >= min_ground_pixels;
  }
  // The body: hidden vertices near a hit one.
  const int reach = static_cast<int>(std::floor(body_depth_m / grid.resolution_m + 1e-9));
  if (reach > 0 && camera_position) {
    // ... behind it along the camera's ray (the thing's body beyond its visible face)
    const std::vector<uint8_t> standing = ev.hit;
    const double step = 0.25 * grid.resolution_m;
    for (int r = 0; r < grid.rows; ++r) {
      for (int c = 0; c < grid.cols; ++c) {
        if (!standing[static_cast<size_t>(grid.index(r, c))]) continue;
        const Eigen::Vector2d p(grid.xOfCol(c), grid.yOfRow(r));
        Eigen::Vector2d dir = p - camera_position->head<2>();
        if (dir.norm() < 1e-6) continue;
        dir.normalize();
        for (double t = step; t <= body_depth_m + 1e-9; t += step) {
          const Eigen::Vector2d q = p + t * dir;
          const int qc = static_cast<int>(std::lround(q.x() / grid.resolution_m)) - grid.col0;
          const int qr = static_cast<int>(std::lround(q.y() / grid.resolution_m)) - grid.row0;
          if (!grid.contains(qr, qc)) break;
          const size_t u = static_cast<size_t>(grid.index(qr, qc));
          if (ev.hidden[u]) ev.hit[u] = 1;
        }
      }
    }
  } else if (reach > 0) {
    const std::vector<uint8_t> standing = ev.hit;
    for (int r = 0; r < grid.rows; ++r) {
      for (int c = 0; c < grid.cols; ++c) {
        if (!standing[static_cast<size_t>(grid.index(r, c))]) continue;
        for (int dr = -reach; dr <= reach; ++dr) {
          for (int dc = -reach; dc <= reach; ++dc) {
            if (dr * dr + dc * dc > reach * reach || !grid.contains(r + dr, c + dc)) continue;
            const size_t u = static_cast<size_t>(grid.index(r + dr, c + dc));
            if (ev.hidden[u]) ev.hit[u] = 1;
          }
        }
      }
    }
  }
  return ev;
}

ObstacleDetector::ObstacleDetector(const ObstacleDetectorOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("ObstacleDetectorOptions: " + why);
}

namespace {
constexpr int kHalfStepBelowPx = 10;  ///< test-level disparities below this are swept in half pixels
constexpr int kFootSearchRows = 3;    ///< test-level rows below an obstacle run searched for its foot's ground
}  // namespace

ObstacleMask ObstacleDetector::detect(const ImagePyramid& left, const ImagePyramid& right, const StereoRig& rig,
                                      const PhotometricParams& ph, const cv::Mat& ground_rho) const {
  const ObstacleDetectorOptions& o = options_;
  ObstacleMask out;
  const int levels = left.levels();
  const int lv = std::min(o.level, levels - 1);
  out.level = lv;
  const cv::Mat& l = left.level(lv).image;
  const int w = l.cols, h = l.rows;
  for (int k = 0; k < levels; ++k) out.excluded.push_back(cv::Mat::zeros(left.height(k), left.width(k), CV_8U));
  out.disparity = cv::Mat::zeros(h, w, CV_32F);
  out.far_disparity = cv::Mat::zeros(h, w, CV_32F);
  out.upright_disparity = cv::Mat::zeros(h, w, CV_32F);
  if (!o.enabled) return out;
  if (ground_rho.size() != l.size() || ground_rho.type() != CV_32F) {
    throw std::invalid_argument("ObstacleDetector: ground inverse depth must be CV_32F of the test level's size");
  }
  const StereoRig r = rig.atLevel(lv);
  const double fxb = r.fx * r.baseline_m;
  cv::Mat a;  // photometrically corrected right image
  right.level(lv).image.convertTo(a, CV_32F, ph.gain, ph.bias_grey);

  // Ground hypothesis: slanted windows following the mesh's own disparity, and the same surface
  // raised or lowered by up to ground_band_m (a plane parallel to the ground raised by h has
  // disparity d * H / (H - h)): raised ground such as a curb top or a terrace is ground.
  cv::Mat dg(h, w, CV_32F);
  for (int v = 0; v < h; ++v) {
    const float* rho = ground_rho.ptr<float>(v);
    float* d = dg.ptr<float>(v);
    for (int u = 0; u < w; ++u) d[u] = rho[u] > 0.0f ? static_cast<float>(fxb * rho[u]) : 0.0f;
  }
  const cv::Size win(o.window_width_px, o.window_height_px);
  // Rows without ground (above the horizon) are skipped by both sweeps; the windows of the rows
  // with ground reach hh rows beyond them (rows without ground add nothing to a ground window).
  int row0 = h, row1 = -1;
  for (int v = 0; v < h; ++v) {
    if (cv::countNonZero(dg.row(v) > 0.0f) > 0) {
      row0 = std::min(row0, v);
      row1 = std::max(row1, v);
    }
  }
  if (row1 < row0) return out;
  const int hw = o.window_width_px / 2, hh = o.window_height_px / 2;
  const int r0 = std::max(0, row0 - hh), r1 = std::min(h - 1, row1 + hh);
  const cv::Range rows(r0, r1 + 1);
  const int bands = std::max(1, static_cast<int>(std::ceil(o.ground_band_m / 0.1)));
  // The band offsets k in [k0, k1): the lowest mean |residual| over each pixel's window.
  auto sweepGround = [&](int k0, int k1, cv::Mat* cost) {
    *cost = cv::Mat(h, w, CV_32F, cv::Scalar(1e30f));
    const int n = r1 - r0 + 1;
    cv::Mat res_g(n, w, CV_32F), valid_g(n, w, CV_32F), sum_g, cnt_g;
    for (int k = k0; k < k1; ++k) {
      const double hk = o.ground_band_m * k / bands;
      const float sc = static_cast<float>(o.camera_height_m / (o.camera_height_m - hk));
      res_g.setTo(0.0f);
      valid_g.setTo(0.0f);
      for (int v = r0; v <= r1; ++v) {
        const float* d = dg.ptr<float>(v);
        const float* lr = l.ptr<float>(v);
        const float* ar = a.ptr<float>(v);
        float* rg = res_g.ptr<float>(v - r0);
        float* vg = valid_g.ptr<float>(v - r0);
        for (int u = 0; u < w; ++u) {
          if (!(d[u] > 0.0f)) continue;
          const float x = static_cast<float>(u) - d[u] * sc;
          if (x < 0.0f || x >= w - 1) continue;
          const int x0 = static_cast<int>(x);
          const float f = x - static_cast<float>(x0);
          rg[u] = std::abs(lr[u] - ((1.0f - f) * ar[x0] + f * ar[x0 + 1]));
          vg[u] = 1.0f;
        }
      }
      cv::boxFilter(res_g, sum_g, CV_32F, win, cv::Point(-1, -1), false, cv::BORDER_CONSTANT);
      cv::boxFilter(valid_g, cnt_g, CV_32F, win, cv::Point(-1, -1), false, cv::BORDER_CONSTANT);
      for (int v = row0; v <= row1; ++v) {
        const float* sm = sum_g.ptr<float>(v - r0);
        const float* c = cnt_g.ptr<float>(v - r0);
        float* cg = cost->ptr<float>(v);
        for (int u = 0; u < w; ++u) {
          if (c[u] >= 0.5f * win.area()) cg[u] = std::min(cg[u], sm[u] / c[u]);
        }
      }
    }
  };
  // Two threads take the two halves of the sweeps; the minimum is the same in any order, and the
  // upright sweep's halves are merged so that the earlier candidate wins ties, as in one pass.
  const bool two = o.num_threads > 1;
  std::unique_ptr<tbb::task_arena> arena = two ? std::make_unique<tbb::task_arena>(2) : nullptr;
  auto both = [&](const std::function<void(int)>& f) {
    if (two) arena->execute([&] { tbb::parallel_for(0, 2, f); });
    else f(0);
  };
  cv::Mat cost_g, cost_g2;
  both([&](int c) {
    const int mid = two ? 0 : bands + 1;  // band offsets -bands..mid-1 and mid..bands
    if (c == 0) sweepGround(-bands, mid, &cost_g);
    else sweepGround(mid, bands + 1, &cost_g2);
  });
  if (two) cv::min(cost_g, cost_g2, cost_g);

  // Upright hypothesis: fronto-parallel windows at integer disparities closer than the ground.
  const double ratio = o.camera_height_m / (o.camera_height_m - o.min_obstacle_height_m);
  const int dmax = std::min(w - 2, static_cast<int>(std::ceil(fxb / o.min_range_m)));
  cv::Mat thr(h, w, CV_32F);
  for (int v = 0; v < h; ++v) {
    const float* d = dg.ptr<float>(v);
    float* t = thr.ptr<float>(v);
    for (int u = 0; u < w; ++u) t[u] = d[u] > 0.0f ? static_cast<float>(d[u] * ratio + o.margin_px) : 1e30f;
  }
  const bool far_test = o.far_depth_ratio > 0.0;
  // Far surfaces: disparities at most the ground's / far_depth_ratio (-1: none).
  cv::Mat thr_far(h, w, CV_32F, cv::Scalar(-1.0f));
  if (far_test) {
    for (int v = 0; v < h; ++v) {
      const float* d = dg.ptr<float>(v);
      float* t = thr_far.ptr<float>(v);
      for (int u = 0; u < w; ++u) t[u] = d[u] > 0.0f ? static_cast<float>(d[u] / o.far_depth_ratio) : -1.0f;
    }
  }
  const float inv_area = 1.0f / static_cast<float>(win.area());
  // Integer disparities, and half-pixel steps where they are small (far obstacles): a window
  // half a pixel off its disparity costs as much as the ground on fine texture.
  std::vector<float> candidates;
  for (int d2 = far_test ? 1 : 2; d2 <= 2 * dmax; ++d2) {
    if (d2 % 2 == 0 || d2 < 2 * kHalfStepBelowPx) candidates.push_back(0.5f * static_cast<float>(d2));
  }
  // Candidates [c0, c1): the cheapest window per pixel (the first of equals) and its disparity.
  auto sweepUpright = [&](size_t c0, size_t c1, cv::Mat* best, cv::Mat* best_d, cv::Mat* best_far,
                          cv::Mat* best_far_d) {
    *best = cv::Mat(h, w, CV_32F, cv::Scalar(1e30f));
    *best_d = cv::Mat::zeros(h, w, CV_32F);
    *best_far = cv::Mat(h, w, CV_32F, cv::Scalar(1e30f));
    *best_far_d = cv::Mat::zeros(h, w, CV_32F);
    cv::Mat diff(h, w, CV_32F, cv::Scalar(0.0f)), sum_d;
    for (size_t ci = c0; ci < c1; ++ci) {
      const float df = candidates[ci];
      const int d = static_cast<int>(std::ceil(df));
      const float f = static_cast<float>(d) - df;  // right sample at u - df = (1 - f) * a[u-d] + f * a[u-d+1]
      for (int v = r0; v <= r1; ++v) {
        const float* lr = l.ptr<float>(v);
        const float* ar = a.ptr<float>(v);
        float* dfp = diff.ptr<float>(v);
        if (f == 0.0f) {
          for (int u = d; u < w; ++u) dfp[u] = std::abs(lr[u] - ar[u - d]);
        } else {
          for (int u = d; u < w; ++u) dfp[u] = std::abs(lr[u] - ((1.0f - f) * ar[u - d] + f * ar[u - d + 1]));
        }
      }
      cv::boxFilter(diff.rowRange(rows), sum_d, CV_32F, win, cv::Point(-1, -1), false, cv::BORDER_REPLICATE);
      for (int v = row0; v <= row1; ++v) {
        const float* s = sum_d.ptr<float>(v - r0);
        const float* t = thr.ptr<float>(v);
        float* b = best->ptr<float>(v);
        float* bd = best_d->ptr<float>(v);
        if (far_test) {
          const float* tf = thr_far.ptr<float>(v);
          float* bf = best_far->ptr<float>(v);
          float* bfd = best_far_d->ptr<float>(v);
          for (int u = d + hw; u < w; ++u) {
            const float m = s[u] * inv_area;
            if (df <= tf[u] && m < bf[u]) {
              bf[u] = m;
              bfd[u] = df;
            }
          }
        }
        for (int u = d + hw; u < w; ++u) {  // windows reaching past the left border are skipped
          if (df < t[u]) continue;
          const float m = s[u] * inv_area;
          if (m < b[u]) {
            b[u] = m;
            bd[u] = df;
          }
        }
      }
    }
  };
  // The split that gives both halves about the same number of columns to sweep.
  size_t mid = candidates.size();
  if (two) {
    double total = 0.0, acc = 0.0;
    for (float df : candidates) total += w - std::ceil(df);
    for (mid = 0; mid < candidates.size() && acc < 0.5 * total; ++mid) acc += w - std::ceil(candidates[mid]);
  }
  cv::Mat best, best_d, best2, best_d2, best_far, best_far2, best_far_d, best_far_d2;
  both([&](int c) {
    if (c == 0) sweepUpright(0, mid, &best, &best_d, &best_far, &best_far_d);
    else sweepUpright(mid, candidates.size(), &best2, &best_d2, &best_far2, &best_far_d2);
  });
  if (two && far_test) {
    const cv::Mat second = best_far2 < best_far;
    best_far2.copyTo(best_far, second);
    best_far_d2.copyTo(best_far_d, second);
  }
  if (two) {
    for (int v = row0; v <= row1; ++v) {
      float* b = best.ptr<float>(v);
      float* bd = best_d.ptr<float>(v);
      const float* b2 = best2.ptr<float>(v);
      const float* bd2 = best_d2.ptr<float>(v);
      for (int u = 0; u < w; ++u) {
        if (b2[u] < b[u]) {
          b[u] = b2[u];
          bd[u] = bd2[u];
        }
      }
    }
  }
  cv::Mat mask = cv::Mat::zeros(h, w, CV_8U);
  const float scale = std::ldexp(1.0f, lv);
  for (int v = 0; v < h; ++v) {
    const float* cg = cost_g.ptr<float>(v);
    const float* b = best.ptr<float>(v);
    const float* bd = best_d.ptr<float>(v);
    const float* rho = ground_rho.ptr<float>(v);
    uint8_t* m = mask.ptr<uint8_t>(v);
    float* od = out.disparity.ptr<float>(v);
    float* ud = out.upright_disparity.ptr<float>(v);
    for (int u = 0; u < w; ++u) {
      if (!(rho[u] > 0.0f) || cg[u] > 1e29f || b[u] > 1e29f) continue;
      if (cg[u] > o.min_ground_cost_grey && b[u] < o.cost_ratio * cg[u]) {
        m[u] = 255;
        od[u] = bd[u] * scale;
        ud[u] = od[u];
      }
    }
  }
  // Left of column d + hw the right image does not see what the left one sees at disparity d, and
  // neither hypothesis can be tested there: a thing entering the view from the left (an
  // overtaking car) is flagged only right of that limit, and the rest of it would enter the
  // temporal pairs as ground that moves. Rows whose leftmost obstacle pixel lies at the limit of
  // its own disparity are taken to continue to the image's border, where such rows form a run
  // (gaps of up to 2 rows) at least two windows tall: a thing, not a few rows of rough ground
  // flagged at the limit.
  if (o.continue_at_left_border) {
    std::vector<int> first(static_cast<size_t>(h), -1);  // the row's leftmost pixel, at the limit
    for (int v = 0; v < h; ++v) {
      const uint8_t* m = mask.ptr<uint8_t>(v);
      const float* od = out.disparity.ptr<float>(v);
      int u0 = 0;
      while (u0 < w && !m[u0]) ++u0;
      if (u0 == 0 || u0 >= w) continue;
      if (u0 <= static_cast<int>(std::ceil(od[u0] / scale)) + hw + 1) first[static_cast<size_t>(v)] = u0;
    }
    const int min_span = 2 * o.window_height_px;
    for (int v = 0; v < h;) {
      if (first[static_cast<size_t>(v)] < 0) {
        ++v;
        continue;
      }
      int end = v, gap = 0;
      for (int k = v + 1; k < h && gap <= 2; ++k) {
        if (first[static_cast<size_t>(k)] >= 0) {
          end = k;
          gap = 0;
        } else {
          ++gap;
        }
      }
      if (end - v + 1 >= min_span) {
        for (int k = v; k <= end; ++k) {
          const int u0 = first[static_cast<size_t>(k)];
          if (u0 < 0) continue;
          uint8_t* m = mask.ptr<uint8_t>(k);
          float* od = out.disparity.ptr<float>(k);
          std::fill(m, m + u0, uint8_t{255});
          std::fill(od, od + u0, od[u0]);
        }
      }
      v = end + 1;
    }
  }
  // An upright obstacle reaches down to where it stands: below a flagged pixel, the column belongs
  // to the obstacle until the ground's disparity reaches the obstacle's (its foot), as long as
  // the upright surface at the obstacle's disparity explains the pixel's window at least as well
  // as the ground. This covers the low parts (bumpers, the base of a pole) whose disparity is too
  // close to the ground's for the test above.
  constexpr int kMinRun = 3;  // a foot is sought only below an upright run of this many pixels
  auto uprightCost = [&](int u, int v, int d) {
    float sum = 0.0f;
    int n = 0;
    for (int dv = -hh; dv <= hh; ++dv) {
      const int vv = v + dv;
      if (vv < 0 || vv >= h) continue;
      const float* lr = l.ptr<float>(vv);
      const float* ar = a.ptr<float>(vv);
      for (int du = -hw; du <= hw; ++du) {
        const int uu = u + du;
        if (uu < 0 || uu >= w || uu - d < 0) continue;
        sum += std::abs(lr[uu] - ar[uu - d]);
        ++n;
      }
    }
    return n > 0 ? sum / static_cast<float>(n) : 1e30f;
  };
  // The flagged pixels' own disparities to a fraction of a pixel (a parabola through the window
  // costs at the best whole disparity and its neighbours): whole pixels at the test level put the
  // points of one disparity on one line across the view, up to a metre apart in depth at 10 m.
  for (int v = 0; v < h; ++v) {
    float* ud = out.upright_disparity.ptr<float>(v);
    for (int u = 0; u < w; ++u) {
      if (!(ud[u] > 0.0f)) continue;
      const int d = static_cast<int>(std::lround(ud[u] / scale));
      const float c0 = uprightCost(u, v, d), cm = uprightCost(u, v, d - 1), cp = uprightCost(u, v, d + 1);
      const float curvature = cm - 2.0f * c0 + cp;
      if (d >= 1 && cm < 1e29f && cp < 1e29f && curvature > 0.0f) {
        ud[u] = (static_cast<float>(d) + std::clamp(0.5f * (cm - cp) / curvature, -0.5f, 0.5f)) * scale;
      }
    }
  }
  for (int u = 0; u < w; ++u) {
    float d_obst = 0.0f;
    int run = 0;  // flagged pixels in a row with consistent disparity just above
    float run_d = 0.0f;
    for (int v = 0; v < h; ++v) {
      uint8_t& m = mask.at<uint8_t>(v, u);
      float& od = out.disparity.at<float>(v, u);
      const float d_ground = dg.at<float>(v, u) * scale;
      if (m) {
        run = (run > 0 && std::abs(od - run_d) <= 0.15f * run_d + scale) ? run + 1 : 1;
        run_d = run > 1 ? std::max(run_d, od) : od;
        if (run >= kMinRun) d_obst = std::max(d_obst, run_d);
      } else if (d_obst > 0.0f && d_ground > 0.0f && d_ground < d_obst * 0.97f &&
                 uprightCost(u, v, static_cast<int>(std::lround(d_obst / scale))) <= 1.5f * cost_g.at<float>(v, u)) {
        m = 255;
        od = d_obst;
      } else {
        d_obst = 0.0f;
        run = 0;
      }
    }
  }
  // The depth of an upright thing is where it stands: each column's run of obstacle pixels takes
  // the ground's disparity just below its lowest pixel (its foot), which the mesh knows well,
  // instead of its own windows' disparities (a car's plain side panel matches at many
  // disparities, and a wrong one throws its points metres behind the car). A run whose foot is
  // not on the ground in view (a car's roof line cut off from its body by a gap in the mask,
  // something overhanging) takes the foot of the run below it in the column when their
  // disparities agree, and otherwise keeps its own. Runs are taken bottom-up.
  if (o.foot_depth) {
    std::vector<float> run_d;
    const auto agrees = [&](float a, float b) {
      return a > 0.0f && a >= o.foot_min_ratio * b && a <= b / o.foot_min_ratio;
    };
    for (int u = 0; u < w; ++u) {
      float below_foot = 0.0f;  // the foot of the run below in this column [level-0 px]
      for (int v1 = h - 1; v1 >= 0;) {
        if (!mask.at<uint8_t>(v1, u)) {
          --v1;
          continue;
        }
        int v0 = v1;
        while (v0 > 0 && mask.at<uint8_t>(v0 - 1, u)) --v0;
        run_d.clear();
        for (int k = v0; k <= v1; ++k) run_d.push_back(out.disparity.at<float>(k, u));
        std::nth_element(run_d.begin(), run_d.begin() + static_cast<std::ptrdiff_t>(run_d.size() / 2), run_d.end());
        const float own = run_d[run_d.size() / 2];
        // The contact is the run's lower edge, between its lowest pixel and the ground pixel
        // below, where the ground's disparity (linear along a column on a plane) is the mean of
        // the two; with no ground in the lowest pixel, the first ground pixel within
        // kFootSearchRows below (the mesh's far edge and the level plane beyond it may leave a
        // row between them).
        float foot = 0.0f;  // level-0 px
        for (int k = v1 + 1; k < h && k <= v1 + kFootSearchRows && !(foot > 0.0f); ++k) foot = dg.at<float>(k, u) * scale;
        if (foot > 0.0f && v1 + 1 < h && dg.at<float>(v1 + 1, u) > 0.0f && dg.at<float>(v1, u) > 0.0f) {
          foot = 0.5f * (dg.at<float>(v1, u) + dg.at<float>(v1 + 1, u)) * scale;
        }
        if (!agrees(foot, own)) foot = agrees(below_foot, own) ? below_foot : 0.0f;
        if (foot > 0.0f) {
          for (int k = v0; k <= v1; ++k) out.disparity.at<float>(k, u) = foot;
          below_foot = foot;
        }
        v1 = v0 - 1;
      }
    }
  }
  out.pixels = cv::countNonZero(mask);
  // Pixels seeing past the surface (far_depth_ratio): excluded, no obstacle (no point, not counted
  // above).
  if (far_test) {
    for (int v = row0; v <= row1; ++v) {
      const float* cg = cost_g.ptr<float>(v);
      const float* b = best.ptr<float>(v);
      const float* bf = best_far.ptr<float>(v);
      const float* bfd = best_far_d.ptr<float>(v);
      const float* rho = ground_rho.ptr<float>(v);
      uint8_t* m = mask.ptr<uint8_t>(v);
      float* fd = out.far_disparity.ptr<float>(v);
      for (int u = 0; u < w; ++u) {
        if (m[u] || !(rho[u] > 0.0f) || cg[u] > 1e29f || bf[u] > 1e29f) continue;
        if (cg[u] > o.min_ground_cost_grey && bf[u] < o.cost_ratio * cg[u] && bf[u] < b[u]) {
          m[u] = 255;
          fd[u] = bfd[u] * scale;
          ++out.far_pixels;
        }
      }
    }
  }
  if (o.dilation_px > 0) {
    cv::dilate(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * o.dilation_px + 1, 2 * o.dilation_px + 1)));
  }
  // Masks for every level: nearest-neighbour upsampling to finer levels, any-of to coarser ones.
  out.excluded = left.maskOnEveryLevel(mask, lv);
  return out;
}

}  // namespace stereo_ground_dem
