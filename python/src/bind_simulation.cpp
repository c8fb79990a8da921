// Simulation (grab / move / release / step), its per-frame reports, ScenarioPlayer and the
// paper's experiment. Lattice arrays are indexed [x, y, z] in the lattice's LPS order.
#include <cstring>
#include <string>

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

Index element_of(const Simulation& sim, py::handle centre) {
  const Model& m = sim.model();
  if (py::isinstance<py::str>(centre)) {
    if (centre.cast<std::string>() != "auto") throw Error("grab centre '" + centre.cast<std::string>() + "': give (x, y, z), an element index or \"auto\"");
    return paper_grab_centre(m);
  }
  if (py::isinstance<py::int_>(centre)) return centre.cast<Index>();
  const auto c = centre.cast<std::vector<long long>>();
  if (c.size() != 3) throw Error("grab centre must be (x, y, z) lattice coordinates, an element index or \"auto\"");
  const int d[3] = {m.dims.x, m.dims.y, m.dims.z};
  for (int a = 0; a < 3; ++a)
    if (c[static_cast<std::size_t>(a)] < 0 || c[static_cast<std::size_t>(a)] >= d[a])
      throw Error("grab centre coordinate " + std::to_string(a) + " = " + std::to_string(c[static_cast<std::size_t>(a)]) +
                  " is out of range [0, " + std::to_string(d[a] - 1) + "]");
  return m.index(int(c[0]), int(c[1]), int(c[2]));
}

StepOptions step_options(bool speeds, bool link_violation, bool cell_jacobian) {
  StepOptions o;
  o.speeds = speeds;
  o.link_violation = link_violation;
  o.cell_jacobian = cell_jacobian;
  return o;
}

Vec3 vec3_from(py::handle v, const char* what) {
  const auto c = v.cast<std::vector<float>>();
  if (c.size() != 3) throw Error(std::string(what) + " must be 3 numbers (dx, dy, dz) in lattice units");
  return {c[0], c[1], c[2]};
}

std::unique_ptr<Simulation> make_simulation(const Volume& lattice, const Params& p, const std::string& backend) {
  return std::make_unique<Simulation>(build_model(lattice, p), p, parse_backend(backend, "backend"));
}

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
  std::vector<Vec3> track = c.centre_track;
  const auto n = static_cast<py::ssize_t>(track.size());
  py::array_t<float> t({n, py::ssize_t{3}});
  std::memcpy(t.mutable_data(), track.data(), track.size() * sizeof(Vec3));
  d["centre_track"] = t;
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
    k["holds"] = c.holds;
    k["value"] = c.value;
    k["threshold"] = c.threshold;
    k["description"] = c.description;
    checks.append(k);
  }
  d["checks"] = checks;
  d["all_hold"] = r.all_hold();
  return d;
}

py::dict run_experiment_py(const Volume& lattice, const Params& p, const Scenario* scenario, int settle_frames,
                           const std::string& backend, py::object progress) {
  const Model model = build_model(lattice, p);
  ExperimentOptions opt;
  if (scenario) opt.scenario = *scenario;
  opt.settle_frames = settle_frames;
  opt.backend = parse_backend(backend, "backend");
  if (!progress.is_none())
    opt.progress = [progress](int condition, int done, int total) {
      py::gil_scoped_acquire gil;
      progress(condition, done, total);
    };
  ExperimentResult r;
  {
    py::gil_scoped_release release;
    r = run_experiment(model, p, opt);
  }
  return experiment_dict(r, model);
}

}  // namespace

