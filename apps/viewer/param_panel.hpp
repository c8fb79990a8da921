#pragma once
// The parameter panel's widgets, from the parameter table (GL-free, so that the tests can see
// which parameters the panel shows and over which span its sliders run).
#include <string>
#include <vector>

#include "hpcm/param_table.hpp"

namespace hpcm::viewer {

struct PanelParam {
  const ParamSpec* spec = nullptr;
  std::string label;        ///< "relax_omega [1, 1.95]": the key's name and (numbers) valid range
  std::string tooltip;      ///< unit and help
  double lo = 0, hi = 0;    ///< slider span (Real, Integer, PerClass, PointField), within the valid range
  bool logarithmic = false;
};

/// The panel's widgets for one section of the table ("solver", "dynamics", "tissue",
/// "material"), in table order; every key of the section is there.
std::vector<PanelParam> panel_params(const std::string& section);

}  // namespace hpcm::viewer
