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
import os as _os
import re as _re
import sys as _sys
import tomllib as _tomllib

import numpy as _np

from . import _hpcm
from ._hpcm import *  # noqa: F401,F403 (the compiled API)
from ._hpcm import Error, Params, ScenarioPlayer, Simulation, Volume, __version__  # noqa: F401

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


# ---- progress: a callback or a tqdm bar ----------------------------------------------------


class _ProgressBar:
    """progress=True: a tqdm bar on stderr (a one-line percentage where tqdm is not installed)."""

    def __init__(self, desc):
        self._desc, self._bar, self._shown = desc, None, -1
        try:
            import tqdm as _tqdm  # optional (Debian python3-tqdm)
            self._tqdm = _tqdm.tqdm
        except ImportError:
            self._tqdm = None

    def __call__(self, done, total):
        if self._tqdm is not None:
            if self._bar is None:
                self._bar = self._tqdm(total=total, desc=self._desc, unit="frame")
            self._bar.update(done - self._bar.n)
        else:
            percent = 100 * done // max(total, 1)
            if percent != self._shown:
                self._shown = percent
                print(f"\r{self._desc}: {percent}% ({done}/{total})", end="", file=_sys.stderr, flush=True)

    def close(self):
        if self._bar is not None:
            self._bar.close()
        elif self._tqdm is None and self._shown >= 0:
            print(file=_sys.stderr)


def _progress_callback(progress, desc):
    """(callback or None, bar or None) for progress=None/False (nothing), True (a bar) or a callable."""
    if progress is None or progress is False:
        return None, None
    if progress is True:
        bar = _ProgressBar(desc)
        return bar, bar
    if callable(progress):
        return progress, None
    raise Error(f"progress={progress!r}: give None, True (a progress bar) or a callable(done, total)")


_compiled_simulation_run = Simulation.run


def _simulation_run(self, frames, *args, progress=None, **kwargs):
    callback, bar = _progress_callback(progress, "hpcm run")
    try:
        return _compiled_simulation_run(self, frames, *args, progress=callback, **kwargs)
    finally:
        if bar is not None:
            bar.close()


_simulation_run.__doc__ = _compiled_simulation_run.__doc__
Simulation.run = _simulation_run

_compiled_player_run = _hpcm.ScenarioPlayer.run


def _player_run(self, frames=-1, *args, progress=None, **kwargs):
    callback, bar = _progress_callback(progress, "hpcm scenario")
    try:
        return _compiled_player_run(self, frames, *args, progress=callback, **kwargs)
    finally:
        if bar is not None:
            bar.close()


_player_run.__doc__ = _compiled_player_run.__doc__
ScenarioPlayer.run = _player_run

_compiled_run_experiment = _hpcm.run_experiment


def run_experiment(lattice, params=None, scenario=None, settle_frames=2000, backend="cpu", progress=None):
    bars = []  # progress=True: one bar per condition (done counts from 1 in each)

    def bar_per_condition(condition, done, total):
        if not bars or bars[-1][0] != condition:
            if bars:
                bars[-1][1].close()
            bars.append((condition, _ProgressBar(f"hpcm experiment, condition {'ABC'[condition]}")))
        bars[-1][1](done, total)

    callback = bar_per_condition if progress is True else (None if progress is False else progress)
    try:
        return _compiled_run_experiment(lattice, Params() if params is None else params, scenario, settle_frames,
                                        backend, callback)
    finally:
        if bars:
            bars[-1][1].close()


run_experiment.__doc__ = _compiled_run_experiment.__doc__ + """
progress=True shows a progress bar (tqdm where installed) on stderr. Ctrl-C stops the run between
two frames with KeyboardInterrupt."""

# ---- nibabel: affines (RAS, as nibabel gives them) and images in and out -------------------

_LPS_TO_RAS = _np.diag([-1.0, -1.0, 1.0])


def _affine_ras(spacing, origin, direction):
    """4x4 voxel index -> RAS mm (nibabel's convention) of a grid given in LPS (ITK's)."""
    a = _np.eye(4)
    a[:3, :3] = _LPS_TO_RAS @ _np.asarray(direction, dtype=float) @ _np.diag(_np.asarray(spacing, dtype=float))
    a[:3, 3] = _LPS_TO_RAS @ _np.asarray(origin, dtype=float)
    return a


