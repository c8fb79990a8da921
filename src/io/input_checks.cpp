// hpcm's own checks of volume headers and DICOM series geometry (see input_checks.hpp).
#include "input_checks.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "hpcm/types.hpp"

namespace hpcm::io::detail {

namespace {

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

// ---- byte access (memcpy: no alignment or aliasing assumption) ----

template <class T>
T read_as(const unsigned char* p, bool swapped) {
  unsigned char b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swapped) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

}  // namespace

void check_spacing_value(const std::string& path, const std::string& field, double v) {
  if (!std::isfinite(v) || !(v >= kMinSpacingMm && v <= kMaxSpacingMm))
    throw Error(path + ": voxel spacing " + field + " = " + num(v) + " mm is outside the plausible range [" +
                num(kMinSpacingMm) + ", " + num(kMaxSpacingMm) + "] mm");
}

// ---- NIfTI ----------------------------------------------------------------------------------

std::size_t nifti_header_size(const unsigned char* bytes, std::size_t size) {
  if (size < 4) return 0;
  for (bool swapped : {false, true}) {
    const std::int32_t sz = read_as<std::int32_t>(bytes, swapped);
    if (sz == 348 || sz == 540) return static_cast<std::size_t>(sz);
  }
  return 0;
}

NiftiHeader check_nifti_header(const std::string& path, const unsigned char* b, std::size_t size) {
  auto bad = [&](const std::string& what) { throw Error(path + ": invalid NIfTI header: " + what); };
  NiftiHeader h;
  const std::size_t hsize = nifti_header_size(b, size);
  if (hsize == 0) bad("sizeof_hdr is neither 348 (NIfTI-1) nor 540 (NIfTI-2)");
  if (size < hsize) bad("the file ends inside its " + std::to_string(hsize) + "-byte header");
  h.version = hsize == 348 ? 1 : 2;
  h.swapped = read_as<std::int32_t>(b, false) != static_cast<std::int32_t>(hsize);
  const bool sw = h.swapped;
  if (h.version == 1) {
    for (int i = 0; i < 8; ++i) h.dim[i] = read_as<std::int16_t>(b + 40 + 2 * i, sw);
    h.datatype = read_as<std::int16_t>(b + 70, sw);
    h.bitpix = read_as<std::int16_t>(b + 72, sw);
    for (int i = 0; i < 8; ++i) h.pixdim[i] = read_as<float>(b + 76 + 4 * i, sw);
    h.vox_offset = read_as<float>(b + 108, sw);
    h.scl_slope = read_as<float>(b + 112, sw);
    h.scl_inter = read_as<float>(b + 116, sw);
    h.qform_code = read_as<std::int16_t>(b + 252, sw);
    h.sform_code = read_as<std::int16_t>(b + 254, sw);
  } else {
    h.datatype = read_as<std::int16_t>(b + 12, sw);
    h.bitpix = read_as<std::int16_t>(b + 14, sw);
    for (int i = 0; i < 8; ++i) h.dim[i] = read_as<std::int64_t>(b + 16 + 8 * i, sw);
    for (int i = 0; i < 8; ++i) h.pixdim[i] = read_as<double>(b + 104 + 8 * i, sw);
    h.vox_offset = static_cast<double>(read_as<std::int64_t>(b + 168, sw));
    h.scl_slope = read_as<double>(b + 176, sw);
    h.scl_inter = read_as<double>(b + 184, sw);
    h.qform_code = read_as<std::int32_t>(b + 344, sw);
    h.sform_code = read_as<std::int32_t>(b + 348, sw);
  }
  if (h.dim[0] < 1 || h.dim[0] > 7) bad("dim[0] = " + std::to_string(h.dim[0]) + " is outside [1, 7]");
  for (int i = 1; i <= h.dim[0]; ++i)
    if (h.dim[i] < 1) bad("dim[" + std::to_string(i) + "] = " + std::to_string(h.dim[i]) + " must be >= 1");
  // pixdim[1..3] are the voxel spacing; the NIfTI library would turn 0, negative or NaN into 1.
  static const char* axis_name[4] = {"", "x", "y", "z"};
  for (int i = 1; i <= 3 && i <= h.dim[0]; ++i) {
    if (!std::isfinite(h.pixdim[i]) || !(h.pixdim[i] > 0))
      throw Error(path + ": voxel spacing pixdim[" + std::to_string(i) + "] (" + axis_name[i] + ") = " + num(h.pixdim[i]) +
                  " is not a positive number; hpcm does not invent a spacing");
    check_spacing_value(path, "pixdim[" + std::to_string(i) + "] (" + axis_name[i] + ")", h.pixdim[i]);
  }
  if (!std::isfinite(h.vox_offset) || h.vox_offset < 0) bad("vox_offset = " + num(h.vox_offset) + " is not a valid offset");
  // NaN or 0 scl_slope means "no scaling" in NIfTI (nibabel writes NaN); a used slope needs a
  // finite intercept and a plausible size (ITK ignores |slope| < 2.2e-16, nibabel applies it).
  if (std::isinf(h.scl_slope)) bad("scl_slope is infinite");
  if (std::isfinite(h.scl_slope) && h.scl_slope != 0) {
    if (!std::isfinite(h.scl_inter))
      bad("scl_inter = " + num(h.scl_inter) + " is not finite while scl_slope = " + num(h.scl_slope) + " scales the data");
    if (!(std::fabs(h.scl_slope) >= kMinSlope && std::fabs(h.scl_slope) <= kMaxSlope))
      bad("scl_slope = " + num(h.scl_slope) + " is outside the plausible magnitudes [" + num(kMinSlope) + ", " +
          num(kMaxSlope) + "] (0 or NaN: no scaling); HU = slope * value + intercept would be meaningless");
  }
  auto real_at = [&](std::size_t at1, std::size_t at2, int i) {
    return h.version == 1 ? double(read_as<float>(b + at1 + 4 * std::size_t(i), sw))
                          : read_as<double>(b + at2 + 8 * std::size_t(i), sw);
  };
  for (int i = 0; i < 3; ++i) h.quatern[std::size_t(i)] = real_at(256, 352, i);
  for (int i = 0; i < 3; ++i) h.qoffset[std::size_t(i)] = real_at(268, 376, i);
  for (int i = 0; i < 12; ++i) h.srow[std::size_t(i)] = real_at(280, 400, i);
  const std::string origin_range = " is outside [-" + num(kMaxOriginMm) + ", " + num(kMaxOriginMm) + "] mm";
  if (h.qform_code > 0) {
    static const char* qname[3] = {"quatern_b", "quatern_c", "quatern_d"};
    static const char* oname[3] = {"qoffset_x", "qoffset_y", "qoffset_z"};
    double norm2 = 0;
    for (int i = 0; i < 3; ++i) {
      const double q = h.quatern[std::size_t(i)], o = h.qoffset[std::size_t(i)];
      if (!std::isfinite(q)) bad(std::string("qform ") + qname[i] + " = " + num(q) + " is non-finite");
      if (!std::isfinite(o) || std::fabs(o) > kMaxOriginMm) bad(std::string("qform ") + oname[i] + " = " + num(o) + origin_range);
      norm2 += q * q;
    }
    // nibabel refuses b^2+c^2+d^2 > 1 (beyond float32 rounding); the NIfTI library rescales it.
    if (norm2 > 1 + 3 * 1.2e-7)
      bad("qform quatern_b^2 + quatern_c^2 + quatern_d^2 = " + num(norm2) + " is above 1: not a rotation");
  }
  if (h.sform_code > 0) {
    static const char* row_name[3] = {"srow_x", "srow_y", "srow_z"};
    const auto& m = h.srow;
    for (int i = 0; i < 12; ++i)
      if (!std::isfinite(m[std::size_t(i)]))
        bad("sform " + std::string(row_name[i / 4]) + "[" + std::to_string(i % 4) + "] = " + num(m[std::size_t(i)]) +
            " is non-finite");
    for (int r = 0; r < 3; ++r)
      if (std::fabs(m[std::size_t(4 * r + 3)]) > kMaxOriginMm)
        bad("sform translation " + std::string(row_name[r]) + "[3] = " + num(m[std::size_t(4 * r + 3)]) + origin_range);
    for (int c = 0; c < 3; ++c) {
      const double len = std::sqrt(m[std::size_t(c)] * m[std::size_t(c)] + m[std::size_t(4 + c)] * m[std::size_t(4 + c)] +
                                   m[std::size_t(8 + c)] * m[std::size_t(8 + c)]);
      if (!(len > 0)) bad("sform column " + std::to_string(c) + " is zero: no voxel spacing along that axis");
      check_spacing_value(path, "sform column " + std::to_string(c) + " length", len);
    }
  }
  return h;
}

void NonFiniteScan::element(const unsigned char* e) {
  bool finite = true;
  if (size_ == 4) finite = std::isfinite(read_as<float>(e, swapped_));
  if (size_ == 8) finite = std::isfinite(read_as<double>(e, swapped_));
  if (!finite && bad_++ == 0) first_ = index_;
  ++index_;
}

void NonFiniteScan::feed(const unsigned char* data, std::size_t n) {
  if (size_ != 4 && size_ != 8) return;
  const std::size_t es = static_cast<std::size_t>(size_);
  std::size_t i = 0;
  if (carried_ > 0) {  // complete the element split across the previous chunk's end
    const std::size_t take = std::min(es - static_cast<std::size_t>(carried_), n);
    std::memcpy(carry_ + carried_, data, take);
    carried_ += static_cast<int>(take);
    i = take;
    if (static_cast<std::size_t>(carried_) < es) return;
    element(carry_);
    carried_ = 0;
  }
  for (; i + es <= n; i += es) element(data + i);
  std::memcpy(carry_, data + i, n - i);  // fewer than es bytes left
  carried_ = static_cast<int>(n - i);
}

NiftiAffine nifti_affine_used(const NiftiHeader& h) {
  if (h.sform_code > 0) return NiftiAffine::Sform;
  if (h.qform_code > 0) return NiftiAffine::Qform;
  return NiftiAffine::Pixdim;
}

std::array<double, 12> nifti_affine(const NiftiHeader& h, NiftiAffine which) {
  if (which == NiftiAffine::Sform) return h.srow;
  std::array<double, 12> m{};
  if (which == NiftiAffine::Pixdim) {
    // nibabel's fallback (shape_zoom_affine): Analyze's x flip, the grid centred on the origin.
    for (int a = 0; a < 3; ++a) {
      const double zoom = (a == 0 ? -1.0 : 1.0) * (h.dim[0] > a ? h.pixdim[std::size_t(a + 1)] : 1.0);
      const double n = h.dim[0] > a ? double(h.dim[std::size_t(a + 1)]) : 1.0;
      m[std::size_t(5 * a)] = zoom;
      m[std::size_t(4 * a + 3)] = -(n - 1) / 2 * zoom;
    }
    return m;
  }
  // The NIfTI-1 quaternion (nifti_quatern_to_mat44): rotation R, then the qfac flip of k.
  const double b = h.quatern[0], c = h.quatern[1], d = h.quatern[2];
  const double a = std::sqrt(std::max(0.0, 1.0 - (b * b + c * c + d * d)));
  const double r[9] = {a * a + b * b - c * c - d * d, 2 * (b * c - a * d),         2 * (b * d + a * c),
                       2 * (b * c + a * d),         a * a + c * c - b * b - d * d, 2 * (c * d - a * b),
                       2 * (b * d - a * c),         2 * (c * d + a * b),         a * a + d * d - c * c - b * b};
  const double qfac = h.pixdim[0] < 0 ? -1.0 : 1.0;
  const double step[3] = {h.pixdim[1], h.pixdim[2], qfac * h.pixdim[3]};
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) m[std::size_t(4 * row + col)] = r[3 * row + col] * step[col];
    m[std::size_t(4 * row + 3)] = h.qoffset[std::size_t(row)];
  }
  return m;
}

