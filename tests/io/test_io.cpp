// Tests of the ITK IO layer (issue 4): reading the real CT data, reorientation to LPS, writer
// round trips, the displacement field export (sign, mm scale), inverse-mapping resampling,
// and one clear error for each kind of bad input.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>

#include "hpcm/io.hpp"
#include "io/io_detail.hpp"

namespace fs = std::filesystem;
using namespace hpcm;

namespace {

const std::string kData = HPCM_SHARED_DATA;
const std::string kNifti = kData + "/abdomen-ct/abdomen_ct.nii.gz";
const std::string kDicom = kData + "/abdomen-ct-dicom";

#define SKIP_WITHOUT(path)                                                                      \
  if (!fs::exists(path)) GTEST_SKIP() << "test data " << (path) << " is absent (../shared/data)"

// A fresh scratch folder per test.
struct Scratch {
  fs::path dir;
  Scratch() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir = fs::temp_directory_path() /
          ("hpcm_io_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" + std::to_string(getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() { fs::remove_all(dir); }
  std::string operator/(const std::string& name) const { return (dir / name).string(); }
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("NOT hpcm::Error: ") + e.what();
  }
  return "NO ERROR";
}

// One line, names the path, contains `what`.
void expect_error(const std::function<void()>& f, const std::string& path, const std::string& what) {
  const std::string msg = error_of(f);
  EXPECT_NE(msg.find(what), std::string::npos) << "message: " << msg;
  EXPECT_NE(msg.find(path), std::string::npos) << "message does not name " << path << ": " << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << "message is not one line: " << msg;
}

// Hand-written NRRD (attached or detached) so that tests control every header field.
void write_nrrd(const std::string& path, const std::string& type, const std::vector<int>& sizes,
                const std::string& extra_header, const void* data, std::size_t bytes, bool detached = false) {
  std::ofstream f(path, std::ios::binary);
  f << "NRRD0004\ntype: " << type << "\ndimension: " << sizes.size() << "\nsizes:";
  for (int s : sizes) f << ' ' << s;
  f << "\nendian: little\nencoding: raw\n" << extra_header;
  if (detached) {
    const std::string raw = path + ".raw";
    f << "data file: " << fs::path(raw).filename().string() << "\n";
    std::ofstream r(raw, std::ios::binary);
    r.write(static_cast<const char*>(data), std::streamsize(bytes));
  } else {
    f << "\n";
    f.write(static_cast<const char*>(data), std::streamsize(bytes));
  }
}

Volume make_volume(Int3 d, bool integral, unsigned seed = 7) {
  Volume v;
  v.dims = d;
  v.spacing = {0.7, 1.3, 2.5};
  v.origin = {-12.5, 30.25, 7.0};
  const double c = std::cos(0.15), s = std::sin(0.15);  // slightly oblique, still LPS-ordered
  v.direction = {c, -s, 0, s, c, 0, 0, 0, 1};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1100.0f, 1500.0f);
  v.hu.resize(v.size());
  for (float& h : v.hu) h = integral ? std::round(u(rng)) : u(rng);
  return v;
}

Model model_from(const Volume& v) {
  Model m;
  m.dims = v.dims;
  m.spacing = v.spacing;
  m.origin = v.origin;
  m.direction = v.direction;
  m.hu = v.hu;
  TissueThresholds t;
  m.tissue.resize(v.size());
  for (std::size_t i = 0; i < v.size(); ++i) m.tissue[i] = static_cast<std::uint8_t>(t.classify(v.hu[i]));
  set_body(m, v.body, v.body_method);
  return m;
}

// An Input around a synthetic stored volume (no file), and the model of its lattice.
io::Input input_of(const Volume& stored, int f = 1, std::optional<io::Box> roi = {}) {
  io::InputOptions opt;
  opt.downsample = f;
  opt.roi = roi;
  return io::prepare_input(stored, opt, "synthetic");
}

/// The rest state's displacements (u = 0): what the exports take.
std::vector<Vec3> rest_positions(const Model& m) { return std::vector<Vec3>(static_cast<std::size_t>(m.size())); }

void expect_same_geometry(const Volume& a, const Volume& b, double tol) {
  EXPECT_EQ(a.dims, b.dims);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.spacing[k], b.spacing[k], tol) << "spacing " << k;
    EXPECT_NEAR(a.origin[k], b.origin[k], tol * 10) << "origin " << k;
  }
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(a.direction[k], b.direction[k], tol) << "direction " << k;
}

// Continuous index of physical point p in volume v.
std::array<double, 3> physical_to_index(const Volume& v, const std::array<double, 3>& p) {
  std::array<double, 9> a{};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) a[r * 3 + c] = v.direction[r * 3 + c] * v.spacing[c];
  const auto inv = io::detail::mat_inverse(a);
  const double d[3] = {p[0] - v.origin[0], p[1] - v.origin[1], p[2] - v.origin[2]};
  return {inv[0] * d[0] + inv[1] * d[1] + inv[2] * d[2], inv[3] * d[0] + inv[4] * d[1] + inv[5] * d[2],
          inv[6] * d[0] + inv[7] * d[1] + inv[8] * d[2]};
}

// Every voxel of the raw (file-order) image appears in the LPS-ordered volume at the same
// physical position with the same value.
void expect_same_physical_content(const io::detail::RawImage& raw, const Volume& v) {
  const auto& g = raw.geometry;
  Volume rv;  // raw geometry as a Volume, for index_to_physical
  rv.dims = g.dims;
  rv.spacing = g.spacing;
  rv.origin = g.origin;
  rv.direction = g.direction;
  int mismatches = 0;
  for (int k = 0; k < g.dims.z; k += std::max(1, g.dims.z / 7))
    for (int j = 0; j < g.dims.y; j += std::max(1, g.dims.y / 7))
      for (int i = 0; i < g.dims.x; i += std::max(1, g.dims.x / 7)) {
        const auto q = physical_to_index(v, rv.index_to_physical(i, j, k));
        const int x = int(std::lround(q[0])), y = int(std::lround(q[1])), z = int(std::lround(q[2]));
        ASSERT_NEAR(q[0], x, 1e-3);
        ASSERT_NEAR(q[1], y, 1e-3);
        ASSERT_NEAR(q[2], z, 1e-3);
        const float raw_value = raw.data[i + std::size_t(g.dims.x) * (j + std::size_t(g.dims.y) * k)];
        if (v.at(x, y, z) != raw_value) ++mismatches;
      }
  EXPECT_EQ(mismatches, 0);
}

// Direction columns run along +L, +P, +S (LPS index order): positive diagonal dominates.
void expect_lps_order(const Volume& v) {
  for (int a = 0; a < 3; ++a) {
    EXPECT_GT(v.direction[a * 3 + a], 0.7) << "axis " << a;
  }
}

}  // namespace

