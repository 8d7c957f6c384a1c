/* Refinement inputs and the refinement network (docs/model.md "Layers"):
 * conv 3x3 stride 2 SAME (TF padding: 0 before, 1 after) + ELU, FC + ELU,
 * LSTMCell, linear head, on the src/nn pairs of nn/nn_refine.h.
 * Activations are [channel][item][pixel]. */
#include "model/refine.h"
#include "nn/nn_refine.h"

#include <math.h>
#include <string.h>

static inline float clampf(float x, float a, float b) { return x < a ? a : x > b ? b : x; }

#ifdef MDL_HAVE_AVX2_PATHS
#define AUX_AVX2 1

/* The counterfactual channel (ell - ell_{-k}, aux_task below) of rays [0, n8), n8 a
 * multiple of 8, on 8 lanes: the scalar loop's operations in its order (bitwise equal). */
static MDL_TGT_AVX2 void aux_cf_avx2(const sooc_dec_ws *w, const sooc_view_rays *vr, int comp, int C, int n8, float smax, float eps_s,
                                 float is2, float lognorm, float *d8) {
    const __m256 tiny = _mm256_set1_ps(1e-8f), zero = _mm256_setzero_ps(), vsmax = _mm256_set1_ps(smax);
    const __m256 veps = _mm256_set1_ps(eps_s), vis2 = _mm256_set1_ps(is2), vln = _mm256_set1_ps(lognorm);
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    for (int r0 = 0; r0 < n8; r0 += 8) {
        __m256i rr = _mm256_add_epi32(_mm256_set1_epi32(r0), lane);
        __m256i ps = _mm256_add_epi32(rr, rr), pa = _mm256_add_epi32(ps, _mm256_set1_epi32(1));
        __m256i is = _mm256_add_epi32(_mm256_mullo_epi32(ps, _mm256_set1_epi32(C)), _mm256_set1_epi32(comp));
        __m256i ia = _mm256_add_epi32(is, _mm256_set1_epi32(C));
        __m256 shs = _mm256_i32gather_ps(w->sh, is, 4), sha = _mm256_i32gather_ps(w->sh, ia, 4);
        __m256 S = _mm256_i32gather_ps(w->S, ps, 4), Sa = _mm256_i32gather_ps(w->S, pa, 4);
        __m256 Qa = _mm256_mul_ps(_mm256_i32gather_ps(w->Sb, pa, 4), Sa);
        __m256 Sa2 = _mm256_sub_ps(Sa, sha), Qa2 = _mm256_sub_ps(Qa, _mm256_mul_ps(sha, sha));
        Sa2 = _mm256_blendv_ps(Sa2, tiny, _mm256_cmp_ps(Sa2, tiny, _CMP_LT_OQ));
        Qa2 = _mm256_blendv_ps(Qa2, zero, _mm256_cmp_ps(Qa2, zero, _CMP_LT_OQ));
        __m256 negw = _mm256_xor_ps(_mm256_loadu_ps(vr->W + r0), _mm256_set1_ps(-0.0f));   /* -W exactly (also for W = 0) */
        __m256 lm = _mm256_div_ps(_mm256_mul_ps(_mm256_mul_ps(negw, vsmax), Qa2), Sa2);
        __m128i sb = _mm_loadl_epi64((const __m128i *)(vr->surf + r0));
        __m256 surf = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_cvtepu8_epi32(sb), _mm256_setzero_si256()));
        if (_mm256_movemask_ps(surf)) {
            __m256 Qs = _mm256_mul_ps(_mm256_i32gather_ps(w->Sb, ps, 4), S);
            __m256 S2 = _mm256_sub_ps(S, shs), Q2 = _mm256_sub_ps(Qs, _mm256_mul_ps(shs, shs));
            S2 = _mm256_blendv_ps(S2, tiny, _mm256_cmp_ps(S2, tiny, _CMP_LT_OQ));
            Q2 = _mm256_blendv_ps(Q2, zero, _mm256_cmp_ps(Q2, zero, _CMP_LT_OQ));
            __m256 lx = _mm256_add_ps(_mm256_div_ps(_mm256_mul_ps(vsmax, Q2), S2), veps);
            __m256 lg = mdl_logf_pos8(lx);
            __m256 ok = _mm256_and_ps(_mm256_cmp_ps(lx, _mm256_set1_ps(1.17549435e-38f), _CMP_GE_OQ),
                                      _mm256_cmp_ps(lx, _mm256_set1_ps(3.40282347e38f), _CMP_LE_OQ));
            int bad = _mm256_movemask_ps(_mm256_andnot_ps(ok, surf));
            if (bad) {   /* 0, subnormal, inf, NaN: logf, as sooc_nn_logf_pos */
                float xs[8], ls[8];
                _mm256_storeu_ps(xs, lx);
                _mm256_storeu_ps(ls, lg);
                for (int q = 0; q < 8; q++)
                    if (bad >> q & 1) ls[q] = logf(xs[q]);
                lg = _mm256_loadu_ps(ls);
            }
            __m256 e = zero;
            __m256i i6 = _mm256_add_epi32(_mm256_add_epi32(ps, ps), ps), ic = _mm256_add_epi32(_mm256_add_epi32(is, is), is);
            __m256i ir = _mm256_add_epi32(_mm256_add_epi32(rr, rr), rr);
            for (int a = 0; a < 3; a++) {
                __m256i va = _mm256_set1_epi32(a);
                __m256 cc = _mm256_i32gather_ps(w->cc, _mm256_add_epi32(i6, va), 4);
                __m256 ct = _mm256_i32gather_ps(w->ct, _mm256_add_epi32(ic, va), 4);
                __m256 rgb = _mm256_i32gather_ps(vr->rgb, _mm256_add_epi32(ir, va), 4);
                __m256 cm = _mm256_div_ps(_mm256_sub_ps(_mm256_mul_ps(cc, S), _mm256_mul_ps(shs, ct)), S2);
                __m256 dd = _mm256_sub_ps(rgb, cm);
                e = _mm256_add_ps(e, _mm256_mul_ps(dd, dd));
            }
            __m256 ls = _mm256_add_ps(lm, lg);
            ls = _mm256_add_ps(ls, _mm256_sub_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(-0.5f), e), vis2), vln));
            lm = _mm256_blendv_ps(lm, ls, surf);
        }
        _mm256_storeu_ps(d8 + r0, _mm256_sub_ps(_mm256_loadu_ps(w->ll + r0), lm));
    }
}
#endif

