/*
 * The decoder MLP layers the model runs (nn/nn_kern.h, src/nn/nerf.c):
 * float64 finite-difference checks of every forward / backward pair, and the
 * GEMMs against a float64 product.
 *
 * For each pair the loss is L = sum(out * r) (fixed random r). A float64 copy
 * of the forward, written here from the layer's formula, gives the numeric
 * gradient by central differences (h = 1e-6, truncation ~1e-12); the float32
 * analytic backward must match it within 1e-5 of the tensor's largest
 * gradient plus 1e-4 relative, and the float32 forward must match the float64
 * forward within 1e-5 of the output scale. Inputs that feed a ReLU are drawn
 * away from its kink (|pre-activation| >= 0.02 is not guaranteed, so a stencil
 * that straddles a kink is detected by comparing one-sided slopes and skipped;
 * at most 2% of the elements may be). Pairs:
 *   dense + ReLU / none, bias or accumulate init, input gradient through the
 *   previous layer's ReLU, with transposed weights (AVX2) and without;
 *   the density / colour heads; layers 2.. of a decoder (the composition).
 * Also: sooc_nn_gemm / sooc_nn_gemm_tn on odd shapes (masked panels, every
 * row remainder) against float64, and row-split invariance (a block of rows
 * computed in two calls gives bitwise the same outputs and input gradients).
 * sooc_nn_gemm_nt too; every GEMM check is the float error bound of a dot
 * product (gamma_n sum |terms|), which the portable kernel must also meet on
 * an AVX2 machine, and which a product with one term dropped must fail.
 * Run twice by CTest: AVX2 kernels, and SOOC_NO_AVX2=1 (the portable C kernel);
 * both keep row splits bitwise (docs/engine.md "Determinism contract").
 */
#include "check.h"
#include "nn/nn_kern.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static sooc_rng g_rng;

static void fill(float *p, int n, float lo, float hi) {
    for (int i = 0; i < n; i++) p[i] = lo + (hi - lo) * sooc_rng_uniformf(&g_rng);
}
/* values in [lo, hi] with |v| >= gap (away from a ReLU kink at 0) */
static void fill_gap(float *p, int n, float lo, float hi, float gap) {
    for (int i = 0; i < n; i++) {
        float v;
        do v = lo + (hi - lo) * sooc_rng_uniformf(&g_rng);
        while (fabsf(v) < gap);
        p[i] = v;
    }
}

/* ------------------------------------------------------------ float64 forwards */

static double relu(double x) { return x > 0 ? x : 0; }
static double sigm(double x) { return 1.0 / (1.0 + exp(-x)); }

/* y = act(x W + init), init = y0 (non-NULL) or b */
static void d_dense(int R, int I, int O, const double *x, const double *W, const double *b, const double *y0,
                    int act, double *y) {
    for (int r = 0; r < R; r++)
        for (int o = 0; o < O; o++) {
            double s = y0 ? y0[r * O + o] : b ? b[o] : 0;
            for (int i = 0; i < I; i++) s += x[r * I + i] * W[i * O + o];
            y[r * O + o] = act ? relu(s) : s;
        }
}

static void d_heads(int R, int H, int Hc, const double *h, const double *hc, const double *Wd, const double *bd,
                    const double *Wc2, const double *bc2, double *sig, double *col) {
    for (int r = 0; r < R; r++) {
        double s = bd[0];
        for (int j = 0; j < H; j++) s += h[r * H + j] * Wd[j];
        sig[r] = sigm(s);
        for (int a = 0; a < 3; a++) {
            double c = bc2[a];
            for (int j = 0; j < Hc; j++) c += hc[r * Hc + j] * Wc2[j * 3 + a];
            col[r * 3 + a] = sigm(c);
        }
    }
}

/* ------------------------------------------------------------ FD harness */

/* A pair under test: nin float64 tensors (inputs and weights), the loss in
 * float64, and the analytic float32 gradient of each. */
#define MAXT 12
typedef struct pair {
    const char *name;
    int nin;
    const char *tname[MAXT];
    double *t[MAXT];
    int n[MAXT];
    float *ga[MAXT];     /* analytic gradient (float32 kernels), NULL = not checked */
    double (*loss)(struct pair *);
    void *ctx;
} pair;

