"""Cohorts on Dask (issue 33): python3 -m hpcm.cohort / hpcm.cohort.run.

One cohort of phantom variants, the abdomen CT and the DICOM series at f = 4 and a broken input
runs on a LocalCluster with two workers, and one worker is killed (SIGKILL) while it runs a case.
The same cohort is then checked against each case run alone with `hpcm experiment` (bitwise for
every non-timing figure), run again (resume), and a 2x2 sweep writes four rows."""
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest

from hpcm import cohort

DATA = Path(os.environ.get("HPCM_SHARED_DATA", "../shared/data"))
NIFTI = DATA / "abdomen-ct" / "abdomen_ct.nii.gz"
DICOM = DATA / "abdomen-ct-dicom"
HPCM = os.environ.get("HPCM_EXE") or os.environ.get("HPCM_CLI") or shutil.which("hpcm")
pytestmark = pytest.mark.skipif(not HPCM, reason="the hpcm executable is not known (HPCM_EXE / HPCM_CLI)")

SETTLE = "40"  # idle frames of the settling check: short, the test is about the cohort machinery
# The case the killer waits for: the largest, so it is still running when its worker dies.
SLOW = "phantom:48,48,32:thick-fat"
PHANTOMS = ["phantom:32,32,20", "phantom:32,32,20:thin-tissue", "phantom:32,32,20:air-pockets", SLOW]


def cohort_inputs(tmp_path):
    broken = tmp_path / "broken.nii.gz"
    broken.write_bytes(NIFTI.read_bytes()[:2000] if NIFTI.exists() else b"not a volume")  # truncated
    # The CTs at f = 4 through a manifest (the phantoms keep their size: the default downsample 1).
    manifest = tmp_path / "cts.csv"
    manifest.write_text("input,downsample\n" + "".join(f"{p},4\n" for p in (NIFTI, DICOM) if p.exists()))
    return list(PHANTOMS) + [str(manifest), str(broken)]


def run_cohort(inputs, out, **kw):
    kw.setdefault("settle_frames", SETTLE)
    return cohort.run(inputs, out, hpcm_exe=HPCM, workers=2, progress=False, **kw)


class WorkerKiller:
    """Kills (SIGKILL) the worker process that runs the SLOW case once it has started it."""

    def __init__(self):
        self.killed_pid = None
        self.case = None

    def __call__(self, client):
        threading.Thread(target=self._kill, args=(client,), daemon=True).start()

    def _kill(self, client):
        case = next(c.id for c in self.cases if "thick-fat" in c.id)
        key = f"hpcm-case-{case}"
        log = self.out / "logs" / f"{case}.log"  # run_case opens it as it starts the case's hpcm
        deadline = time.time() + 60
        while time.time() < deadline:
            if log.exists():
                time.sleep(0.3)  # well into its hpcm
                address = next(a for a, keys in client.processing().items() if key in keys)
                self.killed_pid = client.run(os.getpid, workers=[address])[address]
                self.case = case
                os.kill(self.killed_pid, signal.SIGKILL)
                return
            time.sleep(0.05)


