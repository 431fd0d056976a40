#!/usr/bin/python3
"""Reference numbers for roe eval on the real pairs in ../shared/data/eval, computed with evo's core API.

evo is NOT part of roe and is not imported from this repository: check it out read-only elsewhere and
put it on PYTHONPATH (evo.core needs only numpy + scipy; Debian's python3-numpy/python3-scipy work):

    git clone https://github.com/MichaelGrupp/evo /tmp/evo-src   # used: 26d0953 (v1.36.5)
    PYTHONPATH=/tmp/evo-src /usr/bin/python3 tests/eval/data/evo_reference.py \
        ../shared/data/eval > tests/eval/data/evo_reference.json

evo.tools.file_interface is not used (it needs rosbags); the files are parsed here the same way it
parses them (TUM: 8 space-separated floats; EuRoC: ns / 1e9, quaternion w first).

RPE ("rpe" per pair, nearest-neighbour pairs): evo's metrics.RPE (translation_part in m and
rotation_angle_deg) on the matched trajectories after the given alignment (only Sim(3) changes it), for
several deltas, units (f, m, deg), consecutive and all pairs, and pairs chosen on the estimate (evo's
default) or on the reference; with the index pairs from metrics.id_pairs_from_delta (count, first and
last five).

Per pair and alignment the JSON holds: the matched pairs as (estimate row, ground-truth row) indices
(evo.core.sync.matching_time_indices, max_diff 0.01 s, offset 0), the alignment (R, t, s) from
PoseTrajectory3D.align / align_origin, evo's APE statistics for translation_part (m) and
rotation_angle_deg, and the per-axis RMSE of p_est - p_gt and of the ZYX Euler angles of
R_est^T R_gt (scipy as_euler('ZYX'), each wrapped to [-180, 180)).  The "unique" entries apply
cnspy's duplicate rule (cnspy_timestamp_association: after nearest-neighbour matching keep only the
first occurrence of every matched stamp on both sides) to evo's pairs, then the same evo metrics.
"""
import contextlib
import copy
import json
import os
import sys

import numpy as np
from scipy.spatial.transform import Rotation

from evo.core import metrics, sync
from evo.core.trajectory import PoseTrajectory3D


