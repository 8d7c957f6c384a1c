/* The fused object/layout NeRF decoder, composition, two-sample likelihood and
 * the KL terms of a decode, forward and backward (the SOOC3D paper,
 * arXiv:2309.14010; docs/model.md). The rays and samples are dec_rays.c's, the
 * KL divergences dec_kl.c's.
 *
 * Rows: every (point, object slot) pair whose object-local point falls inside
 * the slot's locality box becomes one row of the object MLP (all slots share
 * the weights, so one GEMM per layer covers every slot; z^what enters as a
 * per-slot bias of layer 1). The layout MLP gets one row per used point.
 * Weight layout: W is [in x out] row-major, Y = X W + b. */
#include "model/decoder.h"

#include <math.h>
#include <string.h>
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

static inline float sigm(float x) { return 1.0f / (1.0f + expf(-x)); }
static inline float clampf(float x, float a, float b) { return x < a ? a : x > b ? b : x; }

static int nthreads(const sooc_model *m) {
#ifdef SOOC_HAVE_OPENMP
    return m->threads > 0 ? m->threads : omp_get_max_threads();
#else
    (void)m;
    return 1;
#endif
}

/* ---------------------------------------------------------------- MLP */

void sooc_mdl_pe_row(const float *x, float inv, int nf, float *out) {
    float v[3] = {x[0] * inv, x[1] * inv, x[2] * inv}, sn[3], cs[3];
    out[0] = v[0], out[1] = v[1], out[2] = v[2];
    for (int a = 0; a < 3; a++) {
        sn[a] = sinf(v[a]);
        cs[a] = cosf(v[a]);
    }
    int o = 3;
    for (int f = 0; f < nf; f++) {
        for (int a = 0; a < 3; a++) {
            out[o + a] = sn[a];
            out[o + 3 + a] = cs[a];
            /* double angle: sin 2x = 2 sin x cos x, cos 2x = cos^2 x - sin^2 x (rel. error ~1e-6 at 2^4) */
            float s2 = 2.0f * sn[a] * cs[a], c2 = cs[a] * cs[a] - sn[a] * sn[a];
            sn[a] = s2, cs[a] = c2;
        }
        o += 6;
    }
}

/* dL/dx from dL/dpe (pe as built by pe_row). */
static void pe_row_back(const float *pe, const float *gpe, float inv, int nf, float gx[3]) {
    for (int a = 0; a < 3; a++) gx[a] = gpe[a] * inv;
    int o = 3;
    for (int f = 0; f < nf; f++) {
        float s = (float)(1 << f) * inv;
        for (int a = 0; a < 3; a++) gx[a] += s * (gpe[o + a] * pe[o + 3 + a] - gpe[o + 3 + a] * pe[o + a]);
        o += 6;
    }
}

/* Rows per block inside a thread's range: a block's activations (~4 x 256 x 64
 * floats) stay in L2 between layers. */
#define MDL_BLOCK_ROWS 256   /* rows per block of a thread's contiguous range (weight-gradient backward) */
/* Rows per dynamically scheduled block of the decode (forward, and backward without weight gradients). */
#define MDL_DYN_ROWS 128

/* Layers 2.. of the decoders run on the engine (nn/nn_kern.h, src/nn/nerf.c).
 * Transposed weights ([out x in]) for the input-gradient GEMMs: dec_wt. */
typedef struct dec_wt {
    const float *W2, *W3, *Wc1, *W1x;
} dec_wt;

static sooc_nn_nerf_tail tail_of(const float *p, const sooc_dec_net *n, const dec_wt *wt) {
    sooc_nn_nerf_tail t = {n->H, n->Hc, p + n->W2, p + n->b2, p + n->W3, p + n->b3, p + n->Wd, p + n->bd,
                           p + n->Wc1, p + n->bc1, p + n->Wc2, p + n->bc2,
                           wt ? wt->W2 : NULL, wt ? wt->W3 : NULL, wt ? wt->Wc1 : NULL};
    return t;
}

/* Layers 2.. of a decoder on R rows (serial; callers split rows across
 * threads) whose layer-1 pre-activation is in a1 (ReLU applied here unless a1_relu). */
static void tail_forward(const sooc_model *m, const sooc_dec_net *n, int R, float *a1, float *a2, float *a3, float *ac,
                         float *sig, float *col, int a1_relu) {
    sooc_nn_nerf_tail t = tail_of(m->p, n, NULL);
    sooc_nn_nerf_tail_forward(&t, R, a1, a2, a3, ac, sig, col, !a1_relu);
}

void sooc_mdl_mlp_tail_forward(const sooc_model *m, const sooc_dec_net *n, int R, float *a1, float *a2, float *a3, float *ac,
                          float *sig, float *col) {
    tail_forward(m, n, R, a1, a2, a3, ac, sig, col, 0);
}

static size_t wt_floats(const sooc_dec_net *n, int with_w1) {
    return (size_t)n->H * (2 * n->H + n->Hc + (with_w1 ? n->din : 0));
}

static void transpose(const float *restrict W, int rows, int cols, float *restrict T) {
    for (int i = 0; i < rows; i++)
        for (int j = 0; j < cols; j++) T[(size_t)j * rows + i] = W[(size_t)i * cols + j];
}

static float *wt_build(const float *p, const sooc_dec_net *n, int with_w1, float *buf, dec_wt *t) {
    int H = n->H, Hc = n->Hc;
    t->W2 = buf, transpose(p + n->W2, H, H, buf), buf += (size_t)H * H;
    t->W3 = buf, transpose(p + n->W3, H, H, buf), buf += (size_t)H * H;
    t->Wc1 = buf, transpose(p + n->Wc1, H, Hc, buf), buf += (size_t)H * Hc;
    t->W1x = NULL;
    if (with_w1) t->W1x = buf, transpose(p + n->W1x, n->din, H, buf), buf += (size_t)H * n->din;
    return buf;
}

/* Backward through layers 2.. to the layer-1 pre-activation gradient g1 (R x H)
 * (serial on a row range). gsig, gcol: dL/d(sigmoid outputs) on entry
 * (overwritten with pre-sigmoid grads). Weight grads scaled by ws go to the
 * slab `g` (a thread-private copy; 0 = skip). Scratch gA, gB (R x H each; the
 * colour hidden layer's gradient lives in gB); g1 may alias gA. */
