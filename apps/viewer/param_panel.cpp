#include "param_panel.hpp"

namespace hpcm::viewer {

std::vector<PanelParam> panel_params(const std::string& section) {
  std::vector<PanelParam> out;
  for (const ParamSpec& s : param_table()) {
    if (s.section() != section) continue;
    PanelParam w;
    w.spec = &s;
    // Numbers show their valid range; a checkbox or a list of choices shows it by itself.
    const bool choice = s.type == ParamType::Flag || s.type == ParamType::Choice || !s.allowed.empty();
    w.label = choice ? s.name() : s.name() + " " + range_text(s);
    w.tooltip = (s.unit.empty() ? "" : s.unit + ": ") + s.help;
    // The table's slider hint where the valid range is too wide or open to drag through.
    const bool hinted = s.slider.lo != 0 || s.slider.hi != 0;
    w.lo = hinted ? s.slider.lo : s.range.lo;
    w.hi = hinted ? s.slider.hi : s.range.hi;
    w.logarithmic = hinted && s.slider.logarithmic;
    out.push_back(w);
  }
  return out;
}

}  // namespace hpcm::viewer
