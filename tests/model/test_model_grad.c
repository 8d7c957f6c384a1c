/* Finite-difference gradient checks of the model ops: Π, the Gaussian-trick
 * backward rule, the KL terms, the fused decoder + composition + likelihood
 * (w.r.t. λ, the prior λ0, the layout latents and the decoder weights), and
 * the refinement network. Central differences in double on float code, so
 * tolerances are relative + absolute; the worst element is printed. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "model/step.h"
#include "synth.h"

typedef struct worst {
    double ratio, a, n;
    char what[96];
} worst;

static void cmp(worst *w, const char *what, int idx, double a, double n, double atol, double rtol) {
    double m = fabs(a) > fabs(n) ? fabs(a) : fabs(n);
    double r = fabs(a - n) / (atol + rtol * m);
    if (r > w->ratio) {
        w->ratio = r, w->a = a, w->n = n;
        snprintf(w->what, sizeof w->what, "%s[%d]", what, idx);
    }
}
static void report(const worst *w, const char *name) {
    printf("%-34s worst %-28s analytic % .6e numeric % .6e  err/tol %.3f\n", name, w->what, w->a, w->n, w->ratio);
    CHECK_MSG(w->ratio <= 1.0, "%s: gradient check failed at %s", name, w->what);
}

/* ---- Π and the Gaussian rule on single points ---- */
static void test_pi_gauss(void) {
    worst w = {0};
    sooc_rng r;
    sooc_rng_seed(&r, 1, 0);
    for (int t = 0; t < 50; t++) {
        float x[3] = {(float)sooc_rng_range(&r, -2, 2), (float)sooc_rng_range(&r, -1.5, 0), (float)sooc_rng_range(&r, 1, 5)};
        double q[3] = {sooc_rng_range(&r, -2, 2), sooc_rng_range(&r, 1, 5), sooc_rng_range(&r, -3, 3)};
        float a[3] = {(float)sooc_rng_normal(&r), (float)sooc_rng_normal(&r), (float)sooc_rng_normal(&r)};
        float h = 1.4f, xk[3], gw[3] = {0, 0, 0};
        sooc_mdl_pi(x, (float)q[0], (float)q[1], (float)q[2], h, xk);
        sooc_mdl_pi_backward(xk, (float)q[2], a, gw);
        for (int i = 0; i < 3; i++) {
            double e = 1e-3, fp = 0, fm = 0;
            double qp[3] = {q[0], q[1], q[2]}, qm[3] = {q[0], q[1], q[2]};
            qp[i] += e, qm[i] -= e;
            float xp[3], xm[3];
            sooc_mdl_pi(x, (float)qp[0], (float)qp[1], (float)qp[2], h, xp);
            sooc_mdl_pi(x, (float)qm[0], (float)qm[1], (float)qm[2], h, xm);
            for (int j = 0; j < 3; j++) fp += a[j] * xp[j], fm += a[j] * xm[j];
            cmp(&w, "pi", i, gw[i], (fp - fm) / (2 * e), 1e-3, 1e-3);
        }
    }
    report(&w, "Pi(z_where) backward");
    /* Gaussian trick: the extra term equals d/dxk of  sig*zp*w_g(xk)/SG(w_g(xk)) */
    worst wg = {0};
    for (int t = 0; t < 50; t++) {
        float xk[3] = {(float)sooc_rng_range(&r, -0.6, 0.6), (float)sooc_rng_range(&r, 0, 1.2),
                       (float)sooc_rng_range(&r, -0.6, 0.6)};
        float sig = (float)sooc_rng_uniform(&r), zp = (float)sooc_rng_uniform(&r), g = (float)sooc_rng_normal(&r);
        float s = 0.3f, gx[3] = {0, 0, 0};
        sooc_mdl_gauss_backward(g, sig, zp, xk, s, gx);
        double w0 = exp(-(xk[0] * xk[0] + xk[2] * xk[2]) / (2.0 * s * s));
        for (int i = 0; i < 3; i++) {
            double e = 1e-4, v[2];
            for (int sgn = 0; sgn < 2; sgn++) {
                double y[3] = {xk[0], xk[1], xk[2]};
                y[i] += sgn ? -e : e;
                double wy = exp(-(y[0] * y[0] + y[2] * y[2]) / (2.0 * s * s));
                v[sgn] = g * sig * zp * wy / w0;
            }
            cmp(&wg, "gauss", i, gx[i], (v[0] - v[1]) / (2 * e), 1e-5, 1e-3);
        }
    }
    report(&wg, "Gaussian-trick backward rule");
}

