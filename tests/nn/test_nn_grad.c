/*
 * Finite-difference gradient check for every nn op (through the tape, which
 * calls the kernel pairs). The decoder MLP kernels the model runs are
 * checked in test_nn_nerf.c.
 *
 * Loss L = sum(out * r) with a fixed random r, evaluated in double from the
 * float32 output. Numeric derivative: 4-point central difference
 *   (8(f(x+h/2) - f(x-h/2)) - (f(x+h) - f(x-h))) / (6h)
 * with h = 1e-2 * max(1, |x|) (float32 forward, so h cannot be tiny).
 * Pass if |ga - gn| <= ATOL + RTOL * max(|ga|, |gn|); the worst element per
 * op is printed. Kinks (ReLU at 0, |x| for ...): an element is skipped and
 * counted when the two one-sided differences disagree (the stencil crossed a
 * kink); ops with a kink (ReLU) may skip up to 10% of their elements,
 * smooth ops none.
 */
#include "check.h"
#include "nn/nn.h"
#include "nn/nn_impl.h" /* sooc_nn_sgemm (internal) */
#include <math.h>
#include <stdio.h>
#include <string.h>
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

#define ATOL 2e-3
#define RTOL 1e-2
#define MAXIN 8

static sooc_nn_arena g_arena;
static sooc_nn_tape *g_tape;
static sooc_rng g_rng;

typedef sooc_nn_tensor *(*op_fn)(sooc_nn_tape *t, sooc_nn_tensor **in, void *ctx);

typedef struct gc_input {
    int ndim;
    int64_t shape[4];
    float lo, hi;     /* uniform init range */
    int no_grad;      /* input without gradient */
    float *data;      /* filled by the harness */
    float *grad;
    int64_t n;
} gc_input;

static double eval_loss(op_fn f, gc_input *in, int n_in, void *ctx, const float *r, int64_t *nout) {
    sooc_nn_tape_reset(g_tape);
    sooc_nn_arena_reset(&g_arena);
    sooc_nn_tensor *ts[MAXIN];
    for (int i = 0; i < n_in; i++)
        ts[i] = sooc_nn_tensor_new(g_tape, in[i].data, in[i].ndim, in[i].shape, !in[i].no_grad);
    sooc_nn_tensor *y = f(g_tape, ts, ctx);
    if (!y) {
        fprintf(stderr, "op failed: %s\n", sooc_nn_tape_errmsg(g_tape));
        return NAN;
    }
    if (nout) *nout = y->n;
    double L = 0;
    if (r)
        for (int64_t i = 0; i < y->n; i++) L += (double)y->data[i] * r[i];
    return L;
}

static float g_r[1 << 16];
/* Fraction of elements that may be skipped as kink crossings: 0 for smooth
 * ops (a "kink" there would be a bug), small for ReLU ops. */
static double g_kink_frac = 0.0;

