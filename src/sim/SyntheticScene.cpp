#include "stereo_ground_dem/sim/SyntheticScene.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/core.hpp>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem::sim {

namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kObstacleBuryM = 1.0;     // obstacles reach this far below the terrain
constexpr double kTerrainHitEpsM = 1e-7;   // a ray closer than this above the terrain hits it
constexpr int kMaxMarchSteps = 20000;

constexpr int kTerrainTop = SurfaceHit::kTerrainTop;
constexpr int kTerrainFaceX = SurfaceHit::kTerrainFaceX;
constexpr int kTerrainFaceY = SurfaceHit::kTerrainFaceY;
constexpr int kBoxFaceBase = SurfaceHit::kBoxFaceBase;
constexpr int kPoleSide = SurfaceHit::kPoleSide;
constexpr int kPoleTop = SurfaceHit::kPoleTop;

// ------------------------------------------------------------------------------------------------
// Materials: mean grey level and the amplitude (grey levels per unit-variance octave) of each
// noise octave, from 16 m (index 0) down to 1.6 cm (index 10).
constexpr int kOctaves = 11;
constexpr double kCoarsestWavelengthM = 16.0;
struct Material {
  double mean;
  std::array<double, kOctaves> amp;
};
enum MaterialId { kAsphalt, kGravel, kGrass, kDirt, kConcrete, kPaint, kRock, kMaterialCount };
const Material kMaterials[kMaterialCount] = {
    // 16m  8m   4m   2m   1m  50cm 25cm 12cm  6cm  3cm 1.6cm
    {98.0, {{9.0, 8.0, 7.0, 6.0, 5.0, 5.0, 6.0, 8.0, 10.0, 12.0, 11.0}}},  // asphalt
    {132.0, {{8.0, 8.0, 7.0, 7.0, 7.0, 8.0, 10.0, 14.0, 17.0, 17.0, 13.0}}},  // gravel
    {84.0, {{10.0, 10.0, 9.0, 8.0, 8.0, 8.0, 9.0, 11.0, 13.0, 13.0, 11.0}}},  // grass
    {118.0, {{11.0, 10.0, 10.0, 9.0, 8.0, 8.0, 9.0, 10.0, 12.0, 12.0, 10.0}}},  // dirt
    {152.0, {{6.0, 5.0, 5.0, 4.0, 4.0, 4.0, 5.0, 7.0, 8.0, 9.0, 8.0}}},  // concrete
    {206.0, {{2.0, 2.0, 2.0, 3.0, 3.0, 3.0, 3.0, 4.0, 5.0, 6.0, 6.0}}},  // paint
    {140.0, {{12.0, 12.0, 11.0, 11.0, 10.0, 10.0, 12.0, 14.0, 14.0, 12.0, 10.0}}},  // rock
};
constexpr std::array<double, kOctaves> kObstacleAmp = {
    {0.0, 0.0, 6.0, 8.0, 9.0, 10.0, 10.0, 10.0, 10.0, 9.0, 8.0}};

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

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Fraction of the box [s - e/2, s + e/2] covered by [a, b] (a <= b; a, b may be infinite).
double intervalCoverage(double s, double a, double b, double e) {
  const double lo = std::max(s - 0.5 * e, a);
  const double hi = std::min(s + 0.5 * e, b);
  return hi > lo ? (hi - lo) / e : 0.0;
}

// Measure of the dashes {[phase + n P, phase + n P + D)} in (-inf, x], up to a constant.
double dashCumulative(double x, double phase, double dash, double period) {
  const double r = x - phase;
  const double n = std::floor(r / period);
  return n * dash + std::min(r - n * period, dash);
}

// Keeps grey levels inside (30, 235) smoothly.
double softClamp(double a) {
  if (a > 200.0) return 200.0 + 35.0 * std::tanh((a - 200.0) / 35.0);
  if (a < 50.0) return 50.0 - 20.0 * std::tanh((50.0 - a) / 20.0);
  return a;
}

struct Footprint {
  double minor = 0.0;  // [m/px]
  double major = 0.0;
  double extent1 = 0.0;  // box extent along texture axis 1 [m/px]
  double extent2 = 0.0;
};

// Footprint of a pixel in texture coordinates (a1, a2 are the 3-D texture axes).
Footprint footprintOf(const TextureFilter& f, const Eigen::Vector3d& a1, const Eigen::Vector3d& a2) {
  const double j00 = a1.dot(f.dp_du), j01 = a1.dot(f.dp_dv);
  const double j10 = a2.dot(f.dp_du), j11 = a2.dot(f.dp_dv);
  const double s = j00 * j00 + j01 * j01 + j10 * j10 + j11 * j11;
  const double det = j00 * j11 - j01 * j10;
  const double disc = std::sqrt(std::max(0.0, s * s - 4.0 * det * det));
  Footprint fp;
  fp.major = std::sqrt(std::max(0.0, 0.5 * (s + disc)));
  fp.minor = std::sqrt(std::max(0.0, 0.5 * (s - disc)));
  fp.extent1 = std::max(1e-6, (std::abs(j00) + std::abs(j01)) * f.edge_box_px);
  fp.extent2 = std::max(1e-6, (std::abs(j10) + std::abs(j11)) * f.edge_box_px);
  return fp;
}

// Band-limited octaves n_k * w_k at texture coordinates (s1, s2); returns how many are non-zero.
int bandLimitedOctaves(const TextureNoise& noise, double s1, double s2, const Footprint& fp,
                       const TextureFilter& f, std::array<double, kOctaves>* out) {
  const double minor = std::max(fp.minor, 1e-9);
  const double major = std::max(fp.major, minor);
  double eff;
  if (f.anisotropy <= 0.0) {
    eff = minor;
  } else if (f.anisotropy >= 1.0) {
    eff = major;
  } else if (f.anisotropy == 0.5) {
    eff = std::sqrt(minor * major);
  } else {
    eff = minor * std::pow(major / minor, f.anisotropy);
  }
  int count = 0;
  for (int k = 0; k < kOctaves && k < noise.octaves(); ++k) {
    const double w =
        TextureNoise::bandWeight(noise.wavelength(k), eff, f.octave_fade_start, f.octave_fade_end);
    if (w <= 0.0) break;
    (*out)[static_cast<size_t>(k)] = w * noise.octave(k, s1, s2);
    count = k + 1;
  }
  return count;
}

