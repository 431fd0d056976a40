#!/usr/bin/env python3
"""The measurements of docs/refine.md §4: filter/smoother vs `roe refine` on simulated presets.

For each preset and seed: roe simulate, roe run (default config), roe refine; then `roe calib-check --json`
on both run folders, whose truth checks (truth.extrinsics, truth.objects: src/calib/calib_check.cpp) give the
figures — the extrinsics' error and per-axis NEES, and each object's error relative to the anchor and its
per-axis NEES — so this script computes no error of its own. Symmetric objects (roe.json) are left out of
the object columns, as in issue 35's table. Also records refine's CPU time (user + sys of the process).

With --summary ROWS.json (a --json output of an earlier call) it prints only the summary of those rows.
The summary: objects' median position / rotation error, the worst, how many have NEES <= chi2_6(0.99),
the median NEES; the extrinsics' median error, how many runs within 15 mm / 1 deg and NEES <= chi2_6(0.99).

With --variant LABEL=ROE[:ARGS] (repeatable) the same run folder is refined once per variant, with that
binary and the extra `roe refine` arguments ARGS (space-separated), e.g. --variant before=/tmp/roe-main
--variant white=build/roe:"--tau 0"; each variant gets its own columns and summary row. Without it the
one variant is "refined" = --roe. Each figure set also carries the worst-axis position RMSE of the
trajectory (`roe eval --json`).

usage: scripts/refine-table.py [--roe BUILD/roe] [--work DIR] [--seeds 1 2] [--presets P ...] [--json OUT]
                               [--variant LABEL=ROE[:ARGS] ...]
       scripts/refine-table.py --summary ROWS.json
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def sh(args, check=True):
    r = subprocess.run(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if check and r.returncode != 0:
        raise RuntimeError("%s: exit %d\n%s" % (" ".join(args), r.returncode, r.stderr[-2000:]))
    return r


def cpu_of(args):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    sh(args)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def truth_figures(roe, run_dir, symmetric):
    """Extrinsics and per-object figures from calib-check's truth checks (exit 1 is a verdict, not an error)."""
    j = json.loads(sh([roe, "calib-check", run_dir, "--json"], check=False).stdout)
    checks = {c["name"]: c for c in j["checks"]}
    e = checks["truth.extrinsics"]["values"]
    out = {"extr_mm": 1e3 * e["error_p_m"], "extr_deg": e["error_rot_deg"], "extr_nees": e.get("nees_diag")}
    objs = []
    for k, v in checks["truth.objects"]["values"].items():
        if k.startswith("object_") and k.endswith("_error_p_m"):  # calib-check's per-object keys
            oid = int(k.split("_")[1])
            if oid in symmetric:
                continue
            vals = checks["truth.objects"]["values"]
            objs.append({"id": oid, "mm": 1e3 * v, "deg": vals["object_%d_error_rot_deg" % oid],
                         "nees": vals.get("object_%d_nees" % oid)})
    out["objects"] = objs
    ev = run_dir + "-eval"
    sh([roe, "eval", run_dir, "--out", ev, "-q", "--force"], check=False)
    try:
        out["worst_axis_m"] = max(json.load(open(os.path.join(ev, "report.json")))["per_axis"]["pos_rmse_m"].values())
    except (OSError, ValueError, KeyError):
        out["worst_axis_m"] = None
    return out


def one(roe, work, preset, seed, variants):
    ds, run = ("%s/%s-%d%s" % (work, preset, seed, s) for s in ("", "-run"))
    if not os.path.isdir(ds):
        sh([roe, "simulate", "--preset", preset, "--seed", str(seed), "--out", ds, "-q"])
    if not os.path.isdir(run):
        sh([roe, "run", ds, "--out", run, "--force", "-q"], check=False)  # exit 1 = unhealthy: still compared
    man = json.load(open(os.path.join(ds, "roe.json")))
    symmetric = {o["id"] for o in man["objects"] if o.get("symmetric")}
    row = {"preset": preset, "seed": seed, "filter": truth_figures(roe, run, symmetric), "variants": {}}
    for label, (binary, args) in variants.items():
        ref = "%s-%s" % (run, label)
        cpu = cpu_of([binary, "refine", run, "--out", ref, "--force", "-q"] + args)
        refj = json.load(open(os.path.join(ref, "run.json")))
        f = truth_figures(binary, ref, symmetric)  # the variant's own reader of its run.json
        f["refine_cpu_s"] = cpu
        f["refine"] = refj["refine"]
        row["variants"][label] = f
    return row


def fmt_objs(objs):
    return "; ".join("%.0f mm %.1f° / %.0f" % (o["mm"], o["deg"], o["nees"] or float("nan")) for o in objs) or "–"


