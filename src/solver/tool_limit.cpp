#include "solver/tool_limit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include "core/parallel.hpp"
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

/// The interval [lo, hi] that the link between e and its neighbour n allows for d_e - d_n on
/// coordinate axis b (displacements d = x - X0): link_interval at a neighbour displacement of 0,
/// in double. side = +1 when e lies on the + side of n along the link axis a.
void relative_interval(const LinkLimits& L, int a, int side, int b, double& lo, double& hi) {
  const LinkBox<double> box{L.min_stretch, L.max_stretch, L.shear};
  link_interval(0.0, box, b == a, side, lo, hi);
}

/// Slack of the link in the direction "n's displacement may exceed e's by at most this":
/// d_n <= d_e + slack (from d_e >= d_n + lo).
double slack_to(const LinkLimits& L, int a, int side, int b) {
  double lo, hi;
  relative_interval(L, a, side, b, lo, hi);
  return -lo;
}

/// Slack in the other direction: d_e <= d_n + slack_from (= hi).
double slack_from(const LinkLimits& L, int a, int side, int b) {
  double lo, hi;
  relative_interval(L, a, side, b, lo, hi);
  return hi;
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

/// Distances of one search, in pages of 4,096 elements allocated when first written: the
/// memory follows the region the search explores, not the lattice.
class SparseDistances {
 public:
  explicit SparseDistances(Index n) : pages_(static_cast<std::size_t>((n + kPage - 1) / kPage)) {}
  double get(Index i) const {
    const auto& page = pages_[static_cast<std::size_t>(i >> kShift)];
    return page ? page[static_cast<std::size_t>(i & (kPage - 1))] : kInfD;
  }
  void set(Index i, double d) {
    auto& page = pages_[static_cast<std::size_t>(i >> kShift)];
    if (!page) {
      page = std::make_unique<double[]>(static_cast<std::size_t>(kPage));
      std::fill_n(page.get(), kPage, kInfD);
    }
    page[static_cast<std::size_t>(i & (kPage - 1))] = d;
  }
  void release() {
    for (auto& page : pages_) page.reset();
  }

 private:
  static constexpr int kShift = 12;
  static constexpr Index kPage = Index{1} << kShift;
  std::vector<std::unique_ptr<double[]>> pages_;
};

/// The largest offset allowed on one side of an axis whose search found `bound` (the smallest
/// start + slack path to an anchor or to the wall), rounded inwards so that a clamped offset is
/// met after float rounding of the targets. Offset 0 stays allowed where the search allows it:
/// the grabbed elements then stay where they are, with no rounding to allow for (a grab at rest
/// on the wall with margin 0). Nondecreasing in bound. The restoration rounds box limits to
/// nearest on displacements (solver/restore.hpp), so a chain stretched to its exact slack keeps
/// its links within half a float step of their displacements: no slack is reserved for it.
float side_limit(double bound) {
  const float below = std::nextafter(static_cast<float>(std::min(bound, 1e30)), -INFINITY);
  return bound >= 0.0 ? std::max(below, 0.0f) : below;
}

void check_inputs(const Model& m, const std::vector<Index>& grabbed, const std::vector<Vec3>& origin,
                  const std::vector<std::uint8_t>& anchored) {
  if (grabbed.size() != origin.size()) throw Error("tool_limit: grabbed and origin sizes differ");
  if (static_cast<Index>(anchored.size()) != m.size()) throw Error("tool_limit: anchor flags do not match the model");
}

}  // namespace

