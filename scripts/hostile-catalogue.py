#!/usr/bin/env python3
"""A catalogue of hostile inputs for every reader of roe, generated (not hand-listed), run against the roe binary.

Each case takes a valid input (the embedded sample dataset, the real files in ../shared/data when present,
and small files made here), damages it with one operator (truncation, bit flips, BOM, UTF-16, CRLF,
NaN/Inf, huge numbers, unsorted and duplicated stamps, degenerate quaternions, lying lengths in a bag,
deep nesting, YAML aliases, special files in its place) and runs the command that reads it, limited to
10 s and 1 GB of address space. The contract (docs/TESTING.md, "Hostile inputs"): every case exits 0
(where the operator's row in OPERATORS says the input stays valid: a BOM, CRLF), 1 (a data problem) or
2 (an input error, located), and never 3, a signal or the time limit.

usage: hostile-catalogue.py ROE_BINARY [--jobs N] [--list] [--keep DIR] [--only SUBSTRING]
Exit status 0 when every case meets the contract; the cases that do not are printed.
"""
import argparse
import concurrent.futures as futures
import json
import os
import random
import resource
import shutil
import signal
import socket
import stat
import struct
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "data")
SAMPLE = os.path.join(ROOT, "datasets", "sample")
TIME_LIMIT_S = 10
MEMORY_LIMIT = 1 << 30  # bytes of address space

# ----------------------------------------------------------------------------------------------------------
# Byte operators. Each takes the valid bytes and a seeded random generator, returns the damaged bytes.
# ----------------------------------------------------------------------------------------------------------


def lines_of(b):
    return b.split(b"\n")


def data_line_indices(ls):
    """Lines that look like data rows: non-empty, not a comment, start with a digit or a sign."""
    return [i for i, l in enumerate(ls) if l[:1].isdigit() or l[:1] in (b"-", b"+")][1:]


