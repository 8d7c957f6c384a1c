/*
 * The refinement network's kernel pairs (nn/nn_refine.h):
 *
 *  1. float64 finite differences: for every pair's _f64 version, the loss
 *     L = sum(r * y) (fixed random r) differentiated by the 4-point central
 *     difference with h = 1e-5 must match the backward within
 *     1e-8 + 1e-6 * max(|ga|, |gn|) for every input and weight element;
 *  2. float32 against float64: the float32 kernels on the same (float-rounded)
 *     inputs match the float64 outputs within 2e-6 + 1e-5 |y| and the
 *     gradients within 1e-5 + 1e-4 |g| (relative to the array's largest value);
 *  3. invariances of the float32 conv: items split into ranges, and the shared
 *     leading channels taken from sooc_nn_rconv_shared, give bitwise the
 *     result of one call over all items; the backward on two item blocks gives
 *     bitwise the input gradients and the weight gradients within 1e-6 of
 *     their largest value.
 * Shapes are small (every pair at its model layout, odd sizes, strided rows).
 */
#include "check.h"
#include "nn/nn_refine.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAXIN 8
#define FD_H 1e-5
#define FD_ATOL 1e-8
#define FD_RTOL 1e-6

static sooc_rng g_rng;

typedef struct op op;
struct op {
    const char *name;
    int nin;
    size_t n[MAXIN];             /* input sizes                         */
    double lo[MAXIN], hi[MAXIN];
    int nograd[MAXIN];           /* no gradient (the f64 backward ignores it) */
    double *x[MAXIN], *gx[MAXIN];
    size_t nout;
    double *y;
    void *ctx;
    void (*fwd)(op *o);                                    /* y = f(x)                   */
    void (*bwd)(op *o, double *dy);                        /* gx += (may overwrite dy)    */
    /* float32: y32 = f(x32); gx32 += backward of dy32 (dy32 may be overwritten) */
    void (*run32)(op *o, float **x32, float *y32, float **gx32, float *dy32);
};

static double *dalloc(size_t n) { return calloc(n ? n : 1, sizeof(double)); }
static float *falloc(size_t n) { return calloc(n ? n : 1, sizeof(float)); }

static double loss(op *o, const double *r) {
    o->fwd(o);
    double L = 0;
    for (size_t i = 0; i < o->nout; i++) L += r[i] * o->y[i];
    return L;
}

