// Hostile volume input (issue 15): what ITK and the libraries under it would repair silently
// (zero/NaN spacing -> 1 mm, NaN voxels -> 0, a DICOM series averaged into one spacing) is an
// error naming the file; library output never comes before hpcm's own message; two headers
// never share one data file. The DICOM cases here copy, delete, truncate or overwrite slices
// of ../shared/data/abdomen-ct-dicom; tag edits (positions, orientation, spacing) are in
// tests/cli/hostile_cli.sh (pydicom).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <zlib.h>

#include "hpcm/io.hpp"
#include "io/input_checks.hpp"
#include "io/io_detail.hpp"

namespace fs = std::filesystem;
using namespace hpcm;
using namespace hpcm::io::detail;

namespace {

const std::string kDicom = std::string(HPCM_SHARED_DATA) + "/abdomen-ct-dicom";

struct Scratch {
  fs::path dir;
  Scratch() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir = fs::temp_directory_path() /
          ("hpcm_hostile_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" + std::to_string(getpid()));
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

/// The first line names `path` and says `what`.
void expect_error(const std::function<void()>& f, const std::string& path, const std::string& what) {
  const std::string msg = error_of(f);
  const std::string first = msg.substr(0, msg.find('\n'));
  EXPECT_NE(first.find(what), std::string::npos) << "message: " << msg;
  EXPECT_NE(first.find(path), std::string::npos) << "message does not name " << path << ": " << msg;
}

// ---- NIfTI-1 files written byte by byte ------------------------------------------------------

struct NiftiSpec {
  float pixdim[3] = {2, 2, 2};
  float qfac = 1;  // pixdim[0]
  float scl_slope = 1, scl_inter = 0;
  short qform_code = 0, sform_code = 0;
  float quatern[3] = {0, 0, 0};  // quatern_b, c, d
  float qoffset[3] = {0, 0, 0};
  float srow[12] = {2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0};
  std::vector<float> voxels = std::vector<float>(4 * 4 * 4, 40.0f);
  std::vector<std::int16_t> shorts;  // when not empty: int16 data (DT_INT16) instead of voxels
};

std::vector<unsigned char> nifti_bytes(const NiftiSpec& s) {
  std::vector<unsigned char> b(352, 0);
  auto put = [&](std::size_t off, const void* v, std::size_t n) { std::memcpy(b.data() + off, v, n); };
  const std::int32_t hs = 348;
  put(0, &hs, 4);
  const std::int16_t dim[8] = {3, 4, 4, 4, 1, 1, 1, 1};
  put(40, dim, 16);
  const bool int16 = !s.shorts.empty();
  const std::int16_t dt[2] = {std::int16_t(int16 ? 4 : 16), std::int16_t(int16 ? 16 : 32)};
  put(70, dt, 4);
  const float pix[8] = {s.qfac, s.pixdim[0], s.pixdim[1], s.pixdim[2], 1, 1, 1, 1};
  put(76, pix, 32);
  const float vo = 352;
  put(108, &vo, 4);
  put(112, &s.scl_slope, 4);
  put(116, &s.scl_inter, 4);
  put(252, &s.qform_code, 2);
  put(254, &s.sform_code, 2);
  put(256, s.quatern, 12);
  put(268, s.qoffset, 12);
  put(280, s.srow, 48);
  std::memcpy(b.data() + 344, "n+1", 4);
  if (int16) {
    b.resize(352 + s.shorts.size() * 2);
    std::memcpy(b.data() + 352, s.shorts.data(), s.shorts.size() * 2);
  } else {
    b.resize(352 + s.voxels.size() * sizeof(float));
    std::memcpy(b.data() + 352, s.voxels.data(), s.voxels.size() * sizeof(float));
  }
  return b;
}

void write_nifti(const std::string& path, const NiftiSpec& s) {
  const std::vector<unsigned char> b = nifti_bytes(s);
  if (path.size() > 3 && path.compare(path.size() - 3, 3, ".gz") == 0) {
    gzFile gz = gzopen(path.c_str(), "wb");
    gzwrite(gz, b.data(), unsigned(b.size()));
    gzclose(gz);
  } else {
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), std::streamsize(b.size()));
  }
}

void write_text(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

std::string short_data(int n) {
  std::string d(std::size_t(n) * 2, '\0');
  for (int i = 0; i < n; ++i) d[std::size_t(2 * i)] = 40;  // int16 little-endian 40
  return d;
}

}  // namespace

// ---- NIfTI ---------------------------------------------------------------------------------

TEST(HostileNifti, NanAndInfVoxelsAreErrorsNotZero) {
  Scratch s;
  for (const std::string name : {"nan.nii", "nan.nii.gz"}) {
    NiftiSpec spec;
    spec.voxels[21] = std::nanf("");
    write_nifti(s / name, spec);
    expect_error([&] { io::read_volume(s / name); }, s / name, "1 non-finite values (NaN or Inf)");
  }
  NiftiSpec inf;
  inf.voxels[3] = INFINITY;
  inf.voxels[4] = -INFINITY;
  write_nifti(s / "inf.nii", inf);
  expect_error([&] { io::read_volume(s / "inf.nii"); }, s / "inf.nii", "2 non-finite values");
}

TEST(HostileNifti, ZeroNanNegativePixdimAreErrorsNotOneMillimetre) {
  Scratch s;
  const float bad[] = {0.0f, std::nanf(""), -2.0f, INFINITY};
  for (int axis = 0; axis < 3; ++axis)
    for (float v : bad) {
      NiftiSpec spec;
      spec.pixdim[axis] = v;
      write_nifti(s / "p.nii.gz", spec);
      expect_error([&] { io::read_volume(s / "p.nii.gz"); }, s / "p.nii.gz",
                   "pixdim[" + std::to_string(axis + 1) + "]");
    }
}

