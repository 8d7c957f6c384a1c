/*
 * nn state tests: Adam/AdamW vs hand calculation, clipping, schedules, arena,
 * and the mid-forward (segment) gradient mechanism of the tape.
 */
#include "check.h"
#include "nn/nn.h"
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

/* ---------------------------------------------------------------- Adam */
static void test_adam(void) {
    for (int adamw = 0; adamw < 2; adamw++) {
        sooc_nn_params p;
        sooc_nn_params_init(&p);
        int64_t s[1] = {3};
        CHECK(sooc_nn_params_add(&p, "w", 1, s) == 0);
        CHECK_OK(sooc_nn_params_alloc(&p));
        float w0[3] = {1.f, -2.f, 0.5f};
        float g1[3] = {0.1f, -0.2f, 0.3f}, g2[3] = {-0.05f, 0.4f, 0.3f};
        memcpy(p.w, w0, sizeof w0);
        sooc_nn_adam_cfg cfg = sooc_nn_adam_default();
        cfg.adamw = adamw;
        cfg.weight_decay = 0.1f;
        float lr = 0.01f;
        double w[3], m[3] = {0}, v[3] = {0};
        for (int i = 0; i < 3; i++) w[i] = w0[i];
        for (int t = 1; t <= 2; t++) {
            const float *g = t == 1 ? g1 : g2;
            memcpy(p.g, g, 3 * sizeof(float));
            CHECK_OK(sooc_nn_adam_step(&p, &cfg, lr));
            /* hand calculation (torch.optim.Adam / AdamW), in double */
            for (int i = 0; i < 3; i++) {
                double gi = g[i];
                if (adamw) w[i] *= 1.0 - lr * 0.1;
                else gi += 0.1 * w[i];
                m[i] = 0.9 * m[i] + 0.1 * gi;
                v[i] = 0.999 * v[i] + 0.001 * gi * gi;
                double mh = m[i] / (1 - pow(0.9, t)), vh = v[i] / (1 - pow(0.999, t));
                w[i] -= lr * mh / (sqrt(vh) + 1e-8);
            }
            for (int i = 0; i < 3; i++) CHECK_CLOSE(p.w[i], w[i], 1e-6, 1e-6);
        }
        if (!adamw) {
            /* literal values after step 1 for the first element (g + wd*w = 0.2): w ~ 1 - lr */
            CHECK(p.adam_t == 2);
        }
        sooc_nn_params_deinit(&p);
    }
    /* step 1 without weight decay moves each weight by lr * sign(g) */
    sooc_nn_params p;
    sooc_nn_params_init(&p);
    int64_t s[1] = {3};
    sooc_nn_params_add(&p, "w", 1, s);
    CHECK_OK(sooc_nn_params_alloc(&p));
    p.w[0] = 1.f; p.w[1] = -2.f; p.w[2] = 0.5f;
    p.g[0] = 0.1f; p.g[1] = -0.2f; p.g[2] = 0.3f;
    sooc_nn_adam_cfg c = sooc_nn_adam_default();
    CHECK_OK(sooc_nn_adam_step(&p, &c, 0.01f));
    CHECK_CLOSE(p.w[0], 0.99, 1e-6, 0);
    CHECK_CLOSE(p.w[1], -1.99, 1e-6, 0);
    CHECK_CLOSE(p.w[2], 0.49, 1e-6, 0);
    /* non-finite gradient: refused, nothing changes */
    p.g[1] = NAN;
    float before = p.w[0];
    CHECK(sooc_nn_adam_step(&p, &c, 0.01f) == SOOC_ENUMERIC);
    CHECK(p.w[0] == before && p.adam_t == 1);
    /* clipping (torch semantics) */
    p.g[0] = 3.f; p.g[1] = 4.f; p.g[2] = 0.f;
    CHECK_CLOSE(sooc_nn_grad_norm(&p), 5.0, 1e-12, 0);
    double n = sooc_nn_clip_grad_norm(&p, 1.0);
    CHECK_CLOSE(n, 5.0, 1e-12, 0);
    CHECK_CLOSE(p.g[0], 3.0 / (5.0 + 1e-6), 1e-6, 0);
    CHECK_CLOSE(sooc_nn_grad_norm(&p), 1.0, 1e-5, 0);
    n = sooc_nn_clip_grad_norm(&p, 5.0); /* below threshold: unchanged */
    CHECK_CLOSE(p.g[1], 4.0 / (5.0 + 1e-6), 1e-6, 0);
    sooc_nn_params_deinit(&p);
}

