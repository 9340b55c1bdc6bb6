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
  // Quadrant q & 3: (s, c) = (sr, cr), (cr, -sr), (-sr, -cr), (-cr, sr). Selected without
  // branches (the quadrant is unpredictable along a ray); exact: a choice and sign changes.
  const double v[2] = {sr, cr};
  const int odd = static_cast<int>(q & 1);
  const double sign_s = (q & 2) ? -1.0 : 1.0;
  const double sign_c = ((q + 1) & 2) ? -1.0 : 1.0;
  *s = sign_s * v[odd];
  *c = sign_c * v[1 - odd];
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
  buildProfile();
  buildWaves();
  for (double x : profile_breaks_) addX(x);
  for (const auto& w : wave_rows_) {
    addX(w.x0);
    addX(w.x1);
  }
  for (const auto& h : o.potholes) {
    addX(h.center_xy.x() - 0.5 * h.length_x_m);
    addX(h.center_xy.x() + 0.5 * h.length_x_m);
    addY(h.center_xy.y() - 0.5 * h.width_y_m);
    addY(h.center_xy.y() + 0.5 * h.width_y_m);
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
  if (!profile_.empty()) {
    double lo = profile_.front().z_min, hi = profile_.front().z_max;
    for (const auto& pc : profile_) {
      hi = std::max(hi, pc.z_max);
      lo = std::min(lo, pc.z_min);
    }
    z_min_ += lo;
    z_max_ += hi;
  }
  if (o.bank_enabled) {
    bank_top_m_ = std::abs(o.bank_superelevation) * (o.bank_half_width_m + 0.5 * o.bank_transition_m);
    z_min_ -= bank_top_m_;
    z_max_ += bank_top_m_;
  }
  double wave_lo = 0.0, wave_hi = 0.0;
  for (const auto& w : wave_rows_) {
    wave_lo = std::min(wave_lo, 2.0 * w.half_height);
    wave_hi = std::max(wave_hi, 2.0 * w.half_height);
  }
  z_min_ += wave_lo;
  z_max_ += wave_hi;
  for (const auto& h : o.potholes) {
    z_min_ -= std::max(0.0, h.depth_m);
    z_max_ += std::max(0.0, -h.depth_m);
  }
}

void TerrainModel::buildProfile() {
  const auto& curves = options_.profile_curves;
  if (curves.empty()) return;
  // Pieces: level before the first curve, then each curve and the straight grade after it.
  double z = 0.0, g = 0.0, x = curves.front().start_x_m;
  profile_.push_back({x, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0});
  for (size_t i = 0; i < curves.size(); ++i) {
    const VerticalCurve& vc = curves[i];
    z += g * (vc.start_x_m - x);  // the straight grade since the previous curve
    const double c = (vc.grade_after - g) / vc.length_m;
    profile_breaks_.push_back(vc.start_x_m);
    profile_.push_back({vc.start_x_m, z, g, c, 0.0, 0.0, 0.0});
    z += g * vc.length_m + 0.5 * c * vc.length_m * vc.length_m;
    g = vc.grade_after;
    const double x_end = vc.start_x_m + vc.length_m;
    x = x_end;
    const bool touching = i + 1 < curves.size() && curves[i + 1].start_x_m == x_end;
    if (!touching) {
      profile_breaks_.push_back(x_end);
      profile_.push_back({x_end, z, g, 0.0, 0.0, 0.0, 0.0});
    }
  }
  // Shift so that z(0) = 0, then the bounds of each piece.
  const size_t i0 = static_cast<size_t>(
      std::upper_bound(profile_breaks_.begin(), profile_breaks_.end(), 0.0) - profile_breaks_.begin());
  const double z_at_0 = profileHeight(0.0, static_cast<int>(i0), nullptr);
  for (size_t i = 0; i < profile_.size(); ++i) {
    ProfilePiece& pc = profile_[i];
    pc.z0 -= z_at_0;
    const bool bounded = i > 0 && i < profile_breaks_.size();
    const double len = bounded ? profile_breaks_[i] - pc.x0 : 0.0;
    const double g1 = pc.g0 + pc.c * len;
    pc.slope_max = std::max(std::abs(pc.g0), std::abs(g1));
    const double z1 = pc.z0 + pc.g0 * len + 0.5 * pc.c * len * len;
    pc.z_max = std::max(pc.z0, z1);
    pc.z_min = std::min(pc.z0, z1);
    if (pc.c != 0.0) {
      const double u = -pc.g0 / pc.c;  // the crest (c < 0) or the bottom (c > 0) of the parabola
      if (u > 0.0 && u < len) {
        const double zv = pc.z0 + pc.g0 * u + 0.5 * pc.c * u * u;
        pc.z_max = std::max(pc.z_max, zv);
        pc.z_min = std::min(pc.z_min, zv);
      }
    }
  }
}

