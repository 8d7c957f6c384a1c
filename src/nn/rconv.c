/*
 * The refinement network's convolution (nn_refine.h): 3x3, stride 2, TF SAME
 * on even sizes, CBHW activations, fused bias + ELU; im2col + one GEMM per
 * call over all the items it is given (items x pixels as the N dimension).
 *
 * The forward GEMM (sooc_nn_gemm, nn/nn_kern.h) keeps every output one
 * FMA chain over k in order, so splitting items across threads, or taking the shared leading
 * channels' share from a precomputed ysh, never changes a result. The
 * backward's two GEMMs (sooc_nn_gemm_nt for dw, sooc_nn_gemm_tn for the
 * columns' gradient) keep the same rule.
 */
#include "rnet_impl.h"

#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

/* ------------------------------------------------------------------ ELU */

/* The SSE2 and AVX2 rows below compute sooc_nn_expf_nonpos's operations in the same
 * order (bitwise equal; nn_kern.h). */
float sooc_nn_r_elu1(float x) { return x > 0 ? x : sooc_nn_expf_nonpos(x) - 1.0f; }

#ifdef SOOC_NN_HAVE_EXPF8
/* The SSE2 rows below on 8 lanes through sooc_nn_expf_nonpos8 (nn_kern.h; its magic-number
 * rounding gives the same n as the SSE2 rows' cvtps for |x log2 e| < 2^22, and x is
 * clamped to [-87, 0] first: bitwise equal); returns the elements done. */
__attribute__((target("avx2"))) static int64_t elu_bias_avx2(float *y, int64_t n, float bias) {
    int64_t j = 0;
    const __m256 vb = _mm256_set1_ps(bias), lo = _mm256_set1_ps(-87.0f), zero = _mm256_setzero_ps();
    const __m256 one = _mm256_set1_ps(1.0f);
    for (; j + 8 <= n; j += 8) {
        __m256 x = _mm256_add_ps(_mm256_loadu_ps(y + j), vb);
        __m256 e = _mm256_sub_ps(sooc_nn_expf_nonpos8(_mm256_max_ps(_mm256_min_ps(x, zero), lo)), one);
        __m256 pos = _mm256_cmp_ps(x, zero, _CMP_GT_OQ);
        _mm256_storeu_ps(y + j, _mm256_blendv_ps(e, x, pos));
    }
    return j;
}
#define NN_ELU_AVX2 1
#endif

/* y[j] = elu(y[j] + bias) over n values (the Cephes-polynomial ELU of nn_refine.h). */
static void sooc_nn_r_elu_bias(float *y, int64_t n, float bias) {
    int64_t j = 0;
#ifdef NN_ELU_AVX2
    if (sooc_nn_gemm_avx2()) j = elu_bias_avx2(y, n, bias);
#endif
#ifdef __SSE2__
    const __m128 vb = _mm_set1_ps(bias), lo = _mm_set1_ps(-87.0f), zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
    const __m128 l2e = _mm_set1_ps(1.44269504088896341f), c1 = _mm_set1_ps(0.693359375f), c2 = _mm_set1_ps(2.12194440e-4f);
    for (; j + 4 <= n; j += 4) {   /* (after the AVX2 rows: the last < 8) */
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
    for (; j < n; j++) y[j] = sooc_nn_r_elu1(y[j] + bias);
}

void sooc_nn_elu_forward(float *y, const float *x, int64_t n) {
    if (y != x) memcpy(y, x, (size_t)n * sizeof(float));
    sooc_nn_r_elu_bias(y, n, 0.0f);
}

void sooc_nn_elu_backward(float *dx, const float *dy, const float *y, int64_t n) {
    for (int64_t i = 0; i < n; i++) dx[i] += dy[i] * (y[i] > 0 ? 1.0f : y[i] + 1.0f);
}

void sooc_nn_elu_forward_f64(double *y, const double *x, int64_t n) {
    for (int64_t i = 0; i < n; i++) y[i] = x[i] > 0 ? x[i] : expm1(x[i]);
}

void sooc_nn_elu_backward_f64(double *dx, const double *dy, const double *y, int64_t n) {
    for (int64_t i = 0; i < n; i++) dx[i] += dy[i] * (y[i] > 0 ? 1.0 : y[i] + 1.0);
}

/* ------------------------------------------------------------ im2col */

/* One input row (2 Wo values) into its three tap rows: r0[ox] = x[2 ox],
 * r1[ox] = x[2 ox + 1], r2[ox] = x[2 ox + 2] (the last one the zero pad). */
static inline void deint_row(const float *restrict xr, int Wo, float *restrict r0, float *restrict r1,
                             float *restrict r2) {
    int ox = 0;
#ifdef __SSE2__
    for (; ox + 4 <= Wo; ox += 4) {
        __m128 a = _mm_loadu_ps(xr + 2 * ox), b = _mm_loadu_ps(xr + 2 * ox + 4);
        __m128 e = _mm_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0));
        _mm_storeu_ps(r0 + ox, e);
        _mm_storeu_ps(r1 + ox, _mm_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1)));
        if (ox + 4 < Wo) {   /* reads up to x[2 ox + 9] <= x[2 Wo - 1] */
            __m128 c = _mm_loadu_ps(xr + 2 * ox + 2), d = _mm_loadu_ps(xr + 2 * ox + 6);
            _mm_storeu_ps(r2 + ox, _mm_shuffle_ps(c, d, _MM_SHUFFLE(2, 0, 2, 0)));
        } else {   /* the last block: r0 shifted down one lane, the pad zero last */
            _mm_storeu_ps(r2 + ox, _mm_castsi128_ps(_mm_srli_si128(_mm_castps_si128(e), 4)));
        }
    }
