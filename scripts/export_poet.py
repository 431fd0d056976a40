#!/usr/bin/python3
"""Export a trained PoET model (aau-cns/poet, YOLOv4 backbone) to a roe model bundle for `roe infer`.

Run it inside (or next to) YOUR checkout of PoET, with a downloaded checkpoint, using the same torch
version as the LibTorch roe links (Debian bookworm: python3-torch 1.13.1 = libtorch-dev 1.13.1):

    /usr/bin/python3 scripts/export_poet.py --poet-dir ~/src/poet --checkpoint poet_ycbv_yolo.pth \\
        --out bundles/poet-ycbv --model-id poet-ycbv-yolo \\
        --intrinsics 1066.778,1067.487,312.9869,241.3109 --selftest-image some_frame.png

What it does (docs/infer.md, "Exporting a PoET checkpoint"):
  * imports PoET (and the YOLO wrapper under PoET's models/) from --poet-dir; nothing of PoET is
    copied into roe or into the bundle except the user's own Darknet cfg and converted weights;
  * stubs the CUDA-only extensions (MultiScaleDeformableAttention, mish_cuda) and routes PoET's
    multi-scale deformable attention through a grid_sample implementation, so tracing runs on CPU;
  * rebuilds the model from checkpoint["args"] and loads the weights strictly (missing/unexpected
    keys are listed and abort the export unless --allow-missing);
  * traces a pose head that takes (boxes [Q,4], classes [Q], three YOLO feature maps) and returns
    (t [Q,3], rotation 6D [Q,6] or quaternion [Q,4] [, logvar_t, logvar_r]); roe runs the detector
    half with OpenCV's Darknet importer, so the YOLO weights are converted with the wrapper's own
    save_weights();
  * checks traced vs eager, and the wrapper against PoET's own forward (ground-truth box mode);
  * writes self-test vectors that `roe infer` checks on load, and poet_bundle.json.
Limitations: Mask/Faster R-CNN backbones use torchvision ops that Debian's LibTorch lacks, so they
cannot be exported this way; use PoET's own inference and `roe import poet` for those.
"""
import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import types
import warnings

import numpy as np
import torch
import torch.nn.functional as F

warnings.filterwarnings("ignore", category=torch.jit.TracerWarning)


# ------------------------------------------------------------------------------------------------
# CPU replacements for PoET's CUDA-only pieces
# ------------------------------------------------------------------------------------------------
def mish(x):
    return x * torch.tanh(F.softplus(x))


class MishModule(torch.nn.Module):
    def forward(self, x):
        return mish(x)


def stub_cuda_extensions():
    """Lets PoET's imports succeed without the compiled CUDA extensions."""
    if "MultiScaleDeformableAttention" not in sys.modules:
        sys.modules["MultiScaleDeformableAttention"] = types.ModuleType("MultiScaleDeformableAttention")
    if "mish_cuda" not in sys.modules:
        m = types.ModuleType("mish_cuda")
        m.MishCuda = MishModule
        sys.modules["mish_cuda"] = m


def deformable_attention_grid_sample(value, spatial_shapes, sampling_locations, attention_weights):
    """Multi-scale deformable attention with bilinear grid_sample (zeros padding, align_corners=False).
    value [N, S, M, D]; spatial_shapes [L, 2] (h, w); sampling_locations [N, Lq, M, L, P, 2] in [0, 1];
    attention_weights [N, Lq, M, L, P] → [N, Lq, M·D]."""
    n, _, m, d = value.shape
    _, lq, _, nl, p, _ = sampling_locations.shape
    shapes = [(int(h), int(w)) for h, w in spatial_shapes]
    per_level = value.split([h * w for h, w in shapes], dim=1)
    grids = 2.0 * sampling_locations - 1.0
    sampled = []
    for lvl, (h, w) in enumerate(shapes):
        v = per_level[lvl].flatten(2).transpose(1, 2).reshape(n * m, d, h, w)
        g = grids[:, :, :, lvl].transpose(1, 2).flatten(0, 1)  # [N·M, Lq, P, 2]
        sampled.append(F.grid_sample(v, g, mode="bilinear", padding_mode="zeros", align_corners=False))
    s = torch.stack(sampled, dim=-2).flatten(-2)  # [N·M, D, Lq, L·P]
    w = attention_weights.transpose(1, 2).reshape(n * m, 1, lq, nl * p)
    return (s * w).sum(-1).view(n, m * d, lq).transpose(1, 2).contiguous()


