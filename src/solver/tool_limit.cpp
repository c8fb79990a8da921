#include "solver/tool_limit.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <utility>

#include "solver/neighbours.hpp"
#include "solver/restore.hpp"

namespace hpcm::solver {

Vec3 ToolLimit::clamp(Vec3 o) const {
  for (int b = 0; b < 3; ++b) o[b] = std::min(std::max(o[b], lo[b]), hi[b]);
  return o;
}

bool ToolLimit::contains(Vec3 o) const {
  for (int b = 0; b < 3; ++b)
    if (!(o[b] >= lo[b] && o[b] <= hi[b])) return false;
  return true;
}

namespace {

constexpr double kInfD = std::numeric_limits<double>::infinity();

/// Slack of the link between e and its neighbour n on coordinate axis b, in the direction
/// "n's displacement may exceed e's by at most this": d_n <= d_e + slack (displacements d = x - X0).
/// side = +1 when e lies on the + side of n along the link axis a.
double slack_to(const LinkLimits& L, int a, int side, int b) {
  if (a != b) return L.shear;
  // n below e along the axis (side +1): n moving up compresses the link, down to min_d.
  return side > 0 ? 1.0 - static_cast<double>(L.min_d) : static_cast<double>(L.max_d) - 1.0;
}

/// Slack in the other direction: d_e <= d_n + slack_from.
double slack_from(const LinkLimits& L, int a, int side, int b) {
  if (a != b) return L.shear;
  return side > 0 ? static_cast<double>(L.max_d) - 1.0 : 1.0 - static_cast<double>(L.min_d);
}

/// The rounding the restoration may take from each link on an axis of n elements: one float step
/// of the axis's largest coordinate (n + margin, beyond the wall at n - 1 + margin) where it rounds
/// box limits inward (solver/restore.hpp, rounds_inward), none where it rounds to nearest.
double inward_rounding_on_axis(int n, float margin) {
  if (!rounds_inward(static_cast<float>(n - 1) + margin)) return 0.0;
  return static_cast<double>(float_step_above(static_cast<float>(n) + margin));
}

/// Dijkstra's priority queue as a radix heap: the keys popped never decrease (the slacks are
/// >= 0), so an entry is filed by the highest bit in which its key differs from the last key
/// popped, and only the lowest non-empty bucket is ever sorted out again. Keys are the doubles'
/// bit patterns mapped to unsigned integers in the same order. Much cheaper per entry than a
/// binary heap of a million entries; the distances found are the same (ties may pop in another
/// order, which changes no minimum).
class RadixHeap {
 public:
  using Entry = std::pair<double, Index>;
  bool empty() const { return size_ == 0; }
  void push(double d, Index e) {
    buckets_[static_cast<std::size_t>(bucket(ordered(d)))].push_back({d, e});
    ++size_;
  }
  /// An entry of the smallest key (the queue must not be empty).
  Entry pop() {
    if (buckets_[0].empty()) {
      std::size_t b = 1;
      while (buckets_[b].empty()) ++b;
      std::uint64_t least = ~std::uint64_t{0};
      for (const Entry& x : buckets_[b]) least = std::min(least, ordered(x.first));
      last_ = least;
      for (const Entry& x : buckets_[b]) buckets_[static_cast<std::size_t>(bucket(ordered(x.first)))].push_back(x);
      buckets_[b].clear();
    }
    const Entry top = buckets_[0].back();
    buckets_[0].pop_back();
    --size_;
    return top;
  }
  void clear() {
    for (auto& b : buckets_) b.clear();
    last_ = 0;
    size_ = 0;
  }

 private:
  /// Order-preserving map of a double (not NaN) to an unsigned integer.
  static std::uint64_t ordered(double d) {
    std::uint64_t u;
    std::memcpy(&u, &d, sizeof u);
    return (u >> 63) ? ~u : u | (std::uint64_t{1} << 63);
  }
  int bucket(std::uint64_t key) const { return key == last_ ? 0 : 64 - __builtin_clzll(key ^ last_); }
  std::array<std::vector<Entry>, 65> buckets_;
  std::uint64_t last_ = 0;
  std::size_t size_ = 0;
};

struct Search {
  const Model& m;
  const std::vector<std::uint8_t>& anchored;
  std::vector<std::uint8_t> grabbed;  // per element
  std::vector<double> dist;
  std::vector<Index> seen;
  float margin;
  RadixHeap heap;

  /// Slack left to a link after the restoration's rounding: on axes of 128 cells and more it
  /// rounds every box limit toward the inside, by less than a float step of the coordinate
  /// (solver/restore.hpp, link_bound), so a chain stretched to its exact slack could not be met
  /// in floats. Two float steps of the axis's largest coordinate per link keep every chain the
  /// tool may stretch feasible after rounding (3e-5 cells per link up to 256; never below zero,
  /// which the search's radix heap needs).
  static double usable(double slack, double float_step) { return std::max(0.0, slack - 2.0 * float_step); }

