/* Model creation, parameter slab, initialisation, checkpoint IO. */
#include "model/weights.h"

#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

void sooc_model_config_default(sooc_model_config *c) {
    memset(c, 0, sizeof *c);
    c->K = 7;
    c->d_what = 32;
    c->d_layout = 16;
    c->L = 3;
    c->img_w = c->img_h = 64;
    c->ray_w = c->ray_h = 32;
    c->dec_width = 64;
    c->dec_color_width = 32;
    c->n_freq = 5;
    c->n_freq_layout = 6;
    c->dens_bias_init = -2.0f;
    c->ref_ch[0] = 32; c->ref_ch[1] = 32; c->ref_ch[2] = 64; c->ref_ch[3] = 64;
    c->ref_fc = 128;
    c->ref_hidden = 128;
    c->sigma_max = 30.0f;
    c->sigma_c = 0.2f;
    c->air_cut = 0.98f;
    c->delta_s = 0.03f;
    c->eps_sigma_rel = 1e-4f;
    c->d_clip = 8.0f;
    c->t_near = 0.1f;
    c->box_rh = 0.6f;
    c->box_hb = 1.2f;
    c->gauss_s = 0.3f;
    c->block_size = 4.0f;
    c->use_box = 1;
    c->rho_min = -10.0f;
    c->rho_max = 4.0f;
    c->prior_sigma_t = 0.5f;
    c->prior_near = 1.3f;
    c->prior_far = 6.2f;
    c->prior_pres_logit = 0.0f;
    c->global_frame = 0;
    c->global_radius = 4.2f;
    c->slots = 0;
    c->invalid_depth = SOOC_INVALID_DEPTH_FREE;
    c->unit_m = 1.0f;
    c->cam_h_min = SOOC_MODEL_CAM_H_MIN;
    c->cam_h_max = SOOC_MODEL_CAM_H_MAX;
}

