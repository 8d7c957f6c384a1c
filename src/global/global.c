/* The MulMON-style global-frame baseline (docs/baseline.md):
 * the same networks as the shipped model, but every object lives in one
 * fixed set of slots in the WORLD frame, persisting across all views of a
 * scene (the posterior after view t is the prior of view t+1), no cognitive
 * map, no query/registration, one global layout latent.
 *
 * Its own module above src/model: it runs the model's step layer
 * (model/step.h: per-view records, forward, reverse sweep); the model never
 * calls it. Its slot priors' initial spiral is the model's (model.c, a
 * weights initialisation for config.global_frame). */
#include "model/step.h"
#include "sooc3d/train.h"

#include <math.h>
#include <string.h>

/* Rays of one view in the decoding frame W_t: world axes, origin (0, h_t, 0)
 * above the world origin (h_t = camera height), so that the floor is the
 * plane y = -h_t exactly as in G_t and Π(z^where) of decoder.c maps a world
 * pose (X, Z, Θ) to the object frame unchanged. The layout block origin is
 * the world origin: the single layout latent sees world coordinates. */
static sooc_status glob_view_setup(sooc_model *m, sooc_view_rec *V, const sooc_frame *f, sooc_rng *rng) {
    const sooc_model_config *c = &m->cfg;
    if (!f->has_pose) return sooc_seterr(SOOC_EINVAL, "frame %lld has no pose", (long long)f->index);
    double Twg[16], h, pitch, roll;
    sooc_status st = sooc_gframe(f->T_wc, Twg, &h, &pitch, &roll);
    if (st) return st;
    double Twc_frame[16];   /* world axes at the camera centre: rays come out relative to the camera */
    sooc_se3_identity(Twc_frame);
    double Xc = f->T_wc[3], Zc = f->T_wc[11];
    Twc_frame[3] = Xc, Twc_frame[7] = f->T_wc[7], Twc_frame[11] = Zc;
    memset(&V->gf, 0, sizeof V->gf);
    V->bi = V->bj = 0;
    V->lay_src = -1;
    V->t_ns = f->t_ns;
    int ox = (int)sooc_rng_below(rng, (uint32_t)(c->img_w / c->ray_w));
    int oy = (int)sooc_rng_below(rng, (uint32_t)(c->img_h / c->ray_h));
    const double blk0[2] = {0, 0};
    if ((st = sooc_mdl_make_rays(m, f, ox, oy, rng, &V->vr, Twc_frame, h, pitch, blk0))) return st;
    /* move the origin from the camera centre to (0, h, 0): + (Xc, 0, Zc), in model units */
    float iu = 1.0f / c->unit_m;
    for (int p = 0; p < 2 * V->vr.N; p++) {
        V->vr.pts[3 * p] += (float)Xc * iu;
        V->vr.pts[3 * p + 2] += (float)Zc * iu;
    }
    V->vr.blk[0] = 0, V->vr.blk[1] = (float)-h * iu, V->vr.blk[2] = 0;
    return SOOC_OK;
}

/* The K (or n) persistent slots: view t starts from view t-1's final
 * posterior (the learnable slot priors for t = 0). */
static void glob_view_start(sooc_model *m, sooc_view_rec *V, int n, int started, const float *lam, const float *lay) {
    int NL = m->NL, D2 = 2 * m->cfg.d_layout;
    V->nslot = n;
    V->n_ret = started ? n : 0;
    memcpy(V->lam0, lam, (size_t)n * NL * sizeof(float));
    memcpy(V->lay0, lay, (size_t)D2 * sizeof(float));
    for (int k = 0; k < n; k++) {
        V->src_id[k] = 0;
        V->src_view[k] = -1;
        V->src_slot[k] = k;
        V->prior_idx[k] = started ? -1 : k;
    }
}

