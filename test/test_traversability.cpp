// TraversabilityFilter: slope, step and roughness on synthetic worlds with known answers, against a
// brute-force reference, NaN propagation, resolution independence and timing.
#include <gtest/gtest.h>

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "stereo_ground_dem/TraversabilityFilter.hpp"

using namespace stereo_ground_dem;

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
const float kNaN = std::numeric_limits<float>::quiet_NaN();

GroundGrid makeGrid(int rows, int cols, double res, int row0 = 0, int col0 = 0) {
  GroundGrid g;
  g.resolution_m = res;
  g.rows = rows;
  g.cols = cols;
  g.row0 = row0;
  g.col0 = col0;
  return g;
}

cv::Mat heightsOf(const GroundGrid& g, const std::function<double(double, double)>& f) {
  cv::Mat z(g.rows, g.cols, CV_32F);
  for (int r = 0; r < g.rows; ++r) {
    for (int c = 0; c < g.cols; ++c) z.at<float>(r, c) = static_cast<float>(f(g.xOfCol(c), g.yOfRow(r)));
  }
  return z;
}

/// Plane of inclination `slope` rising towards azimuth `azimuth` (from +x towards +y), offset z0.
std::function<double(double, double)> plane(double slope, double azimuth, double z0) {
  const double gx = std::tan(slope) * std::cos(azimuth), gy = std::tan(slope) * std::sin(azimuth);
  return [=](double x, double y) { return z0 + gx * x + gy * y; };
}

int countNaN(const cv::Mat& m) {
  int n = 0;
  for (int r = 0; r < m.rows; ++r) {
    for (int c = 0; c < m.cols; ++c) n += std::isnan(m.at<float>(r, c)) ? 1 : 0;
  }
  return n;
}

/// Row index of the vertex at y (exact for the grids used here).
int rowAt(const GroundGrid& g, double y) { return static_cast<int>(std::lround(y / g.resolution_m)) - g.row0; }

/// The definitions of the header, evaluated naively per vertex.
struct Reference {
  cv::Mat slope, step, roughness;
};

Reference bruteForce(const GroundGrid& g, const cv::Mat& z, const TraversabilityOptions& o) {
  const TraversabilityWindows w = TraversabilityFilter(o).windows(g.resolution_m);
  const double res = g.resolution_m;
  Reference ref;
  ref.slope = cv::Mat(g.rows, g.cols, CV_32F, cv::Scalar(kNaN));
  ref.step = ref.slope.clone();
  ref.roughness = ref.slope.clone();
  auto known = [&](int r, int c) { return std::isfinite(z.at<float>(r, c)); };
  auto enough = [&](int r, int c, int k) {
    int inside = 0, n = 0;
    for (int rr = std::max(0, r - k); rr <= std::min(g.rows - 1, r + k); ++rr) {
      for (int cc = std::max(0, c - k); cc <= std::min(g.cols - 1, c + k); ++cc) {
        ++inside;
        n += known(rr, cc) ? 1 : 0;
      }
    }
    return n >= o.min_known_fraction * inside - 1e-9;
  };
  // Returns (slope, residual std) of the least-squares plane, NaN if degenerate.
  auto fit = [&](int r, int c, int k) {
    std::vector<Eigen::Vector3d> rows_a;
    std::vector<double> b;
    for (int rr = std::max(0, r - k); rr <= std::min(g.rows - 1, r + k); ++rr) {
      for (int cc = std::max(0, c - k); cc <= std::min(g.cols - 1, c + k); ++cc) {
        if (!known(rr, cc)) continue;
        rows_a.emplace_back(1.0, (cc - c) * res, (rr - r) * res);
        b.push_back(z.at<float>(rr, cc));
      }
    }
    const int n = static_cast<int>(b.size());
    Eigen::MatrixXd a(n, 3);
    Eigen::VectorXd bv(n);
    for (int i = 0; i < n; ++i) {
      a.row(i) = rows_a[static_cast<size_t>(i)].transpose();
      bv(i) = b[static_cast<size_t>(i)];
    }
    Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
    if (n < 3 || qr.rank() < 3) return std::make_pair(kNaN, kNaN);
    const Eigen::Vector3d p = qr.solve(bv);
    const double rss = (a * p - bv).squaredNorm();
    return std::make_pair(static_cast<float>(std::atan(std::hypot(p(1), p(2)))),
                          static_cast<float>(std::sqrt(rss / std::max(n - 3, 1))));
  };
  for (int r = 0; r < g.rows; ++r) {
    for (int c = 0; c < g.cols; ++c) {
      if (!known(r, c)) continue;
      if (enough(r, c, w.slope_half)) ref.slope.at<float>(r, c) = fit(r, c, w.slope_half).first;
      if (enough(r, c, w.roughness_half)) ref.roughness.at<float>(r, c) = fit(r, c, w.roughness_half).second;
      if (enough(r, c, w.step_half)) {
        const int k = w.step_half, run = w.step_run;
        float best = 0.0f;
        for (int ra = std::max(0, r - k); ra <= std::min(g.rows - 1, r + k); ++ra) {
          for (int ca = std::max(0, c - k); ca <= std::min(g.cols - 1, c + k); ++ca) {
            if (!known(ra, ca)) continue;
            for (int rb = std::max({0, r - k, ra - run}); rb <= std::min({g.rows - 1, r + k, ra + run}); ++rb) {
              for (int cb = std::max({0, c - k, ca - run}); cb <= std::min({g.cols - 1, c + k, ca + run}); ++cb) {
                if (known(rb, cb)) best = std::max(best, std::abs(z.at<float>(ra, ca) - z.at<float>(rb, cb)));
              }
            }
          }
        }
        ref.step.at<float>(r, c) = best;
      }
    }
  }
  return ref;
}