sooc_status sooc_model_config_check(const sooc_model_config *c) {
    if (c->K < 1 || c->K > SOOC_MODEL_K_MAX)
        return sooc_seterr(SOOC_EINVAL, "model config: K = %d outside 1..%d", c->K, SOOC_MODEL_K_MAX);
    if (c->d_what < 1 || c->d_what > SOOC_MODEL_D_MAX || c->d_layout < 1 || c->d_layout > SOOC_MODEL_D_MAX)
        return sooc_seterr(SOOC_EINVAL, "model config: d_what/d_layout outside 1..%d", SOOC_MODEL_D_MAX);
    if (c->L < 0 || c->L > 16) return sooc_seterr(SOOC_EINVAL, "model config: L = %d outside 0..16", c->L);
    if (c->slots != 0 && (c->slots < c->K || c->slots > SOOC_MODEL_K_MAX || c->global_frame))
        return sooc_seterr(SOOC_EINVAL, "model config: slots = %d; 0 or K (%d) .. %d, and 0 for the global-frame baseline",
                           c->slots, c->K, SOOC_MODEL_K_MAX);
    if (c->ray_w < 16 || c->ray_h < 16 || c->ray_w % 16 || c->ray_h % 16)
        return sooc_seterr(SOOC_EINVAL, "model config: ray grid %dx%d must be multiples of 16", c->ray_w, c->ray_h);
    if ((c->ray_w > 32 && c->ray_w % 32) || (c->ray_h > 32 && c->ray_h % 32))
        return sooc_seterr(SOOC_EINVAL, "model config: ray grid %dx%d: above 32 a side must be a multiple of 32",
                           c->ray_w, c->ray_h);
    if (c->img_w % c->ray_w || c->img_h % c->ray_h)
        return sooc_seterr(SOOC_EINVAL, "model config: image %dx%d not divisible by ray grid %dx%d", c->img_w,
                           c->img_h, c->ray_w, c->ray_h);
    if (c->img_w > 4096 || c->img_h > 4096 || c->ray_w > 1024 || c->ray_h > 1024)
        return sooc_seterr(SOOC_EINVAL, "model config: image %dx%d / ray grid %dx%d too large", c->img_w, c->img_h,
                           c->ray_w, c->ray_h);
    if (c->dec_width < 4 || c->dec_width > 1024 || c->dec_color_width < 1 || c->dec_color_width > 1024 ||
        c->n_freq < 0 || c->n_freq > 16 || c->n_freq_layout < 0 || c->n_freq_layout > 16)
        return sooc_seterr(SOOC_EINVAL, "model config: bad decoder sizes (width 4..1024, colour 1..1024, freq 0..16)");
    for (int i = 0; i < 4; i++)
        if (c->ref_ch[i] < 1 || c->ref_ch[i] > 1024)
            return sooc_seterr(SOOC_EINVAL, "model config: ref_ch[%d] = %d outside 1..1024", i, c->ref_ch[i]);
    if (c->ref_fc < 1 || c->ref_fc > 4096 || c->ref_hidden < 1 || c->ref_hidden > 1024)
        return sooc_seterr(SOOC_EINVAL, "model config: bad refinement sizes (fc 1..4096, hidden 1..1024)");
    if (!isfinite(c->dens_bias_init) || !(c->eps_sigma_rel >= 0 && c->eps_sigma_rel < 1) || !(c->delta_s >= 0) ||
        !(c->delta_s < 10) || !(c->t_near >= 0) || !(c->d_clip < 1e4) || !(c->sigma_max < 1e6) ||
        !(c->prior_sigma_t > 0 && c->prior_sigma_t < 1e3) || !isfinite(c->prior_near) || !isfinite(c->prior_far) ||
        !isfinite(c->prior_pres_logit) || !isfinite(c->rho_min) || !isfinite(c->rho_max) || !(c->block_size < 1e4) ||
        (c->use_box != 0 && c->use_box != 1) || (c->global_frame != 0 && c->global_frame != 1) ||
        (c->invalid_depth != SOOC_INVALID_DEPTH_FREE && c->invalid_depth != SOOC_INVALID_DEPTH_UNKNOWN) ||
        !(c->global_radius > 0 && c->global_radius < 1e4) || !(c->unit_m >= 1e-3f && c->unit_m <= 1e3f) ||
        !(c->cam_h_min > 0 && c->cam_h_max > c->cam_h_min && c->cam_h_max < 1e4f))
        return sooc_seterr(SOOC_EINVAL, "model config: constant out of range or non-finite");
    if (!(c->sigma_max > 0) || !(c->sigma_c > 0) || !(c->air_cut > 0 && c->air_cut < 1) || !(c->d_clip > c->t_near) ||
        !(c->box_rh > 0) || !(c->box_hb > 0) || !(c->gauss_s > 0) || !(c->block_size > 0) ||
        !(c->rho_max > c->rho_min))
        return sooc_seterr(SOOC_EINVAL, "model config: bad likelihood/geometry constants");
    return SOOC_OK;
}

static size_t add_t(sooc_model *m, size_t *off, const char *name, int rows, int cols, int no_decay) {
    SOOC_ASSERT(m->nt < MDL_MAXT);
    sooc_model_tensor *t = &m->t[m->nt++];
    t->name = name;
    t->offset = *off;
    t->rows = rows;
    t->cols = cols;
    t->count = (size_t)rows * cols;
    t->no_decay = no_decay;
    *off += t->count;
    return t->offset;
}

static void layout_dec(sooc_model *m, size_t *off, sooc_dec_net *n, int obj) {
    const sooc_model_config *c = &m->cfg;
    n->nfreq = obj ? c->n_freq : c->n_freq_layout;
    n->din = 3 + 6 * n->nfreq;
    n->dz = obj ? c->d_what : c->d_layout;
    n->H = c->dec_width;
    n->Hc = c->dec_color_width;
#define T(f, nm, r, cc, nd) n->f = add_t(m, off, obj ? "dec.obj." nm : "dec.lay." nm, r, cc, nd)
    T(W1x, "W1x", n->din, n->H, 0);
    T(W1z, "W1z", n->dz, n->H, 0);
    T(b1, "b1", n->H, 1, 1);
    T(W2, "W2", n->H, n->H, 0);
    T(b2, "b2", n->H, 1, 1);
    T(W3, "W3", n->H, n->H, 0);
    T(b3, "b3", n->H, 1, 1);
    T(Wd, "Wd", n->H, 1, 0);
    T(bd, "bd", 1, 1, 1);
    T(Wc1, "Wc1", n->H, n->Hc, 0);
    T(bc1, "bc1", n->Hc, 1, 1);
    T(Wc2, "Wc2", n->Hc, 3, 0);
    T(bc2, "bc2", 3, 1, 1);
#undef T
}

