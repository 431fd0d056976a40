#!/usr/bin/python3
"""Plots of a `roe eval` output folder (run with Debian's /usr/bin/python3 + python3-matplotlib).

    /usr/bin/python3 scripts/plot_eval.py EVAL_DIR [--out PLOTS_DIR] [--format png|pdf]

Reads est_matched_aligned.csv, gt_matched.csv, errors.csv and, when present,
reprojection_aligned.csv (per-object IMU poses implied by each raw detection, already aligned), and
writes into EVAL_DIR/plots (or --out):
  trajectory_top.png  top view (x-y) of ground truth, aligned estimate and per-object reprojections
  xyz.png             x, y, z over time: ground truth, estimate, per-object traces (paper Fig. 3)
  rpy.png             roll, pitch, yaw (ZYX, deg) over time, same curves (unwrapped: continuous
                      across +-180 deg, every curve on the ground truth's branch)
  errors.png          position error per axis and norm, rotation error per axis (R_est^T R_gt) over time
  rpe.png             only when rpe.csv is there (roe eval --rpe-delta): relative pose error per
                      delta, translation and rotation, as box plots (evo_res style) and over time
Exit code 0 on success, 2 on bad input, 3 when matplotlib is missing.
"""
import argparse
import csv
import math
import os
import sys

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:  # pragma: no cover
    sys.stderr.write("plot_eval.py: matplotlib is not installed (Debian: apt install python3-matplotlib)\n")
    sys.exit(3)


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise ValueError(f"{path}: empty file")
    header = [h.strip().lstrip("#") for h in rows[0]]
    cols = {h: [] for h in header}
    for line_no, r in enumerate(rows[1:], start=2):
        if len(r) != len(header):
            raise ValueError(f"{path}:{line_no}: expected {len(header)} fields, found {len(r)}")
        for h, v in zip(header, r):
            cols[h].append(v)
    return cols


def floats(col):
    out = []
    for v in col:
        try:
            out.append(float(v))
        except ValueError:
            out.append(float("nan"))
    return out


def euler_zyx_deg(qx, qy, qz, qw):
    """roll, pitch, yaw (deg) of R = Rz(yaw) Ry(pitch) Rx(roll) for a Hamilton quaternion."""
    r, p, y = [], [], []
    for x, yy, z, w in zip(qx, qy, qz, qw):
        n = math.sqrt(x * x + yy * yy + z * z + w * w) or 1.0
        x, yy, z, w = x / n, yy / n, z / n, w / n
        r20 = 2 * (x * z - w * yy)
        r21 = 2 * (yy * z + w * x)
        r22 = 1 - 2 * (x * x + yy * yy)
        r10 = 2 * (x * yy + w * z)
        r00 = 1 - 2 * (yy * yy + z * z)
        r.append(math.degrees(math.atan2(r21, r22)))
        p.append(math.degrees(math.asin(max(-1.0, min(1.0, -r20)))))
        y.append(math.degrees(math.atan2(r10, r00)))
    return r, p, y


def wrap180(a):
    return (a + 180.0) % 360.0 - 180.0


def unwrap_deg(v):
    """Continuous angle (deg): removes the +-360 jumps of a wrapped series."""
    out = []
    for i, a in enumerate(v):
        out.append(a if i == 0 else out[-1] + wrap180(a - v[i - 1]))
    return out


def near_reference(t, v, t_ref, v_ref):
    """Shifts each angle by a multiple of 360 deg to lie within +-180 deg of the (unwrapped)
    reference curve at the same time, so all curves share one continuous branch."""
    import bisect
    out = []
    for ti, vi in zip(t, v):
        j = min(max(bisect.bisect_left(t_ref, ti), 0), len(t_ref) - 1)
        r = v_ref[j]
        out.append(r + wrap180(vi - r))
    return out


def traj(cols, t_key="t"):
    t = floats(cols[t_key])
    x, y, z = floats(cols["tx"]), floats(cols["ty"]), floats(cols["tz"])
    roll, pitch, yaw = euler_zyx_deg(floats(cols["qx"]), floats(cols["qy"]), floats(cols["qz"]), floats(cols["qw"]))
    return {"t": t, "x": x, "y": y, "z": z, "roll": roll, "pitch": pitch, "yaw": yaw}


