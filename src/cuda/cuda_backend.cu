// The CUDA backend (issue 5): the executor of device_backend.hpp on a real device.
//
// Every kernel below is a thin wrapper around a body of kernels.hpp (shared with the host
// emulation that the test suite runs without a GPU). Every CUDA call is checked; allocation
// failures report the bytes requested. Launch overhead: propagation is one single-block kernel
// for the whole wave (no host round trip per bucket); the K relaxation sweeps are captured once
// into a CUDA graph and replayed each frame, with the early exit decided on the device (the
// kernels of the sweeps after the exit return at once).
#include <cuda_runtime.h>

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cuda/cuda_backend.hpp"
#include "cuda/device_backend.hpp"

namespace hpcm {
namespace gpu {
namespace {

std::string cuda_message(cudaError_t e) { return std::string(cudaGetErrorName(e)) + " (" + cudaGetErrorString(e) + ")"; }

void check(cudaError_t e, const char* what, const char* file, int line) {
  if (e == cudaSuccess) return;
  throw Error(std::string("CUDA error: ") + what + " failed at " + file + ":" + std::to_string(line) + ": " + cuda_message(e));
}
#define HPCM_CUDA(call) ::hpcm::gpu::check((call), #call, __FILE__, __LINE__)
#define HPCM_LAUNCHED(name) ::hpcm::gpu::check(cudaGetLastError(), "launch of " name, __FILE__, __LINE__)

/// The Block policy of kernels.hpp on the device: each() = run, then __syncthreads().
struct DevBlock {
  template <class F>
  __host__ __device__ void each(F&& f) {
#if defined(__CUDA_ARCH__)
    f(static_cast<int>(threadIdx.x));
    __syncthreads();
#endif
  }
  __host__ __device__ int threads() const {
#if defined(__CUDA_ARCH__)
    return static_cast<int>(blockDim.x);
#else
    return 1;
#endif
  }
  __host__ __device__ int block() const {
#if defined(__CUDA_ARCH__)
    return static_cast<int>(blockIdx.x);
#else
    return 0;
#endif
  }
  __host__ __device__ int blocks() const {
#if defined(__CUDA_ARCH__)
    return static_cast<int>(gridDim.x);
#else
    return 1;
#endif
  }
};

__device__ __forceinline__ long long global_id() { return static_cast<long long>(blockIdx.x) * blockDim.x + threadIdx.x; }

// ---- kernels ------------------------------------------------------------------------------
__global__ void __launch_bounds__(kBrickThreads) k_set_fixed(FixedArgs a) {
  DevBlock b;
  set_fixed_block(a, b);
}
__global__ void __launch_bounds__(kBrickThreads) k_apply_targets(FixedArgs a) {
  DevBlock b;
  apply_targets_block(a, b);
}
__global__ void __launch_bounds__(kBrickThreads) k_reset_wave(Lattice L) {
  DevBlock b;
  reset_wave_block(L, static_cast<long long>(blockIdx.x), b);
}
__global__ void __launch_bounds__(kPropThreads) k_propagate(PropArgs a) {
  __shared__ PropShared sh;
  DevBlock b;
  propagate_block(a, sh, b);
}
__global__ void k_count_touched(Lattice L, PropCtl* ctl) {
  const long long b = global_id();
  if (b < L.grid.count) count_touched_thread(L, b, ctl);
}
__global__ void k_full_reset(Lattice L) {
  for (long long i = global_id(); i < L.n; i += static_cast<long long>(gridDim.x) * blockDim.x) full_reset_element(L, i);
}
__global__ void k_relax_begin(RelaxArgs a) {
  const int n = relax_begin_threads(a);
  for (int j = static_cast<int>(threadIdx.x); j < n; j += static_cast<int>(blockDim.x)) relax_begin_thread(a, j);
}
__global__ void k_relax_start(RelaxArgs a) { relax_start_thread(a, global_id()); }
__global__ void k_relax_list(RelaxArgs a, int p) { relax_list_thread(a, p, global_id()); }
__global__ void k_relax_finish(RelaxArgs a) { relax_finish_thread(a, global_id()); }
__global__ void __launch_bounds__(kBrickThreads) k_relax_colour(RelaxArgs a, int p) {
  __shared__ RelaxShared sh;
  DevBlock b;
  relax_colour_block(a, p, sh, b);
}
__global__ void k_relax_end(RelaxArgs a, int p) {
  if (global_id() == 0) relax_end_thread(a, p);
}
__global__ void __launch_bounds__(kBrickThreads) k_layer(LayerArgs a) {
  __shared__ LayerShared sh;
  DevBlock b;
  layer_block(a, static_cast<long long>(blockIdx.x), sh, b);
}
__global__ void __launch_bounds__(kReduceThreads) k_speed_sum(LayerArgs a) {
  __shared__ SpeedShared sh;
  DevBlock b;
  speed_sum_block(a, sh, b);
}
__global__ void __launch_bounds__(kBrickThreads) k_check_links(CheckArgs a) {
  DevBlock b;
  check_links_block(a, static_cast<long long>(blockIdx.x), b);
}
__global__ void __launch_bounds__(kBrickThreads) k_gather_bricks(GatherArgs a) {
  DevBlock b;
  gather_brick_block(a, static_cast<long long>(blockIdx.x), b);
}
__global__ void k_scatter_positions(ScatterArgs a) { scatter_position_thread(a, global_id()); }
__global__ void k_probe() {}

unsigned grid_for(long long n, int threads) {
  return static_cast<unsigned>(std::max<long long>(1, (n + threads - 1) / threads));
}

// ---- the executor ---------------------------------------------------------------------------
class GpuExec {
 public:
  GpuExec() {
    HPCM_CUDA(cudaGetDevice(&dev_));
    cudaDeviceProp pr{};
    HPCM_CUDA(cudaGetDeviceProperties(&pr, dev_));
    sms_ = std::max(1, pr.multiProcessorCount);
    name_ = std::string(pr.name) + " (sm_" + std::to_string(pr.major) + std::to_string(pr.minor) + ", " +
            std::to_string(sms_) + " SMs)";
    HPCM_CUDA(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
    for (auto& e : ev_) HPCM_CUDA(cudaEventCreate(&e));
  }
  ~GpuExec() {
    invalidate();
    for (auto& e : ev_)
      if (e) cudaEventDestroy(e);
    if (stream_) cudaStreamDestroy(stream_);
  }
  GpuExec(const GpuExec&) = delete;
  GpuExec& operator=(const GpuExec&) = delete;

  void* alloc(std::size_t bytes, const char* what) {
    void* p = nullptr;
    const cudaError_t e = cudaMalloc(&p, bytes);
    if (e == cudaErrorMemoryAllocation) {
      cudaGetLastError();  // clear the sticky-free error
      std::size_t free_b = 0, total_b = 0;
      cudaMemGetInfo(&free_b, &total_b);
      throw Error("CUDA out of memory: cudaMalloc of " + std::to_string(bytes) + " bytes for " + what + " failed (" +
                  std::to_string(free_b) + " of " + std::to_string(total_b) + " bytes free on the device)");
    }
    check(e, (std::string("cudaMalloc for ") + what).c_str(), __FILE__, __LINE__);
    return p;
  }
  void release(void* p) noexcept {
    if (p) cudaFree(p);
  }
  /// Pinned (page-locked) host memory: copies to and from it run at the bus's full speed.
  void* host_alloc(std::size_t bytes, const char* what) {
    void* p = nullptr;
    const cudaError_t e = cudaMallocHost(&p, bytes);
    if (e != cudaSuccess) {
      cudaGetLastError();
      throw Error("CUDA: cudaMallocHost of " + std::to_string(bytes) + " bytes (pinned " + what + ") failed: " + cuda_message(e));
    }
    return p;
  }
  void host_release(void* p) noexcept {
    if (p) cudaFreeHost(p);
  }
  void upload(void* d, const void* h, std::size_t n) {
    if (n) HPCM_CUDA(cudaMemcpyAsync(d, h, n, cudaMemcpyHostToDevice, stream_));
  }
  void download(void* h, const void* d, std::size_t n) {
    if (n) HPCM_CUDA(cudaMemcpyAsync(h, d, n, cudaMemcpyDeviceToHost, stream_));
  }
  void copy(void* d, const void* s, std::size_t n) {
    if (n) HPCM_CUDA(cudaMemcpyAsync(d, s, n, cudaMemcpyDeviceToDevice, stream_));
  }
  void zero(void* d, std::size_t n) {
    if (n) HPCM_CUDA(cudaMemsetAsync(d, 0, n, stream_));
  }
  void sync() { HPCM_CUDA(cudaStreamSynchronize(stream_)); }
  void invalidate() noexcept {
    for (auto& g : graphs_) cudaGraphExecDestroy(g.second);
    graphs_.clear();
  }

  void set_fixed(const FixedArgs& a) {
    k_set_fixed<<<1, kBrickThreads, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_set_fixed");
  }
  void apply_targets(const FixedArgs& a) {
    if (a.n == 0) return;
    k_apply_targets<<<1, kBrickThreads, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_apply_targets");
  }
  void reset_wave(const Lattice& L) {
    k_reset_wave<<<static_cast<unsigned>(L.grid.count), kBrickThreads, 0, stream_>>>(L);
    HPCM_LAUNCHED("k_reset_wave");
  }
  void propagate(const PropArgs& a) {
    k_propagate<<<1, kPropThreads, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_propagate");
  }
  void count_touched(const Lattice& L, PropCtl* ctl) {
    k_count_touched<<<grid_for(L.grid.count, 256), 256, 0, stream_>>>(L, ctl);
    HPCM_LAUNCHED("k_count_touched");
  }
  void full_reset(const Lattice& L) {
    k_full_reset<<<static_cast<unsigned>(std::min<long long>(grid_for(L.n, 256), 65535)), 256, 0, stream_>>>(L);
    HPCM_LAUNCHED("k_full_reset");
  }
  /// K relaxation sweeps: captured into a CUDA graph on first use of K, replayed after.
  void relax(const RelaxArgs& a) {
    auto it = graphs_.find(a.sweeps);
    if (it == graphs_.end()) {
      cudaGraph_t g = nullptr;
      HPCM_CUDA(cudaStreamBeginCapture(stream_, cudaStreamCaptureModeThreadLocal));
      try {
        enqueue_relax(a);
      } catch (...) {
        cudaStreamEndCapture(stream_, &g);
        if (g) cudaGraphDestroy(g);
        throw;
      }
      HPCM_CUDA(cudaStreamEndCapture(stream_, &g));
      cudaGraphExec_t ex = nullptr;
      const cudaError_t e = cudaGraphInstantiate(&ex, g, 0);
      cudaGraphDestroy(g);
      HPCM_CUDA(e);
      it = graphs_.emplace(a.sweeps, ex).first;
    }
    HPCM_CUDA(cudaGraphLaunch(it->second, stream_));
  }
  void check_links(const CheckArgs& a) {
    k_check_links<<<static_cast<unsigned>(a.L.grid.count), kBrickThreads, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_check_links");
  }
  void gather_bricks(const GatherArgs& a) {
    if (a.n == 0) return;
    k_gather_bricks<<<static_cast<unsigned>(a.n), kBrickThreads, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_gather_bricks");
  }
  void scatter_positions(const ScatterArgs& a) {
    if (a.n == 0) return;
    k_scatter_positions<<<grid_for(a.n, 256), 256, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_scatter_positions");
  }
  void layer(const LayerArgs& a) {
    k_layer<<<static_cast<unsigned>(a.L.grid.count), kBrickThreads, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_layer");
  }
  void speed_sum(const LayerArgs& a) {
    k_speed_sum<<<1, kReduceThreads, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_speed_sum");
  }
  void mark(int slot) { HPCM_CUDA(cudaEventRecord(ev_[slot], stream_)); }
  double elapsed(int a, int b) {
    HPCM_CUDA(cudaEventSynchronize(ev_[b]));
    float ms = 0;
    HPCM_CUDA(cudaEventElapsedTime(&ms, ev_[a], ev_[b]));
    return ms;
  }

  /// Dense fused-layer passes and device-to-device copies of the positions, CUDA events.
  DeviceProbe probe(const LayerArgs& a, int reps, std::size_t held) {
    DeviceProbe p;
    p.available = true;
    p.device = name_;
    p.device_bytes = held;
    const double n = static_cast<double>(a.L.n);
    // Fused layer per element: reads X+, X-, V (36 B), tissue + flags (2 B); writes V, X, X- (36 B).
    p.layer_bytes = n * 74.0;
    std::vector<double> t;
    sync();
    for (int r = 0; r <= reps; ++r) {  // r = 0: warm-up
      HPCM_CUDA(cudaEventRecord(ev_[kProbeBegin], stream_));
      layer(a);
      HPCM_CUDA(cudaEventRecord(ev_[kProbeEnd], stream_));
      const double ms = elapsed(kProbeBegin, kProbeEnd);
      if (r > 0) t.push_back(ms);
    }
    p.layer_ms = median(t);
    const std::size_t bytes = static_cast<std::size_t>(a.L.n) * sizeof(Vec3);
    void* tmp = alloc(bytes, "bandwidth probe (copy target)");
    t.clear();
    try {
      for (int r = 0; r <= reps; ++r) {
        HPCM_CUDA(cudaEventRecord(ev_[kProbeBegin], stream_));
        copy(tmp, a.L.disp, bytes);
        HPCM_CUDA(cudaEventRecord(ev_[kProbeEnd], stream_));
        const double ms = elapsed(kProbeBegin, kProbeEnd);
        if (r > 0) t.push_back(ms);
      }
    } catch (...) {
      release(tmp);
      throw;
    }
    sync();
    release(tmp);
    p.copy_ms = median(t);
    p.copy_bytes = 2.0 * static_cast<double>(bytes);  // read + write
    return p;
  }

 private:
  static double median(std::vector<double> v) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    const std::size_t h = v.size() / 2;
    return v.size() % 2 ? v[h] : 0.5 * (v[h - 1] + v[h]);
  }
  void enqueue_relax(const RelaxArgs& a) {
    const long long nb = a.L.grid.count;
    const unsigned brick_grid = grid_for(nb, 256);
    const unsigned colour_grid = static_cast<unsigned>(std::min<long long>(nb, 8LL * sms_));
    k_relax_begin<<<1, 256, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_relax_begin");
    k_relax_start<<<brick_grid, 256, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_relax_start");
    for (int p = 0; p < 2 * a.sweeps; ++p) {
      k_relax_list<<<brick_grid, 256, 0, stream_>>>(a, p);
      HPCM_LAUNCHED("k_relax_list");
      k_relax_colour<<<colour_grid, kBrickThreads, 0, stream_>>>(a, p);
      HPCM_LAUNCHED("k_relax_colour");
      k_relax_end<<<1, 32, 0, stream_>>>(a, p);
      HPCM_LAUNCHED("k_relax_end");
    }
    k_relax_finish<<<brick_grid, 256, 0, stream_>>>(a);
    HPCM_LAUNCHED("k_relax_finish");
  }