TEST(HostileNifti, DegenerateSformIsAnError) {
  Scratch s;
  NiftiSpec spec;
  spec.sform_code = 1;
  spec.srow[1 * 4 + 1] = 0;  // column y all zero
  write_nifti(s / "sform.nii", spec);
  expect_error([&] { io::read_volume(s / "sform.nii"); }, s / "sform.nii", "sform column 1 is zero");
  spec.srow[1 * 4 + 1] = std::nanf("");
  write_nifti(s / "sform.nii", spec);
  expect_error([&] { io::read_volume(s / "sform.nii"); }, s / "sform.nii", "non-finite");
}

TEST(HostileNifti, NanSlopeMeansNoScalingAsNibabelWritesIt) {
  // nibabel writes scl_slope = scl_inter = NaN for unscaled data: a valid file, read unscaled.
  Scratch s;
  NiftiSpec spec;
  spec.scl_slope = std::nanf("");
  spec.scl_inter = std::nanf("");
  spec.voxels[0] = -1000;
  write_nifti(s / "ok.nii", spec);
  const Volume v = io::read_volume(s / "ok.nii");
  EXPECT_EQ(v.spacing[0], 2.0);
  EXPECT_FLOAT_EQ(*std::max_element(v.hu.begin(), v.hu.end()), 40.0f);
  // A used slope with a non-finite intercept is an error.
  spec.scl_slope = 1;
  write_nifti(s / "bad.nii", spec);
  expect_error([&] { io::read_volume(s / "bad.nii"); }, s / "bad.nii", "scl_inter");
}

TEST(HostileNifti, NonFiniteScanFindsValuesSplitAcrossChunks) {
  std::vector<float> data(37, 1.0f);
  data[5] = std::nanf("");
  data[36] = INFINITY;
  const auto* bytes = reinterpret_cast<const unsigned char*>(data.data());
  for (std::size_t chunk : {1u, 3u, 5u, 7u, 148u}) {
    NonFiniteScan scan(4, false);
    for (std::size_t i = 0; i < data.size() * 4; i += chunk) scan.feed(bytes + i, std::min(chunk, data.size() * 4 - i));
    EXPECT_EQ(scan.count(), 2u) << "chunk " << chunk;
    EXPECT_EQ(scan.first_index(), 5u) << "chunk " << chunk;
  }
  // Other byte order: 1.0f byte-swapped is a finite denormal, the swapped NaN is still NaN.
  std::vector<unsigned char> swapped(data.size() * 4);
  for (std::size_t i = 0; i < data.size(); ++i)
    for (int k = 0; k < 4; ++k) swapped[4 * i + std::size_t(k)] = bytes[4 * i + std::size_t(3 - k)];
  NonFiniteScan scan(4, true);
  scan.feed(swapped.data(), swapped.size());
  EXPECT_EQ(scan.count(), 2u);
}

TEST(HostileNifti, ArbitraryHeaderBytesNeverCrash) {
  // Random headers: every outcome is a return or an hpcm::Error (the fuzz harness goes further).
  std::mt19937 rng(15);
  int errors = 0;
  for (int i = 0; i < 2000; ++i) {
    std::vector<unsigned char> b = nifti_bytes(NiftiSpec{});
    for (int k = 0; k < 8; ++k) b[rng() % 348] = static_cast<unsigned char>(rng());
    try {
      check_nifti_header("x.nii", b.data(), b.size());
    } catch (const Error&) {
      ++errors;
    }
  }
  EXPECT_GT(errors, 0);
}

// ---- MetaImage and NRRD ----------------------------------------------------------------------

TEST(HostileTextHeaders, MetaImageSpacingZeroNanNegative) {
  Scratch s;
  for (const std::string sp : {"0 2 2", "nan 2 2", "-2 2 2", "2 inf 2", "2 2 abc"}) {
    write_text(s / "v.mha", "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\nElementSpacing = " + sp +
                                "\nElementDataFile = LOCAL\n" + short_data(64));
    expect_error([&] { io::read_volume(s / "v.mha"); }, s / "v.mha", "ElementSpacing");
  }
}

TEST(HostileTextHeaders, NrrdSpacingAndDirectionsMustBeUsable) {
  Scratch s;
  const std::string head = "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nendian: little\nencoding: raw\n";
  for (const std::string field : {"spacings: 0 2 2", "spacings: nan 2 2", "spacings: 2 -1 2",
                                  "space: left-posterior-superior\nspace directions: (nan,0,0) (0,2,0) (0,0,2)",
                                  "space: left-posterior-superior\nspace directions: (0,0,0) (0,2,0) (0,0,2)",
                                  "space: left-posterior-superior\nspace directions: none (0,2,0) (0,0,2)"}) {
    write_text(s / "v.nrrd", head + field + "\n\n" + short_data(64));
    expect_error([&] { io::read_volume(s / "v.nrrd"); }, s / "v.nrrd", "spacing");
  }
  // A vector axis (first of four) may have NaN spacing / "none" direction: only spatial axes count.
  EXPECT_NO_THROW(check_nrrd_header("f.nrrd", "NRRD0004\ndimension: 4\nsizes: 3 4 4 4\nspacings: nan 1 1 1\n"
                                              "space directions: none (1,0,0) (0,1,0) (0,0,1)\n\n"));
}

// ---- DICOM stack geometry (synthetic slices) -------------------------------------------------