static void layout_ref(sooc_model *m, size_t *off, sooc_ref_net *n, int obj) {
    const sooc_model_config *c = &m->cfg;
    static const char *cwn[2][4] = {{"ref.lay.conv1.W", "ref.lay.conv2.W", "ref.lay.conv3.W", "ref.lay.conv4.W"},
                                    {"ref.obj.conv1.W", "ref.obj.conv2.W", "ref.obj.conv3.W", "ref.obj.conv4.W"}};
    static const char *cbn[2][4] = {{"ref.lay.conv1.b", "ref.lay.conv2.b", "ref.lay.conv3.b", "ref.lay.conv4.b"},
                                    {"ref.obj.conv1.b", "ref.obj.conv2.b", "ref.obj.conv3.b", "ref.obj.conv4.b"}};
    n->cin = sooc_mdl_aux_channels(!obj);
    int prev = n->cin;
    for (int i = 0; i < 4; i++) {
        n->ch[i] = c->ref_ch[i];
        n->cw[i] = add_t(m, off, cwn[obj][i], n->ch[i], prev * 9, 0);
        n->cb[i] = add_t(m, off, cbn[obj][i], n->ch[i], 1, 1);
        prev = n->ch[i];
    }
    n->nflat = prev * (c->ray_w > 32 ? 2 : c->ray_w / 16) * (c->ray_h > 32 ? 2 : c->ray_h / 16);   /* sooc_mdl_ref_flatten */
    n->fc = c->ref_fc;
    n->hid = c->ref_hidden;
    int NL = MDL_NL(c->d_what);
    n->nvec = obj ? (2 * NL + 4 + 2) : (4 * c->d_layout + 2);
    n->nout = obj ? NL : 2 * c->d_layout;
    n->fcW = add_t(m, off, obj ? "ref.obj.fc.W" : "ref.lay.fc.W", n->nflat, n->fc, 0);
    n->fcb = add_t(m, off, obj ? "ref.obj.fc.b" : "ref.lay.fc.b", n->fc, 1, 1);
    n->Wx = add_t(m, off, obj ? "ref.obj.lstm.Wx" : "ref.lay.lstm.Wx", n->fc + n->nvec, 4 * n->hid, 0);
    n->Wh = add_t(m, off, obj ? "ref.obj.lstm.Wh" : "ref.lay.lstm.Wh", n->hid, 4 * n->hid, 0);
    n->lb = add_t(m, off, obj ? "ref.obj.lstm.b" : "ref.lay.lstm.b", 4 * n->hid, 1, 1);
    n->hW = add_t(m, off, obj ? "ref.obj.head.W" : "ref.lay.head.W", n->hid, n->nout, 0);
    n->hb = add_t(m, off, obj ? "ref.obj.head.b" : "ref.lay.head.b", n->nout, 1, 1);
}

static void fill_unif(float *p, size_t n, float a, sooc_rng *r) {
    for (size_t i = 0; i < n; i++) p[i] = (2.0f * sooc_rng_uniformf(r) - 1.0f) * a;
}

static void init_dec(sooc_model *m, const sooc_dec_net *n, sooc_rng *r) {
    float *p = m->p;
    fill_unif(p + n->W1x, (size_t)n->din * n->H, sqrtf(6.0f / (n->din + n->dz)), r);
    fill_unif(p + n->W1z, (size_t)n->dz * n->H, sqrtf(6.0f / (n->din + n->dz)), r);
    fill_unif(p + n->W2, (size_t)n->H * n->H, sqrtf(6.0f / n->H), r);
    fill_unif(p + n->W3, (size_t)n->H * n->H, sqrtf(6.0f / n->H), r);
    fill_unif(p + n->Wd, (size_t)n->H, sqrtf(3.0f / n->H), r);
    p[n->bd] = m->cfg.dens_bias_init;
    fill_unif(p + n->Wc1, (size_t)n->H * n->Hc, sqrtf(6.0f / n->H), r);
    fill_unif(p + n->Wc2, (size_t)n->Hc * 3, sqrtf(3.0f / n->Hc), r);
}