static void mlp_tail_backward(const sooc_model *m, float *g, const sooc_dec_net *n, const dec_wt *wt, int R,
                              const float *a1, const float *a2, const float *a3, const float *ac, const float *sig,
                              const float *col, float *gsig, float *gcol, float *gA, float *gB, float *g1, float ws) {
    if (R <= 0) return;
    SOOC_ASSERT(n->Hc <= n->H);
    sooc_nn_nerf_tail t = tail_of(m->p, n, wt);
    sooc_nn_nerf_tail_grad tg = {0};
    if (ws != 0)
        tg = (sooc_nn_nerf_tail_grad){g + n->W2, g + n->b2, g + n->W3, g + n->b3, g + n->Wd, g + n->bd,
                                      g + n->Wc1, g + n->bc1, g + n->Wc2, g + n->bc2};
    sooc_nn_nerf_tail_backward(&t, ws != 0 ? &tg : NULL, ws, R, a1, a2, a3, ac, sig, col, gsig, gcol, gA, gB, gB, g1);
}

static inline void chunk_of(int n, int tid, int nth, int *r0, int *r1) {
    *r0 = (int)((long)n * tid / nth);
    *r1 = (int)((long)n * (tid + 1) / nth);
}
#ifdef SOOC_HAVE_OPENMP
#define TID() omp_get_thread_num()
#define NTH() omp_get_num_threads()
#else
#define TID() 0
#define NTH() 1
#endif

/* ---------------------------------------------------------------- decode */

typedef struct slot_sample {
    float sig_t, sig_th, sig_what[SOOC_MODEL_D_MAX];
} slot_sample;

/* Backward of one block of object / layout rows (step 7 of sooc_mdl_decode). Leaves
 * each row's layer-1 pre-activation gradient in gA (object row r at r, layout
 * row r at loff + r) and, for object rows, the row's z^where gradient in the
 * first 3 floats of its gpe row. Weight gradients (ws != 0) go to tg. */
typedef struct bwd_ctx {
    const sooc_model *m;
    const sooc_dec_ws *w;
    const sooc_dec_call *c;
    const sooc_dec_net *no, *nl;
    const dec_wt *pwo, *pwl;
    float *gsig, *gcol, ws, inv_o, s_g;
    int C, loff;
} bwd_ctx;

static void bwd_obj_block(const bwd_ctx *x, int b0, int R, float *tg) {
    const sooc_model *m = x->m;
    const sooc_dec_ws *w = x->w;
    const sooc_dec_net *no = x->no;
    const sooc_dec_call *c = x->c;
    int H = no->H, C = x->C;
    float *g1 = w->gA + (size_t)b0 * H;
    mlp_tail_backward(m, tg, no, x->pwo, R, w->o_a1 + (size_t)b0 * H, w->o_a2 + (size_t)b0 * H, w->o_a3 + (size_t)b0 * H,
                      w->o_ac + (size_t)b0 * no->Hc, w->o_sig + b0, w->o_col + (size_t)b0 * 3, x->gsig + b0,
                      x->gcol + (size_t)b0 * 3, w->gA + (size_t)b0 * H, w->gB + (size_t)b0 * H, g1, x->ws);
    /* layer 1 (its bias is the slot bias, whose gradient the caller sums): W1x and dL/dpe */
    sooc_nn_dense_backward(R, no->din, H, g1, H, w->o_pe + (size_t)b0 * no->din, no->din, m->p + no->W1x,
                           x->pwo ? x->pwo->W1x : NULL, w->gpe + (size_t)b0 * no->din, no->din, 0, NULL,
                           x->ws != 0 ? tg + no->W1x : NULL, NULL, x->ws);
    for (int r = b0; r < b0 + R; r++) {
        int k = w->ro_slot[r], pt = w->ro_pt[r];
        float gx[3], *gw = w->gpe + (size_t)r * no->din;
        const float *xk = w->o_xk + (size_t)r * 3;
        pe_row_back(w->o_pe + (size_t)r * no->din, gw, x->inv_o, no->nfreq, gx);
        sooc_mdl_gauss_backward(w->gsh[(size_t)pt * C + 1 + k], w->o_sig[r], c->zp[k], xk, x->s_g, gx);
        gw[0] = gw[1] = gw[2] = 0.0f;   /* the row's dL/dpe is consumed: reuse it for dL/d(px, pz, th) */
        sooc_mdl_pi_backward(xk, c->zw[k][2], gx, gw);
    }
}

static void bwd_lay_block(const bwd_ctx *x, int b0, int R, float *tg) {
    const sooc_model *m = x->m;
    const sooc_dec_ws *w = x->w;
    const sooc_dec_net *nl = x->nl;
    int H = nl->H, s0 = x->loff + b0;
    float *g1 = w->gA + (size_t)s0 * H;
    mlp_tail_backward(m, tg, nl, x->pwl, R, w->l_a1 + (size_t)b0 * H, w->l_a2 + (size_t)b0 * H, w->l_a3 + (size_t)b0 * H,
                      w->l_ac + (size_t)b0 * nl->Hc, w->l_sig + b0, w->l_col + (size_t)b0 * 3, x->gsig + s0,
                      x->gcol + (size_t)s0 * 3, w->gA + (size_t)s0 * H, w->gB + (size_t)s0 * H, g1, x->ws);
    if (x->ws != 0)
        sooc_nn_dense_backward(R, nl->din, H, g1, H, w->l_pe + (size_t)b0 * nl->din, nl->din, m->p + nl->W1x, NULL, NULL,
                               0, 0, NULL, tg + nl->W1x, NULL, x->ws);
}

/* One fixed block of object or layout rows of the decoder forward (a pool task). */
typedef struct fwd_job {
    const sooc_model *m;
    const sooc_dec_ws *w;
    const sooc_view_rays *vr;
    int nbo, nro, nrl, lpe_keep;   /* lpe_keep: l_pe already holds the layout rows' PE */
    float inv_o, inv_l;
} fwd_job;

