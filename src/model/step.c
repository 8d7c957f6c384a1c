/* The per-view variational update and the training step (the SOOC3D
 * paper; docs/model.md): retrieve -> refine L times -> register, over T input views
 * with a cognitive map, then Q query views decoded from the final map; one
 * local backward per decode, then a reverse sweep over the λ chain and the
 * refinement activations, routing gradients through the map's transforms. */
#include "model/propose.h"
#include "model/step.h"

#include <math.h>
#include <string.h>

static void free_view(sooc_view_rec *V) {
    sooc_mdl_rays_free(&V->vr);
    for (int l = 0; l < V->Lcap; l++) {
        sooc_mdl_ref_act_free(&V->ao[l]);
        sooc_mdl_ref_act_free(&V->al[l]);
    }
    sooc_free(V->ao);
    sooc_free(V->al);
    sooc_free(V->noise);
    sooc_free(V->buf);
    memset(V, 0, sizeof *V);
}

sooc_status sooc_mdl_view_alloc(sooc_model *m, sooc_view_rec *V, int L) {
    const sooc_model_config *c = &m->cfg;
    memset(V, 0, sizeof *V);
    int K = c->K, NL = m->NL, D2 = 2 * c->d_layout;
    sooc_status st = sooc_mdl_rays_alloc(&V->vr, c->ray_w, c->ray_h);
    if (st) return st;
    V->Lcap = L;
    size_t nf = (size_t)(L + 1) * K * NL * 2 + (size_t)(L + 1) * D2 * 2 + (size_t)K * NL * 3 + (size_t)D2 * 3;
    V->buf = sooc_calloc(nf, sizeof(float));
    V->ao = sooc_calloc(L > 0 ? L : 1, sizeof(sooc_ref_act));
    V->al = sooc_calloc(L > 0 ? L : 1, sizeof(sooc_ref_act));
    V->noise = sooc_calloc(L + 1, sizeof(sooc_dec_noise));
    if (!V->buf || !V->ao || !V->al || !V->noise) {
        free_view(V);
        return SOOC_ENOMEM;
    }
    float *p = V->buf;
    V->lam = p, p += (size_t)(L + 1) * K * NL;
    V->glam = p, p += (size_t)(L + 1) * K * NL;
    V->lay = p, p += (size_t)(L + 1) * D2;
    V->glay = p, p += (size_t)(L + 1) * D2;
    V->lam0 = p, p += (size_t)K * NL;
    V->glam0 = p, p += (size_t)K * NL;
    V->G = p, p += (size_t)K * NL;
    V->lay0 = p, p += D2;
    V->glay0 = p, p += D2;
    V->Glay = p, p += D2;
    for (int l = 0; l < L; l++) {
        if ((st = sooc_mdl_ref_act_alloc(&m->robj, K, c->ray_w, c->ray_h, &V->ao[l])) ||
            (st = sooc_mdl_ref_act_alloc(&m->rlay, 1, c->ray_w, c->ray_h, &V->al[l]))) {
            free_view(V);
            return st;
        }
    }
    return SOOC_OK;
}

void sooc_mdl_view_free(sooc_view_rec *V) { free_view(V); }

sooc_step_state *sooc_mdl_step_state(sooc_model_ws *x, int T, int L) {
    sooc_model *m = x->m;
    sooc_step_state *S = x->step;
    const sooc_model_config *c = &m->cfg;
    if (!S) {
        S = sooc_calloc(1, sizeof *S);
        if (!S) return NULL;
        sooc_cogmap_params cp;
        sooc_cogmap_params_default(&cp);
        cp.dim = c->d_what;
        cp.layout_dim = c->d_layout;
        cp.block_size = (double)c->block_size * c->unit_m;   /* the map is in metres */
        cp.cell_size = 2.0;
        if (sooc_cogmap_create(&S->map, &cp)) {
            sooc_free(S);
            return NULL;
        }
        size_t nv = (size_t)c->K * (2 * m->NL + 6);
        S->vec_o = sooc_calloc(nv, sizeof(float));
        S->vec_l = sooc_calloc(4 * c->d_layout + 2, sizeof(float));
        S->gvec = sooc_calloc(nv, sizeof(float));
        S->dh = sooc_calloc((size_t)c->K * c->ref_hidden, sizeof(float));
        S->dc = sooc_calloc((size_t)c->K * c->ref_hidden, sizeof(float));
        S->delta = sooc_calloc((size_t)c->K * m->NL + 2 * c->d_layout, sizeof(float));   /* objects, layout */
        S->tmp0 = sooc_calloc((size_t)c->K * m->NL, sizeof(float));
        S->tmpl0 = sooc_calloc(64, sizeof(float));
        S->gbak = sooc_calloc(m->np, sizeof(float));
        x->step = S;
        if (!S->vec_o || !S->vec_l || !S->gvec || !S->dh || !S->dc || !S->delta || !S->tmp0 || !S->tmpl0 ||
            !S->gbak)
            return NULL;
    }
    if (L > S->L || T > S->ncap) {
        int nc = T > S->ncap ? T : S->ncap;
        int nl = L > S->L ? L : S->L;
        sooc_view_rec *nv = sooc_calloc(nc, sizeof(sooc_view_rec));
        if (!nv) return NULL;
        for (int i = 0; i < S->ncap; i++) free_view(&S->views[i]);
        sooc_free(S->views);
        S->views = nv;
        S->ncap = nc;
        S->L = nl;
        for (int i = 0; i < nc; i++)
            if (sooc_mdl_view_alloc(m, &S->views[i], nl)) return NULL;
    }
    return S;
}

