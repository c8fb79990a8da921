#pragma once
// The independent velocity layer of the paper (SPEC §5), one element at a time. Written
// once for the CPU layer (velocity_layer.cpp) and the fused CUDA kernel. It sees only the
// pre-ChainMail position X-, the post-ChainMail position X+ and its own state: the ChainMail
// solver is never called or changed from here. Positions are displacements from rest
// (u = X - X0): differences and velocities are the same numbers, the rest offset X- - X0 is u-
// itself, and the boundary clamp is the element's own interval.
#include "hpcm/params.hpp"
#include "hpcm/types.hpp"

namespace hpcm::dynamics {

/// Per-class constants of the layer, derived once from DynamicsParams.
struct LayerConstants {
  int mode;            ///< 0 none, 1 simple, 2 viscoelastic
  float alpha, b0, dead_zone, v_max, beta;
  float s[4], b1[4], rho[4], inv_mass[4];
  float lo[3], hi[3];  ///< boundary clamp box [-m, N-1+m] (lattice coordinates; minus X0 per element)
};

LayerConstants make_constants(const DynamicsParams& p, Int3 dims);

/// One element: updates v and returns u_{t+1} (pre, post: u- and u+; `rest`: X0, the element's
/// lattice index as floats). `fixed`: no dynamics for this element this frame
/// (FIXED: grabbed or anchored; or its brick sleeps). `speed`, when given, receives |V| before
/// the magnitude clamp (0 without dynamics): the backends' brick sleep decision.
HPCM_HD inline Vec3 velocity_update(const LayerConstants& k, int tissue, bool fixed, Vec3 pre, Vec3 post, Vec3 rest,
                                    Vec3& v, float* speed_out = nullptr) {
  Vec3 x = post;
  if (speed_out) *speed_out = 0.0f;
  if (fixed || k.inv_mass[tissue] == 0.0f || k.mode == 0) {
    v = Vec3{0, 0, 0};  // 1. FIXED / massless (bone), and condition A: no dynamics
  } else {
    Vec3 dx = post - pre;  // 2. intra-frame ChainMail correction
    if (norm(dx) < k.dead_zone) dx = Vec3{0, 0, 0};
    const float s = k.s[tissue];  // 3. response scale
    if (k.mode == 1) {            // 4. simple (B)
      v = Vec3{k.alpha * v.x + s * dx.x, k.alpha * v.y + s * dx.y, k.alpha * v.z + s * dx.z};
    } else {                      //    viscoelastic (C): implicit damper, never flips the sign
      const Vec3 vt{v.x + s * dx.x, v.y + s * dx.y, v.z + s * dx.z};
      const float denom = 1.0f + k.b0 + k.b1[tissue] * norm(pre);  // |X- - X0|
      v = Vec3{vt.x / denom, vt.y / denom, vt.z / denom};
    }
    const float speed = norm(v);  // 5. magnitude clamp keeping the direction
    if (speed_out) *speed_out = speed;
    if (speed > k.v_max) {
      const float f = k.v_max / speed;
      v = Vec3{v.x * f, v.y * f, v.z * f};
    }
    const float g = k.beta * k.rho[tissue];  // 6. position update
    x = Vec3{post.x + g * v.x, post.y + g * v.y, post.z + g * v.z};
  }
  for (int a = 0; a < 3; ++a) {  // 7. boundary clamp, as bounds on u (solver::wall_lo_of)
    const float c = x[a], lo = k.lo[a] - rest[a], hi = k.hi[a] - rest[a];
    x[a] = c < lo ? lo : (c > hi ? hi : c);
  }
  return x;
}

}  // namespace hpcm::dynamics
