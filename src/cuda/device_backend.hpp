#pragma once
// The CUDA backend's host side, written once over an executor X that owns memory, copies,
// kernel launches and timing:
//   - GpuExec (cuda_backend.cu): cudaMalloc, one stream, __global__ wrappers of the bodies in
//     kernels.hpp, the relaxation sweeps replayed as a CUDA graph, CUDA events;
//   - EmuExec (emulation.hpp): host memory and sequential loops over blocks and threads, so the
//     test suite can check the device algorithm against the CPU backend without a GPU.
// Plain C++ (no CUDA syntax): compiled by nvcc for the backend and by the C++ compiler for the
// emulation test.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "cuda/kernels.hpp"
#include "hpcm/backend.hpp"
#include "solver/link_restore.hpp"
#include "solver/schedule.hpp"

namespace hpcm::gpu {

/// Device-wide results copied back to the host after each stage.
struct Ctl {
  PropCtl prop;
  RelaxCtl relax;
  LayerCtl layer;
  int links_outside;  ///< the device's link check found work for the restoration
};

/// Largest propagation list capacities (entries): pend + 6 * list < 2^31 (int counters).
inline constexpr std::size_t kMaxPendCap = std::numeric_limits<int>::max() / 2;
inline constexpr std::size_t kMaxListCap = std::numeric_limits<int>::max() / 16;

template <class X>
class DeviceBackend final : public Backend {
 public:
  template <class... A>
  explicit DeviceBackend(A&&... args) : x_(std::forward<A>(args)...) {}
  ~DeviceBackend() override {
    // Work still queued (the velocity layer's download into the pinned control block) must end
    // before its buffers are freed.
    try {
      if (!blocks_.empty()) x_.sync();
    } catch (...) {
    }
    free_all();
  }
  DeviceBackend(const DeviceBackend&) = delete;
  DeviceBackend& operator=(const DeviceBackend&) = delete;

  BackendKind kind() const override { return BackendKind::Cuda; }
  X& exec() { return x_; }
  std::size_t device_bytes() const { return held_; }
  /// Test hook: initial capacities of the propagation lists (pending pushes, one bucket) for the
  /// next load(); 0 = the defaults. Small values force the grow-and-rerun path.
  void set_initial_list_capacity(int pending, int bucket) {
    pend_override_ = pending;
    list_override_ = bucket;
  }
  /// Times a wave was rerun with larger lists since load().
  int list_regrowths() const { return regrowths_; }
  /// Test hook: bricks the link restoration copied to the host since load(), and how many of
  /// those copies it asked for on demand (a brick outside the flagged ones and their neighbours).
  Index restore_bricks_copied() const { return cache_fetched_; }
  Index restore_cache_misses() const { return cache_misses_; }

  const Model& model() const override { return *m_; }
  const Params& params() const override { return p_; }

