// Medical-image IO and the exports (hpcm::io, when hpcm was built with ITK). An Input carries
// the input's own grid and index order; exports and displacement_mm() come back on it.
#include "bindings.hpp"
#if defined(HPCM_WITH_ITK)
#include "hpcm/io.hpp"
#endif

namespace hpcm::python {

#if defined(HPCM_WITH_ITK)
namespace {

std::optional<io::Box> roi_from(py::handle roi) {
  if (roi.is_none()) return std::nullopt;
  const auto r = roi.cast<std::vector<long long>>();
  if (r.size() != 6) throw Error("roi must be 6 integers (x0, y0, z0, x1, y1, z1): voxel indices of the input as stored, upper bounds exclusive");
  for (long long v : r)
    if (v < 0 || v > 1'000'000'000) throw Error("roi value " + std::to_string(v) + " is out of range [0, 1000000000]");
  return io::Box{{int(r[0]), int(r[1]), int(r[2])}, {int(r[3]), int(r[4]), int(r[5])}};
}

io::InputOptions input_options(int downsample, py::handle roi, const std::string& series) {
  io::InputOptions o;
  o.downsample = downsample;
  o.roi = roi_from(roi);
  o.series_uid = series;
  return o;
}

py::dict grid_dict(const io::Grid& g) {
  py::dict d;
  d["dims"] = int3_tuple(g.dims);
  d["spacing"] = py::make_tuple(g.spacing[0], g.spacing[1], g.spacing[2]);
  d["origin"] = py::make_tuple(g.origin[0], g.origin[1], g.origin[2]);
  d["direction"] = matrix3(g.direction);
  return d;
}

// Called in the simulation's turn (SimulationTurn): another thread may be stepping it.
const std::vector<Vec3>& displacements_of(Simulation& sim) { return sim.state().disp; }

/// A label map's values as a numpy array of its own integer type, indexed [x, y, z] in the
/// file's own index order (no copy: the array owns the moved map).
py::array label_array(io::LabelMap&& map) {
  const bool is_signed = map.component_type.rfind("unsigned", 0) != 0;
  const py::dtype dt((is_signed ? "i" : "u") + std::to_string(map.bytes));
  auto* owned = new io::LabelMap(std::move(map));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<io::LabelMap*>(p); });
  const py::ssize_t b = owned->bytes, nx = owned->grid.dims.x, ny = owned->grid.dims.y, nz = owned->grid.dims.z;
  return py::array(dt, {nx, ny, nz}, {b, b * nx, b * nx * ny}, owned->data.data(), free_when_done);
}

}  // namespace