static int fd_check(pair *p) {
    int bad = 0;
    for (int q = 0; q < p->nin; q++) {
        if (!p->ga[q]) continue;
        double scale = 0;
        for (int e = 0; e < p->n[q]; e++) scale = fmax(scale, fabs(p->ga[q][e]));
        double worst = 0;
        int we = 0, skipped = 0;
        double wa = 0, wn = 0;
        for (int e = 0; e < p->n[q]; e++) {
            double x0 = p->t[q][e], h = 1e-6 * fmax(1.0, fabs(x0));
            p->t[q][e] = x0 + h;
            double fp = p->loss(p);
            p->t[q][e] = x0 - h;
            double fm = p->loss(p);
            p->t[q][e] = x0;
            double f0 = p->loss(p);
            double gn = (fp - fm) / (2 * h), right = (fp - f0) / h, left = (f0 - fm) / h;
            if (fabs(right - left) > 1e-4 * fmax(1.0, fmax(fabs(right), fabs(left)))) {   /* straddles a kink */
                skipped++;
                continue;
            }
            double ga = p->ga[q][e];
            double err = fabs(ga - gn) / (1e-5 * scale + 1e-4 * fabs(gn) + 1e-9);
            if (!(err <= worst)) worst = err, we = e, wa = ga, wn = gn;
        }
        printf("  %-28s %-6s n=%-5d worst err/tol %.3g (#%d: analytic %.7g, fd %.7g), %d kink skips\n", p->name,
               p->tname[q], p->n[q], worst, we, wa, wn, skipped);
        CHECK_MSG(worst <= 1.0, "%s d/d%s: #%d analytic %.7g, float64 fd %.7g", p->name, p->tname[q], we, wa, wn);
        CHECK_MSG(skipped <= p->n[q] / 50 + 1, "%s d/d%s: %d of %d elements at a kink", p->name, p->tname[q], skipped,
                  p->n[q]);
        bad += worst > 1.0;
    }
    return bad;
}

static void to_f(float *d, const double *s, int n) {
    for (int i = 0; i < n; i++) d[i] = (float)s[i];
}
static void to_d(double *d, const float *s, int n) {
    for (int i = 0; i < n; i++) d[i] = s[i];
}
static void cmp_fwd(const char *what, const float *f, const double *d, int n) {
    double sc = 1e-30, worst = 0;
    for (int i = 0; i < n; i++) sc = fmax(sc, fabs(d[i]));
    for (int i = 0; i < n; i++) worst = fmax(worst, fabs(f[i] - d[i]) / sc);
    printf("  %-28s forward: max |f32 - f64| / max|f64| = %.2g\n", what, worst);
    CHECK_MSG(worst <= 1e-5, "%s forward: %.3g", what, worst);
}

/* ------------------------------------------------------------ dense */

enum { R = 13, I = 11, O = 21, H = 20, HC = 12 };

typedef struct dense_ctx {
    int act, acc;
    double r[R * O];
} dense_ctx;

/* inputs: 0 x_pre [R x I] (x = relu(x_pre)), 1 W [I x O], 2 b [O] or y0 [R x O] */
static double dense_loss(pair *p) {
    dense_ctx *c = p->ctx;
    static double x[R * I], y[R * O];
    for (int i = 0; i < R * I; i++) x[i] = relu(p->t[0][i]);
    d_dense(R, I, O, x, p->t[1], c->acc ? NULL : p->t[2], c->acc ? p->t[2] : NULL, c->act, y);
    double L = 0;
    for (int i = 0; i < R * O; i++) L += y[i] * c->r[i];
    return L;
}

