#!/usr/bin/env python3
"""Cramér–Rao lower bound of the calibration states of a simulated dataset (issue 48; docs/refine.md §6).

Independent of roe's code: it reads the dataset's files only (roe.json's truth and detection-error model,
the true IMU states of mav0/state_groundtruth_estimate0, the IMU stream, detections/sim/detections.csv)
and builds, with numpy/scipy, the Fisher information of

  - one IMU state per image with a usable detection, x = [p, θ, v, b_g, b_a] (error state p + δp,
    R Exp(δθ), v + δv, b + δb), linked image to image by the IMU: the true error-state transition Φ and
    its process noise Q, integrated sample by sample from the IMU stream with the TRUE noise of roe.json
    (δṗ = δv, δv̇ = −R[f]×δθ − R δb_a − R n_a, δθ̇ = −[ω]×δθ − δb_g − n_g, ḃ = n_w): the trajectory is
    unknown, as in the batch;
  - the extrinsics T_I_C (p + δp, R Exp(δθ)) with the run config's prior (extrinsics_sigma_p_m /
    extrinsics_sigma_rot_deg per axis), and the first state's bias prior (init_sigma_gyro_bias /
    init_sigma_accel_bias);
  - one T_O_W per object (p + δp, R Exp(δθ)); the anchor's position and its rotation about W's z held
    (the gauge of roe run's anchor_gauge "position_yaw": those 4 directions are unobservable);
  - the detections, with the simulator's error model (docs/simulator.md §6): the translation error on the
    true viewing ray and across it (σ_ray, σ_lat growing with the depth, × (1 + border gain · cut) and
    × (1 + view gain · end-on)), the rotation error on the right (object frame) with σ_rot; the six
    standardised errors a first-order Gauss–Markov process per object with the true τ: each object's
    standardised errors are pre-whitened, ỹ_k = (y_k − ρ y_{k−1})/√(1 − ρ²), ρ = exp(−Δt/τ), which
    makes the information exact for that model. Gross detections (outliers, blurred frames, bad-frame
    runs: their error is beyond 8 σ of the model at the truth) are left out and the chain bridged, as
    is exact for the simulator (its Gauss–Markov state advances on every detection drawn); symmetric
    objects' detections are mapped to the equivalent nearest the truth (the simulator's default
    symmetries: a half turn about the model z for discrete ones, any turn about z for the bowl, id 13),
    a continuous symmetry's direction projected out. So the bound is optimistic: it knows which
    detections are gross, and the σ of each (the simulator's, not a model of them).

The bound is the inverse of the information, marginalised onto the extrinsics and the objects; the
objects are reported relative to the anchor (T_A_O = T_A_W T_W_O, position in A, rotation error on the
right), as roe calib-check compares them. Output (JSON, stdout or --json FILE): for the extrinsics and each
non-anchor object the 6x6 covariance [δp; δθ] and the root of its position and rotation traces (the RMS
error an efficient unbiased estimator would have), and the detections used / left out.

usage: scripts/crlb.py DATASET [--config configs/default.json] [--anchor ID] [--imu-noise-scale K]
                       [--gross-sigma 8] [--json OUT]
Needs numpy and scipy (python3-numpy, python3-scipy).
"""
import argparse
import json
import os
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial.transform import Rotation

G = np.array([0.0, 0.0, 9.81])  # specific force at rest is +g along W's z (docs/simulator.md §3)
SYMMETRIC_CONTINUOUS = {13}


def skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def read_csv(path, cols):
    rows = []
    with open(path) as f:
        for line in f:
            if not line.strip() or line.startswith('#') or line[0].isalpha():
                continue
            rows.append([float(x) for x in line.split(',')[:cols]])
    return np.array(rows)


def pose_of(j):
    return np.array(j['p'], float), Rotation.from_quat(j['q'])


def load(dataset):
    man = json.load(open(os.path.join(dataset, 'roe.json')))
    gt = read_csv(os.path.join(dataset, 'mav0/state_groundtruth_estimate0/data.csv'), 17)
    imu = read_csv(os.path.join(dataset, 'mav0/imu0/data.csv'), 7)
    dets = []
    with open(os.path.join(dataset, 'detections/sim/detections.csv')) as f:
        for line in f:
            if not line.strip() or line[0].isalpha() or line.startswith('#'):
                continue
            v = line.split(',')
            dets.append((int(v[0]), int(v[1]), [float(x) for x in v[2:9]]))
    return man, gt, imu, dets


