#pragma once
// Sequential host emulation of the CUDA backend's executor (see device_backend.hpp): the same
// kernel bodies (kernels.hpp) and the same host orchestration, with host memory and loops over
// blocks and threads instead of launches. It exists so that the device algorithm is tested
// against the CPU backend on machines without a GPU (tests/cuda/test_cuda_emulation.cpp).
// It checks the schedule and the arithmetic, not what only hardware shows (races, atomics
// interleaving, launch configuration): the GPU parity suite does that where a device exists.
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <algorithm>
#include <memory>
#include <new>

#include "cuda/device_backend.hpp"

namespace hpcm::gpu {

/// One emulated thread block: each() runs f(tid) for every thread in turn (then "barrier").
struct HostBlock {
  int T = 1, bid = 0, nb = 1;
  template <class F>
  void each(F&& f) {
    for (int t = 0; t < T; ++t) f(t);
  }
  int threads() const { return T; }
  int block() const { return bid; }
  int blocks() const { return nb; }
};

class EmuExec {
 public:
  // Emulated block sizes: smaller than on the GPU (the host loops over every thread of every
  // phase), powers of two as the tree reductions need; any size gives the same result.
  static constexpr int kPropT = 32, kBrickT = 64, kReduceT = 64;

  /// `blocks` emulated blocks for grid-stride kernels (any value gives the same result).
  explicit EmuExec(int blocks = 3) : blocks_(blocks) {}

  void* alloc(std::size_t bytes, const char* what) {
    void* p = std::aligned_alloc(64, (bytes + 63) / 64 * 64);
    if (!p) throw Error(std::string("emulated device: out of memory: ") + std::to_string(bytes) + " bytes requested for " + what);
    std::memset(p, 0xA5, bytes);  // garbage, as cudaMalloc gives
    return p;
  }
  void release(void* p) noexcept { std::free(p); }
  void* host_alloc(std::size_t bytes, const char* what) { return alloc(bytes, what); }
  void host_release(void* p) noexcept { std::free(p); }
  void upload(void* d, const void* h, std::size_t n) { if (n) std::memcpy(d, h, n); }
  void download(void* h, const void* d, std::size_t n) { if (n) std::memcpy(h, d, n); }
  void copy(void* d, const void* s, std::size_t n) { if (n) std::memmove(d, s, n); }
  void zero(void* d, std::size_t n) { if (n) std::memset(d, 0, n); }
  void sync() {}
  void invalidate() {}

  void set_fixed(const FixedArgs& a) {
    HostBlock b{kBrickT, 0, 1};
    set_fixed_block(a, b);
  }
  void apply_targets(const FixedArgs& a) {
    HostBlock b{kBrickT, 0, 1};
    apply_targets_block(a, b);
  }
  void reset_wave(const Lattice& L) {
    for (long long br = 0; br < L.grid.count; ++br) {
      HostBlock b{kBrickT, static_cast<int>(br), static_cast<int>(L.grid.count)};
      reset_wave_block(L, br, b);
    }
  }
  void propagate(const PropArgs& a) {
    PropShared sh{};
    HostBlock b{kPropT, 0, 1};
    propagate_block(a, sh, b);
  }
  void count_touched(const Lattice& L, PropCtl* ctl) {
    for (long long br = 0; br < L.grid.count; ++br) count_touched_thread(L, br, ctl);
  }
  void full_reset(const Lattice& L) {
    for (long long i = 0; i < L.n; ++i) full_reset_element(L, i);
  }
  void relax(const RelaxArgs& a) {
    for (int j = 0; j < relax_begin_threads(a); ++j) relax_begin_thread(a, j);
    for (long long br = 0; br < a.L.grid.count; ++br) relax_start_thread(a, br);
    for (int p = 0; p < 2 * a.sweeps; ++p) {
      for (long long br = 0; br < a.L.grid.count; ++br) relax_list_thread(a, p, br);
      for (int bid = 0; bid < blocks_; ++bid) {
        RelaxShared sh{};
        HostBlock b{kBrickT, bid, blocks_};
        relax_colour_block(a, p, sh, b);
      }
      relax_end_thread(a, p);
    }
    for (long long br = 0; br < a.L.grid.count; ++br) relax_finish_thread(a, br);
  }
  void check_links(const CheckArgs& a) {
    for (long long br = 0; br < a.L.grid.count; ++br) {
      HostBlock b{kBrickT, static_cast<int>(br), static_cast<int>(a.L.grid.count)};
      check_links_block(a, br, b);
    }
  }
  void gather_bricks(const GatherArgs& a) {
    for (long long j = 0; j < a.n; ++j) {
      HostBlock b{kBrickT, static_cast<int>(j), a.n};
      gather_brick_block(a, j, b);
    }
  }
  void scatter_positions(const ScatterArgs& a) {
    for (long long j = 0; j < a.n; ++j) scatter_position_thread(a, j);
  }
  void layer(const LayerArgs& a) {
    auto sh = std::make_unique<LayerShared>();
    for (long long br = 0; br < a.L.grid.count; ++br) {
      HostBlock b{kBrickT, static_cast<int>(br), static_cast<int>(a.L.grid.count)};
      layer_block(a, br, *sh, b);
    }
  }
  void speed_sum(const LayerArgs& a) {
    auto sh = std::make_unique<SpeedShared>();
    HostBlock b{kReduceT, 0, 1};
    speed_sum_block(a, *sh, b);
  }
  void mark(int slot) { marks_[slot] = std::chrono::steady_clock::now(); }
  double elapsed(int a, int b) { return std::chrono::duration<double, std::milli>(marks_[b] - marks_[a]).count(); }
  DeviceProbe probe(const LayerArgs&, int, std::size_t held) {
    DeviceProbe p;
    p.device = "host emulation";
    p.device_bytes = held;
    return p;  // available = false: no device timings in the emulation
  }

 private:
  int blocks_;
  std::chrono::steady_clock::time_point marks_[2 * kPhaseCount + 2];  ///< as GpuExec's events
};

/// The CUDA backend's algorithm on the host (for tests).
inline std::unique_ptr<Backend> make_emulated_backend(int blocks = 3) {
  return std::make_unique<DeviceBackend<EmuExec>>(blocks);
}

}  // namespace hpcm::gpu
