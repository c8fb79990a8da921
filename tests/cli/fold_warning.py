#!/usr/bin/python3
"""`hpcm run` and `hpcm experiment` on a grab that folded cells before the frame-end link
restoration (issue 31, item 4): now every frame is fold-free, there is no warning and --strict
passes. With HPCM_SKIP_FRAME_END_RESTORE=1 (the pipeline as it was) the same commands fold:
they must warn on stderr naming the frames, the count and the smallest determinant, as
frames.csv has them, and --strict must fail naming the frames, after writing every file.

Usage: fold_warning.py HPCM OUT_DIR
"""
import csv
import json
import os
import re
import shutil
import subprocess
import sys

HPCM, OUT = sys.argv[1], sys.argv[2]
PHANTOM = "24,24,16"
# A corner grab (three axes at once), fast keyframes: 4 frames out, 4 back, 4 up.
SCENARIO = """[scenario]
name = "corner_grab"
frames = 38

[[grab]]
centre = "auto"
release = 18
keyframes = [[4, 4.0, -4.0, 4.0], [8, 0.0, 0.0, 0.0], [12, 0.0, 0.0, 8.0]]
"""
WARNING = re.compile(r"hpcm: warning: (?:condition ([ABC]): )?(\d+) frames? folds? \(frames? ([0-9, .-]+)\): "
                     r"(?:up to )?(\d+) cells? with a corner determinant <= 0, smallest determinant (\S+) \(frame (\d+)\)")
failures = 0


def check(ok, what):
    global failures
    print(("ok: " if ok else "FAIL: ") + what)
    if not ok:
        failures += 1


def hpcm(args, old=False):
    env = dict(os.environ)
    env.pop("HPCM_SKIP_FRAME_END_RESTORE", None)
    if old:
        env["HPCM_SKIP_FRAME_END_RESTORE"] = "1"
    return subprocess.run([HPCM] + args, capture_output=True, text=True, env=env)


def frames_list(text):
    out = []
    for part in text.split(", "):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def folded_rows(path):
    return [r for r in csv.DictReader(open(path)) if int(r["folded_cells"]) > 0]


def check_warning_against_csv(m, rows, what):
    check(m is not None, f"{what}: the warning names frames, count and smallest determinant")
    if m is None:
        return
    count, listed, cells, det, det_frame = int(m[2]), frames_list(m[3]), int(m[4]), float(m[5]), int(m[6])
    check(count == len(rows) and listed == [int(r["frame"]) for r in rows],
          f"{what}: frames {listed} ({count}) are frames.csv's folded frames {[int(r['frame']) for r in rows]}")
    check(cells == max(int(r["folded_cells"]) for r in rows), f"{what}: up to {cells} folded cells")
    worst = min(rows, key=lambda r: float(r["min_cell_jacobian"]))
    check(abs(det - float(worst["min_cell_jacobian"])) <= 1e-5 * max(1.0, abs(det)) and det <= 0 and
          det_frame == int(worst["frame"]), f"{what}: smallest determinant {det} in frame {det_frame}")


shutil.rmtree(OUT, ignore_errors=True)
os.makedirs(OUT)
scenario = os.path.join(OUT, "corner.toml")
with open(scenario, "w") as f:
    f.write(SCENARIO)

# hpcm run, now: fold-free, silent, --strict passes.
run = ["run", "--phantom", PHANTOM, "--scenario", scenario]
r = hpcm(run + ["--out", f"{OUT}/run"])
check(r.returncode == 0, f"run exits 0 ({r.stderr.strip()[-300:]})")
rows = list(csv.DictReader(open(f"{OUT}/run/frames.csv")))
check(len(rows) == 38 and all(int(x["folded_cells"]) == 0 and float(x["min_cell_jacobian"]) > 0 for x in rows),
      "run: every frame fold-free (folded_cells 0, min_cell_jacobian > 0): smallest %s" %
      min(float(x["min_cell_jacobian"]) for x in rows))
check("hpcm: warning" not in r.stderr, "run: no fold warning")
r = hpcm(run + ["--strict", "--out", f"{OUT}/run_strict"])
check(r.returncode == 0, f"run --strict exits 0 on a fold-free run ({r.stderr.strip()[-300:]})")

# hpcm run without the frame-end restoration: it folds, warns, and --strict fails.
r = hpcm(run + ["--out", f"{OUT}/run_old"], old=True)
rows = folded_rows(f"{OUT}/run_old/frames.csv")
check(r.returncode == 0 and len(rows) > 0, f"run (old pipeline) folds in {len(rows)} frames and exits 0")
check_warning_against_csv(WARNING.search(r.stderr), rows, "run warning")
r = hpcm(run + ["--strict", "--out", f"{OUT}/run_old_strict"], old=True)
m = WARNING.search(r.stderr)
check(r.returncode != 0 and "--strict" in r.stderr and "frames fold" in r.stderr and m is not None and
      f"(frames {m[3]})" in r.stderr.split("--strict", 1)[1],
      f"run --strict (old pipeline) fails naming the frames (exit {r.returncode})")
check(os.path.isfile(f"{OUT}/run_old_strict/frames.csv"), "run --strict still writes frames.csv")

# hpcm experiment, now: no warning, --strict passes, every fold-free check holds.
exp = ["experiment", "--phantom", PHANTOM, "--scenario", scenario, "--settle-frames", "5", "--no-report"]
r = hpcm(exp + ["--strict", "--out", f"{OUT}/exp"])
check(r.returncode == 0 and "hpcm: warning" not in r.stderr,
      f"experiment --strict exits 0 without a fold warning ({r.stderr[-300:]})")
summary = json.load(open(f"{OUT}/exp/summary.json"))
check(all(summary["checks"][f"{c}_fold_free"]["status"] == "held" for c in "ABC"), "experiment: A/B/C_fold_free held")

# hpcm experiment without the frame-end restoration: a warning per folding condition, --strict fails.
r = hpcm(exp + ["--out", f"{OUT}/exp_old"], old=True)
warnings = list(WARNING.finditer(r.stderr))
summary = json.load(open(f"{OUT}/exp_old/summary.json"))
folding = [c for c in "ABC" if summary["checks"][f"{c}_fold_free"]["status"] == "failed"]
check(r.returncode == 0 and len(folding) > 0 and [w[1] for w in warnings] == folding,
      f"experiment (old pipeline) warns for exactly the conditions that fold: {folding}")
for w in warnings:
    check(abs(float(w[5]) - summary["checks"][f"{w[1]}_fold_free"]["value"]) <= 1e-5,
          f"experiment warning, condition {w[1]}: smallest determinant {w[5]} as summary.json")
r = hpcm(exp + ["--strict", "--out", f"{OUT}/exp_old_strict"], old=True)
tail = r.stderr.split("--strict", 1)[1] if "--strict" in r.stderr else ""
check(r.returncode != 0 and all(f"condition {c}: " in tail for c in folding) and "(frame" in tail,
      f"experiment --strict (old pipeline) fails naming the conditions and frames (exit {r.returncode})")
check(os.path.isfile(f"{OUT}/exp_old_strict/summary.json"), "experiment --strict still writes summary.json")

print("all fold-warning checks passed" if failures == 0 else f"FAIL: {failures} fold-warning checks failed")
sys.exit(1 if failures else 0)
