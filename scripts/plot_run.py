#!/usr/bin/python3
"""Figures of one roe run for a paper (run with Debian's /usr/bin/python3 + python3-matplotlib + numpy).

    /usr/bin/python3 scripts/plot_run.py --eval EVAL_DIR [--run RUN_DIR] [--dataset DATASET] --out DIR
        [--objects anchor|all|ID[,ID...]] [--plot-mode xy|xz|yz|xyz] [--color-by-error]
        [--vector pdf|svg|none] [--style default|paper] [--symmetries FILE] [--dpi N]

Reads the output folder of `roe eval` (est_matched_aligned.csv, gt_matched.csv, errors.csv, report.json,
reprojection_aligned.csv, rpe.csv), the run folder (states.csv, states_filter.csv, objects.csv, run.json),
the dataset's roe.json (the truth of a simulation) and the objects' symmetries (--symmetries, written by
roe from the dataset's models_info), and writes into DIR, each as PNG and as PDF or SVG:
  fig3          the paper's Fig. 3: x, y, z and roll, pitch, yaw over time, estimate vs ground truth, with
                the IMU pose reprojected from the raw detections of the chosen objects (used and rejected
                marked apart; points beyond the estimate's range drawn at the axis edge as triangles)
  fig4_obj<ID>  the paper's Fig. 4 for each non-anchor object: its pose relative to the anchor T_A_O over
                time from first sight, +-sigma bands, the truth when the dataset has it; a symmetric
                object's estimate is shown as the symmetry-equivalent pose nearest the truth (or its own
                previous value), its angles unwrapped in time
  extrinsics    T_I_C over time as the causal filter estimated it (states_filter.csv when the smoother ran,
                else states.csv), +-sigma, the smoothed final value, prior and truth
  time_offset   the camera-IMU time offset t_d over time as the causal filter estimated it, +-sigma, the
                smoothed final value, the declared prior and the truth (only when the run estimated it)
  consistency   NEES of the IMU position and orientation (after the alignment) and NIS per detection,
                with their chi-square bounds
  trajectory    the trajectory in a plane or in 3-D, optionally coloured by the position error
  errors        position and rotation errors over time
  rpe           relative pose error per delta (only when rpe.csv is there)
and figures.json: what was drawn (name, title, caption, files, the layers drawn and skipped and why, a
few numbers of the drawn series) and which figures were skipped, and why. Titles and captions there use
no TeX: plain Unicode with X_{sub} and X^{sup} marks, which roe report turns into HTML <sub>/<sup>.
Styles: `default` (titles, a footer with the run and its metrics, screen sizes) and `paper` (no titles or
footers, 3.5 in / 7.16 in wide, TrueType fonts embedded, scatters rasterised inside the vector file).
Exit code 0 on success, 2 on bad input, 3 when matplotlib or numpy is missing.
Euler angles: ZYX, R = Rz(yaw) Ry(pitch) Rx(roll), wrapped to [-180, 180); lines break at wrap and
gimbal-lock jumps instead of drawing them (Fig. 4: unwrapped in time instead).
"""
import argparse
import csv
import io
import json
import math
import os
import re
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


def plain(s):
    """Text from a user (a --label, an object's name, a path) as matplotlib draws it: literally. Every $ is
    escaped, since matplotlib reads text with two unescaped $ as mathtext and a bad formula ends the script."""
    return str(s).replace("$", r"\$")

# ---------------------------------------------------------------------------------------------- style
BASE_RC = {
    "axes.grid": True, "grid.alpha": 0.3, "figure.dpi": 100,
    "svg.fonttype": "none", "path.simplify": True, "agg.path.chunksize": 20000,
    # A fixed title height: matplotlib otherwise measures every axis' tick labels at each draw to place
    # the (empty) axes titles, a fifth of the drawing time.
    "axes.titley": 1.0,
}
# default: today's informative screen figures; paper: column widths, small type, no titles or footers.
STYLES = {
    "default": {"rc": {"font.size": 9, "axes.titlesize": 9, "axes.labelsize": 9, "legend.fontsize": 7.5,
                       "xtick.labelsize": 8, "ytick.labelsize": 8, "lines.linewidth": 1.1, "savefig.dpi": 130,
                       "pdf.fonttype": 3, "ps.fonttype": 3},  # Type 3 subsets: a third faster to write
                "title": True, "footer": True, "single": 7.5, "double": 10.0, "dpi": 130,
                "png_compression": 3},
    "paper": {"rc": {"font.size": 7, "axes.titlesize": 7, "axes.labelsize": 7, "legend.fontsize": 6,
                     "xtick.labelsize": 6, "ytick.labelsize": 6, "lines.linewidth": 0.8, "savefig.dpi": 300,
                     "axes.linewidth": 0.6, "grid.linewidth": 0.4, "xtick.major.width": 0.6,
                     "ytick.major.width": 0.6, "legend.handlelength": 1.6, "legend.columnspacing": 1.0,
                     "pdf.fonttype": 42, "ps.fonttype": 42},  # TrueType embedded, as publishers' checkers ask
              "title": False, "footer": False, "single": 3.5, "double": 7.16, "dpi": 300,
              "png_compression": 6},
}
C_EST, C_GT, C_PRIOR, C_SMOOTH = "#1f77b4", "#000000", "#7f7f7f", "#d62728"
# Objects: one colour each, the same in every figure (tab10 without the estimate's blue, and grey).
OBJ_PALETTE = ["#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf"]
USED = ("accepted", "initialized")


class BadInput(Exception):
    pass


# ------------------------------------------------------------------------------------------------ I/O
TABLES = {}  # CSV path -> {"bin", "columns", "rows"}: the tables roe already parsed (--tables)


def read_table(path, required=True):
    """CSV with a header -> {column: np.array (float) or list (str)}; None when absent and optional.
    A table roe handed over as raw float64 (--tables) is mapped from that file; otherwise the numbers
    are parsed by numpy's C reader, and a file it cannot take whole (empty fields, a short row) goes
    through the checking reader, which names the row."""
    if not os.path.exists(path):
        if required:
            raise BadInput(f"{path}: not found")
        return None
    entry = TABLES.get(os.path.abspath(path)) or TABLES.get(path)
    if entry is not None:
        cols = entry["columns"]
        data = np.fromfile(entry["bin"], dtype=np.float64).reshape(int(entry["rows"]), len(cols))
        out = {c: data[:, k] for k, c in enumerate(cols)}
        for c, values in entry.get("text", {}).items():  # text columns: indices into their values
            out[c] = np.asarray(values, dtype=str)[out[c].astype(np.int64)].tolist()
        out["_n"], out["_path"] = int(entry["rows"]), path
        return out
    with open(path, newline="") as f:
        text = f.read()
    head, _, body = text.partition("\n")
    if not head.strip():
        raise BadInput(f"{path}: empty file")
    header = [h.strip().lstrip("#").strip() for h in head.rstrip("\r").split(",")]
    first = body.split("\n", 1)[0].rstrip("\r").split(",") if body.strip() else []
    out = fast_table(body, header, first) if len(first) == len(header) else None
    if out is None:
        out = checked_table(path, text, header)
    out["_path"] = path
    return out


def read_last_row(path):
    """The header and the last row of a CSV, as read_table gives them (None when absent)."""
    if not os.path.exists(path):
        return None
    with open(path, "rb") as f:
        head = f.readline().decode()
        f.seek(0, os.SEEK_END)
        size = f.tell()
        f.seek(max(len(head), size - 65536))
        tail = f.read().decode(errors="replace").rstrip("\r\n").rsplit("\n", 1)[-1]
    if not tail.strip() or size <= len(head):
        return checked_table(path, head, [h.strip() for h in head.strip().lstrip("#").split(",")]) | {"_path": path}
    out = checked_table(path, head + tail + "\n", [h.strip() for h in head.strip().lstrip("#").split(",")])
    out["_path"] = path
    return out


def is_number(v):
    try:
        float(v)
        return True
    except ValueError:
        return v == ""


def fast_table(body, header, first):
    """The columns via np.loadtxt (numbers) and one split per text column; None when numpy refuses."""
    num = [j for j, v in enumerate(first) if is_number(v) and v != ""]
    txt = [j for j in range(len(header)) if j not in num]
    try:
        data = np.loadtxt(io.StringIO(body), delimiter=",", usecols=num, ndmin=2, dtype=float,
                          comments=None) if num else np.zeros((0, 0))
    except ValueError:
        return None
    out = {header[j]: data[:, k] for k, j in enumerate(num)}
    out["_n"] = data.shape[0] if num else 0
    if txt:
        rows = [ln.split(",") for ln in body.splitlines() if ln.strip()]
        for j in txt:
            out[header[j]] = [r[j].strip() for r in rows]
        out["_n"] = len(rows)
    return out


def checked_table(path, text, header):
    rows = list(csv.reader(io.StringIO(text)))
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
def pixel_columns(ax):
    """Pixel columns the axes span in the saved image (savefig.dpi)."""
    fig = ax.figure
    return max(1, int(math.ceil(ax.get_position().width * fig.get_figwidth() * plt.rcParams["savefig.dpi"])))


