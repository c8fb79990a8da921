#pragma once
// The CPU backend: HP-ChainMail and the velocity layer over host arrays, from the shared rules
// of src/solver and src/dynamics. X- is kept equal to X between frames by the layer's fused frame-end snapshot, so
// snapshot() has nothing left to copy.
#include <chrono>

#include "cpu/chainmail_cpu.hpp"
#include "cpu/velocity_layer_cpu.hpp"
#include "hpcm/backend.hpp"
#include "solver/link_restore.hpp"

namespace hpcm::cpu {

class CpuBackend final : public Backend {
 public:
  BackendKind kind() const override { return BackendKind::Cpu; }
  void load(const Model& m, const Params& p, const State& s) override;
  void set_params(const Params& p) override;
  void set_fixed(const std::vector<Index>& elements, const std::vector<Vec3>& targets,
                 const std::vector<std::uint8_t>& flags) override;
  void snapshot() override {}
  PropagateStats propagate() override;
  RelaxStats relax(int sweeps) override;
  RestoreStats restore_links() override;
  void velocity_layer(SpeedStats* speeds) override;
  Index active_bricks() const override { return active_; }
  void mark(int slot) override;
  double elapsed_ms(int from_slot, int to_slot) override;
  void download(State& s) override;
  void download_positions(std::vector<Vec3>& pos) override { pos = pos_; }
  Vec3 position(Index i) override { return pos_[static_cast<std::size_t>(i)]; }

 private:
  const Model* m_ = nullptr;
  Params p_;
  dynamics::LayerConstants k_{};
  std::vector<Vec3> pos_, pre_, vel_;
  std::vector<float> time_;
  std::vector<std::uint8_t> flags_;
  std::vector<Index> fixed_;
  std::vector<Vec3> targets_;
  ChainMailCpu chainmail_;
  VelocityLayerCpu layer_;
  solver::LinkRestorer restorer_;
  std::vector<std::uint8_t> unchecked_;  ///< bricks whose positions changed since the last link check
  std::vector<Index> check_list_;
  Index active_ = 0;
  std::chrono::steady_clock::time_point marks_[8];
};

}  // namespace hpcm::cpu