#endif
    for (; ox < Wo; ox++) {
        r0[ox] = xr[2 * ox];
        r1[ox] = xr[2 * ox + 1];
        r2[ox] = ox + 1 < Wo ? xr[2 * ox + 2] : 0.0f;
    }
}

/* The backward of deint_row for one tap row ky: x[2 j] += r0[j], then += r2[j - 1];
 * x[2 j + 1] += r1[j] (the order of the taps (ky, kx) of every element is kept). */
static inline void col2im_row(float *restrict x, int Wo, const float *restrict r0, const float *restrict r1,
                              const float *restrict r2) {
    x[0] += r0[0];
    x[1] += r1[0];
    int j = 1;
#ifdef __SSE2__
    for (; j + 4 <= Wo; j += 4) {
        __m128 a = _mm_loadu_ps(x + 2 * j), b = _mm_loadu_ps(x + 2 * j + 4);
        __m128 ev = _mm_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0)), od = _mm_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1));
        ev = _mm_add_ps(_mm_add_ps(ev, _mm_loadu_ps(r0 + j)), _mm_loadu_ps(r2 + j - 1));
        od = _mm_add_ps(od, _mm_loadu_ps(r1 + j));
        _mm_storeu_ps(x + 2 * j, _mm_unpacklo_ps(ev, od));
        _mm_storeu_ps(x + 2 * j + 4, _mm_unpackhi_ps(ev, od));
    }
#endif
    for (; j < Wo; j++) {
        x[2 * j] = (x[2 * j] + r0[j]) + r2[j - 1];
        x[2 * j + 1] += r1[j];
    }
}

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
/* deint_row on 8 outputs per step into nd (1 or 2) destination triples (rows of
 * columns fed by the same input row): d[t][0..2]. Copies only: bitwise the same. */
