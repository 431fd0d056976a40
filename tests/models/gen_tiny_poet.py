#!/usr/bin/python3
"""Builds roe's test model bundles: a tiny PoET-shaped pose head (TorchScript) and a tiny Darknet
detector, with self-test vectors and reference outputs.

    /usr/bin/python3 tests/models/gen_tiny_poet.py                 # tests/models/tiny_poet (committed)
    /usr/bin/python3 tests/models/gen_tiny_poet.py --full OUT_DIR  # PoET-sized, random weights (benchmark)

The pose head keeps PoET's inference contract as roe defines it (docs/infer.md): inputs
boxes float32 [Q,4] (normalised cx, cy, w, h; padding rows -1), classes int64 [Q] (1-based; padding
-1) and the detector's feature maps; outputs t float32 [Q,3] (metres, camera frame) and the raw
rotation [Q,6] (6D: two columns of R, Gram-Schmidt in roe). Architecture, written for roe (no PoET
code): per-level 1x1 projection + GroupNorm, sine box embeddings as queries (placeholders -10),
a deformable-attention encoder over all feature tokens and a decoder (query self-attention +
deformable cross-attention sampled with grid_sample), class-specific heads.

The tiny detector is hand-set, not trained. It finds axis-aligned squares of 24 px filled with one
of three pure colours (red = class 1, green = 2, blue = 3) in a 128x96 RGB image:
  conv 1x1 logistic   colour indicators
  conv 29x29 /4       box filter (24x24 window centred on each YOLO cell centre) = coverage R_k
  maxpool 2/2         (a second, stride-8 feature level for the pose head)
  maxpool 3/1         local maximum of R
  conv 1x1            objectness = high only where R is a local maximum; class = R_k;
                      box-size logits ln(√½/(1 − √½)) = 0.8814
  yolo                one 12x12 anchor: PoET's rule w = (2σ(tw))²·anchor doubles it to 24 px
                      (Darknet's exp() rule, OpenCV's Region layer, would give 29 px)
The detector self-test also stores the detections after NMS that PoET's detector code gives
(poet_detections: the aau-cns/yolov4 YOLOLayer decoding and Scaled-YOLOv4's NMS, re-written here).
The tiny pose head adds a pinhole prior to t (depth from the box width for a 0.06 m square, at the
bundle's training intrinsics) so its outputs are plausible; the transformer adds a bounded term.
"""
import argparse
import hashlib
import json
import math
import os
import struct
import sys

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F
import warnings

# Shapes are fixed by the bundle's image size, so the tracer's notes on constant shapes are expected.
warnings.filterwarnings("ignore", category=torch.jit.TracerWarning)

HERE = os.path.dirname(os.path.abspath(__file__))


# ------------------------------------------------------------------------------------------------
# Pose head
# ------------------------------------------------------------------------------------------------
def box_sine_embedding(boxes, freqs):
    """[Q,4] in [0,1] → [Q, 4*2*freqs]: sin/cos of each coordinate at frequencies 2^k·π."""
    k = torch.arange(freqs, dtype=torch.float32)
    scale = (2.0 ** k) * math.pi  # [F]
    a = boxes[:, :, None] * scale  # [Q,4,F]
    return torch.cat([a.sin(), a.cos()], dim=-1).reshape(boxes.shape[0], -1)


def grid_sine_embedding(h, w, d):
    """2-D sine position code of a h x w map, [h*w, d] (d/2 for y, d/2 for x)."""
    ys = (torch.arange(h, dtype=torch.float32) + 0.5) / h
    xs = (torch.arange(w, dtype=torch.float32) + 0.5) / w
    yy, xx = torch.meshgrid(ys, xs, indexing="ij")
    nf = d // 4
    k = (2.0 ** torch.arange(nf, dtype=torch.float32)) * math.pi
    ey = yy.reshape(-1, 1) * k
    ex = xx.reshape(-1, 1) * k
    return torch.cat([ey.sin(), ey.cos(), ex.sin(), ex.cos()], dim=1)


