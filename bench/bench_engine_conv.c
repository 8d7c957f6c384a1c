/*
 * bench_engine part (included by bench_engine.c): the refinement conv encoder
 * as the model runs it (src/model/refine.c on the nn/nn_refine.h pairs):
 * the object net on K = 7 items (26 input channels, the first 8 shared by
 * every item and stored once) and the layout net on 1 item (25 channels), a
 * 32 x 32 ray grid, 3x3 stride-2 convs 32, 32, 64, 64 with ELU;
 *   forward: the shared channels' share once, then every item's four layers
 *            as one task of a 2-thread sooc_nn_pool (the model's pool tasks);
 *   backward: per net, layers 3..0 on two fixed item blocks as pool tasks (the
 *            second block's weight gradients private, added afterwards; the
 *            one-item layout net serial), no input gradient at layer 0.
 * The PyTorch twin (bench_engine_torch.py "conv") runs the same two nets.
 */
#include "nn/nn_kern.h"
#include "nn/nn_refine.h"

enum { CV_K = 7, CV_G = 32, CV_NSH = 8, CV_NL = 4 };
static const int cv_ch[CV_NL] = {32, 32, 64, 64};

typedef struct conv_net {
    int B, cin, nsh;
    float *w[CV_NL], *b[CV_NL], *dw[CV_NL], *db[CV_NL];
    float *x0, *y[CV_NL], *dy[CV_NL], *r, *ysh;
} conv_net;

typedef struct conv_ctx {
    conv_net net[2];          /* 0 objects, 1 layout */
    float *cols, *gcols;      /* forward: a slice per thread; backward: a slice per item */
    size_t cstride, per_item;
    float *gpriv[CV_NL], *gbpriv[CV_NL];   /* the second block's weight gradients */
    sooc_nn_pool *pool;
    int bwd_net;
    double flop;
} conv_ctx;

static void conv_item_fwd(conv_net *n, int b, float *cols) {
    const float *x = n->x0;
    int Ci = n->cin, H = CV_G;
    for (int i = 0; i < CV_NL; i++) {
        int sh = i == 0 && n->ysh ? n->nsh : 0;
        sooc_nn_rconv_forward(n->y[i], cols, x, n->w[i], n->b[i], sh ? n->ysh : NULL, sh, n->B, b, b + 1, Ci, H, H,
                              cv_ch[i], SOOC_NN_ACT_ELU);
        x = n->y[i], Ci = cv_ch[i], H /= 2;
    }
}

static void conv_fwd_task(void *ctx, int t, int tid) {
    conv_ctx *c = ctx;   /* the layout item first (the costliest), as the model */
    conv_net *n = t == 0 ? &c->net[1] : &c->net[0];
    conv_item_fwd(n, t == 0 ? 0 : t - 1, c->cols + (size_t)tid * c->cstride);
}

static void conv_bwd_task(void *ctx, int q, int tid) {
    conv_ctx *c = ctx;
    conv_net *n = &c->net[c->bwd_net];
    int nblk = n->B >= 2 ? 2 : 1, b0 = q == 0 ? 0 : (n->B + 1) / 2, b1 = nblk == 1 || q == 1 ? n->B : (n->B + 1) / 2;
    (void)tid;
    for (int i = CV_NL - 1; i >= 0; i--) {
        int Hi = CV_G >> i, Ci = i ? cv_ch[i - 1] : n->cin;
        float *gx = NULL;
        if (i > 0) {
            gx = n->dy[i - 1];
            size_t hw = (size_t)Hi * Hi;
            for (int ch = 0; ch < Ci; ch++) memset(gx + ((size_t)ch * n->B + b0) * hw, 0, sizeof(float) * (b1 - b0) * hw);
        }
        sooc_nn_rconv_backward(gx, q ? c->gpriv[i] : n->dw[i], q ? c->gbpriv[i] : n->db[i], n->dy[i], n->y[i],
                               i ? n->y[i - 1] : n->x0, n->w[i], c->cols + c->per_item * b0,
                               c->gcols + c->per_item * b0, n->B, b0, b1, Ci, Hi, Hi, cv_ch[i], SOOC_NN_ACT_ELU);
    }
}

static double g_conv_fwd_s, g_conv_bwd_s;   /* of the last run */

static void conv_run(void *p) {
    conv_ctx *c = p;
    conv_net *no = &c->net[0];
    double t0 = sooc_seconds();
    sooc_nn_rconv_shared(no->ysh, c->cols, no->x0, no->w[0], no->B, no->cin, CV_G, CV_G, cv_ch[0], no->nsh);
    sooc_nn_pool_run(c->pool, c->net[0].B + c->net[1].B, conv_fwd_task, c);
    double t1 = sooc_seconds();
    for (int q = 0; q < 2; q++) {
        conv_net *n = &c->net[q];
        size_t HW = (size_t)CV_G * CV_G;
        for (int ch = 0; ch < n->nsh; ch++)   /* the model's backward fills the shared channels' copies */
            for (int b = 1; b < n->B; b++) memcpy(n->x0 + ((size_t)ch * n->B + b) * HW, n->x0 + (size_t)ch * n->B * HW, HW * 4);
        int H3 = CV_G >> 4, nblk = n->B >= 2 ? 2 : 1, prev = n->cin;
        memcpy(n->dy[3], n->r, sizeof(float) * (size_t)cv_ch[3] * n->B * H3 * H3);
        if (nblk == 2)
            for (int i = 0; i < CV_NL; i++) {
                memset(c->gpriv[i], 0, sizeof(float) * (size_t)cv_ch[i] * prev * 9);
                memset(c->gbpriv[i], 0, sizeof(float) * (size_t)cv_ch[i]);
                prev = cv_ch[i];
            }
        c->bwd_net = q;
        sooc_nn_pool_run(c->pool, nblk, conv_bwd_task, c);
        prev = n->cin;
        for (int i = 0; nblk == 2 && i < CV_NL; i++) {
            for (size_t k = 0; k < (size_t)cv_ch[i] * prev * 9; k++) n->dw[i][k] += c->gpriv[i][k];
            for (int k = 0; k < cv_ch[i]; k++) n->db[i][k] += c->gbpriv[i][k];
            prev = cv_ch[i];
        }
    }
    g_conv_fwd_s = t1 - t0, g_conv_bwd_s = sooc_seconds() - t1;
}

