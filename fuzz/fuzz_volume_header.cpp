// libFuzzer harness: hpcm's checks of volume headers, run before ITK sees a file (NIfTI-1/-2
// binary header, MetaImage and NRRD text headers, the NaN/Inf scan of float voxel data) and the
// DICOM stack planner fed with slices decoded from the input. Every input must end in a
// return or hpcm::Error.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "io/input_checks.hpp"

using namespace hpcm::io::detail;

namespace {
// Consumes doubles/ints from the fuzz input (zero when exhausted).
struct Reader {
  const std::uint8_t* p;
  std::size_t n;
  double f64() {
    double v = 0;
    if (n >= 8) std::memcpy(&v, p, 8), p += 8, n -= 8;
    return v;
  }
  int i8() { return n ? (--n, int(static_cast<std::int8_t>(*p++))) : 0; }
};

void dicom_stack(const std::uint8_t* data, std::size_t size) {
  Reader r{data, size};
  std::vector<DicomSlice> slices;
  const int count = 1 + (r.i8() & 15);
  for (int k = 0; k < count; ++k) {
    DicomSlice s;
    s.file = "f" + std::to_string(k);
    s.has_position = r.i8() != 0;
    s.has_orientation = r.i8() != 0;
    s.has_spacing = r.i8() != 0;
    for (double& v : s.position) v = r.f64();
    for (double& v : s.orientation) v = r.f64();
    for (double& v : s.pixel_spacing) v = r.f64();
    s.rows = r.i8();
    s.columns = r.i8();
    s.frames = r.i8();
    s.instance = r.i8();
    const int rescale = r.i8();
    if (rescale & 1) s.intercept_text = "-1024";
    if (rescale & 2) s.slope_text = "1";
    slices.push_back(s);
  }
  plan_dicom_stack("fuzz", slices, (count & 1) != 0);
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t which = data[0] % 5;
  ++data, --size;
  try {
    switch (which) {
      case 0: {  // an accepted header must also give a grid (or an hpcm::Error)
        const NiftiHeader h = check_nifti_header("fuzz.nii", data, size);
        nifti_geometry_source(h);
        nifti_geometry("fuzz.nii", h);
        break;
      }
      case 1: check_metaimage_header("fuzz.mha", std::string(reinterpret_cast<const char*>(data), size)); break;
      case 2: check_nrrd_header("fuzz.nrrd", std::string(reinterpret_cast<const char*>(data), size)); break;
      case 3: {
        NonFiniteScan scan(size % 2 ? 4 : 8, size % 3 == 0);
        for (std::size_t i = 0; i < size; i += 7) scan.feed(data + i, std::min<std::size_t>(7, size - i));
        break;
      }
      default: dicom_stack(data, size);
    }
  } catch (const hpcm::Error&) {
  }
  return 0;
}
