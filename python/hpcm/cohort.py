"""hpcm cohorts on Dask: the paper experiment, a scenario run or a parameter sweep over many CTs.

    python3 -m hpcm.cohort --out cohort/ --experiment ct1.nii.gz dicom_dir/ phantom:64,64,40:thick-fat
    python3 -m hpcm.cohort --out sweep/ --sweep sweep.toml --downsample 4 ct.nii.gz

One Dask task per (input, parameter set). Each task starts the `hpcm` command-line tool (an
argument vector, never a shell) into the case's own output folder, which hpcm stages and commits
only when the case is complete; so a crash stays in its case, and a case's figures are the ones
`hpcm experiment` gives when run alone. At the end, cohort.csv (one row per case and parameter
set, pandas) and cohort_report.md with plots (matplotlib). See docs/cohort.md.
"""
import argparse
import csv
import ctypes
import hashlib
import itertools
import json
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
import tomllib
from pathlib import Path

__all__ = ["CohortError", "Case", "expand_inputs", "load_sweep", "run", "main"]

TISSUES = ("air", "skin_fat", "muscle_organ", "bone")
CONDITIONS = ("A", "B", "C")
FIGURES = ("initial", "peak", "auc")
VOLUME_SUFFIXES = (".nii", ".nii.gz", ".nrrd", ".nhdr", ".mha", ".mhd")
MANIFEST_COLUMNS = ("input", "downsample", "roi", "series")
LOCK_NAME = ".hpcm-cohort.lock"
OUTPUT_MARKER = ".hpcm-output"  # apps/hpcm/output_dir.hpp kOutputMarker
# Peak bytes per lattice element of one case (apps/common/memory_estimate.hpp, measured).
BYTES_PER_ELEMENT = {"experiment": 220, "sweep": 220, "run": 160}
WORKER_OVERHEAD_BYTES = 500e6  # a Dask worker process itself (about 120 MB measured), without the case


class CohortError(ValueError):
    """A cohort that cannot start: bad option, input list, sweep file or output folder."""


# ---- cases ---------------------------------------------------------------------------------


class Case:
    """One (input, parameter set): what to run and where its results go."""

    def __init__(self, input, downsample=1, roi="", series="", set_name="", set_values=None, params_file=""):
        # Absolute: the workers of a cluster need not share the command's working folder.
        self.input = str(input) if str(input).startswith("phantom:") else os.path.abspath(input)
        self.downsample = int(downsample)
        self.roi = roi or ""
        self.series = series or ""
        self.set_name = set_name
        self.set_values = dict(set_values or {})
        self.params_file = params_file
        self.id = ""

    def is_phantom(self):
        return self.input.startswith("phantom:")

    def source_args(self):
        """hpcm's volume options for this case (--phantom/--phantom-variant/--seed or --input ...)."""
        if self.is_phantom():
            parts = self.input.split(":")
            if len(parts) > 4 or not parts[1]:
                raise CohortError(f"{self.input}: a phantom input is phantom:NX,NY,NZ[:VARIANT[:SEED]]")
            args = ["--phantom", parts[1]]
            if len(parts) > 2 and parts[2]:
                args += ["--phantom-variant", parts[2]]
            if len(parts) > 3 and parts[3]:
                args += ["--seed", parts[3]]
        else:
            args = ["--input", self.input]
            if self.series:
                args += ["--series", self.series]
        if self.downsample != 1:
            args += ["--downsample", str(self.downsample)]
        if self.roi:
            args += ["--roi", self.roi]
        return args

    def base_name(self):
        if self.is_phantom():
            parts = self.input.split(":")
            name = "phantom-" + parts[1].replace(",", "x") + "".join("-" + p for p in parts[2:] if p)
        else:
            p = Path(self.input.rstrip("/"))
            name = p.name
            for suffix in VOLUME_SUFFIXES:
                if name.lower().endswith(suffix):
                    name = name[: -len(suffix)]
                    break
        if self.downsample != 1:
            name += f"-f{self.downsample}"
        if self.roi:
            name += "-roi" + self.roi.replace(",", "_")
        if self.series:
            name += "-series" + self.series.lstrip("#")
        if self.set_name:
            name += "--" + self.set_name
        return re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("._") or "case"


def _is_volume_file(p):
    return p.is_file() and p.name.lower().endswith(VOLUME_SUFFIXES)


