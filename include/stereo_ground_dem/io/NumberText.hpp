#pragma once
/// \file NumberText.hpp
/// Numbers as text for the plain-text writers and readers of this directory (YAML, PLY, KITTI and
/// TUM trajectories): the shortest decimal form that reads back to the same double, and a strict
/// parser that accepts a whole token only.

#include <string>

namespace stereo_ground_dem {

class NumberText {
 public:
  /// Shortest round-trip decimal form ("0.25", "1e-07", "-3"); NaN and infinities as "nan",
  /// "inf", "-inf" (use yaml() for YAML files).
  static std::string shortest(double value);
  /// The shortest form that reads back to the same float ("0.1" for 0.1f).
  static std::string shortestFloat(float value);
  /// As shortest(), but NaN and infinities in YAML's spelling (".nan", ".inf", "-.inf").
  static std::string yaml(double value);
  /// Parses the whole of `token` as a double (also "nan", "inf", YAML's ".nan", ".inf", "-.inf");
  /// false if anything is left over or the token is empty.
  static bool parse(const std::string& token, double* value);
};

}  // namespace stereo_ground_dem
