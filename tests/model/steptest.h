/* Helpers shared by the whole-training-step tests (test_model_step,
 * test_model_global, test_model_overfit): the finite-difference check of
 * d(total)/d(params) over random samples of every parameter tensor, and the
 * plain-Adam overfit loop. The caller supplies the step (plain or
 * global-frame) as a callback. Header-only, tests only (it reads the model's
 * internal tensor table). */
#ifndef SOOC3D_TEST_STEPTEST_H
#define SOOC3D_TEST_STEPTEST_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "model/step.h"

/* Gives every refinement-head tensor ("head" in its name) N(0, s^2) weights,
 * so that gradients reach the refinement trunks (the heads start at zero). */
static inline void steptest_random_heads(sooc_model *m, sooc_rng *r, float s) {
    for (int t = 0; t < m->nt; t++)
        if (strstr(m->t[t].name, "head"))
            for (size_t i = 0; i < m->t[t].count; i++) m->p[m->t[t].offset + i] = s * (float)sooc_rng_normal(r);
}

/* The loss whose gradient is checked, evaluated at the current parameters
 * (deterministic: same seed, stop-gradient inputs replayed). */
typedef double (*steptest_loss_fn)(sooc_model *m, void *ctx);

typedef struct steptest_fd_result {
    double worst;     /* largest |a - n| / (0.1 + 0.08 max(|a|, |n|)); pass: <= 1 */
    double wa, wn;    /* analytic and numeric value at the worst element */
    char wname[96];   /* "<tensor>[<index>]" of the worst element */
    int nchk;         /* elements checked */
} steptest_fd_result;

/* Central difference of f in parameter i at step sizes 1e-3, 3e-4, 3e-3
 * (stopping early once |n - a| <= 0.02 + 0.01 |a|): the loss is piecewise
 * smooth (ReLU kinks, registration thresholds), so one step size sometimes
 * straddles a kink. Returns the estimate closest to the analytic value a. */
static inline double steptest_fd_best(sooc_model *m, size_t i, double a, steptest_loss_fn f, void *ctx) {
    static const double eps[3] = {1e-3, 3e-4, 3e-3};
    double best = 0, berr = 1e300;
    float keep = m->p[i];
    for (int e = 0; e < 3 && berr > 0.02 + 0.01 * fabs(a); e++) {
        m->p[i] = keep + (float)eps[e];
        double fp = f(m, ctx);
        m->p[i] = keep - (float)eps[e];
        double fm = f(m, ctx);
        m->p[i] = keep;
        double n = (fp - fm) / (2 * eps[e]);
        if (fabs(n - a) < berr) berr = fabs(n - a), best = n;
    }
    return best;
}

/* Checks the analytic gradient g (np floats, taken at the current
 * parameters) against finite differences of f: n_prior random elements of
 * each "prior*" tensor and n_other of every other tensor, drawn from r in
 * tensor order. Tolerance |a - n| <= 0.1 + 0.08 max(|a|, |n|) (stiff,
 * piecewise-smooth loss: see test_model_step's header). Prints every element
 * over tolerance (every element if SDBG is set) and one summary line starting
 * with label; fills *res. The caller CHECKs res->worst <= 1. */
static inline void steptest_fd_check(sooc_model *m, const float *g, sooc_rng *r, int n_other, int n_prior,
                                     steptest_loss_fn f, void *ctx, const char *label, steptest_fd_result *res) {
    memset(res, 0, sizeof *res);
    for (int t = 0; t < m->nt; t++) {
        int ns = strncmp(m->t[t].name, "prior", 5) ? n_other : n_prior;
        for (int s = 0; s < ns; s++) {
            size_t i = m->t[t].offset + sooc_rng_below(r, (uint32_t)m->t[t].count);
            double a = g[i], best = steptest_fd_best(m, i, a, f, ctx);
            double mx = fabs(a) > fabs(best) ? fabs(a) : fabs(best);
            double ratio = fabs(a - best) / (0.1 + 0.08 * mx);
            res->nchk++;
            if (ratio > 1 || getenv("SDBG"))
                printf("  %s[%zu] a % .5e n % .5e ratio %.2f\n", m->t[t].name, i - m->t[t].offset, a, best, ratio);
            if (ratio > res->worst) {
                res->worst = ratio, res->wa = a, res->wn = best;
                snprintf(res->wname, sizeof res->wname, "%s[%zu]", m->t[t].name, i - m->t[t].offset);
            }
        }
    }
    printf("%s d(total)/d(params): %d elements, worst %s analytic % .6e numeric % .6e err/tol %.3f\n", label,
           res->nchk, res->wname, res->wa, res->wn, res->worst);
}

