#include "toml_util.hpp"

#include <algorithm>
#include <cctype>
#include <cfloat>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include <sys/stat.h>
#include <cerrno>

namespace hpcm::config::detail {

std::string line_suffix(const toml::node* at) {
  if (!at) return "";
  const auto line = at->source().begin.line;
  if (line == 0) return "";
  return " (line " + std::to_string(line) + ")";
}

void fail(const Ctx& c, const toml::node* at, const std::string& msg) {
  throw Error(c.source + ": " + msg + line_suffix(at));
}

toml::table parse_toml(const std::string& text, const Ctx& c) {
  try {
    return toml::parse(text, c.source);
  } catch (const toml::parse_error& e) {
    const auto& b = e.source().begin;
    std::string where;
    if (b.line > 0) where = "line " + std::to_string(b.line) + ", column " + std::to_string(b.column) + ": ";
    throw Error(c.source + ": " + where + "TOML syntax error: " + std::string(e.description()));
  }
}

std::string type_phrase(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::table: return "a table";
    case toml::node_type::array: return "an array";
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a float";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::date: return "a date";
    case toml::node_type::time: return "a time";
    case toml::node_type::date_time: return "a date-time";
    default: return "nothing";
  }
}

namespace {
std::string quote(std::string_view v) {
  std::string out = "\"";
  for (unsigned char ch : v) {
    if (ch == '"' || ch == '\\') out += '\\', out += static_cast<char>(ch);
    else if (ch < 0x20 || ch == 0x7f) out += '?';
    else out += static_cast<char>(ch);
  }
  return out + "\"";
}
std::string fmt_double(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  for (int prec = 1; prec <= 17; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*g", prec, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  std::string s = buf;
  if (s.find_first_of(".eE") == std::string::npos) s += ".0";
  return s;
}
}  // namespace

std::string show(const toml::node& n) {
  std::string s;
  if (auto* str = n.as_string()) {
    s = quote(str->get());
  } else if (auto* d = n.as_floating_point()) {
    s = fmt_double(d->get());
  } else if (auto* i = n.as_integer()) {
    s = std::to_string(i->get());
  } else if (auto* b = n.as_boolean()) {
    s = b->get() ? "true" : "false";
  } else {
    std::ostringstream os;
    os << toml::node_view<const toml::node>{&n};
    s = os.str();
  }
  for (char& ch : s)
    if (ch == '\n' || ch == '\r') ch = ' ';
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}

std::string fmt_float(float f) {
  if (std::isnan(f)) return "nan";
  if (std::isinf(f)) return f > 0 ? "inf" : "-inf";
  // Fewest significant digits that read back (decimal -> double -> float, as our reader does)
  // as exactly f.
  char buf[64];
  int prec = 1;
  for (; prec <= 17; ++prec) {
    std::snprintf(buf, sizeof buf, "%.*e", prec - 1, static_cast<double>(f));
    if (static_cast<float>(std::strtod(buf, nullptr)) == f) break;
  }
  // Fixed notation for ordinary magnitudes ("1000.0", "0.0001"), scientific otherwise.
  const int exp10 = f == 0.0f ? 0 : std::atoi(std::strchr(buf, 'e') + 1);
  if (exp10 >= -5 && exp10 < 16) {
    std::snprintf(buf, sizeof buf, "%.*f", std::max(0, prec - 1 - exp10), static_cast<double>(f));
    if (static_cast<float>(std::strtod(buf, nullptr)) != f)  // cannot happen; keep exactness anyway
      std::snprintf(buf, sizeof buf, "%.9e", static_cast<double>(f));
  }
  std::string s = buf;
  // TOML needs a '.' or an exponent to read a float; "1e-07" is valid TOML.
  if (s.find_first_of(".eE") == std::string::npos) s += ".0";
  return s;
}

float to_float(const Ctx& c, const toml::node& n, const std::string& path) {
  double v = 0;
  if (auto* i = n.as_integer()) {
    v = static_cast<double>(i->get());
  } else if (auto* d = n.as_floating_point()) {
    v = d->get();
  } else {
    fail(c, &n, path + " must be a number, got " + type_phrase(n) + " " + show(n));
  }
  if (!std::isfinite(v)) fail(c, &n, path + " = " + show(n) + " is not a finite number");
  if (std::fabs(v) > static_cast<double>(FLT_MAX))
    fail(c, &n, path + " = " + show(n) + " is outside the single-precision range");
  // Below FLT_MIN a float loses precision (denormal) or becomes 0: refuse rather than change it.
  if (v != 0.0 && std::fabs(v) < static_cast<double>(FLT_MIN))
    fail(c, &n, path + " = " + show(n) + " is below the smallest positive single-precision value " +
                    fmt_float(FLT_MIN) + " in magnitude; write 0 or a larger value");
  return static_cast<float>(v);
}

int to_int(const Ctx& c, const toml::node& n, const std::string& path) {
  auto* i = n.as_integer();
  if (!i) fail(c, &n, path + " must be an integer, got " + type_phrase(n) + " " + show(n));
  const std::int64_t v = i->get();
  if (v < INT_MIN || v > INT_MAX) fail(c, &n, path + " = " + show(n) + " does not fit in a 32-bit integer");
  return static_cast<int>(v);
}

Section::Section(const Ctx& c, const toml::table& t, std::string path) : ctx_(c), t_(t), path_(std::move(path)) {}

std::string Section::path_of(std::string_view key) const {
  return path_.empty() ? std::string(key) : path_ + "." + std::string(key);
}

const toml::node* Section::get(std::string_view key) {
  if (std::find(known_.begin(), known_.end(), key) == known_.end()) known_.emplace_back(key);
  return t_.get(key);
}

bool Section::read(std::string_view key, float& out) {
  const toml::node* n = get(key);
  if (!n) return false;
  out = to_float(ctx_, *n, path_of(key));
  return true;
}

bool Section::read(std::string_view key, int& out) {
  const toml::node* n = get(key);
  if (!n) return false;
  out = to_int(ctx_, *n, path_of(key));
  return true;
}

bool Section::read(std::string_view key, bool& out) {
  const toml::node* n = get(key);
  if (!n) return false;
  auto* b = n->as_boolean();
  if (!b) fail(ctx_, n, path_of(key) + " must be true or false, got " + type_phrase(*n) + " " + show(*n));
  out = b->get();
  return true;
}

bool Section::read(std::string_view key, std::string& out) {
  const toml::node* n = get(key);
  if (!n) return false;
  auto* s = n->as_string();
  if (!s) fail(ctx_, n, path_of(key) + " must be a string, got " + type_phrase(*n) + " " + show(*n));
  out = s->get();
  return true;
}

const toml::table* Section::table(std::string_view key) {
  const toml::node* n = get(key);
  if (!n) return nullptr;
  auto* t = n->as_table();
  if (!t) fail(ctx_, n, path_of(key) + " must be a table, got " + type_phrase(*n) + " " + show(*n));
  return t;
}

const toml::array* Section::array(std::string_view key) {
  const toml::node* n = get(key);
  if (!n) return nullptr;
  auto* a = n->as_array();
  if (!a) fail(ctx_, n, path_of(key) + " must be an array, got " + type_phrase(*n) + " " + show(*n));
  return a;
}

namespace {
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t sub = prev[j - 1] + (std::tolower(a[i - 1]) == std::tolower(b[j - 1]) ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}
}  // namespace

void Section::finish() const {
  for (auto&& [k, v] : t_) {
    const std::string_view key = k.str();
    if (std::find(known_.begin(), known_.end(), key) != known_.end()) continue;
    std::string msg = "unknown key '" + path_of(key) + "'";
    std::string best;
    std::size_t best_d = 3;
    for (const auto& kk : known_) {
      const std::size_t d = edit_distance(key, kk);
      if (d < best_d) best_d = d, best = kk;
    }
    if (!best.empty()) msg += " (did you mean '" + path_of(best) + "'?)";
    std::string list;
    for (const auto& kk : known_) list += (list.empty() ? "" : ", ") + kk;
    msg += "; valid keys " + (path_.empty() ? std::string("at the top level") : "in [" + path_ + "]") + ": " + list;
    // The key's own position: a table/array node's source, else the value's.
    fail(ctx_, &v, msg);
  }
}

std::string locate_message(const toml::table& root, const std::string& msg) {
  std::size_t end = 0;
  while (end < msg.size() && (std::isalnum(static_cast<unsigned char>(msg[end])) || msg[end] == '_' ||
                              msg[end] == '.' || msg[end] == '[' || msg[end] == ']'))
    ++end;
  if (end == 0 || msg.find('.') >= end) return msg;
  std::string key = msg.substr(0, end);
  while (!key.empty() && key.back() == '.') key.pop_back();
  // Walk up ("material.points[2].tau" -> "material.points[2]" -> ...) to the nearest node.
  // Stop before the bare section name: "[dynamics]" would not help locate the value.
  while (key.find_first_of(".[") != std::string::npos) {
    auto nv = toml::at_path(root, key);
    if (nv) {
      const toml::node* n = nv.node();
      const std::string suffix = line_suffix(n);
      return suffix.empty() ? msg : msg + suffix;
    }
    key.resize(key.find_last_of(".["));
  }
  return msg;
}

std::string read_text(const std::string& path, const std::string& what) {
  // Parameter and scenario files are a few kB: refuse directories and read at most
  // kMaxConfigBytes, so /dev/zero or a multi-GB file is an error, not a hang.
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw Error(path + ": cannot open the " + what + " (" + std::strerror(errno) + ")");
  if (S_ISDIR(st.st_mode)) throw Error(path + ": is a directory, not a " + what);
  // A FIFO or device can block on open or never end: only regular files are read.
  if (!S_ISREG(st.st_mode))
    throw Error(path + ": is not a regular file (a FIFO, device or socket), not a " + what);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open the " + what);
  std::string text(kMaxConfigBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  if (in.bad()) throw Error(path + ": cannot read the " + what);
  text.resize(static_cast<std::size_t>(in.gcount()));
  if (text.size() > kMaxConfigBytes)
    throw Error(path + ": larger than " + std::to_string(kMaxConfigBytes / (1024 * 1024)) + " MiB; not a " + what);
  if (text.find('\0') != std::string::npos)
    throw Error(path + ": holds NUL bytes (binary data), not a " + what + " (TOML text)");
  return text;
}

}  // namespace hpcm::config::detail
