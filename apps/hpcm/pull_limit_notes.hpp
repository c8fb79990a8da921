#pragma once
// How `hpcm run` and `hpcm experiment` tell the user that the tool asked for more than the
// tissue allows: once per stretch of limited frames in one grab and keyframe segment
// (LimitedPullTracker), never once per frame.
#include <nlohmann/json.hpp>
#include <string>

#include "hpcm/hpcm.hpp"

namespace hpcm::cli {

/// Length in millimetres of an offset in lattice units (the lattice's spacing and direction).
double offset_mm(const Model& m, Vec3 offset);
/// "the pull was limited in frames 16-29 (LABEL, grab[0], keyframes[0] to [1]): the tool
/// reached 4.98 of the requested 6 lattice units (41.5 of 50 mm); ..."
std::string limited_pull_text(const LimitedPull& p, const Model& m, const std::string& label);
/// Prints limited_pull_text as a note on stderr.
void print_limited_pull(const LimitedPull& p, const Model& m, const std::string& label);
/// For summary.json: frames, grab, segment, offsets in lattice units and mm.
nlohmann::json limited_pull_json(const LimitedPull& p, const Model& m);

}  // namespace hpcm::cli
