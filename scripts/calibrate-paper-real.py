#!/usr/bin/python3
"""Calibration table of the paper-real presets (docs/simulator.md §6b, docs/RESULTS.md §7).

For each sequence N and seed: `roe simulate --preset paper-real-seqN --seed S`, `roe run` with each
filter config, `roe eval --no-out --json`; the worst axis of the per-axis position RMSE and of the ZYX
Euler RMSE (roe eval's per_axis block, the paper's Table I metrics), averaged over the seeds. Prints a
Markdown table next to the paper's Table I (worst axis per sequence) and the ratios the calibration
targets: per sequence within a factor 1.5 of the paper, mean over the sequences within ±30 %.

usage: calibrate-paper-real.py [--roe build/roe] [--seeds 1-5] [--seqs 1-8] [--jobs 2]
                               [--preset-dir DIR] [--prefix paper-real-seq] [--json OUT]
                               [CONFIG ...]   (default: configs/paper.json configs/default.json)
--preset-dir DIR simulates DIR/<prefix>N.json with --config instead of the embedded preset (to try a
calibration before it is compiled in).
"""
import argparse
import concurrent.futures as cf
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# The paper's Table I (Jantos et al., ICRA 2023): per-axis RMSE (x, y, z) [m] and (roll, pitch, yaw) [deg].
PAPER = {
    1: ([0.066, 0.163, 0.034], [3.00, 6.81, 4.52]),
    2: ([0.162, 0.358, 0.233], [54.38, 19.39, 20.27]),
    3: ([0.163, 0.338, 0.136], [25.34, 16.57, 15.13]),
    4: ([0.045, 0.157, 0.108], [15.38, 5.58, 10.02]),
    5: ([0.075, 0.031, 0.054], [61.12, 9.66, 26.19]),
    6: ([0.061, 0.117, 0.029], [11.00, 5.77, 7.41]),
    7: ([0.093, 0.159, 0.099], [19.38, 12.38, 27.24]),
    8: ([0.127, 0.165, 0.104], [26.19, 11.95, 10.70]),
}


def span(text):
    a, _, b = text.partition("-")
    return list(range(int(a), int(b or a) + 1))


def one(roe, work, prefix, preset_dir, seq, seed, configs):
    """Worst-axis (position m, Euler deg) per config for one sequence and seed; None when a run fails."""
    ds = os.path.join(work, "%s%d-s%d" % (prefix, seq, seed))
    src = (["--config", os.path.join(preset_dir, "%s%d.json" % (prefix, seq))] if preset_dir
           else ["--preset", "%s%d" % (prefix, seq)])
    subprocess.run([roe, "simulate", *src, "--seed", str(seed), "--out", ds, "--force", "-q"], check=True)
    out = {}
    for cfg in configs:
        run = ds + "-run-" + os.path.basename(cfg)
        r = subprocess.run([roe, "run", ds, "--config", cfg, "--out", run, "--force", "-q"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if r.returncode not in (0, 1):  # 1: run finished but judged unhealthy; metrics still apply
            out[cfg] = None
            continue
        e = subprocess.run([roe, "eval", run, "--no-out", "--json"], capture_output=True, text=True)
        if e.returncode != 0:
            out[cfg] = None
            continue
        ax = json.loads(e.stdout)["per_axis"]
        out[cfg] = (max(ax["pos_rmse_m"].values()), max(ax["rpy_rmse_deg"].values()))
    return seq, seed, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("configs", nargs="*")
    ap.add_argument("--roe", default=os.path.join(HERE, "build", "roe"))
    ap.add_argument("--seeds", default="1-5")
    ap.add_argument("--seqs", default="1-8")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--preset-dir")
    ap.add_argument("--prefix", default="paper-real-seq")
    ap.add_argument("--json")
    a = ap.parse_args()
    configs = a.configs or [os.path.join(HERE, "configs", c) for c in ("paper.json", "default.json")]
    seqs, seeds = span(a.seqs), span(a.seeds)
    res = {}
    with tempfile.TemporaryDirectory() as work, cf.ThreadPoolExecutor(a.jobs) as pool:
        jobs = [pool.submit(one, a.roe, work, a.prefix, a.preset_dir, q, s, configs) for q in seqs for s in seeds]
        for j in cf.as_completed(jobs):
            q, s, out = j.result()
            res[(q, s)] = out

    def mean(xs):
        xs = [x for x in xs if x is not None]
        return sum(xs) / len(xs) if xs else float("nan")

    table = {}
    for cfg in configs:
        for q in seqs:
            runs = [res[(q, s)][cfg] for s in seeds]
            ok = [r for r in runs if r is not None]
            table[(cfg, q)] = (mean([r[0] for r in ok]), mean([r[1] for r in ok]), len(runs) - len(ok),
                               [r for r in runs])
    names = [os.path.basename(c) for c in configs]
    print("| seq | paper Table I: worst pos [m] / Euler [deg] | " +
          " | ".join("%s (mean of seeds %s) pos / Euler | ratio to paper" % (n, a.seeds) for n in names) + " |")
    print("|---|---|" + "---|---|" * len(configs))
    for q in seqs:
        pp, pr = max(PAPER[q][0]), max(PAPER[q][1])
        cells = []
        for cfg in configs:
            p, r, failed, _ = table[(cfg, q)]
            cells.append("%.3f / %.1f%s | %.2f / %.2f" % (p, r, " (%d failed)" % failed if failed else "",
                                                           p / pp, r / pr))
        print("| %d | %.3f / %.2f | %s |" % (q, pp, pr, " | ".join(cells)))
    pp = mean([max(PAPER[q][0]) for q in seqs])
    pr = mean([max(PAPER[q][1]) for q in seqs])
    cells = []
    for cfg in configs:
        p = mean([table[(cfg, q)][0] for q in seqs])
        r = mean([table[(cfg, q)][1] for q in seqs])
        cells.append("%.3f / %.1f | %.2f / %.2f" % (p, r, p / pp, r / pr))
    print("| mean | %.3f / %.2f | %s |" % (pp, pr, " | ".join(cells)))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"seeds": seeds, "seqs": seqs,
                       "runs": {"%s/seq%d/seed%d" % (os.path.basename(c), q, s): res[(q, s)][c]
                                for c in configs for q in seqs for s in seeds}}, f, indent=1)


if __name__ == "__main__":
    sys.exit(main())