double nifti_affine_distance(const NiftiHeader& h, const std::array<double, 12>& a, const std::array<double, 12>& b) {
  double worst = 0;
  for (int corner = 0; corner < 8; ++corner) {
    double ijk[3];
    for (int k = 0; k < 3; ++k) ijk[k] = (corner >> k & 1) ? double(std::max<std::int64_t>(h.dim[std::size_t(k + 1)] - 1, 0)) : 0.0;
    double d2 = 0;
    for (int row = 0; row < 3; ++row) {
      double pa = a[std::size_t(4 * row + 3)], pb = b[std::size_t(4 * row + 3)];
      for (int k = 0; k < 3; ++k) {
        pa += a[std::size_t(4 * row + k)] * ijk[k];
        pb += b[std::size_t(4 * row + k)] * ijk[k];
      }
      d2 += (pa - pb) * (pa - pb);
    }
    worst = std::max(worst, std::sqrt(d2));
  }
  return worst;
}

Geometry nifti_geometry(const std::string& path, const NiftiHeader& h) {
  const NiftiAffine which = nifti_affine_used(h);
  const std::array<double, 12> m = nifti_affine(h, which);
  Geometry g;
  g.dims = {int(h.dim[1]), int(h.dim[2]), int(h.dim[3])};
  // RAS -> LPS: the first two rows change sign.
  static const double flip[3] = {-1, -1, 1};
  std::array<double, 3> col[3];
  for (int c = 0; c < 3; ++c) {
    double len2 = 0;
    for (int row = 0; row < 3; ++row) len2 += m[std::size_t(4 * row + c)] * m[std::size_t(4 * row + c)];
    g.spacing[std::size_t(c)] = std::sqrt(len2);
    for (int row = 0; row < 3; ++row) col[c][std::size_t(row)] = flip[row] * m[std::size_t(4 * row + c)] / g.spacing[std::size_t(c)];
  }
  for (int row = 0; row < 3; ++row) g.origin[std::size_t(row)] = flip[row] * m[std::size_t(4 * row + 3)];
  // A sheared sform has no spacing/direction form: refuse rather than drop the shear.
  static const char* pair[3] = {"0 and 1", "0 and 2", "1 and 2"};
  const int ci[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (int p = 0; p < 3; ++p) {
    const auto& u = col[ci[p][0]];
    const auto& v = col[ci[p][1]];
    const double cosine = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    if (std::fabs(cosine) > 1e-3)
      throw Error(path + ": invalid NIfTI header: sform columns " + pair[p] + " are not orthogonal (cosine " + num(cosine) +
                  "): a sheared grid, which hpcm cannot represent");
  }
  for (int row = 0; row < 3; ++row)
    for (int c = 0; c < 3; ++c) g.direction[std::size_t(3 * row + c)] = col[c][std::size_t(row)];
  return g;
}

std::string nifti_geometry_source(const NiftiHeader& h) {
  switch (nifti_affine_used(h)) {
    case NiftiAffine::Sform: {
      std::string s = "sform (sform_code " + std::to_string(h.sform_code);
      if (h.qform_code > 0 &&
          nifti_affine_distance(h, nifti_affine(h, NiftiAffine::Sform), nifti_affine(h, NiftiAffine::Qform)) > 1e-3)
        s += "; the qform differs";
      return s + ")";
    }
    case NiftiAffine::Qform: return "qform (qform_code " + std::to_string(h.qform_code) + ")";
    default: return "pixdim (qform_code and sform_code 0)";
  }
}

// ---- text headers ---------------------------------------------------------------------------

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// Whitespace-separated numbers; false when a token is not a whole number text.
bool parse_numbers(const std::string& text, std::vector<double>& out) {
  std::istringstream in(text);
  std::string tok;
  while (in >> tok) {
    char* end = nullptr;
    const double v = std::strtod(tok.c_str(), &end);
    if (end == tok.c_str() || *end != '\0') return false;
    out.push_back(v);
  }
  return true;
}

std::string shorten(const std::string& s) { return s.size() > 60 ? s.substr(0, 57) + "..." : s; }

}  // namespace

