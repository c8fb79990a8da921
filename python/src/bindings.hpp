#pragma once
// Shared pieces of the hpcm Python bindings: the parts that register classes and functions,
// and numpy arrays over lattice data (x fastest in memory, indexed [x, y, z(, component)]).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include "hpcm/hpcm.hpp"

namespace py = pybind11;

namespace hpcm::python {

void bind_volume(py::module_& m);
void bind_params(py::module_& m);
void bind_simulation(py::module_& m);
void bind_io(py::module_& m);

/// A Simulation as Python holds it. A Simulation is not safe to use from two threads at once,
/// and Python threads may call one at once (step and run release the GIL): every call from
/// Python takes the simulation's turn (SimulationTurn) for its length, so calls run one after
/// another.
class GuardedSimulation : public Simulation {
 public:
  using Simulation::Simulation;

 private:
  friend class SimulationTurn;
  std::mutex mutex_;
  std::atomic<std::thread::id> holder_{};  // the thread whose call runs now (none: default id)
};

/// One call's turn on a simulation (RAII). Called with the GIL held. When another thread's call
/// is running, it waits with the GIL released: that call may need the GIL to finish, and the
/// other Python threads go on meanwhile. A call made while the same thread's call holds the turn
/// (a __del__ run by the garbage collector mid-call) raises hpcm.Error instead of waiting for
/// itself forever.
class SimulationTurn {
 public:
  explicit SimulationTurn(GuardedSimulation& sim);
  ~SimulationTurn();
  SimulationTurn(const SimulationTurn&) = delete;
  SimulationTurn& operator=(const SimulationTurn&) = delete;

 private:
  GuardedSimulation& sim_;
};

/// `f(simulation, args...)` as a method that runs in the simulation's turn.
template <class R, class... Args>
auto in_turn(R (*f)(Simulation&, Args...)) {
  return [f](GuardedSimulation& sim, Args... args) -> R {
    SimulationTurn turn(sim);
    return f(sim, std::forward<Args>(args)...);
  };
}

/// A path argument (str or os.PathLike, via std::filesystem::path) that must exist: a missing
/// one raises FileNotFoundError with the path, as Python's own open() does.
std::string existing_path(const std::filesystem::path& path, const char* what);

/// Between the frames of a long call made without the GIL: every kCheckInterval (and after the
/// last frame) takes the GIL to let Ctrl-C through (KeyboardInterrupt, raised as
/// py::error_already_set between two frames, so the simulation stays usable) and to call
/// `progress(done, total)` when one is given.
class BetweenFrames {
 public:
  static constexpr std::chrono::milliseconds kCheckInterval{20};
  BetweenFrames(py::handle progress, long total) : progress_(progress), total_(total) {}
  /// Called without the GIL after frame `done` (1-based).
  void operator()(long done);

 private:
  py::handle progress_;  // a handle: copied without the GIL, it must not touch reference counts
  long total_;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

static_assert(sizeof(Vec3) == 3 * sizeof(float) && std::is_standard_layout_v<Vec3>, "Vec3 is three packed floats");

/// Shape (nx, ny, nz) or (nx, ny, nz, components) and the strides of data stored x fastest.
template <class T>
void lattice_layout(Int3 dims, int components, std::vector<py::ssize_t>& shape, std::vector<py::ssize_t>& strides) {
  const py::ssize_t e = sizeof(T), c = components;
  shape = {dims.x, dims.y, dims.z};
  strides = {c * e, c * e * dims.x, c * e * dims.x * dims.y};
  if (components > 1) shape.push_back(c), strides.push_back(e);
}

/// A view (no copy) of lattice data that `owner` keeps alive; read-only unless `writable`.
template <class T>
py::array lattice_view(const T* data, Int3 dims, int components, py::handle owner, bool writable = false) {
  std::vector<py::ssize_t> shape, strides;
  lattice_layout<T>(dims, components, shape, strides);
  py::array a(py::dtype::of<T>(), shape, strides, data, owner);
  if (!writable) a.attr("setflags")(py::arg("write") = false);
  return a;
}

/// An array that takes over `values` (moved, not copied).
template <class T>
py::array lattice_array(std::vector<T>&& values, Int3 dims, int components) {
  auto* owned = new std::vector<T>(std::move(values));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  std::vector<py::ssize_t> shape, strides;
  lattice_layout<T>(dims, components, shape, strides);
  return py::array(py::dtype::of<T>(), shape, strides, owned->data(), free_when_done);
}

/// A 0/1 mask as a read-only bool array indexed [x, y, z] (a copy).
inline py::array bool_lattice(std::vector<std::uint8_t> mask, Int3 dims) {
  py::array a = lattice_array(std::move(mask), dims, 1).attr("astype")("bool");
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

/// Vec3 buffers as float arrays of 3 components.
inline py::array vec3_array(std::vector<Vec3>&& v, Int3 dims) {
  auto* owned = new std::vector<Vec3>(std::move(v));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<std::vector<Vec3>*>(p); });
  std::vector<py::ssize_t> shape, strides;
  lattice_layout<float>(dims, 3, shape, strides);
  return py::array(py::dtype::of<float>(), shape, strides, reinterpret_cast<const float*>(owned->data()), free_when_done);
}

/// Positions X0 + u (double, exact) of displacements `disp` as a (nx, ny, nz, 3) float64 array.
inline py::array point3_array(const Model& m, const std::vector<Vec3>& disp) {
  auto* owned = new std::vector<Point3>(positions(m, disp));
  py::capsule free_when_done(owned, [](void* p) { delete static_cast<std::vector<Point3>*>(p); });
  std::vector<py::ssize_t> shape, strides;
  lattice_layout<double>(m.dims, 3, shape, strides);
  return py::array(py::dtype::of<double>(), shape, strides, reinterpret_cast<const double*>(owned->data()), free_when_done);
}

inline py::tuple int3_tuple(Int3 v) { return py::make_tuple(v.x, v.y, v.z); }
inline py::tuple vec3_tuple(Vec3 v) { return py::make_tuple(v.x, v.y, v.z); }
/// 3x3 row-major -> numpy (3, 3) (a copy).
py::array_t<double> matrix3(const std::array<double, 9>& m);
std::array<double, 9> matrix3_from(py::handle m, const char* what);

}  // namespace hpcm::python
