#!/usr/bin/env python3
"""The camera-IMU time offset, simulated and estimated online (issue 49): per sequence, seed and true offset,
`roe simulate --time-offset` (declared 0), then `roe run` three ways: `estimated` (the config with
filter.estimate_time_offset true), `ignored` (the config as given, the offset untold) and `told` (the config as
given on a copy of the dataset whose roe.json declares the true offset), then `roe eval` and
`roe calib-check --json`. Tabulates the final t_d ± σ against the truth, the worst-axis trajectory RMSE, the
extrinsics error/NEES (calib-check's truth.extrinsics) and calib-check's verdicts.

  scripts/time-offset-table.py --roe build/roe --work /tmp/to --config configs/default.json \\
      --sequences paper-real-seq1,paper-real-seq4 --seeds 1-5 --offsets 0.015 [--json out.json]
  scripts/time-offset-table.py ... --from-groundtruth /tmp/tumvi/room1 --offsets 0.010

Standard library only. Datasets and runs are kept under --work and reused when present.
"""
import argparse
import importlib.util
import json
import math
import os
import shutil
import statistics



# sh() and seeds_of() are calib-truth-table.py's (one definition).
_spec = importlib.util.spec_from_file_location("calib_truth_table",
                                               os.path.join(os.path.dirname(os.path.abspath(__file__)),
                                                            "calib-truth-table.py"))
_ctt = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_ctt)
sh, seeds_of = _ctt.sh, _ctt.seeds_of


def check(cc, name):
    for c in cc["checks"]:
        if c["name"] == name:
            v = c.get("values", {})
            return c["status"], (v if isinstance(v, dict) else {k: x for k, x in v})
    return None, {}


def configs(args):
    """{variant: config path}: the given config with estimate_time_offset on and off."""
    base = json.load(open(args.config))
    out = {}
    for variant, on in (("estimated", True), ("ignored", False)):
        c = json.loads(json.dumps(base))
        c["filter"]["estimate_time_offset"] = on
        path = os.path.join(args.work, f"config-{variant}-{args.tag}.json")
        with open(path, "w") as f:
            json.dump(c, f, indent=2)
        out[variant] = path
    out["told"] = out["ignored"]
    return out


def dataset(args, seq, seed, offset):
    ds = os.path.join(args.work, f"{os.path.basename(seq)}-s{seed}-td{offset * 1e3:+.0f}ms")
    if not os.path.exists(os.path.join(ds, "roe.json")):
        src = ["--from-groundtruth", seq] if args.from_groundtruth else ["--preset", seq]
        sh([args.roe, "simulate", *src, "--seed", str(seed), "--time-offset", repr(offset), "--out", ds, "-q",
            "--force"])
    told = ds + "-told"
    if not os.path.exists(os.path.join(told, "roe.json")):
        shutil.copytree(ds, told, dirs_exist_ok=True)
        m = json.load(open(os.path.join(told, "roe.json")))
        m["camera"]["time_offset_s"] = offset
        with open(os.path.join(told, "roe.json"), "w") as f:
            json.dump(m, f, indent=2)
    return ds, told


def one(args, cfgs, seq, seed, offset):
    ds, told = dataset(args, seq, seed, offset)
    row = {"sequence": os.path.basename(seq), "seed": seed, "true_offset_s": offset}
    for variant, cfg in cfgs.items():
        d = told if variant == "told" else ds
        run = f"{ds}-run-{variant}-{args.tag}"
        if not os.path.exists(os.path.join(run, "run.json")):
            sh([args.roe, "run", d, "--out", run, "--config", cfg, "-q", "--force"])
        if not os.path.exists(os.path.join(run, "run.json")):
            row[variant] = {"failed": True}
            continue
        rj = json.load(open(os.path.join(run, "run.json")))
        ev = os.path.join(run, "eval")
        if not os.path.exists(os.path.join(ev, "report.json")):
            sh([args.roe, "eval", run, "--out", ev, "-q", "--force"])
        rep = json.load(open(os.path.join(ev, "report.json")))
        cc = json.loads(sh([args.roe, "calib-check", run, "--dataset", d, "--json", "-q"]).stdout)
        _, ve = check(cc, "truth.extrinsics")
        to_status, to_values = check(cc, "camera.time_offset")
        t = rj["final"].get("time_offset", {})
        r = {"worst_pos_m": max(rep["per_axis"]["pos_rmse_m"].values()),
             "worst_euler_deg": max(rep["per_axis"]["rpy_rmse_deg"].values()),
             "td_s": t.get("value_s"), "td_sigma_s": t.get("sigma_s"),
             "ext_err_mm": ve.get("error_p_m", math.nan) * 1e3, "ext_err_deg": ve.get("error_rot_deg", math.nan),
             "ext_nees": ve.get("nees_diag", math.nan), "time_offset_verdict": to_status,
             "verdicts": {c["name"]: c["status"] for c in cc["checks"]}}
        row[variant] = r
    return row