// ---- real data ---------------------------------------------------------------------------

TEST(RealData, AbdomenNiftiReadsWithGeometryAndHU) {
  SKIP_WITHOUT(kNifti);
  const Volume v = io::read_volume(kNifti);
  EXPECT_EQ(v.dims, (Int3{122, 101, 112}));
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(v.spacing[a], 3.0, 1e-4);
  const auto [lo, hi] = std::minmax_element(v.hu.begin(), v.hu.end());
  EXPECT_EQ(*lo, -1207.0f);
  EXPECT_EQ(*hi, 3382.0f);
  expect_lps_order(v);
  // The file is RAS-stored: reorientation flips x and y; the physical content is unchanged.
  const auto raw = io::detail::read_raw_image(kNifti);
  EXPECT_LT(raw.geometry.direction[0], 0) << "expected a RAS-stored file (ITK direction -1 on x)";
  expect_same_physical_content(raw, v);
}

TEST(RealData, DicomSeriesJpeg2000ReadsAsHU) {
  SKIP_WITHOUT(kDicom);
  const auto series = io::list_dicom_series(kDicom);
  ASSERT_EQ(series.size(), 1u);
  std::cout << "series uid: '" << series[0].uid << "'\n";
  EXPECT_EQ(series[0].modality, "CT");
  EXPECT_EQ(series[0].files, 20);
  const Volume v = io::read_volume(kDicom);
  EXPECT_EQ(v.dims, (Int3{512, 512, 20}));
  EXPECT_NEAR(v.spacing[0], 0.977, 1e-3);
  EXPECT_NEAR(v.spacing[1], 0.977, 1e-3);
  // Slice thickness is 3 mm but the slices overlap: ImagePositionPatient steps by 2 mm, and
  // the spacing comes from the positions.
  EXPECT_NEAR(v.spacing[2], 2.0, 1e-3);
  expect_lps_order(v);
  const auto [lo, hi] = std::minmax_element(v.hu.begin(), v.hu.end());
  // Stored values are >= 0 and RescaleIntercept is -1024: the darkest voxel is exactly -1024 HU
  // (decoded JPEG-2000 + intercept), and values stay within the 12-bit CT range.
  EXPECT_EQ(*lo, -1024.0f);
  EXPECT_LE(*hi, 3071.0f);
  EXPECT_GT(*hi, 500.0f) << "no bone: decoding failed?";
  for (std::size_t i = 0; i < v.hu.size(); i += 997) ASSERT_EQ(v.hu[i], std::round(v.hu[i]));
  // Air inside the field of view is near -1000 HU, soft tissue near 0..100: the median of the
  // central slice lies in the body or air, never near the raw stored value range (> 0 for air).
  std::size_t air = 0;
  for (float h : v.hu) air += (h < -900.0f);
  EXPECT_GT(air, v.hu.size() / 10);
}

TEST(RealData, DicomSeriesSortedByPosition) {
  SKIP_WITHOUT(kDicom);
  const Volume v = io::read_volume(kDicom);
  // z runs inferior -> superior with uniform 3 mm steps: positive direction on S.
  EXPECT_GT(v.direction[8], 0.99);
}

// ---- reorientation -------------------------------------------------------------------------

TEST(Reorient, PermutedAndFlippedNrrdBecomesLpsOrdered) {
  Scratch s;
  // Index axis 0 runs right (-L) at 2 mm, axis 1 runs superior at 3 mm, axis 2 posterior at 1.5 mm.
  const std::vector<int> sizes = {4, 3, 5};
  std::vector<float> data(4 * 3 * 5);
  for (std::size_t i = 0; i < data.size(); ++i) data[i] = float(i) * 10.0f - 300.0f;
  const std::string path = s / "perm.nhdr";
  write_nrrd(path, "float", sizes,
             "space: left-posterior-superior\nspace directions: (-2,0,0) (0,0,3) (0,1.5,0)\n"
             "kinds: domain domain domain\nspace origin: (10,20,30)\n",
             data.data(), data.size() * 4, true);
  const Volume v = io::read_volume(path);
  EXPECT_EQ(v.dims, (Int3{4, 5, 3}));
  EXPECT_NEAR(v.spacing[0], 2.0, 1e-9);
  EXPECT_NEAR(v.spacing[1], 1.5, 1e-9);
  EXPECT_NEAR(v.spacing[2], 3.0, 1e-9);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(v.direction[r * 3 + c], r == c ? 1.0 : 0.0, 1e-12);
  EXPECT_NEAR(v.origin[0], 10.0 - 2.0 * 3, 1e-9);  // the leftmost voxel was the last on axis 0
  EXPECT_NEAR(v.origin[1], 20.0, 1e-9);
  EXPECT_NEAR(v.origin[2], 30.0, 1e-9);
  expect_same_physical_content(io::detail::read_raw_image(path), v);
  // Spot check: file voxel (3,0,0) (value data[3]) is LPS voxel (0,0,0).
  EXPECT_EQ(v.at(0, 0, 0), data[3]);
}

// ---- writers -------------------------------------------------------------------------------

class RoundTrip : public ::testing::TestWithParam<std::string> {};

TEST_P(RoundTrip, GeometryAndValuesSurviveEachWriter) {
  Scratch s;
  for (bool integral : {false, true}) {
    const Volume v = make_volume({7, 5, 4}, integral);
    const std::string path = s / ("vol_" + std::to_string(integral) + GetParam());
    io::write_volume(v, path);
    const Volume r = io::read_volume(path);
    expect_same_geometry(v, r, 1e-5);
    ASSERT_EQ(r.hu.size(), v.hu.size());
    for (std::size_t i = 0; i < v.hu.size(); ++i) ASSERT_EQ(r.hu[i], v.hu[i]) << "voxel " << i;
    const auto raw = io::detail::read_raw_image(path);
    EXPECT_EQ(raw.component_type, integral ? "short" : "float");
  }
  for (const auto& e : fs::directory_iterator(s.dir))
    EXPECT_EQ(e.path().filename().string().rfind(".hpcm-tmp", 0), std::string::npos) << "temporary left behind";
}

INSTANTIATE_TEST_SUITE_P(Formats, RoundTrip, ::testing::Values(".nii", ".nii.gz", ".nrrd", ".nhdr", ".mha", ".mhd"),
                         [](const auto& info) {
                           std::string n = info.param.substr(1);
                           for (char& c : n)
                             if (c == '.') c = '_';
                           return n;
                         });

