#!/usr/bin/env python3
"""Scenarios in millimetres from the command line (issue 32, item 2): `hpcm params
--check-scenario` accepts offset_mm / radius_mm and says that millimetres meet the lattice only
when played; both forms at once is an error naming the line; a millimetre pull on the thick-slice
phantom moves the same distance at --downsample 1 and 2; frames.csv gives the achieved and
requested pull in millimetres in two new columns at the end (the old columns keep their place).

usage: scenario_mm.py HPCM SCRATCH
"""
import csv
import math
import os
import shutil
import subprocess
import sys

PULL_MM = (0.0, -30.0, 0.0)
SCENARIO_MM = f"""[scenario]
name = "pull_mm"
frames = 16

[[grab]]
centre = "auto"
radius_mm = 20.0
release = 12
keyframes = [{{ frame = 10, offset_mm = [{PULL_MM[0]}, {PULL_MM[1]}, {PULL_MM[2]}] }}]
"""
# Columns that scripts read by position (tests/cli/cli_checks.sh, scripts/stability_sweep.sh).
FIXED_COLUMNS = {1: "frame", 3: "grab_offset", 6: "max_link_violation", 10: "mean_speed_skin_fat", 22: "tool_limited"}

failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL: ") + what)
    if not ok:
        failures.append(what)


def hpcm(*args):
    return subprocess.run([HPCM, *args], cwd=SCRATCH, capture_output=True, text=True, timeout=600)


def write(name, text):
    with open(os.path.join(SCRATCH, name), "w", encoding="utf-8") as f:
        f.write(text)
    return name


def frames_csv(out):
    with open(os.path.join(SCRATCH, out, "frames.csv"), newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def main():
    shutil.rmtree(SCRATCH, ignore_errors=True)
    os.makedirs(SCRATCH)

    write("mm.toml", SCENARIO_MM)
    p = hpcm("params", "--check-scenario", "mm.toml")
    check(p.returncode == 0 and "millimetres are checked against the lattice spacing when the scenario is played" in p.stdout,
          f"--check-scenario accepts millimetres and says when they are checked: {p.stdout.strip()} {p.stderr.strip()}")
    p = hpcm("params", "--check-scenario", "mm.toml", "--print")
    check(p.returncode == 0 and "radius_mm = 20.0" in p.stdout and "offset_mm = [0.0, -30.0, 0.0]" in p.stdout,
          f"--print keeps the millimetre forms: {p.stdout.strip()[-300:]}")

    write("both.toml", SCENARIO_MM.replace("radius_mm = 20.0", "radius = 2\nradius_mm = 20.0"))
    p = hpcm("params", "--check-scenario", "both.toml")
    check(p.returncode == 2 and "grab[0] gives both radius and radius_mm" in p.stderr and "(line 8)" in p.stderr,
          f"radius and radius_mm together: exit 2 naming both and the line: {p.stderr.strip()}")
    write("neither.toml", SCENARIO_MM.replace(", offset_mm = [0.0, -30.0, 0.0]", ""))
    p = hpcm("params", "--check-scenario", "neither.toml")
    check(p.returncode == 2 and "grab[0].keyframes[0] needs offset = [dx, dy, dz] (lattice units) or offset_mm" in p.stderr,
          f"a keyframe table without offset or offset_mm: {p.stderr.strip()}")
    write("neg.toml", SCENARIO_MM.replace("radius_mm = 20.0", "radius_mm = -3"))
    p = hpcm("params", "--check-scenario", "neg.toml")
    check(p.returncode == 2 and "grab[0].radius_mm = -3 is out of range: > 0 mm" in p.stderr,
          f"negative radius_mm: {p.stderr.strip()}")

    # The same scenario at two down-samplings of the thick-slice phantom.
    achieved, spacing_y = {}, {}
    for f in (1, 2):
        out = f"run_f{f}"
        p = hpcm("run", "--phantom", "64,64,24", "--phantom-variant", "anisotropic", "--downsample", str(f),
                 "--scenario", "mm.toml", "--no-link-check", "--out", out)
        check(p.returncode == 0, f"run at --downsample {f}: {p.stderr.strip()[-400:]}")
        if p.returncode != 0:
            continue
        header, rows = frames_csv(out)
        check(header[-2:] == ["grab_offset_mm", "requested_offset_mm"],
              f"frames.csv ends with grab_offset_mm,requested_offset_mm: {header[-4:]}")
        check(all(header[i - 1] == name for i, name in FIXED_COLUMNS.items()),
              f"the older columns keep their place: {[(i, header[i - 1]) for i in FIXED_COLUMNS]}")
        col = {name: i for i, name in enumerate(header)}
        check(all(len(r) == len(header) for r in rows), "every row has every column")
        last = [r for r in rows if r[col["stage"]] == "deform"][-1]
        got, asked = float(last[col["grab_offset_mm"]]), float(last[col["requested_offset_mm"]])
        check(abs(asked - math.hypot(*PULL_MM)) < 1e-3 and abs(got - asked) < 1e-3 and last[col["tool_limited"]] == "0",
              f"f = {f}: requested {asked} mm, achieved {got} mm (lattice units {last[col['grab_offset']]})")
        # A pull along y only: mm / lattice units is the lattice spacing along y, f x the input's.
        spacing_y[f] = got / float(last[col["grab_offset"]])
        achieved[f] = got
    if len(achieved) == 2:
        check(abs(spacing_y[2] - 2 * spacing_y[1]) < 1e-3 * spacing_y[2],
              f"the lattice spacing along y doubles at f = 2: {spacing_y}")
        check(abs(achieved[1] - achieved[2]) < spacing_y[2], f"the same physical pull at f = 1 and 2 (mm): {achieved}")

    print(f"{len(failures)} failed" if failures else "all millimetre scenario checks passed")
    return 1 if failures else 0


if __name__ == "__main__":
    HPCM, SCRATCH = sys.argv[1], os.path.abspath(sys.argv[2])
    sys.exit(main())
