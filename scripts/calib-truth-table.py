#!/usr/bin/env python3
"""Self-calibration against the truth on simulated presets (issue 35): per preset and seed, the
non-symmetric object-worlds relative to the anchor and the extrinsics, error and NEES, and the
trajectory accuracy; optionally the correlation of the simulated detection errors.

The truth comparison is calib-check's own (src/calib, `roe calib-check --json`, checks truth.objects
with its per-object values and truth.extrinsics): this script only runs the commands and tabulates.
The detection-error statistics (--detection-errors) are computed here from the dataset (detections
against the true T_C_O = (T_W_I T_I_C)^-1 T_W_O), because no roe command measures them.

  scripts/calib-truth-table.py --roe build/roe --presets paper-real-seq1,paper-real-seq3 --seeds 1-5 \
      --work /tmp/ct --config configs/default.json [--detection-errors] [--json out.json]

Standard library only (no numpy). Datasets and runs are kept under --work and reused when present
(--rerun re-runs `roe run`, e.g. after rebuilding roe).
"""
import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys

CHI2_6_99 = 16.811893829770927


def sh(cmd, check=True):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if check and p.returncode not in (0, 1):
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr.strip()[-2000:]}")
    return p


def seeds_of(text):
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


# --- quaternions [x, y, z, w] (Hamilton) -------------------------------------------------------
def qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return [aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz]


def qconj(q):
    return [-q[0], -q[1], -q[2], q[3]]


def qrot(q, v):
    return qmul(qmul(q, [v[0], v[1], v[2], 0.0]), qconj(q))[:3]


def qlog(q):
    if q[3] < 0:
        q = [-c for c in q]
    n = math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2)
    if n < 1e-12:
        return [2 * c for c in q[:3]]
    ang = 2 * math.atan2(n, q[3])
    return [ang * c / n for c in q[:3]]


def pose_inv(p, q):
    qi = qconj(q)
    t = qrot(qi, p)
    return [-t[0], -t[1], -t[2]], qi


def pose_mul(p1, q1, p2, q2):
    t = qrot(q1, p2)
    return [p1[i] + t[i] for i in range(3)], qmul(q1, q2)


