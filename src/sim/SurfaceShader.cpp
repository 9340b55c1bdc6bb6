#include "stereo_ground_dem/sim/SurfaceShader.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

namespace stereo_ground_dem::sim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

constexpr int kTerrainTop = SurfaceHit::kTerrainTop;
constexpr int kTerrainFaceX = SurfaceHit::kTerrainFaceX;
constexpr int kBoxFaceBase = SurfaceHit::kBoxFaceBase;
constexpr int kPoleSide = SurfaceHit::kPoleSide;

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

// `amp`: the material's octave amplitudes (kMaterials' scaled by the texture contrast).
double materialAlbedo(MaterialId m, const double* amp, const std::array<double, kOctaves>& n,
                      int count) {
  double a = kMaterials[m].mean;
  for (int k = 0; k < count; ++k) a += amp[k] * n[static_cast<size_t>(k)];
  return a;
}

// One band-limited noise value of wavelength `wavelength_m` (for wobbly borders).
double wobble(const TextureNoise& noise, int octave, double x, double y, double footprint,
              const TextureFilter& f) {
  const double w = TextureNoise::bandWeight(noise.wavelength(octave), footprint, f.octave_fade_start,
                                            f.octave_fade_end);
  return w > 0.0 ? w * noise.octave(octave, x, y) : 0.0;
}

}  // namespace

SurfaceShader::SurfaceShader(const SceneOptions& options, std::shared_ptr<const RayCaster> caster)
    : options_(options),
      path_(options.road_path),
      caster_(std::move(caster)),
      ground_noise_(options.seed, kCoarsestWavelengthM, kOctaves),
      detail_noise_(TextureNoise::mix64(options.seed ^ 0xD1B54A32D192ED03ULL), 8.0, 6) {
  const SceneOptions& o = options_;
  for (const Material& m : kMaterials) {
    for (double a : m.amp) material_amp_.push_back(o.texture_contrast * a);
  }
  sun_ = Eigen::Vector3d(std::cos(o.sun_elevation_rad) * std::cos(o.sun_azimuth_rad),
                         std::cos(o.sun_elevation_rad) * std::sin(o.sun_azimuth_rad),
                         std::sin(o.sun_elevation_rad));
  flat_shading_ = o.ambient + (1.0 - o.ambient) * sun_.z();
  shadow_shading_ = o.ambient / flat_shading_;
}

const double* SurfaceShader::amp(int material) const {
  return material_amp_.data() + static_cast<size_t>(material) * kOctaves;
}

bool SurfaceShader::inShadow(const Eigen::Vector3d& p, double time_s) const {
  return caster_ && caster_->blockedUpwards(p, sun_, time_s);
}

double SurfaceShader::shading(const Eigen::Vector3d& normal) const {
  const double amb = options_.ambient;
  return (amb + (1.0 - amb) * std::max(0.0, normal.dot(sun_))) / flat_shading_;
}

double SurfaceShader::skyAlbedo(const Eigen::Vector3d& d) {
  const double n = d.norm();
  const double e = n > 0.0 ? std::max(0.0, d.z() / n) : 0.0;
  return 226.0 - 70.0 * (1.0 - std::exp(-2.5 * e));
}

double SurfaceShader::albedo(const SurfaceHit& hit, const TextureFilter& filter,
                              double time_s) const {
  if (!hit.hit()) return 0.0;
  const double a = hit.object_id == 0 ? terrainAlbedo(hit, filter)
                                      : obstacleAlbedo(hit, filter, time_s);
  if (options_.cast_shadows && hit.object_id == 0 && inShadow(hit.point, time_s)) {
    return a * shadow_shading_;
  }
  return a * shading(hit.normal);
}