double materialAlbedo(MaterialId m, const std::array<double, kOctaves>& n, int count) {
  const Material& mat = kMaterials[m];
  double a = mat.mean;
  for (int k = 0; k < count; ++k) a += mat.amp[static_cast<size_t>(k)] * n[static_cast<size_t>(k)];
  return a;
}

// One band-limited noise value of wavelength `wavelength_m` (for wobbly borders).
double wobble(const TextureNoise& noise, int octave, double x, double y, double footprint,
              const TextureFilter& f) {
  const double w = TextureNoise::bandWeight(noise.wavelength(octave), footprint, f.octave_fade_start,
                                            f.octave_fade_end);
  return w > 0.0 ? w * noise.octave(octave, x, y) : 0.0;
}

uint64_t parseSeed(const std::string& text, const std::string& path) {
  try {
    size_t pos = 0;
    const unsigned long long v = std::stoull(text, &pos);
    if (pos != text.size()) throw std::invalid_argument("trailing characters");
    return static_cast<uint64_t>(v);
  } catch (const std::exception&) {
    throw std::runtime_error("scene file '" + path + "': seed '" + text + "' is not an unsigned integer");
  }
}

}  // namespace

// ------------------------------------------------------------------------------------------------
// Names and options

const char* sceneKindName(SceneKind kind) {
  switch (kind) {
    case SceneKind::kFlatRoad: return "flat";
    case SceneKind::kBumpAndCurb: return "bump";
    case SceneKind::kOffRoad: return "offroad";
  }
  return "?";
}

bool sceneKindFromName(const std::string& name, SceneKind* kind) {
  if (name == "flat" || name == "flat_road") {
    *kind = SceneKind::kFlatRoad;
  } else if (name == "bump" || name == "bump_and_curb") {
    *kind = SceneKind::kBumpAndCurb;
  } else if (name == "offroad" || name == "off_road") {
    *kind = SceneKind::kOffRoad;
  } else {
    return false;
  }
  return true;
}

SceneOptions SceneOptions::standard(SceneKind kind, uint64_t seed) {
  SceneOptions o;
  o.kind = kind;
  o.seed = seed;
  switch (kind) {
    case SceneKind::kFlatRoad:
      break;
    case SceneKind::kBumpAndCurb:
      o.bump_enabled = true;
      o.curb_enabled = true;
      break;
    case SceneKind::kOffRoad:
      o.rolling_enabled = true;
      o.ruts_enabled = true;
      o.terrace_enabled = true;
      o.embankment_enabled = true;
      break;
  }
  return o;
}

void SceneOptions::addStandardObstacles() {
  auto box = [](double x, double y, double yaw, double l, double w, double h, double vx) {
    BoxObstacle b;
    b.center_xy = {x, y};
    b.yaw_rad = yaw;
    b.length_m = l;
    b.width_m = w;
    b.height_m = h;
    b.velocity_xy = {vx, 0.0};
    return b;
  };
  auto pole = [](double x, double y, double r, double h) {
    PoleObstacle p;
    p.xy = {x, y};
    p.radius_m = r;
    p.height_m = h;
    return p;
  };
  if (kind == SceneKind::kOffRoad) {
    boxes.push_back(box(24.0, -3.2, 0.15, 4.4, 1.9, 1.7, 0.0));   // parked vehicle
    boxes.push_back(box(32.0, 2.0, 0.0, 4.2, 1.8, 1.5, 5.0));     // vehicle ahead, 5 m/s
    boxes.push_back(box(30.0, -5.2, 0.05, 5.0, 0.25, 1.0, 0.0));  // wall at the embankment foot
    poles.push_back(pole(15.0, 2.4, 0.15, 2.5));
    poles.push_back(pole(40.0, -4.5, 0.12, 3.0));
  } else {
    boxes.push_back(box(22.0, -2.6, 0.0, 4.2, 1.8, 1.5, 0.0));    // parked car
    boxes.push_back(box(30.0, 2.0, 0.0, 4.2, 1.8, 1.5, 5.0));     // car ahead, 5 m/s
    boxes.push_back(box(28.0, 6.0, 0.0, 6.0, 0.2, 1.2, 0.0));     // wall
    poles.push_back(pole(15.0, 5.0, 0.12, 4.0));
    poles.push_back(pole(40.0, -5.5, 0.10, 3.5));
  }
}

