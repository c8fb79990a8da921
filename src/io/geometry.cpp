// hpcm::io, the parts without ITK: formats by extension, reorientation to LPS index order,
// inverse-mapping resampling of the deformed lattice, displacement in millimetres.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "hpcm/io.hpp"
#include "io_detail.hpp"

namespace hpcm::io {
namespace detail {

namespace {
bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}
}  // namespace

Format format_of(const std::string& path) {
  std::string s = std::filesystem::path(path).filename().string();
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ends_with(s, ".nii.gz")) return Format::NiftiGz;
  if (ends_with(s, ".nii")) return Format::Nifti;
  if (ends_with(s, ".nrrd")) return Format::Nrrd;
  if (ends_with(s, ".nhdr")) return Format::Nhdr;
  if (ends_with(s, ".mha")) return Format::Mha;
  if (ends_with(s, ".mhd")) return Format::Mhd;
  return Format::Unknown;
}

const char* format_name(Format f) {
  switch (f) {
    case Format::Nifti:
    case Format::NiftiGz: return "NIfTI";
    case Format::Nrrd:
    case Format::Nhdr: return "NRRD";
    case Format::Mha:
    case Format::Mhd: return "MetaImage";
    default: return "unknown";
  }
}

std::string extension_of(Format f) {
  switch (f) {
    case Format::Nifti: return ".nii";
    case Format::NiftiGz: return ".nii.gz";
    case Format::Nrrd: return ".nrrd";
    case Format::Nhdr: return ".nhdr";
    case Format::Mha: return ".mha";
    case Format::Mhd: return ".mhd";
    default: return "";
  }
}

Grid grid_in_lps_order(const Grid& g, const IndexOrder& order) {
  const int od[3] = {g.dims.x, g.dims.y, g.dims.z};
  Grid l;
  int nd[3];
  for (int p = 0; p < 3; ++p) {
    const int a = order.axis[static_cast<std::size_t>(p)];
    nd[p] = od[a];
    l.spacing[p] = g.spacing[a];
    const double sgn = order.reversed[static_cast<std::size_t>(p)] ? -1.0 : 1.0;
    for (int r = 0; r < 3; ++r) l.direction[r * 3 + p] = sgn * g.direction[r * 3 + a];
  }
  l.dims = {nd[0], nd[1], nd[2]};
  // New origin: physical position of the stored voxel that becomes (0,0,0).
  for (int r = 0; r < 3; ++r) {
    double o = g.origin[r];
    for (int p = 0; p < 3; ++p) {
      if (!order.reversed[static_cast<std::size_t>(p)]) continue;
      const int a = order.axis[static_cast<std::size_t>(p)];
      o += g.direction[r * 3 + a] * g.spacing[a] * (od[a] - 1);
    }
    l.origin[r] = o;
  }
  return l;
}

double mat_det(const std::array<double, 9>& m) {
  return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) + m[2] * (m[3] * m[7] - m[4] * m[6]);
}

std::array<double, 9> mat_inverse(const std::array<double, 9>& m) {
  const double a = m[0], b = m[1], c = m[2], d = m[3], e = m[4], f = m[5], g = m[6], h = m[7], i = m[8];
  const double A = e * i - f * h, B = -(d * i - f * g), C = d * h - e * g;
  const double det = mat_det(m);
  if (!(std::abs(det) > 1e-300) || !std::isfinite(det)) throw Error("singular direction/spacing matrix");
  const double s = 1.0 / det;
  return {A * s, -(b * i - c * h) * s, (b * f - c * e) * s,
          B * s, (a * i - c * g) * s,  -(a * f - c * d) * s,
          C * s, -(a * h - b * g) * s, (a * e - b * d) * s};
}

// Index -> physical: P = origin + D * diag(spacing) * q.
std::array<double, 9> index_to_physical_matrix(const std::array<double, 9>& dir, const std::array<double, 3>& sp) {
  std::array<double, 9> a{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[r * 3 + c] = dir[r * 3 + c] * sp[c];
  return a;
}

namespace {
std::array<double, 9> mat_mul(const std::array<double, 9>& x, const std::array<double, 9>& y) {
  std::array<double, 9> r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) r[i * 3 + j] += x[i * 3 + k] * y[k * 3 + j];
  return r;
}
std::array<double, 3> mat_vec(const std::array<double, 9>& m, const std::array<double, 3>& v) {
  return {m[0] * v[0] + m[1] * v[1] + m[2] * v[2], m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
          m[6] * v[0] + m[7] * v[1] + m[8] * v[2]};
}

// Snap a continuous index to the nearest integer when within tol (geometry round-off).
inline double snap(double q) {
  const double r = std::nearbyint(q);
  return std::abs(q - r) < 1e-4 ? r : q;
}
}  // namespace

