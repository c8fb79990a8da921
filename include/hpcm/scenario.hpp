#pragma once
// Scripted interactions: grabs with keyframed drag paths, holds and releases (SPEC §7).
#include <optional>
#include <string>
#include <vector>

#include "hpcm/simulation.hpp"

namespace hpcm {

/// Largest tool offset per axis, lattice units: beyond any lattice, and it keeps the
/// interpolation between keyframes finite.
inline constexpr float kMaxToolOffset = 10000.0f;

/// Units of a scenario offset or grab radius: lattice units (element spacings) or millimetres
/// along the lattice axes (LPS), converted with the lattice spacing per axis when played.
enum class Units { lattice, mm };

/// Tool offset reached after `frame` frames of a grab.
struct Keyframe {
  int frame = 0;
  Vec3 offset{};
  Units units = Units::lattice;
};

struct GrabAction {
  std::optional<Int3> centre;   ///< element coordinates; nullopt = "auto" (paper grab centre)
  float radius = 0;             ///< <= 0: params.solver.grab_radius (lattice units only)
  Units radius_units = Units::lattice;  ///< mm: a sphere of `radius` mm (an ellipsoid on the lattice)
  int start = 0;                ///< scenario frame at which the grab begins
  std::vector<Keyframe> path;   ///< offset in relative frame r is path(r + 1), linear, held after the last key
  int release = 0;              ///< relative frame of release (first frame without the grab)
};

struct Scenario {
  std::string name = "custom";
  int frames = 0;               ///< total frames to play
  std::vector<GrabAction> grabs;  ///< in sequence, must not overlap in time

  /// SPEC §7: pull the anterior skin point by `distance` toward -y over `pull` frames,
  /// hold `hold` frames, release, record `record` frames.
  static Scenario paper_protocol(float distance = 6.0f, int pull = 20, int hold = 10, int record = 120);
  /// Throws hpcm::Error when a grab is out of the lattice, overlaps another, or frames < 1.
  void validate(const Model& m) const;
  /// A copy with every keyframe in lattice units (mm divided by m.spacing per axis); grab radii
  /// keep their units (Simulation::grab_mm takes millimetres). Throws hpcm::Error naming the
  /// keyframe when a converted offset is out of range [-kMaxToolOffset, kMaxToolOffset].
  Scenario in_lattice_units(const Model& m) const;
  /// Frame of the last release (the first idle frame after it), or -1 without grabs.
  int last_release_frame() const;
};

/// The grab's largest radius along any lattice axis (lattice units); default_radius when it
/// has none. For check_lattice_extent.
float widest_grab_radius(const GrabAction& g, const Model& m, float default_radius);

/// Tool offset of a grab action in relative frame r (linear between keyframes).
Vec3 path_offset(const GrabAction& g, int r);

/// Where a scenario frame lies: the grab held then and its keyframe segment.
struct ScenarioPlace {
  int grab = -1;     ///< index into Scenario::grabs; -1: no grab at that frame
  int segment = -1;  ///< keyframe j the offset moves towards (held after the last); -1: none
  std::string text;  ///< "grab[0], keyframes[0] to [1]"; empty without a grab
};
ScenarioPlace scenario_place(const Scenario& sc, int frame);

/// A stretch of consecutive frames, within one grab and keyframe segment, in which the tool
/// asked for more than the tissue allows and was limited (SPEC §4, infeasible requests).
struct LimitedPull {
  ScenarioPlace place;
  int first_frame = 0, last_frame = 0;
  /// Tool offsets (lattice units) at the frame of the stretch that asked for the most.
  Vec3 achieved{}, requested{};
};

/// Collects the limited stretches of a run frame by frame, so that each can be reported once.
class LimitedPullTracker {
 public:
  explicit LimitedPullTracker(const Scenario& sc) : scenario_(sc) {}
  /// After each frame: its report and the tool offsets used in it (Simulation::tool_offset()
  /// and requested_offset()). Returns the stretch that ended just before this frame, if any.
  std::optional<LimitedPull> after_frame(const FrameReport& r, Vec3 achieved, Vec3 requested);
  /// At the end of the run: the stretch still open, if any.
  std::optional<LimitedPull> finish();

 private:
  const Scenario& scenario_;
  std::optional<LimitedPull> open_;
};

/// Plays a scenario frame by frame on a Simulation.
class ScenarioPlayer {
 public:
  ScenarioPlayer(const Scenario& s, Simulation& sim);
  bool done() const { return frame_ >= scenario_.frames; }
  int frame() const { return frame_; }
  /// Applies this frame's input (grab / move / release) and steps the simulation.
  FrameReport step(const StepOptions& opt = {});
  /// Resolved grab centre of grab action k.
  Index centre_of(std::size_t k) const { return centres_.at(k); }

 private:
  Scenario scenario_;
  Simulation& sim_;
  std::vector<Index> centres_;
  int frame_ = 0;
};

}  // namespace hpcm