static int gradcheck(const char *name, op_fn f, gc_input *in, int n_in, void *ctx) {
    for (int i = 0; i < n_in; i++) {
        in[i].n = 1;
        for (int d = 0; d < in[i].ndim; d++) in[i].n *= in[i].shape[d];
        in[i].data = sooc_malloc((size_t)in[i].n * sizeof(float));
        in[i].grad = sooc_calloc((size_t)in[i].n, sizeof(float));
        for (int64_t e = 0; e < in[i].n; e++)
            in[i].data[e] = in[i].lo + (in[i].hi - in[i].lo) * sooc_rng_uniformf(&g_rng);
    }
    int64_t nout = 0;
    eval_loss(f, in, n_in, ctx, NULL, &nout);
    SOOC_ASSERT(nout <= (int64_t)(sizeof g_r / sizeof g_r[0]));
    for (int64_t i = 0; i < nout; i++) g_r[i] = (float)(2 * sooc_rng_uniform(&g_rng) - 1);
    /* analytic */
    {
        sooc_nn_tape_reset(g_tape);
        sooc_nn_arena_reset(&g_arena);
        sooc_nn_tensor *ts[MAXIN];
        for (int i = 0; i < n_in; i++)
            ts[i] = sooc_nn_tensor_new(g_tape, in[i].data, in[i].ndim, in[i].shape, !in[i].no_grad);
        sooc_nn_tensor *y = f(g_tape, ts, ctx);
        CHECK_OK(sooc_nn_tape_status(g_tape));
        if (!y) return 1;
        CHECK_OK(sooc_nn_tape_seed(g_tape, y, g_r, 1.f));
        CHECK_OK(sooc_nn_tape_backward(g_tape));
        for (int i = 0; i < n_in; i++)
            if (ts[i]->grad) memcpy(in[i].grad, ts[i]->grad, (size_t)in[i].n * sizeof(float));
    }
    double worst = -1, wa = 0, wn = 0;
    int wi = -1;
    int64_t we = -1, n_checked = 0, n_skipped = 0, n_bad = 0;
    for (int i = 0; i < n_in; i++) {
        if (in[i].no_grad) continue;
        for (int64_t e = 0; e < in[i].n; e++) {
            float x0 = in[i].data[e];
            float h = 1e-2f * (fabsf(x0) > 1.f ? fabsf(x0) : 1.f);
            double fv[4];
            float xs[4] = {x0 + h, x0 - h, x0 + h / 2, x0 - h / 2};
            for (int k = 0; k < 4; k++) {
                in[i].data[e] = xs[k];
                fv[k] = eval_loss(f, in, n_in, ctx, g_r, NULL);
            }
            in[i].data[e] = x0;
            double f0 = eval_loss(f, in, n_in, ctx, g_r, NULL);
            double hp = (double)xs[0] - x0, hm = (double)x0 - xs[1];
            double hh = ((double)xs[0] - xs[1]) / 2;
            double gn = (8 * (fv[2] - fv[3]) - (fv[0] - fv[1])) / (6 * hh);
            double right = (fv[0] - f0) / hp, left = (f0 - fv[1]) / hm;
            double ga = in[i].grad[e];
            double sc = fmax(fabs(right), fabs(left));
            /* kink: one-sided slopes disagree beyond curvature-level noise */
            double mid_r = (fv[2] - f0) / ((double)xs[2] - x0), mid_l = (f0 - fv[3]) / ((double)x0 - xs[3]);
            int kink = fabs(right - left) > 20 * fabs(mid_r - mid_l) + 1e-3 + 0.05 * sc &&
                       fabs(right - left) > 0.05 * sc + 2e-3;
            if (!isfinite(ga) || !isfinite(gn)) { n_bad++; continue; }
            if (kink) { n_skipped++; continue; }
            n_checked++;
            double err = fabs(ga - gn), tol = ATOL + RTOL * fmax(fabs(ga), fabs(gn));
            double ratio = err / tol;
            if (ratio > worst) { worst = ratio; wi = i; we = e; wa = ga; wn = gn; }
            if (err > tol) n_bad++;
        }
    }
    int ok = n_bad == 0 && (double)n_skipped <= g_kink_frac * (double)(n_checked + n_skipped);
    printf("%-28s %s checked %5lld skipped(kink) %3lld  worst err/tol %.3f at in%d[%lld] "
           "analytic %.6g numeric %.6g\n",
           name, ok ? "ok  " : "FAIL", (long long)n_checked, (long long)n_skipped, worst, wi,
           (long long)we, wa, wn);
    CHECK_MSG(ok, "%s gradient check", name);
    for (int i = 0; i < n_in; i++) { sooc_free(in[i].data); sooc_free(in[i].grad); }
    return ok;
}

/* ----------------------------------------------------------- op closures */