def decimate(t, ys, bins):
    """Indices keeping, for each of `bins` equal time bins (at least one per pixel column), the first and
    last sample and each series' minimum and maximum, in time order: a line drawn through them covers
    the same pixels in every column as the full line (every extremum kept), within one pixel. Linear in
    the samples (t is sorted, so a bin's rows are one run: minima and maxima by np.*.reduceat)."""
    n = len(t)
    if n <= 4 * bins:
        return np.arange(n)
    span = (t[-1] - t[0]) or 1.0
    b = np.minimum(((t - t[0]) / span * bins).astype(int), bins - 1)
    starts = np.flatnonzero(np.r_[True, b[1:] != b[:-1]])
    ends = np.r_[starts[1:], n] - 1
    keep = [starts, ends]
    counts = ends - starts + 1
    for y in ys:
        gaps = np.isnan(y)
        lo = np.where(gaps, np.inf, y)
        hi = np.where(gaps, -np.inf, y)
        # The first row of each bin at its bin's minimum, the last at its maximum.
        at_lo = np.flatnonzero(lo == np.repeat(np.minimum.reduceat(lo, starts), counts))
        at_hi = np.flatnonzero(hi == np.repeat(np.maximum.reduceat(hi, starts), counts))
        keep.append(at_lo[np.unique(b[at_lo], return_index=True)[1]])
        keep.append(at_hi[::-1][np.unique(b[at_hi][::-1], return_index=True)[1]])
        if gaps.any():  # the gaps stay gaps
            keep.append(np.flatnonzero(gaps))
    return np.unique(np.concatenate(keep))


def broken(t, y, jump):
    """t, y with NaN inserted where |dy| > jump (a wrap or gimbal-lock jump is not drawn as a line)."""
    if len(y) < 2:
        return t, y
    cut = np.flatnonzero(np.abs(np.diff(y)) > jump) + 1
    return np.insert(t, cut, np.nan), np.insert(y, cut, np.nan)


def line(ax, t, y, angle=False, **kw):
    i = decimate(t, [y], pixel_columns(ax))
    tt, yy = t[i], y[i]
    if angle:
        tt, yy = broken(tt, yy, 90.0)
    return ax.plot(tt, yy, **kw)


def thin(ax, x, y):
    """Indices of the points that fall on distinct half-pixels of the saved image, in order: a dot drawn
    exactly on an identical dot adds nothing but opacity, so a dense scatter keeps its look (every
    isolated point and every extreme stays) at a fraction of the drawing cost. The axes' limits and
    position must be final."""
    n = len(x)
    if n < 1500:
        return np.arange(n)
    scale = 2.0 * plt.rcParams["savefig.dpi"] / ax.figure.dpi
    px = ax.transData.transform(np.column_stack([x, y])) * scale
    ok = np.isfinite(px).all(axis=1)
    k = np.floor(px[ok]).astype(np.int64)
    key = (k[:, 0] - k[:, 0].min(initial=0)) * (1 << 31) + (k[:, 1] - k[:, 1].min(initial=0))
    _, first = np.unique(key, return_index=True)
    return np.flatnonzero(ok)[np.sort(first)]


def scatter(ax, x, y, **kw):
    """ax.scatter of the points that show (thin), rasterised inside vector files."""
    i = thin(ax, x, y)
    return ax.scatter(x[i], y[i], rasterized=True, **kw)


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


def equal_limits(fig, ax, lim_a, lim_b):
    """The two limits widened (never narrowed) so that one metre is as long on both axes of `ax`'s box: the
    whole trajectory stays inside at equal scale (matplotlib's adjustable='datalim' may trim an axis when
    both limits are set)."""
    fw, fh = fig.get_size_inches()
    box = ax.get_position()
    w, h = max(box.width * fw, 1e-6), max(box.height * fh, 1e-6)
    ra, rb = lim_a[1] - lim_a[0], lim_b[1] - lim_b[0]
    if ra / w > rb / h:
        c, half = 0.5 * (lim_b[0] + lim_b[1]), 0.5 * ra * h / w
        return lim_a, (c - half, c + half)
    c, half = 0.5 * (lim_a[0] + lim_a[1]), 0.5 * rb * w / h
    return (c - half, c + half), lim_b


