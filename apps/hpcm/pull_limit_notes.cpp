#include "pull_limit_notes.hpp"

#include <cmath>
#include <cstdio>

namespace hpcm::cli {

PullLimitNotes::PullLimitNotes(const Scenario& sc, const Model& m, std::string label)
    : scenario_(sc), model_(m), label_(std::move(label)) {}

double PullLimitNotes::millimetres(Vec3 v) const {
  double len2 = 0;
  for (int r = 0; r < 3; ++r) {
    double c = 0;
    for (int a = 0; a < 3; ++a) c += model_.direction[r * 3 + a] * model_.spacing[a] * v[a];
    len2 += c * c;
  }
  return std::sqrt(len2);
}

void PullLimitNotes::after_frame(const FrameReport& r, Vec3 achieved, Vec3 requested) {
  const ScenarioPlace place = r.tool_limited ? scenario_place(scenario_, r.frame) : ScenarioPlace{};
  const bool continues = open_ && r.tool_limited && open_->last + 1 == r.frame && open_->place.grab == place.grab &&
                         open_->place.segment == place.segment;
  if (open_ && !continues) {
    print(*open_);
    open_.reset();
  }
  if (!r.tool_limited) return;
  if (!open_) open_ = Stretch{place, r.frame, r.frame, achieved, requested};
  open_->last = r.frame;
  if (norm(requested) >= norm(open_->requested)) {
    open_->requested = requested;
    open_->achieved = achieved;
  }
}

void PullLimitNotes::finish() {
  if (open_) print(*open_);
  open_.reset();
}

void PullLimitNotes::print(const Stretch& s) {
  const std::string frames =
      s.first == s.last ? "frame " + std::to_string(s.first) : "frames " + std::to_string(s.first) + "-" + std::to_string(s.last);
  std::fprintf(stderr,
               "hpcm: note: the pull was limited in %s (%s%s%s): the tool reached %.3g of the requested %.3g lattice "
               "units (%.3g of %.3g mm); the tissue between the tool and the anchors or the lattice border cannot "
               "stretch further, so the tool stopped there and no link is overstretched\n",
               frames.c_str(), label_.c_str(), s.place.text.empty() ? "" : ", ", s.place.text.c_str(),
               static_cast<double>(norm(s.achieved)), static_cast<double>(norm(s.requested)), millimetres(s.achieved),
               millimetres(s.requested));
  ++printed_;
}

}  // namespace hpcm::cli
