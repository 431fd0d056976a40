#!/usr/bin/env python3
"""The filter's detection-error models side by side (issue 49 item 1): today's default (white errors), §15's
white-inflation (filter.detection_error_correlation_s = TAU), the Gauss–Markov error states
(filter.detection_error_states, τ = TAU) and the consider covariance (filter.consider_correlated_errors,
τ = TAU: the white filter's estimate with σ from P_a, docs/filter.md §18), each as the smoother (roe run's
default) and as the causal filter (--estimator filter), on the same simulated datasets.

Every figure comes from roe itself, as in batch-table.py: refine-table.py's truth_figures (calib-check's truth
checks and roe eval's worst axis) and batch-table.py's timed / verdicts; this script only loops and tabulates.

  scripts/gm-table.py --roe build/roe --work /tmp/gm --seeds 1 2 3 --json rows.json
  scripts/gm-table.py ... --sources gt:/tmp/tumvi/room1
  scripts/gm-table.py ... --configs default consider   (a subset of the configurations)
  scripts/gm-table.py --summary rows.json
"""
import argparse
import importlib.util
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def _load(name, file):
    spec = importlib.util.spec_from_file_location(name, os.path.join(HERE, file))
    m = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(m)
    return m


rt = _load("refine_table", "refine-table.py")  # truth_figures, median, CHI2_6_99, sh
bt = _load("batch_table", "batch-table.py")  # timed, verdicts

ESTIMATORS = ("smoother", "filter")


def configs(tau):
    return {"default": None,
            "white-inflation": {"filter": {"detection_error_correlation_s": tau}},
            "gauss-markov": {"filter": {"detection_error_states": True, "detection_error_correlation_s": tau}},
            "consider": {"filter": {"consider_correlated_errors": True, "detection_error_correlation_s": tau}}}


def one(a, source, seed):
    name = os.path.basename(source[3:].rstrip("/")) if source.startswith("gt:") else source
    ds = os.path.join(a.work, "%s-%d" % (name, seed))
    if not os.path.isfile(os.path.join(ds, "roe.json")):
        src = ["--from-groundtruth", source[3:]] if source.startswith("gt:") else ["--preset", source]
        rt.sh([a.roe, "simulate", *src, "--seed", str(seed), "--out", ds, "-q", "--force"])
    man = json.load(open(os.path.join(ds, "roe.json")))
    symmetric = {o["id"] for o in man["objects"] if o.get("symmetric")}
    row = {"preset": name, "seed": seed, "runs": {}}
    for label, cfg in configs(a.tau).items():
        if label not in a.configs:
            continue
        extra = []
        if cfg is not None:
            path = os.path.join(a.work, "config-%s.json" % label)
            json.dump(cfg, open(path, "w"))
            extra = ["--config", path]
        for est in ESTIMATORS:
            out = "%s-%s-%s" % (ds, label, est)
            code, cpu, rss = bt.timed([a.roe, "run", ds, "--out", out, "--force", "-q", "--estimator", est] + extra)
            f = rt.truth_figures(a.roe, out, symmetric)
            rep = json.load(open(out + "-eval/report.json"))
            f["worst_axis_deg"] = max(rep["per_axis"]["rpy_rmse_deg"].values())
            f.update({"cpu_s": cpu, "exit": code, "verdicts": bt.verdicts(a.roe, out)})
            row["runs"]["%s/%s" % (label, est)] = f
    return row


def table(rows):
    print("| configuration | estimator | objects NEES ≤ χ²₆(0.99) | extrinsics NEES ok | worst axis (mean) | "
          "extrinsics error (median) | objects error (median) | truth-free extrinsics pass beyond 3σ |")
    print("|---|---|---|---|---|---|---|---|")
    for label in configs(0.0):
        for est in ESTIMATORS:
            fs = [r["runs"]["%s/%s" % (label, est)] for r in rows if "%s/%s" % (label, est) in r["runs"]]
            if not fs:
                continue
            objs = [o for f in fs for o in f["objects"]]
            ok = sum(1 for o in objs if o["nees"] is not None and o["nees"] <= rt.CHI2_6_99)
            e_ok = sum(1 for f in fs if f["extr_nees"] is not None and f["extr_nees"] <= rt.CHI2_6_99)
            wm = [f["worst_axis_m"] for f in fs if f["worst_axis_m"] is not None]
            wd = [f["worst_axis_deg"] for f in fs if f["worst_axis_m"] is not None]
            # "beyond 3 sigma": the extrinsics NEES beyond chi2_6(0.997) ~ 20.06, with calib-check's truth-free
            # sigma and prior checks both `pass` (batch-table.py's verdict_table rule)
            bad = sum(1 for f in fs if f["extr_nees"] is not None and f["extr_nees"] > 20.06
                      and f["verdicts"].get("extrinsics.prior") == "pass"
                      and f["verdicts"].get("extrinsics.sigma") == "pass")
            print("| %s | %s | %d/%d (%.0f %%) | %d/%d | %.3f m / %.2f° | %.0f mm / %.2f° | %.0f mm / %.1f° | %d/%d |" % (
                label, est, ok, len(objs), 100.0 * ok / max(1, len(objs)), e_ok, len(fs),
                sum(wm) / max(1, len(wm)), sum(wd) / max(1, len(wd)),
                rt.median([f["extr_mm"] for f in fs]), rt.median([f["extr_deg"] for f in fs]),
                rt.median([o["mm"] for o in objs]), rt.median([o["deg"] for o in objs]), bad, len(fs)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roe", default=os.path.join(os.path.dirname(HERE), "build", "roe"))
    ap.add_argument("--work", default="/tmp/roe-gm-table")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--sources", nargs="+", default=["paper-real-seq%d" % i for i in range(1, 9)])
    ap.add_argument("--tau", type=float, default=3.0, help="detection_error_correlation_s of both correlated models")
    ap.add_argument("--configs", nargs="+", default=list(configs(0.0)), choices=list(configs(0.0)),
                    help="the configurations to run (default: all)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--summary", default=None)
    a = ap.parse_args()
    rows = bt.collect_rows(a, one, lambda r: "; ".join(
        "%s %s %.3f m" % (k, rt.fmt_extr(f), f["worst_axis_m"] or float("nan")) for k, f in r["runs"].items()))
    table(rows)


if __name__ == "__main__":
    main()
