#include "stereo_ground_dem/RectificationMonitor.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace stereo_ground_dem {

bool RectificationMonitorOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (match_level < 0 || match_level > 4) return bad("match_level must be in 0..4");
  if (!(min_corner_strength > 0.0 && min_corner_strength < 1.0)) return bad("min_corner_strength must be in (0, 1)");
  if (cell_px < 2 || border_px < 0 || lk_window_px < 3 || lk_levels < 0) {
    return bad("need cell_px >= 2, border_px >= 0, lk_window_px >= 3, lk_levels >= 0");
  }
  if (!(max_forward_backward_px > 0.0)) return bad("max_forward_backward_px must be > 0");
  if (min_matches < 5) return bad("min_matches must be >= 5");
  if (!(min_disparity_px >= 0.0) || !(max_misalignment_px > 0.0) || !(max_disparity_px > 0.0)) {
    return bad("need min_disparity_px >= 0, max_misalignment_px > 0 and max_disparity_px > 0");
  }
  if (!(huber_k > 0.0)) return bad("huber_k must be > 0");
  if (!(forgetting > 0.0 && forgetting <= 1.0)) return bad("forgetting must be in (0, 1]");
  if (!(shape_prior_std_px > 0.0)) return bad("shape_prior_std_px must be > 0");
  return true;
}

RectificationMonitor::RectificationMonitor(const RectificationMonitorOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("RectificationMonitorOptions: " + why);
}

void RectificationMonitor::reset() {
  information_.setZero();
  information_vector_.setZero();
  pairs_ = 0;
}

