#pragma once
// Umbrella header of the hpcm library.
#include "hpcm/backend.hpp"
#include "hpcm/material.hpp"
#include "hpcm/model.hpp"
#include "hpcm/params.hpp"
#include "hpcm/phantom.hpp"
#include "hpcm/scenario.hpp"
#include "hpcm/simulation.hpp"
#include "hpcm/state.hpp"
#include "hpcm/tissue.hpp"
#include "hpcm/types.hpp"
#include "hpcm/volume.hpp"