/// Same NaN pattern and values within `tol`.
void expectLayerNear(const cv::Mat& got, const cv::Mat& want, double tol, const char* name) {
  ASSERT_EQ(got.size(), want.size());
  int mismatches = 0;
  for (int r = 0; r < got.rows; ++r) {
    for (int c = 0; c < got.cols; ++c) {
      const float a = got.at<float>(r, c), b = want.at<float>(r, c);
      const bool ok = (std::isnan(a) && std::isnan(b)) || (!std::isnan(a) && !std::isnan(b) && std::abs(a - b) <= tol);
      if (!ok && ++mismatches <= 5) {
        ADD_FAILURE() << name << " at (" << r << ", " << c << "): got " << a << ", want " << b;
      }
    }
  }
  EXPECT_EQ(mismatches, 0) << name;
}

}  // namespace

TEST(TraversabilityOptions, PresetsValidAndInvalidRejected) {
  std::string why;
  EXPECT_TRUE(TraversabilityOptions().isValid(&why)) << why;
  EXPECT_TRUE(TraversabilityOptions::forCar().isValid(&why)) << why;
  EXPECT_TRUE(TraversabilityOptions::forSmallRobot().isValid(&why)) << why;
  EXPECT_NEAR(TraversabilityOptions::forCar().critical_slope_rad, 20.0 * kDeg, 1e-12);
  EXPECT_NEAR(TraversabilityOptions::forSmallRobot().critical_slope_rad, 15.0 * kDeg, 1e-12);
  EXPECT_DOUBLE_EQ(TraversabilityOptions().critical_step_m, TraversabilityOptions::forCar().critical_step_m);

  std::vector<std::function<void(TraversabilityOptions&)>> breakers = {
      [](TraversabilityOptions& o) { o.critical_slope_rad = 0.0; },
      [](TraversabilityOptions& o) { o.critical_slope_rad = 1.6; },
      [](TraversabilityOptions& o) { o.critical_step_m = -0.1; },
      [](TraversabilityOptions& o) { o.critical_roughness_m = 0.0; },
      [](TraversabilityOptions& o) { o.slope_window_radius_m = -1.0; },
      [](TraversabilityOptions& o) { o.step_window_radius_m = 0.0; },
      [](TraversabilityOptions& o) { o.step_run_m = 0.0; },
      [](TraversabilityOptions& o) { o.roughness_window_radius_m = std::nan(""); },
      [](TraversabilityOptions& o) { o.step_weight = 0.6; },
      [](TraversabilityOptions& o) { o.slope_weight = -0.25;
        o.step_weight = 1.0; },
      [](TraversabilityOptions& o) { o.min_known_fraction = 0.0; },
      [](TraversabilityOptions& o) { o.min_known_fraction = 1.5; },
  };
  for (size_t i = 0; i < breakers.size(); ++i) {
    TraversabilityOptions o;
    breakers[i](o);
    why.clear();
    EXPECT_FALSE(o.isValid(&why)) << "breaker " << i;
    EXPECT_FALSE(why.empty()) << "breaker " << i;
    EXPECT_THROW(TraversabilityFilter{o}, std::invalid_argument) << "breaker " << i;
  }
}

