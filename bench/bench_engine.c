/*
 * bench_engine: forward+backward of the kernels the model runs, against an
 * OpenBLAS sgemm peak and PyTorch on the same shapes, all measured in this run:
 * the decoder MLP as a training step runs it (bench_engine_mlp.c, on the
 * engine's nn/nn_kern.h pairs and task pool, 2 threads) and the
 * refinement conv encoder as src/model/refine.c runs it
 * (bench_engine_conv.c, on the nn/nn_refine.h pairs).
 *
 *   bench_engine [--no-torch] [--reps N]
 *
 * Validates before timing: the MLP forward must match a float64 evaluation.
 * Last line: JSON with mlp_gflops, mlp_vs_sgemm_peak, mlp_vs_torch,
 * conv_vs_torch (and the raw timings).
 */
#include "nn/nn.h"
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
#include "bench_engine_mlp.c"

/* ------------------------------------------------------------------ conv */
#include "bench_engine_conv.c"

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

    /* decoder MLP, as the model runs it */
    bench_mlp_result mr;
    if (bench_mlp_model(g_reps, 2, &rng, &mr)) return 1;
    printf("validate: MLP forward vs float64 on sampled rows: max |diff| = %.3g\n", mr.validate_maxdiff);
    if (!(mr.validate_maxdiff < 1e-4)) { fprintf(stderr, "validation FAILED\n"); return 1; }
    double mlp_ms = mr.ms, mlp_flop = mr.flop;
    double mlp_gf = mlp_flop / (mlp_ms * 1e6);
    printf("mlp fwd+bwd (model's decoder, 2 pool threads): N=%d rows, %.3f GFLOP, %.2f ms, %.1f GFLOP/s (%.0f%% of sgemm peak)\n",
           mr.rows, mlp_flop * 1e-9, mlp_ms, mlp_gf, 100 * mlp_gf / peak);
    printf("  forward %.2f ms (%.1f GFLOP/s), backward %.2f ms (%.1f GFLOP/s)\n", mr.fwd_ms,
           mr.fwd_flop / (mr.fwd_ms * 1e6), mr.bwd_ms, (mlp_flop - mr.fwd_flop) / (mr.bwd_ms * 1e6));

    /* conv encoder, as the model runs it (bench_engine_conv.c) */
    conv_ctx cc;
    conv_setup(&cc, &rng);
    double conv_val = conv_validate(&cc);
    printf("validate: conv encoder forward vs float64: max rel diff %.3g\n", conv_val);
    if (!(conv_val < 1e-4)) { fprintf(stderr, "validation FAILED\n"); return 1; }
    double conv_flop = cc.flop;
    double conv_ms = median_ms(conv_run, &cc);
    printf("conv encoder fwd+bwd (objects K=%d x 26ch, 8 shared, + layout 1 x 25ch, 32x32 -> 64x2x2): %.3f GFLOP, "
           "%.3f ms, %.1f GFLOP/s\n", CV_K, conv_flop * 1e-9, conv_ms, conv_flop / (conv_ms * 1e6));
    printf("  last run: forward %.3f ms, backward %.3f ms\n", 1e3 * g_conv_fwd_s, 1e3 * g_conv_bwd_s);

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
           "\"mlp_fwd_ms\": %.3f, \"mlp_bwd_ms\": %.3f}\n",
           mlp_gf, mlp_gf / peak, a, b2, mlp_ms, conv_ms, c2, d2, peak,
           conv_flop / (conv_ms * 1e6), mr.fwd_ms, mr.bwd_ms);
    return 0;
}