InverseMappingStats for_each_rest_position(const Grid& original, const Model& m, const std::vector<Vec3>& disp,
                                           int max_iterations, int newton_iterations, const RestPositionVisitor& visit) {
  if (static_cast<Index>(disp.size()) != m.size())
    throw Error("deformed volume: " + std::to_string(disp.size()) + " displacements for a lattice of " +
                std::to_string(m.size()) + " elements");
  if (original.size() == 0) throw Error("deformed volume: the original volume is empty");
  const std::array<double, 9> A = index_to_physical_matrix(m.direction, m.spacing);       // lattice -> mm
  const std::array<double, 9> B = index_to_physical_matrix(original.direction, original.spacing);  // input -> mm
  const std::array<double, 9> Ainv = mat_inverse(A), Binv = mat_inverse(B);
  const std::array<double, 9> M = mat_mul(Ainv, B);     // input index -> lattice
  const std::array<double, 9> Minv = mat_mul(Binv, A);  // lattice -> input index
  const std::array<double, 3> c = mat_vec(Ainv, {original.origin[0] - m.origin[0], original.origin[1] - m.origin[1],
                                                 original.origin[2] - m.origin[2]});
  const std::array<double, 3> cinv = mat_vec(Binv, {m.origin[0] - original.origin[0], m.origin[1] - original.origin[1],
                                                    m.origin[2] - original.origin[2]});
  const int N[3] = {m.dims.x, m.dims.y, m.dims.z};
  const int O[3] = {original.dims.x, original.dims.y, original.dims.z};
  // Displacement in lattice units at every lattice point (what the solver stores).
  const std::vector<Vec3>& u = disp;
  bool any = false;
  for (Index i = 0; i < m.size(); ++i) any = any || u[i].x != 0 || u[i].y != 0 || u[i].z != 0;
  // Trilinear u at lattice point X and, when `grad` is given, its derivative
  // grad[r * 3 + a] = du_r / dX_a (zero along an axis where X lies beyond the lattice).
  auto sample_u = [&](const double X[3], double out[3], double* grad = nullptr) {
    int i0[3];
    double f[3];
    bool inside[3];
    out[0] = out[1] = out[2] = 0;
    if (grad) std::fill(grad, grad + 9, 0.0);
    // Outside the lattice u is extended constantly from its border (continuous, so the
    // fixed-point iteration stays well behaved).
    for (int a = 0; a < 3; ++a) {
      double q = std::clamp(X[a], 0.0, double(N[a] - 1));
      int k = std::min(static_cast<int>(q), std::max(N[a] - 2, 0));
      i0[a] = k;
      f[a] = N[a] > 1 ? q - k : 0.0;
      inside[a] = N[a] > 1 && X[a] >= 0.0 && X[a] <= double(N[a] - 1);
    }
    const Index sx = N[0] > 1 ? 1 : 0, sy = N[1] > 1 ? N[0] : 0, sz = N[2] > 1 ? Index(N[0]) * N[1] : 0;
    const Index base = i0[0] + Index(N[0]) * (i0[1] + Index(N[1]) * i0[2]);
    for (int k = 0; k < 8; ++k) {
      double wa[3], dwa[3];  // per-axis weight and its derivative
      for (int a = 0; a < 3; ++a) {
        const bool hi = (k >> a) & 1;
        wa[a] = hi ? f[a] : 1 - f[a];
        dwa[a] = inside[a] ? (hi ? 1.0 : -1.0) : 0.0;
      }
      const double w = wa[0] * wa[1] * wa[2];
      if (w == 0 && !grad) continue;
      const Vec3& d = u[base + ((k & 1) ? sx : 0) + ((k & 2) ? sy : 0) + ((k & 4) ? sz : 0)];
      const double dv[3] = {d.x, d.y, d.z};
      for (int r = 0; r < 3; ++r) out[r] += w * dv[r];
      if (!grad) continue;
      const double dw[3] = {dwa[0] * wa[1] * wa[2], wa[0] * dwa[1] * wa[2], wa[0] * wa[1] * dwa[2]};
      for (int r = 0; r < 3; ++r)
        for (int a = 0; a < 3; ++a) grad[r * 3 + a] += dw[a] * dv[r];
    }
  };
  // |x - (X + u(X))| in millimetres; F receives x - (X + u(X)) in lattice units.
  auto residual_mm = [&](const double xl[3], const double X[3], double F[3], double* grad = nullptr) {
    double d[3];
    sample_u(X, d, grad);
    for (int a = 0; a < 3; ++a) F[a] = xl[a] - X[a] - d[a];
    const std::array<double, 3> f_mm = mat_vec(A, {F[0], F[1], F[2]});
    return std::sqrt(f_mm[0] * f_mm[0] + f_mm[1] * f_mm[1] + f_mm[2] * f_mm[2]);
  };
  // Per output plane: unconverged voxels, the largest residual and where it is (combined in
  // plane order afterwards, so the figures do not depend on the thread count).
  std::vector<Index> plane_unconverged(static_cast<std::size_t>(O[2]), 0);
  std::vector<double> plane_max(static_cast<std::size_t>(O[2]), -1.0);
  std::vector<Int3> plane_worst(static_cast<std::size_t>(O[2]));
#pragma omp parallel for schedule(dynamic, 1)
  for (int z = 0; z < O[2]; ++z) {
    for (int y = 0; y < O[1]; ++y) {
      for (int x = 0; x < O[0]; ++x) {
        const double q[3] = {double(x), double(y), double(z)};
        double xl[3];
        for (int r = 0; r < 3; ++r) xl[r] = M[r * 3] * q[0] + M[r * 3 + 1] * q[1] + M[r * 3 + 2] * q[2] + c[r];
        double X[3] = {xl[0], xl[1], xl[2]};
        if (any) {
          // Fixed point X = x - u(X), starting at X = x.
          for (int it = 0; it < max_iterations; ++it) {
            double d[3];
            sample_u(X, d);
            double change = 0;
            for (int a = 0; a < 3; ++a) {
              const double nx = xl[a] - d[a];
              change = std::max(change, std::abs(nx - X[a]));
              X[a] = nx;
            }
            if (change < 1e-5) break;
          }
          // Where the fixed point is slow (|du/dX| near 1: strong compression or shear),
          // Newton's method on X + u(X) = x, each step halved until the residual drops.
          double F[3], G[9];
          double residual = residual_mm(xl, X, F, G);
          for (int it = 0; it < newton_iterations && residual > kInverseMappingToleranceMm; ++it) {
            std::array<double, 9> J{1, 0, 0, 0, 1, 0, 0, 0, 1};
            for (int k = 0; k < 9; ++k) J[k] += G[k];
            if (!(std::abs(mat_det(J)) > 1e-12)) break;  // singular: folded here, no unique rest position
            const std::array<double, 3> step = mat_vec(mat_inverse(J), {F[0], F[1], F[2]});
            bool improved = false;
            for (double t = 1.0; t > 1e-3 && !improved; t *= 0.5) {
              const double Xt[3] = {X[0] + t * step[0], X[1] + t * step[1], X[2] + t * step[2]};
              double Ft[3], Gt[9];
              const double rt = residual_mm(xl, Xt, Ft, Gt);
              if (rt < residual) {
                improved = true;
                residual = rt;
                std::copy(Xt, Xt + 3, X);
                std::copy(Ft, Ft + 3, F);
                std::copy(Gt, Gt + 9, G);
              }
            }
            if (!improved) break;
          }
          if (residual > plane_max[z]) {
            plane_max[z] = residual;
            plane_worst[z] = {x, y, z};
          }
          if (!(residual <= kInverseMappingToleranceMm)) ++plane_unconverged[z];
        }
        double q0[3];
        // Snapped to the voxel centre within round-off, so that where nothing moved every export
        // (HU, labels, pull-back field) sees exactly the voxel itself.
        for (int r = 0; r < 3; ++r)
          q0[r] = snap(Minv[r * 3] * X[0] + Minv[r * 3 + 1] * X[1] + Minv[r * 3 + 2] * X[2] + cinv[r]);
        visit(x + static_cast<std::int64_t>(O[0]) * (y + static_cast<std::int64_t>(O[1]) * z), X, q0);
      }
    }
  }
  InverseMappingStats stats;
  stats.voxels = static_cast<Index>(original.size());
  for (int z = 0; z < O[2]; ++z) {
    stats.unconverged += plane_unconverged[z];
    if (plane_max[z] > stats.max_residual_mm) {
      stats.max_residual_mm = plane_max[z];
      stats.worst_voxel = plane_worst[z];
    }
  }
  stats.tolerance_mm = kInverseMappingToleranceMm;
  stats.max_iterations = max_iterations;
  stats.newton_iterations = newton_iterations;
  return stats;
}

