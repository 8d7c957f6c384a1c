/* EM finetuning (include/sooc3d/train.h, docs/finetune.md) on a toy scene: two
 * spheres on a checkered floor, four views, the tiny model of the model tests.
 *  1. Finite differences of Σ ℓ with respect to a unit's copied weights and
 *     z^what (object and layout units) against the M-step gradient.
 *  2. The log-likelihood never falls over E/M rounds (full batch, fixed
 *     samples, small steps), and rises in all.
 *  3. Finetuning lowers the rendering error of the views (the model's field
 *     draws the finetuned decoders from the map's payloads).
 *  4. The layout and per-unit ray lists: an object's rays all cross its box. */
#include "check.h"
#include "finetune/finetune_impl.h"
#include "toy_scene.h"
#include "sooc3d/train.h"
#include "sooc3d/render.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* RGB RMSE (channel sum) of the field's renders of the views against them. */
static double render_err(sooc_model *m, const sooc_cogmap *map, const sooc_frame *fr) {
    double se = 0;
    size_t n = 0;
    sooc_render_out ro;
    memset(&ro, 0, sizeof ro);
    for (int v = 0; v < NV; v++) {
        sooc_model_field *fld = NULL;
        if (sooc_model_field_create(&fld, m, map, fr[v].T_wc, &fr[v].K, -1, NULL)) return NAN;
        sooc_render_opts o;
        sooc_render_opts_default(&o);
        o.n_coarse = 48, o.n_fine = 16, o.t_near = 0.1, o.d_clip = 5, o.threads = 1;
        double T_fc[16];
        sooc_model_field_T_fc(fld, T_fc);
        sooc_status st = sooc_render_view(sooc_model_field_get(fld), &fr[v].K, T_fc, &o, &ro);
        sooc_model_field_destroy(fld);
        if (st) return NAN;
        for (int i = 0; i < 32 * 32; i++) {
            for (int a = 0; a < 3; a++) {
                double d = ro.rgb[3 * i + a] - fr[v].rgb[3 * i + a] / 255.0;
                se += d * d;
            }
            n++;
        }
    }
    sooc_render_out_free(&ro);
    return sqrt(se / (double)n);
}

/* Central differences of Σ ℓ over `rays` w.r.t. some of unit k's weights and
 * all of its z, against sooc_ft_objective's gradient. float32 forward: step h on
 * parameters of size ~0.1-1, rays few enough that Σ ℓ is O(10); an element
 * whose difference quotients at h and h/2 disagree crossed a ReLU kink and is
 * not compared (at most 15% may). */