TEST(Writer, OverwriteIsAtomicAndUnknownExtensionRejected) {
  Scratch s;
  const Volume a = make_volume({6, 6, 6}, true, 1), b = make_volume({6, 6, 6}, true, 2);
  io::write_volume(a, s / "x.nrrd");
  io::write_volume(b, s / "x.nrrd");
  EXPECT_EQ(io::read_volume(s / "x.nrrd").hu, b.hu);
  expect_error([&] { io::write_volume(a, s / "x.png"); }, s / "x.png", "unsupported extension");
  expect_error([&] { io::write_volume(a, s / "missing/x.nii"); }, "missing", "does not exist");
}

// ---- exports -------------------------------------------------------------------------------

TEST(Export, DisplacementFieldSignAndMillimetres) {
  Scratch s;
  Volume v = make_volume({6, 5, 4}, true);
  v.spacing = {2.0, 3.0, 4.0};
  v.origin = {-5, 7, 11};
  v.direction = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const io::Input in = input_of(v);
  const Model m = model_from(in.lattice);
  std::vector<Vec3> pos = rest_positions(m);
  // Known synthetic deformation: element (x,y,z) moves by (0.5, -1.0 - 0.1 z, 0.25 x) lattice units
  // (anterior is -y: the y component pulls towards the front).
  for (Index i = 0; i < m.size(); ++i) {
    const Int3 c = m.coords(i);
    pos[i] = pos[i] + Vec3{0.5f, -1.0f - 0.1f * c.z, 0.25f * c.x};
  }
  for (const std::string ext : {".nii.gz", ".nii", ".nrrd"}) {
    const std::string path = s / ("disp" + ext);
    io::write_displacement_field(in, m, pos, path);
    const auto raw = io::detail::read_raw_image(path);
    EXPECT_EQ(raw.components, 3) << ext;
    EXPECT_EQ(raw.component_type, "float") << ext;
    EXPECT_EQ(raw.geometry.dims, m.dims) << ext;
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(raw.geometry.spacing[a], m.spacing[a], 1e-6) << ext;
      EXPECT_NEAR(raw.geometry.origin[a], m.origin[a], 1e-5) << ext;
    }
    ASSERT_EQ(raw.data.size(), std::size_t(m.size()) * 3);
    for (Index i = 0; i < m.size(); ++i) {
      const Int3 c = m.coords(i);
      ASSERT_NEAR(raw.data[3 * i + 0], 0.5 * 2.0, 1e-5) << ext;                 // +L, mm
      ASSERT_NEAR(raw.data[3 * i + 1], (-1.0 - 0.1 * c.z) * 3.0, 1e-5) << ext;  // anterior: negative P
      ASSERT_NEAR(raw.data[3 * i + 2], 0.25 * c.x * 4.0, 1e-5) << ext;
    }
  }
  // 3D Slicer reads the NRRD key telling that the field moves rest positions (modeling).
  std::ifstream nrrd(s / "disp.nrrd", std::ios::binary);
  std::string header(2000, '\0');
  nrrd.read(header.data(), std::streamsize(header.size()));
  EXPECT_NE(header.find("\ndisplacement field type:=modeling\n"), std::string::npos) << header.substr(0, 600);
  expect_error([&] { io::write_displacement_field(in, m, pos, s / "disp.nhdr"); }, "disp.nhdr", "unsupported extension");
  pos.pop_back();
  EXPECT_NE(error_of([&] { io::write_displacement_field(in, m, pos, s / "short.nrrd"); }).find("displacements"), std::string::npos);
  // A model that is not this input's lattice is refused, naming both sizes.
  const Model other = model_from(make_volume({5, 5, 4}, true));
  const std::string msg = error_of([&] { io::write_displacement_field(in, other, rest_positions(other), s / "x.nrrd"); });
  EXPECT_NE(msg.find("5x5x4"), std::string::npos) << msg;
  EXPECT_NE(msg.find("6x5x4"), std::string::npos) << msg;
}

// A stored volume whose index order is not LPS: axis 0 runs right (-L), axis 1 superior, axis 2
// posterior. Every export must come back in exactly this order and geometry.
Volume permuted_stored_volume(Int3 dims) {
  Volume v = make_volume(dims, true, 11);
  v.spacing = {2.0, 3.0, 1.5};
  v.origin = {10, 20, 30};
  v.direction = {-1, 0, 0, /**/ 0, 0, 1, /**/ 0, 1, 0};
  return v;
}

TEST(Export, PermutedInputExportsComeBackInItsOwnOrder) {
  Scratch s;
  const Volume stored = permuted_stored_volume({9, 7, 11});
  for (int f : {1, 2, 3}) {
    SCOPED_TRACE("f = " + std::to_string(f));
    const io::Input in = input_of(stored, f);
    EXPECT_EQ(in.order.axis, (std::array<int, 3>{0, 2, 1}));
    EXPECT_EQ(in.order.reversed, (std::array<bool, 3>{true, false, false}));
    EXPECT_EQ(in.lattice.dims, (Int3{9 / f, 11 / f, 7 / f}));
    EXPECT_EQ(in.left_out, (Int3{9 % f, 7 % f, 11 % f}));
    // The lattice grid is the stored grid coarsened by f in the stored order, computed here
    // independently: downsample the stored volume itself.
    const Volume coarse = f == 1 ? stored : downsample(stored, f);
    const Model m = model_from(in.lattice);
    io::write_label_map(in, m, s / "labels.nrrd");
    const auto raw = io::detail::read_raw_image(s / "labels.nrrd");
    Volume rv;
    rv.dims = raw.geometry.dims;
    rv.spacing = raw.geometry.spacing;
    rv.origin = raw.geometry.origin;
    rv.direction = raw.geometry.direction;
    rv.hu.assign(raw.data.size(), 0);
    expect_same_geometry(coarse, rv, 1e-9);
    const TissueThresholds t;
    // Outside the body (SPEC §3) the label is "outside"; the body keeps its class.
    Index outside = 0;
    for (std::size_t i = 0; i < coarse.hu.size(); ++i) {
      if (raw.data[i] == float(io::kOutsideLabel)) {
        ++outside;
        continue;
      }
      ASSERT_EQ(raw.data[i], float(static_cast<int>(t.classify(coarse.hu[i])))) << "stored voxel " << i;
    }
    EXPECT_EQ(outside, m.body.outside_air + m.body.outside_objects);
    // A rigid shift of the lattice: the same physical vector everywhere, on the coarse grid.
    std::vector<Vec3> pos = rest_positions(m);
    for (auto& p : pos) p = p + Vec3{0.5f, -1.0f, 0.25f};
    const std::vector<float> u = io::displacement_on_input_grid(in, m, pos);
    ASSERT_EQ(u.size(), coarse.hu.size() * 3);
    const double expect[3] = {0.5 * in.lattice.spacing[0] * in.lattice.direction[0],
                              -1.0 * in.lattice.spacing[1] * in.lattice.direction[4],
                              0.25 * in.lattice.spacing[2] * in.lattice.direction[8]};
    for (std::size_t i = 0; i < coarse.hu.size(); ++i)
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(u[3 * i + c], expect[c], 1e-5);
    // Undeformed: the deformed CT is the stored volume itself, voxel for voxel.
    io::write_deformed_volume(in, m, rest_positions(m), s / "deformed.nii.gz");
    const auto d = io::detail::read_raw_image(s / "deformed.nii.gz");
    EXPECT_EQ(d.geometry.dims, stored.dims);
    ASSERT_EQ(d.data.size(), stored.hu.size());
    for (std::size_t i = 0; i < stored.hu.size(); ++i) ASSERT_EQ(d.data[i], stored.hu[i]) << "stored voxel " << i;
  }
}

