#pragma once
// Exact integer parsing for command-line values, shared by hpcm and hpcm-viewer: the whole
// text must be one decimal integer inside [lo, hi]. Nothing wraps (4294967328 is not 32),
// nothing is clamped, and no value outside the range can stand for "not given".
#include <charconv>
#include <cstdint>
#include <string>
#include <system_error>

#include "hpcm/types.hpp"

namespace hpcm::cli {

/// Parses `text` as a decimal integer in [lo, hi]; throws hpcm::Error naming `what` (the option),
/// the text and the range.
inline long long parse_integer(const std::string& text, const std::string& what, long long lo, long long hi) {
  const auto range = [&] { return " (valid: an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "])"; };
  std::string t = text;
  if (!t.empty() && t[0] == '+') t.erase(0, 1);  // from_chars does not take a leading '+'
  long long v = 0;
  const char* end = t.data() + t.size();
  const auto [p, ec] = std::from_chars(t.data(), end, v);
  if (t.empty() || ec == std::errc::invalid_argument || p != end)
    throw Error(what + " '" + text + "' is not an integer" + range());
  if (ec == std::errc::result_out_of_range || v < lo || v > hi)
    throw Error(what + " " + text + " is out of range" + range());
  return v;
}

/// Unsigned 64-bit values (seeds): [0, 2^64 - 1]; "-1" and anything larger are errors.
inline std::uint64_t parse_u64(const std::string& text, const std::string& what) {
  const std::string range = " (valid: an integer in [0, 18446744073709551615])";
  std::string t = text;
  if (!t.empty() && t[0] == '+') t.erase(0, 1);
  std::uint64_t v = 0;
  const char* end = t.data() + t.size();
  if (!t.empty() && t[0] == '-') {
    long long neg = 0;
    const auto [p, ec] = std::from_chars(t.data(), end, neg);
    if (p == end && ec != std::errc::invalid_argument) throw Error(what + " " + text + " is out of range" + range);
    throw Error(what + " '" + text + "' is not an integer" + range);
  }
  const auto [p, ec] = std::from_chars(t.data(), end, v);
  if (t.empty() || ec == std::errc::invalid_argument || p != end)
    throw Error(what + " '" + text + "' is not an integer" + range);
  if (ec == std::errc::result_out_of_range) throw Error(what + " " + text + " is out of range" + range);
  return v;
}

}  // namespace hpcm::cli
