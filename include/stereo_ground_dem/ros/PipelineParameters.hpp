#pragma once
/// \file PipelineParameters.hpp
/// ROS parameters -> PipelineOptions, through the core's ParameterTable (the same flat names as the
/// YAML files of the offline runner, e.g. config/kitti.yaml):
///  - every ParameterTable entry is read as a private parameter; an absent one keeps the struct's
///    default; a present one must be a number (or a boolean), integral for int entries, and any
///    problem is reported with the parameter's name instead of silently falling back;
///  - load() also validates once with PipelineOptions::isValid and throws with the reason, so the
///    node refuses to start on invalid values;
///  - unknown() lists private parameters that neither the table nor the ROS layer knows (typos).
/// fromConfig()/toConfig() copy between PipelineOptions and a dynamic_reconfigure Config by name,
/// so the tunable subset (cfg/DemParameters.cfg) needs no hand-written field list.

#include <dynamic_reconfigure/Config.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <boost/any.hpp>
#include <functional>
#include <string>
#include <vector>

#include "stereo_ground_dem/ParameterTable.hpp"

namespace stereo_ground_dem {

class PipelineParameters {
 public:
  /// Returns false if the parameter is not set, else fills `value`.
  using Lookup = std::function<bool(const std::string& name, XmlRpc::XmlRpcValue* value)>;

  /// Reads every entry `lookup` finds into `options`; returns the problems (empty if none).
  static std::vector<std::string> read(const Lookup& lookup, PipelineOptions* options);
  /// read() from the defaults, then PipelineOptions::isValid; throws std::invalid_argument with
  /// every problem (parameter names and the validation reason).
  static PipelineOptions load(const Lookup& lookup);
  /// Names in `present` that are neither ParameterTable entries nor in `ros_names`.
  static std::vector<std::string> unknown(const std::vector<std::string>& present,
                                          const std::vector<std::string>& ros_names);
  /// int, double or boolean XmlRpc value as a double; false for anything else.
  static bool toNumber(const XmlRpc::XmlRpcValue& value, double* out);

  /// Sets every parameter of `config` in `options` by name; returns the names the table lacks.
  template <class Config>
  static std::vector<std::string> fromConfig(const Config& config, PipelineOptions* options) {
    ParameterTable table(options);
    std::vector<std::string> missing;
    for (const auto& d : Config::__getParamDescriptions__()) {
      boost::any v;
      d->getValue(config, v);
      double x = 0.0;
      if (d->type == "double") x = boost::any_cast<double>(v);
      else if (d->type == "int") x = boost::any_cast<int>(v);
      else if (d->type == "bool") x = boost::any_cast<bool>(v) ? 1.0 : 0.0;
      if ((d->type != "double" && d->type != "int" && d->type != "bool") || !table.set(d->name, x)) {
        missing.push_back(d->name);
      }
    }
    return missing;
  }

  /// Sets every parameter of `config` from `options` (by name); unknown names are left alone.
  template <class Config>
  static void toConfig(const PipelineOptions& options, Config* config) {
    PipelineOptions copy = options;
    const ParameterTable table(&copy);
    dynamic_reconfigure::Config msg;
    for (const auto& d : Config::__getParamDescriptions__()) {
      const ParameterTable::Entry* e = table.find(d->name);
      if (!e) continue;
      const double x = table.get(*e);
      if (d->type == "double") {
        dynamic_reconfigure::DoubleParameter p;
        p.name = d->name;
        p.value = x;
        msg.doubles.push_back(p);
      } else if (d->type == "int") {
        dynamic_reconfigure::IntParameter p;
        p.name = d->name;
        p.value = static_cast<int>(x);
        msg.ints.push_back(p);
      } else if (d->type == "bool") {
        dynamic_reconfigure::BoolParameter p;
        p.name = d->name;
        p.value = x != 0.0;
        msg.bools.push_back(p);
      }
    }
    config->__fromMessage__(msg);
  }
};

}  // namespace stereo_ground_dem
