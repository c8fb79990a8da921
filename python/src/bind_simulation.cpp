// Simulation (grab / move / release / step), its per-frame reports, ScenarioPlayer and the
// paper's experiment. Lattice arrays are indexed [x, y, z] in the lattice's LPS order.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>
#include <variant>

#include "bindings.hpp"
#include "hpcm/experiment.hpp"

namespace hpcm::python {

namespace {

// Every FrameReport field, once: the attribute of hpcm.FrameReport, the key of to_dict() and
// the column of Simulation.run(). A new field is one line here.
template <class Visit>
void for_each_frame_report_field(Visit&& v) {
  v("frame", &FrameReport::frame, "frame number, from 0");
  v("deform", &FrameReport::deform, "deformation stage (a grab is held); False: idle stage");
  v("grab_offset", &FrameReport::grab_offset, "|tool offset| achieved, lattice units (0 when nothing is held)");
  v("requested_offset", &FrameReport::requested_offset, "|tool offset| the input asked for, lattice units");
  v("grab_offset_mm", &FrameReport::grab_offset_mm, "grab_offset in millimetres (lattice spacing and direction)");
  v("requested_offset_mm", &FrameReport::requested_offset_mm, "requested_offset in millimetres");
  v("tool_limited", &FrameReport::tool_limited, "the tissue could not follow the tool this far: the pull was limited");
  v("restored_links", &FrameReport::restored_links, "links found outside their box at the end of the ChainMail stage (then restored)");
  v("restore_violation", &FrameReport::restore_violation, "the largest of those violations before restoring");
  v("moved_elements", &FrameReport::moved_elements, "elements whose position changed this frame");
  v("active_bricks", &FrameReport::active_bricks, "bricks that had work this frame");
  v("active_elements", &FrameReport::active_elements, "elements in the bricks that had work this frame");
  v("max_link_violation", &FrameReport::max_link_violation, "largest link-box violation after the ChainMail stage; -1: not measured");
  v("min_cell_jacobian", &FrameReport::min_cell_jacobian, "smallest cell corner Jacobian determinant at frame end; -1: not measured");
  v("folded_cells", &FrameReport::folded_cells, "cells with a corner determinant <= 0 at frame end; -1: not measured");
  v("propagate_sweeps", &FrameReport::propagate_sweeps, "propagation sweeps this frame");
  v("relax_sweeps", &FrameReport::relax_sweeps, "relaxation sweeps this frame");
  v("propagate_converged", &FrameReport::propagate_converged, "False when the propagation sweep cap was hit");
  v("restore_converged", &FrameReport::restore_converged, "False when a link-restoration pass hit its cap");
  v("chainmail_ms", &FrameReport::chainmail_ms, "ChainMail stage time (propagate + relax), ms");
  v("inertia_ms", &FrameReport::inertia_ms, "velocity layer time, ms");
  v("snapshot_ms", &FrameReport::snapshot_ms, "buffer copies, ms");
  v("sim_total_ms", &FrameReport::sim_total_ms, "whole frame, ms");
  v("mean_speed", &FrameReport::mean_speed, "mean speed per tissue class (air, skin_fat, muscle_organ, bone), lattice units per frame");
  v("max_speed", &FrameReport::max_speed, "largest speed per tissue class, lattice units per frame");
}

template <class M>
py::object field_value(const M& x) {
  if constexpr (std::is_same_v<M, PerTissue>)
    return py::make_tuple(x[0], x[1], x[2], x[3]);
  else
    return py::cast(x);
}

py::dict report_dict(const FrameReport& r) {
  py::dict d;
  for_each_frame_report_field([&](const char* name, auto member, const char*) { d[name] = field_value(r.*member); });
  return d;
}

/// Columns of many reports: one numpy array per field, (frames,) or (frames, 4) per tissue.
py::dict report_columns(const std::vector<FrameReport>& reports) {
  py::dict d;
  const auto n = static_cast<py::ssize_t>(reports.size());
  for_each_frame_report_field([&](const char* name, auto member, const char*) {
    using M = std::remove_cv_t<std::remove_reference_t<decltype(reports[0].*member)>>;
    if constexpr (std::is_same_v<M, PerTissue>) {
      py::array_t<float> a({n, static_cast<py::ssize_t>(kTissueCount)});
      auto w = a.mutable_unchecked<2>();
      for (py::ssize_t i = 0; i < n; ++i)
        for (int t = 0; t < kTissueCount; ++t) w(i, t) = (reports[static_cast<std::size_t>(i)].*member)[static_cast<std::size_t>(t)];
      d[name] = a;
    } else {
      py::array_t<M> a(n);
      auto w = a.template mutable_unchecked<1>();
      for (py::ssize_t i = 0; i < n; ++i) w(i) = reports[static_cast<std::size_t>(i)].*member;
      d[name] = a;
    }
  });
  return d;
}

py::dict per_tissue_dict(const PerTissue& v) {
  py::dict d;
  for (int t = 0; t < kTissueCount; ++t) d[tissue_name(t)] = v[static_cast<std::size_t>(t)];
  return d;
}

/// A copy of the simulation state whose arrays are views of it.
struct StateSnapshot {
  State state;
  Int3 dims;
};

std::string repr_of(py::handle v) { return py::repr(v).cast<std::string>(); }

/// A numpy array (not a 0-d one) or another sequence that is not a string.
bool is_sequence(py::handle v) {
  if (py::isinstance<py::str>(v) || py::isinstance<py::bytes>(v)) return false;
  if (py::isinstance<py::array>(v)) return py::reinterpret_borrow<py::array>(v).ndim() > 0;
  return PySequence_Check(v.ptr()) == 1;
}

/// A Python number (int, float, numpy scalar) as a double; Error "<what> = <value>: <expected>"
/// for anything else, instead of pybind11's "Unable to cast".
double number_of(py::handle v, const std::string& what, const std::string& expected) {
  if (!is_sequence(v) && !py::isinstance<py::str>(v) && PyNumber_Check(v.ptr())) {
    const double d = PyFloat_AsDouble(v.ptr());
    if (!(d == -1.0 && PyErr_Occurred())) return d;
    PyErr_Clear();
  }
  throw Error(what + " = " + repr_of(v) + ": " + expected);
}

/// The items of a sequence of `n` numbers, or Error naming `what` and what is expected.
std::vector<double> numbers_of(py::handle v, std::size_t n, const std::string& what, const std::string& item,
                               const std::string& expected) {
  if (!is_sequence(v)) throw Error(what + " " + repr_of(v) + ": " + expected);
  const auto seq = py::reinterpret_borrow<py::sequence>(v);
  if (seq.size() != n) throw Error(what + " " + repr_of(v) + ": " + expected);
  std::vector<double> out;
  for (std::size_t k = 0; k < n; ++k) out.push_back(number_of(seq[k], item + " " + std::to_string(k), expected));
  return out;
}

constexpr const char* kCentreForms = "give (x, y, z) as 3 whole numbers (an element's lattice coordinates), an element index or \"auto\"";

/// A grab centre as Python gives it, converted (with the GIL, outside the simulation's turn):
/// "auto", an element index, or element coordinates (x, y, z).
using CentreArg = std::variant<std::monostate, double, std::array<double, 3>>;

CentreArg centre_arg(py::handle centre) {
  if (py::isinstance<py::str>(centre)) {
    if (centre.cast<std::string>() != "auto") throw Error("grab centre '" + centre.cast<std::string>() + "': " + kCentreForms);
    return std::monostate{};
  }
  if (!is_sequence(centre)) return number_of(centre, "grab centre", kCentreForms);
  const auto c = numbers_of(centre, 3, "grab centre", "grab centre coordinate", kCentreForms);
  return std::array<double, 3>{c[0], c[1], c[2]};
}

/// Elements are addressed by whole numbers: the grab is centred on an element (docs/python.md).
void check_whole(double v, const std::string& what, const std::string& shown) {
  if (!std::isfinite(v) || v != std::floor(v))
    throw Error(what + " = " + shown + ": lattice coordinates and element indices are whole numbers (the grab is centred on an element)");
}

std::string number_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

Index element_of(const Model& m, const CentreArg& centre) {
  if (std::holds_alternative<std::monostate>(centre)) return paper_grab_centre(m);
  if (const double* index = std::get_if<double>(&centre)) {
    check_whole(*index, "grab centre index", number_text(*index));
    if (!(*index >= 0 && *index < double(m.size())))
      throw Error("grab centre index " + number_text(*index) + " is out of range [0, " + std::to_string(m.size() - 1) + "]");
    return static_cast<Index>(*index);
  }
  const auto& c = std::get<std::array<double, 3>>(centre);
  const int d[3] = {m.dims.x, m.dims.y, m.dims.z};
  for (int a = 0; a < 3; ++a) {
    const double v = c[static_cast<std::size_t>(a)];
    check_whole(v, "grab centre coordinate " + std::to_string(a), number_text(v));
    if (!(v >= 0 && v < d[a]))
      throw Error("grab centre coordinate " + std::to_string(a) + " = " + number_text(v) + " is out of range [0, " +
                  std::to_string(d[a] - 1) + "]");
  }
  return m.index(int(c[0]), int(c[1]), int(c[2]));
}

StepOptions step_options(bool speeds, bool link_violation, bool cell_jacobian) {
  StepOptions o;
  o.speeds = speeds;
  o.link_violation = link_violation;
  o.cell_jacobian = cell_jacobian;
  return o;
}

/// (dx, dy, dz) of the argument `name` in `unit`; finiteness is Simulation::move_tool's rule.
Vec3 offset_from(py::handle v, const std::string& name, const std::string& unit) {
  const auto c = numbers_of(v, 3, name, name + " component", "give 3 numbers (dx, dy, dz) in " + unit);
  return {static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2])};
}

