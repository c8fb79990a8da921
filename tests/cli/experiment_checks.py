#!/usr/bin/python3
"""`hpcm experiment` check statuses (SPEC §8 as amended) as summary.json, the console and
report.md give them.

Usage: experiment_checks.py HPCM SCRATCH

On a 24x24x16 phantom (below 64 along its two longest axes) the motion checks (8.1-8.4, 8.8) are
not applicable with the lattice as the reason; on a 64x64x8 slab they are required (held or
failed). Every check has a status among held / failed / not_applicable, "holds" is true exactly
when held, the §8.8 checks are present with their figures, and each condition gives its far-field
shares. Prints "all experiment check statuses passed" at the end; "FAIL: ..." on the first failure.
"""

import json
import os
import re
import shutil
import subprocess
import sys

STATUSES = ("held", "failed", "not_applicable")
MOTION_CLAUSES = ("8.1", "8.2", "8.3", "8.4", "8.8")
CHECKS_88 = ("C_skin_muscle_peak_ratio", "C_skin_muscle_auc_ratio", "C_far_field_share_skin_fat",
             "C_far_field_share_muscle_organ", "C_far_field_share_bone", "A_skin_auc_below_C")
TISSUES = ("air", "skin_fat", "muscle_organ", "bone")


def fail(msg):
    print(f"FAIL: {msg}")
    sys.exit(1)


def ok(msg):
    print(f"ok: {msg}")


def motion(name, chk):
    return name != "C_bone_velocity_zero" and chk["spec"] in MOTION_CLAUSES


