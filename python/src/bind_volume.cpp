// Volume (HU + geometry) and the synthetic phantom.
#include <cerrno>
#include <cmath>
#include <sstream>

#include "bindings.hpp"

namespace hpcm::python {

py::array_t<double> matrix3(const std::array<double, 9>& m) {
  py::array_t<double> a({3, 3});
  auto r = a.mutable_unchecked<2>();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r(i, j) = m[static_cast<std::size_t>(i * 3 + j)];
  return a;
}

std::array<double, 9> matrix3_from(py::handle m, const char* what) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(m);
  if (!a || a.ndim() != 2 || a.shape(0) != 3 || a.shape(1) != 3)
    throw Error(std::string(what) + " must be a 3x3 matrix (rows of numbers)");
  std::array<double, 9> out{};
  for (int k = 0; k < 9; ++k) out[static_cast<std::size_t>(k)] = a.data()[k];
  return out;
}

std::string existing_path(const std::filesystem::path& path, const char* what) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    const std::string text = path.string();
    // FileNotFoundError(errno, message, filename): str() shows "[Errno 2] ...: '<path>'".
    PyErr_SetObject(PyExc_FileNotFoundError,
                    py::make_tuple(ENOENT, std::string(what) + " not found", text).ptr());
    throw py::error_already_set();
  }
  return path.string();
}

void BetweenFrames::operator()(long done) {
  const auto now = std::chrono::steady_clock::now();
  if (done < total_ && now - last_ < kCheckInterval) return;
  last_ = now;
  py::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() != 0) throw py::error_already_set();
  if (progress_ && !progress_.is_none()) progress_(done, total_);
}

namespace {

std::array<double, 3> triple(py::handle v, const char* what) {
  const auto a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(v);
  if (!a || a.ndim() != 1 || a.shape(0) != 3) throw Error(std::string(what) + " must be 3 numbers");
  return {a.data()[0], a.data()[1], a.data()[2]};
}

std::string number_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// How far direction columns may be from orthonormal: rounding in files and in user code
// (float32 cosines are good to ~1e-7), not a real shear.
constexpr double kOrthonormalTolerance = 1e-3;

/// The geometry every reader and export assumes: a finite origin and a direction whose columns
/// are orthonormal (a rotation, possibly with a flip); scale belongs in spacing. A NaN origin
/// or a zero or sheared direction would otherwise reach the exports' geometry.
void check_geometry(const Volume& v) {
  for (int a = 0; a < 3; ++a)
    if (!std::isfinite(v.origin[static_cast<std::size_t>(a)]))
      throw Error("Volume: origin[" + std::to_string(a) + "] = " + number_text(v.origin[static_cast<std::size_t>(a)]) +
                  " must be finite (LPS mm)");
  const auto d = [&](int r, int c) { return v.direction[static_cast<std::size_t>(r * 3 + c)]; };
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      if (!std::isfinite(d(r, c)))
        throw Error("Volume: direction[" + std::to_string(r) + "][" + std::to_string(c) + "] = " + number_text(d(r, c)) +
                    " must be finite");
  const std::string rule = "the direction's columns must be orthonormal (unit length, mutually orthogonal, within " +
                           number_text(kOrthonormalTolerance) + "); put the voxel size in spacing";
  for (int a = 0; a < 3; ++a)
    for (int b = a; b < 3; ++b) {
      const double dot = d(0, a) * d(0, b) + d(1, a) * d(1, b) + d(2, a) * d(2, b);
      if (a == b && std::fabs(dot - 1) > kOrthonormalTolerance)
        throw Error("Volume: direction column " + std::to_string(a) + " has length " + number_text(std::sqrt(dot)) +
                    ", not unit: " + rule);
      if (a != b && std::fabs(dot) > kOrthonormalTolerance)
        throw Error("Volume: direction columns " + std::to_string(a) + " and " + std::to_string(b) +
                    " are not orthogonal (dot product " + number_text(dot) + "): " + rule);
    }
}

Volume volume_from_array(const py::array_t<float, py::array::f_style | py::array::forcecast>& hu, py::handle spacing,
                         py::handle origin, py::handle direction) {
  if (hu.ndim() != 3) throw Error("hu must be a 3-D array indexed [x, y, z], got " + std::to_string(hu.ndim()) + " dimensions");
  Volume v;
  v.dims = {static_cast<int>(hu.shape(0)), static_cast<int>(hu.shape(1)), static_cast<int>(hu.shape(2))};
  v.spacing = triple(spacing, "spacing");
  v.origin = triple(origin, "origin");
  v.direction = matrix3_from(direction, "direction");
  check_geometry(v);
  v.hu.assign(hu.data(), hu.data() + hu.size());  // Fortran order: x fastest, as hpcm stores it
  validate_volume(v, "Volume");
  return v;
}

}  // namespace