namespace {
std::vector<DicomSlice> axial_stack(int n, double step) {
  std::vector<DicomSlice> v;
  for (int k = 0; k < n; ++k) {
    DicomSlice s;
    s.file = "s" + std::to_string(100 + (k * 7) % n);  // file names not in position order
    s.has_position = s.has_orientation = s.has_spacing = true;
    s.position = {-100, -120, 50 - step * k};
    s.orientation = {1, 0, 0, 0, 1, 0};
    s.pixel_spacing = {0.8, 0.7};
    s.orientation_text = "1\\0\\0\\0\\1\\0";
    s.spacing_text = "0.8\\0.7";
    s.rows = 64;
    s.columns = 32;
    s.instance = k + 1;
    v.push_back(s);
  }
  return v;
}
}  // namespace

TEST(HostileDicomStack, GoodStackGeometryFromThePositions) {
  const DicomStack st = plan_dicom_stack("d", axial_stack(10, 2.5), false);
  ASSERT_EQ(st.files.size(), 10u);
  EXPECT_EQ(st.geometry.dims, (Int3{32, 64, 10}));
  EXPECT_DOUBLE_EQ(st.geometry.spacing[0], 0.7);  // between columns
  EXPECT_DOUBLE_EQ(st.geometry.spacing[1], 0.8);  // between rows
  EXPECT_NEAR(st.geometry.spacing[2], 2.5, 1e-12);
  EXPECT_DOUBLE_EQ(st.geometry.origin[2], 50 - 2.5 * 9);  // the lowest slice comes first
}

TEST(HostileDicomStack, DuplicatePositionsAreAnErrorOrKeepFirstOnRequest) {
  auto v = axial_stack(8, 2);
  DicomSlice dup = v[3];
  dup.file = "zz_dup";
  dup.instance = 99;
  v.push_back(dup);
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "2 slices at the same position");
  const std::string msg = error_of([&] { plan_dicom_stack("d", v, false); });
  EXPECT_NE(msg.find(v[3].file), std::string::npos) << msg;
  EXPECT_NE(msg.find("zz_dup"), std::string::npos) << msg;
  EXPECT_NE(msg.find("--dicom-duplicates first"), std::string::npos) << msg;
  const DicomStack st = plan_dicom_stack("d", v, true);
  EXPECT_EQ(st.files.size(), 8u);
  EXPECT_NEAR(st.geometry.spacing[2], 2.0, 1e-12);
  ASSERT_EQ(st.dropped_duplicates.size(), 1u);
  EXPECT_EQ(st.dropped_duplicates[0], "zz_dup");  // higher InstanceNumber dropped
}

TEST(HostileDicomStack, MissingAndMovedSlicesAreGaps) {
  auto v = axial_stack(10, 2);
  v.erase(v.begin() + 4);
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "not evenly spaced");
  EXPECT_NE(error_of([&] { plan_dicom_stack("d", v, false); }).find("1 slice(s) missing?"), std::string::npos);
  auto m = axial_stack(10, 2);
  m[4].position[2] += 0.5;  // a quarter step
  expect_error([&] { plan_dicom_stack("d", m, false); }, "d", "not evenly spaced");
  auto ok = axial_stack(10, 2);
  ok[4].position[2] += 0.015;  // within 1 %
  EXPECT_NO_THROW(plan_dicom_stack("d", ok, false));
}

TEST(HostileDicomStack, EverySliceAtOnePositionIsAnError) {
  auto v = axial_stack(6, 0);
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "all 6 slices are at the same position");
  expect_error([&] { plan_dicom_stack("d", v, true); }, "d", "all 6 slices are at the same position");
}

TEST(HostileDicomStack, MixedOrientationShiftAndMissingTags) {
  auto v = axial_stack(6, 2);
  v[2].orientation = {1, 0, 0, 0, 0.98480775, 0.17364818};
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "mixed slice orientations");
  v = axial_stack(6, 2);
  v[2].position[0] += 1.0;  // moved in-plane
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "shifted");
  v = axial_stack(6, 2);
  v[1].has_position = false;
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "no ImagePositionPatient");
  v = axial_stack(6, 2);
  v[1].pixel_spacing = {0, 0};
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "PixelSpacing");
  v = axial_stack(6, 2);
  v[1].columns = 16;
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "mixed image sizes");
  v = axial_stack(6, 2);
  v[1].frames = 30;
  expect_error([&] { plan_dicom_stack("d", v, false); }, "d", "multi-frame");
}

TEST(HostileDicomStack, UniformlyTiltedStackKeepsItsDirection) {
  // Every slice tilted the same way, stacked along the tilted normal: a valid oblique stack.
  auto v = axial_stack(5, 0);
  const double c = std::cos(0.2), s = std::sin(0.2);
  for (int k = 0; k < 5; ++k) {
    v[std::size_t(k)].orientation = {1, 0, 0, 0, c, s};
    v[std::size_t(k)].position = {0, -s * 3.0 * k, c * 3.0 * k};  // n = (0, -s, c)
  }
  const DicomStack st = plan_dicom_stack("d", v, false);
  EXPECT_NEAR(st.geometry.spacing[2], 3.0, 1e-9);
  EXPECT_NEAR(st.geometry.direction[1 * 3 + 2], -s, 1e-12);
  EXPECT_NEAR(st.geometry.direction[2 * 3 + 2], c, 1e-12);
}

TEST(HostileDicomStack, DecimalStringsMustHoldFiniteNumbers) {
  double v[3];
  EXPECT_TRUE(parse_ds("1\\-2.5\\3e1", v, 3));
  EXPECT_EQ(v[2], 30.0);
  EXPECT_FALSE(parse_ds("1\\2", v, 3));
  EXPECT_FALSE(parse_ds("1\\2\\3\\4", v, 3));
  EXPECT_FALSE(parse_ds("NaN\\1\\1", v, 3));
  EXPECT_FALSE(parse_ds("1\\x\\1", v, 3));
  EXPECT_FALSE(parse_ds("", v, 3));
}

