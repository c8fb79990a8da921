"""Tests of the Python API (import hpcm). Run by CTest (python_api) with PYTHONPATH=<build>/python."""
import os
import re
from pathlib import Path

import numpy as np
import pytest

import hpcm

DATA = Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
NIFTI = DATA / "abdomen-ct" / "abdomen_ct.nii.gz"
needs_io = pytest.mark.skipif(not hpcm.has_io, reason="hpcm was built without ITK (no hpcm.load_input/exports)")

SMALL = (24, 20, 16)


@pytest.fixture(scope="module")
def phantom():
    return hpcm.phantom(SMALL)


def pulled(volume, params=None, frames=4, pull=-0.5):
    sim = hpcm.Simulation(volume, params or hpcm.Params())
    sim.grab("auto")
    for f in range(frames):
        sim.move_tool((0.0, pull * (f + 1), 0.0))
        sim.step()
    return sim


# ---- volumes ------------------------------------------------------------------------------

def test_phantom_variants():
    standard = hpcm.phantom(SMALL, noise_hu=0)
    thin = hpcm.phantom(SMALL, noise_hu=0, variant="thin-tissue")
    assert thin.dims == standard.dims
    assert not np.array_equal(thin.hu, standard.hu)
    thick = hpcm.phantom(SMALL, variant="anisotropic")
    assert thick.spacing[2] / thick.spacing[0] == pytest.approx(6.25)
    with pytest.raises(hpcm.Error, match="thin-tissue"):
        hpcm.phantom(SMALL, variant="thin")


def test_volume_from_numpy_keeps_index_order_and_geometry():
    a = np.arange(4 * 3 * 2, dtype=np.float32).reshape(4, 3, 2) - 500
    v = hpcm.Volume(a, spacing=(0.5, 0.75, 2.0), origin=(1, 2, 3))
    assert v.dims == (4, 3, 2) and v.spacing == (0.5, 0.75, 2.0)
    np.testing.assert_array_equal(v.hu, a)
    assert v.index_to_physical(1, 2, 1) == pytest.approx((1.5, 3.5, 5.0))
    view = v.hu
    view[0, 0, 0] = 123.0  # a view of the volume's memory, not a copy
    assert v.hu[0, 0, 0] == 123.0
    with pytest.raises(hpcm.Error, match="3-D"):
        hpcm.Volume(np.zeros((3, 3)))


# ---- parameters: the parameter file's names, validation and messages ------------------------

BAD_SETTINGS = [
    ("dynamics", "alpha", "1.5"),
    ("dynamics", "mode", '"fast"'),
    ("dynamics", "alpah", "0.5"),
    ("solver", "brick_size", "5"),
    ("tissue", "t1", "100.0"),
    ("dynamics", "b1", "{ air = 2.0 }"),
]


@pytest.mark.parametrize("section,key,value", BAD_SETTINGS)
def test_bad_parameter_gives_the_parameter_files_message(tmp_path, section, key, value):
    path = tmp_path / "p.toml"
    path.write_text(f"[{section}]\n{key} = {value}\n")
    with pytest.raises(hpcm.Error) as from_file:
        hpcm.Params.load(str(path))
    file_message = re.sub(r" \(line \d+\)$", "", str(from_file.value)).replace(f"{path}: ", "", 1)
    p = hpcm.Params()
    before = p.to_toml()
    with pytest.raises(hpcm.Error) as from_python:
        p.update({f"{section}.{key}": _python_value(value)})
    python_message = str(from_python.value).replace("Params: ", "", 1)
    assert python_message == file_message
    assert p.to_toml() == before, "a rejected setting must change nothing"
    assert isinstance(from_python.value, ValueError)


def _python_value(toml_value):
    import tomllib
    return tomllib.loads(f"v = {toml_value}")["v"]