// Building the model is the long part of the constructor: it runs without the GIL.
std::unique_ptr<GuardedSimulation> make_simulation(const Volume& lattice, const Params& p, const std::string& backend) {
  const BackendKind kind = parse_backend(backend, "backend");
  py::gil_scoped_release release;
  return std::make_unique<GuardedSimulation>(build_model(lattice, p), p, kind);
}

/// A ScenarioPlayer and the simulation it plays on: its calls take that simulation's turn.
struct GuardedPlayer {
  GuardedPlayer(const Scenario& s, GuardedSimulation& simulation) : sim(simulation), player(s, simulation), frames(s.frames) {}
  GuardedSimulation& sim;
  ScenarioPlayer player;
  int frames;  // the scenario's length
};

py::dict condition_dict(const ConditionResult& c) {
  py::dict d;
  d["label"] = c.label;
  d["mode"] = damping_mode_name(c.mode);
  d["initial"] = per_tissue_dict(c.initial);
  d["peak"] = per_tissue_dict(c.peak);
  d["auc"] = per_tissue_dict(c.auc);
  d["chainmail_ms"] = c.chainmail_ms;
  d["inertia_ms"] = c.inertia_ms;
  d["snapshot_ms"] = c.snapshot_ms;
  d["sim_total_ms"] = c.sim_total_ms;
  d["settle_frames"] = c.settle_frames;
  d["settle_max_speed"] = c.settle_max_speed;
  py::dict far;  // SPEC §8.8: share of each class's AUC after release in the far field (None: still)
  for (int t = 0; t < kTissueCount; ++t) {
    const double share = far_field_share(c.far_speed_sum, c.total_speed_sum, t);
    far[tissue_name(t)] = share >= 0 ? py::object(py::float_(share)) : py::object(py::none());
  }
  d["far_field_share"] = far;
  d["finite"] = c.finite;
  d["max_boundary_excess"] = c.max_boundary_excess;
  d["max_bone_velocity"] = c.max_bone_velocity;
  d["max_link_violation"] = c.max_link_violation;
  d["min_cell_jacobian"] = c.min_cell_jacobian;
  d["max_folded_cells"] = c.max_folded_cells;
  d["max_requested_offset"] = c.max_requested_offset;
  d["max_achieved_offset"] = c.max_achieved_offset;
  d["first_limited_frame"] = c.first_limited_frame;
  py::list limited;
  for (const LimitedPull& lp : c.limited_pulls) {
    py::dict l;
    l["first_frame"] = lp.first_frame;
    l["last_frame"] = lp.last_frame;
    l["grab"] = lp.place.grab;
    l["keyframe_segment"] = lp.place.segment;
    l["where"] = lp.place.text;
    l["achieved_offset"] = vec3_tuple(lp.achieved);
    l["requested_offset"] = vec3_tuple(lp.requested);
    limited.append(l);
  }
  d["limited_pulls"] = limited;
  d["centre_rest"] = vec3_tuple(c.centre_rest);
  // Positions X0 + u in double (the track), and the displacements themselves.
  const auto n = static_cast<py::ssize_t>(c.centre_displacement.size());
  py::array_t<double> t({n, py::ssize_t{3}});
  py::array_t<float> u({n, py::ssize_t{3}});
  for (py::ssize_t f = 0; f < n; ++f)
    for (int a = 0; a < 3; ++a) {
      const float ua = c.centre_displacement[static_cast<std::size_t>(f)][a];
      t.mutable_at(f, a) = static_cast<double>(c.centre_rest[a]) + ua;
      u.mutable_at(f, a) = ua;
    }
  d["centre_track"] = t;
  d["centre_displacement"] = u;
  py::array_t<float> v({static_cast<py::ssize_t>(c.centre_velocity.size()), py::ssize_t{3}});
  for (py::ssize_t f = 0; f < static_cast<py::ssize_t>(c.centre_velocity.size()); ++f)
    for (int a = 0; a < 3; ++a) v.mutable_at(f, a) = c.centre_velocity[static_cast<std::size_t>(f)][a];
  d["centre_velocity"] = v;
  d["frames"] = report_columns(c.frames);
  return d;
}

