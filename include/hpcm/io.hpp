#pragma once
// Medical-image IO on ITK (library hpcm::io, optional): NIfTI, NRRD, MetaImage, DICOM series.
// Volumes are reoriented to LPS index order on read (SPEC §2).
#include <functional>
#include <string>
#include <vector>

#include "hpcm/model.hpp"
#include "hpcm/volume.hpp"

namespace hpcm::io {

/// What to do with DICOM slices that lie at the same position.
enum class DicomDuplicates {
  Error,  ///< refuse the series, naming the files (default)
  First,  ///< keep the slice with the lowest InstanceNumber (then file name), drop the others
};

struct ReadOptions {
  std::string series_uid;  ///< DICOM directories with several series: which one
  DicomDuplicates dicom_duplicates = DicomDuplicates::Error;
  /// Skip files of a DICOM directory that are not readable DICOM instead of refusing the
  /// directory (they are reported as a warning; a slice missing from the stack is still an error).
  bool dicom_skip_unreadable = false;
  /// Receives warnings (a volume read but worth a second look: HU outside the CT range, skipped
  /// files). Empty: printed to stderr as "hpcm: warning: ...".
  std::function<void(const std::string&)> warn;
};

/// Reads a volume file or a DICOM series directory; values in HU. Throws hpcm::Error with a
/// message naming the path on any failure: one line, then (only when a library printed
/// something while reading) that library output as indented detail lines. Rejected: non-finite
/// voxels, spacing that is zero, negative or not finite, HU outside [-32768, 65535], and DICOM
/// series whose slices are not one evenly spaced stack (docs/io.md).
Volume read_volume(const std::string& path, const ReadOptions& opt = {});

/// Checks that `path` can be written as a volume (supported extension, an existing writable
/// folder, no other file's data in the way) without writing anything: for commands that must
/// fail before a long computation.
void check_output_path(const std::string& path);

/// One series of a DICOM directory (for listing and --series).
struct DicomSeriesInfo {
  std::string uid;          ///< SeriesInstanceUID (what --series takes)
  std::string modality;     ///< e.g. "CT"
  std::string description;  ///< SeriesDescription, may be empty
  int files = 0;            ///< number of image files (slices)
  int rows = 0, columns = 0;
};
/// Lists the series of a DICOM directory (non-recursive). Throws hpcm::Error naming the path
/// when it is not a directory, is empty or holds no DICOM image.
std::vector<DicomSeriesInfo> list_dicom_series(const std::string& dir);

/// True for the extensions write_volume accepts (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd).
bool is_supported_volume_extension(const std::string& path);
/// The file extension an export of `input` should use so that it keeps the input's format:
/// ".nii.gz", ".nii", ".nrrd", ".nhdr", ".mha" or ".mhd"; for a DICOM series directory (and
/// anything else) ".nrrd" (DICOM export is not supported; NRRD keeps the full geometry).
std::string volume_extension_for(const std::string& input);

/// Writes a scalar volume; format from the extension (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd).
/// Atomic: written to a temporary file in the same folder, then renamed.
void write_volume(const Volume& v, const std::string& path);

// --- exports for 3D Slicer (SPEC §9, docs/slicer.md) ---
/// Displacement field u = X - X0 in millimetres (physical LPS), on the simulated lattice's
/// physical grid, as a 3-component float vector image (.nii, .nii.gz or .nrrd).
void write_displacement_field(const Model& m, const std::vector<Vec3>& pos, const std::string& path);
/// Deformed CT resampled onto the original input grid (inverse mapping; outside keeps air),
/// written in the format given by the extension with the original geometry.
void write_deformed_volume(const Volume& original, const Model& m, const std::vector<Vec3>& pos,
                           const std::string& path);
/// Tissue class label map (uint8: 0 air .. 3 bone) with a Slicer colour table written beside it.
void write_label_map(const Model& m, const std::string& path);

}  // namespace hpcm::io
