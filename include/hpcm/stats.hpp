#pragma once
// What the stages of one frame report (backend-independent): the solver's propagation and
// relaxation statistics and the velocity layer's per-tissue speed reduction.
#include "hpcm/tissue.hpp"

namespace hpcm {

struct PropagateStats {
  int sweeps = 0;          ///< sweeps until nothing changed
  bool converged = true;   ///< false if the sweep cap was hit
  Index reached = 0;       ///< elements the wave moved (finite arrival time, not FIXED)
};

struct RelaxStats {
  int sweeps = 0;              ///< sweeps run (early exit included)
  float max_correction = 0;    ///< largest correction of the last sweep
};

/// Per-tissue speed reduction of one frame: speed = |X_end(t) - X_end(t-1)|.
struct SpeedStats {
  PerTissue sum{};        ///< sum of speeds per class
  PerTissue max{};        ///< max speed per class
  Index moved = 0;        ///< elements with speed > 0
};

}  // namespace hpcm
