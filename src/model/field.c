/* render.h field adapter: the layout of the camera's active block plus the
 * in-view map entries, evaluated with the model's decoders (docs/metrics.md "Rendering"). */
#include "model/dec_own.h"
#include "model/decoder.h"

#include <cblas.h>
#include <math.h>
#include <string.h>

/* The global-frame baseline's map (src/global): world-frame λ of entry id
 * (identity floor frame). */
static void world_lam(const sooc_cogmap *map, uint64_t id, float *lam) {
    sooc_cogmap_entry e;
    sooc_floor_frame ident = {0, 0, 0};
    if (sooc_cogmap_get(map, id, &e) == SOOC_OK) sooc_cogmap_lam_to_local(&ident, &e, lam);
    else sooc_clearerr();
}

typedef struct fcomp {
    uint64_t id;
    float px, pz, th;          /* object pose in G (objects) */
    float *bias;               /* H: W1z z + b1               */
    const float *w;            /* finetuned decoder (dec_own.h, a map payload), NULL = the model's */
    sooc_dec_net rel;               /* its offsets relative to w   */
} fcomp;

struct sooc_model_field {
    sooc_model *m;
    sooc_field f;
    sooc_render_box *boxes;
    fcomp *comp;
    float *biasbuf;
    double T_gc[16];
    float h, blk[3];           /* model units (config.unit_m); the field's frame is in metres */
    float iu;                  /* 1 / unit_m */
    int nw, maxb;
    float *scratch;            /* nw x per-worker */
    size_t per_worker;
};

static void field_eval(void *user, int worker, int comp, const float *pts, int n, float *sigma_hat, float *rgb) {
    sooc_model_field *F = user;
    const sooc_model *m = F->m;
    const sooc_model_config *c = &m->cfg;
    const sooc_dec_net *net = comp ? &m->dobj : &m->dlay;
    int H = net->H, din = net->din;
    float *s = F->scratch + (size_t)(worker < F->nw ? worker : 0) * F->per_worker;
    float *pe = s, *a1 = pe + (size_t)F->maxb * din, *a2 = a1 + (size_t)F->maxb * H, *a3 = a2 + (size_t)F->maxb * H;
    float *ac = a3 + (size_t)F->maxb * H, *sig = ac + (size_t)F->maxb * net->Hc;
    uint8_t *in = (uint8_t *)(sig + F->maxb);
    const fcomp *fc = &F->comp[comp];
    for (int b0 = 0; b0 < n; b0 += F->maxb) {
        int nb = n - b0 < F->maxb ? n - b0 : F->maxb;
        for (int i = 0; i < nb; i++) {
            const float *xm = pts + (size_t)(b0 + i) * 3;
            const float x[3] = {xm[0] * F->iu, xm[1] * F->iu, xm[2] * F->iu};   /* metres -> model units */
            float xk[3];
            if (comp) {
                sooc_mdl_pi(x, fc->px, fc->pz, fc->th, F->h, xk);
                in[i] = fabsf(xk[0]) <= c->box_rh && fabsf(xk[2]) <= c->box_rh && xk[1] >= 0 && xk[1] <= c->box_hb;
                sooc_mdl_pe_row(xk, 1.0f / c->box_rh, net->nfreq, pe + (size_t)i * din);
            } else {
                float xl[3] = {x[0] - F->blk[0], x[1] - F->blk[1], x[2] - F->blk[2]};
                in[i] = 1;
                sooc_mdl_pe_row(xl, 1.0f / c->block_size, net->nfreq, pe + (size_t)i * din);
            }
        }
        if (fc->w) {   /* finetuned copy */
            sooc_mdl_own_forward(fc->w, &fc->rel, nb, pe, fc->bias, a1, a2, a3, ac, sig, rgb + (size_t)b0 * 3);
            for (int i = 0; i < nb; i++) sigma_hat[b0 + i] = in[i] ? sig[i] : 0.0f;
            continue;
        }
        for (int i = 0; i < nb; i++) memcpy(a1 + (size_t)i * H, fc->bias, H * sizeof(float));
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, nb, H, din, 1.0f, pe, din, m->p + net->W1x, H, 1.0f, a1,
                    H);
        sooc_mdl_mlp_tail_forward(m, net, nb, a1, a2, a3, ac, sig, rgb + (size_t)b0 * 3);
        for (int i = 0; i < nb; i++) sigma_hat[b0 + i] = in[i] ? sig[i] : 0.0f;
    }
}