TEST(Export, RoiTakesTheStoredIndices) {
  const Volume stored = permuted_stored_volume({9, 7, 11});
  const io::Input in = input_of(stored, 1, io::Box{{1, 2, 3}, {8, 6, 10}});
  EXPECT_EQ(in.stored.dims, (Int3{7, 4, 7}));
  for (int k = 0; k < 7; ++k)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 7; ++i) ASSERT_EQ(in.stored.at(i, j, k), stored.at(i + 1, j + 2, k + 3));
  const auto o = stored.index_to_physical(1, 2, 3);
  for (int a = 0; a < 3; ++a) EXPECT_NEAR(in.stored.origin[a], o[a], 1e-9);
  const std::string msg = error_of([&] { input_of(stored, 1, io::Box{{0, 0, 0}, {10, 7, 11}}); });
  EXPECT_NE(msg.find("file axis 0"), std::string::npos) << msg;
  EXPECT_NE(msg.find("<= 9"), std::string::npos) << msg;
  EXPECT_NE(error_of([&] { input_of(stored, 8); }).find("downsample factor 8 is out of range [1, 7]"), std::string::npos);
}

TEST(Export, UndeformedLatticeResamplesToTheInputExactly) {
  Scratch s;
  const Volume v = make_volume({13, 11, 9}, false);
  for (int f : {1, 2, 3}) {
    const Volume lat = f == 1 ? v : downsample(v, f);
    const Model m = model_from(lat);
    const auto out = io::detail::resample_deformed(v, m, rest_positions(m));
    ASSERT_EQ(out.size(), v.hu.size());
    for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], v.hu[i]) << "f=" << f << " voxel " << i;
  }
  // Through the writer, in the input's format and geometry.
  const Model m = model_from(downsample(v, 2));
  io::write_deformed_volume(v, m, rest_positions(m), s / "deformed.mha");
  const Volume r = io::read_volume(s / "deformed.mha");
  expect_same_geometry(v, r, 1e-6);
  EXPECT_EQ(r.hu, v.hu);
}

TEST(Export, DeformedVolumeFollowsTheDisplacement) {
  const Volume v = make_volume({12, 10, 8}, false);
  const Model m = model_from(v);
  // Uniform translation by +1 lattice unit along x: out(x) = in(x - 1); x = 0 comes from
  // outside the input and is air.
  std::vector<Vec3> pos = rest_positions(m);
  for (auto& p : pos) p.x += 1.0f;
  auto out = io::detail::resample_deformed(v, m, pos);
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 10; ++y) {
      EXPECT_EQ(out[v.index(0, y, z)], io::detail::kAirHU);
      for (int x = 1; x < 12; ++x) ASSERT_NEAR(out[v.index(x, y, z)], v.at(x - 1, y, z), 1e-3);
    }
  // Half a voxel: trilinear between the two rest neighbours.
  pos = rest_positions(m);
  for (auto& p : pos) p.y -= 0.5f;  // anterior
  out = io::detail::resample_deformed(v, m, pos);
  for (int x = 0; x < 12; ++x)
    for (int y = 0; y < 9; ++y) ASSERT_NEAR(out[v.index(x, y, 3)], 0.5f * (v.at(x, y, 3) + v.at(x, y + 1, 3)), 1e-2);
  // Non-uniform: a smooth bump; the fixed point solves x = X + u(X) (checked by forward map).
  pos = rest_positions(m);
  for (Index i = 0; i < m.size(); ++i) {
    const Int3 c = m.coords(i);
    pos[i].y -= 0.8f * std::exp(-0.1f * float((c.x - 6) * (c.x - 6) + (c.z - 4) * (c.z - 4)));
  }
  io::InverseMappingStats st;
  out = io::detail::resample_deformed(v, m, pos, io::detail::kInverseMappingIterations,
                                      io::detail::kInverseMappingNewtonIterations, &st);
  for (float h : out) ASSERT_TRUE(std::isfinite(h));
  EXPECT_EQ(st.voxels, static_cast<Index>(v.size()));
  EXPECT_EQ(st.unconverged, 0);
  EXPECT_LE(st.max_residual_mm, st.tolerance_mm);
  EXPECT_EQ(st.tolerance_mm, io::kInverseMappingToleranceMm);
}

// ---- integrity of exports: the field's Jacobian, the inverse mapping's residual ----------

// u(p) = G (p - c) in millimetres on every voxel of grid g: the map p -> p + u has Jacobian I + G.
std::vector<float> affine_field(const io::Grid& g, const std::array<double, 9>& G) {
  std::vector<float> u(3 * g.size());
  std::size_t k = 0;
  for (int z = 0; z < g.dims.z; ++z)
    for (int y = 0; y < g.dims.y; ++y)
      for (int x = 0; x < g.dims.x; ++x, ++k) {
        const double q[3] = {double(x), double(y), double(z)};
        double p[3];
        for (int r = 0; r < 3; ++r) {
          p[r] = g.origin[r];
          for (int a = 0; a < 3; ++a) p[r] += g.direction[r * 3 + a] * g.spacing[a] * q[a];
        }
        for (int r = 0; r < 3; ++r) u[3 * k + r] = float(G[r * 3] * p[0] + G[r * 3 + 1] * p[1] + G[r * 3 + 2] * p[2]);
      }
  return u;
}