void sooc_mdl_step_free(sooc_step_state *S) {
    if (!S) return;
    for (int i = 0; i < S->ncap; i++) free_view(&S->views[i]);
    sooc_free(S->views);
    sooc_cogmap_destroy(S->map);
    sooc_cluster_map_destroy(S->prop);
    sooc_free(S->vec_o);
    sooc_free(S->vec_l);
    sooc_free(S->gvec);
    sooc_free(S->dh);
    sooc_free(S->dc);
    sooc_free(S->delta);
    sooc_free(S->tmp0);
    sooc_free(S->tmpl0);
    sooc_free(S->gbak);
    sooc_free(S->id_view);
    sooc_free(S->id_slot);
    sooc_free(S);
}

void sooc_mdl_camera_of(const sooc_model *m, const sooc_frame *f, sooc_cogmap_camera *cam) {
    memset(cam, 0, sizeof *cam);
    memcpy(cam->T_wc, f->T_wc, sizeof cam->T_wc);
    cam->K = f->K;
    double u = m->cfg.unit_m;   /* the map's camera is in metres */
    cam->t_near = m->cfg.t_near * u;
    cam->d_clip = m->cfg.d_clip * u;
    cam->R_h = m->cfg.box_rh * u;
    cam->H_b = m->cfg.box_hb * u;
    cam->mode = SOOC_INVIEW_CENTRE;
}

/* Choose which slot priors pad the view: the ones whose means lie farthest
 * from the retrieved slots (slot order when nothing is retrieved). */
static void pick_priors(const sooc_model *m, const float *lam_ret, int n_ret, int *out) {
    int K = m->cfg.K, NL = m->NL;
    float score[SOOC_MODEL_K_MAX];
    int used[SOOC_MODEL_K_MAX] = {0};
    for (int p = 0; p < K; p++) {
        const float *pr = m->p + m->prior + (size_t)p * NL;
        float best = 1e30f;
        for (int r = 0; r < n_ret; r++) {
            float dx = pr[0] - lam_ret[(size_t)r * NL], dz = pr[1] - lam_ret[(size_t)r * NL + 1];
            float d2 = dx * dx + dz * dz;
            if (d2 < best) best = d2;
        }
        score[p] = best;
    }
    for (int s = 0; s < K - n_ret; s++) {
        int bi = -1;
        for (int p = 0; p < K; p++)
            if (!used[p] && (bi < 0 || score[p] > score[bi] + 1e-6f)) bi = p;
        used[bi] = 1;
        out[s] = bi;
    }
    /* keep slot order among the chosen priors (stable slot identity) */
    for (int i = 1; i < K - n_ret; i++)
        for (int j = i; j > 0 && out[j] < out[j - 1]; j--) {
            int t = out[j];
            out[j] = out[j - 1];
            out[j - 1] = t;
        }
}