/// One of the six searches (an axis, one side), resumable: it stops at a distance cap with
/// every element closer than the cap settled, and goes on from there when asked for more.
struct ToolLimitSearch::Direction {
  Direction(Index n, int axis_, bool upper_) : axis(axis_), upper(upper_), dist(n) {}
  int axis;
  bool upper;  ///< upper bound of the offset: searched along the reversed edges
  RadixHeap heap;
  SparseDistances dist;
  double best = kInfD;  ///< smallest start + slack to an anchor or the wall found so far
  double settled = -kInfD;  ///< every element closer than this has been expanded
  bool done = false;  ///< best is the bound
  /// A lower bound of the search's bound: exact when done.
  double known() const { return done ? best : std::min(best, settled); }
  float allowed() const { return side_limit(known()); }
  /// How far this side must allow the offset to go (positive toward the side).
  double wanted(Vec3 offset) const { return upper ? offset[axis] : -offset[axis]; }
  /// Whether the clamp of `offset` can be told on this side from what is searched so far.
  bool settled_for(Vec3 offset) const { return done || static_cast<double>(allowed()) >= wanted(offset); }
};


ToolLimitSearch::ToolLimitSearch(const Model& m, std::vector<Index> grabbed, const std::vector<Vec3>& origin,
                                 std::vector<std::uint8_t> anchored, float margin)
    : m_(m), grabbed_(std::move(grabbed)), anchored_(std::move(anchored)), margin_(margin) {
  check_inputs(m, grabbed_, origin, anchored_);
  if (grabbed_.empty()) throw Error("tool_limit: no grabbed elements");
  is_grabbed_.assign(static_cast<std::size_t>(m.size()), 0);
  for (Index g : grabbed_) is_grabbed_[static_cast<std::size_t>(g)] = 1;
  dirs_.reserve(6);
  for (int task = 0; task < 6; ++task) {
    Direction& d = dirs_.emplace_back(m.size(), task / 2, task % 2 == 0);
    const int b = d.axis;
    // Upper bound: offset <= slack(anchor or wall -> g) - d_g, searched backwards from g.
    // Lower bound: offset >= -(d_g + slack(g -> anchor or wall)), searched forwards from g.
    for (std::size_t k = 0; k < grabbed_.size(); ++k) {
      const Index g = grabbed_[k];
      const double d_g = static_cast<double>(origin[k][b]);  // displacement at grab time
      const double start = d.upper ? -d_g : d_g;
      if (start < d.dist.get(g)) {
        d.dist.set(g, start);
        d.heap.push(start, g);
      }
    }
  }
}

ToolLimitSearch::~ToolLimitSearch() = default;

/// Dijkstra from the grabbed elements until every element closer than `cap` is settled or the
/// bound is found (forward: paths follow d_next <= d_cur + slack, the lower bound of the tool;
/// upper: the reversed edges).
void ToolLimitSearch::extend(Direction& s, double cap) const {
  const Model& m = m_;
  const std::vector<std::uint8_t>& anchored = anchored_;
  const std::vector<std::uint8_t>& grabbed = is_grabbed_;
  const Wall walls = make_wall(m.dims, margin_);
  const int b = s.axis;
  const bool forward = !s.upper;
  while (!s.heap.empty()) {
    // Named copies, not a structured binding: the lambda below captures d (clang 14 rejects that).
    const RadixHeap::Entry top = s.heap.pop();
    const double d = top.first;
    const Index e = top.second;
    if (d > s.dist.get(e)) continue;
    if (d >= s.best) break;
    if (d >= cap) {  // everything closer is settled; go on from here next time
      s.heap.push(d, e);
      s.settled = d;
      return;
    }
    const Int3 c = m.coords(e);
    // The wall: forward (lower bound) d_e >= wall_lo; reversed d_e <= wall_hi: the same floats
    // the backends clamp to (solver::make_wall, wall_lo_of / wall_hi_of), not the exact value, so
    // a grab held at the wall is inside it on every backend whatever the margin.
    const double wall = forward ? -static_cast<double>(wall_lo_of(walls, b, c[b])) : static_cast<double>(wall_hi_of(walls, b, c[b]));
    if (anchored[static_cast<std::size_t>(e)]) {
      s.best = std::min(s.best, d);
      continue;  // an anchor ends the chain
    }
    s.best = std::min(s.best, d + wall);
    for_each_face_neighbour(m, c.x, c.y, c.z, e, [&](Index n, int a, int side, const LinkLimits& L) {
      if (grabbed[static_cast<std::size_t>(n)]) return;
      const double nd = d + (forward ? slack_to(L, a, side, b) : slack_from(L, a, side, b));
      if (nd < s.dist.get(n)) {
        s.dist.set(n, nd);
        s.heap.push(nd, n);
      }
    });
  }
  s.done = true;  // only the bound is needed from now on
  s.heap = RadixHeap();
  s.dist.release();
}