TEST(ExportIntegrity, JacobianOfKnownFieldsOnAnyGrid) {
  io::Grid g;
  g.dims = {7, 6, 5};
  g.spacing = {2.0, 3.0, 0.5};
  g.origin = {-40, 12, 100};
  // A stored order that is not LPS and reflected (det -1): the physical Jacobian must not care.
  g.direction = {-1, 0, 0, /**/ 0, 0, 1, /**/ 0, 1, 0};
  const std::int64_t cells = 6 * 5 * 4;
  io::FieldJacobianStats st = io::displacement_jacobian(g, std::vector<float>(3 * g.size(), 0.0f));
  EXPECT_EQ(st.cells, cells);
  EXPECT_EQ(st.folded_cells, 0);
  EXPECT_NEAR(st.min_det, 1.0, 1e-12);
  // Stretch and shear: det(I + G) = 1.3 * 0.8 * 1.1 (upper triangular) everywhere.
  const std::array<double, 9> stretch = {0.3, 0.2, -0.1, /**/ 0, -0.2, 0.4, /**/ 0, 0, 0.1};
  st = io::displacement_jacobian(g, affine_field(g, stretch));
  EXPECT_EQ(st.folded_cells, 0);
  EXPECT_NEAR(st.min_det, 1.3 * 0.8 * 1.1, 1e-4);
  // A mirror along x (I + G = diag(-1, 1, 1)) turns every cell inside out.
  const std::array<double, 9> mirror = {-2, 0, 0, /**/ 0, 0, 0, /**/ 0, 0, 0};
  st = io::displacement_jacobian(g, affine_field(g, mirror));
  EXPECT_EQ(st.folded_cells, cells);
  EXPECT_NEAR(st.min_det, -1.0, 1e-4);
  // A grid without cells (an axis of one voxel) checks nothing and says so.
  g.dims = {7, 6, 1};
  EXPECT_EQ(io::displacement_jacobian(g, std::vector<float>(3 * g.size(), 0.0f)).cells, 0);
  EXPECT_NE(error_of([&] { io::displacement_jacobian(g, std::vector<float>(5, 0.0f)); }).find("5 values"), std::string::npos);
}

// A fold planted in the positions (the solver never makes one): the export is written, and its
// integrity figures and problems say which files are affected. `hpcm run --strict` exits
// non-zero exactly when export_problems() is not empty.
TEST(ExportIntegrity, FoldedPositionsAreReportedAndNamed) {
  Scratch s;
  Volume v = make_volume({10, 9, 8}, true);
  const io::Input in = input_of(v);
  const Model m = model_from(in.lattice);

  const io::ExportFiles clean = io::export_frame(in, m, rest_positions(m), s.dir.string(), "rest", true);
  EXPECT_TRUE(clean.integrity.clean());
  EXPECT_EQ(clean.integrity.field.cells, 9 * 8 * 7);
  EXPECT_EQ(clean.integrity.deformed.voxels, static_cast<Index>(v.size()));
  EXPECT_TRUE(io::export_problems(clean).empty());

  std::vector<Vec3> pos = rest_positions(m);
  pos[m.index(5, 4, 4)].x += 2.5f;  // past its +x neighbour: the cells around it turn inside out
  const io::ExportFiles f = io::export_frame(in, m, pos, s.dir.string(), "folded", true);
  EXPECT_TRUE(fs::exists(f.displacement_nifti) && fs::exists(f.displacement_nrrd) && fs::exists(f.deformed));
  EXPECT_FALSE(f.integrity.fold_free());
  EXPECT_FALSE(f.integrity.clean());
  EXPECT_GT(f.integrity.field.folded_cells, 0);
  EXPECT_LE(f.integrity.field.folded_cells, 8);  // only the 8 cells around the moved element
  EXPECT_LT(f.integrity.field.min_det, 0.0);
  const Int3 at = f.integrity.field.min_det_cell;  // one of the 8 cells that share element (5,4,4)
  EXPECT_TRUE(at.x >= 4 && at.x <= 5 && at.y >= 3 && at.y <= 4 && at.z >= 3 && at.z <= 4)
      << at.x << "," << at.y << "," << at.z;
  const std::vector<std::string> problems = io::export_problems(f);
  ASSERT_FALSE(problems.empty());
  EXPECT_NE(problems[0].find("displacement_folded.nii.gz and displacement_folded.nrrd: the displacement field folds"),
            std::string::npos)
      << problems[0];
  EXPECT_NE(problems[0].find("of 504 cells"), std::string::npos) << problems[0];
}

// An inverse mapping that cannot converge in the iterations allowed is counted, with its residual.
TEST(ExportIntegrity, UnconvergedInverseMappingIsCounted) {
  const Volume v = make_volume({12, 10, 8}, false);
  const Model m = model_from(v);
  // A compression along x about the middle: u(X) = -0.9 (X - 5.5), |du/dX| = 0.9 (det 0.1,
  // not folded). The fixed-point iteration contracts by only 0.9 per step: 12 steps leave
  // 0.9^12 = 28 % of the error; Newton's method solves it at once.
  std::vector<Vec3> pos = rest_positions(m);
  for (Index i = 0; i < m.size(); ++i) pos[i].x -= 0.9f * (float(m.coords(i).x) - 5.5f);
  io::InverseMappingStats st;
  io::detail::resample_deformed(v, m, pos, io::detail::kInverseMappingIterations, 0, &st);
  EXPECT_GT(st.unconverged, 0);
  EXPECT_GT(st.max_residual_mm, st.tolerance_mm);
  EXPECT_EQ(st.max_iterations, io::detail::kInverseMappingIterations);
  EXPECT_TRUE(st.worst_voxel.x >= 0 && st.worst_voxel.x < 12 && st.worst_voxel.y >= 0 && st.worst_voxel.y < 10 &&
              st.worst_voxel.z >= 0 && st.worst_voxel.z < 8);
  EXPECT_EQ(st.newton_iterations, 0);
  io::ExportFiles f;
  f.deformed = "/somewhere/deformed_final.nrrd";
  f.integrity.deformed = st;
  const std::vector<std::string> problems = io::export_problems(f);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("deformed_final.nrrd: the inverse mapping did not converge for " +
                             std::to_string(st.unconverged) + " of " + std::to_string(v.size()) + " voxels"),
            std::string::npos)
      << problems[0];
  EXPECT_NE(problems[0].find("at voxel " + std::to_string(st.worst_voxel.x) + "," + std::to_string(st.worst_voxel.y) +
                             "," + std::to_string(st.worst_voxel.z)),
            std::string::npos)
      << problems[0];
  // With the Newton steps the export allows it converges.
  io::detail::resample_deformed(v, m, pos, io::detail::kInverseMappingIterations,
                                io::detail::kInverseMappingNewtonIterations, &st);
  EXPECT_EQ(st.unconverged, 0) << "largest residual " << st.max_residual_mm << " mm";
}