static void fwd_task(void *ctx, int blk, int tid) {
    const fwd_job *j = ctx;
    const sooc_model *m = j->m;
    const sooc_dec_ws *w = j->w;
    const sooc_dec_net *no = &m->dobj, *nl = &m->dlay;
    const sooc_view_rays *vr = j->vr;
    const float *p = m->p;
    int H = m->cfg.dec_width, nro = j->nro, nrl = j->nrl, nbo = j->nbo;
    (void)tid;
    if (blk < nbo) {
        int r0 = blk * MDL_DYN_ROWS, r1 = r0 + MDL_DYN_ROWS < nro ? r0 + MDL_DYN_ROWS : nro;
        for (int r = r0; r < r1; r++) sooc_mdl_pe_row(w->o_xk + (size_t)r * 3, j->inv_o, no->nfreq, w->o_pe + (size_t)r * no->din);
        for (int r = r0; r < r1; r++)
            memcpy(w->o_a1 + (size_t)r * H, w->slot_bias + (size_t)(1 + w->ro_slot[r]) * H, H * sizeof(float));
        sooc_nn_dense_forward(r1 - r0, no->din, H, w->o_pe + (size_t)r0 * no->din, no->din, p + no->W1x, NULL,
                              w->o_a1 + (size_t)r0 * H, H, 1, SOOC_NN_EP_RELU);
        tail_forward(m, no, r1 - r0, w->o_a1 + (size_t)r0 * H, w->o_a2 + (size_t)r0 * H, w->o_a3 + (size_t)r0 * H,
                     w->o_ac + (size_t)r0 * no->Hc, w->o_sig + r0, w->o_col + (size_t)r0 * 3, 1);
    } else {
        int r0 = (blk - nbo) * MDL_DYN_ROWS, r1 = r0 + MDL_DYN_ROWS < nrl ? r0 + MDL_DYN_ROWS : nrl;
        for (int r = r0; r < r1 && !j->lpe_keep; r++) {
            const float *x = vr->pts + (size_t)w->lr_pt[r] * 3;
            float xl[3] = {x[0] - vr->blk[0], x[1] - vr->blk[1], x[2] - vr->blk[2]};
            sooc_mdl_pe_row(xl, j->inv_l, nl->nfreq, w->l_pe + (size_t)r * nl->din);
        }
        sooc_nn_dense_forward(r1 - r0, nl->din, H, w->l_pe + (size_t)r0 * nl->din, nl->din, p + nl->W1x, w->slot_bias,
                              w->l_a1 + (size_t)r0 * H, H, 0, SOOC_NN_EP_RELU);
        tail_forward(m, nl, r1 - r0, w->l_a1 + (size_t)r0 * H, w->l_a2 + (size_t)r0 * H, w->l_a3 + (size_t)r0 * H,
                     w->l_ac + (size_t)r0 * nl->Hc, w->l_sig + r0, w->l_col + (size_t)r0 * 3, 1);
    }
}

/* One fixed block of the decoder backward without weight gradients (a pool task). */
typedef struct bwd_job {
    const bwd_ctx *bx;
    int nbo, no_, nl_;
} bwd_job;

static void bwd_task(void *ctx, int blk, int tid) {
    const bwd_job *j = ctx;
    (void)tid;
    int b0 = (blk < j->nbo ? blk : blk - j->nbo) * MDL_DYN_ROWS, n = blk < j->nbo ? j->no_ : j->nl_;
    int R = n - b0 < MDL_DYN_ROWS ? n - b0 : MDL_DYN_ROWS;
    if (blk < j->nbo) bwd_obj_block(j->bx, b0, R, NULL);
    else bwd_lay_block(j->bx, b0, R, NULL);
}

/* Slot-bias and z^where gradient sums of one backward pass (step 7): task t <
 * SB_TASKS sums columns [t H / SB_TASKS, (t + 1) H / SB_TASKS) of every row's
 * layer-1 pre-activation gradient into its component's g_bias row, task SB_TASKS
 * the object rows' z^where gradients; every sum runs in row order. */
#define SB_TASKS 4
typedef struct sb_job {
    sooc_dec_ws *w;
    int no_, nl_, loff, H, din;
    float (*gzw)[3];
} sb_job;

static void sb_task(void *ctx, int t, int tid) {
    const sb_job *j = ctx;
    sooc_dec_ws *w = j->w;
    int H = j->H;
    (void)tid;
    if (t == SB_TASKS) {
        for (int r = 0; r < j->no_; r++) {
            int k = w->ro_slot[r];
            const float *gw = w->gpe + (size_t)r * j->din;
            j->gzw[k][0] += gw[0], j->gzw[k][1] += gw[1], j->gzw[k][2] += gw[2];
        }
        return;
    }
    int j0 = H * t / SB_TASKS, j1 = H * (t + 1) / SB_TASKS;
    for (int r = 0; r < j->no_; r++) {
        float *restrict gb = w->g_bias + (size_t)(1 + w->ro_slot[r]) * H;
        const float *restrict gr = w->gA + (size_t)r * H;
        for (int q = j0; q < j1; q++) gb[q] += gr[q];
    }
    for (int r = 0; r < j->nl_; r++) {
        float *restrict gb = w->g_bias;
        const float *restrict gr = w->gA + (size_t)(j->loff + r) * H;
        for (int q = j0; q < j1; q++) gb[q] += gr[q];
    }
}

/* One decode's shared state, passed through its parts (sooc_mdl_decode below). */
typedef struct dec_run {
    sooc_model_ws *x;
    sooc_model *m;
    const sooc_model_config *cfg;
    sooc_dec_ws *w;
    sooc_dec_call *c;
    const sooc_view_rays *vr;
    const sooc_dec_net *no, *nl;
    const float *p;
    int N, P, K, C, d, dl, NL, H, nt;
    float rmin, rmax, tau, sigc;
    float inv_o, inv_l;           /* PE scales of the object / layout rows */
    int nro, nrl;                 /* object / layout rows */
    slot_sample ss[SOOC_MODEL_K_MAX];
    float sig_lay[SOOC_MODEL_D_MAX];
    /* backward: gradients w.r.t. the samples */
    float gzw[SOOC_MODEL_K_MAX][3], gzwhat[SOOC_MODEL_K_MAX][SOOC_MODEL_D_MAX], gzp[SOOC_MODEL_K_MAX];
    float gzl[SOOC_MODEL_D_MAX];
} dec_run;

/* 1. Samples: z^where, z^what, z^pres of every slot and the layout latent. */
static void dec_samples(dec_run *r) {
    sooc_dec_call *c = r->c;
    int K = r->K, d = r->d, dl = r->dl, NL = r->NL;
    float rmin = r->rmin, rmax = r->rmax, tau = r->tau;
    slot_sample *ss = r->ss;
    for (int k = 0; k < K; k++) {
        const float *l = c->lam + (size_t)k * NL;
        const sooc_dec_noise *ns = c->noise;
        ss[k].sig_t = expf(0.5f * clampf(l[3], rmin, rmax));
        ss[k].sig_th = expf(0.5f * clampf(l[4], rmin, rmax));
        c->zw[k][0] = l[0] + ss[k].sig_t * ns->eps_where[k][0];
        c->zw[k][1] = l[1] + ss[k].sig_t * ns->eps_where[k][1];
        c->zw[k][2] = l[2] + ss[k].sig_th * ns->eps_where[k][2];
        for (int i = 0; i < d; i++) {
            ss[k].sig_what[i] = expf(0.5f * clampf(l[5 + d + i], rmin, rmax));
            c->zwhat[k][i] = l[5 + i] + ss[k].sig_what[i] * ns->eps_what[k][i];
        }
        float zs = sigm((l[5 + 2 * d] + ns->logistic[k]) / tau);
        c->zp_soft[k] = zs;
        int hm = c->hard ? c->hard[k] : 0;
        c->zp[k] = hm == 1 ? (zs >= 0.5f ? 1.0f : 0.0f) : hm == 2 ? 1.0f : zs;
    }
    for (int i = 0; i < dl; i++) {
        r->sig_lay[i] = expf(0.5f * clampf(c->lay[dl + i], rmin, rmax));
        c->zlay[i] = c->lay[i] + r->sig_lay[i] * c->noise->eps_lay[i];
    }
}

