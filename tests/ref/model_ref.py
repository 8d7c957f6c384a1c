#!/usr/bin/python3
"""PyTorch reference of one sooc3d decode (docs/model.md; the SOOC3D paper):
posterior sampling with given noise, object-local transform Π, locality box,
shared object NeRF + layout NeRF, Gaussian-trick density, σ̂²/S composition,
density-weighted colour, two-sample depth likelihood + colour term, beyond-clip
"empty" term, analytic Gaussian KL (θ wrapped) + Bernoulli KL.

Writes inputs, weights, noise, outputs and gradients (w.r.t. λ, λ0, layout
latents and all decoder weights) to a versioned little-endian binary file that
tests/model/test_model_ref.c reads and compares against the C decoder.

usage: model_ref.py OUT.bin [--seed S] [--unknown]
--unknown: config.invalid_depth = unknown; every ray r with r % 4 == 1 is a
sensor hole (no surface sample, no air sample, no colour term; W = 0). The
surf array then carries the ray state: 1 surface, 0 free, 2 unknown.
Format (version 1): b"SOOCREF1", u32 version, i32[9] ints, f32[16] floats, then
float32 arrays in the order of ARRAYS below, then f64[3] (loss, nll, kl), then
float32 outputs/gradients in the order of OUTPUTS, then b"END!".
"""
import math
import struct
import sys

import numpy as np
import torch

VERSION = 1
torch.set_default_dtype(torch.float64)


