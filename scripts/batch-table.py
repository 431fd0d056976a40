#!/usr/bin/env python3
"""`roe run --estimator batch` against the default `roe run` (filter + RTS smoother), issue 48 item 4.

For each source (a simulator preset, or gt:DIR for `roe simulate --from-groundtruth DIR`) and seed: roe simulate,
then `roe run` (default config: the smoother) and `roe run --estimator batch` on the same dataset, each as its own
process (CPU = user + sys and peak RSS from wait4), then `roe calib-check --json` and `roe eval` on both folders
(refine-table.py's truth_figures: calib-check's truth checks give every error and NEES; this script computes none).
The smoother's folder is judged as calib-check judges it (the filter's states_filter.csv for the extrinsics, the
smoothed trajectory); the batch folder by its own states.csv and marginals. Also kept per batch run: calib-check's
verdict of every check (item 5: a truth-free verdict must not pass extrinsics beyond 3 sigma of the truth).

--prior-draw: the dataset's declared extrinsics (roe.json camera.T_I_C) are replaced by a draw from N(truth, prior
sigma) with the default config's prior sigma per axis (20 mm, 2 deg; p + dp, R Exp(dtheta)), seeded by source and
seed, so that the estimate cannot win by staying at an exact prior.

  scripts/batch-table.py --roe build/roe --work /tmp/bt --seeds 1 2 3 4 5 --json rows.json
  scripts/batch-table.py ... --sources gt:/tmp/tumvi/room1 gt:../shared/data/euroc_v102_snippet
  scripts/batch-table.py --summary rows.json

Standard library only (numpy-free): the draw uses random.Random.
"""
import argparse
import importlib.util
import json
import math
import os
import random
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
_spec = importlib.util.spec_from_file_location("refine_table", os.path.join(HERE, "refine-table.py"))
rt = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rt)  # truth_figures, summary_row, median: one definition
_spec2 = importlib.util.spec_from_file_location("calib_truth_table", os.path.join(HERE, "calib-truth-table.py"))
ctt = importlib.util.module_from_spec(_spec2)
_spec2.loader.exec_module(ctt)  # qmul: one definition of the quaternion product


def timed(args):
    """Runs args; returns (exit code, CPU s = user + sys, peak RSS MB) of that process alone."""
    p = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    err = p.stderr.read().decode(errors="replace")
    p.stderr.close()
    code = os.waitstatus_to_exitcode(status)
    if code not in (0, 1):
        raise RuntimeError("%s: exit %d\n%s" % (" ".join(args), code, err[-2000:]))
    return code, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0


def exp_quat(w):
    a = math.sqrt(sum(x * x for x in w))
    if a < 1e-12:
        return [0.5 * w[0], 0.5 * w[1], 0.5 * w[2], 1.0]
    s = math.sin(0.5 * a) / a
    return [s * w[0], s * w[1], s * w[2], math.cos(0.5 * a)]


def draw_prior(ds, key, sigma_p=0.02, sigma_rot_deg=2.0):
    """roe.json camera.T_I_C := truth ⊞ N(0, diag(σ_p², σ_r²)), seeded by `key`; returns the draw."""
    path = os.path.join(ds, "roe.json")
    m = json.load(open(path))
    t = m["truth"]["T_I_C"]
    rng = random.Random(key)
    dp = [rng.gauss(0.0, sigma_p) for _ in range(3)]
    dth = [rng.gauss(0.0, math.radians(sigma_rot_deg)) for _ in range(3)]
    m["camera"]["T_I_C"] = {"p": [t["p"][i] + dp[i] for i in range(3)], "q": ctt.qmul(t["q"], exp_quat(dth))}
    with open(path, "w") as f:
        json.dump(m, f, indent=2)
    return {"dp_mm": [1e3 * x for x in dp], "dtheta_deg": [math.degrees(x) for x in dth]}


def verdicts(roe, run_dir):
    j = json.loads(rt.sh([roe, "calib-check", run_dir, "--json"], check=False).stdout)
    return {c["name"]: c["status"] for c in j["checks"]}


def one(a, source, seed):
    name = os.path.basename(source[3:].rstrip("/")) if source.startswith("gt:") else source
    ds = os.path.join(a.work, "%s-%d%s" % (name, seed, "-prior" if a.prior_draw else ""))
    if not os.path.isfile(os.path.join(ds, "roe.json")):
        src = ["--from-groundtruth", source[3:]] if source.startswith("gt:") else ["--preset", source]
        rt.sh([a.roe, "simulate", *src, "--seed", str(seed), "--out", ds, "-q", "--force"])
        if a.prior_draw:
            draw_prior(ds, "%s/%d" % (name, seed))
    man = json.load(open(os.path.join(ds, "roe.json")))
    symmetric = {o["id"] for o in man["objects"] if o.get("symmetric")}
    runs = {}
    for label, extra in (("smoother", []), ("batch", ["--estimator", "batch"])):
        out = "%s-%s" % (ds, label)
        code, cpu, rss = timed([a.roe, "run", ds, "--out", out, "--force", "-q"] + extra)
        f = rt.truth_figures(a.roe, out, symmetric)
        f.update({"cpu_s": cpu, "maxrss_mb": rss, "exit": code, "verdicts": verdicts(a.roe, out)})
        rj = json.load(open(os.path.join(out, "run.json")))
        f["timing_s"] = rj["timing_s"]
        if "refine" in rj:
            f["refine"] = rj["refine"]
        runs[label] = f
    b = runs["batch"]
    b["refine_cpu_s"] = b["cpu_s"] - runs["smoother"]["cpu_s"]  # what the batch adds to filter + smoother
    return {"preset": name, "seed": seed, "filter": runs["smoother"], "variants": {"batch": b}}


