/* The shipped models give the same outputs as at the commit that wrote
 * tests/model/data/golden.txt (the decode and the step, on the engine's kernels).
 *
 * For every shipped checkpoint (models/{sooc3d_unity,sooc3d_tabletop,
 * baseline_global}/model.bin; a missing one is skipped with a message), on a
 * fixed synthetic view at the model's resolution, one thread:
 *   - one decode forward + backward from the slot priors plus fixed offsets
 *     (sooc_mdl_decode): loss, nll_d, nll_c, kl, z^pres, the first 4 slots' λ and the layout gradients, the
 *     decoder weight gradients (first 16 of each of dec.obj / dec.lay, their
 *     sum of squares);
 *   - one training step on two input views and one query view
 *     (sooc_model_train_step / sooc_model_global_train_step): the losses and
 *     the gradient slab (norm and 16 fixed entries).
 * The decode numbers must lie within the float error bound of their chain
 * (docs/engine.md "Determinism contract"): |a - b| <= 2 gamma_n M, with
 * gamma_n = n u / (1 - n u), u = 2^-24, n the reduction lengths along a ray's
 * chain (both decoders forward and backward, the K + 1 components of the
 * composite density, the two samples of the depth likelihood; the sums over
 * rays are in float64) and M = max(1, |b|) for a scalar, the group's largest
 * |b| for a vector. Any summation order obeys it, so it holds on every kernel:
 * the decode groups of both the AVX2 and the portable kernel are compared
 * against the same golden.txt. Negative controls on every decode group: all
 * values moved by one float ulp pass, the largest one with the wrong sign fails.
 *
 * The training step is not continuous in rounding, so no rounding bound
 * exists for it: it is compared at 2e-3 (losses) and 3e-2 (gradients, of the
 * group's largest), against the reference of the kernel that runs (golden.txt
 * for AVX2/FMA, golden_portable.txt for the portable kernel; both kernels are
 * bitwise reproducible across machines and BLAS kernels). Its refinement moves the
 * slots, points cross the locality boxes' faces (a row of the object MLP
 * appears or vanishes) and presences cross 0.5 (straight-through, registration),
 * so a change of the last bit in one decoder expression (measured: the colour
 * head's input gradient written as two FMAs instead of multiply-adds) moves
 * the step's losses by up to 3e-4 relative and single gradient norms by up to
 * 0.8% of the largest, while every decode number stays within 4e-7 of its
 * group's scale.
 *
 *   test_model_golden            compare against tests/model/data/golden.txt
 *   test_model_golden --write F  write the reference numbers to F */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "model/step.h"
#include "sooc3d/train.h"
#include "nn/nn_kern.h"
#include "model/synth.h"
#include "model/chain.h"

#define GOLDEN "tests/model/data/golden.txt"
#define GOLDEN_PORTABLE "tests/model/data/golden_portable.txt"
#define MAXV 4096
#define TOL_STEP_LOSS 2e-3
#define TOL_STEP_GRAD 3e-2

static const char *models[] = {"models/sooc3d_unity/model.bin", "models/sooc3d_tabletop/model.bin",
                               "models/baseline_global/model.bin"};

/* one named group of numbers */
typedef struct group {
    char name[96];
    int n;
    double v[MAXV];
} group;

static group g_cur;
static FILE *g_out;
static char *g_ref;      /* reference file text: golden.txt                                 */
static char *g_ref_step; /* the step's: golden.txt or, on the portable kernel, its own file */
static int g_groups;

static void grp_begin(const char *model, const char *what) {
    snprintf(g_cur.name, sizeof g_cur.name, "%s:%s", model, what);
    g_cur.n = 0;
}
static void grp_add(double v) {
    if (g_cur.n < MAXV) g_cur.v[g_cur.n++] = v;
}

/* Scalars: each within tol max(1, |ref|). Vectors ("scale" set): each within tol max(1, max |ref|).
 * ref: the reference text; controls: also run the one-ulp and wrong-sign controls. */