void check_metaimage_header(const std::string& path, const std::string& text) {
  std::istringstream in(text);
  std::string line;
  long long ndims = -1;
  std::vector<double> spacing, size;
  bool have_spacing = false, have_size = false;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = lower(trim(line.substr(0, eq))), value = trim(line.substr(eq + 1));
    std::vector<double> v;
    const auto numbers = [&](const char* name) {
      if (!parse_numbers(value, v))
        throw Error(path + ": MetaImage header: " + name + " = " + shorten(value) + " is not a list of numbers");
      for (double x : v)
        if (!std::isfinite(x)) throw Error(path + ": MetaImage header: " + name + " = " + shorten(value) + " holds a non-finite value");
    };
    if (key == "ndims") {
      numbers("NDims");
      if (v.size() != 1 || v[0] < 1 || v[0] > 16 || v[0] != std::floor(v[0]))
        throw Error(path + ": MetaImage header: NDims = " + shorten(value) + " is not an integer in [1, 16]");
      ndims = static_cast<long long>(v[0]);
    } else if (key == "dimsize") {
      numbers("DimSize");
      for (double x : v)
        if (!(x >= 1) || x != std::floor(x)) throw Error(path + ": MetaImage header: DimSize = " + shorten(value) + " must hold integers >= 1");
    } else if (key == "elementspacing" || key == "elementsize") {
      // ITK uses ElementSpacing, else ElementSize: both must be usable spacings when present.
      const char* name = key == "elementspacing" ? "ElementSpacing" : "ElementSize";
      if (!parse_numbers(value, v))
        throw Error(path + ": MetaImage header: " + name + " = " + shorten(value) + " is not a list of numbers");
      for (std::size_t a = 0; a < v.size(); ++a)
        if (!std::isfinite(v[a]) || !(v[a] > 0))
          throw Error(path + ": voxel spacing " + name + "[" + std::to_string(a) + "] = " + num(v[a]) +
                      " is not a positive number; hpcm does not invent a spacing");
        else
          check_spacing_value(path, name + ("[" + std::to_string(a) + "]"), v[a]);
      if (key == "elementspacing" || !have_spacing) spacing = v;
      have_spacing = true;
    } else if (key == "offset" || key == "position" || key == "origin") {
      numbers("Offset");
    } else if (key == "transformmatrix" || key == "rotation" || key == "orientation") {
      numbers("TransformMatrix");
    } else if (key == "elementdatafile") {
      break;
    }
    if (key == "dimsize") {
      size = v;
      have_size = true;
    }
  }
  if (ndims > 0 && have_size && static_cast<long long>(size.size()) != ndims)
    throw Error(path + ": MetaImage header: DimSize has " + std::to_string(size.size()) + " values for NDims = " +
                std::to_string(ndims));
  if (ndims > 0 && have_spacing && static_cast<long long>(spacing.size()) < std::min<long long>(ndims, 3))
    throw Error(path + ": MetaImage header: ElementSpacing has " + std::to_string(spacing.size()) + " values for NDims = " +
                std::to_string(ndims));
}