/* Set up a view: frame, rays, retrieved slots + priors, layout. */
sooc_status sooc_mdl_view_setup(sooc_model *m, sooc_cogmap *map, sooc_view_rec *V, const sooc_frame *f, int pad,
                           sooc_rng *rng, int *n_inview) {
    const sooc_model_config *c = &m->cfg;
    int K = c->K, NL = m->NL, dl = c->d_layout;
    if (!f->has_pose) return sooc_seterr(SOOC_EINVAL, "frame %lld has no pose", (long long)f->index);
    double Twg[16], h, pitch, roll;
    sooc_status st = sooc_gframe(f->T_wc, Twg, &h, &pitch, &roll);
    if (st) return st;
    sooc_floor_frame_of(&V->gf, Twg);
    sooc_cogmap_camera cam;
    sooc_mdl_camera_of(m, f, &cam);
    sooc_cogmap_slot slots[SOOC_MODEL_K_MAX];
    int nret = 0;
    sooc_floor_frame gq;
    if ((st = sooc_cogmap_query(map, &cam, K, slots, &nret, &gq, n_inview))) return st;
    V->n_ret = nret;
    for (int k = 0; k < nret; k++) {
        memcpy(V->lam0 + (size_t)k * NL, slots[k].lam, NL * sizeof(float));
        V->src_id[k] = slots[k].id;
        V->src_view[k] = slots[k].last_view;
        V->prior_idx[k] = -1;
    }
    sooc_mdl_lam_from_m(c, V->lam0, nret, NL);   /* the map's metres -> model units */
    V->nslot = pad ? K : nret;
    if (pad) {
        int pr[SOOC_MODEL_K_MAX];
        pick_priors(m, V->lam0, nret, pr);
        for (int k = nret; k < K; k++) {
            memcpy(V->lam0 + (size_t)k * NL, m->p + m->prior + (size_t)pr[k - nret] * NL, NL * sizeof(float));
            V->src_id[k] = 0;
            V->src_view[k] = -1;
            V->prior_idx[k] = pr[k - nret];
        }
    }
    /* layout block */
    double blk[2];
    if ((st = sooc_cogmap_active_block(map, f->T_wc, (double)c->d_clip * c->unit_m, &V->bi, &V->bj, blk))) return st;
    float lmu[SOOC_COGMAP_DIM_MAX], llv[SOOC_COGMAP_DIM_MAX];
    if (sooc_cogmap_layout_get(map, V->bi, V->bj, lmu, llv) == SOOC_OK) {
        memcpy(V->lay0, lmu, dl * sizeof(float));
        memcpy(V->lay0 + dl, llv, dl * sizeof(float));
        V->lay_src = -1;   /* resolved by the caller in training */
    } else {
        memcpy(V->lay0, m->p + m->prior_lay, 2 * dl * sizeof(float));
        V->lay_src = -1;
    }
    sooc_clearerr();
    int ox = (int)sooc_rng_below(rng, (uint32_t)(c->img_w / c->ray_w));
    int oy = (int)sooc_rng_below(rng, (uint32_t)(c->img_h / c->ray_h));
    V->t_ns = f->t_ns;
    return sooc_mdl_make_rays(m, f, ox, oy, rng, &V->vr, Twg, h, pitch, blk);
}

/* Bounded refinement update (models/experiments/README.md, "The unity training recipe"): the
 * refinement nets' raw output r is applied as Δ = s·tanh(r/s), per component
 * scale s (metres / radians / log-variance / latent units per iteration).
 * Unbounded, the nets learnt to fling latents (|Δpos| 5-9 m, layout |μ| +73
 * per iteration, KL 1e5 per scene) and presence collapsed. Near 0 the update
 * is the identity (zero-initialised heads start at λ = prior). */
#define BOUND_POS 1.0f     /* x, z (m)                 */
#define BOUND_ANG 1.0f     /* θ (rad)                  */
#define BOUND_RHO 1.0f     /* log-variances            */
#define BOUND_WHAT 1.0f    /* z^what and layout means  */
#define BOUND_PRES 3.0f    /* presence logit           */

static float bound_scale_obj(int i, int d) {
    if (i < 2) return BOUND_POS;
    if (i == 2) return BOUND_ANG;
    if (i < 5) return BOUND_RHO;
    if (i < 5 + d) return BOUND_WHAT;
    if (i < 5 + 2 * d) return BOUND_RHO;
    return BOUND_PRES;
}

static float bound_scale_lay(int i, int dl) { return i < dl ? BOUND_WHAT : BOUND_RHO; }

static float bound_apply(float r, float s) { return s * tanhf(r / s); }

/* d(bounded)/d(raw) from the applied update Δ = λ^{l+1} − λ^l. */
static float bound_deriv(float delta, float s) {
    float t = delta / s;
    float g = 1.0f - t * t;
    return g > 0 ? g : 0;
}

/* Forward over the L refinement iterations of one input view.
 * train = 1: decodes l = 0..L with local backward (weight grads w_l = l/L),
 * stores everything for the reverse sweep. train = 0: decodes l = 0..L-1
 * (backward to the inputs only, for the auxiliary inputs), no final decode. */
