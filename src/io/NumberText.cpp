#include "stereo_ground_dem/io/NumberText.hpp"

#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <system_error>

namespace stereo_ground_dem {

std::string NumberText::shortest(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::array<char, 64> buf{};
  const auto res = std::to_chars(buf.data(), buf.data() + buf.size(), value);
  if (res.ec != std::errc()) return std::to_string(value);  // cannot happen with 64 chars
  return std::string(buf.data(), res.ptr);
}

std::string NumberText::shortestFloat(float value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::array<char, 64> buf{};
  const auto res = std::to_chars(buf.data(), buf.data() + buf.size(), value);
  if (res.ec != std::errc()) return std::to_string(value);
  return std::string(buf.data(), res.ptr);
}

std::string NumberText::yaml(double value) {
  if (std::isnan(value)) return ".nan";
  if (std::isinf(value)) return value > 0 ? ".inf" : "-.inf";
  return shortest(value);
}

bool NumberText::parse(const std::string& token, double* value) {
  if (token.empty()) return false;
  std::string t = token;
  for (char& ch : t) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  if (t == ".nan" || t == "nan") {
    *value = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  if (t == ".inf" || t == "+.inf" || t == "inf" || t == "+inf") {
    *value = std::numeric_limits<double>::infinity();
    return true;
  }
  if (t == "-.inf" || t == "-inf") {
    *value = -std::numeric_limits<double>::infinity();
    return true;
  }
  // strtod (not from_chars) so that a leading '+' is accepted, as written by other tools.
  const char* begin = token.c_str();
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  if (end == begin || *end != '\0') return false;
  *value = v;
  return true;
}

}  // namespace stereo_ground_dem
