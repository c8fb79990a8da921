#pragma once
// Private helpers of hpcm::config: strict TOML reading (every key known, every type checked,
// every message prefixed with the file name) and exact float formatting for writing.
#include <toml++/toml.h>

#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "hpcm/types.hpp"

namespace hpcm::config::detail {

/// Where the text came from: every error message starts with "<source>: ".
struct Ctx {
  std::string source;
};

/// Throws hpcm::Error("<source>: <msg>[ (line N)]").
[[noreturn]] void fail(const Ctx& c, const toml::node* at, const std::string& msg);
/// " (line N)" when the node has a source position, else "".
std::string line_suffix(const toml::node* at);

/// Parses TOML text; syntax errors become hpcm::Error "<source>: line L, column C: ...".
toml::table parse_toml(const std::string& text, const Ctx& c);

/// "a string", "an integer", ... for messages.
std::string type_phrase(const toml::node& n);
/// The node's value as TOML text, shortened for messages.
std::string show(const toml::node& n);

/// Shortest decimal text that reads back (decimal -> double -> float) as exactly f, always
/// valid as a TOML float ("1.0", not "1"; "inf", "nan" for non-finite values).
std::string fmt_float(float f);

/// Number -> float (integers accepted), must be finite and within float range.
float to_float(const Ctx& c, const toml::node& n, const std::string& path);
/// Integer -> int, must fit in an int.
int to_int(const Ctx& c, const toml::node& n, const std::string& path);

/// One TOML table being read: every key asked for is "known"; finish() rejects the rest.
class Section {
 public:
  Section(const Ctx& c, const toml::table& t, std::string path);

  /// The node at key (nullptr when absent); marks the key known.
  const toml::node* get(std::string_view key);
  bool read(std::string_view key, float& out);
  bool read(std::string_view key, int& out);
  bool read(std::string_view key, bool& out);
  bool read(std::string_view key, std::string& out);
  /// Sub-table (nullptr when absent); error when present but not a table.
  const toml::table* table(std::string_view key);
  /// Array (nullptr when absent); error when present but not an array.
  const toml::array* array(std::string_view key);

  /// "dynamics.alpha" for key "alpha" in section "dynamics".
  std::string path_of(std::string_view key) const;
  const Ctx& ctx() const { return ctx_; }
  const toml::table& tbl() const { return t_; }
  /// Throws for the first key that was never asked for, suggesting the closest known key.
  void finish() const;

 private:
  const Ctx& ctx_;
  const toml::table& t_;
  std::string path_;
  std::vector<std::string> known_;
};

/// Adds " (line N)" for the key named at the start of a validate() message, when that key
/// is present in the parsed table (e.g. "dynamics.alpha = 1.5 is out of range ...").
std::string locate_message(const toml::table& root, const std::string& msg);

/// Largest parameter or scenario file read (bytes).
inline constexpr std::size_t kMaxConfigBytes = 4u << 20;

/// Whole file as text; `what` names it in errors ("parameter file", "scenario file").
/// Directories, files over kMaxConfigBytes and binary data (NUL bytes) are errors.
std::string read_text(const std::string& path, const std::string& what);

}  // namespace hpcm::config::detail