void ToolLimitSearch::run(const std::vector<std::pair<int, double>>& work) {
  // Independent searches on threads of their own (core/parallel.hpp: tool moves come every
  // frame, so no OpenMP): the result does not depend on how many.
  const int n = static_cast<int>(work.size());
  run_parts(n, pass_parts(n), [&](int, int lo, int hi) {
    for (int j = lo; j < hi; ++j) {
      const auto& [k, cap] = work[static_cast<std::size_t>(j)];
      extend(dirs_[static_cast<std::size_t>(k)], cap);
    }
  });
}

void ToolLimitSearch::settle_for(Vec3 offset) {
  // Each side must show that its limit admits the offset (or find its exact bound). A search
  // that has to go on is given room: 1.25 times the distance needed and a quarter cell more,
  // so a steady pull extends it every few frames, not every frame.
  std::vector<std::pair<int, double>> work;  // (direction, cap)
  for (int k = 0; k < 6; ++k) {
    const Direction& d = dirs_[static_cast<std::size_t>(k)];
    if (!d.settled_for(offset)) work.emplace_back(k, std::max(d.wanted(offset), 0.0) * 1.25 + 0.25);
  }
  while (!work.empty()) {
    run(work);
    // A cap reached still short of the offset (float rounding at the edge): go twice as far.
    std::vector<std::pair<int, double>> again;
    for (const auto& [k, cap] : work)
      if (!dirs_[static_cast<std::size_t>(k)].settled_for(offset)) again.emplace_back(k, 2.0 * cap + 1.0);
    work = std::move(again);
  }
}

Vec3 ToolLimitSearch::clamp(Vec3 offset) {
  // min(max(offset, lo), hi), one side at a time: each side is settled for the value it is
  // compared with. Where a search is not finished, its limit lies beyond that value, which it
  // then leaves alone. The lower side may raise the offset (a grab held where the tissue
  // cannot stay), so the upper side is settled for the raised value, not the requested one.
  settle_for(offset);
  Vec3 raised = offset;
  for (int b = 0; b < 3; ++b) raised[b] = std::max(offset[b], -dirs_[static_cast<std::size_t>(2 * b + 1)].allowed());
  settle_for(raised);
  Vec3 out = raised;
  for (int b = 0; b < 3; ++b) out[b] = std::min(raised[b], dirs_[static_cast<std::size_t>(2 * b)].allowed());
  return out;
}

ToolLimit ToolLimitSearch::limit() {
  std::vector<std::pair<int, double>> work;
  for (int k = 0; k < 6; ++k)
    if (!dirs_[static_cast<std::size_t>(k)].done) work.emplace_back(k, kInfD);
  run(work);
  ToolLimit lim;
  for (int b = 0; b < 3; ++b) {
    lim.hi[b] = dirs_[static_cast<std::size_t>(2 * b)].allowed();
    lim.lo[b] = -dirs_[static_cast<std::size_t>(2 * b + 1)].allowed();
  }
  return lim;
}

ToolLimit tool_limit(const Model& m, const std::vector<Index>& grabbed, const std::vector<Vec3>& origin,
                     const std::vector<std::uint8_t>& anchored, float margin) {
  check_inputs(m, grabbed, origin, anchored);
  if (grabbed.empty()) return {};
  ToolLimitSearch search(m, grabbed, origin, anchored, margin);
  return search.limit();
}

}  // namespace hpcm::solver