def replace_number(b, rng, token):
    """Replaces one numeric cell of a data row (not the first: the stamp) by `token`."""
    ls = lines_of(b)
    rows = data_line_indices(ls)
    if not rows:
        return b + b"\n" + token
    i = rows[len(rows) // 2]
    sep = b"," if b"," in ls[i] else b" "
    cells = ls[i].split(sep)
    k = 1 + rng.randrange(max(1, len(cells) - 1))
    cells[min(k, len(cells) - 1)] = token
    ls[i] = sep.join(cells)
    return b"\n".join(ls)


def swap_rows(b, rng):
    ls = lines_of(b)
    rows = data_line_indices(ls)
    if len(rows) < 3:
        return b
    i = rows[len(rows) // 3]
    j = rows[2 * len(rows) // 3]
    ls[i], ls[j] = ls[j], ls[i]
    return b"\n".join(ls)


def duplicate_row(b, rng):
    ls = lines_of(b)
    rows = data_line_indices(ls)
    if not rows:
        return b
    i = rows[len(rows) // 2]
    ls.insert(i + 1, ls[i])
    return b"\n".join(ls)


def zero_quaternion(b, rng):
    """Sets the four cells of a pose row's quaternion to 0 (the last four for TUM, 4..7 for EuRoC)."""
    ls = lines_of(b)
    rows = data_line_indices(ls)
    if not rows:
        return b
    i = rows[len(rows) // 2]
    sep = b"," if b"," in ls[i] else b" "
    cells = ls[i].split(sep)
    if len(cells) >= 8:
        span = range(len(cells) - 4, len(cells)) if sep == b" " else range(4, 8)
        for k in span:
            cells[k] = b"0"
    ls[i] = sep.join(cells)
    return b"\n".join(ls)


def bit_flips(b, rng, n=16):
    if not b:
        return b
    a = bytearray(b)
    for _ in range(n):
        k = rng.randrange(len(a))
        a[k] ^= 1 << rng.randrange(8)
    return bytes(a)


def utf16(b):
    return b.decode("latin-1").encode("utf-16")


# name -> (function(bytes, rng) -> bytes, exits allowed). {0, 1, 2} = the input may stay valid or not.
ANY = {0, 1, 2}
OPERATORS = {
    "truncate-10%": (lambda b, r: b[: len(b) // 10], ANY),
    "truncate-50%": (lambda b, r: b[: len(b) // 2], ANY),
    "truncate-last-byte": (lambda b, r: b[:-1], ANY),
    "truncate-in-last-line": (lambda b, r: b[: b.rstrip(b"\n").rfind(b"\n") + 4] if b"\n" in b else b[:5], ANY),
    "empty": (lambda b, r: b"", {1, 2}),
    "bit-flips": (bit_flips, ANY),
    "utf8-bom": (lambda b, r: b"\xef\xbb\xbf" + b, ANY),
    "utf16": (lambda b, r: utf16(b), ANY),  # YAML allows UTF-16 (yaml-cpp reads it); CSV and JSON refuse it
    "crlf": (lambda b, r: b.replace(b"\n", b"\r\n"), ANY),
    "nan": (lambda b, r: replace_number(b, r, b"nan"), ANY),
    "inf": (lambda b, r: replace_number(b, r, b"-inf"), ANY),
    "huge-float": (lambda b, r: replace_number(b, r, b"1e999"), ANY),
    "huge-int": (lambda b, r: replace_number(b, r, b"99999999999999999999999"), ANY),
    "unsorted-stamps": (swap_rows, ANY),
    "duplicated-stamp": (duplicate_row, ANY),
    "zero-quaternion": (zero_quaternion, ANY),
    "nul-bytes": (lambda b, r: b[: len(b) // 2] + b"\0" * 64 + b[len(b) // 2 :], ANY),
    "long-line": (lambda b, r: b + b"1" * (4 << 20) + b"\n", ANY),
}
TEXT_OPERATORS = list(OPERATORS)
BINARY_OPERATORS = ["truncate-10%", "truncate-50%", "truncate-last-byte", "empty", "bit-flips", "utf8-bom", "nul-bytes"]

# Special files put where the input should be: all are input errors, at once.
SPECIAL = ["dev-zero", "fifo", "folder", "symlink-loop", "dangling-symlink"]


def make_special(path, kind):
    if kind == "dev-zero":
        os.symlink("/dev/zero", path)
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        os.makedirs(path)
    elif kind == "symlink-loop":
        os.symlink(os.path.basename(path), path)
    elif kind == "dangling-symlink":
        os.symlink(path + ".absent", path)


# ----------------------------------------------------------------------------------------------------------
# Valid inputs and the commands that read them.
# ----------------------------------------------------------------------------------------------------------


def read(path):
    with open(path, "rb") as f:
        return f.read()


CAMCHAIN = (
    b"cam0:\n  T_cam_imu:\n  - [1.0, 0.0, 0.0, 0.1]\n  - [0.0, 1.0, 0.0, 0.0]\n  - [0.0, 0.0, 1.0, 0.0]\n"
    b"  - [0.0, 0.0, 0.0, 1.0]\n  camera_model: pinhole\n  distortion_coeffs: [0, 0, 0, 0]\n"
    b"  distortion_model: radtan\n  intrinsics: [600, 600, 320, 240]\n  resolution: [640, 480]\n"
    b"  timeshift_cam_imu: -0.01\n"
)
IMU_YAML = (
    b"accelerometer_noise_density: 0.002\naccelerometer_random_walk: 0.003\n"
    b"gyroscope_noise_density: 0.00016\ngyroscope_random_walk: 0.000019\nrostopic: /imu0\nupdate_rate: 200.0\n"
)


def poet_results():
    """A valid results.json for the first frames of the sample dataset."""
    names = [l.split(b",")[1].strip().decode() for l in read(os.path.join(SAMPLE, "mav0/cam0/data.csv")).splitlines()[1:4]]
    det = {"t": [0.1, 0.2, 0.8], "rot": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "box": [0.5, 0.5, 0.1, 0.1], "class": 1}
    return json.dumps({os.path.splitext(n)[0]: {"0": det} for n in names}, indent=1).encode()


def deep_json(depth):
    return b"[" * depth + b"]" * depth


def billion_laughs():
    y = b"a0: &a0 [x, x, x, x, x, x, x, x, x]\n"
    for i in range(1, 10):
        y += b"a%d: &a%d [" % (i, i) + b", ".join([b"*a%d" % (i - 1)] * 9) + b"]\n"
    return y


def lying_bag_length(b, offset_field):
    """A ROS bag whose first record (after the 13-byte magic) claims a header (0) or data (1) length of 2^31."""
    a = bytearray(b)
    if len(a) < 17:
        return bytes(a)
    if offset_field == 0:
        struct.pack_into("<I", a, 13, 0x7FFFFFFF)
    else:
        hlen = struct.unpack_from("<I", a, 13)[0]
        if 17 + hlen + 4 <= len(a):
            struct.pack_into("<I", a, 17 + hlen, 0x7FFFFFFF)
    return bytes(a)


class Case:
    """`check(d)`, when given, is a post-condition on the case folder after the run (None when it holds, else
    what is wrong); `max_rss_mb` bounds the peak resident memory (measured with /usr/bin/time); `expect`, a
    text the error message (stderr's last line) must contain, so that a case refused for another reason
    does not pass; `max_stderr` bounds the bytes written to stderr (a message naming 200 000 frames)."""

    def __init__(self, name, setup, argv, allowed, check=None, max_rss_mb=None, time_limit_s=TIME_LIMIT_S,
                 expect=None, max_stderr=None):
        self.name, self.setup, self.argv, self.allowed = name, setup, argv, allowed
        self.check, self.max_rss_mb, self.time_limit_s = check, max_rss_mb, time_limit_s
        self.expect, self.max_stderr = expect, max_stderr


ROE = None  # the binary under test, for setups that need roe itself (a planned sweep, a run folder)
WORKDIR = None  # the folder of the case folders (and of the folders cases share, _cache/)


def roe_setup(d, *args):
    subprocess.run([ROE] + list(args) + ["-q"], cwd=d, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, env=dict(os.environ, TMPDIR=os.path.join(d, "tmp")))


def dataset_copy(dst):
    """The sample dataset, hard-linked (every write of roe goes through a rename, never into a file)."""
    shutil.copytree(SAMPLE, dst, copy_function=os.link)


def put(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    if os.path.lexists(path):
        os.unlink(path)
    with open(path, "wb") as f:
        f.write(data)


def cases():
    out = []
    rng_seed = 2811

    def add_file_cases(family, filename, base, ops, argv, ds_needed=False, rel=None):
        """One case per operator and per special file: `rel` is the path of the damaged file inside the
        dataset copy (a dataset's own file), else `filename` lives beside it."""
        for op in ops:
            fn, allowed = OPERATORS[op]

            def setup(d, fn=fn, op=op):
                if ds_needed:
                    dataset_copy(os.path.join(d, "ds"))
                damaged = fn(base, random.Random(rng_seed + sum(op.encode())))
                put(os.path.join(d, rel or filename), damaged)

            out.append(Case(f"{family}/{op}", setup, argv, allowed))
        for kind in SPECIAL:

            def setup(d, kind=kind):
                if ds_needed:
                    dataset_copy(os.path.join(d, "ds"))
                p = os.path.join(d, rel or filename)
                if os.path.lexists(p):
                    os.unlink(p)
                os.makedirs(os.path.dirname(p), exist_ok=True)
                make_special(p, kind)

            out.append(Case(f"{family}/{kind}", setup, argv, {2}))

    # Trajectories (roe eval), estimate side: a TUM file (real when ../shared is present).
    est = os.path.join(SHARED, "eval/freiburg1_xyz-rgbdslam.txt")
    gt = os.path.join(SHARED, "eval/freiburg1_xyz-groundtruth.txt")
    if os.path.exists(est) and os.path.exists(gt):
        add_file_cases("eval-tum", "est.txt", read(est), TEXT_OPERATORS, ["eval", "est.txt", "--gt", gt, "--no-out"])
    euroc_gt = os.path.join(SAMPLE, "mav0/state_groundtruth_estimate0/data.csv")
    add_file_cases("eval-euroc-gt", "gt.csv", read(euroc_gt), TEXT_OPERATORS,
                   ["eval", os.path.join(SAMPLE, "mav0/mocap0/data.csv"), "--gt", "gt.csv", "--gt-format", "euroc",
                    "--est-format", "euroc", "--no-out"])
    # Mocap exports (roe import mocap).
    motive = os.path.join(SHARED, "mocap/sample_optitrack_take_v1.21.csv")
    if os.path.exists(motive):
        add_file_cases("import-motive", "take.csv", read(motive), TEXT_OPERATORS,
                       ["import", "mocap", "take.csv", "--into", "newds"])
    add_file_cases("import-euroc-mocap", "mocap.csv", read(os.path.join(SAMPLE, "mav0/mocap0/data.csv")),
                   ["truncate-in-last-line", "nan", "huge-int", "unsorted-stamps", "zero-quaternion", "utf8-bom", "crlf"],
                   ["import", "mocap", "mocap.csv", "--into", "newds", "--format", "euroc"])
    bag = os.path.join(SHARED, "rosbag/evo_ROS_example.bag")
    if os.path.exists(bag):
        b = read(bag)
        add_file_cases("import-bag", "poses.bag", b, BINARY_OPERATORS,
                       ["import", "mocap", "poses.bag", "--into", "newds", "--topic", "groundtruth"])
        for field in (0, 1):
            out.append(Case(f"import-bag/lying-length-{'header' if field == 0 else 'data'}",
                            lambda d, b=b, field=field: put(os.path.join(d, "poses.bag"), lying_bag_length(b, field)),
                            ["import", "mocap", "poses.bag", "--into", "newds", "--topic", "groundtruth"], {1, 2}))
    # Kalibr (roe import kalibr).
    add_file_cases("import-kalibr", "camchain.yaml", CAMCHAIN,
                   ["truncate-50%", "truncate-in-last-line", "empty", "bit-flips", "utf8-bom", "utf16", "crlf", "nan",
                    "huge-float", "nul-bytes"],
                   ["import", "kalibr", "camchain.yaml", "imu.yaml", "--into", "newds"])
    for name, text in [
        ("billion-laughs", billion_laughs()),
        ("deep-nesting", b"a: " + b"[" * 100000 + b"]" * 100000 + b"\n"),
        ("resolution-1e12", CAMCHAIN.replace(b"[640, 480]", b"[1e12, 480]")),
        ("resolution-2^31", CAMCHAIN.replace(b"[640, 480]", b"[2147483648, 480]")),
        ("duplicate-key", CAMCHAIN + b"  camera_model: omni\n"),
    ]:
        out.append(Case(f"import-kalibr/{name}", lambda d, text=text: put(os.path.join(d, "camchain.yaml"), text),
                        ["import", "kalibr", "camchain.yaml", "imu.yaml", "--into", "newds"], {2}))

    # PoET results (roe import poet) into a copy of the sample dataset.
    add_file_cases("import-poet", "results.json", poet_results(),
                   ["truncate-50%", "truncate-last-byte", "empty", "bit-flips", "utf8-bom", "utf16", "crlf", "nul-bytes"],
                   ["import", "poet", "results.json", "--into", "ds", "--name", "poet2"], ds_needed=True)
    # roe.json and the stream files of a dataset (roe run).
    run = ["run", "ds", "--out", "out"]
    add_file_cases("run-roe.json", None, read(os.path.join(SAMPLE, "roe.json")),
                   ["truncate-50%", "truncate-last-byte", "empty", "bit-flips", "utf8-bom", "utf16", "crlf", "nul-bytes"],
                   run, ds_needed=True, rel="ds/roe.json")
    manifest = json.loads(read(os.path.join(SAMPLE, "roe.json")))

    def manifest_variant(mutate):
        m = json.loads(json.dumps(manifest))
        mutate(m)
        return json.dumps(m, indent=1).encode()

    semantic = {
        "fx-zero": lambda m: m["camera"].__setitem__("fx", 0),
        "fx-string": lambda m: m["camera"].__setitem__("fx", "600"),
        "unknown-key": lambda m: m["camera"].__setitem__("fxx", 1),
        "width-1e12": lambda m: m["camera"].__setitem__("width", 10**12),
        "negative-rate": lambda m: m["imu"].__setitem__("rate_hz", -200),
        "non-unit-quaternion": lambda m: m["camera"]["T_I_C"].__setitem__("q", [0, 0, 0, 2]),
    }
    for name, mut in semantic.items():
        def setup(d, mut=mut):
            dataset_copy(os.path.join(d, "ds"))
            put(os.path.join(d, "ds/roe.json"), manifest_variant(mut))
        out.append(Case(f"run-roe.json/{name}", setup, run, {2}))
    out.append(Case("run-roe.json/deep-nesting",
                    lambda d: (dataset_copy(os.path.join(d, "ds")), put(os.path.join(d, "ds/roe.json"), deep_json(200000))),
                    run, {2}))
    add_file_cases("run-imu0", None, read(os.path.join(SAMPLE, "mav0/imu0/data.csv")),
                   ["truncate-50%", "truncate-in-last-line", "bit-flips", "utf8-bom", "utf16", "crlf", "nan", "inf",
                    "huge-float", "huge-int", "unsorted-stamps", "duplicated-stamp", "nul-bytes"],
                   run, ds_needed=True, rel="ds/mav0/imu0/data.csv")
    det = os.path.join(SAMPLE, "detections/sim/detections.csv")
    add_file_cases("run-detections", None, read(det),
                   ["truncate-50%", "truncate-in-last-line", "bit-flips", "nan", "huge-int", "unsorted-stamps",
                    "zero-quaternion", "utf8-bom"],
                   run, ds_needed=True, rel="ds/detections/sim/detections.csv")
    out += third_round_cases()
    out += fourth_round_cases()
    return out


# ----------------------------------------------------------------------------------------------------------
# Third round (issue 40): nothing outside the output, bounded disk and memory, safe generated scripts.
# Each case has a post-condition beyond its exit code.
# ----------------------------------------------------------------------------------------------------------

SWEEP_SPEC = json.dumps({"format": "roe-sweep-spec/1",
                         "axes": {"datasets": [{"preset": "paper-seq1", "duration_s": 2}], "seeds": [1, 2]}})


def plan_sweep(d):
    put(os.path.join(d, "spec.json"), SWEEP_SPEC.encode())
    roe_setup(d, "sweep", "plan", "spec.json", "--out", "sw")


def edit_first_job(d, key, value):
    p = os.path.join(d, "sw", "jobs.jsonl")
    lines = read(p).decode().splitlines()
    j = json.loads(lines[0])
    if key == "id":
        j["id"] = value
    else:
        j["job"][key] = value
    lines[0] = json.dumps(j)
    put(p, ("\n".join(lines) + "\n").encode())


def exists_check(*paths, absent=()):
    def check(d):
        for p in paths:
            if not os.path.exists(os.path.join(d, p)):
                return p + " was deleted"
        for p in absent:
            if os.path.lexists(os.path.join(d, p)):
                return p + " was created"
        return None
    return check


def tmp_empty(d):
    left = os.listdir(os.path.join(d, "tmp"))
    return None if not left else "left in TMPDIR: " + ", ".join(left)


def zstd_bytes(raw_size, pattern=b"\0"):
    """`raw_size` bytes of `pattern`, zstd-compressed (the zstd command line tool)."""
    block = pattern * (1 << 20 // len(pattern))
    p = subprocess.Popen(["zstd", "-q", "-1", "-c"], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    out = []

    def feed():
        left = raw_size
        while left > 0:
            p.stdin.write(block[: min(left, len(block))])
            left -= len(block)
        p.stdin.close()
    import threading
    t = threading.Thread(target=feed)
    t.start()
    out.append(p.stdout.read())
    t.join()
    p.wait()
    return out[0]


def rosbag2_file_bomb(d, raw_size):
    folder = os.path.join(d, "bag")
    put(os.path.join(folder, "metadata.yaml"), (
        "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n"
        "  relative_file_paths: [bomb_0.db3.zstd]\n  compression_format: zstd\n  compression_mode: FILE\n"
        "  message_count: 1\n").encode())
    # zstd decodes concatenated frames: one frame of 256 MiB repeated is a bomb of any size in a few KB.
    frame = zstd_bytes(256 << 20)
    put(os.path.join(folder, "bomb_0.db3.zstd"), frame * max(1, raw_size // (256 << 20)))


def mcap_chunk_bomb(n_chunks, claimed, raw):
    """An MCAP file of `n_chunks` zstd chunks, all at time 0..1 (overlapping), each `raw` bytes of zeros
    padded as one long message record, claiming `claimed` uncompressed bytes."""
    def rec(op, body):
        return bytes([op]) + struct.pack("<Q", len(body)) + body

    def s(t):
        return struct.pack("<I", len(t)) + t

    header = rec(0x01, s(b"ros2") + s(b"roe-hostile"))
    schema = rec(0x03, struct.pack("<H", 1) + s(b"geometry_msgs/msg/PoseStamped") + s(b"ros2msg") + struct.pack("<I", 0))
    channel = rec(0x04, struct.pack("<HH", 1, 1) + s(b"/bomb") + s(b"cdr") + struct.pack("<I", 0))
    body_len = raw - 9 - 22
    msg = bytes([0x05]) + struct.pack("<QHIQQ", 22 + body_len, 1, 0, 1, 1)
    comp = zstd_bytes(body_len)
    # The records of a chunk: one message record whose data is `body_len` zero bytes; zstd of
    # (header + zeros) is built as two frames (zstd decodes concatenated frames).
    p = subprocess.run(["zstd", "-q", "-c"], input=msg, stdout=subprocess.PIPE, check=True)
    records = p.stdout + comp
    chunk = rec(0x06, struct.pack("<QQQI", 0, 1, claimed, 0) + s(b"zstd") + struct.pack("<Q", len(records)) + records)
    body = b"\x89MCAP0\r\n" + header + schema + channel + chunk * n_chunks
    return body + rec(0x02, struct.pack("<QQI", 0, 0, 0)) + b"\x89MCAP0\r\n"


def poet_many(n_images, per_image):
    """A results.json of n_images × per_image detections for the sample's frames (ids = stamps)."""
    stamps = [l.split(b",")[0].decode() for l in read(os.path.join(SAMPLE, "mav0/cam0/data.csv")).splitlines()[1:]]
    det = '{"t": [0.1, 0.2, 0.8], "rot": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "box": [0.5, 0.5, 0.1, 0.1], "class": 1}'
    img = "{" + ", ".join(f'"{k}": {det}' for k in range(per_image)) + "}"
    return ("{" + ",\n".join(f'"{stamps[i]}": {img}' for i in range(min(n_images, len(stamps)))) + "}").encode()


def third_round_cases():
    out = []
    sweep_victim = exists_check("victim", "sw/jobs.jsonl", absent=("victim.old", "victim.lock"))
    for name, value in [("dotdot", "../../victim"), ("absolute", None), ("empty", ""), ("slash", "a/b"),
                        ("upper-hex", "ABCDEF0123456789")]:
        def setup(d, value=value):
            os.makedirs(os.path.join(d, "victim"))
            put(os.path.join(d, "victim", "keep"), b"x")
            plan_sweep(d)
            edit_first_job(d, "id", os.path.join(d, "victim") if value is None else value)
        for cmd in (["sweep", "run", "sw", "--index", "0"], ["sweep", "status", "sw"]):
            out.append(Case(f"sweep-jobs.jsonl/id-{name}/{cmd[1]}", setup, cmd, {2}, sweep_victim))

    def dup_ids(d):
        plan_sweep(d)
        p = os.path.join(d, "sw", "jobs.jsonl")
        lines = read(p).decode().splitlines()
        j0, j1 = json.loads(lines[0]), json.loads(lines[1])
        j1["id"] = j0["id"]
        put(p, (lines[0] + "\n" + json.dumps(j1) + "\n").encode())
    out.append(Case("sweep-jobs.jsonl/duplicate-id", dup_ids, ["sweep", "run", "sw"], {2}))
    for name, value in [("dotdot", "../../victim"), ("slash", "a/b")]:
        out.append(Case(f"sweep-jobs.jsonl/detections-{name}",
                        lambda d, value=value: (plan_sweep(d), edit_first_job(d, "detections", value)),
                        ["sweep", "run", "sw", "--index", "0"], {2}))
    out.append(Case("sweep-folder/work-symlink",
                    lambda d: (os.makedirs(os.path.join(d, "victim")), plan_sweep(d),
                               os.symlink(os.path.join(d, "victim"), os.path.join(d, "sw", "work"))),
                    ["sweep", "run", "sw", "--index", "0"], {2}, exists_check("victim")))
    # The aggregate's --out inside the sweep's own folders (a finished job's marker must survive).
    def finished_marker(d):
        plan_sweep(d)
        os.makedirs(os.path.join(d, "sw", "jobs", "0123456789abcdef"))
        put(os.path.join(d, "sw", "jobs", "0123456789abcdef", "result.json"), b"{}")
    for out_dir in ["sw/jobs", "sw/jobs/0123456789abcdef", "sw/work", "sw/locks/x", "sw", "."]:
        out.append(Case(f"sweep-aggregate/out-{out_dir.replace('/', '-')}", finished_marker,
                        ["sweep", "aggregate", "sw", "--out", out_dir, "--force"], {2},
                        exists_check("sw/jobs/0123456789abcdef/result.json", "sw/jobs.jsonl")))
    # roe report's --out naming one of its inputs' files.
    def run_folder(d):
        dataset_copy(os.path.join(d, "ds"))
        roe_setup(d, "run", "ds", "--out", "run")
    for target, extra in [("run/run.json", []), ("run/trajectory.csv", []), ("ds/roe.json", ["--gt", "ds"])]:
        def keep(d, target=target):
            return None if not read(os.path.join(d, target)).startswith(b"<!DOCTYPE") else target + " was replaced"
        out.append(Case(f"report/out-is-input-{target.replace('/', '-')}", run_folder,
                        ["report", "run", "--out", target, "--force"] + extra, {2}, keep))
    # Sweep plan: 10^9 jobs refused at once in bounded memory; detection names and durations checked at plan time.
    big = {"format": "roe-sweep-spec/1", "axes": {"datasets": ["paper-seq1"], "overrides": {
        "filter.chi2_confidence": [0.9 + i * 1e-5 for i in range(1000)],
        "filter.meas_sigma_p_m": [0.05 + i * 1e-4 for i in range(1000)],
        "filter.meas_sigma_rot_deg": [10 + i * 1e-2 for i in range(1000)]}}}
    for name, spec in [
        ("billion-jobs", big),
        ("detections-dotdot", {"format": "roe-sweep-spec/1", "axes": {"datasets": ["paper-seq1"], "detections": ["../x"]}}),
        ("detections-slash", {"format": "roe-sweep-spec/1", "axes": {"datasets": ["paper-seq1"], "detections": ["a/b"]}}),
        ("duration-1e9", {"format": "roe-sweep-spec/1", "axes": {"datasets": [{"preset": "paper-seq1", "duration_s": 1e9}]}}),
    ]:
        out.append(Case(f"sweep-plan/{name}", lambda d, spec=spec: put(os.path.join(d, "spec.json"), json.dumps(spec).encode()),
                        ["sweep", "plan", "spec.json", "--out", "sw"], {2}, exists_check(absent=("sw",)), max_rss_mb=200))
    # Emitted scripts: a newline in a directive's value.
    out.append(Case("sweep-emit/job-name-newline", plan_sweep,
                    ["sweep", "emit", "slurm", "sw", "--job-name", "x\n#SBATCH --mem=999G", "--out", "job.sbatch"], {2},
                    exists_check(absent=("job.sbatch",))))
    # Decompression: a rosbag2 FILE-compressed bomb (6 GiB of zeros in ~200 KB), MCAP chunk bombs.
    if shutil.which("zstd"):
        out.append(Case("rosbag2-file-compression/bomb-6GiB", lambda d: rosbag2_file_bomb(d, 6 << 30),
                        ["import", "mocap", "bag", "--into", "newds", "--topic", "/tf"], {2}, tmp_empty, max_rss_mb=300))
        for name, n, claimed, raw in [("claims-1e9", 1, 10**9, 8 << 20), ("lies-small", 1, 1 << 20, 64 << 20),
                                      ("overlapping-40x60MiB", 40, 60 << 20, 60 << 20)]:
            out.append(Case(f"mcap-chunk/{name}",
                            lambda d, n=n, claimed=claimed, raw=raw: put(os.path.join(d, "b.mcap"), mcap_chunk_bomb(n, claimed, raw)),
                            ["import", "mocap", "b.mcap", "--into", "newds", "--topic", "/bomb"], ANY,
                            max_rss_mb=400))
    # PoET results: 400 k detections in ~40 MB stay within 1 KB each (+ the file's text).
    out.append(Case("import-poet/400k-detections",
                    lambda d: (dataset_copy(os.path.join(d, "ds")), put(os.path.join(d, "r.json"), poet_many(800, 500))),
                    ["import", "poet", "r.json", "--into", "ds", "--name", "many"], {0, 2}, max_rss_mb=500,
                    time_limit_s=120))  # 45 MB of JSON: 31 s on the loaded 2-core VM
    out.append(Case("import-poet/translation-1e308",
                    lambda d: (dataset_copy(os.path.join(d, "ds")),
                               put(os.path.join(d, "r.json"), poet_results().replace(b"0.8", b"1e308", 1))),
                    ["import", "poet", "r.json", "--into", "ds", "--name", "p"], {2}))
    return out


# ----------------------------------------------------------------------------------------------------------
# Fourth round (issue 51): outputs that are not files, labels that are not plain text, tf trees of 200 000
# edges, one image of 400 000 detections, and roe refine reading as strictly as roe run.
# ----------------------------------------------------------------------------------------------------------

_CACHE_LOCK = threading.Lock()
_CACHE = {}


def cached(name, make):
    """A folder made once per catalogue run (under the work folder) and shared by the cases that copy it."""
    with _CACHE_LOCK:
        if name not in _CACHE:
            d = os.path.join(WORKDIR, "_cache", name)
            os.makedirs(os.path.join(d, "tmp"), exist_ok=True)
            make(d)
            _CACHE[name] = d
        return _CACHE[name]


def make_run(d):
    dataset_copy(os.path.join(d, "ds"))
    roe_setup(d, "run", "ds", "--out", "run")


def run_copy(d):
    """A finished run of the sample (its dataset stays in the cache, as run.json names it), hard-linked."""
    c = cached("run", make_run)
    shutil.copytree(os.path.join(c, "run"), os.path.join(d, "run"), copy_function=os.link)


SPECIAL_OUTPUTS = ["fifo", "socket"] + (["device", "symlink-to-device"] if os.geteuid() == 0 else [])
NULL_DEV = (1, 3)  # /dev/null's numbers, for a private node made in the case folder (never the machine's own)


def make_special_output(path, kind):
    os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        s.bind(path)  # closing the socket leaves its file
        s.close()
    elif kind == "device":
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(*NULL_DEV))
    elif kind == "symlink-to-device":
        node = os.path.join(os.path.dirname(path), ".node")
        os.mknod(node, 0o666 | stat.S_IFCHR, os.makedev(*NULL_DEV))
        os.symlink(".node", path)
    with open(path + ".ident" if kind != "socket" else os.path.join(os.path.dirname(path), ".sock.ident"), "w") as f:
        st = os.stat(path) if kind != "socket" else os.lstat(path)
        f.write(f"{st.st_ino} {st.st_mode} {st.st_rdev}")


def special_untouched(rel, kind):
    def check(d):
        path = os.path.join(d, rel)
        ident = path + ".ident" if kind != "socket" else os.path.join(os.path.dirname(path), ".sock.ident")
        if kind == "symlink-to-device" and not os.path.islink(path):
            return rel + ": the symlink was replaced"
        try:
            st = os.stat(path) if kind != "socket" else os.lstat(path)
        except OSError:
            return rel + " was removed"
        if read(ident).decode() != f"{st.st_ino} {st.st_mode} {st.st_rdev}":
            return rel + " was replaced or changed"
        left = [n for n in os.listdir(os.path.dirname(path)) if ".tmp-" in n]
        return ("temporaries left: " + ", ".join(left)) if left else None
    return check


def writing_commands():
    """(name, setup, argv with OUT, OUT relative to the case folder): every command that writes, each output."""
    est = os.path.join(SAMPLE, "mav0/mocap0/data.csv")
    gt = os.path.join(SAMPLE, "mav0/state_groundtruth_estimate0/data.csv")
    ev = ["eval", est, "--gt", gt, "--est-format", "euroc", "--gt-format", "euroc"]

    def summary_setup(d):
        roe_setup(d, *ev, "--out", "e")

    def mocap_setup(d):
        put(os.path.join(d, "m.csv"), read(est))

    def kalibr_setup(d):
        put(os.path.join(d, "camchain.yaml"), CAMCHAIN)

    def poet_setup(d):
        dataset_copy(os.path.join(d, "ds"))
        put(os.path.join(d, "r.json"), poet_results())

    def spec_setup(d):
        put(os.path.join(d, "spec.json"), SWEEP_SPEC.encode())

    return [
        ("eval-save_results", None, ev + ["--no-out", "--save_results", "OUT"], "o.zip"),
        ("eval-out", None, ev + ["--out", "OUT"], "o"),
        ("eval-summary-out", summary_setup, ["eval", "--summary", "e/report.json", "--out", "OUT"], "s.csv"),
        ("report-out", run_copy, ["report", "run", "--out", "OUT"], "r.html"),
        ("report-figures", run_copy, ["report", "run", "--out", "r.html", "--figures", "OUT"], "figs"),
        ("run-out", lambda d: dataset_copy(os.path.join(d, "ds")), ["run", "ds", "--out", "OUT"], "o"),
        ("refine-out", run_copy, ["refine", "run", "--out", "OUT"], "o"),
        ("simulate-out", None, ["simulate", "--preset", "paper-seq1", "--duration", "2", "--out", "OUT"], "o"),
        ("sweep-plan-out", spec_setup, ["sweep", "plan", "spec.json", "--out", "OUT"], "sw2"),
        ("sweep-emit-out", plan_sweep, ["sweep", "emit", "slurm", "sw", "--out", "OUT"], "job.sbatch"),
        ("sweep-aggregate-out", plan_sweep, ["sweep", "aggregate", "sw", "--out", "OUT"], "agg"),
        ("import-poet-set", poet_setup, ["import", "poet", "r.json", "--into", "ds", "--name", "new"],
         "ds/detections/new"),
        ("import-mocap-into", mocap_setup, ["import", "mocap", "m.csv", "--format", "euroc", "--into", "OUT"], "nd"),
        ("import-mocap-file", lambda d: (dataset_copy(os.path.join(d, "ds")), mocap_setup(d)),
         ["import", "mocap", "m.csv", "--format", "euroc", "--into", "ds", "--name", "mocap7"],
         "ds/mav0/mocap7/data.csv"),
        ("import-kalibr-into", kalibr_setup, ["import", "kalibr", "camchain.yaml", "imu.yaml", "--into", "OUT"], "nd"),
        ("import-kalibr-file", lambda d: (kalibr_setup(d), dataset_copy(os.path.join(d, "ds"))),
         ["import", "kalibr", "camchain.yaml", "imu.yaml", "--into", "ds"], "ds/calib/camchain-imucam.yaml"),
    ]


def output_rule_cases():
    out = []
    for name, setup, argv, rel in writing_commands():
        for kind in SPECIAL_OUTPUTS:
            for force in (False, True):
                def full_setup(d, setup=setup, rel=rel, kind=kind):
                    if setup:
                        setup(d)
                    make_special_output(os.path.join(d, rel), kind)
                args = [rel if a == "OUT" else a for a in argv] + (["--force"] if force else [])
                out.append(Case(f"output-rule/{name}/{kind}{'-force' if force else ''}", full_setup, args, {2},
                                special_untouched(rel, kind), expect="never this"))
    return out


HOSTILE_LABELS = {"dollar": "a $ b", "frac": "$\\frac{", "two-dollars": "$x$ and $\\frac{$", "comment-script":
                  "<!--<script>x</script>&amp;"}


def html_json_readable(label):
    def check(d):
        html = read(os.path.join(d, "r.html")).decode()
        start = html.find('<script type="application/json" id="roe-eval-report">')
        if start < 0:
            return "no embedded JSON block"
        body = html[html.index(">", start) + 1:]
        end = body.find("</script>")
        if "<" in body[:end]:  # "<!--" then "<script" puts a browser in the double-escaped state: no end tag
            return "a raw '<' in the embedded JSON block (HTML's script-data rules can swallow its end tag)"
        try:
            data = json.loads(body[:end])
        except ValueError as e:
            return f"the embedded JSON block does not parse: {e}"
        got = data.get("info", {}).get("label")
        return None if got == label else f"info.label read back as {got!r}"
    return check


def label_cases():
    out = []
    est = os.path.join(SAMPLE, "mav0/mocap0/data.csv")
    gt = os.path.join(SAMPLE, "mav0/state_groundtruth_estimate0/data.csv")
    for name, label in HOSTILE_LABELS.items():
        out.append(Case(f"label/report/{name}", run_copy, ["report", "run", "--out", "r.html", "--label", label],
                        {0}, html_json_readable(label), time_limit_s=120))
        out.append(Case(f"label/eval-plot/{name}", lambda d: None,
                        ["eval", est, "--gt", gt, "--est-format", "euroc", "--gt-format", "euroc", "--plot",
                         "--label", label, "--out", "e"], {0}, exists_check("e/report.json"), time_limit_s=120))

    def named_object(d):
        dataset_copy(os.path.join(d, "ds"))
        m = json.loads(read(os.path.join(SAMPLE, "roe.json")))
        for k, o in enumerate(m.get("objects", [])):
            o["name"] = ["$\\frac{$", "x_{\\frac}$", "<!--<script>"][k % 3]
        put(os.path.join(d, "ds/roe.json"), json.dumps(m, indent=1).encode())
        roe_setup(d, "run", "ds", "--out", "run")
    out.append(Case("label/report/object-names", named_object, ["report", "run", "--out", "r.html"], {0},
                    exists_check("r.html"), time_limit_s=120))

    # A sweep variant is named after its config file: the name reaches plot_sweep.py's box labels.
    def swept_named_config(d):
        name = HOSTILE_LABELS["two-dollars"].replace("/", "_") + ".json"
        put(os.path.join(d, name), b"{}")
        spec = {"format": "roe-sweep-spec/1", "axes": {"datasets": [{"preset": "paper-seq1", "duration_s": 2}],
                                                       "seeds": [1], "configs": ["default", name]}}
        put(os.path.join(d, "spec.json"), json.dumps(spec).encode())
        roe_setup(d, "sweep", "plan", "spec.json", "--out", "sw")
        roe_setup(d, "sweep", "run", "sw")
    out.append(Case("label/sweep-aggregate-plot/config-name", swept_named_config,
                    ["sweep", "aggregate", "sw", "--out", "agg", "--plot"], {0},
                    exists_check("agg/plots/plots.json", "agg/plots/box_ate_rmse_m.png"), time_limit_s=120))
    return out


def cdr_tf_message(transforms):
    """tf2_msgs/msg/TFMessage in CDR (little endian): [(parent, child, sec, t xyz, q xyzw)]."""
    b = bytearray()

    def align(n):
        b.extend(b"\0" * (-len(b) % n))

    def u32(v):
        align(4)
        b.extend(struct.pack("<I", v))

    def text(s):
        e = s.encode()
        u32(len(e) + 1)
        b.extend(e + b"\0")

    u32(len(transforms))
    for parent, child, sec, t, q in transforms:
        u32(sec)
        u32(0)
        text(parent)
        text(child)
        align(8)
        b.extend(struct.pack("<7d", *t, *q))
    return b"\x00\x01\x00\x00" + bytes(b)


def tf_mcap(static, dynamic):
    """An MCAP file (ROS 2, no chunks) with one /tf_static message of `static` transforms and one /tf message
    per entry of `dynamic` (each a list of transforms)."""
    def rec(op, body):
        return bytes([op]) + struct.pack("<Q", len(body)) + body

    def s(t):
        return struct.pack("<I", len(t)) + t

    out = [b"\x89MCAP0\r\n", rec(0x01, s(b"ros2") + s(b"roe-hostile")),
           rec(0x03, struct.pack("<H", 1) + s(b"tf2_msgs/msg/TFMessage") + s(b"ros2msg") + struct.pack("<I", 0))]
    for cid, topic in ((1, b"/tf_static"), (2, b"/tf")):
        out.append(rec(0x04, struct.pack("<HH", cid, 1) + s(topic) + s(b"cdr") + struct.pack("<I", 0)))
    seq = 0
    for cid, msgs in ((1, [static] if static else []), (2, dynamic)):
        for m in msgs:
            seq += 1
            t = (m[0][2] if m else 1) * 10**9
            out.append(rec(0x05, struct.pack("<HIQQ", cid, seq, t, t) + cdr_tf_message(m)))
    out.append(rec(0x02, struct.pack("<QQI", 0, 0, 0)))
    out.append(b"\x89MCAP0\r\n")
    return b"".join(out)


def tf_cases():
    n = 200000
    ident = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    step = ((1.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    world = [[("world", "f0", 1 + k, *ident)] for k in range(50)]
    chain = [(f"f{k}", f"f{k + 1}", 1, *step) for k in range(n)]
    star = [("f0", f"c{k}", 1, *step) for k in range(n)]
    imp = ["import", "mocap", "b.mcap", "--into", "newds", "--topic", "/tf", "--parent", "world", "--child"]
    out = []
    for name, static, child, allowed, expect in [
        ("deep-chain-200k", chain, f"f{n}", {0}, None),
        ("star-200k", star, f"c{n - 1}", {0}, None),
        ("unknown-frame-200k", chain, "nope", {2}, "frames in all"),
    ]:
        out.append(Case(f"tf/{name}", lambda d, static=static: put(os.path.join(d, "b.mcap"), tf_mcap(static, world)),
                        imp + [child], allowed, max_rss_mb=200, time_limit_s=60, expect=expect, max_stderr=8000))
    cycle = [("a", "b", 1, *ident), ("b", "c", 1, *ident), ("c", "a", 1, *ident), ("f0", "x", 1, *ident)]
    cyc = [[("a", "q", 1 + k, *ident)] for k in range(5)]
    out.append(Case("tf/cycle-3", lambda d: put(os.path.join(d, "b.mcap"), tf_mcap(cycle, cyc)),
                    ["import", "mocap", "b.mcap", "--into", "newds", "--topic", "/tf", "--parent", "b", "--child", "q"],
                    {2}, expect="cycle"))
    empty = [[("world", "", 1 + k, *ident)] for k in range(5)]
    out.append(Case("tf/empty-frame-id", lambda d: put(os.path.join(d, "b.mcap"), tf_mcap([], empty)),
                    imp + ["x"], {2}, expect="empty frame id"))
    return out


def edit_run_json(d, edit):
    p = os.path.join(d, "run", "run.json")
    j = json.loads(read(p))
    edit(j)
    put(p, json.dumps(j, indent=1).encode())


def edit_csv(d, name, edit):
    p = os.path.join(d, "run", name)
    ls = read(p).decode().splitlines()
    put(p, ("\n".join(edit(ls)) + "\n").encode())


def shift_first_column(ls, by_ns):
    return [ls[0]] + [str(int(l.split(",")[0]) + by_ns) + l[l.index(","):] for l in ls[1:] if l]


def refine_cases():
    def damaged(edit):
        return lambda d: (run_copy(d), edit(d))

    def set_key(path, value):
        def e(j):
            o = j
            for k in path[:-1]:
                o = o[k]
            if value is KeyError:
                del o[path[-1]]
            else:
                o[path[-1]] = value
        return lambda d: edit_run_json(d, e)

    def no_anchor_rows(d):
        anchor = json.loads(read(os.path.join(d, "run", "run.json")))["anchor_id"]
        edit_csv(d, "objects.csv", lambda ls: [ls[0]] + [l for l in ls[1:] if l.split(",")[1] != str(anchor)])

    def big_position(ls):
        cells = ls[len(ls) // 2].split(",")
        cells[1] = "1e308"
        return ls[:len(ls) // 2] + [",".join(cells)] + ls[len(ls) // 2 + 1:]

    def nan_sigma(ls):
        head = ls[0].split(",")
        k = head.index("sigma_p_W_I_x")
        cells = ls[2].split(",")
        cells[k] = "nan"
        return ls[:2] + [",".join(cells)] + ls[3:]

    cases = [
        ("reprojection-header-only", lambda d: edit_csv(d, "reprojection.csv", lambda ls: ls[:1]), "reprojection.csv"),
        ("reprojection-half-dropped", lambda d: edit_csv(d, "reprojection.csv", lambda ls: ls[: len(ls) // 2]),
         "reprojection.csv"),
        ("reprojection-shifted", lambda d: edit_csv(d, "reprojection.csv", lambda ls: shift_first_column(ls, 10**6)),
         "reprojection.csv"),
        ("objects-without-anchor", no_anchor_rows, "objects.csv"),
        ("states-shifted", lambda d: edit_csv(d, "states.csv", lambda ls: shift_first_column(ls, 10**12)), "states.csv"),
        ("states-position-1e308", lambda d: edit_csv(d, "states.csv", big_position), "states.csv"),
        ("states-nan-sigma", lambda d: edit_csv(d, "states.csv", nan_sigma), "states.csv"),
        ("anchor-unknown", set_key(["anchor_id"], 99), "anchor_id"),
        ("config-filter-missing", set_key(["config", "filter"], KeyError), "config.filter"),
        ("final-scale-0", set_key(["detection_sigmas", "final_scale"], 0), "final_scale"),
        ("final-scale-negative", set_key(["detection_sigmas", "final_scale"], -1), "final_scale"),
        ("final-scale-null", set_key(["detection_sigmas", "final_scale"], None), "final_scale"),
        ("final-scale-1e308", set_key(["detection_sigmas", "final_scale"], 1e308), "final_scale"),
    ]
    out = [Case(f"refine/{name}", damaged(edit), ["refine", "run", "--out", "o"], {2},
                exists_check(absent=("o",)), expect=expect) for name, edit, expect in cases]
    out.append(Case("eval/states-nan-sigma", damaged(lambda d: edit_csv(d, "states.csv", nan_sigma)),
                    ["eval", "run", "--out", "e"], {2}, expect="states.csv"))
    for opt, allowed in (("--linear-solver", "sparse_schur"), ("--loss", "cauchy")):
        out.append(Case(f"refine/{opt[2:]}-bogus", run_copy, ["refine", "run", "--out", "o", opt, "bogus"], {2},
                        exists_check(absent=("o",)), expect=allowed))
    return out


def fourth_round_cases():
    out = output_rule_cases() + label_cases() + tf_cases() + refine_cases()
    # One image of 400 000 detections: refused at roe's per-image limit, in bounded memory.
    out.append(Case("import-poet/400k-detections-one-image",
                    lambda d: (dataset_copy(os.path.join(d, "ds")), put(os.path.join(d, "r.json"), poet_many(1, 400000))),
                    ["import", "poet", "r.json", "--into", "ds", "--name", "many"], {2}, max_rss_mb=300,
                    time_limit_s=60, expect="per-image limit"))
    # A sweep at its own limit of 100 000 jobs.
    spec = {"format": "roe-sweep-spec/1", "axes": {"datasets": ["paper-seq1"], "overrides": {
        "filter.chi2_confidence": [0.9 + i * 1e-4 for i in range(100)],
        "filter.meas_sigma_p_m": [0.05 + i * 1e-4 for i in range(1000)]}}}
    out.append(Case("sweep-plan/100k-jobs", lambda d: put(os.path.join(d, "spec.json"), json.dumps(spec).encode()),
                    ["sweep", "plan", "spec.json", "--out", "sw"], {0}, max_rss_mb=300, time_limit_s=300))
    # An empty zip where eval --summary reads an evo result.
    out.append(Case("eval-summary/empty-zip", lambda d: put(os.path.join(d, "e.zip"), b"PK\x05\x06" + b"\0" * 18),
                    ["eval", "--summary", "e.zip"], {2}, expect="not an evo result"))
    return out


# ----------------------------------------------------------------------------------------------------------
# Running.
# ----------------------------------------------------------------------------------------------------------


def limit_child():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
    os.setsid()


def run_case(roe, case, workdir):
    d = os.path.join(workdir, case.name.replace("/", "__"))
    os.makedirs(os.path.join(d, "tmp"))  # the case's TMPDIR: what roe leaves there is seen
    for name, data in (("imu.yaml", IMU_YAML),):
        put(os.path.join(d, name), data)
    try:
        case.setup(d)
    except Exception as e:  # noqa: BLE001 - a setup that cannot be made is reported, not raised in a worker
        return case.name, "setup", 0.0, f"setup failed: {e}", False
    t0 = time.monotonic()
    timed = ["/usr/bin/time", "-f", "ROE_MAXRSS_KB=%M"] if case.max_rss_mb and os.path.exists("/usr/bin/time") else []
    p = subprocess.Popen(timed + [roe] + case.argv, cwd=d, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         preexec_fn=limit_child, env=dict(os.environ, TMPDIR=os.path.join(d, "tmp")))
    try:
        _, err = p.communicate(timeout=case.time_limit_s)
        code = p.returncode
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        _, err = p.communicate()
        code = "timeout"
    dt = time.monotonic() - t0
    n_stderr = len(err)
    err = err.decode("utf-8", "replace").strip().splitlines()
    rss = [int(l.split("=")[1]) for l in err if l.startswith("ROE_MAXRSS_KB=")]
    err = [l for l in err if not l.startswith("ROE_MAXRSS_KB=") and not l.startswith("Command ")]
    message = err[-1] if err else ""
    ok = code in case.allowed
    if ok and case.expect and not any(case.expect in l for l in err):
        ok, message = False, f"message lacks {case.expect!r} ({message})"
    if ok and any(l.startswith("Traceback") for l in err):
        ok, message = False, f"a Python traceback on stderr ({message})"
    if ok and case.max_stderr and n_stderr > case.max_stderr:
        ok, message = False, f"{n_stderr} bytes on stderr > {case.max_stderr} ({message[:100]})"
    if ok and case.check:
        why = case.check(d)
        if why:
            ok, message = False, f"post-condition: {why} ({message})"
    if ok and rss and rss[0] > case.max_rss_mb * 1024:
        ok, message = False, f"peak RSS {rss[0] // 1024} MB > {case.max_rss_mb} MB ({message})"
    elif rss:
        message = f"[{rss[0] // 1024} MB] " + message
    return case.name, code, dt, message, ok


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("roe")
    ap.add_argument("--jobs", type=int, default=max(1, os.cpu_count() or 1))
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--keep", help="keep the case folders in this folder")
    ap.add_argument("--only", default="")
    ap.add_argument("--verbose", action="store_true")
    a = ap.parse_args()
    all_cases = [c for c in cases() if a.only in c.name]
    if a.list:
        for c in all_cases:
            print(c.name, "exits", sorted(c.allowed))
        print(len(all_cases), "cases")
        return 0
    roe = os.path.abspath(a.roe)
    global ROE
    ROE = roe
    workdir = a.keep or tempfile.mkdtemp(prefix="roe-hostile-")
    os.makedirs(workdir, exist_ok=True)
    global WORKDIR
    WORKDIR = workdir
    t0 = time.monotonic()
    failed = []
    counts = {}
    slowest = (0.0, "")
    try:
        with futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
            for name, code, dt, message, ok in pool.map(lambda c: run_case(roe, c, workdir), all_cases):
                counts[code] = counts.get(code, 0) + 1
                slowest = max(slowest, (dt, name))
                if a.verbose or not ok:
                    print(f"{'ok  ' if ok else 'FAIL'} {name}: exit {code} in {dt:.2f} s: {message[:200]}")
                if not ok:
                    failed.append(name)
    finally:
        if not a.keep:
            shutil.rmtree(workdir, ignore_errors=True)
    print(f"{len(all_cases)} hostile inputs in {time.monotonic() - t0:.1f} s ({a.jobs} at a time); exits "
          + ", ".join(f"{k}: {v}" for k, v in sorted(counts.items(), key=str))
          + f"; slowest {slowest[1]} {slowest[0]:.2f} s; {len(failed)} outside the contract")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