sooc_status sooc_mdl_view_forward(sooc_model_ws *x, sooc_step_state *S, sooc_view_rec *V, int L, const sooc_step_opts *o, int train,
                             sooc_rng *rng, double *loss_w, sooc_dec_call *last) {
    sooc_model *m = x->m;
    const sooc_model_config *c = &m->cfg;
    int K = V->nslot, NL = m->NL, dl = c->d_layout, D2 = 2 * dl, H = c->ref_hidden;
    int gw = c->ray_w, gh = c->ray_h;
    sooc_status st;
    uint8_t hard[SOOC_MODEL_K_MAX] = {0};
    for (int k = 0; k < K; k++)
        hard[k] = o->pres_mode == SOOC_PRES_ST_ONE ? 2 : (o->pres_mode == SOOC_PRES_ST_RETRIEVED && k < V->n_ret);
    memcpy(V->lam, V->lam0, (size_t)K * NL * sizeof(float));
    memcpy(V->lay, V->lay0, D2 * sizeof(float));
    memset(V->glam, 0, (size_t)(L + 1) * K * NL * sizeof(float));
    memset(V->glay, 0, (size_t)(L + 1) * D2 * sizeof(float));
    memset(V->glam0, 0, (size_t)K * NL * sizeof(float));
    memset(V->glay0, 0, D2 * sizeof(float));
    memset(V->G, 0, (size_t)K * NL * sizeof(float));
    memset(V->Glay, 0, D2 * sizeof(float));
    *loss_w = 0;
    int nlast = train ? L : L - 1;
    for (int l = 0; l <= nlast; l++) {
        float *lam = V->lam + (size_t)l * K * NL, *lay = V->lay + (size_t)l * D2;
        float *glam = V->glam + (size_t)l * K * NL, *glay = V->glay + (size_t)l * D2;
        float wl = L > 0 ? (float)l / (float)L : 1.0f;
        sooc_mdl_sample_noise(m, rng, &V->noise[l]);   /* drawn either way: same RNG stream */
        if (o->mean_latents) memset(&V->noise[l], 0, sizeof V->noise[l]);
        sooc_dec_call dc;
        memset(&dc, 0, sizeof dc);
        dc.rays = &V->vr;
        dc.nslot = K;
        dc.lam = lam, dc.lam0 = V->lam0, dc.lay = lay, dc.lay0 = V->lay0;
        dc.noise = &V->noise[l];
        dc.tau = o->tau, dc.beta_kl = o->beta_kl, dc.sigma_c = o->sigma_c;
        dc.hard = hard;
        dc.wgrad = train ? wl : 0.0f;
        dc.backward = 1;
        dc.same_rays = l > 0;   /* the view's rays, unchanged since its previous decode */
        dc.aux_post = l < L && !S->aux_replay;   /* a refinement follows: its inputs' colour posterior */
        dc.g_lam = glam, dc.g_lay = glay;
        memset(S->tmp0, 0, (size_t)K * NL * sizeof(float));
        memset(S->tmpl0, 0, D2 * sizeof(float));
        dc.g_lam0 = S->tmp0, dc.g_lay0 = S->tmpl0;
        if (S->aux_replay) dc.zw_sg = V->zwb[l];
        if ((st = sooc_mdl_decode(x, &dc))) return st;
        if (!S->aux_replay)
            for (int k = 0; k < K; k++)
                for (int i = 0; i < 3; i++) V->zwb[l][k * 3 + i] = dc.zw[k][i];
        if (train && wl > 0) {
            *loss_w += wl * dc.loss;
            for (int i = 0; i < K * NL; i++) V->glam0[i] += wl * S->tmp0[i];
            for (int i = 0; i < D2; i++) V->glay0[i] += wl * S->tmpl0[i];
        }
        if (last) *last = dc;
        if (l == L) break;
        /* refinement */
        sooc_ref_act *ao = &V->ao[l], *al = &V->al[l];
        ao->B = K;
        int nvo = m->robj.nvec, fco = m->robj.fc, nvl = m->rlay.nvec, fcl = m->rlay.fc;
        if (!S->aux_replay) {
            sooc_mdl_aux_inputs(x, &dc, glam, glay, ao->x0, S->vec_o, al->x0, S->vec_l);
            ao->nsh = K > 1 ? MDL_AUX_NSH : 0;
            al->nsh = 0;
            for (int k = 0; k < K; k++)
                memcpy(ao->xin + (size_t)k * (fco + nvo) + fco, S->vec_o + (size_t)k * nvo, nvo * sizeof(float));
            memcpy(al->xin + fcl, S->vec_l, nvl * sizeof(float));
        } else {
            for (int k = 0; k < K; k++) memcpy(ao->xin + (size_t)k * (fco + nvo) + fco, lam + (size_t)k * NL, NL * sizeof(float));
            memcpy(al->xin + fcl, lay, D2 * sizeof(float));
        }
        if (l == 0) {
            memset(ao->h_prev, 0, (size_t)K * H * sizeof(float));
            memset(ao->c_prev, 0, (size_t)K * H * sizeof(float));
            memset(al->h_prev, 0, H * sizeof(float));
            memset(al->c_prev, 0, H * sizeof(float));
        } else {
            memcpy(ao->h_prev, V->ao[l - 1].h, (size_t)K * H * sizeof(float));
            memcpy(ao->c_prev, V->ao[l - 1].c, (size_t)K * H * sizeof(float));
            memcpy(al->h_prev, V->al[l - 1].h, H * sizeof(float));
            memcpy(al->c_prev, V->al[l - 1].c, H * sizeof(float));
        }
        /* objects and layout in one pass (their conv items split across the threads together) */
        float *dl_lay = S->delta + (size_t)c->K * NL;
        sooc_mdl_ref_forward2(x, &m->robj, ao, S->delta, &m->rlay, al, dl_lay, gw, gh);
        float *nlam = lam + (size_t)K * NL, *nlay = lay + D2;
        for (int k = 0; k < K; k++)
            for (int i = 0; i < NL; i++) {
                size_t j = (size_t)k * NL + i;
                nlam[j] = lam[j] + bound_apply(S->delta[j], bound_scale_obj(i, c->d_what));
            }
        for (int i = 0; i < D2; i++) nlay[i] = lay[i] + bound_apply(dl_lay[i], bound_scale_lay(i, dl));
    }
    return SOOC_OK;
}

