#include "stereo_ground_dem/sim/TerrainModel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "stereo_ground_dem/sim/TextureNoise.hpp"

namespace stereo_ground_dem::sim {

namespace {

constexpr double kTwoPi = 2.0 * M_PI;

// sin and cos of x (|x| < 1e6) to about 1e-15 absolute: Cody-Waite reduction to [-pi/4, pi/4]
// and fdlibm's kernel polynomials. About three times faster than the libm call, and it is the
// one definition of the rolling terrain (ray casting and terrainHeight() agree exactly).
inline void sinCos(double x, double* s, double* c) {
  constexpr double kTwoOverPi = 6.36619772367581382433e-01;
  constexpr double kPiO2Hi = 1.57079632673412561417e+00;
  constexpr double kPiO2Lo = 6.07710050650619224932e-11;
  const double qf = x * kTwoOverPi;
  const auto q = static_cast<int64_t>(qf < 0.0 ? qf - 0.5 : qf + 0.5);
  const double qd = static_cast<double>(q);
  const double r = (x - qd * kPiO2Hi) - qd * kPiO2Lo;
  const double z = r * r;
  const double sr =
      r + r * z *
              (-1.66666666666666324348e-01 +
               z * (8.33333333332248946124e-03 +
                    z * (-1.98412698298579493134e-04 +
                         z * (2.75573137070700676789e-06 +
                              z * (-2.50507602534068634195e-08 + z * 1.58969099521155010221e-10)))));
  const double cr =
      1.0 - 0.5 * z +
      z * z *
          (4.16666666666666019037e-02 +
           z * (-1.38888888888741095749e-03 +
                z * (2.48015872894767294178e-05 +
                     z * (-2.75573143513906633035e-07 +
                          z * (2.08757232129817482790e-09 + z * -1.13596475577881948265e-11)))));
  switch (q & 3) {
    case 0: *s = sr; *c = cr; break;
    case 1: *s = cr; *c = -sr; break;
    case 2: *s = -sr; *c = -cr; break;
    default: *s = -cr; *c = sr; break;
  }
}

}  // namespace

TerrainModel::TerrainModel(const SceneOptions& options) : options_(options) {
  const SceneOptions& o = options_;
  if (o.rolling_enabled) {
    const double amp = o.rolling_amplitude_m / std::sqrt(static_cast<double>(o.rolling_components));
    uint64_t s = TextureNoise::mix64(o.seed ^ 0x7A3C5E1F00ULL);
    auto uniform = [&s]() {
      s = TextureNoise::mix64(s);
      return static_cast<double>(s >> 11) / 9007199254740992.0;
    };
    for (int i = 0; i < o.rolling_components; ++i) {
      const double wl =
          o.rolling_min_wavelength_m + uniform() * (o.rolling_max_wavelength_m - o.rolling_min_wavelength_m);
      const double dir = uniform() * kTwoPi;
      const double k = kTwoPi / wl;
      waves_.push_back({k * std::cos(dir), k * std::sin(dir), amp, uniform() * kTwoPi});
      double sp, cp;
      sinCos(waves_.back().phase, &sp, &cp);
      rolling_offset_m_ += amp * sp;
      rolling_amp_sum_m_ += amp;
    }
  }
  embankment_tan_ = std::tan(o.embankment_slope_rad);
  embankment_top_y_m_ = o.embankment_y_m - o.embankment_height_m / embankment_tan_;
  auto addY = [this](double y) { y_lines_.push_back(y); };
  auto addX = [this](double x) { x_lines_.push_back(x); };
  if (o.bump_enabled) {
    addX(o.bump_center_x_m - 0.5 * o.bump_length_m);
    addX(o.bump_center_x_m + 0.5 * o.bump_length_m);
    addY(o.bump_y_min_m);
    addY(o.bump_y_max_m);
    if (o.bump_end_taper_m > 0.0) addY(o.bump_y_max_m + o.bump_end_taper_m);
  }
  if (o.curb_enabled) addY(o.curb_y_m);
  if (o.ruts_enabled) {
    for (double c : {o.rut_offset_y_m, -o.rut_offset_y_m}) {
      addY(c - 0.5 * o.rut_width_m);
      addY(c + 0.5 * o.rut_width_m);
    }
  }
  if (o.terrace_enabled) {
    addX(o.terrace_x_min_m);
    addY(o.terrace_y_min_m);
  }
  if (o.embankment_enabled) {
    addY(o.embankment_y_m);
    addY(embankment_top_y_m_);
  }
  for (auto* v : {&x_lines_, &y_lines_}) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  }
  // Global height bounds.
  z_min_ = -rolling_amp_sum_m_ - rolling_offset_m_;
  z_max_ = rolling_amp_sum_m_ - rolling_offset_m_;
  if (o.bump_enabled) z_max_ += o.bump_height_m;
  if (o.ruts_enabled) z_min_ -= o.rut_depth_m;
  if (o.embankment_enabled) z_max_ += o.embankment_height_m;
  if (o.curb_enabled) {
    z_max_ += std::max(0.0, o.curb_height_m);
    z_min_ += std::min(0.0, o.curb_height_m);
  }
  if (o.terrace_enabled) {
    z_max_ += std::max(0.0, o.terrace_height_m);
    z_min_ += std::min(0.0, o.terrace_height_m);
  }
}