static void check_op(op *o) {
    for (int i = 0; i < o->nin; i++) {
        o->x[i] = dalloc(o->n[i]);
        o->gx[i] = dalloc(o->n[i]);
        for (size_t e = 0; e < o->n[i]; e++)   /* float-representable values: the float32 run sees the same */
            o->x[i][e] = (float)(o->lo[i] + (o->hi[i] - o->lo[i]) * sooc_rng_uniform(&g_rng));
    }
    o->y = dalloc(o->nout);
    o->fwd(o);
    double *r = dalloc(o->nout), *dy = dalloc(o->nout), *y0 = dalloc(o->nout);
    for (size_t i = 0; i < o->nout; i++) r[i] = (float)(2 * sooc_rng_uniform(&g_rng) - 1);
    memcpy(y0, o->y, o->nout * sizeof(double));
    memcpy(dy, r, o->nout * sizeof(double));
    o->bwd(o, dy);
    /* 1. finite differences in float64 */
    double worst = 0;
    for (int i = 0; i < o->nin; i++) {
        if (o->nograd[i]) continue;
        for (size_t e = 0; e < o->n[i]; e++) {
            double v = o->x[i][e], h = FD_H * fmax(1.0, fabs(v));
            o->x[i][e] = v + h;
            double p1 = loss(o, r);
            o->x[i][e] = v - h;
            double m1 = loss(o, r);
            o->x[i][e] = v + h / 2;
            double p2 = loss(o, r);
            o->x[i][e] = v - h / 2;
            double m2 = loss(o, r);
            o->x[i][e] = v;
            double gn = (8 * (p2 - m2) - (p1 - m1)) / (6 * h), ga = o->gx[i][e];
            double err = fabs(ga - gn) / (FD_ATOL + FD_RTOL * fmax(fabs(ga), fabs(gn)));
            worst = fmax(worst, err);
            CHECK_MSG(err <= 1.0, "%s input %d [%zu]: backward %.12g, finite difference %.12g", o->name, i, e, ga, gn);
        }
    }
    o->fwd(o);   /* restore y */
    /* 2. float32 against float64 */
    float *x32[MAXIN], *g32[MAXIN], *y32 = falloc(o->nout), *dy32 = falloc(o->nout);
    for (int i = 0; i < o->nin; i++) {
        x32[i] = falloc(o->n[i]);
        g32[i] = falloc(o->n[i]);
        for (size_t e = 0; e < o->n[i]; e++) x32[i][e] = (float)o->x[i][e];
    }
    for (size_t i = 0; i < o->nout; i++) dy32[i] = (float)r[i];
    o->run32(o, x32, y32, g32, dy32);
    double ymax = 0, werr32 = 0;
    for (size_t i = 0; i < o->nout; i++) ymax = fmax(ymax, fabs(y0[i]));
    for (size_t i = 0; i < o->nout; i++) {
        double err = fabs(y32[i] - y0[i]) / (2e-6 * fmax(1.0, ymax) + 1e-5 * fabs(y0[i]));
        werr32 = fmax(werr32, err);
        CHECK_MSG(err <= 1.0, "%s float32 output [%zu]: %.9g vs float64 %.12g", o->name, i, y32[i], y0[i]);
    }
    for (int i = 0; i < o->nin; i++) {
        if (o->nograd[i]) continue;
        double gmax = 0;
        for (size_t e = 0; e < o->n[i]; e++) gmax = fmax(gmax, fabs(o->gx[i][e]));
        for (size_t e = 0; e < o->n[i]; e++) {
            double err = fabs(g32[i][e] - o->gx[i][e]) / (1e-5 * fmax(1e-3, gmax) + 1e-4 * fabs(o->gx[i][e]));
            werr32 = fmax(werr32, err);
            CHECK_MSG(err <= 1.0, "%s float32 grad %d [%zu]: %.9g vs float64 %.12g", o->name, i, e, g32[i][e],
                      o->gx[i][e]);
        }
    }
    printf("  %-26s finite differences worst err/tol %.3f; float32 vs float64 worst err/tol %.3f\n", o->name, worst,
           werr32);
    for (int i = 0; i < o->nin; i++) free(o->x[i]), free(o->gx[i]), free(x32[i]), free(g32[i]);
    free(o->y), free(r), free(dy), free(y0), free(y32), free(dy32);
}

/* ------------------------------------------------------------------ conv */
typedef struct {
    int B, Ci, H, W, Co;
    sooc_nn_act act;
} conv_c;
static void conv_fwd(op *o) {
    conv_c *c = o->ctx;
    sooc_nn_rconv_forward_f64(o->y, o->x[0], o->x[1], o->x[2], c->B, c->Ci, c->H, c->W, c->Co, c->act);
}
static void conv_bwd(op *o, double *dy) {
    conv_c *c = o->ctx;
    sooc_nn_rconv_backward_f64(o->gx[0], o->gx[1], o->gx[2], dy, o->y, o->x[0], o->x[1], c->B, c->Ci, c->H, c->W,
                               c->Co, c->act);
}
static void conv_32(op *o, float **x, float *y, float **g, float *dy) {
    conv_c *c = o->ctx;
    float *cols = falloc(sooc_nn_rconv_cols_floats(c->Ci, c->B, c->H, c->W));
    float *dcols = falloc(sooc_nn_rconv_cols_floats(c->Ci, c->B, c->H, c->W));
    sooc_nn_rconv_forward(y, cols, x[0], x[1], x[2], NULL, 0, c->B, 0, c->B, c->Ci, c->H, c->W, c->Co, c->act);
    sooc_nn_rconv_backward(g[0], g[1], g[2], dy, y, x[0], x[1], cols, dcols, c->B, 0, c->B, c->Ci, c->H, c->W, c->Co, c->act);
    free(cols), free(dcols);
}
static void test_conv(int B, int Ci, int H, int W, int Co, sooc_nn_act act, const char *name) {
    conv_c c = {B, Ci, H, W, Co, act};
    op o = {.name = name, .nin = 3, .ctx = &c, .fwd = conv_fwd, .bwd = conv_bwd, .run32 = conv_32};
    o.n[0] = (size_t)Ci * B * H * W, o.lo[0] = -1.5, o.hi[0] = 1.5;
    o.n[1] = (size_t)Co * Ci * 9, o.lo[1] = -0.5, o.hi[1] = 0.5;
    o.n[2] = (size_t)Co, o.lo[2] = -0.3, o.hi[2] = 0.3;
    o.nout = (size_t)Co * B * (H / 2) * (W / 2);
    check_op(&o);
}