__attribute__((target("avx2"))) static inline void deint_row_avx2(const float *restrict xr, int Wo, float *d[2][3],
                                                                   int nd) {
    int ox = 0;
    const __m256i rot = _mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 0);
    for (; ox + 8 <= Wo; ox += 8) {
        __m256 a = _mm256_loadu_ps(xr + 2 * ox), b = _mm256_loadu_ps(xr + 2 * ox + 8);
        __m256 e = _mm256_castpd_ps(
            _mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0))), 0xD8));
        __m256 o = _mm256_castpd_ps(
            _mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1))), 0xD8));
        __m256 e2;
        if (ox + 8 < Wo) {   /* reads up to x[2 ox + 17] <= x[2 Wo - 1] */
            __m256 c = _mm256_loadu_ps(xr + 2 * ox + 2), f = _mm256_loadu_ps(xr + 2 * ox + 10);
            e2 = _mm256_castpd_ps(
                _mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(c, f, _MM_SHUFFLE(2, 0, 2, 0))), 0xD8));
        } else {   /* the last block: the evens shifted down one lane, the pad zero last */
            e2 = _mm256_blend_ps(_mm256_permutevar8x32_ps(e, rot), _mm256_setzero_ps(), 0x80);
        }
        for (int t = 0; t < nd; t++) {
            _mm256_storeu_ps(d[t][0] + ox, e);
            _mm256_storeu_ps(d[t][1] + ox, o);
            _mm256_storeu_ps(d[t][2] + ox, e2);
        }
    }
    if (ox < Wo)
        for (int t = 0; t < nd; t++) deint_row(xr + 2 * ox, Wo - ox, d[t][0] + ox, d[t][1] + ox, d[t][2] + ox);
}

#define NN_IM2COL_AVX2 1
#endif

/* Each input row feeds one or two output rows per kx (even columns, odd columns,
 * even columns shifted by one with the pad last): deint_row_avx2 writes both
 * at once 8 wide when the AVX2 kernels run, else deint_row per output row. */
/* Columns of channels [c0, c0 + nc) of items [b0, b1): row (c, ky, kx), column (b, oy, ox). */
static void sooc_nn_rconv_im2col(const float *x, int c0, int nc, int B, int b0, int b1, int Hi, int Wi, float *cols) {
    int Ho = Hi / 2, Wo = Wi / 2, HWo = Ho * Wo;
    size_t No = (size_t)(b1 - b0) * HWo;
    SOOC_ASSERT(Hi % 2 == 0 && Wi % 2 == 0);
#ifdef NN_IM2COL_AVX2
    const int avx2 = Wo >= 8 && sooc_nn_gemm_avx2();
#endif
    for (int cc = 0; cc < nc; cc++)
        for (int b = b0; b < b1; b++) {
            const float *xb = x + ((size_t)(c0 + cc) * B + b) * Hi * Wi;
            float *base = cols + (size_t)cc * 9 * No + (size_t)(b - b0) * HWo;
            for (int kx = 0; kx < 3; kx++) {
                float *restrict r = base + (size_t)(6 + kx) * No + (size_t)(Ho - 1) * Wo;
                for (int ox = 0; ox < Wo; ox++) r[ox] = 0.0f;
            }
            for (int iy = 0; iy < Hi; iy++) {
                const float *restrict xr = xb + (size_t)iy * Wi;
                float *d[2][3];
                int ky[2], oy[2], nt = 0;
                if (iy & 1) {
                    ky[nt] = 1, oy[nt++] = iy >> 1;
                } else {
                    ky[nt] = 0, oy[nt++] = iy >> 1;
                    if (iy >= 2) ky[nt] = 2, oy[nt++] = (iy >> 1) - 1;
                }
                for (int t = 0; t < nt; t++) {
                    float *r0 = base + (size_t)ky[t] * 3 * No + (size_t)oy[t] * Wo;
                    d[t][0] = r0, d[t][1] = r0 + No, d[t][2] = r0 + 2 * No;
                }
#ifdef NN_IM2COL_AVX2
                if (avx2) {
                    deint_row_avx2(xr, Wo, d, nt);
                    continue;
                }
#endif
                for (int t = 0; t < nt; t++) deint_row(xr, Wo, d[t][0], d[t][1], d[t][2]);
            }
        }
}