void bind_simulation(py::module_& m) {
  auto report = py::class_<FrameReport>(m, "FrameReport", "What one frame did (read-only). to_dict() gives every field.");
  for_each_frame_report_field([&](const char* name, auto member, const char* doc) {
    report.def_property_readonly(name, [member](const FrameReport& r) { return field_value(r.*member); }, doc);
  });
  report.def("to_dict", &report_dict).def("__repr__", [](const FrameReport& r) {
    return "<hpcm.FrameReport frame " + std::to_string(r.frame) + (r.deform ? " deform" : " idle") + ", " +
           std::to_string(r.moved_elements) + " moved, " + std::to_string(r.sim_total_ms) + " ms>";
  });

  py::class_<StateSnapshot>(m, "State", "A copy of the simulation state; its arrays are views of this copy.")
      .def_property_readonly("positions", [](py::object self) {
            auto& s = self.cast<StateSnapshot&>();
            return lattice_view(reinterpret_cast<const float*>(s.state.pos.data()), s.dims, 3, self);
          }, "X, lattice units, (nx, ny, nz, 3) float32")
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

  py::class_<Simulation>(m, "Simulation", R"(The frame pipeline on one lattice.

Simulation(lattice, params=Params(), backend="cpu"): `lattice` is a Volume in LPS index order
(Input.lattice, read_volume, phantom). Coordinates, offsets and arrays are in lattice units,
indexed [x, y, z] with x right->left, y anterior->posterior (anterior is -y), z inferior->superior.)")
      .def(py::init(&make_simulation), py::arg("lattice"), py::arg("params") = Params{}, py::arg("backend") = "cpu")
      .def_property_readonly("dims", [](const Simulation& s) { return int3_tuple(s.model().dims); })
      .def_property_readonly("size", [](const Simulation& s) { return s.model().size(); }, "number of elements")
      .def_property_readonly("spacing", [](const Simulation& s) {
            const auto& v = s.model().spacing;
            return py::make_tuple(v[0], v[1], v[2]);
          }, "mm per lattice unit along x, y, z")
      .def_property_readonly("origin", [](const Simulation& s) {
            const auto& v = s.model().origin;
            return py::make_tuple(v[0], v[1], v[2]);
          }, "LPS mm of element (0, 0, 0)")
      .def_property_readonly("direction", [](const Simulation& s) { return matrix3(s.model().direction); })
      .def_property("params", [](const Simulation& s) { return s.params(); }, &Simulation::set_params,
                    "A copy of the parameters; assigning applies new ones (validated).")
      .def_property_readonly("backend", [](Simulation& s) { return backend_name(s.backend().kind()); })
      .def_property_readonly("frame", &Simulation::frame)
      .def_property_readonly("grabbing", &Simulation::grabbing)
      .def_property_readonly("grab_centre", [](const Simulation& s) -> py::object {
            return s.grab_centre() < 0 ? py::object(py::none()) : py::object(int3_tuple(s.model().coords(s.grab_centre())));
          })
      .def_property_readonly("tool_offset", [](const Simulation& s) { return vec3_tuple(s.tool_offset()); },
                             "the offset the grabbed elements follow (the requested one, limited to what the tissue allows)")
      .def_property_readonly("requested_offset", [](const Simulation& s) { return vec3_tuple(s.requested_offset()); })
      .def_property_readonly("tool_limited", &Simulation::tool_limited)
      .def_property_readonly("tool_limit", [](const Simulation& s) {
            return py::make_tuple(vec3_tuple(s.tool_limit_lo()), vec3_tuple(s.tool_limit_hi()));
          }, "feasible tool offsets of the current grab, ((lo x, y, z), (hi x, y, z)), lattice units")
      .def_property_readonly("grabbed", [](const Simulation& s) {
            return py::array_t<Index>(static_cast<py::ssize_t>(s.grabbed().size()), s.grabbed().data());
          }, "linear indices (x + nx (y + ny z)) of the grabbed elements (a copy)")
      .def_property_readonly("hu", [](py::object self) {
            const Model& mdl = self.cast<Simulation&>().model();
            return lattice_view(mdl.hu.data(), mdl.dims, 1, self);
          }, "HU per element, (nx, ny, nz) float32, read-only view (no copy)")
      .def_property_readonly("labels", [](py::object self) {
            const Model& mdl = self.cast<Simulation&>().model();
            return lattice_view(mdl.tissue.data(), mdl.dims, 1, self);
          }, "tissue class per element (0 air .. 3 bone), (nx, ny, nz) uint8, read-only view (no copy)")
      .def_property_readonly("body", [](const Simulation& s) {
            const Model& mdl = s.model();
            std::vector<std::uint8_t> counted(static_cast<std::size_t>(mdl.size()));
            for (Index i = 0; i < mdl.size(); ++i) counted[static_cast<std::size_t>(i)] = mdl.counted(i) ? 1 : 0;
            return bool_lattice(std::move(counted), mdl.dims);
          }, "elements the per-class statistics count (SPEC §3: the body; every element when there is none), "
             "(nx, ny, nz) read-only bool array (a copy)")
      .def_property_readonly("body_summary", [](const Simulation& s) {
            const BodySummary& b = s.model().body;
            py::dict d;
            d["search"] = b.search == BodySummary::Search::Found ? "found"
                          : b.search == BodySummary::Search::NoBody ? "none" : "not searched";
            d["counted_elements"] = b.body;
            d["outside_air"] = b.outside_air;
            d["outside_objects"] = b.outside_objects;
            d["why"] = b.describe();
            return d;
          }, "how many elements were left out of the statistics (outside air, anchored outside objects) and why")
      .def("paper_grab_centre", [](const Simulation& s) { return int3_tuple(s.model().coords(paper_grab_centre(s.model()))); },
           "The paper's grab point: the anterior body surface on the central axial slice, x = nx/2.")
      .def("grab", [](Simulation& s, py::handle centre, float radius) { s.grab(element_of(s, centre), radius); },
           py::arg("centre") = "auto", py::arg("radius") = 0.0f,
           "Grab every element within `radius` (lattice units; 0: solver.grab_radius) of `centre`: (x, y, z), "
           "an element index, or \"auto\" (the paper's grab point).")
      .def("move_tool", [](Simulation& s, py::handle offset) { s.move_tool(vec3_from(offset, "tool offset")); },
           py::arg("offset"), "Move the grabbed elements to their grab positions + offset (lattice units).")
      .def("release", &Simulation::release)
      .def("step", [](Simulation& s, bool speeds, bool link_violation, bool cell_jacobian) {
            const StepOptions o = step_options(speeds, link_violation, cell_jacobian);
            py::gil_scoped_release release;
            return s.step(o);
          }, py::arg("speeds") = true, py::arg("link_violation") = false, py::arg("cell_jacobian") = false,
          "One frame; returns its FrameReport. link_violation / cell_jacobian: also measure those (O(N) each).")
      .def("run", [](Simulation& s, int frames, bool speeds, bool link_violation, bool cell_jacobian) {
            if (frames < 0) throw Error("frames " + std::to_string(frames) + " must be >= 0");
            const StepOptions o = step_options(speeds, link_violation, cell_jacobian);
            std::vector<FrameReport> reports;
            reports.reserve(static_cast<std::size_t>(frames));
            {
              py::gil_scoped_release release;
              for (int f = 0; f < frames; ++f) reports.push_back(s.step(o));
            }
            return report_columns(reports);
          }, py::arg("frames"), py::arg("speeds") = true, py::arg("link_violation") = false, py::arg("cell_jacobian") = false,
          "`frames` frames with the tool as it is; returns per-frame statistics as numpy columns "
          "(one array per FrameReport field).")
      .def("reset", &Simulation::reset, "Back to rest (X = X0, V = 0), grab released, frame 0.")
      .def("positions", [](Simulation& s) {
            std::vector<Vec3> pos;
            s.backend().download_positions(pos);
            return vec3_array(std::move(pos), s.model().dims);
          }, "X in lattice units, (nx, ny, nz, 3) float32: one copy out of the backend, owned by the array")
      .def("displacement", [](Simulation& s) {
            std::vector<Vec3> pos;
            s.backend().download_positions(pos);
            const Model& mdl = s.model();
            for (Index i = 0; i < mdl.size(); ++i) pos[static_cast<std::size_t>(i)] = pos[static_cast<std::size_t>(i)] - mdl.rest(i);
            return vec3_array(std::move(pos), mdl.dims);
          }, "X - X0 in lattice units, (nx, ny, nz, 3) float32 (see displacement_mm for millimetres)")
      .def("state", [](Simulation& s) {
            auto snap = std::make_unique<StateSnapshot>();
            s.backend().download(snap->state);
            snap->dims = s.model().dims;
            return snap;
          }, "A copy of the whole state (positions, velocities, times, flags) as a State.")
      .def("velocities", [](Simulation& s) {
            State st;
            s.backend().download(st);
            return vec3_array(std::move(st.vel), s.model().dims);
          }, "V in lattice units per frame, (nx, ny, nz, 3) float32 (one copy out of the backend)");

  py::class_<ScenarioPlayer>(m, "ScenarioPlayer", "Plays a Scenario frame by frame on a Simulation.")
      .def(py::init<const Scenario&, Simulation&>(), py::arg("scenario"), py::arg("simulation"), py::keep_alive<1, 3>())
      .def_property_readonly("done", &ScenarioPlayer::done)
      .def_property_readonly("frame", &ScenarioPlayer::frame)
      .def("step", [](ScenarioPlayer& p, bool speeds, bool link_violation, bool cell_jacobian) {
            const StepOptions o = step_options(speeds, link_violation, cell_jacobian);
            py::gil_scoped_release release;
            return p.step(o);
          }, py::arg("speeds") = true, py::arg("link_violation") = false, py::arg("cell_jacobian") = false,
          "Applies this frame's input (grab / move / release) and steps the simulation.");

  m.def("run_experiment", &run_experiment_py, py::arg("lattice"), py::arg("params") = Params{},
        py::arg("scenario") = nullptr, py::arg("settle_frames") = 2000, py::arg("backend") = "cpu",
        py::arg("progress") = py::none(),
        R"(The paper's experiment: conditions A (none), B (simple), C (viscoelastic) on identical input.

Returns a dict: dims, elements, grab_centre, release_frame, recorded_frames, params,
conditions {"A"|"B"|"C": {initial, peak, auc (per tissue), stage times in ms, settle checks,
centre_track (frames, 3), frames (numpy columns)}}, checks [{name, spec, holds, value,
threshold, description}], all_hold. progress(condition, done, total) is called per frame.)");
  m.def("report_columns", &report_columns, py::arg("reports"), "FrameReports -> numpy columns (as Simulation.run gives).");
}

}  // namespace hpcm::python
