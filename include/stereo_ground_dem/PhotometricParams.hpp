#pragma once
/// \file PhotometricParams.hpp
/// Gain and bias between a reference image I0 and another image Ij: I0[u0] = gain * Ij[uj] + bias.

namespace stereo_ground_dem {

struct PhotometricParams {
  double gain = 1.0;       ///< [-]
  double bias_grey = 0.0;  ///< [grey levels, 8-bit units]

  /// The inverse compositional update: the increment (dg, db) is applied on the reference side,
  /// (1 + dg) I0 + db = gain * Ij + bias, so gain <- gain / (1 + dg), bias <- (bias - db) / (1 + dg).
  PhotometricParams composedWithInverse(double dg, double db) const {
    return {gain / (1.0 + dg), (bias_grey - db) / (1.0 + dg)};
  }
};

}  // namespace stereo_ground_dem
