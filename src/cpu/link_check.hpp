#pragma once
// The CPU's check for the link restoration (what solver::find_violations does, on the storage
// arrays directly and on the backend's threads): every link with an end in the listed bricks,
// and every element there against the wall.
#include <vector>

#include "cpu/kernels.hpp"
#include "cpu/storage.hpp"
#include "cpu/worker_pool.hpp"
#include "hpcm/stats.hpp"
#include "solver/bricks.hpp"
#include "solver/rules.hpp"

namespace hpcm::cpu {

class LinkCheck {
 public:
  void init(LinkRowKernel filter) { filter_ = filter; }
  /// Appends the ends of the violated links (linear indices, ascending, once each) to `seeds`.
  void run(const Storage& st, const solver::BrickGrid& grid, const std::vector<Index>& bricks, const solver::Wall& wall,
           std::vector<Index>& seeds, RestoreStats& stats, WorkerPool& pool);

 private:
  LinkRowKernel filter_ = nullptr;
  /// Runs of bricks consecutive along x (same brick row), so that the vector filter sees whole
  /// lattice rows instead of one brick's width.
  struct Span {
    Index first_brick;
    int count;
    Int3 lo, hi;  ///< its elements: [lo, hi) on each axis
  };
  std::vector<Span> spans_;
  std::vector<std::size_t> tasks_;  ///< spans_ index where each task starts, and the end (tasks_by_layer)
  std::vector<std::vector<Index>> found_;
  std::vector<std::vector<int>> flagged_;
  std::vector<RestoreStats> partial_;
};

}  // namespace hpcm::cpu