static void init_ref(sooc_model *m, const sooc_ref_net *n, sooc_rng *r) {
    float *p = m->p;
    int prev = n->cin;
    for (int i = 0; i < 4; i++) {
        fill_unif(p + n->cw[i], (size_t)n->ch[i] * prev * 9, sqrtf(3.0f / (prev * 9)), r);
        prev = n->ch[i];
    }
    fill_unif(p + n->fcW, (size_t)n->nflat * n->fc, sqrtf(3.0f / n->nflat), r);
    float a = 1.0f / sqrtf((float)n->hid);
    fill_unif(p + n->Wx, (size_t)(n->fc + n->nvec) * 4 * n->hid, a, r);
    fill_unif(p + n->Wh, (size_t)n->hid * 4 * n->hid, a, r);
    for (int j = 0; j < n->hid; j++) p[n->lb + n->hid + j] = 1.0f;   /* forget-gate bias */
    /* head: zero (training starts from λ = prior) */
}

/* Per-slot prior means spread over the camera's ground footprint. */
static void init_priors(sooc_model *m) {
    const sooc_model_config *c = &m->cfg;
    int NL = m->NL, d = c->d_what;
    for (int k = 0; k < c->K; k++) {
        float *l = m->p + m->prior + (size_t)k * NL;
        float dist = c->K > 1 ? c->prior_near + (c->prior_far - c->prior_near) * k / (c->K - 1) : 0.5f * (c->prior_near + c->prior_far);
        static const float side[3] = {-1.0f, 1.0f, 0.0f};
        l[0] = side[k % 3] * 0.35f * dist;
        l[1] = dist;
        l[2] = 0;
        l[3] = logf(c->prior_sigma_t * c->prior_sigma_t);
        l[4] = logf((float)(M_PI * M_PI));
        for (int i = 0; i < d; i++) l[5 + i] = 0, l[5 + d + i] = 0;
        l[5 + 2 * d] = c->prior_pres_logit;
    }
}

/* The global-frame baseline's slot prior means (src/global, docs/baseline.md):
 * a Vogel (golden-angle) spiral over a disc of radius global_radius around
 * the world origin, so that every prefix of n slots is spread evenly over a
 * disc of radius R·sqrt(n/K) (a scene with fewer objects uses fewer slots,
 * see sooc_model_global_slots). Weights initialisation: this layer's. */
static void init_priors_global(sooc_model *m) {
    const sooc_model_config *c = &m->cfg;
    int NL = m->NL;
    const double ga = M_PI * (3.0 - sqrt(5.0));
    for (int k = 0; k < c->K; k++) {
        float *l = m->p + m->prior + (size_t)k * NL;
        double r = c->global_radius * sqrt((k + 0.5) / c->K), a = ga * k;
        l[0] = (float)(r * cos(a));
        l[1] = (float)(r * sin(a));
    }
}

/* Image channels of a refinement net's input (refine.c builds them). */
int sooc_mdl_aux_channels(int layout) { return layout ? 25 : 26; }

/* The baseline's queries on the config (its step and mapper: src/global). */
int sooc_model_is_global(const sooc_model *m) { return m && m->cfg.global_frame; }

int sooc_model_global_slots(const sooc_model *m, int n_objects) {
    int K = m->cfg.K;
    if (n_objects <= 0 || n_objects + 1 >= K) return K;
    return n_objects + 1;
}

sooc_status sooc_model_create(sooc_model **out, const sooc_model_config *c, uint64_t init_seed) {
    *out = NULL;
    sooc_status st = sooc_model_config_check(c);
    if (st) return st;
    sooc_model *m = sooc_calloc(1, sizeof *m);
    if (!m) return SOOC_ENOMEM;
    m->cfg = *c;
    m->NL = MDL_NL(c->d_what);
    size_t off = 0;
    layout_dec(m, &off, &m->dobj, 1);
    layout_dec(m, &off, &m->dlay, 0);
    layout_ref(m, &off, &m->robj, 1);
    layout_ref(m, &off, &m->rlay, 0);
    m->prior = add_t(m, &off, "prior.slots", c->K, m->NL, 1);
    m->prior_lay = add_t(m, &off, "prior.layout", 2 * c->d_layout, 1, 1);
    m->np = off;
    m->p = sooc_calloc(off, sizeof(float));
    m->g = sooc_calloc(off, sizeof(float));
    if (!m->p || !m->g) {
        sooc_model_destroy(m);
        return SOOC_ENOMEM;
    }
    sooc_rng r;
    sooc_rng_seed(&r, init_seed, 0x4d4f44454cULL);
    init_dec(m, &m->dobj, &r);
    init_dec(m, &m->dlay, &r);
    init_ref(m, &m->robj, &r);
    init_ref(m, &m->rlay, &r);
    init_priors(m);
    if (c->global_frame) init_priors_global(m);   /* the baseline: priors spread over the scene */
    *out = m;
    return SOOC_OK;
}