def correspondence_edges(ax, est, gt, keys, max_edges=500):
    """--correspondences: a thin line from each matched estimate pose to its ground-truth pose (every k-th,
    at most `max_edges`). Returns the number drawn."""
    n = min(len(est["t"]), len(gt["t"]))
    idx = np.arange(0, n, max(1, -(-n // max_edges)))
    if len(idx) == 0:
        return 0
    if len(keys) == 2:
        seg = np.stack([np.stack([est[keys[0]][idx], est[keys[1]][idx]], 1),
                        np.stack([gt[keys[0]][idx], gt[keys[1]][idx]], 1)], 1)
        ax.add_collection(LineCollection(seg, colors="#d62728", linewidths=0.5, alpha=0.6, zorder=2))
    else:
        from mpl_toolkits.mplot3d.art3d import Line3DCollection
        seg = np.stack([np.stack([est[k][idx] for k in keys], 1), np.stack([gt[k][idx] for k in keys], 1)], 1)
        ax.add_collection(Line3DCollection(seg, colors="#d62728", linewidths=0.5, alpha=0.6))
    ax.plot([], [], color="#d62728", lw=0.5, label="correspondences")
    return len(idx)


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
    the edge as triangles (pointing out), so outliers never stretch the axis over the estimate. The
    axes' limits must be set. Returns the number drawn at the edge."""
    lo, hi = lim
    inside = (y >= lo) & (y <= hi)
    n_out = 0
    for mask, marker, alpha, size, lab in ((used, "o", 0.45, 3.0, f"{label} used"),
                                           (~used, "x", 0.55, 9.0, f"{label} rejected")):
        m = mask & inside
        if m.any():
            scatter(ax, t[m], y[m], s=size, marker=marker, color=color, alpha=alpha, linewidths=0.6,
                    label=lab, zorder=2)
    edge = (hi - lo) * 0.012
    for mask, marker, yv in (((y > hi), "^", hi - edge), ((y < lo), "v", lo + edge)):
        if mask.any():
            n_out += int(mask.sum())
            scatter(ax, t[mask], np.full(mask.sum(), yv), s=12, marker=marker, color=color, alpha=0.8,
                    edgecolors="none", zorder=3, clip_on=False)
    return n_out


def mathtext(s):
    """A title/label written with X_{sub} / X^{sup} marks (figures.json's form) as matplotlib mathtext; the
    rest (an object's name in it) as plain text."""
    return re.sub(r"([A-Za-zδθσ]+)((?:[_^]\{[A-Za-z0-9,.+\-−⊤ ]*\})+)",
                  lambda m: "$" + m.group(1).replace("δ", r"\delta ").replace("θ", r"\theta ")
                  .replace("σ", r"\sigma ") + m.group(2) + "$", plain(s))


def empty(fig):
    """Removes what was drawn into `fig` (artists, legends, texts, labels, limits): its axes, their ticks
    and the layout stay, to be drawn into again."""
    for ax in fig.axes:
        for a in [*ax.lines, *ax.collections, *ax.patches, *ax.texts, *ax.images]:
            a.remove()
        if ax.legend_ is not None:
            ax.legend_.remove()
        ax.set_xlabel("")
        ax.set_ylabel("")
        ax.set_prop_cycle(None)
        ax.relim()
        ax.set_autoscale_on(True)
    for leg in list(fig.legends):
        leg.remove()
    for txt in list(fig.texts):  # the footer and the title (suptitle() makes a new one)
        txt.remove()
    fig._suptitle = None


def save_png(fig, path, dpi, compression):
    """The figure as an RGB PNG at `dpi` (drawn at the figure's own dpi when they agree: no re-layout).
    RGB, not matplotlib's RGBA: the background is opaque, and the file a sixth smaller and faster to
    compress (zlib level 3 for the screen style: faster than 6 and hardly larger on flat plot colours)."""
    if abs(fig.dpi - dpi) > 1e-9:
        fig.savefig(path, dpi=dpi, pil_kwargs={"compress_level": compression})
        return
    from PIL import Image, PngImagePlugin
    fig.canvas.draw()
    info = PngImagePlugin.PngInfo()
    info.add_text("Software", f"Matplotlib version{matplotlib.__version__}, https://matplotlib.org/")
    w, h = fig.canvas.get_width_height()
    img = Image.frombuffer("RGBA", (w, h), fig.canvas.buffer_rgba(), "raw", "RGBA", 0, 1).convert("RGB")
    img.save(path, format="png", compress_level=compression, pnginfo=info, dpi=(dpi, dpi))


class Figures:
    """The figure set being drawn: style, output, manifest entries."""

    def __init__(self, out, vector, style, footer):
        self.out, self.vector, self.footer = out, vector, footer
        self.style = STYLES[style]
        self.style_name = style
        self.items, self.skipped = [], []
        self.grid = None  # the 3x2 time-series figure, drawn into again by the next one (new(reuse=True))

    task = 0  # the drawing task in progress: keeps the manifest in task order across workers

    def new(self, nrows, ncols, width, height, reuse=False, **kw):
        """A figure `width` ("single" or "double" column) wide, `height` inches at the default style
        (scaled for the paper), with room at the top for the title (default style) and legend rows.
        reuse=True (the 3x2 time series: Fig. 3, each Fig. 4, the extrinsics): the previous such figure
        emptied and resized instead of a new one; its axes and ticks, half of a figure's cost, stay."""
        w, h = self.new_size(width, height)
        if not reuse:
            return plt.subplots(nrows, ncols, figsize=(w, h), **kw)
        key = (nrows, ncols, width, tuple(sorted(kw.items())))
        if self.grid is None or self.grid[0] != key:
            if self.grid is not None:
                plt.close(self.grid[1])
            self.grid = (key,) + tuple(plt.subplots(nrows, ncols, figsize=(w, h), **kw))
        else:
            empty(self.grid[1])
            self.grid[1].set_size_inches(w, h)
        return self.grid[1], self.grid[2]

    def new_size(self, width, height):
        """(w, h) inches of a figure `width` ("single"/"double" column) of `height` in at the default style."""
        w = self.style[width]
        default_w = STYLES["default"][width]
        return w, (height if w == default_w else height * w / default_w * 1.12)

    def adjust(self, fig, legend_rows=1, left=0.08, right=0.99, xlabel=True, **kw):
        """Margins in inches turned into fractions: title, legend rows, x labels and footer."""
        h = fig.get_figheight()
        pt = plt.rcParams["font.size"] / 72.0
        top = (2.2 * pt if self.style["title"] else 0.6 * pt) + legend_rows * 1.9 * pt
        bottom = (3.4 * pt if xlabel else 1.5 * pt) + (1.6 * pt if self.style["footer"] else 0.0)
        fig.subplots_adjust(left=left, right=right, top=1 - top / h, bottom=bottom / h, **kw)

    def legend(self, fig, handles, labels, ncol, **kw):
        """The figure's legend, in the row below the title."""
        h = fig.get_figheight()
        pt = plt.rcParams["font.size"] / 72.0
        y = 1 - (2.0 * pt if self.style["title"] else 0.3 * pt) / h
        fig.legend(handles, labels, loc="upper center", ncol=ncol, bbox_to_anchor=(0.5, y), frameon=False, **kw)

    def save(self, fig, name, title, caption, layers=None, skipped_layers=None, data=None):
        """Writes the figure; `title`/`caption` use X_{sub} marks (no TeX), `layers` what was drawn,
        `skipped_layers` [(layer, why)] what was asked for and not drawn, `data` numbers of the series."""
        if self.style["title"]:
            fig.suptitle(mathtext(title), fontsize=plt.rcParams["font.size"] + 1, y=0.995)
        if self.style["footer"]:
            fig.text(0.005, 0.004, self.footer, fontsize=6.5, color="#444444", ha="left", va="bottom")
        files = {"png": f"{name}.png"}
        save_png(fig, os.path.join(self.out, files["png"]), self.style["dpi"], self.style["png_compression"])
        if self.vector != "none":
            files[self.vector] = f"{name}.{self.vector}"
            fig.savefig(os.path.join(self.out, files[self.vector]), dpi=self.style["dpi"])
        size = [round(v, 3) for v in fig.get_size_inches()]
        if self.grid is None or fig is not self.grid[1]:
            plt.close(fig)
        self.items.append({"task": self.task, "name": name, "title": title, "caption": caption, "files": files,
                           "size_in": size, "layers": layers or [],
                           "skipped_layers": [{"layer": k, "reason": r} for k, r in (skipped_layers or [])],
                           "data": data or {}})

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
def time_limits(*ts):
    v = np.concatenate([t[np.isfinite(t)] for t in ts if len(t)] or [np.zeros(1)])
    lo, hi = (float(v.min()), float(v.max())) if len(v) else (0.0, 1.0)
    return lo, hi if hi > lo else lo + 1.0


def fig3(F, est, gt, reps, chosen, colors, t0):
    fig, axs = F.new(3, 2, "double", 7.2, sharex=True, reuse=True)
    F.adjust(fig, left=0.07, hspace=0.12, wspace=0.16)
    tg, te = gt["t"] - t0, est["t"] - t0
    names = [("x", "$x$ [m]"), ("y", "$y$ [m]"), ("z", "$z$ [m]"),
             ("roll", r"roll $\phi$ [°]"), ("pitch", r"pitch $\theta$ [°]"), ("yaw", r"yaw $\psi$ [°]")]
    drawn = [oid for oid in chosen if oid in reps]
    xlim = time_limits(tg, te, *[reps[o]["t"] - t0 for o in drawn])
    out_total = 0
    for k, (key, lab) in enumerate(names):
        ax = axs[k % 3][k // 3]
        angle = k >= 3
        g = wrap_window(gt[key]) if angle else gt[key]
        e = onto(est["t"], est[key], gt["t"], g) if angle else est[key]
        lim = robust_limits([g, e], 5.0 if angle else 0.05)
        ax.set_xlim(*xlim)
        ax.set_ylim(*lim)
        for oid in drawn:
            r = reps[oid]
            y = onto(r["t"], r[key], gt["t"], g) if angle else r[key]
            out_total += scatter_clipped(ax, r["t"] - t0, y, r["used"], colors[oid], lim, f"obj {oid}")
        line(ax, tg, g, angle, color=C_GT, lw=1.3, label="ground truth", zorder=4)
        line(ax, te, e, angle, color=C_EST, lw=1.0, label="estimate", zorder=5)
        ax.set_ylabel(lab)
    for ax in axs[-1]:
        ax.set_xlabel("time [s]")
    h, l = axs[0][0].get_legend_handles_labels()
    ncol = min(len(l), 8)
    F.adjust(fig, legend_rows=-(-len(l) // ncol), left=0.07, hspace=0.12, wspace=0.16)  # room for every row
    F.legend(fig, h, l, ncol=ncol, markerscale=2.0)
    cap = ("Position and Euler angles (ZYX, each wrapped into the 360° window in which the ground truth wraps "
           "least; lines break at wrap and gimbal-lock jumps) of the aligned estimate and the ground truth")
    if drawn:
        cap += (f", with the IMU pose reprojected from each raw detection of object(s) {', '.join(map(str, drawn))} "
                "(dots: used by the filter; crosses: rejected). The axes cover the estimate and the truth; "
                f"{out_total} reprojected values beyond them are drawn as triangles at the edge.")
        title = "Estimate vs ground truth with reprojected raw detections (paper Fig. 3)"
    else:
        cap += " (no reprojected detections: the estimate is not a run folder, or no object was detected)."
        title = "Estimate vs ground truth (paper Fig. 3)"
    layers = ["ground truth", "estimate"] + [f"reprojected detections of object {o}" for o in drawn]
    skipped = [(f"reprojected detections of object {o}", "no reprojected detection") for o in chosen if o not in reps]
    F.save(fig, "fig3", title, cap, layers, skipped, {"edge_triangles": out_total})


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
    a_t, a_i = ts[a], np.flatnonzero(a)
    order = np.argsort(a_t, kind="stable")
    a_t, a_i = a_t[order], a_i[order]
    out = {}
    if not len(a_t):
        return out
    for oid in sorted(set(ids.tolist()) - {anchor}):
        rows = np.flatnonzero(ids == oid)
        j = np.clip(np.searchsorted(a_t, ts[rows]), 0, len(a_t) - 1)
        ok = a_t[j] == ts[rows]
        rows, ai = rows[ok], a_i[j[ok]]
        if not len(rows):
            continue
        R_AO = R[ai] @ np.transpose(R[rows], (0, 2, 1))
        p_AO = p[ai] - np.einsum("nij,nj->ni", R_AO, p[rows])
        out[oid] = {"t": ts[rows] * 1e-9, "p": p_AO, "R": R_AO, "sigma": sig[rows]}
    return out


def rot_about(axis, chi):
    """(N,3,3) rotations by the angles chi (N) about the unit axis."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    c, s = np.cos(chi)[:, None, None], np.sin(chi)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def equivalents(p, R, sym):
    """The symmetry-equivalent poses T_A_O · S of each sample (lists of (N,3), (N,3,3)), identity first.
    `sym`: {"discrete": [{"p", "q"}...], "continuous": {"axis", "offset"} or None} (BOP, metres)."""
    cands = [(p, R)]
    for d in sym.get("discrete", []):
        pS, RS = pose_q(d["p"], d["q"])
        cands.append((p + np.einsum("nij,j->ni", R, pS[0]), R @ RS[0]))
    return cands


def nearest_continuous(p, R, R_ref, cont):
    """T_A_O · S(χ) with χ per sample bringing the rotation nearest R_ref (N,3,3): for B = R_refᵀ R,
    tr(B Exp(χa)) is largest at χ = atan2(tr(B [a]×), tr B − aᵀ B a)."""
    a = np.asarray(cont["axis"], dtype=float)
    a = a / np.linalg.norm(a)
    o = np.asarray(cont.get("offset", [0, 0, 0]), dtype=float)
    B = np.transpose(R_ref, (0, 2, 1)) @ R
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    chi = np.arctan2(np.einsum("nij,ji->n", B, K), np.trace(B, axis1=1, axis2=2) - np.einsum("i,nij,j->n", a, B, a))
    E = rot_about(a, chi)
    pS = o - np.einsum("nij,j->ni", E, o)
    return p + np.einsum("nij,nj->ni", R, pS), R @ E


def resolve_symmetry(p, R, sym, R_truth=None):
    """Each sample of a symmetric object's T_A_O replaced by its symmetry-equivalent nearest (rotation
    angle) the truth R_truth (3,3), or, without truth, nearest the previous resolved sample (the first
    kept). Returns (p, R)."""
    n = len(R)
    if n == 0 or not sym or (not sym.get("discrete") and not sym.get("continuous")):
        return p, R
    cont = sym.get("continuous")

    def best(ps, Rs, R_ref):
        cands = equivalents(ps, Rs, sym)
        if cont:
            cands = [nearest_continuous(cp, cR, R_ref, cont) for cp, cR in cands]
        score = np.stack([np.einsum("nij,nij->n", R_ref, cR) for _, cR in cands])  # tr(R_refᵀ R)
        k = np.argmax(score, axis=0)
        rows = np.arange(len(Rs))
        return (np.stack([c[0] for c in cands])[k, rows], np.stack([c[1] for c in cands])[k, rows])

    if R_truth is not None:
        return best(p, R, np.broadcast_to(R_truth, R.shape))
    out_p, out_R = p.copy(), R.copy()
    for i in range(1, n):
        bp, bR = best(p[i:i + 1], R[i:i + 1], out_R[i - 1:i])
        out_p[i], out_R[i] = bp[0], bR[0]
    return out_p, out_R


def unwrapped_euler(R, ref=None):
    """ZYX Euler angles (deg) of each R, unwrapped in time (no step beyond 180° between samples), shifted
    by whole turns so that the median lies within 180° of `ref` (3,) (the truth) or of [-180, 180)."""
    ang = np.degrees(np.unwrap(np.radians(euler_deg(R)), axis=0))
    if len(ang):
        mid = np.median(ang, axis=0)
        target = np.zeros(3) if ref is None else np.asarray(ref, dtype=float)
        ang -= 360.0 * np.round((mid - target) / 360.0)
    return ang


def fig4_tasks(F, objs, anchor, truth_objects, symmetries, colors, t0, label_of):
    """One drawing task per non-anchor object (the paper's Fig. 4)."""
    rel = relative_to_anchor(objs, anchor)
    if not rel:
        return [(0.1, lambda: F.skip("fig4", "no non-anchor object was initialised"))]
    return [(1.5, (lambda oid=oid, r=r: fig4(F, oid, r, anchor, truth_objects, symmetries.get(oid), colors, t0,
                                             label_of)))
            for oid, r in rel.items()]


def relative_truth(truth_objects, anchor, oid):
    """The true T_A_O (p (3,), R (3,3)) from the dataset's T_W_O of both objects, or None."""
    tA = truth_objects.get(anchor)
    if tA is None or oid not in truth_objects:
        return None
    (pA, RA), (pO, RO) = tA, truth_objects[oid]
    R_AO = np.transpose(RA, (0, 2, 1))[0] @ RO[0]
    p_AO = np.transpose(RA, (0, 2, 1))[0] @ (pO[0] - pA[0])
    return p_AO, R_AO


def fig4(F, oid, r, anchor, truth_objects, sym, colors, t0, label_of):
    t = r["t"] - t0
    truth = relative_truth(truth_objects, anchor, oid)
    p, R = resolve_symmetry(r["p"], r["R"], sym, truth[1] if truth is not None else None)
    truth_eul = euler_deg(truth[1][None])[0] if truth is not None else None
    ang = unwrapped_euler(R, truth_eul)
    if truth is not None:  # the truth's angles on the estimate's turn
        truth_eul = truth_eul + 360.0 * np.round((np.median(ang, axis=0) - truth_eul) / 360.0)
    fig, axs = F.new(3, 2, "double", 6.5, sharex=True, reuse=True)
    F.adjust(fig, hspace=0.12, wspace=0.2)
    c = colors.get(oid, C_EST)
    labels = ["$x$ [m]", "$y$ [m]", "$z$ [m]", r"roll $\phi$ [°]", r"pitch $\theta$ [°]", r"yaw $\psi$ [°]"]
    for k in range(6):
        ax = axs[k % 3][k // 3]
        y, s = (p[:, k], r["sigma"][:, k]) if k < 3 else (ang[:, k - 3], np.degrees(r["sigma"][:, k]))
        i = decimate(t, [y, y - s, y + s], pixel_columns(ax))
        ax.fill_between(t[i], (y - s)[i], (y + s)[i], color=c, alpha=0.22, lw=0, label=r"$\pm1\sigma$")
        ax.plot(t[i], y[i], color=c, lw=1.2, label="estimate")
        tv = None
        if truth is not None:
            tv = truth[0][k] if k < 3 else truth_eul[k - 3]
            ax.axhline(tv, color=C_GT, ls="--", lw=1.0, label="truth")
        # The whole estimate and the truth, but the σ band only after the first fifth: the first
        # (uninformed) σ must not squash the converged part; it runs off the axes instead.
        tail = slice(len(y) // 5, None)
        ref_vals = np.concatenate([y, y[tail] - 2 * s[tail], y[tail] + 2 * s[tail]] +
                                  ([np.array([tv])] if tv is not None else []))
        lo, hi = np.nanmin(ref_vals), np.nanmax(ref_vals)
        pad = 0.1 * max(hi - lo, 0.01 if k < 3 else 1.0)
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_ylabel(labels[k])
    for ax in axs[-1]:
        ax.set_xlabel("time [s]")
    h, l = axs[0][0].get_legend_handles_labels()
    F.legend(fig, h, l, ncol=3)
    name = label_of(oid)
    symmetric = bool(sym) and bool(sym.get("discrete") or sym.get("continuous"))
    how = ("" if not symmetric else
           " The object is symmetric: each estimate is shown as its symmetry-equivalent pose nearest the "
           + ("truth" if truth is not None else "previous shown estimate") + ", its angles unwrapped in time.")
    cap = (f"Pose of object {name} relative to the anchor object {label_of(anchor)}, "
           "T_{AO} = T_{AW} T_{OW}^{−1} (the object-world states of both objects; independent of the "
           "gauge), from its first sight, with the filter's ±1σ (rotation: σ of the rotation error per axis, "
           "drawn on the Euler angles)" + (" and the simulated truth." if truth is not None else ".") + how)
    steps = np.abs(np.diff(ang, axis=0))
    data = {"symmetry": ("nearest the truth" if truth is not None else "nearest the previous value")
            if symmetric else "none",
            "max_angle_step_deg": float(steps.max()) if len(steps) else 0.0, "samples": int(len(t))}
    if truth is not None and len(ang):  # how far the shown estimate sits from the truth, per angle
        data["median_truth_offset_deg"] = dict(zip(("roll", "pitch", "yaw"),
                                                   np.median(ang - truth_eul, axis=0).round(4).tolist()))
    layers = ["estimate", "±1σ"] + (["truth"] if truth is not None else [])
    skipped = [] if truth is not None else [("truth", "the dataset has no simulated truth of both objects")]
    F.save(fig, f"fig4_obj{oid}", f"Object {name} relative to the anchor {label_of(anchor)} (paper Fig. 4)", cap,
           layers, skipped, data)


def extrinsics_series(states, p_prior, R_prior):
    """(t [s], p_I_C [mm] (N,3), σ_p [mm], δθ = Log(R_priorᵀ R_I_C) [deg] (N,3), σ_θ [deg]) of a states table."""
    p = np.stack(need(states, "p_I_C_x", "p_I_C_y", "p_I_C_z"), axis=1) * 1000.0
    q = np.stack(need(states, "q_I_C_x", "q_I_C_y", "q_I_C_z", "q_I_C_w"), axis=1)
    sp = np.stack(need(states, "sigma_p_I_C_x", "sigma_p_I_C_y", "sigma_p_I_C_z"), axis=1) * 1000.0
    sr = np.degrees(np.stack(need(states, "sigma_theta_I_C_x", "sigma_theta_I_C_y", "sigma_theta_I_C_z"), axis=1))
    dth = log_so3_deg(np.transpose(R_prior, (0, 2, 1)) @ quat_to_R(q))
    return states["timestamp_ns"] * 1e-9, p, sp, dth, sr


def extrinsics(F, causal, smoothed, prior, truth, t0):
    """T_I_C as the causal filter estimated it (`causal`: states_filter.csv when the smoother ran, else
    states.csv), with the smoother's final value (`smoothed`: states.csv, or None) as a line."""
    if prior is not None:
        p_prior, R_prior = prior
    else:
        q0 = np.stack(need(causal, "q_I_C_x", "q_I_C_y", "q_I_C_z", "q_I_C_w"), axis=1)[:1]
        p_prior = np.stack(need(causal, "p_I_C_x", "p_I_C_y", "p_I_C_z"), axis=1)[:1]
        R_prior = quat_to_R(q0)
    t, p, sp, dth, sr = extrinsics_series(causal, p_prior, R_prior)
    # A run written with --output standard records σ at the rows after each image only (empty cells between);
    # the extrinsics change only at the updates, so the trace is those rows.
    recorded = np.isfinite(sp).all(axis=1) & np.isfinite(sr).all(axis=1)
    if not recorded.all():
        t, p, sp, dth, sr = t[recorded], p[recorded], sp[recorded], dth[recorded], sr[recorded]
    t = t - t0
    final = None
    if smoothed is not None and smoothed["_n"] > 0:
        _, ps, _, ds, _ = extrinsics_series(smoothed, p_prior, R_prior)
        final = np.r_[ps[-1], ds[-1]]
    same_prior = truth is not None and np.allclose(truth[0], p_prior, atol=1e-6) and \
        np.abs(log_so3_deg(np.transpose(R_prior, (0, 2, 1)) @ truth[1])).max() < 1e-4
    fig, axs = F.new(3, 2, "double", 6.5, sharex=True, reuse=True)
    F.adjust(fig, hspace=0.12, wspace=0.2)
    ax_names = "xyz"
    span = []
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
        span.append(float(np.nanmax(y) - np.nanmin(y)) if len(y) else 0.0)
        i = decimate(t, [y, y - s, y + s], pixel_columns(ax))
        ax.fill_between(t[i], (y - s)[i], (y + s)[i], color=C_EST, alpha=0.2, lw=0, label=r"$\pm1\sigma$")
        ax.plot(t[i], y[i], color=C_EST, lw=1.1, label="filter (causal)")
        if final is not None:
            ax.axhline(final[k], color=C_SMOOTH, ls="-.", lw=1.0, label="smoothed (final)")
        if tv is not None and same_prior:
            ax.axhline(tv, color=C_GT, ls="--", lw=1.0, label="prior = truth")
        else:
            ax.axhline(pv, color=C_PRIOR, ls=":", lw=1.4, label="prior")
            if tv is not None:
                ax.axhline(tv, color=C_GT, ls="--", lw=1.0, label="truth")
    for ax in axs[-1]:
        ax.set_xlabel("time [s]")
    h, l = axs[0][0].get_legend_handles_labels()
    F.legend(fig, h, l, ncol=5)
    source = causal["_path"]
    cap = ("Camera–IMU extrinsics T_{IC} as the causal filter estimated them over time ("
           f"{os.path.basename(source)}): the lever arm p_{{IC}} (mm) and the rotation away from the prior, "
           "δθ = Log(R_{IC,prior}^{⊤} R_{IC}) (deg, the filter's error state), with ±1σ"
           + (", the smoother's final value (states.csv: the smoothed calibration is one constant)" if final is not None
              else "") + ", the prior" + (" (here equal to the truth)." if same_prior else
                                          " and the truth." if truth is not None else "."))
    layers = ["filter (causal)", "±1σ"] + (["smoothed (final)"] if final is not None else []) + ["prior"] + \
        (["truth"] if truth is not None else [])
    skipped = [] if final is not None else [("smoothed (final)", "the run has no smoother (states.csv is the filter's)")]
    F.save(fig, "extrinsics", "Extrinsics T_{IC} (self-calibration)", cap, layers, skipped,
           {"source": os.path.basename(source), "span": dict(zip(["p_x_mm", "p_y_mm", "p_z_mm", "dtheta_x_deg",
                                                                  "dtheta_y_deg", "dtheta_z_deg"], span))})


def time_offset_fig(F, causal, smoothed, run_json, truth, t0):
    """The camera–IMU time offset t_d as the causal filter estimated it (issue 49), ±1σ, the smoother's final
    value, the declared prior and the truth (a simulation's truth.camera_time_offset_s), in ms."""
    final = (run_json.get("final") or {}).get("time_offset") or {}
    if "time_offset_s" not in causal or "sigma_time_offset_s" not in causal:
        F.skip("time_offset", "states.csv has no time_offset_s column (a run written before issue 49)")
        return
    if not final.get("estimated", False):
        F.skip("time_offset", "the run did not estimate the camera–IMU time offset (filter.estimate_time_offset "
               "false): it held the declared value")
        return
    t, y, s = causal["timestamp_ns"] * 1e-9 - t0, causal["time_offset_s"] * 1e3, causal["sigma_time_offset_s"] * 1e3
    ok = np.isfinite(y) & np.isfinite(s)
    t, y, s = t[ok], y[ok], s[ok]
    declared = float(final.get("declared_s", 0.0)) * 1e3
    tv = truth.get("camera_time_offset_s")
    fig, ax = F.new(1, 1, "double", 3.0)
    F.adjust(fig, left=0.07)
    i = decimate(t, [y, y - s, y + s], pixel_columns(ax))
    ax.fill_between(t[i], (y - s)[i], (y + s)[i], color=C_EST, alpha=0.2, lw=0, label=r"$\pm1\sigma$")
    ax.plot(t[i], y[i], color=C_EST, lw=1.1, label="filter (causal)")
    layers, skipped = ["filter (causal)", "±1σ", "declared (prior)"], []
    if smoothed is not None and smoothed["_n"] > 0 and "time_offset_s" in smoothed:
        ax.axhline(float(smoothed["time_offset_s"][-1]) * 1e3, color=C_SMOOTH, ls="-.", lw=1.0, label="smoothed (final)")
        layers.append("smoothed (final)")
    else:
        skipped.append(("smoothed (final)", "the run has no smoother (states.csv is the filter's)"))
    ax.axhline(declared, color=C_PRIOR, ls=":", lw=1.4, label="declared (prior)")
    if tv is not None:
        ax.axhline(float(tv) * 1e3, color=C_GT, ls="--", lw=1.0, label="truth")
        layers.append("truth")
    ax.set_ylabel("$t_d$ [ms]")
    ax.set_xlabel("time [s]")
    h, l = ax.get_legend_handles_labels()
    F.legend(fig, h, l, ncol=5)
    cap = ("Camera–IMU time offset t_{d} (t_{imu} = t_{cam} + t_{d}) as the causal filter estimated it over time "
           f"({os.path.basename(causal['_path'])}), ±1σ, the declared prior (roe.json camera.time_offset_s)"
           + (" and the truth." if tv is not None else "."))
    F.save(fig, "time_offset", "Camera–IMU time offset t_{d}", cap, layers, skipped,
           {"final_ms": float(y[-1]) if len(y) else None, "final_sigma_ms": float(s[-1]) if len(s) else None,
            "declared_ms": declared})


def nis_panel(ax, reps, colors, gate, t0):
    """NIS per detection: the NIS of the residual the filter used (reprojection.csv `nis`) for detections
    used whole; a detection of which only the position or the rotation part was used (split gate,
    symmetric flips) has no NIS of that part in the file, so it is drawn apart (open marker, at its
    6-dof NIS) and counted; rejected ones as crosses."""
    lo6, hi6 = chi2_ppf(0.025, 6), chi2_ppf(0.975, 6)
    ax.set_yscale("log")
    vals = [r["nis"][np.isfinite(r["nis"]) & (r["nis"] > 0)] for r in reps.values()]
    nis_all = np.concatenate(vals) if vals else np.zeros(0)
    if len(nis_all):
        ax.set_ylim(max(nis_all.min(), 1e-3) / 2, max(nis_all.max(), gate or hi6) * 40)
    ax.axhspan(lo6, hi6, color="#2ca02c", alpha=0.12, label=r"95% $\chi^2_6$ bounds")
    if gate:
        ax.axhline(gate, color="#d62728", lw=1.0, ls="--", label=f"gate {gate:.1f}")
    n_part = 0
    for oid, r in sorted(reps.items()):
        m = np.isfinite(r["nis"]) & (r["nis"] > 0)
        whole = r["used"] & (r["part"] == "both")
        part = r["used"] & ~whole
        n_part += int((m & part).sum())
        if (m & whole).any():
            scatter(ax, r["t"][m & whole] - t0, r["nis"][m & whole], s=3, color=colors[oid], alpha=0.5,
                    label=f"obj {oid}")
        if (m & part).any():
            scatter(ax, r["t"][m & part] - t0, r["nis"][m & part], s=10, marker="o", facecolors="none",
                    edgecolors=colors[oid], linewidths=0.6, alpha=0.6, label=f"obj {oid} part used")
        x = m & ~r["used"]
        if x.any():
            scatter(ax, r["t"][x] - t0, r["nis"][x], s=8, marker="x", color=colors[oid], alpha=0.5, linewidths=0.6)
    ax.set_ylabel("NIS per detection")
    return n_part


def consistency(F, err, reps, colors, gate, t0):
    have_nees = "nees_p" in err
    have_nis = any(np.isfinite(r["nis"]).any() for r in reps.values())
    if not have_nees and not have_nis:
        F.skip("consistency", "no covariance (states.csv) and no NIS in reprojection.csv")
        return
    n = int(have_nees) * 2 + int(have_nis)
    fig, axs = F.new(n, 1, "double", 2.3 * n + 0.8, sharex=True, squeeze=False)
    axs = axs[:, 0]
    F.adjust(fig, legend_rows=0, hspace=0.16)
    t = err["t_gt"] - t0
    xlim = time_limits(t, *[r["t"] - t0 for r in reps.values()])
    k = 0
    lo3, hi3 = chi2_ppf(0.025, 3), chi2_ppf(0.975, 3)
    if have_nees:
        for key, lab in (("nees_p", r"NEES $\epsilon_p$ (position)"), ("nees_r", r"NEES $\epsilon_\theta$ (orientation)")):
            ax = axs[k]
            ax.set_xlim(*xlim)
            y = err[key]
            line(ax, t, y, color=C_EST, lw=0.8, label="NEES")
            ax.axhline(3.0, color="k", lw=0.8, ls="-", alpha=0.6, label="expected (3)")
            ax.axhspan(lo3, hi3, color="#2ca02c", alpha=0.12, label=r"95% $\chi^2_3$ bounds")
            ax.set_yscale("log")
            ax.set_ylabel(lab)
            finite = y[np.isfinite(y) & (y > 0)]
            if len(finite):
                ax.set_title(f"mean {np.mean(finite):.2f}, {100 * np.mean((finite < lo3) | (finite > hi3)):.1f} % "
                             "outside the bounds", loc="right", fontsize=plt.rcParams["font.size"] - 1)
                ax.set_ylim(max(finite.min(), 1e-3) / 2, max(finite.max(), hi3) * 40)  # headroom for the legend
            ax.legend(loc="upper left", ncol=3)
            k += 1
    n_part = 0
    if have_nis:
        axs[k].set_xlim(*xlim)
        n_part = nis_panel(axs[k], reps, colors, gate, t0)
        axs[k].legend(loc="upper left", ncol=8, markerscale=2)
    axs[-1].set_xlabel("time [s]")
    cap = ("Filter consistency over time. NEES of the IMU position and orientation after the alignment "
           "(states.csv σ, 3 dof each; the alignment's own error is not in the covariance, so the orientation "
           "NEES is inflated when its σ is small) and the NIS of each detection's 6-dof innovation "
           "(dots: used whole; crosses: rejected), with two-sided 95 % χ² bounds for one run.")
    if n_part:
        cap += (f" {n_part} detections were used in part only (position or rotation: split gate or a symmetric "
                "object's flip); their 6-dof NIS, drawn as open circles, is not the NIS of the part the filter used.")
    layers = (["NEES position", "NEES orientation"] if have_nees else []) + (["NIS"] if have_nis else [])
    skipped = ([] if have_nees else [("NEES", "no covariance in states.csv")]) + \
        ([] if have_nis else [("NIS", "no NIS in reprojection.csv")])
    F.save(fig, "consistency", "Consistency: NEES and NIS", cap, layers, skipped, {"nis_part_used": n_part})


def trajectory_3d(F, fig, est, gt, reps, chosen, colors, err, by_error, edges=False):
    """The 3-D trajectory: truth, estimate (coloured by the error when asked), used reprojections of the
    chosen objects (at most 4000 per object, evenly over time), the start. Returns (layers, skipped)."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection
    ax = fig.add_subplot(111, projection="3d")
    bins = pixel_columns(ax)
    layers, skipped = [], []
    lims = [robust_limits([gt[a], est[a]], 0.1) for a in "xyz"]
    for oid in chosen:
        r = reps.get(oid)
        if r is None:
            skipped.append((f"reprojected detections of object {oid}", "no reprojected detection"))
            continue
        m = r["used"] & np.all([(r[a] >= lo) & (r[a] <= hi) for a, (lo, hi) in zip("xyz", lims)], axis=0)
        idx = np.flatnonzero(m)[:: max(1, int(m.sum()) // 4000 + 1)]
        ax.scatter(r["x"][idx], r["y"][idx], r["z"][idx], s=2, color=colors[oid], alpha=0.3, depthshade=False,
                   label=f"obj {oid} (used)", rasterized=True)
        layers.append(f"reprojected detections of object {oid}")
    ig = decimate(gt["t"], [gt["x"], gt["y"], gt["z"]], bins)
    colored = by_error and "e_norm_m" in err and len(err["e_norm_m"]) == len(est["t"])
    ax.plot(gt["x"][ig], gt["y"][ig], gt["z"][ig], color="#9a9a9a" if colored else C_GT, lw=1.1, label="ground truth")
    layers.append("ground truth")
    if colored:
        ie = decimate(est["t"], [est["x"], est["y"], est["z"], err["e_norm_m"]], bins)
        pts = np.stack([est["x"][ie], est["y"][ie], est["z"][ie]], axis=1)
        e = err["e_norm_m"][ie]
        vmax = float(np.nanpercentile(err["e_norm_m"], 98))
        lc = Line3DCollection(np.stack([pts[:-1], pts[1:]], axis=1), cmap="viridis", lw=1.4)
        lc.set_array(e[:-1])
        lc.set_clim(0.0, vmax)
        ax.add_collection(lc)
        cb = fig.colorbar(lc, ax=ax, fraction=0.03, pad=0.08, shrink=0.7,
                          extend="max" if np.nanmax(e) > vmax else "neither")
        cb.set_label(r"position error $\|p_{est}-p_{gt}\|$ [m]")
        ax.plot([], [], color=plt.get_cmap("viridis")(0.6), lw=1.4, label="estimate (colour: error)")
        layers.append("estimate coloured by the position error")
    else:
        if by_error:
            skipped.append(("colour by error", "errors.csv has no e_norm_m row per estimate pose"))
        ie = decimate(est["t"], [est["x"], est["y"], est["z"]], bins)
        ax.plot(est["x"][ie], est["y"][ie], est["z"][ie], color=C_EST, lw=1.0, label="estimate")
        layers.append("estimate")
    if edges and correspondence_edges(ax, est, gt, ("x", "y", "z")):
        layers.append("correspondences")
    ax.plot(gt["x"][:1], gt["y"][:1], gt["z"][:1], "o", color=C_GT, ms=5, label="start")
    layers.append("start")
    for (lo, hi), setter in zip(lims, (ax.set_xlim, ax.set_ylim, ax.set_zlim)):
        setter(lo, hi)
    ax.set_xlabel("$x$ [m]"); ax.set_ylabel("$y$ [m]"); ax.set_zlabel("$z$ [m]")
    ax.set_box_aspect([hi - lo for lo, hi in lims])
    ax.legend(loc="upper left", markerscale=2)
    return layers, skipped, {a: [float(lo), float(hi)] for a, (lo, hi) in zip("xyz", lims)}


def trajectory_2d(F, fig, est, gt, reps, chosen, colors, err, mode, by_error, edges=False):
    """The trajectory in the plane `mode`: as trajectory_3d. Returns (layers, skipped)."""
    ka, kb = mode[0], mode[1]
    ax = fig.add_subplot(111)
    layers, skipped = [], []
    lim_a, lim_b = equal_limits(fig, ax, robust_limits([gt[ka], est[ka]], 0.1), robust_limits([gt[kb], est[kb]], 0.1))
    ax.set_xlim(*lim_a); ax.set_ylim(*lim_b)
    ax.set_aspect("equal", adjustable="box")  # the limits hold every pose: never trimmed to fit the box
    for oid in chosen:
        r = reps.get(oid)
        if r is None:
            skipped.append((f"reprojected detections of object {oid}", "no reprojected detection"))
            continue
        m = r["used"] & (r[ka] >= lim_a[0]) & (r[ka] <= lim_a[1]) & (r[kb] >= lim_b[0]) & (r[kb] <= lim_b[1])
        scatter(ax, r[ka][m], r[kb][m], s=3, color=colors[oid], alpha=0.3, label=f"obj {oid} (used)")
        layers.append(f"reprojected detections of object {oid}")
    colored = by_error and "e_norm_m" in err and len(err["e_norm_m"]) == len(est["t"])
    bins = pixel_columns(ax)
    ig = decimate(gt["t"], [gt[ka], gt[kb]], bins)
    ax.plot(gt[ka][ig], gt[kb][ig], color="#9a9a9a" if colored else C_GT, lw=2.2 if colored else 1.2,
            label="ground truth", zorder=1)
    layers.append("ground truth")
    if colored:
        ie = decimate(est["t"], [est[ka], est[kb], err["e_norm_m"]], bins)
        xa, xb, e = est[ka][ie], est[kb][ie], err["e_norm_m"][ie]
        seg = np.stack([np.stack([xa[:-1], xb[:-1]], 1), np.stack([xa[1:], xb[1:]], 1)], 1)
        # The colour scale stops at the 98th percentile: an initial transient must not darken the rest.
        vmax = float(np.nanpercentile(err["e_norm_m"], 98)) if len(e) else 1.0
        lc = LineCollection(seg, cmap="viridis", lw=1.6, zorder=3)
        lc.set_array(e[:-1])
        lc.set_clim(0.0, vmax)
        ax.add_collection(lc)
        cb = fig.colorbar(lc, ax=ax, fraction=0.04, pad=0.02, extend="max" if np.nanmax(e) > vmax else "neither")
        cb.set_label(r"position error $\|p_{est}-p_{gt}\|$ [m]")
        ax.plot([], [], color=plt.get_cmap("viridis")(0.6), lw=1.6, label="estimate (colour: error)")
        layers.append("estimate coloured by the position error")
    else:
        if by_error:
            skipped.append(("colour by error", "errors.csv has no e_norm_m row per estimate pose"))
        ie = decimate(est["t"], [est[ka], est[kb]], bins)
        ax.plot(est[ka][ie], est[kb][ie], color=C_EST, lw=1.0, label="estimate")
        layers.append("estimate")
    if edges and correspondence_edges(ax, est, gt, (ka, kb)):
        layers.append("correspondences")
    ax.plot(gt[ka][:1], gt[kb][:1], "o", color=C_GT, ms=5, label="start")
    layers.append("start")
    ax.set_xlabel(f"${ka}$ [m]"); ax.set_ylabel(f"${kb}$ [m]")
    ax.legend(loc="best", markerscale=2)
    return layers, skipped, {ka: [float(v) for v in ax.get_xlim()], kb: [float(v) for v in ax.get_ylim()]}


def trajectory(F, est, gt, reps, chosen, colors, err, mode, by_error, edges=False):
    fig = plt.figure(figsize=F.new_size("single", 6.5))
    if mode == "xyz":
        F.adjust(fig, legend_rows=0, left=0.0, right=0.92 if by_error else 0.97)
        layers, skipped, limits = trajectory_3d(F, fig, est, gt, reps, chosen, colors, err, by_error, edges)
    else:
        F.adjust(fig, legend_rows=0, left=0.13, right=0.97 if not by_error else 0.9)
        layers, skipped, limits = trajectory_2d(F, fig, est, gt, reps, chosen, colors, err, mode, by_error, edges)
    drawn = [o for o in chosen if o in reps]
    cap = (f"Trajectory ({'3-D' if mode == 'xyz' else 'plane ' + mode}) of the aligned estimate and the ground "
           "truth, the start marked (dot)" + (", coloured by the position error" if "estimate coloured by the position "
                                             "error" in layers else "") +
           (f", with the used reprojected detections of object(s) {', '.join(map(str, drawn))}" if drawn else "") +
           (" (3-D: at most 4000 per object, evenly over time)" if drawn and mode == "xyz" else "") + ".")
    cap += " Correspondences: a line from each matched estimate pose to its ground truth." if "correspondences" in layers else ""
    # The axes' limits (m) as drawn: every estimate and ground-truth pose lies inside them.
    F.save(fig, "trajectory", f"Trajectory ({mode})", cap, layers, skipped, {"axes_limits_m": limits})


def errors(F, err, t0):
    t = err["t_gt"] - t0
    fig, axs = F.new(2, 1, "double", 5.5, sharex=True)
    F.adjust(fig, legend_rows=0, hspace=0.1)
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
           "R_{est}^{⊤} R_{gt} as ZYX Euler angles and its angle.", ["position error", "rotation error"])


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
    fig, axs = F.new(2, 2, "double", 6.5)
    F.adjust(fig, legend_rows=0, hspace=0.35, wspace=0.2)
    for col, (k, unit) in enumerate((("trans", "m"), ("rot", "°"))):
        axs[0][col].boxplot([blocks[key][k] for key in keys], labels=[f"{lab}\nn = {len(blocks[key][k])}"
                                                                      for key, lab in zip(keys, labels)],
                            flierprops={"markersize": 3})
        axs[0][col].set_ylabel(f"RPE {'translation' if k == 'trans' else 'rotation'} [{unit}]")
        axs[0][col].set_xlabel(r"$\Delta$")
        for key, lab in zip(keys, labels):
            axs[1][col].plot(np.array(blocks[key]["t"]) - t0, blocks[key][k], lw=0.9, marker=".", ms=2, label=lab)
        axs[1][col].set_xlabel("time of the pair's first pose [s]")
        axs[1][col].legend(loc="upper right")
    F.save(fig, "rpe", "Relative pose error", "RPE per Δ (evo): E = (Q_{i}^{−1} Q_{j})^{−1} (P_{i}^{−1} P_{j}), "
           "translation norm and rotation angle.", ["box plots per Δ", "RPE over time"])


# ----------------------------------------------------------------------------------------------- main
def as_traj(tab):
    t, x, y, z = need(tab, "t", "tx", "ty", "tz")
    q = np.stack(need(tab, "qx", "qy", "qz", "qw"), axis=1)
    e = euler_deg(quat_to_R(q))
    return {"t": t, "x": x, "y": y, "z": z, "roll": e[:, 0], "pitch": e[:, 1], "yaw": e[:, 2]}


def used_parts(run_dir, tab):
    """The `used` column of the run's reprojection.csv (which part of each detection updated the filter)
    for the rows of eval's reprojection_aligned.csv, matched by (timestamp, object); "" where the run's
    file has no such row; None when the file or the column is absent."""
    path = os.path.join(run_dir, "reprojection.csv") if run_dir else None
    if tab is None or not path or not os.path.exists(path):
        return None
    run = read_table(path)
    if "used" not in run:
        return None
    ts_run, obj_run = need(run, "timestamp_ns", "object_id")
    # (timestamp, object) as one integer: the timestamp's rank among both files' stamps, then the object.
    stamps, rank = np.unique(np.r_[ts_run, tab["timestamp_ns"]], return_inverse=True)
    objs = np.r_[obj_run, tab["object_id"]].astype(np.int64)
    objs -= objs.min(initial=0)
    key = rank.astype(np.int64) * (int(objs.max(initial=0)) + 1) + objs
    k_run, k_tab = key[:len(ts_run)], key[len(ts_run):]
    if not len(k_run):
        return [""] * len(k_tab)
    order = np.argsort(k_run, kind="stable")
    j = np.maximum(np.searchsorted(k_run[order], k_tab, side="right") - 1, 0)  # a repeated row: the last
    found = k_run[order][j] == k_tab
    used = np.asarray(run["used"], dtype=str)
    return np.where(found, used[order][j], "").tolist()


def read_reprojections(tab, parts=None):
    out = {}
    if tab is None or tab["_n"] == 0:
        return out
    if parts is not None and "used" not in tab:
        tab["used"] = parts
    ids = np.asarray(tab["object_id"], dtype=int)
    t = tab["timestamp_ns"] * 1e-9
    p = np.stack(need(tab, "tx", "ty", "tz"), axis=1)
    q = np.stack(need(tab, "qx", "qy", "qz", "qw"), axis=1)
    ok = np.isfinite(p).all(axis=1) & np.isfinite(q).all(axis=1)
    status = np.asarray(tab["status"]) if isinstance(tab.get("status"), list) else np.full(tab["_n"], "")
    nis = tab["nis"] if "nis" in tab and not isinstance(tab["nis"], list) else np.full(tab["_n"], np.nan)
    # Which part updated the filter (optional column): both, position, rotation or none.
    part = np.asarray(tab["used"]) if isinstance(tab.get("used"), list) else np.full(tab["_n"], "both")
    part = np.where(part == "", "both", part)
    for oid in sorted(set(ids.tolist())):
        m = (ids == oid) & ok
        if not m.any():
            continue
        e = euler_deg(quat_to_R(q[m]))
        out[oid] = {"t": t[m], "x": p[m, 0], "y": p[m, 1], "z": p[m, 2], "roll": e[:, 0], "pitch": e[:, 1],
                    "yaw": e[:, 2], "used": np.isin(status[m], USED), "nis": nis[m], "part": part[m]}
    return out


def read_inputs(a):
    """Everything the figures read: {name: table/json/None}. Raises BadInput/OSError/KeyError."""
    d = a.eval_dir
    x = {"report": read_json(os.path.join(d, "report.json")),
         "est": as_traj(read_table(os.path.join(d, "est_matched_aligned.csv"))),
         "gt": as_traj(read_table(os.path.join(d, "gt_matched.csv"))),
         "err": read_table(os.path.join(d, "errors.csv")),
         "reps": None,
         "rpe": read_table(os.path.join(d, "rpe.csv"), required=False),
         "run_json": None, "states": None, "states_filter": None, "objs": None}
    if a.run:
        x["run_json"] = read_json(os.path.join(a.run, "run.json"), required=False)
        x["states_filter"] = read_table(os.path.join(a.run, "states_filter.csv"), required=False)
        # With the smoother, the smoothed states matter for their final value only.
        x["states"] = (read_table(os.path.join(a.run, "states.csv"), required=False) if x["states_filter"] is None
                       else read_last_row(os.path.join(a.run, "states.csv")))
        x["objs"] = read_table(os.path.join(a.run, "objects.csv"), required=False)
    rep = read_table(os.path.join(d, "reprojection_aligned.csv"), required=False)
    x["reps"] = read_reprojections(rep, used_parts(a.run, rep))
    x["ds"] = read_json(os.path.join(a.dataset, "roe.json"), required=False) if a.dataset else None
    x["symmetries"] = {int(k): v for k, v in (read_json(a.symmetries) if a.symmetries else {}).items()}
    return x


def choose_objects(spec, reps, anchor):
    """The objects whose reprojected detections are drawn (--objects); BadInput for unknown ones."""
    if spec == "all":
        return sorted(reps)
    if spec == "anchor":
        return [anchor] if anchor in reps else sorted(reps)[:1]
    try:
        chosen = [int(v) for v in spec.split(",") if v.strip()]
    except ValueError:
        raise BadInput(f"--objects: expected anchor, all or a list of ids, got '{spec}'")
    missing = [o for o in chosen if o not in reps]
    if missing:
        raise BadInput(f"--objects: no reprojected detection of object(s) {', '.join(map(str, missing))} "
                       f"(objects with detections: {', '.join(map(str, sorted(reps))) or 'none'})")
    return chosen


def footer_of(report):
    info, al, pa = report.get("info", {}), report.get("alignment", {}), report.get("per_axis", {})
    pr, rr = pa.get("pos_rmse_m", {}), pa.get("rpy_rmse_deg", {})
    return (f"{plain(info.get('label', ''))}  ·  alignment {al.get('type', '?')} on {al.get('n_aligned', '?')} poses"
            f" (scale {al.get('scale', 1.0):.4f})  ·  RMSE x/y/z {pr.get('x', math.nan):.3f}/{pr.get('y', math.nan):.3f}/"
            f"{pr.get('z', math.nan):.3f} m, roll/pitch/yaw {rr.get('roll', math.nan):.2f}/{rr.get('pitch', math.nan):.2f}/"
            f"{rr.get('yaw', math.nan):.2f}°  ·  ATE {report.get('ape_trans_m', {}).get('rmse', math.nan):.3f} m"
            f"  ·  roe {info.get('roe_version', '')}")


def make_tasks(F, a, x, chosen, colors, label_of):
    """The drawing tasks (cost, fn) of the figure set."""
    est, gt, err, reps, objs = x["est"], x["gt"], x["err"], x["reps"], x["objs"]
    run_json, truth = x["run_json"] or {}, (x["ds"] or {}).get("truth") or {}
    anchor = run_json.get("anchor_id")
    t0 = float(gt["t"][0]) if len(gt["t"]) else 0.0
    tasks = [(3.0, lambda: fig3(F, est, gt, reps, chosen, colors, t0))]
    if objs is not None and anchor is not None:
        tobj = {o["id"]: pose_q(o["T_W_O"]["p"], o["T_W_O"]["q"]) for o in truth.get("objects", [])}
        tasks += fig4_tasks(F, objs, anchor, tobj, x["symmetries"], colors, t0, label_of)
    else:
        tasks.append((0.1, lambda: F.skip("fig4", a.run_absent or "no objects.csv / run.json (not a run folder)")))
    # The extrinsics as the causal filter had them: states_filter.csv when the smoother rewrote states.csv.
    causal = x["states_filter"] if x["states_filter"] is not None else x["states"]
    if causal is not None and "p_I_C_x" in causal:
        smoothed = x["states"] if x["states_filter"] is not None else None
        pj = (run_json.get("init") or {}).get("T_I_C")
        prior = pose_q(pj["p"], pj["q"]) if pj else None
        tt = truth.get("T_I_C")
        tasks.append((2.0, lambda: extrinsics(F, causal, smoothed, prior, pose_q(tt["p"], tt["q"]) if tt else None,
                                              t0)))
        tasks.append((0.8, lambda: time_offset_fig(F, causal, smoothed, run_json, truth, t0)))
    else:
        tasks.append((0.1, lambda: F.skip("extrinsics", a.run_absent or
                                          "no states.csv with the extrinsics (not a run folder)")))
    gate = (run_json.get("nis") or {}).get("gate")
    tasks.append((3.0, lambda: consistency(F, err, reps, colors, gate, t0)))
    tasks.append((1.2, lambda: trajectory(F, est, gt, reps, chosen, colors, err, a.plot_mode, a.color_by_error,
                                          a.correspondences)))
    tasks.append((1.5, lambda: errors(F, err, t0)))
    if x["rpe"] is not None:
        tasks.append((1.2, lambda: rpe_fig(F, x["rpe"], t0)))
    return tasks


def wait_for_args(argv):
    """`--args-from FILE` (roe starts the script before its input exists, so that the imports above run
    while roe computes): the arguments, once roe has written FILE as {"args": [...]}; None on
    {"abort": true} (roe stopped before the figures). Otherwise `argv` itself."""
    if len(argv) != 2 or argv[0] != "--args-from":
        return argv
    import time
    while not os.path.exists(argv[1]):  # written whole (renamed into place); roe's death ends this process
        time.sleep(0.004)
    with open(argv[1]) as f:
        d = json.load(f)
    return None if d.get("abort") else [str(v) for v in d["args"]]


def main():
    argv = wait_for_args(sys.argv[1:])
    if argv is None:
        return 0
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--eval", required=True, dest="eval_dir")
    ap.add_argument("--run", default=None)
    ap.add_argument("--run-absent", default=None,
                    help="why the run folder has no states/objects tables (roe passes it for --output minimal)")
    ap.add_argument("--dataset", default=None)
    ap.add_argument("--tables", default=None, help="JSON {csv path: {bin, columns, rows}} of tables roe parsed")
    ap.add_argument("--symmetries", default=None, help="JSON {id: {discrete: [pose...], continuous: {axis, offset}}}")
    ap.add_argument("--out", required=True)
    ap.add_argument("--objects", default="anchor")
    ap.add_argument("--plot-mode", default="xy", choices=["xy", "xz", "yz", "xyz"])
    ap.add_argument("--color-by-error", action="store_true")
    ap.add_argument("--correspondences", action="store_true")
    ap.add_argument("--vector", default="pdf", choices=["pdf", "svg", "none"])
    ap.add_argument("--style", default="default", choices=sorted(STYLES))
    ap.add_argument("--dpi", type=int, default=0, help="PNG resolution (0: the style's, 130 or 300)")
    ap.add_argument("--jobs", type=int, default=0, help="processes drawing (0: min(2, CPUs))")
    a = ap.parse_args(argv)
    plt.rcParams.update(BASE_RC)
    plt.rcParams.update(STYLES[a.style]["rc"])
    if a.dpi > 0:
        STYLES[a.style]["dpi"] = a.dpi
    plt.rcParams["savefig.dpi"] = STYLES[a.style]["dpi"]  # also the resolution of rasterised parts
    # Laid out at the resolution it is saved at: the text is measured (and the mathtext parsed) once,
    # not once at the screen's dpi and again at the PNG's.
    plt.rcParams["figure.dpi"] = STYLES[a.style]["dpi"]
    try:
        if a.tables:
            TABLES.update(read_json(a.tables))
        x = read_inputs(a)
        anchor = (x["run_json"] or {}).get("anchor_id")
        chosen = choose_objects(a.objects, x["reps"], anchor)
    except (OSError, BadInput, KeyError) as e:
        sys.stderr.write(f"plot_run.py: {e}\n")
        return 2
    os.makedirs(a.out, exist_ok=True)
    names = {o["id"]: o.get("name", "") for o in (x["ds"] or {}).get("objects", [])}
    all_ids = sorted(set(x["reps"]) | set(names) | ({anchor} if anchor is not None else set()))
    colors = {oid: OBJ_PALETTE[i % len(OBJ_PALETTE)] for i, oid in enumerate(all_ids)}
    label_of = lambda oid: f"{oid} ({names[oid]})" if names.get(oid) else str(oid)  # noqa: E731
    F = Figures(a.out, a.vector, a.style, footer_of(x["report"]))
    run_tasks(F, make_tasks(F, a, x, chosen, colors, label_of), a.jobs if a.jobs > 0 else min(2, os.cpu_count() or 1))
    manifest = {"figures": F.items, "skipped": F.skipped, "objects": {str(k): v for k, v in colors.items()},
                "chosen_objects": chosen, "anchor_id": anchor, "vector": a.vector, "style": a.style,
                "plot_mode": a.plot_mode, "color_by_error": a.color_by_error, "correspondences": a.correspondences}
    with open(os.path.join(a.out, "figures.json"), "w") as f:
        json.dump(manifest, f, indent=1)
    print(f"wrote {a.out}: {', '.join(i['name'] for i in F.items)}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:  # roe kills the whole process group; by hand, no traceback either
        sys.exit(130)
