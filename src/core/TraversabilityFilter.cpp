#include "stereo_ground_dem/TraversabilityFilter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <vector>

namespace stereo_ground_dem {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
constexpr float kInff = std::numeric_limits<float>::infinity();

int halfCells(double radius_m, double resolution_m) {
  return std::max(1, static_cast<int>(std::lround(radius_m / resolution_m)));
}

/// Box sums of M per-vertex quantities over the (2k+1)^2 window of every vertex (vertices outside
/// the grid contribute nothing), row by row with running sums: O(M) per vertex and O(M cols)
/// memory. `fill(r, q)` writes the quantities of row r (q[c * M + i]); `use(r, s)` receives the
/// window sums centred on row r (s[c * M + i]). Sums of integers (counts, coordinate moments) are
/// exact.
template <int M, class Fill, class Use>
void boxSums(int rows, int cols, int k, Fill fill, Use use) {
  const size_t n = static_cast<size_t>(cols) * M;
  std::vector<double> q(n), vertical(n, 0.0);
  auto add_row = [&](int r, double sign) {
    fill(r, q.data());
    double run[M] = {};
    for (int c = 0; c < std::min(k, cols); ++c) {
      for (int i = 0; i < M; ++i) run[i] += q[static_cast<size_t>(c) * M + i];
    }
    for (int c = 0; c < cols; ++c) {
      if (c + k < cols) {
        for (int i = 0; i < M; ++i) run[i] += q[static_cast<size_t>(c + k) * M + i];
      }
      if (c - k - 1 >= 0) {
        for (int i = 0; i < M; ++i) run[i] -= q[static_cast<size_t>(c - k - 1) * M + i];
      }
      double* v = &vertical[static_cast<size_t>(c) * M];
      for (int i = 0; i < M; ++i) v[i] += sign * run[i];
    }
  };
  for (int r = 0; r < std::min(k, rows); ++r) add_row(r, 1.0);
  for (int r = 0; r < rows; ++r) {
    if (r + k < rows) add_row(r + k, 1.0);
    if (r - k - 1 >= 0) add_row(r - k - 1, -1.0);
    use(r, vertical.data());
  }
}

/// Number of grid vertices in the clipped window of half side k along an axis of n vertices.
std::vector<int> clippedExtent(int n, int k) {
  std::vector<int> e(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) e[static_cast<size_t>(i)] = std::min(i + k, n - 1) - std::max(i - k, 0) + 1;
  return e;
}

/// Per vertex: whether its window of half side k holds at least `min_fraction` known vertices (of
/// those inside the grid), from the known counts `count` (CV_32S).
cv::Mat enoughKnown(const cv::Mat& count, int k, double min_fraction) {
  const std::vector<int> er = clippedExtent(count.rows, k), ec = clippedExtent(count.cols, k);
  cv::Mat ok(count.size(), CV_8U);
  for (int r = 0; r < count.rows; ++r) {
    const int* n = count.ptr<int>(r);
    uint8_t* o = ok.ptr<uint8_t>(r);
    for (int c = 0; c < count.cols; ++c) {
      const double inside = static_cast<double>(er[static_cast<size_t>(r)]) * ec[static_cast<size_t>(c)];
      o[c] = n[c] >= min_fraction * inside - 1e-9 ? 1 : 0;
    }
  }
  return ok;
}

/// Known vertices in the (2k+1)^2 window of every vertex (CV_32S).
cv::Mat knownCounts(const cv::Mat& known, int k) {
  cv::Mat count(known.size(), CV_32S);
  boxSums<1>(
      known.rows, known.cols, k,
      [&](int r, double* q) {
        const uint8_t* kr = known.ptr<uint8_t>(r);
        for (int c = 0; c < known.cols; ++c) q[c] = kr[c];
      },
      [&](int r, const double* s) {
        int* o = count.ptr<int>(r);
        for (int c = 0; c < known.cols; ++c) o[c] = static_cast<int>(std::lround(s[c]));
      });
  return count;
}

/// Least-squares planes z = a + gx dx + gy dy over the (2k+1)^2 window of every vertex, from box
/// sums of the moments of the known vertices (grid-centred coordinates in cells, so that the
/// coordinate sums are exact; heights already centred on their mean).
struct PlaneFits {
  cv::Mat count;     ///< CV_32S, known vertices in the window
  cv::Mat slope;     ///< CV_32F, atan |gradient| [rad], NaN if degenerate
  cv::Mat residual;  ///< CV_32F, sqrt(RSS / max(N - 3, 1)) [m], NaN if degenerate
};

PlaneFits fitPlanes(const cv::Mat& z, const cv::Mat& known, int k, double resolution_m) {
  const int rows = z.rows, cols = z.cols;
  enum { kN, kX, kY, kXX, kYY, kXY, kZ, kZX, kZY, kZZ, kMoments };
  PlaneFits out;
  out.count.create(rows, cols, CV_32S);
  out.slope.create(rows, cols, CV_32F);
  out.residual.create(rows, cols, CV_32F);
  auto fill = [&](int r, double* q) {
    const double y = r - 0.5 * rows;
    const double* zr = z.ptr<double>(r);
    const uint8_t* kr = known.ptr<uint8_t>(r);
    for (int c = 0; c < cols; ++c, q += kMoments) {
      if (!kr[c]) {
        std::fill(q, q + kMoments, 0.0);
        continue;
      }
      const double x = c - 0.5 * cols, h = zr[c];
      q[kN] = 1.0;
      q[kX] = x;
      q[kY] = y;
      q[kXX] = x * x;
      q[kYY] = y * y;
      q[kXY] = x * y;
      q[kZ] = h;
      q[kZX] = h * x;
      q[kZY] = h * y;
      q[kZZ] = h * h;
    }
  };
  auto use = [&](int r, const double* p) {
    int* no = out.count.ptr<int>(r);
    float* so = out.slope.ptr<float>(r);
    float* ro = out.residual.ptr<float>(r);
    for (int c = 0; c < cols; ++c, p += kMoments) {
      const double n = p[kN];
      no[c] = static_cast<int>(std::lround(n));
      so[c] = ro[c] = kNaNf;
      if (n < 2.5) continue;
      const double inv = 1.0 / n;
      const double mx = p[kX] * inv, my = p[kY] * inv, mz = p[kZ] * inv;
      const double cxx = p[kXX] * inv - mx * mx, cyy = p[kYY] * inv - my * my;
      const double cxy = p[kXY] * inv - mx * my;
      const double cxz = p[kZX] * inv - mx * mz, cyz = p[kZY] * inv - my * mz;
      const double czz = p[kZZ] * inv - mz * mz;
      const double det = cxx * cyy - cxy * cxy;  // [cells^4]; >= ~1/n^2 unless collinear
      if (!(det > 1e-6)) continue;
      const double gx = (cyy * cxz - cxy * cyz) / det, gy = (cxx * cyz - cxy * cxz) / det;  // [m/cell]
      so[c] = static_cast<float>(std::atan(std::sqrt(gx * gx + gy * gy) / resolution_m));
      const double rss_per_n = std::max(0.0, czz - gx * cxz - gy * cyz);
      ro[c] = static_cast<float>(std::sqrt(rss_per_n * n / std::max(n - 3.0, 1.0)));
    }
  };
  boxSums<kMoments>(rows, cols, k, fill, use);
  return out;
}

/// Steepest incident mesh triangle (GroundGrid triangulation) per vertex; NaN where no incident
/// triangle has three known vertices.
cv::Mat triangleSlopes(const cv::Mat& z, const cv::Mat& known, double resolution_m) {
  cv::Mat slope(z.size(), CV_32F, cv::Scalar(kNaNf));
  auto update = [&slope](int r, int c, float s) {
    float& v = slope.at<float>(r, c);
    if (std::isnan(v) || s > v) v = s;
  };
  for (int r = 0; r + 1 < z.rows; ++r) {
    for (int c = 0; c + 1 < z.cols; ++c) {
      const bool k00 = known.at<uint8_t>(r, c) != 0, k01 = known.at<uint8_t>(r, c + 1) != 0;
      const bool k10 = known.at<uint8_t>(r + 1, c) != 0, k11 = known.at<uint8_t>(r + 1, c + 1) != 0;
      const double z00 = z.at<double>(r, c), z01 = z.at<double>(r, c + 1);
      const double z10 = z.at<double>(r + 1, c), z11 = z.at<double>(r + 1, c + 1);
      if (k00 && k01 && k11) {  // triangle 2q: (r,c), (r,c+1), (r+1,c+1)
        const float s = static_cast<float>(std::atan(std::hypot(z01 - z00, z11 - z01) / resolution_m));
        update(r, c, s);
        update(r, c + 1, s);
        update(r + 1, c + 1, s);
      }
      if (k00 && k11 && k10) {  // triangle 2q+1: (r,c), (r+1,c+1), (r+1,c)
        const float s = static_cast<float>(std::atan(std::hypot(z11 - z10, z10 - z00) / resolution_m));
        update(r, c, s);
        update(r + 1, c + 1, s);
        update(r + 1, c, s);
      }
    }
  }
  return slope;
}

/// Largest max - min over the (run+1)^2 squares that lie inside the (2k+1)^2 window of each
/// vertex; -inf where no such square holds a known vertex.
cv::Mat shortRunSteps(const cv::Mat& zf, const cv::Mat& known, int k, int run) {
  const int n = run + 1;             // short square side [vertices], 2 .. 2k+1
  const int anchor_short = run / 2;  // square of vertex u: [u - anchor_short, u - anchor_short + n - 1]
  const int outer = 2 * k + 2 - n;   // centres u whose square lies inside [v - k, v + k]
  const int anchor_outer = k - anchor_short;
  cv::Mat hi(zf.size(), CV_32F), lo(zf.size(), CV_32F);
  for (int r = 0; r < zf.rows; ++r) {
    const float* zr = zf.ptr<float>(r);
    const uint8_t* kr = known.ptr<uint8_t>(r);
    float* h = hi.ptr<float>(r);
    float* l = lo.ptr<float>(r);
    for (int c = 0; c < zf.cols; ++c) {
      h[c] = kr[c] ? zr[c] : -kInff;
      l[c] = kr[c] ? zr[c] : kInff;
    }
  }
  const cv::Mat square = cv::Mat::ones(n, n, CV_8U);
  cv::dilate(hi, hi, square, cv::Point(anchor_short, anchor_short), 1, cv::BORDER_CONSTANT,
             cv::morphologyDefaultBorderValue());
  cv::erode(lo, lo, square, cv::Point(anchor_short, anchor_short), 1, cv::BORDER_CONSTANT,
            cv::morphologyDefaultBorderValue());
  cv::Mat range(zf.size(), CV_32F);
  for (int r = 0; r < zf.rows; ++r) {
    const float* h = hi.ptr<float>(r);
    const float* l = lo.ptr<float>(r);
    float* o = range.ptr<float>(r);
    for (int c = 0; c < zf.cols; ++c) o[c] = h[c] >= l[c] ? h[c] - l[c] : -kInff;
  }
  cv::Mat step;
  cv::dilate(range, step, cv::Mat::ones(outer, outer, CV_8U), cv::Point(anchor_outer, anchor_outer), 1,
             cv::BORDER_CONSTANT, cv::morphologyDefaultBorderValue());
  return step;
}

}  // namespace