@pytest.fixture(scope="module")
def killed_cohort(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cohort")
    inputs = cohort_inputs(tmp)
    killer = WorkerKiller()
    killer.cases, _ = cohort._cases_for(inputs, tmp / "probe", "experiment", "", "", 1, HPCM)
    killer.out = tmp / "out"
    start = time.time()
    table = run_cohort(inputs, tmp / "out", on_started=killer)
    return {"tmp": tmp, "inputs": inputs, "table": table, "killer": killer, "wall": time.time() - start}


def test_a_killed_worker_is_survived_and_every_good_case_completes(killed_cohort):
    t, killer = killed_cohort["table"], killed_cohort["killer"]
    assert killer.killed_pid, "the worker running the slow case was not found to kill"
    row = t[t["case"] == killer.case].iloc[0]
    assert row["status"] == "done", row["error"]
    # Run again after its worker died: recorded by another worker process.
    assert not row["worker"].endswith(f":{killer.killed_pid}"), row["worker"]
    good = t[t["input"] != killed_cohort["inputs"][-1]]
    assert (good["status"] == "done").all(), good[["case", "status", "error"]].to_string()
    assert len(good) >= 6 or not (NIFTI.exists() and DICOM.exists())


def test_a_broken_input_is_recorded_with_its_error(killed_cohort):
    t = killed_cohort["table"]
    broken = t[t["input"] == killed_cohort["inputs"][-1]]
    assert list(broken["status"]) == ["failed"]
    assert "broken.nii.gz" in broken.iloc[0]["error"]
    csv = pd.read_csv(killed_cohort["tmp"] / "out" / "cohort.csv")
    assert len(csv) == len(t) and list(csv["status"]).count("failed") == 1


TIMING = ("_ms", "wall_s", "worker", "resumed")


def _without_timing(summary):
    summary.pop("machine")
    for c in summary["conditions"].values():
        c.pop("timing_ms")
    return summary


def test_each_case_equals_hpcm_experiment_alone(killed_cohort):
    tmp, t = killed_cohort["tmp"], killed_cohort["table"]
    csv = pd.read_csv(tmp / "out" / "cohort.csv", float_precision="round_trip")
    done = csv[csv["status"] == "done"]
    assert len(done) == len(PHANTOMS) + NIFTI.exists() + DICOM.exists()
    for _, row in done.iterrows():
        record = json.loads((tmp / "out" / "records" / f"{row['case']}.json").read_text())
        argv = record["command"]
        assert argv[:2] == [os.path.abspath(HPCM), "experiment"]
        alone = tmp / "alone" / row["case"]
        argv = [alone.as_posix() if a == str(tmp / "out" / "cases" / row["case"]) else a for a in argv]
        assert str(alone) in argv
        subprocess.run(argv, check=True, capture_output=True)  # as a user runs it: no cohort, no Dask
        case_dir = tmp / "out" / "cases" / row["case"]
        for name in ("table2.csv", "curves.csv"):
            assert (case_dir / name).read_bytes() == (alone / name).read_bytes(), f"{row['case']}: {name} differs"
        mine = _without_timing(json.loads((case_dir / "summary.json").read_text()))
        theirs = _without_timing(json.loads((alone / "summary.json").read_text()))
        assert mine == theirs, row["case"]
        expected = cohort.experiment_row(alone)
        for col, value in expected.items():
            if col.endswith(TIMING) or col == "tool_limited_where":
                continue
            got = row[col]
            if isinstance(value, float) and math.isnan(value):
                assert math.isnan(got), (row["case"], col)
            else:
                assert got == value, (row["case"], col, got, value)
        assert row["C_skin_fat_peak"] > 0  # a real figure, not a default
    assert any(c.startswith("check_") for c in csv.columns)
    assert set(v for c in csv.columns if c.startswith("check_") for v in done[c]) <= {"held", "failed", "not_applicable"}


def test_a_second_run_resumes_and_redoes_nothing_finished(killed_cohort):
    tmp, inputs = killed_cohort["tmp"], killed_cohort["inputs"]
    out = tmp / "out"
    before = {p: p.stat().st_mtime_ns for p in (out / "cases").glob("*/summary.json")}
    assert before
    t = run_cohort(inputs, out)
    assert {p: p.stat().st_mtime_ns for p in (out / "cases").glob("*/summary.json")} == before
    done = t[t["status"] == "done"]
    assert done["resumed"].all() and len(done) == len(before)
    assert list(t[t["status"] == "failed"]["resumed"]) == [False]  # a failed case is tried again
    # An unfinished case (its folder gone) is the only one run again.
    victim = done.iloc[0]["case"]
    shutil.rmtree(out / "cases" / victim)
    t = run_cohort(inputs, out)
    assert list(t[~t["resumed"] & (t["status"] == "done")]["case"]) == [victim]
    assert (out / "cases" / victim / "summary.json").is_file()


def test_report_and_plots(killed_cohort):
    out = killed_cohort["tmp"] / "out"
    report = (out / "cohort_report.md").read_text()
    assert "| C_skin_fat_peak |" in report and "Checks per case" in report and "speed-up" in report
    assert (out / "plots" / "table2_C.png").stat().st_size > 1000


def test_a_2x2_sweep_writes_four_rows_with_the_swept_values(tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('[grid]\n"dynamics.alpha" = [0.8, 0.95]\n"dynamics.b0" = [0.05, 0.2]\n')
    t = run_cohort(["phantom:32,32,20"], tmp_path / "out", job="sweep", sweep=str(sweep))
    assert (t["status"] == "done").all(), t["error"].tolist()
    assert sorted(zip(t["dynamics.alpha"], t["dynamics.b0"])) == [(0.8, 0.05), (0.8, 0.2), (0.95, 0.05), (0.95, 0.2)]
    for _, row in t.iterrows():
        summary = json.loads((tmp_path / "out" / "cases" / row["case"] / "summary.json").read_text())
        assert summary["params"]["dynamics"]["alpha"] == pytest.approx(row["dynamics.alpha"])
        assert summary["params"]["dynamics"]["b0"] == pytest.approx(row["dynamics.b0"])
    assert len(set(t["C_skin_fat_peak"])) > 1  # the parameters reached the simulation
    assert (tmp_path / "out" / "plots" / "sweep_dynamics_alpha.png").is_file()


def test_an_invalid_sweep_set_stops_the_cohort_before_anything_runs(tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('[[set]]\n"dynamics.alpha" = 0.9\n[[set]]\nname = "bad"\n"dynamics.alpha" = -3.0\n')
    with pytest.raises(cohort.CohortError, match="sweep set bad.*alpha"):
        run_cohort(["phantom:32,32,20"], tmp_path / "out", job="sweep", sweep=str(sweep))
    assert not (tmp_path / "out" / "cases").exists()
    assert not (tmp_path / "out" / cohort.LOCK_NAME).exists()


def test_two_cohorts_into_one_folder_are_refused_and_a_stale_lock_is_taken(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    lock = cohort.CohortLock(out)  # this process is the live first cohort
    with pytest.raises(cohort.CohortError, match="another cohort"):
        run_cohort(["phantom:24,24,16"], out)
    lock.release()
    # A lock left by a process that is gone: taken over.
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (out / cohort.LOCK_NAME).write_text(f"host {os.uname().nodename}\npid {dead.pid} start 1\n")
    t = run_cohort(["phantom:24,24,16"], out)
    assert list(t["status"]) == ["done"]
    assert not (out / cohort.LOCK_NAME).exists()


def test_inputs_expand_from_folders_and_manifests(tmp_path):
    (tmp_path / "cts").mkdir()
    for n in ("a.nii.gz", "b.nrrd", "notes.txt"):
        (tmp_path / "cts" / n).write_text("x")
    (tmp_path / "cts" / "series1").mkdir()
    cases = cohort.expand_inputs([str(tmp_path / "cts")], 2)
    assert [Path(c.input).name for c in cases] == ["a.nii.gz", "b.nrrd", "series1"]
    manifest = tmp_path / "m.csv"
    manifest.write_text("input,downsample,roi,series\ncts/a.nii.gz,4,0,0,0,8,8,8,\nphantom:32,32,20,,,\n")
    with pytest.raises(cohort.CohortError, match="line 2"):  # the ROI's commas need quotes
        cohort.expand_inputs([str(manifest)])
    manifest.write_text('input,downsample,roi,series\ncts/a.nii.gz,4,"0,0,0,8,8,8",#2\n"phantom:32,32,20",,,\n')
    a, p = cohort.expand_inputs([str(manifest)], 3)
    assert a.source_args() == ["--input", str(tmp_path / "cts" / "a.nii.gz"), "--series", "#2", "--downsample", "4",
                               "--roi", "0,0,0,8,8,8"]
    assert p.source_args() == ["--phantom", "32,32,20", "--downsample", "3"]
    manifest.write_text("input,downsample\nx.nii,0\n")
    with pytest.raises(cohort.CohortError, match="line 2: downsample '0'"):
        cohort.expand_inputs([str(manifest)])


def test_workers_are_sized_by_cores_and_memory():
    assert cohort.plan_workers(16, 4, 1e9, 64e9) == (4, int(1e9 + cohort.WORKER_OVERHEAD_BYTES))
    n, limit = cohort.plan_workers(16, 1, 10e9, 32e9)
    assert n == 3 and limit == int(10e9 + cohort.WORKER_OVERHEAD_BYTES)  # memory allows 3, not 16
    assert cohort.plan_workers(2, 8, 1e6, None)[0] == 1


def test_command_line_refuses_a_missing_executable(tmp_path):
    p = subprocess.run([sys.executable, "-m", "hpcm.cohort", "--out", str(tmp_path / "o"), "--hpcm",
                        str(tmp_path / "nope"), "phantom:24,24,16"], capture_output=True, text=True)
    assert p.returncode == 2 and "nope: not an executable file" in p.stderr


def _alive(pid):
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_a_case_process_dies_with_its_worker():
    # A killed worker must not leave its hpcm writing into the folder the retry uses.
    code = ("import subprocess; from hpcm import cohort; "
            "p = subprocess.Popen(['sleep', '30'], preexec_fn=cohort._die_with_parent); print(p.pid, flush=True); p.wait()")
    worker = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    child = int(worker.stdout.readline())
    assert _alive(child)
    worker.kill()
    worker.wait()
    deadline = time.time() + 5
    while _alive(child) and time.time() < deadline:
        time.sleep(0.05)
    assert not _alive(child)


def test_a_retry_waits_until_the_killed_workers_hpcm_is_gone(tmp_path):
    # hpcm refuses a staging folder whose writer lives: the retry waits for the dying one.
    writer = subprocess.Popen(["sleep", "1"])
    threading.Thread(target=writer.wait, daemon=True).start()  # reaped as init reaps an orphan
    staging = tmp_path / "case.incomplete"
    staging.mkdir()
    (staging / cohort.OUTPUT_MARKER).write_text(f"hpcm output folder (in progress)\npid {writer.pid} start "
                                                f"{cohort._process_start(writer.pid)}\n")
    start = time.time()
    cohort._wait_for_dead_writer(tmp_path / "case", timeout_s=20)
    assert writer.poll() is not None and 0.5 < time.time() - start < 10


def test_a_scenario_run_cohort_writes_frames_and_exports(tmp_path):
    scenario = tmp_path / "paper.toml"
    scenario.write_text(subprocess.run([HPCM, "params", "--scenario-paper"], capture_output=True, text=True,
                                       check=True).stdout)
    t = run_cohort(["phantom:24,24,16", "phantom:24,24,16:table"], tmp_path / "out", job="run", scenario=str(scenario))
    assert (t["status"] == "done").all(), t["error"].tolist()
    assert list(t["frames"]) == [150, 150] and (t["exports"] >= 1).all()
    for case in t["case"]:
        assert (tmp_path / "out" / "cases" / case / "export" / "export.json").is_file()


def test_a_rerun_with_other_settings_computes_again(tmp_path):
    # Resume takes only cases computed from the same command and files: a changed setting or a
    # changed parameter file must not leave the earlier figures in the table.
    params = tmp_path / "p.toml"
    params.write_text("[dynamics]\nalpha = 0.9\n")
    first = run_cohort(["phantom:24,24,16"], tmp_path / "out", params=str(params))
    assert list(run_cohort(["phantom:24,24,16"], tmp_path / "out", params=str(params))["resumed"]) == [True]
    assert list(run_cohort(["phantom:24,24,16"], tmp_path / "out", params=str(params),
                           settle_frames="41")["resumed"]) == [False]
    params.write_text("[dynamics]\nalpha = 0.8\n")
    again = run_cohort(["phantom:24,24,16"], tmp_path / "out", params=str(params), settle_frames="41")
    assert list(again["resumed"]) == [False] and list(again["status"]) == ["done"]
    summary = json.loads((tmp_path / "out" / "cases" / first["case"][0] / "summary.json").read_text())
    assert summary["params"]["dynamics"]["alpha"] == pytest.approx(0.8)


def test_the_memory_figures_are_hpcms_own():
    # cohort.BYTES_PER_ELEMENT mirrors apps/common/memory_estimate.hpp (what hpcm refuses by).
    header = Path(__file__).resolve().parents[2] / "apps" / "common" / "memory_estimate.hpp"
    text = header.read_text()
    assert f"kExperimentBytesPerElement = {cohort.BYTES_PER_ELEMENT['experiment']};" in text
    assert f"kRunBytesPerElement = {cohort.BYTES_PER_ELEMENT['run']};" in text


@pytest.mark.parametrize("option", [{"settle_frames": 0}, {"downsample": 0}, {"threads_per_case": 0}, {"workers": 0}])
def test_options_out_of_range_are_refused_before_anything_runs(tmp_path, option):
    with pytest.raises(cohort.CohortError, match=r"must be an integer in \[1, "):
        cohort.run(["phantom:24,24,16"], tmp_path / "out", hpcm_exe=HPCM, progress=False, **option)
    assert not (tmp_path / "out").exists()


def test_an_existing_dask_cluster_runs_the_same_cohort(tmp_path):
    """--scheduler ADDRESS: the cohort runs unchanged on a cluster it did not start (here a
    LocalCluster of one worker process started by the test) and writes the same figures."""
    from distributed import Client, LocalCluster
    inputs = ["phantom:32,32,20", "phantom:32,32,20:air-pockets"]
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            pids = set(client.run(os.getpid).values())
        table = cohort.run(inputs, tmp_path / "remote", hpcm_exe=HPCM, scheduler=cluster.scheduler_address,
                           settle_frames=SETTLE, progress=False)
    # Every case ran in that cluster's worker process (the record names host:pid).
    assert {int(w.rsplit(":", 1)[1]) for w in table["worker"]} <= pids, (list(table["worker"]), pids)
    local = cohort.run(inputs, tmp_path / "local", hpcm_exe=HPCM, workers=1, settle_frames=SETTLE, progress=False)
    assert list(table["status"]) == ["done", "done"]
    figures = [c for c in table.columns if c.startswith(("A_", "B_", "C_")) and "time" not in c and "_ms" not in c]
    assert figures, "no figure columns in cohort.csv"
    pd.testing.assert_frame_equal(table.sort_values("case")[figures].reset_index(drop=True),
                                  local.sort_values("case")[figures].reset_index(drop=True))
