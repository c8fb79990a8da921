#pragma once
// An O(N) pass over the lattice split across threads without OpenMP, for passes that run every
// frame outside the CPU backend (metrics, the tool limit). OpenMP's idle threads keep spinning
// for milliseconds after each parallel region (libgomp's default wait policy); a per-frame
// region leaves them spinning while the simulation's own threads work, and takes a core from
// them (measured in `hpcm run`, which checks links and folds every frame: frames 15 % slower).
// The threads here end with the pass. One-off setup (model, phantom, IO) keeps OpenMP.
#include <omp.h>

#include <algorithm>
#include <thread>
#include <vector>

namespace hpcm {

/// How many parts a pass over n items is split into: the OpenMP thread setting (so
/// OMP_NUM_THREADS still decides), at most n, at least 1.
inline int pass_parts(int n) { return std::max(1, std::min(n, omp_get_max_threads())); }

/// Runs f(part, lo, hi) for `parts` contiguous ranges [lo, hi) of [0, n): the caller runs part
/// 0, one std::thread each of the others. f must not throw.
template <class F>
void run_parts(int n, int parts, F&& f) {
  const auto bound = [&](int t) { return static_cast<int>(static_cast<long long>(n) * t / parts); };
  std::vector<std::thread> others;
  others.reserve(static_cast<std::size_t>(std::max(0, parts - 1)));
  for (int t = 1; t < parts; ++t) others.emplace_back([&f, &bound, t] { f(t, bound(t), bound(t + 1)); });
  f(0, bound(0), bound(1));
  for (std::thread& th : others) th.join();
}

}  // namespace hpcm