sooc_status sooc_model_global_train_step(sooc_model_ws *x, const sooc_frame *views, int T, const sooc_frame *queries,
                                         int Q, int n_objects, const sooc_step_opts *opt, sooc_rng *rng,
                                         sooc_step_losses *out) {
    sooc_model *m = x->m;
    sooc_step_opts od;
    if (!opt) {
        sooc_step_opts_default(&od);
        opt = &od;
    }
    memset(out, 0, sizeof *out);
    if (!m->cfg.global_frame) return sooc_seterr(SOOC_EINVAL, "global train step: the model is not global_frame");
    if (T < 1 || T > 64 || Q < 0 || Q > 64)
        return sooc_seterr(SOOC_EINVAL, "global train step: T = %d (1..64), Q = %d (0..64)", T, Q);
    const sooc_model_config *c = &m->cfg;
    int L = opt->L > 0 ? opt->L : c->L, NL = m->NL, dl = c->d_layout, D2 = 2 * dl, d = c->d_what;
    int n = sooc_model_global_slots(m, n_objects);
    if (L < 1) return sooc_seterr(SOOC_EINVAL, "global train step: L must be >= 1");
    sooc_step_state *S = sooc_mdl_step_state(x, T + 1, L);
    if (!S) return sooc_seterr(SOOC_ENOMEM, "global train step: out of memory");
    memcpy(S->gbak, m->g, m->np * sizeof(float));
    sooc_status st = SOOC_OK;
    double total = 0;
    int nonfinite = 0;
    /* ---- forward over the input views: one slot set carried through ---- */
    for (int t = 0; t < T; t++) {
        sooc_view_rec *V = &S->views[t];
        if ((st = glob_view_setup(m, V, &views[t], rng))) goto fail;
        if (t == 0)
            glob_view_start(m, V, n, 0, m->p + m->prior, m->p + m->prior_lay);
        else {
            const sooc_view_rec *P = &S->views[t - 1];
            glob_view_start(m, V, n, 1, P->lam + (size_t)L * n * NL, P->lay + (size_t)L * D2);
            for (int k = 0; k < n; k++) V->src_view[k] = t - 1;
        }
        if ((st = sooc_mdl_view_forward_train(x, S, V, L, opt, rng, &total, out, &nonfinite))) goto fail;
        if (nonfinite) break;
        const float *lamL = V->lam + (size_t)L * n * NL;
        for (int k = 0; k < n; k++) {
            float a = lamL[(size_t)k * NL + 5 + 2 * d];
            out->present_slots += a >= 0;
            out->mean_pres_logit += a;
            if (t == T - 1) out->map_entries += a >= 0;
        }
    }
    out->n_views = T;
    out->present_slots /= T;
    out->mean_pres_logit /= (double)T * n;
    /* ---- query views: every slot of the final posterior ---- */
    const sooc_view_rec *VL = &S->views[T - 1];
    const float *lamF = VL->lam + (size_t)L * n * NL, *layF = VL->lay + (size_t)L * D2;
    if (!nonfinite)
        for (int q = 0; q < Q; q++) {
            sooc_view_rec *V = &S->views[T];   /* scratch record */
            if ((st = glob_view_setup(m, V, &queries[q], rng))) goto fail;
            if ((st = sooc_mdl_query_decode(x, S, V, q, n, lamF, layF, opt, rng, &total, out, &nonfinite))) goto fail;
            if (nonfinite) break;
            sooc_view_rec *W = &S->views[T - 1];
            for (int i = 0; i < n * NL; i++) W->G[i] += S->tmp0[i];
            for (int i = 0; i < D2; i++) W->Glay[i] += S->tmpl0[i];
        }
    /* ---- reverse sweep: identity transport between views (world frame) ---- */
    double t_rev = sooc_seconds();
    if (!nonfinite)
        for (int t = T - 1; t >= 0; t--) {
            sooc_view_rec *V = &S->views[t];
            sooc_mdl_view_backward(x, S, V, L);
            if (t > 0) {
                if (!opt->truncate_views) {
                    sooc_view_rec *P = &S->views[t - 1];
                    for (int i = 0; i < n * NL; i++) P->G[i] += V->G[i];
                    for (int i = 0; i < D2; i++) P->Glay[i] += V->Glay[i];
                }
            } else {
                for (int i = 0; i < n * NL; i++) m->g[m->prior + i] += V->G[i];
                for (int i = 0; i < D2; i++) m->g[m->prior_lay + i] += V->Glay[i];
            }
        }
    out->sec_backward = sooc_seconds() - t_rev;
    return sooc_mdl_step_finish(m, S, total, nonfinite, out);
fail:
    memcpy(m->g, S->gbak, m->np * sizeof(float));
    return st;
}

/* ------------------------------------------------------- online inference */

#define GLOBAL_TAU 0.7f   /* the mapper's (and the trainer's final) temperature */

