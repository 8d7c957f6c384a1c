/* Refinement inputs (model.md §3.1) and the refinement network (§3.2):
 * conv 3x3 stride 2 SAME (TF padding: 0 before, 1 after) + ELU, FC + ELU,
 * LSTMCell, linear head. Activations are [channel][item][pixel]. */
#include "model/model_internal.h"

#include <cblas.h>
#include <math.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

static inline float sigm(float x) { return 1.0f / (1.0f + expf(-x)); }
/* exp(x) for x <= 0 (Cephes expf polynomial after range reduction to |r| <= ln2/2;
 * relative error < 1e-7, like expf). Scalar version, and an SSE2 version for rows. */
static inline float expf_nonpos(float x) {
    x = x < -87.0f ? -87.0f : x;
    float big = x * 1.44269504088896341f + 12582912.0f;   /* 1.5 * 2^23: rounds to the nearest n */
    uint32_t bi;
    memcpy(&bi, &big, sizeof bi);                          /* bits = 0x4B400000 + n */
    float fn = big - 12582912.0f;
    float r = x - fn * 0.693359375f;
    r = r + fn * 2.12194440e-4f;
    float y = 1.9875691500e-4f;
    y = y * r + 1.3981999507e-3f;
    y = y * r + 8.3334519073e-3f;
    y = y * r + 4.1665795894e-2f;
    y = y * r + 1.6666665459e-1f;
    y = y * r + 5.0000001201e-1f;
    y = y * r * r + r + 1.0f;
    uint32_t bits = (bi + 127u) << 23;                     /* 2^n (0x4B400000 << 23 wraps to 0) */
    float s;
    memcpy(&s, &bits, sizeof s);
    return y * s;
}
static inline float elu(float x) { return x > 0 ? x : expf_nonpos(x) - 1.0f; }

/* log(x) for normal x > 0 (Cephes logf polynomial on the mantissa in [sqrt(1/2), sqrt(2));
 * relative error ~1e-7, like logf; inlined in the per-ray loops of the aux inputs). */
static inline float logf_pos(float x) {
    if (!(x >= 1.17549435e-38f && x <= 3.40282347e38f)) return logf(x);   /* 0, subnormal, inf, NaN, < 0 */
    uint32_t ix;
    memcpy(&ix, &x, sizeof ix);
    int e = (int)(ix >> 23) - 127;
    ix = (ix & 0x007fffffu) | 0x3f800000u;
    float mt;
    memcpy(&mt, &ix, sizeof mt);   /* [1, 2) */
    if (mt > 1.41421356237f) {
        mt *= 0.5f;
        e++;
    }
    float f = mt - 1.0f, z = f * f, fe = (float)e;
    float y = 7.0376836292e-2f;
    y = y * f - 1.1514610310e-1f;
    y = y * f + 1.1676998740e-1f;
    y = y * f - 1.2420140846e-1f;
    y = y * f + 1.4249322787e-1f;
    y = y * f - 1.6668057665e-1f;
    y = y * f + 2.0000714765e-1f;
    y = y * f - 2.4999993993e-1f;
    y = y * f + 3.3333331174e-1f;
    y = y * f * z;
    y += -2.12194440e-4f * fe;
    y += -0.5f * z;
    return f + y + 0.693359375f * fe;
}