float sample_trilinear(const Volume& original, const double q[3]) {
  const int O[3] = {original.dims.x, original.dims.y, original.dims.z};
  int i0[3], i1[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    if (!(q[a] >= -0.5 && q[a] <= O[a] - 0.5)) return kAirHU;
    const double s = std::clamp(snap(q[a]), 0.0, double(O[a] - 1));
    i0[a] = static_cast<int>(std::floor(s));
    f[a] = s - i0[a];
    i1[a] = std::min(i0[a] + 1, O[a] - 1);
  }
  double v = 0;
  for (int k = 0; k < 8; ++k) {
    const double w = ((k & 1) ? f[0] : 1 - f[0]) * ((k & 2) ? f[1] : 1 - f[1]) * ((k & 4) ? f[2] : 1 - f[2]);
    if (w == 0) continue;
    v += w * original.at((k & 1) ? i1[0] : i0[0], (k & 2) ? i1[1] : i0[1], (k & 4) ? i1[2] : i0[2]);
  }
  return static_cast<float>(v);
}

std::int64_t nearest_voxel(Int3 dims, const double q[3]) {
  const int n[3] = {dims.x, dims.y, dims.z};
  std::int64_t at = 0, stride = 1;
  for (int a = 0; a < 3; ++a) {
    // Half a voxel beyond the first and last centres still belongs to them (as for the HU).
    if (!(q[a] >= -0.5 && q[a] <= n[a] - 0.5)) return -1;
    const int k = std::clamp(static_cast<int>(std::floor(q[a] + 0.5)), 0, n[a] - 1);
    at += k * stride;
    stride *= n[a];
  }
  return at;
}