TEST(Export, LabelMapWithSlicerColourTable) {
  Scratch s;
  const io::Input in = input_of(make_volume({8, 7, 6}, true));
  const Model m = model_from(in.lattice);
  io::write_label_map(in, m, s / "labels.nii.gz");
  const auto raw = io::detail::read_raw_image(s / "labels.nii.gz");
  EXPECT_EQ(raw.component_type, "unsigned_char");
  ASSERT_EQ(raw.data.size(), m.tissue.size());
  for (std::size_t i = 0; i < m.tissue.size(); ++i)
    ASSERT_EQ(raw.data[i], m.counted(static_cast<Index>(i)) ? float(m.tissue[i]) : float(io::kOutsideLabel));
  std::ifstream ct(s / "labels.ctbl");
  ASSERT_TRUE(ct.good());
  std::string line;
  int entries = 0;
  while (std::getline(ct, line))
    if (!line.empty() && line[0] != '#') {
      std::istringstream ls(line);
      int idx, r, g, b, a;
      std::string name;
      ASSERT_TRUE(bool(ls >> idx >> name >> r >> g >> b >> a)) << line;
      EXPECT_EQ(idx, entries);
      EXPECT_EQ(name, idx == io::kOutsideLabel ? std::string("outside") : std::string(tissue_name(idx)));
      ++entries;
    }
  EXPECT_EQ(entries, kTissueCount + 1);  // the classes and "outside" (SPEC §3)
}

// ---- bad input (issue 4, item 6) -----------------------------------------------------------

TEST(BadInput, MissingFile) {
  expect_error([] { io::read_volume("/nonexistent/ct.nii.gz"); }, "/nonexistent/ct.nii.gz", "no such file");
}

TEST(BadInput, UnknownFormat) {
  Scratch s;
  std::ofstream(s / "hostname") << "myhost\n";
  expect_error([&] { io::read_volume(s / "hostname"); }, s / "hostname", "unknown volume format");
}

TEST(BadInput, TruncatedAndCorruptFiles) {
  Scratch s;
  const Volume v = make_volume({20, 20, 20}, false);
  for (const std::string ext : {".nii.gz", ".nii", ".nrrd", ".mha"}) {
    const std::string path = s / ("t" + ext);
    io::write_volume(v, path);
    fs::resize_file(path, fs::file_size(path) / 2);
    expect_error([&] { io::read_volume(path); }, path, "corrupt");
  }
  // Garbage with a volume extension.
  std::ofstream(s / "garbage.nii", std::ios::binary) << std::string(600, 'x');
  expect_error([&] { io::read_volume(s / "garbage.nii"); }, s / "garbage.nii", "NIfTI");
  std::ofstream(s / "empty.nrrd", std::ios::binary).flush();
  expect_error([&] { io::read_volume(s / "empty.nrrd"); }, s / "empty.nrrd", "empty file");
  // NRRD header whose raw data is too short.
  const float few[10] = {};
  write_nrrd(s / "short.nrrd", "float", {8, 8, 8}, "", few, sizeof few);
  expect_error([&] { io::read_volume(s / "short.nrrd"); }, s / "short.nrrd", "corrupt");
}

TEST(BadInput, TwoDimensionalImage) {
  Scratch s;
  std::vector<short> d(16 * 16, 5);
  write_nrrd(s / "slice.nrrd", "short", {16, 16}, "", d.data(), d.size() * 2);
  expect_error([&] { io::read_volume(s / "slice.nrrd"); }, s / "slice.nrrd", "2-D image");
  write_nrrd(s / "flat.nrrd", "short", {16, 16, 1}, "", d.data(), d.size() * 2);
  expect_error([&] { io::read_volume(s / "flat.nrrd"); }, s / "flat.nrrd", "2-D image");
}

TEST(BadInput, VectorAndRgbImages) {
  Scratch s;
  std::vector<float> d(3 * 4 * 4 * 4, 1.0f);
  write_nrrd(s / "vec.nrrd", "float", {3, 4, 4, 4}, "kinds: vector domain domain domain\n", d.data(), d.size() * 4);
  expect_error([&] { io::read_volume(s / "vec.nrrd"); }, s / "vec.nrrd", "3 components");
  std::vector<unsigned char> rgb(3 * 4 * 4 * 4, 9);
  write_nrrd(s / "rgb.nrrd", "uchar", {3, 4, 4, 4}, "kinds: RGB-color domain domain domain\n", rgb.data(), rgb.size());
  expect_error([&] { io::read_volume(s / "rgb.nrrd"); }, s / "rgb.nrrd", "components");
  // An exported displacement field is not a CT.
  const io::Input in = input_of(make_volume({4, 4, 4}, true));
  const Model m = model_from(in.lattice);
  io::write_displacement_field(in, m, rest_positions(m), s / "field.nii.gz");
  expect_error([&] { io::read_volume(s / "field.nii.gz"); }, s / "field.nii.gz", "components");
}

TEST(BadInput, EmptyDirectoryAndDirectoryWithoutDicom) {
  Scratch s;
  fs::create_directories(s / "empty");
  expect_error([&] { io::read_volume(s / "empty"); }, s / "empty", "empty directory");
  fs::create_directories(s / "text");
  std::ofstream(s / "text/a.txt") << "not dicom\n";
  std::ofstream(s / "text/b.dcm") << std::string(300, '\0');
  expect_error([&] { io::read_volume(s / "text"); }, s / "text", "no DICOM image files");
}

namespace {
// Copies the real series into `dir`, replacing the first occurrence of `from` by `to` in the
// first `count` files (all when count < 0) and `from` by `to2` in the others.
void copy_patched(const std::string& dir, const std::string& from, const std::string& to, int count,
                  const std::string& to2 = "") {
  fs::create_directories(dir);
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(kDicom)) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  int n = 0;
  for (const auto& p : files) {
    std::ifstream in(p, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const bool first = count < 0 || n < count;
    if (first || !to2.empty()) {
      const auto at = bytes.find(from);
      ASSERT_NE(at, std::string::npos);
      bytes.replace(at, from.size(), first ? to : to2);
    }
    std::ofstream(fs::path(dir) / p.filename(), std::ios::binary) << bytes;
    ++n;
  }
}
// Explicit VR little endian element header: tag (group, element), VR, 16-bit length.
std::string element(std::uint16_t g, std::uint16_t e, const char* vr, std::uint16_t len) {
  const char b[8] = {char(g & 0xff), char(g >> 8), char(e & 0xff), char(e >> 8), vr[0], vr[1], char(len & 0xff), char(len >> 8)};
  return std::string(b, 8);
}
}  // namespace

TEST(BadInput, DicomDirectoryWithoutCT) {
  SKIP_WITHOUT(kDicom);
  Scratch s;
  // Modality (0008,0060) "CT" -> "MR".
  copy_patched(s / "mr", element(0x0008, 0x0060, "CS", 2) + "CT", element(0x0008, 0x0060, "CS", 2) + "MR", -1);
  expect_error([&] { io::read_volume(s / "mr"); }, s / "mr", "no CT series");
}