class DeformableAttention(nn.Module):
    """Multi-scale deformable attention: each query samples `points` locations per head and level
    around its reference point (bilinear grid_sample of the projected values) and mixes them with
    softmax weights predicted from the query."""

    def __init__(self, d, heads, levels, points):
        super().__init__()
        self.d, self.h, self.l, self.p = d, heads, levels, points
        self.offsets = nn.Linear(d, heads * levels * points * 2)
        self.weights = nn.Linear(d, heads * levels * points)
        self.value = nn.Linear(d, d)
        self.out = nn.Linear(d, d)
        nn.init.uniform_(self.offsets.bias, -1.5, 1.5)

    def forward(self, query, ref, values, shapes):
        # query [N,d], ref [N,2] normalised (x, y), values: list of [h*w, d], shapes: list of (h, w)
        n = query.shape[0]
        dh = self.d // self.h
        off = self.offsets(query).view(n, self.h, self.l, self.p, 2)
        wgt = F.softmax(self.weights(query).view(n, self.h, self.l * self.p), dim=-1).view(n, self.h, self.l, self.p)
        acc = None
        for lvl in range(self.l):
            h, w = shapes[lvl]
            v = self.value(values[lvl]).view(h, w, self.h, dh).permute(2, 3, 0, 1)  # [H, dh, h, w]
            norm = torch.tensor([float(w), float(h)])
            loc = ref[:, None, None, :] + off[:, :, lvl] / norm  # [N, H, P, 2]
            grid = (2.0 * loc - 1.0).permute(1, 0, 2, 3)  # [H, N, P, 2]
            s = F.grid_sample(v, grid, mode="bilinear", padding_mode="zeros", align_corners=False)  # [H, dh, N, P]
            s = (s * wgt[:, :, lvl].permute(1, 0, 2)[:, None]).sum(-1)  # [H, dh, N]
            acc = s if acc is None else acc + s
        return self.out(acc.permute(2, 0, 1).reshape(n, self.d))


class SelfAttention(nn.Module):
    def __init__(self, d, heads):
        super().__init__()
        self.h = heads
        self.qkv = nn.Linear(d, 3 * d)
        self.out = nn.Linear(d, d)

    def forward(self, x, key_valid):
        n, d = x.shape
        dh = d // self.h
        q, k, v = self.qkv(x).view(n, 3, self.h, dh).permute(1, 2, 0, 3)  # each [H, N, dh]
        att = q @ k.transpose(1, 2) / math.sqrt(dh)
        att = att.masked_fill(~key_valid[None, None, :], -1e4)
        return self.out((F.softmax(att, dim=-1) @ v).permute(1, 0, 2).reshape(n, d))


class FFN(nn.Module):
    def __init__(self, d, hidden):
        super().__init__()
        self.a = nn.Linear(d, hidden)
        self.b = nn.Linear(hidden, d)

    def forward(self, x):
        return self.b(F.relu(self.a(x)))


class EncoderLayer(nn.Module):
    def __init__(self, d, heads, levels, points, ffn):
        super().__init__()
        self.attn = DeformableAttention(d, heads, levels, points)
        self.n1 = nn.LayerNorm(d)
        self.ffn = FFN(d, ffn)
        self.n2 = nn.LayerNorm(d)

    def forward(self, x, pos, ref, shapes, starts):
        values = [x[starts[i]:starts[i + 1]] for i in range(len(shapes))]
        x = self.n1(x + self.attn(x + pos, ref, values, shapes))
        return self.n2(x + self.ffn(x))


class DecoderLayer(nn.Module):
    def __init__(self, d, heads, levels, points, ffn):
        super().__init__()
        self.self_attn = SelfAttention(d, heads)
        self.n1 = nn.LayerNorm(d)
        self.cross = DeformableAttention(d, heads, levels, points)
        self.n2 = nn.LayerNorm(d)
        self.ffn = FFN(d, ffn)
        self.n3 = nn.LayerNorm(d)

    def forward(self, tgt, qpos, valid, ref, memory, shapes, starts):
        tgt = self.n1(tgt + self.self_attn(tgt + qpos, valid))
        values = [memory[starts[i]:starts[i + 1]] for i in range(len(shapes))]
        tgt = self.n2(tgt + self.cross(tgt + qpos, ref, values, shapes))
        return self.n3(tgt + self.ffn(tgt))