std::vector<float> resample_deformed(const Volume& original, const Model& m, const std::vector<Vec3>& disp,
                                     int max_iterations, int newton_iterations, InverseMappingStats* stats) {
  if (original.hu.size() != original.size() || original.size() == 0)
    throw Error("deformed volume: the original volume is empty");
  std::vector<float> out(original.size());
  const InverseMappingStats st = for_each_rest_position(
      grid_of(original), m, disp, max_iterations, newton_iterations,
      [&](std::int64_t voxel, const double*, const double* q0) { out[voxel] = sample_trilinear(original, q0); });
  if (stats) *stats = st;
  return out;
}

std::vector<float> displacement_mm(const Model& m, const std::vector<Vec3>& disp) {
  if (static_cast<Index>(disp.size()) != m.size())
    throw Error("displacement field: " + std::to_string(disp.size()) + " displacements for a lattice of " +
                std::to_string(m.size()) + " elements");
  const std::array<double, 9> A = index_to_physical_matrix(m.direction, m.spacing);
  std::vector<float> out(disp.size() * 3);
  for (Index i = 0; i < m.size(); ++i) {
    const Vec3 d = disp[i];  // exactly the solver's displacement (no subtraction of the rest position)
    if (!std::isfinite(d.x) || !std::isfinite(d.y) || !std::isfinite(d.z))
      throw Error("displacement field: non-finite displacement at element " + std::to_string(i));
    for (int r = 0; r < 3; ++r)
      out[3 * i + r] = static_cast<float>(A[r * 3] * d.x + A[r * 3 + 1] * d.y + A[r * 3 + 2] * d.z);
  }
  return out;
}

std::size_t available_memory_bytes() {
  std::ifstream f("/proc/meminfo");
  std::string key;
  std::size_t value = 0;
  std::string unit;
  while (f >> key >> value >> unit) {
    if (key == "MemAvailable:") return value * 1024;
  }
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? static_cast<std::size_t>(pages) * static_cast<std::size_t>(page) : 0;
}

std::string format_bytes(double bytes) {
  char buf[64];
  if (bytes >= 1e9)
    std::snprintf(buf, sizeof buf, "%.3g GB", bytes / 1e9);
  else if (bytes >= 1e6)
    std::snprintf(buf, sizeof buf, "%.3g MB", bytes / 1e6);
  else
    std::snprintf(buf, sizeof buf, "%.0f bytes", bytes);
  return buf;
}

}  // namespace detail

bool IndexOrder::identity() const {
  return axis == std::array<int, 3>{0, 1, 2} && !reversed[0] && !reversed[1] && !reversed[2];
}