static void grp_end_ref(const char *refs, int scale, double tol0, int controls) {
    g_groups++;
    if (g_out) {
        fprintf(g_out, "%s %d", g_cur.name, g_cur.n);
        for (int i = 0; i < g_cur.n; i++) fprintf(g_out, " %.9g", g_cur.v[i]);
        fputc('\n', g_out);
        return;
    }
    size_t nl = strlen(g_cur.name);
    const char *p = refs;
    while (p && *p) {
        if (!strncmp(p, g_cur.name, nl) && p[nl] == ' ') break;
        p = strchr(p, '\n');
        if (p) p++;
    }
    CHECK_MSG(p && *p, "%s: no reference line in %s", g_cur.name, GOLDEN);
    if (!p || !*p) return;
    char *e;
    long n = strtol(p + nl, &e, 10);
    CHECK_MSG(n == g_cur.n, "%s: %d numbers, reference has %ld", g_cur.name, g_cur.n, n);
    if (n != g_cur.n) return;
    static double ref[MAXV];
    double mx = 1;
    for (int i = 0; i < n; i++) {
        ref[i] = strtod(e, &e);
        if (scale && fabs(ref[i]) > mx) mx = fabs(ref[i]);
    }
    double worst = 0;
    int wi = 0;
    for (int i = 0; i < n; i++) {
        double tol = tol0 * (scale ? mx : fmax(1.0, fabs(ref[i])));
        double r = fabs(g_cur.v[i] - ref[i]) / tol;
        if (!(r <= worst)) worst = r, wi = i;
    }
    printf("  %-40s %4ld numbers, worst |diff| / tol = %.3g (tol %.2g; #%d: %.9g vs %.9g)\n", g_cur.name, n, worst,
           tol0, wi, g_cur.v[wi], ref[wi]);
    CHECK_MSG(worst <= 1.0, "%s: #%d = %.9g, reference %.9g", g_cur.name, wi, g_cur.v[wi], ref[wi]);
    if (!controls) return;
    double ulp_worst = 0;
    int big = 0;
    for (int i = 0; i < n; i++) {
        float f = (float)g_cur.v[i], fu = nextafterf(f, (i & 1) ? INFINITY : -INFINITY);
        double tol = tol0 * (scale ? mx : fmax(1.0, fabs(ref[i])));
        ulp_worst = fmax(ulp_worst, fabs((double)fu - ref[i]) / tol);
        if (fabs(ref[i]) > fabs(ref[big])) big = i;
    }
    double tolb = tol0 * (scale ? mx : fmax(1.0, fabs(ref[big])));
    CHECK_MSG(ulp_worst <= 1.0, "%s: control: values one ulp off fail the bound (%.3g)", g_cur.name, ulp_worst);
    CHECK_MSG(fabs(-g_cur.v[big] - ref[big]) > tolb || ref[big] == 0, "%s: control: #%d with the wrong sign passes",
              g_cur.name, big);
}

static void grp_end(int scale, double tol0, int controls) { grp_end_ref(g_ref, scale, tol0, controls); }

static const synth_sphere g_sp[3] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}},
                                     {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}},
                                     {{0.9, 0.25, 2.0}, 0.25, {0.2f, 0.8f, 0.2f}}};

