/*
 * The decoder MLP part of bench_engine: forward + backward of the object
 * decoder exactly as src/model/decoder.c runs it in a training step, on the
 * engine's kernels (nn/nn_kern.h), at the shipped models' sizes
 * (posenc 33 -> 64 -> 64 -> 64 ReLU, density 64 -> 1 sigmoid, colour
 * 64 -> 32 ReLU -> 3 sigmoid, per-slot bias on layer 1; weights [in x out]):
 *   forward:  blocks of 128 rows through the task pool: slot-bias init,
 *             sooc_nn_dense_forward (ReLU fused), sooc_nn_nerf_tail_forward;
 *   backward: 16 fixed lanes of 256-row blocks through the pool, each with
 *             private weight / slot-bias gradients (reduced in lane order):
 *             sooc_nn_nerf_tail_backward (transposed weights, AVX2 path),
 *             sooc_nn_dense_backward for W1x and d/d(posenc), the slot-bias
 *             sums; the transposed weights are rebuilt every step.
 * Included by bench_engine.c (one translation unit).
 * FLOPs: 2 N mac for the forward and 2 x 2 N mac for the backward (weight and
 * input gradients of every layer), mac = multiply-adds of one row.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "nn/nn_kern.h"

typedef struct bench_mlp_result {
    double ms, fwd_ms, bwd_ms;    /* medians: one training-step forward + backward, and the parts */
    double flop, fwd_flop;        /* FLOPs of a step (forward + backward) and of the forward       */
    double validate_maxdiff;      /* forward against float64 on sampled rows                      */
    int rows;
} bench_mlp_result;

enum { MK = 8, MNK = 8192, MN = MK * MNK, MDIN = 33, MH = 64, MHC = 32, FWD_ROWS = 128, BWD_ROWS = 256, LANES = 16 };

/* parameter slab offsets */
enum { oW1x = 0, oW2 = oW1x + MDIN * MH, ob2 = oW2 + MH * MH, oW3 = ob2 + MH, ob3 = oW3 + MH * MH, oWd = ob3 + MH, obd = oWd + MH,
       oWc1 = obd + 1, obc1 = oWc1 + MH * MHC, oWc2 = obc1 + MHC, obc2 = oWc2 + MHC * 3, NPAR = obc2 + 3 };

typedef struct mlp_ctx {
    sooc_nn_pool *pool;
    float *p, *g, *wt;            /* params, gradients, transposed weights */
    float *sb, *gsb;              /* MK x MH slot bias and its gradient      */
    float *pe, *gpe, *a1, *a2, *a3, *ac, *sig, *col, *dd, *dc;
    float *lane_g;                /* LANES x (NPAR + MK MH) private gradients */
    float *lane_s;                /* LANES x (BWD_ROWS x (3 MH + 4)) scratch */
} mlp_ctx;

static sooc_nn_nerf_tail tail_of(const mlp_ctx *c) {
    const float *p = c->p, *wt = c->wt;
    sooc_nn_nerf_tail t = {MH, MHC, p + oW2, p + ob2, p + oW3, p + ob3, p + oWd, p + obd, p + oWc1, p + obc1, p + oWc2,
                           p + obc2, wt, wt + MH * MH, wt + 2 * MH * MH};
    return t;
}

static void fwd_task(void *ctx, int blk, int tid) {
    mlp_ctx *c = ctx;
    (void)tid;
    int r0 = blk * FWD_ROWS, R = MN - r0 < FWD_ROWS ? MN - r0 : FWD_ROWS;
    for (int r = r0; r < r0 + R; r++) memcpy(c->a1 + (size_t)r * MH, c->sb + (size_t)(r / MNK) * MH, MH * sizeof(float));
    sooc_nn_dense_forward(R, MDIN, MH, c->pe + (size_t)r0 * MDIN, MDIN, c->p + oW1x, NULL, c->a1 + (size_t)r0 * MH, MH, 1,
                          SOOC_NN_EP_RELU);
    sooc_nn_nerf_tail t = tail_of(c);
    sooc_nn_nerf_tail_forward(&t, R, c->a1 + (size_t)r0 * MH, c->a2 + (size_t)r0 * MH, c->a3 + (size_t)r0 * MH,
                              c->ac + (size_t)r0 * MHC, c->sig + r0, c->col + (size_t)r0 * 3, 0);
}