/* The image channels of one component (0 = layout, 1..K objects) after the shared ones (a pool task). */
typedef struct aux_job {
    const sooc_dec_ws *w;
    const sooc_dec_call *c;
    float *img_o, *img_l;
    const float *post_all;
    int N, K, C;
    float smax, eps_s, is2, lognorm, inv_rh, inv_b, s2;
} aux_job;

static void aux_task(void *ctx, int comp, int tid) {
    const aux_job *j = ctx;
    const sooc_dec_call *c = j->c;
    const sooc_dec_ws *w = j->w;
    const sooc_view_rays *vr = c->rays;
    float *img_o = j->img_o, *img_l = j->img_l;
    const float *post_all = j->post_all;
    int N = j->N, K = j->K, C = j->C;
    float smax = j->smax, eps_s = j->eps_s, is2 = j->is2, lognorm = j->lognorm, inv_rh = j->inv_rh, inv_b = j->inv_b,
          s2 = j->s2;
    (void)tid;
    int lay = comp == 0, b = lay ? 0 : comp - 1, B = lay ? 1 : K;
    float *img = lay ? img_l : img_o;
    float cth = lay ? 1.0f : cosf(c->zw[b][2]), sth = lay ? 0.0f : sinf(c->zw[b][2]);
#define CH(ch) (img + ((size_t)(ch) * B + b) * N)
    /* Each channel is written by its own loop over rays: the channels of one item are
     * N floats (4 KB) apart, so writing all 26 per ray thrashes L1 associativity.
     * The shared leading channels are stored for slot 0 only (sooc_ref_act.nsh). */
    if (!lay && b == 0)
        for (int ch = 0; ch < MDL_AUX_NSH; ch++) memcpy(CH(ch), img_l + (size_t)ch * N, (size_t)N * sizeof(float));
    int o = 8;
    /* surface point in the component frame */
    if (!lay) {
        float *restrict x0 = CH(o), *restrict x1 = CH(o + 1), *restrict x2 = CH(o + 2), *restrict wgc = CH(o + 3);
        float px = c->zw[b][0], pz = c->zw[b][1];
        for (int rr = 0; rr < N; rr++) {
            float xk[3] = {0, 0, 0};
            int surf = vr->surf[rr];
            if (surf) mdl_pi_cs(vr->pts + (size_t)2 * rr * 3, px, pz, cth, sth, vr->h, xk);
            x0[rr] = clampf(xk[0] * inv_rh, -3, 3);
            x1[rr] = clampf(xk[1] * inv_rh, -3, 3);
            x2[rr] = clampf(xk[2] * inv_rh, -3, 3);
            wgc[rr] = surf ? sooc_nn_expf_nonpos(-(xk[0] * xk[0] + xk[2] * xk[2]) / (2 * s2)) : 0.0f;
        }
        o += 4;
    } else {
        float *restrict x0 = CH(o), *restrict x1 = CH(o + 1), *restrict x2 = CH(o + 2);
        for (int rr = 0; rr < N; rr++) {
            float xk[3] = {0, 0, 0};
            if (vr->surf[rr]) {
                const float *x = vr->pts + (size_t)2 * rr * 3;
                for (int a = 0; a < 3; a++) xk[a] = clampf((x[a] - vr->blk[a]) * inv_b, -3, 3);
            }
            x0[rr] = xk[0], x1[rr] = xk[1], x2[rr] = xk[2];
        }
        o += 3;
    }
    const float *restrict sh = w->sh, *restrict Sv = w->S, *restrict ctv = w->ct;
    {
        float *restrict d0 = CH(o), *restrict d1 = CH(o + 1), *restrict d5 = CH(o + 5);
        for (int rr = 0; rr < N; rr++) {
            int ps = 2 * rr, pa = ps + 1;
            float ss = sh[(size_t)ps * C + comp], sa = sh[(size_t)pa * C + comp];
            d0[rr] = ss;
            d1[rr] = vr->surf[rr] ? ss / Sv[ps] : 0.0f;
            d5[rr] = vr->unk[rr] ? 0.0f : sa * sa / Sv[pa];   /* unknown: no air sample */
        }
        float *restrict e0 = CH(o + 2), *restrict e1 = CH(o + 3), *restrict e2 = CH(o + 4);
        for (int rr = 0; rr < N; rr++) {
            const float *ct = ctv + ((size_t)2 * rr * C + comp) * 3;
            e0[rr] = ct[0], e1[rr] = ct[1], e2[rr] = ct[2];
        }
        float *restrict d6 = CH(o + 6), *restrict d7 = CH(o + 7);
        for (int rr = 0; rr < N; rr++) {
            d6[rr] = vr->surf[rr] ? post_all[(size_t)rr * C + comp] : 0.0f;
            d7[rr] = w->ll[rr];
        }
    }
    /* counterfactual ell - ell_{-k} */
    {
        float *restrict d8 = CH(o + 8);
        int rr0 = 0;
#ifdef AUX_AVX2
        if (mdl_kern_avx2()) {
            rr0 = N & ~7;
            aux_cf_avx2(w, vr, comp, C, rr0, smax, eps_s, is2, lognorm, d8);
        }
#endif
        for (int rr = rr0; rr < N; rr++) {
            int ps = 2 * rr, pa = ps + 1, surf = vr->surf[rr];
            const float *sh_s = sh + (size_t)ps * C, *sh_a = sh + (size_t)pa * C;
            const float *ct_s = ctv + (size_t)ps * C * 3;
            float S = Sv[ps];
            float Sa = Sv[pa], Qa = w->Sb[pa] * Sa;
            float Sa2 = Sa - sh_a[comp], Qa2 = Qa - sh_a[comp] * sh_a[comp];
            if (Sa2 < 1e-8f) Sa2 = 1e-8f;
            if (Qa2 < 0) Qa2 = 0;
            float lm = -vr->W[rr] * smax * Qa2 / Sa2;
            if (surf) {
                float Qs = w->Sb[ps] * S, S2 = S - sh_s[comp], Q2 = Qs - sh_s[comp] * sh_s[comp];
                if (S2 < 1e-8f) S2 = 1e-8f;
                if (Q2 < 0) Q2 = 0;
                lm += sooc_nn_logf_pos(smax * Q2 / S2 + eps_s);
                float e = 0;
                for (int a = 0; a < 3; a++) {
                    float cm = (w->cc[(size_t)ps * 3 + a] * S - sh_s[comp] * ct_s[comp * 3 + a]) / S2;
                    float dd = vr->rgb[rr * 3 + a] - cm;
                    e += dd * dd;
                }
                lm += -0.5f * e * is2 - lognorm;
            }
            d8[rr] = w->ll[rr] - lm;
        }
    }
    {
        float *restrict d9 = CH(o + 9), *restrict d10 = CH(o + 10);
        for (int rr = 0; rr < N; rr++) {
            d9[rr] = w->gsh[(size_t)2 * rr * C + comp];
            d10[rr] = w->gsh[(size_t)(2 * rr + 1) * C + comp];
        }
        float *restrict e0 = CH(o + 11), *restrict e1 = CH(o + 12), *restrict e2 = CH(o + 13);
        for (int rr = 0; rr < N; rr++) {
            const float *g = w->gct + ((size_t)2 * rr * C + comp) * 3;
            e0[rr] = g[0], e1[rr] = g[1], e2[rr] = g[2];
        }
    }
    sooc_nn_mln_forward(CH(o + 7), NULL, CH(o + 7), 1, N, (int64_t)B * N);
    sooc_nn_mln_forward(CH(o + 8), NULL, CH(o + 8), 1, N, (int64_t)B * N);
    sooc_nn_mln_forward(CH(o + 9), NULL, CH(o + 9), 1, N, (int64_t)B * N);
    sooc_nn_mln_forward(CH(o + 10), NULL, CH(o + 10), 1, N, (int64_t)B * N);
    sooc_nn_mln_forward(CH(o + 11), NULL, CH(o + 11), 3, N, (int64_t)B * N);
#undef CH
}