/* y[j] = elu(y[j] + bias) over a row (the conv epilogue). */
static void elu_bias_rows(float *y, size_t n, float bias) {
    size_t j = 0;
#ifdef __SSE2__
    const __m128 vb = _mm_set1_ps(bias), lo = _mm_set1_ps(-87.0f), zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
    const __m128 l2e = _mm_set1_ps(1.44269504088896341f), c1 = _mm_set1_ps(0.693359375f), c2 = _mm_set1_ps(2.12194440e-4f);
    for (; j + 4 <= n; j += 4) {
        __m128 x = _mm_add_ps(_mm_loadu_ps(y + j), vb);
        __m128 xn = _mm_max_ps(_mm_min_ps(x, zero), lo);
        __m128i ni = _mm_cvtps_epi32(_mm_mul_ps(xn, l2e));   /* round to nearest (default MXCSR) */
        __m128 fn = _mm_cvtepi32_ps(ni);
        __m128 r = _mm_sub_ps(xn, _mm_mul_ps(fn, c1));
        r = _mm_add_ps(r, _mm_mul_ps(fn, c2));
        __m128 p = _mm_set1_ps(1.9875691500e-4f);
        p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(1.3981999507e-3f));
        p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(8.3334519073e-3f));
        p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(4.1665795894e-2f));
        p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(1.6666665459e-1f));
        p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(5.0000001201e-1f));
        p = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_mul_ps(p, r), r), r), one);
        __m128 s = _mm_castsi128_ps(_mm_slli_epi32(_mm_add_epi32(ni, _mm_set1_epi32(127)), 23));
        __m128 e = _mm_sub_ps(_mm_mul_ps(p, s), one);
        __m128 pos = _mm_cmpgt_ps(x, zero);
        _mm_storeu_ps(y + j, _mm_or_ps(_mm_and_ps(pos, x), _mm_andnot_ps(pos, e)));
    }
#endif
    for (; j < n; j++) y[j] = elu(y[j] + bias);
}

static inline float clampf(float x, float a, float b) { return x < a ? a : x > b ? b : x; }

int mdl_aux_channels(int layout) { return layout ? 25 : 26; }

/* MulMON layer norm over n values at stride 1: (x - mean) / (std + 1e-5). */
static void ln_inplace(float *x, int n) {
    double s = 0, s2 = 0;
    for (int i = 0; i < n; i++) s += x[i];
    float mean = (float)(s / n);
    for (int i = 0; i < n; i++) s2 += (double)(x[i] - mean) * (x[i] - mean);
    float inv = 1.0f / ((float)sqrt(s2 / n) + 1e-5f);
    for (int i = 0; i < n; i++) x[i] = (x[i] - mean) * inv;
}

/* LN over channels [c0, c0 + nc) of item b (all pixels), image layout [c][B][HW].
 * Sums in double with 8 independent partial sums (vectorisable; the order is fixed). */
static void ln_img(float *img, int B, int HW, int b, int c0, int nc) {
    double s8[8] = {0}, q8[8] = {0};
    int n = nc * HW;
    for (int c = c0; c < c0 + nc; c++) {
        const float *restrict v = img + ((size_t)c * B + b) * HW;
        int i = 0;
        for (; i + 8 <= HW; i += 8)
            for (int u = 0; u < 8; u++) s8[u] += v[i + u];
        for (; i < HW; i++) s8[0] += v[i];
    }
    double s = ((s8[0] + s8[4]) + (s8[1] + s8[5])) + ((s8[2] + s8[6]) + (s8[3] + s8[7]));
    float mean = (float)(s / n);
    for (int c = c0; c < c0 + nc; c++) {
        const float *restrict v = img + ((size_t)c * B + b) * HW;
        int i = 0;
        for (; i + 8 <= HW; i += 8)
            for (int u = 0; u < 8; u++) {
                double d = v[i + u] - mean;
                q8[u] += d * d;
            }
        for (; i < HW; i++) {
            double d = v[i] - mean;
            q8[0] += d * d;
        }
    }
    double s2 = ((q8[0] + q8[4]) + (q8[1] + q8[5])) + ((q8[2] + q8[6]) + (q8[3] + q8[7]));
    float inv = 1.0f / ((float)sqrt(s2 / n) + 1e-5f);
    for (int c = c0; c < c0 + nc; c++) {
        float *restrict v = img + ((size_t)c * B + b) * HW;
        for (int i = 0; i < HW; i++) v[i] = (v[i] - mean) * inv;
    }
}

/* The image channels of one component (0 = layout, 1..K objects) after the shared ones (a pool task). */
typedef struct aux_job {
    const sooc_model *m;
    const dec_call *c;
    float *img_o, *img_l;
    const float *post_all;
    int N, K, C;
    float smax, eps_s, is2, lognorm, inv_rh, inv_b, s2;
} aux_job;

