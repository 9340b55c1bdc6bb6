#pragma once
/// \file ParameterTable.hpp
/// One list of every user-facing parameter with its name, unit-bearing description and the field
/// it sets, so that the offline runner (YAML files) and the ROS node (private parameters, dynamic
/// reconfigure) read exactly the same names into the same option structs. Names are flat and
/// unique (`smoothness_weight`, `max_range_m`).

#include <string>
#include <vector>

#include "stereo_ground_dem/GreyConverter.hpp"
#include "stereo_ground_dem/GroundAttitudeEstimator.hpp"
#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/OrthoTexture.hpp"
#include "stereo_ground_dem/PhotometricResidualMap.hpp"
#include "stereo_ground_dem/TraversabilityFilter.hpp"

namespace stereo_ground_dem {

/// Everything a run of the product is configured by.
struct PipelineOptions {
  IncrementalEstimatorOptions estimator;
  TraversabilityOptions traversability = TraversabilityOptions::forCar();
  GreyConverterOptions input;  ///< image input: bit depth of 16-bit images, size limits
  OrthoTextureOptions ortho;   ///< the ortho-texture layer (its keep radius follows map_keep_radius_m)
  PhotometricResidualOptions residual;  ///< the photometric-residual layers (keep radius: the map's)
  GroundAttitudeOptions attitude;       ///< the camera above the local ground, and the mount check

  bool isValid(std::string* why) const;
};

class ParameterTable {
 public:
  enum class Type { kDouble, kInt, kBool };
  struct Entry {
    std::string name;
    Type type;
    void* field;
    std::string description;
    bool tunable;  ///< safe to change while running (dynamic reconfigure)
  };

  /// The entries pointing into `options` (which must outlive the table).
  explicit ParameterTable(PipelineOptions* options);

  const std::vector<Entry>& entries() const { return entries_; }
  const Entry* find(const std::string& name) const;

  /// Sets a parameter from a number. Returns false for an unknown name, a non-finite value, a
  /// non-integral or out-of-int-range value for an int, and anything but 0 or 1 for a bool.
  bool set(const std::string& name, double value) const;
  /// "" when set(name, value) would succeed, else the one-line reason (naming the parameter and
  /// the value).
  std::string whyNotSettable(const std::string& name, double value) const;
  double get(const Entry& e) const;

  /// Reads a YAML file of `name: value` pairs (a `stereo_ground_dem:` or `dem_nodelet:`
  /// top-level map is looked into as well). Throws std::runtime_error, one line with the file and
  /// the name, for: an unreadable file or malformed YAML, an unknown name (so typos do not pass
  /// silently), a value that is not a number (maps, lists, text, `true`/`false` for a number),
  /// NaN or Inf, a non-integral or out-of-range integer, and a boolean that is not true/false/0/1.
  /// Value ranges are PipelineOptions::isValid()'s job (call it after loading).
  void loadYaml(const std::string& path) const;

  /// The defaults, then `path`'s values (none when empty), validated once (PipelineOptions::
  /// isValid): what the tools run with. Throws std::runtime_error (loadYaml's errors, or "invalid
  /// parameters: " and the reason).
  static PipelineOptions load(const std::string& path);

 private:
  std::vector<Entry> entries_;
};

}  // namespace stereo_ground_dem