/* Layer-1 biases per component (comp 0 = layout, 1..K objects): b1 + z W1z. */
static void dec_slot_biases(dec_run *r) {
    const sooc_dec_call *c = r->c;
    const float *p = r->p;
    int K = r->K, H = r->H;
    for (int k = 0; k <= K; k++) {
        const sooc_dec_net *n = k ? r->no : r->nl;
        const float *z = k ? c->zwhat[k - 1] : c->zlay;
        float *b = r->w->slot_bias + (size_t)k * H;
        for (int j = 0; j < H; j++) b[j] = p[n->b1 + j];
        for (int i = 0; i < n->dz; i++) {
            const float *Wr = p + n->W1z + (size_t)i * H;
            for (int j = 0; j < H; j++) b[j] += z[i] * Wr[j];
        }
    }
}

/* 2. Rows: an object row per (used point, slot) inside the slot's locality
 * box, a layout row per used point; rowof maps (point, component) -> row. */
static void dec_rows(dec_run *r) {
    const sooc_model_config *cfg = r->cfg;
    const sooc_dec_call *c = r->c;
    const sooc_view_rays *vr = r->vr;
    sooc_dec_ws *w = r->w;
    int P = r->P, K = r->K, C = r->C;
    float cth[SOOC_MODEL_K_MAX], sth[SOOC_MODEL_K_MAX];
    for (int k = 0; k < K; k++) cth[k] = cosf(c->zw[k][2]), sth[k] = sinf(c->zw[k][2]);
    int nro = 0;
    for (int pt = 0; pt < P; pt++) {
        int used = (pt & 1) ? !vr->unk[pt >> 1] : vr->surf[pt >> 1];
        for (int k = 0; k < C; k++) w->rowof[(size_t)pt * C + k] = -1;
        if (!used) continue;
        const float *x = vr->pts + (size_t)pt * 3;
        for (int k = 0; k < K; k++) {
            float xk[3];
            mdl_pi_cs(x, c->zw[k][0], c->zw[k][1], cth[k], sth[k], vr->h, xk);
            if (cfg->use_box && (fabsf(xk[0]) > cfg->box_rh || fabsf(xk[2]) > cfg->box_rh || xk[1] < 0 ||
                                 xk[1] > cfg->box_hb))
                continue;
            w->ro_pt[nro] = pt;
            w->ro_slot[nro] = k;
            memcpy(w->o_xk + (size_t)nro * 3, xk, sizeof xk);
            float gf = 1.0f;
            if (c->zw_sg) {
                float xs[3];
                const float *zs = c->zw_sg + 3 * k;
                sooc_mdl_pi(x, zs[0], zs[1], zs[2], vr->h, xs);
                float is = 1.0f / (2 * cfg->gauss_s * cfg->gauss_s);
                gf = expf(-(xk[0] * xk[0] + xk[2] * xk[2] - xs[0] * xs[0] - xs[2] * xs[2]) * is);
            }
            w->o_gf[nro] = gf;
            w->rowof[(size_t)pt * C + 1 + k] = nro;
            nro++;
        }
    }
    w->nro = nro;
    /* layout rows: the used points, compacted (their row in rowof's comp 0) */
    int nrl = 0;
    for (int pt = 0; pt < P; pt++)
        if ((pt & 1) ? !vr->unk[pt >> 1] : vr->surf[pt >> 1]) w->rowof[(size_t)pt * C] = nrl++;
    for (int pt = 0; pt < P; pt++) {
        int rl = w->rowof[(size_t)pt * C];
        if (rl >= 0) w->lr_pt[rl] = pt;
    }
    r->nro = nro;
    r->nrl = nrl;
}

/* 3. PE + MLPs of every row. Fixed blocks of rows handed out dynamically:
 * every row's result is the same whichever thread computes it, and a thread
 * that the OS delays (a loaded machine) holds up the others by at most one
 * block. */
static void dec_forward(dec_run *r) {
    int nro = r->nro, nrl = r->nrl;
    int nbo = (nro + MDL_DYN_ROWS - 1) / MDL_DYN_ROWS, nbl = (nrl + MDL_DYN_ROWS - 1) / MDL_DYN_ROWS;
    sooc_dec_ws *w = r->w;
    int keep = r->c->same_rays && w->lpe_vr == r->vr && w->lpe_nrl == nrl;
    fwd_job fj = {r->m, w, r->vr, nbo, nro, nrl, keep, r->inv_o, r->inv_l};
    if (nro + nrl >= MDL_PAR_ROWS && r->nt > 1) sooc_mdl_par_run(r->x, nbo + nbl, fwd_task, &fj);
    else
        for (int blk = 0; blk < nbo + nbl; blk++) fwd_task(&fj, blk, 0);
    w->lpe_vr = r->vr;
    w->lpe_nrl = nrl;
}

#ifdef MDL_HAVE_AVX2_PATHS
#define POST_AVX2 1

/* sooc_mdl_aux_post_ray for C <= 8 components on one vector (the scalar loop's operations,
 * the normaliser summed in component order: bitwise equal). */
