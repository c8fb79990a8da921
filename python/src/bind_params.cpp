// Params and Scenario. Parameters are read and validated by hpcm::config, the code that reads
// parameter files, so a value rejected in a file is rejected from Python with the same message.
#include "bindings.hpp"
#if defined(HPCM_WITH_CONFIG)
#include "hpcm/config.hpp"
#endif

namespace hpcm::python {

#if !defined(HPCM_WITH_CONFIG)
namespace {
[[noreturn]] void no_config(const char* what) {
  throw Error(std::string(what) + ": hpcm was built without hpcm::config (toml++), parameter text is unavailable");
}
}  // namespace
#endif

void bind_params(py::module_& m) {
  py::class_<Params>(m, "Params", R"(Every simulation setting, with the names of the TOML parameter file.

Params() holds the defaults. Read and set values by their file names:
    p = hpcm.Params()
    p["dynamics.alpha"]            # 0.98
    p["dynamics.alpha"] = 0.9      # validated like the file: hpcm.Error on a bad value
    p.update({"dynamics.mode": "simple", "tissue.t1": -500})
Params.load(path) / Params.from_toml(text) read parameter files; p.to_toml() writes one.)")
      .def(py::init<>())
      .def("validate", &Params::validate, "Raises hpcm.Error naming the key and the valid range.")
      .def("copy", [](const Params& p) { return Params(p); }, "An independent copy.")
      .def("__copy__", [](const Params& p) { return Params(p); })
      .def("__deepcopy__", [](const Params& p, py::dict) { return Params(p); }, py::arg("memo"))
      .def("__eq__", [](const Params& a, const Params& b) { return a == b; }, py::is_operator())
      .def("_assign", [](Params& self, const Params& other) { self = other; })
#if defined(HPCM_WITH_CONFIG)
      .def_static("load", [](const std::filesystem::path& path) { return config::load_params(existing_path(path, "parameter file")); },
                  py::arg("path"), "Reads and validates a TOML parameter file (str or os.PathLike).")
      .def_static("from_toml", [](const std::string& text, const std::string& source) { return config::parse_params(text, source); },
                  py::arg("text"), py::arg("source") = "<string>", "Parses parameter-file text (missing keys: defaults).")
      .def("to_toml", [](const Params& p) { return config::params_to_toml(p); }, "The complete parameter file of these values.")
      .def("_with_toml", [](const Params& p, const std::string& text, const std::string& source) {
            return config::parse_params(text, source, p);
          }, py::arg("text"), py::arg("source"), "A copy with the keys of `text` set (missing keys keep their values).")
#else
      .def_static("load", [](const std::string&) -> Params { no_config("Params.load"); }, py::arg("path"))
      .def_static("from_toml", [](const std::string&, const std::string&) -> Params { no_config("Params.from_toml"); },
                  py::arg("text"), py::arg("source") = "<string>")
      .def("to_toml", [](const Params&) -> std::string { no_config("Params.to_toml"); })
      .def("_with_toml", [](const Params&, const std::string&, const std::string&) -> Params { no_config("Params.set"); },
           py::arg("text"), py::arg("source"))
#endif
      ;

  py::class_<Scenario>(m, "Scenario", R"(A scripted interaction: grabs with keyframed drag paths, holds and releases.

Scenario.paper_protocol() is the paper's experiment input; Scenario.load(path) /
Scenario.from_toml(text) read scenario files (docs/scenarios.md).)")
      .def_static("paper_protocol", &Scenario::paper_protocol, py::arg("distance") = 6.0f, py::arg("pull") = 20,
                  py::arg("hold") = 10, py::arg("record") = 120,
                  "Pull the anterior skin point by `distance` lattice units (toward -y) over `pull` frames, hold "
                  "`hold` frames, release, record `record` frames.")
      .def_readwrite("name", &Scenario::name, "the scenario's name (reports and file names)")
      .def_readwrite("frames", &Scenario::frames, "total frames to play")
      .def_property_readonly("grabs", [](const Scenario& s) { return s.grabs.size(); }, "number of grab actions")
      .def("last_release_frame", &Scenario::last_release_frame, "The frame of the last release (the first idle frame after it), or -1 without grabs.")
#if defined(HPCM_WITH_CONFIG)
      .def_static("load", [](const std::filesystem::path& path) { return config::load_scenario(existing_path(path, "scenario file")); },
                  py::arg("path"), "Reads a scenario file (docs/scenarios.md).")
      .def_static("from_toml", [](const std::string& text, const std::string& source) { return config::parse_scenario(text, source); },
                  py::arg("text"), py::arg("source") = "<string>", "Parses scenario-file text; errors name `source`.")
      .def("to_toml", [](const Scenario& s) { return config::scenario_to_toml(s); }, "The complete scenario file of this scenario.")
#endif
      .def("__repr__", [](const Scenario& s) {
        return "<hpcm.Scenario '" + s.name + "', " + std::to_string(s.frames) + " frames, " + std::to_string(s.grabs.size()) +
               " grab(s)>";
      });
}

}  // namespace hpcm::python
