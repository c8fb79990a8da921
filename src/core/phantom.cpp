#include "hpcm/phantom.hpp"

#include <cmath>

namespace hpcm {
namespace {

// Counter-based RNG: every voxel draws from (seed, index), so the phantom does not depend on
// the thread count or the loop order.
std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
double uniform01(std::uint64_t h) { return ((h >> 11) + 0.5) * (1.0 / 9007199254740992.0); }
float gaussian(std::uint64_t seed, std::uint64_t i) {
  const std::uint64_t h1 = splitmix64(seed * 0x100000001B3ull ^ (2 * i));
  const std::uint64_t h2 = splitmix64(h1 ^ (2 * i + 1));
  const double u1 = uniform01(h1), u2 = uniform01(h2);
  return static_cast<float>(std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2));
}

// Inside an axis-aligned ellipse / ellipsoid in normalised coordinates.
bool in_ellipse(double x, double y, double cx, double cy, double ax, double ay) {
  const double u = (x - cx) / ax, v = (y - cy) / ay;
  return u * u + v * v <= 1.0;
}
bool in_ellipsoid(double x, double y, double z, double cx, double cy, double cz, double ax, double ay, double az) {
  const double u = (x - cx) / ax, v = (y - cy) / ay, w = (z - cz) / az;
  return u * u + v * v + w * w <= 1.0;
}

// HU of the noiseless phantom at normalised coordinates (x, y, z) in [0,1]^3 (LPS:
// x right->left, y anterior->posterior, z inferior->superior). `cell` is the size of one
// element in normalised y units, so thin layers stay at least about one element thick.
float phantom_hu(double x, double y, double z, double cell) {
  constexpr float kAir = -1000, kSkin = 10, kFat = -100, kMuscle = 50, kLiver = 60, kSpleen = 45,
                  kKidney = 30, kBowel = 20, kGas = -700, kAorta = 40, kCancellous = 330, kCortical = 1000,
                  kDisc = 90, kVisceralFat = -90;
  // Body: an elliptic cylinder whose width breathes slightly along z.
  const double cx = 0.5, cy = 0.53;
  const double ax = 0.40 * (1.0 - 0.04 * std::cos(6.283 * z)), ay = 0.28 * (1.0 - 0.03 * std::cos(6.283 * z));
  const double u = (x - cx) / ax, v = (y - cy) / ay;
  const double r = std::sqrt(u * u + v * v);
  if (r > 1.0) return kAir;
  const double depth = (1.0 - r) * ay;  // inward distance, in normalised y units (exact at the poles)
  const double skin = std::max(0.012, 1.0 * cell), fat = std::max(0.06, 3.0 * cell), muscle = std::max(0.03, 2.0 * cell);
  if (depth < skin) return kSkin;
  if (depth < skin + fat) return kFat;
  // Spine: vertebral body with cortical shell, posterior arch; discs at regular z.
  const double sx = 0.5, sy = 0.70;
  const bool disc = std::fmod(z * 9.0, 1.0) < 0.15;
  if (in_ellipse(x, y, sx, sy, 0.055, 0.05)) {
    if (disc) return kDisc;
    return in_ellipse(x, y, sx, sy, 0.042, 0.037) ? kCancellous : kCortical;
  }
  if (!disc && (in_ellipse(x, y, sx, sy + 0.085, 0.018, 0.04) || in_ellipse(x, y, sx - 0.045, sy + 0.06, 0.04, 0.012) ||
                in_ellipse(x, y, sx + 0.045, sy + 0.06, 0.04, 0.012)))
    return kCortical;
  // Back muscles either side of the spine, and the abdominal wall muscles all around.
  if (in_ellipse(x, y, sx - 0.09, sy + 0.07, 0.06, 0.05) || in_ellipse(x, y, sx + 0.09, sy + 0.07, 0.06, 0.05))
    return kMuscle;
  if (depth < skin + fat + muscle) return kMuscle;
  // Organs.
  if (in_ellipse(x, y, sx + 0.035, sy - 0.085, 0.022, 0.022)) return kAorta;  // left of the midline
  if (in_ellipsoid(x, y, z, 0.30, 0.48, 0.78, 0.17, 0.16, 0.35)) return kLiver;            // patient right
  if (in_ellipsoid(x, y, z, 0.73, 0.58, 0.78, 0.08, 0.08, 0.22)) return kSpleen;           // patient left
  if (in_ellipsoid(x, y, z, 0.36, 0.68, 0.55, 0.06, 0.08, 0.16) ||
      in_ellipsoid(x, y, z, 0.64, 0.68, 0.55, 0.06, 0.08, 0.16))
    return kKidney;
  // Bowel loops with gas pockets in the lower and anterior abdomen.
  const double bz = z * 7.0, bx = x * 11.0, by = y * 13.0;
  const double loop = std::sin(bx + 1.3 * std::sin(bz)) * std::sin(by + 0.7 * std::cos(bx)) * std::cos(bz + by);
  // Retroperitoneal fat in front of the spine; bowel loops in front of that.
  if (y < 0.55 && z < 0.75) {
    if (loop > 0.55) return kGas;
    if (loop > -0.15) return kBowel;
  }
  return kVisceralFat;
}

}  // namespace

Volume make_phantom(const PhantomOptions& o) {
  if (o.dims.x < 8 || o.dims.y < 8 || o.dims.z < 8 || o.dims.x > 4096 || o.dims.y > 4096 || o.dims.z > 4096)
    throw Error("phantom size " + std::to_string(o.dims.x) + "," + std::to_string(o.dims.y) + "," +
                std::to_string(o.dims.z) + " is out of range: each axis must be in [8, 4096]");
  const double n = static_cast<double>(o.dims.x) * o.dims.y * o.dims.z;
  if (n > 2147483647.0) throw Error("phantom size: more than 2^31-1 elements");
  if (!(o.noise_hu >= 0.0f && o.noise_hu <= 200.0f))
    throw Error("phantom noise_hu = " + std::to_string(o.noise_hu) + " is out of range [0, 200]");
  Volume v;
  v.dims = o.dims;
  v.spacing = {400.0 / o.dims.x, 400.0 / o.dims.y, 300.0 / o.dims.z};
  v.origin = {-200.0 + 0.5 * v.spacing[0], -200.0 + 0.5 * v.spacing[1], -150.0 + 0.5 * v.spacing[2]};
  v.hu.resize(v.size());
  const double cell = 1.0 / o.dims.y;
#pragma omp parallel for schedule(static)
  for (int z = 0; z < o.dims.z; ++z)
    for (int y = 0; y < o.dims.y; ++y)
      for (int x = 0; x < o.dims.x; ++x) {
        const Index i = v.index(x, y, z);
        const float base = phantom_hu((x + 0.5) / o.dims.x, (y + 0.5) / o.dims.y, (z + 0.5) / o.dims.z, cell);
        v.hu[static_cast<std::size_t>(i)] = base + o.noise_hu * gaussian(o.seed, static_cast<std::uint64_t>(i));
      }
  return v;
}

}  // namespace hpcm
