#pragma once
// Helpers shared by the solver tests: hand-built volumes, uniform materials, and one
// propagation wave through the public Backend interface.
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <vector>

#include "hpcm/backend_factory.hpp"
#include "hpcm/model.hpp"
#include "hpcm/params.hpp"
#include "hpcm/state.hpp"
#include "hpcm/volume.hpp"

namespace hpcm::test {

/// Volume with HU given per element coordinate.
inline Volume make_volume(Int3 dims, const std::function<float(int, int, int)>& hu) {
  Volume v;
  v.dims = dims;
  v.hu.resize(v.size());
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) v.hu[static_cast<std::size_t>(v.index(x, y, z))] = hu(x, y, z);
  return v;
}

/// Uniform material: every HU gives the same tau and w (two equal control points).
inline Params uniform_params(float tau, float w) {
  Params p;
  p.material.points = {{-1000.0f, tau, w}, {1000.0f, tau, w}};
  p.dynamics.mode = DampingMode::None;
  p.solver.relax_sweeps = 0;
  p.solver.anchors = AnchorMode::None;
  return p;
}

/// Plain ChainMail: no velocity layer, propagation only (no relaxation), no anchors.
inline Params propagation_params() {
  Params p;
  p.dynamics.mode = DampingMode::None;
  p.solver.relax_sweeps = 0;
  p.solver.anchors = AnchorMode::None;
  return p;
}

/// A Backend loaded with a model and a state, to run single waves by hand.
struct WaveRunner {
  const Model& model;
  std::unique_ptr<Backend> backend;
  WaveRunner(const Model& m, const Params& p, const State& s) : model(m), backend(make_backend(BackendKind::Cpu)) {
    backend->load(m, p, s);
  }
  /// One frame of plain ChainMail from the current positions (X- <- X) with `fixed` at
  /// `targets` (grabbed): propagation only. Returns the state right after propagation;
  /// the frame is then finished with the velocity layer (mode none: X_{t+1} = X+), which
  /// is where the CPU backend takes its X- snapshot for the next frame.
  State wave(const std::vector<Index>& fixed, const std::vector<Vec3>& targets) {
    return wave(fixed, targets, std::vector<std::uint8_t>(fixed.size(), static_cast<std::uint8_t>(kGrabbed)));
  }
  /// The same with the FIXED entries' flags (kGrabbed starts the wave, kAnchor holds).
  State wave(const std::vector<Index>& fixed, const std::vector<Vec3>& targets, const std::vector<std::uint8_t>& fl) {
    backend->apply_control(Control(fixed, targets, fl));
    backend->snapshot();
    last = backend->propagate();
    State s;
    backend->download(s);
    backend->velocity_layer(nullptr);
    return s;
  }
  PropagateStats last;
};

/// Elements within `radius` (rest coordinates) of centre c.
inline std::vector<Index> ball(const Model& m, Int3 c, float radius) {
  std::vector<Index> out;
  for (int z = 0; z < m.dims.z; ++z)
    for (int y = 0; y < m.dims.y; ++y)
      for (int x = 0; x < m.dims.x; ++x) {
        const float dx = float(x - c.x), dy = float(y - c.y), dz = float(z - c.z);
        if (dx * dx + dy * dy + dz * dz <= radius * radius) out.push_back(m.index(x, y, z));
      }
  return out;
}

inline float max_abs_diff(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  float d = 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    for (int k = 0; k < 3; ++k) d = std::max(d, std::fabs(a[i][k] - b[i][k]));
  return d;
}

}  // namespace hpcm::test
