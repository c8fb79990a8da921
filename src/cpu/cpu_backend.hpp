#pragma once
// The CPU backend: HP-ChainMail and the velocity layer over the half-split element storage
// (cpu/storage.hpp), from the shared rules of src/solver and src/dynamics, on the backend's
// own threads (cpu/worker_pool.hpp).
//
// Work follows motion. Per brick it tracks what changed: `touched` (positions changed by the
// ChainMail stage this frame: the velocity layer must visit), `hot` (relaxation must look at it
// and its face neighbours), `unchecked` (positions changed since the last link check). A brick
// that none of these mark and that carries no velocity sleeps: it costs nothing, and wakes when
// the wave, a relaxation sweep next door or the tool reaches it. X- is kept equal to X between
// frames by the layer's fused frame-end snapshot, so snapshot() has nothing left to copy.
// Backend::step runs the stages in frame order; the phases are timed by the steady clock.
#include <algorithm>
#include <chrono>
#include <memory>

#include "cpu/layer.hpp"
#include "cpu/link_check.hpp"
#include "cpu/propagate.hpp"
#include "cpu/relax.hpp"
#include "cpu/storage.hpp"
#include "cpu/worker_pool.hpp"
#include "hpcm/backend.hpp"
#include "solver/fixed_set.hpp"
#include "solver/link_restore.hpp"
#include "solver/schedule.hpp"

namespace hpcm::cpu {

class CpuBackend final : public Backend {
 public:
  BackendKind kind() const override { return BackendKind::Cpu; }
  const Model& model() const override { return *m_; }
  const Params& params() const override { return p_; }
  void snapshot() override {}
  PropagateStats propagate() override;
  RelaxStats relax(int sweeps) override;
  RestoreStats restore_links() override;
  RestoreStats restore_frame_end() override;
  void velocity_layer(SpeedStats* speeds) override;
  Index active_bricks() const override;
  Index active_elements() const override;
  void download(State& s) override { st_.store_state(s, *pool_); }
  void download_displacements(std::vector<Vec3>& disp) override { st_.store_displacements(disp, *pool_); }
  /// Copies only the bricks written since `since` (their stamp, written_).
  void download_since(State& s, std::uint64_t& since) override;
  void download_displacements_since(std::vector<Vec3>& disp, std::uint64_t& since) override;
  Vec3 displacement(Index i) override { return st_.displacement(i); }

  /// The SIMD kernels in use ("avx512", "avx2" or "sse2").
  std::string kernels() const override { return kernel_name_; }
  /// Forces the SIMD kernels ("sse2", "avx2", "avx512"; empty: the environment variable
  /// HPCM_CPU_KERNELS if set, else the best this CPU runs) from the next load() on.
  void force_kernels(const std::string& name) { forced_kernel_ = name; }
  int threads() const override { return pool_ ? pool_->threads() : 1; }
  /// Bytes per element of the backend's arrays (the model's table and per-brick data excluded).
  static std::size_t bytes_per_element() { return Storage::bytes_per_element(); }

 protected:
  void upload(const Model& m, const Params& p, const State& s) override;
  void params_changed(const Params& p) override;
  void install_fixed(const Control& c) override;
  void begin_frame() override {
    stamp_written();  // the last frame's work, before its record is cleared
    std::fill(worked_.begin(), worked_.end(), 0);
  }
  void phase_begin(Phase p) override { phase_[static_cast<int>(p)][0] = std::chrono::steady_clock::now(); }
  void phase_end(Phase p) override { phase_[static_cast<int>(p)][1] = std::chrono::steady_clock::now(); }
  double phase_ms(Phase p) override {
    const auto& t = phase_[static_cast<int>(p)];
    return std::chrono::duration<double, std::milli>(t[1] - t[0]).count();
  }

 private:
  void mark_all(std::vector<std::uint8_t>& flags) { std::fill(flags.begin(), flags.end(), 1); }
  /// Every stage writes only bricks it marks worked or touched: those get a new stamp.
  void stamp_written();
  static std::uint64_t next_stamp();
  /// The bricks written since `since` (stamp_written() first), into since_list_.
  const std::vector<Index>& written_since(std::uint64_t since);
  /// A write outside the stages (flags of a new FIXED set): element i's brick gets a stamp above
  /// every one this backend gave a host copy (the next stamp_written() takes one at least as large).
  void mark_written(Index i) { written_[static_cast<std::size_t>(grid_.brick_of_index(i))] = stamp_ + 1; }
  /// restore_links(); with `frame_end`, X- follows every element it moves.
  RestoreStats restore(bool frame_end);

  const Model* m_ = nullptr;
  Params p_;
  dynamics::LayerConstants k_{};
  solver::Wall wall_;
  Storage st_;
  solver::BrickGrid grid_;
  solver::FixedParts fixed_;            ///< the installed FIXED set: still part and tool
  std::vector<std::uint8_t> still_flags_;  ///< element order: kFixed | flags of its still entry, 0 if none
  bool still_targets_pending_ = false;     ///< the still part's targets are applied by the next propagate()
  std::vector<std::uint8_t> touched_, hot_, unchecked_;
  std::vector<std::uint8_t> worked_;  ///< bricks any stage processed this frame
  std::vector<std::uint64_t> written_;  ///< per brick: stamp of its last write (download_since)
  std::uint64_t stamp_ = 0;             ///< the latest of next_stamp() this backend took
  std::vector<Index> since_list_;
  std::unique_ptr<WorkerPool> pool_;
  Propagation propagation_;
  solver::BucketWidth bucket_width_;  ///< of the installed FIXED set
  Relaxation relaxation_;
  VelocityLayer layer_;
  LinkCheck check_;
  solver::LinkRestorer restorer_;
  std::vector<Index> check_list_, seeds_;
  std::vector<std::uint8_t> fold_bricks_;  ///< frame end: bricks with a + link that may fold (solver::may_fold)
  std::string forced_kernel_;
  const char* kernel_name_ = "";
  std::chrono::steady_clock::time_point phase_[kPhaseCount][2];  ///< begin and end of each Phase
};

}  // namespace hpcm::cpu
