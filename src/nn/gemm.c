/* Small row-major GEMMs for the decoder MLPs and the refinement network
 * (nn/nn_kern.h). The layers are narrow (N = 16..64 outputs, K = 3..576),
 * so a general BLAS spends a good part of its time packing A and B and in its
 * beta pass; these kernels read A and B in place (B rows are contiguous in N,
 * A elements are broadcast), start from the bias, the existing C or zero, and
 * apply the epilogue (ReLU or a ReLU-backward mask) before the single store.
 *
 * sooc_nn_gemm_tn (weight gradients, C += alpha A^T B) runs the same kernels
 * with A read down its columns: element (i, k) of A^T is A[k lda + i].
 * sooc_nn_gemm_nt (input gradients, C = A B^T) copies K x 16 panels of B^T to
 * the stack and runs sooc_nn_gemm on them, chunk after chunk along K.
 *
 * Determinism (docs/engine.md "Determinism contract"): every C element is
 * accumulated as one multiply-add chain over k = 0..K-1 in order, whatever the
 * row or column blocking, so results do not depend on how rows are split
 * across threads. Two kernels, both the project's own: AVX2/FMA (GCC/Clang on
 * x86-64, CPUs with AVX2 and FMA, chosen at run time; fused multiply-adds) and
 * a portable C kernel (separate multiply and add: this file is compiled with
 * -ffp-contract=off), which every other CPU and SOOC_NO_AVX2 run. Neither
 * depends on which BLAS library or kernel is installed. */
#include "nn_impl.h"
#include "nn/nn_kern.h"

#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ portable path */

/* Shared parameters of one register-tile call. A's element (row r, k) is
 * A[r ra + k ka] (ra = lda, ka = 1 for A; ra = 1, ka = lda for A^T).
 * init: 0 zero, 1 bias, 2 C. addc: the tile is C += alpha * sum (init zero). */
typedef struct tile {
    int K, ra, ka, ldb, ldc, ldm, init, ep, addc;
    float alpha;
} tile;

enum { PORT_MR = 4, PORT_NR = 8 };   /* the portable register tile: 4 rows x 8 columns */

/* Epilogue and store of an MR x NR tile held in c (row stride PORT_NR). */
static inline __attribute__((always_inline)) void kport_store(int MR, int NR, const tile *t, const float *c, float *C,
                                                              const float *mask) {
    for (int r = 0; r < MR; r++) {
        float *cr = C + (size_t)r * t->ldc;
        const float *mr = mask ? mask + (size_t)r * t->ldm : NULL;
        for (int j = 0; j < NR; j++) {
            float v = c[r * PORT_NR + j];
            if (t->addc) v = t->alpha * v + cr[j];
            if (t->ep == SOOC_NN_EP_RELU) v = v > 0 ? v : 0.0f;
            else if (t->ep == SOOC_NN_EP_MASK) v = mr[j] > 0 ? v : 0.0f;
            cr[j] = v;
        }
    }
}

/* Edge tiles (MR <= PORT_MR, NR <= PORT_NR), scalar: per element the same
 * operations in the same order as kport_full's lanes. */
static void kport_any(int MR, int NR, const tile *t, const float *A, const float *B, float *C, const float *bias,
                      const float *mask) {
    float c[PORT_MR * PORT_NR];
    int K = t->K, ra = t->ra, ka = t->ka, ldb = t->ldb, ldc = t->ldc;
    for (int r = 0; r < MR; r++)
        for (int j = 0; j < NR; j++)
            c[r * PORT_NR + j] = t->init == 2 ? C[(size_t)r * ldc + j] : t->init == 1 ? bias[j] : 0.0f;
    for (int k = 0; k < K; k++) {
        const float *b = B + (size_t)k * ldb, *a = A + (size_t)k * ka;
        for (int r = 0; r < MR; r++) {
            float av = a[(size_t)r * ra];
            for (int j = 0; j < NR; j++) c[r * PORT_NR + j] = c[r * PORT_NR + j] + av * b[j];
        }
    }
    kport_store(MR, NR, t, c, C, mask);
}