bool SceneOptions::isValid(std::string* why) const {
  auto bad = [why](const std::string& msg) {
    if (why) *why = msg;
    return false;
  };
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  auto nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!positive(road_width_m) || !positive(edge_line_width_m) || !nonneg(edge_line_inset_m) ||
      !positive(centre_line_width_m) || !positive(centre_dash_length_m) ||
      !nonneg(centre_gap_length_m) || !nonneg(shoulder_width_m) ||
      !std::isfinite(road_center_y_m) || !std::isfinite(centre_dash_phase_m)) {
    return bad("road widths and dash lengths must be positive (gaps, inset, shoulder >= 0)");
  }
  if (edge_line_inset_m + edge_line_width_m > 0.5 * road_width_m) {
    return bad("edge lines do not fit on the road");
  }
  if (bump_enabled && (!positive(bump_length_m) || !nonneg(bump_height_m) ||
                       !std::isfinite(bump_center_x_m) || !(bump_y_max_m > bump_y_min_m) ||
                       !nonneg(bump_end_taper_m))) {
    return bad("bump: length > 0, height >= 0, bump_y_max_m > bump_y_min_m, taper >= 0");
  }
  if (curb_enabled && (!std::isfinite(curb_y_m) || !std::isfinite(curb_height_m))) {
    return bad("curb position and height must be finite");
  }
  if (rolling_enabled &&
      (!nonneg(rolling_amplitude_m) || !positive(rolling_min_wavelength_m) ||
       !(rolling_max_wavelength_m >= rolling_min_wavelength_m) || rolling_components < 1 ||
       rolling_components > 32)) {
    return bad("rolling terrain: amplitude >= 0, 0 < min <= max wavelength, 1..32 components");
  }
  if (ruts_enabled && (!nonneg(rut_depth_m) || !positive(rut_width_m) ||
                       !std::isfinite(rut_offset_y_m) || rut_width_m > 2.0 * std::abs(rut_offset_y_m))) {
    return bad("ruts: depth >= 0, width > 0 and the two ruts must not overlap");
  }
  if (terrace_enabled && (!std::isfinite(terrace_x_min_m) || !std::isfinite(terrace_y_min_m) ||
                          !std::isfinite(terrace_height_m))) {
    return bad("terrace parameters must be finite");
  }
  if (embankment_enabled &&
      (!std::isfinite(embankment_y_m) || !positive(embankment_height_m) ||
       !(embankment_slope_rad > 0.0 && embankment_slope_rad < 80.0 * M_PI / 180.0))) {
    return bad("embankment: height > 0 and slope in (0, 80) degrees");
  }
  if (!(sun_elevation_rad > 0.0 && sun_elevation_rad <= 0.5 * M_PI) ||
      !std::isfinite(sun_azimuth_rad) || !(ambient >= 0.0 && ambient <= 1.0)) {
    return bad("sun elevation in (0, pi/2], ambient in [0, 1]");
  }
  for (const auto& b : boxes) {
    if (!b.center_xy.allFinite() || !b.velocity_xy.allFinite() || !std::isfinite(b.yaw_rad) ||
        !positive(b.length_m) || !positive(b.width_m) || !positive(b.height_m)) {
      return bad("box obstacle: finite pose and velocity, positive size");
    }
  }
  for (const auto& p : poles) {
    if (!p.xy.allFinite() || !positive(p.radius_m) || !positive(p.height_m)) {
      return bad("pole obstacle: finite position, positive radius and height");
    }
  }
  return true;
}

// ------------------------------------------------------------------------------------------------
// Terrain

struct SyntheticScene::Cell {
  bool bump = false;        // inside the bump's support
  bool bump_taper = false;  // ... in its lateral taper
  bool rut[2] = {false, false};
  int embankment = 0;       // 0 before the foot, 1 on the slope, 2 on top
  double offset = 0.0;      // sum of the steps (curb, terrace)
};

// Per-ray bounds of |d/dt h(o + t d)| (slope) and |d^2/dt^2 h| (curvature) for each feature.
struct SyntheticScene::RayBounds {
  double rolling_slope = 0.0, rolling_curv = 0.0;
  double bump_slope = 0.0, bump_curv = 0.0;
  double taper_slope = 0.0, taper_curv = 0.0;
  double rut_slope = 0.0, rut_curv = 0.0;
  double emb_slope = 0.0;
};

SyntheticScene::SyntheticScene(const SceneOptions& options)
    : options_(options),
      ground_noise_(options.seed, kCoarsestWavelengthM, kOctaves),
      detail_noise_(TextureNoise::mix64(options.seed ^ 0xD1B54A32D192ED03ULL), 8.0, 6) {
  std::string why;
  if (!options_.isValid(&why)) throw std::invalid_argument("SceneOptions: " + why);
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
  sun_ = Eigen::Vector3d(std::cos(o.sun_elevation_rad) * std::cos(o.sun_azimuth_rad),
                         std::cos(o.sun_elevation_rad) * std::sin(o.sun_azimuth_rad),
                         std::sin(o.sun_elevation_rad));
  flat_shading_ = o.ambient + (1.0 - o.ambient) * sun_.z();
}