namespace {

/// "(1,0,0) (0,2,0) none" -> one entry per axis; an empty vector for "none".
bool parse_nrrd_vectors(const std::string& value, std::vector<std::vector<double>>& out) {
  std::size_t i = 0;
  while (i < value.size()) {
    if (std::isspace(static_cast<unsigned char>(value[i]))) {
      ++i;
      continue;
    }
    if (value.compare(i, 4, "none") == 0) {
      out.emplace_back();
      i += 4;
      continue;
    }
    if (value[i] != '(') return false;
    const auto close = value.find(')', i);
    if (close == std::string::npos) return false;
    std::string inner = value.substr(i + 1, close - i - 1);
    std::replace(inner.begin(), inner.end(), ',', ' ');
    std::vector<double> v;
    if (!parse_numbers(inner, v) || v.empty()) return false;
    out.push_back(v);
    i = close + 1;
  }
  return true;
}

}  // namespace

void check_nrrd_header(const std::string& path, const std::string& text) {
  std::istringstream in(text);
  std::string line;
  if (!std::getline(in, line) || line.rfind("NRRD", 0) != 0) throw Error(path + ": not a NRRD file (no NRRD magic line)");
  long long dimension = -1;
  std::vector<double> sizes, spacings;
  std::vector<std::vector<double>> directions;
  bool have_spacings = false, have_directions = false;
  while (std::getline(in, line)) {
    if (trim(line).empty()) break;  // end of the header
    if (line[0] == '#') continue;
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    if (colon + 1 < line.size() && line[colon + 1] == '=') continue;  // key/value pair "key:=value"
    const std::string key = lower(trim(line.substr(0, colon))), value = trim(line.substr(colon + 1));
    if (key == "dimension") {
      std::vector<double> v;
      if (!parse_numbers(value, v) || v.size() != 1 || !(v[0] >= 1 && v[0] <= 16) || v[0] != std::floor(v[0]))
        throw Error(path + ": NRRD header: dimension: " + shorten(value) + " is not an integer in [1, 16]");
      dimension = static_cast<long long>(v[0]);
    } else if (key == "sizes") {
      if (!parse_numbers(value, sizes)) throw Error(path + ": NRRD header: sizes: " + shorten(value) + " is not a list of integers");
      for (double x : sizes)
        if (!(x >= 1) || x != std::floor(x)) throw Error(path + ": NRRD header: sizes: " + shorten(value) + " must hold integers >= 1");
    } else if (key == "spacings") {
      // "nan" marks a non-spatial axis in NRRD: parse it, judge the spatial axes below.
      if (!parse_numbers(value, spacings)) throw Error(path + ": NRRD header: spacings: " + shorten(value) + " is not a list of numbers");
      have_spacings = true;
    } else if (key == "space directions") {
      if (!parse_nrrd_vectors(value, directions))
        throw Error(path + ": NRRD header: space directions: " + shorten(value) + " is not a list of (x,y,z) vectors or none");
      have_directions = true;
    } else if (key == "space origin") {
      std::vector<std::vector<double>> o;
      if (!parse_nrrd_vectors(value, o) || o.size() != 1 || o[0].empty())
        throw Error(path + ": NRRD header: space origin: " + shorten(value) + " is not one (x,y,z) vector");
      for (double x : o[0])
        if (!std::isfinite(x)) throw Error(path + ": NRRD header: space origin " + shorten(value) + " holds a non-finite value");
    }
  }
  // The spatial axes of a scalar CT are the last three (a vector axis, when present, is first).
  const auto spatial = [&](std::size_t count, std::size_t a) { return count >= 3 && a >= count - 3; };
  if (have_spacings)
    for (std::size_t a = 0; a < spacings.size(); ++a)
      if (spatial(spacings.size(), a)) {
        if (!std::isfinite(spacings[a]) || !(spacings[a] > 0))
          throw Error(path + ": voxel spacing spacings[" + std::to_string(a) + "] = " + num(spacings[a]) +
                      " is not a positive number; hpcm does not invent a spacing");
        check_spacing_value(path, "spacings[" + std::to_string(a) + "]", spacings[a]);
      }
  if (have_directions)
    for (std::size_t a = 0; a < directions.size(); ++a) {
      if (!spatial(directions.size(), a)) continue;
      const auto& d = directions[a];
      double len2 = 0;
      bool finite = !d.empty();
      for (double x : d) {
        finite = finite && std::isfinite(x);
        len2 += x * x;
      }
      if (!finite || !(len2 > 0))
        throw Error(path + ": voxel spacing: space directions of axis " + std::to_string(a) +
                    (d.empty() ? std::string(" is none") : " is not a finite, non-zero vector") +
                    "; hpcm does not invent a spacing");
      check_spacing_value(path, "space directions of axis " + std::to_string(a) + " (length)", std::sqrt(len2));
    }
  if (dimension > 0 && !sizes.empty() && static_cast<long long>(sizes.size()) != dimension)
    throw Error(path + ": NRRD header: sizes has " + std::to_string(sizes.size()) + " values for dimension " +
                std::to_string(dimension));
}

