#!/usr/bin/env python3
"""Runs the same commands with two roe builds and compares every output file (issue 39: a step of the
house must not change behaviour).

usage: compare-builds.py OLD_ROE NEW_ROE [--work DIR] [--presets a,b,..] [--seeds 1,2] [--shared DIR]

Cases: the README's first run (simulate paper-seq4 20 s, run, eval, eval -as with RPE, --summary,
calib-check --json), its report (HTML and --json; and the report of a folder with the trajectory alone, where
calib-check cannot run) and refine (--json; when the build has roe-refine), the demo's run and eval of
datasets/sample, a sweep (plan, run of a job that finishes and one that fails, status, aggregate, emit, and a
job left pending), every preset x seed (simulate, run, eval), and the evaluations of the real bags in
../shared/data (a ROS 2 MCAP and a ROS 1 bag), when present. Every file either build writes is compared: JSON
after removing the fields that name the roe version or measure time (roe_version, timing_s, wall/elapsed
seconds) and paths inside the work folder; every other file byte for byte, after the same replacement of the
work folders in text files (and, in the report's HTML, of its temporary evaluation folder, whose name is
random, and of the run's timing_s rows its configuration table shows). Prints
one line per difference and a summary; exit 0 when all match.
"""
import argparse
import json
import pathlib
import re
import shutil
import subprocess
import sys

VOLATILE_KEYS = {"roe_version", "timing_s", "wall_s", "elapsed_s", "cpu_s"}
# roe report evaluates into a temporary folder beside the report (io::OutputDir: a random name), which the
# evaluation report embedded in the HTML names.
REPORT_TMP = re.compile(r"\.work\.tmp-[0-9a-f]+-[0-9]+-[0-9]+-[0-9a-f]+")
# The report's configuration table shows run.json's timing_s (wall seconds: volatile, as in JSON).
REPORT_TIMING = re.compile(r"<tr><th>timing_s\.[^<]*</th><td>[^<]*</td></tr>")

# The sweep case: a job that finishes, one that fails (an anchor the dataset does not have) and one on the
# demo's dataset folder that is left pending.
SWEEP_SPEC = """{
  "format": "roe-sweep-spec/1",
  "description": "compare-builds: a done job, a failed job, a pending job on a dataset folder",
  "axes": [
    {"datasets": [{"preset": "paper-seq1", "duration_s": 3}], "seeds": [1], "configs": ["default"]},
    {"datasets": [{"preset": "paper-seq1", "duration_s": 3}], "seeds": [1], "configs": ["default"],
     "overrides": {"filter.anchor_id": [99]}},
    {"datasets": [{"path": "SAMPLE"}], "configs": ["paper"], "detections": ["sim"]}
  ]
}
"""


def normalise(obj, roots, volatile=VOLATILE_KEYS):
    """The JSON value without volatile fields; the build-specific work folders replaced by one token."""
    if isinstance(obj, dict):
        return {k: normalise(v, roots, volatile) for k, v in obj.items() if k not in volatile}
    if isinstance(obj, list):
        return [normalise(v, roots, volatile) for v in obj]
    if isinstance(obj, str):
        for r in roots:
            obj = obj.replace(r, "<work>")
        return obj
    return obj


def run(roe, args, cwd, stdout_name=None):
    p = subprocess.run([str(roe)] + args, cwd=cwd, capture_output=True, text=True)
    if stdout_name:
        (cwd / stdout_name).write_text(p.stdout)
    (cwd / "exit_codes.txt").open("a").write(f"{p.returncode} roe {' '.join(args)}\n")
    return p.returncode