// ---- DICOM series on disk (copies of the shared series) -------------------------------------

namespace {
std::vector<fs::path> copy_series(const fs::path& to) {
  fs::create_directories(to);
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(kDicom)) {
    fs::copy_file(e.path(), to / e.path().filename());
    files.push_back(to / e.path().filename());
  }
  std::sort(files.begin(), files.end());  // file names follow the position order in this series
  return files;
}
}  // namespace

TEST(HostileDicomSeries, DeletedSliceIsAGapNotAWiderSpacing) {
  if (!fs::exists(kDicom)) GTEST_SKIP() << kDicom << " is absent (../shared/data)";
  Scratch s;
  const auto files = copy_series(s.dir / "series");
  fs::remove(files[10]);
  expect_error([&] { io::read_volume(s / "series"); }, s / "series", "not evenly spaced");
  EXPECT_NE(error_of([&] { io::read_volume(s / "series"); }).find("1 slice(s) missing?"), std::string::npos);
}

TEST(HostileDicomSeries, CopiedSliceIsADuplicateNotHalfTheSpacing) {
  if (!fs::exists(kDicom)) GTEST_SKIP() << kDicom << " is absent (../shared/data)";
  Scratch s;
  const auto files = copy_series(s.dir / "series");
  fs::copy_file(files[7], s.dir / "series" / "copy_of_slice");
  expect_error([&] { io::read_volume(s / "series"); }, s / "series", "2 slices at the same position");
  io::ReadOptions first;
  first.dicom_duplicates = io::DicomDuplicates::First;
  std::vector<std::string> warnings;
  first.warn = [&](const std::string& w) { warnings.push_back(w); };
  const Volume v = io::read_volume(s / "series", first);
  EXPECT_EQ(v.dims.z, 20);
  EXPECT_NEAR(v.spacing[2], 2.0, 1e-9);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("left out 1 slice"), std::string::npos) << warnings[0];
}

TEST(HostileDicomSeries, UnreadableFileIsNamedNotDropped) {
  if (!fs::exists(kDicom)) GTEST_SKIP() << kDicom << " is absent (../shared/data)";
  Scratch s;
  const auto files = copy_series(s.dir / "series");
  const auto size = fs::file_size(files[5]);
  std::string noise(size, '\0');
  std::mt19937 rng(15);
  for (char& c : noise) c = static_cast<char>(rng());
  write_text(files[5].string(), noise);
  expect_error([&] { io::read_volume(s / "series"); }, s / "series", "1 file is not readable DICOM: " + files[5].filename().string());
  // Skipping it on request leaves a hole in the stack: still an error, never a silent gap.
  io::ReadOptions skip;
  skip.dicom_skip_unreadable = true;
  expect_error([&] { io::read_volume(s / "series", skip); }, s / "series", "not evenly spaced");
}

TEST(HostileDicomSeries, LibraryOutputComesAfterHpcmsLineNotBefore) {
  if (!fs::exists(kDicom)) GTEST_SKIP() << kDicom << " is absent (../shared/data)";
  Scratch s;
  const auto files = copy_series(s.dir / "series");
  fs::resize_file(files[9], fs::file_size(files[9]) / 2);  // cut inside the JPEG-2000 data
  ::testing::internal::CaptureStderr();
  ::testing::internal::CaptureStdout();
  const std::string msg = error_of([&] { io::read_volume(s / "series"); });
  const std::string out = ::testing::internal::GetCapturedStdout();
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(out, "");
  EXPECT_EQ(err, "") << "library output escaped: " << err;
  const std::string first = msg.substr(0, msg.find('\n'));
  EXPECT_EQ(first.rfind(s / "series", 0), 0u) << msg;
  EXPECT_NE(first.find(files[9].filename().string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("\n  library output while reading:\n  | "), std::string::npos) << msg;
}

// ---- HU range --------------------------------------------------------------------------------

TEST(HostileHu, FarOutsideAnyCtRangeIsAnErrorPaddingAWarning) {
  Scratch s;
  NiftiSpec spec;
  spec.voxels[0] = -1000;
  spec.voxels[1] = 3e7f;
  write_nifti(s / "huge.nii", spec);
  expect_error([&] { io::read_volume(s / "huge.nii"); }, s / "huge.nii", "not Hounsfield units");
  spec.voxels[1] = -30000;  // padding
  write_nifti(s / "pad.nii", spec);
  std::vector<std::string> w;
  io::ReadOptions ro;
  ro.warn = [&](const std::string& m) { w.push_back(m); };
  EXPECT_NO_THROW(io::read_volume(s / "pad.nii", ro));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("outside [-4096, 32767] HU"), std::string::npos) << w[0];
  NiftiSpec raw;  // no voxel below 0: a missing rescale intercept?
  write_nifti(s / "raw.nii", raw);
  w.clear();
  EXPECT_NO_THROW(io::read_volume(s / "raw.nii", ro));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("no voxel below 0 HU"), std::string::npos) << w[0];
}

// ---- writers: no shared data file ------------------------------------------------------------