py::dict experiment_dict(const ExperimentResult& r, const Model& m) {
  py::dict d;
  d["dims"] = int3_tuple(r.dims);
  d["elements"] = r.elements;
  d["grab_centre"] = r.grab_centre >= 0 ? py::object(int3_tuple(m.coords(r.grab_centre))) : py::object(py::none());
  d["release_frame"] = r.release_frame;
  d["recorded_frames"] = r.recorded_frames;
  d["params"] = r.params;
  py::dict conditions;
  for (const auto& c : r.conditions) conditions[py::str(c.label)] = condition_dict(c);
  d["conditions"] = conditions;
  py::list checks;
  for (const auto& c : r.checks) {
    py::dict k;
    k["name"] = c.name;
    k["spec"] = c.spec;
    k["status"] = check_status_name(c.status);  // held | failed | not_applicable
    k["holds"] = c.holds();                      // true only when held
    k["value"] = c.value;
    k["reason"] = c.reason;                      // why not applicable (empty otherwise)
    k["threshold"] = c.threshold;
    k["description"] = c.description;
    checks.append(k);
  }
  d["checks"] = checks;
  d["all_hold"] = r.all_hold();  // no check failed
  return d;
}

py::dict run_experiment_py(const Volume& lattice, const Params& given, const Scenario* scenario, int settle_frames,
                           const std::string& backend, py::object progress) {
  // The experiment runs without the GIL: it works on copies, not on objects other Python
  // threads may change meanwhile (the lattice is read only by build_model, here).
  const Params p = given;
  ExperimentOptions opt;
  if (scenario) opt.scenario = *scenario;
  opt.settle_frames = settle_frames;
  opt.backend = parse_backend(backend, "backend");
  // Called after every frame, without the GIL: Ctrl-C stops the experiment there
  // (KeyboardInterrupt); `progress` (a handle: copying the std::function without the GIL must not
  // touch the reference count; it outlives the call) is called per frame.
  BetweenFrames between_frames(py::none(), std::numeric_limits<long>::max());  // checks every 20 ms
  opt.progress = [&between_frames, callback = py::handle(progress)](int condition, int done, int total) {
    if (callback.is_none()) return between_frames(0);
    py::gil_scoped_acquire gil;
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    callback(condition, done, total);
  };
  ExperimentResult r;
  Model model;
  {
    py::gil_scoped_release release;
    model = build_model(lattice, p);
    r = run_experiment(model, p, opt);
  }
  return experiment_dict(r, model);
}

}  // namespace

