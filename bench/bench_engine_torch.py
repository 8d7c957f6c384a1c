#!/usr/bin/python3
"""PyTorch twin of bench/bench_engine.c (same shapes, 2 threads).

Prints one JSON line: {"mlp_ms": median fwd+bwd of the decoder MLP,
"conv_ms": median fwd+bwd of the conv encoder, "torch": version}.
"""
import json
import sys
import time

import torch
import torch.nn.functional as F

torch.set_num_threads(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
torch.manual_seed(0)
REPS = 7


def median_ms(fn):
    fn()  # warm-up
    ts = []
    for _ in range(REPS):
        t0 = time.perf_counter()
        fn()
        ts.append((time.perf_counter() - t0) * 1e3)
    ts.sort()
    return ts[len(ts) // 2]


# ---- decoder MLP as the model runs it (bench_engine_mlp.c): K=8 slots x 8192 points,
# posenc 33 -> 64 (+ per-slot bias) -> 64 -> 64 (ReLU), density 64->1 sigmoid, colour
# 64->32 ReLU ->3 sigmoid; gradients of every weight, the slot bias and the input
# (the model needs d/d(posenc) for the object poses).
K, NK, CIN, W = 8, 8192, 33, 64
x = torch.randn(K, NK, CIN).requires_grad_()
sb = (0.1 * torch.randn(K, 1, W)).requires_grad_()
lin = [torch.nn.Linear(CIN, W), torch.nn.Linear(W, W), torch.nn.Linear(W, W),
       torch.nn.Linear(W, 1), torch.nn.Linear(W, 32), torch.nn.Linear(32, 3)]
dd = torch.randn(K, NK, 1)
dc = torch.randn(K, NK, 3)


def mlp_step():
    for m in lin:
        for p in m.parameters():
            p.grad = None
    sb.grad = None
    x.grad = None
    h = F.relu(lin[0](x) + sb)
    h = F.relu(lin[1](h))
    h = F.relu(lin[2](h))
    dens = torch.sigmoid(lin[3](h))
    col = torch.sigmoid(lin[5](F.relu(lin[4](h))))
    loss = (dens * dd).sum() + (col * dc).sum()
    loss.backward()


# ---- conv encoder as the model runs it (bench_engine_conv.c): object net on K=7 items x 26
# channels and layout net on 1 item x 25 channels, 32x32, 26/25->32->32->64->64, 3x3 stride 2
# TF-SAME (pad bottom/right), ELU; weight gradients, no input gradient (stop-gradient inputs).
CONV_NETS = []
for nb, cin in ((7, 26), (1, 25)):
    convs = [torch.nn.Conv2d(ci, co, 3, stride=2) for ci, co in [(cin, 32), (32, 32), (32, 64), (64, 64)]]
    CONV_NETS.append((torch.randn(nb, cin, 32, 32), convs, torch.randn(nb, 64, 2, 2)))


def conv_step():
    loss = 0
    for xc, convs, rc in CONV_NETS:
        for m in convs:
            for p in m.parameters():
                p.grad = None
        h = xc
        for m in convs:
            h = F.elu(m(F.pad(h, (0, 1, 0, 1))))
        loss = loss + (h * rc).sum()
    loss.backward()


# the conv encoder at 2 threads and at 1 thread: the faster median counts (on a loaded
# 2-core machine PyTorch's second thread can cost more than it brings)
conv_ms_2 = median_ms(conv_step)
torch.set_num_threads(1)
conv_ms_1 = median_ms(conv_step)
torch.set_num_threads(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
print(json.dumps({"mlp_ms": median_ms(mlp_step), "conv_ms": min(conv_ms_2, conv_ms_1),
                  "conv_ms_2threads": conv_ms_2, "conv_ms_1thread": conv_ms_1,
                  "threads": torch.get_num_threads(), "torch": torch.__version__}))