static sooc_nn_tensor *f_linear(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    return sooc_nn_linear(t, x[0], x[1], x[2], *(sooc_nn_act *)c);
}
static sooc_nn_tensor *f_linear_nob(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c;
    return sooc_nn_linear(t, x[0], x[1], NULL, SOOC_NN_ACT_NONE);
}
static sooc_nn_tensor *f_slot_bias(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c;
    return sooc_nn_slot_bias(t, x[0], x[1]);
}
static sooc_nn_tensor *f_unary(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    return sooc_nn_unary(t, *(sooc_nn_act *)c, x[0]);
}
static sooc_nn_tensor *f_binary(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    return sooc_nn_binary(t, *(sooc_nn_binop *)c, x[0], x[1]);
}
static sooc_nn_tensor *f_affine(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c;
    return sooc_nn_affine(t, x[0], -1.7f, 0.3f);
}
static sooc_nn_tensor *f_concat(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    return sooc_nn_concat(t, x, 3, *(int *)c);
}
static sooc_nn_tensor *f_slice(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    return sooc_nn_slice(t, x[0], *(int *)c, 1, 2);
}
static const int32_t g_idx[7] = {2, 0, 2, 4, 1, 2, 3};
static sooc_nn_tensor *f_gather(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c;
    return sooc_nn_gather(t, x[0], g_idx, 7);
}
static sooc_nn_tensor *f_scatter(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c;
    return sooc_nn_scatter_add(t, x[0], g_idx, 6);
}
static sooc_nn_tensor *f_sum(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    return sooc_nn_sum(t, x[0], *(int *)c);
}
static sooc_nn_tensor *f_mean(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    return sooc_nn_mean(t, x[0], *(int *)c);
}
static sooc_nn_tensor *f_ln(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    int learn = *(int *)c;
    return sooc_nn_layernorm(t, x[0], learn ? x[1] : NULL, learn ? x[2] : NULL, 1e-5f);
}
static sooc_nn_tensor *f_ln_chw(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c; /* MulMON LN over (C,H,W) per slot: reshape [K,C,H,W] -> [K, CHW] */
    int64_t s2[2] = {x[0]->shape[0], x[0]->n / x[0]->shape[0]};
    sooc_nn_tensor *r = sooc_nn_reshape(t, x[0], 2, s2);
    sooc_nn_tensor *y = sooc_nn_layernorm(t, r, NULL, NULL, 1e-5f);
    return sooc_nn_reshape(t, y, 4, x[0]->shape);
}
static sooc_nn_tensor *f_posenc(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c;
    return sooc_nn_posenc(t, x[0], 5);
}
static sooc_nn_tensor *f_stopgrad(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c; /* y = x0 * SG(x1): gradient to x1 must be zero */
    return sooc_nn_binary(t, SOOC_NN_MUL, x[0], sooc_nn_stop_grad(t, x[1]));
}
static sooc_nn_tensor *f_reshape(sooc_nn_tape *t, sooc_nn_tensor **x, void *c) {
    (void)c;
    int64_t s[2] = {3, 8};
    return sooc_nn_unary(t, SOOC_NN_ACT_TANH, sooc_nn_reshape(t, x[0], 2, s));
}

#define IN(nd, a, b, c_, d, lo_, hi_) {nd, {a, b, c_, d}, lo_, hi_, 0, NULL, NULL, 0}

static void test_stopgrad_zero(void) {
    /* the SG input must get exactly zero gradient */
    float a[4] = {1, 2, 3, 4}, b[4] = {5, 6, 7, 8};
    int64_t s[1] = {4};
    sooc_nn_tape_reset(g_tape);
    sooc_nn_arena_reset(&g_arena);
    sooc_nn_tensor *ta = sooc_nn_tensor_new(g_tape, a, 1, s, 1);
    sooc_nn_tensor *tb = sooc_nn_tensor_new(g_tape, b, 1, s, 1);
    sooc_nn_tensor *y = sooc_nn_binary(g_tape, SOOC_NN_MUL, ta, sooc_nn_stop_grad(g_tape, tb));
    CHECK_OK(sooc_nn_tape_seed(g_tape, y, NULL, 1.f));
    CHECK_OK(sooc_nn_tape_backward(g_tape));
    CHECK(tb->grad == NULL);
    CHECK(ta->grad && ta->grad[2] == 7.f);
}