static void bwd_task(void *ctx, int lane, int tid) {
    mlp_ctx *c = ctx;
    (void)tid;
    float *g = c->lane_g + (size_t)lane * (NPAR + MK * MH), *gs = g + NPAR;
    memset(g, 0, sizeof(float) * (NPAR + MK * MH));
    float *gA = c->lane_s + (size_t)lane * BWD_ROWS * (3 * MH + 4), *gB = gA + BWD_ROWS * MH, *gsig = gB + BWD_ROWS * MH,
          *gcol = gsig + BWD_ROWS;
    sooc_nn_nerf_tail t = tail_of(c);
    sooc_nn_nerf_tail_grad tg = {g + oW2, g + ob2, g + oW3, g + ob3, g + oWd, g + obd, g + oWc1, g + obc1, g + oWc2,
                                 g + obc2};
    int nb = (MN + BWD_ROWS - 1) / BWD_ROWS, b0 = nb * lane / LANES, b1 = nb * (lane + 1) / LANES;
    for (int b = b0; b < b1; b++) {
        int r0 = b * BWD_ROWS, R = MN - r0 < BWD_ROWS ? MN - r0 : BWD_ROWS;
        memcpy(gsig, c->dd + r0, sizeof(float) * R);
        memcpy(gcol, c->dc + (size_t)r0 * 3, sizeof(float) * R * 3);
        sooc_nn_nerf_tail_backward(&t, &tg, 1.0f, R, c->a1 + (size_t)r0 * MH, c->a2 + (size_t)r0 * MH,
                                   c->a3 + (size_t)r0 * MH, c->ac + (size_t)r0 * MHC, c->sig + r0,
                                   c->col + (size_t)r0 * 3, gsig, gcol, gA, gB, gB, gA);
        sooc_nn_dense_backward(R, MDIN, MH, gA, MH, c->pe + (size_t)r0 * MDIN, MDIN, c->p + oW1x, c->wt + 2 * MH * MH + MHC * MH,
                               c->gpe + (size_t)r0 * MDIN, MDIN, 0, NULL, g + oW1x, NULL, 1.0f);
        for (int r = 0; r < R; r++) {   /* slot-bias gradient, row order */
            float *restrict d = gs + (size_t)((r0 + r) / MNK) * MH;
            const float *restrict s = gA + (size_t)r * MH;
            for (int j = 0; j < MH; j++) d[j] += s[j];
        }
    }
}

static float *zalloc(size_t n) {
    float *p = sooc_calloc(n, sizeof(float));
    if (!p) {
        fprintf(stderr, "out of memory\n");
        exit(1);
    }
    return p;
}

static void transpose(const float *W, int rows, int cols, float *T) {
    for (int i = 0; i < rows; i++)
        for (int j = 0; j < cols; j++) T[(size_t)j * rows + i] = W[(size_t)i * cols + j];
}

static void mlp_step(mlp_ctx *c) {
    float *wt = c->wt;
    transpose(c->p + oW2, MH, MH, wt);
    transpose(c->p + oW3, MH, MH, wt + MH * MH);
    transpose(c->p + oWc1, MH, MHC, wt + 2 * MH * MH);
    transpose(c->p + oW1x, MDIN, MH, wt + 2 * MH * MH + MHC * MH);
    sooc_nn_pool_run(c->pool, (MN + FWD_ROWS - 1) / FWD_ROWS, fwd_task, c);
    sooc_nn_pool_run(c->pool, LANES, bwd_task, c);
    for (int l = 0; l < LANES; l++) {   /* lane order: deterministic */
        const float *g = c->lane_g + (size_t)l * (NPAR + MK * MH);
        for (int i = 0; i < NPAR; i++) c->g[i] += g[i];
        for (int i = 0; i < MK * MH; i++) c->gsb[i] += g[NPAR + i];
    }
}

/* Forward + backward of the object decoder as a training step runs it, on
 * `threads` pool threads, reps timed runs (<= 64). 0 on success. */