void sooc_mdl_aux_inputs(sooc_model_ws *x, const sooc_dec_call *c, const float *g_lam, const float *g_lay, float *img_o,
                    float *vec_o, float *img_l, float *vec_l) {
    MDL_PT(tprof);
    const sooc_model *m = x->m;
    const sooc_model_config *cfg = &m->cfg;
    const sooc_dec_ws *w = x->dec;
    const sooc_view_rays *vr = c->rays;
    int N = vr->N, K = c->nslot, C = K + 1, NL = m->NL, d = cfg->d_what, dl = cfg->d_layout;
    float smax = cfg->sigma_max, eps_s = cfg->eps_sigma_rel * smax;
    float sigc = c->sigma_c > 0 ? c->sigma_c : cfg->sigma_c, is2 = 1.0f / (sigc * sigc);
    float lognorm = 3.0f * logf(sigc * sqrtf(2.0f * (float)M_PI));
    float inv_rh = 1.0f / cfg->box_rh, inv_b = 1.0f / cfg->block_size, s2 = cfg->gauss_s * cfg->gauss_s;
    /* colour-likelihood posterior softmax_k [log pi_k + log N(C; c_k, sigma_C^2)], once per
     * surface ray (during the composition when the decode was asked for it) */
    float *post_all = w->ll_cf;   /* N x C */
    if (!c->aux_post)
        for (int rr = 0; rr < N; rr++)
            if (vr->surf[rr]) sooc_mdl_aux_post_ray(x->dec, vr, rr, C, is2);
    /* Channels 0-7 (colour, depth, beyond-clip flag, ray direction) are the same for every
     * component: written once into the layout image, copied into each object's. */
    {
        float *restrict c0 = img_l, *restrict c1 = img_l + N, *restrict c2 = img_l + 2 * (size_t)N;
        float *restrict c3 = img_l + 3 * (size_t)N, *restrict c4 = img_l + 4 * (size_t)N;
        for (int rr = 0; rr < N; rr++) {
            int surf = vr->surf[rr];
            c0[rr] = vr->rgb[rr * 3], c1[rr] = vr->rgb[rr * 3 + 1], c2[rr] = vr->rgb[rr * 3 + 2];
            /* unknown depth (config.invalid_depth UNKNOWN): neither a depth nor the
             * beyond-clip flag, 0 and 0 (docs/model.md "Invalid depth") */
            int unk = vr->unk[rr];
            c3[rr] = surf ? vr->depth[rr] / cfg->d_clip : unk ? 0.0f : 1.0f;
            c4[rr] = surf || unk ? 0.0f : 1.0f;
        }
        float *restrict c5 = img_l + 5 * (size_t)N, *restrict c6 = img_l + 6 * (size_t)N, *restrict c7 = img_l + 7 * (size_t)N;
        for (int rr = 0; rr < N; rr++) c5[rr] = vr->dir[rr * 3], c6[rr] = vr->dir[rr * 3 + 1], c7[rr] = vr->dir[rr * 3 + 2];
    }
    aux_job aj = {w, c, img_o, img_l, post_all, N, K, C, smax, eps_s, is2, lognorm, inv_rh, inv_b, s2};
    if (N >= MDL_PAR_ROWS && sooc_mdl_par_threads(x) > 1) sooc_mdl_par_run(x, C, aux_task, &aj);
    else
        for (int comp = 0; comp < C; comp++) aux_task(&aj, comp, 0);
    /* vector inputs */
    int nv = 2 * NL + 6;
    for (int k = 0; k < K; k++) {
        float *v = vec_o + (size_t)k * nv;
        memcpy(v, c->lam + (size_t)k * NL, NL * sizeof(float));
        memcpy(v + NL, g_lam + (size_t)k * NL, NL * sizeof(float));
        sooc_nn_mln_forward(v + NL, NULL, v + NL, 1, NL, NL);
        v[2 * NL + 0] = c->zw[k][0];
        v[2 * NL + 1] = c->zw[k][1];
        v[2 * NL + 2] = c->zw[k][2];
        v[2 * NL + 3] = c->zp[k];
        v[2 * NL + 4] = vr->h;
        v[2 * NL + 5] = vr->pitch;
    }
    memcpy(vec_l, c->lay, 2 * dl * sizeof(float));
    memcpy(vec_l + 2 * dl, g_lay, 2 * dl * sizeof(float));
    sooc_nn_mln_forward(vec_l + 2 * dl, NULL, vec_l + 2 * dl, 1, 2 * dl, 2 * dl);
    vec_l[4 * dl] = vr->h;
    vec_l[4 * dl + 1] = vr->pitch;
    (void)d;
    MDL_PACC(MDL_PR_AUX, tprof);
}