struct sooc_global_mapper {
    sooc_model *m;
    sooc_model_ws *ws;         /* the mapper's workspace (it runs the model) */
    sooc_cogmap *map;          /* the present slots (id = slot + 1) + the layout at block (0, 0) */
    sooc_view_rec V;
    int L, n, started, view_idx;
    int sample;                /* 1 = SOOC_LATENTS_SAMPLE */
    sooc_rng rng;
    float *lam, *lay;          /* current posterior: n x NL (world frame), 2 d_l */
    int64_t first_ns[SOOC_MODEL_K_MAX];
    uint32_t obs[SOOC_MODEL_K_MAX];
    uint8_t present[SOOC_MODEL_K_MAX];
};

void sooc_global_mapper_set_latents(sooc_global_mapper *g, int latents) { g->sample = latents == SOOC_LATENTS_SAMPLE; }

sooc_status sooc_global_mapper_create(sooc_global_mapper **out, sooc_model *m, int n_objects, int iterations,
                                      uint64_t seed, int threads) {
    *out = NULL;
    if (!m || !m->cfg.global_frame) return sooc_seterr(SOOC_EINVAL, "global mapper: the model is not global_frame");
    const sooc_model_config *c = &m->cfg;
    sooc_global_mapper *g = sooc_calloc(1, sizeof *g);
    if (!g) return SOOC_ENOMEM;
    g->L = iterations > 0 ? iterations : c->L;
    if (g->L > 16) g->L = 16;
    if (g->L < 1) g->L = 1;
    g->n = sooc_model_global_slots(m, n_objects);
    sooc_model_set_threads(m, threads);
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = c->d_what;
    cp.layout_dim = c->d_layout;
    cp.block_size = (double)c->block_size * c->unit_m;
    sooc_status st = sooc_cogmap_create(&g->map, &cp);
    g->lam = sooc_calloc((size_t)c->K * m->NL, sizeof(float));
    g->lay = sooc_calloc((size_t)2 * c->d_layout, sizeof(float));
    if (!st && (!g->lam || !g->lay)) st = SOOC_ENOMEM;
    if (!st) st = sooc_mdl_view_alloc(m, &g->V, g->L);
    if (!st) st = sooc_model_ws_create(&g->ws, m);
    if (!st && !sooc_mdl_step_state(g->ws, 1, g->L)) st = sooc_seterr(SOOC_ENOMEM, "global mapper: out of memory");
    if (st) {
        sooc_global_mapper_destroy(g);
        return st;
    }
    memcpy(g->lam, m->p + m->prior, (size_t)g->n * m->NL * sizeof(float));
    memcpy(g->lay, m->p + m->prior_lay, (size_t)2 * c->d_layout * sizeof(float));
    sooc_rng_seed(&g->rng, seed, 0x676c6f62ULL);
    g->m = m;
    *out = g;
    return SOOC_OK;
}

void sooc_global_mapper_destroy(sooc_global_mapper *g) {
    if (!g) return;
    if (g->V.buf) sooc_mdl_view_free(&g->V);
    sooc_model_ws_destroy(g->ws);
    sooc_cogmap_destroy(g->map);
    sooc_model_destroy(g->m);
    sooc_free(g->lam);
    sooc_free(g->lay);
    sooc_free(g);
}

sooc_model *sooc_global_mapper_model(sooc_global_mapper *g) { return g->m; }
const sooc_cogmap *sooc_global_mapper_cogmap(const sooc_global_mapper *g) { return g->map; }
const float *sooc_global_mapper_slot(const sooc_global_mapper *g, int k) {
    return k >= 0 && k < g->n ? g->lam + (size_t)k * g->m->NL : NULL;
}