SyntheticScene::Cell SyntheticScene::cellAt(double x, double y) const {
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

double SyntheticScene::heightInCell(double x, double y, const Cell& cell, double* gx,
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

double SyntheticScene::terrainHeight(double x, double y) const {
  return heightInCell(x, y, cellAt(x, y), nullptr, nullptr);
}

Eigen::Vector2d SyntheticScene::terrainGradient(double x, double y) const {
  double gx = 0.0, gy = 0.0;
  heightInCell(x, y, cellAt(x, y), &gx, &gy);
  return {gx, gy};
}

int SyntheticScene::obstacleIdAt(double x, double y, double time_s) const {
  const auto& o = options_;
  for (size_t i = 0; i < o.boxes.size(); ++i) {
    const BoxObstacle& b = o.boxes[i];
    const Eigen::Vector2d c = b.centerAt(time_s);
    const double cy = std::cos(b.yaw_rad), sy = std::sin(b.yaw_rad);
    const double lx = cy * (x - c.x()) + sy * (y - c.y());
    const double ly = -sy * (x - c.x()) + cy * (y - c.y());
    if (std::abs(lx) <= 0.5 * b.length_m && std::abs(ly) <= 0.5 * b.width_m) {
      return static_cast<int>(i) + 1;
    }
  }
  for (size_t j = 0; j < o.poles.size(); ++j) {
    const PoleObstacle& p = o.poles[j];
    if ((Eigen::Vector2d(x, y) - p.xy).squaredNorm() <= p.radius_m * p.radius_m) {
      return static_cast<int>(o.boxes.size() + j) + 1;
    }
  }
  return 0;
}

double SyntheticScene::surfaceHeight(double x, double y, double time_s) const {
  const int id = obstacleIdAt(x, y, time_s);
  if (id <= 0) return terrainHeight(x, y);
  const auto nb = static_cast<int>(options_.boxes.size());
  if (id <= nb) {
    const BoxObstacle& b = options_.boxes[static_cast<size_t>(id - 1)];
    const Eigen::Vector2d c = b.centerAt(time_s);
    return terrainHeight(c.x(), c.y()) + b.height_m;
  }
  const PoleObstacle& p = options_.poles[static_cast<size_t>(id - nb - 1)];
  return terrainHeight(p.xy.x(), p.xy.y()) + p.height_m;
}

SurfaceHit SyntheticScene::intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                     double t_max, double time_s) const {
  SurfaceHit best = intersectObstacles(o, d, t_max, time_s);
  const SurfaceHit terrain = intersectTerrain(o, d, best.hit() ? best.t : t_max);
  if (terrain.hit() && (!best.hit() || terrain.t < best.t)) best = terrain;
  return best;
}

SurfaceHit SyntheticScene::intersectTerrain(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                            double t_max) const {
  SurfaceHit none;
  const SceneOptions& so = options_;
  double t_lo = 0.0;
  double t_hi = t_max;
  // Clip to the slab z_min_ <= z <= z_max_ that contains all of the terrain.
  if (o.z() > z_max_) {
    if (d.z() >= 0.0) return none;
    t_lo = (o.z() - z_max_) / -d.z();
  } else if (d.z() > 0.0) {
    t_hi = std::min(t_hi, (z_max_ - o.z()) / d.z());
  }
  if (!(t_lo < t_hi)) return none;

  // Breakpoints: where the ray crosses a feature line, with the line's axis (-1: none), sorted.
  constexpr int kMaxBreakpoints = 48;
  double bp_t[kMaxBreakpoints];
  int bp_axis[kMaxBreakpoints];
  int nbp = 0;
  bp_t[nbp] = t_lo;
  bp_axis[nbp++] = -1;
  auto addCrossings = [&](const std::vector<double>& lines, int axis) {
    const double oc = o[axis], dc = d[axis];
    if (dc == 0.0) return;
    const double inv = 1.0 / dc;
    for (double l : lines) {
      const double t = (l - oc) * inv;
      if (t > t_lo && t < t_hi && nbp < kMaxBreakpoints - 1) {
        // Insertion into the sorted list.
        int j = nbp++;
        while (j > 1 && bp_t[j - 1] > t) {
          bp_t[j] = bp_t[j - 1];
          bp_axis[j] = bp_axis[j - 1];
          --j;
        }
        bp_t[j] = t;
        bp_axis[j] = axis;
      }
    }
  };
  addCrossings(x_lines_, 0);
  addCrossings(y_lines_, 1);
  bp_t[nbp] = t_hi;
  bp_axis[nbp++] = -1;

  // Directional bounds of the features along this ray.
  RayBounds rb;
  const double adx = std::abs(d.x()), ady = std::abs(d.y());
  for (const auto& w : waves_) {
    const double kd = std::abs(w.kx * d.x() + w.ky * d.y());
    rb.rolling_slope += w.amp * kd;
    rb.rolling_curv += w.amp * kd * kd;
  }
  if (so.bump_enabled) {
    const double a = kTwoPi / so.bump_length_m;
    const double h = so.bump_height_m;
    rb.bump_slope = 0.5 * h * a * adx;
    rb.bump_curv = 0.5 * h * a * a * adx * adx;
    if (so.bump_end_taper_m > 0.0) {
      const double b = M_PI / so.bump_end_taper_m;
      rb.taper_slope = rb.bump_slope + 0.5 * h * b * ady;
      rb.taper_curv = rb.bump_curv + 2.0 * (0.5 * h * a) * (0.5 * b) * adx * ady +
                      0.5 * h * b * b * ady * ady;
    }
  }
  if (so.ruts_enabled) {
    const double a = kTwoPi / so.rut_width_m;
    rb.rut_slope = 0.5 * so.rut_depth_m * a * ady;
    rb.rut_curv = 0.5 * so.rut_depth_m * a * a * ady * ady;
  }
  if (so.embankment_enabled) rb.emb_slope = embankment_tan_ * ady;

  const double rolling_top = rolling_amp_sum_m_ - rolling_offset_m_;
  for (int i = 0; i + 1 < nbp; ++i) {
    const double a = bp_t[i];
    const double b = bp_t[i + 1];
    if (!(b > a)) continue;
    const double tm = 0.5 * (a + b);
    const Cell cell = cellAt(o.x() + tm * d.x(), o.y() + tm * d.y());
    // Bounds in this cell.
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

    double gx = 0.0, gy = 0.0;
    const double dz = d.z();
    double t = a;
    Eigen::Vector3d p;
    double f;
    const double za = o.z() + a * dz;
    if (za > ztop) {
      // Above everything in this cell: no face on entry; go down to the cell's top bound.
      if (dz >= 0.0) continue;
      t = a + (za - ztop) / -dz;
      if (t >= b) continue;
      p = o + t * d;
      f = p.z() - heightInCell(p.x(), p.y(), cell, &gx, &gy);
    } else {
      p = o + t * d;
      f = p.z() - heightInCell(p.x(), p.y(), cell, &gx, &gy);
      if (bp_axis[i] >= 0 && f < -1e-9) {
        // Below the terrain on entering the cell: the ray hits the vertical face on the line.
        SurfaceHit hit;
        hit.t = t;
        hit.point = p;
        hit.object_id = 0;
        const int axis = bp_axis[i];
        hit.normal = Eigen::Vector3d::Zero();
        hit.normal[axis] = d[axis] > 0.0 ? -1.0 : 1.0;
        hit.surface = axis == 0 ? kTerrainFaceX : kTerrainFaceY;
        return hit;
      }
    }
    // The ray rises at least as fast as the terrain can: no hit in this cell.
    if (f > kTerrainHitEpsM && dz - slope >= 0.0) continue;
    bool hit_found = false;
    for (int it = 0; it < kMaxMarchSteps; ++it) {
      if (f <= kTerrainHitEpsM) {
        hit_found = true;
        break;
      }
      const double fd = dz - (gx * d.x() + gy * d.y());
      // Safe steps: f(t + s) >= f + (dz - slope) s  and  f(t + s) >= f + fd s - curv s^2 / 2.
      const double s1 = slope - dz > 0.0 ? f / (slope - dz) : kInf;
      double s2;
      if (curv > 0.0) {
        s2 = (fd + std::sqrt(fd * fd + 2.0 * curv * f)) / curv;
      } else {
        s2 = fd >= 0.0 ? kInf : f / -fd;
      }
      const double s = std::max(s1, s2);
      if (t + s >= b) break;
      t += s;
      p = o + t * d;
      f = p.z() - heightInCell(p.x(), p.y(), cell, &gx, &gy);
      if (it + 1 == kMaxMarchSteps) hit_found = true;
    }
    if (hit_found) {
      SurfaceHit hit;
      hit.t = t;
      hit.point = p;
      hit.object_id = 0;
      hit.normal = Eigen::Vector3d(-gx, -gy, 1.0).normalized();
      hit.surface = kTerrainTop;
      return hit;
    }
  }
  return none;
}

SurfaceHit SyntheticScene::intersectObstacles(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                              double t_max, double time_s) const {
  SurfaceHit best;
  double t_best = t_max;
  const auto& so = options_;
  // Whether the ray's x-y trace on [0, t_best] passes within `radius` of `c` (cheap rejection
  // before the terrain height under the obstacle is computed).
  const double dxy2 = d.x() * d.x() + d.y() * d.y();
  auto nearTrace = [&](const Eigen::Vector2d& c, double radius) {
    const double cx = c.x() - o.x(), cy = c.y() - o.y();
    double t = dxy2 > 0.0 ? (cx * d.x() + cy * d.y()) / dxy2 : 0.0;
    t = std::clamp(t, 0.0, t_best);
    const double ex = cx - t * d.x(), ey = cy - t * d.y();
    return ex * ex + ey * ey <= radius * radius;
  };
  for (size_t i = 0; i < so.boxes.size(); ++i) {
    const BoxObstacle& bx = so.boxes[i];
    const Eigen::Vector2d c = bx.centerAt(time_s);
    if (!nearTrace(c, 0.5 * std::hypot(bx.length_m, bx.width_m) + 1e-9)) continue;
    const double zb = terrainHeight(c.x(), c.y());
    const double cy = std::cos(bx.yaw_rad), sy = std::sin(bx.yaw_rad);
    const Eigen::Vector3d lo(cy * (o.x() - c.x()) + sy * (o.y() - c.y()),
                             -sy * (o.x() - c.x()) + cy * (o.y() - c.y()), o.z() - zb);
    const Eigen::Vector3d ld(cy * d.x() + sy * d.y(), -sy * d.x() + cy * d.y(), d.z());
    const double lo_b[3] = {-0.5 * bx.length_m, -0.5 * bx.width_m, -kObstacleBuryM};
    const double hi_b[3] = {0.5 * bx.length_m, 0.5 * bx.width_m, bx.height_m};
    double t_near = -kInf, t_far = kInf;
    int near_axis = -1;
    bool near_positive = false;
    bool miss = false;
    for (int a = 0; a < 3 && !miss; ++a) {
      if (ld[a] == 0.0) {
        if (lo[a] < lo_b[a] || lo[a] > hi_b[a]) miss = true;
        continue;
      }
      double t0 = (lo_b[a] - lo[a]) / ld[a];
      double t1 = (hi_b[a] - lo[a]) / ld[a];
      bool pos = false;  // entering through the positive face?
      if (t0 > t1) {
        std::swap(t0, t1);
        pos = true;
      }
      if (t0 > t_near) {
        t_near = t0;
        near_axis = a;
        near_positive = pos;
      }
      t_far = std::min(t_far, t1);
      if (t_near > t_far) miss = true;
    }
    if (miss || near_axis < 0 || !(t_near > 0.0) || !(t_near < t_best)) continue;
    t_best = t_near;
    best.t = t_near;
    best.point = o + t_near * d;
    best.object_id = static_cast<int>(i) + 1;
    best.surface = kBoxFaceBase + near_axis * 2 + (near_positive ? 1 : 0);
    Eigen::Vector3d n_local = Eigen::Vector3d::Zero();
    n_local[near_axis] = near_positive ? 1.0 : -1.0;
    best.normal = Eigen::Vector3d(cy * n_local.x() - sy * n_local.y(),
                                  sy * n_local.x() + cy * n_local.y(), n_local.z());
  }
  for (size_t j = 0; j < so.poles.size(); ++j) {
    const PoleObstacle& pl = so.poles[j];
    if (!nearTrace(pl.xy, pl.radius_m + 1e-9)) continue;
    const double zb = terrainHeight(pl.xy.x(), pl.xy.y());
    const double z0 = zb - kObstacleBuryM, z1 = zb + pl.height_m;
    const double px = o.x() - pl.xy.x(), py = o.y() - pl.xy.y();
    const double r2 = pl.radius_m * pl.radius_m;
    const int id = static_cast<int>(so.boxes.size() + j) + 1;
    if (px * px + py * py <= r2) continue;  // origin inside the pole's footprint: ignore
    const double qa = d.x() * d.x() + d.y() * d.y();
    if (qa > 0.0) {
      const double qb = px * d.x() + py * d.y();
      const double qc = px * px + py * py - r2;
      const double disc = qb * qb - qa * qc;
      if (disc >= 0.0) {
        const double t = (-qb - std::sqrt(disc)) / qa;
        const double z = o.z() + t * d.z();
        if (t > 0.0 && t < t_best && z >= z0 && z <= z1) {
          t_best = t;
          best.t = t;
          best.point = o + t * d;
          best.object_id = id;
          best.surface = kPoleSide;
          best.normal = Eigen::Vector3d(px + t * d.x(), py + t * d.y(), 0.0).normalized();
        }
      }
    }
    if (d.z() < 0.0 && o.z() > z1) {
      const double t = (z1 - o.z()) / d.z();
      const double hx = px + t * d.x(), hy = py + t * d.y();
      if (t > 0.0 && t < t_best && hx * hx + hy * hy <= r2) {
        t_best = t;
        best.t = t;
        best.point = o + t * d;
        best.object_id = id;
        best.surface = kPoleTop;
        best.normal = Eigen::Vector3d::UnitZ();
      }
    }
  }
  return best;
}

// ------------------------------------------------------------------------------------------------
// Appearance

double SyntheticScene::shading(const Eigen::Vector3d& normal) const {
  const double amb = options_.ambient;
  return (amb + (1.0 - amb) * std::max(0.0, normal.dot(sun_))) / flat_shading_;
}

double SyntheticScene::skyAlbedo(const Eigen::Vector3d& d) {
  const double n = d.norm();
  const double e = n > 0.0 ? std::max(0.0, d.z() / n) : 0.0;
  return 226.0 - 70.0 * (1.0 - std::exp(-2.5 * e));
}

double SyntheticScene::albedo(const SurfaceHit& hit, const TextureFilter& filter,
                              double time_s) const {
  if (!hit.hit()) return 0.0;
  const double a = hit.object_id == 0 ? terrainAlbedo(hit, filter)
                                      : obstacleAlbedo(hit, filter, time_s);
  return a * shading(hit.normal);
}

double SyntheticScene::terrainAlbedo(const SurfaceHit& hit, const TextureFilter& filter) const {
  const SceneOptions& o = options_;
  const Eigen::Vector3d& p = hit.point;
  std::array<double, kOctaves> n{};
  if (hit.surface != kTerrainTop) {
    // Vertical face: texture axes (along the face, up).
    const bool on_x_line = hit.surface == kTerrainFaceX;
    const Eigen::Vector3d a1 = on_x_line ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitX();
    const Eigen::Vector3d a2 = Eigen::Vector3d::UnitZ();
    const Footprint fp = footprintOf(filter, a1, a2);
    const double s1 = on_x_line ? p.y() : p.x();
    const int count = bandLimitedOctaves(ground_noise_, s1 + 517.0, p.z() * 1.3 + 211.0, fp, filter, &n);
    const MaterialId m = o.kind == SceneKind::kOffRoad ? kDirt : kConcrete;
    return softClamp(materialAlbedo(m, n, count) - (m == kDirt ? 10.0 : 0.0));
  }
  const Footprint fp = footprintOf(filter, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY());
  const int count = bandLimitedOctaves(ground_noise_, p.x(), p.y(), fp, filter, &n);
  const double fx = fp.extent1, fy = fp.extent2;
  const double x = p.x(), y = p.y();
  // Blend weights of the materials.
  std::array<double, kMaterialCount> w{};
  if (o.kind != SceneKind::kOffRoad) {
    const double yr = y - o.road_center_y_m;
    const double half = 0.5 * o.road_width_m;
    const double rag = 0.03 * wobble(detail_noise_, 3, x, y, fp.major, filter);
    // The sidewalk beyond the curb is concrete, with a sharp border on the curb line.
    const double side = o.curb_enabled ? intervalCoverage(y, -kInf, o.curb_y_m, fy) : 0.0;
    const double asphalt = std::min(1.0 - side, intervalCoverage(yr, -half - rag, half + rag, fy));
    // Gravel shoulder, then grass with a wide, wobbly border.
    const double border =
        half + o.shoulder_width_m + 0.35 * wobble(detail_noise_, 2, x + 100.0, y, fp.major, filter);
    const double grass = smoothstep(border - 0.25, border + 0.25, std::abs(yr));
    const double rest = std::max(0.0, 1.0 - side - asphalt);
    w[kConcrete] = side;
    w[kAsphalt] = asphalt;
    w[kGravel] = rest * (1.0 - grass);
    w[kGrass] = rest * grass;
    // Lane paint: two solid edge lines and the dashed centre line.
    const double e_out = half - o.edge_line_inset_m;
    const double e_in = e_out - o.edge_line_width_m;
    double paint = intervalCoverage(yr, e_in, e_out, fy) + intervalCoverage(yr, -e_out, -e_in, fy);
    const double cw = 0.5 * o.centre_line_width_m;
    const double cy = intervalCoverage(yr, -cw, cw, fy);
    if (cy > 0.0) {
      const double period = o.centre_dash_length_m + o.centre_gap_length_m;
      const double cx = (dashCumulative(x + 0.5 * fx, o.centre_dash_phase_m, o.centre_dash_length_m, period) -
                         dashCumulative(x - 0.5 * fx, o.centre_dash_phase_m, o.centre_dash_length_m, period)) /
                        fx;
      paint += cy * cx;
    }
    if (paint > 0.0) {
      // Worn paint: a little of the asphalt shows through.
      const double wear = 0.85 + 0.1 * wobble(detail_noise_, 5, x, y + 50.0, fp.major, filter);
      const double share = std::min(w[kAsphalt], paint * wear);
      w[kAsphalt] -= share;
      w[kPaint] += share;
    }
  } else {
    // Dirt track along y = 0 with grass beyond; rock and grass on the embankment; grass on the
    // terrace.
    const double border = 2.1 + 0.4 * wobble(detail_noise_, 1, x, y, fp.major, filter);
    const double grass = smoothstep(border - 0.4, border + 0.4, std::abs(y));
    w[kDirt] = 1.0 - grass;
    w[kGrass] = grass;
    if (o.embankment_enabled && y < o.embankment_y_m + 0.3) {
      const double on = smoothstep(o.embankment_y_m + 0.3, o.embankment_y_m - 0.3, y);
      const double rock =
          on * smoothstep(-0.6, 0.6, wobble(detail_noise_, 2, x, y, fp.major, filter) + 0.3);
      w[kDirt] *= 1.0 - rock;
      w[kGrass] *= 1.0 - rock;
      w[kRock] = rock;
    }
  }
  double a = 0.0;
  for (int m = 0; m < kMaterialCount; ++m) {
    if (w[static_cast<size_t>(m)] > 0.0) {
      a += w[static_cast<size_t>(m)] * materialAlbedo(static_cast<MaterialId>(m), n, count);
    }
  }
  if (o.ruts_enabled && o.kind == SceneKind::kOffRoad) {
    // Compacted, darker soil in the ruts.
    for (double c : {o.rut_offset_y_m, -o.rut_offset_y_m}) {
      const double d = std::abs(y - c) / (0.5 * o.rut_width_m);
      if (d < 1.0) a *= 1.0 - 0.12 * 0.5 * (1.0 + std::cos(M_PI * d));
    }
  }
  return softClamp(a);
}

double SyntheticScene::obstacleAlbedo(const SurfaceHit& hit, const TextureFilter& filter,
                                      double time_s) const {
  const auto& so = options_;
  const int id = hit.object_id;
  const auto nb = static_cast<int>(so.boxes.size());
  Eigen::Vector3d a1, a2;
  double s1 = 0.0, s2 = 0.0;
  const Eigen::Vector3d& p = hit.point;
  if (id <= nb) {
    const BoxObstacle& bx = so.boxes[static_cast<size_t>(id - 1)];
    const Eigen::Vector2d c = bx.centerAt(time_s);
    const double cy = std::cos(bx.yaw_rad), sy = std::sin(bx.yaw_rad);
    const Eigen::Vector3d ex(cy, sy, 0.0), ey(-sy, cy, 0.0), ez = Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d rel(p.x() - c.x(), p.y() - c.y(), p.z());
    const int axis = (hit.surface - kBoxFaceBase) / 2;
    if (axis == 0) {
      a1 = ey;
      a2 = ez;
    } else if (axis == 1) {
      a1 = ex;
      a2 = ez;
    } else {
      a1 = ex;
      a2 = ey;
    }
    s1 = a1.dot(rel) + 31.0 * (hit.surface - kBoxFaceBase);
    s2 = a2.dot(rel);
  } else {
    const PoleObstacle& pl = so.poles[static_cast<size_t>(id - nb - 1)];
    const Eigen::Vector3d rel(p.x() - pl.xy.x(), p.y() - pl.xy.y(), p.z());
    if (hit.surface == kPoleSide) {
      a1 = Eigen::Vector3d(-hit.normal.y(), hit.normal.x(), 0.0);
      a2 = Eigen::Vector3d::UnitZ();
      s1 = std::atan2(rel.y(), rel.x()) * pl.radius_m;
      s2 = rel.z();
    } else {
      a1 = Eigen::Vector3d::UnitX();
      a2 = Eigen::Vector3d::UnitY();
      s1 = rel.x() + 40.0;
      s2 = rel.y();
    }
  }
  const Footprint fp = footprintOf(filter, a1, a2);
  std::array<double, kOctaves> n{};
  const double shift = 1000.0 + 97.0 * id;  // a different patch of the noise per object
  const int count = bandLimitedOctaves(ground_noise_, s1 + shift, s2 - shift, fp, filter, &n);
  const uint32_t h = TextureNoise::hash(id, 7, static_cast<uint32_t>(so.seed));
  double a = 70.0 + static_cast<double>(h % 1000U) * 0.1;  // 70..170
  for (int k = 0; k < count; ++k) a += kObstacleAmp[static_cast<size_t>(k)] * n[static_cast<size_t>(k)];
  return softClamp(a);
}

// ------------------------------------------------------------------------------------------------
// YAML

void SyntheticScene::toYaml(const std::string& path) const {
  cv::FileStorage fs(path, cv::FileStorage::WRITE | cv::FileStorage::FORMAT_YAML);
  if (!fs.isOpened()) throw std::runtime_error("scene file '" + path + "': cannot be written");
  const SceneOptions& o = options_;
  fs << "kind" << sceneKindName(o.kind);
  fs << "seed" << std::to_string(o.seed);
  fs << "road_center_y_m" << o.road_center_y_m << "road_width_m" << o.road_width_m
     << "edge_line_width_m" << o.edge_line_width_m << "edge_line_inset_m" << o.edge_line_inset_m
     << "centre_line_width_m" << o.centre_line_width_m << "centre_dash_length_m"
     << o.centre_dash_length_m << "centre_gap_length_m" << o.centre_gap_length_m
     << "centre_dash_phase_m" << o.centre_dash_phase_m << "shoulder_width_m" << o.shoulder_width_m;
  fs << "bump_enabled" << static_cast<int>(o.bump_enabled) << "bump_center_x_m" << o.bump_center_x_m
     << "bump_length_m" << o.bump_length_m << "bump_height_m" << o.bump_height_m << "bump_y_min_m"
     << o.bump_y_min_m << "bump_y_max_m" << o.bump_y_max_m << "bump_end_taper_m"
     << o.bump_end_taper_m;
  fs << "curb_enabled" << static_cast<int>(o.curb_enabled) << "curb_y_m" << o.curb_y_m
     << "curb_height_m" << o.curb_height_m;
  fs << "rolling_enabled" << static_cast<int>(o.rolling_enabled) << "rolling_amplitude_m"
     << o.rolling_amplitude_m << "rolling_min_wavelength_m" << o.rolling_min_wavelength_m
     << "rolling_max_wavelength_m" << o.rolling_max_wavelength_m << "rolling_components"
     << o.rolling_components;
  fs << "ruts_enabled" << static_cast<int>(o.ruts_enabled) << "rut_offset_y_m" << o.rut_offset_y_m
     << "rut_depth_m" << o.rut_depth_m << "rut_width_m" << o.rut_width_m;
  fs << "terrace_enabled" << static_cast<int>(o.terrace_enabled) << "terrace_x_min_m"
     << o.terrace_x_min_m << "terrace_y_min_m" << o.terrace_y_min_m << "terrace_height_m"
     << o.terrace_height_m;
  fs << "embankment_enabled" << static_cast<int>(o.embankment_enabled) << "embankment_y_m"
     << o.embankment_y_m << "embankment_slope_rad" << o.embankment_slope_rad
     << "embankment_height_m" << o.embankment_height_m;
  fs << "sun_elevation_rad" << o.sun_elevation_rad << "sun_azimuth_rad" << o.sun_azimuth_rad
     << "ambient" << o.ambient;
  fs << "boxes" << "[";
  for (const auto& b : o.boxes) {
    fs << "{" << "center_x_m" << b.center_xy.x() << "center_y_m" << b.center_xy.y() << "yaw_rad"
       << b.yaw_rad << "length_m" << b.length_m << "width_m" << b.width_m << "height_m"
       << b.height_m << "velocity_x_m_per_s" << b.velocity_xy.x() << "velocity_y_m_per_s"
       << b.velocity_xy.y() << "}";
  }
  fs << "]";
  fs << "poles" << "[";
  for (const auto& p : o.poles) {
    fs << "{" << "x_m" << p.xy.x() << "y_m" << p.xy.y() << "radius_m" << p.radius_m << "height_m"
       << p.height_m << "}";
  }
  fs << "]";
  // Derived values, for readers that do not rebuild the scene (ignored by fromYaml).
  fs << "rolling_waves" << "[";
  for (const auto& w : waves_) {
    fs << "{" << "kx_rad_per_m" << w.kx << "ky_rad_per_m" << w.ky << "amplitude_m" << w.amp
       << "phase_rad" << w.phase << "}";
  }
  fs << "]";
  fs << "rolling_offset_m" << rolling_offset_m_;
}

SceneOptions SyntheticScene::optionsFromYaml(const std::string& path) {
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::READ | cv::FileStorage::FORMAT_YAML);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("scene file '" + path + "': cannot be parsed");
  }
  if (!fs.isOpened()) throw std::runtime_error("scene file '" + path + "': cannot be opened");
  SceneOptions o;
  auto fail = [&path](const std::string& why) {
    throw std::runtime_error("scene file '" + path + "': " + why);
  };
  const auto need = [&](const char* key) {
    const cv::FileNode n = fs[key];
    if (n.empty()) fail(std::string("missing key '") + key + "'");
    return n;
  };
  auto num = [&](const char* key, double* v) {
    const cv::FileNode n = need(key);
    if (!n.isReal() && !n.isInt()) fail(std::string("'") + key + "' is not a number");
    *v = static_cast<double>(n);
  };
  auto flag = [&](const char* key, bool* v) {
    const cv::FileNode n = need(key);
    if (!n.isInt()) fail(std::string("'") + key + "' is not 0 or 1");
    *v = static_cast<int>(n) != 0;
  };
  const std::string kind = static_cast<std::string>(need("kind"));
  if (!sceneKindFromName(kind, &o.kind)) fail("unknown kind '" + kind + "'");
  const cv::FileNode seed = need("seed");
  o.seed = seed.isString() ? parseSeed(static_cast<std::string>(seed), path)
                           : static_cast<uint64_t>(static_cast<int>(seed));
  num("road_center_y_m", &o.road_center_y_m);
  num("road_width_m", &o.road_width_m);
  num("edge_line_width_m", &o.edge_line_width_m);
  num("edge_line_inset_m", &o.edge_line_inset_m);
  num("centre_line_width_m", &o.centre_line_width_m);
  num("centre_dash_length_m", &o.centre_dash_length_m);
  num("centre_gap_length_m", &o.centre_gap_length_m);
  num("centre_dash_phase_m", &o.centre_dash_phase_m);
  num("shoulder_width_m", &o.shoulder_width_m);
  flag("bump_enabled", &o.bump_enabled);
  num("bump_center_x_m", &o.bump_center_x_m);
  num("bump_length_m", &o.bump_length_m);
  num("bump_height_m", &o.bump_height_m);
  num("bump_y_min_m", &o.bump_y_min_m);
  num("bump_y_max_m", &o.bump_y_max_m);
  num("bump_end_taper_m", &o.bump_end_taper_m);
  flag("curb_enabled", &o.curb_enabled);
  num("curb_y_m", &o.curb_y_m);
  num("curb_height_m", &o.curb_height_m);
  flag("rolling_enabled", &o.rolling_enabled);
  num("rolling_amplitude_m", &o.rolling_amplitude_m);
  num("rolling_min_wavelength_m", &o.rolling_min_wavelength_m);
  num("rolling_max_wavelength_m", &o.rolling_max_wavelength_m);
  {
    const cv::FileNode n = need("rolling_components");
    if (!n.isInt()) fail("'rolling_components' is not an integer");
    o.rolling_components = static_cast<int>(n);
  }
  flag("ruts_enabled", &o.ruts_enabled);
  num("rut_offset_y_m", &o.rut_offset_y_m);
  num("rut_depth_m", &o.rut_depth_m);
  num("rut_width_m", &o.rut_width_m);
  flag("terrace_enabled", &o.terrace_enabled);
  num("terrace_x_min_m", &o.terrace_x_min_m);
  num("terrace_y_min_m", &o.terrace_y_min_m);
  num("terrace_height_m", &o.terrace_height_m);
  flag("embankment_enabled", &o.embankment_enabled);
  num("embankment_y_m", &o.embankment_y_m);
  num("embankment_slope_rad", &o.embankment_slope_rad);
  num("embankment_height_m", &o.embankment_height_m);
  num("sun_elevation_rad", &o.sun_elevation_rad);
  num("sun_azimuth_rad", &o.sun_azimuth_rad);
  num("ambient", &o.ambient);
  auto field = [&](const cv::FileNode& node, const char* key, const char* what) {
    const cv::FileNode n = node[key];
    if (n.empty() || (!n.isReal() && !n.isInt())) {
      fail(std::string(what) + " entry lacks the number '" + key + "'");
    }
    return static_cast<double>(n);
  };
  const cv::FileNode boxes = fs["boxes"];
  if (!boxes.empty() && !boxes.isSeq()) fail("'boxes' is not a list");
  for (const auto& n : boxes) {
    BoxObstacle b;
    b.center_xy = {field(n, "center_x_m", "box"), field(n, "center_y_m", "box")};
    b.yaw_rad = field(n, "yaw_rad", "box");
    b.length_m = field(n, "length_m", "box");
    b.width_m = field(n, "width_m", "box");
    b.height_m = field(n, "height_m", "box");
    b.velocity_xy = {field(n, "velocity_x_m_per_s", "box"), field(n, "velocity_y_m_per_s", "box")};
    o.boxes.push_back(b);
  }
  const cv::FileNode poles = fs["poles"];
  if (!poles.empty() && !poles.isSeq()) fail("'poles' is not a list");
  for (const auto& n : poles) {
    PoleObstacle p;
    p.xy = {field(n, "x_m", "pole"), field(n, "y_m", "pole")};
    p.radius_m = field(n, "radius_m", "pole");
    p.height_m = field(n, "height_m", "pole");
    o.poles.push_back(p);
  }
  std::string why;
  if (!o.isValid(&why)) fail(why);
  return o;
}

SyntheticScene SyntheticScene::fromYaml(const std::string& path) {
  return SyntheticScene(optionsFromYaml(path));
}

}  // namespace stereo_ground_dem::sim