/* Full 4 x 8 tiles on GCC/Clang vector extensions (SSE2 on x86-64, NEON on
 * aarch64, scalar elsewhere): lane-wise multiply then add, as kport_any. */
typedef float v4f __attribute__((vector_size(16)));

static inline v4f v4_load(const float *p) {
    v4f v;
    memcpy(&v, p, sizeof v);
    return v;
}

static void kport_full(const tile *t, const float *A, const float *B, float *C, const float *bias,
                       const float *mask) {
    v4f c[PORT_MR][2];
    int K = t->K, ra = t->ra, ka = t->ka, ldb = t->ldb, ldc = t->ldc;
    for (int r = 0; r < PORT_MR; r++) {
        const float *src = t->init == 2 ? C + (size_t)r * ldc : bias;
        c[r][0] = t->init ? v4_load(src) : (v4f){0, 0, 0, 0};
        c[r][1] = t->init ? v4_load(src + 4) : (v4f){0, 0, 0, 0};
    }
    for (int k = 0; k < K; k++) {
        const float *b = B + (size_t)k * ldb, *a = A + (size_t)k * ka;
        v4f b0 = v4_load(b), b1 = v4_load(b + 4);
        for (int r = 0; r < PORT_MR; r++) {
            float x = a[(size_t)r * ra];
            v4f av = {x, x, x, x};
            c[r][0] = c[r][0] + av * b0;
            c[r][1] = c[r][1] + av * b1;
        }
    }
    float out[PORT_MR * PORT_NR];
    for (int r = 0; r < PORT_MR; r++) memcpy(out + r * PORT_NR, c[r], sizeof c[r]);
    kport_store(PORT_MR, PORT_NR, t, out, C, mask);
}

static void gemm_port(int M, int N, const tile *t, const float *A, const float *B, float *C, const float *bias,
                      const float *mask) {
    for (int j = 0; j < N; j += PORT_NR) {
        int nr = N - j < PORT_NR ? N - j : PORT_NR;
        const float *Bj = B + j, *bj = bias ? bias + j : NULL, *mj = mask ? mask + j : NULL;
        float *Cj = C + j;
        for (int i = 0; i < M; i += PORT_MR) {
            int mr = M - i < PORT_MR ? M - i : PORT_MR;
            const float *Ai = A + (size_t)i * t->ra, *Mi = mj ? mj + (size_t)i * t->ldm : NULL;
            float *Ci = Cj + (size_t)i * t->ldc;
            if (mr == PORT_MR && nr == PORT_NR) kport_full(t, Ai, Bj, Ci, bj, Mi);
            else kport_any(mr, nr, t, Ai, Bj, Ci, bj, Mi);
        }
    }
}

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#define NN_KERN_X86 1
#include <immintrin.h>

#define TGT __attribute__((target("avx2,fma")))
#define AI __attribute__((always_inline)) inline

/* MR rows x 16 columns (two vectors); m0/m1: column masks of the two vectors
 * (full = 1: no masks, plain loads). */
