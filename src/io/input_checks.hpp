#pragma once
// Checks of volume inputs that hpcm makes itself, before and instead of trusting ITK, because
// ITK and the libraries under it repair bad values silently: a zero or NaN spacing becomes
// 1 mm, a negative one its absolute value, NaN voxels of a NIfTI file become 0, and a DICOM
// series is averaged into one spacing whatever its slices say. Plain C++ (no ITK, no GDCM), so
// the fuzz harnesses (fuzz/) and the tests can call every function directly. Every function
// either returns or throws hpcm::Error naming the file: arbitrary bytes never crash it.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "io_detail.hpp"

namespace hpcm::io::detail {

// ---- NIfTI ----------------------------------------------------------------------------------

struct NiftiHeader {
  int version = 1;                  ///< 1 or 2
  bool swapped = false;             ///< other byte order than this machine
  std::array<std::int64_t, 8> dim{};
  std::array<double, 8> pixdim{};
  int datatype = 0, bitpix = 0;
  double vox_offset = 0;
  double scl_slope = 0, scl_inter = 0;
  int qform_code = 0, sform_code = 0;
};

/// Size of the NIfTI header at the start of `bytes` (348 or 540), 0 when it is neither.
std::size_t nifti_header_size(const unsigned char* bytes, std::size_t size);

/// Parses and checks a NIfTI-1/-2 header (`size` >= 348, or 540 for NIfTI-2): dimensions,
/// pixdim of the spatial axes finite and > 0, finite qform/sform when used, a finite scl_inter
/// when scaling is on, a data offset inside the file. Throws hpcm::Error naming `path`.
NiftiHeader check_nifti_header(const std::string& path, const unsigned char* bytes, std::size_t size);

/// Counts NaN/Inf values in raw floating-point voxel data streamed in chunks (NIfTI float32 /
/// float64, either byte order). Feed every byte of the file after the header in order.
class NonFiniteScan {
 public:
  /// `element_size` 4 or 8 (anything else: nothing is counted); `swapped`: other byte order.
  NonFiniteScan(int element_size, bool swapped) : size_(element_size), swapped_(swapped) {}
  void feed(const unsigned char* data, std::size_t n);
  std::uint64_t count() const { return bad_; }
  std::uint64_t first_index() const { return first_; }  ///< element index of the first one

 private:
  void element(const unsigned char* e);
  int size_;
  bool swapped_;
  unsigned char carry_[8] = {};
  int carried_ = 0;
  std::uint64_t index_ = 0, bad_ = 0, first_ = 0;
};

// ---- MetaImage and NRRD headers (text) ------------------------------------------------------

/// Checks the key = value header of a .mha/.mhd file (up to ElementDataFile): NDims, DimSize,
/// ElementSpacing (finite, > 0; ElementSize when no spacing is given), Offset and
/// TransformMatrix finite. Throws hpcm::Error naming `path`.
void check_metaimage_header(const std::string& path, const std::string& text);

/// Checks the header of a .nrrd/.nhdr file (up to the blank line): sizes, and for the last
/// three (spatial) axes spacings finite and > 0 and space directions finite and non-zero;
/// space origin finite. Throws hpcm::Error naming `path`.
void check_nrrd_header(const std::string& path, const std::string& text);

// ---- DICOM series geometry ------------------------------------------------------------------

/// What hpcm reads from one DICOM file's header (tags only, never pixels).
struct DicomSlice {
  std::string file;                  ///< file name inside the directory
  bool has_position = false, has_orientation = false, has_spacing = false;
  std::string position_text, orientation_text, spacing_text;  ///< raw values, for messages
  std::array<double, 3> position{};      ///< ImagePositionPatient (0020,0032), mm, LPS
  std::array<double, 6> orientation{};   ///< ImageOrientationPatient (0020,0037)
  std::array<double, 2> pixel_spacing{}; ///< PixelSpacing (0028,0030): row spacing, column spacing
  int rows = 0, columns = 0, frames = 1;
  long long instance = 0;                ///< InstanceNumber (0 when absent)
};

/// A validated stack: files in slice order and the volume geometry (file index order:
/// axis 0 along the rows' direction, axis 1 along the columns', axis 2 along the normal).
struct DicomStack {
  std::vector<std::string> files;
  Geometry geometry;
  std::vector<std::string> dropped_duplicates;  ///< files left out under DicomDuplicates::First
};

/// Parses a DICOM decimal-string list ("a\b\c") into exactly `n` finite numbers; false when it
/// does not hold n finite numbers.
bool parse_ds(const std::string& text, double* out, std::size_t n);

/// Orders the slices of one series along their normal and checks that they form one evenly
/// spaced stack: every slice has a position, an orientation and a positive pixel spacing; all
/// share orientation, matrix size and pixel spacing; no two lie at the same position (unless
/// keep_first_duplicate: the lowest InstanceNumber, then file name, is kept); consecutive
/// positions are equally spaced within 1 % and not shifted in-plane. Throws hpcm::Error
/// naming `dir`, the files and their positions.
DicomStack plan_dicom_stack(const std::string& dir, std::vector<DicomSlice> slices, bool keep_first_duplicate);

}  // namespace hpcm::io::detail