static void aux_task(void *ctx, int comp, int tid) {
    const aux_job *j = ctx;
    const dec_call *c = j->c;
    const dec_ws *w = &j->m->ws;
    const view_rays *vr = c->rays;
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
     * The shared leading channels are stored for slot 0 only (ref_act.nsh). */
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
            wgc[rr] = surf ? expf_nonpos(-(xk[0] * xk[0] + xk[2] * xk[2]) / (2 * s2)) : 0.0f;
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
        for (int rr = 0; rr < N; rr++) {
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
                lm += logf_pos(smax * Q2 / S2 + eps_s);
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
    ln_img(img, B, N, b, o + 7, 1);
    ln_img(img, B, N, b, o + 8, 1);
    ln_img(img, B, N, b, o + 9, 1);
    ln_img(img, B, N, b, o + 10, 1);
    ln_img(img, B, N, b, o + 11, 3);
#undef CH
}

void mdl_aux_inputs(sooc_model *m, const dec_call *c, const float *g_lam, const float *g_lay, float *img_o,
                    float *vec_o, float *img_l, float *vec_l) {
    MDL_PT(tprof);
    const sooc_model_config *cfg = &m->cfg;
    const dec_ws *w = &m->ws;
    const view_rays *vr = c->rays;
    int N = vr->N, K = c->nslot, C = K + 1, NL = m->NL, d = cfg->d_what, dl = cfg->d_layout;
    float smax = cfg->sigma_max, eps_s = cfg->eps_sigma_rel * smax;
    float sigc = c->sigma_c > 0 ? c->sigma_c : cfg->sigma_c, is2 = 1.0f / (sigc * sigc);
    float lognorm = 3.0f * logf(sigc * sqrtf(2.0f * (float)M_PI));
    float inv_rh = 1.0f / cfg->box_rh, inv_b = 1.0f / cfg->block_size, s2 = cfg->gauss_s * cfg->gauss_s;
    /* colour-likelihood posterior softmax_k [log pi_k + log N(C; c_k, sigma_C^2)], once per ray */
    float *post_all = w->ll_cf;   /* N x C scratch */
    for (int rr = 0; rr < N; rr++) {
        if (!vr->surf[rr]) continue;
        const float *sh_s = w->sh + (size_t)2 * rr * C, *ct_s = w->ct + (size_t)2 * rr * C * 3;
        float S = w->S[2 * rr], lmax = -1e30f, *lv = post_all + (size_t)rr * C;
        for (int k = 0; k < C; k++) {
            float e = 0;
            for (int a = 0; a < 3; a++) {
                float dd = vr->rgb[rr * 3 + a] - ct_s[k * 3 + a];
                e += dd * dd;
            }
            lv[k] = logf_pos(sh_s[k] / S + 1e-10f) - 0.5f * e * is2;
            if (lv[k] > lmax) lmax = lv[k];
        }
        float z = 0;
        for (int k = 0; k < C; k++) z += (lv[k] = expf_nonpos(lv[k] - lmax));
        for (int k = 0; k < C; k++) lv[k] /= z;
    }
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
    aux_job aj = {m, c, img_o, img_l, post_all, N, K, C, smax, eps_s, is2, lognorm, inv_rh, inv_b, s2};
    if (N >= MDL_PAR_ROWS && mdl_par_threads(m) > 1) mdl_par_run(m, C, aux_task, &aj);
    else
        for (int comp = 0; comp < C; comp++) aux_task(&aj, comp, 0);
    /* vector inputs */
    int nv = 2 * NL + 6;
    for (int k = 0; k < K; k++) {
        float *v = vec_o + (size_t)k * nv;
        memcpy(v, c->lam + (size_t)k * NL, NL * sizeof(float));
        memcpy(v + NL, g_lam + (size_t)k * NL, NL * sizeof(float));
        ln_inplace(v + NL, NL);
        v[2 * NL + 0] = c->zw[k][0];
        v[2 * NL + 1] = c->zw[k][1];
        v[2 * NL + 2] = c->zw[k][2];
        v[2 * NL + 3] = c->zp[k];
        v[2 * NL + 4] = vr->h;
        v[2 * NL + 5] = vr->pitch;
    }
    memcpy(vec_l, c->lay, 2 * dl * sizeof(float));
    memcpy(vec_l + 2 * dl, g_lay, 2 * dl * sizeof(float));
    ln_inplace(vec_l + 2 * dl, 2 * dl);
    vec_l[4 * dl] = vr->h;
    vec_l[4 * dl + 1] = vr->pitch;
    (void)d;
    MDL_PACC(MDL_PR_AUX, tprof);
}

/* ---------------------------------------------------------------- network */

sooc_status mdl_ref_act_alloc(const ref_net *n, int B, int gw, int gh, ref_act *a) {
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
        mdl_ref_act_free(a);
        return SOOC_ENOMEM;
    }
    return SOOC_OK;
}