TEST(TraversabilityFilter, WindowsInCells) {
  const TraversabilityFilter car(TraversabilityOptions::forCar());
  const TraversabilityFilter small(TraversabilityOptions::forSmallRobot());
  TraversabilityWindows w = car.windows(0.1);
  EXPECT_EQ(w.slope_half, 10);
  EXPECT_EQ(w.step_half, 10);
  EXPECT_EQ(w.step_run, 2);
  EXPECT_EQ(w.roughness_half, 10);
  w = car.windows(0.25);
  EXPECT_EQ(w.slope_half, 4);
  EXPECT_EQ(w.step_run, 1);
  w = car.windows(1.0);  // never below one cell
  EXPECT_EQ(w.slope_half, 1);
  EXPECT_EQ(w.step_half, 1);
  EXPECT_EQ(w.step_run, 1);
  w = small.windows(0.1);
  EXPECT_EQ(w.slope_half, 3);
  EXPECT_EQ(w.step_run, 1);
  TraversabilityOptions o;
  o.step_run_m = 50.0;  // clamped to the window: plain max - min
  o.slope_window_radius_m = 0.0;
  w = TraversabilityFilter(o).windows(0.1);
  EXPECT_EQ(w.step_run, 20);
  EXPECT_EQ(w.slope_half, 0);
}

TEST(TraversabilityFilter, CombineFollowsTheFormula) {
  const TraversabilityFilter f(TraversabilityOptions::forCar());
  EXPECT_DOUBLE_EQ(f.combine(0.0, 0.0, 0.0), 1.0);
  EXPECT_NEAR(f.combine(10.0 * kDeg, 0.1, 0.02), 0.25 * 0.5 + 0.5 * 0.5 + 0.25 * 0.75, 1e-12);
  EXPECT_DOUBLE_EQ(f.combine(20.0 * kDeg, 0.0, 0.0), 0.0);
  EXPECT_DOUBLE_EQ(f.combine(0.0, 0.2, 0.0), 0.0);
  EXPECT_DOUBLE_EQ(f.combine(0.0, 0.0, 0.09), 0.0);
}

TEST(TraversabilityFilter, FlatPlaneIsFullyTraversable) {
  const GroundGrid g = makeGrid(50, 70, 0.1, -25, 3);
  const cv::Mat z = heightsOf(g, [](double, double) { return 12.34; });
  for (const auto& o : {TraversabilityOptions::forCar(), TraversabilityOptions::forSmallRobot()}) {
    const TraversabilityLayers t = TraversabilityFilter(o).compute(g, z);
    ASSERT_EQ(t.traversability.type(), CV_32F);
    ASSERT_EQ(t.traversability.rows, g.rows);
    ASSERT_EQ(t.traversability.cols, g.cols);
    for (int r = 0; r < g.rows; ++r) {
      for (int c = 0; c < g.cols; ++c) {  // border vertices included (clipped windows)
        ASSERT_NEAR(t.slope_rad.at<float>(r, c), 0.0, 1e-6) << r << " " << c;
        ASSERT_EQ(t.step_m.at<float>(r, c), 0.0f);
        ASSERT_NEAR(t.roughness_m.at<float>(r, c), 0.0, 1e-6);
        ASSERT_NEAR(t.traversability.at<float>(r, c), 1.0, 1e-5);
      }
    }
  }
}

TEST(TraversabilityFilter, TiltedPlane10DegIsTraversableForACar) {
  const GroundGrid g = makeGrid(80, 100, 0.1, 10, -40);
  const double az = 30.0 * kDeg;
  const cv::Mat z = heightsOf(g, plane(10.0 * kDeg, az, 50.0));
  const TraversabilityFilter car(TraversabilityOptions::forCar());
  const TraversabilityLayers t = car.compute(g, z);
  // A plane of gradient g adds (run cells * res) * (|g_x| + |g_y|) to the short-run step.
  const double step = 0.2 * std::tan(10.0 * kDeg) * (std::cos(az) + std::sin(az));
  const double expected = 0.25 * 0.5 + 0.5 * (1.0 - step / 0.2) + 0.25;
  EXPECT_NEAR(expected, 0.7546, 1e-3);
  for (int r = 0; r < g.rows; ++r) {
    for (int c = 0; c < g.cols; ++c) {
      ASSERT_NEAR(t.slope_rad.at<float>(r, c), 10.0 * kDeg, 0.1 * kDeg) << r << " " << c;
      ASSERT_NEAR(t.step_m.at<float>(r, c), step, 2e-4);
      ASSERT_LT(t.roughness_m.at<float>(r, c), 1e-3);
      ASSERT_NEAR(t.traversability.at<float>(r, c), expected, 3e-3);
    }
  }
}