def interp_truth(gt, t_ns):
    """True T_W_I (p, R) at t_ns: positions linear, rotations slerped between the rows around it."""
    t = gt[:, 0]
    i = np.clip(np.searchsorted(t, t_ns) - 1, 0, len(t) - 2)
    u = (t_ns - t[i]) / (t[i + 1] - t[i])
    p = gt[i, 1:4] + u[:, None] * (gt[i + 1, 1:4] - gt[i, 1:4])
    q0 = Rotation.from_quat(gt[i][:, [5, 6, 7, 4]])  # EuRoC columns: qw qx qy qz
    q1 = Rotation.from_quat(gt[i + 1][:, [5, 6, 7, 4]])
    d = (q0.inv() * q1).as_rotvec()
    return p, q0 * Rotation.from_rotvec(u[:, None] * d)


def predict_T_C_O(p_WI, R_WI, p_IC, R_IC, p_OW, R_OW):
    """T_C_O = (T_O_W T_W_I T_I_C)^-1, batched."""
    R_OC = R_OW * R_WI * R_IC
    p_OC = p_OW + R_OW.apply(p_WI + R_WI.apply(p_IC))
    R_CO = R_OC.inv()
    return -R_CO.apply(p_OC), R_CO


def detection_error(meas_t, meas_R, p_WI, R_WI, p_IC, R_IC, p_OW, R_OW):
    """e = [t − t̂ ; Log(R̂ᵀ R)] (camera-frame translation, object-frame rotation), batched (n x 6)."""
    t_hat, R_hat = predict_T_C_O(p_WI, R_WI, p_IC, R_IC, p_OW, R_OW)
    return np.hstack([meas_t - t_hat, (R_hat.inv() * meas_R).as_rotvec()])


def ray_axes(t):
    """(u1, u2, r) per row: r along t, u1 ∥ ŷ × r, u2 = r × u1 (the simulator's translation frame)."""
    r = t / np.linalg.norm(t, axis=1, keepdims=True)
    u1 = np.cross(np.array([0.0, 1.0, 0.0]), r)
    u1 /= np.linalg.norm(u1, axis=1, keepdims=True)
    return u1, np.cross(r, u1), r


def sigmas(noise, cam, t_true, R_true):
    """The simulator's σ_lat, σ_ray, σ_rot at the true T_C_O (bad frames are gross here: left out)."""
    z = np.maximum(t_true[:, 2], 0.0)
    k = np.ones(len(z))
    gain = noise.get('border_sigma_gain', 0.0)
    if gain and noise.get('object_radius_m', 0.0) > 0:
        u = cam['fx'] * t_true[:, 0] / t_true[:, 2] + cam['cx']
        v = cam['fy'] * t_true[:, 1] / t_true[:, 2] + cam['cy']
        r_px = min(cam['fx'], cam['fy']) * noise['object_radius_m'] / t_true[:, 2]
        d_edge = np.minimum.reduce([u, cam['width'] - u, v, cam['height'] - v])
        k *= 1.0 + gain * np.clip((r_px - d_edge) / (2 * r_px), 0.0, 1.0)
    vgain = noise.get('view_sigma_gain', 0.0)
    if vgain:
        sight = -R_true.inv().apply(t_true)
        k *= 1.0 + vgain * np.abs(sight[:, 2]) / np.linalg.norm(sight, axis=1)
    s_lat = (noise['lateral_sigma_m'] + noise['lateral_sigma_per_depth'] * z) * k
    s_ray = (noise['along_ray_sigma_m'] + noise['along_ray_sigma_per_depth'] * z) * k
    s_rot = np.deg2rad(noise['rotation_sigma_deg'] + noise.get('rotation_sigma_per_depth_deg', 0.0) * z) * k
    return s_lat, s_ray, s_rot


def standardiser(noise, cam, t_true, R_true, camera_axes):
    s_lat, s_ray, s_rot = sigmas(noise, cam, t_true, R_true)
    n = len(t_true)
    if camera_axes:
        u1, u2, r = (np.tile(np.eye(3)[i], (n, 1)) for i in range(3))
    else:
        u1, u2, r = ray_axes(t_true)
    S = np.zeros((n, 6, 6))
    S[:, 0, :3] = u1 / s_lat[:, None]
    S[:, 1, :3] = u2 / s_lat[:, None]
    S[:, 2, :3] = r / s_ray[:, None]
    for i in range(3):
        S[:, 3 + i, 3 + i] = 1.0 / s_rot
    return S


