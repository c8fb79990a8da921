#include "hpcm/state.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>

#include "core/link_box.hpp"
#include "core/parallel.hpp"

namespace hpcm {

State State::rest(const Model& m) {
  State s;
  const Index n = m.size();
  s.disp.assign(static_cast<std::size_t>(n), Vec3{});
  s.vel.assign(static_cast<std::size_t>(n), Vec3{});
  s.time.assign(static_cast<std::size_t>(n), std::numeric_limits<float>::infinity());
  s.flags.assign(static_cast<std::size_t>(n), 0);
  return s;
}

std::vector<Point3> positions(const Model& m, const std::vector<Vec3>& disp) {
  std::vector<Point3> out(disp.size());
  for (Index i = 0; i < static_cast<Index>(disp.size()); ++i) out[static_cast<std::size_t>(i)] = position_of(m, i, disp[static_cast<std::size_t>(i)]);
  return out;
}

namespace {

/// Largest link violation over the links whose lower element lies in [x0, x1) × [y0, y1) ×
/// [z0, z1) (each element owns its +x, +y and +z link).
float link_max_in(const Model& m, const std::vector<Vec3>& disp, Int3 lo, Int3 hi) {
  const int d[3] = {m.dims.x, m.dims.y, m.dims.z};
  const Index stride[3] = {1, d[0], static_cast<Index>(d[0]) * d[1]};
  float w = 0.0f;
  for (int z = lo.z; z < hi.z; ++z)
    for (int y = lo.y; y < hi.y; ++y)
      for (int x = lo.x; x < hi.x; ++x) {
        const Index i = m.index(x, y, z);
        const int c[3] = {x, y, z};
        for (int a = 0; a < 3; ++a)
          if (c[a] + 1 < d[a]) w = std::max(w, link_violation(disp[i], disp[i + stride[a]], m.link(a, i), a));
      }
  return w;
}

struct CellRange {
  double min_det = 1.0;
  Index folded = 0;
};

/// The cells whose lower corner lies in [lo, hi) (clipped to the cells there are).
CellRange cells_in(const Model& m, const std::vector<Vec3>& disp, Int3 lo, Int3 hi) {
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
  const Index sy = nx, sz = static_cast<Index>(nx) * ny;
  CellRange r;
  for (int z = lo.z; z < std::min(hi.z, nz - 1); ++z)
    for (int y = lo.y; y < std::min(hi.y, ny - 1); ++y)
      for (int x = lo.x; x < std::min(hi.x, nx - 1); ++x) {
        const Index base = m.index(x, y, z);
        // The cell's 12 edges, oriented along +x, +y, +z: exJK joins (0, J, K) to (1, J, K), eyIK
        // and ezIJ likewise; corner (i, j, k) spans ex[j][k], ey[i][k] and ez[i][j]. Named
        // values, not arrays: nothing of this frame lives in memory (ASan would check each use).
        const Vec3* c = &disp[static_cast<std::size_t>(base)];
        const Vec3 ex00 = c[1] - c[0], ex10 = c[1 + sy] - c[sy], ex01 = c[1 + sz] - c[sz], ex11 = c[1 + sy + sz] - c[sy + sz];
        const Vec3 ey00 = c[sy] - c[0], ey10 = c[1 + sy] - c[1], ey01 = c[sy + sz] - c[sz], ey11 = c[1 + sy + sz] - c[1 + sz];
        const Vec3 ez00 = c[sz] - c[0], ez10 = c[1 + sz] - c[1], ez01 = c[sy + sz] - c[sy], ez11 = c[1 + sy + sz] - c[1 + sy];
        double cell_min = 1e30;
        cell_min = std::min(cell_min, corner_determinant(ex00, ey00, ez00));  // (0, 0, 0)
        cell_min = std::min(cell_min, corner_determinant(ex00, ey10, ez10));  // (1, 0, 0)
        cell_min = std::min(cell_min, corner_determinant(ex10, ey00, ez01));  // (0, 1, 0)
        cell_min = std::min(cell_min, corner_determinant(ex10, ey10, ez11));  // (1, 1, 0)
        cell_min = std::min(cell_min, corner_determinant(ex01, ey01, ez00));  // (0, 0, 1)
        cell_min = std::min(cell_min, corner_determinant(ex01, ey11, ez10));  // (1, 0, 1)
        cell_min = std::min(cell_min, corner_determinant(ex11, ey01, ez01));  // (0, 1, 1)
        cell_min = std::min(cell_min, corner_determinant(ex11, ey11, ez11));  // (1, 1, 1)
        r.min_det = std::min(r.min_det, cell_min);
        if (cell_min <= 0.0) ++r.folded;
      }
  return r;
}

CellJacobianStats cell_stats(const Model& m, double min_det, Index folded) {
  CellJacobianStats st;
  st.min_det = static_cast<float>(min_det);
  st.folded = folded;
  st.cells = static_cast<Index>(m.dims.x - 1) * (m.dims.y - 1) * (m.dims.z - 1);
  return st;
}

}  // namespace

float max_link_violation(const Model& m, const std::vector<Vec3>& disp) {
  const int nz = m.dims.z;
  const int parts = pass_parts(nz);
  std::vector<float> worst(static_cast<std::size_t>(parts), 0.0f);
  run_parts(nz, parts, [&](int part, int z0, int z1) {
    worst[static_cast<std::size_t>(part)] = link_max_in(m, disp, {0, 0, z0}, {m.dims.x, m.dims.y, z1});
  });
  return *std::max_element(worst.begin(), worst.end());
}

CellJacobianStats cell_jacobian(const Model& m, const std::vector<Vec3>& disp) {
  const int nx = m.dims.x, ny = m.dims.y, nz = m.dims.z;
  if (nx < 2 || ny < 2 || nz < 2) return {};
  const int parts = pass_parts(nz - 1);
  std::vector<CellRange> part(static_cast<std::size_t>(parts));
  run_parts(nz - 1, parts, [&](int t, int z0, int z1) { part[static_cast<std::size_t>(t)] = cells_in(m, disp, {0, 0, z0}, {nx, ny, z1}); });
  double min_det = 1.0;
  Index folded = 0;
  for (const CellRange& r : part) {
    min_det = std::min(min_det, r.min_det);
    folded += r.folded;
  }
  return cell_stats(m, min_det, folded);
}

// --- IncrementalMetrics ---

void IncrementalMetrics::reset() {
  seen_.clear();
  link_max_.clear();
  cell_min_.clear();
  cell_folded_.clear();
}

Int3 IncrementalMetrics::block_lo(int b) const {
  const int bx = b % blocks_.x, by = (b / blocks_.x) % blocks_.y, bz = b / (blocks_.x * blocks_.y);
  return {bx * kBlock, by * kBlock, bz * kBlock};
}

std::vector<int> IncrementalMetrics::dirty_blocks(const Model& m, const std::vector<Vec3>& disp) {
  const Int3 d = m.dims;
  const Int3 nb{(d.x + kBlock - 1) / kBlock, (d.y + kBlock - 1) / kBlock, (d.z + kBlock - 1) / kBlock};
  const int count = nb.x * nb.y * nb.z;
  std::vector<int> dirty;
  if (seen_.size() != disp.size() || !(nb == blocks_) || static_cast<Index>(disp.size()) != m.size()) {
    // First call, or another lattice: every block.
    blocks_ = nb;
    seen_ = disp;
    dirty.resize(static_cast<std::size_t>(count));
    for (int b = 0; b < count; ++b) dirty[static_cast<std::size_t>(b)] = b;
    return dirty;
  }
  // Blocks holding an element whose displacement differs (bitwise) from the last call; the
  // parts own whole planes of blocks, so each flag has one writer.
  std::vector<std::uint8_t> changed(static_cast<std::size_t>(count), 0);
  run_parts(nb.z, pass_parts(nb.z), [&](int, int k0, int k1) {
    for (int z = k0 * kBlock; z < std::min(k1 * kBlock, d.z); ++z)
      for (int y = 0; y < d.y; ++y) {
        // Most rows are still: one comparison of the whole row first.
        const auto row = static_cast<std::size_t>(m.index(0, y, z));
        if (std::memcmp(&disp[row], &seen_[row], sizeof(Vec3) * static_cast<std::size_t>(d.x)) == 0) continue;
        for (int x = 0; x < d.x; ++x) {
          const std::size_t i = row + static_cast<std::size_t>(x);
          if (std::memcmp(&disp[i], &seen_[i], sizeof(Vec3)) == 0) continue;
          seen_[i] = disp[i];
          changed[static_cast<std::size_t>(x / kBlock + nb.x * (y / kBlock + nb.y * (z / kBlock)))] = 1;
        }
      }
  });
  // An element is an end of links and a corner of cells owned by elements up to one lower
  // along each axis: its block and the blocks below it are dirty.
  std::vector<std::uint8_t> mark(static_cast<std::size_t>(count), 0);
  for (int bz = 0; bz < nb.z; ++bz)
    for (int by = 0; by < nb.y; ++by)
      for (int bx = 0; bx < nb.x; ++bx) {
        if (!changed[static_cast<std::size_t>(bx + nb.x * (by + nb.y * bz))]) continue;
        for (int k = std::max(0, bz - 1); k <= bz; ++k)
          for (int j = std::max(0, by - 1); j <= by; ++j)
            for (int i = std::max(0, bx - 1); i <= bx; ++i) mark[static_cast<std::size_t>(i + nb.x * (j + nb.y * k))] = 1;
      }
  for (int b = 0; b < count; ++b)
    if (mark[static_cast<std::size_t>(b)]) dirty.push_back(b);
  return dirty;
}

float IncrementalMetrics::max_link_violation(const Model& m, const std::vector<Vec3>& disp) {
  const std::vector<int> dirty = dirty_blocks(m, disp);
  link_max_.resize(static_cast<std::size_t>(blocks_.x) * blocks_.y * blocks_.z, 0.0f);
  const int n = static_cast<int>(dirty.size());
  run_parts(n, pass_parts(n), [&](int, int a, int b) {
    for (int k = a; k < b; ++k) {
      const int blk = dirty[static_cast<std::size_t>(k)];
      const Int3 lo = block_lo(blk);
      const Int3 hi{std::min(lo.x + kBlock, m.dims.x), std::min(lo.y + kBlock, m.dims.y), std::min(lo.z + kBlock, m.dims.z)};
      link_max_[static_cast<std::size_t>(blk)] = link_max_in(m, disp, lo, hi);
    }
  });
  return link_max_.empty() ? 0.0f : *std::max_element(link_max_.begin(), link_max_.end());
}

CellJacobianStats IncrementalMetrics::cell_jacobian(const Model& m, const std::vector<Vec3>& disp) {
  const std::vector<int> dirty = dirty_blocks(m, disp);
  if (m.dims.x < 2 || m.dims.y < 2 || m.dims.z < 2) return {};
  const std::size_t count = static_cast<std::size_t>(blocks_.x) * blocks_.y * blocks_.z;
  cell_min_.resize(count, 1.0);
  cell_folded_.resize(count, 0);
  const int n = static_cast<int>(dirty.size());
  run_parts(n, pass_parts(n), [&](int, int a, int b) {
    for (int k = a; k < b; ++k) {
      const int blk = dirty[static_cast<std::size_t>(k)];
      const Int3 lo = block_lo(blk);
      const CellRange r = cells_in(m, disp, lo, {lo.x + kBlock, lo.y + kBlock, lo.z + kBlock});
      cell_min_[static_cast<std::size_t>(blk)] = r.min_det;
      cell_folded_[static_cast<std::size_t>(blk)] = r.folded;
    }
  });
  double min_det = 1.0;
  Index folded = 0;
  for (std::size_t b = 0; b < count; ++b) {
    min_det = std::min(min_det, cell_min_[b]);
    folded += cell_folded_[b];
  }
  return cell_stats(m, min_det, folded);
}

}  // namespace hpcm