/* The small config of the overfit tests: K 3, d_what 8, d_layout 4, L 2,
 * 32x32 images with 16x16 rays, 32-wide decoders and refinement nets. */
static inline void steptest_overfit_cfg(sooc_model_config *c) {
    sooc_model_config_default(c);
    c->K = 3, c->d_what = 8, c->d_layout = 4, c->L = 2;
    c->img_w = c->img_h = 32, c->ray_w = c->ray_h = 16;
    c->dec_width = 32, c->dec_color_width = 16;
    c->ref_ch[0] = 8, c->ref_ch[1] = 8, c->ref_ch[2] = 16, c->ref_ch[3] = 16;
    c->ref_fc = 32, c->ref_hidden = 32;
}

/* One training step (gradients accumulate into the model's gradient slab). */
typedef sooc_status (*steptest_step_fn)(sooc_model *m, const sooc_step_opts *o, sooc_rng *r,
                                        sooc_step_losses *ls, void *ctx);

/* Plain Adam (lr 3e-3, betas 0.9/0.999, eps 1e-8, global-norm clip at 1e4,
 * i.e. 5 * the loss scale) for `steps` steps from an rng seeded (5, 0) and the
 * default step options; steps with non-finite losses are skipped. Prints the
 * losses at step 1 and every print_every steps. *first and *last get the mean
 * total loss of the first and the last 10 steps. The trainer owns the real
 * optimiser; this is the test's own. */
static inline void steptest_overfit(sooc_model *m, int steps, int print_every, steptest_step_fn step, void *ctx,
                                    double *first, double *last) {
    size_t n = sooc_model_param_count(m);
    float *p = sooc_model_params(m), *g = sooc_model_grads(m);
    float *mo = calloc(n, sizeof(float)), *vo = calloc(n, sizeof(float));
    if (!mo || !vo) {
        fprintf(stderr, "steptest_overfit: out of memory\n");
        exit(1);
    }
    sooc_rng r;
    sooc_rng_seed(&r, 5, 0);
    sooc_step_opts o;
    sooc_step_opts_default(&o);
    double lr = 3e-3;
    *first = *last = 0;
    for (int s = 1; s <= steps; s++) {
        sooc_model_zero_grad(m);
        sooc_step_losses ls;
        CHECK_OK(step(m, &o, &r, &ls, ctx));
        if (ls.nonfinite) continue;
        if (s <= 10) *first += ls.total / 10;
        if (s > steps - 10) *last += ls.total / 10;
        double gn = 0;
        for (size_t i = 0; i < n; i++) gn += (double)g[i] * g[i];
        gn = sqrt(gn);
        float cs = gn > 1e4 ? (float)(1e4 / gn) : 1.0f;
        double b1 = 1 - pow(0.9, s), b2 = 1 - pow(0.999, s);
        for (size_t i = 0; i < n; i++) {
            float gi = g[i] * cs;
            mo[i] = 0.9f * mo[i] + 0.1f * gi;
            vo[i] = 0.999f * vo[i] + 0.001f * gi * gi;
            p[i] -= (float)(lr * (mo[i] / b1) / (sqrt(vo[i] / b2) + 1e-8));
        }
        if (s % print_every == 0 || s == 1)
            printf("step %3d total %10.1f nll_in %9.1f kl %7.2f nll_q %9.1f present %.2f entries %.0f\n", s, ls.total,
                   ls.nll_input, ls.kl, ls.nll_query, ls.present_slots, ls.map_entries);
    }
    free(mo), free(vo);
}

#endif
