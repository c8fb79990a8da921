#!/usr/bin/python3
"""Self-test of scripts/hpcm_report.py (CTest `report_script`).

Writes synthetic `hpcm experiment` outputs (damped oscillations of plausible size) into a
temporary folder, runs the report, and checks that figure3.png / figure4.png are valid,
non-blank PNGs of sensible size and that report.md holds the tables, the checks and the
paper's figures. Then breaks the inputs one way at a time and checks that the report exits
non-zero with a one-line message naming the file (no traceback).
"""

import csv
import json
import math
import os
import shutil
import struct
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPORT = os.path.join(HERE, "hpcm_report.py")
TISSUES = ["air", "skin_fat", "muscle_organ", "bone"]
N = 120

failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print(f"FAIL: {what}")


def synthetic_curves():
    """mean speed per condition/tissue/frame: A stops, B oscillates, C oscillates and damps."""
    out = {}
    for c in "ABC":
        out[c] = {}
        for t in TISSUES:
            scale = {"air": 0.5, "skin_fat": 1.0, "muscle_organ": 0.04, "bone": 0.0015}[t]
            series = []
            for k in range(N):
                if c == "A":
                    v = 0.012 * math.exp(-k / 1.5)
                elif c == "B":
                    v = 0.028 * abs(math.cos(k / 4.0 + 0.3)) * math.exp(-k / 70.0)
                else:
                    v = 0.023 * abs(math.cos(k / 4.0 + 0.3)) * math.exp(-k / 22.0)
                v *= scale
                if t == "bone" and k == 0:
                    v = 0.0
                series.append((v, 3.0 * v))
            out[c][t] = series
    return out


