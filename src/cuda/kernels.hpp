#pragma once
// The device-side algorithm of the CUDA backend, written as HPCM_HD "kernel bodies".
//
// Every kernel of src/cuda is a thin __global__ wrapper around one of the bodies below. A body
// that needs block-wide barriers is a template over a Block policy: `blk.each(f)` runs f(tid)
// for every thread of the block and then synchronises (on the GPU: f(threadIdx.x) followed by
// __syncthreads(); in the host emulation of src/cuda/emulation.hpp: a loop over tid). The same
// code therefore runs on the GPU and, sequentially, on the CPU, where the test suite checks it
// against the CPU backend even on machines without a GPU (tests/cuda/test_cuda_emulation.cpp).
//
// The per-element rules are not repeated here: they come from solver/rules.hpp (propagation,
// relaxation, deformation boxes) and dynamics/velocity_update.hpp (the velocity layer), which are
// HPCM_HD and shared with the CPU backend. What is here is the schedule: buckets, brick lists,
// red-black colouring, reductions, and the per-element memory layout.
#include <cstdint>

#include "dynamics/velocity_update.hpp"
#include "hpcm/state.hpp"
#include "solver/bricks.hpp"
#include "solver/neighbours.hpp"
#include "solver/restore.hpp"
#include "solver/rules.hpp"

namespace hpcm::gpu {

// ---------------------------------------------------------------------------------------------
// Constants and small helpers
// ---------------------------------------------------------------------------------------------

/// Internal flag bits (besides kFixed/kGrabbed/kAnchor of state.hpp); never downloaded.
inline constexpr std::uint8_t kFinalBit = 0x80;   ///< decided in the current wave
inline constexpr std::uint8_t kListedBit = 0x40;  ///< in the current bucket's list
inline constexpr std::uint8_t kInternalBits = kFinalBit | kListedBit;

inline constexpr int kMaxSweeps = 256;         ///< SolverParams::relax_sweeps upper bound
inline constexpr int kPropThreads = 512;       ///< the single-block propagation kernel
inline constexpr int kBrickThreads = 256;      ///< brick kernels (relaxation, velocity layer)
inline constexpr int kReduceThreads = 256;     ///< single-block reductions

// Atomics: device atomics on the GPU, plain operations in the (sequential) host emulation.
HPCM_HD inline int at_add(int* p, int v) {
#if defined(__CUDA_ARCH__)
  return atomicAdd(p, v);
#else
  const int o = *p;
  *p = o + v;
  return o;
#endif
}
HPCM_HD inline void at_min_u64(unsigned long long* p, unsigned long long v) {
#if defined(__CUDA_ARCH__)
  atomicMin(p, v);
#else
  if (v < *p) *p = v;
#endif
}
HPCM_HD inline void at_max_u32(unsigned* p, unsigned v) {
#if defined(__CUDA_ARCH__)
  atomicMax(p, v);
#else
  if (v > *p) *p = v;
#endif
}
/// Atomic test-and-set of `bit` in byte i of a byte array that is 4-byte aligned and padded to
/// a multiple of 4 bytes. Returns whether the bit was already set.
HPCM_HD inline bool test_and_set_bit(std::uint8_t* base, long long i, std::uint8_t bit) {
#if defined(__CUDA_ARCH__)
  unsigned* word = reinterpret_cast<unsigned*>(base + (i & ~3LL));
  const unsigned m = static_cast<unsigned>(bit) << (8u * static_cast<unsigned>(i & 3));
  return (atomicOr(word, m) & m) != 0u;
#else
  const bool old = (base[i] & bit) != 0;
  base[i] = static_cast<std::uint8_t>(base[i] | bit);
  return old;
#endif
}
/// Bits of a non-negative float: ordered like the float, so atomicMax on them is a float max.
HPCM_HD inline unsigned float_bits(float f) {
#if defined(__CUDA_ARCH__)
  return __float_as_uint(f);
#else
  unsigned u;
  __builtin_memcpy(&u, &f, sizeof u);
  return u;
#endif
}
HPCM_HD inline float bits_float(unsigned u) {
#if defined(__CUDA_ARCH__)
  return __uint_as_float(u);
#else
  float f;
  __builtin_memcpy(&f, &u, sizeof f);
  return f;
#endif
}

// ---------------------------------------------------------------------------------------------
// Lattice on the device
// ---------------------------------------------------------------------------------------------

/// Device pointers and geometry, passed by value to every kernel.
/// Per element: disp, pre, vel 3 x 12 B, time 4, tau 4, link index 3 x 2, tissue 1, statistics
/// class 1, flags 1 = 53 bytes, plus the Model's link table (at most 65,536 x 16 bytes).
struct Lattice {
  int nx = 0, ny = 0, nz = 0;
  long long n = 0;
  solver::BrickGrid grid;  ///< brick geometry, shared with the CPU backend
  Vec3* disp = nullptr;  ///< u = X - X0, displacements from rest (u+ after ChainMail)
  Vec3* pre = nullptr;   ///< u- (pre-ChainMail snapshot; equal to u between frames)
  Vec3* vel = nullptr;   ///< V
  float* time = nullptr;
  std::uint8_t* flags = nullptr;  ///< ElementFlags | internal bits; 4-byte aligned, padded
  const float* tau = nullptr;     ///< element tolerance (relaxation weights)
  const std::uint8_t* tissue = nullptr;
  /// Tissue, or kTissueCount outside the body (SPEC §3): the class whose speed statistics count it.
  const std::uint8_t* stat_class = nullptr;
  const std::uint16_t* link_index[3] = {nullptr, nullptr, nullptr};  ///< Model::link_index
  const LinkLimits* link_table = nullptr;                            ///< Model::link_table
  // per brick
  std::uint8_t* touched = nullptr;  ///< positions changed this frame (velocity layer must visit)
  std::uint8_t* hot = nullptr;      ///< relaxation must look at it (and its face neighbours)
  std::uint8_t* has_vel = nullptr;  ///< carries velocity (velocity layer must visit)
  std::uint8_t* wave = nullptr;     ///< holds elements with a finite time of the last wave
  std::uint8_t* unchecked = nullptr;  ///< positions changed since the last link check (restoration)
  float* speed = nullptr;             ///< largest |V| (before the clamp) of the brick's last visit
  /// Some stage worked on it this frame (the active bricks are their union, as on the CPU).
  std::uint8_t* worked = nullptr;

