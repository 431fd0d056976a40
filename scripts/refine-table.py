#!/usr/bin/env python3
"""The measurements of docs/refine.md §4: filter/smoother vs `roe refine` on simulated presets.

For each preset and seed: roe simulate, roe run (default config), roe refine; then `roe calib-check --json`
on both run folders, whose truth checks (truth.extrinsics, truth.objects: src/calib/calib_check.cpp) give the
figures — the extrinsics' error and per-axis NEES, and each object's error relative to the anchor and its
per-axis NEES — so this script computes no error of its own. Symmetric objects (roe.json) are left out of
the object columns, as in issue 35's table. Also records refine's CPU time (user + sys of the process).

usage: scripts/refine-table.py [--roe BUILD/roe] [--work DIR] [--seeds 1 2] [--presets P ...] [--json OUT]
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
    return out


def one(roe, work, preset, seed):
    ds, run, ref = ("%s/%s-%d%s" % (work, preset, seed, s) for s in ("", "-run", "-ref"))
    if not os.path.isdir(ds):
        sh([roe, "simulate", "--preset", preset, "--seed", str(seed), "--out", ds, "-q"])
    sh([roe, "run", ds, "--out", run, "--force", "-q"], check=False)  # exit 1 = unhealthy: still compared
    cpu = cpu_of([roe, "refine", run, "--out", ref, "--force", "-q"])
    man = json.load(open(os.path.join(ds, "roe.json")))
    symmetric = {o["id"] for o in man["objects"] if o.get("symmetric")}
    refj = json.load(open(os.path.join(ref, "run.json")))
    return {"preset": preset, "seed": seed, "refine_cpu_s": cpu, "refine": refj["refine"],
            "filter": truth_figures(roe, run, symmetric), "refined": truth_figures(roe, ref, symmetric)}


def fmt_objs(objs):
    return "; ".join("%.0f mm %.1f° / %.0f" % (o["mm"], o["deg"], o["nees"] or float("nan")) for o in objs) or "–"


def fmt_extr(f):
    return "%.0f mm %.2f° / %.0f" % (f["extr_mm"], f["extr_deg"], f["extr_nees"] or float("nan"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--roe", default=os.path.join(HERE, "build", "roe"))
    ap.add_argument("--work", default=None)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--presets", nargs="+", default=["paper-real-seq%d" % i for i in range(1, 9)])
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    work = a.work or tempfile.mkdtemp(prefix="roe-refine-table-")
    os.makedirs(work, exist_ok=True)
    rows = []
    print("| preset | seed | objects vs anchor, filter: error / NEES | refined | extrinsics, filter: error / NEES | refined | refine CPU s |")
    print("|---|---|---|---|---|---|---|")
    for p in a.presets:
        for s in a.seeds:
            try:
                r = one(a.roe, work, p, s)
            except RuntimeError as e:
                print("| %s | %d | failed: %s |" % (p, s, str(e).splitlines()[0]))
                continue
            rows.append(r)
            print("| %s | %d | %s | %s | %s | %s | %.2f |" % (p, s, fmt_objs(r["filter"]["objects"]),
                  fmt_objs(r["refined"]["objects"]), fmt_extr(r["filter"]), fmt_extr(r["refined"]), r["refine_cpu_s"]))
            sys.stdout.flush()
    if a.json:
        json.dump(rows, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
