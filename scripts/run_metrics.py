#!/usr/bin/python3
"""Metrics of one `roe run` against the dataset's ground truth, for docs/RESULTS.md.

usage: run_metrics.py RUN_DIR DATASET [--json]

Fused: trajectory.csv associated with state_groundtruth_estimate0 by equal stamps (both at the IMU
rate), SE(3) Umeyama alignment on positions (no scale), per-axis position RMSE (m) and ZYX Euler RMSE
(deg) of R_err = (R_align R_est)^T R_gt. Raw: every row of reprojection.csv with an implied IMU pose
(T_W_I from the raw detection and the current object-world estimate, paper Fig. 3 "obj"), mapped by
the same alignment and compared with the ground truth at its stamp (linear interpolation of the
position); per-object per-axis RMSE.
"""
import json
import sys

import numpy as np
from scipy.spatial.transform import Rotation as Rot


def load(run, ds):
    est = np.genfromtxt(run + "/trajectory.csv", delimiter=",", skip_header=1)
    gt = np.genfromtxt(ds + "/mav0/state_groundtruth_estimate0/data.csv", delimiter=",", comments="#")
    return est, gt


def main():
    run, ds = sys.argv[1], sys.argv[2]
    est, gt = load(run, ds)
    tg = gt[:, 0].astype(np.int64)
    te = np.round(est[:, 0] * 1e9).astype(np.int64)
    idx = np.clip(np.searchsorted(tg, te), 0, len(tg) - 1)
    ok = np.abs(tg[idx] - te) <= 1000
    est, te, g = est[ok], te[ok], gt[idx[ok]]
    X, Y = est[:, 1:4], g[:, 1:4]
    mx, my = X.mean(0), Y.mean(0)
    C = (Y - my).T @ (X - mx) / len(X)
    U, _, Vt = np.linalg.svd(C)
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1
    R = U @ S @ Vt
    t = my - R @ mx
    e = (R @ X.T).T + t - Y
    pos_rmse = np.sqrt((e ** 2).mean(0))
    Ra = Rot.from_matrix(R)
    Re = Ra * Rot.from_quat(est[:, 4:8])
    Rg = Rot.from_quat(g[:, [5, 6, 7, 4]])
    eul = (Re.inv() * Rg).as_euler("ZYX", degrees=True)[:, ::-1]
    eul_rmse = np.sqrt((eul ** 2).mean(0))

    raw = {}
    rp = np.genfromtxt(run + "/reprojection.csv", delimiter=",", names=True, dtype=None, encoding="utf-8")
    for row in np.atleast_1d(rp):
        if not np.isfinite(row["tx"]):
            continue
        ts = int(row["timestamp_ns"])
        k = np.searchsorted(tg, ts)
        if k <= 0 or k >= len(tg):
            continue
        a = (ts - tg[k - 1]) / (tg[k] - tg[k - 1])
        p_gt = (1 - a) * gt[k - 1, 1:4] + a * gt[k, 1:4]
        p = R @ np.array([row["tx"], row["ty"], row["tz"]]) + t
        raw.setdefault(int(row["object_id"]), []).append(p - p_gt)
    raw_rmse = {k: np.sqrt((np.array(v) ** 2).mean(0)).tolist() for k, v in sorted(raw.items())}
    med = np.median(np.array(list(raw_rmse.values())), axis=0) if raw_rmse else np.full(3, np.nan)
    out = {
        "fused_pos_rmse_m": pos_rmse.tolist(),
        "fused_euler_rmse_deg": eul_rmse.tolist(),
        "raw_pos_rmse_m": {str(k): v for k, v in raw_rmse.items()},
        "raw_median_m": med.tolist(),
        "criterion_fused_le_half_median_raw": bool(np.all(pos_rmse <= 0.5 * med)),
        "objects": len(raw_rmse),
        "pairs": int(len(X)),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