TEST(BadInput, SeveralSeriesNeedSeriesOption) {
  SKIP_WITHOUT(kDicom);
  Scratch s;
  // The anonymised files have an empty SeriesInstanceUID (0020,000E): give 8 files one UID
  // and the other 12 another (the element is at the top level, so its length may change).
  const std::string empty_uid = element(0x0020, 0x000e, "UI", 0);
  copy_patched(s / "two", empty_uid, element(0x0020, 0x000e, "UI", 6) + std::string("1.2.3\0", 6), 8,
               element(0x0020, 0x000e, "UI", 6) + std::string("1.2.4\0", 6));
  const auto list = io::list_dicom_series(s / "two");
  ASSERT_EQ(list.size(), 2u);
  const std::string msg = error_of([&] { io::read_volume(s / "two"); });
  EXPECT_NE(msg.find("2 CT series; choose one with --series"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1.2.3 (CT, 8 slices"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1.2.4 (CT, 12 slices"), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos);
  io::ReadOptions ro;
  ro.series_uid = "1.2.3";
  EXPECT_EQ(io::read_volume(s / "two", ro).dims, (Int3{512, 512, 8}));
  ro.series_uid = "1.2.4";
  EXPECT_EQ(io::read_volume(s / "two", ro).dims, (Int3{512, 512, 12}));
  ro.series_uid = "1.2.5";
  expect_error([&] { io::read_volume(s / "two", ro); }, s / "two", "no series with --series 1.2.5");
}

TEST(BadInput, NonFiniteValues) {
  Scratch s;
  std::vector<float> d(4 * 4 * 4, 0.0f);
  d[21] = std::nanf("");
  d[40] = INFINITY;
  write_nrrd(s / "nan.nrrd", "float", {4, 4, 4}, "", d.data(), d.size() * 4);
  expect_error([&] { io::read_volume(s / "nan.nrrd"); }, s / "nan.nrrd", "2 non-finite values");
}

TEST(BadInput, TooLargeForMemoryCheckedBeforeAllocating) {
  Scratch s;
  const float tiny[4] = {};
  write_nrrd(s / "huge.nhdr", "short", {100000, 100000, 100000}, "", tiny, sizeof tiny, true);
  const std::string msg = error_of([&] { io::read_volume(s / "huge.nhdr"); });
  EXPECT_NE(msg.find("too large"), std::string::npos) << msg;
  EXPECT_NE(msg.find("bytes"), std::string::npos) << msg;
  EXPECT_NE(msg.find("14000000000000000"), std::string::npos) << "the bytes needed: " << msg;
}

TEST(BadInput, DownsampleFactorLargerThanADimension) {
  const Volume v = make_volume({9, 8, 5}, true);
  const std::string msg = error_of([&] { downsample(v, 6); });
  EXPECT_NE(msg.find("6"), std::string::npos) << msg;
  EXPECT_NE(msg.find("[1, 5]"), std::string::npos) << msg;
}

TEST(BadInput, SingleDicomFileAndSeriesOnAFile) {
  SKIP_WITHOUT(kDicom);
  const std::string one = (*fs::directory_iterator(kDicom)).path().string();
  expect_error([&] { io::read_volume(one); }, one, "give the directory");
  io::ReadOptions ro;
  ro.series_uid = "1.2";
  SKIP_WITHOUT(kNifti);
  expect_error([&] { io::read_volume(kNifti, ro); }, kNifti, "--series applies only");
}

// ---- deformed labels and the pull-back field (issue 32): one inverse mapping for all -------

TEST(DeformedLabels, TranslationMovesLabelsClassesAndPullbackTogether) {
  const Volume v = make_volume({12, 10, 8}, true);  // slightly oblique, LPS-ordered
  const io::Input in = input_of(v);
  const Model m = model_from(in.lattice);
  io::LabelMap map;
  map.source = "synthetic labels";
  map.grid = io::grid_of(v);
  map.component_type = "short";
  map.bytes = 2;
  map.data.resize(v.size() * 2);
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 10; ++y)
      for (int x = 0; x < 12; ++x) {
        const std::int16_t label = static_cast<std::int16_t>(-(1000 * z + 100 * y + x + 1));  // distinct, signed
        std::memcpy(map.data.data() + 2 * v.index(x, y, z), &label, 2);
      }
  // Every element moved by +1 lattice unit along x: voxel x shows what was at x - 1.
  std::vector<Vec3> pos = rest_positions(m);
  for (auto& p : pos) p.x += 1.0f;
  const io::DeformedOnInputGrid d = io::deform_on_input_grid(in, m, pos, {map});
  ASSERT_EQ(d.labels.size(), 1u);
  EXPECT_EQ(d.stats.unconverged, 0);
  EXPECT_EQ(d.hu, io::detail::resample_deformed(v, m, pos));  // the same inverse mapping
  const auto label_at = [](const io::LabelMap& l, std::size_t i) {
    std::int16_t value;
    std::memcpy(&value, l.data.data() + 2 * i, 2);
    return value;
  };
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 10; ++y)
      for (int x = 0; x < 12; ++x) {
        const std::size_t i = static_cast<std::size_t>(v.index(x, y, z));
        const std::size_t from = static_cast<std::size_t>(v.index(x - 1, y, z));
        ASSERT_EQ(label_at(d.labels[0], i), x == 0 ? 0 : label_at(map, from)) << x << "," << y << "," << z;
        ASSERT_EQ(d.classes[i], x == 0 ? 0 : m.tissue[from]) << x << "," << y << "," << z;
        // Pull-back: one voxel back along index axis x, in millimetres.
        for (int r = 0; r < 3; ++r)
          ASSERT_NEAR(d.pullback_mm[3 * i + r], -v.direction[r * 3] * v.spacing[0], 1e-4) << r;
      }
}

TEST(DeformedLabels, LabelMapsKeepTypeAndGridThroughEveryFormat) {
  Scratch s;
  const Volume v = make_volume({7, 5, 4}, true);
  io::LabelMap map;
  map.grid = io::grid_of(v);
  map.component_type = "unsigned_int";
  map.bytes = 4;
  map.data.resize(v.size() * 4);
  for (std::size_t i = 0; i < v.size(); ++i) {
    const std::uint32_t label = 4000000000u - static_cast<std::uint32_t>(i);
    std::memcpy(map.data.data() + 4 * i, &label, 4);
  }
  for (const char* ext : {".nii.gz", ".nrrd", ".mha"}) {
    const std::string path = s / (std::string("labels") + ext);
    io::write_label_values(map, path);
    const io::LabelMap back = io::read_label_map(path);
    EXPECT_EQ(back.component_type, "unsigned_int") << ext;
    EXPECT_EQ(back.data, map.data) << ext;
    EXPECT_EQ(back.grid.dims, map.grid.dims) << ext;
    const io::Input in = input_of(v);
    EXPECT_NO_THROW(io::label_map_on_input_grid(back, in)) << ext;
  }
  // A grid 0.01 mm away is another grid: refused, naming the map, the input and both grids.
  io::LabelMap shifted = map;
  shifted.source = "shifted.nii.gz";
  shifted.grid.origin[1] += 0.01;
  const std::string msg = error_of([&] { io::label_map_on_input_grid(shifted, input_of(v)); });
  EXPECT_NE(msg.find("shifted.nii.gz"), std::string::npos) << msg;
  EXPECT_NE(msg.find("synthetic"), std::string::npos) << msg;
  EXPECT_NE(msg.find("label map 7x5x4 voxels"), std::string::npos) << msg;
  EXPECT_NE(msg.find("input 7x5x4 voxels"), std::string::npos) << msg;
  // Float voxels are not labels.
  const std::string floats = s / "float.nii.gz";
  Volume f = v;
  f.hu[0] = 0.5f;
  io::write_volume(f, floats);
  expect_error([&] { io::read_label_map(floats); }, floats, "integer type");
}

