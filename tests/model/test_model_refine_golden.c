/* The refinement network of the shipped unity model (models/sooc3d_unity/model.bin)
 * against reference numbers of an independent implementation
 * (tests/model/data/refine_golden.txt, written by this program with --write at
 * commit 71da594: refine.c with its own conv, ELU, layer norm and LSTM, and
 * OpenBLAS in its backward):
 *
 *   1. sooc_mdl_ref_forward2 of the object net (K = 7 items, the 8 shared leading
 *      channels stored once) and the layout net on fixed pseudo-random inputs:
 *      outputs, LSTM state;
 *   2. sooc_mdl_ref_backward of both nets from fixed output / state gradients:
 *      dh, dc, the vector-input gradients and the weight gradients (large
 *      arrays as digests: sum, absolute sum and 16 entries at fixed positions);
 *   3. two keyframe updates (query on an empty map, pad with the priors, L = 3
 *      refinements, mean latents, as the mapper runs them; one thread) on
 *      synthetic frames: the refined object and layout latents.
 *
 * Tolerance (docs/engine.md "Determinism contract"): an error bound, not one
 * machine's output. A float32 dot product of length n, summed in ANY order or
 * blocking, lies within gamma_n * sum_i |a_i b_i| of the exact value, with
 * gamma_n = n u / (1 - n u), u = 2^-24 (Higham, Accuracy and Stability of
 * Numerical Algorithms, 2nd ed., eq. 3.5); through a chain of layers whose
 * nonlinearities are 1-Lipschitz or less (ELU, sigmoid, tanh, ReLU) the
 * first-order bounds add, so the reduction length n of a value is the sum of
 * the reduction lengths along its chain (Higham Thm 3.7 for products). Two
 * computations in different orders (another kernel, another code path, the
 * reference's OpenBLAS) each obey it, so
 *
 *     |a - b| <= 2 gamma_n M
 *
 * with n from the nets' shapes (chain_n, wgrad_n: every GEMM of the forward,
 * the backward's input gradients and the value's own weight-gradient sum) and
 * M the magnitude of the terms, taken from the results: |x_j| + mean |x| for
 * an entry (the mean keeps an entry that cancelled to near zero from getting
 * a zero bound), sum |x_j| for a digest's sum and absolute sum. The keyframe
 * latents add the chains of their L iterations (decoder + both refinement
 * nets per iteration). Because the bound holds for every summation order it
 * holds on every BLAS kernel and on both of the project's own kernels.
 *
 * It still fails on a real bug, checked here (negative controls): every value
 * moved by one ulp passes; one layer's gradient with the wrong sign, or the
 * backward with one item's term dropped, fails. Skips (77) when the shipped
 * model is absent. About 1 s in Release.
 *   test_model_refine_golden [--write FILE]
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "model/step.h"
#include "model/synth.h"
#include "model/chain.h"

#define SHIPPED "models/sooc3d_unity/model.bin"
#define GOLDEN "tests/model/data/refine_golden.txt"
#define NSAMP 16

/* negative controls: how the values are corrupted before they are checked */
enum { MUT_NONE, MUT_ULP, MUT_SIGN, MUT_DROP };

/* ------------------------------------------------------------ value stream */

typedef struct gold {
    FILE *w;                 /* --write: the output file                     */
    double *v;               /* check: the reference values                  */
    size_t n, pos;
    double worst;            /* largest |a - b| / bound                      */
    char worst_what[256];
    int probe;               /* negative control: count failures, no CHECK   */
    int mut;                 /* MUT_*: corruption applied before checking    */
    const char *mut_name;    /* MUT_SIGN: the array whose sign is flipped    */
    size_t nfail;            /* values outside their bound                   */
} gold;

/* x against the next reference value: |x - r| <= 2 gamma_n M */
static void put(gold *g, const char *what, double x, double n, double M) {
    if (g->w) {
        fprintf(g->w, "%s %.9g\n", what, x);
        return;
    }
    if (g->pos >= g->n) {
        CHECK_MSG(0, "%s: golden file has only %zu values", what, g->n);
        return;
    }
    double r = g->v[g->pos++], bound = 2.0 * check_gamma_n(n) * M, e = fabs(x - r);
    int ok = e <= bound;
    g->nfail += !ok;
    if (g->probe) return;
    if (!(e / bound <= g->worst)) {
        g->worst = e / bound;
        snprintf(g->worst_what, sizeof g->worst_what, "%s (%.9g vs %.9g, bound %.3g, n %.0f)", what, x, r, bound, n);
    }
    CHECK_MSG(ok, "%s: %.9g, golden %.9g (|a - b| %.3g > 2 gamma_%.0f M = %.3g)", what, x, r, e, n, bound);
}

