/*
 * bench_engine: forward+backward of the decoder MLP (model.md 3.3) and the
 * refinement conv encoder (model.md 3.2) on the sooc3d nn engine, against an
 * OpenBLAS sgemm peak and PyTorch on the same shapes, all measured in this run.
 *
 *   bench_engine [--no-torch] [--reps N]
 *
 * Validates before timing: the fused MLP must match the unfused layer-by-layer
 * kernels. Last line: JSON with mlp_gflops, mlp_vs_sgemm_peak, mlp_vs_torch,
 * conv_vs_torch (and the raw timings).
 */
#include "sooc3d/nn.h"
#include <cblas.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef SOOC_SOURCE_DIR
#define SOOC_SOURCE_DIR "."
#endif

static int g_reps = 7;

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static void fmtnum(char *buf, size_t n, double v, const char *fmt) {
    if (isnan(v)) snprintf(buf, n, "null");
    else snprintf(buf, n, fmt, v);
}

typedef void (*bench_fn)(void *);
static double median_ms(bench_fn fn, void *ctx) {
    double t[64];
    fn(ctx); /* warm-up */
    for (int r = 0; r < g_reps; r++) {
        double t0 = sooc_seconds();
        fn(ctx);
        t[r] = (sooc_seconds() - t0) * 1e3;
    }
    qsort(t, (size_t)g_reps, sizeof t[0], cmp_d);
    return t[g_reps / 2];
}

static float *falloc(size_t n) {
    float *p = sooc_malloc(n * sizeof(float));
    if (!p) { fprintf(stderr, "out of memory\n"); exit(1); }
    return p;
}
static void frand(float *p, size_t n, sooc_rng *r, float s) {
    for (size_t i = 0; i < n; i++) p[i] = s * (float)sooc_rng_normal(r);
}

/* ------------------------------------------------------------ sgemm peak */
typedef struct { int n; float *a, *b, *c; } gemm_ctx;
static void gemm_run(void *p) {
    gemm_ctx *g = p;
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, g->n, g->n, g->n, 1.f, g->a, g->n,
                g->b, g->n, 0.f, g->c, g->n);
}

/* ------------------------------------------------------------------- MLP */
enum { K = 8, NK = 8192, N = K * NK, CIN = 33, WID = 64 };
typedef struct {
    sooc_nn_mlp m;
    float *x, *sb, *dsb, *acts, *scratch, *dd, *dc;
    const float *dout[SOOC_NN_MLP_MAX_LAYERS];
} mlp_ctx;

static void mlp_run(void *p) {
    mlp_ctx *c = p;
    sooc_nn_mlp_forward(&c->m, c->acts, c->x, N, c->sb, NK);
    sooc_nn_mlp_backward(&c->m, NULL, c->dsb, c->dout, c->acts, c->x, N, c->sb, NK, c->scratch);
}

/* Unfused variant on the tape: whole-N layer-by-layer kernels, the way a
 * generic autodiff would run it (design comparison for docs/engine.md). */
typedef struct {
    mlp_ctx *m;
    sooc_nn_arena ar;
    sooc_nn_tape *t;
    sooc_nn_tensor *w[6], *b[6];
} tape_ctx;

