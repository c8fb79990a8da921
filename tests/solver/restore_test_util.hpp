#pragma once
// Helpers shared by the tests of the link restoration and the fold guard's search: positions
// in a vector behind solver::RestoreAccess, and two ways to run a ParallelFor's items.
#include <cstdint>
#include <functional>
#include <thread>
#include <vector>

#include "solver/link_restore.hpp"

namespace hpcm::test {

/// Displacements in a vector, FIXED where `fixed_flags` is not 0.
struct FixedVectorAccess : solver::RestoreAccess {
  std::vector<Vec3>& pos;
  const std::vector<std::uint8_t>& fixed_flags;
  FixedVectorAccess(std::vector<Vec3>& p, const std::vector<std::uint8_t>& f) : pos(p), fixed_flags(f) {}
  Vec3 displacement(Index i) const override { return pos[static_cast<std::size_t>(i)]; }
  void set_coordinate(Index i, int axis, float value) override { pos[static_cast<std::size_t>(i)][axis] = value; }
  bool fixed(Index i) const override { return fixed_flags[static_cast<std::size_t>(i)] != 0; }
};

/// Items in reverse order on this thread.
inline void reverse_order(std::int64_t items, const std::function<void(std::int64_t)>& item) {
  for (std::int64_t i = items - 1; i >= 0; --i) item(i);
}

/// Items split between two threads (run by the ThreadSanitizer job).
inline void two_threads(std::int64_t items, const std::function<void(std::int64_t)>& item) {
  std::thread odd([&] {
    for (std::int64_t i = 1; i < items; i += 2) item(i);
  });
  for (std::int64_t i = 0; i < items; i += 2) item(i);
  odd.join();
}

}  // namespace hpcm::test