/* The values as checked: a copy of x, corrupted for the negative controls. */
static const float *mutated(gold *g, const char *what, const float *x, size_t n, float *buf) {
    int flip = g->mut == MUT_SIGN && g->mut_name && !strcmp(what, g->mut_name);
    if (g->mut != MUT_ULP && !flip) return x;
    for (size_t j = 0; j < n; j++)
        buf[j] = flip ? -x[j] : nextafterf(x[j], (j * 2654435761u) & 1 ? INFINITY : -INFINITY);
    return buf;
}

static float mut_buf[1 << 20];

/* Every entry; reduction length nred. */
static void put_arr(gold *g, const char *what, const float *x0, size_t n, double nred) {
    SOOC_ASSERT(n <= sizeof mut_buf / sizeof *mut_buf);
    const float *x = mutated(g, what, x0, n, mut_buf);
    double ma = 0;
    for (size_t i = 0; i < n; i++) ma += fabs(x[i]);
    ma /= (double)n;
    char name[96];
    for (size_t i = 0; i < n; i++) {
        snprintf(name, sizeof name, "%s[%zu]", what, i);
        put(g, name, x[i], nred, fabs(x[i]) + ma);
    }
}

/* Large arrays: sum, absolute sum and NSAMP entries at fixed positions. */
static void put_digest(gold *g, const char *what, const float *x0, size_t n, double nred) {
    SOOC_ASSERT(n <= sizeof mut_buf / sizeof *mut_buf);
    const float *x = mutated(g, what, x0, n, mut_buf);
    double s = 0, sa = 0;
    for (size_t j = 0; j < n; j++) s += x[j], sa += fabs(x[j]);
    char name[96];
    snprintf(name, sizeof name, "%s.sum", what);
    put(g, name, s, nred, sa);
    snprintf(name, sizeof name, "%s.abssum", what);
    put(g, name, sa, nred, sa);
    for (int q = 0; q < NSAMP; q++) {
        size_t j = (size_t)(((uint64_t)q * 2654435761u + 17) % n);
        snprintf(name, sizeof name, "%s[%zu]", what, j);
        put(g, name, x[j], nred, fabs(x[j]) + sa / (double)n);
    }
}

/* ------------------------------------------------------------ reduction lengths */

/* One refinement net, every GEMM along its chain: the forward (four 3x3 convs,
 * fc, the LSTM's input and recurrent products, the head) and the backward's
 * input gradients (head, LSTM gates, fc, the convs' column gradients over the
 * output channels plus the up to 9 overlapping taps of col2im). */
static double chain_n(const sooc_ref_net *n) {
    double s = 9.0 * n->cin + n->nflat + (n->fc + n->nvec) + n->hid + n->hid;   /* forward */
    for (int l = 0; l < 3; l++) s += 9.0 * n->ch[l];
    s += n->nout + 4.0 * n->hid + n->fc;                                          /* backward */
    for (int l = 0; l < 4; l++) s += n->ch[l] + 9.0;
    return s;
}

/* The weight-gradient sum of tensor `name` of a net run on B items of gw x gh:
 * a conv's over its output pixels of all items, the others' over the items. */
static double wgrad_n(const char *name, int B, int gw, int gh) {
    const char *cv = strstr(name, ".conv");
    if (cv && cv[5] >= '1' && cv[5] <= '4') {
        int l = cv[5] - '0';
        return (double)B * (gw >> l) * (gh >> l);
    }
    return B;
}


static int load_golden(gold *g) {
    FILE *f = fopen(GOLDEN, "r");
    if (!f) return -1;
    size_t cap = 1 << 14;
    g->v = malloc(cap * sizeof(double));
    char name[128];
    double x;
    while (g->v && fscanf(f, "%127s %lf", name, &x) == 2) {
        if (g->n == cap) {
            double *nv = realloc(g->v, 2 * cap * sizeof(double));
            if (!nv) break;
            g->v = nv, cap *= 2;
        }
        g->v[g->n++] = x;
    }
    fclose(f);
    return g->v ? 0 : -1;
}

static void fill(float *x, size_t n, sooc_rng *r, float s) {
    for (size_t i = 0; i < n; i++) x[i] = s * (float)sooc_rng_normal(r);
}

/* ------------------------------------------------------------ 1 + 2: the nets */