def fmt_extr(f):
    return "%.0f mm %.2f° / %.0f" % (f["extr_mm"], f["extr_deg"], f["extr_nees"] or float("nan"))


CHI2_6_99 = 16.812


def median(v):
    v = sorted(v)
    n = len(v)
    return float("nan") if n == 0 else (v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2]))


def figures(row, which):
    return row["filter"] if which == "filter" else row["variants"][which]


def summary_row(rows, which):
    sets = [figures(r, which) for r in rows if which == "filter" or which in r["variants"]]
    objs = [o for f in sets for o in f["objects"]]
    ok = [o for o in objs if o["nees"] is not None and o["nees"] <= CHI2_6_99]
    worst = max(objs, key=lambda o: o["mm"]) if objs else None
    within = [e for e in sets if e["extr_mm"] <= 20.0 and e["extr_deg"] <= 1.3]
    e_ok = [e for e in sets if e["extr_nees"] is not None and e["extr_nees"] <= CHI2_6_99]
    traj = [f["worst_axis_m"] for f in sets if f.get("worst_axis_m") is not None]
    return ("| %s | %.0f mm / %.1f° | %s | %d / %d | %.0f | %.0f mm / %.2f° | %d / %d | %d / %d | %.3f m |" % (
        which, median([o["mm"] for o in objs]), median([o["deg"] for o in objs]),
        "%.0f mm / %.1f°" % (worst["mm"], worst["deg"]) if worst else "–", len(ok), len(objs),
        median([o["nees"] for o in objs if o["nees"] is not None]), median([e["extr_mm"] for e in sets]),
        median([e["extr_deg"] for e in sets]), len(within), len(sets), len(e_ok), len(sets),
        sum(traj) / len(traj) if traj else float("nan")))


def print_summary(rows):
    print("| | objects: median error | worst (position) | NEES <= 16.8 | median NEES | extrinsics: median error | "
          "within 20 mm / 1.3° | NEES <= 16.8 | mean worst-axis position RMSE |")
    print("|---|---|---|---|---|---|---|---|---|")
    labels = ["filter"] + sorted({k for r in rows for k in r["variants"]})
    for which in labels:
        print(summary_row(rows, which))
    for label in labels[1:]:
        cpu = [r["variants"][label]["refine_cpu_s"] for r in rows if label in r["variants"]]
        models = [r["variants"][label]["refine"].get("detection_error_model", {}) for r in rows if label in r["variants"]]
        taus = [m["tau_s"] for m in models if "tau_s" in m and m.get("tau_s") is not None]
        print("%s: refine CPU median %.2f s (min %.2f, max %.2f)%s" % (
            label, median(cpu), min(cpu), max(cpu),
            ", tau median %.2f s (min %.2f, max %.2f)" % (median(taus), min(taus), max(taus)) if taus else ""))


def parse_variants(specs, roe):
    out = {}
    for spec in specs or ["refined=%s" % roe]:
        label, rest = spec.split("=", 1)
        binary, _, args = rest.partition(":")
        out[label] = (binary, args.split())
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roe", default=os.path.join(HERE, "build", "roe"))
    ap.add_argument("--work", default=None)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--presets", nargs="+", default=["paper-real-seq%d" % i for i in range(1, 9)])
    ap.add_argument("--variant", action="append", default=None, help="LABEL=ROE[:ARGS]")
    ap.add_argument("--json", default=None)
    ap.add_argument("--summary", default=None, help="print the summary of the rows of an earlier --json")
    a = ap.parse_args()
    if a.summary:
        print_summary(json.load(open(a.summary)))
        return
    variants = parse_variants(a.variant, a.roe)
    work = a.work or tempfile.mkdtemp(prefix="roe-refine-table-")
    os.makedirs(work, exist_ok=True)
    rows = []
    print("| preset | seed | objects vs anchor, filter: error / NEES | %s | extrinsics, filter: error / NEES | %s |" % (
        " | ".join(variants), " | ".join(variants)))
    print("|---|---|---|%s---|%s" % ("---|" * len(variants), "---|" * len(variants)))
    for p in a.presets:
        for s in a.seeds:
            try:
                r = one(a.roe, work, p, s, variants)
            except RuntimeError as e:
                print("| %s | %d | failed: %s |" % (p, s, str(e).splitlines()[0]))
                continue
            rows.append(r)
            v = [r["variants"][k] for k in variants]
            print("| %s | %d | %s | %s | %s | %s |" % (p, s, fmt_objs(r["filter"]["objects"]),
                  " | ".join(fmt_objs(f["objects"]) for f in v), fmt_extr(r["filter"]),
                  " | ".join(fmt_extr(f) for f in v)))
            sys.stdout.flush()
            if a.json:
                json.dump(rows, open(a.json, "w"), indent=1)
    print()
    print_summary(rows)


if __name__ == "__main__":
    main()