  int dev_ = 0, sms_ = 1;
  std::string name_;
  cudaStream_t stream_ = nullptr;
  // Events 0-7: the frame's phases (two per Phase, DeviceBackend::phase_begin); 8-9: the probe.
  static constexpr int kProbeBegin = 2 * kPhaseCount, kProbeEnd = 2 * kPhaseCount + 1;
  cudaEvent_t ev_[2 * kPhaseCount + 2] = {};
  std::map<int, cudaGraphExec_t> graphs_;
};

}  // namespace
}  // namespace gpu

bool cuda_device_present(std::string* why) {
  int n = 0;
  cudaError_t e = cudaGetDeviceCount(&n);
  if (e != cudaSuccess || n == 0) {
    if (why) {
      if (e == cudaErrorInsufficientDriver || e == cudaErrorNoDevice)
        *why = "no usable NVIDIA GPU or driver on this machine (cudaGetDeviceCount: " + gpu::cuda_message(e) + ")";
      else
        *why = e != cudaSuccess ? "cudaGetDeviceCount: " + gpu::cuda_message(e) : std::string("cudaGetDeviceCount found no device");
    }
    cudaGetLastError();
    return false;
  }
  int dev = 0;
  cudaDeviceProp pr{};
  e = cudaGetDevice(&dev);
  if (e == cudaSuccess) e = cudaGetDeviceProperties(&pr, dev);
  if (e != cudaSuccess) {
    if (why) *why = "cudaGetDeviceProperties: " + gpu::cuda_message(e);
    cudaGetLastError();
    return false;
  }
  // The build holds sm_90 code and compute_90 PTX by default: older devices cannot run it.
  cudaFuncAttributes fa{};
  e = cudaFuncGetAttributes(&fa, gpu::k_probe);
  if (e != cudaSuccess) {
    if (why)
      *why = std::string("device ") + std::to_string(dev) + " (" + pr.name + ", compute capability " +
             std::to_string(pr.major) + "." + std::to_string(pr.minor) +
             ") cannot run this build's kernels (built for CMAKE_CUDA_ARCHITECTURES; rebuild for this device): " +
             gpu::cuda_message(e);
    cudaGetLastError();
    return false;
  }
  return true;
}

std::unique_ptr<Backend> make_cuda_backend() { return std::make_unique<gpu::DeviceBackend<gpu::GpuExec>>(); }

}  // namespace hpcm