static void test_dense(int act, int acc, int transposed) {
    static double xp[R * I], W[I * O], b[R * O];
    static float fx[R * I], fW[I * O], fWt[O * I], fb[R * O], fy[R * O], dz[R * O], dx[R * I], dW[I * O], db[R * O];
    static double yd[R * O], xd[R * I];
    dense_ctx c = {act, acc, {0}};
    float tmp[R * O];
    fill_gap(tmp, R * I, -1, 1, 0.02f), to_d(xp, tmp, R * I);
    fill(tmp, I * O, -0.5f, 0.5f), to_d(W, tmp, I * O);
    int nb = acc ? R * O : O;
    fill(tmp, nb, -0.3f, 0.3f), to_d(b, tmp, nb);
    fill(tmp, R * O, -1, 1), to_d(c.r, tmp, R * O);
    for (int i = 0; i < R * I; i++) fx[i] = (float)relu(xp[i]), xd[i] = fx[i];
    to_f(fW, W, I * O);
    to_f(fb, b, nb);
    for (int i = 0; i < I; i++)
        for (int o = 0; o < O; o++) fWt[o * I + i] = fW[i * O + o];
    /* forward */
    if (acc) memcpy(fy, fb, sizeof(float) * R * O);
    sooc_nn_dense_forward(R, I, O, fx, I, fW, acc ? NULL : fb, fy, O, acc, act ? SOOC_NN_EP_RELU : SOOC_NN_EP_NONE);
    d_dense(R, I, O, xd, W, acc ? NULL : b, acc ? b : NULL, act, yd);
    char name[96];
    snprintf(name, sizeof name, "dense %s %s %s", act ? "relu" : "none", acc ? "acc" : "bias", transposed ? "Wt" : "W");
    cmp_fwd(name, fy, yd, R * O);
    /* backward: dz = r * act'(y) */
    for (int i = 0; i < R * O; i++) dz[i] = (float)c.r[i] * (act ? (fy[i] > 0 ? 1.0f : 0.0f) : 1.0f);
    memset(dW, 0, sizeof dW);
    memset(db, 0, sizeof db);
    for (int i = 0; i < R * I; i++) dx[i] = 123.0f;   /* overwritten (acc_dx = 0) */
    sooc_nn_dense_backward(R, I, O, dz, O, fx, I, fW, transposed ? fWt : NULL, dx, I, 0, fx, dW, acc ? NULL : db, 1.0f);
    if (acc)   /* the init's gradient is dz itself */
        memcpy(db, dz, sizeof(float) * R * O);
    pair p = {name, 3, {"x", "W", acc ? "y0" : "b"}, {xp, W, b}, {R * I, I * O, nb}, {dx, dW, db}, dense_loss, &c};
    fd_check(&p);
    /* alpha scales the weight gradients and accumulates; acc_dx accumulates the input gradient */
    static float dW2[I * O], db2[O], dx2[R * I];
    for (int i = 0; i < I * O; i++) dW2[i] = 1.0f;
    for (int i = 0; i < O; i++) db2[i] = 1.0f;
    for (int i = 0; i < R * I; i++) dx2[i] = fx[i] > 0 ? 0.5f : 0.0f;
    sooc_nn_dense_backward(R, I, O, dz, O, fx, I, fW, transposed ? fWt : NULL, dx2, I, 1, fx, dW2, db2, 0.25f);
    double e = 0;
    for (int i = 0; i < I * O; i++) e = fmax(e, fabs(dW2[i] - (1.0f + 0.25f * dW[i])) / (1 + fabs(dW[i])));
    for (int i = 0; i < R * I; i++) e = fmax(e, fabs(dx2[i] - (fx[i] > 0 ? 0.5f + dx[i] : 0.0f)) / (1 + fabs(dx[i])));
    if (!acc)
        for (int i = 0; i < O; i++) e = fmax(e, fabs(db2[i] - (1.0f + 0.25f * db[i])) / (1 + fabs(db[i])));
    CHECK_MSG(e < 1e-5, "%s: alpha / accumulate: %.3g", name, e);
}

/* ------------------------------------------------------------ heads */

typedef struct heads_ctx {
    double rs[R], rc[R * 3];
} heads_ctx;

/* inputs: 0 h [R x H], 1 hc_pre [R x HC] (hc = relu), 2 Wd [H], 3 bd, 4 Wc2 [HC x 3], 5 bc2 [3] */
static double heads_loss(pair *p) {
    heads_ctx *c = p->ctx;
    static double hc[R * HC], sig[R], col[R * 3];
    for (int i = 0; i < R * HC; i++) hc[i] = relu(p->t[1][i]);
    d_heads(R, H, HC, p->t[0], hc, p->t[2], p->t[3], p->t[4], p->t[5], sig, col);
    double L = 0;
    for (int r = 0; r < R; r++) {
        L += sig[r] * c->rs[r];
        for (int a = 0; a < 3; a++) L += col[r * 3 + a] * c->rc[r * 3 + a];
    }
    return L;
}

