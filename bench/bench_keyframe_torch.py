#!/usr/bin/python3
"""PyTorch reference of one sooc3d keyframe update (the same work as
bench_keyframe.c): 64x64 frame, 32x32 rays (--rays G: G x G; surface + air sample each), K = 7
(--K) slots + layout, d = 32, L = 3 refinement iterations. Each iteration: sample,
decode (object rows gathered inside their locality boxes, layout on all
points), compose, likelihood + KL, one backward for the auxiliary gradients,
the 26 auxiliary channels, the refinement nets (conv 26->32->32->64->64 stride
2 SAME + ELU, FC 128, LSTMCell 128, linear head) for all K slots and the
layout (above 32x32 rays the last conv map is average-pooled to 2x2, as in C). Prints a JSON object with median_ms last (the faster of --threads
and 1 thread: see the comment at the end).
usage: bench_keyframe_torch.py [--threads T] [--n N] [--K K] [--rays G] [--serve]
--serve: stay up and run one batch of updates per line read on stdin (the
interleaved rounds of bench_keyframe.c).
"""
import json
import math
import sys
import time

import torch
import torch.nn.functional as F

args = sys.argv
threads = int(args[args.index("--threads") + 1]) if "--threads" in args else 2
n_iter = int(args[args.index("--n") + 1]) if "--n" in args else 30
serve = "--serve" in args
torch.set_num_threads(threads)
torch.manual_seed(0)
K = int(args[args.index("--K") + 1]) if "--K" in args else 7
G = int(args[args.index("--rays") + 1]) if "--rays" in args else 32
d, dl, L, H, Hc, N = 32, 16, 3, 64, 32, G * G
NL = 6 + 2 * d
Rh, Hb, s_g, smax, sigc, Bs, h = 0.6, 1.2, 0.3, 30.0, 0.2, 4.0, 1.5


def dec_params(din, dz):
    lin = lambda i, o: (torch.randn(i, o) * math.sqrt(2.0 / i), torch.zeros(o))
    return [lin(din, H), (torch.randn(dz, H) * 0.1,), lin(H, H), lin(H, H), lin(H, 1), lin(H, Hc), lin(Hc, 3)]


obj, lay = dec_params(33, d), dec_params(39, dl)