/* ---- KL ---- */
static void test_kl(void) {
    sooc_model_config c;
    synth_tiny_cfg(&c, 2, 1);
    int NL = MDL_NL(c.d_what);
    sooc_rng r;
    sooc_rng_seed(&r, 2, 0);
    worst w = {0};
    for (int t = 0; t < 20; t++) {
        float lam[70], lam0[70], g[70] = {0}, g0[70] = {0};
        for (int i = 0; i < NL; i++) lam[i] = (float)sooc_rng_normal(&r), lam0[i] = (float)sooc_rng_normal(&r);
        lam[2] = 3.0f, lam0[2] = -3.0f;   /* θ difference wraps */
        sooc_mdl_kl_slot(&c, lam, lam0, 0.7f, g, g0);
        for (int i = 0; i < NL; i++) {
            for (int side = 0; side < 2; side++) {
                float *v = side ? lam0 : lam, keep = v[i];
                double e = 1e-3;
                v[i] = keep + (float)e;
                double fp = sooc_mdl_kl_slot(&c, lam, lam0, 0.7f, NULL, NULL);
                v[i] = keep - (float)e;
                double fm = sooc_mdl_kl_slot(&c, lam, lam0, 0.7f, NULL, NULL);
                v[i] = keep;
                cmp(&w, side ? "dKL/dlam0" : "dKL/dlam", i, side ? g0[i] : g[i], (fp - fm) / (2 * e), 2e-3, 2e-2);
            }
        }
    }
    report(&w, "KL (Gauss + Bernoulli, wrapped θ)");
    /* KL of identical posteriors is 0 */
    float l[70];
    for (int i = 0; i < NL; i++) l[i] = 0.3f * i;
    CHECK_CLOSE(sooc_mdl_kl_slot(&c, l, l, 1.0f, NULL, NULL), 0.0, 1e-5, 0);
}

/* ---- the fused decoder and the per-view loss of one decode ---- */
typedef struct dec_fixture {
    sooc_model *m;
    sooc_model_ws *w;
    sooc_frame f;
    sooc_view_rays vr;
    sooc_dec_noise nz;
    float lam[2 * 70], lam0[2 * 70], lay[64], lay0[64], zw_sg[6];
    uint8_t hard[2];
} dec_fixture;