static void test_heads(void) {
    static double h[R * H], hcp[R * HC], Wd[H], bd[1], Wc2[HC * 3], bc2[3], hcd[R * HC], sd[R], cd[R * 3];
    static float fh[R * H], fhc[R * HC], fWd[H], fbd[1], fWc2[HC * 3], fbc2[3], sig[R], col[R * 3], gs[R], gc[R * 3];
    static float dh[R * H], dhc[R * HC], dWd[H], dbd[1], dWc2[HC * 3], dbc2[3];
    heads_ctx c;
    float tmp[R * H];
    fill(tmp, R * H, 0, 1), to_d(h, tmp, R * H);
    fill_gap(tmp, R * HC, -1, 1, 0.02f), to_d(hcp, tmp, R * HC);
    fill(tmp, H, -0.5f, 0.5f), to_d(Wd, tmp, H);
    fill(tmp, 1, -0.5f, 0.5f), to_d(bd, tmp, 1);
    fill(tmp, HC * 3, -0.5f, 0.5f), to_d(Wc2, tmp, HC * 3);
    fill(tmp, 3, -0.5f, 0.5f), to_d(bc2, tmp, 3);
    fill(tmp, R, -1, 1), to_d(c.rs, tmp, R);
    fill(tmp, R * 3, -1, 1), to_d(c.rc, tmp, R * 3);
    to_f(fh, h, R * H), to_f(fWd, Wd, H), to_f(fbd, bd, 1), to_f(fWc2, Wc2, HC * 3), to_f(fbc2, bc2, 3);
    for (int i = 0; i < R * HC; i++) fhc[i] = (float)relu(hcp[i]), hcd[i] = fhc[i];
    sooc_nn_nerf_heads_forward(R, H, HC, fh, fhc, fWd, fbd, fWc2, fbc2, sig, col);
    d_heads(R, H, HC, h, hcd, Wd, bd, Wc2, bc2, sd, cd);
    cmp_fwd("heads sig", sig, sd, R);
    cmp_fwd("heads col", col, cd, R * 3);
    for (int r = 0; r < R; r++) gs[r] = (float)c.rs[r];
    for (int i = 0; i < R * 3; i++) gc[i] = (float)c.rc[i];
    memset(dWd, 0, sizeof dWd), memset(dbd, 0, sizeof dbd), memset(dWc2, 0, sizeof dWc2), memset(dbc2, 0, sizeof dbc2);
    sooc_nn_nerf_heads_backward(R, H, HC, fh, fhc, sig, col, fWd, fWc2, gs, gc, dh, dhc, dWd, dbd, dWc2, dbc2, 1.0f);
    pair p = {"heads", 6, {"h", "hc", "Wd", "bd", "Wc2", "bc2"}, {h, hcp, Wd, bd, Wc2, bc2},
              {R * H, R * HC, H, 1, HC * 3, 3}, {dh, dhc, dWd, dbd, dWc2, dbc2}, heads_loss, &c};
    fd_check(&p);
}

/* ------------------------------------------------------------ tail */

/* inputs: 0 a1_pre [R x H], 1 W2, 2 b2, 3 W3, 4 b3, 5 Wd, 6 bd, 7 Wc1 [H x HC], 8 bc1, 9 Wc2, 10 bc2 */
static double tail_loss(pair *p) {
    heads_ctx *c = p->ctx;
    static double a1[R * H], a2[R * H], a3[R * H], ac[R * HC], sig[R], col[R * 3];
    double **t = p->t;
    for (int i = 0; i < R * H; i++) a1[i] = relu(t[0][i]);
    d_dense(R, H, H, a1, t[1], t[2], NULL, 1, a2);
    d_dense(R, H, H, a2, t[3], t[4], NULL, 1, a3);
    d_dense(R, H, HC, a3, t[7], t[8], NULL, 1, ac);
    d_heads(R, H, HC, a3, ac, t[5], t[6], t[9], t[10], sig, col);
    double L = 0;
    for (int r = 0; r < R; r++) {
        L += sig[r] * c->rs[r];
        for (int a = 0; a < 3; a++) L += col[r * 3 + a] * c->rc[r * 3 + a];
    }
    return L;
}

