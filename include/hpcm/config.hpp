#pragma once
// Parameter and scenario files (TOML, library hpcm::config). Every value is validated; an
// invalid file is rejected with hpcm::Error naming the file, key, value and valid range.
#include <string>

#include "hpcm/params.hpp"
#include "hpcm/scenario.hpp"

namespace hpcm::config {

Params load_params(const std::string& path);
Params parse_params(const std::string& toml_text, const std::string& source_name);
/// Same, starting from `base` instead of the defaults: keys the text leaves out keep base's
/// values (the Python API sets single parameters this way, with the file's validation).
Params parse_params(const std::string& toml_text, const std::string& source_name, const Params& base);
/// A complete, commented parameter file holding every default.
std::string default_params_toml();
std::string params_to_toml(const Params& p);

Scenario load_scenario(const std::string& path);
Scenario parse_scenario(const std::string& toml_text, const std::string& source_name);
std::string scenario_to_toml(const Scenario& s);

}  // namespace hpcm::config