static MDL_TGT_AVX2 void post_ray_avx2(sooc_dec_ws *w, const sooc_view_rays *vr, int rr, int C, float is2) {
    const float *sh_s = w->sh + (size_t)2 * rr * C, *ct_s = w->ct + (size_t)2 * rr * C * 3;
    float S = w->S[2 * rr], *lv = w->ll_cf + (size_t)rr * C;
    __m256i k = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    __m256i m = _mm256_cmpgt_epi32(_mm256_set1_epi32(C), k);
    __m256 mf = _mm256_castsi256_ps(m), zero = _mm256_setzero_ps(), e = zero;
    __m256i k3 = _mm256_add_epi32(_mm256_add_epi32(k, k), k);
    for (int a = 0; a < 3; a++) {
        __m256 ct = _mm256_mask_i32gather_ps(zero, ct_s + a, k3, mf, 4);
        __m256 dd = _mm256_sub_ps(_mm256_set1_ps(vr->rgb[rr * 3 + a]), ct);
        e = _mm256_add_ps(e, _mm256_mul_ps(dd, dd));
    }
    __m256 lx = _mm256_add_ps(_mm256_div_ps(_mm256_maskload_ps(sh_s, m), _mm256_set1_ps(S)), _mm256_set1_ps(1e-10f));
    __m256 lg = mdl_logf_pos8(lx);
    __m256 ok = _mm256_and_ps(_mm256_cmp_ps(lx, _mm256_set1_ps(1.17549435e-38f), _CMP_GE_OQ),
                              _mm256_cmp_ps(lx, _mm256_set1_ps(3.40282347e38f), _CMP_LE_OQ));
    float xs[8], l[8];
    int bad = _mm256_movemask_ps(_mm256_andnot_ps(ok, mf));
    if (bad) {   /* 0, subnormal, inf, NaN: logf, as sooc_nn_logf_pos */
        _mm256_storeu_ps(xs, lx);
        _mm256_storeu_ps(l, lg);
        for (int q = 0; q < C; q++)
            if (bad >> q & 1) l[q] = logf(xs[q]);
        lg = _mm256_loadu_ps(l);
    }
    __m256 v = _mm256_sub_ps(lg, _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(0.5f), e), _mm256_set1_ps(is2)));
    _mm256_storeu_ps(l, v);
    float lmax = -1e30f;   /* the scalar loop's running maximum (NaN never counts) */
    for (int q = 0; q < C; q++)
        if (l[q] > lmax) lmax = l[q];
    __m256 ex = sooc_nn_expf_nonpos8(_mm256_sub_ps(v, _mm256_set1_ps(lmax)));
    _mm256_storeu_ps(l, ex);
    float z = 0;
    for (int q = 0; q < C; q++) z += l[q];
    _mm256_maskstore_ps(lv, m, _mm256_div_ps(ex, _mm256_set1_ps(z)));
}
#endif

void sooc_mdl_aux_post_ray(sooc_dec_ws *w, const sooc_view_rays *vr, int rr, int C, float is2) {
#ifdef POST_AVX2
    if (C <= 8 && mdl_kern_avx2()) {
        post_ray_avx2(w, vr, rr, C, is2);
        return;
    }
#endif
    const float *sh_s = w->sh + (size_t)2 * rr * C, *ct_s = w->ct + (size_t)2 * rr * C * 3;
    float S = w->S[2 * rr], lmax = -1e30f, *lv = w->ll_cf + (size_t)rr * C;
    for (int k = 0; k < C; k++) {
        float e = 0;
        for (int a = 0; a < 3; a++) {
            float dd = vr->rgb[rr * 3 + a] - ct_s[k * 3 + a];
            e += dd * dd;
        }
        lv[k] = sooc_nn_logf_pos(sh_s[k] / S + 1e-10f) - 0.5f * e * is2;
        if (lv[k] > lmax) lmax = lv[k];
    }
    float z = 0;
    for (int k = 0; k < C; k++) z += (lv[k] = sooc_nn_expf_nonpos(lv[k] - lmax));
    for (int k = 0; k < C; k++) lv[k] /= z;
}

/* 4. Dense σ̂, c̃ per point and component, composition, the two-sample
 * likelihood (c->nll, nll_d, nll_c), its gradients w.r.t. σ̂ and c̃ (gsh,
 * gct), the per-ray log-likelihood (ll, for the auxiliary inputs) and, with
 * c->aux_post, the auxiliary inputs' colour posterior (ll_cf). Rays in fixed
 * blocks (pool tasks); each ray's likelihood terms go to w->lt and are summed
 * in ray order afterwards, so the sums do not depend on the thread count. */
#define COMPOSE_RAYS 64
typedef struct comp_job {
    const sooc_model_config *cfg;
    const sooc_dec_call *c;
    const sooc_view_rays *vr;
    sooc_dec_ws *w;
    int N, C;
    float smax, eps_s, scale, lognorm, is2;
} comp_job;

static void comp_task(void *ctx, int blk, int tid) {
    const comp_job *j = ctx;
    const sooc_dec_call *c = j->c;
    const sooc_view_rays *vr = j->vr;
    sooc_dec_ws *w = j->w;
    int C = j->C, r0 = blk * COMPOSE_RAYS, r1 = r0 + COMPOSE_RAYS < j->N ? r0 + COMPOSE_RAYS : j->N;
    float smax = j->smax, eps_s = j->eps_s, scale = j->scale, lognorm = j->lognorm, is2 = j->is2;
    (void)tid;
    for (int rr = r0; rr < r1; rr++) {
        float *lt = w->lt + (size_t)rr * 3;   /* surface density, surface colour, air density terms */
        for (int q = 0; q < 2; q++) {
            int pt = 2 * rr + q;
            float *sh = w->sh + (size_t)pt * C, *ct = w->ct + (size_t)pt * C * 3;
            float *gsh = w->gsh + (size_t)pt * C, *gct = w->gct + (size_t)pt * C * 3;
            memset(gsh, 0, sizeof(float) * C);
            memset(gct, 0, sizeof(float) * 3 * C);
            if (q ? vr->unk[rr] : !vr->surf[rr]) {   /* no such sample: contributes nothing */
                memset(sh, 0, sizeof(float) * C);
                memset(ct, 0, sizeof(float) * 3 * C);
                w->S[pt] = w->Sb[pt] = 0;
                continue;
            }
            float S = 1e-8f, Q2 = 0, col[3] = {0, 0, 0};
            for (int k = 0; k < C; k++) {
                int ri = w->rowof[(size_t)pt * C + k];
                float s = 0, cl[3] = {0, 0, 0};
                if (ri >= 0) {
                    if (k == 0) {
                        s = w->l_sig[ri];
                        memcpy(cl, w->l_col + (size_t)ri * 3, sizeof cl);
                    } else {
                        s = w->o_sig[ri] * c->zp[k - 1] * w->o_gf[ri];
                        memcpy(cl, w->o_col + (size_t)ri * 3, sizeof cl);
                    }
                }
                sh[k] = s;
                memcpy(ct + k * 3, cl, sizeof cl);
                S += s;
                Q2 += s * s;
                for (int a = 0; a < 3; a++) col[a] += s * cl[a];
            }
            for (int a = 0; a < 3; a++) col[a] /= S;
            float Sb = Q2 / S;
            w->S[pt] = S;
            w->Sb[pt] = Sb;
            memcpy(w->cc + (size_t)pt * 3, col, sizeof col);
            float gSb, gc[3] = {0, 0, 0};
            if (q == 0) {
                float v = smax * Sb + eps_s;
                lt[0] = logf(v);
                gSb = -scale * smax / v;
                float e = 0;
                for (int a = 0; a < 3; a++) {
                    float dd = vr->rgb[rr * 3 + a] - col[a];
                    e += dd * dd;
                    gc[a] = scale * (-dd) * is2;
                }
                lt[1] = -0.5f * e * is2 - lognorm;
            } else {
                lt[2] = -vr->W[rr] * smax * Sb;
                gSb = scale * vr->W[rr] * smax;
            }
            for (int k = 0; k < C; k++) {
                float s = sh[k];
                float g = gSb * (2 * s / S - Q2 / (S * S));
                for (int a = 0; a < 3; a++) {
                    g += gc[a] * (ct[k * 3 + a] - col[a]) / S;
                    gct[k * 3 + a] = gc[a] * s / S;
                }
                gsh[k] = g;
            }
        }
        /* per-ray log-likelihood (for aux inputs) */
        int ps = 2 * rr, pa = ps + 1;
        float l = -vr->W[rr] * smax * w->Sb[pa];
        if (vr->surf[rr]) {
            l += logf(smax * w->Sb[ps] + eps_s);
            float e = 0;
            for (int a = 0; a < 3; a++) {
                float dd = vr->rgb[rr * 3 + a] - w->cc[(size_t)ps * 3 + a];
                e += dd * dd;
            }
            l += -0.5f * e * is2 - lognorm;
        }
        w->ll[rr] = l;
        if (c->aux_post && vr->surf[rr]) sooc_mdl_aux_post_ray(w, vr, rr, C, is2);
    }
}

