#pragma once
// Small value types shared by every module. Lattice positions are in lattice units
// (one unit = one element spacing); millimetres appear only in IO.
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#if defined(__CUDACC__)
#define HPCM_HD __host__ __device__
#else
#define HPCM_HD
#endif

namespace hpcm {

/// Every user-facing error (bad parameter, bad file, bad option) is an hpcm::Error whose
/// message names the file, key or value and the valid range.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Int3 {
  int x = 0, y = 0, z = 0;
  HPCM_HD int operator[](int a) const { return a == 0 ? x : (a == 1 ? y : z); }
  friend bool operator==(const Int3&, const Int3&) = default;
};

struct Vec3 {
  float x = 0, y = 0, z = 0;
  HPCM_HD float operator[](int a) const { return a == 0 ? x : (a == 1 ? y : z); }
  HPCM_HD float& operator[](int a) { return a == 0 ? x : (a == 1 ? y : z); }
  friend bool operator==(const Vec3&, const Vec3&) = default;
};
HPCM_HD inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
HPCM_HD inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
HPCM_HD inline Vec3 operator*(float s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }
HPCM_HD inline float dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
HPCM_HD inline float norm(Vec3 a) { return sqrtf(dot(a, a)); }

/// Linear element index i = x + Nx*(y + Ny*z).
using Index = std::int64_t;

}  // namespace hpcm