static void fixture(dec_fixture *F, int use_box, uint64_t seed) {
    memset(F, 0, sizeof *F);
    sooc_model_config c;
    synth_tiny_cfg(&c, 2, use_box);
    CHECK_OK(sooc_model_create(&F->m, &c, seed));
    CHECK_OK(sooc_model_ws_create(&F->w, F->m));
    double T[16], Twg[16], h, pitch, roll;
    synth_pose(T, 0, 1.5, 0, 0.1, -0.45);
    synth_sphere sp[2] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}}};
    CHECK_OK(synth_frame(&F->f, 32, 32, 60, T, sp, 2));
    CHECK_OK(sooc_gframe(T, Twg, &h, &pitch, &roll));
    CHECK_OK(sooc_mdl_rays_alloc(&F->vr, 16, 16));
    sooc_rng r;
    sooc_rng_seed(&r, seed, 1);
    double blk[2] = {0.5, 4.0};
    CHECK_OK(sooc_mdl_make_rays(F->m, &F->f, 1, 0, &r, &F->vr, Twg, h, pitch, blk));
    sooc_mdl_sample_noise(F->m, &r, &F->nz);
    int NL = F->m->NL, d = c.d_what, dl = c.d_layout;
    memcpy(F->lam0, F->m->p + F->m->prior, sizeof(float) * 2 * NL);
    for (int k = 0; k < 2; k++)
        for (int i = 0; i < NL; i++) F->lam[k * NL + i] = F->lam0[k * NL + i] + 0.2f * (float)sooc_rng_normal(&r);
    /* put the slots near the spheres (G ≈ world rotated by yaw 0.1) */
    F->lam[0] = 0.0f, F->lam[1] = 3.0f, F->lam[NL] = -1.0f, F->lam[NL + 1] = 2.2f;
    F->lam[3] = F->lam[NL + 3] = logf(0.1f * 0.1f);
    F->lam[5 + 2 * d] = 0.5f;
    for (int i = 0; i < 2 * dl; i++) F->lay[i] = 0.1f * (float)sooc_rng_normal(&r), F->lay0[i] = 0.05f * i;
    (void)d;
}
static void fixture_free(dec_fixture *F) {
    sooc_mdl_rays_free(&F->vr);
    sooc_frame_free(&F->f);
    sooc_model_ws_destroy(F->w);
    sooc_model_destroy(F->m);
}

static double run_dec(dec_fixture *F, int backward, float *g_lam, float *g_lam0, float *g_lay, float *g_lay0,
                      float wgrad, int use_sg) {
    sooc_dec_call c;
    memset(&c, 0, sizeof c);
    c.rays = &F->vr;
    c.nslot = 2;
    c.lam = F->lam, c.lam0 = F->lam0, c.lay = F->lay, c.lay0 = F->lay0;
    c.noise = &F->nz;
    c.tau = 0.8f, c.beta_kl = 0.9f;
    c.hard = F->hard;
    c.wgrad = wgrad;
    c.backward = backward;
    c.g_lam = g_lam, c.g_lam0 = g_lam0, c.g_lay = g_lay, c.g_lay0 = g_lay0;
    c.zw_sg = use_sg ? F->zw_sg : NULL;
    CHECK_OK(sooc_mdl_decode(F->w, &c));
    if (backward)
        for (int k = 0; k < 2; k++)
            for (int i = 0; i < 3; i++) F->zw_sg[k * 3 + i] = c.zw[k][i];
    return c.loss;
}

/* Central difference of the decode loss in one float, at several step sizes:
 * the loss is piecewise smooth (ReLU kinks on hundreds of rows, each with a
 * large per-ray weight), so a single step size sometimes straddles a kink.
 * Returns the estimate closest to `a` (the analytic value). */
static double fd_best(dec_fixture *F, float *v, double a) {
    static const double eps[3] = {1e-3, 3e-4, 3e-3};
    double best = 0, berr = 1e300;
    float keep = *v;
    for (int i = 0; i < 3; i++) {
        *v = keep + (float)eps[i];
        double fp = run_dec(F, 0, NULL, NULL, NULL, NULL, 0, 1);
        *v = keep - (float)eps[i];
        double fm = run_dec(F, 0, NULL, NULL, NULL, NULL, 0, 1);
        *v = keep;
        double n = (fp - fm) / (2 * eps[i]);
        if (fabs(n - a) < berr) berr = fabs(n - a), best = n;
    }
    return best;
}