def _read_manifest(path, default_downsample):
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise CohortError(f"manifest {path}: cannot read it as CSV ({e})") from None
    header = [h.strip() for h in rows[0]] if rows else []
    if "input" not in header or any(h not in MANIFEST_COLUMNS for h in header) or len(set(header)) != len(header):
        raise CohortError(f"manifest {path}: the header must name the columns input (required), downsample, roi, "
                          f"series; found {header}")
    cases = []
    for line, fields in enumerate(rows[1:], start=2):
        if not any(x.strip() for x in fields):
            continue
        if len(fields) != len(header):
            raise CohortError(f"manifest {path} line {line}: {len(fields)} fields for {len(header)} columns "
                              "(quote a ROI: \"x0,y0,z0,x1,y1,z1\")")
        row = {h: x.strip() for h, x in zip(header, fields)}
        text = row["input"]
        if not text:
            raise CohortError(f"manifest {path} line {line}: input is empty")
        where = text if text.startswith("phantom:") or os.path.isabs(text) else str(Path(path).parent / text)
        f = row.get("downsample") or str(default_downsample)
        if not re.fullmatch(r"[0-9]+", f) or not 1 <= int(f) <= 4096:
            raise CohortError(f"manifest {path} line {line}: downsample '{f}' must be an integer in [1, 4096]")
        cases.append(Case(where, int(f), row.get("roi", ""), row.get("series", "")))
    return cases


def expand_inputs(inputs, downsample=1):
    """Cases for a list of inputs: volume files, DICOM folders, folders of them (one case per
    volume file and per sub-folder), CSV manifests (columns input, downsample, roi, series) and
    phantoms written phantom:NX,NY,NZ[:VARIANT[:SEED]]. A path that does not exist stays a case
    (it fails and is recorded)."""
    cases = []
    for item in inputs:
        text = str(item)
        p = Path(text)
        if text.startswith("phantom:"):
            cases.append(Case(text, downsample))
        elif p.is_file() and p.suffix.lower() == ".csv":
            cases += _read_manifest(p, downsample)
        elif p.is_dir():
            entries = sorted(p.iterdir())
            if any(_is_volume_file(e) or e.is_dir() for e in entries):
                cases += [Case(str(e), downsample) for e in entries if _is_volume_file(e) or e.is_dir()]
            else:
                cases.append(Case(text, downsample))  # a DICOM series folder
        else:
            cases.append(Case(text, downsample))
    if not cases:
        raise CohortError("no inputs: name volume files, DICOM folders, folders of them, a CSV manifest or phantom:NX,NY,NZ")
    return cases


# ---- sweeps --------------------------------------------------------------------------------