/* the fixed-block parallel sgemm against a naive double product, all
 * transpose combinations, split along M and along N, beta 0 and 1 */
static void test_sgemm_blocks(void) {
    int dims[2][3] = {{300, 40, 200}, {24, 900, 200}}; /* M, N, K: split M / split N */
    double worst = 0;
    for (int d = 0; d < 2; d++)
        for (int ta = 0; ta < 2; ta++)
            for (int tb = 0; tb < 2; tb++)
                for (int beta = 0; beta < 2; beta++) {
                    int M = dims[d][0], N = dims[d][1], K = dims[d][2];
                    int lda = ta ? M : K, ldb = tb ? K : N;
                    float *A = sooc_malloc(sizeof(float) * M * K), *B = sooc_malloc(sizeof(float) * K * N);
                    float *C = sooc_malloc(sizeof(float) * M * N);
                    for (int i = 0; i < M * K; i++) A[i] = (float)sooc_rng_normal(&g_rng);
                    for (int i = 0; i < K * N; i++) B[i] = (float)sooc_rng_normal(&g_rng);
                    for (int i = 0; i < M * N; i++) C[i] = (float)sooc_rng_normal(&g_rng);
                    double *R = sooc_malloc(sizeof(double) * M * N);
                    for (int i = 0; i < M; i++)
                        for (int j = 0; j < N; j++) {
                            double acc = beta ? C[i * N + j] : 0.0;
                            for (int k = 0; k < K; k++)
                                acc += 0.5 * (double)(ta ? A[k * lda + i] : A[i * lda + k]) *
                                       (double)(tb ? B[j * ldb + k] : B[k * ldb + j]);
                            R[i * N + j] = acc;
                        }
                    sooc_nn_sgemm(ta, tb, M, N, K, 0.5f, A, lda, B, ldb, (float)beta, C, N);
                    for (int i = 0; i < M * N; i++) {
                        double e = fabs(C[i] - R[i]) / (1e-4 + 1e-5 * fabs(R[i]));
                        if (e > worst) worst = e;
                    }
                    sooc_free(A); sooc_free(B); sooc_free(C); sooc_free(R);
                }
    printf("%-28s %s worst err/tol %.3f (tol 1e-4 + 1e-5|ref|)\n", "sgemm fixed blocks",
           worst <= 1 ? "ok  " : "FAIL", worst);
    CHECK_MSG(worst <= 1, "sooc_nn_sgemm worst %.3g", worst);
}

