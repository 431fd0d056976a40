#!/usr/bin/python3
"""How much a filter can gain from modelling time-correlated detection errors (docs/RESULTS.md §5).

A 1-D toy of the camera-to-object position along the viewing ray: a double integrator driven by the
IMU's in-flight accelerometer noise (0.025 m/s^2/sqrt(Hz), what the filter's propagation error grows
with), observed at 30 Hz with a first-order Gauss-Markov error (sigma 0.1 m, tau 0.3 s: the simulator's
PoET-like errors, docs/simulator.md §6). Compares the position RMSE of Kalman filters that treat the
error as white with R = k sigma^2, against the filter that augments the state with the Gauss-Markov
error (the exact model). Usage: scripts/correlated-noise-toy.py [seed]
"""
import sys

import numpy as np


def main():
    rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 1)
    dt, qa, sig, tau = 1 / 30, 0.025, 0.1, 0.3
    rho = np.exp(-dt / tau)
    n = 30 * 600
    F = np.array([[1, dt], [0, 1]])
    Q = qa**2 * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    x = np.zeros((n, 2))
    b = np.zeros(n)
    Lq = np.linalg.cholesky(Q)
    for k in range(1, n):
        x[k] = F @ x[k - 1] + Lq @ rng.standard_normal(2)
        b[k] = rho * b[k - 1] + sig * np.sqrt(1 - rho**2) * rng.standard_normal()
    z = x[:, 0] + b

    def run(Fa, Qa, H, R, P0, pred):
        m, P, err = np.zeros(len(P0)), np.diag(P0), []
        for k in range(n):
            if k:
                m, P = Fa @ m, Fa @ P @ Fa.T + Qa
            S = H @ P @ H.T + R
            K = P @ H.T / S
            m = m + (K * (z[k] - pred(m))).ravel()
            P = (np.eye(len(m)) - K @ H) @ P
            err.append(m[0] - x[k, 0])
        e = np.array(err[n // 10:])
        return np.sqrt(np.mean(e**2))

    print("rho %.3f per frame, (1+rho)/(1-rho) = %.1f" % (rho, (1 + rho) / (1 - rho)))
    for k in [1, 4, 9, 18, 36, 72]:
        r = run(F, Q, np.array([[1.0, 0]]), k * sig**2, [1, 1], lambda m: m[0])
        print("white error model, R = %2d sigma^2: position RMSE %.4f m" % (k, r))
    Fa = np.eye(3)
    Fa[:2, :2] = F
    Fa[2, 2] = rho
    Qa = np.zeros((3, 3))
    Qa[:2, :2] = Q
    Qa[2, 2] = sig**2 * (1 - rho**2)
    r = run(Fa, Qa, np.array([[1.0, 0, 1]]), 1e-4 * sig**2, [1, 1, sig**2], lambda m: m[0] + m[2])
    print("Gauss-Markov error in the state (exact): position RMSE %.4f m" % r)


if __name__ == "__main__":
    main()