/* Item ranges and shared channels change nothing (float32, bitwise). */
static void test_conv_invariance(void) {
    int B = 4, Ci = 5, H = 8, W = 6, Co = 7, nsh = 2, HWo = (H / 2) * (W / 2);
    size_t nx = (size_t)Ci * B * H * W, ny = (size_t)Co * B * HWo;
    float *x = falloc(nx), *w = falloc((size_t)Co * Ci * 9), *b = falloc(Co), *y0 = falloc(ny), *y1 = falloc(ny),
          *y2 = falloc(ny), *ysh = falloc((size_t)Co * HWo), *cols = falloc(sooc_nn_rconv_cols_floats(Ci, B, H, W));
    for (size_t i = 0; i < nx; i++) x[i] = (float)sooc_rng_normal(&g_rng);
    for (int c = 0; c < nsh; c++)   /* the shared channels: the same for every item */
        for (int bb = 1; bb < B; bb++) memcpy(x + ((size_t)c * B + bb) * H * W, x + (size_t)c * B * H * W, sizeof(float) * H * W);
    for (int i = 0; i < Co * Ci * 9; i++) w[i] = 0.3f * (float)sooc_rng_normal(&g_rng);
    for (int i = 0; i < Co; i++) b[i] = 0.1f * (float)sooc_rng_normal(&g_rng);
    sooc_nn_rconv_forward(y0, cols, x, w, b, NULL, 0, B, 0, B, Ci, H, W, Co, SOOC_NN_ACT_ELU);
    sooc_nn_rconv_forward(y1, cols, x, w, b, NULL, 0, B, 0, 1, Ci, H, W, Co, SOOC_NN_ACT_ELU);
    sooc_nn_rconv_forward(y1, cols, x, w, b, NULL, 0, B, 1, B, Ci, H, W, Co, SOOC_NN_ACT_ELU);
    sooc_nn_rconv_shared(ysh, cols, x, w, B, Ci, H, W, Co, nsh);
    for (int bb = 0; bb < B; bb++)
        sooc_nn_rconv_forward(y2, cols, x, w, b, ysh, nsh, B, bb, bb + 1, Ci, H, W, Co, SOOC_NN_ACT_ELU);
    CHECK_MSG(!memcmp(y0, y1, ny * sizeof(float)), "conv: items [0,1) + [1,B) differ from [0,B)");
    CHECK_MSG(!memcmp(y0, y2, ny * sizeof(float)), "conv: shared-channel share differs from the full product");
    /* backward on two item blocks (the model's split): input gradients bitwise equal to one
     * call, weight gradients (block partial sums added) equal to rounding */
    float *dy0 = falloc(ny), *dy1 = falloc(ny), *dx0 = falloc(nx), *dx1 = falloc(nx), *dw0 = falloc((size_t)Co * Ci * 9),
          *dw1 = falloc((size_t)Co * Ci * 9), *dw2 = falloc((size_t)Co * Ci * 9), *db0 = falloc(Co), *db1 = falloc(Co),
          *db2 = falloc(Co), *dcols = falloc(sooc_nn_rconv_cols_floats(Ci, B, H, W));
    for (size_t i = 0; i < ny; i++) dy0[i] = dy1[i] = (float)sooc_rng_normal(&g_rng);
    sooc_nn_rconv_backward(dx0, dw0, db0, dy0, y0, x, w, cols, dcols, B, 0, B, Ci, H, W, Co, SOOC_NN_ACT_ELU);
    sooc_nn_rconv_backward(dx1, dw1, db1, dy1, y0, x, w, cols, dcols, B, 0, 1, Ci, H, W, Co, SOOC_NN_ACT_ELU);
    sooc_nn_rconv_backward(dx1, dw2, db2, dy1, y0, x, w, cols, dcols, B, 1, B, Ci, H, W, Co, SOOC_NN_ACT_ELU);
    double dwerr = 0, dwmax = 0;   /* relative to the largest gradient (sums with cancellation) */
    for (int i = 0; i < Co * Ci * 9; i++) dwmax = fmax(dwmax, fabs(dw0[i]));
    for (int i = 0; i < Co; i++) dwmax = fmax(dwmax, fabs(db0[i]));
    for (int i = 0; i < Co * Ci * 9; i++) dwerr = fmax(dwerr, fabs(dw1[i] + dw2[i] - dw0[i]) / dwmax);
    for (int i = 0; i < Co; i++) dwerr = fmax(dwerr, fabs(db1[i] + db2[i] - db0[i]) / dwmax);
    CHECK_MSG(!memcmp(dx0, dx1, nx * sizeof(float)), "conv backward: item blocks change the input gradient");
    CHECK_MSG(!memcmp(dy0, dy1, ny * sizeof(float)), "conv backward: item blocks change the pre-activation gradient");
    CHECK_MSG(dwerr < 1e-6, "conv backward: item blocks' weight gradients differ by %.3g (relative)", dwerr);
    printf("  conv backward on item blocks: input gradients %s, weight gradients within %.2g\n",
           !memcmp(dx0, dx1, nx * sizeof(float)) ? "bitwise equal" : "DIFFER", dwerr);
    free(dy0), free(dy1), free(dx0), free(dx1), free(dw0), free(dw1), free(dw2), free(db0), free(db1), free(db2),
        free(dcols);
    printf("  conv item ranges and shared channels: %s\n",
           !memcmp(y0, y1, ny * sizeof(float)) && !memcmp(y0, y2, ny * sizeof(float)) ? "bitwise equal" : "DIFFER");
    free(x), free(w), free(b), free(y0), free(y1), free(y2), free(ysh), free(cols);
}