void mdl_ref_act_free(ref_act *a) {
    float **p[] = {&a->x0, &a->y[0], &a->y[1], &a->y[2], &a->y[3], &a->flat, &a->f, &a->xin, &a->gates,
                   &a->c_prev, &a->h_prev, &a->c, &a->h};
    for (size_t i = 0; i < sizeof p / sizeof p[0]; i++) {
        sooc_free(*p[i]);
        *p[i] = NULL;
    }
}

/* Columns of items [b0, b1) (No = (b1 - b0) Ho Wo columns), 3x3 stride 2, TF SAME
 * padding on even sizes (nothing before, one zero row/column after).
 * Row (ci, ky, kx), column (b, oy, ox) = x[ci][b][2 oy + ky][2 ox + kx]. Each input row
 * feeds one or two output rows per kx (even columns, odd columns, even columns shifted
 * by one with the pad last), written by plain loops (no small memcpy calls). */
static void im2col(const float *x, int Ci, int B, int b0, int b1, int Hi, int Wi, float *cols) {
    int Ho = Hi / 2, Wo = Wi / 2, HWo = Ho * Wo;
    size_t No = (size_t)(b1 - b0) * HWo;
    SOOC_ASSERT(Hi % 2 == 0 && Wi % 2 == 0);
    for (int ci = 0; ci < Ci; ci++)
        for (int b = b0; b < b1; b++) {
            const float *xb = x + ((size_t)ci * B + b) * Hi * Wi;
            float *base = cols + (size_t)ci * 9 * No + (size_t)(b - b0) * HWo;
            for (int kx = 0; kx < 3; kx++) {
                float *restrict r = base + (size_t)(6 + kx) * No + (size_t)(Ho - 1) * Wo;
                for (int ox = 0; ox < Wo; ox++) r[ox] = 0.0f;
            }
            for (int iy = 0; iy < Hi; iy++) {
                const float *restrict xr = xb + (size_t)iy * Wi;
                int ky[2], oy[2], nt = 0;
                if (iy & 1) {
                    ky[nt] = 1, oy[nt++] = iy >> 1;
                } else {
                    ky[nt] = 0, oy[nt++] = iy >> 1;
                    if (iy >= 2) ky[nt] = 2, oy[nt++] = (iy >> 1) - 1;
                }
                for (int t = 0; t < nt; t++) {
                    float *restrict r0 = base + (size_t)ky[t] * 3 * No + (size_t)oy[t] * Wo;
                    float *restrict r1 = r0 + No, *restrict r2 = r0 + 2 * No;
                    for (int ox = 0; ox < Wo; ox++) {
                        r0[ox] = xr[2 * ox];
                        r1[ox] = xr[2 * ox + 1];
                    }
                    for (int ox = 0; ox + 1 < Wo; ox++) r2[ox] = xr[2 * ox + 2];
                    r2[Wo - 1] = 0.0f;
                }
            }
        }
}

static void col2im(const float *cols, int Ci, int B, int Hi, int Wi, float *gx) {
    int Ho = Hi / 2, Wo = Wi / 2, No = B * Ho * Wo;
    memset(gx, 0, sizeof(float) * (size_t)Ci * B * Hi * Wi);
    for (int ci = 0; ci < Ci; ci++)
        for (int ky = 0; ky < 3; ky++)
            for (int kx = 0; kx < 3; kx++) {
                const float *row = cols + ((size_t)ci * 9 + ky * 3 + kx) * No;
                for (int b = 0; b < B; b++) {
                    float *xb = gx + ((size_t)ci * B + b) * Hi * Wi;
                    for (int oy = 0; oy < Ho; oy++) {
                        int iy = 2 * oy + ky;
                        if (iy >= Hi) continue;
                        const float *r = row + ((size_t)b * Ho + oy) * Wo;
                        for (int ox = 0; ox < Wo; ox++) {
                            int ix = 2 * ox + kx;
                            if (ix < Wi) xb[iy * Wi + ix] += r[ox];
                        }
                    }
                }
            }
}