class PoseHead(nn.Module):
    def __init__(self, in_channels, d, heads, points, enc, dec, ffn, classes, extra_levels, freqs, prior=None,
                 aleatoric=False):
        super().__init__()
        self.d = d
        self.freqs = freqs
        self.classes = classes
        levels = len(in_channels) + extra_levels
        self.proj = nn.ModuleList([nn.Sequential(nn.Conv2d(c, d, 1), nn.GroupNorm(min(32, d // 2), d)) for c in in_channels])
        self.extra = nn.ModuleList()
        c_last = in_channels[-1]
        for _ in range(extra_levels):
            self.extra.append(nn.Sequential(nn.Conv2d(c_last, d, 3, stride=2, padding=1), nn.GroupNorm(min(32, d // 2), d)))
            c_last = d
        self.level_embed = nn.Parameter(torch.randn(levels, d) * 0.1)
        self.encoder = nn.ModuleList([EncoderLayer(d, heads, levels, points, ffn) for _ in range(enc)])
        self.decoder = nn.ModuleList([DecoderLayer(d, heads, levels, points, ffn) for _ in range(dec)])
        self.query_split = nn.Linear(4 * 2 * freqs, 2 * d)
        self.t_head = nn.Sequential(nn.Linear(d, d), nn.ReLU(), nn.Linear(d, 3 * classes))
        self.r_head = nn.Sequential(nn.Linear(d, d), nn.ReLU(), nn.Linear(d, 6 * classes))
        # prior = (fx, fy, cx, cy, width, height, object size): pinhole depth from the box width.
        self.prior = prior
        # Aleatoric heads as PoET's (flag `aleatoric`): per class a log-variance s = log(sigma^2) of t (m^2)
        # and of the rotation error in so(3) (rad^2, R_pred R_true^T, camera frame). Made last so the
        # other modules keep their random weights.
        self.aleatoric = aleatoric
        if aleatoric:
            self.tv_head = nn.Sequential(nn.Linear(d, d), nn.ReLU(), nn.Linear(d, 3 * classes))
            self.rv_head = nn.Sequential(nn.Linear(d, d), nn.ReLU(), nn.Linear(d, 3 * classes))

    def forward(self, boxes, classes, *features):
        srcs = [p(f) for p, f in zip(self.proj, features)]
        x = features[-1]
        for e in self.extra:  # the first extra level from the raw last feature map, then chained
            x = e(x)
            srcs.append(x)
        shapes, tokens, pos, refs = [], [], [], []
        for lvl, s in enumerate(srcs):
            h, w = int(s.shape[2]), int(s.shape[3])
            shapes.append((h, w))
            tokens.append(s[0].flatten(1).transpose(0, 1))
            pos.append(grid_sine_embedding(h, w, self.d) + self.level_embed[lvl])
            ys = (torch.arange(h, dtype=torch.float32) + 0.5) / h
            xs = (torch.arange(w, dtype=torch.float32) + 0.5) / w
            yy, xx = torch.meshgrid(ys, xs, indexing="ij")
            refs.append(torch.stack([xx.reshape(-1), yy.reshape(-1)], dim=1))
        starts = [0]
        for h, w in shapes:
            starts.append(starts[-1] + h * w)
        mem = torch.cat(tokens, 0)
        mpos = torch.cat(pos, 0)
        mref = torch.cat(refs, 0)
        for layer in self.encoder:
            mem = layer(mem, mpos, mref, shapes, starts)

        valid = classes >= 0
        emb = box_sine_embedding(boxes, self.freqs)
        emb = torch.where(valid[:, None], emb, torch.full_like(emb, -10.0))  # placeholder queries
        qpos, tgt = self.query_split(emb).split(self.d, dim=1)
        ref = boxes[:, :2].clamp(0.0, 1.0)  # box centres
        for layer in self.decoder:
            tgt = layer(tgt, qpos, valid, ref, mem, shapes, starts)

        slot = (classes.clamp(min=1) - 1)  # class-specific heads; placeholders use slot 0
        q = boxes.shape[0]
        t_all = self.t_head(tgt).view(q, self.classes, 3)
        r_all = self.r_head(tgt).view(q, self.classes, 6)
        t = t_all.gather(1, slot[:, None, None].expand(q, 1, 3)).squeeze(1)
        r = r_all.gather(1, slot[:, None, None].expand(q, 1, 6)).squeeze(1)
        if self.aleatoric:
            s_t = self.tv_head(tgt).view(q, self.classes, 3).gather(1, slot[:, None, None].expand(q, 1, 3)).squeeze(1)
            s_r = self.rv_head(tgt).view(q, self.classes, 3).gather(1, slot[:, None, None].expand(q, 1, 3)).squeeze(1)
        if self.prior is not None:
            fx, fy, cx, cy, W, H, size = self.prior
            z = fx * size / (boxes[:, 2].clamp(min=1e-3) * W)
            tx = (boxes[:, 0] * W - cx) / fx * z
            ty = (boxes[:, 1] * H - cy) / fy * z
            t = torch.stack([tx, ty, z], dim=1) + 0.01 * torch.tanh(t)
            r = r + torch.tensor([1.0, 0.0, 0.0, 0.0, 1.0, 0.0]) * 3.0
            if self.aleatoric:  # plausible scales: sigma about 1 cm and 3 degrees
                s_t = s_t + 2.0 * math.log(0.01)
                s_r = s_r + 2.0 * math.log(0.05)
        if self.aleatoric:
            return t, r, s_t, s_r
        return t, r


# ------------------------------------------------------------------------------------------------
# Darknet files
# ------------------------------------------------------------------------------------------------
class DarknetWriter:
    """Collects [sections] and conv weights in Darknet's order (biases, [bn], weights)."""

    def __init__(self, width, height):
        self.lines = ["[net]", f"width={width}", f"height={height}", "channels=3", "batch=1", ""]
        self.blobs = []
        self.torch_layers = []  # for the reference forward
        self.channels = [3]
        self.nlayers = 0
        # OpenCV's names of each Darknet layer's output (cv::dnn::readNetFromDarknet): a conv with an
        # activation is named after its activation and the *next* index ("logistic_1" for layer 0).
        self.cv_names = []

    def conv(self, filters, size, stride, pad, act, weight=None, bias=None, bn=False, rng=None):
        c_in = self.channels[-1]
        self.lines += ["[convolutional]", f"batch_normalize={1 if bn else 0}", f"filters={filters}", f"size={size}",
                       f"stride={stride}", f"pad={1 if pad else 0}", f"activation={act}", ""]
        if weight is None:
            std = math.sqrt(2.0 / (c_in * size * size))
            weight = (rng.standard_normal((filters, c_in, size, size)) * std).astype(np.float32)
        if bias is None:
            bias = np.zeros(filters, np.float32) if rng is None else (rng.standard_normal(filters) * 0.01).astype(np.float32)
        self.blobs.append(bias.astype(np.float32))
        if bn:  # scales, rolling mean, rolling variance (identity normalisation)
            self.blobs += [np.ones(filters, np.float32), np.zeros(filters, np.float32), np.ones(filters, np.float32)]
        self.blobs.append(weight.astype(np.float32))
        self.torch_layers.append(("conv", weight, bias, stride, size // 2 if pad else 0, act))
        self.cv_names.append(f"conv_{self.nlayers}" if act == "linear" else f"{act}_{self.nlayers + 1}")
        self.channels.append(filters)
        self.nlayers += 1
        return self.nlayers - 1

    def maxpool(self, size, stride):
        self.lines += ["[maxpool]", f"size={size}", f"stride={stride}", ""]
        self.torch_layers.append(("maxpool", size, stride))
        self.cv_names.append(f"pool_{self.nlayers}")
        self.channels.append(self.channels[-1])
        self.nlayers += 1
        return self.nlayers - 1

    def route(self, layers):
        self.lines += ["[route]", "layers=" + ",".join(str(x) for x in layers), ""]
        self.torch_layers.append(("route", layers))
        self.cv_names.append(f"concat_{self.nlayers}" if len(layers) > 1 else f"identity_{self.nlayers}")
        self.channels.append(sum(self.channels[1 + (x if x >= 0 else self.nlayers + x)] for x in layers))
        self.nlayers += 1
        return self.nlayers - 1

    def shortcut(self, frm):
        self.lines += ["[shortcut]", f"from={frm}", "activation=linear", ""]
        self.torch_layers.append(("shortcut", frm))
        self.cv_names.append(f"shortcut_{self.nlayers}")
        self.channels.append(self.channels[-1])
        self.nlayers += 1
        return self.nlayers - 1

    def yolo(self, anchors, classes):
        flat = ",".join(f"{a},{b}" for a, b in anchors)
        self.lines += ["[yolo]", "mask=" + ",".join(str(i) for i in range(len(anchors))), f"anchors={flat}",
                       f"classes={classes}", f"num={len(anchors)}", "jitter=0", "ignore_thresh=.7", "truth_thresh=1",
                       "random=0", ""]
        self.torch_layers.append(("yolo",))
        self.cv_names.append(f"yolo_{self.nlayers}")
        self.channels.append(self.channels[-1])
        self.nlayers += 1
        return self.nlayers - 1

    def write(self, cfg_path, weights_path):
        with open(cfg_path, "w") as f:
            f.write("\n".join(self.lines))
        with open(weights_path, "wb") as f:
            f.write(struct.pack("<iiiq", 0, 2, 0, 0))  # major, minor, revision, images seen (int64 from 0.2)
            for b in self.blobs:
                f.write(np.ascontiguousarray(b, dtype="<f4").tobytes())

    def forward(self, x):
        """Reference forward in PyTorch (float64 for a tight reference); returns every layer output."""
        outs = []
        for spec in self.torch_layers:
            kind = spec[0]
            if kind == "conv":
                _, w, b, stride, pad, act = spec
                y = F.conv2d(x, torch.from_numpy(w).double(), torch.from_numpy(b).double(), stride=stride, padding=pad)
                if act == "logistic":
                    y = torch.sigmoid(y)
                elif act == "leaky":
                    y = F.leaky_relu(y, 0.1)
                elif act == "mish":
                    y = y * torch.tanh(F.softplus(y))
                elif act != "linear":
                    raise ValueError(act)
            elif kind == "maxpool":
                _, size, stride = spec
                # Darknet pads size-1 in total, (size-1)//2 before, with -inf.
                lo = (size - 1) // 2
                hi = size - 1 - lo
                y = F.max_pool2d(F.pad(x, (lo, hi, lo, hi), value=-math.inf), size, stride)
            elif kind == "route":
                y = torch.cat([outs[i if i >= 0 else len(outs) + i] for i in spec[1]], dim=1)
            elif kind == "shortcut":
                y = x + outs[spec[1] if spec[1] >= 0 else len(outs) + spec[1]]
            else:
                y = x
            outs.append(y)
            x = y
        return outs


def tiny_detector(width, height, obj_size, stride):
    d = DarknetWriter(width, height)
    # Layer 0: colour indicators, sigmoid(20 (c_k - others - 0.5)) = 1 on a pure colour, 0 on grey.
    w0 = np.full((3, 3, 1, 1), -20.0, np.float32)
    for k in range(3):
        w0[k, k, 0, 0] = 20.0
    d.conv(3, 1, 1, False, "logistic", w0, np.full(3, -10.0, np.float32))
    # Layer 1: mean of the indicator over an obj_size window centred on the YOLO cell centre
    # (stride*i + stride/2): a (obj_size + 5)-tap kernel padded by half its size, window at its end.
    k = obj_size + 5
    w1 = np.zeros((3, 3, k, k), np.float32)
    start = k // 2 - obj_size // 2 + stride // 2
    for c in range(3):
        w1[c, c, start:start + obj_size, start:start + obj_size] = 1.0 / (obj_size * obj_size)
    d.conv(3, k, stride, True, "linear", w1, np.zeros(3, np.float32))
    d.maxpool(2, 2)  # layer 2: stride-2x feature level
    d.route([1])  # layer 3
    d.maxpool(3, 1)  # layer 4: local max of R
    d.route([1, 4])  # layer 5: [R, maxR]
    w6 = np.zeros((8, 6, 1, 1), np.float32)
    b6 = np.zeros(8, np.float32)
    for c in range(3):  # objectness: 40 Σ(R − maxR) + 10 ΣR − 5
        w6[4, c, 0, 0] = 40.0 + 10.0
        w6[4, 3 + c, 0, 0] = -40.0
        w6[5 + c, c, 0, 0] = 20.0  # class logits 20 R_k − 10
        b6[5 + c] = -10.0
    b6[4] = -5.0
    b6[2] = b6[3] = math.log(math.sqrt(0.5) / (1.0 - math.sqrt(0.5)))  # σ = √½, so (2σ)² = 2
    d.conv(8, 1, 1, False, "linear", w6, b6)
    d.yolo([(obj_size // 2, obj_size // 2)], 3)
    return d


def poet_detections(raw, anchors, stride, conf_thresh, iou_thresh, class_offset=1, agnostic=False, max_det=300):
    """PoET's detections after NMS from the raw output [A*(5+C), ny, nx] of the convolution before a
    [yolo] layer, in float32 as PyTorch computes them: the YOLOLayer of aau-cns/yolov4 (inference)
    and Scaled-YOLOv4's non_max_suppression (multi-label when C > 1, greedy NMS by score with
    class-aware suppression). Rows x1, y1, x2, y2, score, class + class_offset, best first."""
    a_n = len(anchors)
    no = raw.shape[0] // a_n
    ny, nx = raw.shape[1:]
    p = raw.reshape(a_n, no, ny, nx).transpose(0, 2, 3, 1).astype(np.float32)
    io = (1.0 / (1.0 + np.exp(-p))).astype(np.float32)
    gy, gx = np.meshgrid(np.arange(ny, dtype=np.float32), np.arange(nx, dtype=np.float32), indexing="ij")
    anc = np.asarray(anchors, np.float32) / np.float32(stride)
    io[..., 0] = (io[..., 0] * 2 - 0.5 + gx) * stride
    io[..., 1] = (io[..., 1] * 2 - 0.5 + gy) * stride
    io[..., 2] = (io[..., 2] * 2) ** 2 * anc[:, 0, None, None] * stride
    io[..., 3] = (io[..., 3] * 2) ** 2 * anc[:, 1, None, None] * stride
    x = io.reshape(-1, no)
    x = x[x[:, 4] > conf_thresh]
    x[:, 5:] *= x[:, 4:5]
    box = np.stack([x[:, 0] - x[:, 2] / 2, x[:, 1] - x[:, 3] / 2, x[:, 0] + x[:, 2] / 2, x[:, 1] + x[:, 3] / 2], 1)
    if no - 5 > 1:
        i, j = np.nonzero(x[:, 5:] > conf_thresh)
        det = np.concatenate([box[i], x[i, j + 5, None], j[:, None].astype(np.float32)], 1)
    else:
        det = np.concatenate([box, x[:, 5:6], np.zeros((len(x), 1), np.float32)], 1)[x[:, 5] > conf_thresh]
    order = np.argsort(-det[:, 4], kind="stable")
    kept = []
    for k in order:
        b = det[k]
        ok = True
        for m in kept:
            if not agnostic and m[5] != b[5]:
                continue
            iw = min(m[2], b[2]) - max(m[0], b[0])
            ih = min(m[3], b[3]) - max(m[1], b[1])
            inter = max(iw, 0) * max(ih, 0)
            union = (m[2] - m[0]) * (m[3] - m[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
            if inter / union > iou_thresh:
                ok = False
                break
        if ok:
            kept.append(b)
        if len(kept) >= max_det:
            break
    out = np.asarray(kept, np.float32).reshape(-1, 6)
    out[:, 5] += class_offset
    return out


def full_detector(width, height, classes, rng):
    """A Darknet-53-style backbone with three taps (256/512/1024 channels at strides 8/16/32) and a
    YOLO head, about the size of PoET's YOLOv4-CSP (random weights)."""
    d = DarknetWriter(width, height)
    d.conv(32, 3, 1, True, "mish", bn=True, rng=rng)
    taps = []
    for filters, blocks in [(64, 1), (128, 2), (256, 8), (512, 8), (1024, 4)]:
        d.conv(filters, 3, 2, True, "mish", bn=True, rng=rng)
        for _ in range(blocks):
            start = d.nlayers - 1
            d.conv(filters // 2, 1, 1, True, "mish", bn=True, rng=rng)
            d.conv(filters, 3, 1, True, "mish", bn=True, rng=rng)
            d.shortcut(start)
        if filters >= 256:
            taps.append(d.nlayers - 1)
    for _ in range(3):
        d.conv(512, 1, 1, True, "mish", bn=True, rng=rng)
        d.conv(1024, 3, 1, True, "mish", bn=True, rng=rng)
    d.conv(3 * (5 + classes), 1, 1, True, "linear", rng=rng)
    d.yolo([(116, 90), (156, 198), (373, 326)], classes)
    return d, taps


# ------------------------------------------------------------------------------------------------
# Bundle writing
# ------------------------------------------------------------------------------------------------
def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def render_squares(width, height, objects, obj_size):
    """Grey image with filled pure-colour squares: objects = [(class 1..3, cx, cy)] in pixels."""
    img = np.full((height, width, 3), 128, np.uint8)
    for cls, cx, cy in objects:
        x0 = int(round(cx - obj_size / 2))
        y0 = int(round(cy - obj_size / 2))
        col = [0, 0, 0]
        col[cls - 1] = 255
        img[max(0, y0):max(0, y0 + obj_size), max(0, x0):max(0, x0 + obj_size)] = col
    return img


def save_png(path, rgb):
    from PIL import Image
    Image.fromarray(rgb, "RGB").save(path)


def write_expected_detections(path, head, dets, feats, q, width, height):
    """What `roe infer` must write for the detector self-test image (tests/infer/test_aleatoric.cpp):
    PoET's detections after NMS (poet_detections) as the queries, the eager head's pose, and
    sigma = sqrt(exp(s)) per axis from the log-variances, computed here in float64."""
    boxes = torch.full((q, 4), -1.0)
    cls = torch.full((q,), -1, dtype=torch.int64)
    n = min(q, len(dets))
    for r in range(n):
        x1, y1, x2, y2, _, c = (float(v) for v in dets[r])
        boxes[r] = torch.tensor([(x1 + x2) / 2 / width, (y1 + y2) / 2 / height, (x2 - x1) / width, (y2 - y1) / height])
        cls[r] = int(c)
    with torch.no_grad():
        t, r6, s_t, s_r = (o.double() for o in head(boxes, cls, *feats))
    x = F.normalize(r6[:, 0:3], dim=1)  # Gram-Schmidt: R = [x y z]
    z = F.normalize(torch.cross(x, r6[:, 3:6], dim=1), dim=1)
    y = torch.cross(z, x, dim=1)
    R = torch.stack([x, y, z], dim=2)
    sigma = torch.exp(0.5 * torch.cat([s_t, s_r], dim=1))
    cols = ["class", "score", "tx", "ty", "tz"] + [f"r{i}{j}" for i in range(3) for j in range(3)] + \
           ["sigma_tx", "sigma_ty", "sigma_tz", "sigma_rx", "sigma_ry", "sigma_rz"]
    with open(path, "w") as f:
        f.write("# written by tests/models/gen_tiny_poet.py: expected roe infer output on detector_input.png\n")
        f.write(",".join(cols) + "\n")
        for k in range(n):
            vals = [float(dets[k][4])] + t[k].tolist() + R[k].flatten().tolist() + sigma[k].tolist()
            f.write(f"{int(cls[k])}," + ",".join(f"{v:.9g}" for v in vals) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(HERE, "tiny_poet"), help="bundle folder to (re)write")
    ap.add_argument("--full", metavar="OUT_DIR", help="write a PoET-sized bundle with random weights instead")
    args = ap.parse_args()
    torch.manual_seed(7)
    rng = np.random.default_rng(7)
    full = args.full is not None
    out = args.full if full else args.out
    os.makedirs(os.path.join(out, "selftest"), exist_ok=True)

    if full:
        width, height, classes, q = 640, 480, 21, 10
        intr = {"fx": 1066.778, "fy": 1067.487, "cx": 312.9869, "cy": 241.3109}
        det, taps = full_detector(width, height, classes, rng)
        names = [f"{i}" for i in taps]
        head = PoseHead([256, 512, 1024], d=256, heads=16, points=4, enc=5, dec=5, ffn=1024, classes=classes,
                        extra_levels=1, freqs=32)
        class_names = ["002_master_chef_can", "003_cracker_box", "004_sugar_box", "005_tomato_soup_can",
                       "006_mustard_bottle", "007_tuna_fish_can", "008_pudding_box", "009_gelatin_box",
                       "010_potted_meat_can", "011_banana", "019_pitcher_base", "021_bleach_cleanser", "024_bowl",
                       "025_mug", "035_power_drill", "036_wood_block", "037_scissors", "040_large_marker",
                       "051_large_clamp", "052_extra_large_clamp", "061_foam_brick"]
        symmetric = [13, 16, 19, 20, 21]
        model_id = "poet-sized-random"
        obj_size = 24
        test_objects = [(1, 200.0, 150.0), (2, 400.0, 300.0)]
    else:
        width, height, classes, q = 128, 96, 3, 4
        intr = {"fx": 120.0, "fy": 120.0, "cx": 64.0, "cy": 48.0}
        obj_size, stride = 24, 4
        det = tiny_detector(width, height, obj_size, stride)
        taps = [1, 2]
        head = PoseHead([3, 3], d=16, heads=2, points=2, enc=1, dec=1, ffn=32, classes=classes, extra_levels=0,
                        freqs=2, prior=(intr["fx"], intr["fy"], intr["cx"], intr["cy"], width, height, 0.06),
                        aleatoric=True)
        class_names = ["red_square", "green_square", "blue_square"]
        symmetric = [3]
        model_id = "tiny-poet"
        test_objects = [(1, 30.0, 30.0), (2, 90.0, 60.0), (3, 64.0, 70.0)]
    head.eval()

    det.write(os.path.join(out, "detector.cfg"), os.path.join(out, "detector.weights"))

    # Detector self-test: a rendered image and the reference outputs of the tapped layers.
    img = render_squares(width, height, test_objects, obj_size)
    save_png(os.path.join(out, "selftest", "detector_input.png"), img)
    x = torch.from_numpy(img.astype(np.float64) / 255.0).permute(2, 0, 1)[None]
    with torch.no_grad():
        layer_outs = det.forward(x)
    det_refs = {}
    for i in taps:
        fn = f"selftest/detector_layer{i}.npy"
        np.save(os.path.join(out, fn), layer_outs[i].numpy().astype(np.float32))
        det_refs[det.cv_names[i]] = fn
    feats = [layer_outs[i].float() for i in taps]
    if not full:  # PoET's detections on the image (the conv before [yolo] is layer 6, stride 4)
        dets = poet_detections(layer_outs[6][0].numpy().astype(np.float32), [(obj_size // 2, obj_size // 2)], stride,
                               0.4, 0.5)
        if len(dets) != len(test_objects):
            sys.exit(f"the tiny detector finds {len(dets)} squares, not {len(test_objects)}")
        np.save(os.path.join(out, "selftest", "detections.npy"), dets)

    # Pose-head self-test on the reference features and hand-made boxes (one placeholder row).
    boxes = torch.full((q, 4), -1.0)
    cls = torch.full((q,), -1, dtype=torch.int64)
    for r, (c, cx, cy) in enumerate(test_objects[: q - 1]):
        boxes[r] = torch.tensor([cx / width, cy / height, obj_size / width, obj_size / height])
        cls[r] = c
    with torch.no_grad():
        eager = head(boxes, cls, *feats)
        traced = torch.jit.trace(head, (boxes, cls, *feats), check_trace=False)
        # The trace must not have baked in the number of valid boxes: check with another count.
        boxes2, cls2 = boxes.clone(), cls.clone()
        boxes2[1:] = -1.0
        cls2[1:] = -1
        for b, c in [(boxes, cls), (boxes2, cls2)]:
            err = max((e - t).abs().max().item() for e, t in zip(head(b, c, *feats), traced(b, c, *feats)))
            if err > 1e-5:
                sys.exit(f"traced and eager pose heads differ by {err}")
    traced.save(os.path.join(out, "pose_head.ts"))
    st_inputs = ["selftest/boxes.npy", "selftest/classes.npy"]
    np.save(os.path.join(out, st_inputs[0]), boxes.numpy().astype(np.float32))
    np.save(os.path.join(out, st_inputs[1]), cls.numpy().astype(np.int64))
    for i, f in enumerate(feats):
        fn = f"selftest/feature{i}.npy"
        np.save(os.path.join(out, fn), f.numpy().astype(np.float32))
        st_inputs.append(fn)
    st_outputs = ["selftest/t.npy", "selftest/rot.npy", "selftest/logvar_t.npy", "selftest/logvar_r.npy"][: len(eager)]
    for fn, o in zip(st_outputs, eager):
        np.save(os.path.join(out, fn), o.numpy().astype(np.float32))
    if not full:
        write_expected_detections(os.path.join(out, "selftest", "expected_detections.csv"), head, dets, feats, q,
                                  width, height)

    bundle = {
        "schema": "roe-poet-bundle/1",
        "model_id": model_id,
        "image": {"width": width, "height": height, "color": "RGB", "scale": 1.0 / 255.0, "mean": [0.0, 0.0, 0.0],
                  "std": [1.0, 1.0, 1.0]},
        "train_intrinsics": intr,
        "num_queries": q,
        "classes": [{"id": i + 1, "name": n} for i, n in enumerate(class_names)],
        "symmetric": symmetric,
        "rotation": "6d",
        "translation_unit": "m",
        "detector": {
            "kind": "darknet",
            "cfg": "detector.cfg",
            "weights": "detector.weights",
            "conf_thresh": 0.4,
            "iou_thresh": 0.5,
            "max_detections": 300,
            "multi_label": True,
            "class_offset": 1,
            "feature_layers": [det.cv_names[i] for i in taps],
            "selftest": {"image": "selftest/detector_input.png", "outputs": det_refs, "atol": 1e-4,
                         **({} if full else {"detections": "selftest/detections.npy"})},
        },
        "pose": {"file": "pose_head.ts", "torch_version": torch.__version__.split("a")[0].split("+")[0],
                 "inputs": "features", "aleatoric": head.aleatoric},
        "provenance": {
            "generator": "tests/models/gen_tiny_poet.py" + (" --full" if full else ""),
            "weights": "random (pose head), hand-set (detector)" if not full else "random",
            "torch_version": torch.__version__,
            "pose_head_sha256": sha256(os.path.join(out, "pose_head.ts")),
        },
        "selftest": {"inputs": st_inputs, "outputs": st_outputs, "atol": 1e-5},
    }
    with open(os.path.join(out, "poet_bundle.json"), "w") as f:
        json.dump(bundle, f, indent=2)
        f.write("\n")
    print(f"wrote {out} (model {model_id})")


if __name__ == "__main__":
    main()