void sooc_model_destroy(sooc_model *m) {
    if (!m) return;
    sooc_free(m->p);
    sooc_free(m->g);
    sooc_free(m);
}

const sooc_model_config *sooc_model_get_config(const sooc_model *m) { return &m->cfg; }
void sooc_model_set_threads(sooc_model *m, int n) { m->threads = n < 0 ? 0 : n; }
void sooc_model_box_extent(const sooc_model_config *c, float ext[3]) {
    ext[0] = ext[2] = 2 * c->box_rh * c->unit_m;
    ext[1] = c->box_hb * c->unit_m;
}
sooc_status sooc_model_set_clip(sooc_model *m, float d_clip) {
    float u = m ? m->cfg.unit_m : 1.0f, dc = d_clip / u;   /* metres -> model units */
    if (!m || !(dc > m->cfg.t_near && dc < 1e4f))
        return sooc_seterr(SOOC_EINVAL, "model: clip depth %g m outside (t_near %g m, 1e4 units)", (double)d_clip,
                           m ? (double)(m->cfg.t_near * u) : 0.0);
    m->cfg.d_clip = dc;
    return SOOC_OK;
}
sooc_status sooc_model_set_unit(sooc_model *m, float unit_m) {
    if (!m) return sooc_seterr(SOOC_EINVAL, "model: no model");
    if (!(unit_m >= 1e-3f && unit_m <= 1e3f))
        return sooc_seterr(SOOC_EINVAL, "model: unit %g m per model unit outside [0.001, 1000]", (double)unit_m);
    m->cfg.unit_m = unit_m;
    return SOOC_OK;
}
void sooc_model_cam_heights_m(const sooc_model_config *c, double *lo_m, double *hi_m) {
    *lo_m = (double)c->cam_h_min * c->unit_m;
    *hi_m = (double)c->cam_h_max * c->unit_m;
}
sooc_status sooc_model_set_cam_heights(sooc_model *m, double lo_m, double hi_m) {
    if (!m) return sooc_seterr(SOOC_EINVAL, "model: no model");
    double u = m->cfg.unit_m;
    if (!(lo_m > 0 && hi_m > lo_m && hi_m / u < 1e4))
        return sooc_seterr(SOOC_EINVAL, "model: camera heights %g .. %g m: need 0 < min < max", lo_m, hi_m);
    m->cfg.cam_h_min = (float)(lo_m / u);
    m->cfg.cam_h_max = (float)(hi_m / u);
    return SOOC_OK;
}
void sooc_mdl_lam_from_m(const sooc_model_config *c, float *lam, int n, int NL) {
    float u = c->unit_m;
    if (u == 1.0f) return;   /* bit-identical for the unit model */
    float iu = 1.0f / u, dr = 2.0f * logf(u);
    for (int k = 0; k < n; k++, lam += NL) lam[0] *= iu, lam[1] *= iu, lam[3] -= dr;
}
void sooc_mdl_lam_to_m(const sooc_model_config *c, float *lam, int n, int NL) {
    float u = c->unit_m;
    if (u == 1.0f) return;
    float dr = 2.0f * logf(u);
    for (int k = 0; k < n; k++, lam += NL) lam[0] *= u, lam[1] *= u, lam[3] += dr;
}
/* Extra slot priors for a model run with more slots than it was trained with
 * (docs/model.md "slots at inference"): mirror images (x -> -x) of the learnt
 * priors whose depths are nearest the median of the learnt ones (mirror_order
 * ranks them middle-out; each round of added slots keeps slot order), so the
 * added slots cover the side of the footprint the alternating learnt priors
 * leave open, at the middle distances where a view holds most objects. */