void TerrainModel::buildWaves() {
  for (const auto& w : options_.transverse_waves) {
    WaveRow r;
    r.x0 = w.start_x_m;
    r.x1 = w.start_x_m + w.count * w.period_m;
    r.k = kTwoPi / w.period_m;
    r.half_height = 0.5 * w.height_m;
    r.slope = std::abs(r.half_height) * r.k;
    r.curv = std::abs(r.half_height) * r.k * r.k;
    wave_rows_.push_back(r);
  }
  std::sort(wave_rows_.begin(), wave_rows_.end(),
            [](const WaveRow& a, const WaveRow& b) { return a.x0 < b.x0; });
}

double TerrainModel::profileHeight(double x, int piece, double* gx) const {
  const ProfilePiece& pc = profile_[static_cast<size_t>(piece)];
  const double u = x - pc.x0;
  if (gx) *gx = pc.g0 + pc.c * u;
  return pc.z0 + pc.g0 * u + 0.5 * pc.c * u * u;
}

double TerrainModel::bankHeight(double x, double y, double* gx, double* gy) const {
  const SceneOptions& o = options_;
  const double ex = x - o.bank_center_xy_m.x(), ey = y - o.bank_center_xy_m.y();
  const double r = std::sqrt(ex * ex + ey * ey);
  const double rho = r - o.bank_radius_m;
  const double a = std::abs(rho);
  const double w0 = o.bank_half_width_m, wt = o.bank_transition_m;
  double b, db;  // b(|rho|) and its derivative
  if (a <= w0) {
    b = a;
    db = 1.0;
  } else if (a < w0 + wt) {
    const double v = a - w0;
    b = w0 + v - 0.5 * v * v / wt;
    db = 1.0 - v / wt;
  } else {
    b = w0 + 0.5 * wt;
    db = 0.0;
  }
  const double sign = rho < 0.0 ? -1.0 : 1.0;
  const double e = o.bank_superelevation;
  // d rho / d(x, y) = (ex, ey) / r; db = 0 wherever r is small (radius > half width + transition).
  const double scale = db > 0.0 ? e * db / r : 0.0;
  *gx = scale * ex;
  *gy = scale * ey;
  return e * sign * b;
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
  if (!profile_.empty()) {
    c.profile_piece = static_cast<int>(
        std::upper_bound(profile_breaks_.begin(), profile_breaks_.end(), x) - profile_breaks_.begin());
  }
  for (size_t i = 0; i < wave_rows_.size(); ++i) {
    if (x > wave_rows_[i].x0 && x < wave_rows_[i].x1) c.wave_row = static_cast<int>(i);
  }
  for (size_t i = 0; i < o.potholes.size(); ++i) {
    const Pothole& h = o.potholes[i];
    if (std::abs(x - h.center_xy.x()) < 0.5 * h.length_x_m &&
        std::abs(y - h.center_xy.y()) < 0.5 * h.width_y_m) {
      c.potholes |= 1U << i;
    }
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
  if (cell.profile_piece >= 0) {
    double g;
    h += profileHeight(x, cell.profile_piece, &g);
    dx += g;
  }
  if (o.bank_enabled) {
    double bx, by;
    h += bankHeight(x, y, &bx, &by);
    dx += bx;
    dy += by;
  }
  if (cell.wave_row >= 0) {
    const WaveRow& w = wave_rows_[static_cast<size_t>(cell.wave_row)];
    const double ph = w.k * (x - w.x0);
    double sp, cp;
    sinCos(ph, &sp, &cp);
    h += w.half_height * (1.0 - cp);
    dx += w.half_height * w.k * sp;
  }
  for (uint32_t bits = cell.potholes; bits != 0; bits &= bits - 1) {
    const Pothole& p = o.potholes[static_cast<size_t>(__builtin_ctz(bits))];
    const double ax = kTwoPi / p.length_x_m, ay = kTwoPi / p.width_y_m;
    const double px = ax * (x - p.center_xy.x()), py = ay * (y - p.center_xy.y());
    double sx, cosx, sy, cosy;
    sinCos(px, &sx, &cosx);
    sinCos(py, &sy, &cosy);
    const double cx = 0.5 * (1.0 + cosx), cy = 0.5 * (1.0 + cosy);
    const double dcx = -0.5 * ax * sx, dcy = -0.5 * ay * sy;
    h -= p.depth_m * cx * cy;
    dx -= p.depth_m * dcx * cy;
    dy -= p.depth_m * cx * dcy;
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
  if (o.bank_enabled) {
    // h = e b(rho(x, y)): |dh/dt| <= |e| |d_xy|; |d2h/dt2| <= |e| (|b''| + |b'| / r) |d_xy|^2 with
    // |b'| <= 1, |b''| <= 1 / transition and r >= radius - half width - transition where b' != 0.
    const double dxy2 = d.x() * d.x() + d.y() * d.y();
    const double e = std::abs(o.bank_superelevation);
    const double r_min = o.bank_radius_m - o.bank_half_width_m - o.bank_transition_m;
    rb.bank_slope = e * std::sqrt(dxy2);
    rb.bank_curv = e * (1.0 / o.bank_transition_m + 1.0 / r_min) * dxy2;
  }
  rb.dx = d.x();
  rb.adx = adx;
  rb.ady = ady;
  return rb;
}

void TerrainModel::cellBounds(const RayBounds& rb, const Cell& cell, double* slope_out,
                              double* curv_out, double* z_top, double* linear_out) const {
  double linear = 0.0;
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
  if (cell.profile_piece >= 0) {
    const ProfilePiece& pc = profile_[static_cast<size_t>(cell.profile_piece)];
    if (pc.c == 0.0) {
      linear += pc.g0 * rb.dx;  // a straight grade: exactly linear along the ray
    } else {
      slope += pc.slope_max * rb.adx;
      curv += std::abs(pc.c) * rb.adx * rb.adx;
    }
    ztop += pc.z_max;
  }
  if (so.bank_enabled) {
    slope += rb.bank_slope;
    curv += rb.bank_curv;
    ztop += bank_top_m_;
  }
  if (cell.wave_row >= 0) {
    const WaveRow& w = wave_rows_[static_cast<size_t>(cell.wave_row)];
    slope += w.slope * rb.adx;
    curv += w.curv * rb.adx * rb.adx;
    ztop += std::max(0.0, 2.0 * w.half_height);
  }
  for (uint32_t bits = cell.potholes; bits != 0; bits &= bits - 1) {
    // h = -D c(x) c(y): |c'| <= pi / L, |c''| <= 2 pi^2 / L^2.
    const Pothole& p = so.potholes[static_cast<size_t>(__builtin_ctz(bits))];
    const double depth = std::abs(p.depth_m);
    const double sx = M_PI / p.length_x_m * rb.adx, sy = M_PI / p.width_y_m * rb.ady;
    slope += depth * (sx + sy);
    curv += depth * 2.0 * (sx + sy) * (sx + sy);
    ztop += std::max(0.0, -p.depth_m);
  }
  *slope_out = slope;
  *curv_out = curv;
  *z_top = ztop;
  *linear_out = linear;
}

}  // namespace stereo_ground_dem::sim