 protected:
  void upload(const Model& m, const Params& p, const State& s) override {
    p.validate();
    const Index n = m.size();
    if (static_cast<Index>(s.disp.size()) != n || static_cast<Index>(s.vel.size()) != n ||
        static_cast<Index>(s.flags.size()) != n)
      throw Error("CUDA backend: state size does not match the model (" + std::to_string(n) + " elements)");
    // Element indices are 32-bit on the device (fixed set, pending and bucket lists).
    if (n > static_cast<Index>(std::numeric_limits<int>::max()))
      throw Error("CUDA backend: " + std::to_string(n) + " elements: at most " +
                  std::to_string(std::numeric_limits<int>::max()) + " are supported");
    if (!blocks_.empty()) x_.sync();  // nothing queued may still use the buffers freed below
    free_all();
    m_ = &m;
    p_ = p;
    k_ = dynamics::make_constants(p.dynamics, m.dims);
    wall_ = solver::make_wall(m.dims, p.dynamics.margin);
    L_ = Lattice{};
    L_.nx = m.dims.x;
    L_.ny = m.dims.y;
    L_.nz = m.dims.z;
    L_.n = n;
    L_.grid.init(m.dims, p.solver.brick_size);


    const std::size_t N = static_cast<std::size_t>(n), NB = static_cast<std::size_t>(L_.grid.count);
    const std::size_t N4 = (N + 3) / 4 * 4;
    L_.disp = alloc<Vec3>(N, "positions");
    L_.pre = alloc<Vec3>(N, "pre-ChainMail snapshot");
    L_.vel = alloc<Vec3>(N, "velocities");
    L_.time = alloc<float>(N, "arrival times");
    L_.flags = alloc<std::uint8_t>(N4, "flags");
    L_.tau = alloc<float>(N, "element tolerances");
    L_.tissue = alloc<std::uint8_t>(N, "tissue classes");
    L_.stat_class = alloc<std::uint8_t>(N, "statistics classes");
    for (int a = 0; a < 3; ++a) L_.link_index[a] = alloc<std::uint16_t>(N, "link indices");
    L_.link_table = alloc<LinkLimits>(m.link_table.size(), "link table");
    L_.touched = alloc<std::uint8_t>(NB, "brick flags");
    L_.hot = alloc<std::uint8_t>(NB, "brick flags");
    relax_start_ = alloc<std::uint8_t>(NB, "brick flags");
    for (auto& ph : relax_phase_) ph = alloc<std::uint8_t>(NB, "brick flags");
    L_.has_vel = alloc<std::uint8_t>(NB, "brick flags");
    L_.wave = alloc<std::uint8_t>(NB, "brick flags");
    L_.unchecked = alloc<std::uint8_t>(NB, "brick flags");
    L_.speed = alloc<float>(NB, "brick speeds");
    L_.worked = alloc<std::uint8_t>(NB, "brick flags");
    save_touched_ = alloc<std::uint8_t>(NB, "brick flags");
    save_hot_ = alloc<std::uint8_t>(NB, "brick flags");
    relax_list_ = alloc<int>(NB, "relaxation brick list");
    check_bricks_ = alloc<std::uint8_t>(NB, "brick flags");
    part_sum_ = alloc<float>(NB * kTissueCount, "speed partials");
    part_max_ = alloc<float>(NB * kTissueCount, "speed partials");
    part_moved_ = alloc<int>(NB, "speed partials");
    ctl_ = alloc<Ctl>(1, "control block");
    host_ctl_ = static_cast<Ctl*>(x_.host_alloc(sizeof(Ctl), "control block"));
    std::memset(static_cast<void*>(host_ctl_), 0, sizeof(Ctl));
    // Propagation lists: grown on overflow (the wave is then rerun from its start).
    pend_cap_ = pend_override_ > 0 ? pend_override_ : static_cast<int>(std::max<std::size_t>(65536, N / 32));
    list_cap_ = list_override_ > 0 ? list_override_ : static_cast<int>(std::max<std::size_t>(16384, N / 128));
    regrowths_ = 0;
    cache_fetched_ = cache_misses_ = 0;
    alloc_prop_lists();

    // Upload: model, then the state (as CpuBackend::load).
    std::vector<float> buf(N);
    x_.upload(const_cast<float*>(L_.tau), m.tau.data(), N * sizeof(float));
    x_.upload(const_cast<std::uint8_t*>(L_.tissue), m.tissue.data(), N);
    std::vector<std::uint8_t> stat_class(N);
    for (std::size_t i = 0; i < N; ++i)
      stat_class[i] = m.counted(static_cast<Index>(i)) ? m.tissue[i] : static_cast<std::uint8_t>(kTissueCount);
    x_.upload(const_cast<std::uint8_t*>(L_.stat_class), stat_class.data(), N);
    for (int a = 0; a < 3; ++a)
      x_.upload(const_cast<std::uint16_t*>(L_.link_index[a]), m.link_index[a].data(), N * sizeof(std::uint16_t));
    x_.upload(const_cast<LinkLimits*>(L_.link_table), m.link_table.data(), m.link_table.size() * sizeof(LinkLimits));
    x_.upload(L_.disp, s.disp.data(), N * sizeof(Vec3));
    x_.upload(L_.pre, s.disp.data(), N * sizeof(Vec3));  // invariant between frames: u- == u
    x_.upload(L_.vel, s.vel.data(), N * sizeof(Vec3));
    std::fill(buf.begin(), buf.end(), solver::kInf);  // a new wave starts from scratch
    x_.upload(L_.time, buf.data(), N * sizeof(float));
    std::vector<std::uint8_t> fl(N4, 0);
    for (std::size_t i = 0; i < N; ++i) fl[i] = (s.flags[i] & kFixed) ? 0 : static_cast<std::uint8_t>(s.flags[i] & ~kInternalBits);
    x_.upload(L_.flags, fl.data(), N4);
    // Anything that carries velocity or is off rest must be looked at by the first frame.
    std::vector<std::uint8_t> touched(NB, 0);
    for (Index i = 0; i < n; ++i) {
      const std::size_t u = static_cast<std::size_t>(i);
      if (!(s.vel[u] == Vec3{}) || !(s.disp[u] == Vec3{})) touched[static_cast<std::size_t>(L_.brick_of_index(i))] = 1;
    }
    x_.upload(L_.touched, touched.data(), NB);
    x_.upload(L_.hot, touched.data(), NB);
    x_.zero(L_.has_vel, NB);
    x_.zero(L_.speed, NB * sizeof(float));
    x_.zero(L_.wave, NB);
    x_.zero(L_.worked, NB);
    std::vector<std::uint8_t> all(NB, 1);
    x_.upload(L_.unchecked, all.data(), NB);  // a loaded state is checked once
    x_.zero(ctl_, sizeof(Ctl));

    cache_slot_.assign(NB, -1);
    // The restoration's host state, allocated here (as on the CPU) rather than in the frame of
    // the first restoration, where it would stall that frame on a large lattice.
    restorer_.init(m);
    host_fixed_.assign(N, 0);
    bucket_width_.reset(m);
    delta_ = bucket_width_.value();
    fixed_.clear();
    n_fixed_dev_ = 0;
    active_ = active_elements_ = 0;
    activity_known_ = true;
    layer_pending_ = false;
    x_.invalidate();
    x_.sync();
  }