def detection_error_stats(dataset, block_s=5.0):
    """Per object: error σ (camera frame, mm / deg), lag-1 correlation of consecutive detections and
    the variance inflation of a run mean, var(block means) · frames per block / var (1 = white)."""
    roe = json.load(open(os.path.join(dataset, "roe.json")))
    tic = roe["truth"]["T_I_C"]
    two = {o["id"]: (o["T_W_O"]["p"], o["T_W_O"]["q"]) for o in roe["truth"]["objects"]}
    gt = {}
    with open(os.path.join(dataset, "mav0/state_groundtruth_estimate0/data.csv")) as f:
        for row in csv.reader(f):
            if row[0].startswith("#"):
                continue
            v = [float(x) for x in row[1:8]]
            gt[int(row[0])] = (v[0:3], [v[4], v[5], v[6], v[3]])
    stamps = sorted(gt)
    import bisect
    det_dir = os.path.join(dataset, "detections", "sim")
    per = {}
    with open(os.path.join(det_dir, "detections.csv")) as f:
        for row in csv.DictReader(f):
            t = int(row["timestamp_ns"])
            k = bisect.bisect_left(stamps, t)
            if k >= len(stamps) or stamps[k] != t:
                k = min(max(k, 0), len(stamps) - 1)
            pwi, qwi = gt[stamps[k]]
            pwc, qwc = pose_mul(pwi, qwi, tic["p"], tic["q"])
            pcw, qcw = pose_inv(pwc, qwc)
            oid = int(row["object_id"])
            pco, qco = pose_mul(pcw, qcw, *two[oid])
            tm = [float(row["tx"]), float(row["ty"]), float(row["tz"])]
            qm = [float(row["qx"]), float(row["qy"]), float(row["qz"]), float(row["qw"])]
            e = [tm[i] - pco[i] for i in range(3)] + qlog(qmul(qm, qconj(qco)))
            per.setdefault(oid, []).append((t, e))
    out = {}
    for oid, rows in per.items():
        # Gross errors (outliers, blur, flips) are not the correlated part: keep |rot| < 30°, |t| < 0.5 m.
        rows = [(t, e) for t, e in rows if math.hypot(*e[3:]) < math.radians(30) and math.hypot(*e[:3]) < 0.5]
        if len(rows) < 50:
            continue
        res = {"n": len(rows)}
        for name, idx, scale in (("pos", range(3), 1e3), ("rot", range(3, 6), math.degrees(1))):
            rho, vif, sd = [], [], []
            for i in idx:
                x = [e[i] for _, e in rows]
                m = statistics.fmean(x)
                var = statistics.fmean([(a - m) ** 2 for a in x])
                sd.append(math.sqrt(var) * scale)
                rho.append(sum((x[j] - m) * (x[j + 1] - m) for j in range(len(x) - 1)) / (len(x) * var))
                blocks = {}
                for (t, e) in rows:
                    blocks.setdefault(int((t - rows[0][0]) * 1e-9 // block_s), []).append(e[i])
                means = [statistics.fmean(b) for b in blocks.values() if len(b) > 5]
                per_block = len(rows) / max(1, len(blocks))
                if len(means) > 2:
                    vif.append(statistics.pvariance(means) * per_block / var)
            res[name] = {"sigma": statistics.fmean(sd), "rho1": statistics.fmean(rho),
                         "inflation": statistics.fmean(vif) if vif else float("nan")}
        out[oid] = res
    return out


def check_values(cc, name):
    for c in cc["checks"]:
        if c["name"] == name:
            return c["status"], dict(c.get("values", {})) if isinstance(c.get("values"), dict) else {
                k: v for k, v in c.get("values", [])}
    return None, {}


def one(args, preset, seed):
    ds = os.path.join(args.work, f"{preset}-s{seed}")
    run = os.path.join(args.work, f"{preset}-s{seed}-run-{args.tag}")
    if not os.path.exists(os.path.join(ds, "roe.json")):
        sh([args.roe, "simulate", "--preset", preset, "--seed", str(seed), "--out", ds, "-q", "--force"])
    if args.rerun or not os.path.exists(os.path.join(run, "run.json")):
        cmd = [args.roe, "run", ds, "--out", run, "-q", "--force"]
        if args.config:
            cmd += ["--config", args.config]
        p = sh(cmd)
        if p.returncode != 0 and not os.path.exists(os.path.join(run, "run.json")):
            return {"preset": preset, "seed": seed, "failed": p.stderr.strip()[-300:]}
    cc = json.loads(sh([args.roe, "calib-check", run, "--json", "-q"]).stdout)
    ev = os.path.join(run, "eval")
    if not os.path.exists(os.path.join(ev, "report.json")):
        sh([args.roe, "eval", run, "--out", ev, "-q", "--force"])
    rep = json.load(open(os.path.join(ev, "report.json")))
    pa = rep["per_axis"]
    row = {"preset": preset, "seed": seed, "calib_check_exit": 1 if cc.get("passed") is False else 0,
           "verdicts": {c["name"]: c["status"] for c in cc["checks"]}}
    row["worst_pos_m"] = max(pa["pos_rmse_m"].values())
    row["worst_euler_deg"] = max(pa["rpy_rmse_deg"].values())
    _, ve = check_values(cc, "truth.extrinsics")
    row["extrinsics"] = {"err_mm": ve.get("error_p_m", float("nan")) * 1e3,
                         "err_deg": ve.get("error_rot_deg", float("nan")), "nees": ve.get("nees_diag", float("nan"))}
    _, vo = check_values(cc, "truth.objects")
    objs = {}
    for k, v in vo.items():
        if k.startswith("object_"):
            oid, _, field = k[len("object_"):].partition("_")
            objs.setdefault(int(oid), {})[field] = v
    marked = {o["id"] for o in json.load(open(os.path.join(ds, "roe.json")))["objects"] if o.get("symmetric")}
    row["objects"] = {oid: {"err_mm": o.get("error_p_m", float("nan")) * 1e3,
                            "err_deg": o.get("error_rot_deg", float("nan")), "nees": o.get("nees", float("nan")),
                            "symmetric": bool(o.get("symmetric", 0)) or oid in marked}
                      for oid, o in sorted(objs.items())}
    if args.detection_errors:
        row["detection_errors"] = detection_error_stats(ds)
    return row


def summary(rows):
    objs = [o for r in rows if "objects" in r for o in r["objects"].values() if not o["symmetric"]]
    ext = [r["extrinsics"] for r in rows if "extrinsics" in r]
    ok = [r for r in rows if "worst_pos_m" in r]
    if not objs or not ext:
        return {}
    return {
        "objects": len(objs),
        "obj_median_mm": statistics.median(o["err_mm"] for o in objs),
        "obj_median_deg": statistics.median(o["err_deg"] for o in objs),
        "obj_max_mm": max(o["err_mm"] for o in objs),
        "obj_max_deg": max(o["err_deg"] for o in objs),
        "obj_nees_ok": sum(o["nees"] <= CHI2_6_99 for o in objs) / len(objs),
        "runs": len(ext),
        "ext_within_15mm_1deg": sum(e["err_mm"] <= 15 and e["err_deg"] <= 1 for e in ext) / len(ext),
        "ext_median_mm": statistics.median(e["err_mm"] for e in ext),
        "ext_median_deg": statistics.median(e["err_deg"] for e in ext),
        "ext_nees_ok": sum(e["nees"] <= CHI2_6_99 for e in ext) / len(ext),
        "mean_worst_pos_m": statistics.fmean(r["worst_pos_m"] for r in ok),
        "mean_worst_euler_deg": statistics.fmean(r["worst_euler_deg"] for r in ok),
        "calib_check_exit1": sum(r.get("calib_check_exit", 0) for r in rows),
    }


def fmt_row(r):
    if "failed" in r:
        return f"| {r['preset']} | {r['seed']} | run failed: {r['failed']} | | | |"
    objs = "; ".join(f"{oid}{'*' if o['symmetric'] else ''}: {o['err_mm']:.0f} mm {o['err_deg']:.1f}° / {o['nees']:.0f}"
                     for oid, o in r["objects"].items())
    e = r["extrinsics"]
    return (f"| {r['preset']} | {r['seed']} | {objs} | {e['err_mm']:.0f} mm {e['err_deg']:.2f}° / {e['nees']:.1f} | "
            f"{r['worst_pos_m']:.3f} m / {r['worst_euler_deg']:.2f}° | {'fail' if r['calib_check_exit'] else 'ok'} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--roe", default="build/roe")
    ap.add_argument("--presets", default=",".join(f"paper-real-seq{i}" for i in range(1, 9)))
    ap.add_argument("--seeds", default="1")
    ap.add_argument("--config", default="")
    ap.add_argument("--tag", default="default", help="names the run folders, so configs do not overwrite each other")
    ap.add_argument("--work", required=True)
    ap.add_argument("--rerun", action="store_true")
    ap.add_argument("--detection-errors", action="store_true")
    ap.add_argument("--json", default="")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    rows = []
    print("| preset | seed | objects rel. anchor (* symmetric): error / NEES | extrinsics: error / NEES | "
          "worst axis pos / Euler | calib-check |")
    print("|---|---|---|---|---|---|")
    for preset in args.presets.split(","):
        for seed in seeds_of(args.seeds):
            r = one(args, preset, seed)
            rows.append(r)
            print(fmt_row(r), flush=True)
            if "detection_errors" in r:
                for oid, d in r["detection_errors"].items():
                    print(f"|  | | detections of {oid}: n {d['n']}, pos σ {d['pos']['sigma']:.0f} mm ρ1 "
                          f"{d['pos']['rho1']:.3f} inflation {d['pos']['inflation']:.0f}; rot σ {d['rot']['sigma']:.1f}° "
                          f"ρ1 {d['rot']['rho1']:.3f} inflation {d['rot']['inflation']:.0f} | | | |", flush=True)
    s = summary(rows)
    print(json.dumps(s, indent=1))
    if args.json:
        json.dump({"rows": rows, "summary": s}, open(args.json, "w"), indent=1)


if __name__ == "__main__":
    main()
