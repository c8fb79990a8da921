"""Python that behaves like Python (issue 32, item 5): Ctrl-C between frames, the GIL released in
long calls, progress callbacks, os.PathLike paths, FileNotFoundError, move_tool before grab,
read-only arrays, `hpcm --version` == hpcm.__version__.

Runs that could hang on a regression (Ctrl-C not honoured) run in a child interpreter with a
time limit, so they fail instead of stalling the test run."""
import os
import pathlib
import subprocess
import sys
import textwrap
import threading
import time

import numpy as np
import pytest

import hpcm

DATA = pathlib.Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
NIFTI = DATA / "abdomen-ct" / "abdomen_ct.nii.gz"
needs_io = pytest.mark.skipif(not hpcm.has_io, reason="hpcm built without ITK")
needs_ct = pytest.mark.skipif(not NIFTI.exists(), reason=f"{NIFTI} not present")


def run_child(body, timeout=60):
    """Runs `body` in a fresh interpreter; its stdout, or a failure on a crash or a time-out."""
    try:
        p = subprocess.run([sys.executable, "-c", textwrap.dedent(body)], capture_output=True, text=True,
                           timeout=timeout, env=dict(os.environ))
    except subprocess.TimeoutExpired:
        pytest.fail(f"no result after {timeout} s: Ctrl-C (SIGINT) did not stop the call")
    assert p.returncode == 0, f"child exited with {p.returncode}\nstdout: {p.stdout[-2000:]}\nstderr: {p.stderr[-2000:]}"
    return p.stdout


# A child that interrupts itself (SIGINT, as Ctrl-C) 0.5 s into a call that would take minutes.
SIGINT_PRELUDE = """
import os, signal, threading, time
import hpcm
sim = hpcm.Simulation(hpcm.phantom((32, 28, 24)))
sim.grab("auto")
sim.move_tool((0.0, -2.0, 0.0))
def ctrl_c_soon():
    threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
"""


def test_ctrl_c_stops_simulation_run_between_frames_and_the_simulation_stays_usable():
    out = run_child(SIGINT_PRELUDE + """
ctrl_c_soon()
try:
    sim.run(10_000_000, speeds=False)
    print("finished")
except KeyboardInterrupt:
    print("interrupted after", sim.frame, "frames")
before = sim.frame
report = sim.step()
print("stepped", report.frame == before, sim.frame == before + 1)
""")
    assert "interrupted after" in out and "finished" not in out, out
    assert "stepped True True" in out, out


def test_ctrl_c_stops_run_experiment():
    out = run_child("""
import os, signal, threading
import hpcm
lattice = hpcm.phantom((32, 28, 24))
threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
try:
    hpcm.run_experiment(lattice, settle_frames=10_000_000)
    print("finished")
except KeyboardInterrupt:
    print("interrupted")
""")
    assert "interrupted" in out and "finished" not in out, out


def test_ctrl_c_stops_a_scenario_player_run():
    out = run_child(SIGINT_PRELUDE + """
scenario = hpcm.Scenario.paper_protocol()
scenario.frames = 10_000_000
player = hpcm.ScenarioPlayer(scenario, sim)
ctrl_c_soon()
try:
    player.run(speeds=False)
    print("finished")
except KeyboardInterrupt:
    print("interrupted at frame", player.frame)
player.step()
print("stepped on")
""")
    assert "interrupted at frame" in out and "finished" not in out and "stepped on" in out, out