class Refine(torch.nn.Module):
    def __init__(self, cin, nvec, nout):
        super().__init__()
        self.convs = torch.nn.ModuleList([torch.nn.Conv2d(a, b, 3, 2) for a, b in
                                          zip([cin, 32, 32, 64], [32, 32, 64, 64])])
        self.fc = torch.nn.Linear(256, 128)
        self.lstm = torch.nn.LSTMCell(128 + nvec, 128)
        self.head = torch.nn.Linear(128, nout)

    def forward(self, img, vec, hc):
        x = img
        for c in self.convs:
            x = F.elu(c(F.pad(x, (0, 1, 0, 1))))
        if x.shape[-1] > 2:
            x = F.avg_pool2d(x, x.shape[-1] // 2)
        f = F.elu(self.fc(x.flatten(1)))
        h_, c_ = self.lstm(torch.cat([f, vec], 1), hc)
        return self.head(h_), (h_, c_)


ref_o, ref_l = Refine(26, 2 * NL + 6, NL), Refine(25, 4 * dl + 2, 2 * dl)


def pe(x, n):
    out = [x]
    for f in range(n):
        out += [torch.sin((2 ** f) * x), torch.cos((2 ** f) * x)]
    return torch.cat(out, -1)


def mlp(p, pe_in, bias):
    a = torch.relu(pe_in @ p[0][0] + bias)
    a = torch.relu(a @ p[2][0] + p[2][1])
    a = torch.relu(a @ p[3][0] + p[3][1])
    sig = torch.sigmoid(a @ p[4][0] + p[4][1])[:, 0]
    col = torch.sigmoid(torch.relu(a @ p[5][0] + p[5][1]) @ p[6][0] + p[6][1])
    return sig, col


# one synthetic view in G, like bench_keyframe.c's frames: 64x64 pinhole camera with a 60 degree
# field of view, pitched down 0.45 rad, 1.5 m above the floor (y = -h), rays on the 32x32 stratified
# grid; the slots sit where that bench's spheres are (so a similar number of object rows is decoded).
fx = 0.5 * 64 / math.tan(math.radians(30.0))
jj, ii = torch.meshgrid(torch.arange(G), torch.arange(G), indexing="xy")
xc = (((jj.flatten() + 0.5) * (64 / G)).float() - 32.0) / fx
yc = (((ii.flatten() + 0.5) * (64 / G)).float() - 32.0) / fx
p_ = -0.45
dirs = torch.stack([xc, -yc * math.cos(p_) + math.sin(p_), yc * math.sin(p_) + math.cos(p_)], 1)
dirs = dirs / dirs.norm(dim=1, keepdim=True)
depth = torch.where(dirs[:, 1] < -0.05, -h / dirs[:, 1].clamp(max=-0.05), torch.full((N,), 100.0))
# the six spheres of bench_keyframe.c (centre x, height, z relative to the camera; radius)
for cx, cy, cz, rad in [(0.3, 0.4, 3.5, 0.4), (-0.8, 0.3, 2.7, 0.3), (1.2, 0.35, 5.0, 0.35),
                        (-1.5, 0.5, 5.5, 0.5), (0.0, 0.25, 2.3, 0.25), (2.0, 0.4, 3.7, 0.4)]:
    cvec = torch.tensor([cx, cy - h, cz])
    bq = dirs @ cvec
    disc = bq * bq - (cvec @ cvec - rad * rad)
    tq = bq - disc.clamp(min=0).sqrt()
    depth = torch.where((disc > 0) & (tq > 0) & (tq < depth), tq, depth)
surf = depth <= 8.0
depth = torch.where(surf, depth, torch.zeros(N))
rgb = torch.rand(N, 3)
ta = torch.where(surf, depth * torch.rand(N), 8.0 * torch.rand(N))
W = torch.where(surf, 2 * 0.98 * depth, torch.full((N,), 8.0))
pts = torch.cat([(depth + 0.03 * torch.rand(N))[:, None] * dirs, ta[:, None] * dirs], 0)   # 2N x 3
blk = torch.tensor([0.5, -h, 4.0])
used = torch.cat([surf, torch.ones(N, dtype=torch.bool)])   # points the C decoder evaluates
ui = used.nonzero()[:, 0]
zero_i = torch.zeros_like(ui)
rows_seen = []
lam0 = torch.zeros(K, NL)
x7, z7 = [0.3, -0.8, 1.2, -1.5, 0.0, 2.0, 0.0], [3.5, 2.7, 5.0, 5.5, 2.3, 3.7, 1.3]
lam0[:, 0] = torch.tensor([x7[k % 7] * (-1) ** (k // 7) for k in range(K)])   # slots past 7: mirrored
lam0[:, 1] = torch.tensor([z7[k % 7] for k in range(K)])
lam0[:, 3] = math.log(0.25)
lay0 = torch.zeros(2 * dl)


def update():
    lam, layv = lam0.clone(), lay0.clone()
    hco, hcl = None, None
    for it in range(L):
        lam_ = lam.clone().requires_grad_(True)
        lay_ = layv.clone().requires_grad_(True)
        st = torch.exp(0.5 * lam_[:, 3])
        px = lam_[:, 0] + st * torch.randn(K)
        pz = lam_[:, 1] + st * torch.randn(K)
        th = lam_[:, 2] + torch.exp(0.5 * lam_[:, 4]) * torch.randn(K)
        zw = lam_[:, 5:5 + d] + torch.exp(0.5 * lam_[:, 5 + d:5 + 2 * d]) * torch.randn(K, d)
        zp = torch.sigmoid((lam_[:, -1] + torch.logit(torch.rand(K).clamp(1e-6, 1 - 1e-6))) / 0.7)
        zl = lay_[:dl] + torch.exp(0.5 * lay_[dl:]) * torch.randn(dl)
        c, s = torch.cos(th), torch.sin(th)
        vx = pts[:, None, 0] - px[None]
        vz = pts[:, None, 2] - pz[None]
        xk = torch.stack([c * vx - s * vz, (pts[:, 1] + h)[:, None].expand(-1, K), s * vx + c * vz], 2)  # P x K x 3
        inside = ((xk[..., 0].abs() <= Rh) & (xk[..., 2].abs() <= Rh) & (xk[..., 1] >= 0) & (xk[..., 1] <= Hb)
                  & used[:, None])
        pi, ki = inside.nonzero(as_tuple=True)
        rows_seen.append((int(pi.numel()), int(ui.numel())))
        rows = xk[pi, ki]
        sig, col = mlp(obj, pe(rows / Rh, 5), (zw @ obj[1][0] + obj[0][1])[ki])
        wg = torch.exp(-(rows[:, 0] ** 2 + rows[:, 2] ** 2) / (2 * s_g ** 2))
        sh_o = sig * zp[ki] * wg / wg.detach()
        # layout rows: used points only (surface samples of rays with a surface, every air sample), as in C
        sl, cl = mlp(lay, pe((pts[ui] - blk) / Bs, 6), zl @ lay[1][0] + lay[0][1])
        SH = torch.zeros(2 * N, K + 1).index_put((pi, ki + 1), sh_o).index_put((ui, zero_i), sl)
        CT = torch.zeros(2 * N, K + 1, 3).index_put((pi, ki + 1), col).index_put((ui, zero_i), cl)
        SH.retain_grad()
        CT.retain_grad()
        S = SH.sum(1) + 1e-8
        Sb = (SH ** 2).sum(1) / S
        colc = (SH[..., None] * CT).sum(1) / S[:, None]
        ll = torch.where(surf, torch.log(smax * Sb[:N] + 3e-3) - ((rgb - colc[:N]) ** 2).sum(1) / (2 * sigc ** 2),
                         torch.zeros(N)) - W * smax * Sb[N:]
        kl = 0.5 * (torch.exp(lam_[:, 3:]) - lam_[:, 3:] - 1).sum() + 0.5 * ((lam_ - lam0) ** 2).sum()
        loss = -(4096.0 / N) * ll.sum() + kl
        loss.backward()
        with torch.no_grad():
            gl = (lam_.grad - lam_.grad.mean(1, keepdim=True)) / (lam_.grad.std(1, keepdim=True) + 1e-5)
            ln = lambda t: (t - t.mean()) / (t.std() + 1e-5)
            img = torch.cat([
                rgb.T[None].expand(K, -1, -1), depth[None, None].expand(K, 1, -1), surf.float()[None, None].expand(K, 1, -1),
                dirs.T[None].expand(K, -1, -1), (xk[:N].permute(1, 2, 0) / Rh).clamp(-3, 3),
                torch.exp(-(xk[:N, :, 0] ** 2 + xk[:N, :, 2] ** 2) / (2 * s_g ** 2)).T[:, None],
                SH[:N, 1:].T[:, None], (SH[:N, 1:] / S[:N, None]).T[:, None], CT[:N, 1:].permute(1, 2, 0),
                (SH[N:, 1:] ** 2 / S[N:, None]).T[:, None], torch.softmax(SH[:N, 1:], 1).T[:, None],
                ln(ll)[None, None].expand(K, 1, -1), ln(ll)[None, None].expand(K, 1, -1),
                ln(SH.grad[:N, 1:]).T[:, None], ln(SH.grad[N:, 1:]).T[:, None], ln(CT.grad[:N, 1:]).permute(1, 2, 0)],
                1).reshape(K, 26, G, G)
            vec = torch.cat([lam, gl, torch.stack([px, pz, th, zp], 1), torch.full((K, 2), 1.0)], 1)
            dlam, hco = ref_o(img, vec, hco)
            imgl = img[:1, :25]
            gll = lay_.grad
            vecl = torch.cat([layv, (gll - gll.mean()) / (gll.std() + 1e-5), torch.ones(2)])[None]
            dlay, hcl = ref_l(imgl, vecl, hcl)
            lam = lam + dlam
            layv = layv + dlay[0]
    return lam


def measure(nt, n):
    torch.set_num_threads(nt)
    ts = []
    for _ in range(n):
        t0 = time.perf_counter()
        update()
        ts.append(1e3 * (time.perf_counter() - t0))
    return ts


def med(ts):
    ts = sorted(ts)
    return ts[len(ts) // 2]


# On a busy 2-core machine PyTorch's intra-op threads can be much slower than
# one thread; both settings are measured and the faster counts, so that the
# C/PyTorch ratio is conservative.
settings = sorted({threads, 1}, reverse=True)
for nt in settings:
    measure(nt, 3)   # warm-up
if serve:
    # bench_keyframe.c: one batch of n updates per setting for each line "n" on stdin;
    # answers "times <threads> <n> t_1 .. t_n [<threads> <n> ...]" (ms per update).
    print("ready: torch %s, threads %s" % (torch.__version__, settings), flush=True)
    for line in sys.stdin:
        n = int(line)
        out = ["times"]
        for nt in settings:
            ts = measure(nt, n)
            out += [str(nt), str(n)] + ["%.4f" % t for t in ts]
        print(" ".join(out), flush=True)
    sys.exit(0)
res = {}
for nt in settings:
    ts = sorted(measure(nt, n_iter))
    res[nt] = (ts[len(ts) // 2], ts[int(0.99 * (len(ts) - 1))])
    print("torch keyframe update, %d thread(s): median %.2f ms, p99 %.2f ms (torch %s)" %
          (nt, res[nt][0], res[nt][1], torch.__version__))
best = min(res, key=lambda k: res[k][0])
nro = sum(r[0] for r in rows_seen) / max(len(rows_seen), 1)
nrl = sum(r[1] for r in rows_seen) / max(len(rows_seen), 1)
print("torch decode rows per iteration: objects %.0f, layout %.0f (C bench: ~430-630 / ~1770-1800)" % (nro, nrl))
print(json.dumps({"bench": "keyframe_torch", "threads_asked": threads, "threads_best": best, "n": n_iter,
                  "median_ms_by_threads": {str(k): round(v[0], 3) for k, v in res.items()},
                  "obj_rows": round(nro), "layout_rows": round(nrl),
                  "median_ms": round(res[best][0], 3)}))