static void test_decode(int use_box) {
    dec_fixture F;
    fixture(&F, use_box, 7);
    sooc_model *m = F.m;
    int NL = m->NL, dl = m->cfg.d_layout;
    float g_lam[140] = {0}, g_lam0[140] = {0}, g_lay[64] = {0}, g_lay0[64] = {0};
    sooc_model_zero_grad(m);
    double L0 = run_dec(&F, 1, g_lam, g_lam0, g_lay, g_lay0, 1.0f, 0);
    printf("decode loss %.4f (box %d, %d object rows)\n", L0, use_box, F.w->dec->nro);
    CHECK(F.w->dec->nro > 0);
    /* the SG forward equals the plain forward at the base point */
    CHECK_CLOSE(run_dec(&F, 0, NULL, NULL, NULL, NULL, 0, 1), L0, 1e-6, 1e-6);
    double atol = 0.05, rtol = 0.03;
    worst w = {0};
    float *vecs[4] = {F.lam, F.lam0, F.lay, F.lay0};
    float *grads[4] = {g_lam, g_lam0, g_lay, g_lay0};
    int lens[4] = {2 * NL, 2 * NL, 2 * dl, 2 * dl};
    const char *names[4] = {"lam", "lam0", "lay", "lay0"};
    for (int v = 0; v < 4; v++)
        for (int i = 0; i < lens[v]; i++) {
            /* with the box on, moving a slot moves points across the box
             * boundary (a jump in the forward): where-means are checked with
             * the box off only */
            if (use_box && v == 0 && (i % NL) < 3) continue;
            cmp(&w, names[v], i, grads[v][i], fd_best(&F, &vecs[v][i], grads[v][i]), atol, rtol);
        }
    report(&w, use_box ? "decode dL/dlambda (box on)" : "decode dL/dlambda (box off)");
    /* weights: every tensor of both decoders, a few elements each */
    worst ww = {0};
    sooc_rng r;
    sooc_rng_seed(&r, 3, 0);
    for (int t = 0; t < m->nt; t++) {
        if (strncmp(m->t[t].name, "dec.", 4)) continue;
        for (int s = 0; s < 6; s++) {
            size_t i = m->t[t].offset + sooc_rng_below(&r, (uint32_t)m->t[t].count);
            cmp(&ww, m->t[t].name, (int)(i - m->t[t].offset), m->g[i], fd_best(&F, &m->p[i], m->g[i]), atol, rtol);
        }
    }
    report(&ww, use_box ? "decode dL/dweights (box on)" : "decode dL/dweights (box off)");
    fixture_free(&F);
}

/* ---- refinement network: d(sum a*out)/d(weights, vector inputs) over two LSTM steps ---- */
static double ref_run(sooc_model_ws *x, const sooc_ref_net *n, sooc_ref_act a[2], const float *coef, int backward, float *gvec) {
    const sooc_model *m = x->m;
    int gw = m->cfg.ray_w, gh = m->cfg.ray_h, B = a[0].B, H = n->hid;
    float out[2][16 * 80];
    double f = 0;
    memset(a[0].h_prev, 0, sizeof(float) * B * H);
    memset(a[0].c_prev, 0, sizeof(float) * B * H);
    for (int s = 0; s < 2; s++) {
        if (s) {
            memcpy(a[1].h_prev, a[0].h, sizeof(float) * B * H);
            memcpy(a[1].c_prev, a[0].c, sizeof(float) * B * H);
        }
        sooc_mdl_ref_forward(x, n, &a[s], gw, gh, out[s]);
        for (int i = 0; i < B * n->nout; i++) f += coef[s * B * n->nout + i] * out[s][i];
    }
    if (backward) {
        float dh[16 * 128] = {0}, dc[16 * 128] = {0};
        for (int s = 1; s >= 0; s--)
            sooc_mdl_ref_backward(x, n, &a[s], gw, gh, coef + s * B * n->nout, dh, dc, gvec + s * B * n->nvec);
    }
    return f;
}

/* pooled = 1: a 64 x 64 ray grid, whose last conv map (4 x 4) is average-pooled
 * to the 2 x 2 of a 32 x 32 grid before the FC layer (sooc_mdl_ref_flatten). */