// Every integer type ITK names, through every format a label map is written in: the voxels come
// back bit for bit (all bytes of each voxel differ), with the type's size and signedness and the
// grid; a byte count that does not match the type is refused before anything is written.
TEST(DeformedLabels, EveryIntegerTypeRoundTripsBitForBitThroughEveryFormat) {
  Scratch s;
  const Volume v = make_volume({6, 5, 3}, true);
  const std::pair<const char*, int> types[] = {{"unsigned_char", 1}, {"char", 1}, {"unsigned_short", 2},
                                               {"short", 2}, {"unsigned_int", 4}, {"int", 4},
                                               {"unsigned_long", 8}, {"long", 8}, {"unsigned_long_long", 8},
                                               {"long_long", 8}};
  for (const auto& [type, bytes] : types) {
    io::LabelMap map;
    map.grid = io::grid_of(v);
    map.component_type = type;
    map.bytes = bytes;
    map.data.resize(v.size() * bytes);
    for (std::size_t i = 0; i < map.data.size(); ++i) map.data[i] = static_cast<unsigned char>(i * 37 + i / 7 + 11);
    for (const char* ext : {".nii", ".nii.gz", ".nrrd", ".nhdr", ".mha", ".mhd"}) {
      const std::string path = s / (std::string("labels_") + type + "_" + (ext + 1) + ext);  // .nhdr and .mhd: own .raw
      io::write_label_values(map, path);
      const io::LabelMap back = io::read_label_map(path);
      const std::string name = std::string(type) + " " + ext;
      EXPECT_EQ(back.bytes, bytes) << name;
      EXPECT_EQ(back.component_type.rfind("unsigned", 0) == 0, std::string(type).rfind("unsigned", 0) == 0)
          << name << " came back as " << back.component_type;
      EXPECT_EQ(back.data, map.data) << name;
      EXPECT_EQ(back.grid.dims, map.grid.dims) << name;
      for (int a = 0; a < 3; ++a) {
        EXPECT_NEAR(back.grid.spacing[a], map.grid.spacing[a], 1e-6) << name;
        EXPECT_NEAR(back.grid.origin[a], map.grid.origin[a], 1e-4) << name;
      }
      for (int k = 0; k < 9; ++k) EXPECT_NEAR(back.grid.direction[k], map.grid.direction[k], 1e-6) << name;
    }
  }
  io::LabelMap wrong;
  wrong.grid = io::grid_of(v);
  wrong.component_type = "short";
  wrong.bytes = 4;
  wrong.data.resize(v.size() * 4);
  const std::string path = s / "wrong_bytes.nrrd";
  expect_error([&] { io::write_label_values(wrong, path); }, path, "4 bytes per voxel, but short has 2");
  EXPECT_FALSE(std::filesystem::exists(path));
}

// SPEC §3: the body on the lattice with ITK's filters. A box of tissue with an air-filled
// cavity lies on a table slab, joined to it by a one-element bridge; noisy air around them.
TEST(Body, FindsTheBodyCutsThinContactsAndFillsHoles) {
  Volume v;
  v.dims = {30, 30, 20};
  v.hu.assign(v.size(), -1000.0f);
  std::mt19937 rng(3);
  std::normal_distribution<float> noise(0.0f, 30.0f);
  for (float& h : v.hu) h += noise(rng);
  auto set = [&](Int3 lo, Int3 hi, float hu) {
    for (int z = lo.z; z < hi.z; ++z)
      for (int y = lo.y; y < hi.y; ++y)
        for (int x = lo.x; x < hi.x; ++x) v.hu[static_cast<std::size_t>(v.index(x, y, z))] = hu;
  };
  set({5, 4, 3}, {25, 20, 17}, 40.0f);     // the body
  set({10, 9, 8}, {15, 14, 12}, -900.0f);  // gas inside it (a hole to fill)
  set({2, 23, 0}, {28, 27, 20}, 600.0f);   // the table, 3 elements below the body
  set({15, 20, 10}, {16, 23, 11}, 40.0f);  // a one-element bridge between them
  const std::vector<std::uint8_t> body = io::find_body(v);
  ASSERT_EQ(body.size(), v.size());
  // The opening cuts the bridge and the table off and rounds the box's edges (a ball of radius
  // 2 does not fit into them); what it took within its radius of the body comes back: the
  // edges and the first two elements of the bridge. Nothing else is body.
  Index inside = 0;
  for (Index i = 0; i < static_cast<Index>(v.size()); ++i) {
    const int x = static_cast<int>(i % 30), y = static_cast<int>(i / 30 % 30), z = static_cast<int>(i / 900);
    const bool in_box = x >= 5 && x < 25 && y >= 4 && y < 20 && z >= 3 && z < 17;
    const bool near_bridge = x == 15 && z == 10 && (y == 20 || y == 21);
    const bool in_body = body[static_cast<std::size_t>(i)] != 0;
    inside += in_body;
    ASSERT_EQ(in_body, in_box || near_bridge) << "element " << x << "," << y << "," << z;
  }
  EXPECT_EQ(inside, 20 * 16 * 14 + 2);  // the gas is body (filled); the table and the rest of the bridge are not
  v.body = body;
  v.body_method = io::kBodyMethod;
  const Model m = build_model(v, Params{});
  EXPECT_EQ(m.body.outside_objects, Index{26 * 4 * 20 + 1});  // the table and the bridge's last element: anchored
  EXPECT_TRUE(m.outside_object(m.index(15, 22, 10)));
  EXPECT_TRUE(m.outside_object(m.index(15, 24, 10)));

  Volume air = v;  // nothing dense: no body, everything counted
  air.hu.assign(air.size(), -1000.0f);
  air.body = io::find_body(air);
  EXPECT_EQ(std::count(air.body.begin(), air.body.end(), 1), 0);
  EXPECT_EQ(build_model(air, Params{}).body.search, BodySummary::Search::NoBody);
  // prepare_input gives the lattice its body.
  const io::Input in = input_of(v);
  EXPECT_EQ(in.lattice.body, body);
}