def _volume_affine(self):
    """4x4 voxel index [i, j, k, 1] -> RAS millimetres, as nibabel's img.affine (a copy)."""
    return _affine_ras(self.spacing, self.origin, self.direction)


def _input_affine(self):
    """4x4 RAS affine (as nibabel's img.affine) of input.stored's grid: the grid of the input file
    (cropped to roi) on which the exports, warp_labels and pullback_mm come back."""
    return _volume_affine(self.stored)


def _input_lattice_affine(self):
    """4x4 RAS affine of input.lattice_grid (stored coarsened by downsample, the file's index order):
    the grid of displacement_mm."""
    g = self.lattice_grid
    return _affine_ras(g["spacing"], g["origin"], g["direction"])


Volume.affine = property(_volume_affine)
if getattr(_hpcm, "has_io", False):
    _hpcm.Input.affine = property(_input_affine)
    _hpcm.Input.lattice_affine = property(_input_lattice_affine)


def from_nibabel(img, downsample=1, roi=None):
    """An Input (as load_input gives) from a 3-D nibabel image (NIfTI, MGH, ...): the data (scaled
    to HU by the image's slope/intercept) in the image's own index order and its RAS affine turned
    into hpcm's LPS geometry. The affine must be a rotation (with flips) times voxel sizes: a
    sheared one raises hpcm.Error. inp.stored is the image as an hpcm Volume."""
    shape = tuple(img.shape)
    if len(shape) != 3:
        raise Error(f"from_nibabel: the image has shape {shape}; hpcm takes a 3-D image (one CT volume)")
    affine = _np.asarray(img.affine, dtype=float)
    if affine.shape != (4, 4) or not _np.all(_np.isfinite(affine)):
        raise Error(f"from_nibabel: the image's affine must be a finite 4x4 matrix, got {affine!r}")
    lps = _LPS_TO_RAS @ affine[:3, :3]  # RAS -> LPS: negate the first two rows
    spacing = _np.linalg.norm(lps, axis=0)
    if not _np.all(spacing > 0):
        raise Error(f"from_nibabel: the affine's voxel sizes {tuple(spacing)} must be > 0")
    hu = _np.asarray(img.get_fdata(dtype=_np.float32), dtype=_np.float32)
    volume = Volume(hu, spacing=spacing, origin=_LPS_TO_RAS @ affine[:3, 3], direction=lps / spacing[None, :])
    source = getattr(img, "get_filename", lambda: None)() or "nibabel image"
    return _hpcm.prepare_input(volume, downsample=downsample, roi=roi, source=str(source))


def to_nibabel(data, like=None, affine=None):
    """A nibabel Nifti1Image of a Volume (its HU and geometry) or of an array on an Input's grid.

    data: a Volume, or an array indexed [x, y, z(, component)] in the input's own index order
    (warp_labels, pullback_mm: input.stored's grid; displacement_mm: input.lattice_grid).
    like: the Input (or Volume) whose grid the array lies on, picked by the array's shape; or
    affine: a 4x4 RAS affine. Vector components are written as they are (hpcm's are LPS mm)."""
    import nibabel as _nib

    if isinstance(data, Volume):
        return _nib.Nifti1Image(_np.array(data.hu), _volume_affine(data))
    array = _np.asarray(data)
    if array.ndim not in (3, 4):
        raise Error(f"to_nibabel: the array has shape {array.shape}; give [x, y, z] or [x, y, z, component]")
    if affine is None:
        if like is None:
            raise Error("to_nibabel: an array needs like=<Input or Volume> or affine=<4x4 RAS>")
        if isinstance(like, Volume):
            grids = {tuple(like.dims): _volume_affine(like)}
        else:
            grids = {tuple(like.lattice_grid["dims"]): like.lattice_affine, tuple(like.stored.dims): like.affine}
        affine = grids.get(tuple(array.shape[:3]))
        if affine is None:
            raise Error(f"to_nibabel: the array's grid {array.shape[:3]} is none of like's grids {sorted(grids)}")
    affine = _np.asarray(affine, dtype=float)
    if affine.shape != (4, 4):
        raise Error(f"to_nibabel: affine must be 4x4, got shape {affine.shape}")
    if array.ndim == 4:
        array = array[:, :, :, None, :]  # NIfTI keeps vector components on the 5th axis
    img = _nib.Nifti1Image(_np.ascontiguousarray(array), affine)
    if array.ndim == 5:
        img.header.set_intent("vector")
    return img