// ---- data files of detached headers ---------------------------------------------------------

std::string metaimage_data_file(const std::string& text, std::string* field) {
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    const auto eq = line.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = trim(line.substr(0, eq));
    if (lower(key) != "elementdatafile") continue;
    if (field) *field = key;
    return trim(line.substr(eq + 1));
  }
  return "";
}

std::string nrrd_data_file(const std::string& text, std::string* field) {
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);  // magic
  while (std::getline(in, line)) {
    if (trim(line).empty()) break;
    const auto colon = line.find(':');
    if (line[0] == '#' || colon == std::string::npos || (colon + 1 < line.size() && line[colon + 1] == '=')) continue;
    const std::string key = trim(line.substr(0, colon));
    if (lower(key) != "data file" && lower(key) != "datafile") continue;
    if (field) *field = key;
    return trim(line.substr(colon + 1));
  }
  return "";
}

namespace {
std::string file_kind(const std::filesystem::file_status& st) {
  namespace fs = std::filesystem;
  if (fs::is_fifo(st)) return "a FIFO";
  if (fs::is_character_file(st) || fs::is_block_file(st)) return "a device";
  if (fs::is_directory(st)) return "a folder";
  return "a socket or other special file";
}
}  // namespace

std::string resolve_data_file(const std::string& header, const std::string& field, const std::string& entry) {
  namespace fs = std::filesystem;
  const std::string sep = lower(field) == "elementdatafile" ? " = " : ": ";
  const std::string named = header + ": " + field + sep + (entry.size() > 200 ? entry.substr(0, 197) + "..." : entry);
  // hpcm reads one data file: no lists (LIST) and no numbered patterns ("slice%03d.raw 1 40 1").
  if (entry.empty() || lower(entry).rfind("list", 0) == 0 || entry.find('%') != std::string::npos)
    throw Error(named + " is not a single file name; hpcm reads one data file per header");
  std::error_code ec;
  const fs::path dir = fs::absolute(fs::path(header), ec).parent_path();
  const fs::path p = fs::path(entry).is_absolute() ? fs::path(entry) : dir / entry;
  const fs::file_status st = fs::status(p, ec);  // follows symbolic links; never opens the file
  if (!fs::exists(st)) throw Error(named + " is missing (no such file: " + p.string() + ")");
  if (!fs::is_regular_file(st))
    throw Error(named + " is not a regular file (" + file_kind(st) + "); hpcm reads volume data only from regular files");
  std::error_code ec_file, ec_dir;
  const fs::path real = fs::canonical(p, ec_file), real_dir = fs::canonical(dir, ec_dir);
  if (ec_file || ec_dir) throw Error(named + ": cannot resolve the path: " + (ec_file ? ec_file : ec_dir).message());
  auto r = real.begin();
  for (auto d = real_dir.begin(); d != real_dir.end(); ++d, ++r)
    if (r == real.end() || *r != *d)
      throw Error(named + " resolves to " + real.string() + ", outside the header's folder " + real_dir.string() +
                  "; hpcm reads data files only beside the header or in its sub-folders");
  return real.string();
}