static void fd_check(sooc_finetune *ft, int k, const char *what) {
    sooc_ft_comp *c = &ft->comp[k];
    /* 30 rays whose surface lies in the unit's box (so its colour and density at
     * the surface matter; with the support plane on, up to 15 of them on the
     * plane first), then 10 others */
    uint32_t rays[40];
    size_t n = 0, n_sup = 0;
    const sooc_model_config *mc = &ft->m->cfg;
    for (size_t j = 0; j < 2 * c->nrays && n < 30; j++) {
        uint32_t r = c->rays[(j * 7919) % c->nrays];
        int pass0 = j < c->nrays;
        if (!ft->surf[r] || (pass0 && (ft->surf[r] != 2 || n_sup >= 15)) || (!pass0 && ft->surf[r] == 2)) continue;
        const sooc_ft_view *v = &ft->views[ft->rview[r]];
        float x[3], xk[3];
        float off = ft->surf[r] == 2 ? -0.01f : 0.01f;   /* support-plane samples lie in front */
        for (int a = 0; a < 3; a++) x[a] = (ft->depth[r] + off) * ft->dir[(size_t)r * 3 + a];
        int in = c->kind == SOOC_FT_LAYOUT;
        for (int q = 0; q < v->nc && !in; q++)
            if (v->comp[q] == (int)(c - ft->comp)) {
                sooc_mdl_pi(x, v->pose[q][0], v->pose[q][1], v->pose[q][2], v->h, xk);
                in = fabsf(xk[0]) <= mc->box_rh && fabsf(xk[2]) <= mc->box_rh && xk[1] >= 0 && xk[1] <= mc->box_hb;
            }
        if (in) rays[n++] = r, n_sup += ft->surf[r] == 2;
    }
    CHECK(n == 30);
    CHECK(ft->p.support_m <= 0 || n_sup >= 10);
    for (size_t j = 0; n < 40 && j < c->nrays; j++) rays[n++] = c->rays[(j * 104729) % c->nrays];
    size_t nw = c->nw;
    int dz = c->net->dz;
    float *gw = calloc(nw, sizeof(float));
    float gz[SOOC_MODEL_D_MAX] = {0};
    double ll0 = 0;
    CHECK_OK(sooc_ft_objective(ft, k, rays, n, 11, gw, gz, &ll0));
    sooc_rng r;
    sooc_rng_seed(&r, 5, (uint64_t)k);
    int tested = 0, kinks = 0, bad = 0;
    double worst = 0;
    double gmax = 0;
    for (size_t i = 0; i < nw; i++) gmax = fabs(gw[i]) > gmax ? fabs(gw[i]) : gmax;
    for (int t = 0; t < 60 + dz; t++) {
        int isz = t >= 60;
        size_t i = isz ? (size_t)(t - 60) : (size_t)sooc_rng_below(&r, (uint32_t)nw);
        float *p = isz ? &c->z[i] : &c->w[i];
        double ga = isz ? gz[i] : gw[i];
        double q[2];
        for (int s = 0; s < 2; s++) {
            float h = s ? 1e-3f : 2e-3f, p0 = *p;
            double lp = 0, lm = 0;
            *p = p0 + h;
            sooc_ft_comp_bias(c);
            sooc_ft_objective(ft, -1, rays, n, 11, NULL, NULL, &lp);
            *p = p0 - h;
            sooc_ft_comp_bias(c);
            sooc_ft_objective(ft, -1, rays, n, 11, NULL, NULL, &lm);
            *p = p0;
            sooc_ft_comp_bias(c);
            q[s] = (lp - lm) / (2.0 * ((double)(p0 + h) - (double)(p0 - h)) / 2.0);
        }
        double scale = fabs(q[0]) > fabs(q[1]) ? fabs(q[0]) : fabs(q[1]);
        if (fabs(q[0] - q[1]) > 0.05 * scale + 2e-3 * gmax) {
            kinks++;
            continue;
        }
        tested++;
        double gn = q[1], err = fabs(ga - gn), tol = 3e-3 * gmax + 3e-2 * fmax(fabs(ga), fabs(gn));
        if (err / tol > worst) worst = err / tol;
        if (err > tol) {
            bad++;
            fprintf(stderr, "%s: %s[%zu] analytic %.6g numeric %.6g\n", what, isz ? "z" : "w", i, ga, gn);
        }
    }
    printf("%s: FD of sum ell (%zu rays, %zu on the support plane, ell %.4f): %d elements compared, %d at a kink, "
           "worst %.3f of tol\n", what, n, n_sup, ll0, tested, kinks, worst);
    CHECK_MSG(bad == 0, "%s: %d elements off", what, bad);
    CHECK_MSG(kinks * 100 <= 15 * (60 + dz), "%s: %d of %d elements at kinks", what, kinks, 60 + dz);
    CHECK(tested >= 40);
    free(gw);
}