IndexOrder lps_order_of(const std::array<double, 9>& d) {
  // Greedy on the largest |direction| entries: row r is the LPS axis, column c the stored axis.
  IndexOrder o;
  bool row_used[3] = {false, false, false}, col_used[3] = {false, false, false};
  for (int k = 0; k < 3; ++k) {
    int br = 0, bc = 0;
    double best = -1;
    for (int r = 0; r < 3; ++r) {
      if (row_used[r]) continue;
      for (int c = 0; c < 3; ++c) {
        if (col_used[c]) continue;
        const double v = std::abs(d[r * 3 + c]);
        if (v > best) best = v, br = r, bc = c;
      }
    }
    row_used[br] = col_used[bc] = true;
    o.axis[static_cast<std::size_t>(br)] = bc;
    o.reversed[static_cast<std::size_t>(br)] = d[br * 3 + bc] < 0;
  }
  return o;
}

Grid grid_of(const Volume& v) {
  Grid g;
  g.dims = v.dims;
  g.spacing = v.spacing;
  g.origin = v.origin;
  g.direction = v.direction;
  return g;
}

Volume to_lps_order(const Volume& stored) {
  const IndexOrder order = lps_order_of(stored.direction);
  const Grid g = detail::grid_in_lps_order(grid_of(stored), order);
  Volume v;
  v.dims = g.dims;
  v.spacing = g.spacing;
  v.origin = g.origin;
  v.direction = g.direction;
  if (order.identity()) {
    v.hu = stored.hu;
    return v;
  }
  v.hu.resize(stored.hu.size());
  const float* src = stored.hu.data();
  float* dst = v.hu.data();
  detail::for_each_lattice_voxel(stored.dims, order, [&](std::int64_t l, std::int64_t s) { dst[l] = src[s]; });
  return v;
}

Input prepare_input(Volume stored, const InputOptions& opt, const std::string& source) {
  validate_volume(stored, source);
  Input in;
  in.source = source;
  in.downsample = opt.downsample;
  in.roi = {{0, 0, 0}, stored.dims};
  if (opt.roi) {
    const Box& r = *opt.roi;
    const int d[3] = {stored.dims.x, stored.dims.y, stored.dims.z};
    const int lo[3] = {r.lo.x, r.lo.y, r.lo.z}, hi[3] = {r.hi.x, r.hi.y, r.hi.z};
    for (int a = 0; a < 3; ++a)
      if (lo[a] < 0 || hi[a] > d[a] || lo[a] >= hi[a])
        throw Error("roi " + std::to_string(r.lo.x) + "," + std::to_string(r.lo.y) + "," + std::to_string(r.lo.z) +
                    "," + std::to_string(r.hi.x) + "," + std::to_string(r.hi.y) + "," + std::to_string(r.hi.z) +
                    ": file axis " + std::to_string(a) + " range [" + std::to_string(lo[a]) + ", " +
                    std::to_string(hi[a]) + ") must satisfy 0 <= lo < hi <= " + std::to_string(d[a]) +
                    " (voxel indices of " + source + " as stored, upper bound exclusive)");
    stored = crop(stored, r.lo, r.hi);
    in.roi = r;
  }
  const int f = opt.downsample;
  const int mind = std::min({stored.dims.x, stored.dims.y, stored.dims.z});
  if (f < 1 || f > mind)
    throw Error("downsample factor " + std::to_string(f) + " is out of range [1, " + std::to_string(mind) +
                "] (the smallest dimension of " + source + (opt.roi ? " after the roi crop" : "") + ")");
  in.left_out = {stored.dims.x % f, stored.dims.y % f, stored.dims.z % f};
  in.order = lps_order_of(stored.direction);
  if (f > 1) {
    const Volume coarse = downsample(stored, f);
    in.lattice_grid = grid_of(coarse);
    in.lattice = to_lps_order(coarse);
  } else {
    in.lattice_grid = grid_of(stored);
    in.lattice = to_lps_order(stored);
  }
  in.lattice.body = find_body(in.lattice);  // SPEC §3: on the lattice grid, whatever the source
  in.lattice.body_method = kBodyMethod;
  in.stored = std::move(stored);
  return in;
}

bool is_supported_volume_extension(const std::string& path) {
  return detail::format_of(path) != detail::Format::Unknown;
}

std::string volume_extension_for(const std::string& input) {
  std::error_code ec;
  if (!input.empty() && !std::filesystem::is_directory(input, ec)) {
    const detail::Format f = detail::format_of(input);
    if (f != detail::Format::Unknown) return detail::extension_of(f);
  }
  return ".nrrd";
}

}  // namespace hpcm::io