def load_sweep(path):
    """Parameter sets of a sweep file: [grid] (every combination, in file order) or [[set]]
    (a list; an optional `name` per set). Keys are parameter-file names ("dynamics.alpha").
    Returns [(set_name, {key: value})] and the optional base parameter file."""
    try:
        doc = tomllib.loads(Path(path).read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise CohortError(f"sweep {path}: {e}") from None
    unknown = set(doc) - {"base", "grid", "set"}
    if unknown or ("grid" in doc) == ("set" in doc):
        raise CohortError(f"sweep {path}: give exactly one of [grid] or [[set]] (and optionally base = \"params.toml\"); "
                          f"unknown keys: {sorted(unknown)}")
    base = doc.get("base", "")
    if base and not os.path.isabs(base):
        base = str(Path(path).parent / base)
    sets = []
    if "grid" in doc:
        grid = _flatten(doc["grid"]) if isinstance(doc["grid"], dict) else None  # [grid.dynamics] alpha = [...]
        if not grid:
            raise CohortError(f"sweep {path}: [grid] must map parameter names to lists of values")
        for key, values in grid.items():
            if not isinstance(values, list) or not values:
                raise CohortError(f"sweep {path}: grid.{key} must be a non-empty list of values")
        keys = list(grid)
        for combo in itertools.product(*(grid[k] for k in keys)):
            sets.append(dict(zip(keys, combo)))
        names = [f"set{i + 1:03d}" for i in range(len(sets))]
    else:
        raw = doc["set"]
        if not isinstance(raw, list) or not raw or not all(isinstance(s, dict) for s in raw):
            raise CohortError(f"sweep {path}: [[set]] must be a list of tables")
        names, sets = [], []
        for i, s in enumerate(raw):
            s = dict(s)
            name = str(s.pop("name", f"set{i + 1:03d}"))
            if not re.fullmatch(r"[A-Za-z0-9._-]+", name) or name in names:
                raise CohortError(f"sweep {path}: set {i + 1}: name '{name}' must be unique and of letters, digits, . _ -")
            if not s:
                raise CohortError(f"sweep {path}: set {name} sets no parameter")
            names.append(name)
            sets.append(s)
    return list(zip(names, sets)), base


def _flatten(values, prefix=""):
    """{"dynamics": {"alpha": 1}} or {"dynamics.alpha": 1} -> {"dynamics.alpha": 1}."""
    flat = {}
    for k, v in values.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and "." not in k and not prefix:
            flat.update(_flatten(v, key + "."))
        else:
            flat[key] = v
    return flat


def write_sweep_params(sweep, params_dir, base_params, hpcm_exe):
    """Writes one parameter file per set and validates every one with the hpcm that runs the
    cases (`hpcm params --check`) before anything starts: the first invalid set stops the cohort."""
    import hpcm

    sets, base = sweep
    base = base_params or base
    params_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, values in sets:
        try:
            p = hpcm.Params.load(base) if base else hpcm.Params()
            p.update(_flatten(values))
        except (hpcm.Error, OSError) as e:
            raise CohortError(f"sweep set {name} {values}: {e}") from None
        path = params_dir / f"{name}.toml"
        path.write_text(p.to_toml())
        check = subprocess.run([hpcm_exe, "params", "--check", str(path)], capture_output=True, text=True)
        if check.returncode != 0:
            raise CohortError(f"sweep set {name} {values}: {path}: {check.stderr.strip() or check.stdout.strip()}")
        written.append((name, _flatten(values), str(path)))
    return written


# ---- the hpcm executable, the command of a case ----------------------------------------------


def find_hpcm(exe=None):
    """--hpcm, else $HPCM_EXE, else `hpcm` on PATH, else the build folder next to this package."""
    for candidate in (exe, os.environ.get("HPCM_EXE")):
        if candidate:
            if not (os.path.isfile(candidate) and os.access(candidate, os.X_OK)):
                raise CohortError(f"hpcm executable {candidate}: not an executable file (--hpcm / HPCM_EXE)")
            return os.path.abspath(candidate)
    on_path = shutil.which("hpcm")
    if on_path:
        return on_path
    here = Path(__file__).resolve().parent  # <build>/python/hpcm when run from a build tree
    for c in (here.parent.parent / "apps" / "hpcm" / "hpcm", here.parent.parent / "bin" / "hpcm"):
        if c.is_file() and os.access(c, os.X_OK):
            return str(c)
    raise CohortError("the hpcm executable was not found: give --hpcm PATH or set HPCM_EXE, or put hpcm on PATH")


def case_command(hpcm_exe, job, case, out_dir, settle_frames=None, scenario="", params="", export_args=()):
    """The argument vector that runs one case (never a shell)."""
    params = case.params_file or params
    if job == "run":
        argv = [hpcm_exe, "run", *case.source_args(), "--out", out_dir]
        if scenario:
            argv += ["--scenario", scenario]
        argv += ["--export", str(Path(out_dir) / "export"), *export_args]
    else:
        argv = [hpcm_exe, "experiment", *case.source_args(), "--out", out_dir, "--no-report"]
        if scenario:
            argv += ["--scenario", scenario]
        if settle_frames:
            argv += ["--settle-frames", str(settle_frames)]
    if params:
        argv += ["--params", params]
    return argv


def case_fingerprint(argv, params_file, scenario_file):
    """What a finished case was computed from: its command, the contents of its parameter and
    scenario files, and the hpcm executable (size and time of change)."""
    h = hashlib.sha256(json.dumps(argv).encode())
    for path in (params_file, scenario_file, argv[0]):
        if path and os.path.isfile(path):
            st = os.stat(path)
            h.update(f"{path} {st.st_size} {st.st_mtime_ns}".encode() if path == argv[0] else Path(path).read_bytes())
    return h.hexdigest()


def is_finished(case_dir, job):
    """A case folder hpcm committed: its marker lists the files of a finished run."""
    marker = Path(case_dir) / OUTPUT_MARKER
    try:
        text = marker.read_text()
    except OSError:
        return False
    wanted = "frames.csv" if job == "run" else "summary.json"
    return "\nentries " in text and (Path(case_dir) / wanted).is_file()


# ---- one case, on a Dask worker --------------------------------------------------------------


def _die_with_parent():
    """In the child, before exec: SIGKILL when the worker that started it dies (a killed
    worker must not leave its hpcm writing into the folder its retry uses)."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except OSError:
        pass


def _error_text(log_text):
    lines = [ln for ln in log_text.splitlines() if ln.strip()]
    errors = [ln for ln in lines if "error" in ln.lower()]
    return " | ".join((errors or lines)[-3:])[:2000]


def _wait_for_dead_writer(case_dir, timeout_s=30.0):
    """A retry after a killed worker: the killed worker's hpcm (sent SIGKILL as its worker died)
    may still exist for a moment, and hpcm refuses a staging folder whose writer lives. Waits
    until that process is gone (at most `timeout_s`; then hpcm's own refusal names it)."""
    marker = Path(str(case_dir) + ".incomplete") / OUTPUT_MARKER
    try:
        m = re.search(r"^pid (\d+) start (\d+)", marker.read_text(), re.M)
    except OSError:
        return
    deadline = time.time() + timeout_s
    while m and time.time() < deadline and _process_start(int(m.group(1))) == m.group(2):
        time.sleep(0.1)


def run_case(task):
    """Runs one case's hpcm command; returns what happened (never raises for a failed case)."""
    _wait_for_dead_writer(task["out"])
    start = time.time()
    log_path = Path(task["log"])
    log_path.parent.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, OMP_NUM_THREADS=str(task["threads"]), CI="1")  # CI: no progress bars in the log
    with open(log_path, "wb") as log:
        try:
            proc = subprocess.run(task["argv"], stdout=log, stderr=subprocess.STDOUT, env=env,
                                  preexec_fn=_die_with_parent)
            rc = proc.returncode
        except OSError as e:
            rc, extra = 127, f"cannot start {task['argv'][0]}: {e}"
            log.write(extra.encode())
    result = {"id": task["id"], "returncode": rc, "wall_s": time.time() - start,
              "worker": f"{socket.gethostname()}:{os.getpid()}", "error": ""}
    if rc != 0:
        text = log_path.read_text(errors="replace")
        how = f"signal {-rc}" if rc < 0 else f"exit status {rc}"
        result["error"] = f"hpcm {how}: {_error_text(text)}"
    elif not is_finished(task["out"], task["job"]):
        result["returncode"] = -1
        result["error"] = f"hpcm exited 0 but {task['out']} is not a finished output folder"
    return result


# ---- the cohort folder's lock ----------------------------------------------------------------


def _process_start(pid):
    """Start time of a process (clock ticks after boot), "" when it does not exist."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return ""
    return stat[stat.rfind(")") + 2:].split()[19]


class CohortLock:
    """out/.hpcm-cohort.lock holding host, pid and start time: a second cohort into the same
    folder is refused while the first lives; a lock whose process is gone is stale and taken."""

    def __init__(self, out):
        self.path = Path(out) / LOCK_NAME
        me = f"host {socket.gethostname()}\npid {os.getpid()} start {_process_start(os.getpid())}\n"
        for _ in range(2):
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                self._refuse_or_clear()
                continue
            with os.fdopen(fd, "w") as f:
                f.write(me)
            return
        raise CohortError(f"{self.path}: another cohort took the lock at the same time")

    def _refuse_or_clear(self):
        text = self.path.read_text(errors="replace")
        host = re.search(r"^host (\S+)", text, re.M)
        m = re.search(r"^pid (\d+) start (\d*)", text, re.M)
        if host and host.group(1) != socket.gethostname():
            raise CohortError(f"{self.path.parent}: a cohort on host {host.group(1)} holds {self.path}; "
                              "if it is gone, delete the lock file")
        if m and _process_start(int(m.group(1))) and _process_start(int(m.group(1))) == m.group(2):
            raise CohortError(f"{self.path.parent}: another cohort (process {m.group(1)}) is writing into this folder")
        self.path.unlink(missing_ok=True)  # stale: its process is gone

    def release(self):
        self.path.unlink(missing_ok=True)


# ---- geometry and memory before the start ----------------------------------------------------


def probe(hpcm_exe, case):
    """Lattice dims, elements and spacing from `hpcm info` (the same loading as the case);
    raises CohortError with hpcm's message for an input that cannot be read."""
    proc = subprocess.run([hpcm_exe, "info", *case.source_args()], capture_output=True, text=True,
                          env=dict(os.environ, CI="1"))
    if proc.returncode != 0:
        raise CohortError(_error_text(proc.stderr + proc.stdout) or f"hpcm info: exit status {proc.returncode}")
    lat = re.search(r"^lattice\s+(\d+)x(\d+)x(\d+) = (\d+) elements", proc.stdout, re.M)
    sp = re.search(r"^lattice\s+([0-9.eE+-]+) x ([0-9.eE+-]+) x ([0-9.eE+-]+) mm", proc.stdout, re.M)
    if not sp:
        sp = re.search(r"^spacing\s+([0-9.eE+-]+) x ([0-9.eE+-]+) x ([0-9.eE+-]+) mm", proc.stdout, re.M)
    if not lat:
        raise CohortError(f"hpcm info {' '.join(case.source_args())}: no lattice line in its output")
    return {"dims": [int(lat.group(i)) for i in (1, 2, 3)], "elements": int(lat.group(4)),
            "spacing": [float(sp.group(i)) for i in (1, 2, 3)] if sp else [math.nan] * 3}


def available_memory_bytes():
    """MemAvailable, lowered to the cgroup's limit (as hpcm's own estimate does)."""
    avail = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                avail = float(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        mx, cur = (Path("/sys/fs/cgroup/" + n).read_text().strip() for n in ("memory.max", "memory.current"))
        if mx != "max":
            left = float(mx) - float(cur)
            avail = left if avail is None else min(avail, left)
    except OSError:
        pass
    return avail


def plan_workers(cores, threads_per_case, case_bytes, available, workers=None):
    """Workers of the default LocalCluster and each one's memory limit: as many as the cores
    allow at `threads_per_case` each, no more than the memory allows for the largest case."""
    per_worker = case_bytes + WORKER_OVERHEAD_BYTES
    n = workers or max(1, cores // max(1, threads_per_case))
    if not workers and available:
        n = max(1, min(n, int(available // per_worker)))
    return n, int(per_worker)


# ---- results -> rows ---------------------------------------------------------------------------


def _check_status(check):
    status = check.get("status")
    if status in ("held", "failed", "not_applicable"):
        return status
    return "held" if check.get("holds") else "failed"


def _ratio(a, b):
    return a / b if b else math.nan


def experiment_row(case_dir):
    """The figures of one finished `hpcm experiment` folder (summary.json)."""
    js = json.loads((Path(case_dir) / "summary.json").read_text())
    lat = js["lattice"]
    row = {"dims_x": lat["dims"][0], "dims_y": lat["dims"][1], "dims_z": lat["dims"][2],
           "elements": lat["elements"], "body_elements": js.get("body", {}).get("counted_elements", math.nan)}
    limited, where = 0, []
    for cond in CONDITIONS:
        c = js["conditions"][cond]
        for t in TISSUES:
            for fig in FIGURES:
                row[f"{cond}_{t}_{fig}"] = c["tissues"][t][fig]
        for fig in FIGURES:  # the paper's hierarchy: muscle & organ over skin & fat, bone over skin & fat
            row[f"{cond}_muscle_over_skin_{fig}"] = _ratio(c["tissues"]["muscle_organ"][fig], c["tissues"]["skin_fat"][fig])
            row[f"{cond}_bone_over_skin_{fig}"] = _ratio(c["tissues"]["bone"][fig], c["tissues"]["skin_fat"][fig])
        row[f"{cond}_sim_total_ms"] = c["timing_ms"]["sim_total"]
        limited += len(c.get("limited_pulls", []))
        where += [p.get("where", "") for p in c.get("limited_pulls", []) if p.get("where", "") not in where]
    row["skin_peak_C_over_B"] = _ratio(row["C_skin_fat_peak"], row["B_skin_fat_peak"])
    row["tool_limited_pulls"] = limited
    row["tool_limited_where"] = "; ".join(w for w in where if w)
    checks = js.get("checks", {})
    for name, ch in checks.items():
        row[f"check_{name}"] = _check_status(ch)
    statuses = [_check_status(ch) for ch in checks.values()]
    row["checks_held"] = statuses.count("held")
    row["checks_failed"] = statuses.count("failed")
    row["checks_not_applicable"] = statuses.count("not_applicable")
    return row


def run_row(case_dir):
    """Figures of one finished `hpcm run` folder (frames.csv, export.json)."""
    import pandas as pd

    frames = pd.read_csv(Path(case_dir) / "frames.csv")
    row = {"frames": len(frames), "max_link_violation": frames["max_link_violation"].max(),
           "tool_limited_frames": int(frames["tool_limited"].sum()), "sim_total_ms": frames["sim_total_ms"].sum(),
           "elements_moved_max": int(frames["moved_elements"].max())}
    for t in TISSUES:
        row[f"peak_mean_speed_{t}"] = frames[f"mean_speed_{t}"].max()
    export = Path(case_dir) / "export" / "export.json"
    row["exports"] = len(json.loads(export.read_text()).get("exports", [])) if export.is_file() else 0
    return row


# ---- the cohort ----------------------------------------------------------------------------------


def _assign_ids(cases):
    seen = {}
    for c in cases:
        base = c.base_name()
        n = seen.get(base, 0) + 1
        seen[base] = n
        c.id = base if n == 1 else f"{base}-{n}"


def _json_write(path, doc):
    tmp = Path(str(path) + ".tmp")
    tmp.write_text(json.dumps(doc, indent=2, default=str) + "\n")
    os.replace(tmp, path)


def run(inputs, out, job="experiment", *, scenario="", sweep="", params="", downsample=1, settle_frames=None,
        export_args=(), hpcm_exe=None, scheduler=None, workers=None, threads_per_case=1, plots=True,
        progress=True, on_started=None):
    """Runs a cohort and returns cohort.csv as a pandas DataFrame (see the module docstring and
    docs/cohort.md). `on_started(client)` is called once the tasks are submitted (tests use it)."""
    import pandas as pd

    if job not in ("experiment", "run", "sweep"):
        raise CohortError(f"job '{job}': must be experiment, run or sweep")
    if job == "run" and not scenario:
        raise CohortError("job run needs a scenario file (--run SCENARIO.toml)")
    if job == "sweep" and not sweep:
        raise CohortError("job sweep needs a sweep file (--sweep SWEEP.toml)")
    # The ranges of hpcm's own options: refused once here, not once per case.
    for name, value, lo, hi in (("--threads-per-case", threads_per_case, 1, 4096), ("--downsample", downsample, 1, 4096),
                                ("--settle-frames", settle_frames, 1, 10_000_000), ("--workers", workers, 1, 4096)):
        if value is not None and (not re.fullmatch(r"[0-9]+", str(value)) or not lo <= int(value) <= hi):
            raise CohortError(f"{name} {value}: must be an integer in [{lo}, {hi}]")
    hpcm_exe = find_hpcm(hpcm_exe)
    out = Path(out).absolute()
    if out.exists() and not out.is_dir():
        raise CohortError(f"--out {out}: exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    lock = CohortLock(out)
    try:
        return _run_locked(inputs, out, job, scenario, sweep, params, downsample, settle_frames, export_args,
                           hpcm_exe, scheduler, workers, int(threads_per_case), plots, progress, on_started, pd)
    finally:
        lock.release()


def _cases_for(inputs, out, job, sweep, params, downsample, hpcm_exe):
    base_cases = expand_inputs(inputs, downsample)
    if job != "sweep":
        cases = base_cases
        swept = []
    else:
        sets = write_sweep_params(load_sweep(sweep), out / "params", params, hpcm_exe)
        swept = list(dict.fromkeys(k for _, values, _ in sets for k in values))
        cases = [Case(c.input, c.downsample, c.roi, c.series, name, values, path)
                 for c in base_cases for name, values, path in sets]
    _assign_ids(cases)
    return cases, swept


def _probe_all(hpcm_exe, cases, records, records_dir):
    """`hpcm info` once per distinct input (in parallel, as many as there are cores); a case
    whose input cannot be read is recorded as failed here. Returns the cases to run."""
    from concurrent.futures import ThreadPoolExecutor

    def one(args):
        try:
            return probe(hpcm_exe, next(c for c in cases if tuple(c.source_args()) == args))
        except CohortError as e:
            return e

    keys = list(dict.fromkeys(tuple(c.source_args()) for c in cases))
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        found = dict(zip(keys, pool.map(one, keys)))
    todo = []
    for c in cases:
        geometry, rec = found[tuple(c.source_args())], records[c.id]
        if isinstance(geometry, CohortError):
            rec.update(status="failed", error=f"input {c.input}: {geometry}", wall_s=0.0)
            _json_write(records_dir / f"{c.id}.json", rec)
        else:
            rec.update(geometry)
            todo.append(c)
    return todo


def _run_locked(inputs, out, job, scenario, sweep, params, downsample, settle_frames, export_args, hpcm_exe,
                scheduler, workers, threads, plots, progress, on_started, pd):
    from tqdm import tqdm

    cohort_start = time.time()
    if params:
        check = subprocess.run([hpcm_exe, "params", "--check", params], capture_output=True, text=True)
        if check.returncode != 0:
            raise CohortError(f"--params {params}: {check.stderr.strip()}")
    if scenario:
        check = subprocess.run([hpcm_exe, "params", "--check-scenario", scenario], capture_output=True, text=True)
        if check.returncode != 0:
            raise CohortError(f"scenario {scenario}: {check.stderr.strip()}")
    cases, swept = _cases_for(inputs, out, job, sweep, params, downsample, hpcm_exe)
    records_dir, logs_dir, cases_dir = out / "records", out / "logs", out / "cases"
    for d in (records_dir, logs_dir, cases_dir):
        d.mkdir(exist_ok=True)

    records, pending = {}, []
    for c in cases:
        rec_path = records_dir / f"{c.id}.json"
        case_dir = cases_dir / c.id
        argv = case_command(hpcm_exe, job, c, str(case_dir), settle_frames, scenario, params, export_args)
        fingerprint = case_fingerprint(argv, c.params_file or params, scenario)
        old = json.loads(rec_path.read_text()) if rec_path.is_file() else {}
        # Resume: only a finished case of the same command and files; another setting reruns it.
        if is_finished(case_dir, job) and old.get("status") == "done" and old.get("fingerprint") == fingerprint:
            old["resumed"] = True
            records[c.id] = old
            continue
        rec = {"case": c.id, "input": c.input, "downsample": c.downsample, "roi": c.roi, "series": c.series,
               "set": c.set_name, **{f"param:{k}": v for k, v in c.set_values.items()}, "resumed": False,
               "command": argv, "fingerprint": fingerprint}
        records[c.id] = rec
        pending.append(c)
    todo = _probe_all(hpcm_exe, pending, records, records_dir)

    largest = max((records[c.id]["elements"] for c in todo), default=0)
    case_bytes = largest * BYTES_PER_ELEMENT[job]
    resumed, unreadable = len(cases) - len(pending), len(pending) - len(todo)
    print(f"cohort: {len(cases)} cases, {resumed} finished earlier, {unreadable} with an unreadable input, "
          f"{len(todo)} to run", end="", flush=True)
    n_workers = 0
    if todo:  # nothing to run: no cluster to start
        client, cluster = _start_dask(scheduler, workers, threads, case_bytes)
        n_workers = len(client.scheduler_info()["workers"])
        print(f" on {n_workers} Dask workers ({threads} thread(s) per case, largest case {largest} elements, "
              f"about {case_bytes / 1e9:.2f} GB); output {out}", flush=True)
        try:
            _run_tasks(client, todo, records, out, job, scenario, settle_frames, export_args, params, hpcm_exe,
                       threads, progress, on_started, tqdm)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    else:
        print(f"; output {out}", flush=True)

    table = _table(cases, records, out, job, swept, pd)
    table.to_csv(out / "cohort.csv", index=False)
    from . import cohort_report

    cohort_report.write(out, table, job, swept, time.time() - cohort_start, n_workers, plots)
    failed = int((table["status"] != "done").sum())
    print(f"cohort: {len(table) - failed} done, {failed} failed; wrote {out / 'cohort.csv'} and "
          f"{out / 'cohort_report.md'}", flush=True)
    return table


def _start_dask(scheduler, workers, threads, case_bytes):
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler), None
    n, memory_limit = plan_workers(os.cpu_count() or 1, threads, case_bytes, available_memory_bytes(), workers)
    # A task whose worker died is run again once on another worker, then recorded as failed.
    dask.config.set({"distributed.scheduler.allowed-failures": 1})
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, memory_limit=memory_limit,
                           dashboard_address=None)
    return Client(cluster), cluster


def _run_tasks(client, todo, records, out, job, scenario, settle_frames, export_args, params, hpcm_exe, threads,
               progress, on_started, tqdm):
    from distributed import as_completed

    futures = {}
    for c in todo:
        case_dir = out / "cases" / c.id
        task = {"id": c.id, "job": job, "out": str(case_dir), "log": str(out / "logs" / f"{c.id}.log"),
                "threads": threads, "argv": records[c.id]["command"]}
        # retries=1: a task that raised (not a failed case: that returns) is run once more.
        futures[client.submit(run_case, task, key=f"hpcm-case-{c.id}", pure=False, retries=1)] = c
    if on_started:
        on_started(client)
    bar = tqdm(total=len(todo), unit="case", disable=not progress or not todo, file=sys.stderr)
    for fut in as_completed(futures):
        c = futures[fut]
        rec = records[c.id]
        try:
            result = fut.result()
            rec.update(wall_s=result["wall_s"], worker=result["worker"], error=result["error"],
                       status="done" if result["returncode"] == 0 else "failed")
        except Exception as e:  # KilledWorker (its worker died twice), or the task itself failed
            rec.update(status="failed", error=f"{type(e).__name__}: {e}", wall_s=math.nan)
        _json_write(out / "records" / f"{c.id}.json", rec)
        line = f"case {c.id}: {rec['status']} in {rec['wall_s']:.1f} s" + (f" ({rec['error']})" if rec["error"] else "")
        bar.write(line) if progress else print(line, flush=True)
        bar.update(1)
    bar.close()


def _table(cases, records, out, job, swept, pd):
    rows = []
    for c in cases:
        rec = dict(records[c.id])
        row = {k: rec.get(k, "") for k in ("case", "input", "downsample", "roi", "series", "set")}
        for k in swept:
            row[k] = c.set_values.get(k, "")
        dims = rec.get("dims", [math.nan] * 3)
        spacing = rec.get("spacing", [math.nan] * 3)
        row.update(dims_x=dims[0], dims_y=dims[1], dims_z=dims[2], spacing_x=spacing[0], spacing_y=spacing[1],
                   spacing_z=spacing[2], elements=rec.get("elements", math.nan))
        if rec.get("status") == "done":
            try:
                row.update(run_row(out / "cases" / c.id) if job == "run" else experiment_row(out / "cases" / c.id))
            except (OSError, KeyError, ValueError) as e:
                rec.update(status="failed", error=f"results of {c.id} unreadable: {e}")
        row.update(status=rec.get("status", "failed"), error=rec.get("error", ""), wall_s=rec.get("wall_s", math.nan),
                   worker=rec.get("worker", ""), resumed=rec.get("resumed", False))
        rows.append(row)
    return pd.DataFrame(rows)


# ---- command line ---------------------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python3 -m hpcm.cohort", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="Inputs: volume files, DICOM folders, folders of them, CSV manifests "
                                        "(columns input, downsample, roi, series), phantom:NX,NY,NZ[:VARIANT[:SEED]]. "
                                        "See docs/cohort.md.")
    ap.add_argument("inputs", nargs="+", help="cases (see below)")
    ap.add_argument("--out", required=True, help="cohort folder (cases/, records/, logs/, cohort.csv, cohort_report.md)")
    job = ap.add_mutually_exclusive_group()
    job.add_argument("--experiment", action="store_true", help="the paper experiment per case (default)")
    job.add_argument("--run", metavar="SCENARIO", help="hpcm run of a scenario file with exports per case")
    job.add_argument("--sweep", metavar="SWEEP", help="the experiment per case and parameter set of a sweep file")
    ap.add_argument("--params", default="", help="parameter file for every case (a sweep's base)")
    ap.add_argument("--scenario", default="", help="with --experiment/--sweep: a scenario instead of the paper protocol")
    ap.add_argument("--downsample", "-f", type=int, default=1, help="down-sampling factor for inputs without their own")
    ap.add_argument("--settle-frames", type=int, default=None, help="hpcm experiment --settle-frames")
    ap.add_argument("--export-every", type=int, default=None, help="with --run: hpcm run --export-every")
    ap.add_argument("--hpcm", default=None, help="the hpcm executable (default: $HPCM_EXE, PATH, the build folder)")
    ap.add_argument("--scheduler", default=None, help="address of a running Dask scheduler (default: a LocalCluster)")
    ap.add_argument("--workers", type=int, default=None, help="LocalCluster workers (default: cores / threads per case)")
    ap.add_argument("--threads-per-case", type=int, default=1, help="simulation threads of each case (OMP_NUM_THREADS)")
    ap.add_argument("--no-plots", action="store_true", help="cohort_report.md without PNG plots")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar (one line per case still)")
    a = ap.parse_args(argv)
    job_name = "run" if a.run else "sweep" if a.sweep else "experiment"
    export_args = ["--export-every", str(a.export_every)] if a.export_every else []
    try:
        table = run(a.inputs, a.out, job_name, scenario=a.run or a.scenario, sweep=a.sweep or "", params=a.params,
                    downsample=a.downsample, settle_frames=a.settle_frames, export_args=export_args, hpcm_exe=a.hpcm,
                    scheduler=a.scheduler, workers=a.workers, threads_per_case=a.threads_per_case,
                    plots=not a.no_plots, progress=not a.no_progress)
    except CohortError as e:
        print(f"hpcm.cohort: error: {e}", file=sys.stderr)
        return 2
    return 0 if (table["status"] == "done").all() else 1


if __name__ == "__main__":
    # Through the package module (not __main__), so Dask workers import run_case by its name.
    from hpcm.cohort import main as _main

    sys.exit(_main())