static void dec_compose(dec_run *r) {
    const sooc_model_config *cfg = r->cfg;
    sooc_dec_call *c = r->c;
    const sooc_view_rays *vr = r->vr;
    sooc_dec_ws *w = r->w;
    int N = r->N;
    float sigc = r->sigc;
    comp_job j = {cfg, c, vr, w, N, r->C, cfg->sigma_max, cfg->eps_sigma_rel * cfg->sigma_max,
                  (float)(cfg->img_w * cfg->img_h) / (float)N, 3.0f * logf(sigc * sqrtf(2.0f * (float)M_PI)),
                  1.0f / (sigc * sigc)};
    int nb = (N + COMPOSE_RAYS - 1) / COMPOSE_RAYS;
    if (N >= MDL_PAR_ROWS / 4 && r->nt > 1) sooc_mdl_par_run(r->x, nb, comp_task, &j);
    else
        for (int b = 0; b < nb; b++) comp_task(&j, b, 0);
    double sum_d = 0, sum_c = 0;   /* ray order, as the terms were added one by one */
    for (int rr = 0; rr < N; rr++) {
        const float *lt = w->lt + (size_t)rr * 3;
        if (vr->surf[rr]) {
            sum_d += lt[0];
            sum_c += lt[1];
        }
        if (!vr->unk[rr]) sum_d += lt[2];
    }
    c->nll_d = -j.scale * sum_d;
    c->nll_c = -j.scale * sum_c;
    c->nll = c->nll_d + c->nll_c;
}

/* 5. KL terms (c->kl) and the loss; 6. (backward) their gradients. */
static void dec_kl(dec_run *r) {
    const sooc_model_config *cfg = r->cfg;
    sooc_dec_call *c = r->c;
    int K = r->K, NL = r->NL, dl = r->dl;
    c->kl = 0;
    if (c->lam0) {
        for (int k = 0; k < K; k++)
            c->kl += sooc_mdl_kl_slot(cfg, c->lam + (size_t)k * NL, c->lam0 + (size_t)k * NL, 1.0f, NULL, NULL);
    }
    if (c->lay0)
        c->kl += sooc_mdl_kl_gauss(dl, c->lay, c->lay + dl, c->lay0, c->lay0 + dl, r->rmin, r->rmax, 1.0f, NULL, NULL, NULL,
                              NULL);
    c->loss = c->nll + c->beta_kl * c->kl;
}

static void dec_kl_backward(dec_run *r) {
    const sooc_model_config *cfg = r->cfg;
    sooc_dec_call *c = r->c;
    int K = r->K, NL = r->NL, dl = r->dl;
    float beta = c->beta_kl;
    if (c->lam0)
        for (int k = 0; k < K; k++)
            sooc_mdl_kl_slot(cfg, c->lam + (size_t)k * NL, c->lam0 + (size_t)k * NL, beta,
                        c->g_lam ? c->g_lam + (size_t)k * NL : NULL, c->g_lam0 ? c->g_lam0 + (size_t)k * NL : NULL);
    if (c->lay0)
        sooc_mdl_kl_gauss(dl, c->lay, c->lay + dl, c->lay0, c->lay0 + dl, r->rmin, r->rmax, beta, c->g_lay,
                     c->g_lay ? c->g_lay + dl : NULL, c->g_lay0, c->g_lay0 ? c->g_lay0 + dl : NULL);
}

/* 7. Decoder backward over the rows: object and layout rows in one parallel
 * region (each thread takes a contiguous share of both; thread-private weight
 * gradients, reduced in thread order), then the slot-bias (layer-1
 * pre-activation) and z^where sums per component (sb_task), z^pres gradients
 * into r->gzp. The layout rows' scratch follows the object rows' when it
 * fits; otherwise two passes. */