def test_progress_callback_reports_done_and_total():
    sim = hpcm.Simulation(hpcm.phantom((24, 20, 16)))
    seen = []
    columns = sim.run(30, progress=lambda done, total: seen.append((done, total)))
    assert len(columns["frame"]) == 30
    assert seen and seen[-1] == (30, 30)
    assert all(total == 30 and 0 < done <= 30 for done, total in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


def test_a_failing_progress_callback_stops_the_run_with_its_exception():
    sim = hpcm.Simulation(hpcm.phantom((24, 20, 16)))

    def fail(done, total):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        sim.run(5, progress=fail)
    assert 1 <= sim.frame <= 5  # stopped after a whole frame
    sim.step()


def test_progress_true_draws_a_bar_on_stderr_and_bad_values_are_refused(capsys):
    sim = hpcm.Simulation(hpcm.phantom((24, 20, 16)))
    sim.run(10, progress=True)
    assert "10/10" in capsys.readouterr().err
    with pytest.raises(hpcm.Error, match="progress"):
        sim.run(3, progress="yes")


def test_scenario_player_run_plays_to_the_end_with_progress():
    sim = hpcm.Simulation(hpcm.phantom((24, 20, 16)))
    scenario = hpcm.Scenario.paper_protocol()
    scenario.frames = 40
    player = hpcm.ScenarioPlayer(scenario, sim)
    seen = []
    columns = player.run(progress=lambda done, total: seen.append((done, total)))
    assert len(columns["frame"]) == 40 and player.done and seen[-1] == (40, 40)
    with pytest.raises(hpcm.Error, match="frames -2"):
        player.run(-2)


# ---- the GIL is released in long calls ---------------------------------------------------


def ticks_during(call):
    """How often another Python thread ran while `call()` ran (0 when the call held the GIL)."""
    stamps, stop = [], threading.Event()

    def tick():
        while not stop.is_set():
            stamps.append(time.perf_counter())
            time.sleep(0.0005)

    ticker = threading.Thread(target=tick)
    ticker.start()
    time.sleep(0.02)
    start = time.perf_counter()
    result = call()
    end = time.perf_counter()
    stop.set()
    ticker.join()
    # Stamps well inside the call: not the ones at its edges.
    margin = min(0.005, (end - start) / 4)
    return sum(start + margin < t < end - margin for t in stamps), end - start, result


def test_another_thread_runs_while_a_simulation_is_constructed():
    lattice = hpcm.phantom((160, 150, 120), noise_hu=0)
    ticks, seconds, _ = ticks_during(lambda: hpcm.Simulation(lattice))
    assert seconds > 0.05, "the construction is too short to tell"
    assert ticks >= 5, f"no other thread ran during the {seconds:.2f} s constructor ({ticks} ticks)"


@needs_io
@needs_ct
def test_another_thread_runs_while_an_input_loads_and_exports(tmp_path):
    ticks, seconds, inp = ticks_during(lambda: hpcm.load_input(str(NIFTI)))
    assert ticks >= 3, f"no other thread ran during the {seconds:.3f} s load_input ({ticks} ticks)"
    sim = hpcm.Simulation(inp.lattice)
    sim.grab("auto")
    sim.move_tool((0.0, -3.0, 0.0))
    sim.run(5)
    ticks, seconds, _ = ticks_during(lambda: hpcm.export_frame(inp, sim, str(tmp_path), nrrd=False))
    assert ticks >= 3, f"no other thread ran during the {seconds:.3f} s export ({ticks} ticks)"


# ---- paths and the exceptions Python users expect -----------------------------------------


@needs_io
@needs_ct
def test_pathlib_paths_are_accepted_everywhere(tmp_path):
    inp = hpcm.load_input(NIFTI, downsample=4)  # a pathlib.Path
    assert hpcm.read_volume(NIFTI).dims == hpcm.read_volume(str(NIFTI)).dims
    assert hpcm.read_volume_as_stored(NIFTI).dims == inp.stored.dims
    hpcm.write_volume(inp.stored, tmp_path / "stored.nii.gz")
    assert (tmp_path / "stored.nii.gz").exists()
    sim = hpcm.Simulation(inp.lattice)
    (tmp_path / "export").mkdir()
    files = hpcm.export_frame(inp, sim, tmp_path / "export", nrrd=False)
    assert pathlib.Path(files["deformed"]).exists()
    hpcm.write_label_map(inp, sim, tmp_path / "labels.nii.gz")
    hpcm.write_deformed_volume(inp, sim, tmp_path / "deformed.nii.gz")
    hpcm.write_displacement_field(inp, sim, tmp_path / "u.nii.gz")
    import nibabel as nib
    nib.save(hpcm.to_nibabel(np.ones(inp.stored.dims, np.int16), like=inp), tmp_path / "mask.nii.gz")
    hpcm.warp_labels(inp, sim, tmp_path / "mask.nii.gz", tmp_path / "warped.nii.gz")
    assert (tmp_path / "warped.nii.gz").exists()
    (tmp_path / "s.toml").write_text(hpcm.Scenario.paper_protocol().to_toml())
    assert hpcm.Scenario.load(tmp_path / "s.toml").frames > 0
    (tmp_path / "p.toml").write_text(hpcm.Params().to_toml())
    hpcm.Params.load(tmp_path / "p.toml")


@needs_io
def test_a_missing_file_raises_file_not_found_error_with_the_path(tmp_path):
    missing = tmp_path / "no_such_ct.nii.gz"
    for call in (lambda: hpcm.load_input(missing), lambda: hpcm.read_volume(str(missing)),
                 lambda: hpcm.read_volume_as_stored(missing), lambda: hpcm.Params.load(missing),
                 lambda: hpcm.Scenario.load(missing), lambda: hpcm.list_dicom_series(missing)):
        with pytest.raises(FileNotFoundError) as e:
            call()
        assert e.value.filename == str(missing) and str(missing) in str(e.value)


def test_move_tool_before_grab_raises():
    sim = hpcm.Simulation(hpcm.phantom((24, 20, 16)))
    with pytest.raises(hpcm.Error, match="grab"):
        sim.move_tool((0.0, -2.0, 0.0))
    with pytest.raises(hpcm.Error, match="grab"):
        sim.move_tool(offset_mm=(0.0, -2.0, 0.0))
    assert sim.requested_offset == (0.0, 0.0, 0.0)
    sim.grab("auto")
    sim.release()
    with pytest.raises(hpcm.Error, match="grab"):
        sim.move_tool((0.0, -2.0, 0.0))


# ---- arrays that must not be written ------------------------------------------------------


@needs_io
def test_an_inputs_volumes_are_read_only_and_own_volumes_stay_writable():
    own = hpcm.phantom((24, 20, 16))
    inp = hpcm.prepare_input(own, downsample=2)
    for hu in (inp.stored.hu, inp.lattice.hu):
        assert not hu.flags.writeable
        with pytest.raises(ValueError):
            hu[0, 0, 0] = 1000.0
    before = float(inp.stored.hu[0, 0, 0])
    own.hu[0, 0, 0] = before + 500.0  # the Input holds its own copy
    assert own.hu[0, 0, 0] == before + 500.0 and inp.stored.hu[0, 0, 0] == before
    copy = np.array(inp.stored.hu)
    copy[0, 0, 0] = 7.0
    assert inp.stored.hu[0, 0, 0] == before


def test_simulation_and_state_arrays_are_read_only():
    sim = hpcm.Simulation(hpcm.phantom((24, 20, 16)))
    state = sim.state()
    for a in (sim.hu, sim.labels, state.displacements, state.velocities, state.time, state.flags):
        assert not a.flags.writeable


# ---- one version ----------------------------------------------------------------------------


@pytest.mark.skipif(not os.environ.get("HPCM_CLI"), reason="HPCM_CLI (the hpcm tool) not given")
def test_cli_version_is_the_python_modules_version():
    p = subprocess.run([os.environ["HPCM_CLI"], "--version"], capture_output=True, text=True, timeout=30)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == f"hpcm {hpcm.__version__}"


def test_progress_true_uses_tqdm_where_installed(monkeypatch):
    bars = []

    class FakeTqdm:  # stands in for tqdm.tqdm: records what the bar is told
        def __init__(self, total, desc, unit):
            self.n, self.total, self.closed = 0, total, False
            bars.append(self)

        def update(self, k):
            self.n += k

        def close(self):
            self.closed = True

    monkeypatch.setitem(sys.modules, "tqdm", type(sys)("tqdm"))
    sys.modules["tqdm"].tqdm = FakeTqdm
    hpcm.Simulation(hpcm.phantom((24, 20, 16))).run(12, progress=True)
    assert len(bars) == 1 and bars[0].total == 12 and bars[0].n == 12 and bars[0].closed
    hpcm.run_experiment(hpcm.phantom((24, 20, 16)), settle_frames=3, progress=True)
    assert len(bars) == 4  # one per condition A, B, C
    assert all(b.n == b.total and b.closed for b in bars[1:])