/* ---------------------------------------------------------------- network */

sooc_status sooc_mdl_ref_act_alloc(const sooc_ref_net *n, int B, int gw, int gh, sooc_ref_act *a) {
    memset(a, 0, sizeof *a);
    a->B = B;
    size_t HW = (size_t)gw * gh;
    int ok = 1;
#define A(p, cnt) ok &= (a->p = sooc_calloc((cnt), sizeof(float))) != NULL
    A(x0, (size_t)n->cin * B * HW);
    for (int i = 0; i < 4; i++) A(y[i], (size_t)n->ch[i] * B * (HW >> (2 * (i + 1))));
    A(flat, (size_t)B * n->nflat);
    A(f, (size_t)B * n->fc);
    A(xin, (size_t)B * (n->fc + n->nvec));
    A(gates, (size_t)B * 4 * n->hid);
    A(c_prev, (size_t)B * n->hid);
    A(h_prev, (size_t)B * n->hid);
    A(c, (size_t)B * n->hid);
    A(h, (size_t)B * n->hid);
#undef A
    if (!ok) {
        sooc_mdl_ref_act_free(a);
        return SOOC_ENOMEM;
    }
    return SOOC_OK;
}

void sooc_mdl_ref_act_free(sooc_ref_act *a) {
    float **p[] = {&a->x0, &a->y[0], &a->y[1], &a->y[2], &a->y[3], &a->flat, &a->f, &a->xin, &a->gates,
                   &a->c_prev, &a->h_prev, &a->c, &a->h};
    for (size_t i = 0; i < sizeof p / sizeof p[0]; i++) {
        sooc_free(*p[i]);
        *p[i] = NULL;
    }
}