static void test_schedule(void) {
    sooc_nn_schedule s = {2e-4f, 1000, 11000, 0.1f, SOOC_NN_DECAY_LINEAR};
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 0), 2e-7, 1e-12, 1e-5);
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 499), 1e-4, 1e-12, 1e-5);
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 999), 2e-4, 1e-12, 1e-5);
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 1000), 2e-4, 1e-12, 1e-5);
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 6000), 2e-4 * (0.1 + 0.9 * 0.5), 1e-12, 1e-5);
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 11000), 2e-5, 1e-12, 1e-5);
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 50000), 2e-5, 1e-12, 1e-5);
    s.decay = SOOC_NN_DECAY_COSINE;
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 6000), 2e-4 * (0.1 + 0.9 * 0.5), 1e-12, 1e-5);
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 3500), 2e-4 * (0.1 + 0.9 * 0.5 * (1 + cos(M_PI * 0.25))), 1e-12, 1e-5);
    s.decay = SOOC_NN_DECAY_CONST;
    CHECK_CLOSE(sooc_nn_schedule_lr(&s, 9000), 2e-4, 1e-12, 1e-6);
}

static void test_arena(void) {
    sooc_nn_arena a;
    CHECK_OK(sooc_nn_arena_init(&a, 1000));
    float *x = sooc_nn_arena_floats(&a, 10);
    CHECK(x && ((uintptr_t)x & 63) == 0);
    size_t mk = sooc_nn_arena_mark(&a);
    CHECK(sooc_nn_arena_floats(&a, 100) != NULL);
    CHECK(sooc_nn_arena_floats(&a, 1000) == NULL); /* full: NULL + message */
    CHECK(strstr(sooc_errmsg(), "arena full") != NULL);
    sooc_nn_arena_rewind(&a, mk);
    CHECK(a.used == mk);
    sooc_nn_arena_reset(&a);
    CHECK(a.used == 0 && a.peak > 0);
    sooc_nn_arena_deinit(&a);
    sooc_nn_arena_deinit(NULL);
    /* sticky tape error on arena exhaustion */
    CHECK_OK(sooc_nn_arena_init(&a, 4096));
    sooc_nn_tape *t;
    CHECK_OK(sooc_nn_tape_create(&t, &a, 8));
    int64_t big[2] = {100, 100};
    CHECK(sooc_nn_tensor_zeros(t, 2, big, 1) == NULL);
    CHECK(sooc_nn_tape_status(t) == SOOC_ENOMEM);
    int64_t sm[1] = {2};
    CHECK(sooc_nn_tensor_zeros(t, 1, sm, 1) == NULL); /* sticky */
    sooc_nn_tape_reset(t);
    sooc_nn_arena_reset(&a);
    CHECK(sooc_nn_tensor_zeros(t, 1, sm, 1) != NULL);
    sooc_nn_tape_destroy(t);
    sooc_nn_arena_deinit(&a);
}


/* ------------------------------------------------- mid-forward gradients */
/* Segment: y1 = tanh(lam W1^T); y2 = tanh(y1 W2^T); L1 = sum(y2^2).
 * Local grad of L1 wrt {lam, y1} with params accumulated at scale 0.5.
 * Then aux = SG(dL1/dy1); z = concat(y1, aux) W3^T; L2 = sum(z * r).
 * Expected main grads: W1: 0.5 dL1/dW1 + dL2/dW1|aux fixed; W2: 0.5 dL1/dW2;
 * W3: dL2/dW3; lam (not a parameter): dL2/dlam|aux fixed only, its local
 * dL1/dlam is returned separately. */
static sooc_nn_params g_p;
static float g_lam[6], g_r[4], g_aux[8];
static sooc_nn_arena g_ar;

static double mf_eval(sooc_nn_tape *t, double *L1out, int use_fixed_aux, int do_grad,
                      float *dlam_local, float *dy1_local, int cut) {
    sooc_nn_tape_reset(t);
    sooc_nn_arena_reset(&g_ar);
    int64_t sl[2] = {2, 3};
    sooc_nn_tensor *lam = sooc_nn_tensor_new(t, g_lam, 2, sl, 1);
    sooc_nn_tensor *W1 = sooc_nn_params_tensor(&g_p, 0), *W2 = sooc_nn_params_tensor(&g_p, 1),
                   *W3 = sooc_nn_params_tensor(&g_p, 2);
    int mark = sooc_nn_tape_mark(t);
    sooc_nn_tensor *y1 = sooc_nn_linear(t, lam, W1, NULL, SOOC_NN_ACT_TANH);
    sooc_nn_tensor *y2 = sooc_nn_linear(t, y1, W2, NULL, SOOC_NN_ACT_TANH);
    sooc_nn_tensor *L1 = sooc_nn_sum(t, sooc_nn_unary(t, SOOC_NN_ACT_SQUARE, y2), SOOC_NN_ALL);
    if (!L1) return NAN;
    *L1out = L1->data[0];
    float dy1[8];
    if (do_grad) {
        sooc_nn_tensor *wrt[2] = {lam, y1};
        float *dw[2] = {dlam_local, dy1};
        CHECK_OK(sooc_nn_tape_grad(t, mark, L1, NULL, wrt, dw, 2, 0.5f));
        memcpy(dy1_local, dy1, sizeof dy1);
        memcpy(g_aux, dy1, sizeof dy1);
        CHECK(lam->grad == NULL && y1->grad == NULL); /* main grads untouched */
        if (cut) sooc_nn_tape_cut(t, mark + 1);       /* keep y1's node, drop the L1 branch */
    }
    (void)use_fixed_aux;
    int64_t sa[2] = {2, 4};
    sooc_nn_tensor *aux = sooc_nn_tensor_new(t, g_aux, 2, sa, 0);
    sooc_nn_tensor *cat[2] = {y1, aux};
    sooc_nn_tensor *z = sooc_nn_linear(t, sooc_nn_concat(t, cat, 2, 1), W3, NULL, SOOC_NN_ACT_NONE);
    int64_t sr[2] = {2, 2};
    sooc_nn_tensor *rr = sooc_nn_tensor_new(t, g_r, 2, sr, 0);
    sooc_nn_tensor *L2 = sooc_nn_sum(t, sooc_nn_binary(t, SOOC_NN_MUL, z, rr), SOOC_NN_ALL);
    if (!L2) return NAN;
    if (do_grad) {
        CHECK_OK(sooc_nn_tape_seed(t, L2, NULL, 1.f));
        CHECK_OK(sooc_nn_tape_backward(t));
        memcpy(dlam_local + 6, lam->grad, 6 * sizeof(float)); /* main lam grad after */
    }
    return L2->data[0];
}

