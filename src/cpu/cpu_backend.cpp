#include "cpu/cpu_backend.hpp"

#include <algorithm>
#include <atomic>
#include <functional>

namespace hpcm::cpu {

namespace {

/// The link restoration's view of the storage. At frame end (after the velocity layer) X-
/// follows X, so that it stays the frame-end position.
class StorageAccess final : public solver::RestoreAccess {
 public:
  StorageAccess(Storage& st, bool frame_end) : st_(st), frame_end_(frame_end) {}
  Vec3 displacement(Index i) const override { return st_.displacement(i); }
  void set_coordinate(Index i, int axis, float value) override {
    const std::size_t k = static_cast<std::size_t>(st_.lay.at(i));
    st_.p[axis][k] = value;
    if (frame_end_) st_.q[axis][k] = value;
  }
  bool fixed(Index i) const override { return (st_.flags[static_cast<std::size_t>(st_.lay.at(i))] & kFixed) != 0; }

 private:
  Storage& st_;
  bool frame_end_;
};

}  // namespace

void CpuBackend::upload(const Model& m, const Params& p, const State& s) {
  p.validate();
  if (static_cast<Index>(s.disp.size()) != m.size() || s.vel.size() != s.disp.size() || s.flags.size() != s.disp.size())
    throw Error("CPU backend: state size does not match the model (" + std::to_string(m.size()) + " elements)");
  m_ = &m;
  p_ = p;
  k_ = dynamics::make_constants(p.dynamics, m.dims);
  wall_ = solver::make_wall(m.dims, p.dynamics.margin);
  const int threads = default_thread_count();
  if (!pool_ || pool_->threads() != threads) pool_ = std::make_unique<WorkerPool>(threads);
  st_.load(m, s, *pool_);
  grid_.init(m.dims, p.solver.brick_size);
  const std::size_t nb = static_cast<std::size_t>(grid_.count);
  touched_.assign(nb, 0);
  unchecked_.assign(nb, 1);  // a loaded state is checked once
  // Anything that carries velocity or is off rest must be looked at by the first frame.
  for (Index i = 0; i < m.size(); ++i)
    if (!(s.vel[static_cast<std::size_t>(i)] == Vec3{}) || !(s.disp[static_cast<std::size_t>(i)] == Vec3{}))
      touched_[static_cast<std::size_t>(grid_.brick_of_index(i))] = 1;
  hot_ = touched_;
  worked_.assign(nb, 0);
  stamp_ = next_stamp();
  written_.assign(nb, stamp_);  // every brick is new to every host copy
  fixed_ = {};
  still_flags_.assign(static_cast<std::size_t>(m.size()), 0);
  still_targets_pending_ = false;
  propagation_.init(m, st_.lay, grid_);
  bucket_width_.reset(m);
  propagation_.set_bucket_width(bucket_width_.value());
  const SimdKernels kernels = select_kernels(chosen_kernels(forced_kernel_));
  kernel_name_ = kernels.name;
  relaxation_.init(grid_, kernels.relax);
  layer_.init(grid_, kernels.layer);
  check_.init(kernels.link_check);
  restorer_.init(m);
  // The fold guard's search for folded cells on the pool (the same cells, found faster).
  restorer_.set_parallel([this](std::int64_t items, const std::function<void(std::int64_t)>& item) {
    pool_->run(items, [&item](std::int64_t i) { item(i); });
  });
}

void CpuBackend::params_changed(const Params& p) {
  const bool bricks_changed = p.solver.brick_size != p_.solver.brick_size;
  p_ = p;
  k_ = dynamics::make_constants(p.dynamics, m_->dims);
  wall_ = solver::make_wall(m_->dims, p.dynamics.margin);
  mark_all(unchecked_);  // a new margin may put elements outside the wall
  if (bricks_changed) {
    State s;
    download(s);
    load(*m_, p, s);
  }
}

void CpuBackend::install_fixed(const Control& c) {
  const Layout& L = st_.lay;
  auto flag_of = [&](Index i) -> std::uint8_t& { return st_.flags[static_cast<std::size_t>(L.at(i))]; };
  solver::FixedParts next = solver::FixedParts::split(c.fixed(), c.targets(), c.flags());
  // Elements that may leave the FIXED set: the old tool, and the old still part if it changes.
  std::vector<Index> leaving = fixed_.tool.elements;
  for (Index i : fixed_.tool.elements) {
    flag_of(i) = still_flags_[static_cast<std::size_t>(i)];
    mark_written(i);
  }
  if (!(next.still == fixed_.still)) {
    // The anchors changed (rare: a new control from the caller, new params): O(still) work.
    for (Index i : fixed_.still.elements) {
      flag_of(i) = 0;
      still_flags_[static_cast<std::size_t>(i)] = 0;
      mark_written(i);
      leaving.push_back(i);
    }
    fixed_.still = std::move(next.still);
    const solver::FixedParts::Part& still = fixed_.still;
    for (std::size_t k = 0; k < still.elements.size(); ++k)
      still_flags_[static_cast<std::size_t>(still.elements[k])] = static_cast<std::uint8_t>(kFixed | still.flags[k]);
    for (Index i : still.elements) {
      flag_of(i) = still_flags_[static_cast<std::size_t>(i)];
      mark_written(i);
    }
    if (bucket_width_.update(*m_, still.elements)) propagation_.set_bucket_width(bucket_width_.value());
    propagation_.set_still(still.elements);
    still_targets_pending_ = true;
  }
  fixed_.tool = std::move(next.tool);
  for (std::size_t k = 0; k < fixed_.tool.elements.size(); ++k) {
    flag_of(fixed_.tool.elements[k]) = static_cast<std::uint8_t>(kFixed | fixed_.tool.flags[k]);
    mark_written(fixed_.tool.elements[k]);
  }
  // Elements released from FIXED (grab released) must be relaxed again: mark their bricks.
  for (Index i : leaving)
    if (!(flag_of(i) & kFixed)) {
      const std::size_t b = static_cast<std::size_t>(grid_.brick_of_index(i));
      hot_[b] = touched_[b] = 1;
    }
}

PropagateStats CpuBackend::propagate() {
  const Layout& L = st_.lay;
  // FIXED elements move only here, to their targets: the still part's stay there until it
  // changes, so only the tool's are looked at every wave.
  auto apply_targets = [&](const solver::FixedParts::Part& part) {
    for (std::size_t k = 0; k < part.elements.size(); ++k) {
      const std::size_t e = static_cast<std::size_t>(L.at(part.elements[k]));
      const Vec3 t = part.targets[k];
      if (!(Vec3{st_.p[0][e], st_.p[1][e], st_.p[2][e]} == t)) {
        for (int a = 0; a < 3; ++a) st_.p[a][e] = t[a];
        const std::size_t b = static_cast<std::size_t>(grid_.brick_of_index(part.elements[k]));
        touched_[b] = hot_[b] = 1;
      }
    }
  };
  if (still_targets_pending_) {
    apply_targets(fixed_.still);
    still_targets_pending_ = false;
  }
  apply_targets(fixed_.tool);
  const PropagateStats ps =
      propagation_.run(st_, fixed_.tool.elements, wall_, p_.solver.max_propagation_sweeps, touched_, hot_, *pool_);
  for (std::size_t b = 0; b < touched_.size(); ++b) worked_[b] |= touched_[b];
  return ps;
}

RelaxStats CpuBackend::relax(int sweeps) {
  if (!p_.solver.sleep) mark_all(hot_);  // every brick awake: the exact reference
  const RelaxContext ctx = make_relax_context(st_, *m_, wall_, p_.solver);
  return relaxation_.run(ctx, sweeps, hot_, touched_, worked_, *pool_);
}

RestoreStats CpuBackend::restore_links() { return restore(false); }

RestoreStats CpuBackend::restore_frame_end() { return restore(true); }

RestoreStats CpuBackend::restore(bool frame_end) {
  RestoreStats rs;
  for (std::size_t b = 0; b < unchecked_.size(); ++b) unchecked_[b] |= touched_[b];
  if (!p_.solver.sleep) mark_all(unchecked_);
  grid_.dilate_to_list(unchecked_, check_list_);
  // The frame-end guard leaves the bricks unchecked: the next ChainMail stage still holds every
  // link the velocity layer moved to its box.
  if (!frame_end) std::fill(unchecked_.begin(), unchecked_.end(), 0);
  if (check_list_.empty()) return rs;
  for (Index b : check_list_) worked_[static_cast<std::size_t>(b)] = 1;
  StorageAccess access(st_, frame_end);
  seeds_.clear();
  check_.run(st_, grid_, check_list_, wall_, seeds_, rs, *pool_);
  if (seeds_.empty()) return rs;
  std::vector<std::uint8_t> moved(touched_.size(), 0);
  if (frame_end) {
    // As the CUDA backend: the bricks with a + link that may take part in a fold (such a link is
    // outside its box, so its lower end is a seed), then the links outside their boxes there.
    fold_bricks_.assign(touched_.size(), 0);
    const Int3 d = m_->dims;
    const Index stride[3] = {1, d.x, static_cast<Index>(d.x) * d.y};
    for (Index e : seeds_) {
      const Int3 c = m_->coords(e);
      const int cc[3] = {c.x, c.y, c.z}, n[3] = {d.x, d.y, d.z};
      for (int a = 0; a < 3; ++a)
        if (cc[a] + 1 < n[a] && solver::may_fold(access.displacement(e), access.displacement(e + stride[a]), a))
          fold_bricks_[static_cast<std::size_t>(grid_.brick_of_index(e))] = 1;
    }
    solver::BrickGrid::to_list(fold_bricks_, check_list_);
    seeds_.clear();
    RestoreStats links;  // the guard reports the cells it found folded, not these links
    // The same elements as solver::find_violations over these bricks (the check is its exact
    // rule, sorted and unique), found by the threads and the vector filter.
    check_.run(st_, grid_, check_list_, wall_, seeds_, links, *pool_);
    rs = {};
    restorer_.guard_folds(*m_, grid_, seeds_, access, wall_, moved, rs);
  } else {
    restorer_.restore(*m_, grid_, seeds_, access, wall_, moved, rs);
  }
  // Bricks the restoration moved are touched (the velocity layer visits them); relaxation
  // looks at them again next frame.
  for (std::size_t b = 0; b < moved.size(); ++b)
    if (moved[b]) touched_[b] = hot_[b] = 1;
  return rs;
}

void CpuBackend::velocity_layer(SpeedStats* speeds) {
  layer_.apply(st_, k_, p_.solver.sleep ? p_.dynamics.sleep_speed : 0.0f, !p_.solver.sleep, touched_, hot_, unchecked_,
               worked_, speeds, *pool_);
}

std::uint64_t CpuBackend::next_stamp() {
  // One sequence for every backend of the process: a host copy kept with another backend
  // (or before a reload) holds a smaller stamp than anything this one writes from now on.
  static std::atomic<std::uint64_t> counter{1};
  return ++counter;
}

void CpuBackend::stamp_written() {
  stamp_ = next_stamp();
  for (std::size_t b = 0; b < written_.size(); ++b)
    if (worked_[b] || touched_[b]) written_[b] = stamp_;
}

const std::vector<Index>& CpuBackend::written_since(std::uint64_t since) {
  stamp_written();
  since_list_.clear();
  for (std::size_t b = 0; b < written_.size(); ++b)
    if (written_[b] > since) since_list_.push_back(static_cast<Index>(b));
  return since_list_;
}

void CpuBackend::download_since(State& s, std::uint64_t& since) {
  const std::size_t n = static_cast<std::size_t>(m_->size());
  if (since == 0 || s.disp.size() != n || s.vel.size() != n || s.time.size() != n || s.flags.size() != n) {
    stamp_written();
    st_.store_state(s, *pool_);
  } else {
    st_.store_state(s, grid_, written_since(since), *pool_);
  }
  since = stamp_;
}

void CpuBackend::download_displacements_since(std::vector<Vec3>& disp, std::uint64_t& since) {
  if (since == 0 || disp.size() != static_cast<std::size_t>(m_->size())) {
    stamp_written();
    st_.store_displacements(disp, *pool_);
  } else {
    st_.store_displacements(disp, grid_, written_since(since), *pool_);
  }
  since = stamp_;
}

Index CpuBackend::active_bricks() const { return static_cast<Index>(std::count(worked_.begin(), worked_.end(), 1)); }

Index CpuBackend::active_elements() const {
  Index n = 0;
  for (Index b = 0; b < grid_.count; ++b)
    if (worked_[static_cast<std::size_t>(b)]) {
      Int3 lo, hi;
      grid_.range(b, lo, hi);
      n += static_cast<Index>(hi.x - lo.x) * (hi.y - lo.y) * (hi.z - lo.z);
    }
  return n;
}

}  // namespace hpcm::cpu