def test_parameters_by_name_round_trip(tmp_path):
    p = hpcm.Params()
    assert p["dynamics.alpha"] == pytest.approx(0.98)
    p["dynamics.alpha"] = 0.9
    p.update(dynamics={"mode": "simple", "b1": {"skin_fat": 0.3}}, tissue={"preset": "robust"})
    assert p["dynamics.mode"] == "simple" and p["dynamics.alpha"] == pytest.approx(0.9)
    assert p["dynamics.b1"]["skin_fat"] == pytest.approx(0.3) and p["dynamics.b1"]["muscle_organ"] == pytest.approx(hpcm.Params()["dynamics.b1"]["muscle_organ"])
    assert (p["tissue.t1"], p["tissue.t2"], p["tissue.t3"]) == (-500.0, 0.0, 200.0)
    path = tmp_path / "saved.toml"
    path.write_text(p.to_toml())
    assert hpcm.Params.load(str(path)) == p
    q = p.copy()
    q["solver.relax_sweeps"] = 12
    assert q != p and p["solver.relax_sweeps"] == 8


# ---- simulation ---------------------------------------------------------------------------

def test_grab_move_step_and_arrays(phantom):
    sim = hpcm.Simulation(phantom)
    assert sim.dims == SMALL and sim.size == np.prod(SMALL)
    centre = sim.paper_grab_centre()
    sim.grab("auto")
    assert sim.grab_centre == centre and sim.grabbing
    sim.move_tool((0.0, -1.0, 0.0))
    report = sim.step(link_violation=True)
    assert report.deform and report.frame == 0 and report.grab_offset == pytest.approx(1.0)
    assert 0 <= report.max_link_violation < 1e-4
    assert set(report.to_dict()) >= {"frame", "mean_speed", "sim_total_ms"}
    x = sim.positions()
    assert x.shape == SMALL + (3,) and x.dtype == np.float64
    # The grabbed elements sit exactly at rest + tool offset (lattice units, [x, y, z]).
    g = np.unravel_index(sim.grabbed, SMALL, order="F")
    rest = np.stack(g, axis=-1).astype(np.float64)
    np.testing.assert_array_equal(x[g], rest + np.float64([0, -1, 0]))
    # The solver stores u = X - X0 (float32); X is X0 + u in double, so the difference is exact.
    u = sim.displacement()
    assert u.dtype == np.float32
    np.testing.assert_array_equal(u.astype(np.float64), x - np.stack(np.indices(SMALL), axis=-1))
    # Model arrays are views without a copy, read-only.
    labels, hu = sim.labels, sim.hu
    assert not labels.flags.owndata and not labels.flags.writeable and labels.dtype == np.uint8
    np.testing.assert_array_equal(hu, phantom.hu)
    with pytest.raises(ValueError):
        labels[0, 0, 0] = 3
    # millimetres: lattice units times spacing (identity direction for the phantom)
    np.testing.assert_allclose(sim.displacement_mm(), sim.displacement() * np.float32(sim.spacing), rtol=1e-6)
    st = sim.state()
    np.testing.assert_array_equal(st.displacements, u)
    assert st.flags[centre] & 2  # grabbed
    sim.release()
    assert not sim.grabbing and sim.grab_centre is None
    cols = sim.run(5)
    assert cols["frame"].tolist() == [1, 2, 3, 4, 5] and cols["mean_speed"].shape == (5, 4)
    assert not cols["deform"].any()
    sim.reset()
    assert sim.frame == 0 and np.abs(sim.displacement()).max() == 0


def test_run_columns_equal_stepped_reports(phantom):
    a, b = hpcm.Simulation(phantom), hpcm.Simulation(phantom)
    for s in (a, b):
        s.grab((12, 4, 8))
        s.move_tool((0.0, -1.5, 0.5))
    cols = a.run(6)
    reports = [b.step().to_dict() for _ in range(6)]
    for name, column in cols.items():
        if name.endswith("_ms"):
            continue  # timings differ run to run
        np.testing.assert_array_equal(column, np.array([r[name] for r in reports]), err_msg=name)
    np.testing.assert_array_equal(a.positions(), b.positions())


