#pragma once
// What the stages of one frame report (backend-independent): the solver's propagation and
// relaxation statistics and the velocity layer's per-tissue speed reduction.
#include "hpcm/tissue.hpp"

namespace hpcm {

struct PropagateStats {
  int sweeps = 0;          ///< sweeps until nothing changed
  bool converged = true;   ///< false if the sweep cap was hit
  Index reached = 0;       ///< elements the wave moved (finite arrival time, not FIXED)
  Index largest_bucket = 0;  ///< most elements decided together in one time bucket (CPU; above 1024 they are split among threads)
};

struct RelaxStats {
  int sweeps = 0;              ///< sweeps run (early exit included)
  float max_correction = 0;    ///< largest correction of the last sweep
};

/// The link restoration at the end of every ChainMail stage (docs/solver.md).
struct RestoreStats {
  Index violated_links = 0;     ///< links found outside their box (beyond the tolerance) before restoring
  float max_violation = 0;      ///< the largest of those violations, lattice units
  Index moved = 0;              ///< elements the restoration moved
  bool capped = false;          ///< a pass reached its cap (solver::kRestoreVisitsPerElement) and stopped early
};

/// Per-tissue speed reduction of one frame: speed = |X_end(t) - X_end(t-1)|.
struct SpeedStats {
  PerTissue sum{};        ///< sum of speeds per class
  PerTissue max{};        ///< max speed per class
  Index moved = 0;        ///< elements with speed > 0
};

}  // namespace hpcm