/* Reverse sweep of one view: V->G / V->Glay hold the gradient w.r.t. λ^L from
 * later views and queries. On return, V->G / V->Glay hold the gradient w.r.t.
 * the view's starting λ^0 = its prior (including the KL-prior terms). */
void sooc_mdl_view_backward(sooc_model_ws *x, sooc_step_state *S, sooc_view_rec *V, int L) {
    sooc_model *m = x->m;
    const sooc_model_config *c = &m->cfg;
    int K = V->nslot, NL = m->NL, D2 = 2 * c->d_layout, H = c->ref_hidden;
    int gw = c->ray_w, gh = c->ray_h;
    float *G = V->G, *Gl = V->Glay;
    /* final iterate: weight 1 */
    const float *gL = V->glam + (size_t)L * K * NL, *glL = V->glay + (size_t)L * D2;
    for (int i = 0; i < K * NL; i++) G[i] += gL[i];
    for (int i = 0; i < D2; i++) Gl[i] += glL[i];
    memset(S->dh, 0, (size_t)K * H * sizeof(float));
    memset(S->dc, 0, (size_t)K * H * sizeof(float));
    float dhl[1024], dcl[1024];
    SOOC_ASSERT(H <= 1024);
    memset(dhl, 0, H * sizeof(float));
    memset(dcl, 0, H * sizeof(float));
    int nvo = m->robj.nvec, nvl = m->rlay.nvec;
    for (int l = L - 1; l >= 0; l--) {
        float wl = (float)l / (float)L;
        /* objects: λ^{l+1} = λ^l + f(λ^l, ...) */
        memset(S->gvec, 0, (size_t)K * nvo * sizeof(float));
        /* through the bound: d/d(raw) = G · (1 − (Δ/s)²) */
        const float *la = V->lam + (size_t)l * K * NL, *lb = la + (size_t)K * NL;
        for (int k = 0; k < K; k++)
            for (int i = 0; i < NL; i++) {
                size_t j = (size_t)k * NL + i;
                float s = bound_scale_obj(i, c->d_what);
                S->tmp0[j] = G[j] * bound_deriv(lb[j] - la[j], s);
            }
        sooc_mdl_ref_backward(x, &m->robj, &V->ao[l], gw, gh, S->tmp0, S->dh, S->dc, S->gvec);
        const float *gl = V->glam + (size_t)l * K * NL;
        for (int k = 0; k < K; k++)
            for (int i = 0; i < NL; i++) G[k * NL + i] += S->gvec[(size_t)k * nvo + i] + wl * gl[k * NL + i];
        memset(S->gvec, 0, nvl * sizeof(float));
        const float *ya = V->lay + (size_t)l * D2, *yb = ya + D2;
        for (int i = 0; i < D2; i++) S->tmpl0[i] = Gl[i] * bound_deriv(yb[i] - ya[i], bound_scale_lay(i, c->d_layout));
        sooc_mdl_ref_backward(x, &m->rlay, &V->al[l], gw, gh, S->tmpl0, dhl, dcl, S->gvec);
        const float *gll = V->glay + (size_t)l * D2;
        for (int i = 0; i < D2; i++) Gl[i] += S->gvec[i] + wl * gll[i];
    }
    for (int i = 0; i < K * NL; i++) G[i] += V->glam0[i];
    for (int i = 0; i < D2; i++) Gl[i] += V->glay0[i];
}

