#include "cpu/relax.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "hpcm/state.hpp"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace hpcm::cpu {

namespace {
void cpu_relax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#endif
}
}  // namespace

using solver::Neighbour;
using solver::Wall;

float relax_element_scalar(const RelaxContext& c, int x, int y, int z) {
  const Layout& L = *c.lay;
  const Index k = L.at(x, y, z);
  if (c.flags[k] & kFixed) return 0.0f;
  const int nx = L.dims.x, ny = L.dims.y, nz = L.dims.z;
  // The six neighbours in the rule's order: -x, +x, -y, +y, -z, +z.
  struct Nb {
    Index k;        ///< storage index
    Index linear;
    int axis, side;
    Index link_owner;  ///< storage index of the link's - element
  };
  Nb nb[6];
  int count = 0;
  const Index i = x + static_cast<Index>(nx) * (y + static_cast<Index>(ny) * z);
  const Index sy = nx, sz = static_cast<Index>(nx) * ny;
  if (x > 0) { const Index n = L.at(x - 1, y, z); nb[count++] = {n, i - 1, 0, +1, n}; }
  if (x + 1 < nx) nb[count++] = {L.at(x + 1, y, z), i + 1, 0, -1, k};
  if (y > 0) { const Index n = L.at(x, y - 1, z); nb[count++] = {n, i - sy, 1, +1, n}; }
  if (y + 1 < ny) nb[count++] = {L.at(x, y + 1, z), i + sy, 1, -1, k};
  if (z > 0) { const Index n = L.at(x, y, z - 1); nb[count++] = {n, i - sz, 2, +1, n}; }
  if (z + 1 < nz) nb[count++] = {L.at(x, y, z + 1), i + sz, 2, -1, k};
  if (count == 0) return 0.0f;
  const Vec3 cur{c.p[0][k], c.p[1][k], c.p[2][k]};

  // The rule with precomputed weights (solver::relax_weight per element): solver::relax_element's
  // sum and step, the boxes rebuilt from the links' tolerances as the SIMD kernels do.
  solver::ProposalSum<float> sum;
  const solver::Wall wall = solver::element_wall(c.wall, x, y, z);
  float lo[3] = {wall.lo[0], wall.lo[1], wall.lo[2]}, hi[3] = {wall.hi[0], wall.hi[1], wall.hi[2]};
  for (int q = 0; q < count; ++q) {
    const Nb& n = nb[q];
    const Vec3 pn{c.p[0][n.k], c.p[1][n.k], c.p[2][n.k]};
    const Vec3 off = pn - cur;  // the proposal's offset from cur
    sum.add(c.weight[n.k], off.x, off.y, off.z);
    const LinkBox<float> box = box_from_tau(c.link_tau[n.axis][n.link_owner]);
    for (int b = 0; b < 3; ++b) {
      float l, h;
      link_interval(pn[b], box, b == n.axis, n.side, l, h);
      lo[b] = lo[b] > l ? lo[b] : l;
      hi[b] = hi[b] < h ? hi[b] : h;
    }
  }
  Vec3 out;
  if (!(lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2])) {
    const Vec3 target{sum.target(0, cur.x, c.omega), sum.target(1, cur.y, c.omega), sum.target(2, cur.z, c.omega)};
    for (int b = 0; b < 3; ++b) out[b] = clampf(target[b], lo[b], hi[b]);
  } else {
    // Conflicting boxes: the general rule decides (earliest neighbour's box, then the wall).
    Neighbour g[6];
    for (int q = 0; q < count; ++q) {
      const Nb& n = nb[q];
      g[q] = Neighbour{n.linear, n.axis, n.side,
                       limits_from_tau(c.link_tau[n.axis][n.link_owner], 1.0f), c.time[n.k],
                       c.model->tau[static_cast<std::size_t>(n.linear)], Vec3{c.p[0][n.k], c.p[1][n.k], c.p[2][n.k]}};
    }
    out = solver::relax_element(g, count, cur, c.omega, wall);
  }
  const Vec3 d = out - cur;
  const float corr_sq = d.x * d.x + d.y * d.y + d.z * d.z;
  const float disp_sq = cur.x * cur.x + cur.y * cur.y + cur.z * cur.z;
  if (!solver::relax_step_applies(corr_sq, c.threshold_sq, disp_sq, c.slack_sq)) return 0.0f;
  c.p[0][k] = out.x;
  c.p[1][k] = out.y;
  c.p[2][k] = out.z;
  return std::sqrt(corr_sq);
}

