#pragma once
/// \file TextureNoise.hpp
/// Seeded, non-periodic 2-D gradient noise in octaves, the raw material of every synthetic texture.
///
/// Octave k has lattice spacing ("wavelength") coarsest_wavelength_m / 2^k. Each octave has its own
/// seed, rotation and offset so that no lattice direction or period shows. Values come from an
/// integer hash of the lattice corner: no tables, no period (the lattice index is a 32-bit integer,
/// so the pattern would only repeat after 2^32 wavelengths).
///
/// Band limiting: a renderer samples a texture at a finite footprint F (the size of a pixel on the
/// surface). Octaves with a wavelength below about F alias; bandWeight() gives the smooth factor
/// with which an octave is kept (1 well above the footprint, 0 below it).

#include <array>
#include <cstddef>
#include <cstdint>

namespace stereo_ground_dem::sim {

class TextureNoise {
 public:
  static constexpr int kMaxOctaves = 12;

  TextureNoise() : TextureNoise(1, 16.0, 11) {}
  /// `octaves` octaves (at most kMaxOctaves) from `coarsest_wavelength_m` down by factors of two.
  TextureNoise(uint64_t seed, double coarsest_wavelength_m, int octaves);

  int octaves() const { return octaves_; }
  double wavelength(int k) const { return wavelength_[static_cast<std::size_t>(k)]; }

  /// Octave k at (x, y) [m]: zero-mean, standard deviation about 1, |value| < 4.
  double octave(int k, double x, double y) const;

  /// Unit-lattice gradient noise (Perlin's construction with hashed gradient directions and the
  /// quintic fade), scaled to a standard deviation of about 1.
  static double gradientNoise(double x, double y, uint32_t seed);

  /// The weight of an octave of wavelength `wavelength_m` seen with footprint `footprint_m`:
  /// smoothstep of wavelength / footprint from `fade_start` (weight 0) to `fade_end` (weight 1).
  static double bandWeight(double wavelength_m, double footprint_m, double fade_start,
                           double fade_end) {
    if (!(footprint_m > 0.0)) return 1.0;
    const double r = wavelength_m / footprint_m;
    if (r <= fade_start) return 0.0;
    if (r >= fade_end) return 1.0;
    const double t = (r - fade_start) / (fade_end - fade_start);
    return t * t * (3.0 - 2.0 * t);
  }

  /// A well-mixed 32-bit hash of a lattice point and a seed.
  static uint32_t hash(int32_t ix, int32_t iy, uint32_t seed);
  /// A 64-bit mix (splitmix64 finalizer), used to derive seeds.
  static uint64_t mix64(uint64_t x);

 private:
  int octaves_ = 0;
  std::array<double, kMaxOctaves> wavelength_{};
  std::array<double, kMaxOctaves> inv_wavelength_{};
  std::array<double, kMaxOctaves> cos_{};
  std::array<double, kMaxOctaves> sin_{};
  std::array<double, kMaxOctaves> offset_x_{};
  std::array<double, kMaxOctaves> offset_y_{};
  std::array<uint32_t, kMaxOctaves> seed_{};
};

}  // namespace stereo_ground_dem::sim