/* The layers are the src/nn pairs of nn/nn_refine.h (conv 3x3 stride 2 +
 * ELU, pool + flatten, linear + ELU, LSTM cell, linear head); this file wires
 * them to the model's slab and workspace and splits items across the pool. */

/* The conv stack's last map (C x B x fh x fw, fh = gh / 16) flattened per item
 * for the FC layer. Ray grids up to 32 x 32 are flattened as they are; a
 * larger grid (a multiple of 32) is average-pooled to the 2 x 2 map of a
 * 32 x 32 grid, so the FC weights (and every other weight) do not depend on
 * the ray grid and a model trained on one grid runs on another
 * (sooc_model_copy_rays). */
void sooc_mdl_ref_flatten(const sooc_ref_net *n, const float *y3, int B, int gw, int gh, float *flat) {
    sooc_nn_pool2_forward(flat, y3, n->ch[3], B, gh >> 4, gw >> 4);
}

/* Backward of sooc_mdl_ref_flatten: writes (not adds) the gradient w.r.t. y3. */
static void sooc_mdl_ref_flatten_backward(const sooc_ref_net *n, const float *gflat, int B, int gw, int gh, float *gy3) {
    memset(gy3, 0, sizeof(float) * (size_t)n->ch[3] * B * (gh >> 4) * (gw >> 4));
    sooc_nn_pool2_backward(gy3, gflat, n->ch[3], B, gh >> 4, gw >> 4);
}

/* The four conv layers of item b of a (on the calling thread; ct: its column scratch).
 * The first a->nsh input channels are stored once (item 0) and their share of the first
 * convolution is in ysh (ch[0] x HW1): the item's own channels continue its FMA chains. */
static void conv_item(const float *p, const sooc_ref_net *n, sooc_ref_act *a, int b, const float *ysh, float *ct, int gw, int gh) {
    const float *x = a->x0;
    int Ci = n->cin, Hi = gh, Wi = gw;
    for (int i = 0; i < 4; i++) {
        int sh = i == 0 && ysh ? a->nsh : 0;
        sooc_nn_rconv_forward(a->y[i], ct, x, p + n->cw[i], p + n->cb[i], sh ? ysh : NULL, sh, a->B, b, b + 1, Ci, Hi,
                              Wi, n->ch[i], SOOC_NN_ACT_ELU);
        x = a->y[i];
        Ci = n->ch[i], Hi /= 2, Wi /= 2;
    }
}