static void conv_setup(conv_ctx *c, sooc_rng *rng) {
    memset(c, 0, sizeof *c);
    size_t colmax = 0;
    for (int q = 0; q < 2; q++) {
        conv_net *n = &c->net[q];
        n->B = q ? 1 : CV_K, n->cin = q ? 25 : 26, n->nsh = q ? 0 : CV_NSH;
        size_t HW = (size_t)CV_G * CV_G;
        n->x0 = falloc((size_t)n->cin * n->B * HW);
        frand(n->x0, (size_t)n->cin * n->B * HW, rng, 1.f);
        int prev = n->cin;
        for (int i = 0; i < CV_NL; i++) {
            int Hi = CV_G >> i, Ho = Hi / 2;
            size_t nw = (size_t)cv_ch[i] * prev * 9, ny = (size_t)cv_ch[i] * n->B * Ho * Ho;
            n->w[i] = falloc(nw), n->b[i] = falloc((size_t)cv_ch[i]);
            sooc_nn_init_uniform(n->w[i], nw, 1.f / sqrtf(9.f * prev), rng);
            sooc_nn_init_uniform(n->b[i], (size_t)cv_ch[i], 1.f / sqrtf(9.f * prev), rng);
            n->dw[i] = falloc(nw), n->db[i] = falloc((size_t)cv_ch[i]);
            memset(n->dw[i], 0, nw * 4), memset(n->db[i], 0, (size_t)cv_ch[i] * 4);
            n->y[i] = falloc(ny), n->dy[i] = falloc(ny);
            size_t cs = sooc_nn_rconv_cols_floats(prev, n->B, Hi, Hi), c1 = sooc_nn_rconv_cols_floats(prev, 1, Hi, Hi);
            if (cs > colmax) colmax = cs;
            if (c1 > c->cstride) c->cstride = c1;
            /* multiply-adds: forward (objects: the shared channels once), weight grads, input grads (not layer 0) */
            double mac = (double)cv_ch[i] * 9 * Ho * Ho;
            double fwd = i == 0 && n->nsh ? mac * (n->nsh + (double)(prev - n->nsh) * n->B) : mac * prev * n->B;
            c->flop += 2 * (fwd + mac * prev * n->B * (i > 0 ? 2 : 1));
            prev = cv_ch[i];
        }
        n->r = falloc((size_t)cv_ch[3] * n->B * 4);
        frand(n->r, (size_t)cv_ch[3] * n->B * 4, rng, 1.f);
        n->ysh = n->nsh ? falloc((size_t)cv_ch[0] * (CV_G / 2) * (CV_G / 2)) : NULL;
    }
    if (2 * c->cstride > colmax) colmax = 2 * c->cstride;
    c->per_item = colmax / CV_K;
    c->cols = falloc(colmax);
    c->gcols = falloc(colmax);
    int prev = 26;
    for (int i = 0; i < CV_NL; i++) {
        c->gpriv[i] = falloc((size_t)cv_ch[i] * prev * 9), c->gbpriv[i] = falloc((size_t)cv_ch[i]);
        prev = cv_ch[i];
    }
    if (sooc_nn_pool_create(&c->pool, 2)) {
        fprintf(stderr, "pool: %s\n", sooc_errmsg());
        exit(1);
    }
}

/* The forward must match a float64 evaluation of the same nets (sampled outputs). */
static double conv_validate(conv_ctx *c) {
    conv_run(c);
    double worst = 0;
    for (int q = 0; q < 2; q++) {
        conv_net *n = &c->net[q];
        size_t HW = (size_t)CV_G * CV_G, nx = (size_t)n->cin * n->B * HW;
        double *x = malloc(nx * sizeof(double)), *w = NULL, *b = NULL, *y = NULL;
        for (size_t i = 0; i < nx; i++) x[i] = n->x0[i];
        int prev = n->cin;
        for (int i = 0; i < CV_NL; i++) {
            int Hi = CV_G >> i, Ho = Hi / 2;
            size_t nw = (size_t)cv_ch[i] * prev * 9, ny = (size_t)cv_ch[i] * n->B * Ho * Ho;
            w = realloc(w, nw * sizeof(double)), b = realloc(b, (size_t)cv_ch[i] * sizeof(double));
            y = malloc(ny * sizeof(double));
            for (size_t j = 0; j < nw; j++) w[j] = n->w[i][j];
            for (int j = 0; j < cv_ch[i]; j++) b[j] = n->b[i][j];
            sooc_nn_rconv_forward_f64(y, x, w, b, n->B, prev, Hi, Hi, cv_ch[i], SOOC_NN_ACT_ELU);
            for (size_t j = 0; j < ny; j++) worst = fmax(worst, fabs(y[j] - n->y[i][j]) / (1.0 + fabs(y[j])));
            free(x);
            x = y;
            prev = cv_ch[i];
        }
        free(x), free(w), free(b);
    }
    return worst;
}