bool TraversabilityOptions::isValid(std::string* why) const {
  auto bad = [why](const char* m) {
    if (why) *why = m;
    return false;
  };
  if (!(critical_slope_rad > 0.0 && critical_slope_rad < 0.5 * kPi)) {
    return bad("critical_slope_rad must be in (0, pi/2)");
  }
  if (!(critical_step_m > 0.0)) return bad("critical_step_m must be > 0");
  if (!(critical_roughness_m > 0.0)) return bad("critical_roughness_m must be > 0");
  if (!(slope_window_radius_m >= 0.0)) return bad("slope_window_radius_m must be >= 0");
  if (!(step_window_radius_m > 0.0)) return bad("step_window_radius_m must be > 0");
  if (!(step_run_m > 0.0)) return bad("step_run_m must be > 0");
  if (!(roughness_window_radius_m > 0.0)) return bad("roughness_window_radius_m must be > 0");
  if (!(slope_weight >= 0.0) || !(step_weight >= 0.0) || !(roughness_weight >= 0.0)) {
    return bad("the weights must be >= 0");
  }
  if (!(std::abs(slope_weight + step_weight + roughness_weight - 1.0) <= 1e-6)) {
    return bad("slope_weight + step_weight + roughness_weight must be 1");
  }
  if (!(min_known_fraction > 0.0 && min_known_fraction <= 1.0)) {
    return bad("min_known_fraction must be in (0, 1]");
  }
  if (!(height_std_floor_m > 0.0 && std::isfinite(height_std_floor_m))) return bad("height_std_floor_m must be > 0");
  return true;
}

