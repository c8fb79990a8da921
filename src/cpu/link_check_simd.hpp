#pragma once
// The vector filter of the link check (cpu/link_check.cpp), N elements at a time: included by
// each simd_*.cpp (4-, 8- or 16-wide). It only decides which elements the exact
// scalar check looks at, so any lane it flags is checked again exactly; the test is
// link_violation (core/link_box.hpp) on the box from the link's tolerance (box_from_tau), the
// same definition at every width, so every width flags the same elements.
#include <vector>

#include "cpu/kernels.hpp"
#include "cpu/simd.hpp"
#include "solver/restore.hpp"

namespace hpcm::cpu::simd {

/// Elements j in [j0, j1) of half h of row (y, z) (all with a +x neighbour); appends those whose
/// +x, +y or +z link or whose wall distance may exceed the restoration tolerance to `flagged`.
template <class V>
void link_check_row(const Storage& st, const solver::Wall& wall, int h, int y, int z, int j0, int j1,
                   std::vector<int>& flagged) {
  constexpr int N = sizeof(V) / sizeof(float);
  const Layout& L = st.lay;
  const Index k0 = L.row_start(h, y, z);
  const Index ko = L.row_start(1 - h, y, z) + (h == 0 ? 0 : 1);  // +x neighbour of j
  const Index sy = L.width[h], sz = L.plane[h];
  const bool has_y = y + 1 < L.dims.y, has_z = z + 1 < L.dims.z;
  // The element's wall (solver::element_wall): lane by lane on x, per row on y and z.
  const V wlo_x = splat<V>(wall.lo[0]), whi_x = splat<V>(wall.hi[0]);
  const V wlo_yz[2] = {splat<V>(solver::wall_lo_of(wall, 1, y)), splat<V>(solver::wall_lo_of(wall, 2, z))};
  const V whi_yz[2] = {splat<V>(solver::wall_hi_of(wall, 1, y)), splat<V>(solver::wall_hi_of(wall, 2, z))};
  const V tol = splat<V>(solver::kRestoreTolerance);
  V lane;
  for (int l = 0; l < N; ++l) lane[l] = static_cast<float>(l);
  for (int j = j0; j < j1; j += N) {  // the last vector is masked; its loads may run into the padding
    const Index k = k0 + j;
    const V x = splat<V>(static_cast<float>(h)) + splat<V>(2.0f) * (lane + splat<V>(static_cast<float>(j)));
    const V wlo[3] = {wlo_x - x, wlo_yz[0], wlo_yz[1]};
    const V whi[3] = {whi_x - x, whi_yz[0], whi_yz[1]};
    const V p[3] = {load<V>(st.p[0].data() + k), load<V>(st.p[1].data() + k), load<V>(st.p[2].data() + k)};
    V worst = splat<V>(0.0f);
    for (int b = 0; b < 3; ++b) worst = vmax(worst, vmax(wlo[b] - p[b], p[b] - whi[b]));
    auto link = [&](Index kq, int a) {
      const V d[3] = {load<V>(st.p[0].data() + kq) - p[0], load<V>(st.p[1].data() + kq) - p[1],
                      load<V>(st.p[2].data() + kq) - p[2]};  // the link's + end minus its - end
      worst = vmax(worst, link_violation(d, box_from_tau(load<V>(st.link_tau[a].data() + k)), a));
    };
    link(ko + j, 0);
    if (has_y) link(k + sy, 1);
    if (has_z) link(k + sz, 2);
    const auto in_run = lane < splat<V>(static_cast<float>(j1 - j));
    for (unsigned bits = lane_bits<V>((worst > tol) & in_run); bits; bits &= bits - 1) flagged.push_back(j + __builtin_ctz(bits));
  }
}

}  // namespace hpcm::cpu::simd