double SurfaceShader::terrainAlbedo(const SurfaceHit& hit, const TextureFilter& filter) const {
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
    const MaterialId m = o.offRoad() ? kDirt : kConcrete;
    return softClamp(materialAlbedo(m, amp(m), n, count) - (m == kDirt ? 10.0 : 0.0));
  }
  const Footprint fp = footprintOf(filter, Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY());
  const int count = bandLimitedOctaves(ground_noise_, p.x(), p.y(), fp, filter, &n);
  const double fx = fp.extent1, fy = fp.extent2;
  const double x = p.x(), y = p.y();
  // Blend weights of the materials.
  std::array<double, kMaterialCount> w{};
  if (!o.offRoad()) {
    // Road coordinates: distance along the road and signed offset from its axis, with the box
    // filter's extents along them.
    double s = x, yr = y - o.road_center_y_m, fs = fx, fn = fy;
    if (!path_.empty()) {
      const RoadPath::Coordinates rc = path_.coordinates(x, y);
      const double ch = std::cos(rc.heading_rad), sh = std::sin(rc.heading_rad);
      const Footprint fpr = footprintOf(filter, Eigen::Vector3d(ch, sh, 0.0), Eigen::Vector3d(-sh, ch, 0.0));
      s = rc.s_m;
      yr = rc.n_m;
      fs = fpr.extent1 / std::max(0.05, 1.0 - rc.curvature_per_m * rc.n_m);  // arc length at offset n
      fn = fpr.extent2;
    }
    const double half = 0.5 * o.road_width_m;
    // The gore and the carriageway beyond it widen the asphalt on the left.
    double gore = 0.0, far_edge = half;
    if (o.gore_enabled) {
      const double u = std::clamp((s - o.gore_start_s_m) / (o.gore_end_s_m - o.gore_start_s_m), 0.0, 1.0);
      gore = o.gore_start_width_m + u * (o.gore_end_width_m - o.gore_start_width_m);
      far_edge = half + gore + o.gore_lane_width_m;
    }
    const double rag = 0.03 * wobble(detail_noise_, 3, x, y, fp.major, filter);
    // The sidewalk beyond the curb is concrete, with a sharp border on the curb line.
    const double side = o.curb_enabled ? intervalCoverage(y, -kInf, o.curb_y_m, fy) : 0.0;
    const double asphalt = std::min(1.0 - side, intervalCoverage(yr, -half - rag, far_edge + rag, fn));
    // Gravel shoulder, then grass with a wide, wobbly border.
    const double border =
        half + o.shoulder_width_m + 0.35 * wobble(detail_noise_, 2, x + 100.0, y, fp.major, filter);
    const double beyond = o.gore_enabled && yr > 0.0 ? yr - (far_edge - half) : std::abs(yr);
    const double grass = smoothstep(border - 0.25, border + 0.25, beyond);
    const double rest = std::max(0.0, 1.0 - side - asphalt);
    w[kConcrete] = side;
    w[kAsphalt] = asphalt;
    w[kGravel] = rest * (1.0 - grass);
    w[kGrass] = rest * grass;
    // Lane paint: two solid edge lines and the dashed centre line.
    const double e_out = half - o.edge_line_inset_m;
    const double e_in = e_out - o.edge_line_width_m;
    double paint = intervalCoverage(yr, e_in, e_out, fn) + intervalCoverage(yr, -e_out, -e_in, fn);
    const double cw = 0.5 * o.centre_line_width_m;
    const double period = o.centre_dash_length_m + o.centre_gap_length_m;
    auto dashes = [&](double centre) {
      const double cy = intervalCoverage(yr, centre - cw, centre + cw, fn);
      if (cy <= 0.0) return 0.0;
      const double cx = (dashCumulative(s + 0.5 * fs, o.centre_dash_phase_m, o.centre_dash_length_m, period) -
                         dashCumulative(s - 0.5 * fs, o.centre_dash_phase_m, o.centre_dash_length_m, period)) /
                        fs;
      return cy * cx;
    };
    if (o.centre_line_enabled) paint += dashes(0.0);
    if (o.gore_enabled) {
      // The far carriageway's edge lines (the near one borders the gore) and lane line, and the
      // hatching of the gore (under the solid lines that border it): stripes at 45 degrees.
      const double near_in = half + gore + o.edge_line_inset_m;
      paint += intervalCoverage(yr, near_in, near_in + o.edge_line_width_m, fn);
      paint += intervalCoverage(yr, far_edge - o.edge_line_inset_m - o.edge_line_width_m,
                                far_edge - o.edge_line_inset_m, fn);
      paint += dashes(half + gore + 0.5 * o.gore_lane_width_m);
      const double across = gore > 0.0 ? intervalCoverage(yr, half, half + gore, fn) : 0.0;
      if (across > 0.0) {
        const double q = s - yr, fq = fs + fn;
        const double along = (dashCumulative(q + 0.5 * fq, 0.0, o.hatch_width_m, o.hatch_period_m) -
                              dashCumulative(q - 0.5 * fq, 0.0, o.hatch_width_m, o.hatch_period_m)) /
                             fq;
        paint += across * along;
      }
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
      a += w[static_cast<size_t>(m)] * materialAlbedo(static_cast<MaterialId>(m), amp(m), n, count);
    }
  }
  if (o.ruts_enabled && o.offRoad()) {
    // Compacted, darker soil in the ruts.
    for (double c : {o.rut_offset_y_m, -o.rut_offset_y_m}) {
      const double d = std::abs(y - c) / (0.5 * o.rut_width_m);
      if (d < 1.0) a *= 1.0 - 0.12 * 0.5 * (1.0 + std::cos(M_PI * d));
    }
  }
  return softClamp(a);
}

double SurfaceShader::obstacleAlbedo(const SurfaceHit& hit, const TextureFilter& filter,
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

}  // namespace stereo_ground_dem::sim