TraversabilityOptions TraversabilityOptions::forCar() {
  TraversabilityOptions o;
  o.critical_slope_rad = 20.0 * kPi / 180.0;
  o.critical_step_m = 0.20;
  o.critical_roughness_m = 0.08;
  o.slope_window_radius_m = 1.0;
  o.step_window_radius_m = 1.0;
  o.step_run_m = 0.2;
  o.roughness_window_radius_m = 1.0;
  o.slope_weight = 0.25;
  o.step_weight = 0.5;
  o.roughness_weight = 0.25;
  o.min_known_fraction = 0.5;
  return o;
}

TraversabilityOptions TraversabilityOptions::forSmallRobot() {
  TraversabilityOptions o;
  o.critical_slope_rad = 15.0 * kPi / 180.0;
  o.critical_step_m = 0.08;
  o.critical_roughness_m = 0.03;
  o.slope_window_radius_m = 0.3;
  o.step_window_radius_m = 0.3;
  o.step_run_m = 0.1;
  o.roughness_window_radius_m = 0.3;
  o.slope_weight = 0.3;
  o.step_weight = 0.4;
  o.roughness_weight = 0.3;
  o.min_known_fraction = 0.5;
  return o;
}

TraversabilityFilter::TraversabilityFilter(const TraversabilityOptions& options) : options_(options) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("TraversabilityOptions: " + why);
}