static void nets(gold *g, sooc_model_ws *w) {
    sooc_model *m = w->m;
    const sooc_model_config *c = sooc_model_get_config(m);
    int K = c->K, gw = c->ray_w, gh = c->ray_h, HW = gw * gh, H = c->ref_hidden;
    const sooc_ref_net *no = &m->robj, *nl = &m->rlay;
    double n_o = chain_n(no), n_l = chain_n(nl);
    sooc_ref_act ao, al;
    CHECK_OK(sooc_mdl_ref_act_alloc(no, K, gw, gh, &ao));
    CHECK_OK(sooc_mdl_ref_act_alloc(nl, 1, gw, gh, &al));
    sooc_rng r;
    sooc_rng_seed(&r, 2021, 4);
    /* images in [0, 1]-ish ranges like the aux inputs; shared channels for item 0 only */
    ao.B = K, ao.nsh = MDL_AUX_NSH, al.B = 1, al.nsh = 0;
    for (int ch = 0; ch < no->cin; ch++)
        for (int b = 0; b < K; b++) {
            if (ch < MDL_AUX_NSH && b > 0) continue;
            fill(ao.x0 + ((size_t)ch * K + b) * HW, (size_t)HW, &r, 0.7f);
        }
    fill(al.x0, (size_t)nl->cin * HW, &r, 0.7f);
    for (int b = 0; b < K; b++) fill(ao.xin + (size_t)b * (no->fc + no->nvec) + no->fc, (size_t)no->nvec, &r, 0.5f);
    fill(al.xin + nl->fc, (size_t)nl->nvec, &r, 0.5f);
    fill(ao.h_prev, (size_t)K * H, &r, 0.3f);
    fill(ao.c_prev, (size_t)K * H, &r, 0.3f);
    fill(al.h_prev, (size_t)H, &r, 0.3f);
    fill(al.c_prev, (size_t)H, &r, 0.3f);
    float *out_o = calloc((size_t)K * no->nout, sizeof(float)), *out_l = calloc((size_t)nl->nout, sizeof(float));
    sooc_mdl_ref_forward2(w, no, &ao, out_o, nl, &al, out_l, gw, gh);
    put_arr(g, "fwd.obj.out", out_o, (size_t)K * no->nout, n_o);
    put_digest(g, "fwd.obj.h", ao.h, (size_t)K * H, n_o);
    put_digest(g, "fwd.obj.c", ao.c, (size_t)K * H, n_o);
    put_arr(g, "fwd.lay.out", out_l, (size_t)nl->nout, n_l);
    put_digest(g, "fwd.lay.h", al.h, (size_t)H, n_l);
    put_digest(g, "fwd.lay.c", al.c, (size_t)H, n_l);
    /* the one-net entry point gives the same numbers */
    float *out1 = calloc((size_t)K * no->nout, sizeof(float));
    sooc_mdl_ref_forward(w, no, &ao, gw, gh, out1);
    double d1 = 0;
    for (int i = 0; i < K * no->nout; i++) d1 = fmax(d1, fabs(out1[i] - out_o[i]));
    CHECK_MSG(d1 == 0, "sooc_mdl_ref_forward vs sooc_mdl_ref_forward2: max diff %.3g", d1);

    /* backward */
    float *go = malloc(sizeof(float) * (size_t)K * no->nout), *gl = malloc(sizeof(float) * (size_t)nl->nout);
    float *dh = malloc(sizeof(float) * (size_t)K * H), *dc = malloc(sizeof(float) * (size_t)K * H);
    float *dhl = malloc(sizeof(float) * (size_t)H), *dcl = malloc(sizeof(float) * (size_t)H);
    float *gvo = calloc((size_t)K * no->nvec, sizeof(float)), *gvl = calloc((size_t)nl->nvec, sizeof(float));
    fill(go, (size_t)K * no->nout, &r, 1.0f);
    fill(gl, (size_t)nl->nout, &r, 1.0f);
    fill(dh, (size_t)K * H, &r, 0.5f);
    fill(dc, (size_t)K * H, &r, 0.5f);
    fill(dhl, (size_t)H, &r, 0.5f);
    fill(dcl, (size_t)H, &r, 0.5f);
    if (g->mut == MUT_DROP) {   /* a dropped term: the last item's gradients never reach the sums */
        memset(go + (size_t)(K - 1) * no->nout, 0, sizeof(float) * (size_t)no->nout);
        memset(dh + (size_t)(K - 1) * H, 0, sizeof(float) * (size_t)H);
        memset(dc + (size_t)(K - 1) * H, 0, sizeof(float) * (size_t)H);
    }
    memset(m->g, 0, m->np * sizeof(float));
    sooc_mdl_ref_backward(w, no, &ao, gw, gh, go, dh, dc, gvo);
    sooc_mdl_ref_backward(w, nl, &al, gw, gh, gl, dhl, dcl, gvl);
    put_digest(g, "bwd.obj.dh", dh, (size_t)K * H, n_o);
    put_digest(g, "bwd.obj.dc", dc, (size_t)K * H, n_o);
    put_digest(g, "bwd.obj.gvec", gvo, (size_t)K * no->nvec, n_o);
    put_digest(g, "bwd.lay.dh", dhl, (size_t)H, n_l);
    put_digest(g, "bwd.lay.dc", dcl, (size_t)H, n_l);
    put_digest(g, "bwd.lay.gvec", gvl, (size_t)nl->nvec, n_l);
    sooc_model_tensor t[MDL_MAXT];
    int ntens = sooc_model_tensors(m, t, MDL_MAXT);
    for (int i = 0; i < ntens && i < MDL_MAXT; i++) {
        if (strncmp(t[i].name, "ref.", 4)) continue;
        char name[96];
        snprintf(name, sizeof name, "grad.%s", t[i].name);
        int obj = !strncmp(t[i].name, "ref.obj.", 8);
        put_digest(g, name, m->g + t[i].offset, t[i].count,
                   (obj ? n_o : n_l) + wgrad_n(t[i].name, obj ? K : 1, gw, gh));
    }
    sooc_mdl_ref_act_free(&ao);
    sooc_mdl_ref_act_free(&al);
    free(out_o), free(out_l), free(out1), free(go), free(gl), free(dh), free(dc), free(dhl), free(dcl), free(gvo),
        free(gvl);
}