static int bench_mlp_model(int reps, int threads, sooc_rng *rng, bench_mlp_result *res) {
    mlp_ctx c;
    memset(&c, 0, sizeof c);
    if (sooc_nn_pool_create(&c.pool, threads)) {
        fprintf(stderr, "pool: %s\n", sooc_errmsg());
        return 1;
    }
    c.p = zalloc(NPAR), c.g = zalloc(NPAR), c.wt = zalloc((size_t)MH * (2 * MH + MHC + MDIN));
    c.sb = zalloc((size_t)MK * MH), c.gsb = zalloc((size_t)MK * MH);
    c.pe = zalloc((size_t)MN * MDIN), c.gpe = zalloc((size_t)MN * MDIN);
    c.a1 = zalloc((size_t)MN * MH), c.a2 = zalloc((size_t)MN * MH), c.a3 = zalloc((size_t)MN * MH);
    c.ac = zalloc((size_t)MN * MHC), c.sig = zalloc(MN), c.col = zalloc((size_t)MN * 3);
    c.dd = zalloc(MN), c.dc = zalloc((size_t)MN * 3);
    c.lane_g = zalloc((size_t)LANES * (NPAR + MK * MH));
    c.lane_s = zalloc((size_t)LANES * BWD_ROWS * (3 * MH + 4));
    static const int fan[][3] = {{oW1x, MDIN * MH, MDIN}, {oW2, MH * MH + MH, MH}, {oW3, MH * MH + MH, MH},
                                 {oWd, MH + 1, MH},      {oWc1, MH * MHC + MHC, MH}, {oWc2, MHC * 3 + 3, MHC}};
    for (size_t l = 0; l < sizeof fan / sizeof fan[0]; l++) {
        float s = 1.0f / sqrtf((float)fan[l][2]);
        for (int i = 0; i < fan[l][1]; i++) c.p[fan[l][0] + i] = s * (2 * sooc_rng_uniformf(rng) - 1);
    }
    for (int i = 0; i < MK * MH; i++) c.sb[i] = 0.1f * (float)sooc_rng_normal(rng);
    for (size_t i = 0; i < (size_t)MN * MDIN; i++) c.pe[i] = (float)sooc_rng_normal(rng);
    for (int i = 0; i < MN; i++) c.dd[i] = (float)sooc_rng_normal(rng);
    for (size_t i = 0; i < (size_t)MN * 3; i++) c.dc[i] = (float)sooc_rng_normal(rng);

    /* validate one forward against a float64 evaluation of a few rows */
    mlp_step(&c);
    double maxd = 0;
    for (int r = 0; r < MN; r += 4099) {
        double a[MH], b[MH], h3[MH], hc[MHC];
        for (int j = 0; j < MH; j++) {
            double s = c.sb[(r / MNK) * MH + j];
            for (int i = 0; i < MDIN; i++) s += (double)c.pe[(size_t)r * MDIN + i] * c.p[oW1x + i * MH + j];
            a[j] = s > 0 ? s : 0;
        }
        for (int j = 0; j < MH; j++) {
            double s = c.p[ob2 + j];
            for (int i = 0; i < MH; i++) s += a[i] * c.p[oW2 + i * MH + j];
            b[j] = s > 0 ? s : 0;
        }
        for (int j = 0; j < MH; j++) {
            double s = c.p[ob3 + j];
            for (int i = 0; i < MH; i++) s += b[i] * c.p[oW3 + i * MH + j];
            h3[j] = s > 0 ? s : 0;
        }
        double sd = c.p[obd];
        for (int i = 0; i < MH; i++) sd += h3[i] * c.p[oWd + i];
        maxd = fmax(maxd, fabs(1 / (1 + exp(-sd)) - c.sig[r]));
        for (int j = 0; j < MHC; j++) {
            double s = c.p[obc1 + j];
            for (int i = 0; i < MH; i++) s += h3[i] * c.p[oWc1 + i * MHC + j];
            hc[j] = s > 0 ? s : 0;
        }
        for (int q = 0; q < 3; q++) {
            double s = c.p[obc2 + q];
            for (int i = 0; i < MHC; i++) s += hc[i] * c.p[oWc2 + i * 3 + q];
            maxd = fmax(maxd, fabs(1 / (1 + exp(-s)) - c.col[(size_t)r * 3 + q]));
        }
    }
    res->validate_maxdiff = maxd;

    double t[64], tf[64], tb[64];
    for (int r = 0; r < reps; r++) {
        double t0 = sooc_seconds();
        mlp_step(&c);
        t[r] = (sooc_seconds() - t0) * 1e3;
        /* split (not part of the ratio) */
        t0 = sooc_seconds();
        sooc_nn_pool_run(c.pool, (MN + FWD_ROWS - 1) / FWD_ROWS, fwd_task, &c);
        double t1 = sooc_seconds();
        sooc_nn_pool_run(c.pool, LANES, bwd_task, &c);
        tf[r] = (t1 - t0) * 1e3, tb[r] = (sooc_seconds() - t1) * 1e3;
    }
    qsort(t, (size_t)reps, sizeof t[0], cmp_d);
    qsort(tf, (size_t)reps, sizeof t[0], cmp_d);
    qsort(tb, (size_t)reps, sizeof t[0], cmp_d);
    /* multiply-adds per row: forward all layers; backward the weight gradients of
     * every layer and the input gradients of every layer (layer 1's is d/d(posenc)) */
    double mac = (double)MDIN * MH + 2.0 * MH * MH + MH + (double)MH * MHC + MHC * 3;
    res->ms = t[reps / 2];
    res->fwd_ms = tf[reps / 2];
    res->bwd_ms = tb[reps / 2];
    res->flop = 2.0 * MN * 3 * mac;
    res->fwd_flop = 2.0 * MN * mac;
    res->rows = MN;
    sooc_nn_pool_destroy(c.pool);
    float *bufs[] = {c.p, c.g, c.wt, c.sb, c.gsb, c.pe, c.gpe, c.a1, c.a2, c.a3, c.ac, c.sig, c.col, c.dd, c.dc,
                     c.lane_g, c.lane_s};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++) sooc_free(bufs[i]);
    return 0;
}