sooc_status sooc_global_mapper_update(sooc_global_mapper *g, const sooc_frame *f, sooc_update_stats *stp) {
    double t0 = sooc_seconds();
    sooc_update_stats st0;
    sooc_update_stats *us = stp ? stp : &st0;
    memset(us, 0, sizeof *us);
    sooc_model *m = g->m;
    const sooc_model_config *c = &m->cfg;
    if (!f->has_pose) return sooc_seterr(SOOC_EINVAL, "global mapper: frame %lld has no pose", (long long)f->index);
    if (f->width != c->img_w || f->height != c->img_h)
        return sooc_seterr(SOOC_EINVAL, "global mapper: frame %lld is %dx%d, the model needs %dx%d",
                           (long long)f->index, f->width, f->height, c->img_w, c->img_h);
    sooc_step_state *S = sooc_mdl_step_state(g->ws, 1, g->L);
    if (!S) return sooc_seterr(SOOC_ENOMEM, "global mapper: out of memory");
    S->aux_replay = 0;
    sooc_view_rec *V = &g->V;
    sooc_status s = glob_view_setup(m, V, f, &g->rng);
    if (s) return s;
    glob_view_start(m, V, g->n, g->started, g->lam, g->lay);
    sooc_step_opts o;
    sooc_step_opts_default(&o);
    o.tau = GLOBAL_TAU;
    o.mean_latents = !g->sample;
    o.L = g->L;
    double lw;
    if ((s = sooc_mdl_view_forward(g->ws, S, V, g->L, &o, 0, &g->rng, &lw, NULL))) return s;
    int NL = m->NL, D2 = 2 * c->d_layout, d = c->d_what, n = g->n;
    const float *lamL = V->lam + (size_t)g->L * n * NL, *layL = V->lay + (size_t)g->L * D2;
    for (int i = 0; i < n * NL; i++)
        if (!isfinite(lamL[i])) return sooc_seterr(SOOC_ENUMERIC, "global mapper: non-finite posterior");
    memcpy(g->lam, lamL, (size_t)n * NL * sizeof(float));
    memcpy(g->lay, layL, (size_t)D2 * sizeof(float));
    /* the "map" the eval path renders: the present slots, ids = slot + 1 */
    sooc_cogmap_clear(g->map, 1);
    for (int k = 0; k < n; k++) {
        const float *l = g->lam + (size_t)k * NL;
        int pres = l[5 + 2 * d] >= 0;
        us->n_new += pres && !g->present[k];
        us->n_removed += !pres && g->present[k];
        if (pres && !g->present[k]) g->first_ns[k] = f->t_ns, g->obs[k] = 0;
        g->present[k] = (uint8_t)pres;
        if (!pres) continue;
        g->obs[k]++;
        sooc_cogmap_entry e;
        memset(&e, 0, sizeof e);
        e.id = (uint64_t)k + 1;
        float lm[5] = {l[0], l[1], l[2], l[3], l[4]};
        sooc_mdl_lam_to_m(c, lm, 1, 5);   /* model units -> metres */
        e.X = lm[0], e.Z = lm[1], e.Theta = lm[2];
        e.rho_t = lm[3], e.rho_theta = lm[4];
        e.pres_logit = l[5 + 2 * d];
        e.dim = d;
        memcpy(e.what_mu, l + 5, d * sizeof(float));
        memcpy(e.what_logvar, l + 5 + d, d * sizeof(float));
        e.first_seen_ns = g->first_ns[k], e.last_seen_ns = f->t_ns;
        e.obs_count = g->obs[k];
        e.last_view = g->view_idx;
        if ((s = sooc_cogmap_insert(g->map, &e, NULL))) return s;
        us->n_registered++;
    }
    if ((s = sooc_cogmap_layout_set(g->map, 0, 0, g->lay, g->lay + c->d_layout))) return s;
    us->n_retrieved = g->started ? n : 0;
    g->started = 1;
    g->view_idx++;
    us->elapsed_ms = 1e3 * (sooc_seconds() - t0);
    return SOOC_OK;
}

sooc_status sooc_global_mapper_entries(const sooc_global_mapper *g, sooc_map_entry *out, size_t cap, size_t *n) {
    size_t cnt = sooc_cogmap_count(g->map);
    if (!out) {
        *n = cnt;
        return SOOC_OK;
    }
    if (cnt > cap) cnt = cap;
    sooc_cogmap_entry tmp[SOOC_MODEL_K_MAX];
    if (cnt > SOOC_MODEL_K_MAX) cnt = SOOC_MODEL_K_MAX;
    size_t got = 0;
    sooc_status s = sooc_cogmap_entries(g->map, tmp, cnt, &got);
    const sooc_model_config *c = &g->m->cfg;
    float ext[3];
    sooc_model_box_extent(c, ext);
    for (size_t i = 0; !s && i < got; i++) sooc_map_entry_from_cogmap(&tmp[i], ext, &out[i]);
    *n = s ? 0 : got;
    return s;
}
