#!/usr/bin/python3
"""The paper's Table I Euler column under roe eval's three Euler metrics (docs/RESULTS.md §7, issue 36).

For each sequence N and seed S: `roe simulate --preset paper-real-seqN --seed S`, `roe run --config paper`,
then `roe eval --euler M --no-out --json` for M = error, absolute, absolute-unwrapped (with
--fit-body-rotation on the first). Per run the worst axis of the per-axis Euler RMSE (and of the position
RMSE), as the paper's Table I row and scripts/calibrate-paper-real.py take it; averaged over the seeds per
sequence, then over the sequences. Prints a Markdown table next to the paper's Table I (its numbers from
calibrate-paper-real.py), with the share of pairs whose absolute-angle difference jumped by 360 deg and the
fitted body-frame rotation angle.

usage: euler-metrics-table.py [--roe build/roe] [--seeds 1-5] [--seqs 1-8] [--jobs 2] [--config paper]
                              [--work DIR] [--json OUT]
"""
import argparse
import concurrent.futures as cf
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
METRICS = ("error", "absolute", "absolute-unwrapped")


def paper_table_one():
    """The paper's Table I as calibrate-paper-real.py holds it (one copy of those numbers)."""
    spec = importlib.util.spec_from_file_location("calib", os.path.join(HERE, "scripts", "calibrate-paper-real.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.PAPER, mod.span


def one(roe, work, config, seq, seed):
    """{metric: (worst-axis Euler, jump share any axis)}, worst-axis position, body-rotation angle; None on failure."""
    ds = os.path.join(work, "seq%d-s%d" % (seq, seed))
    run = ds + "-run"
    t0 = time.time()
    subprocess.run([roe, "simulate", "--preset", "paper-real-seq%d" % seq, "--seed", str(seed), "--out", ds,
                    "--force", "-q"], check=True)
    r = subprocess.run([roe, "run", ds, "--config", config, "--out", run, "--force", "-q"],
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    if r.returncode not in (0, 1):  # 1: finished but judged unhealthy; the metrics still apply
        return seq, seed, None
    res = {"metrics": {}, "seconds": 0.0}
    for m in METRICS:
        extra = ["--fit-body-rotation"] if m == "error" else []
        e = subprocess.run([roe, "eval", run, "--euler", m, "--no-out", "--json", *extra], capture_output=True,
                           text=True)
        if e.returncode != 0:
            return seq, seed, None
        j = json.loads(e.stdout)
        ax = j["per_axis"]
        jump = ax.get("jump_360_share", {}).get("any", 0.0)
        res["metrics"][m] = (max(ax["rpy_rmse_deg"].values()), jump)
        if m == "error":
            res["pos"] = max(ax["pos_rmse_m"].values())
            res["body_deg"] = j["body_rotation"]["angle_deg"]
    res["seconds"] = time.time() - t0
    return seq, seed, res


def mean(v):
    return sum(v) / len(v) if v else float("nan")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roe", default=os.path.join(HERE, "build", "roe"))
    ap.add_argument("--seeds", default="1-5")
    ap.add_argument("--seqs", default="1-8")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--config", default="paper")
    ap.add_argument("--work")
    ap.add_argument("--json")
    a = ap.parse_args()
    paper, span = paper_table_one()
    seqs, seeds = span(a.seqs), span(a.seeds)
    work = a.work or tempfile.mkdtemp(prefix="roe-euler-")
    t0 = time.time()
    with cf.ThreadPoolExecutor(a.jobs) as ex:
        runs = list(ex.map(lambda qs: one(a.roe, work, a.config, *qs), [(q, s) for q in seqs for s in seeds]))
    wall = time.time() - t0
    by_seq = {q: [r for (qq, _, r) in runs if qq == q and r] for q in seqs}
    failed = [(q, s) for (q, s, r) in runs if not r]
    print("| seq | paper Table I: pos / Euler | roe pos | error | absolute | absolute-unwrapped | "
          "unwrapped / paper | 360-deg jumps | body rotation |")
    print("|---|---|---|---|---|---|---|---|---|")
    cols = {k: [] for k in ("paper_pos", "paper_rot", "pos", "body") + METRICS + ("jump",)}
    for q in seqs:
        rs = by_seq[q]
        pp, pr = max(paper[q][0]), max(paper[q][1])
        vals = {m: mean([r["metrics"][m][0] for r in rs]) for m in METRICS}
        jump = mean([r["metrics"]["absolute-unwrapped"][1] for r in rs])
        pos, body = mean([r["pos"] for r in rs]), mean([r["body_deg"] for r in rs])
        for k, v in (("paper_pos", pp), ("paper_rot", pr), ("pos", pos), ("body", body), ("jump", jump)):
            cols[k].append(v)
        for m in METRICS:
            cols[m].append(vals[m])
        print("| %d | %.3f / %.2f | %.3f | %.1f | %.1f | **%.1f** | %.2f | %.2f %% | %.1f deg |" % (
            q, pp, pr, pos, vals["error"], vals["absolute"], vals["absolute-unwrapped"],
            vals["absolute-unwrapped"] / pr, 100 * jump, body))
    m = {k: mean(v) for k, v in cols.items()}
    print("| mean | %.3f / %.2f | %.3f | %.1f | %.1f | **%.1f** | %.2f | %.2f %% | %.1f deg |" % (
        m["paper_pos"], m["paper_rot"], m["pos"], m["error"], m["absolute"], m["absolute-unwrapped"],
        m["absolute-unwrapped"] / m["paper_rot"], 100 * m["jump"], m["body"]))
    print("\n%d runs (seqs %s, seeds %s, --config %s) in %.1f s wall with %d jobs; failed: %s; work %s" % (
        len(runs), a.seqs, a.seeds, a.config, wall, a.jobs, failed or "none", work))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"%d-%d" % (q, s): r for (q, s, r) in runs}, f, indent=1)
    within = abs(m["absolute-unwrapped"] / m["paper_rot"] - 1.0) <= 0.3
    print("mean worst-axis absolute-unwrapped Euler RMSE %.1f deg vs the paper's %.1f deg: %s ±30 %%" % (
        m["absolute-unwrapped"], m["paper_rot"], "within" if within else "NOT within"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
