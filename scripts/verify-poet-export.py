#!/usr/bin/python3
"""Checks scripts/export_poet.py and `roe infer` against the real PoET architecture (docs/infer.md,
"Verified against the real PoET code").

Needs checkouts of aau-cns/poet, aau-cns/yolov4 (PoET's Scaled-YOLOv4 wrapper) and
fundamentalvision/Deformable-DETR (its models/ops is PoET's `deformable_attention` package), Debian's
python3-torch / python3-torchvision / python3-opencv, and a built `roe` (with roe-infer beside it):

    /usr/bin/python3 scripts/verify-poet-export.py --poet ~/src/poet --yolo ~/src/yolov4 \\
        --ddetr ~/src/Deformable-DETR --roe build/roe --work /tmp/poet-verify [--images a.png b.png]

Nothing of PoET is written into roe: the work folder gets a copy of PoET with the wrapper placed in
models/ (as PoET's README says), the ops folder renamed to `deformable_attention`, random-weight
checkpoints, the exported bundles, a dataset of the given images and roe's detections.

For each variant (without and with the aleatoric heads) it
  1. builds PoET's model with PoET's own build() and its own argument parser's defaults, overridden by
     the released YCB-V hyper-parameters (hidden 256, 5+5 layers, 16 heads, 4 points, 10 queries,
     21 classes, YOLOv4-CSP from PoET's configs/) and random weights, and saves it as a checkpoint;
  2. exports it with scripts/export_poet.py (its self-checks: traced vs eager, wrapper vs PoET forward);
  3. runs PoET's own forward in its ground-truth-box mode (the same boxes go to `roe infer --boxes`) with
     Deformable-DETR's pure-PyTorch attention (ms_deform_attn_core_pytorch; the CUDA op is absent)
     on every image: t, R and, with the heads, the log-variances -> sigma = exp(s / 2);
  4. runs `roe infer --boxes` on a dataset of the same images (camera = the training camera: no warp) and
     compares detections.csv with (3): the same objects per frame (PoET's first detection of each
     class, roe's one row per object), |t| difference, rotation angle, relative sigma difference.
Exit status 0 when every difference is within the tolerances (--tol-*), 1 otherwise; a JSON summary
with the figures and timings is printed and written to WORK/summary.json.
"""
import argparse
import ast
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))

# The released YCB-V model's settings (PoET's README / model zoo args), over PoET's parser defaults.
RELEASED = {"backbone": "yolov4", "backbone_cfg": "configs/ycbv_yolov4-csp.cfg", "num_feature_levels": 4,
            "enc_layers": 5, "dec_layers": 5, "nheads": 16, "dim_feedforward": 1024, "hidden_dim": 256,
            "num_queries": 10, "n_classes": 21, "dec_n_points": 4, "enc_n_points": 4, "class_mode": "specific",
            "rotation_representation": "6d", "bbox_mode": "gt", "lr_backbone": 0.0,
            "backbone_weights": None, "device": "cpu"}


def git_commit(path):
    r = subprocess.run(["git", "-C", path, "rev-parse", "HEAD"], capture_output=True, text=True)
    return r.stdout.strip() or "unknown"


def assemble(a, work):
    """work/poet = PoET + wrapper in models/; work/ops/deformable_attention = Deformable-DETR's ops."""
    poet = os.path.join(work, "poet")
    if os.path.exists(poet):
        shutil.rmtree(poet)
    shutil.copytree(a.poet, poet, ignore=shutil.ignore_patterns(".git"))
    shutil.copy(os.path.join(a.yolo, "cns_yolo.py"), os.path.join(poet, "models", "cns_yolo.py"))
    shutil.copytree(os.path.join(a.yolo, "yolo"), os.path.join(poet, "models", "yolo"))
    ops = os.path.join(work, "ops", "deformable_attention")
    if os.path.exists(ops):
        shutil.rmtree(ops)
    os.makedirs(ops)
    for sub in ("functions", "modules"):
        shutil.copytree(os.path.join(a.ddetr, "models", "ops", sub), os.path.join(ops, sub))
    with open(os.path.join(ops, "__init__.py"), "w") as f:
        f.write("from .modules import MSDeformAttn\n")
    return poet, os.path.join(work, "ops")