SimulationTurn::SimulationTurn(GuardedSimulation& sim) : sim_(sim) {
  if (sim.holder_.load() == std::this_thread::get_id())
    throw Error("Simulation: called while this thread's own call to it is still running (e.g. from a __del__ "
                "during that call); call it after that call returns");
  if (!sim.mutex_.try_lock()) {
    py::gil_scoped_release release;
    sim.mutex_.lock();
  }
  sim.holder_.store(std::this_thread::get_id());
}

SimulationTurn::~SimulationTurn() {
  sim_.holder_.store(std::thread::id{});
  sim_.mutex_.unlock();
}

void bind_simulation(py::module_& m) {
  auto report = py::class_<FrameReport>(m, "FrameReport", "What one frame did (read-only). to_dict() gives every field.");
  for_each_frame_report_field([&](const char* name, auto member, const char* doc) {
    report.def_property_readonly(name, [member](const FrameReport& r) { return field_value(r.*member); }, doc);
  });
  report.def("to_dict", &report_dict, "Every field as a dict.").def("__repr__", [](const FrameReport& r) {
    return "<hpcm.FrameReport frame " + std::to_string(r.frame) + (r.deform ? " deform" : " idle") + ", " +
           std::to_string(r.moved_elements) + " moved, " + std::to_string(r.sim_total_ms) + " ms>";
  });

  py::class_<StateSnapshot>(m, "State", "A copy of the simulation state; its arrays are views of this copy.")
      .def_property_readonly("displacements", [](py::object self) {
            auto& s = self.cast<StateSnapshot&>();
            return lattice_view(reinterpret_cast<const float*>(s.state.disp.data()), s.dims, 3, self);
          }, "u = X - X0, lattice units, (nx, ny, nz, 3) float32: what the solver stores")
      .def_property_readonly("velocities", [](py::object self) {
            auto& s = self.cast<StateSnapshot&>();
            return lattice_view(reinterpret_cast<const float*>(s.state.vel.data()), s.dims, 3, self);
          }, "V, lattice units per frame, (nx, ny, nz, 3) float32")
      .def_property_readonly("time", [](py::object self) {
            auto& s = self.cast<StateSnapshot&>();
            return lattice_view(s.state.time.data(), s.dims, 1, self);
          }, "arrival time of the last wave (inf: not reached), (nx, ny, nz) float32")
      .def_property_readonly("flags", [](py::object self) {
            auto& s = self.cast<StateSnapshot&>();
            return lattice_view(s.state.flags.data(), s.dims, 1, self);
          }, "element flags (1 fixed, 2 grabbed, 4 anchor), (nx, ny, nz) uint8");

  // Every method runs in the simulation's turn (in_turn / SimulationTurn): Python threads may
  // share one Simulation, its calls run one after another.
  py::class_<GuardedSimulation>(m, "Simulation", R"(The frame pipeline on one lattice.

Simulation(lattice, params=Params(), backend="cpu"): `lattice` is a Volume in LPS index order
(Input.lattice, read_volume, phantom). Coordinates, offsets and arrays are in lattice units,
indexed [x, y, z] with x right->left, y anterior->posterior (anterior is -y), z inferior->superior.
Several threads may call one Simulation: the calls run one at a time.)")
      .def(py::init(&make_simulation), py::arg("lattice"), py::arg("params") = Params{}, py::arg("backend") = "cpu")
      .def_property_readonly("dims", in_turn(+[](Simulation& s) { return int3_tuple(s.model().dims); }), "elements per lattice axis (nx, ny, nz)")
      .def_property_readonly("size", in_turn(+[](Simulation& s) { return s.model().size(); }), "number of elements")
      .def_property_readonly("spacing", in_turn(+[](Simulation& s) {
            const auto& v = s.model().spacing;
            return py::make_tuple(v[0], v[1], v[2]);
          }), "mm per lattice unit along x, y, z")
      .def_property_readonly("origin", in_turn(+[](Simulation& s) {
            const auto& v = s.model().origin;
            return py::make_tuple(v[0], v[1], v[2]);
          }), "LPS mm of element (0, 0, 0)")
      .def_property_readonly("direction", in_turn(+[](Simulation& s) { return matrix3(s.model().direction); }),
                             "LPS direction cosines of the lattice axes (columns), 3x3")
      .def_property("params", in_turn(+[](Simulation& s) { return s.params(); }),
                    in_turn(+[](Simulation& s, const Params& p) { s.set_params(p); }),
                    "A copy of the parameters; assigning applies new ones (validated).")
      .def_property_readonly("backend", in_turn(+[](Simulation& s) { return backend_name(s.backend().kind()); }), "\"cpu\" or \"cuda\"")
      .def_property_readonly("frame", in_turn(+[](Simulation& s) { return s.frame(); }), "frames stepped so far")
      .def_property_readonly("grabbing", in_turn(+[](Simulation& s) { return s.grabbing(); }), "whether elements are grabbed")
      .def_property_readonly("grab_centre", in_turn(+[](Simulation& s) -> py::object {
            return s.grab_centre() < 0 ? py::object(py::none()) : py::object(int3_tuple(s.model().coords(s.grab_centre())));
          }), "(x, y, z) of the grab centre, None when nothing is grabbed")
      .def_property_readonly("tool_offset", in_turn(+[](Simulation& s) { return vec3_tuple(s.tool_offset()); }),
                             "the offset the grabbed elements follow (the requested one, limited to what the tissue allows)")
      .def_property_readonly("requested_offset", in_turn(+[](Simulation& s) { return vec3_tuple(s.requested_offset()); }),
                             "the tool offset last asked for by move_tool, lattice units")
      .def_property_readonly("tool_limited", in_turn(+[](Simulation& s) { return s.tool_limited(); }),
                             "the tissue could not follow the tool this far: tool_offset is limited")
      .def_property_readonly("tool_limit", in_turn(+[](Simulation& s) {
            return py::make_tuple(vec3_tuple(s.tool_limit_lo()), vec3_tuple(s.tool_limit_hi()));
          }), "feasible tool offsets of the current grab, ((lo x, y, z), (hi x, y, z)), lattice units")
      .def_property_readonly("grabbed", in_turn(+[](Simulation& s) {
            return py::array_t<Index>(static_cast<py::ssize_t>(s.grabbed().size()), s.grabbed().data());
          }), "linear indices (x + nx (y + ny z)) of the grabbed elements (a copy)")
      // Views of the model's arrays: taking one needs no turn (the arrays stay where they are;
      // assigning params rewrites the labels in place).
      .def_property_readonly("hu", [](py::object self) {
            const Model& mdl = self.cast<GuardedSimulation&>().model();
            return lattice_view(mdl.hu.data(), mdl.dims, 1, self);
          }, "HU per element, (nx, ny, nz) float32, read-only view (no copy)")
      .def_property_readonly("labels", [](py::object self) {
            const Model& mdl = self.cast<GuardedSimulation&>().model();
            return lattice_view(mdl.tissue.data(), mdl.dims, 1, self);
          }, "tissue class per element (0 air .. 3 bone), (nx, ny, nz) uint8, read-only view (no copy)")
      .def_property_readonly("body", in_turn(+[](Simulation& s) {
            const Model& mdl = s.model();
            std::vector<std::uint8_t> counted(static_cast<std::size_t>(mdl.size()));
            for (Index i = 0; i < mdl.size(); ++i) counted[static_cast<std::size_t>(i)] = mdl.counted(i) ? 1 : 0;
            return bool_lattice(std::move(counted), mdl.dims);
          }), "elements the per-class statistics count (SPEC §3: the body; every element when there is none), "
             "(nx, ny, nz) read-only bool array (a copy)")
      .def_property_readonly("body_summary", in_turn(+[](Simulation& s) {
            const BodySummary& b = s.model().body;
            py::dict d;
            d["search"] = b.search == BodySummary::Search::Found ? "found"
                          : b.search == BodySummary::Search::NoBody ? "none" : "not searched";
            d["counted_elements"] = b.body;
            d["outside_air"] = b.outside_air;
            d["outside_objects"] = b.outside_objects;
            d["why"] = b.describe();
            return d;
          }), "how many elements were left out of the statistics (outside air, anchored outside objects) and why")
      .def("paper_grab_centre", in_turn(+[](Simulation& s) { return int3_tuple(s.model().coords(paper_grab_centre(s.model()))); }),
           "The paper's grab point: the anterior body surface on the central axial slice, x = nx/2.")
      .def("grab", [](GuardedSimulation& s, py::handle centre, std::optional<float> radius, std::optional<float> radius_mm) {
            if (radius && radius_mm) throw Error("grab: give radius (lattice units) or radius_mm (millimetres), not both");
            const CentreArg c = centre_arg(centre);  // Python objects first, outside the turn
            SimulationTurn turn(s);
            if (radius_mm) s.grab_mm(element_of(s.model(), c), *radius_mm);
            else s.grab(element_of(s.model(), c), radius.value_or(0.0f));
          },
           py::arg("centre") = "auto", py::arg("radius") = py::none(), py::arg("radius_mm") = py::none(),
           "Grab every element within `radius` (lattice units, [0, 64]; 0 or neither: solver.grab_radius) or "
           "`radius_mm` (millimetres, > 0; an ellipsoid on an anisotropic lattice) of `centre`: (x, y, z) (whole "
           "numbers), an element index, or \"auto\" (the paper's grab point).")
      .def("move_tool", [](GuardedSimulation& s, py::handle offset, py::handle offset_mm) {
            if (offset.is_none() == offset_mm.is_none())
              throw Error("move_tool: give the tool offset (lattice units) or offset_mm (millimetres), exactly one");
            const bool mm = offset.is_none();
            const Vec3 o = mm ? offset_from(offset_mm, "tool offset_mm", "millimetres")
                              : offset_from(offset, "tool offset", "lattice units");
            SimulationTurn turn(s);
            // Without a grab there is nothing to move: say so rather than do nothing.
            if (!s.grabbing()) throw Error("move_tool: nothing is grabbed; call grab(...) first");
            s.move_tool(mm ? lattice_offset_of_mm(s.model(), o) : o);
          },
           py::arg("offset") = py::none(), py::arg("offset_mm") = py::none(),
           "Move the grabbed elements to their grab positions + offset: `offset` in lattice units or `offset_mm` "
           "in millimetres along the lattice axes (LPS; divided by the lattice spacing per axis), exactly one.")
      .def("release", in_turn(+[](Simulation& s) { s.release(); }), "Let go of the grabbed elements.")
      .def("step", in_turn(+[](Simulation& s, bool speeds, bool link_violation, bool cell_jacobian) {
            const StepOptions o = step_options(speeds, link_violation, cell_jacobian);
            py::gil_scoped_release release;
            return s.step(o);
          }), py::arg("speeds") = true, py::arg("link_violation") = false, py::arg("cell_jacobian") = false,
          "One frame; returns its FrameReport. link_violation / cell_jacobian: also measure those (O(N) each).")
      .def("run", [](GuardedSimulation& s, int frames, bool speeds, bool link_violation, bool cell_jacobian,
                     py::handle progress) {
            if (frames < 0) throw Error("frames " + std::to_string(frames) + " must be >= 0");
            const StepOptions o = step_options(speeds, link_violation, cell_jacobian);
            std::vector<FrameReport> reports;
            reports.reserve(static_cast<std::size_t>(frames));
            {
              SimulationTurn turn(s);
              BetweenFrames between_frames(progress, frames);
              py::gil_scoped_release release;
              for (int f = 0; f < frames; ++f) {
                reports.push_back(s.step(o));
                between_frames(f + 1);  // Ctrl-C: KeyboardInterrupt here, after a whole frame
              }
            }
            return report_columns(reports);
          }, py::arg("frames"), py::arg("speeds") = true, py::arg("link_violation") = false, py::arg("cell_jacobian") = false,
          py::arg("progress") = py::none(),
          "`frames` frames with the tool as it is; returns per-frame statistics as numpy columns "
          "(one array per FrameReport field). progress(done, total) is called every 20 ms and after the last "
          "frame (hpcm.Simulation.run also takes progress=True: a tqdm bar). Ctrl-C stops it between two frames "
          "with KeyboardInterrupt; the frames done stay done.")
      .def("reset", in_turn(+[](Simulation& s) { s.reset(); }), "Back to rest (X = X0, V = 0), grab released, frame 0.")
      .def("positions", in_turn(+[](Simulation& s) {
            std::vector<Vec3> disp;
            s.backend().download_displacements(disp);
            return point3_array(s.model(), disp);
          }), "X = X0 + u in lattice units, (nx, ny, nz, 3) float64 (exact: computed in double from the displacements)")
      .def("displacement", in_turn(+[](Simulation& s) {
            std::vector<Vec3> disp;
            s.backend().download_displacements(disp);
            return vec3_array(std::move(disp), s.model().dims);
          }), "u = X - X0 in lattice units, (nx, ny, nz, 3) float32: what the solver stores, one copy out of the "
              "backend (see displacement_mm for millimetres)")
      .def("state", in_turn(+[](Simulation& s) {
            auto snap = std::make_unique<StateSnapshot>();
            s.backend().download(snap->state);
            snap->dims = s.model().dims;
            return snap;
          }), "A copy of the whole state (displacements from rest, velocities, times, flags) as a State.")
      .def("velocities", in_turn(+[](Simulation& s) {
            State st;
            s.backend().download(st);
            return vec3_array(std::move(st.vel), s.model().dims);
          }), "V in lattice units per frame, (nx, ny, nz, 3) float32 (one copy out of the backend)");

  py::class_<GuardedPlayer>(m, "ScenarioPlayer",
                            "Plays a Scenario frame by frame on a Simulation (its calls take the simulation's turn).")
      .def(py::init([](const Scenario& scenario, GuardedSimulation& sim) {
             SimulationTurn turn(sim);
             return std::make_unique<GuardedPlayer>(scenario, sim);
           }),
           py::arg("scenario"), py::arg("simulation"), py::keep_alive<1, 3>())
      .def_property_readonly("done", [](GuardedPlayer& p) {
            SimulationTurn turn(p.sim);
            return p.player.done();
          }, "whether every frame of the scenario has been played")
      .def_property_readonly("frame", [](GuardedPlayer& p) {
            SimulationTurn turn(p.sim);
            return p.player.frame();
          }, "the scenario frame played next")
      .def("step", [](GuardedPlayer& p, bool speeds, bool link_violation, bool cell_jacobian) {
            const StepOptions o = step_options(speeds, link_violation, cell_jacobian);
            SimulationTurn turn(p.sim);
            py::gil_scoped_release release;
            return p.player.step(o);
          }, py::arg("speeds") = true, py::arg("link_violation") = false, py::arg("cell_jacobian") = false,
          "Applies this frame's input (grab / move / release) and steps the simulation.")
      .def("run", [](GuardedPlayer& p, int frames, bool speeds, bool link_violation, bool cell_jacobian,
                     py::handle progress) {
            if (frames < -1) throw Error("frames " + std::to_string(frames) + " must be >= 0 (or -1: to the scenario's end)");
            const StepOptions o = step_options(speeds, link_violation, cell_jacobian);
            std::vector<FrameReport> reports;
            SimulationTurn turn(p.sim);
            const long left = p.player.done() ? 0 : std::max<long>(0, p.frames - p.player.frame());
            const long total = frames < 0 ? left : std::min<long>(frames, left);
            {
              BetweenFrames between_frames(progress, total);
              py::gil_scoped_release release;
              for (long f = 0; f < total && !p.player.done(); ++f) {
                reports.push_back(p.player.step(o));
                between_frames(f + 1);  // Ctrl-C: KeyboardInterrupt here, after a whole frame
              }
            }
            return report_columns(reports);
          }, py::arg("frames") = -1, py::arg("speeds") = true, py::arg("link_violation") = false,
          py::arg("cell_jacobian") = false, py::arg("progress") = py::none(),
          "Plays `frames` frames (-1: to the scenario's end) and returns their statistics as numpy columns, as "
          "Simulation.run does (progress, Ctrl-C between frames: the same).");

  m.def("run_experiment", &run_experiment_py, py::arg("lattice"), py::arg("params") = Params{},
        py::arg("scenario") = nullptr, py::arg("settle_frames") = 2000, py::arg("backend") = "cpu",
        py::arg("progress") = py::none(),
        R"(The paper's experiment: conditions A (none), B (simple), C (viscoelastic) on identical input.

Returns a dict: dims, elements, grab_centre, release_frame, recorded_frames, params,
conditions {"A"|"B"|"C": {initial, peak, auc (per tissue), stage times in ms, settle checks,
far_field_share (per tissue, SPEC 8.8; None: still), centre_track (frames, 3), frames (numpy
columns)}}, checks [{name, spec, status
(held | failed | not_applicable), holds, value, threshold, description, reason}], all_hold (no
check failed). progress(condition, done, total) is called per frame.)");
  m.def("report_columns", &report_columns, py::arg("reports"), "FrameReports -> numpy columns (as Simulation.run gives).");
}

}  // namespace hpcm::python