/* FC + ELU, LSTM cell and linear head of every item of a (serial). */
static void ref_tail(const float *p, const sooc_ref_net *n, sooc_ref_act *a, int gw, int gh, float *out, int prof) {
    int B = a->B, H = n->hid, nin = n->fc + n->nvec;
    MDL_PT(tprof);
    sooc_mdl_ref_flatten(n, a->y[3], B, gw, gh, a->flat);
    sooc_nn_rlinear_forward(a->f, a->flat, n->nflat, p + n->fcW, p + n->fcb, B, n->nflat, n->fc, SOOC_NN_ACT_ELU);
    for (int b = 0; b < B; b++) memcpy(a->xin + (size_t)b * nin, a->f + (size_t)b * n->fc, n->fc * sizeof(float));
    if (prof) MDL_PACC(MDL_PR_FC, tprof);
    sooc_nn_rlstm_forward(a->h, a->c, a->gates, a->xin, a->h_prev, a->c_prev, p + n->Wx, p + n->Wh, p + n->lb, B, nin,
                          H);
    if (prof) MDL_PACC(MDL_PR_LSTM, tprof);
    sooc_nn_rlinear_forward(out, a->h, H, p + n->hW, p + n->hb, B, H, n->nout, SOOC_NN_ACT_NONE);
    if (prof) MDL_PACC(MDL_PR_HEAD, tprof);
}

typedef struct ref_job {
    const float *p;
    const sooc_ref_net *nn[2];
    sooc_ref_act *aa[2];
    float *oo[2];
    const float *ysh[2];
    float *cols;
    size_t cstride;
    int nnet, gw, gh;
} ref_job;

static void ref_conv_task(void *ctx, int t, int tid) {
    const ref_job *j = ctx;
    int q = j->nnet - 1, b = t;
    if (b >= j->aa[q]->B) b -= j->aa[q]->B, q = 0;
    conv_item(j->p, j->nn[q], j->aa[q], b, j->ysh[q], j->cols + (size_t)tid * j->cstride, j->gw, j->gh);
}

static void ref_tail_task(void *ctx, int q, int tid) {
    const ref_job *j = ctx;
    ref_tail(j->p, j->nn[q], j->aa[q], j->gw, j->gh, j->oo[q], tid == 0);
}

void sooc_mdl_ref_forward2(sooc_model_ws *x, const sooc_ref_net *n0, sooc_ref_act *a0, float *out0, const sooc_ref_net *n1, sooc_ref_act *a1,
                      float *out1, int gw, int gh) {
    const float *p = x->m->p;
    const sooc_ref_ws *rw = x->ref;
    const sooc_ref_net *nn[2] = {n0, n1};
    sooc_ref_act *aa[2] = {a0, a1};
    float *oo[2] = {out0, out1};
    int nnet = n1 ? 2 : 1;
    size_t HW = (size_t)gw * gh, HW1 = HW / 4;
    MDL_PT(tprof);
    /* shared leading channels: their share of the first convolution, once per net */
    const float *ysh[2] = {NULL, NULL};
    size_t cstride = 0;
    int ntask = 0;
    for (int q = 0; q < nnet; q++) {
        const sooc_ref_net *n = nn[q];
        sooc_ref_act *a = aa[q];
        ntask += a->B;
        if (a->nsh > 0 && a->nsh < n->cin && a->B > 1 && (size_t)n->ch[0] <= (size_t)rw->ysh_ch) {
            float *y = rw->ysh + (size_t)q * rw->ysh_ch * HW1;
            sooc_nn_rconv_shared(y, rw->cols, a->x0, p + n->cw[0], a->B, n->cin, gh, gw, n->ch[0], a->nsh);
            ysh[q] = y;
        }
        size_t s = sooc_nn_rconv_cols_floats(n->cin, 1, gh, gw);
        for (int i = 1; i < 4; i++) {
            size_t t = sooc_nn_rconv_cols_floats(n->ch[i - 1], 1, gh >> i, gw >> i);
            if (t > s) s = t;
        }
        if (s > cstride) cstride = s;
    }
    int nt = sooc_mdl_par_threads(x);
    if ((size_t)nt * cstride > rw->ncols) nt = 1;   /* a column slice per thread does not fit (never at K >= threads) */
    /* Items are independent through the conv stack: each runs all four layers on one
     * thread (the second net's items first: the layout item has no shared channels and
     * costs the most); then each net's FC/LSTM/head on one thread. */
    ref_job j = {p, {nn[0], nn[1]}, {aa[0], aa[1]}, {oo[0], oo[1]}, {ysh[0], ysh[1]}, rw->cols, cstride, nnet, gw, gh};
    if (nt > 1) {
        sooc_mdl_par_run(x, ntask, ref_conv_task, &j);
        MDL_PACC(MDL_PR_CONV0, tprof);
        sooc_mdl_par_run(x, nnet, ref_tail_task, &j);
    } else {
        for (int t = 0; t < ntask; t++) ref_conv_task(&j, t, 0);
        MDL_PACC(MDL_PR_CONV0, tprof);
        for (int q = 0; q < nnet; q++) ref_tail_task(&j, q, 0);
    }
}