class DeformAttnShim:
    """Stands in for Deformable-DETR's MSDeformAttnFunction (same apply() arguments)."""

    @staticmethod
    def apply(value, spatial_shapes, level_start_index, sampling_locations, attention_weights, im2col_step):
        return deformable_attention_grid_sample(value, spatial_shapes, sampling_locations, attention_weights)


def find_yolo_builder():
    """The Scaled-YOLOv4 wrapper (aau-cns/yolov4) placed into PoET's models/ as its README says:
    models/cns_yolo.py + models/yolo/. Returns build_cns_yolo, or None when it is not there."""
    try:
        from models.cns_yolo import build_cns_yolo
    except ImportError as e:
        if "cns_yolo" not in str(e):
            raise
        return None
    return build_cns_yolo


def patch_yolo_backbone():
    """aau-cns/poet's build_backbone builds only Mask/Faster R-CNN and raises NotImplementedError for
    'yolov4' (commit 227f6a4, Sep 2025): the YOLO wrapper is a separate download. This routes
    'yolov4' to the wrapper with PoET's own Joiner and position encoding, as PoET's training code does
    once the wrapper is in place."""
    import models.backbone as bb
    import models.pose_estimation_transformer as pet
    original = bb.build_backbone

    def build_backbone(args):
        if args.backbone not in ("yolov4", "yolo"):
            return original(args)
        build_cns_yolo = find_yolo_builder()
        if build_cns_yolo is None:
            sys.exit("error: the YOLO wrapper is missing: put aau-cns/yolov4's cns_yolo.py and yolo/ into "
                     "PoET's models/ folder (PoET README, 'Scaled-YOLOv4 Backbone')")
        return bb.Joiner(build_cns_yolo(args), bb.build_position_encoding(args))

    bb.build_backbone = build_backbone
    pet.build_backbone = build_backbone


def darknet_weights_writer(model):
    """The wrapper's Darknet module and its save_weights (a module-level function in
    yolo/backbone_models/models.py, save_weights(model, path)) → a callable path → None."""
    for m in model.backbone.modules():
        if hasattr(m, "module_defs") and hasattr(m, "module_list"):
            if callable(getattr(m, "save_weights", None)):
                return m.save_weights
            for cls in type(m).__mro__:
                fn = getattr(sys.modules.get(cls.__module__), "save_weights", None)
                if callable(fn):
                    return lambda path, m=m, fn=fn: fn(m, path=path)
    return None


def patch_deformable_attention():
    patched = []
    for name, mod in list(sys.modules.items()):
        if mod is not None and hasattr(mod, "MSDeformAttnFunction"):
            setattr(mod, "MSDeformAttnFunction", DeformAttnShim)
            patched.append(name)
    return patched


# ------------------------------------------------------------------------------------------------
# The traced pose head: PoET's transformer and heads on given boxes and backbone features
# ------------------------------------------------------------------------------------------------
class PoseHeadFromFeatures(torch.nn.Module):
    def __init__(self, poet, nested_tensor_cls):
        super().__init__()
        self.poet = poet
        self.nt = nested_tensor_cls

    def forward(self, boxes, classes, *features):
        poet = self.poet
        srcs, masks, pos = [], [], []
        for lvl, f in enumerate(features):
            mask = torch.zeros((f.shape[0], f.shape[2], f.shape[3]), dtype=torch.bool)
            pos.append(poet.backbone[1](self.nt(f, mask)).to(f.dtype))
            srcs.append(poet.input_proj[lvl](f))
            masks.append(mask)
        for lvl in range(len(features), poet.num_feature_levels):
            src = poet.input_proj[lvl](features[-1] if lvl == len(features) else srcs[-1])
            mask = torch.zeros((src.shape[0], src.shape[2], src.shape[3]), dtype=torch.bool)
            pos.append(poet.backbone[1](self.nt(src, mask)).to(src.dtype))
            srcs.append(src)
            masks.append(mask)
        valid = classes >= 0
        emb = poet.bbox_embedding(boxes).repeat(1, 2)
        emb = torch.where(valid[:, None], emb, torch.full_like(emb, -10.0))  # PoET's placeholder queries
        hs = poet.transformer(srcs, masks, pos, emb[None], boxes[None, :, :2])[0]
        h = hs[-1]
        q = boxes.shape[0]
        slot = torch.where(classes > 0, classes, torch.zeros_like(classes))

        def select(x):
            if poet.class_mode == "specific":
                x = x.view(q, poet.n_classes, -1)
                return x.gather(1, slot[:, None, None].expand(q, 1, x.shape[2])).squeeze(1)
            return x.view(q, -1)

        outs = [select(poet.translation_head[-1](h)), select(poet.rotation_head[-1](h))]
        if getattr(poet, "aleatoric", False):
            outs += [select(poet.translation_head_aleatoric[-1](h)), select(poet.rotation_head_aleatoric[-1](h))]
        return tuple(outs)


