#pragma once
// The CPU propagation (SPEC §4): the timestamped HP-ChainMail wave from the grabbed elements,
// processed in time buckets (solver/rules.hpp, docs/solver.md). Every link the wave crosses
// has w >= delta (solver::BucketWidth: the smallest penalty of the links without an anchored
// end), so all candidate times in the bucket [k delta, (k+1) delta) come from elements already
// final in earlier buckets or FIXED: each bucket is decided by a short,
// provably finite Jacobi iteration, and the result is exactly the Dijkstra-order result.
// FIXED elements are final with time 0 (upstream of everything); only grabbed ones start the
// wave: anchors never move, and their neighbours are already inside their boxes (the link
// restoration keeps them so). The still part of the FIXED set (anchors: the same for a whole
// run, tens of thousands of elements on a CT) stays final between waves; a wave forgets and
// seeds only the grabbed part and the elements it reached.
#include <cstdint>
#include <map>
#include <vector>

#include "cpu/storage.hpp"
#include "cpu/worker_pool.hpp"
#include "hpcm/stats.hpp"
#include "solver/bricks.hpp"
#include "solver/rules.hpp"

namespace hpcm::cpu {

class Propagation {
 public:
  void init(const Model& m, const Layout& lay, const solver::BrickGrid& grid);
  /// The bucket width of the FIXED set the next waves start from (solver::BucketWidth).
  void set_bucket_width(float delta) { delta_ = delta; }
  /// The still part of the FIXED set (not grabbed), in force from the next wave on.
  void set_still(const std::vector<Index>& still);
  /// One wave from the grabbed elements `tool` and the still part; FIXED elements are at their
  /// targets in st.p, everything else starts at st.q (u-). `wall` in lattice coordinates (each
  /// element gets its own, solver::element_wall). Marks the bricks it moves in `touched` and `hot`.
  PropagateStats run(Storage& st, const std::vector<Index>& tool, const solver::Wall& wall, int max_sweeps,
                     std::vector<std::uint8_t>& touched, std::vector<std::uint8_t>& hot, WorkerPool& pool);

 private:
  int gather(const Storage& st, Index e, solver::Neighbour* nb) const;
  void recycle(std::vector<Index>& pending);
  const Model* m_ = nullptr;
  solver::BrickGrid grid_;
  float delta_ = 1.0f;
  std::vector<std::uint8_t> final_;          ///< storage order: decided in this wave
  std::vector<Index> reached_;               ///< linear indices whose time was set in the last wave (not still ones)
  std::vector<Index> still_;                 ///< still part seeded (time 0, final) by the waves so far
  std::vector<Index> next_still_;            ///< set_still()'s, seeded by the next wave
  bool still_pending_ = false;
  std::vector<std::uint8_t> still_mark_;     ///< storage order: in still_
  // Pending elements (linear) per non-empty time bucket. Sparse: a wide w range (w_max / w_min
  // large) spreads a wave over very many bucket numbers, most of them empty; storage follows
  // the pending elements, not the highest bucket number.
  std::map<unsigned long long, std::vector<Index>> buckets_;
  std::vector<std::vector<Index>> spare_;  ///< emptied bucket lists, kept for their capacity
  std::vector<float> scratch_t_;
  std::vector<Vec3> scratch_p_;
  std::vector<std::uint8_t> chunk_any_;
};

}  // namespace hpcm::cpu