  /// Smallest (start_g + shortest slack path to an anchor or to the wall) over the grabbed
  /// elements on axis b. forward: paths follow d_next <= d_cur + slack (the lower bound of
  /// the tool); otherwise the reversed edges (the upper bound).
  double run(const std::vector<Index>& starts, const std::vector<double>& start_dist, int b, bool forward) {
    for (Index i : seen) dist[static_cast<std::size_t>(i)] = kInfD;
    seen.clear();
    heap.clear();
    for (std::size_t k = 0; k < starts.size(); ++k) {
      const Index g = starts[k];
      if (start_dist[k] < dist[static_cast<std::size_t>(g)]) {
        if (dist[static_cast<std::size_t>(g)] == kInfD) seen.push_back(g);
        dist[static_cast<std::size_t>(g)] = start_dist[k];
        heap.push(start_dist[k], g);
      }
    }
    const int n_b = b == 0 ? m.dims.x : (b == 1 ? m.dims.y : m.dims.z);
    const double step = inward_rounding_on_axis(n_b, margin);
    double best = kInfD;
    while (!heap.empty()) {
      // Named copies, not a structured binding: the lambda below captures d (clang 14 rejects that).
      const RadixHeap::Entry top = heap.pop();
      const double d = top.first;
      const Index e = top.second;
      if (d > dist[static_cast<std::size_t>(e)]) continue;
      if (d >= best) break;
      const Int3 c = m.coords(e);
      const double rest = c[b];
      // The wall: forward (lower bound) d_e >= -(rest + margin); reversed d_e <= N - 1 + margin - rest.
      const double wall = forward ? rest + margin : (n_b - 1 + margin) - rest;
      if (anchored[static_cast<std::size_t>(e)]) {
        best = std::min(best, d);
        continue;  // an anchor ends the chain
      }
      best = std::min(best, d + wall);
      for_each_face_neighbour(m, c.x, c.y, c.z, e, [&](Index n, int a, int side, const LinkLimits& L) {
        if (grabbed[static_cast<std::size_t>(n)]) return;
        const double nd = d + usable(forward ? slack_to(L, a, side, b) : slack_from(L, a, side, b), step);
        if (nd < dist[static_cast<std::size_t>(n)]) {
          if (dist[static_cast<std::size_t>(n)] == kInfD) seen.push_back(n);
          dist[static_cast<std::size_t>(n)] = nd;
          heap.push(nd, n);
        }
      });
    }
    return best;
  }
};

}  // namespace

ToolLimit tool_limit(const Model& m, const std::vector<Index>& grabbed, const std::vector<Vec3>& origin,
                     const std::vector<std::uint8_t>& anchored, float margin) {
  if (grabbed.size() != origin.size()) throw Error("tool_limit: grabbed and origin sizes differ");
  if (static_cast<Index>(anchored.size()) != m.size()) throw Error("tool_limit: anchor flags do not match the model");
  ToolLimit lim;
  if (grabbed.empty()) return lim;
  // Six independent searches (three axes, two directions): they run on the available threads,
  // each with its own distance array, so the result does not depend on the thread count.
  double bound[3][2];  // [axis][0: upper bound of the offset, 1: lower bound, negated]
  const int threads = std::min(6, omp_get_max_threads());  // no search state for idle threads
#pragma omp parallel num_threads(threads)
  {
    Search s{m, anchored, std::vector<std::uint8_t>(static_cast<std::size_t>(m.size()), 0),
             std::vector<double>(static_cast<std::size_t>(m.size()), kInfD), {}, margin, {}};
    for (Index g : grabbed) s.grabbed[static_cast<std::size_t>(g)] = 1;
#pragma omp for schedule(dynamic, 1)
    for (int task = 0; task < 6; ++task) {
      const int b = task / 2;
      const bool upper = task % 2 == 0;
      std::vector<double> start(grabbed.size());
      // Upper bound: offset <= slack(anchor or wall -> g) - d_g, searched backwards from g.
      // Lower bound: offset >= -(d_g + slack(g -> anchor or wall)), searched forwards from g.
      for (std::size_t k = 0; k < grabbed.size(); ++k) {
        const double d_g = static_cast<double>(origin[k][b]) - m.coords(grabbed[k])[b];
        start[k] = upper ? -d_g : d_g;
      }
      bound[b][upper ? 0 : 1] = s.run(grabbed, start, b, !upper);
    }
  }
  const int n[3] = {m.dims.x, m.dims.y, m.dims.z};
  for (int b = 0; b < 3; ++b) {
    // A grabbed element's position (origin + offset) is rounded to the coordinate's float grid:
    // on an axis that rounds inward, one more float step keeps it feasible (a grab at the wall
    // has no link to spare). Then rounded inwards so that a clamped offset is met after float
    // rounding of the targets.
    // Offset 0 stays allowed where the search allows it: the grabbed elements then stay where
    // they are, with no rounding to allow for (a grab at rest on the wall with margin 0).
    const double step = inward_rounding_on_axis(n[b], margin);
    const auto below = [](double v) { return std::nextafter(static_cast<float>(std::min(v, 1e30)), -INFINITY); };
    lim.hi[b] = std::max(below(bound[b][0] - step), std::min(below(bound[b][0]), 0.0f));
    lim.lo[b] = -std::max(below(bound[b][1] - step), std::min(below(bound[b][1]), 0.0f));
  }
  return lim;
}

}  // namespace hpcm::solver