int main(void) {
    sooc_model_config cfg;
    synth_tiny_cfg(&cfg, 2, 1);
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_create(&m, &cfg, 3));
    sooc_frame fr[NV];
    memset(fr, 0, sizeof fr);
    CHECK_OK(make_views(fr));
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = cfg.d_what, cp.layout_dim = cfg.d_layout, cp.block_size = cfg.block_size;
    sooc_cogmap *map = NULL;
    CHECK_OK(sooc_cogmap_create(&map, &cp));
    for (int i = 0; i < 2; i++) {
        sooc_cogmap_entry e;
        memset(&e, 0, sizeof e);
        e.X = k_sp[i].c[0], e.Z = k_sp[i].c[2], e.Theta = 0.3 * i, e.rho_t = -4, e.rho_theta = -2, e.pres_logit = 3;
        e.dim = cfg.d_what, e.obs_count = 1;
        for (int j = 0; j < cfg.d_what; j++) e.what_mu[j] = 0.3f * (float)((i + j) % 3) - 0.3f, e.what_logvar[j] = -2;
        CHECK_OK(sooc_cogmap_insert(map, &e, NULL));
    }
    if (g_check_fail) return check_report("test_finetune_em");

    sooc_finetune_params p;
    sooc_finetune_params_default(&p);
    p.rays = 0, p.fixed_samples = 1, p.seed = 11, p.iterations = 4, p.lr = p.lr_z = 3e-4f;
    sooc_finetune *ft = NULL;
    CHECK_OK(sooc_finetune_create(&ft, m, map, &p));
    for (int v = 0; v < NV; v++) CHECK_OK(sooc_finetune_add_view(ft, &fr[v]));
    int nu = sooc_finetune_n_units(ft);
    int n_obj = 0, n_lay = 0;
    for (int u = 0; u < nu; u++) {
        sooc_finetune_unit un;
        CHECK_OK(sooc_finetune_unit_get(ft, u, &un));
        n_obj += un.kind == SOOC_FT_OBJECT, n_lay += un.kind == SOOC_FT_LAYOUT;
        CHECK(un.n_rays > 0 && un.n_views >= 1);
    }
    printf("toy scene: %d views, %zu rays, %d object units, %d layout units\n", NV, ft->nr, n_obj, n_lay);
    CHECK(n_obj == 2 && n_lay >= 1);
    /* 4. every ray of an object unit crosses its box: its surface or air sample
     * must be inside for at least some rays, and a ray of another view never
     * lists a component that is not in that view */
    for (int u = 0; u < nu; u++) {
        const sooc_ft_comp *c = &ft->comp[ft->units[u]];
        if (c->kind != SOOC_FT_OBJECT) continue;
        CHECK(c->nrays < ft->nr);   /* restricted: not every ray */
    }

    /* 1. gradient check: first object unit and the first layout unit */
    for (int u = 0; u < nu; u++) {
        const sooc_ft_comp *c = &ft->comp[ft->units[u]];
        if (u == 0 || (c->kind == SOOC_FT_LAYOUT && (u == 0 || ft->comp[ft->units[u - 1]].kind == SOOC_FT_OBJECT)))
            fd_check(ft, ft->units[u], c->kind == SOOC_FT_OBJECT ? "object" : "layout");
    }

    /* 1b. the same with the support plane on (docs/finetune.md "The support
     * plane"): floor rays within 5 cm of it carry the layout-only surface term
     * and the objects' penalty */
    {
        sooc_finetune_params ps = p;
        ps.support_m = 0.05f;
        sooc_finetune *fs = NULL;
        CHECK_OK(sooc_finetune_create(&fs, m, map, &ps));
        for (int v = 0; v < NV; v++) CHECK_OK(sooc_finetune_add_view(fs, &fr[v]));
        size_t nsup = 0;
        for (size_t r = 0; r < fs->nr; r++) nsup += fs->surf[r] == 2;
        printf("support plane 5 cm: %zu of %zu rays on it\n", nsup, fs->nr);
        CHECK(nsup > fs->nr / 10 && nsup < fs->nr);
        int nus = sooc_finetune_n_units(fs), lay_done = 0;
        for (int u = 0; u < nus; u++) {
            const sooc_ft_comp *c = &fs->comp[fs->units[u]];
            if (u == 0) fd_check(fs, fs->units[u], "object, support plane");
            else if (c->kind == SOOC_FT_LAYOUT && !lay_done) fd_check(fs, fs->units[u], "layout, support plane"), lay_done = 1;
        }
        sooc_finetune_destroy(fs);
    }

    /* 3 (before): rendering error of the base decoders */
    double err0 = render_err(m, map, fr);
    /* 2. E/M rounds: every unit takes 4 full-batch Adam steps per round */
    double ll_prev = 0, ll_first = 0;
    size_t nr = 0;
    CHECK_OK(sooc_finetune_loglik(ft, p.seed, &ll_prev, &nr));
    ll_first = ll_prev;
    int falls = 0;
    for (int round = 0; round < 6; round++) {
        CHECK_OK(sooc_finetune_run_all(ft, NULL, NULL, 0));
        double ll = 0;
        CHECK_OK(sooc_finetune_loglik(ft, p.seed, &ll, &nr));
        printf("round %d: log-likelihood %.4f (%+.4f)\n", round + 1, ll, ll - ll_prev);
        if (ll < ll_prev - 1e-6 * fabs(ll_prev) - 1e-3) falls++;
        ll_prev = ll;
    }
    CHECK_MSG(falls == 0, "the log-likelihood fell in %d of 6 rounds", falls);
    CHECK_MSG(ll_prev > ll_first + 1e-3 * (double)nr, "ll %.4f -> %.4f over %zu rays", ll_first, ll_prev, nr);
    CHECK(sooc_cogmap_payload_count(map) == (size_t)nu);

    /* 3. a few more steps with minibatches and fresh samples (the default use),
     * then the rendering error of the views */
    sooc_finetune_destroy(ft);
    ft = NULL;
    p.rays = 256, p.fixed_samples = 0, p.iterations = 150, p.lr = p.lr_z = 2e-3f;
    CHECK_OK(sooc_finetune_create(&ft, m, map, &p));
    for (int v = 0; v < NV; v++) CHECK_OK(sooc_finetune_add_view(ft, &fr[v]));
    CHECK_OK(sooc_finetune_run_all(ft, NULL, NULL, 0));
    double err1 = render_err(m, map, fr);
    printf("rendering RGB RMSE of the views: %.4f base -> %.4f finetuned\n", err0, err1);
    CHECK(isfinite(err0) && isfinite(err1));
    CHECK_MSG(err1 < 0.9 * err0, "RMSE %.4f -> %.4f", err0, err1);
    /* the learning-rate schedule: constant by default, a half cosine from 1
     * to lr_final otherwise; an lr_final outside [0, 1] is refused */
    {
        sooc_finetune_params q;
        sooc_finetune_params_default(&q);
        q.iterations = 100;
        CHECK(sooc_finetune_lr_scale(&q, 0) == 1.0f && sooc_finetune_lr_scale(&q, 99) == 1.0f);
        q.lr_final = 0.1f;
        CHECK_CLOSE(sooc_finetune_lr_scale(&q, 0), 1.0, 1e-6, 0);
        CHECK_CLOSE(sooc_finetune_lr_scale(&q, 50), 0.55, 1e-5, 0);
        CHECK(sooc_finetune_lr_scale(&q, 99) < 0.101f && sooc_finetune_lr_scale(&q, 99) > 0.1f);
        for (int i = 1; i < 100; i++) CHECK(sooc_finetune_lr_scale(&q, i) < sooc_finetune_lr_scale(&q, i - 1));
        q.lr_final = 1.5f;
        sooc_finetune *bad = NULL;
        CHECK(sooc_finetune_create(&bad, m, map, &q) == SOOC_EINVAL && bad == NULL);
        sooc_clearerr();
    }
    /* the model's own weights are untouched */
    sooc_model *m2 = NULL;
    CHECK_OK(sooc_model_create(&m2, &cfg, 3));
    CHECK(!memcmp(sooc_model_params(m), sooc_model_params(m2), sooc_model_param_count(m) * sizeof(float)));
    sooc_model_destroy(m2);

    sooc_finetune_destroy(ft);
    sooc_cogmap_destroy(map);
    for (int v = 0; v < NV; v++) sooc_frame_free(&fr[v]);
    sooc_model_destroy(m);
    return check_report("test_finetune_em");
}
