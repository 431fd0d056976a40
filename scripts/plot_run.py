#!/usr/bin/python3
"""Figures of one roe run for a paper (run with Debian's /usr/bin/python3 + python3-matplotlib + numpy).

    /usr/bin/python3 scripts/plot_run.py --eval EVAL_DIR [--run RUN_DIR] [--dataset DATASET] --out DIR
        [--objects anchor|all|ID[,ID...]] [--plot-mode xy|xz|yz|xyz] [--color-by-error]
        [--vector pdf|svg|none] [--dpi N]

Reads the output folder of `roe eval` (est_matched_aligned.csv, gt_matched.csv, errors.csv, report.json,
reprojection_aligned.csv, rpe.csv), the run folder (states.csv, objects.csv, run.json) and the dataset's
roe.json (the truth of a simulation), and writes into DIR, each as PNG and as PDF or SVG:
  fig3          the paper's Fig. 3: x, y, z and roll, pitch, yaw over time, estimate vs ground truth, with
                the IMU pose reprojected from the raw detections of the chosen objects (used and rejected
                marked apart; points beyond the estimate's range drawn at the axis edge as triangles)
  fig4_obj<ID>  the paper's Fig. 4 for each non-anchor object: its pose relative to the anchor T_A_O over
                time from first sight, +-sigma bands, the truth when the dataset has it
  extrinsics    T_I_C over time: p_I_C and the rotation away from the prior, +-sigma, prior and truth
  consistency   NEES of the IMU position and orientation (after the alignment) and NIS per detection,
                with their chi-square bounds
  trajectory    the trajectory in a plane or in 3-D, optionally coloured by the position error
  errors        position and rotation errors over time
  rpe           relative pose error per delta (only when rpe.csv is there)
and figures.json: what was drawn (name, title, caption, files) and what was skipped, and why.
Exit code 0 on success, 2 on bad input, 3 when matplotlib or numpy is missing.
Euler angles: ZYX, R = Rz(yaw) Ry(pitch) Rx(roll), wrapped to [-180, 180); lines break at wrap and
gimbal-lock jumps instead of drawing them.
"""
import argparse
import csv
import json
import math
import os
import sys

try:
    import numpy as np
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
except ImportError as e:  # pragma: no cover
    sys.stderr.write(f"plot_run.py: {e} (Debian: apt install python3-matplotlib python3-numpy)\n")
    sys.exit(3)

# ---------------------------------------------------------------------------------------------- style
plt.rcParams.update({
    "font.size": 9, "axes.titlesize": 9, "axes.labelsize": 9, "legend.fontsize": 7.5,
    "xtick.labelsize": 8, "ytick.labelsize": 8, "axes.grid": True, "grid.alpha": 0.3,
    "lines.linewidth": 1.1, "figure.dpi": 100, "savefig.dpi": 130, "pdf.fonttype": 42,
    "svg.fonttype": "none", "path.simplify": True, "agg.path.chunksize": 20000,
})
C_EST, C_GT, C_PRIOR = "#1f77b4", "#000000", "#7f7f7f"
# Objects: one colour each, the same in every figure (tab10 without the estimate's blue, and grey).
OBJ_PALETTE = ["#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf"]
USED = ("accepted", "initialized")
SCREEN_BINS = 1600  # lines are decimated to min/max per bin: about one bin per pixel column


class BadInput(Exception):
    pass


# ------------------------------------------------------------------------------------------------ I/O
def read_table(path, required=True):
    """CSV with a header -> {column: np.array (float) or list (str)}; None when absent and optional."""
    if not os.path.exists(path):
        if required:
            raise BadInput(f"{path}: not found")
        return None
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        raise BadInput(f"{path}: empty file")
    header = [h.strip().lstrip("#").strip() for h in rows[0]]
    body = rows[1:]
    for n, r in enumerate(body, start=2):
        if len(r) != len(header):
            raise BadInput(f"{path}:{n}: expected {len(header)} fields, found {len(r)}")
    out = {}
    for j, h in enumerate(header):
        col = [r[j] for r in body]
        try:
            out[h] = np.array([float(v) if v != "" else math.nan for v in col], dtype=float)
        except ValueError:
            out[h] = col
    out["_n"] = len(body)
    out["_path"] = path
    return out


def need(table, *cols):
    for c in cols:
        if c not in table:
            raise BadInput(f"{table['_path']}: no column '{c}'")
    return [table[c] for c in cols]


def read_json(path, required=True):
    if not os.path.exists(path):
        if required:
            raise BadInput(f"{path}: not found")
        return None
    try:
        with open(path) as f:
            return json.load(f)
    except json.JSONDecodeError as e:
        raise BadInput(f"{path}:{e.lineno}:{e.colno}: {e.msg}")


# ----------------------------------------------------------------------------------------------- math
def quat_to_R(q):
    """(N,4) x,y,z,w Hamilton -> (N,3,3)."""
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    R = np.empty((len(q), 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z); R[:, 0, 1] = 2 * (x * y - w * z); R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z); R[:, 1, 1] = 1 - 2 * (x * x + z * z); R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y); R[:, 2, 1] = 2 * (y * z + w * x); R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def pose_q(p, q):
    return np.asarray(p, dtype=float).reshape(1, 3), quat_to_R(np.asarray(q, dtype=float).reshape(1, 4))