TEST(HostileOutput, TwoHeadersNeverShareOneDataFile) {
  Scratch s;
  Volume a;
  a.dims = {4, 4, 4};
  a.hu.assign(64, -1000.0f);
  io::write_volume(a, s / "a.nhdr");
  ASSERT_TRUE(fs::exists(s / "a.raw"));
  const auto before = fs::last_write_time(s / "a.raw");
  Volume b = a;
  b.hu.assign(64, 500.0f);
  expect_error([&] { io::write_volume(b, s / "a.mhd"); }, "a.mhd", "belongs to a.nhdr");
  expect_error([&] { io::check_output_path(s / "a.mhd"); }, "a.mhd", "belongs to a.nhdr");
  EXPECT_EQ(fs::last_write_time(s / "a.raw"), before);
  EXPECT_FALSE(fs::exists(s / "a.mhd"));
  EXPECT_EQ(io::read_volume(s / "a.nhdr").hu[0], -1000.0f);
  // Rewriting the same header replaces its own data file.
  EXPECT_NO_THROW(io::write_volume(b, s / "a.nhdr"));
  EXPECT_EQ(io::read_volume(s / "a.nhdr").hu[0], 500.0f);
  // An unrelated file with the data file's name is never overwritten.
  write_text(s / "c.raw", "someone's notes");
  expect_error([&] { io::write_volume(a, s / "c.nhdr"); }, "c.nhdr", "is not this header's");
}

TEST(HostileOutput, DestinationCheckedWithoutWriting) {
  Scratch s;
  expect_error([&] { io::check_output_path(s / "missing/ct.nii.gz"); }, "missing/ct.nii.gz", "does not exist");
  expect_error([&] { io::check_output_path(s.dir.string()); }, s.dir.string(), "unsupported extension");
  fs::create_directories(s.dir / "d.nii");
  expect_error([&] { io::check_output_path(s / "d.nii"); }, "d.nii", "is a folder");
  EXPECT_NO_THROW(io::check_output_path(s / "ok.nii.gz"));
  EXPECT_FALSE(fs::exists(s / "ok.nii.gz"));
}

// ---- issue 29: geometry bounds, scaled integers, compressed MetaImage, data-file paths ----------

namespace {
/// The message of the first line, for checks of several parts.
std::string first_line(const std::function<void()>& f) {
  const std::string msg = error_of(f);
  return msg.substr(0, msg.find('\n'));
}
void expect_parts(const std::function<void()>& f, const std::vector<std::string>& parts) {
  const std::string first = first_line(f);
  for (const std::string& p : parts) EXPECT_NE(first.find(p), std::string::npos) << "'" << p << "' not in: " << first;
}
}  // namespace

TEST(HostileNiftiGeometry, HugeSformTranslationIsAnErrorNamingTheValueNotAHang) {
  Scratch s;
  for (const float t : {3e38f, 1e6f, -2e5f}) {
    NiftiSpec spec;
    spec.sform_code = 1;
    spec.srow[1 * 4 + 3] = t;  // srow_y[3]
    write_nifti(s / "t.nii", spec);
    char value[32];
    std::snprintf(value, sizeof value, "%.6g", double(t));
    expect_parts([&] { io::read_volume(s / "t.nii"); }, {s / "t.nii", "srow_y[3]", value, "[-100000, 100000] mm"});
  }
  NiftiSpec ok;  // within the bound
  ok.sform_code = 1;
  ok.srow[3] = -99999;
  write_nifti(s / "ok.nii", ok);
  EXPECT_NO_THROW(io::read_volume(s / "ok.nii"));
}

TEST(HostileNiftiGeometry, QformFieldsAreChecked) {
  Scratch s;
  NiftiSpec spec;
  spec.qform_code = 1;
  spec.qoffset[2] = 3e38f;
  write_nifti(s / "q.nii", spec);
  expect_parts([&] { io::read_volume(s / "q.nii"); }, {s / "q.nii", "qoffset_z", "3e+38", "[-100000, 100000] mm"});
  spec.qoffset[2] = 0;
  spec.quatern[0] = 0.9f;
  spec.quatern[1] = 0.9f;  // b^2 + c^2 + d^2 = 1.62 > 1: not a rotation
  write_nifti(s / "q.nii", spec);
  expect_parts([&] { io::read_volume(s / "q.nii"); }, {s / "q.nii", "quatern_b", "1.62"});
  spec.quatern[1] = std::nanf("");
  write_nifti(s / "q.nii", spec);
  expect_parts([&] { io::read_volume(s / "q.nii"); }, {s / "q.nii", "quatern_c", "nan"});
}

TEST(HostileSpacing, HugeOrTinySpacingIsAnErrorInEveryFormat) {
  Scratch s;
  for (const float v : {3e38f, 1e-5f}) {
    NiftiSpec spec;
    spec.pixdim[2] = v;
    write_nifti(s / "p.nii", spec);
    expect_parts([&] { io::read_volume(s / "p.nii"); }, {s / "p.nii", "pixdim[3]", "[0.001, 1000] mm"});
  }
  NiftiSpec sform;  // the sform's column length is the spacing ITK uses
  sform.sform_code = 1;
  sform.srow[0] = 3e38f;
  write_nifti(s / "s.nii", sform);
  expect_parts([&] { io::read_volume(s / "s.nii"); }, {s / "s.nii", "sform column 0", "3e+38", "[0.001, 1000] mm"});
  write_text(s / "v.mha", "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\nElementSpacing = 2 3e38 2"
                          "\nElementDataFile = LOCAL\n" + short_data(64));
  expect_parts([&] { io::read_volume(s / "v.mha"); }, {s / "v.mha", "ElementSpacing[1]", "3e+38", "[0.001, 1000] mm"});
  write_text(s / "v.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nendian: little\nencoding: raw\n"
                           "spacings: 2 2 3e38\n\n" + short_data(64));
  expect_parts([&] { io::read_volume(s / "v.nrrd"); }, {s / "v.nrrd", "spacings[2]", "3e+38", "[0.001, 1000] mm"});
  write_text(s / "d.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nendian: little\nencoding: raw\n"
                           "space: left-posterior-superior\nspace directions: (3e38,0,0) (0,2,0) (0,0,2)\n\n" + short_data(64));
  expect_parts([&] { io::read_volume(s / "d.nrrd"); }, {s / "d.nrrd", "axis 0", "3e+38", "[0.001, 1000] mm"});
}