static sooc_status ensure_ids(sooc_step_state *S, uint64_t id) {
    if (id < S->id_cap) return SOOC_OK;
    size_t nc = (size_t)(id + 64) * 2;
    int *a = sooc_realloc(S->id_view, nc * sizeof(int)), *b;
    if (!a) return SOOC_ENOMEM;
    S->id_view = a;
    b = sooc_realloc(S->id_slot, nc * sizeof(int));
    if (!b) return SOOC_ENOMEM;
    S->id_slot = b;
    S->id_cap = nc;
    return SOOC_OK;
}

static int lay_find(const sooc_step_state *S, int32_t bi, int32_t bj) {
    for (int i = 0; i < S->n_lay; i++)
        if (S->lay_bi[i] == bi && S->lay_bj[i] == bj) return i;
    return -1;
}

/* Proposals for an input view in training: its padded slots on its clusters; a
 * slot so placed starts at a constant (no gradient to the learnt priors). */
static sooc_status view_propose(sooc_model *m, sooc_step_state *S, sooc_view_rec *V, const sooc_frame *f,
                                const sooc_step_opts *opt) {
    sooc_mdl_prop_params pp;
    sooc_cluster_params cp;
    sooc_mdl_prop_from_opts(opt, &pp, &cp);
    sooc_status st;
    if (!S->prop && (st = sooc_cluster_map_create(&S->prop, &cp))) return st;
    float before[SOOC_MODEL_K_MAX][2];
    for (int k = 0; k < V->nslot; k++)
        before[k][0] = V->lam0[(size_t)k * m->NL + SOOC_LAM_X], before[k][1] = V->lam0[(size_t)k * m->NL + SOOC_LAM_Z];
    sooc_mdl_propose(S->prop, &m->cfg, m->NL, f, V, &pp, &st);
    if (st) return st;
    for (int k = V->n_ret; k < V->nslot; k++)
        if (V->lam0[(size_t)k * m->NL + SOOC_LAM_X] != before[k][0] ||
            V->lam0[(size_t)k * m->NL + SOOC_LAM_Z] != before[k][1])
            V->prior_idx[k] = -1;
    return SOOC_OK;
}