  void params_changed(const Params& p) override {
    const bool bricks_changed = p.solver.brick_size != p_.solver.brick_size;
    p_ = p;
    k_ = dynamics::make_constants(p.dynamics, m_->dims);
    wall_ = solver::make_wall(m_->dims, p.dynamics.margin);
    x_.invalidate();  // the relaxation graph holds the threshold and the wall
    {
      std::vector<std::uint8_t> all(static_cast<std::size_t>(L_.grid.count), 1);
      x_.upload(L_.unchecked, all.data(), all.size());  // a new margin may put elements outside the wall
    }
    if (bricks_changed) {
      State s;
      download(s);
      load(*m_, p, s);
    }
  }

  void install_fixed(const Control& c) override {
    const std::vector<Index>& elements = c.fixed();
    const std::vector<Vec3>& targets = c.targets();
    const std::vector<std::uint8_t>& flags = c.flags();
    if (bucket_width_.update(*m_, elements, flags)) delta_ = bucket_width_.value();
    // Duplicates (an anchor that is also grabbed): the last occurrence wins, as on the CPU.
    std::vector<int> idx;
    std::vector<Vec3> tg;
    std::vector<std::uint8_t> fl;
    idx.reserve(elements.size());
    if (seen_.size() != static_cast<std::size_t>(L_.n)) seen_.assign(static_cast<std::size_t>(L_.n), 0);
    for (std::size_t k = elements.size(); k-- > 0;) {
      const Index e = elements[k];
      if (seen_[static_cast<std::size_t>(e)]) continue;
      seen_[static_cast<std::size_t>(e)] = 1;
      idx.push_back(static_cast<int>(e));
      tg.push_back(targets[k]);
      fl.push_back(flags[k]);
    }
    for (int e : idx) seen_[static_cast<std::size_t>(e)] = 0;
    const int n = static_cast<int>(idx.size());
    ensure_fixed_capacity(n);
    FixedArgs a;
    a.L = L_;
    a.old_fixed = fixed_dev_[cur_fixed_];
    a.n_old = n_fixed_dev_;
    const int nxt = cur_fixed_ ^ 1;
    if (n > 0) {
      x_.upload(fixed_dev_[nxt], idx.data(), idx.size() * sizeof(int));
      x_.upload(targets_dev_[nxt], tg.data(), tg.size() * sizeof(Vec3));
      x_.upload(fflags_dev_[nxt], fl.data(), fl.size());
    }
    a.fixed = fixed_dev_[nxt];
    a.fflags = fflags_dev_[nxt];
    a.targets = targets_dev_[nxt];
    a.n = n;
    x_.set_fixed(a);
    cur_fixed_ = nxt;
    n_fixed_dev_ = n;
    fixed_ = std::move(idx);
  }

  void begin_frame() override {
    settle_layer();  // the last frame's layer statistics have arrived
    x_.zero(L_.worked, static_cast<std::size_t>(L_.grid.count));
    active_ = active_elements_ = 0;
    activity_known_ = true;
  }
  /// Phase p is timed between events 2p and 2p + 1 of the executor (CUDA events on the stream).
  void phase_begin(Phase p) override { x_.mark(2 * static_cast<int>(p)); }
  void phase_end(Phase p) override { x_.mark(2 * static_cast<int>(p) + 1); }
  double phase_ms(Phase p) override { return x_.elapsed(2 * static_cast<int>(p), 2 * static_cast<int>(p) + 1); }

 public:
  void snapshot() override {}  // fused into velocity_layer(): X- == X between frames

