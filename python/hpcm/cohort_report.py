"""cohort_report.md and its plots from cohort.csv (hpcm.cohort writes both at the end)."""
import math
from pathlib import Path

TISSUES = ("skin_fat", "muscle_organ", "bone")  # air has no Table 2 row worth a plot
CONDITIONS = ("A", "B", "C")
FIGURES = ("initial", "peak", "auc")


def _fmt(v):
    if isinstance(v, float):
        if math.isnan(v):
            return ""
        return f"{v:.4g}"
    return str(v)


def _md_table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(_fmt(v).replace("|", "\\|") for v in r) + " |" for r in rows]
    return "\n".join(lines)


def figure_columns(table):
    """Table 2 figures and the ratios, in cohort.csv order."""
    return [c for c in table.columns
            if c.split("_", 1)[0] in CONDITIONS and (c.endswith(FIGURES) and "_ms" not in c)] + \
        [c for c in table.columns if c == "skin_peak_C_over_B"]


def _plot_cases(table, out, plots):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    done = table[table["status"] == "done"]
    for cond in CONDITIONS:
        fig, axes = plt.subplots(1, 3, figsize=(14, 4 + 0.12 * len(done)))
        for ax, what in zip(axes, FIGURES):
            width = 0.8 / len(TISSUES)
            for i, t in enumerate(TISSUES):
                col = f"{cond}_{t}_{what}"
                ys = [j + (i - 1) * width for j in range(len(done))]
                ax.barh(ys, done[col], height=width, label=t)
            ax.set_yticks(range(len(done)))
            ax.set_yticklabels(done["case"], fontsize=7)
            ax.invert_yaxis()
            ax.set_title(f"condition {cond}: {what}")
            ax.set_xlabel("voxel/frame" if what != "auc" else "voxel")
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        name = f"table2_{cond}.png"
        fig.savefig(plots / name, dpi=90)
        plt.close(fig)
        names.append(name)
    return names


def _plot_sweep(table, swept, plots):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = []
    done = table[table["status"] == "done"]
    for p in swept:
        try:
            x, labels = done[p].astype(float), None
        except (TypeError, ValueError):  # a mode name or a per-tissue table: one position per value
            labels = list(dict.fromkeys(str(v) for v in done[p]))
            x = [labels.index(str(v)) for v in done[p]]
        fig, axes = plt.subplots(3, 3, figsize=(12, 10), squeeze=False)
        for r, cond in enumerate(CONDITIONS):
            for k, what in enumerate(FIGURES):
                ax = axes[r][k]
                for t in TISSUES:
                    ax.scatter(x, done[f"{cond}_{t}_{what}"], label=t, s=16)
                if labels:
                    ax.set_xticks(range(len(labels)))
                    ax.set_xticklabels(labels, fontsize=6, rotation=20)
                ax.set_title(f"{cond} {what}", fontsize=9)
                ax.set_xlabel(p, fontsize=8)
        axes[0][0].legend(fontsize=7)
        fig.tight_layout()
        name = "sweep_" + "".join(ch if ch.isalnum() else "_" for ch in p) + ".png"
        fig.savefig(plots / name, dpi=80)
        plt.close(fig)
        names.append(name)
    return names


def write(out, table, job, swept, cohort_wall_s, workers, plots=True):
    """Writes out/cohort_report.md (and out/plots/*.png when `plots`)."""
    out = Path(out)
    done = table[table["status"] == "done"]
    ran = table[(table["status"] == "done") & (~table["resumed"].astype(bool))]
    case_sum = float(ran["wall_s"].sum()) if len(ran) else 0.0
    L = [f"# Cohort report ({job})", ""]
    L.append(f"{len(table)} cases: {len(done)} done, {len(table) - len(done)} failed; "
             f"{int(table['resumed'].astype(bool).sum())} taken from an earlier run of the same cohort (resume).")
    L.append("")
    L.append(f"Cohort wall time {cohort_wall_s:.1f} s on {workers} Dask worker(s), against {case_sum:.1f} s for the "
             f"sum of the {len(ran)} cases run now"
             + (f" (speed-up {case_sum / cohort_wall_s:.2f}x)." if cohort_wall_s > 0 and len(ran) else "."))
    L.append("")
    if job != "run" and len(done):
        L += ["## Table 2 figures over the cases", "",
              "Median and range over the cases done (speeds in voxel/frame, AUC in voxel; body elements only).", ""]
        rows = []
        for col in figure_columns(table):
            v = done[col].astype(float)
            rows.append([col, v.median(), v.min(), v.max()])
        L += [_md_table(["figure", "median", "min", "max"], rows), ""]
        L += ["## Checks per case", ""]
        check_cols = [c for c in table.columns if c.startswith("check_")]
        rows = []
        for _, r in done.iterrows():
            failed = [c[6:] for c in check_cols if r[c] == "failed"]
            rows.append([r["case"], int(r["checks_held"]), int(r["checks_failed"]), int(r["checks_not_applicable"]),
                         ", ".join(failed)])
        L += [_md_table(["case", "held", "failed", "not applicable", "failed checks"], rows), ""]
    L += ["## Cases", ""]
    rows = [[r["case"], r["status"], r["wall_s"], "yes" if r["resumed"] else "", r.get("elements", ""), r["error"]]
            for _, r in table.iterrows()]
    L += [_md_table(["case", "status", "wall time (s)", "resumed", "elements", "error"], rows), ""]
    if plots and job != "run" and len(done):
        plot_dir = out / "plots"
        plot_dir.mkdir(exist_ok=True)
        names = _plot_cases(table, out, plot_dir)
        if swept:
            names += _plot_sweep(table, swept, plot_dir)
        L += ["## Plots", ""] + [f"![{n}](plots/{n})" for n in names] + [""]
    L += ["Columns of every case: cohort.csv (docs/cohort.md lists them)."]
    (out / "cohort_report.md").write_text("\n".join(L) + "\n")
