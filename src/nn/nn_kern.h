/*
 * sooc3d nn: the kernels the model runs. The internal interface of src/nn for
 * src/model (docs/architecture.md "Layers"): not installed, not a public API.
 *
 *  - sooc_nn_gemm / sooc_nn_gemm_tn: row-major GEMMs for narrow layers
 *    (N = 16..64 outputs, K = 33..576) with the bias / accumulate init and a
 *    ReLU or ReLU-backward epilogue applied on the registers (AVX2/FMA kernel
 *    chosen at run time, the portable C kernel otherwise; no BLAS library);
 *    sooc_nn_gemm_nt for input gradients (C = A B^T).
 *  - sooc_nn_pool: a small pthread task pool whose caller waits only for the
 *    tasks a helper has claimed (robust on a loaded machine).
 *  - the decoder MLP layers (docs/engine.md §9) as forward / backward pairs:
 *    sooc_nn_dense_* (linear + ReLU, weights [in x out] row-major, Y = X W + b),
 *    sooc_nn_nerf_heads_* (the density and colour sigmoid heads), and their
 *    composition sooc_nn_nerf_tail_* (layers 2.. of the decoder).
 *
 * Determinism (docs/engine.md "Determinism contract"): every output element
 * of every kernel here is one multiply-add chain over the reduction index in
 * order, whatever the row blocking, so results do not depend on how callers
 * split rows across threads, nor on the BLAS library or its kernel. No kernel
 * allocates; none is multi-threaded by itself (callers split rows).
 * Backward kernels ACCUMULATE (+=) weight gradients, scaled by alpha;
 * any weight-gradient pointer may be NULL to skip it.
 */
#ifndef SOOC3D_NN_KERN_H
#define SOOC3D_NN_KERN_H

#include "sooc3d/core.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ========================================================= scalar math */

/* exp(x) for x <= 0 (Cephes expf polynomial after range reduction to |r| <= ln2/2;
 * relative error < 1e-7, like expf; the ELU of the refinement convs and the per-ray loops of
 * the decoder's aux inputs). */
static inline float sooc_nn_expf_nonpos(float x) {
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

/* log(x) for normal x > 0 (Cephes logf polynomial on the mantissa in [sqrt(1/2), sqrt(2));
 * relative error ~1e-7, like logf; the decoder's per-ray loops). */
static inline float sooc_nn_logf_pos(float x) {
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

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define SOOC_NN_HAVE_EXPF8 1
/* sooc_nn_expf_nonpos on 8 lanes (its operations in its order, AVX2 without FMA: bitwise
 * equal; NaN lanes stay NaN). Callers check sooc_nn_gemm_avx2() first. */
static __attribute__((target("avx2"))) inline __m256 sooc_nn_expf_nonpos8(__m256 x) {
    x = _mm256_blendv_ps(x, _mm256_set1_ps(-87.0f), _mm256_cmp_ps(x, _mm256_set1_ps(-87.0f), _CMP_LT_OQ));   /* NaN stays */
    __m256 big = _mm256_add_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504088896341f)), _mm256_set1_ps(12582912.0f));
    __m256i bi = _mm256_castps_si256(big);
    __m256 fn = _mm256_sub_ps(big, _mm256_set1_ps(12582912.0f));
    __m256 r = _mm256_sub_ps(x, _mm256_mul_ps(fn, _mm256_set1_ps(0.693359375f)));
    r = _mm256_add_ps(r, _mm256_mul_ps(fn, _mm256_set1_ps(2.12194440e-4f)));
    __m256 y = _mm256_set1_ps(1.9875691500e-4f);
    y = _mm256_add_ps(_mm256_mul_ps(y, r), _mm256_set1_ps(1.3981999507e-3f));
    y = _mm256_add_ps(_mm256_mul_ps(y, r), _mm256_set1_ps(8.3334519073e-3f));
    y = _mm256_add_ps(_mm256_mul_ps(y, r), _mm256_set1_ps(4.1665795894e-2f));
    y = _mm256_add_ps(_mm256_mul_ps(y, r), _mm256_set1_ps(1.6666665459e-1f));
    y = _mm256_add_ps(_mm256_mul_ps(y, r), _mm256_set1_ps(5.0000001201e-1f));
    y = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(y, r), r), r), _mm256_set1_ps(1.0f));
    __m256 s = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_add_epi32(bi, _mm256_set1_epi32(127)), 23));
    return _mm256_mul_ps(y, s);
}
#endif