def main():
    out = sys.argv[1]
    seed = int(sys.argv[sys.argv.index("--seed") + 1]) if "--seed" in sys.argv else 3
    rs = np.random.RandomState(seed)
    unknown = "--unknown" in sys.argv
    K, d, dl, H, Hc, nf, nfl, N, use_box = 3, 8, 4, 16, 8, 3, 3, 256, 1
    smax, sigc, eps_rel, Rh, Hb, s_g, Bs, rmin, rmax = 30.0, 0.2, 1e-4, 0.6, 1.2, 0.3, 4.0, -10.0, 4.0
    tau, beta, h, npix, dclip, cut, dels = 0.8, 0.9, 1.5, 1024.0, 8.0, 0.98, 0.03
    blk = np.array([0.5, -h, 4.0], np.float32)
    NL = 6 + 2 * d

    f32 = lambda a: np.asarray(a, np.float32)
    # rays in G (origin 0), looking forward and down; a floor at y = -h and a sphere
    yaw = rs.uniform(-0.5, 0.5, N)
    pitch = rs.uniform(-0.9, 0.2, N)
    dirs = np.stack([np.sin(yaw) * np.cos(pitch), np.sin(pitch), np.cos(yaw) * np.cos(pitch)], 1)
    cen, rad = np.array([0.2, -h + 0.4, 3.0]), 0.45
    depth = np.zeros(N)
    surf = np.zeros(N)
    for r in range(N):
        t = 1e9
        if dirs[r, 1] < -1e-6:
            t = -h / dirs[r, 1]
        b = 2 * dirs[r] @ (-cen)
        c = cen @ cen - rad * rad
        disc = b * b - 4 * c
        if disc > 0:
            ts = (-b - math.sqrt(disc)) / 2
            if 0 < ts < t:
                t = ts
        if t <= dclip:
            depth[r], surf[r] = t, 1
    rgb = rs.uniform(0, 1, (N, 3))
    W = np.zeros(N)
    pts = np.zeros((2 * N, 3))
    for r in range(N):
        if surf[r]:
            es = dels * rs.uniform()
            pts[2 * r] = (depth[r] + es) * dirs[r]
            if rs.uniform() < 0.5:
                ta, W[r] = depth[r] * (cut + (1 - cut) * rs.uniform()), 2 * (1 - cut) * depth[r]
            else:
                ta, W[r] = depth[r] * cut * rs.uniform(), 2 * cut * depth[r]
        else:
            ta, W[r] = dclip * rs.uniform(), dclip
        pts[2 * r + 1] = ta * dirs[r]
    unk = np.zeros(N, bool)
    if unknown:   # holes: the drawn samples stay in pts (never decoded), the state says unknown
        unk[1::4] = True
        surf[unk], W[unk] = 2, 0
    dirs, depth, surf, rgb, W, pts = map(f32, (dirs, depth, surf, rgb, W, pts))

    lam = np.zeros((K, NL))
    lam0 = np.zeros((K, NL))
    for k in range(K):
        lam0[k, :2] = [rs.uniform(-1, 1), rs.uniform(1.5, 5)]
        lam0[k, 2] = rs.uniform(-3, 3)
        lam0[k, 3], lam0[k, 4] = math.log(0.25), math.log(math.pi ** 2)
        lam0[k, 5:5 + 2 * d] = rs.normal(0, 0.3, 2 * d)
        lam0[k, 5 + 2 * d] = rs.normal()
        lam[k] = lam0[k] + rs.normal(0, 0.3, NL)
    lam[0, :2] = [0.2, 3.0]            # one slot on the sphere
    lam[0, 2] = 3.0
    lam0[0, 2] = -3.0                  # wrapped θ difference
    lam[:, 3] = math.log(0.1 ** 2)
    lay = rs.normal(0, 0.3, 2 * dl)
    lay0 = rs.normal(0, 0.3, 2 * dl)
    eps_where = rs.normal(size=(K, 3))
    eps_what = rs.normal(size=(K, d))
    logi = rs.logistic(size=K)
    eps_lay = rs.normal(size=dl)
    lam, lam0, lay, lay0, eps_where, eps_what, logi, eps_lay = map(
        f32, (lam, lam0, lay, lay0, eps_where, eps_what, logi, eps_lay))

    def net_weights(din, dz):
        u = lambda *s: f32(rs.uniform(-1, 1, s) * math.sqrt(3.0 / s[0]))
        return [u(din, H), u(dz, H), f32(rs.normal(0, 0.1, H)), u(H, H), f32(rs.normal(0, 0.1, H)), u(H, H),
                f32(rs.normal(0, 0.1, H)), u(H, 1), f32([-1.0]), u(H, Hc), f32(rs.normal(0, 0.1, Hc)), u(Hc, 3),
                f32(rs.normal(0, 0.1, 3))]
    wo = net_weights(3 + 6 * nf, d)
    wl = net_weights(3 + 6 * nfl, dl)

    ints = [K, d, dl, H, Hc, nf, nfl, N, use_box]
    floats = [smax, sigc, eps_rel, Rh, Hb, s_g, Bs, rmin, rmax, tau, beta, h, npix, blk[0], blk[1], blk[2]]
    arrays = [rgb, depth, surf, W, pts, lam, lam0, lay, lay0, eps_where, eps_what, logi, eps_lay] + wo + wl

    # ---- torch ----
    T = lambda a, g=False: torch.tensor(np.asarray(a, np.float64), requires_grad=g)
    tlam, tlam0, tlay, tlay0 = T(lam, True), T(lam0, True), T(lay, True), T(lay0, True)
    two = [T(a, True) for a in wo]
    twl = [T(a, True) for a in wl]
    tpts = T(pts)
    cl = lambda x: torch.clamp(x, rmin, rmax)

    def pe(x, inv, n):
        v = x * inv
        out = [v]
        for f in range(n):
            out += [torch.sin((2 ** f) * v), torch.cos((2 ** f) * v)]
        return torch.cat(out, -1)

    def mlp(wts, pe_in, bias):
        W1x, W1z, b1, W2, b2, W3, b3, Wd, bd, Wc1, bc1, Wc2, bc2 = wts
        a1 = torch.relu(pe_in @ W1x + bias)
        a2 = torch.relu(a1 @ W2 + b2)
        a3 = torch.relu(a2 @ W3 + b3)
        sig = torch.sigmoid(a3 @ Wd + bd)[..., 0]
        col = torch.sigmoid(torch.relu(a3 @ Wc1 + bc1) @ Wc2 + bc2)
        return sig, col

    sig_t = torch.exp(0.5 * cl(tlam[:, 3]))
    sig_th = torch.exp(0.5 * cl(tlam[:, 4]))
    px = tlam[:, 0] + sig_t * T(eps_where[:, 0])
    pz = tlam[:, 1] + sig_t * T(eps_where[:, 1])
    th = tlam[:, 2] + sig_th * T(eps_where[:, 2])
    zwhat = tlam[:, 5:5 + d] + torch.exp(0.5 * cl(tlam[:, 5 + d:5 + 2 * d])) * T(eps_what)
    zp = torch.sigmoid((tlam[:, 5 + 2 * d] + T(logi)) / tau)
    zl = tlay[:dl] + torch.exp(0.5 * cl(tlay[dl:])) * T(eps_lay)

    P = 2 * N
    used = torch.ones(P, dtype=torch.bool)
    used[0::2] = torch.tensor((surf > 0.5) & (surf < 1.5))
    used[1::2] = torch.tensor(~unk)
    # layout
    xl = tpts - T(blk)
    sl, cl_l = mlp(twl, pe(xl, 1.0 / Bs, nfl), zl @ twl[1] + twl[2])
    shs, cts = [sl], [cl_l]
    for k in range(K):
        c, s = torch.cos(th[k]), torch.sin(th[k])
        vx, vy, vz = tpts[:, 0] - px[k], tpts[:, 1] + h, tpts[:, 2] - pz[k]
        xk = torch.stack([c * vx - s * vz, vy, s * vx + c * vz], 1)
        sg, co = mlp(two, pe(xk, 1.0 / Rh, nf), zwhat[k] @ two[1] + two[2])
        inside = ((xk[:, 0].abs() <= Rh) & (xk[:, 2].abs() <= Rh) & (xk[:, 1] >= 0) & (xk[:, 1] <= Hb)).detach()
        wg = torch.exp(-(xk[:, 0] ** 2 + xk[:, 2] ** 2) / (2 * s_g * s_g))
        sh = sg * zp[k] * (wg / wg.detach()) * inside.double()
        shs.append(sh)
        cts.append(co)
    SH = torch.stack(shs, 1)                    # P x C
    CT = torch.stack(cts, 1)                    # P x C x 3
    S = SH.sum(1) + 1e-8
    Sb = (SH * SH).sum(1) / S
    col = (SH[:, :, None] * CT).sum(1) / S[:, None]
    scale = npix / N
    ps, pa = torch.arange(0, P, 2), torch.arange(1, P, 2)
    tsurf = (T(surf) > 0.5) & (T(surf) < 1.5)
    lnorm = 3 * math.log(sigc * math.sqrt(2 * math.pi))
    ld = torch.where(tsurf, torch.log(smax * Sb[ps] + eps_rel * smax), torch.zeros(N)) - T(W) * smax * Sb[pa]
    lc = torch.where(tsurf, -((T(rgb) - col[ps]) ** 2).sum(1) / (2 * sigc ** 2) - lnorm, torch.zeros(N))
    nll = -scale * (ld.sum() + lc.sum())

    def kl_g(mu, rho, mu0, rho0):
        r, r0 = cl(rho), cl(rho0)
        return (0.5 * (r0 - r) + 0.5 * (torch.exp(r) + (mu - mu0) ** 2) * torch.exp(-r0) - 0.5).sum()

    kl = 0
    for k in range(K):
        l, l0 = tlam[k], tlam0[k]
        dth = l[2] - l0[2]
        wrapped = torch.remainder(dth + math.pi, 2 * math.pi) - math.pi
        dth = dth - (dth - wrapped).detach()
        kl = kl + kl_g(l[0:2], l[3].expand(2), l0[0:2], l0[3].expand(2))
        kl = kl + kl_g(dth[None], l[4:5], torch.zeros(1), l0[4:5])
        kl = kl + kl_g(l[5:5 + d], l[5 + d:5 + 2 * d], l0[5:5 + d], l0[5 + d:5 + 2 * d])
        p, p0 = torch.sigmoid(l[5 + 2 * d]), torch.sigmoid(l0[5 + 2 * d])
        kl = kl + p * (torch.log(p) - torch.log(p0)) + (1 - p) * (torch.log(1 - p) - torch.log(1 - p0))
    kl = kl + kl_g(tlay[:dl], tlay[dl:], tlay0[:dl], tlay0[dl:])
    loss = nll + beta * kl
    loss.backward()

    SHo = SH.detach().clone()
    SHo[~used] = 0
    colo = col.detach().clone()
    colo[~used] = 0
    outputs = [SHo, colo, tlam.grad, tlam0.grad, tlay.grad, tlay0.grad] + [t.grad for t in two] + [t.grad for t in twl]
    with open(out, "wb") as f:
        f.write(b"SOOCREF1")
        f.write(struct.pack("<I", VERSION))
        f.write(struct.pack("<9i", *ints))
        f.write(struct.pack("<16f", *floats))
        for a in arrays:
            f.write(np.ascontiguousarray(a, np.float32).tobytes())
        f.write(struct.pack("<3d", loss.item(), nll.item(), kl.item()))
        for a in outputs:
            f.write(np.ascontiguousarray(a.detach().numpy(), np.float32).tobytes())
        f.write(b"END!")
    print("model_ref: loss %.6f nll %.6f kl %.6f -> %s" % (loss.item(), nll.item(), kl.item(), out))


if __name__ == "__main__":
    main()
