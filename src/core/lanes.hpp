#pragma once
// What the rules written once over a lane type (core/link_box.hpp, solver/rules.hpp) need
// beyond + - * / and comparisons: the lane type may be float (host and device code) or a GCC
// vector of floats (the CPU's SIMD kernels, cpu/simd.hpp). For both, `c ? a : b` picks lane by
// lane (a bool for float, a comparison's integer mask for a vector), and every operation is
// plain IEEE single precision per lane, so one definition gives the same bits at every width.
#include <cstdint>
#include <cstring>

#include "hpcm/types.hpp"

namespace hpcm {

/// The integer lanes of lane type T: int32 for float; for a GCC vector, the type of its
/// comparisons (an int vector of the same width).
template <class T>
struct LaneInt {
  using type = decltype(T{} < T{});
};
template <>
struct LaneInt<float> {
  using type = std::int32_t;
};
template <class T>
using lane_int_t = typename LaneInt<T>::type;

/// The bit patterns of the lanes (as lane_int_t<T>), and back. Device code has float lanes only.
template <class T>
HPCM_HD inline lane_int_t<T> bit_pattern(T x) {
#if defined(__CUDA_ARCH__)
  return __float_as_int(x);
#else
  lane_int_t<T> i;
  std::memcpy(&i, &x, sizeof i);
  return i;
#endif
}
template <class T>
HPCM_HD inline T from_bit_pattern(lane_int_t<T> i) {
#if defined(__CUDA_ARCH__)
  return __int_as_float(i);
#else
  T x;
  std::memcpy(&x, &i, sizeof x);
  return x;
#endif
}

/// a + b on integer lanes, wrapping around (modulo 2^32) instead of overflowing: bit-pattern
/// arithmetic evaluates every lane, also those whose result is not used (t = -0.0f has the bit
/// pattern INT32_MIN, and INT32_MIN - 1 would be a signed overflow, undefined behaviour).
HPCM_HD inline std::int32_t wrapping_add(std::int32_t a, std::int32_t b) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) + static_cast<std::uint32_t>(b));
}
#if !defined(__CUDACC__)
template <class I>
inline I wrapping_add(I a, I b) {  // GCC integer vectors (device code has float lanes only)
  typedef unsigned int U __attribute__((vector_size(sizeof(I))));  // an alias-declaration would drop the attribute
  static_assert(sizeof(U) == sizeof(I));
  U ua, ub;
  std::memcpy(&ua, &a, sizeof ua);
  std::memcpy(&ub, &b, sizeof ub);
  const U sum = ua + ub;
  I out;
  std::memcpy(&out, &sum, sizeof out);
  return out;
}
#endif

/// a + b and a - b, one IEEE rounding each: the plain operators. The AVX-512 kernels
/// (cpu/simd_avx512.cpp) specialise them as fused multiply-adds by one (a * 1 + b rounds once,
/// to the same bits), which run on the multiply pipes while plain additions, maxima and minima
/// queue on the add pipes (AMD Zen 4).
template <class T>
HPCM_HD inline T add_exact(T a, T b) {
  return a + b;
}
template <class T>
HPCM_HD inline T sub_exact(T a, T b) {
  return a - b;
}

}  // namespace hpcm
