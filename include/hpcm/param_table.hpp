#pragma once
// The parameter table: one entry per key of the parameter file (name, default, range, unit,
// help and the field it sets). Validation (Params::validate), the parameter file's reader and
// writer (hpcm::config), the viewer's panel and docs/parameters.md are produced from it, so a
// range is written once. The rules that relate several keys (s_min <= s_max, the stability
// rule, ...) stay named rules in params.cpp; each is described in the help of the keys it reads.
#include <string>
#include <vector>

#include "hpcm/params.hpp"

namespace hpcm {

enum class ParamType {
  Real,        ///< float
  Integer,     ///< int (a range, or a set of allowed values)
  Flag,        ///< bool
  Choice,      ///< enum, given by name
  PerClass,    ///< PerTissue: one value per tissue class, each within the range
  Points,      ///< material.points: the list of control points (its columns are PointField entries)
  PointField,  ///< one column of material.points (hu, tau, w), each point within the range
};

/// Closed or half-open interval; an infinite bound means "finite" on that side.
struct ParamRange {
  double lo, hi;
  bool lo_open = false, hi_open = false;
};

/// The span a slider covers where the valid range is too wide (or open) to drag through.
struct SliderHint {
  double lo, hi;
  bool logarithmic = false;
};

struct ParamSpec {
  std::string key;      ///< TOML key with its section, "dynamics.alpha"; a point column: "material.points[].tau"
  ParamType type = ParamType::Real;
  ParamRange range{0, 0};          ///< Real, Integer, PerClass, PointField
  std::vector<int> allowed;        ///< Integer: the only valid values when not empty (brick_size)
  std::vector<std::string> choices;  ///< Choice: the names accepted (the first of each value is written)
  std::string unit;                ///< "lattice units", "HU", "" (dimensionless)
  std::string help;                ///< what it does; the named rules that also bound it
  SliderHint slider{0, 0};         ///< the viewer's slider span; {0, 0}: the range itself
  std::string out_of_range_note;   ///< appended to the out-of-range message (why the range is what it is)

  // The field, exactly one set according to the type (getter-free: every consumer reads and
  // writes through the same reference).
  float& (*real)(Params&) = nullptr;
  int& (*integer)(Params&) = nullptr;
  bool& (*flag)(Params&) = nullptr;
  PerTissue& (*per_class)(Params&) = nullptr;
  std::vector<MaterialPoint>& (*points)(Params&) = nullptr;
  float MaterialPoint::*point_field = nullptr;
  /// Choice: the value's name, and setting it by name (throws hpcm::Error naming the key).
  std::string (*choice_name)(const Params&) = nullptr;
  void (*set_choice)(Params&, const std::string& name) = nullptr;

  /// "alpha" for "dynamics.alpha", "tau" for "material.points[].tau".
  std::string name() const;
  /// "dynamics" for "dynamics.alpha".
  std::string section() const;
};

/// Every parameter, in file order: tissue, material, solver, dynamics.
const std::vector<ParamSpec>& param_table();
/// The entry of `key`, or nullptr.
const ParamSpec* find_param(const std::string& key);

/// "[0, 1]", "(0, 64]", "[1, 1e7]", "4 | 8 | 16", "\"none\" | \"bone\"", "true | false", "finite"
/// (docs, comments and labels).
std::string range_text(const ParamSpec& s);
/// The default (from a default-constructed Params) as text: "0.98", "8", "\"bone\"", "true",
/// "air 0, skin_fat 0.15, ..." (docs and labels).
std::string default_text(const ParamSpec& s);
/// A number as range_text writes it: at most 6 significant digits, 1e-6 and 1e6 rather than
/// 1e-06 and 1e+06, integers below 1e5 in full.
std::string format_number(double v);

/// docs/parameters.md's tables: one Markdown table per section, each between comment fences
/// (`hpcm params --markdown`; scripts/param_docs.py puts them into the page and checks them).
std::string param_table_markdown();

/// The per-key range checks of every table entry (Params::validate runs them first). Throws
/// hpcm::Error "<key> = <value> is out of range [lo, hi]" (or the key's own form).
void check_param_ranges(const Params& p);

}  // namespace hpcm