TraversabilityWindows TraversabilityFilter::windows(double resolution_m) const {
  TraversabilityWindows w;
  w.slope_half = options_.slope_window_radius_m > 0.0 ? halfCells(options_.slope_window_radius_m, resolution_m) : 0;
  w.step_half = halfCells(options_.step_window_radius_m, resolution_m);
  w.step_run = std::min(2 * w.step_half, halfCells(options_.step_run_m, resolution_m));
  w.roughness_half = halfCells(options_.roughness_window_radius_m, resolution_m);
  return w;
}

double TraversabilityFilter::combine(double slope_rad, double step_m, double roughness_m) const {
  const double qs = slope_rad / options_.critical_slope_rad;
  const double qt = step_m / options_.critical_step_m;
  const double qr = roughness_m / options_.critical_roughness_m;
  if (qs >= 1.0 || qt >= 1.0 || qr >= 1.0) return 0.0;
  const double t = options_.slope_weight * (1.0 - qs) + options_.step_weight * (1.0 - qt) +
                   options_.roughness_weight * (1.0 - qr);
  return std::min(1.0, std::max(0.0, t));
}

TraversabilityLayers TraversabilityFilter::compute(const GroundGrid& grid, const Eigen::VectorXd& heights) const {
  if (heights.size() != static_cast<Eigen::Index>(grid.vertexCount()) || grid.rows <= 0 || grid.cols <= 0) {
    throw std::invalid_argument("TraversabilityFilter: heights must hold grid.rows * grid.cols values");
  }
  const cv::Mat view(grid.rows, grid.cols, CV_64F, const_cast<double*>(heights.data()));
  return compute(grid, view);
}