static void check_decode(sooc_model_ws *w, const char *tag, const sooc_frame *f) {
    sooc_model *m = w->m;
    const sooc_model_config *c = &m->cfg;
    int K = c->K, NL = m->NL, dl = c->d_layout;
    /* a ray's chain: both decoders (layer 1 on the positional code and the slot
     * latent, two hidden layers, the colour layer, the heads; forward and
     * backward), the K + 1 components, the two depth samples */
    double nred = K + 1 + 2 + dec_chain_n(&m->dobj) + dec_chain_n(&m->dlay);
    const double TOL = 2.0 * check_gamma_n(nred);
    printf("  decode bound: 2 gamma_n with n = %.0f: %.3g of the group's scale\n", nred, TOL);
    sooc_view_rays vr;
    CHECK_OK(sooc_mdl_rays_alloc(&vr, c->ray_w, c->ray_h));
    sooc_rng r;
    sooc_rng_seed(&r, 77, 0);
    double T_wg[16];
    memcpy(T_wg, f->T_wc, sizeof T_wg);   /* G frame: the camera's position, axes of the world */
    T_wg[0] = 1, T_wg[1] = 0, T_wg[2] = 0, T_wg[4] = 0, T_wg[5] = 1, T_wg[6] = 0, T_wg[8] = 0, T_wg[9] = 0, T_wg[10] = 1;
    double blk[2] = {0, 0};
    CHECK_OK(sooc_mdl_make_rays(m, f, 0, 0, &r, &vr, T_wg, T_wg[7], -0.45, blk));
    float lam[SOOC_MODEL_K_MAX * (6 + 2 * SOOC_MODEL_D_MAX)], lay[2 * SOOC_MODEL_D_MAX];
    float g_lam[SOOC_MODEL_K_MAX * (6 + 2 * SOOC_MODEL_D_MAX)], g_lay[2 * SOOC_MODEL_D_MAX];
    memcpy(lam, m->p + m->prior, sizeof(float) * (size_t)K * NL);
    for (int k = 0; k < K; k++) {   /* move the slots into the view a little, deterministically */
        lam[k * NL + 0] += 0.1f * (float)((k % 3) - 1);
        lam[k * NL + 1] += 0.05f * (float)(k % 2);
        for (int i = 5; i < NL; i++) lam[k * NL + i] += 0.02f * (float)(((k + i) % 5) - 2);
    }
    memcpy(lay, m->p + m->prior_lay, sizeof(float) * 2 * dl);
    for (int i = 0; i < dl; i++) lay[i] += 0.03f * (float)((i % 3) - 1);
    sooc_dec_noise nz;
    sooc_mdl_sample_noise(m, &r, &nz);
    memset(g_lam, 0, sizeof g_lam);
    memset(g_lay, 0, sizeof g_lay);
    sooc_dec_call dc;
    memset(&dc, 0, sizeof dc);
    dc.rays = &vr;
    dc.nslot = K;
    dc.lam = lam;
    dc.lam0 = m->p + m->prior;
    dc.lay = lay;
    dc.lay0 = m->p + m->prior_lay;
    dc.noise = &nz;
    dc.tau = 1.0f;
    dc.beta_kl = 1.0f;
    dc.wgrad = 1.0f;
    dc.backward = 1;
    dc.g_lam = g_lam;
    dc.g_lay = g_lay;
    sooc_model_zero_grad(m);
    CHECK_OK(sooc_mdl_decode(w, &dc));
    grp_begin(tag, "decode.loss");
    grp_add(dc.loss), grp_add(dc.nll_d), grp_add(dc.nll_c), grp_add(dc.kl);
    for (int k = 0; k < K; k++) grp_add(dc.zp[k]);
    grp_end(0, TOL, 1);
    grp_begin(tag, "decode.g_lam");
    for (int i = 0; i < K * NL && i < 4 * NL; i++) grp_add(g_lam[i]);   /* the first 4 slots */
    for (int i = 0; i < 2 * dl; i++) grp_add(g_lay[i]);
    grp_end(1, TOL, 1);
    const sooc_dec_net *nets[2] = {&m->dobj, &m->dlay};
    for (int q = 0; q < 2; q++) {
        const sooc_dec_net *n = nets[q];
        size_t offs[] = {n->W1x, n->W1z, n->b1, n->W2, n->b2, n->W3, n->b3, n->Wd, n->bd, n->Wc1, n->bc1, n->Wc2, n->bc2};
        size_t cnt[] = {(size_t)n->din * n->H, (size_t)n->dz * n->H, (size_t)n->H, (size_t)n->H * n->H, (size_t)n->H,
                        (size_t)n->H * n->H, (size_t)n->H, (size_t)n->H, 1, (size_t)n->H * n->Hc, (size_t)n->Hc,
                        (size_t)n->Hc * 3, 3};
        grp_begin(tag, q ? "decode.g_dec_lay" : "decode.g_dec_obj");
        for (int t = 0; t < 13; t++) {
            double ss = 0;
            for (size_t i = 0; i < cnt[t]; i++) ss += (double)m->g[offs[t] + i] * m->g[offs[t] + i];
            grp_add(sqrt(ss));
            for (size_t i = 0; i < cnt[t] && i < 4; i++) grp_add(m->g[offs[t] + i * 7 % cnt[t]]);
        }
        grp_end(1, TOL, 1);
    }
    sooc_mdl_rays_free(&vr);
}

static void check_step(sooc_model_ws *w, const char *tag, const sooc_frame *F) {
    sooc_model *m = w->m;
    sooc_step_opts o;
    sooc_step_opts_default(&o);
    sooc_step_losses l;
    memset(&l, 0, sizeof l);
    sooc_rng r;
    sooc_rng_seed(&r, 4242, 0);
    sooc_model_zero_grad(m);
    if (sooc_model_is_global(m)) CHECK_OK(sooc_model_global_train_step(w, F, 2, F + 2, 1, 3, &o, &r, &l));
    else CHECK_OK(sooc_model_train_step(w, F, 2, F + 2, 1, &o, &r, &l));
    grp_begin(tag, "step.losses");
    grp_add(l.total), grp_add(l.nll_input), grp_add(l.kl), grp_add(l.nll_query), grp_add(l.nll_depth);
    grp_add(l.nll_color), grp_add(l.present_slots), grp_add(l.mean_pres_logit), grp_add(l.map_entries);
    grp_add(l.nonfinite);
    grp_end_ref(g_ref_step, 0, TOL_STEP_LOSS, 0);
    size_t np = sooc_model_param_count(m);
    const float *g = sooc_model_grads(m);
    grp_begin(tag, "step.grads");
    sooc_model_tensor t[MDL_MAXT];
    int nt = sooc_model_tensors(m, t, MDL_MAXT);
    for (int i = 0; i < nt && i < MDL_MAXT; i++) {   /* per-tensor gradient norms */
        double ss = 0;
        for (size_t j = 0; j < t[i].count; j++) ss += (double)g[t[i].offset + j] * g[t[i].offset + j];
        grp_add(sqrt(ss));
    }
    for (int i = 0; i < 16; i++) grp_add(g[(size_t)i * 7919 % np]);
    grp_end_ref(g_ref_step, 1, TOL_STEP_GRAD, 0);
}