int main(void) {
    CHECK_OK(sooc_nn_arena_init(&g_arena, (size_t)64 << 20));
    CHECK_OK(sooc_nn_tape_create(&g_tape, &g_arena, 256));
    sooc_rng_seed(&g_rng, 42, 0);

    static const sooc_nn_act acts[] = {SOOC_NN_ACT_NONE, SOOC_NN_ACT_RELU, SOOC_NN_ACT_ELU,
                                       SOOC_NN_ACT_SIGMOID, SOOC_NN_ACT_TANH};
    static const char *act_names[] = {"none", "relu", "elu", "sigmoid", "tanh"};
    for (int a = 0; a < 5; a++) {
        char nm[64];
        snprintf(nm, sizeof nm, "linear+%s", act_names[a]);
        gc_input in[3] = {IN(3, 2, 5, 6, 0, -1, 1), IN(2, 4, 6, 0, 0, -0.5f, 0.5f), IN(1, 4, 0, 0, 0, -0.5f, 0.5f)};
        g_kink_frac = acts[a] == SOOC_NN_ACT_RELU ? 0.1 : 0.0;
        gradcheck(nm, f_linear, in, 3, (void *)&acts[a]);
        g_kink_frac = 0.0;
    }
    {
        gc_input in[2] = {IN(2, 9, 5, 0, 0, -1, 1), IN(2, 3, 5, 0, 0, -1, 1)};
        gradcheck("linear (no bias)", f_linear_nob, in, 2, NULL);
    }
    {
        gc_input in[2] = {IN(3, 3, 4, 5, 0, -1, 1), IN(2, 3, 5, 0, 0, -1, 1)};
        gradcheck("slot_bias [K,N,C]+[K,C]", f_slot_bias, in, 2, NULL);
    }
    static const sooc_nn_act un[] = {SOOC_NN_ACT_RELU, SOOC_NN_ACT_ELU, SOOC_NN_ACT_SIGMOID,
                                     SOOC_NN_ACT_SOFTPLUS, SOOC_NN_ACT_EXP, SOOC_NN_ACT_LOG,
                                     SOOC_NN_ACT_SQUARE, SOOC_NN_ACT_TANH};
    static const char *un_names[] = {"relu", "elu", "sigmoid", "softplus", "exp", "log", "square", "tanh"};
    for (int a = 0; a < 8; a++) {
        char nm[64];
        snprintf(nm, sizeof nm, "unary %s", un_names[a]);
        float lo = un[a] == SOOC_NN_ACT_LOG ? 0.2f : -3.f;
        gc_input in[1] = {IN(2, 6, 7, 0, 0, lo, 3)};
        g_kink_frac = un[a] == SOOC_NN_ACT_RELU ? 0.1 : 0.0;
        gradcheck(nm, f_unary, in, 1, (void *)&un[a]);
        g_kink_frac = 0.0;
    }
    {   /* softplus above the torch threshold (identity branch) */
        gc_input in[1] = {IN(1, 5, 0, 0, 0, 20.5f, 30)};
        gradcheck("unary softplus x>20", f_unary, in, 1, (void *)&un[3]);
    }
    {   /* relu with inputs exactly at the kink: analytic 0 at x == 0 */
        sooc_nn_tape_reset(g_tape);
        sooc_nn_arena_reset(&g_arena);
        float z[3] = {0.f, -0.f, 1.f};
        int64_t s[1] = {3};
        sooc_nn_tensor *tz = sooc_nn_tensor_new(g_tape, z, 1, s, 1);
        sooc_nn_tensor *y = sooc_nn_unary(g_tape, SOOC_NN_ACT_RELU, tz);
        sooc_nn_tape_seed(g_tape, y, NULL, 1.f);
        sooc_nn_tape_backward(g_tape);
        CHECK(tz->grad[0] == 0.f && tz->grad[1] == 0.f && tz->grad[2] == 1.f);
    }
    static const sooc_nn_binop bo[] = {SOOC_NN_ADD, SOOC_NN_SUB, SOOC_NN_MUL, SOOC_NN_DIV};
    static const char *bo_names[] = {"add", "sub", "mul", "div"};
    for (int o = 0; o < 4; o++) {
        char nm[64];
        float blo = o == 3 ? 0.5f : -2.f;
        snprintf(nm, sizeof nm, "binary %s same shape", bo_names[o]);
        gc_input a[2] = {IN(2, 3, 4, 0, 0, -2, 2), IN(2, 3, 4, 0, 0, blo, 2)};
        gradcheck(nm, f_binary, a, 2, (void *)&bo[o]);
        snprintf(nm, sizeof nm, "binary %s bcast [3,1,5]x[4,1]", bo_names[o]);
        gc_input b[2] = {IN(3, 3, 1, 5, 0, -2, 2), IN(2, 4, 1, 0, 0, blo, 2)};
        gradcheck(nm, f_binary, b, 2, (void *)&bo[o]);
        snprintf(nm, sizeof nm, "binary %s bcast [2,3,4]x[3,1]", bo_names[o]);
        gc_input c[2] = {IN(3, 2, 3, 4, 0, -2, 2), IN(2, 3, 1, 0, 0, blo, 2)};
        gradcheck(nm, f_binary, c, 2, (void *)&bo[o]);
    }
    {
        gc_input in[1] = {IN(2, 3, 4, 0, 0, -2, 2)};
        gradcheck("affine", f_affine, in, 1, NULL);
    }
    for (int ax = 0; ax < 3; ax++) {
        char nm[64];
        snprintf(nm, sizeof nm, "concat axis %d", ax);
        int64_t sh[3][3] = {{2, 3, 4}, {2, 3, 4}, {2, 3, 4}};
        for (int k = 0; k < 3; k++) sh[k][ax] = k + 1;
        gc_input in[3] = {IN(3, sh[0][0], sh[0][1], sh[0][2], 0, -1, 1),
                          IN(3, sh[1][0], sh[1][1], sh[1][2], 0, -1, 1),
                          IN(3, sh[2][0], sh[2][1], sh[2][2], 0, -1, 1)};
        int a = ax;
        gradcheck(nm, f_concat, in, 3, &a);
        snprintf(nm, sizeof nm, "slice axis %d", ax);
        gc_input s[1] = {IN(3, 4, 5, 6, 0, -1, 1)};
        gradcheck(nm, f_slice, s, 1, &a);
    }
    {
        gc_input g[1] = {IN(2, 5, 3, 0, 0, -1, 1)};
        gradcheck("gather (repeated rows)", f_gather, g, 1, NULL);
        gc_input s[1] = {IN(2, 7, 3, 0, 0, -1, 1)};
        gradcheck("scatter_add", f_scatter, s, 1, NULL);
    }
    int axes[4] = {0, 1, -1, SOOC_NN_ALL};
    for (int a = 0; a < 4; a++) {
        char nm[64];
        gc_input in[1] = {IN(3, 3, 4, 5, 0, -1, 1)};
        snprintf(nm, sizeof nm, "sum axis %d", axes[a]);
        gradcheck(nm, f_sum, in, 1, &axes[a]);
        gc_input in2[1] = {IN(3, 3, 4, 5, 0, -1, 1)};
        snprintf(nm, sizeof nm, "mean axis %d", axes[a]);
        gradcheck(nm, f_mean, in2, 1, &axes[a]);
    }
    {
        int learn = 0;
        gc_input a[1] = {IN(2, 4, 9, 0, 0, -2, 2)};
        gradcheck("layernorm (non-learnable)", f_ln, a, 1, &learn);
        learn = 1;
        gc_input b[3] = {IN(2, 4, 9, 0, 0, -2, 2), IN(1, 9, 0, 0, 0, 0.5f, 1.5f), IN(1, 9, 0, 0, 0, -1, 1)};
        gradcheck("layernorm (learnable)", f_ln, b, 3, &learn);
        gc_input c[1] = {IN(4, 2, 3, 4, 4, -2, 2)};
        gradcheck("layernorm over (C,H,W)", f_ln_chw, c, 1, NULL);
    }
    {
        gc_input in[1] = {IN(2, 6, 3, 0, 0, -1.5f, 1.5f)};
        gradcheck("posenc F=5", f_posenc, in, 1, NULL);
    }
    {
        /* y is checked for zero gradient in test_stopgrad_zero; here only x */
        gc_input in[2] = {IN(1, 5, 0, 0, 0, -1, 1), IN(1, 5, 0, 0, 0, -1, 1)};
        in[1].no_grad = 1;
        gradcheck("stop_grad (x * SG(y))", f_stopgrad, in, 2, NULL);
        test_stopgrad_zero();
        gc_input r[1] = {IN(3, 2, 3, 4, 0, -1, 1)};
        gradcheck("reshape", f_reshape, r, 1, NULL);
    }
    test_sgemm_blocks();
    sooc_nn_tape_destroy(g_tape);
    sooc_nn_arena_deinit(&g_arena);
    return check_report("test_nn_grad");
}
