#!/usr/bin/python3
"""Box plots of a `roe sweep aggregate` folder: one PNG per metric, one box per configuration variant
(config + overrides), from DIR/jobs.csv. Called by `roe sweep aggregate --plot` (embedded in roe);
usage: plot_sweep.py AGGREGATE_DIR"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

out = sys.argv[1]
with open(os.path.join(out, "jobs.csv"), newline="") as f:
    rows = [r for r in csv.DictReader(f) if r["status"] == "done"]
metrics = [c for c in (rows[0].keys() if rows else []) if c.endswith("_m") or c.endswith("_deg")]
os.makedirs(os.path.join(out, "plots"), exist_ok=True)
variants = []
for r in rows:
    if r["variant"] not in variants:
        variants.append(r["variant"])
for m in metrics:
    data = [[float(r[m]) for r in rows if r["variant"] == v] for v in variants]
    fig, ax = plt.subplots(figsize=(max(4.0, 1.2 * len(variants) + 2), 3.6))
    ax.boxplot(data, labels=variants, showmeans=True)
    ax.set_ylabel(m.replace("_m", " [m]").replace("_deg", " [deg]") if m.endswith(("_m", "_deg")) else m)
    ax.set_title(m)
    ax.grid(True, axis="y", alpha=0.3)
    plt.setp(ax.get_xticklabels(), rotation=20, ha="right")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "plots", "box_%s.png" % m), dpi=120)
    plt.close(fig)