def poet_args(poet_dir, aleatoric):
    """PoET's own argument parser (main.get_args_parser, taken from main.py without importing PoET's
    data stack), parsed with no arguments, then the released settings."""
    src = open(os.path.join(poet_dir, "main.py")).read()
    fn = next(n for n in ast.parse(src).body if isinstance(n, ast.FunctionDef) and n.name == "get_args_parser")
    import argparse as ap
    import numpy as np
    env = {"argparse": ap, "np": np}
    exec(compile(ast.Module(body=[fn], type_ignores=[]), "main.py", "exec"), env)
    args = env["get_args_parser"]().parse_args([])
    for k, v in RELEASED.items():
        if not hasattr(args, k):
            sys.exit(f"error: PoET's parser has no '{k}' (another PoET version?)")
        setattr(args, k, v)
    args.backbone_cfg = os.path.join(poet_dir, RELEASED["backbone_cfg"])
    args.aleatoric = aleatoric
    return args


def load_poet(poet_dir, ops_dir):
    """Imports PoET with the CUDA-only pieces stubbed (export_poet's stubs) and the YOLO backbone routed
    to the wrapper (export_poet's patch); the attention stays Deformable-DETR's, set to its own
    pure-PyTorch core by the caller."""
    sys.path.insert(0, HERE)
    import export_poet as ex
    ex.stub_cuda_extensions()
    sys.path[:0] = [ops_dir, poet_dir]
    from models import build_model
    ex.patch_yolo_backbone()
    return build_model


def use_pytorch_attention():
    """Deformable-DETR's own fallback (ms_deform_attn_core_pytorch) in place of its CUDA function."""
    from deformable_attention.functions import ms_deform_attn_func as f
    from deformable_attention.modules import ms_deform_attn as m

    class CorePyTorch:
        @staticmethod
        def apply(value, shapes, level_start, locations, weights, im2col_step):
            return f.ms_deform_attn_core_pytorch(value, shapes, locations, weights)

    m.MSDeformAttnFunction = CorePyTorch


def make_checkpoint(a, poet_dir, ops_dir, aleatoric, path, seed):
    import torch
    torch.manual_seed(seed)
    build_model = load_poet(poet_dir, ops_dir)
    args = poet_args(poet_dir, aleatoric)
    model = build_model(args)[0]
    torch.save({"model": model.state_dict(), "args": args}, path)


# Boxes per image (class, x1, y1, x2, y2 as fractions of the image): PoET's ground-truth-box mode and
# `roe infer --boxes` get the same ones. Random YOLO heads give no usable detections (their outputs barely
# vary over the image), so the detector is checked by the bundle's layer self-test instead.
BOXES = [[(1, 0.10, 0.15, 0.30, 0.45), (6, 0.55, 0.20, 0.80, 0.60), (13, 0.35, 0.50, 0.50, 0.90),
          (21, 0.70, 0.65, 0.95, 0.95)],
         [(2, 0.05, 0.05, 0.40, 0.40), (13, 0.45, 0.30, 0.60, 0.75), (17, 0.62, 0.10, 0.98, 0.50)]]


def frame_boxes(k, width, height):
    """Integer pixel boxes of image k: (class, x1, y1, x2, y2, score)."""
    return [(c, round(x1 * width), round(y1 * height), round(x2 * width), round(y2 * height), 0.9 - 0.1 * i)
            for i, (c, x1, y1, x2, y2) in enumerate(BOXES[k % len(BOXES)])]