/* ------------------------------------------------------------------- ELU */
static void elu_fwd(op *o) { sooc_nn_elu_forward_f64(o->y, o->x[0], (int64_t)o->nout); }
static void elu_bwd(op *o, double *dy) { sooc_nn_elu_backward_f64(o->gx[0], dy, o->y, (int64_t)o->nout); }
static void elu_32(op *o, float **x, float *y, float **g, float *dy) {
    sooc_nn_elu_forward(y, x[0], (int64_t)o->nout);
    sooc_nn_elu_backward(g[0], dy, y, (int64_t)o->nout);
}

/* ---------------------------------------------------------- MulMON LN */
typedef struct {
    int nblk;
    int64_t len, ld;
    double st[3];
} mln_c;
static void mln_fwd(op *o) {
    mln_c *c = o->ctx;
    sooc_nn_mln_forward_f64(o->y, c->st, o->x[0], c->nblk, c->len, c->ld);
}
static void mln_bwd(op *o, double *dy) {
    mln_c *c = o->ctx;
    sooc_nn_mln_backward_f64(o->gx[0], dy, o->y, c->st, c->nblk, c->len, c->ld);
}
static void mln_32(op *o, float **x, float *y, float **g, float *dy) {
    mln_c *c = o->ctx;
    float st[3];
    memcpy(y, x[0], o->nout * sizeof(float));   /* the gaps between blocks pass through */
    sooc_nn_mln_forward(y, st, x[0], c->nblk, c->len, c->ld);
    sooc_nn_mln_backward(g[0], dy, y, st, c->nblk, c->len, c->ld);
}
static void test_mln(int nblk, int64_t len, int64_t ld, const char *name) {
    mln_c c = {nblk, len, ld, {0}};
    op o = {.name = name, .nin = 1, .ctx = &c, .fwd = mln_fwd, .bwd = mln_bwd, .run32 = mln_32};
    o.n[0] = o.nout = (size_t)(nblk - 1) * ld + len, o.lo[0] = -0.5, o.hi[0] = 2.0;
    check_op(&o);   /* elements in the gaps: y = 0 (f64 leaves them), gradient 0 */
}
static void mln_fwd_gap(op *o) {
    memset(o->y, 0, o->nout * sizeof(double));
    mln_fwd(o);
}
static void mln_32_gap(op *o, float **x, float *y, float **g, float *dy) {
    mln_c *c = o->ctx;
    float st[3];
    memset(y, 0, o->nout * sizeof(float));
    sooc_nn_mln_forward(y, st, x[0], c->nblk, c->len, c->ld);
    sooc_nn_mln_backward(g[0], dy, y, st, c->nblk, c->len, c->ld);
}