  PropagateStats propagate() override {
    FixedArgs fa = fixed_args();
    x_.apply_targets(fa);
    x_.reset_wave(L_);
    x_.copy(save_touched_, L_.touched, static_cast<std::size_t>(L_.grid.count));
    x_.copy(save_hot_, L_.hot, static_cast<std::size_t>(L_.grid.count));
    for (;;) {
      PropArgs a;
      a.L = L_;
      a.fixed = fixed_dev_[cur_fixed_];
      a.nfixed = n_fixed_dev_;
      for (int k = 0; k < 2; ++k) {
        a.pend_e[k] = pend_e_[k];
        a.pend_b[k] = pend_b_[k];
      }
      a.pend_cap = pend_cap_;
      a.list = list_;
      a.st = st_;
      a.sp = sp_;
      a.list_cap = list_cap_;
      a.delta = static_cast<double>(delta_);
      a.wall = wall_;
      a.max_sweeps = p_.solver.max_propagation_sweeps;
      a.ctl = &ctl_->prop;
      x_.propagate(a);
      x_.count_touched(L_, &ctl_->prop);
      x_.download(&host_ctl_->prop, &ctl_->prop, sizeof(PropCtl));
      x_.sync();
      if (!host_ctl_->prop.overflow) break;
      // A list was too small: grow, put the lattice back as it was before the wave, rerun.
      ++regrowths_;
      const std::size_t N = static_cast<std::size_t>(L_.n);
      // Upper bounds: every push (6 per final or FIXED element) / every element fits. The caps
      // also keep the kernel's 32-bit counters from wrapping: a round appends at most
      // pend_cap + 6 * list_cap entries (< 2^31 with these limits).
      const std::size_t pend_max = std::min<std::size_t>(6 * N + 6 * fixed_.size() + 64, kMaxPendCap);
      const std::size_t list_max = std::min<std::size_t>(N + 64, kMaxListCap);
      const int pend_new = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(pend_cap_) * 4, pend_max));
      const int list_new = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(list_cap_) * 4, list_max));
      if (pend_new <= pend_cap_ && list_new <= list_cap_)
        throw Error("CUDA backend: propagation lists overflowed at their largest size (pending " +
                    std::to_string(pend_cap_) + ", bucket " + std::to_string(list_cap_) + " entries)");
      pend_cap_ = std::max(pend_cap_, pend_new);
      list_cap_ = std::max(list_cap_, list_new);
      alloc_prop_lists();
      x_.full_reset(L_);
      x_.zero(L_.wave, static_cast<std::size_t>(L_.grid.count));
      x_.copy(L_.touched, save_touched_, static_cast<std::size_t>(L_.grid.count));
      x_.copy(L_.hot, save_hot_, static_cast<std::size_t>(L_.grid.count));
    }
    PropagateStats st;
    st.sweeps = host_ctl_->prop.sweeps;
    st.converged = host_ctl_->prop.converged != 0;
    st.reached = host_ctl_->prop.reached;
    activity_known_ = false;
    return st;
  }

  /// The link restoration runs on the host with the host schedule (solver::LinkRestorer), so it
  /// computes exactly the CPU backend's floats. The device first runs the host's check
  /// (check_links_block): in most frames it finds nothing, and nothing is copied. Otherwise the
  /// host check runs only on the bricks the device flagged (find_violations attributes each
  /// violation to the brick of its element, so it finds the same seeds and statistics as over
  /// every changed brick), and the restoration reads the positions through a brick cache
  /// (BrickCache): only the bricks it reaches are copied, so the copies follow the region it
  /// works on, not the lattice. The FIXED set is known on the host (fixed_); only the moved
  /// elements go back. A device schedule of the restoration itself is future work.
  RestoreStats restore_links() override { return restore(false); }
  /// After the velocity layer: X- follows every element the restoration moves.
  RestoreStats restore_frame_end() override { return restore(true); }

  RestoreStats restore(bool frame_end) {
    const std::size_t NB = static_cast<std::size_t>(L_.grid.count);
    CheckArgs ca;
    ca.L = L_;
    ca.wall = wall_;
    ca.found = &ctl_->links_outside;
    ca.bricks = check_bricks_;
    ca.fold = frame_end;  // the fold guard downloads only bricks where a link could fold a cell
    x_.zero(ca.found, sizeof(int));
    x_.zero(ca.bricks, NB);
    x_.check_links(ca);
    activity_known_ = false;  // the checked bricks had work
    // The frame-end guard leaves the bricks unchecked: the next ChainMail stage still holds every
    // link the velocity layer moved to its box.
    if (!frame_end) x_.zero(L_.unchecked, NB);
    x_.download(&host_ctl_->links_outside, ca.found, sizeof(int));
    x_.sync();
    if (!host_ctl_->links_outside) return {};
    host_bricks_.resize(NB);
    x_.download(host_bricks_.data(), check_bricks_, NB);
    x_.sync();
    solver::BrickGrid::to_list(host_bricks_, check_list_);
    for (int e : fixed_) host_fixed_[static_cast<std::size_t>(e)] = 1;
    moved_elements_.clear();
    RestoreStats st;
    try {
      // The flagged bricks and their face neighbours (where find_violations reads) in one copy.
      cache_clear();
      L_.grid.dilate_to_list(host_bricks_, prefetch_list_);
      cache_fetch(prefetch_list_);
      BrickCache access(*this);
      seeds_.clear();
      solver::find_violations(*m_, L_.grid, check_list_, access, wall_, seeds_, st);
      host_moved_bricks_.assign(NB, 0);
      if (frame_end) {
        st = {};
        restorer_.guard_folds(*m_, L_.grid, seeds_, access, wall_, host_moved_bricks_, st);
      } else {
        restorer_.restore(*m_, L_.grid, seeds_, access, wall_, host_moved_bricks_, st);
      }
    } catch (...) {
      // A copy failed halfway (device error, out of memory): leave no half-done host state
      // behind for the next restoration.
      host_fixed_.assign(host_fixed_.size(), 0);
      restorer_.init(*m_);
      cache_clear();
      throw;
    }
    for (int e : fixed_) host_fixed_[static_cast<std::size_t>(e)] = 0;
    upload_moved(frame_end);
    cache_clear();
    return st;
  }

  RelaxStats relax(int sweeps) override {
    RelaxStats st;
    if (sweeps <= 0) return st;
    if (sweeps > kMaxSweeps) throw Error("relax: sweeps = " + std::to_string(sweeps) + " is out of range [0, 256]");
    RelaxArgs a;
    a.L = L_;
    a.list = relax_list_;
    a.start = relax_start_;
    for (int r = 0; r < 3; ++r) a.phase[r] = relax_phase_[r];
    a.ctl = &ctl_->relax;
    a.threshold_sq = solver::squared_length_bound(p_.solver.relax_threshold);
    a.slack_sq = solver::squared_length_bound(p_.solver.relax_slack);
    a.omega = p_.solver.relax_omega;
    a.wall = wall_;
    a.sweeps = sweeps;
    x_.relax(a);
    // sweeps, active_max and last_max are contiguous at the end of RelaxCtl
    x_.download(&host_ctl_->relax.stop, &ctl_->relax.stop, sizeof(RelaxCtl) - offsetof(RelaxCtl, stop));
    x_.sync();
    st.sweeps = host_ctl_->relax.sweeps;
    st.max_correction = host_ctl_->relax.last_max;
    activity_known_ = false;
    return st;
  }

  void velocity_layer(SpeedStats* speeds) override {
    LayerArgs a = layer_args(speeds != nullptr, false);
    x_.zero(&ctl_->layer, sizeof(LayerCtl));
    x_.layer(a);
    if (speeds) x_.speed_sum(a);
    x_.download(&host_ctl_->layer, &ctl_->layer, sizeof(LayerCtl));
    layer_pending_ = true;
    activity_known_ = false;
    if (speeds) {
      x_.sync();
      layer_pending_ = false;
      SpeedStats out;
      for (int t = 0; t < kTissueCount; ++t) {
        out.sum[t] = host_ctl_->layer.sum[t];
        out.max[t] = host_ctl_->layer.max[t];
      }
      out.moved = host_ctl_->layer.moved;
      *speeds = out;
    }
  }

  /// The bricks some stage worked on since the frame began (their union, counted on the host
  /// from the device's per-brick flags, as CpuBackend counts its own) and the elements in them.
  Index active_bricks() const override {
    const_cast<DeviceBackend*>(this)->settle_activity();
    return active_;
  }
  Index active_elements() const override {
    const_cast<DeviceBackend*>(this)->settle_activity();
    return active_elements_;
  }

  DeviceProbe probe(int reps) override {
    if (reps < 1) reps = 1;
    return x_.probe(layer_args(false, true), reps, held_);
  }

  void download(State& s) override {
    const std::size_t N = static_cast<std::size_t>(L_.n);
    s.disp.resize(N);
    s.vel.resize(N);
    s.time.resize(N);
    s.flags.resize(N);
    x_.download(s.disp.data(), L_.disp, N * sizeof(Vec3));
    x_.download(s.vel.data(), L_.vel, N * sizeof(Vec3));
    x_.download(s.time.data(), L_.time, N * sizeof(float));
    x_.download(s.flags.data(), L_.flags, N);
    x_.sync();
    for (auto& f : s.flags) f = static_cast<std::uint8_t>(f & ~kInternalBits);
  }
  void download_displacements(std::vector<Vec3>& disp) override {
    disp.resize(static_cast<std::size_t>(L_.n));
    x_.download(disp.data(), L_.disp, disp.size() * sizeof(Vec3));
    x_.sync();
  }
  Vec3 displacement(Index i) override {
    if (i < 0 || i >= L_.n) throw Error("displacement: element " + std::to_string(i) + " is out of range");
    Vec3 v;
    x_.download(&v, L_.disp + i, sizeof(Vec3));
    x_.sync();
    return v;
  }

 private:
  /// Waits for the velocity layer's statistics (queued without a wait when no speeds were asked).
  void settle_layer() {
    if (!layer_pending_) return;
    x_.sync();
    layer_pending_ = false;
  }
  void settle_activity() {
    if (activity_known_) return;
    const std::size_t NB = static_cast<std::size_t>(L_.grid.count);
    worked_host_.resize(NB);
    x_.download(worked_host_.data(), L_.worked, NB);
    x_.sync();
    layer_pending_ = false;
    active_ = active_elements_ = 0;
    for (std::size_t b = 0; b < NB; ++b)
      if (worked_host_[b]) {
        Int3 lo, hi;
        L_.grid.range(static_cast<Index>(b), lo, hi);
        ++active_;
        active_elements_ += static_cast<Index>(hi.x - lo.x) * (hi.y - lo.y) * (hi.z - lo.z);
      }
    activity_known_ = true;
  }
  template <class T>
  T* alloc(std::size_t count, const char* what) {
    const std::size_t bytes = std::max<std::size_t>(count, 1) * sizeof(T);
    void* p = x_.alloc(bytes, what);
    blocks_.push_back(p);
    held_ += bytes;
    return static_cast<T*>(p);
  }
  void release(void* p, std::size_t bytes) {
    if (!p) return;
    auto it = std::find(blocks_.begin(), blocks_.end(), p);
    if (it != blocks_.end()) blocks_.erase(it);
    x_.release(p);
    held_ -= bytes;
  }
  /// Host address of element i's position in the brick cache; a brick not yet there is copied
  /// now, with its face neighbours that are not there either (the restoration's work list moves
  /// to neighbours, so they are likely next).
  Vec3* cache_element(Index i) {
    const solver::BrickGrid& g = L_.grid;
    const int x = static_cast<int>(i % g.dims.x);
    const Index r = i / g.dims.x;
    const int y = static_cast<int>(r % g.dims.y), z = static_cast<int>(r / g.dims.y);
    const Index b = g.brick_of(x, y, z);
    if (cache_slot_[static_cast<std::size_t>(b)] < 0) {
      ++cache_misses_;
      fetch_list_.assign(1, b);
      g.for_each_face_neighbour(b, [&](Index n) {
        if (cache_slot_[static_cast<std::size_t>(n)] < 0) fetch_list_.push_back(n);
      });
      cache_fetch(fetch_list_);
    }
    const int bs = g.size;
    const std::size_t q = static_cast<std::size_t>(x % bs + bs * (y % bs + bs * (z % bs)));
    return cache_host_ + static_cast<std::size_t>(cache_slot_[static_cast<std::size_t>(b)]) * brick_volume() + q;
  }
  std::size_t brick_volume() const { return static_cast<std::size_t>(L_.grid.size) * L_.grid.size * L_.grid.size; }
  /// Copies the listed bricks (none of them in the cache yet) from the device into the cache.
  void cache_fetch(const std::vector<Index>& bricks) {
    const std::size_t n = bricks.size(), per = brick_volume();
    if (n == 0) return;
    if (cache_used_ + n > cache_cap_) grow_host_cache(std::max(cache_used_ + n, 2 * cache_cap_));
    grow_lists(gather_ids_, gather_out_, gather_cap_, n, per, "restoration brick list", "restoration brick copies");
    gather_ids_host_.assign(bricks.begin(), bricks.end());
    x_.upload(gather_ids_, gather_ids_host_.data(), n * sizeof(int));
    GatherArgs a;
    a.L = L_;
    a.bricks = gather_ids_;
    a.out = gather_out_;
    a.n = static_cast<int>(n);
    x_.gather_bricks(a);
    x_.download(cache_host_ + cache_used_ * per, gather_out_, n * per * sizeof(Vec3));
    x_.sync();
    for (std::size_t j = 0; j < n; ++j) cache_slot_[static_cast<std::size_t>(bricks[j])] = static_cast<int>(cache_used_ + j);
    cache_bricks_.insert(cache_bricks_.end(), bricks.begin(), bricks.end());
    cache_used_ += n;
    cache_fetched_ += static_cast<Index>(n);
  }
  /// Room for `cap` bricks, the bricks already there kept: pinned memory (copies at the bus's
  /// speed) where the driver grants it, pageable otherwise.
  void grow_host_cache(std::size_t cap) {
    const std::size_t per = brick_volume(), keep = cache_used_ * per;
    Vec3* pinned = nullptr;
    try {
      pinned = static_cast<Vec3*>(x_.host_alloc(cap * per * sizeof(Vec3), "restoration brick cache"));
    } catch (const Error&) {
      pinned = nullptr;
    }
    if (pinned) {
      if (keep) std::memcpy(static_cast<void*>(pinned), cache_host_, keep * sizeof(Vec3));
      release_host_cache();
      cache_pinned_ = pinned;
      cache_host_ = pinned;
    } else {
      std::vector<Vec3> bigger(cap * per);
      if (keep) std::memcpy(static_cast<void*>(bigger.data()), cache_host_, keep * sizeof(Vec3));
      release_host_cache();
      cache_pageable_ = std::move(bigger);
      cache_host_ = cache_pageable_.data();
    }
    cache_cap_ = cap;
  }
  void release_host_cache() noexcept {
    if (cache_pinned_) x_.host_release(cache_pinned_);
    cache_pinned_ = nullptr;
    cache_pageable_.clear();
    cache_pageable_.shrink_to_fit();
    cache_host_ = nullptr;
  }
  /// Forgets the bricks of this restoration (the device moves on; the room is kept).
  void cache_clear() {
    for (Index b : cache_bricks_) cache_slot_[static_cast<std::size_t>(b)] = -1;
    cache_bricks_.clear();
    cache_used_ = 0;
  }
  /// Device room for n entries of a pair of lists (indices, and `per` values per index), grown
  /// to at least twice the old room; the contents are not kept.
  void grow_lists(int*& ids, Vec3*& values, std::size_t& cap, std::size_t n, std::size_t per, const char* what_ids,
                  const char* what_values) {
    if (n <= cap) return;
    release(ids, cap * sizeof(int));
    release(values, cap * per * sizeof(Vec3));
    ids = nullptr;
    values = nullptr;
    const std::size_t room = std::max(n, 2 * cap);
    cap = 0;  // no room if an allocation below fails
    ids = alloc<int>(room, what_ids);
    values = alloc<Vec3>(room * per, what_values);
    cap = room;
  }
  /// Uploads the elements the restoration moved and puts them in place on the device.
  void upload_moved(bool frame_end) {
    std::sort(moved_elements_.begin(), moved_elements_.end());
    moved_elements_.erase(std::unique(moved_elements_.begin(), moved_elements_.end()), moved_elements_.end());
    const std::size_t n = moved_elements_.size();
    if (n == 0) return;
    moved_positions_.resize(n);
    for (std::size_t j = 0; j < n; ++j) moved_positions_[j] = *cache_element(moved_elements_[j]);
    grow_lists(scatter_elements_, scatter_positions_, scatter_cap_, n, 1, "restored elements", "restored positions");
    x_.upload(scatter_elements_, moved_elements_.data(), n * sizeof(int));
    x_.upload(scatter_positions_, moved_positions_.data(), n * sizeof(Vec3));
    ScatterArgs a;
    a.L = L_;
    a.elements = scatter_elements_;
    a.positions = scatter_positions_;
    a.n = static_cast<int>(n);
    a.snapshot = frame_end;
    x_.scatter_positions(a);
    x_.sync();  // the host vectors above are reused by the next restoration
  }
  void free_all() noexcept {
    for (void* p : blocks_) x_.release(p);
    blocks_.clear();
    release_host_cache();
    cache_cap_ = cache_used_ = 0;
    cache_bricks_.clear();
    gather_ids_ = nullptr;
    gather_out_ = nullptr;
    gather_cap_ = 0;
    scatter_elements_ = nullptr;
    scatter_positions_ = nullptr;
    scatter_cap_ = 0;
    if (host_ctl_) x_.host_release(host_ctl_);
    host_ctl_ = nullptr;
    held_ = 0;
    fixed_cap_ = 0;
    for (int k = 0; k < 2; ++k) fixed_dev_[k] = nullptr, targets_dev_[k] = nullptr, fflags_dev_[k] = nullptr;
    for (int k = 0; k < 2; ++k) pend_e_[k] = nullptr, pend_b_[k] = nullptr;
    list_ = nullptr, st_ = nullptr, sp_ = nullptr;
    prop_bytes_ = 0;
  }
  void alloc_prop_lists() {
    for (int k = 0; k < 2; ++k) {
      release(pend_e_[k], prop_pend_bytes_e_);
      release(pend_b_[k], prop_pend_bytes_b_);
    }
    release(list_, prop_list_bytes_i_);
    release(st_, prop_list_bytes_f_);
    release(sp_, prop_list_bytes_v_);
    const std::size_t pc = static_cast<std::size_t>(pend_cap_), lc = static_cast<std::size_t>(list_cap_);
    for (int k = 0; k < 2; ++k) {
      pend_e_[k] = alloc<int>(pc, "propagation pending list");
      pend_b_[k] = alloc<unsigned long long>(pc, "propagation pending list");
    }
    list_ = alloc<int>(lc, "propagation bucket list");
    st_ = alloc<float>(lc, "propagation scratch");
    sp_ = alloc<Vec3>(lc, "propagation scratch");
    prop_pend_bytes_e_ = pc * sizeof(int);
    prop_pend_bytes_b_ = pc * sizeof(unsigned long long);
    prop_list_bytes_i_ = lc * sizeof(int);
    prop_list_bytes_f_ = lc * sizeof(float);
    prop_list_bytes_v_ = lc * sizeof(Vec3);
    x_.invalidate();
  }
  void ensure_fixed_capacity(int n) {
    if (n <= fixed_cap_ && fixed_dev_[0]) return;
    // Keep the current list (it is released by the next set_fixed kernel): copy it over.
    const int cap = std::max(n, std::max(64, fixed_cap_ * 2));
    int* nf[2];
    Vec3* nt[2];
    std::uint8_t* nfl[2];
    for (int k = 0; k < 2; ++k) {
      nf[k] = alloc<int>(static_cast<std::size_t>(cap), "fixed set");
      nt[k] = alloc<Vec3>(static_cast<std::size_t>(cap), "fixed targets");
      nfl[k] = alloc<std::uint8_t>(static_cast<std::size_t>(cap), "fixed flags");
    }
    if (fixed_dev_[cur_fixed_] && n_fixed_dev_ > 0) {
      x_.copy(nf[cur_fixed_], fixed_dev_[cur_fixed_], static_cast<std::size_t>(n_fixed_dev_) * sizeof(int));
      x_.copy(nt[cur_fixed_], targets_dev_[cur_fixed_], static_cast<std::size_t>(n_fixed_dev_) * sizeof(Vec3));
      x_.copy(nfl[cur_fixed_], fflags_dev_[cur_fixed_], static_cast<std::size_t>(n_fixed_dev_));
    }
    x_.sync();
    const std::size_t old = static_cast<std::size_t>(std::max(fixed_cap_, 1));
    for (int k = 0; k < 2; ++k) {
      release(fixed_dev_[k], old * sizeof(int));
      release(targets_dev_[k], old * sizeof(Vec3));
      release(fflags_dev_[k], old);
      fixed_dev_[k] = nf[k];
      targets_dev_[k] = nt[k];
      fflags_dev_[k] = nfl[k];
    }
    fixed_cap_ = cap;
  }
  FixedArgs fixed_args() const {
    FixedArgs a;
    a.L = L_;
    a.fixed = fixed_dev_[cur_fixed_];
    a.targets = targets_dev_[cur_fixed_];
    a.fflags = fflags_dev_[cur_fixed_];
    a.n = n_fixed_dev_;
    return a;
  }
  LayerArgs layer_args(bool speeds, bool all) const {
    LayerArgs a;
    a.L = L_;
    a.k = k_;
    a.speeds = speeds;
    a.all = all;
    a.sleep_speed = p_.solver.sleep ? p_.dynamics.sleep_speed : 0.0f;
    a.part_sum = part_sum_;
    a.part_max = part_max_;
    a.part_moved = part_moved_;
    a.ctl = &ctl_->layer;
    return a;
  }

  X x_;
  const Model* m_ = nullptr;
  Params p_;
  dynamics::LayerConstants k_{};
  Lattice L_{};
  float delta_ = 1.0f;
  solver::BucketWidth bucket_width_;  ///< of the installed FIXED set (delta_ is its value)
  // link restoration on the host (restore_links)
  /// Runs on the calling thread (no set_parallel): the brick cache copies a brick from the
  /// device when first read, so its reads must not come from two threads at once.
  solver::LinkRestorer restorer_;
  solver::Wall wall_;
  std::vector<std::uint8_t> host_bricks_;
  std::vector<Index> check_list_, seeds_;
  std::vector<std::uint8_t> host_fixed_, host_moved_bricks_;
  std::vector<int> moved_elements_;
  std::vector<Vec3> moved_positions_;
  // the brick cache of the restoration: slot per brick (-1: not on the host), host room for
  // cache_cap_ bricks (pinned where the driver grants it), the device's packed copies
  std::vector<int> cache_slot_;
  std::vector<Index> cache_bricks_, prefetch_list_, fetch_list_;
  Vec3* cache_host_ = nullptr;
  Vec3* cache_pinned_ = nullptr;
  std::vector<Vec3> cache_pageable_;
  std::size_t cache_cap_ = 0, cache_used_ = 0;
  std::vector<int> gather_ids_host_;
  int* gather_ids_ = nullptr;
  Vec3* gather_out_ = nullptr;
  std::size_t gather_cap_ = 0;
  Index cache_fetched_ = 0, cache_misses_ = 0;
  // the moved elements on the device (grown as needed)
  int* scatter_elements_ = nullptr;
  Vec3* scatter_positions_ = nullptr;
  std::size_t scatter_cap_ = 0;
  /// The restoration's view of the device positions (linear element order) through the brick
  /// cache; records every element it moves.
  struct BrickCache final : solver::RestoreAccess {
    explicit BrickCache(DeviceBackend& d) : dev(d) {}
    Vec3 displacement(Index i) const override { return *dev.cache_element(i); }
    void set_coordinate(Index i, int axis, float value) override {
      (*dev.cache_element(i))[axis] = value;
      dev.moved_elements_.push_back(static_cast<int>(i));
    }
    bool fixed(Index i) const override { return dev.host_fixed_[static_cast<std::size_t>(i)] != 0; }
    DeviceBackend& dev;
  };
  std::vector<void*> blocks_;
  std::size_t held_ = 0;
  Ctl* ctl_ = nullptr;
  Ctl* host_ctl_ = nullptr;
  std::uint8_t *save_touched_ = nullptr, *save_hot_ = nullptr;
  int* relax_list_ = nullptr;
  std::uint8_t* check_bricks_ = nullptr;  ///< per brick: the link check found work there
  std::uint8_t* relax_start_ = nullptr;
  std::uint8_t* relax_phase_[3] = {nullptr, nullptr, nullptr};
  float *part_sum_ = nullptr, *part_max_ = nullptr;
  int* part_moved_ = nullptr;
  // propagation lists
  int pend_cap_ = 0, list_cap_ = 0;
  int* pend_e_[2] = {nullptr, nullptr};
  unsigned long long* pend_b_[2] = {nullptr, nullptr};
  int* list_ = nullptr;
  float* st_ = nullptr;
  Vec3* sp_ = nullptr;
  std::size_t prop_pend_bytes_e_ = 0, prop_pend_bytes_b_ = 0, prop_list_bytes_i_ = 0, prop_list_bytes_f_ = 0,
              prop_list_bytes_v_ = 0, prop_bytes_ = 0;
  // FIXED set (double-buffered: the kernel releases the old set and sets the new one)
  int* fixed_dev_[2] = {nullptr, nullptr};
  Vec3* targets_dev_[2] = {nullptr, nullptr};
  std::uint8_t* fflags_dev_[2] = {nullptr, nullptr};
  int fixed_cap_ = 0, cur_fixed_ = 0, n_fixed_dev_ = 0;
  std::vector<int> fixed_;
  std::vector<std::uint8_t> seen_;
  Index active_ = 0, active_elements_ = 0;  ///< of L_.worked, when activity_known_
  bool activity_known_ = true;
  std::vector<std::uint8_t> worked_host_;
  bool layer_pending_ = false;
  int pend_override_ = 0, list_override_ = 0, regrowths_ = 0;
};

}  // namespace hpcm::gpu