// ---- DICOM ----------------------------------------------------------------------------------

bool parse_ds(const std::string& text, double* out, std::size_t n) {
  std::size_t k = 0, start = 0;
  while (start <= text.size()) {
    auto end = text.find('\\', start);
    if (end == std::string::npos) end = text.size();
    const std::string tok = trim(text.substr(start, end - start));
    if (k >= n || tok.empty()) return false;
    char* stop = nullptr;
    const double v = std::strtod(tok.c_str(), &stop);
    if (stop == tok.c_str() || *stop != '\0' || !std::isfinite(v)) return false;
    out[k++] = v;
    start = end + 1;
  }
  return k == n;
}

namespace {

struct Placed {
  const DicomSlice* s;
  double along;  // position along the slice normal, mm
};

std::string at_text(const Placed& p) { return p.s->file + " (at " + num(p.along) + " mm)"; }

std::string list_files(const std::vector<std::string>& files, std::size_t show = 4) {
  std::string out;
  for (std::size_t i = 0; i < files.size() && i < show; ++i) out += (i ? ", " : "") + files[i];
  if (files.size() > show) out += " and " + std::to_string(files.size() - show) + " more";
  return out;
}

/// All slices or none carry RescaleIntercept / RescaleSlope: a slice without the intercept of
/// its neighbours (-1024) would be read 1024 HU too bright. Their values may differ (legal
/// DICOM): each slice's own are applied.
void check_rescale_tags(const std::string& pre, const std::vector<DicomSlice>& slices) {
  struct Tag {
    const char* name;
    std::string DicomSlice::*text;
  };
  for (const Tag& t : {Tag{"RescaleIntercept (0028,1052)", &DicomSlice::intercept_text},
                       Tag{"RescaleSlope (0028,1053)", &DicomSlice::slope_text}}) {
    std::vector<std::string> without;
    const DicomSlice* with = nullptr;
    for (const DicomSlice& s : slices) {
      if ((s.*t.text).empty())
        without.push_back(s.file);
      else if (!with)
        with = &s;
    }
    if (with && !without.empty())
      throw Error(pre + list_files(without) + (without.size() == 1 ? " has no " : " have no ") + t.name + " while the other " +
                  std::to_string(slices.size() - without.size()) + " slice(s) have one (" + with->file + ": '" +
                  shorten(with->*t.text) + "'); its values would be read unscaled, hpcm needs every slice of a series to carry the tag");
  }
}

}  // namespace