void sooc_mdl_ref_forward(sooc_model_ws *x, const sooc_ref_net *n, sooc_ref_act *a, int gw, int gh, float *out) {
    sooc_mdl_ref_forward2(x, n, a, out, NULL, NULL, NULL, gw, gh);
}

/* The conv stack's backward on items [bb[q], bb[q + 1]) (a pool task): weight
 * gradients into gd[q] (slab offsets less g0), columns in the block's share of
 * rws.cols / gcols, input gradients of those items only. */
typedef struct conv_bjob {
    const float *p;
    sooc_ref_ws *s;
    const sooc_ref_net *n;
    sooc_ref_act *a;
    int gw, gh, nblk, bb[3];
    float *gd[2];
    size_t g0;
} conv_bjob;

static void conv_bwd_task(void *ctx, int q, int tid) {
    const conv_bjob *j = ctx;
    const sooc_ref_net *n = j->n;
    sooc_ref_act *a = j->a;
    sooc_ref_ws *s = j->s;
    const float *p = j->p;
    int B = a->B, b0 = j->bb[q], b1 = j->bb[q + 1];
    size_t per_item = s->ncols / (size_t)B;   /* every layer's columns are a multiple of the items */
    float *cols = s->cols + per_item * b0, *gcols = s->gcols + per_item * b0, *gd = j->gd[q];
    int Hs[5], Ws[5], Cs[5];
    Hs[0] = j->gh, Ws[0] = j->gw, Cs[0] = n->cin;
    for (int i = 0; i < 4; i++) Hs[i + 1] = Hs[i] / 2, Ws[i + 1] = Ws[i] / 2, Cs[i + 1] = n->ch[i];
    (void)tid;
    for (int i = 3; i >= 0; i--) {
        float *gxi = NULL;
        if (i > 0) {   /* inputs are stop-gradient */
            gxi = s->gy[i - 1];
            size_t hw = (size_t)Hs[i] * Ws[i];
            for (int c = 0; c < Cs[i]; c++) memset(gxi + ((size_t)c * B + b0) * hw, 0, sizeof(float) * (b1 - b0) * hw);
        }
        sooc_nn_rconv_backward(gxi, gd + (n->cw[i] - j->g0), gd + (n->cb[i] - j->g0), s->gy[i], a->y[i], i ? a->y[i - 1] : a->x0,
                               p + n->cw[i], cols, gcols, B, b0, b1, Cs[i], Hs[i], Ws[i], Cs[i + 1], SOOC_NN_ACT_ELU);
    }
}

void sooc_mdl_ref_backward(sooc_model_ws *x, const sooc_ref_net *n, sooc_ref_act *a, int gw, int gh, const float *gout, float *dh,
                      float *dc, float *gvec) {
    const float *p = x->m->p;
    float *g = x->m->g;
    sooc_ref_ws *s = x->ref;
    int B = a->B, H = n->hid, nin = n->fc + n->nvec;
    size_t HW = (size_t)gw * gh;
    /* head (act NONE: gout is not written) */
    float *ghh = s->gh;   /* B x H: dL/dh, then + the next iteration's */
    memset(ghh, 0, sizeof(float) * (size_t)B * H);
    sooc_nn_rlinear_backward(ghh, g + n->hW, g + n->hb, (float *)gout, a->h, H, NULL, p + n->hW, B, H, n->nout,
                             SOOC_NN_ACT_NONE);
    for (size_t i = 0; i < (size_t)B * H; i++) ghh[i] += dh[i];
    /* LSTM: dh, dc become the gradients w.r.t. the previous state */
    float *dcn = s->gy[0];   /* B x H (free until the conv stack) */
    SOOC_ASSERT((size_t)B * H <= (size_t)n->ch[0] * B * (HW / 4));
    memset(dcn, 0, sizeof(float) * (size_t)B * H);
    memset(dh, 0, sizeof(float) * (size_t)B * H);
    float *gx = s->gx;
    memset(gx, 0, sizeof(float) * (size_t)B * nin);
    sooc_nn_rlstm_backward(gx, dh, dcn, g + n->Wx, g + n->Wh, g + n->lb, ghh, dc, s->gg, a->gates, a->c, a->xin,
                           a->h_prev, a->c_prev, p + n->Wx, p + n->Wh, B, nin, H);
    memcpy(dc, dcn, sizeof(float) * (size_t)B * H);
    for (int b = 0; b < B; b++)
        for (int j = 0; j < n->nvec; j++) gvec[(size_t)b * n->nvec + j] += gx[(size_t)b * nin + n->fc + j];
    /* FC (its input gradient is the first fc columns of gx) */
    float *gf = s->gf, *gflat = s->gflat;
    for (int b = 0; b < B; b++) memcpy(gf + (size_t)b * n->fc, gx + (size_t)b * nin, n->fc * sizeof(float));
    memset(gflat, 0, sizeof(float) * (size_t)B * n->nflat);
    sooc_nn_rlinear_backward(gflat, g + n->fcW, g + n->fcb, gf, a->flat, n->nflat, a->f, p + n->fcW, B, n->nflat,
                             n->fc, SOOC_NN_ACT_ELU);
    /* conv stack, top down */
    sooc_mdl_ref_flatten_backward(n, gflat, B, gw, gh, s->gy[3]);
    /* shared leading channels stored for item 0 only: fill the other items' copies */
    for (int c = 0; c < a->nsh; c++)
        for (int b = 1; b < B; b++)
            memcpy(a->x0 + ((size_t)c * B + b) * HW, a->x0 + (size_t)c * B * HW, HW * sizeof(float));
    /* The conv stack in two fixed item blocks (whatever the thread count): the
     * first accumulates into the model's gradients, the second into rws.gconv,
     * added afterwards. */
    size_t g0 = n->cw[0], ng = n->cb[3] + n->ch[3] - g0;
    SOOC_ASSERT(ng <= s->ngconv);
    int nblk = B >= 2 ? 2 : 1;
    if (nblk == 2) memset(s->gconv, 0, ng * sizeof(float));
    conv_bjob j = {p, s, n, a, gw, gh, nblk, {0, (B + 1) / 2, B}, {g + g0, s->gconv}, g0};
    if (nblk == 2 && sooc_mdl_par_threads(x) > 1) sooc_mdl_par_run(x, 2, conv_bwd_task, &j);
    else
        for (int q = 0; q < nblk; q++) conv_bwd_task(&j, q, 0);
    if (nblk == 2)
        for (size_t i = 0; i < ng; i++) g[g0 + i] += s->gconv[i];
}