TEST(TraversabilityFilter, TiltedPlane30DegIsNotTraversable) {
  const GroundGrid g = makeGrid(60, 60, 0.1);
  const cv::Mat z = heightsOf(g, plane(30.0 * kDeg, -100.0 * kDeg, 0.0));
  for (const auto& o : {TraversabilityOptions::forCar(), TraversabilityOptions::forSmallRobot()}) {
    const TraversabilityLayers t = TraversabilityFilter(o).compute(g, z);
    for (int r = 0; r < g.rows; ++r) {
      for (int c = 0; c < g.cols; ++c) {
        ASSERT_NEAR(t.slope_rad.at<float>(r, c), 30.0 * kDeg, 0.1 * kDeg);
        ASSERT_EQ(t.traversability.at<float>(r, c), 0.0f);
      }
    }
  }
}

// Units are metres and radians, not cells: the same world at 0.25 m and 1.0 m.
TEST(TraversabilityFilter, SlopeAndStepIndependentOfResolution) {
  for (double res : {0.25, 1.0}) {
    SCOPED_TRACE(res);
    const GroundGrid g = makeGrid(static_cast<int>(std::lround(16.0 / res)) + 1,
                                  static_cast<int>(std::lround(12.0 / res)) + 1, res,
                                  static_cast<int>(std::lround(-8.0 / res)), static_cast<int>(std::lround(4.0 / res)));
    TraversabilityOptions o = TraversabilityOptions::forCar();
    const TraversabilityFilter car(o);
    const TraversabilityWindows w = car.windows(res);
    // Tilted plane: slope (plane fit and steepest triangle) and short-run step in metres.
    const double az = 70.0 * kDeg;
    const cv::Mat tilted = heightsOf(g, plane(10.0 * kDeg, az, -3.0));
    const TraversabilityLayers t = car.compute(g, tilted);
    o.slope_window_radius_m = 0.0;
    const TraversabilityLayers tri = TraversabilityFilter(o).compute(g, tilted);
    const double step = w.step_run * res * std::tan(10.0 * kDeg) * (std::cos(az) + std::sin(az));
    for (int r = 0; r < g.rows; ++r) {
      for (int c = 0; c < g.cols; ++c) {
        ASSERT_NEAR(t.slope_rad.at<float>(r, c), 10.0 * kDeg, 0.1 * kDeg);
        ASSERT_NEAR(tri.slope_rad.at<float>(r, c), 10.0 * kDeg, 0.1 * kDeg);
        ASSERT_NEAR(t.step_m.at<float>(r, c), step, 1e-4);
      }
    }
    // A sharp 0.3 m step along the line y = 0.5 res: measured as 0.3 m within the window of the
    // edge, 0 farther than the window radius (1.0 m, at least one cell) from it.
    const cv::Mat stepped = heightsOf(g, [res](double, double y) { return y > 0.5 * res ? 0.3 : 0.0; });
    const TraversabilityLayers s = car.compute(g, stepped);
    const int edge = rowAt(g, 0.0);  // last low row
    for (int r = 0; r < g.rows; ++r) {
      const bool sees = r >= edge + 1 - w.step_half && r <= edge + w.step_half;
      for (int c = 0; c < g.cols; ++c) {
        ASSERT_NEAR(s.step_m.at<float>(r, c), sees ? 0.3 : 0.0, 1e-5) << "row " << r;
        if (std::abs(g.yOfRow(r) - 0.5 * res) > std::max(1.0, res) + res) {
          ASSERT_EQ(s.step_m.at<float>(r, c), 0.0f);
          ASSERT_NEAR(s.traversability.at<float>(r, c), 1.0, 1e-5);
        }
      }
      if (r == edge || r == edge + 1) {
        EXPECT_EQ(s.traversability.at<float>(r, 0), 0.0f);  // 0.3 > 0.2 m
      }
    }
  }
}