static TGT AI void k16(int MR, int full, const tile *t, const float *A, const float *B, float *C, const float *bias,
                       const float *mask, __m256i m0, __m256i m1) {
    __m256 c0[6], c1[6];
    int K = t->K, ra = t->ra, ka = t->ka, ldb = t->ldb, ldc = t->ldc;
#define LD0(p) (full ? _mm256_loadu_ps(p) : _mm256_maskload_ps((p), m0))
#define LD1(p) (full ? _mm256_loadu_ps(p) : _mm256_maskload_ps((p), m1))
#pragma GCC unroll 6
    for (int r = 0; r < MR; r++) {
        if (t->init == 2) {
            c0[r] = LD0(C + (size_t)r * ldc);
            c1[r] = LD1(C + (size_t)r * ldc + 8);
        } else if (t->init == 1) {
            c0[r] = LD0(bias);
            c1[r] = LD1(bias + 8);
        } else {
            c0[r] = _mm256_setzero_ps();
            c1[r] = _mm256_setzero_ps();
        }
    }
    for (int k = 0; k < K; k++) {
        const float *b = B + (size_t)k * ldb, *a = A + (size_t)k * ka;
        __m256 b0 = LD0(b), b1 = LD1(b + 8);
#pragma GCC unroll 6
        for (int r = 0; r < MR; r++) {
            __m256 av = _mm256_broadcast_ss(a + (size_t)r * ra);
            c0[r] = _mm256_fmadd_ps(av, b0, c0[r]);
            c1[r] = _mm256_fmadd_ps(av, b1, c1[r]);
        }
    }
    const __m256 z = _mm256_setzero_ps(), al = _mm256_set1_ps(t->alpha);
#pragma GCC unroll 6
    for (int r = 0; r < MR; r++) {
        float *cr = C + (size_t)r * ldc;
        if (t->addc) {
            c0[r] = _mm256_fmadd_ps(al, c0[r], LD0(cr));
            c1[r] = _mm256_fmadd_ps(al, c1[r], LD1(cr + 8));
        }
        if (t->ep == SOOC_NN_EP_RELU) {
            c0[r] = _mm256_max_ps(c0[r], z);
            c1[r] = _mm256_max_ps(c1[r], z);
        } else if (t->ep == SOOC_NN_EP_MASK) {
            const float *mr = mask + (size_t)r * t->ldm;
            c0[r] = _mm256_and_ps(c0[r], _mm256_cmp_ps(LD0(mr), z, _CMP_GT_OQ));
            c1[r] = _mm256_and_ps(c1[r], _mm256_cmp_ps(LD1(mr + 8), z, _CMP_GT_OQ));
        }
        if (full) {
            _mm256_storeu_ps(cr, c0[r]);
            _mm256_storeu_ps(cr + 8, c1[r]);
        } else {
            _mm256_maskstore_ps(cr, m0, c0[r]);
            _mm256_maskstore_ps(cr + 8, m1, c1[r]);
        }
    }
#undef LD0
#undef LD1
}

/* MR rows x up to 8 columns (one masked vector): narrow panels (the last columns of an
 * odd-width layer, the 2x2 outputs of the last conv). */
static TGT AI void k8(int MR, const tile *t, const float *A, const float *B, float *C, const float *bias,
                      const float *mask, __m256i m0) {
    __m256 c0[12];
    int K = t->K, ra = t->ra, ka = t->ka, ldb = t->ldb, ldc = t->ldc;
#pragma GCC unroll 12
    for (int r = 0; r < MR; r++)
        c0[r] = t->init == 2 ? _mm256_maskload_ps(C + (size_t)r * ldc, m0)
              : t->init == 1 ? _mm256_maskload_ps(bias, m0)
                             : _mm256_setzero_ps();
    for (int k = 0; k < K; k++) {
        __m256 b0 = _mm256_maskload_ps(B + (size_t)k * ldb, m0);
        const float *a = A + (size_t)k * ka;
#pragma GCC unroll 12
        for (int r = 0; r < MR; r++) c0[r] = _mm256_fmadd_ps(_mm256_broadcast_ss(a + (size_t)r * ra), b0, c0[r]);
    }
    const __m256 z = _mm256_setzero_ps(), al = _mm256_set1_ps(t->alpha);
#pragma GCC unroll 12
    for (int r = 0; r < MR; r++) {
        if (t->addc) c0[r] = _mm256_fmadd_ps(al, c0[r], _mm256_maskload_ps(C + (size_t)r * ldc, m0));
        if (t->ep == SOOC_NN_EP_RELU) c0[r] = _mm256_max_ps(c0[r], z);
        else if (t->ep == SOOC_NN_EP_MASK)
            c0[r] = _mm256_and_ps(c0[r], _mm256_cmp_ps(_mm256_maskload_ps(mask + (size_t)r * t->ldm, m0), z, _CMP_GT_OQ));
        _mm256_maskstore_ps(C + (size_t)r * ldc, m0, c0[r]);
    }
}

