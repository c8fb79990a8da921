#include "hpcm/phantom.hpp"

#include <algorithm>
#include <cmath>

namespace hpcm {

namespace {
struct VariantName {
  PhantomVariant variant;
  const char* name;
};
constexpr VariantName kVariantNames[] = {
    {PhantomVariant::Standard, "standard"},   {PhantomVariant::ThinTissue, "thin-tissue"},
    {PhantomVariant::ThickFat, "thick-fat"},  {PhantomVariant::AirPockets, "air-pockets"},
    {PhantomVariant::Table, "table"},         {PhantomVariant::Anisotropic, "anisotropic"},
};
}  // namespace

const char* phantom_variant_name(PhantomVariant v) {
  for (const auto& e : kVariantNames)
    if (e.variant == v) return e.name;
  return "unknown";
}

PhantomVariant parse_phantom_variant(const std::string& name, const std::string& option) {
  std::string valid;
  for (const auto& e : kVariantNames) {
    if (name == e.name) return e.variant;
    valid += std::string(valid.empty() ? "" : ", ") + e.name;
  }
  throw Error(option + " '" + name + "' is not a phantom variant; valid: " + valid);
}

std::vector<PhantomVariant> all_phantom_variants() {
  std::vector<PhantomVariant> out;
  for (const auto& e : kVariantNames) out.push_back(e.variant);
  return out;
}

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

// Thicknesses of the body wall layers, in normalised y units.
struct WallLayers {
  double skin, fat, muscle;
};
WallLayers wall_layers(PhantomVariant variant, double cell) {
  if (variant == PhantomVariant::ThinTissue) return {cell, cell, std::max(0.03, 2.0 * cell)};
  return {std::max(0.012, 1.0 * cell), std::max(0.06, 3.0 * cell), std::max(0.03, 2.0 * cell)};
}

// HU of the noiseless phantom at normalised coordinates (x, y, z) in [0,1]^3 (LPS:
// x right->left, y anterior->posterior, z inferior->superior). `cell` is the size of one
// element in normalised y units, so thin layers stay at least about one element thick.
// The standard variant's arithmetic is the original phantom's, unchanged (tests compare it).
// `in_body` is set to whether the point lies in the body (not the air around it, not the table).
float phantom_hu(double x, double y, double z, double cell, PhantomVariant variant, bool& in_body) {
  in_body = false;
  constexpr float kAir = -1000, kSkin = 10, kFat = -100, kMuscle = 50, kLiver = 60, kSpleen = 45,
                  kKidney = 30, kBowel = 20, kGas = -700, kAorta = 40, kCancellous = 330, kCortical = 1000,
                  kDisc = 90, kVisceralFat = -90;
  // Variants: bowel gas pocket, sternal marrow, CT table (carbon-fibre shells over a foam core).
  constexpr float kPocketGas = -980, kSternalMarrow = 400, kTableShell = 600, kTableFoam = -850;
  if (variant == PhantomVariant::Table) {
    // The table top cuts the body's posterior pole: the supine body rests flattened on it.
    const double top = 0.80, thickness = std::max(0.05, 4.0 * cell), shell = std::max(0.006, 1.0 * cell);
    if (y >= top && y < top + thickness && std::abs(x - 0.5) < 0.45)
      return (y < top + shell || y >= top + thickness - shell) ? kTableShell : kTableFoam;
  }
  in_body = true;  // until the outline tests below say otherwise
  // Body: an elliptic cylinder whose width breathes slightly along z.
  const double cx = 0.5, cy = 0.53;
  const double ax = 0.40 * (1.0 - 0.04 * std::cos(6.283 * z)), ay = 0.28 * (1.0 - 0.03 * std::cos(6.283 * z));
  const double u = (x - cx) / ax, v = (y - cy) / ay;
  const double r = std::sqrt(u * u + v * v);
  const WallLayers wall = wall_layers(variant, cell);
  const double skin = wall.skin, fat = wall.fat, muscle = wall.muscle;
  if (variant == PhantomVariant::ThickFat) {
    // Extra subcutaneous fat outside the standard body, mostly anterior and posterior; the
    // standard skin becomes fat, the new outer surface is skin.
    const double extra = std::max(0.10, 5.0 * cell);
    const double ux = (x - cx) / (ax + 0.6 * extra), vy = (y - cy) / (ay + extra);
    const double outer = std::sqrt(ux * ux + vy * vy);
    if (outer > 1.0) return in_body = false, kAir;
    if ((1.0 - outer) * (ay + extra) < skin) return kSkin;
    if (r > 1.0) return kFat;
  }
  if (r > 1.0) return in_body = false, kAir;
  const double depth = (1.0 - r) * ay;  // inward distance, in normalised y units (exact at the poles)
  if (depth < skin) return variant == PhantomVariant::ThickFat ? kFat : kSkin;
  if (depth < skin + fat) return kFat;
  if (variant == PhantomVariant::ThinTissue && y < cy && std::abs(x - 0.5) < 0.045 && z > 0.35) {
    // Sternum-like plate right under the thin anterior tissue (where the paper protocol grabs).
    const double plate = std::max(0.025, 2.0 * cell), inside = depth - skin - fat;
    if (inside < plate) return (inside < cell || inside >= plate - cell) ? kCortical : kSternalMarrow;
  }
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
  if (variant == PhantomVariant::AirPockets &&
      in_ellipsoid(x, y, z, 0.5, cy - ay + skin + fat + muscle + 0.045, 0.5, 0.07, 0.045, 0.12))
    return kPocketGas;  // right behind the anterior wall, under the grab
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
  const double gas_above = variant == PhantomVariant::AirPockets ? 0.30 : 0.55;
  // Retroperitoneal fat in front of the spine; bowel loops in front of that.
  if (y < 0.55 && z < 0.75) {
    if (loop > gas_above) return variant == PhantomVariant::AirPockets ? kPocketGas : kGas;
    if (loop > -0.15) return kBowel;
  }
  return kVisceralFat;
}

// The anisotropic variant covers more than the standard 300 mm along z: beyond it the anatomy
// is mirrored (a continuous body), so the normalised z folds back into [0, 1].
double fold01(double z) {
  const double m = std::fmod(std::abs(z), 2.0);
  return m <= 1.0 ? m : 2.0 - m;
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
  const bool thick_slices = o.variant == PhantomVariant::Anisotropic;
  if (thick_slices) {
    // 0.8 : 0.8 : 5 mm like a thick-slice CT, keeping the 400 x 400 mm in-plane field of view,
    // centred on the origin like the standard phantom.
    const double in_plane = 400.0 / std::max(o.dims.x, o.dims.y);
    v.spacing = {in_plane, in_plane, in_plane * 5.0 / 0.8};
    for (int a = 0; a < 3; ++a) v.origin[a] = 0.5 * v.spacing[a] * (1 - v.dims[a]);
  } else {
    v.spacing = {400.0 / o.dims.x, 400.0 / o.dims.y, 300.0 / o.dims.z};
    v.origin = {-200.0 + 0.5 * v.spacing[0], -200.0 + 0.5 * v.spacing[1], -150.0 + 0.5 * v.spacing[2]};
  }
  v.hu.resize(v.size());
  // The generator knows its own body: the outline of the anatomy, without the table (SPEC §3).
  v.body.resize(v.size());
  v.body_method = "the phantom's own outline";
  const double cell = 1.0 / o.dims.y;
  // A thick slice is the mean of the anatomy across its thickness (partial volume).
  constexpr int kSlabSamples = 5;
#pragma omp parallel for schedule(static)
  for (int z = 0; z < o.dims.z; ++z)
    for (int y = 0; y < o.dims.y; ++y)
      for (int x = 0; x < o.dims.x; ++x) {
        const Index i = v.index(x, y, z);
        const double nx = (x + 0.5) / o.dims.x, ny = (y + 0.5) / o.dims.y;
        float base = 0;
        bool in_body = false;
        if (thick_slices) {
          double sum = 0;
          int body_samples = 0;
          for (int s = 0; s < kSlabSamples; ++s) {
            const double z_mm = (z + (s + 0.5) / kSlabSamples - 0.5 * o.dims.z) * v.spacing[2];
            bool b = false;
            sum += phantom_hu(nx, ny, fold01(0.5 + z_mm / 300.0), cell, o.variant, b);
            body_samples += b;
          }
          base = static_cast<float>(sum / kSlabSamples);
          in_body = 2 * body_samples > kSlabSamples;  // most of the slab
        } else {
          base = phantom_hu(nx, ny, (z + 0.5) / o.dims.z, cell, o.variant, in_body);
        }
        v.body[static_cast<std::size_t>(i)] = in_body ? 1 : 0;
        v.hu[static_cast<std::size_t>(i)] = base + o.noise_hu * gaussian(o.seed, static_cast<std::uint64_t>(i));
      }
  return v;
}

}  // namespace hpcm