def per_source(rows):
    print("| source | runs | objects: smoother → batch (median, NEES ok) | extrinsics: filter → batch (median, "
          "NEES ok) | worst-axis position, smoother → batch (mean) | batch CPU beyond the smoother (median) |")
    print("|---|---|---|---|---|---|")
    for src in sorted({r["preset"] for r in rows}):
        rs = [r for r in rows if r["preset"] == src]
        cells = []
        for which in ("filter", "batch"):
            sets = [rt.figures(r, which) for r in rs]
            objs = [o for f in sets for o in f["objects"]]
            ok = sum(1 for o in objs if o["nees"] is not None and o["nees"] <= rt.CHI2_6_99)
            e_ok = sum(1 for f in sets if f["extr_nees"] is not None and f["extr_nees"] <= rt.CHI2_6_99)
            traj = [f["worst_axis_m"] for f in sets if f.get("worst_axis_m") is not None]
            cells.append(("%s, %d/%d" % ("%.0f mm / %.1f°" % (rt.median([o["mm"] for o in objs]),
                                                                rt.median([o["deg"] for o in objs]))
                                          if objs else "–", ok, len(objs)),
                          "%.0f mm / %.2f°, %d/%d" % (rt.median([f["extr_mm"] for f in sets]),
                                                      rt.median([f["extr_deg"] for f in sets]), e_ok, len(sets)),
                          sum(traj) / len(traj) if traj else float("nan")))
        cpu = rt.median([r["variants"]["batch"]["refine_cpu_s"] for r in rs])
        print("| %s | %d | %s → %s | %s → %s | %.3f → %.3f m | %.2f s |" % (
            src, len(rs), cells[0][0], cells[1][0], cells[0][1], cells[1][1], cells[0][2], cells[1][2], cpu))


def verdict_table(rows):
    """Item 5: calib-check's truth-free extrinsics verdicts on the batch folder against its truth NEES."""
    bad = []
    counts = {}
    for r in rows:
        b = r["variants"]["batch"]
        for k in ("extrinsics.sigma", "extrinsics.settled", "extrinsics.prior"):
            counts.setdefault(k, {}).setdefault(b["verdicts"].get(k, "?"), 0)
            counts[k][b["verdicts"].get(k, "?")] += 1
        # "beyond 3 sigma of the truth": the per-axis NEES beyond chi2_6(0.997) ~ 20.1 (3-sigma coverage in 6 dof)
        if b["extr_nees"] is not None and b["extr_nees"] > 20.06 and b["verdicts"].get("extrinsics.prior") == "pass" \
                and b["verdicts"].get("extrinsics.sigma") == "pass":
            bad.append("%s seed %d" % (r["preset"], r["seed"]))
    for k, v in counts.items():
        print("%s: %s" % (k, ", ".join("%s %d" % kv for kv in sorted(v.items()))))
    print("truth-free pass (sigma and prior) with the extrinsics beyond 3 sigma of the truth: %s" % (", ".join(bad) or "none"))


def collect_rows(a, one, describe):
    """The rows of `one(a, source, seed)` over a.sources x a.seeds (or read back from a.summary), each printed
    with `describe(row)` as it comes and the whole list saved to a.json after each; a failed run is said and
    skipped. Shared with gm-table.py."""
    if a.summary:
        return json.load(open(a.summary))
    os.makedirs(a.work, exist_ok=True)
    rows = []
    for s in a.sources:
        for seed in a.seeds:
            try:
                rows.append(one(a, s, seed))
            except RuntimeError as e:
                print("%s seed %d failed: %s" % (s, seed, str(e).splitlines()[0]))
                continue
            print("%s %d: %s" % (s, seed, describe(rows[-1])))
            sys.stdout.flush()
            if a.json:
                json.dump(rows, open(a.json, "w"), indent=1)
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roe", default=os.path.join(os.path.dirname(HERE), "build", "roe"))
    ap.add_argument("--work", default="/tmp/roe-batch-table")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--sources", nargs="+", default=["paper-real-seq%d" % i for i in range(1, 9)])
    ap.add_argument("--prior-draw", action="store_true")
    ap.add_argument("--json", default=None)
    ap.add_argument("--summary", default=None)
    a = ap.parse_args()

    def describe(r):
        f, b = r["filter"], r["variants"]["batch"]
        return ("extrinsics %s → %s; objects %s → %s; worst axis %.3f → %.3f m; CPU %.2f → %.2f s (peak %.0f → %.0f MB)"
                % (rt.fmt_extr(f), rt.fmt_extr(b), rt.fmt_objs(f["objects"]), rt.fmt_objs(b["objects"]),
                   f["worst_axis_m"] or float("nan"), b["worst_axis_m"] or float("nan"),
                   f["cpu_s"], b["cpu_s"], f["maxrss_mb"], b["maxrss_mb"]))
    rows = collect_rows(a, one, describe)
    print()
    rt.print_summary(rows)
    print()
    per_source(rows)
    print()
    verdict_table(rows)


if __name__ == "__main__":
    main()