def test_errors_become_hpcm_error(phantom):
    with pytest.raises(hpcm.Error, match="backend"):
        hpcm.Simulation(phantom, backend="gpu")
    sim = hpcm.Simulation(phantom)
    with pytest.raises(hpcm.Error, match=r"coordinate 0 = 99 is out of range \[0, 23\]"):
        sim.grab((99, 0, 0))
    sim.grab("auto")  # move_tool without a grab is refused too (test_behaviour.py)
    with pytest.raises(hpcm.Error, match="finite"):
        sim.move_tool((float("nan"), 0, 0))
    sim.release()
    with pytest.raises(hpcm.Error, match="frames -1 must be >= 0"):
        sim.run(-1)


# ---- scenarios and the experiment ---------------------------------------------------------

def test_experiment_summary_and_scenario_player_agree(phantom):
    scenario = hpcm.Scenario.paper_protocol(distance=3.0, pull=5, hold=2, record=12)
    params = hpcm.Params()
    result = hpcm.run_experiment(phantom, params, scenario=scenario, settle_frames=5)
    assert set(result["conditions"]) == {"A", "B", "C"}
    assert result["dims"] == SMALL and result["release_frame"] == 7
    c = result["conditions"]["C"]
    assert c["mode"] == "viscoelastic" and set(c["peak"]) == set(hpcm.TISSUES)
    assert c["frames"]["mean_speed"].shape == (scenario.frames, 4)
    assert c["centre_track"].shape == (scenario.frames, 3)
    assert len(result["checks"]) == 33, "the paper protocol reports 33 checks (the all() below holds on none)"
    assert all({"name", "spec", "status", "holds", "value", "threshold", "description", "reason"} <= set(k)
               for k in result["checks"])
    assert all(k["status"] in ("held", "failed", "not_applicable") for k in result["checks"])
    assert all(k["holds"] == (k["status"] == "held") for k in result["checks"])
    assert result["all_hold"] == all(k["status"] != "failed" for k in result["checks"])
    shares = c["far_field_share"]
    assert set(shares) == set(hpcm.TISSUES)
    assert all(v is None or 0.0 <= v <= 1.0 for v in shares.values())
    assert isinstance(result["all_hold"], bool)
    # The same protocol played frame by frame through the API gives the same grab-centre track.
    sim = hpcm.Simulation(phantom, params)
    player = hpcm.ScenarioPlayer(scenario, sim)
    idx = np.ravel_multi_index(result["grab_centre"], SMALL, order="F")
    track, velocity = [], []
    while not player.done:
        player.step()
        track.append(sim.positions().reshape(-1, 3, order="F")[idx])
        velocity.append(sim.velocities().reshape(-1, 3, order="F")[idx])
    np.testing.assert_array_equal(np.array(track), c["centre_track"])
    # And the same velocity state: 0 while held, moving after release under C.
    np.testing.assert_array_equal(np.array(velocity), c["centre_velocity"])
    assert not c["centre_velocity"][:7].any() and c["centre_velocity"][7:].any()


# ---- input grids and exports ----------------------------------------------------------------