/* ================================================================== GEMM */

/* C[M x N] = init + A[M x K] B[K x N], row-major with leading dimensions
 * lda, ldb, ldc; init = C (acc != 0), else the row vector bias[N] (NULL: 0);
 * then the epilogue ep: SOOC_NN_EP_RELU max(0, .), SOOC_NN_EP_MASK zero where
 * mask[i ldm + j] <= 0 (ReLU backward on a post-activation). AVX2/FMA when the
 * CPU has it, the project's portable C kernel otherwise (SOOC_NO_AVX2 in the
 * environment forces it). */
enum { SOOC_NN_EP_NONE = 0, SOOC_NN_EP_RELU = 1, SOOC_NN_EP_MASK = 2 };
void sooc_nn_gemm(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                  const float *bias, int acc, int ep, const float *mask, int ldm);
/* C[M x N] += alpha A^T B with A [R x M] (lda), B [R x N] (ldb): the weight
 * gradient of a layer over R rows. Each element sums r = 0..R-1 in order. */
void sooc_nn_gemm_tn(int M, int N, int R, float alpha, const float *A, int lda, const float *B, int ldb, float *C,
                     int ldc);
/* C[M x N] = init + A[M x K] B^T with B [N x K] (ldb), e.g. the input gradient
 * dz W^T of a layer whose weights W are [in x out]; init = C (acc != 0) or 0,
 * then the epilogue ep as sooc_nn_gemm. Each element sums k = 0..K-1 in order. */
void sooc_nn_gemm_nt(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                     int acc, int ep, const float *mask, int ldm);
/* 1 when the AVX2/FMA kernels run (CPU support and SOOC_NO_AVX2 unset). */
int sooc_nn_gemm_avx2(void);
/* Choose the kernel for the whole process: 1 AVX2/FMA (where the CPU has it),
 * 0 the portable one; returns the previous choice. For tests and benchmarks
 * that compare the two; not thread-safe against running GEMMs. */
int sooc_nn_gemm_set_kernel(int avx2);

/* ============================================================ task pool */

typedef struct sooc_nn_pool sooc_nn_pool;
/* A task: fn(ctx, task, tid), tid 0 = the caller, 1.. = helpers. A task's
 * result must not depend on tid (tid only selects per-thread scratch). */
typedef void (*sooc_nn_task_fn)(void *ctx, int task, int tid);
#define SOOC_NN_POOL_MAX 16
/* nthr threads in all (the caller and nthr - 1 helpers; 1 <= nthr <= SOOC_NN_POOL_MAX).
 * Helpers that fail to start are left out (sooc_nn_pool_threads says how many run). */
sooc_status sooc_nn_pool_create(sooc_nn_pool **out, int nthr);
void sooc_nn_pool_destroy(sooc_nn_pool *p);   /* NULL-safe; joins the helpers */
/* Threads that take tasks (caller included); 1 for NULL. */
int sooc_nn_pool_threads(const sooc_nn_pool *p);
/* The nthr the pool was created with (0 for NULL). */
int sooc_nn_pool_size(const sooc_nn_pool *p);
/* Run fn for task = 0..n-1: tasks are claimed one at a time, the caller takes
 * part, and it waits only for tasks a helper has claimed. p NULL or n < 2: serial. */
void sooc_nn_pool_run(sooc_nn_pool *p, int n, sooc_nn_task_fn fn, void *ctx);

/* ========================================================== decoder MLP */

/* Dense layer, weights W [nin x nout] row-major (the model's layout), on R rows
 * (I = nin, O = nout below):
 *   y[R x O] = act(x[R x I] W + init), init = y (acc) or b[O] (NULL: 0),
 *   act = SOOC_NN_EP_NONE or SOOC_NN_EP_RELU. Leading dimensions ldx, ldy. */
void sooc_nn_dense_forward(int R, int nin, int nout, const float *x, int ldx, const float *W, const float *b, float *y,
                           int ldy, int acc, int act);