RelaxContext make_relax_context(Storage& st, const Model& m, const solver::Wall& wall, const SolverParams& s) {
  RelaxContext c;
  c.lay = &st.lay;
  for (int a = 0; a < 3; ++a) {
    c.p[a] = st.p[a].data();
    c.link_tau[a] = st.link_tau[a].data();
  }
  c.weight = st.weight.data();
  c.flags = st.flags.data();
  c.time = st.time.data();
  c.model = &m;
  c.wall = wall;
  c.threshold_sq = solver::squared_length_bound(s.relax_threshold);
  c.slack_sq = solver::squared_length_bound(s.relax_slack);
  c.omega = s.relax_omega;
  return c;
}

void Relaxation::init(const solver::BrickGrid& grid, RelaxRunKernel kernel) {
  grid_ = grid;
  kernel_ = kernel;
  cells_ = static_cast<Index>(grid.nb.x) * grid.nb.y;
  start_.assign(static_cast<std::size_t>(grid.count), 0);
}

// The schedule. A sweep is two phases (colour 0, then colour 1); phase p of the frame is
// colour p % 2 of sweep p / 2. The lattice is traversed plane by plane in a wavefront: at step
// t, phase p works on plane z = t - p, for p = 0, 1, ..., P - 1 in that order. Phase p at plane
// z reads the other colour at planes z - 1, z, z + 1 as phase p - 1 left them: plane z + 1 was
// done by phase p - 1 earlier in the same step, planes z and z - 1 in earlier steps, and phase
// p - 1 does not touch them again. So the result is that of full sweeps one after the other,
// while every plane is read from memory once per frame and then reused from cache by the
// following phases (temporal blocking).
//
// Work within a plane is per cell: the B x B elements of one brick column in that plane. A
// cell is processed in phase p when its elements' inputs may have changed since their last
// evaluation: the cell itself changed in phase p - 2 (own positions), or it or a face-
// neighbouring cell changed in phase p - 1 (the other colour); in the first sweep, when its
// brick or a face-neighbouring brick is in `hot` (changed by the rest of the last frame). A
// skipped element would compute what it computed last time, so this gives the same floats as
// processing everything.
//
// The threads share the phases dynamically (work_until_done below).
void Relaxation::cells_to_process(int p, int z, std::uint8_t* active) const {
  const Index n = cells_;
  const int nbx = grid_.nb.x, nz = grid_.dims.z;
  auto changed_in = [this](int q, int zz) { return changed_.data() + (static_cast<Index>(q) * grid_.dims.z + zz) * cells_; };
  const std::uint8_t* first = p < 2 ? start_.data() + cells_ * (z / grid_.size) : changed_in(p - 2, z);
  for (Index c = 0; c < n; ++c) active[c] = first[c];
  if (p == 0) return;
  // Byte-wise ORs over the whole plane (vectorised by the compiler) instead of a test per cell.
  for (int zz = std::max(0, z - 1); zz <= std::min(nz - 1, z + 1); ++zz) {
    const std::uint8_t* other = changed_in(p - 1, zz);
    for (Index c = 0; c < n; ++c) active[c] |= other[c];
  }
  const std::uint8_t* same = changed_in(p - 1, z);
  for (Index c = nbx; c < n; ++c) active[c] |= same[c - nbx];  // the -y neighbour
  for (Index c = 0; c + nbx < n; ++c) active[c] |= same[c + nbx];  // the +y neighbour
  for (Index row = 0; row < n; row += nbx)  // -x and +x, within the brick row
    for (int bx = 0; bx < nbx; ++bx)
      active[row + bx] |= static_cast<std::uint8_t>((bx > 0 ? same[row + bx - 1] : 0) | (bx + 1 < nbx ? same[row + bx + 1] : 0));
}