  HPCM_HD long long index(int x, int y, int z) const { return x + static_cast<long long>(nx) * (y + static_cast<long long>(ny) * z); }
  HPCM_HD void coords(long long i, int& x, int& y, int& z) const {
    x = static_cast<int>(i % nx);
    const long long r = i / nx;
    y = static_cast<int>(r % ny);
    z = static_cast<int>(r / ny);
  }
  HPCM_HD long long brick_of_index(long long i) const { return grid.brick_of_index(i); }
  /// Element range [lo, hi) of brick b.
  HPCM_HD void brick_range(long long b, int lo[3], int hi[3]) const {
    Int3 l, h;
    grid.range(b, l, h);
    lo[0] = l.x, lo[1] = l.y, lo[2] = l.z;
    hi[0] = h.x, hi[1] = h.y, hi[2] = h.z;
  }
  /// Limits of the link along axis a between element lo and its + neighbour hi.
  HPCM_HD LinkLimits link_of(int a, long long lo, long long) const { return link_table[link_index[a][lo]]; }
};

/// ChainMailCpu::gather on the device layout: the shared face-neighbour walk.
HPCM_HD inline int gather(const Lattice& L, int x, int y, int z, long long i, solver::Neighbour* nb) {
  int c = 0;
  solver::for_each_face_neighbour(L.nx, L.ny, L.nz, x, y, z, i, [&](long long n, int axis, int side, long long lo, long long hi) {
    nb[c].idx = n;
    nb[c].axis = axis;
    nb[c].side = side;
    nb[c].L = L.link_of(axis, lo, hi);
    nb[c].t = L.time[n];
    nb[c].tau = L.tau[n];
    nb[c].p = L.disp[n];
    ++c;
  });
  return c;
}

// ---------------------------------------------------------------------------------------------
// Fixed set and targets
// ---------------------------------------------------------------------------------------------

struct FixedArgs {
  Lattice L;
  const int* old_fixed = nullptr;
  int n_old = 0;
  const int* fixed = nullptr;         ///< new FIXED set (no duplicates)
  const std::uint8_t* fflags = nullptr;
  const Vec3* targets = nullptr;
  int n = 0;
};

/// set_fixed: the previous FIXED set is released (flags 0), then the new one set.
template <class B>
HPCM_HD void set_fixed_block(const FixedArgs& a, B& blk) {
  const int T = blk.threads();
  blk.each([&](int tid) {
    for (int j = tid; j < a.n_old; j += T) a.L.flags[a.old_fixed[j]] = 0;
  });
  blk.each([&](int tid) {
    for (int j = tid; j < a.n; j += T) a.L.flags[a.fixed[j]] = static_cast<std::uint8_t>(kFixed | a.fflags[j]);
  });
  // Elements released from FIXED must be relaxed again (as CpuBackend::install_fixed does).
  blk.each([&](int tid) {
    for (int j = tid; j < a.n_old; j += T) {
      const long long i = a.old_fixed[j];
      if (!(a.L.flags[i] & kFixed)) {
        const long long b = a.L.brick_of_index(i);
        a.L.touched[b] = 1;
        a.L.hot[b] = 1;
      }
    }
  });
}

/// Grabbed / anchored elements go to their targets; their bricks become touched and hot.
template <class B>
HPCM_HD void apply_targets_block(const FixedArgs& a, B& blk) {
  const int T = blk.threads();
  blk.each([&](int tid) {
    for (int j = tid; j < a.n; j += T) {
      const long long i = a.fixed[j];
      if (!(a.L.disp[i] == a.targets[j])) {
        a.L.disp[i] = a.targets[j];
        const long long b = a.L.brick_of_index(i);
        a.L.touched[b] = 1;
        a.L.hot[b] = 1;
      }
    }
  });
}

// ---------------------------------------------------------------------------------------------
// Propagation: the bucketed schedule of src/cpu/chainmail_propagate.cpp on one thread block
// ---------------------------------------------------------------------------------------------

struct PropCtl {
  int sweeps = 0;     ///< Jacobi passes over all buckets
  int converged = 1;
  int reached = 0;
  int overflow = 0;   ///< a pending or bucket list was too small: grow and rerun
  int active = 0;     ///< touched bricks after the wave
  int buckets = 0;    ///< non-empty buckets processed
};

struct PropArgs {
  Lattice L;
  const int* fixed = nullptr;
  int nfixed = 0;
  int* pend_e[2] = {nullptr, nullptr};                 ///< pending (element, bucket) pushes
  unsigned long long* pend_b[2] = {nullptr, nullptr};
  int pend_cap = 0;
  int* list = nullptr;  ///< the current bucket's elements
  float* st = nullptr;  ///< Jacobi scratch per list entry
  Vec3* sp = nullptr;
  int list_cap = 0;
  double delta = 1.0;   ///< bucket width (smallest link w), as ChainMailCpu
  solver::Wall wall;    ///< boundary box of every clamp (lattice coordinates; per element: solver::element_wall)
  int max_sweeps = 0;
  PropCtl* ctl = nullptr;
};

struct PropShared {
  unsigned long long kmin;
  int np_in, np_out, nl, any, overflow, cur, reached;
};

// The bucket schedule's rule (bucket_of, propagate_in_bucket) is shared with the CPU solver.
using solver::bucket_of;
using solver::propagate_in_bucket;

/// Appends one pending entry to the output buffer.
HPCM_HD inline void pend_put(const PropArgs& a, PropShared& sh, int e, unsigned long long b) {
  const int s = at_add(&sh.np_out, 1);
  if (s < a.pend_cap) {
    const int out = sh.cur ^ 1;
    a.pend_e[out][s] = e;
    a.pend_b[out][s] = b;
  } else {
    sh.overflow = 1;
  }
}

/// push_neighbours of propagate.cpp. Pushes into buckets below `processed` are dropped: the CPU
/// files them into buckets its loop has already passed, which are never processed again. A
/// push into bucket `processed` itself (float rounding of t + w) is kept: the CPU decides that
/// bucket again before moving on, and so does the next round here (its smallest bucket).
HPCM_HD inline void push_neighbours(const PropArgs& a, PropShared& sh, long long i, float t, long long processed) {
  const Lattice& L = a.L;
  int x, y, z;
  L.coords(i, x, y, z);
  solver::for_each_face_neighbour(L.nx, L.ny, L.nz, x, y, z, i, [&](long long n, int axis, int, long long lo, long long hi) {
    if (L.flags[n] & (kFinalBit | kFixed)) return;
    const float c = t + L.link_of(axis, lo, hi).w;
    const unsigned long long b = bucket_of(c, a.delta);
    if (processed >= 0 && b < static_cast<unsigned long long>(processed)) return;
    pend_put(a, sh, static_cast<int>(n), b);
    // n's anchors' candidate times after i's key, as the CPU (propagate.cpp).
    int xn, yn, zn;
    L.coords(n, xn, yn, zn);
    solver::for_each_face_neighbour(L.nx, L.ny, L.nz, xn, yn, zn, n, [&](long long f, int af, int, long long lf, long long hf) {
      const std::uint8_t ff = L.flags[f];
      if (!(ff & kFixed) || (ff & kGrabbed)) return;
      const float cf = L.link_of(af, lf, hf).w;
      if (!(t < cf || (t == cf && i < n))) return;
      const unsigned long long bf = bucket_of(cf, a.delta);
      if (bf != b && (processed < 0 || bf >= static_cast<unsigned long long>(processed))) pend_put(a, sh, static_cast<int>(n), bf);
    });
  });
}

/// The whole wave on one block: buckets in ascending order (smallest pending bucket by a block
/// reduction), each decided by a Jacobi iteration until nothing changes, then its newly final
/// elements push their neighbours. No host round trip per bucket.
/// Precondition: the previous wave was reset (reset_wave_block), targets applied.
template <class B>
HPCM_HD void propagate_block(const PropArgs& a, PropShared& sh, B& blk) {
  const Lattice& L = a.L;
  const int T = blk.threads();
  blk.each([&](int tid) {
    if (tid == 0) {
      sh.kmin = ~0ull;
      sh.np_in = sh.np_out = sh.nl = sh.any = sh.overflow = sh.cur = sh.reached = 0;
      a.ctl->active = 0;
    }
  });
  // FIXED elements: t = 0, final (before any push, as on the CPU); the grabbed ones start the
  // wave (anchors never move).
  blk.each([&](int tid) {
    for (int j = tid; j < a.nfixed; j += T) {
      const long long f = a.fixed[j];
      L.time[f] = 0.0f;
      L.flags[f] = static_cast<std::uint8_t>(L.flags[f] | kFinalBit);
      const long long b = L.brick_of_index(f);
      L.wave[b] = 1;
      if (L.flags[f] & kGrabbed) {
        L.touched[b] = 1;
        L.hot[b] = 1;
      }
    }
  });
  blk.each([&](int tid) {
    for (int j = tid; j < a.nfixed; j += T)
      if (L.flags[a.fixed[j]] & kGrabbed) push_neighbours(a, sh, a.fixed[j], 0.0f, -1);
  });
  blk.each([&](int tid) {
    if (tid == 0) {
      sh.cur ^= 1;
      sh.np_in = sh.np_out;
      sh.np_out = 0;
    }
  });
  int iterations = 0, buckets = 0;
  bool converged = true;
  while (!sh.overflow) {
    // (1) smallest pending bucket. The bucket list is emptied here, not at the end of the
    // previous round: every thread read sh.nl before that round's last barrier, so this write
    // races with no read (an empty bucket has no barrier between its read and the round's end).
    blk.each([&](int tid) {
      if (tid == 0) sh.nl = 0;
      const int in = sh.cur;
      for (int j = tid; j < sh.np_in; j += T) at_min_u64(&sh.kmin, a.pend_b[in][j]);
    });
    if (sh.np_in == 0) break;
    const unsigned long long k = sh.kmin;
    // (2) take bucket k out of the pending list (unique, not final); keep the rest
    blk.each([&](int tid) {
      const int in = sh.cur;
      for (int j = tid; j < sh.np_in; j += T) {
        const int e = a.pend_e[in][j];
        const unsigned long long b = a.pend_b[in][j];
        if (b != k) {
          pend_put(a, sh, e, b);
          continue;
        }
        if (L.flags[e] & kFinalBit) continue;
        if (test_and_set_bit(L.flags, e, kListedBit)) continue;
        const int s = at_add(&sh.nl, 1);
        if (s < a.list_cap)
          a.list[s] = e;
        else
          sh.overflow = 1;
      }
    });
    if (sh.overflow) break;
    const int nl = sh.nl;
    if (nl > 0) {
      ++buckets;
      // (3) Jacobi inside the bucket: candidate times of this bucket come from final elements
      for (int pass = 0;; ++pass) {
        blk.each([&](int tid) {
          if (tid == 0) sh.any = 0;
        });
        blk.each([&](int tid) {
          for (int j = tid; j < nl; j += T) {
            const long long e = a.list[j];
            int x, y, z;
            L.coords(e, x, y, z);
            solver::Neighbour nb[6];
            const int c = gather(L, x, y, z, e, nb);
            propagate_in_bucket(e, L.pre[e], nb, c, k, a.delta, solver::element_wall(a.wall, x, y, z), a.st[j], a.sp[j]);
            if (!(a.st[j] == L.time[e]) || !(a.sp[j] == L.disp[e])) sh.any = 1;
          }
        });
        ++iterations;
        if (!sh.any) break;
        if (pass >= a.max_sweeps) {
          converged = false;
          break;
        }
        blk.each([&](int tid) {
          for (int j = tid; j < nl; j += T) {
            const long long e = a.list[j];
            L.time[e] = a.st[j];
            L.disp[e] = a.sp[j];
          }
        });
      }
      // (4) elements with a finite time are final
      blk.each([&](int tid) {
        for (int j = tid; j < nl; j += T) {
          const long long e = a.list[j];
          std::uint8_t f = static_cast<std::uint8_t>(L.flags[e] & ~kListedBit);
          if (L.time[e] < solver::kInf) {
            f = static_cast<std::uint8_t>(f | kFinalBit);
            at_add(&sh.reached, 1);
            const long long b = L.brick_of_index(e);
            L.touched[b] = 1;
            L.hot[b] = 1;
            L.wave[b] = 1;
          }
          L.flags[e] = f;
        }
      });
      // (5) the newly final elements push their neighbours
      blk.each([&](int tid) {
        for (int j = tid; j < nl; j += T) {
          const long long e = a.list[j];
          if (L.flags[e] & kFinalBit) push_neighbours(a, sh, e, L.time[e], static_cast<long long>(k));
        }
      });
    }
    // (6) next round reads what was written
    blk.each([&](int tid) {
      if (tid == 0) {
        sh.cur ^= 1;
        sh.np_in = sh.np_out;
        sh.np_out = 0;
        sh.kmin = ~0ull;
      }
    });
  }
  blk.each([&](int tid) {
    if (tid == 0) {
      a.ctl->sweeps = iterations;
      a.ctl->converged = converged ? 1 : 0;
      a.ctl->reached = sh.reached;
      a.ctl->overflow = sh.overflow;
      a.ctl->buckets = buckets;
    }
  });
}

/// Forgets the previous wave in brick b: times back to +inf, internal bits cleared.
template <class B>
HPCM_HD void reset_wave_block(const Lattice& L, long long b, B& blk) {
  if (!L.wave[b]) return;  // uniform over the block
  const int T = blk.threads();
  int lo[3], hi[3];
  L.brick_range(b, lo, hi);
  const int bs = L.grid.size, per = bs * bs * bs;
  blk.each([&](int tid) {
    for (int q = tid; q < per; q += T) {
      const int x = lo[0] + q % bs, y = lo[1] + (q / bs) % bs, z = lo[2] + q / (bs * bs);
      if (x >= hi[0] || y >= hi[1] || z >= hi[2]) continue;
      const long long i = L.index(x, y, z);
      L.time[i] = solver::kInf;
      L.flags[i] = static_cast<std::uint8_t>(L.flags[i] & ~kInternalBits);
    }
  });
  blk.each([&](int tid) {
    if (tid == 0) L.wave[b] = 0;
  });
}

/// After a list overflow: the whole lattice back to the state before the wave (element i).
HPCM_HD inline void full_reset_element(const Lattice& L, long long i) {
  L.time[i] = solver::kInf;
  L.flags[i] = static_cast<std::uint8_t>(L.flags[i] & ~kInternalBits);
  if (!(L.flags[i] & kFixed)) L.disp[i] = L.pre[i];
}

/// Touched bricks after the wave (they had work), thread per brick.
HPCM_HD inline void count_touched_thread(const Lattice& L, long long b, PropCtl* ctl) {
  if (!L.touched[b]) return;
  at_add(&ctl->active, 1);
  L.worked[b] = 1;
}

// ---------------------------------------------------------------------------------------------
// Relaxation: red-black Gauss-Seidel on a compacted list of active bricks (src/cpu/chainmail_relax.cpp)
// ---------------------------------------------------------------------------------------------

struct RelaxCtl {
  int count[2 * kMaxSweeps];         ///< active bricks of phase p
  unsigned maxcorr[2 * kMaxSweeps];  ///< float bits of the largest correction of phase p
  int stop;                          ///< first phase that does not run (nothing can move any more)
  int sweeps;
  int active_max;
  float last_max;
};

/// The relaxation's schedule (the CPU's, src/cpu/relax.cpp, at brick granularity): phase p is
/// colour p % 2 of sweep p / 2. A brick is relaxed in phase p when one of its elements' inputs
/// may have changed since that element was last relaxed: the brick changed in phase p - 2 (its
/// own positions), or it or a face neighbour changed in phase p - 1 (the other colour); in the
/// first sweep, when it or a face neighbour is `hot` (changed by the rest of the last frame). A
/// skipped element would compute what it computed last time, so the result is that of full
/// red-black sweeps over the whole lattice, on every backend and for every work split.
struct RelaxArgs {
  Lattice L;
  int* list = nullptr;  ///< capacity nbricks
  RelaxCtl* ctl = nullptr;
  std::uint8_t* start = nullptr;                              ///< per brick: first-sweep work
  std::uint8_t* phase[3] = {nullptr, nullptr, nullptr};       ///< per brick: changed in phase p (ring, p % 3)
  /// solver::squared_length_bound of SolverParams::relax_threshold and relax_slack
  /// (solver::relax_step_applies)
  float threshold_sq = 0.0f, slack_sq = solver::kInf;
  float omega = 1.0f;   ///< over-relaxation factor (SolverParams::relax_omega)
  solver::Wall wall;    ///< boundary box of every clamp (lattice coordinates; per element: solver::element_wall)
  int sweeps = 0;
};

struct RelaxShared {
  int any;
  unsigned maxc;
};

/// Threads relax_begin_thread needs: one per phase counter (2K), at least one.
HPCM_HD inline int relax_begin_threads(const RelaxArgs& a) { return a.sweeps > 0 ? 2 * a.sweeps : 1; }

/// Relaxation start, thread per index < relax_begin_threads(a).
HPCM_HD inline void relax_begin_thread(const RelaxArgs& a, int j) {
  if (j < 2 * a.sweeps) {
    a.ctl->count[j] = 0;
    a.ctl->maxcorr[j] = 0;
  }
  if (j == 0) {
    a.ctl->stop = 2 * a.sweeps;
    a.ctl->sweeps = 0;
    a.ctl->active_max = 0;
    a.ctl->last_max = 0.0f;
  }
}

/// Relaxation start, thread per brick: first-sweep work and clear phase flags.
HPCM_HD inline void relax_start_thread(const RelaxArgs& a, long long b) {
  if (b >= a.L.grid.count) return;
  a.start[b] = a.L.grid.flagged_or_face_neighbour(a.L.hot, b) ? 1 : 0;
  for (int r = 0; r < 3; ++r) a.phase[r][b] = 0;
}

/// Work list of phase p, thread per brick. The order of the list does not matter: every
/// result is order-free.
HPCM_HD inline void relax_list_thread(const RelaxArgs& a, int p, long long b) {
  if (p >= a.ctl->stop || b >= a.L.grid.count) return;
  const solver::BrickGrid& g = a.L.grid;
  bool on;
  if (p < 2)
    on = a.start[b] || (p == 1 && g.flagged_or_face_neighbour(a.phase[0], b));
  else
    on = a.phase[(p - 2) % 3][b] || g.flagged_or_face_neighbour(a.phase[(p - 1) % 3], b);
  if (p >= 2) a.phase[p % 3][b] = 0;  // held phase p - 3, no longer needed
  if (!on) return;
  a.list[at_add(&a.ctl->count[p], 1)] = static_cast<int>(b);
  a.L.worked[b] = 1;
}

/// Phase p over the listed bricks (blocks stride over the list). Elements of one colour only
/// read the other colour, so the order inside the pass does not matter.
template <class B>
HPCM_HD void relax_colour_block(const RelaxArgs& a, int p, RelaxShared& sh, B& blk) {
  if (p >= a.ctl->stop) return;  // uniform; nobody writes stop during this kernel
  const Lattice& L = a.L;
  const int T = blk.threads();
  const int n = a.ctl->count[p];
  const int colour = p & 1;
  const int bs = L.grid.size, half = bs / 2, per = bs * bs * half;
  blk.each([&](int tid) {
    if (tid == 0) {
      sh.any = 0;
      sh.maxc = 0;
    }
  });
  for (int j = blk.block(); j < n; j += blk.blocks()) {
    const long long b = a.list[j];
    int lo[3], hi[3];
    L.brick_range(b, lo, hi);
    blk.each([&](int tid) {
      for (int q = tid; q < per; q += T) {
        const int lz = q / (bs * half), r = q % (bs * half);
        const int y = lo[1] + r / half, z = lo[2] + lz;
        if (y >= hi[1] || z >= hi[2]) continue;
        const int x = lo[0] + ((lo[0] + y + z + colour) & 1) + 2 * (r % half);
        if (x >= hi[0]) continue;
        const long long i = L.index(x, y, z);
        if (L.flags[i] & kFixed) continue;
        solver::Neighbour nb[6];
        const int c = gather(L, x, y, z, i, nb);
        if (c == 0) continue;
        const Vec3 cur = L.disp[i];
        const Vec3 p = solver::relax_element(nb, c, cur, a.omega, solver::element_wall(a.wall, x, y, z));
        const Vec3 d = p - cur;
        const float corr_sq = d.x * d.x + d.y * d.y + d.z * d.z;
        const float disp_sq = cur.x * cur.x + cur.y * cur.y + cur.z * cur.z;
        if (!solver::relax_step_applies(corr_sq, a.threshold_sq, disp_sq, a.slack_sq)) continue;
        const float corr = sqrtf(corr_sq);
        L.disp[i] = p;
        sh.any = 1;
        at_max_u32(&sh.maxc, float_bits(corr));
      }
    });
    blk.each([&](int tid) {
      if (tid == 0) {
        if (sh.any) {
          a.phase[p % 3][b] = 1;
          L.touched[b] = 1;
          at_max_u32(&a.ctl->maxcorr[p], sh.maxc);
        }
        sh.any = 0;
        sh.maxc = 0;
      }
    });
  }
}

/// End of phase p (one thread): books the phase; an empty phase ends the relaxation (every later
/// phase would be empty too).
HPCM_HD inline void relax_end_thread(const RelaxArgs& a, int p) {
  if (p >= a.ctl->stop) return;
  const int n = a.ctl->count[p];
  if (n == 0) {
    a.ctl->stop = p;
    return;
  }
  const int s = p / 2;
  const float m = bits_float(a.ctl->maxcorr[p]);
  a.ctl->last_max = s + 1 > a.ctl->sweeps ? m : (m > a.ctl->last_max ? m : a.ctl->last_max);
  a.ctl->sweeps = s + 1;
  if (n > a.ctl->active_max) a.ctl->active_max = n;
}

/// After the last phase, thread per brick: hot <- changed by the last sweep (work for the
/// next frame; nothing when the relaxation ended early).
HPCM_HD inline void relax_finish_thread(const RelaxArgs& a, long long b) {
  if (b >= a.L.grid.count) return;
  const int P = 2 * a.sweeps;
  a.L.hot[b] = a.ctl->stop >= P && P >= 2 && (a.phase[(P - 1) % 3][b] || a.phase[(P - 2) % 3][b]) ? 1 : 0;
}

// ---------------------------------------------------------------------------------------------
// Link check before the restoration: solver::find_violations' test on the device
// ---------------------------------------------------------------------------------------------

/// The restoration (host, solver::LinkRestorer) needs the positions on the host. Most frames
/// leave every link in its box, so the device first asks whether the host's check would find
/// anything: the same bricks (changed since the last check, or a face neighbour of one), the
/// same test per element (outside the wall, or a + link outside its box by more than
/// kRestoreTolerance) with the same float operations. Only when it does are the positions
/// downloaded, and the host checks only the bricks flagged here.
struct CheckArgs {
  Lattice L;
  solver::Wall wall;
  int* found = nullptr;             ///< set to 1 when some element or link fails the test
  std::uint8_t* bricks = nullptr;   ///< per brick: set to 1 when one of its elements fails it
  /// The frame-end fold guard's test instead: a + link that may take part in a fold
  /// (solver::may_fold); the wall is not tested.
  bool fold = false;
};

template <class B>
HPCM_HD void check_links_block(const CheckArgs& a, long long b, B& blk) {
  const Lattice& L = a.L;
  if (!L.grid.flagged_or_face_neighbour(L.unchecked, b) && !L.grid.flagged_or_face_neighbour(L.touched, b)) return;
  blk.each([&](int tid) {
    if (tid == 0) L.worked[b] = 1;  // checked: work, as on the CPU
  });
  int lo[3], hi[3];
  L.brick_range(b, lo, hi);
  const int bs = L.grid.size, per = bs * bs * bs;
  const int d[3] = {L.nx, L.ny, L.nz};
  const long long stride[3] = {1, L.nx, static_cast<long long>(L.nx) * L.ny};
  const int T = blk.threads();
  blk.each([&](int tid) {
    bool found = false;
    for (int q = tid; q < per && !found; q += T) {
      const int c[3] = {lo[0] + q % bs, lo[1] + (q / bs) % bs, lo[2] + q / (bs * bs)};
      if (c[0] >= hi[0] || c[1] >= hi[1] || c[2] >= hi[2]) continue;
      const long long e = L.index(c[0], c[1], c[2]);
      const Vec3 pe = L.disp[e];
      if (a.fold) {
        for (int ax = 0; ax < 3; ++ax)
          if (c[ax] + 1 < d[ax] && solver::may_fold(pe, L.disp[e + stride[ax]], ax))
            found = true;
        continue;
      }
      for (int ax = 0; ax < 3; ++ax) {
        const float below = solver::wall_lo_of(a.wall, ax, c[ax]) - pe[ax], above = pe[ax] - solver::wall_hi_of(a.wall, ax, c[ax]);
        if ((below < above ? above : below) > solver::kRestoreTolerance) found = true;
        if (c[ax] + 1 >= d[ax]) continue;
        const long long n = e + stride[ax];
        if (link_violation(pe, L.disp[n], L.link_of(ax, e, n), ax) > solver::kRestoreTolerance) found = true;
      }
    }
    if (found) {  // every writer stores the same value
      *a.found = 1;
      a.bricks[b] = 1;
    }
  });
}

/// Bricks the restoration reads, packed for one copy to the host: brick j of the list goes to
/// out[j * B^3 ...] in brick-local order (x fastest); elements past the lattice edge are left
/// unwritten (never read).
struct GatherArgs {
  Lattice L;
  const int* bricks = nullptr;
  Vec3* out = nullptr;
  int n = 0;
};

template <class B>
HPCM_HD void gather_brick_block(const GatherArgs& a, long long j, B& blk) {
  if (j >= a.n) return;  // uniform over the block
  const Lattice& L = a.L;
  int lo[3], hi[3];
  L.brick_range(a.bricks[j], lo, hi);
  const int bs = L.grid.size, per = bs * bs * bs;
  const int T = blk.threads();
  Vec3* out = a.out + j * per;
  blk.each([&](int tid) {
    for (int q = tid; q < per; q += T) {
      const int x = lo[0] + q % bs, y = lo[1] + (q / bs) % bs, z = lo[2] + q / (bs * bs);
      if (x < hi[0] && y < hi[1] && z < hi[2]) out[q] = L.disp[L.index(x, y, z)];
    }
  });
}

/// The restoration's result back on the device: only the elements it moved are uploaded
/// (index and position); their bricks become touched (velocity layer) and hot (next relaxation).
struct ScatterArgs {
  Lattice L;
  const int* elements = nullptr;
  const Vec3* positions = nullptr;
  int n = 0;
  bool snapshot = false;  ///< frame end (after the velocity layer): X- follows X
};

/// Thread per moved element (every writer of a brick flag stores the same value).
HPCM_HD inline void scatter_position_thread(const ScatterArgs& a, long long j) {
  if (j >= a.n) return;
  const long long e = a.elements[j];
  a.L.disp[e] = a.positions[j];
  if (a.snapshot) a.L.pre[e] = a.positions[j];
  const long long b = a.L.brick_of_index(e);
  a.L.touched[b] = 1;
  a.L.hot[b] = 1;
}

// ---------------------------------------------------------------------------------------------
// The fused velocity layer: dX from X-, damping, clamp, position update, boundary clamp and the
// frame-end snapshot in one pass (no separate snapshot copy remains)
// ---------------------------------------------------------------------------------------------

struct LayerCtl {
  int count;  ///< bricks visited
  int pad;
  long long moved;
  float sum[kTissueCount];
  float max[kTissueCount];
};

struct LayerArgs {
  Lattice L;
  dynamics::LayerConstants k;
  bool speeds = false;  ///< write per-brick speed partials
  bool all = false;     ///< visit every brick (benchmark probe)
  float sleep_speed = 0.0f;  ///< a brick untouched this frame, below it last frame, comes to rest (0: never)
  float* part_sum = nullptr;  ///< [nbricks][4]
  float* part_max = nullptr;  ///< [nbricks][4]
  int* part_moved = nullptr;  ///< [nbricks]
  LayerCtl* ctl = nullptr;
};

/// Per-tissue speed sums and maxima and a count, one entry per thread of the block, reduced
/// into entry 0 as a fixed-shape tree (deterministic run to run). T is a power of two <= N.
template <class B, class S, class M, class C, int N>
HPCM_HD void tree_reduce_speeds(B& blk, int T, S (&sum)[kTissueCount][N], M (&max)[kTissueCount][N], C (&cnt)[N]) {
  for (int h = T / 2; h > 0; h /= 2)
    blk.each([&](int tid) {
      if (tid < h) {
        for (int t = 0; t < kTissueCount; ++t) {
          sum[t][tid] += sum[t][tid + h];
          max[t][tid] = max[t][tid] > max[t][tid + h] ? max[t][tid] : max[t][tid + h];
        }
        cnt[tid] += cnt[tid + h];
      }
    });
}

struct LayerShared {
  int anyv, moved;
  unsigned vmax;  ///< float bits of the largest |V| before the clamp
  float sum[kTissueCount][kBrickThreads];
  float max[kTissueCount][kBrickThreads];
  int cnt[kBrickThreads];
};

/// One brick of the layer (block per brick). Bricks neither touched this frame nor carrying
/// velocity are skipped, as on the CPU (VelocityLayerCpu::apply).
template <class B>
HPCM_HD void layer_block(const LayerArgs& a, long long b, LayerShared& sh, B& blk) {
  const Lattice& L = a.L;
  const int T = blk.threads();
  const bool on = a.all || L.touched[b] || L.has_vel[b];  // uniform; written only after a barrier
  if (!on) {
    if (a.speeds) {
      blk.each([&](int tid) {
        if (tid < kTissueCount) {
          a.part_sum[b * kTissueCount + tid] = 0.0f;
          a.part_max[b * kTissueCount + tid] = 0.0f;
        }
        if (tid == 0) a.part_moved[b] = 0;
      });
    }
    return;
  }
  int lo[3], hi[3];
  L.brick_range(b, lo, hi);
  const int bs = L.grid.size, per = bs * bs * bs;
  // An untouched brick whose velocities all stayed below the sleep speed comes to rest (as the
  // CPU's VelocityLayer::apply): its elements get no dynamics this frame. Uniform over the block.
  const bool asleep = a.sleep_speed > 0.0f && !L.touched[b] && L.speed[b] < a.sleep_speed;
  blk.each([&](int tid) {
    if (tid == 0) {
      sh.anyv = 0;
      sh.moved = 0;
      sh.vmax = 0;
    }
  });
  blk.each([&](int tid) {
    float ls[kTissueCount] = {0, 0, 0, 0}, lm[kTissueCount] = {0, 0, 0, 0};
    int lc = 0;
    bool anyv = false, moved = false;
    for (int q = tid; q < per; q += T) {
      const int x = lo[0] + q % bs, y = lo[1] + (q / bs) % bs, z = lo[2] + q / (bs * bs);
      if (x >= hi[0] || y >= hi[1] || z >= hi[2]) continue;
      const long long i = L.index(x, y, z);
      const int t = L.tissue[i];
      const Vec3 post = L.disp[i], before = L.pre[i];
      Vec3 v = L.vel[i];
      float speed;
      const Vec3 out = dynamics::velocity_update(a.k, t, asleep || (L.flags[i] & kFixed) != 0, before, post,
                                                 Vec3{float(x), float(y), float(z)}, v, &speed);
      at_max_u32(&sh.vmax, float_bits(speed));
      L.vel[i] = v;
      L.disp[i] = out;
      L.pre[i] = out;  // frame-end snapshot: next frame's X-
      if (!(v == Vec3{})) anyv = true;
      if (!(out == post)) moved = true;
      if (a.speeds) {
        const float sp = norm(out - before);
        if (sp > 0) ++lc;
        const int c = L.stat_class[i];
        if (c < kTissueCount) {  // outside the body: not in the statistics (SPEC §3)
          ls[c] += sp;
          lm[c] = lm[c] > sp ? lm[c] : sp;
        }
      }
    }
    if (anyv) sh.anyv = 1;
    if (moved) sh.moved = 1;
    if (a.speeds) {
      for (int t = 0; t < kTissueCount; ++t) {
        sh.sum[t][tid] = ls[t];
        sh.max[t][tid] = lm[t];
      }
      sh.cnt[tid] = lc;
    }
  });
  if (a.speeds) tree_reduce_speeds(blk, T, sh.sum, sh.max, sh.cnt);
  blk.each([&](int tid) {
    if (tid == 0) {
      L.has_vel[b] = sh.anyv ? 1 : 0;
      L.speed[b] = bits_float(sh.vmax);
      if (sh.moved) L.hot[b] = L.unchecked[b] = 1;
      L.touched[b] = 0;
      L.worked[b] = 1;
      at_add(&a.ctl->count, 1);
      if (a.speeds) {
        for (int t = 0; t < kTissueCount; ++t) {
          a.part_sum[b * kTissueCount + t] = sh.sum[t][0];
          a.part_max[b * kTissueCount + t] = sh.max[t][0];
        }
        a.part_moved[b] = sh.cnt[0];
      }
    }
  });
}

struct SpeedShared {
  double sum[kTissueCount][kReduceThreads];
  float max[kTissueCount][kReduceThreads];
  long long moved[kReduceThreads];
};

/// Per-tissue speed totals over all bricks (one block, fixed order: deterministic).
template <class B>
HPCM_HD void speed_sum_block(const LayerArgs& a, SpeedShared& sh, B& blk) {
  const int T = blk.threads();
  blk.each([&](int tid) {
    double s[kTissueCount] = {0, 0, 0, 0};
    float m[kTissueCount] = {0, 0, 0, 0};
    long long mv = 0;
    for (long long b = tid; b < a.L.grid.count; b += T) {
      for (int t = 0; t < kTissueCount; ++t) {
        s[t] += a.part_sum[b * kTissueCount + t];
        const float x = a.part_max[b * kTissueCount + t];
        m[t] = m[t] > x ? m[t] : x;
      }
      mv += a.part_moved[b];
    }
    for (int t = 0; t < kTissueCount; ++t) {
      sh.sum[t][tid] = s[t];
      sh.max[t][tid] = m[t];
    }
    sh.moved[tid] = mv;
  });
  tree_reduce_speeds(blk, T, sh.sum, sh.max, sh.moved);
  blk.each([&](int tid) {
    if (tid == 0) {
      for (int t = 0; t < kTissueCount; ++t) {
        a.ctl->sum[t] = static_cast<float>(sh.sum[t][0]);
        a.ctl->max[t] = sh.max[t][0];
      }
      a.ctl->moved = sh.moved[0];
    }
  });
}

}  // namespace hpcm::gpu
