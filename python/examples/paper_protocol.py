#!/usr/bin/python3
"""The paper's experiment from Python: conditions A (plain HP-ChainMail), B (simple damping)
and C (viscoelastic damping) on identical input -- grab the anterior skin, pull it 6 lattice
units anterior over 20 frames, hold 10, release, record 120 -- then Table 2 (initial, peak and
AUC of the mean speed per tissue), Table 3 (stage times), the behaviour checks, and the speed
curves per tissue (the paper's Figures 3 and 4) plotted with matplotlib.

    PYTHONPATH=build/python /usr/bin/python3 python/examples/paper_protocol.py --out results
    ... --input ct.nii.gz --downsample 2          # a CT instead of the built-in phantom

Writes OUT/summary.json (tables and checks) and OUT/speed_curves.png.
"""
import argparse
import json
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display needed
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import hpcm  # noqa: E402


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--input", help="CT volume file or DICOM directory")
    src.add_argument("--phantom", default="96,96,64", help="built-in phantom size NX,NY,NZ (default 96,96,64)")
    ap.add_argument("--downsample", type=int, default=1, help="block-mean factor for --input (default 1)")
    ap.add_argument("--params", help="parameter file (TOML); default: built-in defaults")
    ap.add_argument("--settle", type=int, default=2000, help="idle frames after the protocol for the drift check")
    ap.add_argument("--backend", default="cpu", help="cpu | cuda")
    ap.add_argument("--out", default="paper_protocol_results", help="output folder")
    ap.add_argument("--strict", action="store_true", help="exit with status 1 when a behaviour check fails")
    return ap.parse_args()


def lattice_of(args):
    if args.input:
        inp = hpcm.load_input(args.input, downsample=args.downsample)
        return inp.lattice, f"{args.input} (downsample {args.downsample})"
    dims = tuple(int(v) for v in args.phantom.split(","))
    return hpcm.phantom(dims), f"phantom {args.phantom}"


def print_tables(result):
    conds = result["conditions"]
    print(f"\nTable 2: mean speed per tissue over the {result['recorded_frames']} frames after release "
          "(lattice units per frame)")
    print(f"{'tissue':14s}{'cond':>5s}{'initial':>12s}{'peak':>12s}{'AUC':>12s}")
    for tissue in hpcm.TISSUES[1:]:
        for label, c in conds.items():
            print(f"{tissue:14s}{label:>5s}{c['initial'][tissue]:12.6f}{c['peak'][tissue]:12.6f}{c['auc'][tissue]:12.6f}")
    print("\nTable 3: mean stage times per frame (ms)")
    print(f"{'cond':6s}{'ChainMail':>11s}{'Inertia':>9s}{'Snapshot':>10s}{'SimTotal':>10s}")
    for label, c in conds.items():
        print(f"{label:6s}{c['chainmail_ms']:11.3f}{c['inertia_ms']:9.3f}{c['snapshot_ms']:10.3f}{c['sim_total_ms']:10.3f}")
    print("\nBehaviour checks:")
    for k in result["checks"]:
        mark = {"held": "ok  ", "failed": "FAIL", "not_applicable": "n/a "}[k["status"]]
        why = f" not applicable: {k['reason']}" if k["status"] == "not_applicable" else ""
        print(f"  {mark} {k['name']:34s} {k['value']:.6g} (threshold {k['threshold']:.6g}){why}")


def plot(result, title, path):
    conds = result["conditions"]
    release = result["release_frame"]
    fig, axes = plt.subplots(1, len(conds) + 1, figsize=(4.2 * (len(conds) + 1), 3.6))
    for ax, (label, c) in zip(axes, conds.items()):
        speed = c["frames"]["mean_speed"][release:]  # (frames after release, 4 tissues)
        for t, tissue in enumerate(hpcm.TISSUES[1:], start=1):
            ax.plot(np.arange(len(speed)), speed[:, t], label=tissue)
        ax.set_title(f"{label}: {c['mode']}")
        ax.set_xlabel("frames after release")
        ax.set_ylabel("mean speed (lattice units / frame)")
        ax.legend(fontsize=8)
    ax = axes[-1]
    for label, c in conds.items():
        track = c["centre_track"][:, 1] - c["centre_rest"][1]
        ax.plot(track, label=label)
    ax.axvline(release, color="grey", lw=0.8, ls=":")
    ax.set_title("grab centre, y - rest (anterior < 0)")
    ax.set_xlabel("frame")
    ax.set_ylabel("lattice units")
    ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    args = parse_args()
    lattice, title = lattice_of(args)
    params = hpcm.Params.load(args.params) if args.params else hpcm.Params()
    print(f"{title}: lattice {lattice.dims}, conditions A, B, C, {args.settle} settle frames ...", flush=True)
    # A progress bar on a terminal (the experiment takes minutes); quiet in logs and tests.
    result = hpcm.run_experiment(lattice, params, settle_frames=args.settle, backend=args.backend,
                                 progress=sys.stderr.isatty())
    print_tables(result)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    plot(result, title, out / "speed_curves.png")
    summary = {
        "source": title,
        "dims": result["dims"],
        "elements": result["elements"],
        "grab_centre": result["grab_centre"],
        "release_frame": result["release_frame"],
        "conditions": {label: {k: c[k] for k in ("mode", "initial", "peak", "auc", "chainmail_ms", "inertia_ms",
                                                  "snapshot_ms", "sim_total_ms", "settle_max_speed")}
                       for label, c in result["conditions"].items()},
        "checks": result["checks"],
        "all_hold": result["all_hold"],
        "params": result["params"].to_dict(),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(f"\nwrote {out / 'summary.json'} and {out / 'speed_curves.png'}")
    return 1 if args.strict and not result["all_hold"] else 0


if __name__ == "__main__":
    sys.exit(main())
