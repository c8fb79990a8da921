#pragma once
// Medical-image IO on ITK (library hpcm::io, optional): NIfTI, NRRD, MetaImage, DICOM series,
// and the exports of a simulation on the input's own grid.
//
// Two index orders meet here. A file stores its voxels in its own index order (the first index
// of a NIfTI with a RAS affine runs towards the patient's right); the simulation lattice always
// runs in LPS index order (x: right->left, y: anterior->posterior, z: inferior->superior). Everything a
// user gives or gets back (ROI boxes, exported volumes and fields) is in the file's order;
// `Input` carries the mapping between the two from the reader to the writers.
#include <array>
#include <functional>
#include <optional>
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

/// Reads a volume file or a DICOM series directory as stored: values in HU, in the file's own
/// index order (first index fastest; for DICOM: column, row, slice sorted along the slice
/// normal) with the file's geometry (ITK conventions: LPS physical space). Throws
/// hpcm::Error with a message naming the path on any failure: one line, then (only when a
/// library printed something while reading) that library output as indented detail lines.
/// Rejected: non-finite voxels, spacing outside [0.001, 1000] mm, origins beyond 1e5 mm, HU
/// outside [-32768, 65535], implausible NIfTI scaling or qform/sform fields, MetaImage data that
/// does not match its header, data files outside the header's folder or not regular files, and
/// DICOM series whose slices are not one evenly spaced stack or disagree on their rescale tags
/// (docs/io.md, "What is refused, and why"). NIfTI geometry follows nibabel's affine rule.
Volume read_volume_as_stored(const std::string& path, const ReadOptions& opt = {});
/// The same volume reoriented to LPS index order (to_lps_order of the above).
Volume read_volume(const std::string& path, const ReadOptions& opt = {});

/// Which header fields give the grid of a volume file, for `hpcm info` and export.json. NIfTI
/// (nibabel's rule): "sform (sform_code 2)" when sform_code > 0, with "; the qform differs"
/// when the qform is set and places the grid elsewhere; else "qform (qform_code 1)"; else
/// "pixdim (qform_code and sform_code 0)". Other formats: "" (one geometry in the header).
std::string nifti_geometry_source(const std::string& path);

/// How the lattice's LPS index order lies on a grid stored in another index order: LPS axis p
/// (0 = L, 1 = P, 2 = S) runs along stored axis `axis[p]`, backwards when `reversed[p]`.
struct IndexOrder {
  std::array<int, 3> axis{0, 1, 2};
  std::array<bool, 3> reversed{false, false, false};
  bool identity() const;
  friend bool operator==(const IndexOrder&, const IndexOrder&) = default;
};
/// The LPS order of a grid with this direction matrix: each LPS axis takes the stored axis whose
/// direction is closest to it (a permutation), reversed when that axis runs backwards.
IndexOrder lps_order_of(const std::array<double, 9>& direction);

/// A volume stored in any index order, permuted/flipped into LPS index order. Every voxel keeps
/// its physical position: spacing, origin and direction follow (an axis-aligned scan gets the
/// identity direction, an oblique one keeps its small rotation).
Volume to_lps_order(const Volume& stored);