def run_experiment(hpcm, scratch, phantom):
    out = os.path.join(scratch, "exp_" + phantom.replace(",", "x"))
    p = subprocess.run([hpcm, "experiment", "--phantom", phantom, "--settle-frames", "5", "--out", out],
                       capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        fail(f"hpcm experiment --phantom {phantom}: exit {p.returncode}: {p.stderr.strip()[-400:]}")
    with open(os.path.join(out, "summary.json"), encoding="utf-8") as f:
        summary = json.load(f)
    with open(os.path.join(out, "report.md"), encoding="utf-8") as f:
        report = f.read()
    return summary, p.stdout, report


def check_common(label, summary, stdout, report):
    checks = summary["checks"]
    if len(checks) != 33:
        fail(f"{label}: {len(checks)} checks reported, expected 33: {sorted(checks)}")
    for name in CHECKS_88:
        if name not in checks:
            fail(f"{label}: SPEC 8.8 check {name} missing")
        chk = checks[name]
        if chk["spec"] != "8.8" or chk["threshold"] is None:
            fail(f"{label}: {name}: spec {chk['spec']!r}, threshold {chk['threshold']!r}")
        if name.startswith("C_far_field_share_") and not isinstance(chk["value"], (int, float)):
            fail(f"{label}: {name} has no figure: {chk['value']!r}")
    counts = {s: 0 for s in STATUSES}
    for name, chk in checks.items():
        status = chk.get("status")
        if status not in STATUSES:
            fail(f"{label}: {name}: status {status!r} is not one of {STATUSES}")
        counts[status] += 1
        if chk["holds"] is not (status == "held"):
            fail(f"{label}: {name}: holds {chk['holds']} with status {status}")
        if not (chk["value"] is None or isinstance(chk["value"], (int, float))):
            fail(f"{label}: {name}: value {chk['value']!r} is not a number or null")
        if status == "not_applicable" and not chk.get("reason"):
            fail(f"{label}: {name}: not applicable without a reason")
        # report.md lists each check with its status.
        row = next((l for l in report.splitlines() if l.startswith(f"| `{name}` |")), None)
        want = {"held": "✓ held", "failed": "✗ failed", "not_applicable": "not applicable ("}[status]
        if row is None or want not in row:
            fail(f"{label}: report.md row for {name} does not say {want!r}: {row!r}")
    if summary["check_counts"] != counts:
        fail(f"{label}: check_counts {summary['check_counts']} but the checks give {counts}")
    if summary["all_hold"] != (counts["failed"] == 0):
        fail(f"{label}: all_hold {summary['all_hold']} with {counts['failed']} failed")
    line = f"checks: {counts['held']} held, {counts['failed']} failed, {counts['not_applicable']} not applicable (of 33)"
    if line not in stdout:
        fail(f"{label}: console does not say {line!r}: {stdout.strip()[:300]}")
    for c in ("A", "B", "C"):
        shares = summary["conditions"][c]["far_field_share"]
        if set(shares) != set(TISSUES):
            fail(f"{label}: condition {c} far_field_share keys {sorted(shares)}")
        for t, v in shares.items():
            if v is not None and not 0.0 <= v <= 1.0:
                fail(f"{label}: condition {c} far_field_share.{t} = {v} outside [0, 1]")
    c_share = summary["conditions"]["C"]["far_field_share"]["skin_fat"]
    if c_share is None or abs(c_share - checks["C_far_field_share_skin_fat"]["value"]) > 1e-9:
        fail(f"{label}: C far_field_share.skin_fat {c_share} differs from its check's figure")
    if summary["scenario"]["far_field_distance"] != 40:
        fail(f"{label}: far_field_distance {summary['scenario']['far_field_distance']}")
    check_centre_velocity(label, summary)
    for needle in ("SPEC §8.8, local response", "| `C_skin_muscle_auc_ratio` | 18.7 |"):
        if needle not in report:
            fail(f"{label}: report.md lacks {needle!r}")
    ok(f"{label}: 33 checks, {counts}; console, report.md and far-field shares agree")
    return counts


def check_centre_velocity(label, summary):
    """The grab centre's velocity state per frame, beside its displacement: 0 while the grab holds
    it (FIXED) and in every frame under A (no dynamics); under B and C the layer moves it after
    release."""
    release = summary["scenario"]["release_frame"]
    for c in ("A", "B", "C"):
        cond = summary["conditions"][c]
        v, u = cond.get("grab_centre_velocity"), cond["grab_centre_displacement"]
        if v is None or len(v) != len(u):
            fail(f"{label}: condition {c} grab_centre_velocity has {None if v is None else len(v)} frames, "
                 f"the displacement {len(u)}")
        if any(x != 0 for f in v[:release] for x in f):
            fail(f"{label}: condition {c}: the grab centre has a velocity while held")
        moving = any(x != 0 for f in v[release:] for x in f)
        if moving != (c != "A"):
            fail(f"{label}: condition {c}: grab centre velocity after release {'non-zero' if moving else 'zero'}")


def check_params_recorded(hpcm, summary):
    """summary.json's "params" holds every key of `hpcm params --defaults` (the parameter table),
    in its section, with the default's value (the run used the defaults)."""
    import tomllib
    defaults = tomllib.loads(subprocess.run([hpcm, "params", "--defaults"], capture_output=True, text=True,
                                            check=True).stdout)
    recorded = summary["params"]
    for section, keys in defaults.items():
        for key, value in keys.items():
            if key not in recorded.get(section, {}):
                fail(f"summary.json params: {section}.{key} is missing")
            got = recorded[section][key]
            if isinstance(value, dict):  # per tissue class
                value, got = list(value.values()), [got[c] for c in value]
            if isinstance(value, list):  # per class, or the material's points as rows
                flat = lambda v: [x for e in v for x in (e.values() if isinstance(e, dict) else [e])]
                if len(flat(got)) != len(flat(value)) or any(abs(g - w) > 1e-6 * max(1.0, abs(w))
                                                             for g, w in zip(flat(got), flat(value))):
                    fail(f"summary.json params: {section}.{key} = {got}, the default is {value}")
                continue
            if isinstance(value, float) and abs(got - value) > 1e-6 * max(1.0, abs(value)):
                fail(f"summary.json params: {section}.{key} = {got}, the default is {value}")
            if isinstance(value, (bool, str, int)) and not isinstance(value, float) and got != value:
                fail(f"summary.json params: {section}.{key} = {got!r}, the default is {value!r}")
    ok(f"summary.json records every parameter ({sum(len(k) for k in defaults.values())} keys)")


def main():
    if len(sys.argv) != 3:
        fail("usage: experiment_checks.py HPCM SCRATCH")
    hpcm, scratch = sys.argv[1], sys.argv[2]
    shutil.rmtree(scratch, ignore_errors=True)
    os.makedirs(scratch)

    summary, stdout, report = run_experiment(hpcm, scratch, "24,24,16")
    check_common("24x24x16", summary, stdout, report)
    reason = "lattice 24×24×16 below 64 along its two longest axes"
    for name, chk in summary["checks"].items():
        if motion(name, chk):
            if chk["status"] != "not_applicable" or chk["reason"] != reason:
                fail(f"24x24x16: {name} ({chk['spec']}) is {chk['status']} ({chk.get('reason')!r}), "
                     f"expected not applicable ({reason})")
        elif chk["status"] == "not_applicable":
            fail(f"24x24x16: {name} ({chk['spec']}) is required on every lattice, got not applicable")
    if f"not applicable ({reason})" not in report:
        fail("24x24x16: report.md does not give the reason")
    ok("24x24x16: the motion checks are not applicable, with the lattice as the reason")
    check_params_recorded(hpcm, summary)

    summary, stdout, report = run_experiment(hpcm, scratch, "64,64,8")
    check_common("64x64x8", summary, stdout, report)
    for name in (n for n in CHECKS_88 if n != "C_far_field_share_bone"):  # bone may be still
        if summary["checks"][name]["status"] == "not_applicable":
            fail(f"64x64x8: {name} must be required: {summary['checks'][name].get('reason')!r}")
    if re.search(r"below 64", json.dumps(summary["checks"], ensure_ascii=False)):
        fail("64x64x8: a check names the lattice rule on a lattice that meets it")
    ok("64x64x8: the SPEC 8.8 checks are required (held or failed)")
    print("all experiment check statuses passed")


if __name__ == "__main__":
    main()