def plot_rpe(rpe, rpe_sum, rel, path):
    """Relative pose error per delta: box plots of translation and rotation (one box per delta, as
    evo_res draws them) and both over time (at the pair's first stamp). A delta listed in
    rpe_summary.csv without pairs gets an empty slot labelled 'no pairs'. Returns False when no delta
    has a pair."""
    blocks = {}
    for i, (delta, unit) in enumerate(zip(rpe["delta"], rpe["unit"])):
        b = blocks.setdefault((float(delta), unit), {"t": [], "trans": [], "rot": []})
        b["t"].append(float(rpe["t_i"][i]))
        b["trans"].append(float(rpe["trans_m"][i]))
        b["rot"].append(float(rpe["rot_deg"][i]))
    if not blocks:
        return False
    if rpe_sum is not None:
        for delta, unit in zip(rpe_sum["delta"], rpe_sum["unit"]):
            blocks.setdefault((float(delta), unit), {"t": [], "trans": [], "rot": []})
    keys = sorted(blocks)
    labels = [f"{d:g} {u}" + ("" if blocks[(d, u)]["t"] else "\n(no pairs)") for d, u in keys]
    fig, axs = plt.subplots(2, 2, figsize=(10, 7), gridspec_kw={"height_ratios": [1, 1]})
    for col, (k, unit) in enumerate((("trans", "m"), ("rot", "deg"))):
        ax = axs[0][col]
        ax.boxplot([blocks[key][k] or [float("nan")] for key in keys], labels=labels, showfliers=True,
                   flierprops={"markersize": 3})
        ax.set_ylabel(f"RPE {'translation' if k == 'trans' else 'rotation'} [{unit}]")
        ax.set_xlabel("delta")
        ax.grid(True, axis="y", alpha=0.3)
        ax = axs[1][col]
        for key, lab in zip(keys, labels):
            if not blocks[key]["t"]:
                continue
            ax.plot(rel(blocks[key]["t"]), blocks[key][k], lw=1.0, marker=".", markersize=3, label=lab)
        ax.set_ylabel(f"RPE {'translation' if k == 'trans' else 'rotation'} [{unit}]")
        ax.set_xlabel("time of the pair's first pose [s]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    fig.suptitle("Relative pose error (|trans(E)|, angle(rot(E)); E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j))", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=150)
    plt.close(fig)
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("eval_dir")
    ap.add_argument("--out", default=None)
    ap.add_argument("--format", default="png", choices=["png", "pdf", "svg"])
    a = ap.parse_args()
    d = a.eval_dir
    out = a.out or os.path.join(d, "plots")
    try:
        est = traj(read_csv(os.path.join(d, "est_matched_aligned.csv")))
        gt = traj(read_csv(os.path.join(d, "gt_matched.csv")))
        err = read_csv(os.path.join(d, "errors.csv"))
        rep_path = os.path.join(d, "reprojection_aligned.csv")
        rep = read_csv(rep_path) if os.path.exists(rep_path) else None
        rpe_path = os.path.join(d, "rpe.csv")
        rpe = read_csv(rpe_path) if os.path.exists(rpe_path) else None
        rpe_sum_path = os.path.join(d, "rpe_summary.csv")
        rpe_sum = read_csv(rpe_sum_path) if os.path.exists(rpe_sum_path) else None
    except (OSError, ValueError, KeyError) as e:
        sys.stderr.write(f"plot_eval.py: {e}\n")
        return 2
    os.makedirs(out, exist_ok=True)
    t0 = gt["t"][0] if gt["t"] else 0.0
    rel = lambda ts: [t - t0 for t in ts]  # noqa: E731

    objects = {}
    if rep is not None:
        ids = rep["object_id"]
        t_rep = [int(v) * 1e-9 for v in rep["timestamp_ns"]]
        tr = {"t": t_rep, "x": floats(rep["tx"]), "y": floats(rep["ty"]), "z": floats(rep["tz"])}
        tr["roll"], tr["pitch"], tr["yaw"] = euler_zyx_deg(floats(rep["qx"]), floats(rep["qy"]), floats(rep["qz"]),
                                                           floats(rep["qw"]))
        for i, oid in enumerate(ids):
            if math.isnan(tr["x"][i]):
                continue
            o = objects.setdefault(oid, {k: [] for k in tr} | {"status": []})
            for k in tr:
                o[k].append(tr[k][i])
            o["status"].append(rep["status"][i])
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    obj_color = {oid: colors[(2 + i) % len(colors)] for i, oid in enumerate(sorted(objects, key=lambda s: int(s)))}

    # Top view.
    fig, ax = plt.subplots(figsize=(6.5, 6))
    for oid, o in sorted(objects.items(), key=lambda kv: int(kv[0])):
        ax.scatter(o["x"], o["y"], s=4, alpha=0.35, color=obj_color[oid], label=f"obj {oid}")
    ax.plot(gt["x"], gt["y"], color="k", lw=1.2, label="ground truth")
    ax.plot(est["x"], est["y"], color=colors[0], lw=1.0, label="estimate (aligned)")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title("Top view")
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"trajectory_top.{a.format}"), dpi=150)
    plt.close(fig)

    # x, y, z and roll, pitch, yaw over time (paper Fig. 3 layout).
    for name, keys, unit in (("xyz", ("x", "y", "z"), "m"), ("rpy", ("roll", "pitch", "yaw"), "deg")):
        fig, axs = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
        for ax, k in zip(axs, keys):
            if unit == "deg":
                g = unwrap_deg(gt[k])
                # Start the ground truth's continuous branch in [-180, 180).
                g = [a - 360.0 * math.floor((g[0] + 180.0) / 360.0) for a in g] if g else g
                for oid, o in sorted(objects.items(), key=lambda kv: int(kv[0])):
                    ax.scatter(rel(o["t"]), near_reference(o["t"], o[k], gt["t"], g), s=3, alpha=0.35,
                               color=obj_color[oid], label=f"obj {oid}")
                ax.plot(rel(gt["t"]), g, color="k", lw=1.2, label="ground truth")
                ax.plot(rel(est["t"]), near_reference(est["t"], est[k], gt["t"], g), color=colors[0], lw=1.0,
                        label="estimate")
            else:
                for oid, o in sorted(objects.items(), key=lambda kv: int(kv[0])):
                    ax.scatter(rel(o["t"]), o[k], s=3, alpha=0.35, color=obj_color[oid], label=f"obj {oid}")
                ax.plot(rel(gt["t"]), gt[k], color="k", lw=1.2, label="ground truth")
                ax.plot(rel(est["t"]), est[k], color=colors[0], lw=1.0, label="estimate")
            ax.set_ylabel(f"{k} [{unit}]")
            ax.grid(True, alpha=0.3)
        axs[0].legend(loc="upper right", fontsize=8, ncol=3)
        axs[-1].set_xlabel("time [s]")
        fig.tight_layout()
        fig.savefig(os.path.join(out, f"{name}.{a.format}"), dpi=150)
        plt.close(fig)

    # Errors over time.
    te = rel(floats(err["t_gt"]))
    fig, axs = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for k, lab in (("ex_m", "x"), ("ey_m", "y"), ("ez_m", "z"), ("e_norm_m", "|e|")):
        axs[0].plot(te, floats(err[k]), lw=1.0 if k != "e_norm_m" else 1.4, color="k" if k == "e_norm_m" else None,
                    label=lab)
    axs[0].set_ylabel("position error [m]\n(p_est - p_gt)")
    for k, lab in (("roll_deg", "roll"), ("pitch_deg", "pitch"), ("yaw_deg", "yaw"), ("angle_deg", "angle")):
        axs[1].plot(te, floats(err[k]), lw=1.0 if k != "angle_deg" else 1.4, color="k" if k == "angle_deg" else None,
                    label=lab)
    axs[1].set_ylabel("rotation error [deg]\n(R_est^T R_gt, ZYX)")
    axs[1].set_xlabel("time [s]")
    for ax in axs:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=4)
    fig.tight_layout()
    fig.savefig(os.path.join(out, f"errors.{a.format}"), dpi=150)
    plt.close(fig)
    written = ["trajectory_top", "xyz", "rpy", "errors"]
    if rpe is not None and plot_rpe(rpe, rpe_sum, rel, os.path.join(out, f"rpe.{a.format}")):
        written.append("rpe")
    print(f"wrote {out}: {', '.join(written)} (.{a.format})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