/* Rows i.. of one 16-column panel: blocks of 6, then the remainder. */
#define PANEL16(FULL)                                                                                        \
    do {                                                                                                     \
        int i = 0;                                                                                           \
        for (; i + 6 <= M; i += 6)                                                                           \
            k16(6, FULL, t, A + (size_t)i * t->ra, Bj, Cj + (size_t)i * t->ldc, bj,                          \
                mj ? mj + (size_t)i * t->ldm : NULL, m0, m1);                                                \
        const float *Ai = A + (size_t)i * t->ra, *Mi = mj ? mj + (size_t)i * t->ldm : NULL;                  \
        float *Ci = Cj + (size_t)i * t->ldc;                                                                 \
        switch (M - i) {                                                                                     \
        case 5: k16(5, FULL, t, Ai, Bj, Ci, bj, Mi, m0, m1); break;                                          \
        case 4: k16(4, FULL, t, Ai, Bj, Ci, bj, Mi, m0, m1); break;                                          \
        case 3: k16(3, FULL, t, Ai, Bj, Ci, bj, Mi, m0, m1); break;                                          \
        case 2: k16(2, FULL, t, Ai, Bj, Ci, bj, Mi, m0, m1); break;                                          \
        case 1: k16(1, FULL, t, Ai, Bj, Ci, bj, Mi, m0, m1); break;                                          \
        default: break;                                                                                      \
        }                                                                                                    \
    } while (0)

static TGT void gemm_avx2(int M, int N, const tile *t, const float *A, const float *B, float *C, const float *bias,
                          const float *mask) {
    /* column panels outermost: a K x 16 panel of B stays in L1 while all rows stream past */
    for (int j = 0; j < N; j += 16) {
        int nr = N - j < 16 ? N - j : 16;
        const float *Bj = B + j, *bj = bias ? bias + j : NULL, *mj = mask ? mask + j : NULL;
        float *Cj = C + j;
        int32_t lane[16];
        for (int q = 0; q < 16; q++) lane[q] = q < nr ? -1 : 0;
        __m256i m0 = _mm256_loadu_si256((const __m256i *)lane), m1 = _mm256_loadu_si256((const __m256i *)(lane + 8));
        if (nr <= 8) {
            int i = 0;
            for (; i + 12 <= M; i += 12)
                k8(12, t, A + (size_t)i * t->ra, Bj, Cj + (size_t)i * t->ldc, bj, mj ? mj + (size_t)i * t->ldm : NULL, m0);
            for (; i + 4 <= M; i += 4)
                k8(4, t, A + (size_t)i * t->ra, Bj, Cj + (size_t)i * t->ldc, bj, mj ? mj + (size_t)i * t->ldm : NULL, m0);
            for (; i < M; i++)
                k8(1, t, A + (size_t)i * t->ra, Bj, Cj + (size_t)i * t->ldc, bj, mj ? mj + (size_t)i * t->ldm : NULL, m0);
        } else if (nr == 16) {
            PANEL16(1);
        } else {
            PANEL16(0);
        }
    }
}
#endif

static atomic_int kern_mode = -1;   /* -1 unknown, 0 portable, 1 AVX2/FMA */

int sooc_nn_gemm_avx2(void) {
    int mode = atomic_load_explicit(&kern_mode, memory_order_relaxed);
    if (mode < 0) {
        mode = 0;
#ifdef NN_KERN_X86
        __builtin_cpu_init();
        mode = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#endif
        if (getenv("SOOC_NO_AVX2")) mode = 0;
        atomic_store_explicit(&kern_mode, mode, memory_order_relaxed);
    }
    return mode;
}