namespace {

double medianOf(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

inline float sample(const cv::Mat& img, float u, float v) {
  const int u0 = static_cast<int>(u), v0 = static_cast<int>(v);
  const float fu = u - static_cast<float>(u0), fv = v - static_cast<float>(v0);
  const float* r0 = img.ptr<float>(v0) + u0;
  const float* r1 = img.ptr<float>(v0 + 1) + u0;
  return (1.0f - fv) * ((1.0f - fu) * r0[0] + fu * r0[1]) + fv * ((1.0f - fu) * r1[0] + fu * r1[1]);
}

}  // namespace

bool RectificationMonitor::refineWithShear(const cv::Mat& left, const cv::Mat& right, const cv::Mat& right_gu,
                                           const cv::Mat& right_gv, const cv::Point2f& p, cv::Point2f* q) const {
  // Gauss-Newton on a window around the left corner: the right window is displaced by (dx, dy)
  // with a horizontal shear (dx grows by a per column and b per row: a slanted surface), and
  // scaled by gain and offset. Lucas-Kanade's pure translation mistakes the ground's shear, whose
  // disparity grows by about baseline / camera height per row, for a vertical offset.
  const int r = options_.lk_window_px / 2 + 1;
  const int u0 = static_cast<int>(std::lround(p.x)), v0 = static_cast<int>(std::lround(p.y));
  if (u0 - r < 0 || v0 - r < 0 || u0 + r >= left.cols || v0 + r >= left.rows) return false;
  double dx = q->x - u0, dy = q->y - v0, a = 0.0, b = 0.0, gain = 1.0, bias = 0.0;
  const float umax = static_cast<float>(right.cols - 2), vmax = static_cast<float>(right.rows - 2);
  for (int it = 0; it < 10; ++it) {
    Matrix6d h = Matrix6d::Zero();
    Vector6d g = Vector6d::Zero();
    for (int j = -r; j <= r; ++j) {
      const float* lrow = left.ptr<float>(v0 + j);
      for (int i = -r; i <= r; ++i) {
        const float ur = static_cast<float>(u0 + i + dx + a * i + b * j), vr = static_cast<float>(v0 + j + dy);
        if (!(ur >= 0.0f && vr >= 0.0f && ur < umax && vr < vmax)) return false;
        const double ir = sample(right, ur, vr);
        const double gu = gain * sample(right_gu, ur, vr), gv = gain * sample(right_gv, ur, vr);
        const double e = gain * ir + bias - lrow[u0 + i];
        const double jac[6] = {gu, gv, gu * i, gu * j, ir, 1.0};
        for (int rr = 0; rr < 6; ++rr) {
          for (int cc = 0; cc <= rr; ++cc) h(rr, cc) += jac[rr] * jac[cc];  // the lower triangle
          g[rr] += e * jac[rr];
        }
      }
    }
    h = h.selfadjointView<Eigen::Lower>();
    const Eigen::LDLT<Matrix6d> ldlt(h);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return false;
    const Vector6d d = -ldlt.solve(g);
    if (!d.allFinite()) return false;
    dx += d[0];
    dy += d[1];
    a += d[2];
    b += d[3];
    gain += d[4];
    bias += d[5];
    if (std::abs(d[0]) < 1e-3 && std::abs(d[1]) < 1e-3) break;
  }
  // A window that needs more than a little shear or moved far from Lucas-Kanade's answer is not trusted.
  if (std::abs(a) > 0.5 || std::abs(b) > 0.8 || std::hypot(u0 + dx - q->x, v0 + dy - q->y) > 1.0 || !(gain > 0.2)) {
    return false;
  }
  q->x = static_cast<float>(u0 + dx);
  q->y = static_cast<float>(v0 + dy);
  return true;
}


StereoPairCheck RectificationMonitor::measure(const cv::Mat& left, const cv::Mat& right_in, const StereoRig& rig,
                                              const std::vector<float>* row_disparity) const {
  const auto t0 = std::chrono::steady_clock::now();
  StereoPairCheck out;
  if (left.empty() || left.size() != right_in.size() || left.type() != CV_32F || right_in.type() != CV_32F) {
    throw std::invalid_argument("RectificationMonitor::measure: two CV_32F images of one size are required");
  }
  // The expected disparity of each row (0 without one): the right image's rows shifted by it.
  const auto shiftAt = [row_disparity](float v) -> float {
    if (!row_disparity || row_disparity->empty()) return 0.0f;
    const int n = static_cast<int>(row_disparity->size());
    const float vc = std::min(std::max(v, 0.0f), static_cast<float>(n - 1));
    const int v0 = std::min(static_cast<int>(vc), n - 1), v1 = std::min(v0 + 1, n - 1);
    const float f = vc - static_cast<float>(v0);
    return (1.0f - f) * (*row_disparity)[static_cast<size_t>(v0)] + f * (*row_disparity)[static_cast<size_t>(v1)];
  };
  cv::Mat right = right_in;
  if (row_disparity && !row_disparity->empty()) {
    cv::Mat map_u(right_in.size(), CV_32F), map_v(right_in.size(), CV_32F);
    for (int v = 0; v < right_in.rows; ++v) {
      const float d = shiftAt(static_cast<float>(v));
      float* mu = map_u.ptr<float>(v);
      float* mv = map_v.ptr<float>(v);
      for (int u = 0; u < right_in.cols; ++u) {
        mu[u] = static_cast<float>(u) - d;
        mv[u] = static_cast<float>(v);
      }
    }
    cv::remap(right_in, right, map_u, map_v, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  }
  const RectificationMonitorOptions& o = options_;
  // Lucas-Kanade assumes equal brightness: map the right image to the left one's mean and
  // contrast (the cameras' gains differ, and auto exposure changes them per frame).
  cv::Scalar ml, sl, mr, sr;
  cv::meanStdDev(left, ml, sl);
  cv::meanStdDev(right, mr, sr);
  const double g = sr[0] > 1e-3 ? sl[0] / sr[0] : 1.0;
  cv::Mat l8, r8;
  left.convertTo(l8, CV_8U);
  right.convertTo(r8, CV_8U, g, ml[0] - g * mr[0]);

  // The strongest corner (minimum eigenvalue of the structure tensor) per cell.
  cv::Mat strength;
  cv::cornerMinEigenVal(l8, strength, 3, 3);
  double max_strength = 0.0;
  cv::minMaxLoc(strength, nullptr, &max_strength);
  const float min_strength = static_cast<float>(o.min_corner_strength * max_strength);
  std::vector<cv::Point2f> p0, p1, pb;
  for (int y0 = o.border_px; y0 < strength.rows - o.border_px; y0 += o.cell_px) {
    for (int x0 = o.border_px; x0 < strength.cols - o.border_px; x0 += o.cell_px) {
      float best = min_strength;
      cv::Point2f at(-1.0f, -1.0f);
      for (int y = y0; y < std::min(y0 + o.cell_px, strength.rows - o.border_px); ++y) {
        const float* row = strength.ptr<float>(y);
        for (int x = x0; x < std::min(x0 + o.cell_px, strength.cols - o.border_px); ++x) {
          if (row[x] > best) {
            best = row[x];
            at = cv::Point2f(static_cast<float>(x), static_cast<float>(y));
          }
        }
      }
      if (at.x >= 0.0f) p0.push_back(at);
    }
  }
  out.features = static_cast<int>(p0.size());

  const double scale = std::ldexp(1.0, o.match_level);  // level-0 px per match-level px
  std::vector<double> du, dv, ur, vl;
  if (!p0.empty()) {
    std::vector<uchar> st, stb;
    std::vector<float> err;
    const cv::Size win(o.lk_window_px, o.lk_window_px);
    const cv::TermCriteria crit(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
    cv::calcOpticalFlowPyrLK(l8, r8, p0, p1, st, err, win, o.lk_levels, crit);
    cv::calcOpticalFlowPyrLK(r8, l8, p1, pb, stb, err, win, o.lk_levels, crit);
    cv::Mat rgu, rgv;
    if (o.refine_shear) {
      const cv::Mat k = (cv::Mat_<float>(1, 3) << -0.5f, 0.0f, 0.5f);
      cv::filter2D(right, rgu, CV_32F, k, cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
      cv::filter2D(right, rgv, CV_32F, k.t(), cv::Point(-1, -1), 0.0, cv::BORDER_REPLICATE);
    }
    for (size_t i = 0; i < p0.size(); ++i) {
      if (!st[i] || !stb[i]) continue;
      if (std::hypot(pb[i].x - p0[i].x, pb[i].y - p0[i].y) > o.max_forward_backward_px) continue;
      cv::Point2f q = p1[i];
      if (o.refine_shear && !refineWithShear(left, right, rgu, rgv, p0[i], &q)) continue;
      q.x -= shiftAt(q.y);  // where the shifted row came from
      du.push_back(scale * (p0[i].x - q.x));  // disparity, level 0
      dv.push_back(scale * (q.y - p0[i].y));  // vertical offset right - left, level 0
      ur.push_back(scale * q.x);
      vl.push_back(scale * p0[i].y);
    }
  }
  out.matches = static_cast<int>(du.size());
  out.points.reserve(du.size());
  for (size_t i = 0; i < du.size(); ++i) {
    out.points.emplace_back(static_cast<float>(ur[i] + du[i]), static_cast<float>(vl[i]), static_cast<float>(du[i]));
  }
  for (double d : du) {
    if (d > o.min_disparity_px) ++out.positive;
    if (d < -o.min_disparity_px) ++out.negative;
  }
  out.median_disparity_px = medianOf(du);
  auto finish = [&]() {
    out.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return out;
  };
  std::ostringstream why;
  if (out.matches < o.min_matches) {
    why << "no consistent stereo matches between the left and right images (" << out.matches << " of "
        << out.features << " corners; at least " << o.min_matches << " needed)";
    out.problem = why.str();
    return finish();
  }
  if (out.negative > out.positive) {
    why << "left and right images appear swapped: " << out.negative << " of " << out.matches
        << " matches have negative disparity";
    out.problem = why.str();
    return finish();
  }
  if (out.positive < o.min_matches) {
    why << "no disparity between the left and right images (" << out.positive << " of " << out.matches
        << " matches above " << o.min_disparity_px << " px): identical images, or nothing near the camera";
    out.problem = why.str();
    return finish();
  }

  // Robust (Huber) fit of the vertical offsets over the matches with positive disparity.
  std::vector<size_t> use;
  for (size_t i = 0; i < du.size(); ++i)
    if (du[i] > o.min_disparity_px) use.push_back(i);
  const int n = static_cast<int>(use.size());
  Eigen::MatrixXd a(n, 6);
  Eigen::VectorXd y(n), w = Eigen::VectorXd::Ones(n);
  for (int k = 0; k < n; ++k) {
    const size_t i = use[static_cast<size_t>(k)];
    const auto b = VerticalMisalignment::basis((ur[i] - rig.cx) / rig.fx, (vl[i] - rig.cy) / rig.fy);
    for (int c = 0; c < 6; ++c) a(k, c) = b[static_cast<size_t>(c)];
    y[k] = dv[i];
  }
  Matrix6d prior = Matrix6d::Zero();
  for (int c = 1; c < 6; ++c) prior(c, c) = 1.0 / std::pow(o.termPriorStd(c), 2);
  Vector6d theta = Vector6d::Zero();
  double sigma = 1.0;
  for (int it = 0; it < 8; ++it) {
    const Eigen::VectorXd r = y - a * theta;
    std::vector<double> absr(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) absr[static_cast<size_t>(k)] = std::abs(r[k]);
    sigma = std::max(1e-3, 1.4826 * medianOf(absr));
    for (int k = 0; k < n; ++k) {
      const double t = std::abs(r[k]) / (o.huber_k * sigma);
      w[k] = t <= 1.0 ? 1.0 : 1.0 / t;
    }
    const Matrix6d h = a.transpose() * w.asDiagonal() * a / (sigma * sigma) + prior;
    theta = h.ldlt().solve(a.transpose() * (w.asDiagonal() * y) / (sigma * sigma));
  }
  for (int c = 0; c < 6; ++c) out.fit.row_shift_px[static_cast<size_t>(c)] = theta[c];
  out.residual_std_px = sigma;
  out.information = a.transpose() * w.asDiagonal() * a / (sigma * sigma);
  const double worst = out.fit.maxAbsPx(rig, o.max_disparity_px);
  if (!std::isfinite(worst) || worst > o.max_misalignment_px) {
    why << "the pair is not rectified: the right image is displaced vertically by up to " << worst
        << " px (at most " << o.max_misalignment_px << " px is modelled)";
    out.problem = why.str();
  }
  return finish();
}

void RectificationMonitor::accumulate(const StereoPairCheck& check) {
  if (!check.ok()) return;
  accumulate(check.fit, check.information);
}

void RectificationMonitor::accumulate(const VerticalMisalignment& fit, const Eigen::Matrix<double, 6, 6>& information) {
  if (!information.allFinite()) return;
  Vector6d theta;
  for (int c = 0; c < 6; ++c) theta[c] = fit.row_shift_px[static_cast<size_t>(c)];
  if (!theta.allFinite()) return;
  information_ = options_.forgetting * information_ + information;
  information_vector_ = options_.forgetting * information_vector_ + information * theta;
  ++pairs_;
}

VerticalMisalignment RectificationMonitor::estimate() const {
  VerticalMisalignment m;
  if (pairs_ == 0) return m;
  Matrix6d h = information_;
  for (int c = 1; c < 6; ++c) h(c, c) += 1.0 / std::pow(options_.termPriorStd(c), 2);
  const Vector6d t = h.ldlt().solve(information_vector_);
  if (!t.allFinite()) return m;
  for (int c = 0; c < 6; ++c) m.row_shift_px[static_cast<size_t>(c)] = t[c];
  return m;
}

}  // namespace stereo_ground_dem