static sooc_status field_prepare(void *user, int n_workers, int max_batch) {
    sooc_model_field *F = user;
    const sooc_model *m = F->m;
    int din = m->dobj.din > m->dlay.din ? m->dobj.din : m->dlay.din, H = m->cfg.dec_width, Hc = m->cfg.dec_color_width;
    int maxb = max_batch < 4096 ? max_batch : 4096;
    if (maxb < 1) maxb = 1;
    size_t per = (size_t)maxb * (din + 3 * H + Hc + 1) + (size_t)maxb / 4 + 16;
    if (n_workers <= F->nw && maxb <= F->maxb) return SOOC_OK;
    sooc_free(F->scratch);
    F->scratch = sooc_malloc((size_t)n_workers * per * sizeof(float));
    if (!F->scratch) return SOOC_ENOMEM;
    F->nw = n_workers, F->maxb = maxb, F->per_worker = per;
    return SOOC_OK;
}

sooc_status sooc_model_field_create(sooc_model_field **out, sooc_model *m, const sooc_cogmap *map,
                                    const double T_wc[16], const sooc_intrinsics *K, int max_obj,
                                    sooc_rng *sample_rng) {
    *out = NULL;
    const sooc_model_config *c = &m->cfg;
    if (max_obj < 0 || max_obj > SOOC_RENDER_MAX_COMP - 1) max_obj = SOOC_RENDER_MAX_COMP - 1;
    if (max_obj > SOOC_COGMAP_K_MAX) max_obj = SOOC_COGMAP_K_MAX;
    sooc_model_field *F = sooc_calloc(1, sizeof *F);
    if (!F) return SOOC_ENOMEM;
    F->m = m;
    double T_wg[16], T_gw[16], h, pitch, roll;
    sooc_status st = sooc_gframe(T_wc, T_wg, &h, &pitch, &roll);
    if (st) goto fail;
    sooc_se3_inverse(T_gw, T_wg);
    sooc_se3_mul(F->T_gc, T_gw, T_wc);
    F->iu = 1.0f / c->unit_m;
    F->h = (float)h * F->iu;
    if (c->global_frame) {   /* global-frame baseline (src/global): world axes, origin (0, h, 0) */
        double T_fw[16];
        sooc_se3_identity(T_fw);
        T_fw[7] = -h;
        sooc_se3_mul(F->T_gc, T_fw, T_wc);
    }
    sooc_cogmap_camera cam;
    memset(&cam, 0, sizeof cam);
    memcpy(cam.T_wc, T_wc, sizeof cam.T_wc);
    cam.K = *K;
    double u = c->unit_m;   /* the map's camera is in metres */
    cam.t_near = c->t_near * u, cam.d_clip = c->d_clip * u, cam.R_h = c->box_rh * u, cam.H_b = c->box_hb * u;
    cam.mode = SOOC_INVIEW_CORNERS;
    sooc_cogmap_slot slots[SOOC_COGMAP_K_MAX];
    int nret = 0;
    sooc_floor_frame gf;
    if ((st = sooc_cogmap_query(map, &cam, max_obj, slots, &nret, &gf, NULL))) goto fail;
    int32_t bi = 0, bj = 0;
    double blk[2] = {0, 0};
    if (c->global_frame)   /* baseline: world-frame slots, one layout latent at the world origin */
        for (int i = 0; i < nret; i++) world_lam(map, slots[i].id, slots[i].lam);
    else if ((st = sooc_cogmap_active_block(map, T_wc, cam.d_clip, &bi, &bj, blk)))
        goto fail;
    for (int i = 0; i < nret; i++) sooc_mdl_lam_from_m(c, slots[i].lam, 1, SOOC_LAM_SIZE(c->d_what));
    F->blk[0] = (float)blk[0] * F->iu, F->blk[1] = (float)-h * F->iu, F->blk[2] = (float)blk[1] * F->iu;
    int nc = 1 + nret, H = c->dec_width, d = c->d_what, dl = c->d_layout;
    F->comp = sooc_calloc(nc, sizeof(fcomp));
    F->boxes = sooc_calloc(nc, sizeof(sooc_render_box));
    F->biasbuf = sooc_calloc((size_t)nc * H, sizeof(float));
    if (!F->comp || !F->boxes || !F->biasbuf) {
        st = SOOC_ENOMEM;
        goto fail;
    }
    for (int k = 0; k < nc; k++) {
        fcomp *fc = &F->comp[k];
        fc->bias = F->biasbuf + (size_t)k * H;
        const sooc_dec_net *net = k ? &m->dobj : &m->dlay;
        float z[SOOC_MODEL_D_MAX];
        if (k == 0) {
            float mu[SOOC_COGMAP_DIM_MAX], lv[SOOC_COGMAP_DIM_MAX];
            if (sooc_cogmap_layout_get(map, bi, bj, mu, lv) != SOOC_OK) {
                sooc_clearerr();
                memcpy(mu, m->p + m->prior_lay, dl * sizeof(float));
                memcpy(lv, m->p + m->prior_lay + dl, dl * sizeof(float));
            }
            for (int i = 0; i < dl; i++)
                z[i] = mu[i] + (sample_rng ? expf(0.5f * lv[i]) * (float)sooc_rng_normal(sample_rng) : 0.0f);
            fc->id = 0;
            F->boxes[0].enabled = 0;
        } else {
            const float *l = slots[k - 1].lam;
            float st_ = sample_rng ? expf(0.5f * l[3]) : 0, sth = sample_rng ? expf(0.5f * l[4]) : 0;
            fc->px = l[0] + (sample_rng ? st_ * (float)sooc_rng_normal(sample_rng) : 0);
            fc->pz = l[1] + (sample_rng ? st_ * (float)sooc_rng_normal(sample_rng) : 0);
            fc->th = l[2] + (sample_rng ? sth * (float)sooc_rng_normal(sample_rng) : 0);
            for (int i = 0; i < d; i++)
                z[i] = l[5 + i] + (sample_rng ? expf(0.5f * l[5 + d + i]) * (float)sooc_rng_normal(sample_rng) : 0.0f);
            fc->id = slots[k - 1].id;
            /* the object's locality box in G (same as sooc_render_box_object) */
            sooc_render_box *b = &F->boxes[k];
            double R[9], t[3] = {fc->px * u, -h, fc->pz * u};   /* in metres */
            sooc_m3_rot_y(R, fc->th);
            b->enabled = 1;
            sooc_se3_from_rt(b->T_fb, R, t);
            b->lo[0] = -c->box_rh * u, b->lo[1] = 0, b->lo[2] = -c->box_rh * u;
            b->hi[0] = c->box_rh * u, b->hi[1] = c->box_hb * u, b->hi[2] = c->box_rh * u;
        }
        /* a finetuned decoder kept with the map (include/sooc3d/train.h): its own weights and z */
        size_t npl = 0;
        const float *pl = c->global_frame ? NULL
                          : k ? sooc_cogmap_payload_get(map, fc->id, &npl)
                              : sooc_cogmap_block_payload_get(map, bi, bj, &npl);
        if (pl && sooc_mdl_ft_payload_ok(net, k ? MDL_FT_OBJ : MDL_FT_LAY, pl, npl)) {
            fc->w = mdl_ft_payload_w(net, pl);
            sooc_mdl_dec_rel(net, &fc->rel);
            sooc_mdl_own_bias(fc->w, &fc->rel, mdl_ft_payload_z(pl), fc->bias);
            continue;
        }
        for (int j = 0; j < H; j++) fc->bias[j] = m->p[net->b1 + j];
        for (int i = 0; i < net->dz; i++)
            for (int j = 0; j < H; j++) fc->bias[j] += z[i] * m->p[net->W1z + (size_t)i * H + j];
    }
    F->f.n_comp = nc;
    F->f.boxes = F->boxes;
    F->f.sigma_max = c->sigma_max * F->iu;   /* density per metre */
    F->f.eval = field_eval;
    F->f.prepare = field_prepare;
    F->f.user = F;
    if ((st = field_prepare(F, 1, 256))) goto fail;
    *out = F;
    return SOOC_OK;
fail:
    sooc_model_field_destroy(F);
    return st;
}

void sooc_model_field_destroy(sooc_model_field *F) {
    if (!F) return;
    sooc_free(F->comp);
    sooc_free(F->boxes);
    sooc_free(F->biasbuf);
    sooc_free(F->scratch);
    sooc_free(F);
}

const sooc_field *sooc_model_field_get(const sooc_model_field *F) { return &F->f; }
void sooc_model_field_T_fc(const sooc_model_field *F, double T_fc[16]) { memcpy(T_fc, F->T_gc, sizeof F->T_gc); }
uint64_t sooc_model_field_comp_id(const sooc_model_field *F, int c) {
    return c >= 0 && c < F->f.n_comp ? F->comp[c].id : 0;
}