static void test_refine(int pooled) {
    sooc_model_config c;
    synth_tiny_cfg(&c, 2, 1);
    if (pooled) c.img_w = c.img_h = c.ray_w = c.ray_h = 64;
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 11));
    sooc_model_ws *x;
    CHECK_OK(sooc_model_ws_create(&x, m));
    sooc_rng r;
    sooc_rng_seed(&r, 5, 0);
    /* the head starts at zero: give it weights so that gradients reach the trunk */
    for (size_t i = 0; i < m->np; i++)
        if (m->p[i] == 0.0f) m->p[i] = 0.1f * (float)sooc_rng_normal(&r);
    for (int which = 0; which < 2; which++) {
        const sooc_ref_net *n = which ? &m->rlay : &m->robj;
        int B = which ? 1 : 2, nin = n->fc + n->nvec;
        sooc_ref_act a[2];
        CHECK_OK(sooc_mdl_ref_act_alloc(n, B, c.ray_w, c.ray_h, &a[0]));
        CHECK_OK(sooc_mdl_ref_act_alloc(n, B, c.ray_w, c.ray_h, &a[1]));
        for (int s = 0; s < 2; s++) {
            for (int i = 0; i < n->cin * B * c.ray_w * c.ray_h; i++) a[s].x0[i] = (float)sooc_rng_normal(&r);
            for (int b = 0; b < B; b++)
                for (int j = 0; j < n->nvec; j++) a[s].xin[b * nin + n->fc + j] = (float)sooc_rng_normal(&r);
        }
        float coef[2 * 16 * 80], gvec[2 * 16 * 160] = {0};
        for (int i = 0; i < 2 * B * n->nout; i++) coef[i] = (float)sooc_rng_normal(&r);
        sooc_model_zero_grad(m);
        ref_run(x, n, a, coef, 1, gvec);
        worst w = {0};
        const char *pre = which ? "ref.lay" : "ref.obj";
        for (int t = 0; t < m->nt; t++) {
            if (strncmp(m->t[t].name, pre, 7)) continue;
            for (int s = 0; s < 5; s++) {
                size_t i = m->t[t].offset + sooc_rng_below(&r, (uint32_t)m->t[t].count);
                float keep = m->p[i];
                double e = 1e-2;
                m->p[i] = keep + (float)e;
                double fp = ref_run(x, n, a, coef, 0, NULL);
                m->p[i] = keep - (float)e;
                double fm = ref_run(x, n, a, coef, 0, NULL);
                m->p[i] = keep;
                cmp(&w, m->t[t].name, (int)(i - m->t[t].offset), m->g[i], (fp - fm) / (2 * e), 1e-2, 2e-2);
            }
        }
        for (int s = 0; s < 2; s++)
            for (int b = 0; b < B; b++)
                for (int j = 0; j < n->nvec; j += 3) {
                    float *v = &a[s].xin[b * nin + n->fc + j], keep = *v;
                    double e = 1e-2;
                    *v = keep + (float)e;
                    double fp = ref_run(x, n, a, coef, 0, NULL);
                    *v = keep - (float)e;
                    double fm = ref_run(x, n, a, coef, 0, NULL);
                    *v = keep;
                    cmp(&w, "vec", j, gvec[(s * B + b) * n->nvec + j], (fp - fm) / (2 * e), 1e-2, 2e-2);
                }
        report(&w, which ? (pooled ? "refinement net (layout, 64x64 rays, pooled)" : "refinement net (layout)")
                         : (pooled ? "refinement net (objects, 64x64 rays, pooled)" : "refinement net (objects)"));
        sooc_mdl_ref_act_free(&a[0]);
        sooc_mdl_ref_act_free(&a[1]);
    }
    sooc_model_ws_destroy(x);
    sooc_model_destroy(m);
}

int main(void) {
    test_pi_gauss();
    test_kl();
    test_decode(0);
    test_decode(1);
    test_refine(0);
    test_refine(1);
    return check_report("test_model_grad");
}