def imu_transitions(imu, gt, node_t, noise, scale):
    """Φ and Q of the error state between consecutive node times (true states, IMU at its samples)."""
    t = imu[:, 0]
    bg = np.interp(t, gt[:, 0], gt[:, 11]), np.interp(t, gt[:, 0], gt[:, 12]), np.interp(t, gt[:, 0], gt[:, 13])
    ba = np.interp(t, gt[:, 0], gt[:, 14]), np.interp(t, gt[:, 0], gt[:, 15]), np.interp(t, gt[:, 0], gt[:, 16])
    w = imu[:, 1:4] - np.stack(bg, 1)
    f = imu[:, 4:7] - np.stack(ba, 1)
    _, R = interp_truth(gt, t)
    Rm = R.as_matrix()
    sg, sa = scale * noise['gyro_noise_density'], scale * noise['accel_noise_density']
    wg, wa = scale * noise['gyro_random_walk'], scale * noise['accel_random_walk']
    Qc = np.diag([sa ** 2] * 3 + [sg ** 2] * 3 + [wg ** 2] * 3 + [wa ** 2] * 3)
    out = []
    j = np.searchsorted(t, node_t[0], side='right') - 1
    for k in range(len(node_t) - 1):
        Phi, Q = np.eye(15), np.zeros((15, 15))
        tk = node_t[k]
        while tk < node_t[k + 1]:
            t_next = min(t[j + 1], node_t[k + 1]) if j + 1 < len(t) else node_t[k + 1]
            dt = (t_next - tk) * 1e-9
            A = np.zeros((15, 15))
            A[0:3, 6:9] = np.eye(3)
            A[6:9, 3:6] = -Rm[j] @ skew(f[j])
            A[6:9, 12:15] = -Rm[j]
            A[3:6, 3:6] = -skew(w[j])
            A[3:6, 9:12] = -np.eye(3)
            Gm = np.zeros((15, 12))
            Gm[6:9, 0:3] = -Rm[j]
            Gm[3:6, 3:6] = -np.eye(3)
            Gm[9:15, 6:12] = np.eye(6)
            F = np.eye(15) + A * dt + A @ A * (dt * dt / 2)
            Q = F @ Q @ F.T + Gm @ Qc @ Gm.T * dt
            Phi = F @ Phi
            tk = t_next
            if j + 1 < len(t) and t_next >= t[j + 1]:
                j += 1
        out.append((Phi, Q))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('dataset')
    ap.add_argument('--config', default=os.path.join(os.path.dirname(__file__), '..', 'configs', 'default.json'))
    ap.add_argument('--anchor', type=int, default=None, help='anchor object id (default: the first detected)')
    ap.add_argument('--imu-noise-scale', type=float, default=1.0)
    ap.add_argument('--gross-sigma', type=float, default=8.0)
    ap.add_argument('--json', default=None)
    a = ap.parse_args()
    man, gt, imu, dets = load(a.dataset)
    filt = json.load(open(a.config)).get('filter', {})
    truth = man['truth']
    noise = truth['detection_noise']
    cam = man['camera']
    tau = noise['correlation_time_s']
    p_IC, R_IC = pose_of(truth['T_I_C'])
    T_W_O = {o['id']: pose_of(o['T_W_O']) for o in truth['objects']}
    symmetric = {o['id'] for o in man['objects'] if o.get('symmetric')}
    dets = [d for d in dets if d[1] in T_W_O]
    t_ns = np.array([d[0] for d in dets], dtype=np.int64)
    obj = np.array([d[1] for d in dets])
    meas_t = np.array([d[2][:3] for d in dets])
    meas_R = Rotation.from_quat([d[2][3:7] for d in dets])
    p_WI, R_WI = interp_truth(gt, t_ns.astype(float))
    p_OW = np.array([-(T_W_O[o][1].inv().apply(T_W_O[o][0])) for o in obj])
    R_OW = Rotation.from_quat([T_W_O[o][1].inv().as_quat() for o in obj])
    n = len(dets)
    p_ICn, R_ICn = np.tile(p_IC, (n, 1)), Rotation.from_quat(np.tile(R_IC.as_quat(), (n, 1)))
    t_true, R_true = predict_T_C_O(p_WI, R_WI, p_ICn, R_ICn, p_OW, R_OW)
    # Symmetric objects: the equivalent nearest the truth (a half turn about the model z), or the turn about z
    # projected out (the bowl).
    half = Rotation.from_rotvec([0, 0, np.pi])
    for i in range(n):
        if obj[i] in symmetric and obj[i] not in SYMMETRIC_CONTINUOUS:
            alt = meas_R[i] * half
            if np.linalg.norm((R_true[i].inv() * alt).as_rotvec()) < np.linalg.norm((R_true[i].inv() * meas_R[i]).as_rotvec()):
                q = meas_R.as_quat()
                q[i] = alt.as_quat()
                meas_R = Rotation.from_quat(q)
    S = standardiser(noise, cam, t_true, R_true, noise.get('translation_frame', 'ray') == 'camera')
    for i in range(n):
        if obj[i] in SYMMETRIC_CONTINUOUS:
            d = S[i] @ np.array([0, 0, 0, 0, 0, 1.0])
            d /= np.linalg.norm(d)
            S[i] = (np.eye(6) - np.outer(d, d)) @ S[i]
    e0 = detection_error(meas_t, meas_R, p_WI, R_WI, p_ICn, R_ICn, p_OW, R_OW)
    y0 = np.einsum('nij,nj->ni', S, e0)
    if any(o in SYMMETRIC_CONTINUOUS for o in obj):  # the turn about the axis is free: not an error
        pass
    good = np.sum(y0 ** 2, axis=1) <= a.gross_sigma ** 2
    # Nodes: the times with a good detection.
    node_t = np.unique(t_ns[good])
    node_of = np.searchsorted(node_t, t_ns)
    ids = sorted(set(obj[good]))
    anchor = a.anchor if a.anchor is not None else int(obj[good][np.argmin(t_ns[good])])
    N = len(node_t)
    nx = 15 * N
    col_extr = nx
    col_obj = {o: nx + 6 + 6 * i for i, o in enumerate(ids)}
    dim = nx + 6 + 6 * len(ids)
    # Detection Jacobians: central differences of e over the 18 tangent coordinates (node pose, T_I_C, T_O_W).
    h = 1e-6
    J = np.zeros((n, 6, 18))
    base = [p_WI, R_WI, p_ICn, R_ICn, p_OW, R_OW]
    for blk in range(3):
        for c in range(6):
            ep = []
            for s in (h, -h):
                args = list(base)
                step = np.zeros((n, 3))
                step[:, c % 3] = s
                if c < 3:
                    args[2 * blk] = args[2 * blk] + step
                else:
                    args[2 * blk + 1] = args[2 * blk + 1] * Rotation.from_rotvec(step)
                ep.append(detection_error(meas_t, meas_R, *args))
            J[:, :, 6 * blk + c] = (ep[0] - ep[1]) / (2 * h)
    # e ≈ n − (−J) ... the sign does not matter for the information: use A = S J.
    A = np.einsum('nij,njk->nik', S, J)
    rows, cols, vals = [], [], []

    def add_block(r0, c0, M):
        ii, jj = np.nonzero(np.abs(M) > 0)
        rows.extend(r0 + ii)
        cols.extend(c0 + jj)
        vals.extend(M[ii, jj])

    def columns(i):
        k = node_of[i]
        return [15 * k + c for c in range(6)] + [col_extr + c for c in range(6)] + [col_obj[obj[i]] + c for c in range(6)]

    # Whitened detection rows, object by object.
    r = 0
    used = 0
    for o in ids:
        idx = np.nonzero((obj == o) & good)[0]
        idx = idx[np.argsort(t_ns[idx], kind='stable')]
        prev = None
        for i in idx:
            rho = np.exp(-(t_ns[i] - t_ns[prev]) * 1e-9 / tau) if (prev is not None and tau > 0) else 0.0
            c = 1.0 / np.sqrt(1.0 - rho * rho)
            Mi = np.zeros((6, dim))
            Mi[:, columns(i)] += c * A[i]
            if rho > 0:
                Mi[:, columns(prev)] -= c * rho * A[prev]
            nz = np.nonzero(np.any(Mi != 0, axis=0))[0]
            for j, cc in enumerate(nz):
                for rr in range(6):
                    if Mi[rr, cc] != 0:
                        rows.append(r + rr)
                        cols.append(cc)
                        vals.append(Mi[rr, cc])
            r += 6
            prev = i
            used += 1
    # IMU: L_k (x_{k+1} − Φ x_k) with Lᵀ L = Q⁻¹.
    trans = imu_transitions(imu, gt, node_t, truth['imu_noise'], a.imu_noise_scale)
    for k, (Phi, Q) in enumerate(trans):
        L = np.linalg.cholesky(np.linalg.inv(Q + 1e-18 * np.eye(15))).T
        add_block(r, 15 * (k + 1), L)
        add_block(r, 15 * k, -L @ Phi)
        r += 15
    # Priors: the extrinsics, the first state's biases.
    sp_ = np.array([filt.get('extrinsics_sigma_p_m', 0.02)] * 3 + [np.deg2rad(filt.get('extrinsics_sigma_rot_deg', 2.0))] * 3)
    add_block(r, col_extr, np.diag(1.0 / sp_))
    r += 6
    sb = np.array([filt.get('init_sigma_gyro_bias', 0.01)] * 3 + [filt.get('init_sigma_accel_bias', 0.1)] * 3)
    add_block(r, 9, np.diag(1.0 / sb))
    r += 6
    Wm = sp.csr_matrix((vals, (rows, cols)), shape=(r, dim))
    H = (Wm.T @ Wm).tocsc()
    # Gauge: the anchor's position and its rotation about W's z are held.
    fixed = set(range(col_obj[anchor], col_obj[anchor] + 3)) | {col_obj[anchor] + 5}
    keep = np.array([c for c in range(dim) if c not in fixed])
    H = H[keep][:, keep]
    pos = {c: i for i, c in enumerate(keep)}
    calib = [pos[c] for c in range(nx, dim) if c in pos]
    nodes = np.arange(nx)
    Hnn = H[nodes][:, nodes].tocsc()
    Hnc = H[nodes][:, calib].toarray()
    Hcc = H[calib][:, calib].toarray()
    lu = spla.splu(Hnn)
    Sc = Hcc - Hnc.T @ lu.solve(Hnc)
    C = np.linalg.inv(Sc)
    cidx = {c: i for i, c in enumerate(c for c in range(nx, dim) if c in pos)}

    def cov_of(cols_):
        m = np.zeros((len(cols_), len(cols_)))
        for i, ci in enumerate(cols_):
            for j, cj in enumerate(cols_):
                if ci in cidx and cj in cidx:
                    m[i, j] = C[cidx[ci], cidx[cj]]
        return m

    out = {'dataset': a.dataset, 'anchor': anchor, 'tau_s': tau, 'imu_noise_scale': a.imu_noise_scale,
           'detections_used': used, 'detections_left_out': int(n - used), 'nodes': N}
    Ce = cov_of(list(range(col_extr, col_extr + 6)))
    out['extrinsics'] = {'cov': Ce.tolist(), 'rms_position_m': float(np.sqrt(np.trace(Ce[:3, :3]))),
                         'rms_rotation_deg': float(np.rad2deg(np.sqrt(np.trace(Ce[3:, 3:]))))}
    # Objects relative to the anchor: T_A_O = T_A_W T_W_O; its error [p_A_O; Log(R̂_A_Oᵀ R_A_O)] against the
    # anchor's and the object's tangent (central differences).
    pa, Ra = -(T_W_O[anchor][1].inv().apply(T_W_O[anchor][0])), T_W_O[anchor][1].inv()
    out['objects'] = {}
    for o in ids:
        if o == anchor:
            continue
        po, Ro = -(T_W_O[o][1].inv().apply(T_W_O[o][0])), T_W_O[o][1].inv()

        def rel(pa_, Ra_, po_, Ro_):
            R_AO = Ra_ * Ro_.inv()
            return pa_ - R_AO.apply(po_), R_AO

        p0, R0 = rel(pa, Ra, po, Ro)
        Jr = np.zeros((6, 12))
        for c in range(12):
            vals_ = []
            for s in (h, -h):
                x = [pa.copy(), Ra, po.copy(), Ro]
                b = 0 if c < 6 else 2
                cc = c % 6
                if cc < 3:
                    x[b][cc] += s
                else:
                    st = np.zeros(3)
                    st[cc - 3] = s
                    x[b + 1] = x[b + 1] * Rotation.from_rotvec(st)
                p1, R1 = rel(*x)
                vals_.append(np.concatenate([p1 - p0, (R0.inv() * R1).as_rotvec()]))
            Jr[:, c] = (vals_[0] - vals_[1]) / (2 * h)
        Cc = cov_of(list(range(col_obj[anchor], col_obj[anchor] + 6)) + list(range(col_obj[o], col_obj[o] + 6)))
        Cr = Jr @ Cc @ Jr.T
        out['objects'][str(o)] = {'symmetric': bool(o in symmetric), 'cov': Cr.tolist(),
                                  'rms_position_m': float(np.sqrt(np.trace(Cr[:3, :3]))),
                                  'rms_rotation_deg': float(np.rad2deg(np.sqrt(max(np.trace(Cr[3:, 3:]), 0.0))))}
    text = json.dumps(out, indent=1)
    if a.json:
        with open(a.json, 'w') as f:
            f.write(text + '\n')
    else:
        print(text)


if __name__ == '__main__':
    sys.exit(main())