static void mirror_order(const sooc_model *m, int *order) {
    int K = m->cfg.K, NL = m->NL;
    float z[SOOC_MODEL_K_MAX], zs[SOOC_MODEL_K_MAX];
    for (int k = 0; k < K; k++) zs[k] = z[k] = m->p[m->prior + (size_t)k * NL + 1];
    for (int i = 1; i < K; i++)   /* insertion sort for the median */
        for (int j = i; j > 0 && zs[j] < zs[j - 1]; j--) {
            float t = zs[j];
            zs[j] = zs[j - 1];
            zs[j - 1] = t;
        }
    float med = zs[(K - 1) / 2];
    for (int k = 0; k < K; k++) order[k] = k;
    for (int i = 1; i < K; i++)   /* stable: ties keep slot order */
        for (int j = i; j > 0 && fabsf(z[order[j]] - med) < fabsf(z[order[j - 1]] - med); j--) {
            int t = order[j];
            order[j] = order[j - 1];
            order[j - 1] = t;
        }
}

sooc_status sooc_model_copy_slots(const sooc_model *m, int K, sooc_model **out) {
    *out = NULL;
    if (!m) return sooc_seterr(SOOC_EINVAL, "model copy: no model");
    int K0 = m->cfg.K;
    if (K <= 0) K = m->cfg.slots > 0 ? m->cfg.slots : K0;
    if (K < K0 || K > SOOC_MODEL_K_MAX || (K != K0 && m->cfg.global_frame))
        return sooc_seterr(SOOC_EINVAL, "model: %d slots requested; this model has %d and runs with %d..%d%s", K, K0,
                           K0, m->cfg.global_frame ? K0 : SOOC_MODEL_K_MAX,
                           m->cfg.global_frame ? " (the global-frame baseline's slots are its scene's objects)" : "");
    sooc_model_config c = m->cfg;
    c.K = K;
    c.slots = 0;
    sooc_model *w;
    sooc_status st = sooc_model_create(&w, &c, 0);
    if (st) return sooc_adderr(st, "model copy with %d slots", K);
    /* the slab is laid out identically up to the slot priors, which come
     * last but for the layout prior (sooc_model_create) */
    int NL = m->NL;
    memcpy(w->p, m->p, m->prior * sizeof(float));
    memcpy(w->p + w->prior, m->p + m->prior, (size_t)K0 * NL * sizeof(float));
    memcpy(w->p + w->prior_lay, m->p + m->prior_lay, (size_t)2 * c.d_layout * sizeof(float));
    int order[SOOC_MODEL_K_MAX];
    mirror_order(m, order);
    for (int k = K0; k < K;) {   /* rounds of up to K0 added slots */
        int n = K - k < K0 ? K - k : K0;
        uint8_t chosen[SOOC_MODEL_K_MAX] = {0};
        for (int i = 0; i < n; i++) chosen[order[i]] = 1;
        for (int j = 0; j < K0; j++) {   /* the chosen priors in slot order, as pick_priors keeps them */
            if (!chosen[j]) continue;
            float *dst = w->p + w->prior + (size_t)k++ * NL;
            memcpy(dst, m->p + m->prior + (size_t)j * NL, NL * sizeof(float));
            dst[0] = -dst[0];   /* x -> -x; the heading prior (mean ~0, std ~pi) is kept */
        }
    }
    w->threads = m->threads;
    *out = w;
    return SOOC_OK;
}

sooc_status sooc_model_copy_rays(const sooc_model *m, int ray_w, int ray_h, sooc_model **out) {
    *out = NULL;
    if (!m) return sooc_seterr(SOOC_EINVAL, "model copy: no model");
    sooc_model_config c = m->cfg;
    c.ray_w = ray_w;
    c.ray_h = ray_h;
    sooc_status st = sooc_model_config_check(&c);
    if (st) return sooc_adderr(st, "model copy with a %dx%d ray grid", ray_w, ray_h);
    sooc_model *w;
    if ((st = sooc_model_create(&w, &c, 0))) return sooc_adderr(st, "model copy with a %dx%d ray grid", ray_w, ray_h);
    if (w->np != m->np) {   /* below 32 x 32 the grid sets the refinement FC size (sooc_mdl_ref_flatten) */
        sooc_model_destroy(w);
        return sooc_seterr(SOOC_EINVAL,
                           "model copy: its %dx%d ray grid and %dx%d give the refinement nets different FC sizes "
                           "(grids of 32 and more per side share them)",
                           m->cfg.ray_w, m->cfg.ray_h, ray_w, ray_h);
    }
    memcpy(w->p, m->p, m->np * sizeof(float));
    w->threads = m->threads;
    *out = w;
    return SOOC_OK;
}