def read_tum(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            fields = line.rstrip("\n").split(" ")
            assert len(fields) == 8, (path, line)
            rows.append([float(x) for x in fields])
    m = np.array(rows)
    return PoseTrajectory3D(m[:, 1:4], np.roll(m[:, 4:8], 1, axis=1), m[:, 0])


def read_euroc(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            rows.append([float(x) for x in line.strip().split(",")])
    m = np.array(rows)
    return PoseTrajectory3D(m[:, 1:4], m[:, 4:8], np.divide(m[:, 0], 1e9))


def match(ref, est):
    """evo.core.sync.associate_trajectories, returning (est_idx, gt_idx) instead of trajectories."""
    est_longer = len(est.timestamps) > len(ref.timestamps)
    if est_longer:
        i_ref, i_est = sync.matching_time_indices(ref.timestamps, est.timestamps, 0.01, 0.0)
    else:
        i_est, i_ref = sync.matching_time_indices(est.timestamps, ref.timestamps, 0.01, -0.0)
    # cross-check with evo's own association
    r2, e2 = sync.associate_trajectories(ref, est, max_diff=0.01)
    assert np.array_equal(r2.positions_xyz, ref.positions_xyz[i_ref])
    assert np.array_equal(e2.positions_xyz, est.positions_xyz[i_est])
    return list(map(int, i_est)), list(map(int, i_ref))


def unique_rule(est, ref, i_est, i_ref):
    keep, seen_e, seen_g = [], set(), set()
    for k, (a, b) in enumerate(zip(i_est, i_ref)):
        te, tg = est.timestamps[a], ref.timestamps[b]
        if te in seen_e or tg in seen_g:
            continue
        seen_e.add(te)
        seen_g.add(tg)
        keep.append(k)
    return [i_est[k] for k in keep], [i_ref[k] for k in keep]


def wrap180(a):
    return (a + 180.0) % 360.0 - 180.0


def evaluate(ref, est, i_est, i_ref, align, n_align=-1):
    r = copy.deepcopy(ref)
    e = copy.deepcopy(est)
    r.reduce_to_ids(i_ref)
    e.reduce_to_ids(i_est)
    out = {"n_matched": len(i_est)}
    if align in ("se3", "sim3"):
        R, t, s = e.align(r, correct_scale=(align == "sim3"), n=n_align)
        out["alignment"] = {"R": R.tolist(), "t": t.tolist(), "s": float(s)}
    elif align == "origin":
        T = e.align_origin(r)
        out["alignment"] = {"R": T[:3, :3].tolist(), "t": T[:3, 3].tolist(), "s": 1.0}
    else:
        out["alignment"] = {"R": np.eye(3).tolist(), "t": [0.0, 0.0, 0.0], "s": 1.0}
    for name, rel in (("ape_trans_m", metrics.PoseRelation.translation_part),
                      ("ape_rot_deg", metrics.PoseRelation.rotation_angle_deg)):
        ape = metrics.APE(rel)
        ape.process_data((r, e))
        out[name] = {k: float(v) for k, v in ape.get_all_statistics().items()}
    dp = e.positions_xyz - r.positions_xyz
    out["pos_rmse_m"] = np.sqrt(np.mean(dp ** 2, axis=0)).tolist()
    out["pos_mean_m"] = np.mean(dp, axis=0).tolist()
    rpy = []
    for Pe, Pr in zip(e.poses_se3, r.poses_se3):
        Re = Pe[:3, :3].T @ Pr[:3, :3]
        yaw, pitch, roll = Rotation.from_matrix(Re).as_euler("ZYX", degrees=True)
        rpy.append([wrap180(roll), wrap180(pitch), wrap180(yaw)])
    out["rpy_rmse_deg"] = np.sqrt(np.mean(np.array(rpy) ** 2, axis=0)).tolist()
    return out


RPE_CASES = [
    # (name, delta, unit, all_pairs, pairs_from_reference, align)
    ("f1", 1, "f", False, False, "se3"),
    ("f10_all", 10, "f", True, False, "se3"),
    ("f10", 10, "f", False, False, "se3"),
    ("m0.5", 0.5, "m", False, False, "se3"),
    ("m0.5_all", 0.5, "m", True, False, "se3"),
    ("m0.5_ref", 0.5, "m", False, True, "se3"),
    ("m0.5_all_ref", 0.5, "m", True, True, "se3"),
    ("m1_sim3", 1.0, "m", False, False, "sim3"),
    ("deg10", 10.0, "deg", False, False, "se3"),
    ("deg10_all", 10.0, "deg", True, False, "se3"),
    ("rad0.2_ref", 0.2, "rad", False, True, "none"),
]


def rpe_cases(ref, est, i_est, i_ref):
    units = {"f": metrics.Unit.frames, "m": metrics.Unit.meters, "deg": metrics.Unit.degrees,
             "rad": metrics.Unit.radians}
    out = {}
    for name, delta, unit, all_pairs, from_ref, align in RPE_CASES:
        r = copy.deepcopy(ref)
        e = copy.deepcopy(est)
        r.reduce_to_ids(i_ref)
        e.reduce_to_ids(i_est)
        if align in ("se3", "sim3"):
            e.align(r, correct_scale=(align == "sim3"))
        entry = {"delta": delta, "unit": unit, "all_pairs": all_pairs,
                 "pairs_from": "gt" if from_ref else "est", "align": align}
        # evo prints a progress line on stdout for angles in all-pairs mode: keep the JSON clean.
        with contextlib.redirect_stdout(sys.stderr):
            pairs = metrics.id_pairs_from_delta((r if from_ref else e).poses_se3, delta, units[unit],
                                                0.1, all_pairs=all_pairs)
        entry["n_pairs"] = len(pairs)
        entry["first_pairs"] = [list(map(int, q)) for q in pairs[:5]]
        entry["last_pairs"] = [list(map(int, q)) for q in pairs[-5:]]
        for key, rel in (("trans_m", metrics.PoseRelation.translation_part),
                         ("rot_deg", metrics.PoseRelation.rotation_angle_deg)):
            rpe = metrics.RPE(rel, delta, units[unit], 0.1, all_pairs=all_pairs,
                              pairs_from_reference=from_ref)
            with contextlib.redirect_stdout(sys.stderr):
                rpe.process_data((r, e))
            entry[key] = {k: float(v) for k, v in rpe.get_all_statistics().items()}
        out[name] = entry
    return out


def main():
    data = sys.argv[1]
    import evo
    pairs = {
        "tum_fr1_xyz": (read_tum(os.path.join(data, "freiburg1_xyz-groundtruth.txt")),
                        read_tum(os.path.join(data, "freiburg1_xyz-rgbdslam.txt")),
                        "freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-rgbdslam.txt"),
        "euroc_v102": (read_euroc(os.path.join(data, "V102_groundtruth.csv")),
                       read_tum(os.path.join(data, "V102.txt")), "V102_groundtruth.csv", "V102.txt"),
    }
    result = {"generator": "tests/eval/data/evo_reference.py",
              "evo_version": getattr(evo, "__version__", "unknown"), "numpy": np.__version__,
              "max_dt_s": 0.01, "t_offset_s": 0.0, "pairs": {}}
    for key, (ref, est, gt_name, est_name) in pairs.items():
        i_est, i_ref = match(ref, est)
        u_est, u_ref = unique_rule(est, ref, i_est, i_ref)
        entry = {"gt": gt_name, "est": est_name, "n_gt": len(ref.timestamps), "n_est": len(est.timestamps),
                 "matches": {"nearest": {"est_index": i_est, "gt_index": i_ref},
                             "unique": {"est_index": u_est, "gt_index": u_ref}},
                 "results": {}}
        for policy, (ie, ig) in (("nearest", (i_est, i_ref)), ("unique", (u_est, u_ref))):
            for align in ("se3", "sim3", "origin", "none"):
                entry["results"][f"{policy}/{align}"] = evaluate(ref, est, ie, ig, align)
            entry["results"][f"{policy}/se3_n100"] = evaluate(ref, est, ie, ig, "se3", n_align=100)
            entry["results"][f"{policy}/sim3_n100"] = evaluate(ref, est, ie, ig, "sim3", n_align=100)
        entry["rpe"] = rpe_cases(ref, est, i_est, i_ref)
        result["pairs"][key] = entry
    json.dump(result, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
