#!/usr/bin/python3
"""PyTorch reference (float64) for the refinement-network kernel pairs of
src/nn/nn_refine.h, in the model's layouts.

A small refinement net as src/model/refine.c wires it:
  * MulMON layer norm (x - mean) / (std + 1e-5) of image channels 1..2 of
    each item (one group per item) and of the first 5 vector entries;
  * conv 3x3 stride 2, TF SAME (pad bottom/right) + ELU, twice
    (4 -> 5 -> 6 channels, 16x16 -> 8x8 -> 4x4);
  * average pool 4x4 -> 2x2 and flatten per item (channel-major);
  * FC (w[I][O]) + ELU; LSTM cell on [fc, vector] with wx[I][4G], wh[G][4G],
    one bias, gates i, f, g, o; linear head.
Loss = sum(out r_out) + sum(h1 r_h) + sum(c1 r_c). Writes inputs, weights,
outputs and every gradient (weights, image, vector, h0, c0) in the SOOCNNRF
format of nn_ref.py (version 1): magic b"SOOCNNRF", u32 version, u32
n_records, records u32 name_len, name, u32 ndim, i64 shape[ndim], f32 data.
Images are stored in the model's [C][B][H][W] layout.

usage: refine_ref.py OUT.bin
"""
import struct
import sys

import torch
import torch.nn.functional as F

VERSION = 1
torch.manual_seed(2021)
torch.set_num_threads(1)
D = torch.float64

B, CIN, HW = 3, 4, 16
C1, C2 = 5, 6
FC, NVEC, G, NOUT = 10, 7, 8, 7
NFLAT = C2 * 4


def u(*shape, s=0.5):
    return ((torch.rand(*shape, dtype=D) * 2 - 1) * s).float().double().requires_grad_()


P = {
    "c1.w": u(C1, CIN * 9, s=0.4), "c1.b": u(C1, s=0.1),
    "c2.w": u(C2, C1 * 9, s=0.3), "c2.b": u(C2, s=0.1),
    "fc.w": u(NFLAT, FC, s=0.3), "fc.b": u(FC, s=0.1),
    "lstm.wx": u(FC + NVEC, 4 * G, s=0.3), "lstm.wh": u(G, 4 * G, s=0.3), "lstm.b": u(4 * G, s=0.2),
    "head.w": u(G, NOUT, s=0.4), "head.b": u(NOUT, s=0.1),
}
X = {
    "in.img": u(CIN, B, HW, HW, s=1.5),     # [C][B][H][W]
    "in.vec": u(B, NVEC, s=1.0),
    "in.h0": u(B, G, s=0.6),
    "in.c0": u(B, G, s=0.6),
    "in.r_out": u(B, NOUT, s=1.0),
    "in.r_h": u(B, G, s=1.0),
    "in.r_c": u(B, G, s=1.0),
}


def mln(x):
    m = x.mean()
    return (x - m) / ((x - m).pow(2).mean().sqrt() + 1e-5)


def conv(x_nchw, w, b, co):
    return F.elu(F.conv2d(F.pad(x_nchw, (0, 1, 0, 1)), w.view(co, -1, 3, 3), b, stride=2))


def forward():
    img = X["in.img"]
    items = []
    for bb in range(B):
        ch = img[:, bb]                                   # [C][H][W]
        ln = mln(ch[1:3])
        items.append(torch.cat([ch[0:1], ln, ch[3:]], 0))
    x = torch.stack(items, 0)                             # NCHW
    y1 = conv(x, P["c1.w"], P["c1.b"], C1)
    y2 = conv(y1, P["c2.w"], P["c2.b"], C2)
    flat = F.avg_pool2d(y2, 2).reshape(B, NFLAT)          # channel-major per item
    f = F.elu(flat @ P["fc.w"] + P["fc.b"])
    vec = torch.stack([torch.cat([mln(X["in.vec"][bb, :5]), X["in.vec"][bb, 5:]]) for bb in range(B)])
    xin = torch.cat([f, vec], 1)
    h1, c1 = torch.lstm_cell(xin, (X["in.h0"], X["in.c0"]), P["lstm.wx"].t(), P["lstm.wh"].t(), P["lstm.b"],
                             torch.zeros(4 * G, dtype=D))
    out = h1 @ P["head.w"] + P["head.b"]
    loss = (out * X["in.r_out"]).sum() + (h1 * X["in.r_h"]).sum() + (c1 * X["in.r_c"]).sum()
    return loss, {"out.y1": y1.permute(1, 0, 2, 3), "out.y2": y2.permute(1, 0, 2, 3), "out.f": f, "out.h1": h1,
                  "out.c1": c1, "out.out": out}


records = []


def add(name, t):
    records.append((name, t.detach().float().contiguous()))


for n, t in P.items():
    add(n, t)
for n, t in X.items():
    add(n, t)
loss, outs = forward()
loss.backward()
add("out.loss", loss.reshape(1))
for n, t in outs.items():
    add(n, t)
for n, t in P.items():
    add("grad." + n, t.grad)
for n in ("in.img", "in.vec", "in.h0", "in.c0"):
    add("grad." + n, X[n].grad)

with open(sys.argv[1], "wb") as fh:
    fh.write(b"SOOCNNRF")
    fh.write(struct.pack("<II", VERSION, len(records)))
    for name, t in records:
        nb = name.encode()
        fh.write(struct.pack("<I", len(nb)))
        fh.write(nb)
        fh.write(struct.pack("<I", t.dim()))
        fh.write(struct.pack("<%dq" % t.dim(), *t.shape))
        fh.write(t.numpy().astype("<f4").tobytes())
print("refine_ref.py: wrote %d records, loss %.9f" % (len(records), loss.item()))