sooc_status sooc_model_set_slots(sooc_model *m, int slots) {
    if (!m) return sooc_seterr(SOOC_EINVAL, "model: no model");
    sooc_model_config c = m->cfg;
    c.slots = slots;
    sooc_status st = sooc_model_config_check(&c);
    if (!st) m->cfg.slots = slots;
    return st;
}
sooc_status sooc_model_invalid_depth_parse(const char *s, int *mode) {
    if (s && !strcmp(s, "free")) *mode = SOOC_INVALID_DEPTH_FREE;
    else if (s && !strcmp(s, "unknown")) *mode = SOOC_INVALID_DEPTH_UNKNOWN;
    else return sooc_seterr(SOOC_EINVAL, "invalid depth mode '%s': expected free or unknown", s ? s : "(null)");
    return SOOC_OK;
}
const char *sooc_model_invalid_depth_name(int mode) {
    return mode == SOOC_INVALID_DEPTH_UNKNOWN ? "unknown" : mode == SOOC_INVALID_DEPTH_FREE ? "free" : "?";
}
sooc_status sooc_model_set_invalid_depth(sooc_model *m, int mode) {
    if (!m) return sooc_seterr(SOOC_EINVAL, "model: no model");
    if (mode != SOOC_INVALID_DEPTH_FREE && mode != SOOC_INVALID_DEPTH_UNKNOWN)
        return sooc_seterr(SOOC_EINVAL, "model: invalid depth mode %d (0 = free, 1 = unknown)", mode);
    m->cfg.invalid_depth = mode;
    return SOOC_OK;
}
size_t sooc_model_param_count(const sooc_model *m) { return m->np; }
float *sooc_model_params(sooc_model *m) { return m->p; }
float *sooc_model_grads(sooc_model *m) { return m->g; }
void sooc_model_zero_grad(sooc_model *m) { memset(m->g, 0, m->np * sizeof(float)); }

int sooc_model_tensors(const sooc_model *m, sooc_model_tensor *out, int cap) {
    if (out)
        for (int i = 0; i < m->nt && i < cap; i++) out[i] = m->t[i];
    return m->nt;
}

void sooc_step_opts_default(sooc_step_opts *o) {
    memset(o, 0, sizeof *o);
    o->tau = 1.0f;
    o->beta_kl = 1.0f;
    o->pres_mode = SOOC_PRES_RELAXED;
    o->prop_logit = o->prop_rest_logit = NAN;
}

/* ------------------------------------------------------------ checkpoint */

#define MDL_MAGIC "SOOCMDL1"
#define MDL_VERSION 6u   /* 2: config gained global_frame, global_radius; 3: slots; 4: invalid_depth; 5: unit_m;
                            6: cam_h_min, cam_h_max (appended) */
/* older files: the config without the fields appended since */
#define MDL_V1_CONFIG_SIZE offsetof(sooc_model_config, global_frame)
#define MDL_V2_CONFIG_SIZE offsetof(sooc_model_config, slots)
#define MDL_V3_CONFIG_SIZE offsetof(sooc_model_config, invalid_depth)
#define MDL_V4_CONFIG_SIZE offsetof(sooc_model_config, unit_m)
#define MDL_V5_CONFIG_SIZE offsetof(sooc_model_config, cam_h_min)

sooc_status sooc_model_save(const sooc_model *m, const char *path, const void *blob, size_t blob_size) {
    sooc_afile f;
    sooc_status st = sooc_afile_open(&f, path);
    if (st) return st;
    uint32_t ver = MDL_VERSION, csz = (uint32_t)sizeof(sooc_model_config);
    uint64_t np = m->np, bs = blob ? blob_size : 0;
    st = sooc_afile_write(&f, MDL_MAGIC, 8);
    if (!st) st = sooc_afile_write(&f, &ver, 4);
    if (!st) st = sooc_afile_write(&f, &csz, 4);
    if (!st) st = sooc_afile_write(&f, &m->cfg, csz);
    if (!st) st = sooc_afile_write(&f, &np, 8);
    if (!st) st = sooc_afile_write(&f, m->p, np * sizeof(float));
    if (!st) st = sooc_afile_write(&f, &bs, 8);
    if (!st && bs) st = sooc_afile_write(&f, blob, bs);
    if (!st) {
        uint32_t crc = f.crc;
        st = sooc_afile_write(&f, &crc, 4);
    }
    if (st) {
        sooc_afile_abort(&f);
        return sooc_adderr(st, "%s", path);
    }
    return sooc_afile_commit(&f);
}