float Relaxation::phase(const RelaxContext& ctx, int p, int z, bool prefetch, Index& active_cells) {
  const Layout& L = *ctx.lay;
  const int B = grid_.size, colour = p & 1;
  const Int3 nb = grid_.nb;
  std::uint8_t* ch = changed_.data() + (static_cast<Index>(p) * grid_.dims.z + z) * cells_;
  thread_local std::vector<std::uint8_t> active;  // per thread: phases run concurrently
  active.resize(static_cast<std::size_t>(cells_));
  cells_to_process(p, z, active.data());
  auto cell_active = [&](Index cell) { return active[static_cast<std::size_t>(cell)] != 0; };
  float mc = 0.0f;
  for (int by = 0; by < nb.y; ++by) {
    const Index row = static_cast<Index>(by) * nb.x;
    const int y1 = std::min((by + 1) * B, L.dims.y);
    // One run from the first to the last active cell of this brick row. The inactive cells
    // between them compute what they computed last time (nothing moves there: the schedule's
    // argument above), so they change no result, and on a CT, where bone and quiet tissue
    // split the rows into pieces, one long run keeps the vectors full and the calls few
    // (measured faster than skipping them, BENCHMARKS.md).
    int first = 0, last = nb.x - 1;
    while (first < nb.x && !cell_active(row + first)) ++first;
    if (first == nb.x) continue;
    while (!cell_active(row + last)) --last;
    for (int c = first; c <= last; ++c) {
      if (!cell_active(row + c)) continue;
      ++active_cells;  // several threads may mark one brick: atomic, relaxed
      std::atomic_ref<std::uint8_t>(worked_[row + c + cells_ * (z / B)]).store(1, std::memory_order_relaxed);
    }
    // Cells [first, last] of this brick row: their rows, this colour's half of each.
    const int x0 = first * B, x1 = std::min((last + 1) * B, L.dims.x);
    mc = std::max(mc, kernel_(ctx, RelaxRun{colour, by * B, y1, z, x0, x1, ch + row + first, x0 / 2, B / 2, prefetch}));
  }
  return mc;
}

// Phase p may process plane z once phase p - 1 has finished plane z + 1 (or the last plane),
// and the planes of one phase go in ascending order: that is all the schedule above needs, so
// whichever thread runs a plane computes the same floats. A thread takes the deepest phase whose
// next plane is ready (keeping the band of planes in flight narrow), one plane at a time; one
// thread at most works on a phase at once. Nothing waits for a thread that has not started
// (the others take its share), no thread idles while another works through a fixed share of
// the phases, and the wavefront fills and drains in a few planes. (A fixed split of the phases
// between the threads, measured before this: the second thread waited 4-6 ms per frame.)
bool Relaxation::plane_ready(int p, int z) const {
  const int nz = grid_.dims.z;
  if (z >= nz) return false;
  return p == 0 || progress_[static_cast<std::size_t>(p - 1)].planes.load(std::memory_order_acquire) >= std::min(z + 2, nz);
}