/* ---------------------------------------------------------------- linear */
typedef struct {
    int M, K, N, ldx;
    sooc_nn_act act;
} lin_c;
static void lin_fwd(op *o) {
    lin_c *c = o->ctx;
    sooc_nn_rlinear_forward_f64(o->y, o->x[0], c->ldx, o->x[1], o->x[2], c->M, c->K, c->N, c->act);
}
static void lin_bwd(op *o, double *dy) {
    lin_c *c = o->ctx;
    sooc_nn_rlinear_backward_f64(o->gx[0], o->gx[1], o->gx[2], dy, o->x[0], c->ldx, o->y, o->x[1], c->M, c->K, c->N,
                                 c->act);
}
static void lin_32(op *o, float **x, float *y, float **g, float *dy) {
    lin_c *c = o->ctx;
    sooc_nn_rlinear_forward(y, x[0], c->ldx, x[1], x[2], c->M, c->K, c->N, c->act);
    sooc_nn_rlinear_backward(g[0], g[1], g[2], dy, x[0], c->ldx, y, x[1], c->M, c->K, c->N, c->act);
}
static void test_lin(int M, int K, int N, int ldx, sooc_nn_act act, const char *name) {
    lin_c c = {M, K, N, ldx, act};
    op o = {.name = name, .nin = 3, .ctx = &c, .fwd = lin_fwd, .bwd = lin_bwd, .run32 = lin_32};
    o.n[0] = (size_t)M * ldx, o.lo[0] = -1, o.hi[0] = 1;
    o.n[1] = (size_t)K * N, o.lo[1] = -0.6, o.hi[1] = 0.6;
    o.n[2] = (size_t)N, o.lo[2] = -0.3, o.hi[2] = 0.3;
    o.nout = (size_t)M * N;
    check_op(&o);
}

/* ------------------------------------------------------------------ LSTM */
typedef struct {
    int B, I, G, state;
    double *gates, *c1;
} lstm_c;
/* y = [h1, c1] */
static void lstm_fwd(op *o) {
    lstm_c *c = o->ctx;
    size_t n = (size_t)c->B * c->G;
    sooc_nn_rlstm_forward_f64(o->y, o->y + n, c->gates, o->x[0], c->state ? o->x[1] : NULL, c->state ? o->x[2] : NULL,
                              o->x[3], o->x[4], o->x[5], c->B, c->I, c->G);
}
static void lstm_bwd(op *o, double *dy) {
    lstm_c *c = o->ctx;
    size_t n = (size_t)c->B * c->G;
    sooc_nn_rlstm_backward_f64(o->gx[0], o->gx[1], o->gx[2], o->gx[3], o->gx[4], o->gx[5], dy, dy + n, c->gates, o->y + n,
                               o->x[0], c->state ? o->x[1] : NULL, c->state ? o->x[2] : NULL, o->x[3], o->x[4], c->B,
                               c->I, c->G);
}
static void lstm_32(op *o, float **x, float *y, float **g, float *dy) {
    lstm_c *c = o->ctx;
    size_t n = (size_t)c->B * c->G;
    float *gates = falloc(4 * n), *scr = falloc(4 * n);
    const float *h0 = c->state ? x[1] : NULL, *c0 = c->state ? x[2] : NULL;
    sooc_nn_rlstm_forward(y, y + n, gates, x[0], h0, c0, x[3], x[4], x[5], c->B, c->I, c->G);
    sooc_nn_rlstm_backward(g[0], g[1], g[2], g[3], g[4], g[5], dy, dy + n, scr, gates, y + n, x[0], h0, c0, x[3], x[4],
                           c->B, c->I, c->G);
    free(gates), free(scr);
}
static void test_lstm(int B, int I, int G, int state, const char *name) {
    lstm_c c = {B, I, G, state, NULL, NULL};
    c.gates = dalloc((size_t)4 * B * G);
    op o = {.name = name, .nin = 6, .ctx = &c, .fwd = lstm_fwd, .bwd = lstm_bwd, .run32 = lstm_32};
    size_t n[6] = {(size_t)B * I, (size_t)B * G, (size_t)B * G, (size_t)I * 4 * G, (size_t)G * 4 * G, (size_t)4 * G};
    double s[6] = {1, 0.8, 0.8, 0.5, 0.5, 0.3};
    for (int i = 0; i < 6; i++) o.n[i] = n[i], o.lo[i] = -s[i], o.hi[i] = s[i];
    if (!state) o.nograd[1] = o.nograd[2] = o.nograd[4] = 1;   /* zero state: no h0, c0, no wh gradient */
    o.nout = (size_t)2 * B * G;
    check_op(&o);
    free(c.gates);
}