sooc_status sooc_model_load(sooc_model **out, const char *path, void **blob, size_t *blob_size) {
    *out = NULL;
    if (blob) *blob = NULL;
    if (blob_size) *blob_size = 0;
    void *buf = NULL;
    size_t n = 0;
    sooc_status st = sooc_file_read_all(path, (size_t)1 << 32, &buf, &n);
    if (st) return st;
    const uint8_t *b = buf;
    uint32_t ver, csz, crc;
    uint64_t np, bs;
    sooc_model_config cfg;
    sooc_model *m = NULL;
    if (n < 8 + 4 + 4 + sizeof cfg + 8 + 8 + 4 || memcmp(b, MDL_MAGIC, 8)) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: not a sooc3d model file (bad magic or too short)", path);
        goto done;
    }
    memcpy(&crc, b + n - 4, 4);
    if (sooc_crc32(0, b, n - 4) != crc) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: CRC mismatch (file corrupt or truncated)", path);
        goto done;
    }
    memcpy(&ver, b + 8, 4);
    memcpy(&csz, b + 12, 4);
    int v1 = (ver == 1u && csz == MDL_V1_CONFIG_SIZE) || (ver == 2u && csz == MDL_V2_CONFIG_SIZE) ||
             (ver == 3u && csz == MDL_V3_CONFIG_SIZE) || (ver == 4u && csz == MDL_V4_CONFIG_SIZE) ||
             (ver == 5u && csz == MDL_V5_CONFIG_SIZE);
    if (!v1 && (ver != MDL_VERSION || csz != sizeof cfg)) {
        st = sooc_seterr(SOOC_EVERSION, "%s: model file version %u / config size %u, expected %u / %zu", path, ver,
                         csz, MDL_VERSION, sizeof cfg);
        goto done;
    }
    if (v1) {                              /* version 1 to 5 */
        sooc_model_config_default(&cfg);   /* appended fields keep their defaults */
        if (n < 8 + 4 + 4 + (size_t)csz + 8 + 8 + 4) {
            st = sooc_seterr(SOOC_EFORMAT, "%s: too short", path);
            goto done;
        }
    }
    memcpy(&cfg, b + 16, csz);
    size_t o = 16 + (size_t)csz;
    memcpy(&np, b + o, 8);
    o += 8;
    if ((st = sooc_model_create(&m, &cfg, 0))) {
        sooc_adderr(st, "%s: config", path);
        goto done;
    }
    if (np != m->np || np > (n - o) / 4 || o + np * 4 + 8 + 4 > n) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: %llu parameters stored, config needs %zu", path, (unsigned long long)np,
                         m->np);
        goto done;
    }
    memcpy(m->p, b + o, np * 4);
    o += np * 4;
    memcpy(&bs, b + o, 8);
    o += 8;
    if (bs > n || o + bs + 4 != n) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: trainer blob size %llu inconsistent with file size", path,
                         (unsigned long long)bs);
        goto done;
    }
    if (blob && bs) {
        *blob = sooc_malloc(bs);
        if (!*blob) {
            st = SOOC_ENOMEM;
            goto done;
        }
        memcpy(*blob, b + o, bs);
        if (blob_size) *blob_size = bs;
    }
    for (size_t i = 0; i < m->np; i++)
        if (!isfinite(m->p[i])) {
            st = sooc_seterr(SOOC_ENUMERIC, "%s: non-finite parameter at index %zu", path, i);
            goto done;
        }
    *out = m;
    m = NULL;
done:
    if (st && blob && *blob) {
        sooc_free(*blob);
        *blob = NULL;
    }
    sooc_model_destroy(m);
    sooc_free(buf);
    return st;
}