/* ------------------------------------------------------------ 3: keyframe updates */

/* The refined latents of both keyframes, also copied to out (n floats, at most cap). */
static void keyframes(gold *g, sooc_model_ws *w, float *out, size_t cap, size_t *n) {
    sooc_model *m = w->m;
    const sooc_model_config *c = sooc_model_get_config(m);
    int L = 3, NL = MDL_NL(c->d_what), D2 = 2 * c->d_layout;
    /* per iteration: both decoders, both refinement nets and their weight-free
     * input gradients; the iterations' first-order errors add */
    SOOC_ASSERT((size_t)2 * (c->K * NL + D2) <= cap);
    double n_kf = L * (dec_chain_n(&m->dobj) + dec_chain_n(&m->dlay) + chain_n(&m->robj) + chain_n(&m->rlay));
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = c->d_what;
    cp.layout_dim = c->d_layout;
    cp.block_size = (double)c->block_size * c->unit_m;
    sooc_cogmap *map = NULL;
    CHECK_OK(sooc_cogmap_create(&map, &cp));
    sooc_view_rec V;
    memset(&V, 0, sizeof V);
    CHECK_OK(sooc_mdl_view_alloc(m, &V, L));
    sooc_step_state *S = sooc_mdl_step_state(w, 1, L);
    CHECK(S != NULL);
    if (!map || !S) return;
    synth_sphere sp[4] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}},
                          {{1.2, 0.35, 4.5}, 0.35, {0.2f, 0.8f, 0.2f}}, {{-1.5, 0.5, 5.0}, 0.5, {0.8f, 0.8f, 0.1f}}};
    sooc_rng rng;
    sooc_rng_seed(&rng, 77, 0x6d6170ULL);
    for (int v = 0; v < 2; v++) {
        double T[16];
        synth_pose(T, 0.3 * v, 1.5, -0.5 + 0.2 * v, 0.15 * v, -0.45);
        sooc_frame f;
        CHECK_OK(synth_frame(&f, c->img_w, c->img_h, 60, T, sp, 4));
        f.index = v, f.t_ns = (int64_t)v * 100000000;
        S->aux_replay = 0;
        CHECK_OK(sooc_mdl_view_setup(m, map, &V, &f, 1, &rng, NULL));
        sooc_step_opts o;
        sooc_step_opts_default(&o);
        o.tau = 0.7f;   /* the mapper's */
        o.L = L;
        o.mean_latents = 1;
        double lw = 0;
        CHECK_OK(sooc_mdl_view_forward(w, S, &V, L, &o, 0, &rng, &lw, NULL));
        char name[64];
        snprintf(name, sizeof name, "kf%d.lam", v);
        put_arr(g, name, V.lam + (size_t)L * c->K * NL, (size_t)c->K * NL, n_kf);
        memcpy(out + *n, V.lam + (size_t)L * c->K * NL, sizeof(float) * (size_t)c->K * NL), *n += (size_t)c->K * NL;
        snprintf(name, sizeof name, "kf%d.lay", v);
        put_arr(g, name, V.lay + (size_t)L * D2, (size_t)D2, n_kf);
        memcpy(out + *n, V.lay + (size_t)L * D2, sizeof(float) * (size_t)D2), *n += (size_t)D2;
        sooc_frame_free(&f);
    }
    sooc_mdl_view_free(&V);
    sooc_cogmap_destroy(map);
}