TraversabilityLayers TraversabilityFilter::compute(const GroundGrid& grid, const cv::Mat& heights) const {
  if (grid.rows <= 0 || grid.cols <= 0 || !(grid.resolution_m > 0.0)) {
    throw std::invalid_argument("TraversabilityFilter: empty grid or resolution_m <= 0");
  }
  if (heights.rows != grid.rows || heights.cols != grid.cols ||
      (heights.type() != CV_32F && heights.type() != CV_64F)) {
    throw std::invalid_argument("TraversabilityFilter: heights must be CV_32F or CV_64F of grid.rows x grid.cols");
  }
  const int rows = grid.rows, cols = grid.cols;
  const double res = grid.resolution_m;
  const TraversabilityWindows w = windows(res);

  // Known mask and heights centred on their mean (conditioning of the moment sums).
  cv::Mat z;
  heights.convertTo(z, CV_64F);
  cv::Mat known(rows, cols, CV_8U);
  double sum = 0.0;
  int n_known = 0;
  for (int r = 0; r < rows; ++r) {
    const double* zr = z.ptr<double>(r);
    uint8_t* kr = known.ptr<uint8_t>(r);
    for (int c = 0; c < cols; ++c) {
      kr[c] = std::isfinite(zr[c]) ? 1 : 0;
      if (kr[c]) {
        sum += zr[c];
        ++n_known;
      }
    }
  }
  const double mean = n_known > 0 ? sum / n_known : 0.0;
  cv::Mat zf(rows, cols, CV_32F);
  for (int r = 0; r < rows; ++r) {
    double* zr = z.ptr<double>(r);
    const uint8_t* kr = known.ptr<uint8_t>(r);
    float* fr = zf.ptr<float>(r);
    for (int c = 0; c < cols; ++c) {
      zr[c] = kr[c] ? zr[c] - mean : 0.0;
      fr[c] = static_cast<float>(zr[c]);
    }
  }

  const PlaneFits rough = fitPlanes(z, known, w.roughness_half, res);
  cv::Mat slope, slope_ok;
  if (w.slope_half == 0) {
    slope = triangleSlopes(z, known, res);
    slope_ok = cv::Mat(rows, cols, CV_8U, cv::Scalar(1));
  } else if (w.slope_half == w.roughness_half) {
    slope = rough.slope;
    slope_ok = enoughKnown(rough.count, w.slope_half, options_.min_known_fraction);
  } else {
    const PlaneFits fit = fitPlanes(z, known, w.slope_half, res);
    slope = fit.slope;
    slope_ok = enoughKnown(fit.count, w.slope_half, options_.min_known_fraction);
  }
  const cv::Mat rough_ok = enoughKnown(rough.count, w.roughness_half, options_.min_known_fraction);
  const cv::Mat step = shortRunSteps(zf, known, w.step_half, w.step_run);
  const cv::Mat step_ok = enoughKnown(knownCounts(known, w.step_half), w.step_half, options_.min_known_fraction);

  TraversabilityLayers out;
  out.slope_rad.create(rows, cols, CV_32F);
  out.step_m.create(rows, cols, CV_32F);
  out.roughness_m.create(rows, cols, CV_32F);
  out.traversability.create(rows, cols, CV_32F);
  for (int r = 0; r < rows; ++r) {
    const uint8_t* kr = known.ptr<uint8_t>(r);
    const uint8_t* sok = slope_ok.ptr<uint8_t>(r);
    const uint8_t* tok = step_ok.ptr<uint8_t>(r);
    const uint8_t* rok = rough_ok.ptr<uint8_t>(r);
    const float* sl = slope.ptr<float>(r);
    const float* st = step.ptr<float>(r);
    const float* ro = rough.residual.ptr<float>(r);
    float* o_sl = out.slope_rad.ptr<float>(r);
    float* o_st = out.step_m.ptr<float>(r);
    float* o_ro = out.roughness_m.ptr<float>(r);
    float* o_t = out.traversability.ptr<float>(r);
    for (int c = 0; c < cols; ++c) {
      const bool k = kr[c] != 0;
      o_sl[c] = k && sok[c] ? sl[c] : kNaNf;
      o_st[c] = k && tok[c] && st[c] >= 0.0f ? st[c] : kNaNf;
      o_ro[c] = k && rok[c] ? ro[c] : kNaNf;
      o_t[c] = std::isnan(o_sl[c]) || std::isnan(o_st[c]) || std::isnan(o_ro[c])
                   ? kNaNf
                   : static_cast<float>(combine(o_sl[c], o_st[c], o_ro[c]));
    }
  }
  return out;
}

cv::Mat TraversabilityFilter::probability(const GroundGrid& grid, const TraversabilityLayers& layers,
                                         const cv::Mat& variance) const {
  if (variance.type() != CV_32F || variance.rows != grid.rows || variance.cols != grid.cols ||
      layers.traversability.size() != variance.size()) {
    throw std::invalid_argument("TraversabilityFilter::probability: variance and layers must be CV_32F of the grid's size");
  }
  const TraversabilityWindows w = windows(grid.resolution_m);
  const double s = grid.resolution_m;
  const double k = w.slope_half;
  // The least-squares gradient's std per unit height std over the slope window.
  const double gradient_per_sigma =
      w.slope_half == 0 ? std::sqrt(2.0) / s : 1.0 / (s * std::sqrt((2 * k + 1) * (2 * k + 1) * k * (k + 1) / 3.0));
  const double tan_crit = std::tan(options_.critical_slope_rad);
  auto phi = [](double x) { return 0.5 * std::erfc(-x / std::sqrt(2.0)); };
  cv::Mat out(grid.rows, grid.cols, CV_32F, cv::Scalar(kNaNf));
  for (int r = 0; r < grid.rows; ++r) {
    const float* t = layers.traversability.ptr<float>(r);
    const float* sl = layers.slope_rad.ptr<float>(r);
    const float* st = layers.step_m.ptr<float>(r);
    const float* ro = layers.roughness_m.ptr<float>(r);
    const float* var = variance.ptr<float>(r);
    float* o = out.ptr<float>(r);
    for (int c = 0; c < grid.cols; ++c) {
      if (std::isnan(t[c])) continue;
      const double sigma = std::max(options_.height_std_floor_m, std::isfinite(var[c]) && var[c] > 0.0f ? std::sqrt(var[c]) : 0.0);
      const double p = phi((tan_crit - std::tan(sl[c])) / (gradient_per_sigma * sigma)) *
                       phi((options_.critical_step_m - st[c]) / (std::sqrt(2.0) * sigma)) *
                       phi((options_.critical_roughness_m - ro[c]) / sigma);
      o[c] = static_cast<float>(p);
    }
  }
  return out;
}

}  // namespace stereo_ground_dem