DicomStack plan_dicom_stack(const std::string& dir, std::vector<DicomSlice> slices, bool keep_first_duplicate) {
  const std::string pre = dir + ": ";
  if (slices.empty()) throw Error(pre + "the series has no image files");
  std::sort(slices.begin(), slices.end(), [](const DicomSlice& a, const DicomSlice& b) { return a.file < b.file; });
  // Every slice must say where it is, how it is oriented and how large its pixels are.
  for (const DicomSlice& s : slices) {
    if (s.frames != 1)
      throw Error(pre + s.file + " is a multi-frame image (" + std::to_string(s.frames) +
                  " frames); hpcm reads series of single-frame slices");
    if (!s.has_position)
      throw Error(pre + s.file + " has " + (s.position_text.empty() ? std::string("no ImagePositionPatient (0020,0032)")
                                                                     : "an unusable ImagePositionPatient '" + shorten(s.position_text) + "'") +
                  "; its place in the stack is unknown");
    if (!s.has_orientation)
      throw Error(pre + s.file + " has " + (s.orientation_text.empty() ? std::string("no ImageOrientationPatient (0020,0037)")
                                                                        : "an unusable ImageOrientationPatient '" + shorten(s.orientation_text) + "'"));
    if (!s.has_spacing || !(s.pixel_spacing[0] > 0) || !(s.pixel_spacing[1] > 0))
      throw Error(pre + s.file + ": PixelSpacing (0028,0030) = " +
                  (s.spacing_text.empty() ? std::string("(missing)") : "'" + shorten(s.spacing_text) + "'") +
                  " is not a positive spacing; hpcm does not invent a spacing");
    for (int i = 0; i < 2; ++i)
      if (!(s.pixel_spacing[i] >= kMinSpacingMm && s.pixel_spacing[i] <= kMaxSpacingMm))
        throw Error(pre + s.file + ": PixelSpacing (0028,0030) = '" + shorten(s.spacing_text) +
                    "' is outside the plausible range [" + num(kMinSpacingMm) + ", " + num(kMaxSpacingMm) + "] mm");
    if (s.rows < 1 || s.columns < 1) throw Error(pre + s.file + " has no image matrix (Rows/Columns)");
  }
  check_rescale_tags(pre, slices);
  // One orientation: unit, orthogonal row and column directions, the same in every slice.
  const DicomSlice& ref = slices.front();
  const auto& o = ref.orientation;
  const double rlen = std::sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
  const double clen = std::sqrt(o[3] * o[3] + o[4] * o[4] + o[5] * o[5]);
  const double dot = o[0] * o[3] + o[1] * o[4] + o[2] * o[5];
  if (std::fabs(rlen - 1) > 1e-2 || std::fabs(clen - 1) > 1e-2 || std::fabs(dot) > 1e-2)
    throw Error(pre + ref.file + ": ImageOrientationPatient '" + shorten(ref.orientation_text) +
                "' is not two orthogonal unit vectors");
  for (const DicomSlice& s : slices) {
    for (int i = 0; i < 6; ++i)
      if (std::fabs(s.orientation[i] - o[i]) > 1e-3)
        throw Error(pre + "mixed slice orientations: " + s.file + " has ImageOrientationPatient '" +
                    shorten(s.orientation_text) + "' but " + ref.file + " has '" + shorten(ref.orientation_text) +
                    "'; hpcm reads one stack of parallel slices");
    if (s.rows != ref.rows || s.columns != ref.columns)
      throw Error(pre + "mixed image sizes: " + s.file + " is " + std::to_string(s.columns) + "x" + std::to_string(s.rows) +
                  " but " + ref.file + " is " + std::to_string(ref.columns) + "x" + std::to_string(ref.rows));
    for (int i = 0; i < 2; ++i)
      if (std::fabs(s.pixel_spacing[i] - ref.pixel_spacing[i]) > 1e-4 * ref.pixel_spacing[i])
        throw Error(pre + "mixed pixel spacings: " + s.file + " has PixelSpacing '" + shorten(s.spacing_text) + "' but " +
                    ref.file + " has '" + shorten(ref.spacing_text) + "'");
  }
  // Orthonormal frame: row direction r, column direction c, normal n = r x c.
  std::array<double, 3> r{o[0] / rlen, o[1] / rlen, o[2] / rlen};
  std::array<double, 3> c{o[3], o[4], o[5]};
  const double rc = r[0] * c[0] + r[1] * c[1] + r[2] * c[2];
  for (int i = 0; i < 3; ++i) c[i] -= rc * r[i];
  const double cl = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  for (double& x : c) x /= cl;
  const std::array<double, 3> n{r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2], r[0] * c[1] - r[1] * c[0]};

  std::vector<Placed> placed;
  for (const DicomSlice& s : slices)
    placed.push_back({&s, s.position[0] * n[0] + s.position[1] * n[1] + s.position[2] * n[2]});
  std::stable_sort(placed.begin(), placed.end(), [](const Placed& a, const Placed& b) { return a.along < b.along; });

  // Same position: closer than 0.1 % of the largest step between neighbours (or 1 um).
  double max_step = 0;
  for (std::size_t i = 1; i < placed.size(); ++i) max_step = std::max(max_step, placed[i].along - placed[i - 1].along);
  const double same = std::max(1e-3, 1e-3 * max_step);
  if (placed.size() > 1 && max_step <= same)
    throw Error(pre + "all " + std::to_string(placed.size()) + " slices are at the same position (" + num(placed[0].along) +
                " mm along the slice normal); the slice spacing cannot be known");
  DicomStack out;
  std::vector<Placed> kept;
  for (std::size_t i = 0; i < placed.size();) {
    std::size_t j = i + 1;
    while (j < placed.size() && placed[j].along - placed[i].along <= same) ++j;
    if (j - i > 1) {
      std::vector<Placed> group(placed.begin() + static_cast<std::ptrdiff_t>(i), placed.begin() + static_cast<std::ptrdiff_t>(j));
      std::sort(group.begin(), group.end(), [](const Placed& a, const Placed& b) {
        return a.s->instance != b.s->instance ? a.s->instance < b.s->instance : a.s->file < b.s->file;
      });
      if (!keep_first_duplicate) {
        std::vector<std::string> names;
        for (const Placed& p : group) names.push_back(p.s->file + " (InstanceNumber " + std::to_string(p.s->instance) + ")");
        std::size_t groups = 0;
        for (std::size_t k = 1; k < placed.size(); ++k) groups += placed[k].along - placed[k - 1].along <= same;
        throw Error(pre + std::to_string(group.size()) + " slices at the same position " + num(placed[i].along) +
                    " mm along the slice normal: " + list_files(names) +
                    (groups > group.size() - 1 ? " (and more positions with duplicates)" : "") +
                    "; pass --dicom-duplicates first to keep the lowest InstanceNumber");
      }
      kept.push_back(group.front());
      for (std::size_t k = 1; k < group.size(); ++k) out.dropped_duplicates.push_back(group[k].s->file);
    } else {
      kept.push_back(placed[i]);
    }
    i = j;
  }
  if (kept.size() < 2)
    throw Error(pre + "a single slice (" + kept.front().s->file + "); a 3-D volume needs at least 2 slices");

  // Even spacing within 1 % of the median step; name the two slices around the first odd step.
  std::vector<double> steps;
  for (std::size_t i = 1; i < kept.size(); ++i) steps.push_back(kept[i].along - kept[i - 1].along);
  std::vector<double> sorted = steps;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (std::size_t i = 0; i < steps.size(); ++i)
    if (std::fabs(steps[i] - median) > 0.01 * median) {
      const double ratio = steps[i] / median;
      std::string why;
      if (ratio > 1.5 && std::fabs(ratio - std::round(ratio)) < 0.05)
        why = " (" + std::to_string(static_cast<long long>(std::round(ratio)) - 1) + " slice(s) missing?)";
      throw Error(pre + "slices are not evenly spaced: " + at_text(kept[i]) + " and " + at_text(kept[i + 1]) + " are " +
                  num(steps[i]) + " mm apart where the series' usual step is " + num(median) + " mm" + why +
                  "; hpcm needs one evenly spaced stack (within 1 %)");
    }
  // All slices on one line along the normal: no in-plane shift (gantry tilt, a moved slice).
  const auto& p0 = kept.front().s->position;
  const double in_plane_tol = std::max(1e-3, 0.01 * std::min(ref.pixel_spacing[0], ref.pixel_spacing[1]));
  for (const Placed& p : kept) {
    double shift2 = 0;
    for (int a = 0; a < 3; ++a) {
      const double d = (p.s->position[a] - p0[a]) - (p.along - kept.front().along) * n[a];
      shift2 += d * d;
    }
    if (std::sqrt(shift2) > in_plane_tol)
      throw Error(pre + p.s->file + " is shifted " + num(std::sqrt(shift2)) + " mm in the slice plane against " +
                  kept.front().s->file + " (gantry tilt or a moved slice); hpcm reads stacks whose slices line up along the normal");
  }

  out.geometry.dims = {ref.columns, ref.rows, static_cast<int>(kept.size())};
  // PixelSpacing is (between rows, between columns): index axis 0 runs along a row.
  out.geometry.spacing = {ref.pixel_spacing[1], ref.pixel_spacing[0],
                          (kept.back().along - kept.front().along) / static_cast<double>(kept.size() - 1)};
  out.geometry.origin = p0;
  for (int a = 0; a < 3; ++a) {
    out.geometry.direction[a * 3 + 0] = r[a];
    out.geometry.direction[a * 3 + 1] = c[a];
    out.geometry.direction[a * 3 + 2] = n[a];
  }
  for (const Placed& p : kept) out.files.push_back(p.s->file);
  return out;
}

}  // namespace hpcm::io::detail