TEST(TraversabilityFilter, TriangleModeIsTheSteepestIncidentTriangle) {
  const GroundGrid g = makeGrid(20, 20, 0.1);
  cv::Mat z = heightsOf(g, [](double, double) { return 0.0; });
  const double h = 0.05;
  z.at<float>(10, 10) = static_cast<float>(h);
  TraversabilityOptions o = TraversabilityOptions::forSmallRobot();
  o.slope_window_radius_m = 0.0;
  const TraversabilityLayers t = TraversabilityFilter(o).compute(g, z);
  // The raised vertex is the right-angle corner of two of its six triangles: gradient sqrt(2) h / res.
  EXPECT_NEAR(t.slope_rad.at<float>(10, 10), std::atan(std::sqrt(2.0) * h / 0.1), 1e-5);
  // Its neighbour at (10, 11) shares triangles whose gradient along x is h / res.
  EXPECT_NEAR(t.slope_rad.at<float>(10, 11), std::atan(std::sqrt(2.0) * h / 0.1), 1e-5);
  EXPECT_NEAR(t.slope_rad.at<float>(11, 10), std::atan(std::sqrt(2.0) * h / 0.1), 1e-5);
  // (11, 9) is not a neighbour in the triangulation (diagonal (r,c)-(r+1,c+1) only).
  EXPECT_NEAR(t.slope_rad.at<float>(11, 9), 0.0, 1e-6);
  EXPECT_NEAR(t.slope_rad.at<float>(9, 11), 0.0, 1e-6);
  EXPECT_NEAR(t.slope_rad.at<float>(11, 11), std::atan(h / 0.1), 1e-5);
  for (int r = 0; r < g.rows; ++r) {
    for (int c = 0; c < g.cols; ++c) {
      if (std::max(std::abs(r - 10), std::abs(c - 10)) >= 2) {
        ASSERT_NEAR(t.slope_rad.at<float>(r, c), 0.0, 1e-6);
      }
    }
  }
  // A vertex without a complete incident triangle has no slope.
  cv::Mat lonely = z.clone();
  lonely.at<float>(0, 1) = lonely.at<float>(1, 0) = lonely.at<float>(1, 1) = kNaN;
  o.min_known_fraction = 0.1;
  const TraversabilityLayers l = TraversabilityFilter(o).compute(g, lonely);
  EXPECT_TRUE(std::isnan(l.slope_rad.at<float>(0, 0)));
  EXPECT_FALSE(std::isnan(l.step_m.at<float>(0, 0)));
  EXPECT_FALSE(std::isnan(l.slope_rad.at<float>(0, 2)));
}

// A 12 cm curb: the road (y <= 0) 12 cm below the sidewalk (y >= 0.1 m).
TEST(TraversabilityFilter, Curb12cm) {
  const GroundGrid g = makeGrid(81, 60, 0.1, -40, 0);
  const cv::Mat z = heightsOf(g, [](double, double y) { return y > 0.05 ? 0.12 : 0.0; });
  const int edge = rowAt(g, 0.0);
  const int road = rowAt(g, -1.0);     // 1.05 m from the curb line
  const int walk = rowAt(g, 1.1);      // 1.05 m on the other side
  // Small robot: critical step 0.08 m < 0.12 m: not traversable along the curb.
  const TraversabilityLayers s = TraversabilityFilter(TraversabilityOptions::forSmallRobot()).compute(g, z);
  // Car: critical step 0.20 m: a curb is mountable but poor.
  const TraversabilityLayers k = TraversabilityFilter(TraversabilityOptions::forCar()).compute(g, z);
  float car_min = 1.0f;
  for (int c = 0; c < g.cols; ++c) {
    for (int r : {edge, edge + 1}) {
      EXPECT_NEAR(s.step_m.at<float>(r, c), 0.12, 1e-5);
      EXPECT_EQ(s.traversability.at<float>(r, c), 0.0f);
      EXPECT_NEAR(k.step_m.at<float>(r, c), 0.12, 1e-5);
      EXPECT_GT(k.traversability.at<float>(r, c), 0.2f);
      EXPECT_LT(k.traversability.at<float>(r, c), 0.65f);
      car_min = std::min(car_min, k.traversability.at<float>(r, c));
    }
    for (int r : {road, walk}) {
      EXPECT_GT(s.traversability.at<float>(r, c), 0.8f);
      EXPECT_GT(k.traversability.at<float>(r, c), 0.8f);
    }
  }
  std::cout << "[          ] car traversability at the 12 cm curb: " << car_min << "\n";
  // Every vertex whose small-robot step window holds both sides of the curb is blocked.
  for (int r = edge - 2; r <= edge + 3; ++r) EXPECT_EQ(s.traversability.at<float>(r, 30), 0.0f) << r;
  EXPECT_GT(s.traversability.at<float>(edge - 3, 30), 0.8f);
}

