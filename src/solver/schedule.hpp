#pragma once
// The propagation schedule's one model-wide constant, shared by both backends.
#include "hpcm/model.hpp"

namespace hpcm::solver {

/// Bucket width of the bucketed propagation: the smallest time penalty w of any link of the
/// model (w > 0 is validated), 1 for a lattice without links.
float bucket_width(const Model& m);

}  // namespace hpcm::solver