def cases(roe, work, presets, seeds, shared):
    """Runs every case with `roe` inside `work` (an empty folder)."""
    src = pathlib.Path(__file__).resolve().parent.parent
    # The README's first run.
    run(roe, ["simulate", "--preset", "paper-seq4", "--seed", "1", "--duration", "20", "--out", "seq4", "-q"], work)
    run(roe, ["run", "seq4", "--out", "runs/seq4", "-q"], work)
    run(roe, ["eval", "runs/seq4", "-q"], work)
    run(roe, ["eval", "runs/seq4", "-as", "--rpe-delta", "1,2", "--label", "sim3", "--out", "runs/seq4/eval-sim3",
              "-q"], work)
    run(roe, ["eval", "--summary", "runs/seq4/eval", "runs/seq4/eval-sim3", "--out", "table.md", "-q"], work)
    run(roe, ["calib-check", "runs/seq4", "--json"], work, "calib-check.json")
    # Its report (the HTML embeds the figures: python3 with matplotlib), and one of the trajectory alone.
    run(roe, ["report", "runs/seq4", "--out", "report.html", "--json"], work, "report-summary.json")
    (work / "traj").mkdir()
    shutil.copy(work / "runs/seq4/trajectory.csv", work / "traj/trajectory.csv")
    run(roe, ["report", "traj", "--gt", "seq4", "--out", "report-traj.html", "--json"], work, "report-traj.json")
    if (roe.parent / "roe-refine").exists():
        run(roe, ["refine", "runs/seq4", "--out", "runs/seq4-refined", "--json", "-q"], work, "refine.json")
    # A sweep.
    (work / "spec.json").write_text(SWEEP_SPEC.replace("SAMPLE", str(src / "datasets/sample")))
    run(roe, ["sweep", "plan", "spec.json", "--out", "sw", "-q"], work)
    run(roe, ["sweep", "run", "sw", "--index", "0", "--json"], work, "sweep-run-0.json")
    run(roe, ["sweep", "run", "sw", "--index", "1", "--json"], work, "sweep-run-1.json")
    run(roe, ["sweep", "status", "sw", "--json"], work, "sweep-status.json")
    run(roe, ["sweep", "aggregate", "sw", "--out", "sw-tables", "--json"], work, "sweep-aggregate.json")
    run(roe, ["sweep", "emit", "slurm", "sw", "--out", "sw.sbatch", "--roe", "roe", "-q"], work)
    # The demo's data.
    run(roe, ["run", str(src / "datasets/sample"), "--out", "demo/run", "-q"], work)
    run(roe, ["eval", "demo/run", "-q"], work)
    # Presets x seeds.
    for p in presets:
        for s in seeds:
            d = f"presets/{p}-{s}"
            run(roe, ["simulate", "--preset", p, "--seed", str(s), "--duration", "30", "--out", d + "/data", "-q"], work)
            run(roe, ["run", d + "/data", "--out", d + "/run", "-q"], work)
            run(roe, ["eval", d + "/run", "-q"], work)
    # Real bags.
    mcap = shared / "rosbag2/nav2_turtlebot.mcap"
    if mcap.exists():
        run(roe, ["eval", f"{mcap}:/odom", "--gt", f"{mcap}:/amcl_pose", "--align", "se3", "--out", "bags/nav2", "-q"],
            work)
    bag1 = shared / "rosbag/evo_ROS_example.bag"
    if bag1.exists():
        run(roe, ["eval", f"{bag1}:ORB-SLAM", "--gt", f"{bag1}:groundtruth", "--out", "bags/ros1", "-q"], work)


def compare(a, b):
    diffs = []
    files_a = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
    files_b = {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
    for f in sorted(files_a ^ files_b):
        diffs.append(f"only in {'old' if f in files_a else 'new'}: {f}")
    roots = [str(a.resolve()), str(b.resolve())]
    for f in sorted(files_a & files_b):
        x, y = (a / f).read_bytes(), (b / f).read_bytes()
        if x == y:
            continue
        if f.suffix == ".json":
            # roe report's summary: "bytes" is the HTML's size, which the run's timings it shows change (the
            # HTML itself is compared below them).
            volatile = VOLATILE_KEYS | {"bytes"} if f.name.startswith("report-") else VOLATILE_KEYS
            try:
                if normalise(json.loads(x), roots, volatile) == normalise(json.loads(y), roots, volatile):
                    continue
            except ValueError:
                pass
        else:  # text that names the work folder (a dataset path in summary.csv, table.md)
            try:
                tx, ty = (REPORT_TIMING.sub("<timing>", REPORT_TMP.sub("<tmp>", t.decode().replace(r, "<work>")))
                          for t, r in ((x, roots[0]), (y, roots[1])))
                if tx == ty:
                    continue
            except UnicodeDecodeError:
                pass
        diffs.append(f"differs: {f}")
    return diffs, len(files_a | files_b)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("old_roe")
    ap.add_argument("new_roe")
    ap.add_argument("--work", default="compare-builds")
    ap.add_argument("--presets", default="paper-seq1,paper-seq2,paper-seq3,paper-seq4,paper-seq5,paper-seq6,"
                                         "paper-seq7,paper-seq8")
    ap.add_argument("--seeds", default="1,2")
    ap.add_argument("--shared", default=str(pathlib.Path(__file__).resolve().parent.parent.parent / "shared/data"))
    a = ap.parse_args()
    work = pathlib.Path(a.work)
    if work.exists():
        shutil.rmtree(work)
    presets = [p for p in a.presets.split(",") if p]
    seeds = [int(s) for s in a.seeds.split(",") if s]
    for name, roe in (("old", a.old_roe), ("new", a.new_roe)):
        d = work / name
        d.mkdir(parents=True)
        cases(pathlib.Path(roe).resolve(), d, presets, seeds, pathlib.Path(a.shared))
    diffs, n = compare(work / "old", work / "new")
    for d in diffs:
        print(d)
    print(f"{n} files compared, {len(diffs)} differ")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