/* dx[ci] of items [b0, b1) += the columns of channel ci, taps in (ky, kx) order. */
static void col2im_ch(const float *cols, int ci, int B, int b0, int b1, int Hi, int Wi, float *dx) {
    int Ho = Hi / 2, Wo = Wi / 2;
    size_t No = (size_t)(b1 - b0) * Ho * Wo;
    for (int ky = 0; ky < 3; ky++) {
        const float *row = cols + ((size_t)ci * 9 + ky * 3) * No;
        for (int b = b0; b < b1; b++) {
            float *xb = dx + ((size_t)ci * B + b) * Hi * Wi;
            for (int oy = 0; oy < Ho; oy++) {
                int iy = 2 * oy + ky;
                if (iy >= Hi) continue;
                const float *r = row + ((size_t)(b - b0) * Ho + oy) * Wo;
                col2im_row(xb + (size_t)iy * Wi, Wo, r, r + No, r + 2 * No);
            }
        }
    }
}

/* ------------------------------------------------------------ forward */

void sooc_nn_rconv_shared(float *ysh, float *cols, const float *x, const float *w, int B, int Ci, int H, int W,
                          int Co, int nsh) {
    int HWo = (H / 2) * (W / 2);
    sooc_nn_rconv_im2col(x, 0, nsh, B, 0, 1, H, W, cols);
    sooc_nn_gemm(Co, HWo, nsh * 9, w, Ci * 9, cols, HWo, ysh, HWo, NULL, 0, SOOC_NN_EP_NONE, NULL, 0);
}

void sooc_nn_rconv_forward(float *y, float *cols, const float *x, const float *w, const float *b,
                           const float *ysh, int nsh, int B, int b0, int b1, int Ci, int H, int W, int Co,
                           sooc_nn_act act) {
    SOOC_ASSERT(act == SOOC_NN_ACT_NONE || act == SOOC_NN_ACT_ELU);
    int HWo = (H / 2) * (W / 2), nb = b1 - b0, ldy = B * HWo, N = nb * HWo;
    if (nb <= 0) return;
    int c0 = ysh ? nsh : 0;
    float *yb = y + (size_t)b0 * HWo;
    if (ysh)
        for (int co = 0; co < Co; co++)
            for (int q = 0; q < nb; q++) memcpy(yb + (size_t)co * ldy + (size_t)q * HWo, ysh + (size_t)co * HWo,
                                                (size_t)HWo * sizeof(float));
    sooc_nn_rconv_im2col(x, c0, Ci - c0, B, b0, b1, H, W, cols);
    sooc_nn_gemm(Co, N, (Ci - c0) * 9, w + c0 * 9, Ci * 9, cols, N, yb, ldy, NULL, ysh != NULL, SOOC_NN_EP_NONE, NULL, 0);
    for (int co = 0; co < Co; co++) {
        float *r = yb + (size_t)co * ldy, bias = b ? b[co] : 0.0f;
        if (act == SOOC_NN_ACT_ELU) sooc_nn_r_elu_bias(r, N, bias);
        else if (b)
            for (int j = 0; j < N; j++) r[j] += bias;
    }
}

/* ------------------------------------------------------------ backward */