static void test_tail(int transposed) {
    static const int sz[11] = {R * H, H * H, H, H * H, H, H, 1, H * HC, HC, HC * 3, 3};
    static double dt[11][R * H > H * H ? R * H : H * H];
    static float ft[11][R * H > H * H ? R * H : H * H], gr[11][R * H > H * H ? R * H : H * H];
    static float a1[R * H], a2[R * H], a3[R * H], ac[R * HC], sig[R], col[R * 3], gs[R], gc[R * 3];
    static float gA[R * H], gB[R * H], W2t[H * H], W3t[H * H], Wc1t[HC * H];
    heads_ctx c;
    fill_gap(ft[0], R * H, -1, 1, 0.02f);
    for (int q = 1; q < 11; q++) fill(ft[q], sz[q], q % 2 ? -0.45f : -0.1f, q % 2 ? 0.45f : 0.2f);
    for (int q = 0; q < 11; q++) to_d(dt[q], ft[q], sz[q]);
    float tmp[R * 3];
    fill(tmp, R, -1, 1), to_d(c.rs, tmp, R);
    fill(tmp, R * 3, -1, 1), to_d(c.rc, tmp, R * 3);
    for (int i = 0; i < H; i++)
        for (int j = 0; j < H; j++) W2t[j * H + i] = ft[1][i * H + j], W3t[j * H + i] = ft[3][i * H + j];
    for (int i = 0; i < H; i++)
        for (int j = 0; j < HC; j++) Wc1t[j * H + i] = ft[7][i * HC + j];
    sooc_nn_nerf_tail t = {H, HC, ft[1], ft[2], ft[3], ft[4], ft[5], ft[6], ft[7], ft[8], ft[9], ft[10],
                           transposed ? W2t : NULL, transposed ? W3t : NULL, transposed ? Wc1t : NULL};
    memcpy(a1, ft[0], sizeof(float) * R * H);
    sooc_nn_nerf_tail_forward(&t, R, a1, a2, a3, ac, sig, col, 1);
    /* forward against float64 */
    pair p = {transposed ? "tail (Wt)" : "tail (W)", 11, {"a1", "W2", "b2", "W3", "b3", "Wd", "bd", "Wc1", "bc1", "Wc2", "bc2"},
              {0}, {0}, {0}, tail_loss, &c};
    for (int q = 0; q < 11; q++) p.t[q] = dt[q], p.n[q] = sz[q], p.ga[q] = gr[q];
    {
        double a1d[R * H], a2d[R * H], a3d[R * H], acd[R * HC], sd[R], cd[R * 3];
        for (int i = 0; i < R * H; i++) a1d[i] = relu(dt[0][i]);
        d_dense(R, H, H, a1d, dt[1], dt[2], NULL, 1, a2d);
        d_dense(R, H, H, a2d, dt[3], dt[4], NULL, 1, a3d);
        d_dense(R, H, HC, a3d, dt[7], dt[8], NULL, 1, acd);
        d_heads(R, H, HC, a3d, acd, dt[5], dt[6], dt[9], dt[10], sd, cd);
        cmp_fwd(p.name, sig, sd, R);
        cmp_fwd(p.name, col, cd, R * 3);
    }
    for (int r = 0; r < R; r++) gs[r] = (float)c.rs[r];
    for (int i = 0; i < R * 3; i++) gc[i] = (float)c.rc[i];
    for (int q = 1; q < 11; q++) memset(gr[q], 0, sizeof(float) * sz[q]);
    sooc_nn_nerf_tail_grad g = {gr[1], gr[2], gr[3], gr[4], gr[5], gr[6], gr[7], gr[8], gr[9], gr[10]};
    /* alpha 0.5: weight gradients are half the loss gradient */
    sooc_nn_nerf_tail_backward(&t, &g, 0.5f, R, a1, a2, a3, ac, sig, col, gs, gc, gA, gB, gB, gr[0]);
    for (int q = 1; q < 11; q++)
        for (int e = 0; e < sz[q]; e++) gr[q][e] *= 2.0f;
    fd_check(&p);

    /* row-split invariance: rows 0..4 and 5..R-1 in two calls, bitwise equal */
    static float b1[R * H], b2[R * H], b3[R * H], bc[R * HC], bs[R], bcol[R * 3], hs[R], hcl[R * 3], g1b[R * H];
    memcpy(b1, ft[0], sizeof(float) * R * H);
    sooc_nn_nerf_tail_forward(&t, 5, b1, b2, b3, bc, bs, bcol, 1);
    sooc_nn_nerf_tail_forward(&t, R - 5, b1 + 5 * H, b2 + 5 * H, b3 + 5 * H, bc + 5 * HC, bs + 5, bcol + 15, 1);
    CHECK(!memcmp(bs, sig, sizeof bs) && !memcmp(bcol, col, sizeof bcol) && !memcmp(b3, a3, sizeof b3));
    for (int r = 0; r < R; r++) hs[r] = (float)c.rs[r];
    for (int i = 0; i < R * 3; i++) hcl[i] = (float)c.rc[i];
    sooc_nn_nerf_tail_backward(&t, NULL, 0, 5, b1, b2, b3, bc, bs, bcol, hs, hcl, gA, gB, gB, g1b);
    sooc_nn_nerf_tail_backward(&t, NULL, 0, R - 5, b1 + 5 * H, b2 + 5 * H, b3 + 5 * H, bc + 5 * HC, bs + 5, bcol + 15,
                               hs + 5, hcl + 15, gA, gB, gB, g1b + 5 * H);
    CHECK_MSG(!memcmp(g1b, gr[0], sizeof g1b), "%s: the input gradient depends on the row split", p.name);
}