static void dec_backward_rows(dec_run *r) {
    const sooc_model *m = r->m;
    const sooc_dec_call *c = r->c;
    sooc_dec_ws *w = r->w;
    const sooc_dec_net *no = r->no, *nl = r->nl;
    int C = r->C, H = r->H, nt = r->nt, nro = r->nro, nrl = r->nrl;
    float ws = c->wgrad;
    size_t Rall = (size_t)w->Pmax * (w->Kmax > 1 ? w->Kmax : 1);
    int merged = (size_t)nro + nrl <= Rall;
    int loff = merged ? nro : 0;   /* first scratch row of the layout rows */
    int nrt = merged ? nro + nrl : (nro > nrl ? nro : nrl);
    float *gsig = w->gC, *gcol = w->gC + (size_t)nrt;   /* gC has >= Rall*H >= 4 nrt floats */
    /* transposed weights for the backward GEMMs (without AVX2 the portable kernel's
     * sooc_nn_gemm_nt reads the untransposed ones) */
    dec_wt wto, wtl;
    const dec_wt *pwo = NULL, *pwl = NULL;
    if (mdl_kern_avx2() && wt_floats(no, 1) + wt_floats(nl, 0) <= w->nwt) {
        float *q = wt_build(r->p, no, 1, w->wt, &wto);
        wt_build(r->p, nl, 0, q, &wtl);
        pwo = &wto, pwl = &wtl;
    }
    for (int rw = 0; rw < nro; rw++) {
        int pt = w->ro_pt[rw], k = w->ro_slot[rw];
        float g = w->gsh[(size_t)pt * C + 1 + k];
        gsig[rw] = g * c->zp[k];
        r->gzp[k] += g * w->o_sig[rw];
        memcpy(gcol + (size_t)rw * 3, w->gct + ((size_t)pt * C + 1 + k) * 3, 3 * sizeof(float));
    }
    int ntb = nt < w->nthr ? nt : w->nthr;
    size_t tstride = w->dec_np;
    /* Weight gradients (ws != 0) go to thread-private copies of the decoder slab, reduced in
     * thread order below (deterministic for a thread count; rows then split statically).
     * Without them (inference) rows are handed out in dynamically scheduled fixed blocks.
     * Slot-bias and z^where gradients are summed per row in row order after each pass,
     * so they do not depend on the thread count. */
    if (ws != 0)
        for (int t = 0; t < ntb; t++) memset(w->tbuf + (size_t)t * tstride, 0, tstride * sizeof(float));
    bwd_ctx bx = {m, w, c, no, nl, pwo, pwl, gsig, gcol, ws, r->inv_o, r->cfg->gauss_s, C, 0};
    memset(w->g_bias, 0, sizeof(float) * (size_t)C * H);
    for (int pass = merged ? 1 : 0; pass < 2; pass++) {
        /* pass 0 (only when the scratch does not fit): object rows alone; pass 1: layout (+ objects if merged) */
        int do_obj = merged || pass == 0, do_lay = pass == 1;
        if (do_lay)
            for (int rl = 0; rl < nrl; rl++) {
                int pt = w->lr_pt[rl];
                gsig[loff + rl] = w->gsh[(size_t)pt * C];
                memcpy(gcol + (size_t)(loff + rl) * 3, w->gct + (size_t)pt * C * 3, 3 * sizeof(float));
            }
        bx.loff = loff;
        int no_ = do_obj ? nro : 0, nl_ = do_lay ? nrl : 0, rows = no_ + nl_;
        if (ws != 0) {
MDL_OMP(omp parallel num_threads(ntb) if (rows >= MDL_PAR_ROWS))
            {
                int r0, r1, tid = TID(), nth = NTH();
                float *tg = w->tbuf + (size_t)tid * tstride;
                chunk_of(no_, tid, nth, &r0, &r1);
                for (int b0 = r0; b0 < r1; b0 += MDL_BLOCK_ROWS)
                    bwd_obj_block(&bx, b0, r1 - b0 < MDL_BLOCK_ROWS ? r1 - b0 : MDL_BLOCK_ROWS, tg);
                chunk_of(nl_, tid, nth, &r0, &r1);
                for (int b0 = r0; b0 < r1; b0 += MDL_BLOCK_ROWS)
                    bwd_lay_block(&bx, b0, r1 - b0 < MDL_BLOCK_ROWS ? r1 - b0 : MDL_BLOCK_ROWS, tg);
            }
        } else {
            int nbo = (no_ + MDL_DYN_ROWS - 1) / MDL_DYN_ROWS, nbl = (nl_ + MDL_DYN_ROWS - 1) / MDL_DYN_ROWS;
            bwd_job bj = {&bx, nbo, no_, nl_};
            if (rows >= MDL_PAR_ROWS && ntb > 1) sooc_mdl_par_run(r->x, nbo + nbl, bwd_task, &bj);
            else
                for (int blk = 0; blk < nbo + nbl; blk++) bwd_task(&bj, blk, 0);
        }
        /* slot-bias (layer-1 pre-activation) and z^where gradients, row order; split
         * by columns across the pool (each sum keeps its row order: bitwise the same) */
        sb_job sj = {w, no_, nl_, loff, H, no->din, r->gzw};
        if (rows >= MDL_PAR_ROWS && nt > 1) sooc_mdl_par_run(r->x, SB_TASKS + 1, sb_task, &sj);
        else
            for (int t = 0; t <= SB_TASKS; t++) sb_task(&sj, t, 0);
    }
    if (ws != 0)   /* thread order: deterministic */
        for (int t = 0; t < ntb; t++) {
            const float *tg = w->tbuf + (size_t)t * tstride;
            for (size_t i = 0; i < w->dec_np; i++) r->m->g[i] += tg[i];
        }
}

/* Slot biases -> z^what / the layout latent (r->gzwhat, r->gzl) and, with
 * weight gradients, b1 and W1z. */
static void dec_bias_backward(dec_run *r) {
    const sooc_dec_call *c = r->c;
    const sooc_dec_ws *w = r->w;
    const float *p = r->p;
    float *g = r->m->g;
    int K = r->K, H = r->H;
    float ws = c->wgrad;
    for (int k = 0; k <= K; k++) {
        const sooc_dec_net *n = k ? r->no : r->nl;
        const float *gb = w->g_bias + (size_t)k * H;
        const float *z = k ? c->zwhat[k - 1] : c->zlay;
        float *gz = k ? r->gzwhat[k - 1] : r->gzl;
        for (int i = 0; i < n->dz; i++) {
            const float *Wr = p + n->W1z + (size_t)i * H;
            float v = 0;
            for (int j = 0; j < H; j++) v += Wr[j] * gb[j];
            gz[i] = v;
            if (ws != 0) {
                float *gW = g + n->W1z + (size_t)i * H;
                for (int j = 0; j < H; j++) gW[j] += ws * z[i] * gb[j];
            }
        }
        if (ws != 0)
            for (int j = 0; j < H; j++) g[n->b1 + j] += ws * gb[j];
    }
}

/* 8. Reparameterisation backward: sample gradients -> λ and the layout posterior. */
static void dec_reparam_backward(dec_run *r) {
    sooc_dec_call *c = r->c;
    int K = r->K, d = r->d, dl = r->dl, NL = r->NL;
    float rmin = r->rmin, rmax = r->rmax, tau = r->tau;
    const slot_sample *ss = r->ss;
    if (c->g_lam)
        for (int k = 0; k < K; k++) {
            const float *l = c->lam + (size_t)k * NL;
            float *g = c->g_lam + (size_t)k * NL;
            const sooc_dec_noise *ns = c->noise;
            g[0] += r->gzw[k][0];
            g[1] += r->gzw[k][1];
            g[2] += r->gzw[k][2];
            if (l[3] >= rmin && l[3] <= rmax)
                g[3] += 0.5f * ss[k].sig_t * (r->gzw[k][0] * ns->eps_where[k][0] + r->gzw[k][1] * ns->eps_where[k][1]);
            if (l[4] >= rmin && l[4] <= rmax) g[4] += 0.5f * ss[k].sig_th * r->gzw[k][2] * ns->eps_where[k][2];
            for (int i = 0; i < d; i++) {
                g[5 + i] += r->gzwhat[k][i];
                if (l[5 + d + i] >= rmin && l[5 + d + i] <= rmax)
                    g[5 + d + i] += 0.5f * ss[k].sig_what[i] * r->gzwhat[k][i] * ns->eps_what[k][i];
            }
            float zs = c->zp_soft[k];
            g[5 + 2 * d] += r->gzp[k] * zs * (1 - zs) / tau;
        }
    if (c->g_lay)
        for (int i = 0; i < dl; i++) {
            c->g_lay[i] += r->gzl[i];
            if (c->lay[dl + i] >= rmin && c->lay[dl + i] <= rmax)
                c->g_lay[dl + i] += 0.5f * r->sig_lay[i] * r->gzl[i] * c->noise->eps_lay[i];
        }
}