def gram_schmidt(r6):
    x = F.normalize(r6[:, 0:3], dim=1)
    z = F.normalize(torch.cross(x, r6[:, 3:6], dim=1), dim=1)
    y = torch.cross(z, x, dim=1)
    return torch.stack([x, y, z], dim=2)


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poet-dir", required=True, help="checkout of aau-cns/poet (with the YOLO wrapper under models/)")
    ap.add_argument("--checkpoint", required=True, help="PoET checkpoint (.pth with 'model' and 'args')")
    ap.add_argument("--out", required=True, help="bundle folder to create")
    ap.add_argument("--model-id", required=True, help="roe model id (letters, digits, . _ -)")
    ap.add_argument("--ops-dir", help="Deformable-DETR models/ops folder, if its package is not installed")
    ap.add_argument("--darknet-cfg", help="the detector cfg (default: the checkpoint's backbone_cfg, relative to "
                                          "--poet-dir, else PoET's configs/ycbv_yolov4-csp.cfg)")
    ap.add_argument("--feature-layers", default="mish_143,mish_158,mish_173",
                    help="OpenCV names of the YOLO layers PoET taps (YOLOv4-CSP: Darknet 142/157/172)")
    ap.add_argument("--intrinsics", required=True, help="training camera fx,fy,cx,cy (pixels)")
    ap.add_argument("--image-size", default="640x480", help="training image size WxH (multiples of 32)")
    ap.add_argument("--classes", help="class-info JSON (default: PoET's dataset_files/ycbv_classes.json)")
    ap.add_argument("--symmetries", help="symmetric class ids JSON (default: dataset_files/ycbv_symmetries.json)")
    ap.add_argument("--selftest-image", help="PNG at the training size for the self-test (default: random)")
    ap.add_argument("--allow-missing", action="store_true", help="accept missing/unexpected checkpoint keys")
    a = ap.parse_args()

    width, height = (int(v) for v in a.image_size.lower().split("x"))
    fx, fy, cx, cy = (float(v) for v in a.intrinsics.split(","))
    poet_dir = os.path.abspath(a.poet_dir)
    stub_cuda_extensions()
    for p in [a.ops_dir, poet_dir]:
        if p:
            sys.path.insert(0, os.path.abspath(p))
    from models import build_model  # PoET's, from the user's checkout
    from util.misc import NestedTensor
    patch_yolo_backbone()
    patched = patch_deformable_attention()
    if not patched:
        sys.exit("error: PoET's deformable attention (MSDeformAttnFunction) was not found to patch; is the "
                 "Deformable-DETR ops package importable (--ops-dir)?")

    ckpt = torch.load(a.checkpoint, map_location="cpu")
    if "args" not in ckpt or "model" not in ckpt:
        sys.exit("error: the checkpoint has no 'args'/'model' entries; roe needs PoET's training args to rebuild it")
    args = ckpt["args"]
    args.device = "cpu"
    if getattr(args, "backbone", "yolov4") not in ("yolov4", "yolo"):
        sys.exit(f"error: backbone '{args.backbone}' uses torchvision ops LibTorch lacks; use `roe import poet`")
    args.bbox_mode = "gt"
    args.backbone_weights = None  # the detector's weights are in the checkpoint
    args.lr_backbone = 0.0  # frozen backbone: PoET's Joiner refuses a trainable one in forward()
    built = build_model(args)
    model = built[0] if isinstance(built, (tuple, list)) else built
    missing, unexpected = model.load_state_dict(ckpt["model"], strict=False)
    if missing or unexpected:
        print(f"missing keys: {missing}\nunexpected keys: {unexpected}", file=sys.stderr)
        if not a.allow_missing:
            sys.exit("error: checkpoint and model do not match (see above); --allow-missing to export anyway")
    model.eval()
    rotation = {"6d": "6d", "quat": "quat_wxyz", "silho_quat": "quat_wxyz"}[model.rotation_mode]
    q = int(model.n_queries)

    os.makedirs(os.path.join(a.out, "selftest"), exist_ok=True)
    # Self-test image → backbone features and detections (PyTorch, the reference for OpenCV).
    if a.selftest_image:
        from PIL import Image
        img = np.asarray(Image.open(a.selftest_image).convert("RGB"))
    else:
        img = np.random.default_rng(0).integers(0, 256, (height, width, 3), dtype=np.uint8)
    if img.shape[:2] != (height, width):
        sys.exit(f"error: the self-test image must be {width}x{height}")
    from PIL import Image
    Image.fromarray(img).save(os.path.join(a.out, "selftest", "detector_input.png"))
    x = torch.from_numpy(img.astype(np.float32) / 255.0).permute(2, 0, 1)[None]
    mask = torch.zeros((1, height, width), dtype=torch.bool)
    with torch.no_grad():
        features, _, preds = model.backbone(NestedTensor(x, mask))
    feats = [f.tensors if hasattr(f, "tensors") else f.decompose()[0] for f in features]

    # The wrapper's detections after NMS (x1, y1, x2, y2, conf, class + 1): roe's decoding and NMS must
    # reproduce them (detector.selftest.detections).
    p_all = preds[0] if preds and preds[0] is not None else torch.zeros((0, 6))
    np.save(os.path.join(a.out, "selftest", "detections.npy"), p_all.detach().numpy().astype(np.float32).reshape(-1, 6))

    boxes = torch.full((q, 4), -1.0)
    classes = torch.full((q,), -1, dtype=torch.int64)
    n = 0
    if preds and preds[0] is not None and len(preds[0]):
        p = preds[0][:q]
        xyxy = p[:, :4]
        boxes[: len(p)] = torch.stack([(xyxy[:, 0] + xyxy[:, 2]) / 2 / width, (xyxy[:, 1] + xyxy[:, 3]) / 2 / height,
                                       (xyxy[:, 2] - xyxy[:, 0]) / width, (xyxy[:, 3] - xyxy[:, 1]) / height], 1)
        classes[: len(p)] = p[:, 5].long()
        n = len(p)
    if n == 0:  # no detection on the image: two made-up boxes still exercise the head
        boxes[0] = torch.tensor([0.3, 0.4, 0.2, 0.25])
        boxes[1] = torch.tensor([0.6, 0.5, 0.15, 0.3])
        classes[:2] = torch.tensor([1, 2])
        n = 2

    head = PoseHeadFromFeatures(model, NestedTensor).eval()
    with torch.no_grad():
        eager = head(boxes, classes, *feats)
        traced = torch.jit.trace(head, (boxes, classes, *feats), check_trace=False)
        b2, c2 = boxes.clone(), classes.clone()
        b2[1:], c2[1:] = -1.0, -1
        for b, c in [(boxes, classes), (b2, c2)]:
            e, t = head(b, c, *feats), traced(b, c, *feats)
            err = max((x1 - x2).abs().max().item() for x1, x2 in zip(e, t))
            print(f"traced vs eager ({int((c >= 0).sum())} boxes): max |diff| = {err:.3g}")
            if err > 1e-5:
                sys.exit("error: the traced pose head differs from the eager one")
        # The wrapper against PoET's own forward with the same boxes (ground-truth box mode).
        target = [{"boxes": boxes[:n], "labels": classes[:n]}]
        out, _ = model(NestedTensor(x, mask), target)
        rot_ref = out["pred_rotation"][0, :n]
        rot_ours = gram_schmidt(eager[1][:n]) if rotation == "6d" else F.normalize(eager[1][:n], dim=1)
        err_r = (rot_ref - rot_ours).abs().max().item()
        err_t = (out["pred_translation"][0, :n] - eager[0][:n]).abs().max().item()
        print(f"wrapper vs PoET forward: max |diff| t = {err_t:.3g}, rotation = {err_r:.3g}")
        if max(err_r, err_t) > 1e-4:
            sys.exit("error: the exported head does not reproduce PoET's forward")

    traced.save(os.path.join(a.out, "pose_head.ts"))
    inputs = ["selftest/boxes.npy", "selftest/classes.npy"]
    np.save(os.path.join(a.out, inputs[0]), boxes.numpy().astype(np.float32))
    np.save(os.path.join(a.out, inputs[1]), classes.numpy().astype(np.int64))
    layers = [s.strip() for s in a.feature_layers.split(",")]
    if len(layers) != len(feats):
        sys.exit(f"error: {len(feats)} backbone feature maps but {len(layers)} --feature-layers")
    det_refs = {}
    for i, f in enumerate(feats):
        fn = f"selftest/feature{i}.npy"
        np.save(os.path.join(a.out, fn), f.numpy().astype(np.float32))
        inputs.append(fn)
        det_refs[layers[i]] = fn
    names = ["t", "rotation", "logvar_t", "logvar_r"]
    outputs = []
    for i, o in enumerate(eager):
        fn = f"selftest/{names[i]}.npy"
        np.save(os.path.join(a.out, fn), o.numpy().astype(np.float32))
        outputs.append(fn)

    # Detector: the user's cfg and the backbone's weights in Darknet format (the wrapper's converter).
    cfg = a.darknet_cfg
    if not cfg:
        trained = getattr(args, "backbone_cfg", "") or "configs/ycbv_yolov4-csp.cfg"
        cfg = trained if os.path.isabs(trained) else os.path.join(poet_dir, trained)
    if not os.path.exists(cfg):
        sys.exit(f"error: the detector cfg {cfg} does not exist (give it with --darknet-cfg)")
    shutil.copyfile(cfg, os.path.join(a.out, "detector.cfg"))
    write_weights = darknet_weights_writer(model)
    if write_weights is None:
        sys.exit("error: no Darknet module with the wrapper's save_weights() in PoET's backbone")
    write_weights(os.path.join(a.out, "detector.weights"))

    names_file = a.classes or os.path.join(poet_dir, "dataset_files", "ycbv_classes.json")
    with open(names_file) as f:
        class_names = {int(k): v for k, v in json.load(f).items() if int(k) > 0}
    sym_file = a.symmetries or os.path.join(poet_dir, "dataset_files", "ycbv_symmetries.json")
    symmetric = []
    if os.path.exists(sym_file):
        with open(sym_file) as f:
            s = json.load(f)
        # PoET's dataset_files/ycbv_symmetries.json maps class *names* to true/false; ids are accepted too.
        by_name = {v: k for k, v in class_names.items()}
        items = s.items() if isinstance(s, dict) else enumerate(s)
        unknown = [k for k, v in items if v and not str(k).isdigit() and k not in by_name]
        if unknown:
            sys.exit(f"error: {sym_file}: symmetric classes {unknown} are not in {names_file}")
        items = s.items() if isinstance(s, dict) else enumerate(s)
        symmetric = sorted(int(k) if str(k).isdigit() else by_name[k] for k, v in items if v)
    try:
        commit = subprocess.run(["git", "-C", poet_dir, "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    except OSError:
        commit = ""
    bundle = {
        "schema": "roe-poet-bundle/1",
        "model_id": a.model_id,
        "image": {"width": width, "height": height, "color": "RGB", "scale": 1.0 / 255.0, "mean": [0, 0, 0], "std": [1, 1, 1]},
        "train_intrinsics": {"fx": fx, "fy": fy, "cx": cx, "cy": cy},
        "num_queries": q,
        "classes": [{"id": k, "name": v} for k, v in sorted(class_names.items())],
        "symmetric": symmetric,
        "rotation": rotation,
        "translation_unit": "m",
        "detector": {
            "kind": "darknet", "cfg": "detector.cfg", "weights": "detector.weights",
            "conf_thresh": float(getattr(args, "backbone_conf_thresh", 0.4)),
            "iou_thresh": float(getattr(args, "backbone_iou_thresh", 0.5)),
            "max_detections": 300, "multi_label": len(class_names) > 1,
            "class_aware": not bool(getattr(args, "backbone_agnostic_nms", False)), "class_offset": 1,
            "feature_layers": layers,
            "selftest": {"image": "selftest/detector_input.png", "outputs": det_refs, "atol": 1e-4,
                         "detections": "selftest/detections.npy"},
        },
        "pose": {"file": "pose_head.ts", "torch_version": torch.__version__.split("+")[0], "inputs": "features",
                 "aleatoric": bool(getattr(model, "aleatoric", False))},
        "provenance": {
            "exporter": "roe scripts/export_poet.py", "poet_dir": poet_dir, "poet_commit": commit,
            "checkpoint": os.path.abspath(a.checkpoint), "checkpoint_sha256": sha256(a.checkpoint),
            "training_args": {k: str(v) for k, v in sorted(vars(args).items())}, "patched_modules": patched,
        },
        "selftest": {"inputs": inputs, "outputs": outputs, "atol": 1e-5},
    }
    with open(os.path.join(a.out, "poet_bundle.json"), "w") as f:
        json.dump(bundle, f, indent=2)
        f.write("\n")
    print(f"wrote {a.out}: check it with `roe infer DATASET --model {a.out}` (the self-test runs on load)")


if __name__ == "__main__":
    main()
