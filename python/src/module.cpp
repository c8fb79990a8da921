// The compiled part of the Python package hpcm (python/hpcm/__init__.py adds the rest).
#include "bindings.hpp"

PYBIND11_MODULE(_hpcm, m) {
  m.doc() = "hpcm: dynamic HP-ChainMail soft-tissue simulation on CT volumes (compiled core)";
  m.attr("__version__") = HPCM_VERSION;
  // Every hpcm::Error (bad parameter, file, option) becomes hpcm.Error, a ValueError, with the
  // same one-line message.
  py::register_exception<hpcm::Error>(m, "Error", PyExc_ValueError);
#if defined(HPCM_WITH_ITK)
  m.attr("has_io") = true;
#else
  m.attr("has_io") = false;
#endif
  m.def("cuda_available", [] { return hpcm::cuda_available(); },
        "True when the CUDA backend is built and a device is present.");
  hpcm::python::bind_volume(m);
  hpcm::python::bind_params(m);
  hpcm::python::bind_simulation(m);
  hpcm::python::bind_io(m);
}