void sooc_nn_rconv_backward(float *dx, float *dw, float *db, float *dy, const float *y, const float *x,
                            const float *w, float *cols, float *dcols, int B, int b0, int b1, int Ci, int H, int W,
                            int Co, sooc_nn_act act) {
    SOOC_ASSERT(act == SOOC_NN_ACT_NONE || act == SOOC_NN_ACT_ELU);
    int HWo = (H / 2) * (W / 2), ldy = B * HWo, N = (b1 - b0) * HWo, Kc = Ci * 9;
    if (N <= 0) return;
    float *g0 = dy + (size_t)b0 * HWo;
    const float *y0 = y + (size_t)b0 * HWo;
    for (int co = 0; co < Co; co++) {
        float *restrict g = g0 + (size_t)co * ldy;
        const float *restrict yy = y0 + (size_t)co * ldy;
        if (act == SOOC_NN_ACT_ELU) {   /* dz = dy (y > 0 ? 1 : y + 1), without branches */
            int j = 0;
#ifdef __SSE2__
            const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f);
            for (; j + 4 <= N; j += 4) {
                __m128 v = _mm_loadu_ps(yy + j), pos = _mm_cmpgt_ps(v, zero);
                __m128 d = _mm_or_ps(_mm_and_ps(pos, one), _mm_andnot_ps(pos, _mm_add_ps(v, one)));
                _mm_storeu_ps(g + j, _mm_mul_ps(_mm_loadu_ps(g + j), d));
            }
#endif
            for (; j < N; j++) g[j] *= yy[j] > 0 ? 1.0f : yy[j] + 1.0f;
        }
        if (db) {   /* four partial sums in double (a fixed order) */
            double s4[4] = {0, 0, 0, 0};
            int j = 0;
            for (; j + 4 <= N; j += 4)
                for (int u = 0; u < 4; u++) s4[u] += g[j + u];
            for (; j < N; j++) s4[0] += g[j];
            db[co] += (float)((s4[0] + s4[2]) + (s4[1] + s4[3]));
        }
    }
    sooc_nn_rconv_im2col(x, 0, Ci, B, b0, b1, H, W, cols);
    /* dw[Co][Kc] += dz[Co][N] cols[Kc][N]^T */
    if (dw) sooc_nn_gemm_nt(Co, Kc, N, g0, ldy, cols, N, dw, Kc, 1, SOOC_NN_EP_NONE, NULL, 0);
    if (!dx) return;
    /* dcols[Kc][N] = w^T dz, then back onto the items' pixels */
    memset(dcols, 0, sizeof(float) * (size_t)Kc * N);
    sooc_nn_gemm_tn(Kc, N, Co, 1.0f, w, Kc, g0, ldy, dcols, N);
    for (int ci = 0; ci < Ci; ci++) col2im_ch(dcols, ci, B, b0, b1, H, W, dx);
}

/* ------------------------------------------------------------ float64 */

void sooc_nn_rconv_forward_f64(double *y, const double *x, const double *w, const double *b, int B, int Ci, int H,
                               int W, int Co, sooc_nn_act act) {
    int Ho = H / 2, Wo = W / 2;
    for (int co = 0; co < Co; co++)
        for (int bb = 0; bb < B; bb++)
            for (int oy = 0; oy < Ho; oy++)
                for (int ox = 0; ox < Wo; ox++) {
                    double s = b ? b[co] : 0.0;
                    for (int ci = 0; ci < Ci; ci++)
                        for (int ky = 0; ky < 3; ky++)
                            for (int kx = 0; kx < 3; kx++) {
                                int iy = 2 * oy + ky, ix = 2 * ox + kx;
                                if (iy >= H || ix >= W) continue;
                                s += w[((size_t)co * Ci + ci) * 9 + ky * 3 + kx] *
                                     x[(((size_t)ci * B + bb) * H + iy) * W + ix];
                            }
                    double *o = y + (((size_t)co * B + bb) * Ho + oy) * Wo + ox;
                    *o = act == SOOC_NN_ACT_ELU && s <= 0 ? expm1(s) : s;
                }
}

void sooc_nn_rconv_backward_f64(double *dx, double *dw, double *db, const double *dy, const double *y,
                                const double *x, const double *w, int B, int Ci, int H, int W, int Co,
                                sooc_nn_act act) {
    int Ho = H / 2, Wo = W / 2;
    for (int co = 0; co < Co; co++)
        for (int bb = 0; bb < B; bb++)
            for (int oy = 0; oy < Ho; oy++)
                for (int ox = 0; ox < Wo; ox++) {
                    size_t o = (((size_t)co * B + bb) * Ho + oy) * Wo + ox;
                    double g = dy[o] * (act == SOOC_NN_ACT_ELU && y[o] <= 0 ? y[o] + 1.0 : 1.0);
                    if (db) db[co] += g;
                    for (int ci = 0; ci < Ci; ci++)
                        for (int ky = 0; ky < 3; ky++)
                            for (int kx = 0; kx < 3; kx++) {
                                int iy = 2 * oy + ky, ix = 2 * ox + kx;
                                if (iy >= H || ix >= W) continue;
                                size_t wi = ((size_t)co * Ci + ci) * 9 + ky * 3 + kx;
                                size_t xi = (((size_t)ci * B + bb) * H + iy) * W + ix;
                                if (dw) dw[wi] += g * x[xi];
                                if (dx) dx[xi] += g * w[wi];
                            }
                }
}