TEST(HostileSpacing, DicomPixelSpacingOutsideThePlausibleRange) {
  auto v = axial_stack(6, 2);
  for (auto& sl : v) sl.pixel_spacing = {3e38, 3e38};
  expect_parts([&] { plan_dicom_stack("d", v, false); }, {"d: ", "PixelSpacing", "[0.001, 1000] mm"});
}

TEST(HostileNiftiScaling, Int16WithSlopeAndInterceptIsReadAsHu) {
  Scratch s;
  NiftiSpec spec;
  spec.shorts.resize(64);
  for (int i = 0; i < 64; ++i) spec.shorts[std::size_t(i)] = std::int16_t(i * 50);  // 0 .. 3150
  spec.scl_slope = 1;
  spec.scl_inter = -1024;
  write_nifti(s / "ct.nii.gz", spec);
  const Volume v = io::read_volume_as_stored(s / "ct.nii.gz");
  ASSERT_EQ(v.hu.size(), 64u);
  for (int i = 0; i < 64; ++i) EXPECT_FLOAT_EQ(v.hu[std::size_t(i)], float(i * 50) - 1024.0f) << i;
  spec.scl_slope = 0.5f;
  write_nifti(s / "half.nii", spec);
  const Volume h = io::read_volume_as_stored(s / "half.nii");
  for (int i = 0; i < 64; ++i) EXPECT_FLOAT_EQ(h.hu[std::size_t(i)], 0.5f * float(i * 50) - 1024.0f) << i;
}

TEST(HostileNiftiScaling, TinyOrHugeSlopeIsRefusedNotIgnored) {
  Scratch s;
  for (const float slope : {1e-30f, 1e-7f, 1e7f}) {
    NiftiSpec spec;
    spec.scl_slope = slope;
    write_nifti(s / "s.nii", spec);
    char value[32];
    std::snprintf(value, sizeof value, "%.6g", double(slope));
    expect_parts([&] { io::read_volume(s / "s.nii"); }, {s / "s.nii", "scl_slope", value, "[1e-06, 1e+06]"});
  }
}

namespace {
std::string zlib_of(const std::string& raw) {
  uLongf n = compressBound(uLong(raw.size()));
  std::string out(n, '\0');
  compress(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()));
  out.resize(n);
  return out;
}
std::string compressed_mha(const std::string& stream, long long announced) {
  return "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\nElementSpacing = 2 2 2\n"
         "CompressedData = True\nCompressedDataSize = " + std::to_string(announced) + "\nElementDataFile = LOCAL\n" + stream;
}
}  // namespace

TEST(HostileMetaImage, LyingCompressedDataSizeIsAnError) {
  Scratch s;
  const std::string full = zlib_of(short_data(64));
  write_text(s / "ok.mha", compressed_mha(full, (long long)full.size()));
  EXPECT_EQ(io::read_volume(s / "ok.mha").hu[5], 40.0f);
  // Announced size too small / too large for the bytes present.
  for (long long announced : {(long long)full.size() / 2, (long long)full.size() * 4}) {
    write_text(s / "v.mha", compressed_mha(full, announced));
    expect_parts([&] { io::read_volume(s / "v.mha"); }, {s / "v.mha", "CompressedDataSize = " + std::to_string(announced)});
  }
  // An honest size, but the stream holds only half the voxels.
  const std::string half = zlib_of(short_data(32));
  write_text(s / "h.mha", compressed_mha(half, (long long)half.size()));
  expect_parts([&] { io::read_volume(s / "h.mha"); }, {s / "h.mha", "inflates to 64 bytes", "128"});
  // A stream cut short (and announced so).
  const std::string cut = full.substr(0, full.size() - 6);
  write_text(s / "c.mha", compressed_mha(cut, (long long)cut.size()));
  expect_parts([&] { io::read_volume(s / "c.mha"); }, {s / "c.mha", "compressed data"});
}