def reference(a, poet_dir, ops_dir, ckpt_path, images, out_path):
    """PoET's own forward (ground-truth-box mode) on each image → per box (class, t, R[, log-variances])."""
    import numpy as np
    import torch
    from PIL import Image
    torch.set_num_threads(a.threads)
    build_model = load_poet(poet_dir, ops_dir)
    use_pytorch_attention()
    from util.misc import NestedTensor
    ckpt = torch.load(ckpt_path, map_location="cpu")
    model = build_model(ckpt["args"])[0]
    model.load_state_dict(ckpt["model"], strict=True)
    model.eval()
    res = []
    for img_path in images:
        img = np.asarray(Image.open(img_path).convert("RGB"))
        x = torch.from_numpy(img.astype(np.float32) / 255.0).permute(2, 0, 1)[None]
        mask = torch.zeros((1,) + img.shape[:2], dtype=torch.bool)
        h, w = img.shape[:2]
        fb = frame_boxes(len(res), w, h)
        boxes = torch.tensor([[(x1 + x2) / 2 / w, (y1 + y2) / 2 / h, (x2 - x1) / w, (y2 - y1) / h]
                              for _, x1, y1, x2, y2, _ in fb], dtype=torch.float32)
        target = [{"boxes": boxes, "labels": torch.tensor([b[0] for b in fb], dtype=torch.int64)}]
        t0 = time.perf_counter()
        with torch.no_grad():
            out, n_boxes = model(NestedTensor(x, mask), target)
        ms = 1e3 * (time.perf_counter() - t0)
        dets = []
        for d in range(n_boxes[0]):
            e = {"class": int(out["pred_classes"][0, d]), "t": out["pred_translation"][0, d].tolist(),
                 "R": out["pred_rotation"][0, d].tolist(), "box": out["pred_boxes"][0, d].tolist()}
            if "pred_translation_aleatoric" in out:  # PoET's names for the log-variances
                e["pred_translation_aleatoric"] = out["pred_translation_aleatoric"][0, d].tolist()
                e["pred_rotation_aleatoric"] = out["pred_rotation_aleatoric"][0, d].tolist()
            dets.append(e)
        res.append({"image": img_path, "ms": ms, "detections": dets})
    with open(out_path, "w") as f:
        json.dump(res, f)


def make_dataset(ds, images, width, height, K):
    from PIL import Image
    if os.path.exists(ds):
        shutil.rmtree(ds)
    data = os.path.join(ds, "mav0", "cam0", "data")
    os.makedirs(data)
    stamps = []
    for k, p in enumerate(images):
        if Image.open(p).size != (width, height):
            sys.exit(f"error: {p} is not {width}x{height}")
        t = 1_000_000_000 + k * 100_000_000
        shutil.copyfile(p, os.path.join(data, f"{t}.png"))
        stamps.append(t)
    with open(os.path.join(ds, "mav0", "cam0", "data.csv"), "w") as f:
        f.write("#timestamp [ns],filename\n")
        f.writelines(f"{t},{t}.png\n" for t in stamps)
    manifest = {"schema": "roe-dataset/1", "name": "poet-verify",
                "camera": {"width": width, "height": height, "fx": K[0], "fy": K[1], "cx": K[2], "cy": K[3]}}
    with open(os.path.join(ds, "roe.json"), "w") as f:
        json.dump(manifest, f, indent=2)
    with open(os.path.join(ds, "boxes.csv"), "w") as f:
        f.write("timestamp_ns,class,x1,y1,x2,y2,score\n")
        for k, t in enumerate(stamps):
            f.writelines(f"{t},{c},{x1},{y1},{x2},{y2},{s:.1f}\n" for c, x1, y1, x2, y2, s in frame_boxes(k, width, height))
    return stamps


def quat_to_R(qx, qy, qz, qw):
    return [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]]


def angle_between(R1, R2):
    tr = sum(R1[i][j] * R2[i][j] for i in range(3) for j in range(3))  # trace(R1ᵀ R2)
    return math.acos(max(-1.0, min(1.0, (tr - 1) / 2)))


