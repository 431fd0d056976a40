#!/usr/bin/python3
"""CPU profile of a bundle's TorchScript pose head (docs/BENCHMARKS.md, "PoET pose head on the CPU").

    /usr/bin/python3 scripts/profile-pose-head.py BUNDLE_DIR plain|optimized THREADS

Runs the head on the bundle's self-test inputs once to warm up, then once under torch's profiler; prints
the process CPU time and wall time of that run, the largest difference from the self-test outputs and the
operators by self CPU time. `optimized` = torch.jit.freeze + optimize_for_inference, as `roe infer` does.
The system BLAS is whatever libblas.so.3 resolves to (LD_LIBRARY_PATH chooses another one).
"""
import json
import os
import sys
import time

import numpy as np
import torch

d, mode, threads = sys.argv[1], sys.argv[2], int(sys.argv[3])
torch.set_num_threads(threads)
b = json.load(open(os.path.join(d, "poet_bundle.json")))
ins = [torch.from_numpy(np.load(os.path.join(d, f))) for f in b["selftest"]["inputs"]]
refs = [np.load(os.path.join(d, f)) for f in b["selftest"]["outputs"]]
m = torch.jit.load(os.path.join(d, b["pose"]["file"])).eval()
if mode == "optimized":
    m = torch.jit.optimize_for_inference(torch.jit.freeze(m))
with torch.inference_mode():
    m(*ins)  # warm-up (the profiling executor optimises after the first run)
    c0, w0 = time.process_time(), time.perf_counter()
    with torch.autograd.profiler.profile() as prof:
        out = m(*ins)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
err = max(float(np.abs(o.numpy() - r).max()) for o, r in zip(out, refs))
print(f"== {mode}, {threads} thread(s), LD_LIBRARY_PATH={os.environ.get('LD_LIBRARY_PATH', '')}: "
      f"process CPU {cpu:.2f} s, wall {wall:.2f} s, max|diff| {err:.2g}")
print(prof.key_averages().table(sort_by="self_cpu_time_total", row_limit=8))
