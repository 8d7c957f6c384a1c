#!/usr/bin/python3
"""PyTorch reference for the decoder MLP as the model runs it (src/nn/nerf.c,
src/model/decoder.c; docs/engine.md §9), at the shipped models' sizes.

Rows of R points in S slots: pe [R, 33] (the positional encoding of the
object-local point), slot[r] in 0..S-1, z [S, 8] (z^what of each slot).
Weights [in x out] row-major (the checkpoint layout), Y = X W + b:
  a1 = relu(pe W1x + b1 + z[slot] W1z)            (the slot bias)
  a2 = relu(a1 W2 + b2), a3 = relu(a2 W3 + b3)
  sig = sigmoid(a3 Wd + bd)                        (density head)
  ac = relu(a3 Wc1 + bc1), col = sigmoid(ac Wc2 + bc2)   (colour head)
  loss = sum(sig * t_sig) + sum(col * t_col)
Writes every input, weight, output and gradient (float32) as text lines
"name count v0 v1 ..." (%.9g) for tests/nn/test_nn_nerf_ref.c.

usage: nerf_ref.py OUT.txt
"""
import sys

import torch

torch.manual_seed(2121)
torch.set_num_threads(1)
R, S, DIN, DZ, H, HC = 40, 3, 33, 8, 64, 32


def u(*shape, s=0.3):
    return ((torch.rand(*shape) * 2 - 1) * s).requires_grad_()


w = {"W1x": u(DIN, H, s=0.25), "W1z": u(DZ, H), "b1": u(H, s=0.1),
     "W2": u(H, H, s=0.2), "b2": u(H, s=0.1), "W3": u(H, H, s=0.2), "b3": u(H, s=0.1),
     "Wd": u(H, 1, s=0.3), "bd": u(1, s=0.1), "Wc1": u(H, HC, s=0.2), "bc1": u(HC, s=0.1),
     "Wc2": u(HC, 3, s=0.3), "bc2": u(3, s=0.1)}
pe = u(R, DIN, s=1.0)
z = torch.randn(S, DZ).requires_grad_()
slot = torch.arange(R) % S
t_sig = torch.rand(R, 1) * 2 - 1
t_col = torch.rand(R, 3) * 2 - 1

a1 = torch.relu(pe @ w["W1x"] + w["b1"] + (z @ w["W1z"])[slot])
a2 = torch.relu(a1 @ w["W2"] + w["b2"])
a3 = torch.relu(a2 @ w["W3"] + w["b3"])
sig = torch.sigmoid(a3 @ w["Wd"] + w["bd"])
ac = torch.relu(a3 @ w["Wc1"] + w["bc1"])
col = torch.sigmoid(ac @ w["Wc2"] + w["bc2"])
loss = (sig * t_sig).sum() + (col * t_col).sum()
loss.backward()

rec = [("dims", torch.tensor([R, S, DIN, DZ, H, HC], dtype=torch.float32))]
rec += [("in." + k, v) for k, v in w.items()]
rec += [("in.pe", pe), ("in.z", z), ("in.slot", slot.float()), ("in.t_sig", t_sig), ("in.t_col", t_col)]
rec += [("out.loss", loss.reshape(1)), ("out.a3", a3), ("out.sig", sig), ("out.col", col)]
rec += [("grad." + k, v.grad) for k, v in w.items()]
rec += [("grad.pe", pe.grad), ("grad.z", z.grad)]
with open(sys.argv[1], "w") as f:
    for name, t in rec:
        v = t.detach().float().reshape(-1).tolist()
        f.write("%s %d %s\n" % (name, len(v), " ".join("%.9g" % x for x in v)))
print("nerf_ref.py: wrote %d records, loss %.6f" % (len(rec), loss.item()))