def write_inputs(d, curves):
    with open(os.path.join(d, "curves.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["condition", "frame_after_release", "tissue", "mean_speed", "max_speed"])
        for c in "ABC":
            for k in range(N):
                for t in TISSUES:
                    m, mx = curves[c][t][k]
                    w.writerow([c, k, t, f"{m:.9g}", f"{mx:.9g}"])
    table2 = {}
    with open(os.path.join(d, "table2.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["condition", "tissue", "initial", "peak", "auc"])
        for c in "ABC":
            for t in TISSUES:
                m = [float(f"{v:.9g}") for v, _ in curves[c][t]]
                table2[(c, t)] = (m[0], max(m), math.fsum(m))
                w.writerow([c, t] + [f"{x:.9g}" for x in table2[(c, t)]])
    times = {"A": (2.1, 0.0, 0.3, 2.4), "B": (2.2, 0.5, 0.3, 3.0), "C": (2.2, 0.55, 0.3, 3.05)}
    with open(os.path.join(d, "table3.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["condition", "chainmail_ms", "inertia_ms", "snapshot_ms", "sim_total_ms"])
        for c in "ABC":
            w.writerow([c] + list(times[c]))
    summary = {
        "lattice": {"dims": [96, 96, 64], "elements": 96 * 96 * 64, "source": "phantom 96,96,64"},
        "backend": "cpu",
        "body": {"search": "found", "why": "body: 400000 elements (selftest); left out of the statistics: 189824 outside "
                                           "air (HU < -500, free) and 0 outside objects (HU >= -500, anchored)"},
        "machine": "selftest machine (2 threads)",
        "scenario": {"name": "paper_protocol", "frames": 150, "release_frame": 30},
        "params": {"dynamics": {"alpha": 0.85, "b0": 0.15}},
        "conditions": {
            c: {
                "tissues": {t: dict(zip(("initial", "peak", "auc"), table2[(c, t)])) for t in TISSUES},
                "timing_ms": dict(zip(("chainmail", "inertia", "snapshot", "sim_total"), times[c])),
            }
            for c in "ABC"
        },
        "checks": {
            "A_no_overshoot": {"holds": True, "value": 0.0, "threshold": 0.0, "spec": "8.1",
                               "description": "largest increase of the grab centre's distance from rest after release"},
            "B_overshoot": {"status": "not_applicable", "holds": False, "value": 2e-4, "threshold": 1e-3, "spec": "8.2",
                            "reason": "achieved pull 0.02 lattice units, below 0.5",
                            "description": "largest distance of the grab centre beyond rest"},
            "C_skin_muscle_peak_ratio": {"status": "held", "holds": True, "value": None, "threshold": 10, "spec": "8.8",
                                         "description": "skin_fat Peak / muscle_organ Peak under C"},
            "C_far_field_share_skin_fat": {"status": "held", "holds": True, "value": 0.031, "threshold": 0.1,
                                           "spec": "8.8", "description": "far share"},
            "C_settles_5pct": {"holds": True, "value": 0.012, "threshold": 0.05, "spec": "8.3",
                               "description": "skin&fat mean speed at the end / peak under C"},
            "settle_2000": {"holds": False, "value": 3.2e-6, "threshold": 1e-6, "spec": "8.5",
                            "description": "largest element speed after 2,000 idle frames"},
        },
        "all_hold": False,
    }
    with open(os.path.join(d, "summary.json"), "w") as f:
        json.dump(summary, f, indent=2)


def run(d, *extra):
    p = subprocess.run([sys.executable, REPORT, d, *extra], capture_output=True, text=True, timeout=120)
    return p.returncode, p.stdout, p.stderr


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    if head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        return None
    return struct.unpack(">II", head[16:24])


def test_good(root):
    d = os.path.join(root, "good")
    os.makedirs(d)
    write_inputs(d, synthetic_curves())
    rc, out, err = run(d)
    check(rc == 0, f"report on valid inputs exits 0 (rc={rc}, stderr={err.strip()!r})")
    check("warning" not in err, f"no consistency warning on consistent inputs ({err.strip()!r})")
    for name in ("figure3.png", "figure4.png"):
        p = os.path.join(d, name)
        check(os.path.isfile(p), f"{name} written")
        if not os.path.isfile(p):
            continue
        size = png_size(p)
        check(size is not None, f"{name} is a PNG")
        if size:
            check(600 <= size[0] <= 4000 and 400 <= size[1] <= 4000, f"{name} has a sensible size ({size})")
        check(10_000 < os.path.getsize(p) < 5_000_000, f"{name} file size {os.path.getsize(p)} bytes is sensible")
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.image as mpimg
        img = mpimg.imread(p)
        flat = img[..., :3].reshape(-1, 3)
        # Not blank: a white page has a single colour; curves, axes and text add many.
        distinct = len({tuple(px) for px in flat[:: max(1, len(flat) // 20000)].tolist()})
        check(distinct > 20, f"{name} is not blank ({distinct} distinct colours)")
    md_path = os.path.join(d, "report.md")
    check(os.path.isfile(md_path), "report.md written")
    if os.path.isfile(md_path):
        md = open(md_path, encoding="utf-8").read()
        for needle in ["# hpcm experiment report", "96 x 96 x 64", "phantom 96,96,64", "Backend: cpu",
                       "selftest machine", "## Table 2", "## Table 3", "![Figure 3", "(figure3.png)", "(figure4.png)",
                       "## Behaviour checks", "`A_no_overshoot`", "`settle_2000`", "✓ held", "✗ failed", "some failed",
                       "not applicable (achieved pull 0.02 lattice units, below 0.5)",
                       "4 held, 1 failed, 1 not applicable, of 6", "| `C_skin_muscle_peak_ratio` | 26.3 | n/a | >= 10 |",
                       "| `C_skin_muscle_auc_ratio` | 18.7 | not reported |", "| `C_far_field_share_skin_fat` | not given | 0.031 |",
                       "0.692066", "0.000856", "0.001233", "1,228,800", "RTX 4070", "2.64", "3.23", "3.15",
                       "compare the shapes", "| C | skin & fat |",
                       "Counted elements: body: 400000 elements (selftest); left out of the statistics: 189824"]:
            check(needle in md, f"report.md contains {needle!r}")
        # Table 2's skin&fat peak under C appears with six decimals.
        check("0.0" in md and "| C | bone | 0 |" in md, "bone Initial under C is printed as 0")

    # --out to another folder; the input folder stays as it is.
    d2 = os.path.join(root, "elsewhere")
    rc, _, err = run(d, "--out", d2)
    check(rc == 0 and os.path.isfile(os.path.join(d2, "report.md")), f"--out writes elsewhere (rc={rc}, {err.strip()!r})")

    # Inconsistent Table 2: reported as a warning, still a report.
    d3 = os.path.join(root, "inconsistent")
    shutil.copytree(d, d3)
    t2 = open(os.path.join(d3, "table2.csv")).read().splitlines()
    parts = t2[1].split(",")
    parts[3] = "0.5"
    t2[1] = ",".join(parts)
    open(os.path.join(d3, "table2.csv"), "w").write("\n".join(t2) + "\n")
    rc, _, err = run(d3)
    check(rc == 0 and "warning" in err and "table2.csv A/air peak" in err, f"inconsistent Table 2 warns ({err.strip()!r})")
    return d


def test_malformed(root, good):
    def variant(name, mutate):
        d = os.path.join(root, "bad_" + name)
        shutil.copytree(good, d)
        for f in ("figure3.png", "figure4.png", "report.md"):
            if os.path.exists(os.path.join(d, f)):
                os.remove(os.path.join(d, f))
        mutate(d)
        return d

    def rewrite(fname, fn):
        def m(d):
            p = os.path.join(d, fname)
            with open(p) as f:
                text = f.read()
            with open(p, "w") as f:
                f.write(fn(text))
        return m

    def replace_row(fname, prefix, new):
        return rewrite(fname, lambda t: "\n".join(new if l.startswith(prefix) else l for l in t.splitlines()) + "\n")

    def drop(fname):
        return lambda d: os.remove(os.path.join(d, fname))

    def summary_edit(fn):
        def m(d):
            p = os.path.join(d, "summary.json")
            s = json.load(open(p))
            fn(s)
            json.dump(s, open(p, "w"))
        return m

    cases = [
        ("missing_curves", drop("curves.csv"), "curves.csv: missing"),
        ("missing_table2", drop("table2.csv"), "table2.csv: missing"),
        ("missing_table3", drop("table3.csv"), "table3.csv: missing"),
        ("missing_summary", drop("summary.json"), "summary.json: missing"),
        ("curves_header", rewrite("curves.csv", lambda t: t.replace("mean_speed", "speed", 1)), "curves.csv: header"),
        ("curves_text", replace_row("curves.csv", "B,5,skin_fat,", "B,5,skin_fat,fast,0.1"), "'fast' is not a number"),
        ("curves_nan", replace_row("curves.csv", "C,7,bone,", "C,7,bone,nan,0"), "'nan' is not a finite number"),
        ("curves_gap", rewrite("curves.csv", lambda t: "\n".join(l for l in t.splitlines() if not l.startswith("C,50,muscle_organ,")) + "\n"),
         "missing [50]"),
        ("curves_condition", rewrite("curves.csv", lambda t: t.replace("\nA,0,air,", "\nD,0,air,", 1)),
         "condition 'D' is not one of A, B, C"),
        ("curves_fields", rewrite("curves.csv", lambda t: t.replace("\nA,1,air,", "\nA,1,air,1,", 1)), "fields, expected 5"),
        ("curves_empty", rewrite("curves.csv", lambda t: ""), "curves.csv: empty file"),
        ("table2_row", rewrite("table2.csv", lambda t: "\n".join(l for l in t.splitlines() if not l.startswith("B,bone")) + "\n"),
         "table2.csv: no row for condition B, tissue bone"),
        ("table3_negative", rewrite("table3.csv", lambda t: t.replace("\nC,2.2,", "\nC,-2.2,", 1)), "must be >= 0"),
        ("summary_json", rewrite("summary.json", lambda t: t[: len(t) // 2]), "summary.json: invalid JSON"),
        ("summary_checks", summary_edit(lambda s: s.pop("checks")), "missing key 'checks'"),
        ("summary_holds", summary_edit(lambda s: s["checks"]["A_no_overshoot"].update(holds="yes")),
         "checks.A_no_overshoot.holds: expected bool"),
        ("summary_status", summary_edit(lambda s: s["checks"]["A_no_overshoot"].update(status="maybe")),
         "checks.A_no_overshoot.status: 'maybe' is not one of held, failed, not_applicable"),
        ("summary_status_holds", summary_edit(lambda s: s["checks"]["A_no_overshoot"].update(status="failed")),
         "checks.A_no_overshoot: holds true contradicts status 'failed'"),
        ("summary_reason", summary_edit(lambda s: s["checks"]["B_overshoot"].pop("reason")),
         "checks.B_overshoot: missing key 'reason'"),
        ("summary_dims", summary_edit(lambda s: s["lattice"].update(dims=[96, 96])), "lattice.dims must be 3 positive integers"),
    ]
    for name, mutate, want in cases:
        d = variant(name, mutate)
        rc, out, err = run(d)
        check(rc != 0, f"{name}: exits non-zero (rc={rc})")
        check("hpcm_report: error:" in err and want in err, f"{name}: message contains {want!r} (stderr={err.strip()!r})")
        check("Traceback" not in err, f"{name}: no traceback")
        check(len(err.strip().splitlines()) == 1, f"{name}: one-line message")
        check(not os.path.exists(os.path.join(d, "report.md")), f"{name}: no report written")
    rc, _, err = run(os.path.join(root, "does_not_exist"))
    check(rc != 0 and "not a folder" in err, f"missing DIR is an error ({err.strip()!r})")


def main():
    root = tempfile.mkdtemp(prefix="hpcm_report_selftest_")
    try:
        good = test_good(root)
        test_malformed(root, good)
    finally:
        if failures:
            print(f"kept {root} for inspection")
        else:
            shutil.rmtree(root, ignore_errors=True)
    if failures:
        print(f"{len(failures)} check(s) failed")
        return 1
    print("hpcm_report selftest: all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