/* ------------------------------------------------------------- pool2 */
typedef struct {
    int C, B, fh, fw;
} pool_c;
static void pool_fwd(op *o) {
    pool_c *c = o->ctx;
    sooc_nn_pool2_forward_f64(o->y, o->x[0], c->C, c->B, c->fh, c->fw);
}
static void pool_bwd(op *o, double *dy) {
    pool_c *c = o->ctx;
    sooc_nn_pool2_backward_f64(o->gx[0], dy, c->C, c->B, c->fh, c->fw);
}
static void pool_32(op *o, float **x, float *y, float **g, float *dy) {
    pool_c *c = o->ctx;
    sooc_nn_pool2_forward(y, x[0], c->C, c->B, c->fh, c->fw);
    sooc_nn_pool2_backward(g[0], dy, c->C, c->B, c->fh, c->fw);
}
static void test_pool(int C, int B, int fh, int fw, const char *name) {
    pool_c c = {C, B, fh, fw};
    op o = {.name = name, .nin = 1, .ctx = &c, .fwd = pool_fwd, .bwd = pool_bwd, .run32 = pool_32};
    o.n[0] = (size_t)C * B * fh * fw, o.lo[0] = -1, o.hi[0] = 1;
    o.nout = (size_t)B * C * (fh > 2 ? 2 : fh) * (fw > 2 ? 2 : fw);
    check_op(&o);
}

int main(void) {
    sooc_rng_seed(&g_rng, 21, 4);
    printf("test_nn_refine_grad: float64 finite differences and float32 vs float64\n");
    test_conv(3, 4, 6, 8, 5, SOOC_NN_ACT_ELU, "conv 3x3 s2 ELU");
    test_conv(2, 3, 4, 4, 4, SOOC_NN_ACT_NONE, "conv 3x3 s2 linear");
    test_conv(1, 5, 2, 2, 3, SOOC_NN_ACT_ELU, "conv 3x3 s2 ELU 2x2 input");
    test_conv_invariance();
    {
        op o = {.name = "ELU", .nin = 1, .fwd = elu_fwd, .bwd = elu_bwd, .run32 = elu_32};
        o.n[0] = o.nout = 61, o.lo[0] = -4, o.hi[0] = 3;
        check_op(&o);
    }
    test_mln(1, 37, 37, "MulMON LN vector");
    {   /* three strided blocks (one item's channels of a CBHW image); gaps stay 0 */
        mln_c c = {3, 10, 14, {0}};
        op o = {.name = "MulMON LN strided blocks", .nin = 1, .ctx = &c, .fwd = mln_fwd_gap, .bwd = mln_bwd,
                .run32 = mln_32_gap};
        o.n[0] = o.nout = (size_t)2 * 14 + 10, o.lo[0] = -0.5, o.hi[0] = 2.0;
        check_op(&o);
    }
    test_lin(3, 5, 4, 7, SOOC_NN_ACT_ELU, "linear ELU (strided x)");
    test_lin(4, 6, 9, 6, SOOC_NN_ACT_NONE, "linear");
    test_lstm(2, 5, 3, 1, "LSTM cell");
    test_lstm(3, 4, 2, 0, "LSTM cell, zero state");
    test_pool(3, 2, 4, 4, "pool2 4x4 -> 2x2");
    test_pool(2, 3, 2, 2, "pool2 2x2 (flatten only)");
    test_pool(2, 2, 1, 2, "pool2 1x2 (flatten only)");
    return check_report("test_nn_refine_grad");
}