TEST(HostileMetaImage, ShortRawDataIsAnError) {
  Scratch s;
  const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\nElementSpacing = 2 2 2\n";
  write_text(s / "v.mha", head + "ElementDataFile = LOCAL\n" + short_data(50));
  expect_parts([&] { io::read_volume(s / "v.mha"); }, {s / "v.mha", "truncated", "100 bytes", "128"});
  write_text(s / "v.mhd", head + "ElementDataFile = v.raw\n");
  write_text(s / "v.raw", short_data(63));
  expect_parts([&] { io::read_volume(s / "v.mhd"); }, {s / "v.mhd", "truncated", "126 bytes", "128"});
  // NRRD: ITK (teem) reports short raw and gzip data itself.
  const std::string nrrd = "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nendian: little\nspacings: 2 2 2\n";
  write_text(s / "v.nrrd", nrrd + "encoding: raw\n\n" + short_data(50));
  expect_parts([&] { io::read_volume(s / "v.nrrd"); }, {s / "v.nrrd", "truncated or corrupt NRRD file"});
  gzFile gz = gzopen((s / "g.gz").c_str(), "wb");
  const std::string part = short_data(50);
  gzwrite(gz, part.data(), unsigned(part.size()));
  gzclose(gz);
  std::ifstream in(s / "g.gz", std::ios::binary);
  const std::string packed((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  write_text(s / "g.nrrd", nrrd + "encoding: gzip\n\n" + packed);
  expect_parts([&] { io::read_volume(s / "g.nrrd"); }, {s / "g.nrrd", "truncated or corrupt NRRD file"});
}

TEST(HostileDataFile, OnlyRegularFilesBesideOrBelowTheHeader) {
  Scratch s;
  fs::create_directories(s.dir / "h" / "sub");
  const std::string head = "ObjectType = Image\nNDims = 3\nDimSize = 4 4 4\nElementType = MET_SHORT\nElementSpacing = 2 2 2\n";
  const std::string nhead = "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 4\nendian: little\nencoding: raw\nspacings: 2 2 2\n";
  write_text(s / "outside.raw", short_data(64));
  write_text(s / "h/sub/in.raw", short_data(64));
  fs::create_symlink(s.dir / "outside.raw", s.dir / "h" / "link.raw");
  const std::string mhd = s / "h/v.mhd", nhdr = s / "h/v.nhdr";
  // Allowed: beside or below the header's folder.
  write_text(mhd, head + "ElementDataFile = sub/in.raw\n");
  EXPECT_EQ(io::read_volume(mhd).hu[0], 40.0f);
  write_text(nhdr, nhead + "data file: sub/in.raw\n\n");
  EXPECT_EQ(io::read_volume(nhdr).hu[0], 40.0f);
  // Refused: outside (by .., an absolute path or a symlink).
  for (const std::string& entry : std::vector<std::string>{"../outside.raw", s / "outside.raw", "link.raw", "sub/../../outside.raw"}) {
    write_text(mhd, head + "ElementDataFile = " + entry + "\n");
    expect_parts([&] { io::read_volume(mhd); }, {mhd, "ElementDataFile = " + entry, "outside the header's folder"});
    write_text(nhdr, nhead + "data file: " + entry + "\n\n");
    expect_parts([&] { io::read_volume(nhdr); }, {nhdr, "data file: " + entry, "outside the header's folder"});
  }
  // Not a regular file: a FIFO (would block forever) and a device; never opened.
  ASSERT_EQ(::mkfifo((s.dir / "h" / "fifo.raw").c_str(), 0600), 0);
  for (const std::string entry : {"fifo.raw", "/dev/urandom"}) {
    write_text(mhd, head + "ElementDataFile = " + entry + "\n");
    expect_parts([&] { io::read_volume(mhd); }, {mhd, "ElementDataFile = " + entry, "not a regular file"});
    write_text(nhdr, nhead + "data file: " + entry + "\n\n");
    expect_parts([&] { io::read_volume(nhdr); }, {nhdr, "data file: " + entry, "not a regular file"});
  }
  write_text(mhd, head + "ElementDataFile = nothing.raw\n");
  expect_parts([&] { io::read_volume(mhd); }, {mhd, "ElementDataFile = nothing.raw", "missing"});
}

TEST(HostileNiftiGeometry, SformWinsOverQformAsInNibabel) {
  // sform and qform both set and different: the sform is used (nibabel's rule), with a warning.
  Scratch s;
  NiftiSpec spec;
  spec.qform_code = 1;
  spec.qoffset[0] = 5;  // qform: identity rotation, 2 mm, origin (5, 0, 0) RAS
  spec.sform_code = 2;
  const float srow[12] = {0, 3, 0, 10, -2, 0, 0, 20, 0, 0, 2.5f, 30};  // axes swapped, own spacings
  std::copy(srow, srow + 12, spec.srow);
  write_nifti(s / "both.nii", spec);
  std::vector<std::string> w;
  io::ReadOptions ro;
  ro.warn = [&](const std::string& m) { w.push_back(m); };
  const Volume v = io::read_volume_as_stored(s / "both.nii", ro);
  EXPECT_NEAR(v.spacing[0], 2.0, 1e-6);
  EXPECT_NEAR(v.spacing[1], 3.0, 1e-6);
  EXPECT_NEAR(v.spacing[2], 2.5, 1e-6);
  // RAS (10, 20, 30) is LPS (-10, -20, 30); column 0 = RAS (0,-1,0) = LPS (0, 1, 0).
  EXPECT_NEAR(v.origin[0], -10, 1e-6);
  EXPECT_NEAR(v.origin[1], -20, 1e-6);
  EXPECT_NEAR(v.origin[2], 30, 1e-6);
  EXPECT_NEAR(v.direction[0 * 3 + 0], 0, 1e-6);
  EXPECT_NEAR(v.direction[1 * 3 + 0], 1, 1e-6);
  EXPECT_NEAR(v.direction[0 * 3 + 1], -1, 1e-6);
  EXPECT_NEAR(v.direction[2 * 3 + 2], 1, 1e-6);
  bool noted = false;
  for (const std::string& m : w) noted = noted || (m.find("sform") != std::string::npos && m.find("qform") != std::string::npos);
  EXPECT_TRUE(noted) << "no warning that sform and qform differ";
  // qform only: the qform.
  spec.sform_code = 0;
  write_nifti(s / "q.nii", spec);
  const Volume q = io::read_volume_as_stored(s / "q.nii");
  EXPECT_NEAR(q.origin[0], -5, 1e-6);
  EXPECT_NEAR(q.spacing[1], 2.0, 1e-6);
}

TEST(HostileNiftiGeometry, GeometrySourceIsReported) {
  Scratch s;
  NiftiSpec spec;
  write_nifti(s / "p.nii", spec);
  EXPECT_EQ(io::nifti_geometry_source(s / "p.nii"), "pixdim (qform_code and sform_code 0)");
  spec.qform_code = 1;
  spec.qoffset[0] = 5;
  write_nifti(s / "q.nii", spec);
  EXPECT_EQ(io::nifti_geometry_source(s / "q.nii"), "qform (qform_code 1)");
  spec.sform_code = 2;
  spec.srow[3] = 5;  // the same grid as the qform: no note
  write_nifti(s / "same.nii", spec);
  EXPECT_EQ(io::nifti_geometry_source(s / "same.nii"), "sform (sform_code 2)");
  spec.srow[3] = 6;
  write_nifti(s / "both.nii.gz", spec);
  EXPECT_EQ(io::nifti_geometry_source(s / "both.nii.gz"), "sform (sform_code 2; the qform differs)");
  EXPECT_EQ(io::nifti_geometry_source(s / "both.nrrd"), "");
}

TEST(HostileNiftiGeometry, WithoutQformAndSformTheGridIsNibabels) {
  // nibabel's get_base_affine: RAS diag(-2, 2, 2), centred: voxel 0 at RAS (3, -3, -3) for 4^3.
  Scratch s;
  write_nifti(s / "p.nii", NiftiSpec{});
  const Volume v = io::read_volume_as_stored(s / "p.nii");
  EXPECT_NEAR(v.origin[0], -3, 1e-9);  // LPS
  EXPECT_NEAR(v.origin[1], 3, 1e-9);
  EXPECT_NEAR(v.origin[2], -3, 1e-9);
  EXPECT_NEAR(v.direction[0], 1, 1e-12);
  EXPECT_NEAR(v.direction[4], -1, 1e-12);
  EXPECT_NEAR(v.direction[8], 1, 1e-12);
}

TEST(HostileNiftiGeometry, ShearedSformIsAnError) {
  Scratch s;
  NiftiSpec spec;
  spec.sform_code = 1;
  spec.srow[1] = 0.5f;  // column 1 leans towards x
  write_nifti(s / "shear.nii", spec);
  expect_parts([&] { io::read_volume(s / "shear.nii"); }, {s / "shear.nii", "sform columns 0 and 1 are not orthogonal"});
  spec.qform_code = 1;  // ITK would fall back to this qform silently
  write_nifti(s / "shear_q.nii", spec);
  expect_parts([&] { io::read_volume(s / "shear_q.nii"); }, {s / "shear_q.nii", "sform columns 0 and 1 are not orthogonal"});
}

TEST(HostileDicomStack, RescaleTagsInEverySliceOrNone) {
  auto v = axial_stack(6, 2);
  for (auto& sl : v) sl.intercept_text = "-1024", sl.slope_text = "1";
  EXPECT_NO_THROW(plan_dicom_stack("d", v, false));
  v[3].intercept_text = "-1000";  // differing values are legal DICOM: applied per slice
  EXPECT_NO_THROW(plan_dicom_stack("d", v, false));
  v[3].intercept_text.clear();
  expect_parts([&] { plan_dicom_stack("d", v, false); }, {"d: ", v[3].file, "RescaleIntercept (0028,1052)", "-1024"});
  v[3].intercept_text = "-1024";
  v[1].slope_text.clear();
  expect_parts([&] { plan_dicom_stack("d", v, false); }, {"d: ", v[1].file, "RescaleSlope (0028,1053)"});
  for (auto& sl : v) sl.intercept_text.clear(), sl.slope_text.clear();  // none: the raw values (a warning may follow)
  EXPECT_NO_THROW(plan_dicom_stack("d", v, false));
}

TEST(HostileDicomSeries, RescaleInterceptIsAppliedPerSlice) {
  // Slices may carry different intercepts (legal DICOM): each slice's own must be applied.
  if (!fs::exists(kDicom)) GTEST_SKIP() << kDicom << " is absent (../shared/data)";
  Scratch s;
  const auto files = copy_series(s.dir / "series");
  const Volume before = io::read_volume_as_stored(s / "series");
  // Rewrite slice 7's RescaleIntercept '-1024' as '-1000' in place (same length: the file stays
  // valid; explicit VR little endian: tag 0028,1052, VR DS, 2-byte length, value).
  std::ifstream in(files[7], std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  const std::string tag("\x28\x00\x52\x10" "DS", 6);
  const auto at = bytes.find(tag);
  ASSERT_NE(at, std::string::npos);
  const auto value = at + 8;
  const std::size_t length = std::size_t(static_cast<unsigned char>(bytes[at + 6])) | std::size_t(static_cast<unsigned char>(bytes[at + 7])) << 8;
  ASSERT_GE(length, 5u);
  ASSERT_EQ(bytes.compare(value, 5, "-1024"), 0) << bytes.substr(value, length);
  bytes.replace(value, 5, "-1000");
  write_text(files[7].string(), bytes);
  const Volume after = io::read_volume_as_stored(s / "series");
  ASSERT_EQ(after.dims, before.dims);
  const std::size_t plane = std::size_t(before.dims.x) * before.dims.y;
  std::size_t changed_slices = 0;
  for (int k = 0; k < before.dims.z; ++k) {
    const float shift = after.hu[k * plane] - before.hu[k * plane];
    bool all_same = true;
    for (std::size_t i = 0; i < plane; ++i) all_same = all_same && after.hu[k * plane + i] - before.hu[k * plane + i] == shift;
    EXPECT_TRUE(all_same) << "slice " << k;
    if (shift != 0) {
      ++changed_slices;
      EXPECT_EQ(shift, 24.0f) << "slice " << k;
    }
  }
  EXPECT_EQ(changed_slices, 1u);
}