sooc_status sooc_model_train_step(sooc_model_ws *x, const sooc_frame *views, int T, const sooc_frame *queries, int Q,
                                  const sooc_step_opts *opt, sooc_rng *rng, sooc_step_losses *out) {
    sooc_model *m = x->m;
    sooc_step_opts od;
    if (!opt) {
        sooc_step_opts_default(&od);
        opt = &od;
    }
    memset(out, 0, sizeof *out);
    if (T < 1 || T > 64 || Q < 0 || Q > 64)
        return sooc_seterr(SOOC_EINVAL, "train step: T = %d (1..64), Q = %d (0..64)", T, Q);
    const sooc_model_config *c = &m->cfg;
    int L = opt->L > 0 ? opt->L : c->L, K = c->K, NL = m->NL, dl = c->d_layout, D2 = 2 * dl, d = c->d_what;
    if (L < 1) return sooc_seterr(SOOC_EINVAL, "train step: L must be >= 1");
    sooc_step_state *S = sooc_mdl_step_state(x, T + 1, L);
    if (!S) return sooc_seterr(SOOC_ENOMEM, "train step: out of memory");
    memcpy(S->gbak, m->g, m->np * sizeof(float));
    sooc_cogmap_clear(S->map, 1);
    S->n_lay = 0;
    sooc_status st = SOOC_OK;
    double total = 0;
    int nonfinite = 0;
    /* ---- forward over input views ---- */
    for (int t = 0; t < T; t++) {
        sooc_view_rec *V = &S->views[t];
        if ((st = sooc_mdl_view_setup(m, S->map, V, &views[t], 1, rng, NULL))) goto fail;
        if (opt->proposals && (st = view_propose(m, S, V, &views[t], opt))) goto fail;
        int li = lay_find(S, V->bi, V->bj);
        V->lay_src = li >= 0 ? S->lay_view[li] : -1;
        for (int k = 0; k < V->n_ret; k++) {
            uint64_t id = V->src_id[k];
            int ok = id < S->id_cap;
            V->src_view[k] = ok ? S->id_view[id] : -1;
            V->src_slot[k] = ok ? S->id_slot[id] : -1;
        }
        if ((st = sooc_mdl_view_forward_train(x, S, V, L, opt, rng, &total, out, &nonfinite))) goto fail;
        if (nonfinite) break;
        /* register */
        const float *lamL = V->lam + (size_t)L * K * NL;
        uint64_t ids[SOOC_MODEL_K_MAX];
        sooc_cogmap_reg_stats rs;
        memcpy(S->tmp0, lamL, (size_t)K * NL * sizeof(float));   /* model units -> the map's metres */
        sooc_mdl_lam_to_m(c, S->tmp0, K, NL);
        if ((st = sooc_cogmap_register(S->map, &V->gf, K, S->tmp0, V->src_id, V->t_ns, t, ids, NULL, &rs))) {
            if (st == SOOC_ENUMERIC) {
                nonfinite = 1;
                st = SOOC_OK;
                break;
            }
            goto fail;
        }
        for (int k = 0; k < K; k++) {
            float a = lamL[(size_t)k * NL + 5 + 2 * d];
            out->present_slots += a >= 0;
            out->mean_pres_logit += a;
            if (ids[k]) {
                if ((st = ensure_ids(S, ids[k]))) goto fail;
                S->id_view[ids[k]] = t;
                S->id_slot[ids[k]] = k;
            }
        }
        const float *layL = V->lay + (size_t)L * D2;
        if ((st = sooc_cogmap_layout_set(S->map, V->bi, V->bj, layL, layL + dl))) goto fail;
        if (li < 0 && S->n_lay < STEP_MAX_LAY) li = S->n_lay++;
        if (li >= 0) {
            S->lay_bi[li] = V->bi, S->lay_bj[li] = V->bj, S->lay_view[li] = t;
        }
    }
    out->n_views = T;
    out->present_slots /= T;
    out->mean_pres_logit /= (double)T * K;
    out->map_entries = (double)sooc_cogmap_count(S->map);
    /* ---- query views ---- */
    if (!nonfinite)
        for (int q = 0; q < Q; q++) {
            sooc_view_rec *V = &S->views[T];   /* scratch record */
            if ((st = sooc_mdl_view_setup(m, S->map, V, &queries[q], 0, rng, NULL))) goto fail;
            int li = lay_find(S, V->bi, V->bj);
            V->lay_src = li >= 0 ? S->lay_view[li] : -1;
            if ((st = sooc_mdl_query_decode(x, S, V, q, V->nslot, V->lam0, V->lay0, opt, rng, &total, out, &nonfinite)))
                goto fail;
            if (nonfinite) break;
            /* route to the registering views */
            for (int k = 0; k < V->nslot; k++) {
                uint64_t id = V->src_id[k];
                if (id >= S->id_cap) continue;
                int tv = S->id_view[id], ks = S->id_slot[id];
                sooc_cogmap_grad_route(&S->views[tv].gf, &V->gf, d, S->tmp0 + (size_t)k * NL,
                                       S->views[tv].G + (size_t)ks * NL);
            }
            if (V->lay_src >= 0)
                for (int i = 0; i < D2; i++) S->views[V->lay_src].Glay[i] += S->tmpl0[i];
            else
                for (int i = 0; i < D2; i++) m->g[m->prior_lay + i] += S->tmpl0[i];
        }
    /* ---- reverse sweep ---- */
    double t_rev = sooc_seconds();
    if (!nonfinite)
        for (int t = T - 1; t >= 0; t--) {
            sooc_view_rec *V = &S->views[t];
            sooc_mdl_view_backward(x, S, V, L);
            for (int k = 0; k < K; k++) {
                const float *g = V->G + (size_t)k * NL;
                if (V->prior_idx[k] >= 0) {
                    float *gp = m->g + m->prior + (size_t)V->prior_idx[k] * NL;
                    for (int i = 0; i < NL; i++) gp[i] += g[i];
                } else if (!opt->truncate_views && V->src_view[k] >= 0 && V->src_view[k] < t && V->src_slot[k] >= 0) {
                    int tv = V->src_view[k];
                    sooc_cogmap_grad_route(&S->views[tv].gf, &V->gf, d, g, S->views[tv].G + (size_t)V->src_slot[k] * NL);
                }
            }
            if (V->lay_src >= 0 && V->lay_src < t) {
                if (!opt->truncate_views)
                    for (int i = 0; i < D2; i++) S->views[V->lay_src].Glay[i] += V->Glay[i];
            } else
                for (int i = 0; i < D2; i++) m->g[m->prior_lay + i] += V->Glay[i];
        }
    out->sec_backward = sooc_seconds() - t_rev;
    return sooc_mdl_step_finish(m, S, total, nonfinite, out);
fail:
    memcpy(m->g, S->gbak, m->np * sizeof(float));
    return st;
}