/* One GEMM on the kernel this CPU runs. */
static void gemm_run(int M, int N, const tile *t, const float *A, const float *B, float *C, const float *bias,
                     const float *mask) {
#ifdef NN_KERN_X86
    if (sooc_nn_gemm_avx2()) {
        gemm_avx2(M, N, t, A, B, C, bias, mask);
        return;
    }
#endif
    gemm_port(M, N, t, A, B, C, bias, mask);
}

int sooc_nn_gemm_set_kernel(int avx2) {
    int prev = sooc_nn_gemm_avx2(), can = 0;
#ifdef NN_KERN_X86
    can = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#endif
    atomic_store_explicit(&kern_mode, avx2 && can, memory_order_relaxed);
    return prev;
}

void sooc_nn_gemm(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                  const float *bias, int acc, int ep, const float *mask, int ldm) {
    if (M <= 0 || N <= 0) return;
    tile t = {K, lda, 1, ldb, ldc, ldm, acc ? 2 : bias ? 1 : 0, ep, 0, 1.0f};
    gemm_run(M, N, &t, A, B, C, bias, mask);
}

void sooc_nn_gemm_tn(int M, int N, int R, float alpha, const float *A, int lda, const float *B, int ldb, float *C,
                     int ldc) {
    if (M <= 0 || N <= 0 || R <= 0) return;
    /* A read in place down its columns (element (i, k) of A^T is A[k lda + i]),
     * R in chunks of TN_ROWS rows so that a chunk's rows of A and B stay in L1
     * while every register tile of C passes over them (64 x 64 x 256, AVX2, CPU
     * time: one pass over all R 95 GFLOP/s, chunks of 32-64 rows 104-106, 16
     * rows 94; a transposed copy of A cost more than it saved).
     * C += alpha (chunk sum) per chunk, chunks in order. */
    enum { TN_ROWS = 64 };
    for (int r0 = 0; r0 < R; r0 += TN_ROWS) {
        int n = R - r0 < TN_ROWS ? R - r0 : TN_ROWS;
        tile t = {n, 1, lda, ldb, ldc, 0, 0, SOOC_NN_EP_NONE, 1, alpha};
        gemm_run(M, N, &t, A + (size_t)r0 * lda, B + (size_t)r0 * ldb, C, NULL, NULL);
    }
}

void sooc_nn_gemm_nt(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                     int acc, int ep, const float *mask, int ldm) {
    if (M <= 0 || N <= 0) return;
    /* B^T panel: NT_K rows of K by 16 columns of N (4 KB on the stack); the
     * chain of a C element goes on through the chunks (init = C after the
     * first), so the chunking does not change its rounding. */
    enum { NT_K = 64 };
    float bt[NT_K * 16];
    for (int j0 = 0; j0 < N; j0 += 16) {
        int nr = N - j0 < 16 ? N - j0 : 16;
        if (K <= 0) {   /* C = 0 (or C) with the epilogue */
            tile t = {0, lda, 1, 16, ldc, ldm, acc ? 2 : 0, ep, 0, 1.0f};
            gemm_run(M, nr, &t, A, bt, C + j0, NULL, mask ? mask + j0 : NULL);
            continue;
        }
        for (int k0 = 0; k0 < K; k0 += NT_K) {
            int kc = K - k0 < NT_K ? K - k0 : NT_K, last = k0 + kc == K;
            for (int j = 0; j < nr; j++) {
                const float *bj = B + (size_t)(j0 + j) * ldb + k0;
                for (int k = 0; k < kc; k++) bt[k * 16 + j] = bj[k];
            }
            tile t = {kc, lda, 1, 16, ldc, ldm, k0 > 0 || acc ? 2 : 0, last ? ep : SOOC_NN_EP_NONE, 0, 1.0f};
            gemm_run(M, nr, &t, A + k0, bt, C + j0, NULL, last && mask ? mask + j0 : NULL);
        }
    }
}