TEST(TraversabilityFilter, Step40cmBlocksBothPresets) {
  const GroundGrid g = makeGrid(81, 40, 0.1, -40, 0);
  const cv::Mat z = heightsOf(g, [](double, double y) { return y > 0.05 ? 0.4 : 0.0; });
  const int edge = rowAt(g, 0.0);
  for (const auto& o : {TraversabilityOptions::forCar(), TraversabilityOptions::forSmallRobot()}) {
    const TraversabilityFilter f(o);
    const int k = f.windows(g.resolution_m).step_half;
    const TraversabilityLayers t = f.compute(g, z);
    for (int r = 0; r < g.rows; ++r) {
      const bool near = r >= edge + 1 - k && r <= edge + k;  // the step window holds both sides
      for (int c = 0; c < g.cols; ++c) {
        ASSERT_NEAR(t.step_m.at<float>(r, c), near ? 0.4 : 0.0, 1e-5) << r;
        if (near) {
          ASSERT_EQ(t.traversability.at<float>(r, c), 0.0f) << r;
        } else if (r < edge - k - 1 || r > edge + k + 2) {
          ASSERT_NEAR(t.traversability.at<float>(r, c), 1.0, 1e-5) << r;
        }
      }
    }
  }
}

TEST(TraversabilityFilter, RoughnessIsTheInjectedNoise) {
  const GroundGrid g = makeGrid(120, 120, 0.1);
  std::mt19937 rng(42);
  const double sigma = 0.03;
  std::normal_distribution<double> noise(0.0, sigma);
  const auto base = plane(5.0 * kDeg, 1.0, 2.0);
  const cv::Mat z = heightsOf(g, [&](double x, double y) { return base(x, y) + noise(rng); });

  const TraversabilityFilter car(TraversabilityOptions::forCar());
  const int k = car.windows(g.resolution_m).roughness_half;
  const TraversabilityLayers t = car.compute(g, z);
  double sum = 0.0, slope_sum = 0.0;
  int n = 0;
  for (int r = k; r < g.rows - k; ++r) {
    for (int c = k; c < g.cols - k; ++c) {  // full 21 x 21 windows
      const float rough = t.roughness_m.at<float>(r, c);
      ASSERT_NEAR(rough, sigma, 0.2 * sigma) << r << " " << c;
      sum += rough;
      slope_sum += t.slope_rad.at<float>(r, c);
      ++n;
    }
  }
  EXPECT_NEAR(sum / n, sigma, 0.03 * sigma);
  EXPECT_NEAR(slope_sum / n, 5.0 * kDeg, 0.3 * kDeg);

  // Small robot: 7 x 7 windows, 46 degrees of freedom: the median is within 10 %.
  const TraversabilityLayers s = TraversabilityFilter(TraversabilityOptions::forSmallRobot()).compute(g, z);
  std::vector<float> values;
  for (int r = 3; r < g.rows - 3; ++r) {
    for (int c = 3; c < g.cols - 3; ++c) values.push_back(s.roughness_m.at<float>(r, c));
  }
  std::nth_element(values.begin(), values.begin() + static_cast<long>(values.size() / 2), values.end());
  EXPECT_NEAR(values[values.size() / 2], sigma, 0.1 * sigma);
}

TEST(TraversabilityFilter, NaNOnlyWhereTheWindowHasTooFewKnownVertices) {
  const GroundGrid g = makeGrid(60, 60, 0.1);
  const TraversabilityOptions o = TraversabilityOptions::forSmallRobot();  // 7 x 7 windows, 50 %
  const TraversabilityFilter f(o);
  cv::Mat z = heightsOf(g, plane(3.0 * kDeg, 0.5, 1.0));
  // (a) a single unknown vertex: only it is NaN.
  cv::Mat one = z.clone();
  one.at<float>(30, 30) = kNaN;
  TraversabilityLayers t = f.compute(g, one);
  for (const cv::Mat* m : {&t.slope_rad, &t.step_m, &t.roughness_m, &t.traversability}) {
    EXPECT_EQ(countNaN(*m), 1);
    EXPECT_TRUE(std::isnan(m->at<float>(30, 30)));
  }
  // (b) a 9 x 9 hole: its neighbours keep >= 4/7 of their window: exactly the hole is NaN.
  cv::Mat hole = z.clone();
  hole(cv::Rect(10, 40, 9, 9)).setTo(kNaN);
  t = f.compute(g, hole);
  for (const cv::Mat* m : {&t.slope_rad, &t.step_m, &t.roughness_m, &t.traversability}) EXPECT_EQ(countNaN(*m), 81);
  EXPECT_NEAR(t.slope_rad.at<float>(44, 19), 3.0 * kDeg, 0.01 * kDeg);  // right next to the hole
  // (c) a sparse block (every second row and column known, 25 %): its known vertices are NaN
  // where their window is mostly inside the block, valid near its rim; matches the definition.
  cv::Mat sparse = z.clone();
  for (int r = 20; r < 40; ++r) {
    for (int c = 20; c < 40; ++c) {
      if (r % 2 != 0 || c % 2 != 0) sparse.at<float>(r, c) = kNaN;
    }
  }
  t = f.compute(g, sparse);
  EXPECT_TRUE(std::isnan(t.traversability.at<float>(30, 30)));  // known, window 16/49 known
  EXPECT_FALSE(std::isnan(t.traversability.at<float>(20, 20)));  // known, window 37/49 known
  const Reference ref = bruteForce(g, sparse, o);
  expectLayerNear(t.slope_rad, ref.slope, 1e-4, "slope");
  expectLayerNear(t.step_m, ref.step, 1e-5, "step");
  expectLayerNear(t.roughness_m, ref.roughness, 1e-5, "roughness");
  // (d) nothing known: all NaN, no exception.
  t = f.compute(g, cv::Mat(g.rows, g.cols, CV_32F, cv::Scalar(kNaN)));
  EXPECT_EQ(countNaN(t.traversability), g.vertexCount());
  EXPECT_EQ(countNaN(t.slope_rad), g.vertexCount());
}