void Relaxation::work_until_done(const RelaxContext& ctx, int P) {
  const int nz = grid_.dims.z;
  PhaseProgress& last = progress_[static_cast<std::size_t>(P - 1)];
  for (;;) {
    // Read before the test for the end: a last plane finished between the two would otherwise
    // leave this thread asleep waiting for a plane after it.
    const std::uint32_t seen = planes_done_.load(std::memory_order_seq_cst);
    if (last.planes.load(std::memory_order_acquire) >= nz) return;
    bool worked = false;
    for (int p = P - 1; p >= 0 && !worked; --p) {
      PhaseProgress& ph = progress_[static_cast<std::size_t>(p)];
      if (!plane_ready(p, ph.planes.load(std::memory_order_acquire))) continue;
      if (ph.claimed.exchange(true, std::memory_order_acquire)) continue;
      const int z = ph.planes.load(std::memory_order_relaxed);  // as of the claim
      if (plane_ready(p, z)) {
        // Phase 0 meets each plane first: it prefetches what the wavefront reads next.
        ph.max_correction = std::max(ph.max_correction, phase(ctx, p, z, p == 0, ph.cells));
        ph.planes.store(z + 1, std::memory_order_release);
        worked = true;
      }
      ph.claimed.store(false, std::memory_order_release);
    }
    if (worked) {
      planes_done_.fetch_add(1, std::memory_order_seq_cst);
      if (sleepers_.load(std::memory_order_seq_cst) > 0) planes_done_.notify_all();
      continue;
    }
    // Nothing ready: another thread holds the work this one waits for. Spin briefly (a plane
    // takes tens of microseconds), then sleep until a plane is finished.
    bool moved = false;
    for (int spin = 0; spin < 256 && !moved; ++spin) {
      cpu_relax();
      moved = planes_done_.load(std::memory_order_acquire) != seen;
    }
    if (moved) continue;
    sleepers_.fetch_add(1, std::memory_order_seq_cst);
    if (planes_done_.load(std::memory_order_seq_cst) == seen) planes_done_.wait(seen, std::memory_order_seq_cst);
    sleepers_.fetch_sub(1, std::memory_order_seq_cst);
  }
}

RelaxStats Relaxation::run(const RelaxContext& ctx, int sweeps, std::vector<std::uint8_t>& hot,
                           std::vector<std::uint8_t>& touched, std::vector<std::uint8_t>& worked, WorkerPool& pool) {
  RelaxStats st;
  worked_ = worked.data();
  if (sweeps <= 0) return st;
  const int nz = grid_.dims.z, P = 2 * sweeps;
  // First-sweep work: bricks changed by the last frame, and their face neighbours.
  bool any = false;
  for (Index b = 0; b < grid_.count; ++b) {
    start_[static_cast<std::size_t>(b)] = grid_.flagged_or_face_neighbour(hot, b) ? 1 : 0;
    any = any || start_[static_cast<std::size_t>(b)];
  }
  if (!any) return st;
  changed_.assign(static_cast<std::size_t>(P) * nz * cells_, 0);
  if (progress_size_ < P) {
    progress_ = std::make_unique<PhaseProgress[]>(static_cast<std::size_t>(P));
    progress_size_ = P;
  }
  for (int p = 0; p < P; ++p) {
    PhaseProgress& ph = progress_[static_cast<std::size_t>(p)];
    ph.planes.store(0, std::memory_order_relaxed);
    ph.claimed.store(false, std::memory_order_relaxed);
    ph.max_correction = 0.0f;
    ph.cells = 0;
  }
  const int T = std::min(pool.threads(), P);
  pool.run(T, [&](std::int64_t) { work_until_done(ctx, P); });
  // Statistics and the bricks for the next frame.
  std::fill(hot.begin(), hot.end(), 0);
  for (int s = 0; s < sweeps; ++s) {
    const Index cells = progress_[static_cast<std::size_t>(2 * s)].cells + progress_[static_cast<std::size_t>(2 * s + 1)].cells;
    if (cells == 0) break;
    st.sweeps = s + 1;
    st.max_correction = std::max(progress_[static_cast<std::size_t>(2 * s)].max_correction, progress_[static_cast<std::size_t>(2 * s + 1)].max_correction);
  }
  const int B = grid_.size;
  for (int p = 0; p < P; ++p)
    for (int z = 0; z < nz; ++z) {
      const std::uint8_t* ch = changed_.data() + (static_cast<Index>(p) * nz + z) * cells_;
      const Index brick_layer = cells_ * (z / B);
      for (Index c = 0; c < cells_; ++c) {
        if (!ch[c]) continue;
        touched[static_cast<std::size_t>(brick_layer + c)] = 1;
        // What the last sweep changed is work for the next frame.
        if (p >= P - 2) hot[static_cast<std::size_t>(brick_layer + c)] = 1;
      }
    }
  return st;
}

}  // namespace hpcm::cpu