sooc_status sooc_mdl_decode(sooc_model_ws *x, sooc_dec_call *c) {
    dec_run run, *r = &run;
    memset(r, 0, sizeof *r);
    sooc_model *m = x->m;
    const sooc_model_config *cfg = &m->cfg;
    r->x = x, r->m = m, r->cfg = cfg, r->w = x->dec, r->c = c, r->vr = c->rays;
    r->no = &m->dobj, r->nl = &m->dlay, r->p = m->p;
    r->N = r->vr->N, r->P = 2 * r->N, r->K = c->nslot, r->C = r->K + 1;
    r->d = cfg->d_what, r->dl = cfg->d_layout, r->NL = m->NL, r->H = cfg->dec_width, r->nt = nthreads(m);
    SOOC_ASSERT(r->P <= r->w->Pmax && r->K <= r->w->Kmax);
    MDL_PT(tprof);
    r->rmin = cfg->rho_min, r->rmax = cfg->rho_max, r->tau = c->tau > 0 ? c->tau : 1.0f;
    r->sigc = c->sigma_c > 0 ? c->sigma_c : cfg->sigma_c;
    r->inv_o = 1.0f / cfg->box_rh, r->inv_l = 1.0f / cfg->block_size;

    dec_samples(r);
    dec_slot_biases(r);
    dec_rows(r);
    MDL_PACC(MDL_PR_DEC_PREP, tprof);
    dec_forward(r);
    MDL_PACC(MDL_PR_DEC_FWD, tprof);
    dec_compose(r);
    MDL_PACC(MDL_PR_DEC_COMP, tprof);
    dec_kl(r);
    if (!c->backward) return SOOC_OK;
    if (!isfinite(c->loss)) return sooc_seterr(SOOC_ENUMERIC, "decode: non-finite loss");
    dec_kl_backward(r);
    dec_backward_rows(r);
    MDL_PACC(MDL_PR_DEC_BWD, tprof);
    dec_bias_backward(r);
    dec_reparam_backward(r);
    MDL_PACC(MDL_PR_DEC_RED, tprof);
    return SOOC_OK;
}

/* ------------------------------------------------------------ workspace */

/* The decoder's part of a runner's workspace (sooc_model_ws): every buffer
 * of a decode, sized for P = 2 ray_w ray_h points and K slots. */
sooc_status sooc_mdl_dec_ws_create(const sooc_model *m, sooc_dec_ws **out) {
    *out = NULL;
    const sooc_model_config *c = &m->cfg;
    sooc_dec_ws *w = sooc_calloc(1, sizeof *w);
    if (!w) return SOOC_ENOMEM;
    int P = 2 * c->ray_w * c->ray_h, K = c->K, C = K + 1, H = c->dec_width;
    size_t R = (size_t)P * K;
    w->Pmax = P;
    w->Kmax = K;
    int dmax = m->dobj.din > m->dlay.din ? m->dobj.din : m->dlay.din;
    size_t Rall = R > (size_t)P ? R : (size_t)P;
#define A(p, n, t) if (!(w->p = sooc_calloc((n), sizeof(t)))) { sooc_mdl_dec_ws_destroy(w); return SOOC_ENOMEM; }
    A(ro_pt, R, int);
    A(ro_slot, R, int);
    A(o_pe, R * m->dobj.din, float);
    A(o_a1, R * H, float);
    A(o_a2, R * H, float);
    A(o_a3, R * H, float);
    A(o_ac, R * c->dec_color_width, float);
    A(o_sig, R, float);
    A(o_col, R * 3, float);
    A(o_xk, R * 3, float);
    A(o_gf, R, float);
    A(l_pe, (size_t)P * m->dlay.din, float);
    A(l_a1, (size_t)P * H, float);
    A(l_a2, (size_t)P * H, float);
    A(l_a3, (size_t)P * H, float);
    A(l_ac, (size_t)P * c->dec_color_width, float);
    A(l_sig, P, float);
    A(l_col, (size_t)P * 3, float);
    A(gA, Rall * H, float);
    A(gB, Rall * H, float);
    A(gC, Rall * H, float);
    A(gpe, Rall * dmax, float);
    A(sh, (size_t)P * C, float);
    A(ct, (size_t)P * C * 3, float);
    A(gsh, (size_t)P * C, float);
    A(gct, (size_t)P * C * 3, float);
    A(rowof, (size_t)P * C, int);
    A(S, P, float);
    A(Sb, P, float);
    A(cc, (size_t)P * 3, float);
    A(ll, P, float);
    A(ll_cf, (size_t)P * C, float);
    A(lt, (size_t)(P / 2) * 3, float);
    A(slot_bias, (size_t)C * H, float);
    A(lr_pt, P, int);
    w->dec_np = m->robj.cw[0];   /* both decoders come first in the slab */
    w->nthr = 8;
    A(tbuf, (size_t)w->nthr * (w->dec_np + (size_t)C * H + 3 * (size_t)K), float);
    A(g_bias, (size_t)C * H, float);
    /* transposed W2, W3, Wc1 of both decoders and W1x of the object decoder */
    w->nwt = (size_t)H * (2 * H + c->dec_color_width) * 2 + (size_t)H * m->dobj.din;
    A(wt, w->nwt, float);
#undef A
    *out = w;
    return SOOC_OK;
}

void sooc_mdl_dec_ws_destroy(sooc_dec_ws *w) {
    if (!w) return;
    float **fp[] = {&w->o_pe, &w->o_a1, &w->o_a2, &w->o_a3, &w->o_ac, &w->o_sig, &w->o_col, &w->o_xk, &w->o_gf, &w->l_pe,
                    &w->l_a1, &w->l_a2, &w->l_a3, &w->l_ac, &w->l_sig, &w->l_col, &w->gA, &w->gB, &w->gC, &w->gpe,
                    &w->sh, &w->ct, &w->gsh, &w->gct, &w->S, &w->Sb, &w->cc, &w->ll, &w->ll_cf, &w->lt, &w->slot_bias,
                    &w->g_bias, &w->wt};
    for (size_t i = 0; i < sizeof fp / sizeof fp[0]; i++) sooc_free(*fp[i]);
    sooc_free(w->ro_pt);
    sooc_free(w->ro_slot);
    sooc_free(w->rowof);
    sooc_free(w->lr_pt);
    sooc_free(w->tbuf);
    sooc_free(w);
}