static void tape_run(void *p) {
    tape_ctx *c = p;
    sooc_nn_tape_reset(c->t);
    sooc_nn_arena_reset(&c->ar);
    int64_t sx[2] = {N, CIN}, ssb[2] = {K, WID}, s3[3] = {K, NK, WID}, s2[2] = {N, WID};
    sooc_nn_tensor *x = sooc_nn_tensor_new(c->t, c->m->x, 2, sx, 0);
    sooc_nn_tensor *sb = sooc_nn_tensor_new(c->t, c->m->sb, 2, ssb, 1);
    sooc_nn_tensor *h = sooc_nn_linear(c->t, x, c->w[0], c->b[0], SOOC_NN_ACT_NONE);
    h = sooc_nn_slot_bias(c->t, sooc_nn_reshape(c->t, h, 3, s3), sb);
    h = sooc_nn_reshape(c->t, sooc_nn_unary(c->t, SOOC_NN_ACT_RELU, h), 2, s2);
    h = sooc_nn_linear(c->t, h, c->w[1], c->b[1], SOOC_NN_ACT_RELU);
    h = sooc_nn_linear(c->t, h, c->w[2], c->b[2], SOOC_NN_ACT_RELU);
    sooc_nn_tensor *d = sooc_nn_linear(c->t, h, c->w[3], c->b[3], SOOC_NN_ACT_SIGMOID);
    sooc_nn_tensor *g = sooc_nn_linear(c->t, h, c->w[4], c->b[4], SOOC_NN_ACT_RELU);
    sooc_nn_tensor *col = sooc_nn_linear(c->t, g, c->w[5], c->b[5], SOOC_NN_ACT_SIGMOID);
    sooc_nn_tape_seed(c->t, d, c->m->dd, 1.f);
    sooc_nn_tape_seed(c->t, col, c->m->dc, 1.f);
    sooc_nn_tape_backward(c->t);
    if (sooc_nn_tape_status(c->t)) { fprintf(stderr, "tape: %s\n", sooc_nn_tape_errmsg(c->t)); exit(1); }
}

/* ------------------------------------------------------------------ conv */
enum { CB = 8, NCONV = 4 };
static const int conv_ci[NCONV] = {26, 32, 32, 64}, conv_co[NCONV] = {32, 32, 64, 64};
static const int conv_hw[NCONV] = {32, 16, 8, 4};
typedef struct {
    float *w[NCONV], *b[NCONV], *dw[NCONV], *db[NCONV];
    float *act[NCONV + 1], *dact[NCONV + 1], *col[NCONV], *scratch, *r;
} conv_ctx;

static void conv_run(void *p) {
    conv_ctx *c = p;
    for (int l = 0; l < NCONV; l++)
        sooc_nn_conv2d_forward(c->act[l + 1], c->col[l], c->scratch, c->act[l], c->w[l], c->b[l],
                               CB, conv_ci[l], conv_hw[l], conv_hw[l], conv_co[l], 2,
                               SOOC_NN_ACT_ELU);
    size_t nout = (size_t)CB * 64 * 2 * 2;
    memcpy(c->dact[NCONV], c->r, nout * sizeof(float)); /* d(sum(y*r))/dy = r */
    for (int l = NCONV - 1; l >= 0; l--) {
        if (l > 0)
            memset(c->dact[l], 0,
                   (size_t)CB * conv_ci[l] * conv_hw[l] * conv_hw[l] * sizeof(float));
        sooc_nn_conv2d_backward(l > 0 ? c->dact[l] : NULL, c->dw[l], c->db[l], c->dact[l + 1],
                                c->col[l], c->scratch, c->act[l + 1], c->w[l], CB, conv_ci[l],
                                conv_hw[l], conv_hw[l], conv_co[l], 2, SOOC_NN_ACT_ELU);
    }
}