// Random terrain with holes, windows of three different sizes: every layer equals the naive
// evaluation of the definitions (NaN pattern included).
TEST(TraversabilityFilter, MatchesBruteForceOnRandomTerrain) {
  const GroundGrid g = makeGrid(45, 52, 0.1, 7, -3);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  cv::Mat z = heightsOf(g, [&](double x, double y) {
    return 0.3 * std::sin(0.8 * x) + 0.2 * std::cos(1.3 * y) + 0.15 * x + (y > 1.5 ? 0.1 : 0.0) + noise(rng);
  });
  for (int r = 0; r < g.rows; ++r) {
    for (int c = 0; c < g.cols; ++c) {
      if (u(rng) < 0.15) z.at<float>(r, c) = kNaN;
    }
  }
  z(cv::Rect(30, 5, 6, 10)).setTo(kNaN);
  TraversabilityOptions o;
  o.slope_window_radius_m = 0.3;
  o.step_window_radius_m = 0.4;
  o.step_run_m = 0.2;
  o.roughness_window_radius_m = 0.5;
  o.min_known_fraction = 0.7;
  for (const auto& opts : {o, TraversabilityOptions::forCar(), TraversabilityOptions::forSmallRobot()}) {
    const TraversabilityFilter f(opts);
    const TraversabilityLayers t = f.compute(g, z);
    const Reference ref = bruteForce(g, z, opts);
    expectLayerNear(t.slope_rad, ref.slope, 1e-4, "slope");
    expectLayerNear(t.step_m, ref.step, 1e-5, "step");
    expectLayerNear(t.roughness_m, ref.roughness, 1e-5, "roughness");
    EXPECT_GE(countNaN(t.traversability), countNaN(z));
    EXPECT_LT(countNaN(t.traversability), g.vertexCount());
    for (int r = 0; r < g.rows; ++r) {
      for (int c = 0; c < g.cols; ++c) {
        const float s = ref.slope.at<float>(r, c), st = ref.step.at<float>(r, c), ro = ref.roughness.at<float>(r, c);
        const float want = std::isnan(s) || std::isnan(st) || std::isnan(ro) ? kNaN : static_cast<float>(f.combine(s, st, ro));
        const float got = t.traversability.at<float>(r, c);
        ASSERT_EQ(std::isnan(got), std::isnan(want)) << r << " " << c;
        if (!std::isnan(want)) {
          ASSERT_NEAR(got, want, 1e-3) << r << " " << c;
        }
      }
    }
  }
}

TEST(TraversabilityFilter, InputFormsAgreeAndBadInputIsRejected) {
  const GroundGrid g = makeGrid(30, 40, 0.1);
  cv::Mat z = heightsOf(g, [](double x, double y) { return 0.1 * std::sin(3.0 * x) * std::cos(2.0 * y); });
  z.at<float>(5, 7) = kNaN;
  const TraversabilityFilter f(TraversabilityOptions::forSmallRobot());
  const TraversabilityLayers a = f.compute(g, z);
  Eigen::VectorXd v(g.vertexCount());
  for (int i = 0; i < g.vertexCount(); ++i) v(i) = z.at<float>(g.rowOf(i), g.colOf(i));
  const TraversabilityLayers b = f.compute(g, v);
  cv::Mat z64;
  z.convertTo(z64, CV_64F);
  const TraversabilityLayers c = f.compute(g, z64);
  expectLayerNear(b.traversability, a.traversability, 1e-6, "eigen");
  expectLayerNear(c.roughness_m, a.roughness_m, 1e-7, "double");
  expectLayerNear(b.step_m, a.step_m, 1e-7, "eigen step");

  EXPECT_THROW(f.compute(g, cv::Mat(g.rows, g.cols + 1, CV_32F, cv::Scalar(0))), std::invalid_argument);
  EXPECT_THROW(f.compute(g, cv::Mat(g.rows, g.cols, CV_8U, cv::Scalar(0))), std::invalid_argument);
  EXPECT_THROW(f.compute(g, Eigen::VectorXd::Zero(g.vertexCount() - 1)), std::invalid_argument);
  GroundGrid bad = g;
  bad.resolution_m = 0.0;
  EXPECT_THROW(f.compute(bad, z), std::invalid_argument);
}

