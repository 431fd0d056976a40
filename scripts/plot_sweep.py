#!/usr/bin/python3
"""Box plots of a `roe sweep aggregate` folder: one PNG per metric, one box per configuration variant
(config + overrides), from DIR/jobs.csv. Called by `roe sweep aggregate --plot` (embedded in roe);
usage: plot_sweep.py AGGREGATE_DIR; also writes plots/plots.json (per plot: metric, title, file, n per variant)

Each plot is titled with what the metric is (not its column key) and every box is labelled with its
variant and the number of finished jobs it summarises (n); the mean is the triangle."""
import csv
import json
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# Variant names come from the user's spec (config files, overrides): drawn as plain text, never as
# mathtext (a `$` in a name would otherwise end the script; issue 51). None of this script's labels uses it.
if "text.parse_math" in matplotlib.rcParams:
    matplotlib.rcParams["text.parse_math"] = False

# jobs.csv column -> (title, unit): the columns of `roe eval --summary` (app/eval_summary.cpp).
TITLES = {
    "rmse_x_m": ("Position RMSE along x", "m"),
    "rmse_y_m": ("Position RMSE along y", "m"),
    "rmse_z_m": ("Position RMSE along z", "m"),
    "rmse_roll_deg": ("Roll RMSE (ZYX Euler)", "°"),
    "rmse_pitch_deg": ("Pitch RMSE (ZYX Euler)", "°"),
    "rmse_yaw_deg": ("Yaw RMSE (ZYX Euler)", "°"),
    "ate_rmse_m": ("Absolute trajectory error (APE translation RMSE)", "m"),
    "rot_rmse_deg": ("APE rotation RMSE", "°"),
}


def title_of(metric):
    """(title, unit) of a jobs.csv metric column; unknown columns read as words with their unit."""
    if metric in TITLES:
        return TITLES[metric]
    unit = "m" if metric.endswith("_m") else "°" if metric.endswith("_deg") else ""
    stem = metric[: -len("_m")] if unit == "m" else metric[: -len("_deg")] if unit else metric
    words = stem.replace("_", " ").replace("rmse", "RMSE")
    return words[:1].upper() + words[1:], unit


def main(out):
    with open(os.path.join(out, "jobs.csv"), newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["status"] == "done"]
    metrics = [c for c in (rows[0].keys() if rows else []) if c.endswith("_m") or c.endswith("_deg")]
    os.makedirs(os.path.join(out, "plots"), exist_ok=True)
    variants = []
    for r in rows:
        if r["variant"] not in variants:
            variants.append(r["variant"])
    listed = []
    for m in metrics:
        data = [[float(r[m]) for r in rows if r["variant"] == v and r[m] != "" and math.isfinite(float(r[m]))]
                for v in variants]
        title, unit = title_of(m)
        fig, ax = plt.subplots(figsize=(max(4.5, 1.2 * len(variants) + 2), 3.8))
        ax.boxplot(data, labels=[f"{v}\nn = {len(d)}" for v, d in zip(variants, data)], showmeans=True)
        ax.set_ylabel(f"{title.split(' (')[0]} [{unit}]" if unit else title)
        ns = sorted({len(d) for d in data})
        ax.set_title(f"{title}, n = {ns[0]} per variant" if len(ns) == 1 else f"{title} (n per box below)")
        ax.grid(True, axis="y", alpha=0.3)
        plt.setp(ax.get_xticklabels(), rotation=20, ha="right")
        fig.tight_layout()
        fig.savefig(os.path.join(out, "plots", "box_%s.png" % m), dpi=120)
        listed.append({"metric": m, "title": ax.get_title(), "ylabel": ax.get_ylabel(), "file": "box_%s.png" % m,
                       "n": {v: len(d) for v, d in zip(variants, data)}})
        plt.close(fig)
    with open(os.path.join(out, "plots", "plots.json"), "w") as f:
        json.dump({"plots": listed}, f, indent=1)


if __name__ == "__main__":
    main(sys.argv[1])