void bind_volume(py::module_& m) {
  py::class_<Volume>(m, "Volume", R"(A CT volume: HU values and geometry (ITK conventions, LPS millimetres).

Volume(hu, spacing=(1, 1, 1), origin=(0, 0, 0), direction=identity) copies a 3-D array
indexed [x, y, z]; `direction` columns are the physical directions of the index axes.)")
      .def(py::init(&volume_from_array), py::arg("hu"), py::arg("spacing") = py::make_tuple(1.0, 1.0, 1.0),
           py::arg("origin") = py::make_tuple(0.0, 0.0, 0.0),
           py::arg("direction") = py::make_tuple(py::make_tuple(1.0, 0.0, 0.0), py::make_tuple(0.0, 1.0, 0.0),
                                                 py::make_tuple(0.0, 0.0, 1.0)))
      .def_property_readonly("dims", [](const Volume& v) { return int3_tuple(v.dims); }, "voxels per index axis (nx, ny, nz)")
      .def_property_readonly("spacing", [](const Volume& v) { return py::make_tuple(v.spacing[0], v.spacing[1], v.spacing[2]); },
                             "mm per voxel along each index axis")
      .def_property_readonly("origin", [](const Volume& v) { return py::make_tuple(v.origin[0], v.origin[1], v.origin[2]); },
                             "physical position (LPS mm) of voxel (0, 0, 0)")
      .def_property_readonly("direction", [](const Volume& v) { return matrix3(v.direction); },
                             "3x3 matrix, column a = physical (LPS) direction of index axis a (a copy)")
      .def_property_readonly(
          "hu", [](py::object self) {
            const Volume& v = self.cast<const Volume&>();
            // A Volume Python owns (Volume(...), read_volume, phantom) may be edited; one an Input
            // holds (inp.stored, inp.lattice) may not: the exports read it later.
            const bool owned = reinterpret_cast<py::detail::instance*>(self.ptr())->owned;
            return lattice_view(v.hu.data(), v.dims, 1, self, owned);
          },
          "HU values indexed [x, y, z] (float32, a view of the volume's memory, no copy): writable for a Volume "
          "of your own (Volume(...), read_volume, phantom), read-only for one an Input holds (inp.stored, "
          "inp.lattice); np.array(v.hu) gives a writable copy")
      .def_property_readonly(
          "body", [](const Volume& v) -> py::object {
            if (v.body.empty()) return py::none();
            return bool_lattice(v.body, v.dims);
          },
          "The body found on this grid (SPEC §3) indexed [x, y, z], a read-only bool array (a copy); None when "
          "it was not searched (a Volume made from an array). All False: no body (statistics count every element).")
      .def("index_to_physical", [](const Volume& v, double i, double j, double k) {
            const auto p = v.index_to_physical(i, j, k);
            return py::make_tuple(p[0], p[1], p[2]);
          }, py::arg("i"), py::arg("j"), py::arg("k"), "LPS millimetres of a continuous voxel index")
      .def("__repr__", [](const Volume& v) {
        return "<hpcm.Volume " + std::to_string(v.dims.x) + "x" + std::to_string(v.dims.y) + "x" + std::to_string(v.dims.z) +
               ", spacing " + std::to_string(v.spacing[0]) + " x " + std::to_string(v.spacing[1]) + " x " +
               std::to_string(v.spacing[2]) + " mm>";
      });

  m.def("phantom", [](py::handle dims, std::uint64_t seed, float noise_hu, const std::string& variant) {
        const auto d = triple(dims, "dims");
        PhantomOptions o;
        o.dims = {static_cast<int>(d[0]), static_cast<int>(d[1]), static_cast<int>(d[2])};
        o.seed = seed;
        o.noise_hu = noise_hu;
        o.variant = parse_phantom_variant(variant, "variant");
        return make_phantom(o);
      },
      py::arg("dims") = py::make_tuple(128, 128, 75), py::arg("seed") = 1, py::arg("noise_hu") = 12.0f,
      py::arg("variant") = "standard",
      "The built-in synthetic abdominal phantom (LPS index order), deterministic for given options. variant: "
      "'standard', 'thin-tissue', 'thick-fat', 'air-pockets', 'table' or 'anisotropic'.");

  m.def("downsample", &downsample, py::arg("volume"), py::arg("factor"), py::call_guard<py::gil_scoped_release>(),
        "Block mean over complete factor^3 blocks in the volume's own index order (see docs/io.md).");
  m.def("tissue_names", [] {
    py::list names;
    for (int t = 0; t < kTissueCount; ++t) names.append(tissue_name(t));
    return py::tuple(names);
  }, "The tissue classes in label order: ('air', 'skin_fat', 'muscle_organ', 'bone').");
}

}  // namespace hpcm::python