/* Backward of a dense layer given dz[R x O] = dL/d(pre-activation) (ldz):
 *   dW[I x O] += alpha x^T dz, db[O] += alpha sum_r dz (both NULL-able; dW needs x);
 *   dx[R x I] = (acc_dx ? dx : 0) + dz W^T, then zeroed where xmask <= 0 when
 *   xmask != NULL (the ReLU backward of the layer that produced x: pass x).
 * Wt: W transposed ([O x I]) for the AVX2 kernel, or NULL (OpenBLAS on W).
 * dx NULL: no input gradient. */
void sooc_nn_dense_backward(int R, int nin, int nout, const float *dz, int ldz, const float *x, int ldx, const float *W,
                            const float *Wt, float *dx, int lddx, int acc_dx, const float *xmask, float *dW,
                            float *db, float alpha);

/* The decoder's heads on R rows: density from the last hidden
 * layer h[R x H], colour from the colour hidden layer hc[R x Hc]:
 *   sig[r] = sigmoid(h[r] . Wd + bd[0]),  col[r] = sigmoid(hc[r] Wc2 + bc2)
 * Wd [H], Wc2 [Hc x 3] row-major, bc2 [3]. Hc <= SOOC_NN_HC_MAX. */
#define SOOC_NN_HC_MAX 256
void sooc_nn_nerf_heads_forward(int R, int H, int Hc, const float *h, const float *hc, const float *Wd,
                                const float *bd, const float *Wc2, const float *bc2, float *sig, float *col);
/* Backward: gsig[R], gcol[R x 3] = dL/d(sig, col) on entry, OVERWRITTEN with
 * the pre-sigmoid gradients. Writes dh[R x H] = gsig' Wd^T (the density's
 * share of dL/dh, to be accumulated onto by the colour branch) and
 * dhc[R x Hc] = (gcol' Wc2^T) masked by hc > 0 (the ReLU backward of hc: the
 * colour hidden layer's pre-activation gradient). Weight gradients scaled by
 * alpha accumulate into dWd [H], dbd [1], dWc2 [Hc x 3], dbc2 [3] (NULL-able
 * as a group: pass dWd = NULL to skip all four). */
void sooc_nn_nerf_heads_backward(int R, int H, int Hc, const float *h, const float *hc, const float *sig,
                                 const float *col, const float *Wd, const float *Wc2, float *gsig, float *gcol,
                                 float *dh, float *dhc, float *dWd, float *dbd, float *dWc2, float *dbc2,
                                 float alpha);

/* Layers 2.. of a decoder: a1 -> W2 ReLU -> a2 -> W3 ReLU ->
 * a3 -> {density head; Wc1 ReLU -> ac -> colour head}. Weights [in x out]. */
typedef struct sooc_nn_nerf_tail {
    int H, Hc;
    const float *W2, *b2, *W3, *b3, *Wd, *bd, *Wc1, *bc1, *Wc2, *bc2;
    /* transposed copies for the backward's input gradients (NULL: sooc_nn_gemm_nt on W):
       W2t, W3t [H x H], Wc1t [Hc x H] */
    const float *W2t, *W3t, *Wc1t;
} sooc_nn_nerf_tail;
typedef struct sooc_nn_nerf_tail_grad {   /* weight gradients (+=); all NULL or all set */
    float *W2, *b2, *W3, *b3, *Wd, *bd, *Wc1, *bc1, *Wc2, *bc2;
} sooc_nn_nerf_tail_grad;
/* a1 [R x H]: the layer-1 pre-activation (relu_a1 = 1: ReLU applied here, in
 * place) or post-activation (relu_a1 = 0). Writes a2, a3 [R x H], ac [R x Hc],
 * sig [R], col [R x 3]. */
void sooc_nn_nerf_tail_forward(const sooc_nn_nerf_tail *t, int R, float *a1, float *a2, float *a3, float *ac,
                               float *sig, float *col, int relu_a1);
/* Backward to g1 [R x H] = dL/d(layer-1 pre-activation) given gsig, gcol
 * (overwritten as in the heads). Scratch gA, gB [R x H] and gC [R x Hc]; g1
 * may alias gA. g NULL: no weight gradients. */
void sooc_nn_nerf_tail_backward(const sooc_nn_nerf_tail *t, const sooc_nn_nerf_tail_grad *g, float alpha, int R,
                                const float *a1, const float *a2, const float *a3, const float *ac, const float *sig,
                                const float *col, float *gsig, float *gcol, float *gA, float *gB, float *gC,
                                float *g1);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_NN_KERN_H */