void bind_io(py::module_& m) {
  py::class_<io::Input>(m, "Input", R"(A simulation input and what the exports need to come back to its grid.

stored: the input as stored (cropped to roi), in the file's own index order and geometry.
lattice: down-sampled and reoriented to LPS index order -- give it to Simulation.
lattice_grid: the lattice's grid in the file's index order (stored coarsened by downsample).
order: {"axis", "reversed"}: LPS axis p runs along stored axis axis[p], backwards if reversed[p].)")
      .def_readonly("source", &io::Input::source, "the path read, or a description (\"phantom 128x128x75\")")
      .def_readonly("stored", &io::Input::stored, "the input as stored (cropped to roi), in the file's own index order and geometry")
      .def_readonly("lattice", &io::Input::lattice, "down-sampled and reoriented to LPS index order: give it to Simulation")
      .def_property_readonly("body", [](const io::Input& in) { return bool_lattice(in.lattice.body, in.lattice.dims); },
                             "the body on the lattice (SPEC §3), indexed [x, y, z] in LPS order: read-only bool array "
                             "(a copy); elements outside it are left out of every per-class statistic")
      .def_property_readonly("lattice_grid", [](const io::Input& in) { return grid_dict(in.lattice_grid); },
                             "the lattice's grid in the file's index order (stored coarsened by downsample), a dict")
      .def_property_readonly("order", [](const io::Input& in) {
            py::dict d;
            d["axis"] = py::make_tuple(in.order.axis[0], in.order.axis[1], in.order.axis[2]);
            d["reversed"] = py::make_tuple(in.order.reversed[0], in.order.reversed[1], in.order.reversed[2]);
            return d;
          }, "{\"axis\", \"reversed\"}: LPS axis p runs along stored axis axis[p], backwards if reversed[p]")
      .def_readonly("downsample", &io::Input::downsample, "the down-sampling factor (stored voxels per lattice unit and axis)")
      .def_property_readonly("roi", [](const io::Input& in) {
            return py::make_tuple(in.roi.lo.x, in.roi.lo.y, in.roi.lo.z, in.roi.hi.x, in.roi.hi.y, in.roi.hi.z);
          }, "the stored box of the file, (x0, y0, z0, x1, y1, z1) voxels, upper bounds exclusive")
      .def_property_readonly("left_out", [](const io::Input& in) { return int3_tuple(in.left_out); },
                             "stored voxels per axis beyond the last complete down-sampling block");

  // Paths are str or os.PathLike (std::filesystem::path); a missing input raises
  // FileNotFoundError. The reads, writes and exports run without the GIL: other Python threads
  // go on meanwhile.
  m.def("read_volume", [](const std::filesystem::path& path, const std::string& series) {
        const std::string file = existing_path(path, "volume");
        io::ReadOptions o;
        o.series_uid = series;
        py::gil_scoped_release release;
        return io::read_volume(file, o);
      }, py::arg("path"), py::arg("series") = "", "A volume file or DICOM directory, reoriented to LPS index order.");
  m.def("read_volume_as_stored", [](const std::filesystem::path& path, const std::string& series) {
        const std::string file = existing_path(path, "volume");
        io::ReadOptions o;
        o.series_uid = series;
        py::gil_scoped_release release;
        return io::read_volume_as_stored(file, o);
      }, py::arg("path"), py::arg("series") = "", "A volume file or DICOM directory in the file's own index order.");
  m.def("write_volume", [](const Volume& volume, const std::filesystem::path& path) {
        io::write_volume(volume, path.string());
      }, py::arg("volume"), py::arg("path"), py::call_guard<py::gil_scoped_release>(),
        "Writes a volume (.nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd) in its own index order and geometry.");
  m.def("load_input", [](const std::filesystem::path& path, int downsample, py::handle roi, const std::string& series) {
        const std::string file = existing_path(path, "input");
        const io::InputOptions o = input_options(downsample, roi, series);
        py::gil_scoped_release release;
        return io::load_input(file, o);
      }, py::arg("path"), py::arg("downsample") = 1, py::arg("roi") = py::none(), py::arg("series") = "",
      "Reads a CT (file or DICOM directory), crops to roi (x0, y0, z0, x1, y1, z1 in the file's own voxel "
      "indices, upper bounds exclusive), block-averages by `downsample` in the file's index order and "
      "reorients to LPS. Returns an Input.");
  m.def("prepare_input", [](const Volume& stored, int downsample, py::handle roi, const std::string& source) {
        const io::InputOptions o = input_options(downsample, roi, "");
        py::gil_scoped_release release;
        return io::prepare_input(stored, o, source);
      }, py::arg("stored"), py::arg("downsample") = 1, py::arg("roi") = py::none(), py::arg("source") = "array",
      "As load_input, for a Volume given in its own index order (e.g. phantom()).");
  m.def("list_dicom_series", [](const std::filesystem::path& dir) {
        const std::string folder = existing_path(dir, "DICOM directory");
        std::vector<io::DicomSeriesInfo> series;
        {
          py::gil_scoped_release release;
          series = io::list_dicom_series(folder);
        }
        py::list out;
        for (const auto& s : series) {
          py::dict d;
          d["uid"] = s.uid;
          d["modality"] = s.modality;
          d["description"] = s.description;
          d["files"] = s.files;
          d["rows"] = s.rows;
          d["columns"] = s.columns;
          out.append(d);
        }
        return out;
      }, py::arg("directory"), "The DICOM series in `directory`: a list of dicts (uid, modality, description, files, rows, columns).");

  // The exports read a simulation that other Python threads may be stepping: each takes the
  // simulation's turn, then compute without the GIL.
  m.def("displacement_mm", [](const io::Input& in, GuardedSimulation& sim) {
        SimulationTurn turn(sim);
        std::vector<float> u;
        {
          py::gil_scoped_release release;
          u = io::displacement_on_input_grid(in, sim.model(), displacements_of(sim));
        }
        return lattice_array(std::move(u), in.lattice_grid.dims, 3);
      }, py::arg("input"), py::arg("simulation"),
      "Forward displacement X - X0 in millimetres (LPS components) on input.lattice_grid, indexed in the "
      "input's own order: exactly what write_displacement_field writes.");
  m.def("write_displacement_field", [](const io::Input& in, GuardedSimulation& sim, const std::filesystem::path& path) {
        SimulationTurn turn(sim);
        py::gil_scoped_release release;
        io::write_displacement_field(in, sim.model(), displacements_of(sim), path.string());
      }, py::arg("input"), py::arg("simulation"), py::arg("path"), "Writes displacement_mm(input, simulation) to `path` (.nii, .nii.gz, .nrrd, .mha by its extension).");
  m.def("write_label_map", [](const io::Input& in, GuardedSimulation& sim, const std::filesystem::path& path) {
        SimulationTurn turn(sim);
        py::gil_scoped_release release;
        io::write_label_map(in, sim.model(), path.string());
      }, py::arg("input"), py::arg("simulation"), py::arg("path"), "Writes the tissue class label map (uint8: 0 air .. 3 bone, 4 outside the body) on input.lattice_grid to `path`, a Slicer colour table (.ctbl) beside it.");
  m.def("write_deformed_volume", [](const io::Input& in, GuardedSimulation& sim, const std::filesystem::path& path) {
        SimulationTurn turn(sim);
        py::gil_scoped_release release;
        io::write_deformed_volume(in, sim.model(), displacements_of(sim), path.string());
      }, py::arg("input"), py::arg("simulation"), py::arg("path"), "Writes the deformed CT on input.stored's grid to `path` by inverse mapping (air where the rest position lies outside).");
  m.def("export_frame", [](const io::Input& in, GuardedSimulation& sim, const std::filesystem::path& folder,
                           const std::string& tag, bool nrrd_field) {
        SimulationTurn turn(sim);
        io::ExportFiles f;
        {
          py::gil_scoped_release release;
          f = io::export_frame(in, sim.model(), displacements_of(sim), folder.string(), tag, nrrd_field);
        }
        py::dict d;
        d["displacement_nifti"] = f.displacement_nifti;
        d["displacement_nrrd"] = f.displacement_nrrd.empty() ? py::object(py::none()) : py::object(py::str(f.displacement_nrrd));
        d["deformed"] = f.deformed;
        d["pullback_nifti"] = f.pullback_nifti;
        d["pullback_nrrd"] = f.pullback_nrrd.empty() ? py::object(py::none()) : py::object(py::str(f.pullback_nrrd));
        d["labels_deformed"] = f.labels_deformed;
        const io::ExportIntegrity& ig = f.integrity;
        py::dict jac, inv;
        jac["cells"] = ig.field.cells;
        jac["folded_cells"] = ig.field.folded_cells;
        jac["min_det"] = ig.field.cells > 0 ? py::object(py::float_(ig.field.min_det)) : py::object(py::none());
        inv["voxels"] = ig.deformed.voxels;
        inv["unconverged"] = ig.deformed.unconverged;
        inv["max_residual_mm"] = ig.deformed.max_residual_mm;
        inv["tolerance_mm"] = ig.deformed.tolerance_mm;
        d["displacement_jacobian"] = jac;
        d["inverse_mapping"] = inv;
        d["problems"] = io::export_problems(f);
        return d;
      }, py::arg("input"), py::arg("simulation"), py::arg("folder"), py::arg("tag") = "final", py::arg("nrrd") = true,
      "Writes displacement_<tag>.nii.gz (+ .nrrd) and deformed_<tag><input's extension> into `folder`, "
      "as `hpcm run --export` does; returns the paths, the field's Jacobian check (displacement_jacobian), the "
      "deformed CT's inverse-mapping residuals (inverse_mapping) and the problems found (empty when clean).");

  m.def("warp_labels", [](const io::Input& in, GuardedSimulation& sim, const std::filesystem::path& labels,
                          std::optional<std::filesystem::path> path) {
        const std::string labels_file = existing_path(labels, "label map");
        io::LabelMap map;
        {
          py::gil_scoped_release release;
          map = io::label_map_on_input_grid(io::read_label_map(labels_file), in);
        }
        SimulationTurn turn(sim);
        io::DeformedOnInputGrid d;
        {
          py::gil_scoped_release release;
          d = io::deform_on_input_grid(in, sim.model(), displacements_of(sim), {map});
          if (path) io::write_label_values(d.labels[0], path->string());
        }
        return label_array(std::move(d.labels[0]));
      }, py::arg("input"), py::arg("simulation"), py::arg("labels"), py::arg("path") = py::none(),
      "Deforms the label map file `labels` (NIfTI/NRRD/MetaImage, any integer type, on the input's grid: "
      "input.stored's, or the whole file's for an roi input) by nearest label through the deformed CT's inverse "
      "mapping (0 where the rest position lies outside the input). Returns the deformed labels, same dtype, "
      "indexed [x, y, z] in the input's own order; writes them to `path` (same type) when given. "
      "A float label map or one on another grid raises hpcm.Error naming both grids.");
  m.def("pullback_mm", [](const io::Input& in, GuardedSimulation& sim) {
        SimulationTurn turn(sim);
        io::DeformedOnInputGrid d;
        {
          py::gil_scoped_release release;
          d = io::deform_on_input_grid(in, sim.model(), displacements_of(sim));
        }
        return lattice_array(std::move(d.pullback_mm), d.grid.dims, 3);
      }, py::arg("input"), py::arg("simulation"),
      "Pull-back (resampling) displacement v = X - x in millimetres (LPS components) on input.stored's grid, "
      "indexed in the input's own order: the deformed CT at x is the input at x + v(x). What "
      "displacement_pullback_<tag>.nii.gz holds.");
}
#else
void bind_io(py::module_&) {}
#endif

}  // namespace hpcm::python