/* A whole text file, NUL-terminated (NULL on error, sooc_errmsg says why). */
static char *read_text(const char *path) {
    void *buf;
    size_t n;
    if (sooc_file_read_all(path, (size_t)1 << 22, &buf, &n)) return NULL;
    char *z = sooc_malloc(n + 1);
    if (z) memcpy(z, buf, n), z[n] = 0;
    sooc_free(buf);
    return z;
}

int main(int argc, char **argv) {
    const char *write = NULL;
    if (argc == 3 && !strcmp(argv[1], "--write")) write = argv[2];
    else if (argc != 1) {
        fprintf(stderr, "usage: test_model_golden [--write FILE]\n");
        return 2;
    }
    if (write) {
        g_out = fopen(write, "w");
        if (!g_out) return fprintf(stderr, "cannot write %s\n", write), 1;
        fprintf(g_out, "# test_model_golden reference numbers (one group a line: name count values)\n");
    } else {
        if (!(g_ref = read_text(GOLDEN))) {
            printf("test_model_golden: SKIP: %s not found (run from the repository root): %s\n", GOLDEN, sooc_errmsg());
            return SOOC_TEST_SKIP;
        }
        g_ref_step = g_ref;
        if (!sooc_nn_gemm_avx2() && !(g_ref_step = read_text(GOLDEN_PORTABLE))) {
            fprintf(stderr, "test_model_golden: cannot read %s: %s\n", GOLDEN_PORTABLE, sooc_errmsg());
            return 1;
        }
        printf("test_model_golden: %s kernel; step reference %s\n", sooc_nn_gemm_avx2() ? "AVX2/FMA" : "portable",
               sooc_nn_gemm_avx2() ? GOLDEN : GOLDEN_PORTABLE);
    }
    int nrun = 0;
    for (size_t i = 0; i < sizeof models / sizeof models[0]; i++) {
        FILE *fp = fopen(models[i], "rb");
        if (!fp) {
            printf("test_model_golden: %s not found, skipped\n", models[i]);
            continue;
        }
        fclose(fp);
        sooc_model *m = NULL;
        CHECK_OK(sooc_model_load(&m, models[i], NULL, NULL));
        if (!m) continue;
        sooc_model_set_threads(m, 1);
        const sooc_model_config *c = sooc_model_get_config(m);
        double T[3][16];
        double s = c->unit_m;   /* the scene in the model's metres */
        synth_pose(T[0], 0, 1.5 * s, 0, 0.1, -0.45);
        synth_pose(T[1], 0.4 * s, 1.4 * s, 0.3 * s, -0.1, -0.4);
        synth_pose(T[2], -0.3 * s, 1.5 * s, 0.2 * s, 0.2, -0.45);
        synth_sphere sp[3];
        for (int j = 0; j < 3; j++) {
            sp[j] = g_sp[j];
            for (int a = 0; a < 3; a++) sp[j].c[a] *= s;
            sp[j].r *= s;
        }
        sooc_frame F[3];
        memset(F, 0, sizeof F);
        for (int j = 0; j < 3; j++) CHECK_OK(synth_frame(&F[j], c->img_w, c->img_h, 60, T[j], sp, 3));
        char tag[64];
        const char *a = strchr(models[i], '/'), *b = a ? strchr(a + 1, '/') : NULL;
        snprintf(tag, sizeof tag, "%.*s", a && b ? (int)(b - a - 1) : 8, a ? a + 1 : models[i]);
        printf("%s: K %d, %dx%d rays, width %d\n", tag, c->K, c->ray_w, c->ray_h, c->dec_width);
        sooc_model_ws *w;
        CHECK_OK(sooc_model_ws_create(&w, m));
        check_decode(w, tag, &F[0]);
        check_step(w, tag, F);
        for (int j = 0; j < 3; j++) sooc_frame_free(&F[j]);
        sooc_model_ws_destroy(w);
        sooc_model_destroy(m);
        nrun++;
    }
    if (g_out) {
        fclose(g_out);
        printf("test_model_golden: wrote %d groups to %s\n", g_groups, write);
        return 0;
    }
    if (g_ref_step != g_ref) sooc_free(g_ref_step);
    sooc_free(g_ref);
    if (!nrun) {
        printf("test_model_golden: SKIP: no shipped model found\n");
        return SOOC_TEST_SKIP;
    }
    return check_report("test_model_golden");
}