def compare(ref, stamps, det_csv, aleatoric):
    """roe's rows vs PoET's first detection of each class per frame."""
    rows = {}
    with open(det_csv) as f:
        for r in csv.DictReader(f):
            rows.setdefault(int(r["timestamp_ns"]), {})[int(r["object_id"])] = r
    worst = {"t_m": 0.0, "rot_rad": 0.0, "sigma_rel": 0.0}
    n, problems = 0, []
    for t_ns, frame in zip(stamps, ref):
        want = {}
        for d in frame["detections"]:
            want.setdefault(d["class"], d)
        got = rows.get(t_ns, {})
        if set(want) != set(got):
            problems.append(f"frame {t_ns}: PoET objects {sorted(want)}, roe {sorted(got)}")
        for c in set(want) & set(got):
            d, r = want[c], got[c]
            n += 1
            t = [float(r["tx"]), float(r["ty"]), float(r["tz"])]
            worst["t_m"] = max(worst["t_m"], max(abs(x - y) for x, y in zip(t, d["t"])))
            R = quat_to_R(*(float(r[k]) for k in ("qx", "qy", "qz", "qw")))
            worst["rot_rad"] = max(worst["rot_rad"], angle_between(R, d["R"]))
            if aleatoric:
                want_s = [math.exp(s / 2) for s in d["pred_translation_aleatoric"] + d["pred_rotation_aleatoric"]]
                cols = ["sigma_tx", "sigma_ty", "sigma_tz", "sigma_rx", "sigma_ry", "sigma_rz"]
                if not all(r.get(k) for k in cols):
                    problems.append(f"frame {t_ns} object {c}: no sigma columns")
                    continue
                got_s = [float(r[k]) for k in cols]
                worst["sigma_rel"] = max(worst["sigma_rel"], max(abs(g / w - 1) for g, w in zip(got_s, want_s)))
    return n, worst, problems


