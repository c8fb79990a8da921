#pragma once
// Helpers of the parameter-table tests (tests/core, tests/viewer).
#include <string>

#include "hpcm/param_table.hpp"

namespace hpcm::test {

/// The message of check_param_ranges(p), or "" when it passes.
inline std::string range_error(const Params& p) {
  try {
    check_param_ranges(p);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

/// Sets every number the entry holds (every class, every control point) to v.
inline void set_all(const ParamSpec& s, Params& p, double v) {
  switch (s.type) {
    case ParamType::Real: s.real(p) = static_cast<float>(v); break;
    case ParamType::Integer: s.integer(p) = static_cast<int>(v); break;
    case ParamType::PerClass: s.per_class(p).fill(static_cast<float>(v)); break;
    case ParamType::PointField:
      for (auto& pt : p.material.points) pt.*s.point_field = static_cast<float>(v);
      break;
    default: break;
  }
}

}  // namespace hpcm::test
