#include "cpu/cpu_backend.hpp"

namespace hpcm::cpu {

void CpuBackend::load(const Model& m, const Params& p, const State& s) {
  m_ = &m;
  p_ = p;
  k_ = dynamics::make_constants(p.dynamics, m.dims);
  pos_ = s.pos;
  pre_ = s.pos;  // invariant between frames: X- == X
  vel_ = s.vel;
  // A new wave starts from scratch: stale times of an earlier wave would be read as final.
  time_.assign(s.pos.size(), solver::kInf);
  flags_ = s.flags;
  fixed_.clear();
  targets_.clear();
  for (Index i = 0; i < m.size(); ++i)
    if (flags_[i] & kFixed) flags_[i] = 0;
  chainmail_.init(m, p.solver.brick_size);
  chainmail_.set_wall(solver::make_wall(m.dims, p.dynamics.margin));
  layer_.init(chainmail_.grid());
  // Anything that carries velocity or is off rest must be looked at by the first frame.
  const auto& g = chainmail_.grid();
  for (Index i = 0; i < m.size(); ++i)
    if (!(vel_[i] == Vec3{}) || !(pos_[i] == m.rest(i))) chainmail_.touched()[g.brick_of_index(i)] = 1;
  chainmail_.hot() = chainmail_.touched();
  restorer_.init(m);
  unchecked_.assign(static_cast<std::size_t>(g.count), 1);  // a loaded state is checked once
}

void CpuBackend::set_params(const Params& p) {
  const bool bricks_changed = p.solver.brick_size != p_.solver.brick_size;
  p_ = p;
  k_ = dynamics::make_constants(p.dynamics, m_->dims);
  chainmail_.set_wall(solver::make_wall(m_->dims, p.dynamics.margin));
  std::fill(unchecked_.begin(), unchecked_.end(), 1);  // a new margin may put elements outside the wall
  if (bricks_changed) {
    State s;
    download(s);
    load(*m_, p, s);
  }
}

void CpuBackend::set_fixed(const std::vector<Index>& elements, const std::vector<Vec3>& targets,
                           const std::vector<std::uint8_t>& flags) {
  for (Index i : fixed_) flags_[i] = 0;
  std::vector<Index> old;
  old.swap(fixed_);
  fixed_ = elements;
  targets_ = targets;
  for (std::size_t k = 0; k < fixed_.size(); ++k) flags_[fixed_[k]] = static_cast<std::uint8_t>(kFixed | flags[k]);
  // Elements released from FIXED (grab released) must be relaxed again: mark their bricks.
  const auto& g = chainmail_.grid();
  for (Index i : old)
    if (!(flags_[i] & kFixed)) {
      chainmail_.hot()[g.brick_of_index(i)] = 1;
      chainmail_.touched()[g.brick_of_index(i)] = 1;
    }
}

PropagateStats CpuBackend::propagate() {
  const auto& g = chainmail_.grid();
  for (std::size_t k = 0; k < fixed_.size(); ++k) {
    const Index i = fixed_[k];
    if (!(pos_[i] == targets_[k])) {
      pos_[i] = targets_[k];
      chainmail_.touched()[g.brick_of_index(i)] = 1;
      chainmail_.hot()[g.brick_of_index(i)] = 1;
    }
  }
  PropagateStats st = chainmail_.propagate(*m_, pos_, pre_, time_, flags_, fixed_, p_.solver.max_propagation_sweeps);
  active_ = chainmail_.last_active_bricks();
  return st;
}

RelaxStats CpuBackend::relax(int sweeps) {
  RelaxStats st = chainmail_.relax(*m_, pos_, time_, flags_, sweeps, p_.solver.relax_threshold, p_.solver.relax_omega);
  active_ = std::max(active_, chainmail_.last_active_bricks());
  return st;
}

RestoreStats CpuBackend::restore_links() {
  auto& touched = chainmail_.touched();
  for (std::size_t b = 0; b < unchecked_.size(); ++b) unchecked_[b] |= touched[b];
  chainmail_.grid().dilate_to_list(unchecked_, check_list_);
  const RestoreStats st = restorer_.run(*m_, chainmail_.grid(), check_list_, pos_, flags_, chainmail_.wall(), touched);
  std::fill(unchecked_.begin(), unchecked_.end(), 0);
  // Bricks the restoration moved are touched (the velocity layer visits them); relaxation
  // looks at them again next frame.
  for (std::size_t b = 0; b < touched.size(); ++b)
    if (touched[b]) chainmail_.hot()[b] = 1;
  return st;
}

void CpuBackend::velocity_layer(SpeedStats* speeds) {
  LayerBuffers buf{&pos_, &pre_, &vel_, &flags_};
  layer_.apply(*m_, k_, chainmail_.grid(), buf, chainmail_.touched(), chainmail_.hot(), unchecked_, speeds);
  active_ = std::max(active_, layer_.last_bricks());
}

void CpuBackend::mark(int slot) {
  if (slot == 0) active_ = 0;
  marks_[slot] = std::chrono::steady_clock::now();
}

double CpuBackend::elapsed_ms(int a, int b) {
  return std::chrono::duration<double, std::milli>(marks_[b] - marks_[a]).count();
}

void CpuBackend::download(State& s) {
  s.pos = pos_;
  s.vel = vel_;
  s.time = time_;
  s.flags = flags_;
}

}  // namespace hpcm::cpu