@needs_io
def test_displacement_in_the_inputs_own_order(tmp_path, phantom):
    nib = pytest.importorskip("nibabel")
    # The phantom stored with permuted, flipped axes: stored axis 0 runs -P, 1 runs +S, 2 runs +L.
    lps = phantom.hu
    stored = np.ascontiguousarray(np.flip(lps.transpose(1, 2, 0), axis=0))
    sp = phantom.spacing
    direction = [[0, 0, 1], [-1, 0, 0], [0, 1, 0]]
    origin = phantom.index_to_physical(0, SMALL[1] - 1, 0)
    volume = hpcm.Volume(stored, spacing=(sp[1], sp[2], sp[0]), origin=origin, direction=direction)
    inp = hpcm.prepare_input(volume, downsample=2, source="permuted phantom")
    assert inp.order == {"axis": (2, 0, 1), "reversed": (False, True, False)}
    assert inp.lattice.dims == tuple(d // 2 for d in SMALL)
    sim = pulled(inp.lattice)
    u = hpcm.displacement_mm(inp, sim)
    assert u.shape == tuple(d // 2 for d in stored.shape) + (3,)
    np.testing.assert_allclose(u, hpcm.to_stored_order(inp, sim.displacement_mm()), atol=1e-5)
    files = hpcm.export_frame(inp, sim, str(tmp_path))
    field = nib.load(files["displacement_nifti"])
    np.testing.assert_allclose(np.asarray(field.dataobj)[:, :, :, 0, :], u, atol=1e-6)
    hpcm.write_label_map(inp, sim, str(tmp_path / "labels.nii.gz"))
    labels = np.asarray(nib.load(str(tmp_path / "labels.nii.gz")).dataobj)
    outside = np.uint8(4)  # SPEC §3: elements outside the body have their own label
    np.testing.assert_array_equal(labels, hpcm.to_stored_order(inp, np.where(sim.body, sim.labels, outside)))
    assert Path(files["deformed"]).name == "deformed_final.nii.gz"
    assert nib.load(files["deformed"]).shape == stored.shape


@needs_io
def test_real_ct_input(tmp_path):
    if not NIFTI.is_file():
        pytest.skip(f"{NIFTI} is absent (../shared/data)")
    nib = pytest.importorskip("nibabel")
    inp = hpcm.load_input(str(NIFTI), downsample=4, roi=(0, 0, 10, 122, 101, 90))
    assert inp.stored.dims == (122, 101, 80) and inp.lattice.dims == (30, 25, 20)
    assert inp.left_out == (2, 1, 0)
    sim = pulled(inp.lattice, frames=2)
    hpcm.write_label_map(inp, sim, str(tmp_path / "labels.nii.gz"))
    src = nib.load(str(NIFTI))
    labels = nib.load(str(tmp_path / "labels.nii.gz"))
    expected = src.affine.copy()
    expected[:3, 3] = src.affine[:3, :3] @ [1.5, 1.5, 11.5] + src.affine[:3, 3]  # roi start + first block centre
    expected[:3, :3] *= 4
    np.testing.assert_allclose(labels.affine, expected, atol=1e-3)
    assert labels.shape == (30, 25, 20)
    with pytest.raises(hpcm.Error, match="roi"):
        hpcm.load_input(str(NIFTI), roi=(0, 0, 0, 200, 10, 10))
    with pytest.raises(FileNotFoundError, match="missing.nii.gz"):
        hpcm.load_input(str(tmp_path / "missing.nii.gz"))


def test_body_mask_is_exposed_read_only():
    # SPEC §3: the body found on load (ITK on the lattice), the phantom's own outline, none for an array.
    table = hpcm.phantom((32, 32, 24), variant="table")
    assert table.body is not None and table.body.dtype == bool and table.body.shape == (32, 32, 24)
    assert not table.body.flags.writeable
    inp = hpcm.prepare_input(table, downsample=1, source="table phantom")
    body = inp.body
    assert body.dtype == bool and body.shape == inp.lattice.dims and not body.flags.writeable
    with pytest.raises(ValueError):
        body[0, 0, 0] = True
    hu = np.asarray(inp.lattice.hu)
    assert body.sum() > 0 and not body[:, 0, :].any()  # the anterior border row is air
    assert ((~body) & (hu >= -500)).sum() > 0  # the table is not body
    sim = hpcm.Simulation(inp.lattice)
    np.testing.assert_array_equal(sim.body, body)
    summary = sim.body_summary
    assert summary["search"] == "found"
    assert summary["counted_elements"] == int(body.sum())
    assert summary["outside_objects"] == int(((~body) & (hu >= -500)).sum())
    assert summary["counted_elements"] + summary["outside_air"] + summary["outside_objects"] == body.size
    array = hpcm.Volume(np.full((8, 8, 8), -1000.0, np.float32))
    assert array.body is None
    free = hpcm.Simulation(array)
    assert free.body.all() and free.body_summary["search"] == "not searched"
