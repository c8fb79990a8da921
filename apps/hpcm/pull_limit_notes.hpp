#pragma once
// Tells the user, once per stretch of frames, that the tool asked for more than the tissue
// allows: the solver then limits the tool (the achieved offset is smaller than the requested
// one, no link is overstretched). One note per grab and keyframe segment, not one per frame.
#include <optional>
#include <string>

#include "run_options.hpp"

namespace hpcm::cli {

class PullLimitNotes {
 public:
  /// `label` names the scenario in messages ("the paper protocol", "scenario FILE").
  PullLimitNotes(const Scenario& sc, const Model& m, std::string label);
  /// After each frame: its report and the tool offsets (lattice units) used in it.
  void after_frame(const FrameReport& r, Vec3 achieved, Vec3 requested);
  /// At the end of the run: reports a stretch still open.
  void finish();
  int notes_printed() const { return printed_; }

 private:
  struct Stretch {
    ScenarioPlace place;
    int first = 0, last = 0;
    Vec3 achieved{}, requested{};  ///< at the frame of the stretch that asked for the most
  };
  void print(const Stretch& s);
  double millimetres(Vec3 v) const;  ///< length of a lattice-unit vector in mm
  const Scenario& scenario_;
  const Model& model_;
  std::string label_;
  std::optional<Stretch> open_;
  int printed_ = 0;
};

}  // namespace hpcm::cli
