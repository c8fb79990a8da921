#include "pull_limit_notes.hpp"

#include <cmath>
#include <cstdio>

namespace hpcm::cli {

double offset_mm(const Model& m, Vec3 offset) { return offset_length_mm(m, offset); }

std::string limited_pull_text(const LimitedPull& p, const Model& m, const std::string& label) {
  const std::string frames = p.first_frame == p.last_frame
                                 ? "frame " + std::to_string(p.first_frame)
                                 : "frames " + std::to_string(p.first_frame) + "-" + std::to_string(p.last_frame);
  char buf[512];
  std::snprintf(buf, sizeof buf,
                ": the tool reached %.3g of the requested %.3g lattice units (%.3g of %.3g mm); the tissue between "
                "the tool and the anchors or the lattice border cannot stretch further, so the tool stopped there "
                "and no link is overstretched",
                static_cast<double>(norm(p.achieved)), static_cast<double>(norm(p.requested)), offset_mm(m, p.achieved),
                offset_mm(m, p.requested));
  return "the pull was limited in " + frames + " (" + label + (p.place.text.empty() ? "" : ", " + p.place.text) + ")" +
         buf;
}

void print_limited_pull(const LimitedPull& p, const Model& m, const std::string& label) {
  std::fprintf(stderr, "hpcm: note: %s\n", limited_pull_text(p, m, label).c_str());
}

nlohmann::json limited_pull_json(const LimitedPull& p, const Model& m) {
  return {{"first_frame", p.first_frame},
          {"last_frame", p.last_frame},
          {"grab", p.place.grab},
          {"keyframe_segment", p.place.segment},
          {"where", p.place.text},
          {"achieved_offset", {p.achieved.x, p.achieved.y, p.achieved.z}},
          {"requested_offset", {p.requested.x, p.requested.y, p.requested.z}},
          {"achieved_mm", offset_mm(m, p.achieved)},
          {"requested_mm", offset_mm(m, p.requested)}};
}

}  // namespace hpcm::cli