TerrainModel::Cell TerrainModel::cellAt(double x, double y) const {
  const SceneOptions& o = options_;
  Cell c;
  if (o.bump_enabled && std::abs(x - o.bump_center_x_m) < 0.5 * o.bump_length_m &&
      y >= o.bump_y_min_m && y < o.bump_y_max_m + o.bump_end_taper_m) {
    c.bump = true;
    c.bump_taper = y > o.bump_y_max_m;
  }
  if (o.ruts_enabled) {
    c.rut[0] = std::abs(y - o.rut_offset_y_m) < 0.5 * o.rut_width_m;
    c.rut[1] = std::abs(y + o.rut_offset_y_m) < 0.5 * o.rut_width_m;
  }
  if (o.embankment_enabled && y < o.embankment_y_m) {
    c.embankment = y > embankment_top_y_m_ ? 1 : 2;
  }
  if (o.curb_enabled && y < o.curb_y_m) c.offset += o.curb_height_m;
  if (o.terrace_enabled && x > o.terrace_x_min_m && y > o.terrace_y_min_m) {
    c.offset += o.terrace_height_m;
  }
  return c;
}

double TerrainModel::heightInCell(double x, double y, const Cell& cell, double* gx,
                                  double* gy) const {
  const SceneOptions& o = options_;
  double h = cell.offset;
  double dx = 0.0, dy = 0.0;
  if (!waves_.empty()) {
    for (const auto& w : waves_) {
      double s, c;
      sinCos(w.kx * x + w.ky * y + w.phase, &s, &c);
      h += w.amp * s;
      dx += w.amp * c * w.kx;
      dy += w.amp * c * w.ky;
    }
    h -= rolling_offset_m_;
  }
  if (cell.bump) {
    const double a = kTwoPi / o.bump_length_m;
    const double ph = a * (x - o.bump_center_x_m);
    const double p = 0.5 * o.bump_height_m * (1.0 + std::cos(ph));
    const double dp = -0.5 * o.bump_height_m * a * std::sin(ph);
    double q = 1.0, dq = 0.0;
    if (cell.bump_taper) {
      const double b = M_PI / o.bump_end_taper_m;
      const double pq = b * (y - o.bump_y_max_m);
      q = 0.5 * (1.0 + std::cos(pq));
      dq = -0.5 * b * std::sin(pq);
    }
    h += p * q;
    dx += dp * q;
    dy += p * dq;
  }
  for (int i = 0; i < 2; ++i) {
    if (!cell.rut[i]) continue;
    const double yc = i == 0 ? o.rut_offset_y_m : -o.rut_offset_y_m;
    const double a = kTwoPi / o.rut_width_m;
    const double ph = a * (y - yc);
    h -= 0.5 * o.rut_depth_m * (1.0 + std::cos(ph));
    dy += 0.5 * o.rut_depth_m * a * std::sin(ph);
  }
  if (cell.embankment == 1) {
    h += (o.embankment_y_m - y) * embankment_tan_;
    dy -= embankment_tan_;
  } else if (cell.embankment == 2) {
    h += o.embankment_height_m;
  }
  if (gx) *gx = dx;
  if (gy) *gy = dy;
  return h;
}

double TerrainModel::height(double x, double y) const {
  return heightInCell(x, y, cellAt(x, y), nullptr, nullptr);
}

Eigen::Vector2d TerrainModel::gradient(double x, double y) const {
  double gx = 0.0, gy = 0.0;
  heightInCell(x, y, cellAt(x, y), &gx, &gy);
  return {gx, gy};
}

TerrainModel::RayBounds TerrainModel::rayBounds(const Eigen::Vector3d& d) const {
  const SceneOptions& o = options_;
  RayBounds rb;
  const double adx = std::abs(d.x()), ady = std::abs(d.y());
  for (const auto& w : waves_) {
    const double kd = std::abs(w.kx * d.x() + w.ky * d.y());
    rb.rolling_slope += w.amp * kd;
    rb.rolling_curv += w.amp * kd * kd;
  }
  if (o.bump_enabled) {
    const double a = kTwoPi / o.bump_length_m;
    const double h = o.bump_height_m;
    rb.bump_slope = 0.5 * h * a * adx;
    rb.bump_curv = 0.5 * h * a * a * adx * adx;
    if (o.bump_end_taper_m > 0.0) {
      const double b = M_PI / o.bump_end_taper_m;
      rb.taper_slope = rb.bump_slope + 0.5 * h * b * ady;
      rb.taper_curv = rb.bump_curv + 2.0 * (0.5 * h * a) * (0.5 * b) * adx * ady +
                      0.5 * h * b * b * ady * ady;
    }
  }
  if (o.ruts_enabled) {
    const double a = kTwoPi / o.rut_width_m;
    rb.rut_slope = 0.5 * o.rut_depth_m * a * ady;
    rb.rut_curv = 0.5 * o.rut_depth_m * a * a * ady * ady;
  }
  if (o.embankment_enabled) rb.emb_slope = embankment_tan_ * ady;
  return rb;
}

void TerrainModel::cellBounds(const RayBounds& rb, const Cell& cell, double* slope_out,
                              double* curv_out, double* z_top) const {
  const SceneOptions& so = options_;
  const double rolling_top = rolling_amp_sum_m_ - rolling_offset_m_;
  double slope = rb.rolling_slope, curv = rb.rolling_curv;
  double ztop = rolling_top + cell.offset;
  if (cell.bump) {
    slope += cell.bump_taper ? rb.taper_slope : rb.bump_slope;
    curv += cell.bump_taper ? rb.taper_curv : rb.bump_curv;
    ztop += so.bump_height_m;
  }
  for (int r = 0; r < 2; ++r) {
    if (cell.rut[r]) {
      slope += rb.rut_slope;
      curv += rb.rut_curv;
    }
  }
  if (cell.embankment == 1) slope += rb.emb_slope;
  if (cell.embankment != 0) ztop += so.embankment_height_m;
  *slope_out = slope;
  *curv_out = curv;
  *z_top = ztop;
}

}  // namespace stereo_ground_dem::sim
