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

// ---- plausible geometry -----------------------------------------------------------------------

/// Voxel spacing hpcm accepts, mm: 1 um (far finer than any CT, micro-CT included) to 1 m (a
/// single voxel larger than a body). Outside it a header is corrupt, and 3e38 mm would turn
/// into Inf in the exported displacement field.
inline constexpr double kMinSpacingMm = 1e-3, kMaxSpacingMm = 1e3;
/// Largest |origin| / |translation| hpcm accepts, mm: 100 m. Scanner coordinates stay within a
/// few metres of the isocentre; beyond 1e5 mm a float32 coordinate (NIfTI) no longer resolves
/// 0.01 mm, and ITK's geometry code spins or overflows on values like 3e38.
inline constexpr double kMaxOriginMm = 1e5;
/// Applied NIfTI scl_slope magnitudes hpcm accepts: [1e-6, 1e6]. Below 1e-6 even the whole
/// int32 range maps into +-2148 HU (a slope of 1e-30 makes every voxel ~0 HU); above 1e6 one
/// stored step is a million HU. nibabel applies any finite non-zero slope; ITK ignores slopes
/// below machine epsilon: hpcm refuses instead of picking either silently.
inline constexpr double kMinSlope = 1e-6, kMaxSlope = 1e6;

/// Throws hpcm::Error "PATH: voxel spacing FIELD = V ..." unless V is finite and within
/// [kMinSpacingMm, kMaxSpacingMm].
void check_spacing_value(const std::string& path, const std::string& field, double v);

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
  std::array<double, 3> quatern{};  ///< quatern_b, quatern_c, quatern_d
  std::array<double, 3> qoffset{};  ///< qoffset_x, y, z (mm, RAS)
  std::array<double, 12> srow{};    ///< srow_x, srow_y, srow_z (4 each; mm, RAS)
};

/// Which NIfTI affine gives the grid, by nibabel's rule (`get_best_affine`): the sform when
/// sform_code > 0, else the qform when qform_code > 0, else pixdim alone as nibabel reads it
/// (`get_base_affine`: diag(-pixdim1, pixdim2, pixdim3), the grid centred on the origin; ITK
/// would put voxel 0 at the origin with y running the other way).
enum class NiftiAffine { Sform, Qform, Pixdim };
NiftiAffine nifti_affine_used(const NiftiHeader& h);
/// The 3x4 index -> RAS mm matrix (row-major) of the qform, the sform or pixdim alone.
std::array<double, 12> nifti_affine(const NiftiHeader& h, NiftiAffine which);
/// Largest distance (mm) between where two affines put the 8 corner voxels of the grid.
double nifti_affine_distance(const NiftiHeader& h, const std::array<double, 12>& a, const std::array<double, 12>& b);
/// The grid of `h` in ITK conventions (LPS) from the affine nibabel uses. Throws hpcm::Error
/// naming `path` when its columns are not orthogonal (a sheared grid hpcm cannot represent).
Geometry nifti_geometry(const std::string& path, const NiftiHeader& h);
/// "sform (sform_code 2)", "qform (qform_code 1)" or "pixdim (qform_code and sform_code 0)",
/// with "; the qform differs" when both are set and place a corner over 1e-3 mm apart.
std::string nifti_geometry_source(const NiftiHeader& h);

/// Size of the NIfTI header at the start of `bytes` (348 or 540), 0 when it is neither.
std::size_t nifti_header_size(const unsigned char* bytes, std::size_t size);

/// Parses and checks a NIfTI-1/-2 header (`size` >= 348, or 540 for NIfTI-2): dimensions,
/// pixdim of the spatial axes within [kMinSpacingMm, kMaxSpacingMm], the qform (when
/// qform_code > 0: quatern_b/c/d finite with b^2+c^2+d^2 <= 1, qoffset finite and within
/// +-kMaxOriginMm) and the sform (when sform_code > 0: finite, column lengths a plausible
/// spacing, translations within +-kMaxOriginMm), a finite scl_inter and a slope within
/// [kMinSlope, kMaxSlope] when scaling is on, a data offset inside the file. Runs before ITK
/// sees the file (ITK hangs on a 3e38 sform). Throws hpcm::Error naming `path` and the field.
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
/// ElementSpacing (within [kMinSpacingMm, kMaxSpacingMm]; ElementSize when no spacing is
/// given), Offset and TransformMatrix finite. Throws hpcm::Error naming `path`.
void check_metaimage_header(const std::string& path, const std::string& text);

/// Checks the header of a .nrrd/.nhdr file (up to the blank line): sizes, and for the last
/// three (spatial) axes spacings and space direction lengths within [kMinSpacingMm,
/// kMaxSpacingMm]; space origin finite. Throws hpcm::Error naming `path`.
void check_nrrd_header(const std::string& path, const std::string& text);

/// The data-file entry of a detached header: MetaImage `ElementDataFile` (its value, "LOCAL"
/// when the data follows the header) or NRRD `data file`/`datafile` ("" when absent: the data
/// is attached). `field` receives the key as written, for messages.
std::string metaimage_data_file(const std::string& text, std::string* field);
std::string nrrd_data_file(const std::string& text, std::string* field);

/// Resolves the data-file entry `entry` (key `field`) of the header `header` and returns the
/// path to read. Refused, naming the entry: a file list or pattern (hpcm reads one data file),
/// a missing file, anything that is not a regular file (a FIFO would block the reader forever,
/// a device never ends; checked without opening it), and a file that (after resolving symbolic
/// links and "..") lies outside the header's folder and its sub-folders.
std::string resolve_data_file(const std::string& header, const std::string& field, const std::string& entry);

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
  /// RescaleIntercept (0028,1052) / RescaleSlope (0028,1053) as written ("" when absent).
  std::string intercept_text, slope_text;
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
/// keep_first_duplicate: the lowest InstanceNumber, then file name, is kept); all or none carry
/// RescaleIntercept and RescaleSlope (values may differ: they are applied per slice); consecutive
/// positions are equally spaced within 1 % and not shifted in-plane. Throws hpcm::Error
/// naming `dir`, the files and their positions.
DicomStack plan_dicom_stack(const std::string& dir, std::vector<DicomSlice> slices, bool keep_first_duplicate);

}  // namespace hpcm::io::detail