def summarise(rows):
    s = {}
    for variant in ("estimated", "ignored", "told"):
        rs = [r[variant] for r in rows if variant in r and "failed" not in r[variant]]
        if not rs:
            continue
        s[variant] = {"runs": len(rs), "mean_worst_pos_m": statistics.fmean(r["worst_pos_m"] for r in rs),
                      "mean_worst_euler_deg": statistics.fmean(r["worst_euler_deg"] for r in rs),
                      "ext_median_mm": statistics.median(r["ext_err_mm"] for r in rs),
                      "ext_median_deg": statistics.median(r["ext_err_deg"] for r in rs),
                      "ext_nees_ok": sum(r["ext_nees"] <= _ctt.CHI2_6_99 for r in rs) / len(rs)}
    est = [(r["true_offset_s"], r["estimated"]) for r in rows if "estimated" in r and "failed" not in r["estimated"]]
    if est:
        errs = [abs(e["td_s"] - t) for t, e in est]
        s["estimated"].update({"td_max_abs_err_ms": max(errs) * 1e3,
                               "td_within_3ms": sum(x <= 0.003 for x in errs) / len(errs),
                               "td_within_max_1ms_3sigma": sum(abs(e["td_s"] - t) <= max(0.001, 3 * e["td_sigma_s"])
                                                               for t, e in est) / len(est),
                               "td_mean_nees": statistics.fmean((e["td_s"] - t) ** 2 / e["td_sigma_s"] ** 2
                                                                for t, e in est)})
    return s


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--roe", default="build/roe")
    ap.add_argument("--work", required=True)
    ap.add_argument("--config", default="configs/default.json")
    ap.add_argument("--tag", default="a")
    ap.add_argument("--sequences", help="presets, comma-separated")
    ap.add_argument("--from-groundtruth", help="a mav0 parent folder for roe simulate --from-groundtruth")
    ap.add_argument("--seeds", default="1-5")
    ap.add_argument("--offsets", default="0.015", help="true offsets in s, comma-separated")
    ap.add_argument("--json")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    cfgs = configs(args)
    seqs = [args.from_groundtruth] if args.from_groundtruth else args.sequences.split(",")
    rows = []
    for seq in seqs:
        for seed in seeds_of(args.seeds):
            for off in [float(v) for v in args.offsets.split(",")]:
                r = one(args, cfgs, seq, seed, off)
                rows.append(r)
                e, i, t = r.get("estimated", {}), r.get("ignored", {}), r.get("told", {})
                print(f"{r['sequence']} s{seed} td {off * 1e3:+.0f} ms: est {e.get('td_s', math.nan) * 1e3:+.2f} ± "
                      f"{e.get('td_sigma_s', math.nan) * 1e3:.2f} ms | worst pos est/ign/told "
                      f"{e.get('worst_pos_m', math.nan):.3f}/{i.get('worst_pos_m', math.nan):.3f}/"
                      f"{t.get('worst_pos_m', math.nan):.3f} m | ext est {e.get('ext_err_mm', math.nan):.1f} mm "
                      f"NEES {e.get('ext_nees', math.nan):.1f}, ign {i.get('ext_err_mm', math.nan):.1f} mm NEES "
                      f"{i.get('ext_nees', math.nan):.1f} | time_offset verdict {e.get('time_offset_verdict')}",
                      flush=True)
    s = summarise(rows)
    print(json.dumps(s, indent=2))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rows": rows, "summary": s}, f, indent=2)


if __name__ == "__main__":
    main()