/* ------------------------------------------------------------ GEMMs */

/* Every check of a GEMM below is the float error bound of a dot product
 * (check_gamma_n, tests/check.h), element by element, with n the products,
 * the init and the chunk additions, and the terms' magnitudes computed in
 * float64; it holds for every summation order, so for every kernel. */

enum { GL = 64 };
typedef struct gcase {
    int M, N, K, mode, kind;   /* kind 0 gemm, 1 gemm_tn (alpha 0.5), 2 gemm_nt */
} gcase;

/* Run one case on the current kernel into C (from C0). */
static void gemm_case(const gcase *g, const float *A, const float *B, const float *C0, const float *bias,
                      const float *mask, float *C) {
    int ld = GL, acc = g->mode == 1;
    int ep = g->mode == 2 ? SOOC_NN_EP_RELU : g->mode == 3 ? SOOC_NN_EP_MASK : SOOC_NN_EP_NONE;
    memcpy(C, C0, sizeof(float) * GL * GL);
    if (g->kind == 0) sooc_nn_gemm(g->M, g->N, g->K, A, ld, B, ld, C, ld, g->mode == 2 ? bias : NULL, acc, ep, mask, ld);
    else if (g->kind == 1) sooc_nn_gemm_tn(g->M, g->N, g->K, 0.5f, A, ld, B, ld, C, ld);
    else sooc_nn_gemm_nt(g->M, g->N, g->K, A, ld, B, ld, C, ld, acc, g->mode == 2 ? SOOC_NN_EP_NONE : ep, mask, ld);
}

/* Exact value (float64, before the epilogue) and magnitude of element (i, j). */
static void gemm_exact(const gcase *g, const float *A, const float *B, const float *C0, const float *bias, int i,
                       int j, int drop, double *want, double *mag) {
    int ld = GL, K = g->K - drop;
    double s, m;
    if (g->kind == 1) {
        s = 0, m = 0;
        for (int q = 0; q < K; q++) s += (double)A[q * ld + i] * B[q * ld + j], m += fabs((double)A[q * ld + i] * B[q * ld + j]);
        s = C0[i * ld + j] + 0.5 * s, m = fabs(C0[i * ld + j]) + 0.5 * m;
    } else {
        s = g->mode == 1 ? C0[i * ld + j] : g->mode == 2 && g->kind == 0 ? bias[j] : 0;
        m = fabs(s);
        for (int q = 0; q < K; q++) {
            double t = g->kind == 0 ? (double)A[i * ld + q] * B[q * ld + j] : (double)A[i * ld + q] * B[j * ld + q];
            s += t, m += fabs(t);
        }
    }
    *want = s, *mag = m;
}

/* Largest |C - exact| / bound over the case (epilogue applied to the exact
 * value; elements outside M x N must be untouched: returns 1e30 if not). */