def run_variant(a, poet_dir, ops_dir, work, images, aleatoric):
    name = "poet-verify-aleatoric" if aleatoric else "poet-verify"
    vdir = os.path.join(work, name)
    os.makedirs(vdir, exist_ok=True)
    ckpt, bundle = os.path.join(vdir, "checkpoint.pth"), os.path.join(vdir, "bundle")
    me = os.path.abspath(__file__)
    py = sys.executable
    common = ["--poet", a.poet, "--yolo", a.yolo, "--ddetr", a.ddetr, "--work", work, "--threads", str(a.threads)]
    timings = {}
    t0 = time.perf_counter()
    subprocess.run([py, me, *common, "--step", "checkpoint", "--aleatoric", str(int(aleatoric)), "--out", ckpt], check=True)
    if os.path.exists(bundle):
        shutil.rmtree(bundle)
    t1 = time.perf_counter()
    subprocess.run([py, os.path.join(HERE, "export_poet.py"), "--poet-dir", poet_dir, "--ops-dir", ops_dir,
                    "--checkpoint", ckpt, "--out", bundle, "--model-id", name, "--intrinsics", a.intrinsics,
                    "--image-size", a.image_size, "--selftest-image", images[0]], check=True)
    t2 = time.perf_counter()
    ref_path = os.path.join(vdir, "reference.json")
    subprocess.run([py, me, *common, "--step", "reference", "--checkpoint", ckpt, "--out", ref_path,
                    "--images", *images], check=True)
    t3 = time.perf_counter()
    with open(ref_path) as f:
        ref = json.load(f)
    w, h = (int(v) for v in a.image_size.lower().split("x"))
    ds = os.path.join(vdir, "dataset")
    stamps = make_dataset(ds, images, w, h, [float(v) for v in a.intrinsics.split(",")])
    env = dict(os.environ, OMP_NUM_THREADS=str(a.threads))
    r = subprocess.run([a.roe, "infer", ds, "--model", bundle, "--boxes", os.path.join(ds, "boxes.csv"), "--json"],
                       capture_output=True, text=True, env=env)
    t4 = time.perf_counter()
    if r.returncode != 0:
        sys.exit(f"error: roe infer failed ({r.returncode}):\n{r.stdout}\n{r.stderr}")
    with open(os.path.join(ds, "detections", name, "meta.json")) as f:
        meta = json.load(f)
    n, worst, problems = compare(ref, stamps, os.path.join(ds, "detections", name, "detections.csv"), aleatoric)
    timings = {"checkpoint_s": t1 - t0, "export_s": t2 - t1, "reference_s": t3 - t2, "roe_infer_s": t4 - t3,
               "pytorch_ms_per_frame": [f["ms"] for f in ref], "roe_ms_per_frame": [p["ms"] for p in meta["per_frame"]]}
    return {"variant": name, "aleatoric": aleatoric, "detections_compared": n,
            "poet_detections": [len(f["detections"]) for f in ref], "worst": worst, "problems": problems,
            "selftest": meta.get("selftest"), "timings": timings}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poet", required=True, help="aau-cns/poet checkout")
    ap.add_argument("--yolo", required=True, help="aau-cns/yolov4 checkout (PoET's YOLO wrapper)")
    ap.add_argument("--ddetr", required=True, help="fundamentalvision/Deformable-DETR checkout")
    ap.add_argument("--roe", default=os.path.join(HERE, "..", "build", "roe"), help="roe binary")
    ap.add_argument("--work", required=True, help="scratch folder (outside the repository)")
    ap.add_argument("--images", nargs="+", help="PNG/JPEG images at --image-size (default: two generated)")
    ap.add_argument("--image-size", default="640x480")
    ap.add_argument("--intrinsics", default="1066.778,1067.487,312.9869,241.3109", help="training camera fx,fy,cx,cy")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variants", default="plain,aleatoric")
    ap.add_argument("--tol-t", type=float, default=1e-3, help="max |t| difference (m)")
    ap.add_argument("--tol-rot", type=float, default=1e-3, help="max rotation difference (rad)")
    ap.add_argument("--tol-sigma", type=float, default=1e-3, help="max relative sigma difference")
    ap.add_argument("--step", help=argparse.SUPPRESS)
    ap.add_argument("--aleatoric", help=argparse.SUPPRESS)
    ap.add_argument("--checkpoint", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    a = ap.parse_args()
    a.poet, a.yolo, a.ddetr, a.work = (os.path.abspath(p) for p in (a.poet, a.yolo, a.ddetr, a.work))
    a.roe = os.path.abspath(a.roe)
    poet_dir, ops_dir = os.path.join(a.work, "poet"), os.path.join(a.work, "ops")
    if a.step == "checkpoint":
        return make_checkpoint(a, poet_dir, ops_dir, a.aleatoric == "1", a.out, seed=29)
    if a.step == "reference":
        return reference(a, poet_dir, ops_dir, a.checkpoint, a.images, a.out)

    os.makedirs(a.work, exist_ok=True)
    assemble(a, a.work)
    images = [os.path.abspath(p) for p in a.images] if a.images else generated_images(a)
    summary = {"poet_commit": git_commit(a.poet), "yolo_wrapper_commit": git_commit(a.yolo),
               "deformable_detr_commit": git_commit(a.ddetr), "image_size": a.image_size, "images": images,
               "tolerance": {"t_m": a.tol_t, "rot_rad": a.tol_rot, "sigma_rel": a.tol_sigma}, "variants": []}
    ok = True
    for v in a.variants.split(","):
        res = run_variant(a, poet_dir, ops_dir, a.work, images, v == "aleatoric")
        w = res["worst"]
        res["pass"] = (not res["problems"] and res["detections_compared"] > 0 and w["t_m"] <= a.tol_t
                       and w["rot_rad"] <= a.tol_rot and w["sigma_rel"] <= a.tol_sigma)
        ok = ok and res["pass"]
        summary["variants"].append(res)
    summary["pass"] = ok
    with open(os.path.join(a.work, "summary.json"), "w") as f:
        json.dump(summary, f, indent=2)
    print(json.dumps(summary, indent=2))
    return 0 if ok else 1


def generated_images(a):
    """Two images when none are given: smooth colour gradients with filled shapes (PIL)."""
    from PIL import Image, ImageDraw
    w, h = (int(v) for v in a.image_size.lower().split("x"))
    out = []
    for k in range(2):
        img = Image.new("RGB", (w, h))
        px = img.load()
        for y in range(h):
            for x in range(w):
                px[x, y] = ((x * 255) // w, (y * 255) // h, ((x + y + 80 * k) * 255) // (w + h))
        d = ImageDraw.Draw(img)
        d.rectangle([w // 5 + 40 * k, h // 4, w // 5 + 90 + 40 * k, h // 4 + 120], fill=(200, 30, 30))
        d.ellipse([w // 2, h // 2 - 30 * k, w // 2 + 110, h // 2 + 80 - 30 * k], fill=(30, 30, 220))
        p = os.path.join(a.work, f"image{k}.png")
        img.save(p)
        out.append(p)
    return out


if __name__ == "__main__":
    sys.exit(main() or 0)