/// A voxel grid (a volume's geometry without its values).
struct Grid {
  Int3 dims;
  std::array<double, 3> spacing{1, 1, 1};
  std::array<double, 3> origin{0, 0, 0};
  std::array<double, 9> direction{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::size_t size() const { return static_cast<std::size_t>(dims.x) * dims.y * dims.z; }
};
Grid grid_of(const Volume& v);

/// Voxel box [lo, hi) in the stored (file) index order; hi exclusive.
struct Box {
  Int3 lo, hi;
};

struct InputOptions {
  std::string series_uid;     ///< DICOM directories with several series
  DicomDuplicates dicom_duplicates = DicomDuplicates::Error;  ///< see ReadOptions
  bool dicom_skip_unreadable = false;                          ///< see ReadOptions
  std::optional<Box> roi;     ///< crop, in the input file's own voxel indices
  int downsample = 1;         ///< block mean of f x f x f voxels, in the file's index order
};

/// A simulation input and everything the exports need to come back to the input's grid.
struct Input {
  std::string source;   ///< path, or a description ("phantom 128x128x75")
  Volume stored;        ///< the input as stored (cropped to the ROI): its own index order and geometry
  Volume lattice;       ///< down-sampled, then in LPS index order: what build_model() takes
  Grid lattice_grid;    ///< the lattice's grid in the stored index order: `stored` coarsened by f
  IndexOrder order;     ///< how the lattice lies on `lattice_grid` (and on `stored`)
  int downsample = 1;
  Box roi;              ///< the ROI applied (the whole volume without --roi), stored indices
  Int3 left_out{};      ///< stored voxels per axis beyond the last full block (not in the lattice)
};

/// How find_body finds the body, as the reports say it.
inline constexpr const char* kBodyMethod =
    "largest 6-connected region of HU >= -500 after a binary opening with a ball of radius 2 lattice units, "
    "its surface within that radius given back, holes filled";
/// The body on a lattice (SPEC §3), with ITK's filters on its grid: threshold HU >= -500, binary
/// opening with a ball of radius 2 elements (cuts contacts up to about 4 elements thin: pads,
/// blankets, cables, the 1-element shells of a table), 6-connected components (the lattice's
/// links), the largest one, a dilation by the same ball kept to HU >= -500 (gives back the
/// body's own surface that the opening shaved off, not the cut contacts beyond its radius), 3D
/// hole filling (lungs, bowel gas). 1 = body, 0 = outside; all 0 when nothing survives the
/// opening (a test object without a body).
std::vector<std::uint8_t> find_body(const Volume& lattice);

/// Crops `stored` to the ROI (its own indices), block-averages by the factor in its own index
/// order (complete blocks only; see downsample()) and reorients the result to LPS order.
/// Throws hpcm::Error naming the setting ("roi", "downsample factor") and the valid range.
Input prepare_input(Volume stored, const InputOptions& opt, const std::string& source);
/// The lattice carries its body (find_body) for build_model().
/// Reads `path` (read_volume_as_stored) and prepares it.
Input load_input(const std::string& path, const InputOptions& opt = {});

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

/// Writes a scalar volume in its own index order and geometry; format from the extension
/// (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd). Atomic: written to a temporary file in the same
/// folder, then renamed.
void write_volume(const Volume& v, const std::string& path);

// --- exports (docs/io.md, docs/slicer.md) ---
// Each checks that `m` is the lattice of `in` (same dims and geometry) and throws otherwise.

/// Forward displacement u = X - X0 of every element in millimetres (LPS components), on
/// `in.lattice_grid` in the input's index order, as a 3-component float vector image (.nii,
/// .nii.gz, .nrrd, .mha). NRRD files carry `displacement field type: modeling`.
void write_displacement_field(const Input& in, const Model& m, const std::vector<Vec3>& disp, const std::string& path);
/// The displacement in millimetres as written by write_displacement_field: 3 floats per voxel
/// of `in.lattice_grid` (interleaved, first index fastest).
std::vector<float> displacement_on_input_grid(const Input& in, const Model& m, const std::vector<Vec3>& disp);
/// Label of the elements outside the body (SPEC §3) in write_label_map.
inline constexpr unsigned char kOutsideLabel = 4;
/// Tissue class label map (uint8: 0 air .. 3 bone for the body's elements, kOutsideLabel = 4
/// "outside" for the rest) on `in.lattice_grid`, with a Slicer colour table (.ctbl) written
/// beside it.
void write_label_map(const Input& in, const Model& m, const std::string& path);

/// Fold check of a displacement field u (millimetres, LPS components, 3 interleaved floats per
/// voxel in the grid's own index order) on grid `g`: the map p -> p + u(p) in physical space.
/// Every cell (8 neighbouring voxels) is a trilinear hexahedron; at each of its 8 corners the
/// Jacobian is I + du/dp from the differences along the cell's three edges at that corner
/// (forward differences at the low corners, backward at the high ones), divided through by the
/// grid's own index-to-millimetre matrix. Its determinant is 1 where nothing moved; a cell with
/// any corner determinant <= 0 is folded (the map turns it inside out there).
struct FieldJacobianStats {
  double min_det = 1;      ///< smallest corner determinant (meaningless when cells == 0)
  Int3 min_det_cell{};     ///< where it is: the cell's first voxel (lowest indices), grid's own order
  Index folded_cells = 0;  ///< cells with a corner determinant <= 0
  Index cells = 0;         ///< cells checked: (nx-1)(ny-1)(nz-1)
};
FieldJacobianStats displacement_jacobian(const Grid& g, const std::vector<float>& u_mm);

/// How well the deformed CT's inverse mapping converged: for each output voxel at x the rest
/// position X solves X + u(X) = x; the residual |X + u(X) - x| left after the last iteration,
/// in millimetres, must stay at or below `tolerance_mm`.
struct InverseMappingStats {
  Index voxels = 0;             ///< output voxels mapped
  Index unconverged = 0;        ///< voxels whose residual exceeds tolerance_mm
  double max_residual_mm = 0;   ///< largest residual over all voxels
  Int3 worst_voxel{};           ///< where it is: voxel index in the output grid's own order
  double tolerance_mm = 0;      ///< the tolerance applied
  int max_iterations = 0;       ///< fixed-point iterations allowed per voxel
  int newton_iterations = 0;    ///< Newton iterations allowed after them where the residual is still too large
};
/// Residual tolerance of the inverse mapping, millimetres.
inline constexpr double kInverseMappingToleranceMm = 0.01;

/// Deformed CT on the grid of `in.stored` (the input cropped to the ROI, never down-sampled),
/// by inverse mapping; voxels whose rest position lies outside the input are air.
InverseMappingStats write_deformed_volume(const Input& in, const Model& m, const std::vector<Vec3>& disp,
                                          const std::string& path);
/// Deformed CT on the grid of `target` (any grid: its index order and geometry).
InverseMappingStats write_deformed_volume(const Volume& target, const Model& m, const std::vector<Vec3>& disp,
                                          const std::string& path);

/// An integer label map (a segmentation: organ masks, a multi-label map) as stored: its grid and
/// raw values in the file's own index order.
struct LabelMap {
  std::string source;               ///< path it was read from
  Grid grid;                        ///< in the file's own index order
  std::string component_type;       ///< ITK's name: "unsigned_char", "short", "int", "unsigned_long_long", ...
  int bytes = 1;                    ///< bytes per voxel
  std::vector<unsigned char> data;  ///< grid.size() * bytes, first index fastest, native byte order
};
/// Reads a 3-D scalar integer label map (NIfTI, NRRD, MetaImage; any signed or unsigned integer
/// type). Throws hpcm::Error naming the path for any other pixel type (float, vector, RGB) and
/// for NIfTI files that scale their values (scl_slope / scl_inter).
LabelMap read_label_map(const std::string& path);
/// The label map on the grid of `in.stored`: as it is when its grid is that one, cropped to
/// `in.roi` when its grid is the whole input file's (an --roi run). Throws hpcm::Error naming
/// both grids otherwise (tolerance 1e-4 mm / 1e-6 of direction).
LabelMap label_map_on_input_grid(LabelMap map, const Input& in);
/// Writes a label map with its own grid and integer type (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd).
void write_label_values(const LabelMap& map, const std::string& path);

/// Everything resampled through one inverse mapping of the deformed lattice onto the grid of
/// `in.stored` (the deformed CT's grid).
struct DeformedOnInputGrid {
  Grid grid;                          ///< in.stored's grid, the input's own index order
  std::vector<float> hu;              ///< deformed CT (trilinear; air outside the input)
  std::vector<float> pullback_mm;     ///< pull-back field v = X - x, mm, LPS components, 3 per voxel
  std::vector<unsigned char> classes; ///< tissue class of the nearest lattice element (air outside)
  std::vector<LabelMap> labels;       ///< each given label map, nearest label (0 outside the input)
  InverseMappingStats stats;          ///< how well the inverse mapping converged
};
/// One inverse mapping (fixed point, then Newton) per output voxel of `in.stored`'s grid, and
/// every export that follows it: the deformed CT, the pull-back field, the deformed class labels
/// and each of `labels` (each must be on in.stored's grid: label_map_on_input_grid).
DeformedOnInputGrid deform_on_input_grid(const Input& in, const Model& m, const std::vector<Vec3>& disp,
                                         const std::vector<LabelMap>& labels = {});
/// Writes a pull-back field (pullback_mm of deform_on_input_grid) on `g` as a 3-component float
/// vector image; NRRD files carry `displacement field type: resampling`.
void write_pullback_field(const Grid& g, const std::vector<float>& pullback_mm, const std::string& path);
/// Writes a tissue class map (uint8) on `g` with its Slicer colour table (.ctbl) beside it.
void write_class_labels(const Grid& g, const std::vector<unsigned char>& classes, const std::string& path);

/// File name of a warped label map: "warped_<name without extension>_<tag><its extension>",
/// e.g. organs.nii.gz -> warped_organs_final.nii.gz.
std::string warped_label_name(const std::string& label_path, const std::string& tag);

/// The figures that say whether an export can be trusted: the field is fold-free and every
/// voxel of the deformed CT found its rest position.
struct ExportIntegrity {
  FieldJacobianStats field;       ///< of the displacement field as written (float32, millimetres)
  InverseMappingStats deformed;   ///< of the deformed CT
  bool fold_free() const { return field.folded_cells == 0; }
  bool converged() const { return deformed.unconverged == 0; }
  bool clean() const { return fold_free() && converged(); }
};

/// The files one export writes into a folder (names as `hpcm run --export` writes them).
struct ExportFiles {
  std::string displacement_nifti;  ///< displacement_<tag>.nii.gz
  std::string displacement_nrrd;   ///< displacement_<tag>.nrrd (empty unless requested)
  std::string deformed;            ///< deformed_<tag><input's extension>
  std::string pullback_nifti;      ///< displacement_pullback_<tag>.nii.gz
  std::string pullback_nrrd;       ///< displacement_pullback_<tag>.nrrd (empty unless requested)
  std::string labels_deformed;     ///< labels_deformed_<tag>.nii.gz (+ .ctbl)
  std::vector<std::string> warped_labels;  ///< warped_label_name of each label map given
  ExportIntegrity integrity;
};
/// Writes the displacement field (NIfTI, and NRRD when `nrrd_field`), and through one inverse
/// mapping the deformed CT, the pull-back field (NIfTI, and NRRD when `nrrd_field`), the deformed
/// class labels and each of `labels` warped, for the displacements `disp` into folder `dir`, tagged
/// `tag` ("final", "0020", ...), and checks them. `labels`: label_map_on_input_grid of each.
ExportFiles export_frame(const Input& in, const Model& m, const std::vector<Vec3>& disp, const std::string& dir,
                         const std::string& tag, bool nrrd_field, const std::vector<LabelMap>& labels = {});
/// What is wrong with an export, one sentence per problem naming the file and the figures;
/// empty when the export is clean.
std::vector<std::string> export_problems(const ExportFiles& f);
/// The extension deformed CTs of this input get (volume_extension_for its source; ".nii.gz"
/// for inputs that are not files, e.g. the phantom).
std::string deformed_extension(const Input& in);

}  // namespace hpcm::io