/* The four conv layers of item b of a (on the calling thread; ct: its column scratch).
 * The first a->nsh input channels are stored once (item 0) and their share of the first
 * convolution is in ysh (ch[0] x HW1): the item's own channels are accumulated onto it
 * (the same FMA chain over k as the full product with the AVX2 kernel). */
static void conv_item(const float *p, const ref_net *n, ref_act *a, int b, const float *ysh, float *ct, int gw, int gh) {
    int B = a->B, nsh = ysh ? a->nsh : 0;
    const float *x = a->x0;
    int Ci = n->cin, Hi = gh, Wi = gw;
    for (int i = 0; i < 4; i++) {
        int Co = n->ch[i], Ho = Hi / 2, Wo = Wi / 2, HWo = Ho * Wo, ldy = B * HWo;
        float *y = a->y[i] + (size_t)b * HWo;
        if (i == 0 && nsh > 0) {
            for (int co = 0; co < Co; co++) memcpy(y + (size_t)co * ldy, ysh + (size_t)co * HWo, HWo * sizeof(float));
            im2col(x + (size_t)nsh * B * Hi * Wi, Ci - nsh, B, b, b + 1, Hi, Wi, ct);
            mdl_gemm(Co, HWo, (Ci - nsh) * 9, p + n->cw[i] + nsh * 9, Ci * 9, ct, HWo, y, ldy, NULL, 1, MDL_EP_NONE, NULL,
                     0);
        } else {
            im2col(x, Ci, B, b, b + 1, Hi, Wi, ct);
            mdl_gemm(Co, HWo, Ci * 9, p + n->cw[i], Ci * 9, ct, HWo, y, ldy, NULL, 0, MDL_EP_NONE, NULL, 0);
        }
        for (int co = 0; co < Co; co++) elu_bias_rows(y + (size_t)co * ldy, (size_t)HWo, p[n->cb[i] + co]);
        x = a->y[i];
        Ci = Co, Hi = Ho, Wi = Wo;
    }
}

/* The conv stack's last map (C x B x fh x fw, fh = gh / 16) flattened per item
 * for the FC layer. Ray grids up to 32 x 32 are flattened as they are; a
 * larger grid (a multiple of 32) is average-pooled to the 2 x 2 map of a
 * 32 x 32 grid, so the FC weights (and every other weight) do not depend on
 * the ray grid and a model trained on one grid runs on another
 * (sooc_model_copy_rays). */
typedef struct pool_geom {
    int fh, fw;   /* last conv map            */
    int ph, pw;   /* FC input map (<= 2 x 2)  */
    int sh, sw;   /* pooling window           */
    float inv;    /* 1 / window size          */
} pool_geom;

static pool_geom pool_of(int gw, int gh) {
    pool_geom g;
    g.fh = gh >> 4, g.fw = gw >> 4;
    g.ph = g.fh > 2 ? 2 : g.fh, g.pw = g.fw > 2 ? 2 : g.fw;
    g.sh = g.fh / g.ph, g.sw = g.fw / g.pw;
    g.inv = 1.0f / (float)(g.sh * g.sw);
    return g;
}

void mdl_ref_flatten(const ref_net *n, const float *y3, int B, int gw, int gh, float *flat) {
    pool_geom g = pool_of(gw, gh);
    for (int b = 0; b < B; b++)
        for (int c = 0; c < n->ch[3]; c++) {
            const float *src = y3 + ((size_t)c * B + b) * g.fh * g.fw;
            float *dst = flat + (size_t)b * n->nflat + (size_t)c * g.ph * g.pw;
            for (int i = 0; i < g.ph; i++)
                for (int j = 0; j < g.pw; j++) {
                    float acc = 0;
                    for (int u = 0; u < g.sh; u++)
                        for (int v = 0; v < g.sw; v++) acc += src[(i * g.sh + u) * g.fw + j * g.sw + v];
                    dst[i * g.pw + j] = acc * g.inv;
                }
        }
}

