"""A Simulation used from several Python threads at once: calls take turns, nothing crashes or hangs.

Each scenario runs in a child interpreter with a time limit, so a crash (abort, segfault) or a
deadlock fails the test instead of killing or stalling the test run."""
import os
import subprocess
import sys
import textwrap

import pytest

import hpcm

# What every child script starts with: a small phantom and a simulation holding a grab.
PRELUDE = """
import threading, sys
import numpy as np
import hpcm
vol = hpcm.phantom((24, 20, 16))
sim = hpcm.Simulation(vol)
sim.grab("auto")
sim.move_tool((0.0, -1.0, 0.0))
errors = []

def guarded(f):
    def run():
        try:
            f()
        except BaseException as e:  # reported by the parent test
            errors.append(repr(e))
    return run

def start(*functions):
    threads = [threading.Thread(target=guarded(f)) for f in functions]
    for t in threads:
        t.start()
    for t in threads:
        t.join(60)
        if t.is_alive():
            print("a thread is still running after 60 s", flush=True)
            import os; os._exit(3)
    if errors:
        print("errors:", errors, flush=True)
        sys.exit(2)
"""


def run_child(body, timeout=90):
    script = PRELUDE + textwrap.dedent(body)
    try:
        p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=timeout,
                           env=dict(os.environ))
    except subprocess.TimeoutExpired:
        pytest.fail(f"the threads deadlocked: no result after {timeout} s")
    assert p.returncode == 0, f"child exited with {p.returncode}\nstdout: {p.stdout[-2000:]}\nstderr: {p.stderr[-2000:]}"
    return p.stdout


def test_four_threads_stepping_one_simulation_take_turns():
    out = run_child("""
        def stepper():
            for _ in range(100):
                sim.step()
        start(stepper, stepper, stepper, stepper)
        print("frame", sim.frame)
        """)
    assert "frame 400" in out  # every step counted once: the calls took turns


def test_run_in_one_thread_and_every_other_call_in_another(tmp_path):
    # The exports read the simulation too (they keep the GIL, the running frames do not).
    out = run_child(f"""
        inp = hpcm.prepare_input(vol) if hpcm.has_io else None
        if inp is not None:
            sim = hpcm.Simulation(inp.lattice)
            sim.grab("auto")
            sim.move_tool((0.0, -1.0, 0.0))
        done = threading.Event()
        def runner():
            try:
                sim.run(3000)
            finally:
                done.set()
        def reader():
            calls = 0
            while not done.is_set() or calls < 3:
                p = sim.positions()
                d = sim.displacement()
                if calls % 8 == 0:  # the rest less often: collisions with the frames are what matters
                    assert np.isfinite(p).all() and np.isfinite(d).all()
                    sim.velocities(); sim.state(); sim.frame; sim.tool_offset; sim.grabbed
                    if inp is not None:
                        assert np.isfinite(hpcm.displacement_mm(inp, sim)).all()
                        hpcm.write_displacement_field(inp, sim, r"{tmp_path}/u%d.nii.gz" % (calls % 2))
                calls += 1
        def toolmaker():
            for k in range(20):
                sim.release()
                sim.grab("auto")
                sim.move_tool((0.0, -0.1 * k, 0.0))
            sim.reset()
        for round in range(20):  # each round collides at different moments
            done.clear()
            start(runner, reader, toolmaker)
        print("ok")
        """)
    assert "ok" in out


def test_scenario_players_and_params_from_several_threads():
    run_child("""
        player = hpcm.ScenarioPlayer(hpcm.Scenario.paper_protocol(distance=2, pull=20, hold=10, record=600), sim)
        def play():
            while not player.done:
                player.step()
        def tune():
            for k in range(10):
                p = sim.params
                p["dynamics.alpha"] = 0.9 + 0.005 * k
                sim.params = p
                sim.step()
        start(play, play, play, play, tune)
        """)


def test_a_failing_progress_callback_surfaces_as_its_own_exception(tmp_path):
    def progress(condition, done, total):
        raise KeyError("stop here")

    with pytest.raises(KeyError, match="stop here"):
        hpcm.run_experiment(hpcm.phantom((24, 20, 16)), scenario=hpcm.Scenario.paper_protocol(distance=2, pull=4, hold=2, record=4),
                            settle_frames=2, progress=progress)
