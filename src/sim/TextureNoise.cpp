#include "stereo_ground_dem/sim/TextureNoise.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace stereo_ground_dem::sim {

namespace {

inline uint32_t mix32(uint32_t h) {
  h ^= h >> 16;
  h *= 0x7feb352dU;
  h ^= h >> 15;
  h *= 0x846ca68bU;
  h ^= h >> 16;
  return h;
}

// 16 unit gradient directions.
struct GradientTable {
  double gx[16];
  double gy[16];
  GradientTable() {
    for (int i = 0; i < 16; ++i) {
      const double a = (i + 0.5) * (2.0 * M_PI / 16.0);
      gx[i] = std::cos(a);
      gy[i] = std::sin(a);
    }
  }
};
const GradientTable kGradients;

// Empirical standard deviation of the raw 2-D gradient noise with unit gradients (measured over
// 10^6 samples: 0.2182); dividing by it gives unit standard deviation.
constexpr double kNoiseScale = 1.0 / 0.2182;

inline double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

}  // namespace

uint32_t TextureNoise::hash(int32_t ix, int32_t iy, uint32_t seed) {
  return mix32(static_cast<uint32_t>(ix) * 0x9E3779B1U ^
               mix32(static_cast<uint32_t>(iy) * 0x85EBCA77U + seed));
}

uint64_t TextureNoise::mix64(uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

double TextureNoise::gradientNoise(double x, double y, uint32_t seed) {
  // floor() without the libm call (|x|, |y| < 2^31 here: coordinates are metres / wavelength).
  auto ifloor = [](double a) {
    const auto i = static_cast<int32_t>(a);
    return a < static_cast<double>(i) ? i - 1 : i;
  };
  const int32_t ix = ifloor(x);
  const int32_t iy = ifloor(y);
  const double rx = x - static_cast<double>(ix);
  const double ry = y - static_cast<double>(iy);
  const uint32_t row0 = mix32(static_cast<uint32_t>(iy) * 0x85EBCA77U + seed);
  const uint32_t row1 = mix32(static_cast<uint32_t>(iy + 1) * 0x85EBCA77U + seed);
  const uint32_t h00 = mix32(static_cast<uint32_t>(ix) * 0x9E3779B1U ^ row0) & 15U;
  const uint32_t h10 = mix32(static_cast<uint32_t>(ix + 1) * 0x9E3779B1U ^ row0) & 15U;
  const uint32_t h01 = mix32(static_cast<uint32_t>(ix) * 0x9E3779B1U ^ row1) & 15U;
  const uint32_t h11 = mix32(static_cast<uint32_t>(ix + 1) * 0x9E3779B1U ^ row1) & 15U;
  const double n00 = kGradients.gx[h00] * rx + kGradients.gy[h00] * ry;
  const double n10 = kGradients.gx[h10] * (rx - 1.0) + kGradients.gy[h10] * ry;
  const double n01 = kGradients.gx[h01] * rx + kGradients.gy[h01] * (ry - 1.0);
  const double n11 = kGradients.gx[h11] * (rx - 1.0) + kGradients.gy[h11] * (ry - 1.0);
  const double u = fade(rx);
  const double v = fade(ry);
  const double a = n00 + u * (n10 - n00);
  const double b = n01 + u * (n11 - n01);
  return (a + v * (b - a)) * kNoiseScale;
}

TextureNoise::TextureNoise(uint64_t seed, double coarsest_wavelength_m, int octaves) {
  if (octaves < 1 || octaves > kMaxOctaves || !(coarsest_wavelength_m > 0.0)) {
    throw std::invalid_argument("TextureNoise: octaves must be 1..12 and the wavelength positive");
  }
  octaves_ = octaves;
  uint64_t s = mix64(seed ^ 0x5DEECE66DULL);
  for (int k = 0; k < octaves; ++k) {
    const auto i = static_cast<size_t>(k);
    wavelength_[i] = std::ldexp(coarsest_wavelength_m, -k);
    inv_wavelength_[i] = 1.0 / wavelength_[i];
    s = mix64(s);
    // An irrational-looking rotation per octave, plus an offset of up to 1000 lattice cells.
    const double angle = static_cast<double>(s & 0xFFFFFFU) / 16777216.0 * 2.0 * M_PI;
    cos_[i] = std::cos(angle);
    sin_[i] = std::sin(angle);
    s = mix64(s);
    offset_x_[i] = static_cast<double>(s & 0xFFFFFU) / 1048576.0 * 1000.0;
    offset_y_[i] = static_cast<double>((s >> 20) & 0xFFFFFU) / 1048576.0 * 1000.0;
    seed_[i] = static_cast<uint32_t>(s >> 40);
  }
}

double TextureNoise::octave(int k, double x, double y) const {
  const auto i = static_cast<size_t>(k);
  const double xs = (cos_[i] * x - sin_[i] * y) * inv_wavelength_[i] + offset_x_[i];
  const double ys = (sin_[i] * x + cos_[i] * y) * inv_wavelength_[i] + offset_y_[i];
  return gradientNoise(xs, ys, seed_[i]);
}

}  // namespace stereo_ground_dem::sim
