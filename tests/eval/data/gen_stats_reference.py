#!/usr/bin/python3
"""Reference values for tests/eval/test_stats.cpp, computed independently with scipy (Debian
python3-scipy 1.10): Student-t quantiles, the mean's t confidence interval (scipy.stats.t.interval)
and the Wilcoxon signed-rank test with scipy's defaults (scipy.stats.wilcoxon).

usage: /usr/bin/python3 tests/eval/data/gen_stats_reference.py > tests/eval/data/stats_reference.json
"""
import json
import warnings

import numpy as np
import scipy
from scipy import stats

rng = np.random.default_rng(20261201)

quantiles = []
for dof in (1, 2, 3, 4, 5, 9, 19, 29, 49, 120):
    for p in (0.6, 0.9, 0.95, 0.975, 0.995, 0.9995, 0.025):
        quantiles.append({"p": p, "dof": dof, "t": float(stats.t.ppf(p, dof))})


def interval(x, conf):
    x = np.asarray(x, dtype=float)
    m = float(np.mean(x))
    s = float(np.std(x, ddof=1))
    lo, hi = stats.t.interval(conf, len(x) - 1, loc=m, scale=s / np.sqrt(len(x)))
    # roe's names (docs/eval.md "std"): std is numpy's default (ddof 0), std_sample the ddof-1 one
    return {"values": x.tolist(), "confidence": conf, "mean": m, "std_sample": s,
            "std": float(np.std(x, ddof=0)), "ci_low": float(lo), "ci_high": float(hi)}


samples = [
    interval([0.061, 0.058, 0.072, 0.049, 0.066, 0.070, 0.055, 0.063, 0.059, 0.068], 0.95),
    interval([1.0, 2.0], 0.95),
    interval([3.2, 3.1, 3.3], 0.99),
    interval(rng.normal(0.1, 0.02, 30).round(6), 0.95),
    interval(rng.lognormal(-3, 0.5, 7).round(6), 0.9),
]


def wilcoxon_case(name, a, b):
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    d = b - a
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = stats.wilcoxon(d)
    n_zero = int(np.sum(d == 0))
    method = "exact" if len(d) <= 50 and n_zero == 0 else "normal"
    return {"name": name, "a": a.tolist(), "b": b.tolist(), "statistic": float(res.statistic),
            "p_value": float(res.pvalue), "method": method}


a10 = [0.061, 0.058, 0.072, 0.049, 0.066, 0.070, 0.055, 0.063, 0.059, 0.068]
b10 = [0.052, 0.060, 0.061, 0.045, 0.059, 0.071, 0.050, 0.057, 0.054, 0.060]
wilcoxon = [
    wilcoxon_case("exact, no ties", a10, b10),
    wilcoxon_case("exact, all one sign", [1, 2, 3, 4, 5, 6], [1.5, 2.7, 3.1, 4.9, 5.2, 6.8]),
    # |b - a| ties (half ranks; scipy truncates r+ in the exact distribution)
    wilcoxon_case("exact, ties", [0, 0, 0, 0, 0, 0, 0, 0], [1, -1, 2, 2, -3, 4, 5, -2]),
    # a zero difference: scipy switches to the normal approximation and drops the zero
    wilcoxon_case("normal, zeros", [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12],
                  [1, 2.5, 2.1, 4.8, 5.3, 6.0, 7.9, 8.4, 9.6, 10.2, 11.7, 13.1]),
    wilcoxon_case("normal, zeros and ties", [0] * 15, [0, 0, 1, -1, 1, 2, -2, 3, 3, 3, -4, 5, 6, -6, 7]),
    wilcoxon_case("normal, n > 50", rng.normal(0, 1, 60).round(4), rng.normal(0.3, 1, 60).round(4)),
    wilcoxon_case("exact, symmetric centre", [0, 0, 0, 0], [1, -2, -3, 4]),
]

print(json.dumps({"generator": "tests/eval/data/gen_stats_reference.py", "scipy": scipy.__version__,
                  "numpy": np.__version__, "t_quantiles": quantiles, "samples": samples,
                  "wilcoxon": wilcoxon}, indent=1))