/* Backward of mdl_ref_flatten: writes (not adds) the gradient w.r.t. y3. */
void mdl_ref_flatten_backward(const ref_net *n, const float *gflat, int B, int gw, int gh, float *gy3) {
    pool_geom g = pool_of(gw, gh);
    for (int b = 0; b < B; b++)
        for (int c = 0; c < n->ch[3]; c++) {
            float *dst = gy3 + ((size_t)c * B + b) * g.fh * g.fw;
            const float *src = gflat + (size_t)b * n->nflat + (size_t)c * g.ph * g.pw;
            for (int y = 0; y < g.fh; y++)
                for (int x = 0; x < g.fw; x++) dst[y * g.fw + x] = src[(y / g.sh) * g.pw + x / g.sw] * g.inv;
        }
}

/* FC + ELU, LSTM cell and linear head of every item of a (serial). */
static void ref_tail(const float *p, const ref_net *n, ref_act *a, int gw, int gh, float *out, int prof) {
    int B = a->B, H = n->hid, nin = n->fc + n->nvec;
    MDL_PT(tprof);
    mdl_ref_flatten(n, a->y[3], B, gw, gh, a->flat);
    mdl_gemm(B, n->fc, n->nflat, a->flat, n->nflat, p + n->fcW, n->fc, a->f, n->fc, NULL, 0, MDL_EP_NONE, NULL, 0);
    for (int b = 0; b < B; b++)
        for (int j = 0; j < n->fc; j++) {
            float v = elu(a->f[(size_t)b * n->fc + j] + p[n->fcb + j]);
            a->f[(size_t)b * n->fc + j] = v;
            a->xin[(size_t)b * nin + j] = v;
        }
    if (prof) MDL_PACC(MDL_PR_FC, tprof);
    float *gt = a->gates;
    mdl_gemm(B, 4 * H, nin, a->xin, nin, p + n->Wx, 4 * H, gt, 4 * H, NULL, 0, MDL_EP_NONE, NULL, 0);
    mdl_gemm(B, 4 * H, H, a->h_prev, H, p + n->Wh, 4 * H, gt, 4 * H, NULL, 1, MDL_EP_NONE, NULL, 0);
    if (prof) MDL_PACC(MDL_PR_GATES, tprof);
    for (int b = 0; b < B; b++) {
        float *g = gt + (size_t)b * 4 * H;
        for (int j = 0; j < H; j++) {
            float gi = sigm(g[j] + p[n->lb + j]), gf = sigm(g[H + j] + p[n->lb + H + j]);
            float gg = tanhf(g[2 * H + j] + p[n->lb + 2 * H + j]), go = sigm(g[3 * H + j] + p[n->lb + 3 * H + j]);
            g[j] = gi, g[H + j] = gf, g[2 * H + j] = gg, g[3 * H + j] = go;
            float cc = gf * a->c_prev[(size_t)b * H + j] + gi * gg;
            a->c[(size_t)b * H + j] = cc;
            a->h[(size_t)b * H + j] = go * tanhf(cc);
        }
    }
    if (prof) MDL_PACC(MDL_PR_LSTM, tprof);
    mdl_gemm(B, n->nout, H, a->h, H, p + n->hW, n->nout, out, n->nout, NULL, 0, MDL_EP_NONE, NULL, 0);
    for (int b = 0; b < B; b++)
        for (int j = 0; j < n->nout; j++) out[(size_t)b * n->nout + j] += p[n->hb + j];
    if (prof) MDL_PACC(MDL_PR_HEAD, tprof);
}