static double gemm_err(const gcase *g, const float *A, const float *B, const float *C0, const float *bias,
                       const float *mask, const float *C, int drop) {
    double worst = 0;
    /* tn sums in chunks of 64 rows (+1 per chunk) and scales by alpha (+1) */
    int n = g->K + 2 + g->K / 64;
    for (int i = 0; i < GL; i++)
        for (int j = 0; j < GL; j++) {
            if (i >= g->M || j >= g->N) {
                if (memcmp(&C[i * GL + j], &C0[i * GL + j], sizeof(float))) return 1e30;
                continue;
            }
            double want, mag;
            gemm_exact(g, A, B, C0, bias, i, j, drop, &want, &mag);
            int ep = g->kind == 1 ? 0 : g->mode;
            if (ep == 2 && g->kind == 0) want = want > 0 ? want : 0;
            if (ep == 3 && !(mask[i * GL + j] > 0)) want = 0;
            double e = fabs(C[i * GL + j] - want), bound = check_gamma_n(n) * mag + 1e-45;
            worst = fmax(worst, e / bound);
        }
    return worst;
}

static void test_gemm(void) {
    static const int Ms[] = {1, 5, 6, 7, 13, 25}, Ns[] = {1, 3, 8, 9, 16, 21, 33, 64}, Ks[] = {1, 7, 33, 64, 65, 150};
    static float A[GL * GL * 3], B[GL * GL * 3], C[GL * GL], Cp[GL * GL], C0[GL * GL], bias[GL], mask[GL * GL];
    double worst[3] = {0, 0, 0}, cross = 0, dropped = 1e30;
    int avx2 = sooc_nn_gemm_avx2();
    fill(A, GL * GL * 3, -1, 1), fill(B, GL * GL * 3, -1, 1), fill(C0, GL * GL, -1, 1), fill(bias, GL, -1, 1);
    fill(mask, GL * GL, -1, 1);
    for (int kind = 0; kind < 3; kind++)
        for (size_t a = 0; a < sizeof Ms / sizeof *Ms; a++)
            for (size_t b = 0; b < sizeof Ns / sizeof *Ns; b++)
                for (size_t k = 0; k < sizeof Ks / sizeof *Ks; k++)
                    for (int mode = 0; mode < 4; mode++) {
                        gcase g = {Ms[a], Ns[b], Ks[k], mode, kind};
                        if (kind == 1 && mode) continue;
                        gemm_case(&g, A, B, C0, bias, mask, C);
                        double e = gemm_err(&g, A, B, C0, bias, mask, C, 0);
                        worst[kind] = fmax(worst[kind], e);
                        /* negative control: a product with the last term dropped is outside
                         * the bound somewhere (largest case of each kind, ReLU-free) */
                        if (g.K >= 7 && g.M >= 13 && g.N >= 33 && (mode == 0 || mode == 1))
                            dropped = fmin(dropped, gemm_err(&g, A, B, C0, bias, mask, C, 1));
                        if (!avx2) continue;
                        /* the portable kernel on the same case: both within the bound, so
                         * they agree within twice it */
                        sooc_nn_gemm_set_kernel(0);
                        gemm_case(&g, A, B, C0, bias, mask, Cp);
                        sooc_nn_gemm_set_kernel(1);
                        cross = fmax(cross, gemm_err(&g, A, B, C0, bias, mask, Cp, 0));
                    }
    printf("  gemm (%s): worst |f32 - exact| / (gamma_n sum|terms|): gemm %.2g, gemm_tn %.2g, gemm_nt %.2g; "
           "portable kernel %.2g%s; a dropped term: %.3g\n",
           avx2 ? "AVX2" : "portable", worst[0], worst[1], worst[2], cross, avx2 ? "" : " (not run)", dropped);
    CHECK_MSG(worst[0] <= 1 && worst[1] <= 1 && worst[2] <= 1, "a GEMM outside its error bound");
    CHECK_MSG(cross <= 1, "the portable kernel outside the error bound (%.3g)", cross);
    CHECK_MSG(dropped > 1, "control: a product with a term dropped passed the bound (%.3g)", dropped);
}

char *openblas_get_corename(void);   /* OpenBLAS's cblas.h */

int main(void) {
    sooc_rng_seed(&g_rng, 2121, 0);
    /* the OpenBLAS kernel is named to show that no result here depends on it */
    printf("test_nn_nerf: %s kernels (OpenBLAS core %s, not used by these kernels)\n",
           sooc_nn_gemm_avx2() ? "AVX2/FMA" : "portable C", openblas_get_corename());
    test_gemm();
    for (int act = 0; act < 2; act++)
        for (int acc = 0; acc < 2; acc++)
            for (int tr = 0; tr < 2; tr++) test_dense(act, acc, tr);
    test_heads();
    test_tail(0);
    test_tail(1);
    return check_report("test_nn_nerf");
}