/* ------------------------------------------------------------ workspace */

/* The refinement's part of a runner's workspace (sooc_model_ws): conv
 * columns, the backward's gradient maps, sized for K items. */
sooc_status sooc_mdl_ref_ws_create(const sooc_model *m, sooc_ref_ws **out) {
    *out = NULL;
    const sooc_model_config *c = &m->cfg;
    int K = c->K;
    sooc_ref_ws *r = sooc_calloc(1, sizeof *r);
    if (!r) return SOOC_ENOMEM;
    int gw = c->ray_w, gh = c->ray_h;
    int cinmax = m->robj.cin > m->rlay.cin ? m->robj.cin : m->rlay.cin;
    size_t colmax = (size_t)cinmax * 9 * K * (gw / 2) * (gh / 2);
    for (int i = 1; i < 4; i++) {
        size_t s = (size_t)c->ref_ch[i - 1] * 9 * K * (gw >> (i + 1)) * (gh >> (i + 1));
        if (s > colmax) colmax = s;
    }
#define B(p, n) if (!(r->p = sooc_calloc((n), sizeof(float)))) { sooc_mdl_ref_ws_destroy(r); return SOOC_ENOMEM; }
    B(cols, colmax);
    B(gcols, colmax);
    r->ncols = colmax;
    r->ysh_ch = c->ref_ch[0];
    B(ysh, (size_t)2 * c->ref_ch[0] * (gw / 2) * (gh / 2));
    for (int i = 0; i < 4; i++) B(gy[i], (size_t)c->ref_ch[i] * K * (gw >> (i + 1)) * (gh >> (i + 1)));
    int hid = c->ref_hidden;
    B(gflat, (size_t)K * m->robj.nflat);
    B(gf, (size_t)K * c->ref_fc);
    B(gx, (size_t)K * (c->ref_fc + m->robj.nvec));
    B(gg, (size_t)K * 4 * hid);
    B(gh, (size_t)K * hid);
    r->ngconv = m->robj.cb[3] + m->robj.ch[3] - m->robj.cw[0];   /* the object net's conv weights and biases */
    if (m->rlay.cb[3] + m->rlay.ch[3] - m->rlay.cw[0] > r->ngconv) r->ngconv = m->rlay.cb[3] + m->rlay.ch[3] - m->rlay.cw[0];
    B(gconv, r->ngconv);
#undef B
    *out = r;
    return SOOC_OK;
}

void sooc_mdl_ref_ws_destroy(sooc_ref_ws *r) {
    if (!r) return;
    float **rp[] = {&r->cols, &r->gcols, &r->ysh, &r->gy[0], &r->gy[1], &r->gy[2], &r->gy[3], &r->gflat, &r->gf, &r->gx,
                    &r->gg, &r->gh, &r->gconv};
    for (size_t i = 0; i < sizeof rp / sizeof rp[0]; i++) sooc_free(*rp[i]);
    sooc_free(r);
}