int main(int argc, char **argv) {
    int use_torch = 1;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--no-torch")) use_torch = 0;
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) g_reps = atoi(argv[++i]);
        else { fprintf(stderr, "usage: %s [--no-torch] [--reps N]\n", argv[0]); return 2; }
    }
    if (g_reps < 1 || g_reps > 64) g_reps = 7;
    sooc_rng rng;
    sooc_rng_seed(&rng, 1234, 0);

    /* sgemm peak: 2048^3 with OpenBLAS' default threads (2 here) */
    gemm_ctx g = {2048, NULL, NULL, NULL};
    g.a = falloc((size_t)g.n * g.n); g.b = falloc((size_t)g.n * g.n); g.c = falloc((size_t)g.n * g.n);
    frand(g.a, (size_t)g.n * g.n, &rng, 1.f);
    frand(g.b, (size_t)g.n * g.n, &rng, 1.f);
    int blas_thr = sooc_nn_blas_set_threads(2);
    double gemm_ms = median_ms(gemm_run, &g);
    double peak = 2.0 * g.n * (double)g.n * g.n / (gemm_ms * 1e6);
    printf("sgemm %dx%dx%d (%d BLAS threads): %.2f ms  %.1f GFLOP/s\n", g.n, g.n, g.n,
           openblas_get_num_threads(), gemm_ms, peak);
    sooc_nn_blas_set_threads(blas_thr);
    sooc_free(g.a); sooc_free(g.b); sooc_free(g.c);

    /* decoder MLP */
    mlp_ctx mc;
    memset(&mc, 0, sizeof mc);
    static const int src[6] = {-1, 0, 1, 2, 2, 4}, cin[6] = {CIN, WID, WID, WID, WID, 32},
                     cout[6] = {WID, WID, WID, 1, 32, 3};
    static const sooc_nn_act act[6] = {SOOC_NN_ACT_RELU, SOOC_NN_ACT_RELU, SOOC_NN_ACT_RELU,
                                       SOOC_NN_ACT_SIGMOID, SOOC_NN_ACT_RELU, SOOC_NN_ACT_SIGMOID};
    mc.m.n_layers = 6;
    mc.m.c_in = CIN;
    double mac_pt = 0, dx_mac_pt = 0;
    for (int l = 0; l < 6; l++) {
        sooc_nn_mlp_layer *L = &mc.m.layer[l];
        L->src = src[l]; L->c_in = cin[l]; L->c_out = cout[l]; L->act = act[l];
        float *w = falloc((size_t)cin[l] * cout[l]), *b = falloc((size_t)cout[l]);
        sooc_nn_init_uniform(w, (size_t)cin[l] * cout[l], 1.f / sqrtf((float)cin[l]), &rng);
        sooc_nn_init_uniform(b, (size_t)cout[l], 1.f / sqrtf((float)cin[l]), &rng);
        L->w = w; L->b = b;
        L->dw = falloc((size_t)cin[l] * cout[l]); L->db = falloc((size_t)cout[l]);
        memset(L->dw, 0, (size_t)cin[l] * cout[l] * sizeof(float));
        memset(L->db, 0, (size_t)cout[l] * sizeof(float));
        mac_pt += (double)cin[l] * cout[l];
        if (src[l] >= 0) dx_mac_pt += (double)cin[l] * cout[l];
    }
    mc.x = falloc((size_t)N * CIN); frand(mc.x, (size_t)N * CIN, &rng, 1.f);
    mc.sb = falloc((size_t)K * WID); frand(mc.sb, (size_t)K * WID, &rng, 0.1f);
    mc.dsb = falloc((size_t)K * WID); memset(mc.dsb, 0, (size_t)K * WID * sizeof(float));
    mc.acts = falloc(sooc_nn_mlp_act_floats(&mc.m, N));
    mc.scratch = falloc(sooc_nn_mlp_scratch_floats(&mc.m, K));
    mc.dd = falloc((size_t)N); frand(mc.dd, (size_t)N, &rng, 1.f);
    mc.dc = falloc((size_t)N * 3); frand(mc.dc, (size_t)N * 3, &rng, 1.f);
    mc.dout[3] = mc.dd;
    mc.dout[5] = mc.dc;

    /* validate the fused forward against the unfused kernels */
    {
        if (sooc_nn_mlp_forward(&mc.m, mc.acts, mc.x, N, mc.sb, NK)) {
            fprintf(stderr, "mlp forward: %s\n", sooc_errmsg());
            return 1;
        }
        float *h[6];
        for (int l = 0; l < 6; l++) h[l] = falloc((size_t)N * cout[l]);
        for (int l = 0; l < 6; l++) {
            const sooc_nn_mlp_layer *L = &mc.m.layer[l];
            const float *in = src[l] < 0 ? mc.x : h[src[l]];
            sooc_nn_linear_forward(h[l], in, L->w, L->b, N, cin[l], cout[l], SOOC_NN_ACT_NONE);
            if (l == 0) sooc_nn_slot_bias_forward(h[0], h[0], mc.sb, K, NK, WID);
            sooc_nn_unary_forward(act[l] == SOOC_NN_ACT_RELU ? SOOC_NN_ACT_RELU : SOOC_NN_ACT_SIGMOID,
                                  h[l], h[l], (int64_t)N * cout[l]);
        }
        double maxd = 0, sum = 0;
        for (int l = 3; l <= 5; l += 2) {
            const float *o = sooc_nn_mlp_output(&mc.m, mc.acts, N, l);
            for (size_t i = 0; i < (size_t)N * cout[l]; i++) {
                double d = fabs((double)o[i] - h[l][i]);
                if (d > maxd) maxd = d;
                sum += o[i];
            }
        }
        printf("validate: fused vs unfused MLP max |diff| = %.3g, output checksum %.6f\n", maxd, sum);
        for (int l = 0; l < 6; l++) sooc_free(h[l]);
        if (!(maxd < 1e-4)) { fprintf(stderr, "validation FAILED\n"); return 1; }
    }
    double mlp_ms = median_ms(mlp_run, &mc);
    double mlp_flop = 2.0 * N * (2 * mac_pt + dx_mac_pt);
    double mlp_gf = mlp_flop / (mlp_ms * 1e6);
    printf("mlp fwd+bwd: N=%d (K=%d x %d), %.3f GFLOP, %.2f ms, %.1f GFLOP/s (%.0f%% of sgemm peak)\n",
           N, K, NK, mlp_flop * 1e-9, mlp_ms, mlp_gf, 100 * mlp_gf / peak);
    {   /* split forward/backward */
        double t0 = sooc_seconds();
        sooc_nn_mlp_forward(&mc.m, mc.acts, mc.x, N, mc.sb, NK);
        double t1 = sooc_seconds();
        sooc_nn_mlp_backward(&mc.m, NULL, mc.dsb, mc.dout, mc.acts, mc.x, N, mc.sb, NK, mc.scratch);
        double t2 = sooc_seconds();
        printf("  forward %.2f ms (%.1f GFLOP/s), backward %.2f ms (%.1f GFLOP/s)\n", (t1 - t0) * 1e3,
               2.0 * N * mac_pt / ((t1 - t0) * 1e9), (t2 - t1) * 1e3,
               2.0 * N * (mac_pt + dx_mac_pt) / ((t2 - t1) * 1e9));
    }

    /* the same MLP through the tape, unfused */
    double tape_ms;
    {
        tape_ctx tc;
        memset(&tc, 0, sizeof tc);
        tc.m = &mc;
        if (sooc_nn_arena_init(&tc.ar, (size_t)512 << 20) || sooc_nn_tape_create(&tc.t, &tc.ar, 64)) {
            fprintf(stderr, "tape setup: %s\n", sooc_errmsg());
            return 1;
        }
        sooc_nn_tape_reset(tc.t);
        for (int l = 0; l < 6; l++) {
            int64_t sw[2] = {cout[l], cin[l]}, sbb[1] = {cout[l]};
            /* persistent leaf structs: allocate outside the per-run arena */
            tc.w[l] = calloc(1, sizeof(sooc_nn_tensor));
            tc.b[l] = calloc(1, sizeof(sooc_nn_tensor));
            *tc.w[l] = (sooc_nn_tensor){.data = (float *)mc.m.layer[l].w, .grad = mc.m.layer[l].dw,
                                        .ndim = 2, .shape = {sw[0], sw[1]}, .n = sw[0] * sw[1],
                                        .requires_grad = 1, .is_param = 1};
            *tc.b[l] = (sooc_nn_tensor){.data = (float *)mc.m.layer[l].b, .grad = mc.m.layer[l].db,
                                        .ndim = 1, .shape = {sbb[0]}, .n = sbb[0],
                                        .requires_grad = 1, .is_param = 1};
        }
        tape_ms = median_ms(tape_run, &tc);
        printf("mlp fwd+bwd unfused on the tape (whole-N kernels): %.2f ms, %.1f GFLOP/s, arena peak %.1f MB\n",
               tape_ms, mlp_flop / (tape_ms * 1e6), tc.ar.peak / 1048576.0);
        sooc_nn_tape_destroy(tc.t);
        sooc_nn_arena_deinit(&tc.ar);
        for (int l = 0; l < 6; l++) { free(tc.w[l]); free(tc.b[l]); }
    }

    /* conv encoder */
    conv_ctx cc;
    memset(&cc, 0, sizeof cc);
    double conv_flop = 0;
    size_t scr = 0;
    cc.act[0] = falloc((size_t)CB * 26 * 32 * 32);
    frand(cc.act[0], (size_t)CB * 26 * 32 * 32, &rng, 1.f);
    for (int l = 0; l < NCONV; l++) {
        int ci = conv_ci[l], co = conv_co[l], hw = conv_hw[l], ho = hw / 2;
        size_t nw = (size_t)co * ci * 9;
        cc.w[l] = falloc(nw); cc.b[l] = falloc((size_t)co);
        sooc_nn_init_uniform(cc.w[l], nw, 1.f / sqrtf(9.f * ci), &rng);
        sooc_nn_init_uniform(cc.b[l], (size_t)co, 1.f / sqrtf(9.f * ci), &rng);
        cc.dw[l] = falloc(nw); cc.db[l] = falloc((size_t)co);
        memset(cc.dw[l], 0, nw * sizeof(float)); memset(cc.db[l], 0, (size_t)co * sizeof(float));
        cc.act[l + 1] = falloc((size_t)CB * co * ho * ho);
        cc.dact[l + 1] = falloc((size_t)CB * co * ho * ho);
        if (l > 0) cc.dact[l] = cc.dact[l] ? cc.dact[l] : falloc((size_t)CB * ci * hw * hw);
        cc.col[l] = falloc(sooc_nn_conv2d_col_floats(CB, ci, hw, hw, 2));
        size_t s = sooc_nn_conv2d_scratch_floats(CB, ci, hw, hw, co, 2);
        if (s > scr) scr = s;
        double f = 2.0 * CB * ho * ho * co * ci * 9;
        conv_flop += f * (l > 0 ? 3 : 2);
    }
    cc.scratch = falloc(scr);
    cc.r = falloc((size_t)CB * 64 * 4);
    frand(cc.r, (size_t)CB * 64 * 4, &rng, 1.f);
    double conv_ms = median_ms(conv_run, &cc);
    printf("conv encoder fwd+bwd: B=%d 26x32x32 -> 64x2x2, %.3f GFLOP, %.3f ms, %.1f GFLOP/s\n", CB,
           conv_flop * 1e-9, conv_ms, conv_flop / (conv_ms * 1e6));

    double t_mlp = NAN, t_conv = NAN;
    if (use_torch) {
        char cmd[4096];
        snprintf(cmd, sizeof cmd, "/usr/bin/python3 %s/bench/bench_engine_torch.py 2 2>&1",
                 SOOC_SOURCE_DIR);
        FILE *p = popen(cmd, "r");
        char line[1024], last[1024] = "";
        while (p && fgets(line, sizeof line, p)) snprintf(last, sizeof last, "%s", line);
        int rc = p ? pclose(p) : -1;
        const char *a = strstr(last, "\"mlp_ms\":"), *b = strstr(last, "\"conv_ms\":");
        if (rc == 0 && a && b) {
            t_mlp = atof(a + 9);
            t_conv = atof(b + 10);
            printf("torch (2 threads): mlp %.2f ms (%.1f GFLOP/s), conv %.3f ms  [%s]\n", t_mlp,
                   mlp_flop / (t_mlp * 1e6), t_conv, strtok(last, "\n"));
        } else {
            printf("torch reference unavailable (%s): %s\n", cmd, last);
        }
    }
    double vs_torch = t_mlp / mlp_ms, conv_vs = t_conv / conv_ms;
    char a[32], b2[32], c2[32], d2[32];
    fmtnum(a, sizeof a, vs_torch, "%.2f");
    fmtnum(b2, sizeof b2, conv_vs, "%.2f");
    fmtnum(c2, sizeof c2, t_mlp, "%.3f");
    fmtnum(d2, sizeof d2, t_conv, "%.4f");
    printf("{\"mlp_gflops\": %.2f, \"mlp_vs_sgemm_peak\": %.3f, \"mlp_vs_torch\": %s, "
           "\"conv_vs_torch\": %s, \"mlp_ms\": %.3f, \"conv_ms\": %.4f, \"torch_mlp_ms\": %s, "
           "\"torch_conv_ms\": %s, \"sgemm_peak_gflops\": %.1f, \"conv_gflops\": %.2f, "
           "\"mlp_tape_unfused_ms\": %.3f}\n",
           mlp_gf, mlp_gf / peak, a, b2, mlp_ms, conv_ms, c2, d2, peak,
           conv_flop / (conv_ms * 1e6), tape_ms);
    return 0;
}
