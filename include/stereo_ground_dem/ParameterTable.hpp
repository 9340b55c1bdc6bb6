#pragma once
/// \file ParameterTable.hpp
/// One list of every user-facing parameter with its name, unit-bearing description and the field
/// it sets, so that the offline runner (YAML files) and the ROS node (private parameters, dynamic
/// reconfigure) read exactly the same names into the same option structs. Names are flat and
/// unique (`smoothness_weight`, `max_range_m`).

#include <string>
#include <vector>

#include "stereo_ground_dem/IncrementalEstimator.hpp"
#include "stereo_ground_dem/TraversabilityFilter.hpp"

namespace stereo_ground_dem {

/// Everything a run of the product is configured by.
struct PipelineOptions {
  IncrementalEstimatorOptions estimator;
  TraversabilityOptions traversability = TraversabilityOptions::forCar();

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

  /// Sets a parameter from a number (ints are rounded, bools are != 0). Returns false for an
  /// unknown name or a non-integral value for an int.
  bool set(const std::string& name, double value) const;
  double get(const Entry& e) const;

  /// Reads a YAML file of `name: value` pairs (a `stereo_ground_dem:` or `/**: ros__parameters`
  /// top-level map is looked into as well). Unknown names throw std::runtime_error with the file
  /// and the name, so typos do not pass silently; so do values that are not numbers or booleans.
  void loadYaml(const std::string& path) const;

 private:
  std::vector<Entry> entries_;
};

}  // namespace stereo_ground_dem