def euler_deg(R):
    """ZYX: roll, pitch, yaw (deg) of R = Rz(yaw) Ry(pitch) Rx(roll), each in [-180, 180)."""
    roll = np.degrees(np.arctan2(R[:, 2, 1], R[:, 2, 2]))
    pitch = np.degrees(np.arcsin(np.clip(-R[:, 2, 0], -1.0, 1.0)))
    yaw = np.degrees(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
    return np.stack([roll, pitch, yaw], axis=1)


def log_so3_deg(R):
    """Rotation vector (deg) of each R."""
    c = np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1.0, 1.0)
    th = np.arccos(c)
    v = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    s = np.sin(th)
    f = np.where(s > 1e-9, th / (2 * np.where(s > 1e-9, s, 1.0)), 0.5)
    return np.degrees(v * f[:, None])


def wrap180(a):
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


def chi2_cdf(x, k):
    """P(X <= x) for X ~ chi-square with integer k dof (closed forms; no scipy needed)."""
    if x <= 0:
        return 0.0
    if k % 2 == 0:
        term, s = 1.0, 1.0
        for i in range(1, k // 2):
            term *= (x / 2) / i
            s += term
        return 1.0 - math.exp(-x / 2) * s
    s, term = 0.0, math.sqrt(x / 2)
    for i in range(1, (k - 1) // 2 + 1):
        term_i = math.exp(-x / 2) * (x / 2) ** (i - 0.5) / math.gamma(i + 0.5)
        s += term_i
    return math.erf(math.sqrt(x / 2)) - s


def chi2_ppf(p, k):
    lo, hi = 0.0, max(10.0, 10.0 * k)
    while chi2_cdf(hi, k) < p:
        hi *= 2
    for _ in range(100):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if chi2_cdf(mid, k) < p else (lo, mid)
    return (lo + hi) / 2


# ------------------------------------------------------------------------------------------- drawing
def decimate(t, ys):
    """Indices keeping each series' min and max per screen bin (a line drawn from them looks the same)."""
    n = len(t)
    if n <= 4 * SCREEN_BINS:
        return np.arange(n)
    span = (t[-1] - t[0]) or 1.0
    bins = np.minimum(((t - t[0]) / span * SCREEN_BINS).astype(int), SCREEN_BINS - 1)
    keep = [np.array([0, n - 1])]
    starts = np.flatnonzero(np.r_[True, bins[1:] != bins[:-1]])
    for y in ys:
        yy = np.where(np.isnan(y), np.inf, y)
        order = np.lexsort((yy, bins))
        ends = np.r_[starts[1:], n] - 1
        keep.append(order[starts])
        keep.append(order[ends])
    return np.unique(np.concatenate(keep))


def broken(t, y, jump):
    """t, y with NaN inserted where |dy| > jump (a wrap or gimbal-lock jump is not drawn as a line)."""
    if len(y) < 2:
        return t, y
    cut = np.flatnonzero(np.abs(np.diff(y)) > jump) + 1
    return np.insert(t, cut, np.nan), np.insert(y, cut, np.nan)


def line(ax, t, y, angle=False, **kw):
    i = decimate(t, [y])
    tt, yy = t[i], y[i]
    if angle:
        tt, yy = broken(tt, yy, 90.0)
    return ax.plot(tt, yy, **kw)


def wrap_window(a):
    """Angles (deg) wrapped into [L, L + 360) with L in -180, -90, 0, 90: the window in which the series
    wraps least often (an orbit hovering around yaw 180 deg is drawn in [0, 360) instead of flipping)."""
    best = None
    for low in (-180.0, -90.0, 0.0, 90.0):
        w = (np.asarray(a) - low) % 360.0 + low
        jumps = int(np.sum(np.abs(np.diff(w)) > 180.0))
        if best is None or jumps < best[0]:
            best = (jumps, w)
    return best[1]


def onto(t, y, t_ref, y_ref):
    """Angles shifted by multiples of 360 deg to lie within 180 deg of the reference at the same time."""
    if len(t_ref) == 0:
        return y
    j = np.clip(np.searchsorted(t_ref, t), 0, len(t_ref) - 1)
    r = y_ref[j]
    return r + wrap180(y - r)


def robust_limits(series, floor):
    """Axis limits covering the estimate and the truth (not the raw detections) with a margin."""
    v = np.concatenate([s[np.isfinite(s)] for s in series if len(s)] or [np.zeros(1)])
    if len(v) == 0:
        v = np.zeros(1)
    lo, hi = float(v.min()), float(v.max())
    pad = max(0.12 * (hi - lo), floor)
    return lo - pad, hi + pad


def scatter_clipped(ax, t, y, used, color, lim, label):
    """Reprojected detections: used (filled dots) and rejected (crosses); those beyond `lim` drawn at
    the edge as triangles (pointing out), so outliers never stretch the axis over the estimate."""
    lo, hi = lim
    inside = (y >= lo) & (y <= hi)
    n_out = 0
    for mask, marker, alpha, size, lab in ((used, "o", 0.45, 3.0, f"{label} used"),
                                           (~used, "x", 0.55, 9.0, f"{label} rejected")):
        m = mask & inside
        if m.any():
            ax.scatter(t[m], y[m], s=size, marker=marker, color=color, alpha=alpha, linewidths=0.6,
                       label=lab, rasterized=True, zorder=2)
    edge = (hi - lo) * 0.012
    for mask, marker, yv in (((y > hi), "^", hi - edge), ((y < lo), "v", lo + edge)):
        if mask.any():
            n_out += int(mask.sum())
            ax.scatter(t[mask], np.full(mask.sum(), yv), s=12, marker=marker, color=color, alpha=0.8,
                       edgecolors="none", rasterized=True, zorder=3, clip_on=False)
    return n_out


class Figures:
    def __init__(self, out, vector, dpi, footer):
        self.out, self.vector, self.dpi, self.footer = out, vector, dpi, footer
        self.items, self.skipped = [], []

    task = 0  # the drawing task in progress: keeps the manifest in task order across workers

    def save(self, fig, name, title, caption):
        fig.suptitle(title, fontsize=10, y=0.995)
        fig.text(0.005, 0.004, self.footer, fontsize=6.5, color="#444444", ha="left", va="bottom")
        files = {"png": f"{name}.png"}
        fig.savefig(os.path.join(self.out, files["png"]), dpi=self.dpi)
        if self.vector != "none":
            files[self.vector] = f"{name}.{self.vector}"
            fig.savefig(os.path.join(self.out, files[self.vector]))
        plt.close(fig)
        self.items.append({"task": self.task, "name": name, "title": title, "caption": caption, "files": files})

    def skip(self, name, reason):
        self.skipped.append({"task": self.task, "name": name, "reason": reason})


def run_tasks(F, tasks, jobs):
    """Runs the drawing tasks (cost, fn) on `jobs` processes: this one and jobs-1 forks of it (the
    imports and data are shared, nothing is read twice). Greedy by cost. A fork reports its figures
    through a hidden file; a failing fork fails the whole set (its traceback is on stderr)."""
    share = [[] for _ in range(max(1, jobs))]
    load = [0.0] * len(share)
    for i in sorted(range(len(tasks)), key=lambda i: -tasks[i][0]):
        j = load.index(min(load))
        share[j].append(i)
        load[j] += tasks[i][0]
    children = []
    try:
        for j in range(1, len(share)):
            if not share[j]:
                continue
            part = os.path.join(F.out, f".figures-part{j}.json")
            pid = os.fork()
            if pid == 0:
                code = 0
                try:
                    F.items, F.skipped = [], []
                    for i in sorted(share[j]):
                        F.task = i
                        tasks[i][1]()
                    with open(part, "w") as f:
                        json.dump({"items": F.items, "skipped": F.skipped}, f)
                except BaseException:  # noqa: B036 - the fork must never return into the caller
                    import traceback
                    traceback.print_exc()
                    code = 1
                finally:
                    sys.stdout.flush()
                    sys.stderr.flush()
                    os._exit(code)
            children.append((pid, part))
        for i in sorted(share[0]):
            F.task = i
            tasks[i][1]()
    finally:
        failed = False
        for pid, part in children:
            _, status = os.waitpid(pid, 0)
            if os.waitstatus_to_exitcode(status) != 0 or not os.path.exists(part):
                failed = True
                continue
            with open(part) as f:
                d = json.load(f)
            os.remove(part)
            F.items += d["items"]
            F.skipped += d["skipped"]
    if failed:
        raise RuntimeError("a figure process failed (its traceback is above)")
    F.items.sort(key=lambda it: it["task"])
    F.skipped.sort(key=lambda it: it["task"])


# ------------------------------------------------------------------------------------------- figures
def fig3(F, est, gt, reps, chosen, colors, t0):
    fig, axs = plt.subplots(3, 2, figsize=(11, 7.2), sharex=True)
    fig.subplots_adjust(left=0.07, right=0.99, top=0.91, bottom=0.1, hspace=0.12, wspace=0.16)
    tg, te = gt["t"] - t0, est["t"] - t0
    names = [("x", "$x$ [m]"), ("y", "$y$ [m]"), ("z", "$z$ [m]"),
             ("roll", r"roll $\phi$ [°]"), ("pitch", r"pitch $\theta$ [°]"), ("yaw", r"yaw $\psi$ [°]")]
    out_total = 0
    for k, (key, lab) in enumerate(names):
        ax = axs[k % 3][k // 3]
        angle = k >= 3
        g = wrap_window(gt[key]) if angle else gt[key]
        e = onto(est["t"], est[key], gt["t"], g) if angle else est[key]
        lim = robust_limits([g, e], 5.0 if angle else 0.05)
        for oid in chosen:
            r = reps.get(oid)
            if r is None:
                continue
            y = onto(r["t"], r[key], gt["t"], g) if angle else r[key]
            out_total += scatter_clipped(ax, r["t"] - t0, y, r["used"], colors[oid], lim, f"obj {oid}")
        line(ax, tg, g, angle, color=C_GT, lw=1.3, label="ground truth", zorder=4)
        line(ax, te, e, angle, color=C_EST, lw=1.0, label="estimate", zorder=5)
        ax.set_ylim(*lim)
        ax.set_ylabel(lab)
    for ax in axs[-1]:
        ax.set_xlabel("time [s]")
    h, l = axs[0][0].get_legend_handles_labels()
    fig.legend(h, l, loc="upper center", ncol=min(len(l), 8), bbox_to_anchor=(0.5, 0.965), frameon=False,
               markerscale=2.0)
    cap = ("Position and Euler angles (ZYX, each wrapped into the 360° window in which the ground truth wraps "
           "least; lines break at wrap and gimbal-lock jumps) of the aligned estimate and the ground truth, with the IMU pose reprojected from each raw "
           f"detection of object(s) {', '.join(str(o) for o in chosen) or '(none)'} (dots: used by the filter; "
           "crosses: rejected). The axes cover the estimate and the truth; "
           f"{out_total} reprojected values beyond them are drawn as triangles at the edge.")
    F.save(fig, "fig3", "Estimate vs ground truth with reprojected raw detections (paper Fig. 3)", cap)


def relative_to_anchor(objs, anchor):
    """T_A_O = T_A_W T_O_W^-1 per object (keyed by object id) at the stamps both rows exist."""
    ids = np.asarray(objs["object_id"], dtype=int)
    ts = objs["timestamp_ns"]
    p = np.stack(need(objs, "p_O_W_x", "p_O_W_y", "p_O_W_z"), axis=1)
    q = np.stack(need(objs, "q_O_W_x", "q_O_W_y", "q_O_W_z", "q_O_W_w"), axis=1)
    R = quat_to_R(q)
    sig = np.stack(need(objs, "sigma_p_A_O_x", "sigma_p_A_O_y", "sigma_p_A_O_z",
                        "sigma_theta_A_O_x", "sigma_theta_A_O_y", "sigma_theta_A_O_z"), axis=1)
    a = ids == anchor
    a_index = {t: i for i, t in zip(np.flatnonzero(a), ts[a])}
    out = {}
    for oid in sorted(set(ids.tolist()) - {anchor}):
        rows = [i for i in np.flatnonzero(ids == oid) if ts[i] in a_index]
        if not rows:
            continue
        rows = np.array(rows)
        ai = np.array([a_index[ts[i]] for i in rows])
        R_AO = R[ai] @ np.transpose(R[rows], (0, 2, 1))
        p_AO = p[ai] - np.einsum("nij,nj->ni", R_AO, p[rows])
        out[oid] = {"t": ts[rows] * 1e-9, "p": p_AO, "R": R_AO, "sigma": sig[rows]}
    return out


def fig4_tasks(F, objs, anchor, truth_objects, colors, t0, label_of):
    """One drawing task per non-anchor object (the paper's Fig. 4)."""
    rel = relative_to_anchor(objs, anchor)
    if not rel:
        return [(0.1, lambda: F.skip("fig4", "no non-anchor object was initialised"))]
    return [(1.5, (lambda oid=oid, r=r: fig4(F, oid, r, anchor, truth_objects, colors, t0, label_of)))
            for oid, r in rel.items()]


def fig4(F, oid, r, anchor, truth_objects, colors, t0, label_of):
    tA = truth_objects.get(anchor)
    if True:
        t = r["t"] - t0
        ang = euler_deg(r["R"])
        truth = None
        if tA is not None and oid in truth_objects:
            pA, RA = tA
            pO, RO = truth_objects[oid]
            R_AO = np.transpose(RA, (0, 2, 1)) @ RO
            p_AO = (np.transpose(RA, (0, 2, 1)) @ (pO - pA).reshape(1, 3, 1)).reshape(3)
            truth = (p_AO, euler_deg(R_AO)[0])
        fig, axs = plt.subplots(3, 2, figsize=(10, 6.5), sharex=True)
        fig.subplots_adjust(left=0.08, right=0.99, top=0.9, bottom=0.1, hspace=0.12, wspace=0.2)
        c = colors.get(oid, C_EST)
        labels = ["$x$ [m]", "$y$ [m]", "$z$ [m]", r"roll $\phi$ [°]", r"pitch $\theta$ [°]", r"yaw $\psi$ [°]"]
        for k in range(6):
            ax = axs[k % 3][k // 3]
            if k < 3:
                y, s = r["p"][:, k], r["sigma"][:, k]
            else:
                ref = truth[1][k - 3] if truth is not None else ang[-1, k - 3]
                y = ref + wrap180(ang[:, k - 3] - ref)
                s = np.degrees(r["sigma"][:, k])
            i = decimate(t, [y, s])
            ax.fill_between(t[i], (y - s)[i], (y + s)[i], color=c, alpha=0.22, lw=0, label=r"$\pm1\sigma$")
            ax.plot(t[i], y[i], color=c, lw=1.2, label="estimate")
            if truth is not None:
                tv = truth[0][k] if k < 3 else truth[1][k - 3]
                ax.axhline(tv, color=C_GT, ls="--", lw=1.0, label="truth")
            # The whole estimate and the truth, but the σ band only after the first fifth: the first
            # (uninformed) σ must not squash the converged part; it runs off the axes instead.
            tail = slice(len(y) // 5, None)
            ref_vals = np.concatenate([y, y[tail] - 2 * s[tail], y[tail] + 2 * s[tail]] +
                                      ([np.array([tv])] if truth is not None else []))
            lo, hi = np.nanmin(ref_vals), np.nanmax(ref_vals)
            pad = 0.1 * max(hi - lo, 0.01 if k < 3 else 1.0)
            ax.set_ylim(lo - pad, hi + pad)
            ax.set_ylabel(labels[k])
        for ax in axs[-1]:
            ax.set_xlabel("time [s]")
        h, l = axs[0][0].get_legend_handles_labels()
        fig.legend(h, l, loc="upper center", ncol=3, bbox_to_anchor=(0.5, 0.955), frameon=False)
        name = label_of(oid)
        cap = (f"Pose of object {name} relative to the anchor object {label_of(anchor)}, "
               r"$T_{A O} = T_{A W}\,T_{O W}^{-1}$ (the object-world states of both objects; independent of the "
               "gauge), from its first sight, with the filter's ±1σ (rotation: σ of the rotation error per axis, "
               "drawn on the Euler angles)" + (" and the simulated truth." if truth is not None else "."))
        F.save(fig, f"fig4_obj{oid}", f"Object {name} relative to the anchor {label_of(anchor)} (paper Fig. 4)", cap)


def extrinsics(F, states, prior, truth, t0):
    p = np.stack(need(states, "p_I_C_x", "p_I_C_y", "p_I_C_z"), axis=1) * 1000.0
    q = np.stack(need(states, "q_I_C_x", "q_I_C_y", "q_I_C_z", "q_I_C_w"), axis=1)
    sp = np.stack(need(states, "sigma_p_I_C_x", "sigma_p_I_C_y", "sigma_p_I_C_z"), axis=1) * 1000.0
    sr = np.degrees(np.stack(need(states, "sigma_theta_I_C_x", "sigma_theta_I_C_y", "sigma_theta_I_C_z"), axis=1))
    t = states["timestamp_ns"] * 1e-9 - t0
    R = quat_to_R(q)
    if prior is not None:
        p_prior, R_prior = prior
    else:
        p_prior, R_prior = p[:1] / 1000.0, R[:1]
    # The rotation as the error state: R_I_C = R_prior Exp(dtheta), dtheta in degrees.
    dth = log_so3_deg(np.transpose(R_prior, (0, 2, 1)) @ R)
    same_prior = truth is not None and np.allclose(truth[0], p_prior, atol=1e-6) and \
        np.abs(log_so3_deg(np.transpose(R_prior, (0, 2, 1)) @ truth[1])).max() < 1e-4
    fig, axs = plt.subplots(3, 2, figsize=(10, 6.5), sharex=True)
    fig.subplots_adjust(left=0.08, right=0.99, top=0.9, bottom=0.1, hspace=0.12, wspace=0.2)
    ax_names = "xyz"
    for k in range(6):
        ax = axs[k % 3][k // 3]
        if k < 3:
            y, s = p[:, k], sp[:, k]
            pv = p_prior[0, k] * 1000.0
            tv = truth[0][0, k] * 1000.0 if truth is not None else None
            ax.set_ylabel(f"$p_{{IC,{ax_names[k]}}}$ [mm]")
        else:
            y, s = dth[:, k - 3], sr[:, k - 3]
            pv = 0.0
            tv = log_so3_deg(np.transpose(R_prior, (0, 2, 1)) @ truth[1])[0, k - 3] if truth is not None else None
            ax.set_ylabel(f"$\\delta\\theta_{{IC,{ax_names[k - 3]}}}$ [°]")
        i = decimate(t, [y, s])
        ax.fill_between(t[i], (y - s)[i], (y + s)[i], color=C_EST, alpha=0.2, lw=0, label=r"$\pm1\sigma$")
        ax.plot(t[i], y[i], color=C_EST, lw=1.1, label="estimate")
        if tv is not None and same_prior:
            ax.axhline(tv, color=C_GT, ls="--", lw=1.0, label="prior = truth")
        else:
            ax.axhline(pv, color=C_PRIOR, ls=":", lw=1.4, label="prior")
            if tv is not None:
                ax.axhline(tv, color=C_GT, ls="--", lw=1.0, label="truth")
    for ax in axs[-1]:
        ax.set_xlabel("time [s]")
    h, l = axs[0][0].get_legend_handles_labels()
    fig.legend(h, l, loc="upper center", ncol=4, bbox_to_anchor=(0.5, 0.955), frameon=False)
    cap = (r"Camera–IMU extrinsics $T_{IC}$ over time: the lever arm $p_{IC}$ (mm) and the rotation away from "
           r"the prior, $\delta\theta = \mathrm{Log}(R_{IC,\mathrm{prior}}^\top R_{IC})$ (deg, the filter's error "
           "state), with ±1σ, the prior" + (" (here equal to the truth)." if same_prior else
                                            " and the truth." if truth is not None else "."))
    F.save(fig, "extrinsics", r"Extrinsics $T_{IC}$ (self-calibration)", cap)


def consistency(F, err, reps, colors, gate, t0):
    have_nees = "nees_p" in err
    have_nis = any(np.isfinite(r["nis"]).any() for r in reps.values())
    if not have_nees and not have_nis:
        F.skip("consistency", "no covariance (states.csv) and no NIS in reprojection.csv")
        return
    n = int(have_nees) * 2 + int(have_nis)
    fig, axs = plt.subplots(n, 1, figsize=(10, 2.3 * n + 0.8), sharex=True, squeeze=False)
    axs = axs[:, 0]
    height = 2.3 * n + 0.8
    fig.subplots_adjust(left=0.08, right=0.99, top=1 - 0.62 / height, bottom=0.62 / height, hspace=0.16)
    k = 0
    lo3, hi3 = chi2_ppf(0.025, 3), chi2_ppf(0.975, 3)
    if have_nees:
        t = err["t_gt"] - t0
        for key, lab in (("nees_p", r"NEES $\epsilon_p$ (position)"), ("nees_r", r"NEES $\epsilon_\theta$ (orientation)")):
            ax = axs[k]
            y = err[key]
            line(ax, t, y, color=C_EST, lw=0.8, label="NEES")
            ax.axhline(3.0, color="k", lw=0.8, ls="-", alpha=0.6, label="expected (3)")
            ax.axhspan(lo3, hi3, color="#2ca02c", alpha=0.12, label=r"95% $\chi^2_3$ bounds")
            ax.set_yscale("log")
            ax.set_ylabel(lab)
            finite = y[np.isfinite(y) & (y > 0)]
            if len(finite):
                ax.set_title(f"mean {np.mean(finite):.2f}, {100 * np.mean((finite < lo3) | (finite > hi3)):.1f} % "
                             "outside the bounds", loc="right", fontsize=8)
            if len(finite):  # headroom on the log axis: the legend must not cover the curve
                ax.set_ylim(max(finite.min(), 1e-3) / 2, max(finite.max(), hi3) * 40)
            ax.legend(loc="upper left", ncol=3)
            k += 1
    if have_nis:
        ax = axs[k]
        lo6, hi6 = chi2_ppf(0.025, 6), chi2_ppf(0.975, 6)
        ax.axhspan(lo6, hi6, color="#2ca02c", alpha=0.12, label=r"95% $\chi^2_6$ bounds")
        if gate:
            ax.axhline(gate, color="#d62728", lw=1.0, ls="--", label=f"gate {gate:.1f}")
        for oid, r in sorted(reps.items()):
            m = np.isfinite(r["nis"]) & (r["nis"] > 0)
            u = m & r["used"]
            x = m & ~r["used"]
            ax.scatter(r["t"][u] - t0, r["nis"][u], s=3, color=colors[oid], alpha=0.5, label=f"obj {oid}",
                       rasterized=True)
            ax.scatter(r["t"][x] - t0, r["nis"][x], s=8, marker="x", color=colors[oid], alpha=0.5, linewidths=0.6,
                       rasterized=True)
        ax.set_yscale("log")
        nis_all = np.concatenate([r["nis"][np.isfinite(r["nis"]) & (r["nis"] > 0)] for r in reps.values()])
        if len(nis_all):
            ax.set_ylim(max(nis_all.min(), 1e-3) / 2, max(nis_all.max(), gate or hi6) * 40)
        ax.set_ylabel("NIS per detection")
        ax.legend(loc="upper left", ncol=8, markerscale=2)
    axs[-1].set_xlabel("time [s]")
    cap = ("Filter consistency over time. NEES of the IMU position and orientation after the alignment "
           "(states.csv σ, 3 dof each; the alignment's own error is not in the covariance, so the orientation "
           "NEES is inflated when its σ is small) and the NIS of each detection's 6-dof innovation "
           "(dots used, crosses rejected), with two-sided 95 % χ² bounds for one run.")
    F.save(fig, "consistency", "Consistency: NEES and NIS", cap)


def trajectory(F, est, gt, reps, chosen, colors, err, mode, by_error):
    axes = {"x": 0, "y": 1, "z": 2}
    if mode == "xyz":
        fig = plt.figure(figsize=(7.5, 6.5))
        ax = fig.add_subplot(111, projection="3d")
        fig.subplots_adjust(left=0.0, right=0.95, top=0.93, bottom=0.06)
        ig = decimate(gt["t"], [gt["x"], gt["y"], gt["z"]])
        ax.plot(gt["x"][ig], gt["y"][ig], gt["z"][ig], color=C_GT, lw=1.1, label="ground truth")
        ie = decimate(est["t"], [est["x"], est["y"], est["z"]])
        ax.plot(est["x"][ie], est["y"][ie], est["z"][ie], color=C_EST, lw=1.0, label="estimate")
        ax.set_xlabel("$x$ [m]"); ax.set_ylabel("$y$ [m]"); ax.set_zlabel("$z$ [m]")
        span = [np.ptp(gt[a]) or 1.0 for a in "xyz"]
        ax.set_box_aspect(span)
        ax.legend(loc="upper left")
    else:
        a, b = axes[mode[0]], axes[mode[1]]
        ka, kb = "xyz"[a], "xyz"[b]
        fig, ax = plt.subplots(figsize=(7.5, 6.5))
        fig.subplots_adjust(left=0.11, right=0.97 if not by_error else 0.92, top=0.93, bottom=0.1)
        lim_a = robust_limits([gt[ka], est[ka]], 0.1)
        lim_b = robust_limits([gt[kb], est[kb]], 0.1)
        for oid in chosen:
            r = reps.get(oid)
            if r is None:
                continue
            m = r["used"] & (r[ka] >= lim_a[0]) & (r[ka] <= lim_a[1]) & (r[kb] >= lim_b[0]) & (r[kb] <= lim_b[1])
            ax.scatter(r[ka][m], r[kb][m], s=3, color=colors[oid], alpha=0.3, label=f"obj {oid} (used)", rasterized=True)
        colored = by_error and "e_norm_m" in err and len(err["e_norm_m"]) == len(est["t"])
        ig = decimate(gt["t"], [gt[ka], gt[kb]])
        ax.plot(gt[ka][ig], gt[kb][ig], color="#9a9a9a" if colored else C_GT, lw=2.2 if colored else 1.2,
                label="ground truth", zorder=1)
        if colored:
            step = max(1, len(est["t"]) // (4 * SCREEN_BINS))
            xa, xb, e = est[ka][::step], est[kb][::step], err["e_norm_m"][::step]
            seg = np.stack([np.stack([xa[:-1], xb[:-1]], 1), np.stack([xa[1:], xb[1:]], 1)], 1)
            # The colour scale stops at the 98th percentile: an initial transient must not darken the rest.
            vmax = float(np.nanpercentile(e, 98)) if len(e) else 1.0
            lc = LineCollection(seg, cmap="viridis", lw=1.6, zorder=3)
            lc.set_array(e[:-1])
            lc.set_clim(0.0, vmax)
            ax.add_collection(lc)
            cb = fig.colorbar(lc, ax=ax, fraction=0.04, pad=0.02, extend="max" if np.nanmax(e) > vmax else "neither")
            cb.set_label(r"position error $\|p_{est}-p_{gt}\|$ [m]")
            ax.plot([], [], color=plt.get_cmap("viridis")(0.6), lw=1.6, label="estimate (colour: error)")
        else:
            ie = decimate(est["t"], [est[ka], est[kb]])
            ax.plot(est[ka][ie], est[kb][ie], color=C_EST, lw=1.0, label="estimate")
        ax.plot(gt[ka][:1], gt[kb][:1], "o", color=C_GT, ms=5, label="start")
        ax.set_xlim(*lim_a); ax.set_ylim(*lim_b)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"${ka}$ [m]"); ax.set_ylabel(f"${kb}$ [m]")
        ax.legend(loc="best", markerscale=2)
    cap = (f"Trajectory ({'3-D' if mode == 'xyz' else 'plane ' + mode}) of the aligned estimate and the ground "
           "truth" + (", coloured by the position error" if by_error and mode != "xyz" else "") +
           (f", with the used reprojected detections of object(s) {', '.join(map(str, chosen))}" if chosen and mode != "xyz" else "") + ".")
    F.save(fig, "trajectory", f"Trajectory ({mode})", cap)


def errors(F, err, t0):
    t = err["t_gt"] - t0
    fig, axs = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    fig.subplots_adjust(left=0.08, right=0.99, top=0.91, bottom=0.12, hspace=0.1)
    for key, lab, c in (("ex_m", "$e_x$", None), ("ey_m", "$e_y$", None), ("ez_m", "$e_z$", None),
                        ("e_norm_m", r"$\|e\|$", "k")):
        line(axs[0], t, err[key], color=c, lw=1.4 if c else 0.9, label=lab)
    axs[0].set_ylabel(r"$p_{est}-p_{gt}$ [m]")
    for key, lab, c in (("roll_deg", "roll", None), ("pitch_deg", "pitch", None), ("yaw_deg", "yaw", None),
                        ("angle_deg", "angle", "k")):
        line(axs[1], t, err[key], color=c, lw=1.4 if c else 0.9, label=lab)
    axs[1].set_ylabel(r"$R_{est}^\top R_{gt}$ [°]")
    axs[1].set_xlabel("time [s]")
    for ax in axs:
        ax.legend(loc="upper right", ncol=4)
    F.save(fig, "errors", "Errors over time", "Position error per axis and its norm; rotation error "
           r"$R_{est}^\top R_{gt}$ as ZYX Euler angles and its angle.")


def rpe_fig(F, rpe, t0):
    blocks = {}
    for i in range(rpe["_n"]):
        key = (float(rpe["delta"][i]), rpe["unit"][i])
        b = blocks.setdefault(key, {"t": [], "trans": [], "rot": []})
        b["t"].append(rpe["t_i"][i]); b["trans"].append(rpe["trans_m"][i]); b["rot"].append(rpe["rot_deg"][i])
    if not blocks:
        F.skip("rpe", "no pair of matched poses is a delta apart")
        return
    keys = sorted(blocks)
    labels = [f"{d:g} {u}" for d, u in keys]
    fig, axs = plt.subplots(2, 2, figsize=(10, 6.5))
    fig.subplots_adjust(left=0.08, right=0.99, top=0.91, bottom=0.1, hspace=0.3, wspace=0.2)
    for col, (k, unit) in enumerate((("trans", "m"), ("rot", "°"))):
        axs[0][col].boxplot([blocks[key][k] for key in keys], labels=labels, flierprops={"markersize": 3})
        axs[0][col].set_ylabel(f"RPE {'translation' if k == 'trans' else 'rotation'} [{unit}]")
        axs[0][col].set_xlabel(r"$\Delta$")
        for key, lab in zip(keys, labels):
            axs[1][col].plot(np.array(blocks[key]["t"]) - t0, blocks[key][k], lw=0.9, marker=".", ms=2, label=lab)
        axs[1][col].set_xlabel("time of the pair's first pose [s]")
        axs[1][col].legend(loc="upper right")
    F.save(fig, "rpe", "Relative pose error", r"RPE per $\Delta$ (evo): $E=(Q_i^{-1}Q_j)^{-1}(P_i^{-1}P_j)$, "
           "translation norm and rotation angle.")


# ----------------------------------------------------------------------------------------------- main
def as_traj(tab):
    t, x, y, z = need(tab, "t", "tx", "ty", "tz")
    q = np.stack(need(tab, "qx", "qy", "qz", "qw"), axis=1)
    e = euler_deg(quat_to_R(q))
    return {"t": t, "x": x, "y": y, "z": z, "roll": e[:, 0], "pitch": e[:, 1], "yaw": e[:, 2]}


def read_reprojections(tab):
    out = {}
    if tab is None or tab["_n"] == 0:
        return out
    ids = np.asarray(tab["object_id"], dtype=int)
    t = tab["timestamp_ns"] * 1e-9
    p = np.stack(need(tab, "tx", "ty", "tz"), axis=1)
    q = np.stack(need(tab, "qx", "qy", "qz", "qw"), axis=1)
    ok = np.isfinite(p).all(axis=1) & np.isfinite(q).all(axis=1)
    status = np.asarray(tab["status"]) if isinstance(tab["status"], list) else np.full(tab["_n"], "")
    nis = tab["nis"] if "nis" in tab and not isinstance(tab["nis"], list) else np.full(tab["_n"], np.nan)
    for oid in sorted(set(ids.tolist())):
        m = (ids == oid) & ok
        if not m.any():
            continue
        e = euler_deg(quat_to_R(q[m]))
        out[oid] = {"t": t[m], "x": p[m, 0], "y": p[m, 1], "z": p[m, 2], "roll": e[:, 0], "pitch": e[:, 1],
                    "yaw": e[:, 2], "used": np.isin(status[m], USED), "nis": nis[m]}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--eval", required=True, dest="eval_dir")
    ap.add_argument("--run", default=None)
    ap.add_argument("--dataset", default=None)
    ap.add_argument("--out", required=True)
    ap.add_argument("--objects", default="anchor")
    ap.add_argument("--plot-mode", default="xy", choices=["xy", "xz", "yz", "xyz"])
    ap.add_argument("--color-by-error", action="store_true")
    ap.add_argument("--vector", default="pdf", choices=["pdf", "svg", "none"])
    ap.add_argument("--dpi", type=int, default=130)
    ap.add_argument("--jobs", type=int, default=0, help="processes drawing (0: min(2, CPUs))")
    a = ap.parse_args()
    d = a.eval_dir
    try:
        report = read_json(os.path.join(d, "report.json"))
        est = as_traj(read_table(os.path.join(d, "est_matched_aligned.csv")))
        gt = as_traj(read_table(os.path.join(d, "gt_matched.csv")))
        err = read_table(os.path.join(d, "errors.csv"))
        reps = read_reprojections(read_table(os.path.join(d, "reprojection_aligned.csv"), required=False))
        rpe = read_table(os.path.join(d, "rpe.csv"), required=False)
        run_json = states = objs = None
        if a.run:
            run_json = read_json(os.path.join(a.run, "run.json"), required=False)
            states = read_table(os.path.join(a.run, "states.csv"), required=False)
            objs = read_table(os.path.join(a.run, "objects.csv"), required=False)
        ds = read_json(os.path.join(a.dataset, "roe.json"), required=False) if a.dataset else None
    except (OSError, BadInput, KeyError) as e:
        sys.stderr.write(f"plot_run.py: {e}\n")
        return 2
    os.makedirs(a.out, exist_ok=True)

    anchor = run_json.get("anchor_id") if run_json else None
    names = {o["id"]: o.get("name", "") for o in (ds or {}).get("objects", [])}
    all_ids = sorted(set(reps) | set(names) | ({anchor} if anchor is not None else set()))
    colors = {oid: OBJ_PALETTE[i % len(OBJ_PALETTE)] for i, oid in enumerate(all_ids)}
    if a.objects == "all":
        chosen = sorted(reps)
    elif a.objects == "anchor":
        chosen = [anchor] if anchor in reps else sorted(reps)[:1]
    else:
        try:
            chosen = [int(v) for v in a.objects.split(",") if v.strip()]
        except ValueError:
            sys.stderr.write(f"plot_run.py: --objects: expected anchor, all or a list of ids, got '{a.objects}'\n")
            return 2
        missing = [o for o in chosen if o not in reps]
        if missing:
            sys.stderr.write(f"plot_run.py: --objects: no reprojected detection of object(s) "
                             f"{', '.join(map(str, missing))} (objects with detections: "
                             f"{', '.join(map(str, sorted(reps))) or 'none'})\n")
            return 2
    label_of = lambda oid: f"{oid} ({names[oid]})" if names.get(oid) else str(oid)  # noqa: E731

    info, al, pa = report.get("info", {}), report.get("alignment", {}), report.get("per_axis", {})
    pr, rr = pa.get("pos_rmse_m", {}), pa.get("rpy_rmse_deg", {})
    footer = (f"{info.get('label', '')}  ·  alignment {al.get('type', '?')} on {al.get('n_aligned', '?')} poses"
              f" (scale {al.get('scale', 1.0):.4f})  ·  RMSE x/y/z {pr.get('x', math.nan):.3f}/{pr.get('y', math.nan):.3f}/"
              f"{pr.get('z', math.nan):.3f} m, roll/pitch/yaw {rr.get('roll', math.nan):.2f}/{rr.get('pitch', math.nan):.2f}/"
              f"{rr.get('yaw', math.nan):.2f}°  ·  ATE {report.get('ape_trans_m', {}).get('rmse', math.nan):.3f} m"
              f"  ·  roe {info.get('roe_version', '')}")
    F = Figures(a.out, a.vector, a.dpi, footer)
    t0 = float(gt["t"][0]) if len(gt["t"]) else 0.0

    truth = (ds or {}).get("truth") or {}
    tasks = [(3.0, lambda: fig3(F, est, gt, reps, chosen, colors, t0))]
    if objs is not None and anchor is not None:
        tobj = {o["id"]: pose_q(o["T_W_O"]["p"], o["T_W_O"]["q"]) for o in truth.get("objects", [])}
        tasks += fig4_tasks(F, objs, anchor, tobj, colors, t0, label_of)
    else:
        tasks.append((0.1, lambda: F.skip("fig4", "no objects.csv / run.json (not a run folder)")))
    if states is not None and "p_I_C_x" in states:
        pj = ((run_json or {}).get("init") or {}).get("T_I_C")
        prior = pose_q(pj["p"], pj["q"]) if pj else None
        tt = truth.get("T_I_C")
        tasks.append((2.0, lambda: extrinsics(F, states, prior, pose_q(tt["p"], tt["q"]) if tt else None, t0)))
    else:
        tasks.append((0.1, lambda: F.skip("extrinsics", "no states.csv with the extrinsics (not a run folder)")))
    gate = ((run_json or {}).get("nis") or {}).get("gate")
    tasks.append((3.0, lambda: consistency(F, err, reps, colors, gate, t0)))
    tasks.append((1.2, lambda: trajectory(F, est, gt, reps, chosen, colors, err, a.plot_mode, a.color_by_error)))
    tasks.append((1.5, lambda: errors(F, err, t0)))
    if rpe is not None:
        tasks.append((1.2, lambda: rpe_fig(F, rpe, t0)))
    run_tasks(F, tasks, a.jobs if a.jobs > 0 else min(2, os.cpu_count() or 1))
    manifest = {"figures": F.items, "skipped": F.skipped, "objects": {str(k): v for k, v in colors.items()},
                "chosen_objects": chosen, "anchor_id": anchor, "vector": a.vector}
    with open(os.path.join(a.out, "figures.json"), "w") as f:
        json.dump(manifest, f, indent=1)
    print(f"wrote {a.out}: {', '.join(i['name'] for i in F.items)}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:  # roe kills the whole process group; by hand, no traceback either
        sys.exit(130)
