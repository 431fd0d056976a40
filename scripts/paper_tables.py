#!/usr/bin/python3
"""The paper's Tables I-III next to their simulated analogues, as Markdown, from a `roe sweep aggregate`
folder of configs/sweeps/paper-tables.json (its jobs.csv) and, when given, the paper's LaTeX source (the
paper's numbers are read from its three tabulars; without it only the simulated columns are printed).
Mean and std over runs are the population std (ddof 0), as in the paper's tables.

usage: scripts/paper_tables.py AGGREGATE_DIR [PAPER_TEX]"""
import csv
import math
import os
import re
import sys

POS = ["rmse_x_m", "rmse_y_m", "rmse_z_m"]
ROT = ["rmse_roll_deg", "rmse_pitch_deg", "rmse_yaw_deg"]


def paper_tables(tex_path):
    """Rows of the paper's three result tabulars: [{run: (pos, rot)}], Table I rows also with #objects."""
    text = open(tex_path, encoding="utf-8").read()
    row = re.compile(r"^(\d+)\s*&\s*(?:(\d+)\s*&\s*)?\{\[\}([^{]*)\{\]\}\s*&\s*\{\[\}([^{]*)\{\]\}", re.M)
    tables = []
    for body in text.split("\\begin{tabular}")[1:]:
        body = body.split("\\end{tabular}")[0]
        rows = {}
        for m in row.finditer(body):
            pos = [float(v) for v in m.group(3).split(",")]
            rot = [float(v) for v in m.group(4).split(",")]
            rows[int(m.group(1))] = (pos, rot, m.group(2))
        if rows:
            tables.append(rows)
    return tables[:3] if len(tables) >= 3 else None


def fmt(v, d):
    return "[" + ", ".join("%.*f" % (d, x) for x in v) + "]"


def mean_std(rows):
    n = len(rows)
    cols = list(zip(*rows))
    mean = [sum(c) / n for c in cols]
    std = [math.sqrt(sum((x - m) ** 2 for x in c) / n) for c, m in zip(cols, mean)]
    return mean, std


def table(title, label, keys, sim, paper, with_objects=False):
    head = "| %s | paper (x, y, z) [m] | simulated (x, y, z) [m] | paper (roll, pitch, yaw) [deg] | " \
           "simulated (roll, pitch, yaw) [deg] |" % label
    out = ["### " + title, "", head, "|---|---|---|---|---|"]
    sp, sr, pp, pr = [], [], [], []
    for k, key in enumerate(keys, 1):
        job = sim.get(key)
        p = paper.get(k) if paper else None
        name = str(k) + (" (%s obj.)" % p[2] if with_objects and p and p[2] else "")
        s_pos = fmt([job[c] for c in POS], 3) if job else "not run"
        s_rot = fmt([job[c] for c in ROT], 2) if job else "not run"
        out.append("| %s | %s | %s | %s | %s |" % (name, fmt(p[0], 3) if p else "-", s_pos,
                                                     fmt(p[1], 2) if p else "-", s_rot))
        if job:
            sp.append([job[c] for c in POS])
            sr.append([job[c] for c in ROT])
        if p:
            pp.append(p[0])
            pr.append(p[1])
    cells = []
    for rows, d in ((pp, 3), (sp, 3), (pr, 2), (sr, 2)):
        cells.append(mean_std(rows) if rows else None)
    out.append("| mean | %s |" % " | ".join(fmt(c[0], d) if c else "-" for c, d in zip(cells, (3, 3, 2, 2))))
    out.append("| ± std | %s |" % " | ".join("± " + fmt(c[1], d) if c else "-" for c, d in zip(cells, (3, 3, 2, 2))))
    return "\n".join(out) + "\n"


def main():
    agg = sys.argv[1]
    jobs = {}
    with open(os.path.join(agg, "jobs.csv"), newline="") as f:
        for r in csv.DictReader(f):
            if r["status"] == "done":
                jobs[(r["dataset"], int(r["seed"]))] = {c: float(r[c]) for c in POS + ROT}
    paper = paper_tables(sys.argv[2]) if len(sys.argv) > 2 and os.path.exists(sys.argv[2]) else None
    p1, p2, p3 = paper if paper else (None, None, None)
    print(table("Table I: one run per sequence (simulated: seed 1)", "Sequence",
                [("paper-seq%d" % i, 1) for i in range(1, 9)], jobs, p1, with_objects=True))
    print(table("Table II: sequence 4, ten runs (simulated: seeds 1-10)", "Run",
                [("paper-seq4", s) for s in range(1, 11)], jobs, p2))
    print(table("Table III: sequence 6, ten runs (simulated: seeds 1-10)", "Run",
                [("paper-seq6", s) for s in range(1, 11)], jobs, p3))


main()