/* Negative control: the nets again with corrupted values, counting failures. */
static size_t control(gold *g, sooc_model_ws *w, int mut, const char *mut_name) {
    gold c = *g;
    c.pos = 0, c.nfail = 0, c.probe = 1, c.mut = mut, c.mut_name = mut_name;
    nets(&c, w);
    return c.nfail;
}

int main(int argc, char **argv) {
    const char *wpath = argc == 3 && !strcmp(argv[1], "--write") ? argv[2] : NULL;
    if (argc > 1 && !wpath) {
        fprintf(stderr, "usage: test_model_refine_golden [--write FILE]\n");
        return 2;
    }
    FILE *mf = fopen(SHIPPED, "rb");
    if (!mf) {
        printf("test_model_refine_golden: SKIP (%s not found; run from the repository root)\n", SHIPPED);
        return SOOC_TEST_SKIP;
    }
    fclose(mf);
    gold g;
    memset(&g, 0, sizeof g);
    if (wpath) {
        if (!(g.w = fopen(wpath, "w"))) return fprintf(stderr, "cannot write %s\n", wpath), 1;
    } else if (load_golden(&g)) {
        fprintf(stderr, "test_model_refine_golden: cannot read %s\n", GOLDEN);
        return 1;
    }
    sooc_model *m;
    if (sooc_model_load(&m, SHIPPED, NULL, NULL)) return fprintf(stderr, "%s\n", sooc_errmsg()), 1;
    sooc_model_set_threads(m, 2);
    sooc_model_ws *w;
    if (sooc_model_ws_create(&w, m)) return fprintf(stderr, "%s\n", sooc_errmsg()), 1;
    nets(&g, w);
    double worst_nets = g.worst;
    size_t f_ulp = 0, f_sign = 0, f_drop = 0;
    if (!g.w) {
        f_ulp = control(&g, w, MUT_ULP, NULL);
        f_sign = control(&g, w, MUT_SIGN, "grad.ref.obj.fc.W");
        f_drop = control(&g, w, MUT_DROP, NULL);
        CHECK_MSG(f_ulp == 0, "control: every value moved by one ulp must pass (%zu failed)", f_ulp);
        CHECK_MSG(f_sign > 0, "control: the fc weight gradient with the wrong sign must fail");
        CHECK_MSG(f_drop > 0, "control: the backward without the last item's term must fail");
    }
    /* the keyframe updates on one thread, then on two: no weight gradient, so
     * bitwise the same (docs/engine.md "Determinism contract", item 2) */
    static float kf1[1 << 14], kf2[1 << 14];
    size_t n1 = 0, n2 = 0;
    sooc_model_set_threads(m, 1);
    keyframes(&g, w, kf1, sizeof kf1 / sizeof *kf1, &n1);
    if (!g.w) {
        gold c = g;
        c.probe = 1;
        c.pos -= n1;
        sooc_model_set_threads(m, 2);
        keyframes(&c, w, kf2, sizeof kf2 / sizeof *kf2, &n2);
        CHECK_MSG(n1 == n2 && !memcmp(kf1, kf2, n1 * sizeof(float)),
                  "the keyframe latents differ between one and two threads");
    }
    sooc_model_ws_destroy(w);
    sooc_model_destroy(m);
    if (g.w) {
        fclose(g.w);
        printf("test_model_refine_golden: wrote %s\n", wpath);
        return 0;
    }
    CHECK_MSG(g.pos == g.n, "golden file has %zu values, the test produced %zu", g.n, g.pos);
    printf("test_model_refine_golden: %zu values, worst |a - b| / bound: nets %.3g, overall %.3g at %s; "
           "controls: one ulp %zu failed, wrong sign %zu failed, dropped term %zu failed\n",
           g.pos, worst_nets, g.worst, g.worst_what, f_ulp, f_sign, f_drop);
    free(g.v);
    return check_report("test_model_refine_golden");
}
