"""hpcm: real-time dynamic soft-tissue deformation of CT volumes (HP-ChainMail + an independent
velocity layer), from Python.

    import hpcm
    inp = hpcm.load_input("ct.nii.gz", downsample=2)        # or hpcm.phantom((96, 96, 64))
    sim = hpcm.Simulation(inp.lattice, hpcm.Params())
    sim.grab("auto"); sim.move_tool((0, -3, 0)); sim.step()
    u = hpcm.displacement_mm(inp, sim)                      # on the input's own grid, mm
    summary = hpcm.run_experiment(inp.lattice)              # the paper's conditions A/B/C

Errors (bad parameter, file, option) raise hpcm.Error (a ValueError) with the message the
command-line tool and the parameter files give. See docs/python.md.
"""
import re as _re
import tomllib as _tomllib

import numpy as _np

from . import _hpcm
from ._hpcm import *  # noqa: F401,F403 (the compiled API)
from ._hpcm import Error, Params, Simulation, __version__  # noqa: F401

TISSUES = _hpcm.tissue_names()

# ---- Params by the names of the parameter file --------------------------------------------


def _toml_value(v):
    """A Python value as TOML text (validation stays with hpcm's parameter-file reader)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, _np.integer)):
        return str(int(v))
    if isinstance(v, (float, _np.floating)):
        f = float(v)
        return "nan" if f != f else ("inf" if f == float("inf") else ("-inf" if f == float("-inf") else repr(f)))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple, _np.ndarray)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise Error(f"{v!r}: a parameter value must be a number, a string, a bool, a table (dict) or a list")


def _settings_toml(settings):
    """{"dynamics.alpha": 0.9, "tissue.t1": -500} -> TOML text with one table per section."""
    tables = {}
    for key, value in settings.items():
        if not isinstance(key, str) or "." not in key:
            raise Error(f"{key!r}: parameter names are 'section.key', e.g. 'dynamics.alpha' (see Params.to_toml())")
        section, name = key.rsplit(".", 1)
        tables.setdefault(section, []).append(f"{name} = {_toml_value(value)}")
    return "".join(f"[{s}]\n" + "\n".join(lines) + "\n" for s, lines in tables.items())


def _params_update(self, settings=None, **sections):
    """Sets parameters by their file names, all at once, validated like a parameter file:
    p.update({"dynamics.alpha": 0.9}) or p.update(dynamics={"alpha": 0.9, "mode": "simple"}).
    On an invalid value nothing changes and hpcm.Error names the key and the valid range."""
    flat = dict(settings or {})
    for section, values in sections.items():
        if not isinstance(values, dict):
            raise Error(f"{section}=...: give a dict of that section's keys, e.g. {section}={{'...': ...}}")
        flat.update({f"{section}.{k}": v for k, v in values.items()})
    try:
        new = self._with_toml(_settings_toml(flat), "Params")
    except Error as e:
        # The text above is generated: its line numbers would mean nothing to the caller.
        raise Error(_re.sub(r" \(line \d+\)$", "", str(e))) from None
    self._assign(new)
    return self


def _params_to_dict(self):
    """Every parameter as nested dicts, named as in the parameter file."""
    return _tomllib.loads(self.to_toml())


def _params_getitem(self, key):
    node = self.to_dict()
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            raise KeyError(key)
        node = node[part]
    return node


def _params_setitem(self, key, value):
    self.update({key: value})


def _params_repr(self):
    d = self.to_dict()
    return f"<hpcm.Params dynamics.mode={d['dynamics']['mode']!r} ...; to_toml() shows all>"


Params.update = _params_update


def _params_set(self, key, value):
    """Sets one parameter by its file name, validated: p.set("dynamics.alpha", 0.9)."""
    return _params_update(self, {key: value})


Params.set = _params_set
Params.to_dict = _params_to_dict
Params.__getitem__ = _params_getitem
Params.__setitem__ = _params_setitem
Params.__repr__ = _params_repr

# ---- lattice arrays in the input's own index order -----------------------------------------


def to_stored_order(inp, lattice_array):
    """A lattice array (indexed [x, y, z, ...] in LPS order, as Simulation gives) as a view (no
    copy) indexed in the input's own order, on inp.lattice_grid: the order of the exports."""
    axis, reversed_ = inp.order["axis"], inp.order["reversed"]
    a = _np.asarray(lattice_array)
    # Stored axis s is lattice axis p with axis[p] == s.
    perm = [axis.index(s) for s in range(3)] + list(range(3, a.ndim))
    v = a.transpose(perm)
    for s in range(3):
        if reversed_[axis.index(s)]:
            v = _np.flip(v, s)
    return v


def _displacement_mm_lattice(self):
    """X - X0 in millimetres (LPS components) on the lattice, indexed [x, y, z, component]."""
    u = self.displacement()
    m = self.direction * _np.asarray(self.spacing)[None, :]  # column a: mm of one lattice step on axis a
    return (u @ m.T.astype(_np.float32)).astype(_np.float32)


Simulation.displacement_mm = _displacement_mm_lattice