typedef struct ref_job {
    const float *p;
    const ref_net *nn[2];
    ref_act *aa[2];
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

void mdl_ref_forward2(sooc_model *m, const ref_net *n0, ref_act *a0, float *out0, const ref_net *n1, ref_act *a1,
                      float *out1, int gw, int gh) {
    const float *p = m->p;
    const ref_net *nn[2] = {n0, n1};
    ref_act *aa[2] = {a0, a1};
    float *oo[2] = {out0, out1};
    int nnet = n1 ? 2 : 1;
    size_t HW = (size_t)gw * gh, HW1 = HW / 4;
    MDL_PT(tprof);
    /* shared leading channels: their share of the first convolution, once per net */
    const float *ysh[2] = {NULL, NULL};
    size_t cstride = 0;
    int ntask = 0;
    for (int q = 0; q < nnet; q++) {
        const ref_net *n = nn[q];
        ref_act *a = aa[q];
        ntask += a->B;
        if (a->nsh > 0 && a->nsh < n->cin && a->B > 1 && (size_t)n->ch[0] <= (size_t)m->rws.ysh_ch) {
            float *y = m->rws.ysh + (size_t)q * m->rws.ysh_ch * HW1;
            im2col(a->x0, a->nsh, a->B, 0, 1, gh, gw, m->rws.cols);
            mdl_gemm(n->ch[0], (int)HW1, a->nsh * 9, p + n->cw[0], n->cin * 9, m->rws.cols, (int)HW1, y, (int)HW1, NULL,
                     0, MDL_EP_NONE, NULL, 0);
            ysh[q] = y;
        }
        size_t s = (size_t)n->cin * 9 * HW1;
        for (int i = 1; i < 4; i++) {
            size_t t = (size_t)n->ch[i - 1] * 9 * (HW >> (2 * (i + 1)));
            if (t > s) s = t;
        }
        if (s > cstride) cstride = s;
    }
    int nt = mdl_par_threads(m);
    if ((size_t)nt * cstride > m->rws.ncols) nt = 1;   /* a column slice per thread does not fit (never at K >= threads) */
    /* Items are independent through the conv stack: each runs all four layers on one
     * thread (the second net's items first: the layout item has no shared channels and
     * costs the most); then each net's FC/LSTM/head on one thread. */
    ref_job j = {p, {nn[0], nn[1]}, {aa[0], aa[1]}, {oo[0], oo[1]}, {ysh[0], ysh[1]}, m->rws.cols, cstride, nnet, gw, gh};
    if (nt > 1) {
        mdl_par_run(m, ntask, ref_conv_task, &j);
        MDL_PACC(MDL_PR_CONV0, tprof);
        mdl_par_run(m, nnet, ref_tail_task, &j);
    } else {
        for (int t = 0; t < ntask; t++) ref_conv_task(&j, t, 0);
        MDL_PACC(MDL_PR_CONV0, tprof);
        for (int q = 0; q < nnet; q++) ref_tail_task(&j, q, 0);
    }
}

void mdl_ref_forward(sooc_model *m, const ref_net *n, ref_act *a, int gw, int gh, float *out) {
    mdl_ref_forward2(m, n, a, out, NULL, NULL, NULL, gw, gh);
}

void mdl_ref_backward(sooc_model *m, const ref_net *n, ref_act *a, int gw, int gh, const float *gout, float *dh,
                      float *dc, float *gvec) {
    const float *p = m->p;
    float *g = m->g;
    ref_ws *s = &m->rws;
    int B = a->B, H = n->hid, nin = n->fc + n->nvec;
    /* head */
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, H, n->nout, B, 1.0f, a->h, H, gout, n->nout, 1.0f, g + n->hW,
                n->nout);
    for (int b = 0; b < B; b++)
        for (int j = 0; j < n->nout; j++) g[n->hb + j] += gout[(size_t)b * n->nout + j];
    float *ghh = s->gh;   /* B x H: dL/dh */
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, B, H, n->nout, 1.0f, gout, n->nout, p + n->hW, n->nout, 0.0f,
                ghh, H);
    float *gg = s->gg;
    for (int b = 0; b < B; b++) {
        const float *gt = a->gates + (size_t)b * 4 * H;
        float *q = gg + (size_t)b * 4 * H;
        for (int j = 0; j < H; j++) {
            size_t i = (size_t)b * H + j;
            float gh_ = ghh[i] + dh[i];
            float gi = gt[j], gf = gt[H + j], ggt = gt[2 * H + j], go = gt[3 * H + j];
            float tc = tanhf(a->c[i]);
            float gc = gh_ * go * (1 - tc * tc) + dc[i];
            q[j] = gc * ggt * gi * (1 - gi);
            q[H + j] = gc * a->c_prev[i] * gf * (1 - gf);
            q[2 * H + j] = gc * gi * (1 - ggt * ggt);
            q[3 * H + j] = gh_ * tc * go * (1 - go);
            dc[i] = gc * gf;
        }
    }
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, nin, 4 * H, B, 1.0f, a->xin, nin, gg, 4 * H, 1.0f, g + n->Wx,
                4 * H);
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, H, 4 * H, B, 1.0f, a->h_prev, H, gg, 4 * H, 1.0f, g + n->Wh,
                4 * H);
    for (int b = 0; b < B; b++)
        for (int j = 0; j < 4 * H; j++) g[n->lb + j] += gg[(size_t)b * 4 * H + j];
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, B, H, 4 * H, 1.0f, gg, 4 * H, p + n->Wh, 4 * H, 0.0f, dh, H);
    float *gx = s->gx;
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, B, nin, 4 * H, 1.0f, gg, 4 * H, p + n->Wx, 4 * H, 0.0f, gx,
                nin);
    for (int b = 0; b < B; b++)
        for (int j = 0; j < n->nvec; j++) gvec[(size_t)b * n->nvec + j] += gx[(size_t)b * nin + n->fc + j];
    /* FC */
    float *gf = s->gf;
    for (int b = 0; b < B; b++)
        for (int j = 0; j < n->fc; j++) {
            float y = a->f[(size_t)b * n->fc + j];
            gf[(size_t)b * n->fc + j] = gx[(size_t)b * nin + j] * (y > 0 ? 1.0f : y + 1.0f);
        }
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, n->nflat, n->fc, B, 1.0f, a->flat, n->nflat, gf, n->fc, 1.0f,
                g + n->fcW, n->fc);
    for (int b = 0; b < B; b++)
        for (int j = 0; j < n->fc; j++) g[n->fcb + j] += gf[(size_t)b * n->fc + j];
    float *gflat = s->gflat;
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, B, n->nflat, n->fc, 1.0f, gf, n->fc, p + n->fcW, n->fc, 0.0f,
                gflat, n->nflat);
    /* conv stack, top down */
    int Hs[5], Ws[5], Cs[5];
    Hs[0] = gh, Ws[0] = gw, Cs[0] = n->cin;
    for (int i = 0; i < 4; i++) Hs[i + 1] = Hs[i] / 2, Ws[i + 1] = Ws[i] / 2, Cs[i + 1] = n->ch[i];
    size_t HW = (size_t)gw * gh;
    mdl_ref_flatten_backward(n, gflat, B, gw, gh, s->gy[3]);
    for (int i = 3; i >= 0; i--) {
        int Co = Cs[i + 1], Ci = Cs[i], No = B * Hs[i + 1] * Ws[i + 1];
        float *gy = s->gy[i];
        const float *y = a->y[i];
        for (size_t j = 0; j < (size_t)Co * No; j++) gy[j] *= y[j] > 0 ? 1.0f : y[j] + 1.0f;
        const float *x = i ? a->y[i - 1] : a->x0;
        if (i == 0)   /* shared leading channels stored for item 0 only: fill the other items' copies */
            for (int c = 0; c < a->nsh; c++)
                for (int b = 1; b < B; b++)
                    memcpy(a->x0 + ((size_t)c * B + b) * HW, a->x0 + (size_t)c * B * HW, HW * sizeof(float));
        im2col(x, Ci, B, 0, B, Hs[i], Ws[i], s->cols);
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, Co, Ci * 9, No, 1.0f, gy, No, s->cols, No, 1.0f,
                    g + n->cw[i], Ci * 9);
        for (int co = 0; co < Co; co++) {
            double sb = 0;
            for (int j = 0; j < No; j++) sb += gy[(size_t)co * No + j];
            g[n->cb[i] + co] += (float)sb;
        }
        if (i == 0) break;   /* inputs are stop-gradient */
        cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, Ci * 9, No, Co, 1.0f, p + n->cw[i], Ci * 9, gy, No, 0.0f,
                    s->gcols, No);
        col2im(s->gcols, Ci, B, Hs[i], Ws[i], s->gy[i - 1]);
    }
}