TEST(TraversabilityFilter, LargeGridWithAHole) {
  // 400 x 400 vertices with an unknown block: the block stays unknown for both presets. (Speed is
  // measured by the benchmark, sgd_benchmark, not asserted here.)
  const GroundGrid g = makeGrid(400, 400, 0.1);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  cv::Mat z = heightsOf(g, [&](double x, double y) { return 0.5 * std::sin(0.3 * x) + 0.1 * y + noise(rng); });
  z(cv::Rect(100, 100, 50, 80)).setTo(kNaN);
  for (const auto& [name, o] : {std::make_pair("car", TraversabilityOptions::forCar()),
                                std::make_pair("small robot", TraversabilityOptions::forSmallRobot())}) {
    const TraversabilityLayers t = TraversabilityFilter(o).compute(g, z);
    EXPECT_GE(countNaN(t.traversability), 50 * 80) << name;
  }
}

// The probability of being traversable: certain on flat ground with a small std, one half at a
// step exactly at the critical height, falling as the heights' std grows; NaN where unknown.
TEST(TraversabilityFilter, ProbabilityPropagatesTheHeightStd) {
  GroundGrid g;
  g.resolution_m = 0.1;
  g.rows = 41;
  g.cols = 41;
  TraversabilityOptions o;
  o.height_std_floor_m = 0.001;
  const TraversabilityFilter f(o);
  cv::Mat z(g.rows, g.cols, CV_32F, cv::Scalar(0.0f));
  for (int r = 0; r < g.rows; ++r)
    for (int c = 21; c < g.cols; ++c) z.at<float>(r, c) = 0.2f;  // a 0.2 m step (the critical one) at column 21
  const TraversabilityLayers t = f.compute(g, z);
  auto p_at = [&](double std_m, int r, int c) {
    const cv::Mat var(g.rows, g.cols, CV_32F, cv::Scalar(static_cast<float>(std_m * std_m)));
    return f.probability(g, t, var).at<float>(r, c);
  };
  EXPECT_NEAR(p_at(0.01, 20, 5), 1.0, 1e-6);      // flat, 1 cm: certain
  EXPECT_NEAR(t.step_m.at<float>(20, 20), 0.2f, 1e-6);
  EXPECT_NEAR(p_at(0.01, 20, 20), 0.5, 0.02);     // step at the critical height: even odds
  // 10 cm std on flat ground: the 0.2 m step criterion alone, Phi(0.2 / (sqrt(2) 0.1)) = 0.921
  // (the step on exactly flat ground is 0), times the roughness Phi(0.08 / 0.1) = 0.788.
  EXPECT_NEAR(p_at(0.10, 20, 5), 0.9214 * 0.7881, 0.01);
  EXPECT_LT(p_at(0.5, 20, 5), p_at(0.1, 20, 5));
  // NaN where the layers are unknown, and size checks.
  cv::Mat zn = z.clone();
  zn.at<float>(3, 3) = kNaN;
  const TraversabilityLayers tn = f.compute(g, zn);
  EXPECT_TRUE(std::isnan(f.probability(g, tn, cv::Mat(g.rows, g.cols, CV_32F, cv::Scalar(1e-4f))).at<float>(3, 3)));
  EXPECT_THROW(f.probability(g, t, cv::Mat(3, 3, CV_32F)), std::invalid_argument);
  // The floor: a zero variance counts as height_std_floor_m.
  o.height_std_floor_m = 0.1;
  const TraversabilityFilter floored(o);
  EXPECT_NEAR(floored.probability(g, t, cv::Mat(g.rows, g.cols, CV_32F, cv::Scalar(0.0f))).at<float>(20, 5),
              0.9214 * 0.7881, 0.01);
  o.height_std_floor_m = 0.0;
  EXPECT_FALSE(o.isValid(nullptr));
}
