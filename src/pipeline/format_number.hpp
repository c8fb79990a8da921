#pragma once
// Numbers in messages and check reasons: the shortest "%g" form (or another printf float format,
// e.g. "%.3g"), one definition for the pipeline's texts.
#include <cstdio>
#include <string>

namespace hpcm::detail {

inline std::string format_number(double v, const char* format = "%g") {
  char buf[32];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace hpcm::detail