/* End of a training step (plain and global-frame): record the loss and, if
 * the loss or any accumulated gradient is non-finite, restore the gradient
 * slab to its value at entry (S->gbak) and flag the step as skipped. */
sooc_status sooc_mdl_step_finish(sooc_model *m, sooc_step_state *S, double total, int nonfinite, sooc_step_losses *out) {
    out->total = total;
    int bad = nonfinite || !isfinite(total);
    for (size_t i = 0; i < m->np && !bad; i++) bad = !isfinite(m->g[i]);
    if (bad) {
        memcpy(m->g, S->gbak, m->np * sizeof(float));
        out->nonfinite = 1;
    }
    return SOOC_OK;
}

/* Training forward of one input view (plain and global-frame steps): add its
 * weighted loss to *total and its final-iterate terms to out. A non-finite
 * loss is not an error: it sets *nonfinite and returns SOOC_OK. */
sooc_status sooc_mdl_view_forward_train(sooc_model_ws *x, sooc_step_state *S, sooc_view_rec *V, int L, const sooc_step_opts *opt,
                                   sooc_rng *rng, double *total, sooc_step_losses *out, int *nonfinite) {
    double lw;
    sooc_dec_call last;
    sooc_status st = sooc_mdl_view_forward(x, S, V, L, opt, 1, rng, &lw, &last);
    if (st == SOOC_ENUMERIC) {
        *nonfinite = 1;
        return SOOC_OK;
    }
    if (st) return st;
    *total += lw;
    out->nll_input += last.nll;
    out->nll_depth += last.nll_d;
    out->nll_color += last.nll_c;
    out->kl += last.kl;
    return SOOC_OK;
}

/* Decode query view q of a training step (plain and global-frame) from the
 * slot posteriors lam (nslot x NL) and layout lay, with one local backward:
 * the λ-gradients land in S->tmp0 / S->tmpl0 (zeroed here) for the caller to
 * route; the loss goes to *total and out. The sampled z_where are kept in
 * S->zq[q] (or replayed from it, S->aux_replay) for the gradient checks. A
 * non-finite loss sets *nonfinite and returns SOOC_OK. */
sooc_status sooc_mdl_query_decode(sooc_model_ws *x, sooc_step_state *S, sooc_view_rec *V, int q, int nslot, const float *lam,
                             const float *lay, const sooc_step_opts *opt, sooc_rng *rng, double *total,
                             sooc_step_losses *out, int *nonfinite) {
    sooc_model *m = x->m;
    sooc_mdl_sample_noise(m, rng, &V->noise[0]);
    memset(S->tmp0, 0, (size_t)nslot * m->NL * sizeof(float));
    memset(S->tmpl0, 0, 2 * (size_t)m->cfg.d_layout * sizeof(float));
    sooc_dec_call dc;
    memset(&dc, 0, sizeof dc);
    dc.rays = &V->vr;
    dc.nslot = nslot;
    dc.lam = lam, dc.lay = lay;
    dc.noise = &V->noise[0];
    dc.tau = opt->tau, dc.beta_kl = opt->beta_kl, dc.sigma_c = opt->sigma_c;
    uint8_t hard[SOOC_MODEL_K_MAX];
    for (int k = 0; k < nslot; k++)
        hard[k] = opt->pres_mode == SOOC_PRES_ST_ONE ? 2 : opt->pres_mode == SOOC_PRES_ST_RETRIEVED;
    dc.hard = hard;
    dc.wgrad = 1.0f;
    dc.backward = 1;
    dc.g_lam = S->tmp0, dc.g_lay = S->tmpl0;
    if (S->aux_replay) dc.zw_sg = S->zq[q];
    sooc_status st = sooc_mdl_decode(x, &dc);
    if (st == SOOC_ENUMERIC) {
        *nonfinite = 1;
        return SOOC_OK;
    }
    if (st) return st;
    if (!S->aux_replay)
        for (int k = 0; k < nslot; k++)
            for (int i = 0; i < 3; i++) S->zq[q][k * 3 + i] = dc.zw[k][i];
    *total += dc.loss;
    out->nll_query += dc.nll;
    out->n_queries++;
    return SOOC_OK;
}
