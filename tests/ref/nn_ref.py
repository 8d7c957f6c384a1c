#!/usr/bin/python3
"""PyTorch reference for the sooc3d nn engine (llm.c style).

Builds a small composite network with the same structure as the model's:
  * a per-slot-conditioned NeRF MLP: posenc(pts) -> Linear + per-slot bias
    (z Wz^T) -> ReLU -> Linear ReLU -> density head (sigmoid) and colour head
    (sigmoid);
  * an encoder: MulMON LN over (C,H,W) -> flatten -> FC ELU -> learnable
    layer norm; a linear head on concat(encoder, z).
(The refinement network's conv and LSTM in the model's layouts: refine_ref.py.)
Writes parameters, inputs, outputs, all gradients (parameters and inputs),
the losses of 5 Adam steps and the final parameters to a versioned binary
file that tests/nn/test_nn_ref.c compares against.

File: magic b"SOOCNNRF", u32 version, u32 n_records, then records
  u32 name_len, name, u32 ndim, i64 shape[ndim], f32 data[prod(shape)].

usage: nn_ref.py OUT.bin
"""
import struct
import sys

import torch
import torch.nn.functional as F

VERSION = 1
torch.manual_seed(1234)
torch.set_num_threads(1)

K, NPTS, FREQ = 2, 16, 5
D_Z, W_MLP = 8, 16
C_IN, IMG = 5, 8


def posenc(x):
    out = [x]
    for f in range(FREQ):
        out += [torch.sin(x * 2.0 ** f), torch.cos(x * 2.0 ** f)]
    return torch.cat(out, dim=-1)


def u(*shape, s=0.5):
    return ((torch.rand(*shape) * 2 - 1) * s).requires_grad_()


params = {
    "mlp.wz": u(W_MLP, D_Z), "mlp.w0": u(W_MLP, 33), "mlp.b0": u(W_MLP),
    "mlp.w1": u(W_MLP, W_MLP), "mlp.b1": u(W_MLP),
    "mlp.wd": u(1, W_MLP), "mlp.bd": u(1), "mlp.wc": u(3, W_MLP), "mlp.bc": u(3),
    "enc.fc.w": u(16, C_IN * IMG * IMG, s=0.1), "enc.fc.b": u(16, s=0.1),
    "enc.ln.g": (1 + u(16, s=0.2)).detach().requires_grad_(), "enc.ln.b": u(16, s=0.1),
    "head.w": u(D_Z, 16 + D_Z, s=0.3), "head.b": u(D_Z, s=0.1),
}
inputs = {
    "in.pts": (torch.rand(K * NPTS, 3) * 2 - 1).requires_grad_(),
    "in.z": torch.randn(K, D_Z).requires_grad_(),
    "in.img": torch.randn(K, C_IN, IMG, IMG),
    "in.t_dens": torch.rand(K * NPTS, 1),
    "in.t_col": torch.rand(K * NPTS, 3),
    "in.t_dz": torch.randn(K, D_Z),
}


def forward(p, x):
    pe = posenc(x["in.pts"])                                     # [K*N, 33]
    sb = x["in.z"] @ p["mlp.wz"].t()                             # [K, W]
    h = (pe @ p["mlp.w0"].t() + p["mlp.b0"]).view(K, NPTS, W_MLP) + sb[:, None, :]
    h = F.relu(h).reshape(K * NPTS, W_MLP)
    h = F.relu(h @ p["mlp.w1"].t() + p["mlp.b1"])
    dens = torch.sigmoid(h @ p["mlp.wd"].t() + p["mlp.bd"])     # [K*N, 1]
    col = torch.sigmoid(h @ p["mlp.wc"].t() + p["mlp.bc"])      # [K*N, 3]
    img = F.layer_norm(x["in.img"], x["in.img"].shape[1:], eps=1e-5)
    e = F.elu(img.reshape(K, -1) @ p["enc.fc.w"].t() + p["enc.fc.b"])
    e = F.layer_norm(e, (16,), p["enc.ln.g"], p["enc.ln.b"], eps=1e-5)
    dz = torch.cat([e, x["in.z"]], dim=1) @ p["head.w"].t() + p["head.b"]
    loss = (((dens - x["in.t_dens"]) ** 2).mean() + ((col - x["in.t_col"]) ** 2).mean()
            + ((dz - x["in.t_dz"]) ** 2).mean())
    return loss, {"out.dens": dens, "out.col": col, "out.enc": e, "out.dz": dz}


records = []


def add(name, t):
    records.append((name, t.detach().float().clone().contiguous()))  # snapshot (params change later)


for n, t in params.items():
    add(n, t)
for n, t in inputs.items():
    add(n, t)
loss, outs = forward(params, inputs)
for o in outs.values():
    o.retain_grad()
loss.backward()
add("out.loss", loss.reshape(1))
for n, t in outs.items():
    add(n, t)
    add("grad." + n, t.grad)
for n, t in params.items():
    add("grad." + n, t.grad)
add("grad.in.pts", inputs["in.pts"].grad)
add("grad.in.z", inputs["in.z"].grad)

opt = torch.optim.Adam(list(params.values()), lr=1e-2)
losses = []
for step in range(5):
    opt.zero_grad()
    loss, _ = forward(params, inputs)
    loss.backward()
    losses.append(loss.item())
    opt.step()
add("adam.losses", torch.tensor(losses))
for n, t in params.items():
    add("final." + n, t)

with open(sys.argv[1], "wb") as f:
    f.write(b"SOOCNNRF")
    f.write(struct.pack("<II", VERSION, len(records)))
    for name, t in records:
        nb = name.encode()
        f.write(struct.pack("<I", len(nb)))
        f.write(nb)
        f.write(struct.pack("<I", t.dim()))
        f.write(struct.pack("<%dq" % t.dim(), *t.shape))
        f.write(t.numpy().astype("<f4").tobytes())
print("nn_ref.py: wrote %d records, loss %.6f, adam losses %s" % (len(records), losses[0],
      " ".join("%.6f" % v for v in losses)))