static void test_midforward(void) {
    sooc_nn_params_init(&g_p);
    int64_t s1[2] = {4, 3}, s2[2] = {4, 4}, s3[2] = {2, 8};
    sooc_nn_params_add(&g_p, "W1", 2, s1);
    sooc_nn_params_add(&g_p, "W2", 2, s2);
    sooc_nn_params_add(&g_p, "W3", 2, s3);
    CHECK_OK(sooc_nn_params_alloc(&g_p));
    CHECK_OK(sooc_nn_arena_init(&g_ar, 1 << 20));
    sooc_nn_tape *t;
    CHECK_OK(sooc_nn_tape_create(&t, &g_ar, 64));
    sooc_rng r;
    sooc_rng_seed(&r, 3, 0);
    for (size_t i = 0; i < g_p.n_total; i++) g_p.w[i] = 0.6f * (float)sooc_rng_normal(&r);
    for (int i = 0; i < 6; i++) g_lam[i] = (float)sooc_rng_normal(&r);
    for (int i = 0; i < 4; i++) g_r[i] = (float)sooc_rng_normal(&r);
    for (int cut = 0; cut < 2; cut++) {
        sooc_nn_params_zero_grad(&g_p);
        float dlam[12], dy1[8];
        double L1;
        mf_eval(t, &L1, 0, 1, dlam, dy1, cut);
        /* g_aux now holds the fixed aux; FD with it fixed */
        int bad = 0;
        double worst = 0;
        float *targets[4] = {g_p.w + g_p.views[0].offset, g_p.w + g_p.views[1].offset,
                             g_p.w + g_p.views[2].offset, g_lam};
        float *grads[4] = {g_p.g + g_p.views[0].offset, g_p.g + g_p.views[1].offset,
                           g_p.g + g_p.views[2].offset, dlam + 6};
        int sizes[4] = {12, 16, 16, 6};
        for (int k = 0; k < 4; k++) {
            for (int e = 0; e < sizes[k]; e++) {
                float x0 = targets[k][e], h = 1e-2f;
                double f[4], l1[4];
                float xs[4] = {x0 + h, x0 - h, x0 + h / 2, x0 - h / 2};
                for (int j = 0; j < 4; j++) {
                    targets[k][e] = xs[j];
                    f[j] = mf_eval(t, &l1[j], 1, 0, NULL, NULL, 0);
                    if (k < 3) f[j] += 0.5 * l1[j]; /* params get 0.5 dL1 folded in */
                }
                targets[k][e] = x0;
                double gn = (8 * (f[2] - f[3]) - (f[0] - f[1])) / (6 * h);
                double ga = grads[k][e];
                double err = fabs(ga - gn) / (1e-3 + 1e-2 * fmax(fabs(ga), fabs(gn)));
                if (err > worst) worst = err;
                if (err > 1) { bad++; fprintf(stderr, "k %d e %d ga %g gn %g\n", k, e, ga, gn); }
                /* local dL1/dlam vs FD of L1 */
                if (k == 3) {
                    double gl = (8 * (l1[2] - l1[3]) - (l1[0] - l1[1])) / (6 * h);
                    double el = fabs(dlam[e] - gl) / (1e-3 + 1e-2 * fmax(fabs(dlam[e]), fabs(gl)));
                    if (el > worst) worst = el;
                    if (el > 1) { bad++; fprintf(stderr, "local e %d ga %g gn %g\n", e, dlam[e], gl); }
                }
            }
        }
        printf("mid-forward gradient (%s): worst err/tol %.3f, %d bad\n",
               cut ? "segment cut" : "segment kept", worst, bad);
        CHECK_MSG(bad == 0, "mid-forward gradient mismatch");
    }
    sooc_nn_tape_destroy(t);
    sooc_nn_arena_deinit(&g_ar);
    sooc_nn_params_deinit(&g_p);
}

int main(void) {
    test_adam();
    test_schedule();
    test_arena();
    test_midforward();
    return check_report("test_nn_state");
}
