// Sequential Dijkstra-order reference of the timestamped HP-ChainMail wave (see dijkstra.hpp).
#include "solver/reference/dijkstra.hpp"

#include <algorithm>
#include <cmath>

#include "hpcm/state.hpp"
#include "solver/rules.hpp"  // kGapTolerance only: the rule itself is re-implemented here

namespace hpcm::reference {

int neighbours(const Model& m, Index e, Neighbour out[6]) {
  const Int3 c = m.coords(e);
  const int cc[3] = {c.x, c.y, c.z};
  const int d[3] = {m.dims.x, m.dims.y, m.dims.z};
  const Index stride[3] = {1, static_cast<Index>(d[0]), static_cast<Index>(d[0]) * d[1]};
  int k = 0;
  for (int a = 0; a < 3; ++a) {
    if (cc[a] > 0) {  // n = e - unit_a: e on the + side, link stored at n
      const Index n = e - stride[a];
      out[k++] = {n, a, true, m.link(a, n)};
    }
    if (cc[a] < d[a] - 1) {  // n = e + unit_a: e on the - side, link stored at e
      out[k++] = {e + stride[a], a, false, m.link(a, e)};
    }
  }
  return k;
}

namespace {
inline bool key_less(float ta, Index a, float tb, Index b) { return ta < tb || (ta == tb && a < b); }
}  // namespace

Vec3 clamp_against(const Vec3& p0, const Neighbour* nb, int count, const bool* use, const std::vector<Vec3>& pos,
                   const std::vector<float>& time, const solver::Wall& wall) {
  int earliest = -1;
  for (int k = 0; k < count; ++k) {
    if (!use[k]) continue;
    if (earliest < 0 || key_less(time[static_cast<std::size_t>(nb[k].n)], nb[k].n,
                                 time[static_cast<std::size_t>(nb[earliest].n)], nb[earliest].n))
      earliest = k;
  }
  if (earliest < 0) return p0;
  Vec3 out = p0;
  for (int b = 0; b < 3; ++b) {
    float lo = wall.lo[b], hi = wall.hi[b];  // the boundary box is one more box
    for (int k = 0; k < count; ++k) {
      if (!use[k]) continue;
      const Interval iv = link_interval(nb[k].L, nb[k].axis, nb[k].e_plus, pos[static_cast<std::size_t>(nb[k].n)], b);
      lo = std::max(lo, iv.lo);
      hi = std::min(hi, iv.hi);
    }
    if (lo > hi) {
      // Boxes that only rounding separates (tight links meeting in a point): take the
      // touching point, as the parallel solver does (src/solver/rules.hpp, kGapTolerance).
      if (lo - hi <= solver::kGapTolerance * (1.0f + std::fabs(lo))) {
        out[b] = 0.5f * (lo + hi);
        continue;
      }
      // Truly empty intersection on this axis: the earliest neighbour's box wins, inside the wall.
      const Neighbour& f = nb[earliest];
      const Interval iv = link_interval(f.L, f.axis, f.e_plus, pos[static_cast<std::size_t>(f.n)], b);
      out[b] = std::min(std::max(std::min(std::max(p0[b], iv.lo), iv.hi), wall.lo[b]), wall.hi[b]);
      continue;
    }
    out[b] = std::min(std::max(p0[b], lo), hi);
  }
  return out;
}

DijkstraPropagator::DijkstraPropagator(const Model& m, const solver::Wall& wall)
    : m_(m), wall_(wall), time_(static_cast<std::size_t>(m.size()), kInf), final_(static_cast<std::size_t>(m.size()), 0) {}

Index DijkstraPropagator::run(std::vector<Vec3>& pos, const std::vector<Index>& fixed,
                              const std::vector<Vec3>& targets) {
  if (pos.size() != static_cast<std::size_t>(m_.size()))
    throw Error("reference: position array has " + std::to_string(pos.size()) + " entries for " +
                std::to_string(m_.size()) + " elements");
  if (fixed.size() != targets.size()) throw Error("reference: fixed and targets differ in size");
  for (Index i : touched_) {
    time_[static_cast<std::size_t>(i)] = kInf;
    final_[static_cast<std::size_t>(i)] = 0;
  }
  touched_.clear();
  heap_.clear();
  pops_ = 0;
  const Later later;

  for (std::size_t k = 0; k < fixed.size(); ++k) {
    const Index i = fixed[k];
    if (i < 0 || i >= m_.size()) throw Error("reference: fixed element " + std::to_string(i) + " out of range");
    pos[static_cast<std::size_t>(i)] = targets[k];
    time_[static_cast<std::size_t>(i)] = 0.0f;
    final_[static_cast<std::size_t>(i)] = 1;
    touched_.push_back(i);
  }
  Neighbour nb[6];
  for (Index i : fixed) {
    const int cnt = neighbours(m_, i, nb);
    for (int k = 0; k < cnt; ++k)
      if (!final_[static_cast<std::size_t>(nb[k].n)]) {
        heap_.push_back({0.0f + nb[k].L.w, nb[k].n});
        std::push_heap(heap_.begin(), heap_.end(), later);
      }
  }

  Index reached = 0;
  bool use[6];
  while (!heap_.empty()) {
    std::pop_heap(heap_.begin(), heap_.end(), later);
    const Entry top = heap_.back();
    heap_.pop_back();
    ++pops_;
    const std::size_t e = static_cast<std::size_t>(top.e);
    if (final_[e]) continue;
    const int cnt = neighbours(m_, top.e, nb);
    for (int k = 0; k < cnt; ++k) {
      const std::size_t n = static_cast<std::size_t>(nb[k].n);
      use[k] = final_[n] && key_less(time_[n], nb[k].n, top.c, top.e);
    }
    const Vec3 p0 = pos[e];  // a non-final element still sits at its wave-start position
    const Int3 ce = m_.coords(e);
    const Vec3 q = clamp_against(p0, nb, cnt, use, pos, time_, solver::element_wall(wall_, ce.x, ce.y, ce.z));
    if (q == p0) continue;  // not moved: it may be pushed again by a later neighbour
    pos[e] = q;
    time_[e] = top.c;
    final_[e] = 1;
    touched_.push_back(top.e);
    ++reached;
    for (int k = 0; k < cnt; ++k)
      if (!final_[static_cast<std::size_t>(nb[k].n)]) {
        heap_.push_back({top.c + nb[k].L.w, nb[k].n});
        std::push_heap(heap_.begin(), heap_.end(), later);
      }
  }
  return reached;
}

ReferenceWave dijkstra_propagate(const Model& m, const std::vector<Vec3>& p0, const std::vector<std::uint8_t>& flags,
                                 const std::vector<Vec3>& targets, const solver::Wall& wall) {
  const std::size_t n = static_cast<std::size_t>(m.size());
  if (p0.size() != n || flags.size() != n || targets.size() != n)
    throw Error("dijkstra_propagate: p0, flags and targets need one entry per element (" + std::to_string(n) + ")");
  std::vector<Index> fixed;
  std::vector<Vec3> tg;
  for (std::size_t i = 0; i < n; ++i)
    if (flags[i] & kFixed) {
      fixed.push_back(static_cast<Index>(i));
      tg.push_back(targets[i]);
    }
  DijkstraPropagator prop(m, wall);
  ReferenceWave w;
  w.pos = p0;
  w.reached = prop.run(w.pos, fixed, tg);
  w.time = prop.time();
  return w;
}

RuleResult evaluate_rule(const Model& m, Index e, const std::vector<Vec3>& p0, const std::vector<Vec3>& pos,
                         const std::vector<float>& time, const solver::Wall& wall) {
  Neighbour nb[6];
  const int cnt = neighbours(m, e, nb);
  float cand[6];
  int nc = 0;
  for (int k = 0; k < cnt; ++k) {
    const float tn = time[static_cast<std::size_t>(nb[k].n)];
    if (std::isfinite(tn)) cand[nc++] = tn + nb[k].L.w;
  }
  for (int j = 1; j < nc; ++j)  // insertion sort of at most 6 candidates
    for (int k = j; k > 0 && cand[k] < cand[k - 1]; --k) std::swap(cand[k], cand[k - 1]);
  int distinct = 0;
  for (int j = 0; j < nc; ++j)
    if (distinct == 0 || cand[j] != cand[distinct - 1]) cand[distinct++] = cand[j];
  nc = distinct;
  const Vec3 q0 = p0[static_cast<std::size_t>(e)];
  bool use[6];
  for (int j = 0; j < nc; ++j) {
    for (int k = 0; k < cnt; ++k) use[k] = key_less(time[static_cast<std::size_t>(nb[k].n)], nb[k].n, cand[j], e);
    const Int3 ce = m.coords(e);
    const Vec3 q = clamp_against(q0, nb, cnt, use, pos, time, solver::element_wall(wall, ce.x, ce.y, ce.z));
    if (!(q == q0)) return {cand[j], q};
  }
  return {kInf, q0};
}

float link_violation(const Model& m, Index i, int a, const std::vector<Vec3>& pos) {
  const Index stride = a == 0 ? 1 : a == 1 ? m.dims.x : static_cast<Index>(m.dims.x) * m.dims.y;
  const LinkLimits& L = m.link(a, i);
  const Vec3 d = pos[static_cast<std::size_t>(i + stride)] - pos[static_cast<std::size_t>(i)];
  float v = std::max({0.0f, L.min_stretch - d[a], d[a] - L.max_stretch});
  for (int b = 0; b < 3; ++b)
    if (b != a) v = std::max(v, std::fabs(d[b]) - L.shear);
  return v;
}

float upstream_link_violation(const Model& m, const std::vector<Vec3>& pos, const std::vector<float>& time) {
  float worst = 0.0f;
  const int d[3] = {m.dims.x, m.dims.y, m.dims.z};
  const Index stride[3] = {1, static_cast<Index>(d[0]), static_cast<Index>(d[0]) * d[1]};
  for (Index i = 0; i < m.size(); ++i) {
    const Int3 c = m.coords(i);
    const int cc[3] = {c.x, c.y, c.z};
    for (int a = 0; a < 3; ++a) {
      if (cc[a] >= d[a] - 1) continue;
      const float ti = time[static_cast<std::size_t>(i)], tj = time[static_cast<std::size_t>(i + stride[a])];
      // Links between two FIXED (t = 0) or two unreached (t = +inf) elements have no
      // upstream side; every other link has one by the key (t, index).
      if (ti == tj && (ti == 0.0f || std::isinf(ti))) continue;
      worst = std::max(worst, link_violation(m, i, a, pos));
    }
  }
  return worst;
}

}  // namespace hpcm::reference
