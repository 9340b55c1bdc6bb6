#include "stereo_ground_dem/ros/PipelineParameters.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace stereo_ground_dem {

bool PipelineParameters::toNumber(const XmlRpc::XmlRpcValue& value, double* out) {
  XmlRpc::XmlRpcValue v = value;  // the accessors are non-const
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeInt: *out = static_cast<int>(v); return true;
    case XmlRpc::XmlRpcValue::TypeDouble: *out = static_cast<double>(v); return true;
    case XmlRpc::XmlRpcValue::TypeBoolean: *out = static_cast<bool>(v) ? 1.0 : 0.0; return true;
    default: return false;
  }
}

std::vector<std::string> PipelineParameters::read(const Lookup& lookup, PipelineOptions* options) {
  const ParameterTable table(options);
  std::vector<std::string> problems;
  for (const ParameterTable::Entry& e : table.entries()) {
    XmlRpc::XmlRpcValue v;
    if (!lookup(e.name, &v)) continue;
    double x = 0.0;
    if (!toNumber(v, &x)) {
      problems.push_back("~" + e.name + " must be a number, got '" + v.toXml() + "'");
      continue;
    }
    const bool is_bool = v.getType() == XmlRpc::XmlRpcValue::TypeBoolean;
    if (e.type == ParameterTable::Type::kBool && !is_bool && v.getType() != XmlRpc::XmlRpcValue::TypeInt) {
      problems.push_back("~" + e.name + " must be true or false");
      continue;
    }
    if (e.type != ParameterTable::Type::kBool && is_bool) {
      problems.push_back("~" + e.name + " must be a number, got a boolean");
      continue;
    }
    if (!std::isfinite(x) || !table.set(e.name, x)) {
      std::ostringstream os;
      os << "~" << e.name << " = " << x << " is not valid for this parameter"
         << (e.type == ParameterTable::Type::kInt ? " (an integer)" : "");
      problems.push_back(os.str());
    }
  }
  return problems;
}

PipelineOptions PipelineParameters::load(const Lookup& lookup) {
  PipelineOptions o;
  std::vector<std::string> problems = read(lookup, &o);
  std::string why;
  if (problems.empty() && !o.isValid(&why)) problems.push_back("invalid parameters: " + why);
  if (!problems.empty()) {
    std::ostringstream os;
    for (size_t i = 0; i < problems.size(); ++i) os << (i ? "; " : "") << problems[i];
    throw std::invalid_argument(os.str());
  }
  return o;
}

std::vector<std::string> PipelineParameters::unknown(const std::vector<std::string>& present,
                                                     const std::vector<std::string>& ros_names) {
  PipelineOptions o;
  const ParameterTable table(&o);
  std::vector<std::string> out;
  for (const std::string& n : present) {
    if (table.find(n)) continue;
    if (std::find(ros_names.begin(), ros_names.end(), n) != ros_names.end()) continue;
    out.push_back(n);
  }
  return out;
}

}  // namespace stereo_ground_dem
