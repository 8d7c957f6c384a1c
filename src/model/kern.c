/* Small row-major GEMM for the decoder MLPs and the refinement convs
 * (model_internal.h, mdl_gemm). The layers are narrow (N = 16..64 outputs,
 * K = 33..576), so OpenBLAS spends a good part of its time packing A and B
 * and in its beta pass; this kernel reads A and B in place (B rows are
 * contiguous in N, A elements are broadcast), starts from the bias, the
 * existing C or zero, and applies the epilogue (ReLU or a ReLU-backward mask)
 * on the registers before the single store.
 *
 * Every C element is accumulated as one FMA chain over k = 0..K-1 in order,
 * whatever the row or column blocking, so results do not depend on how rows
 * are split across threads. The AVX2/FMA kernel is selected at run time
 * (GCC/Clang on x86-64, CPUs with AVX2 and FMA); elsewhere OpenBLAS runs
 * instead (different rounding, also independent of the thread split). */
#include "model/model_internal.h"

#include <cblas.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

/* portable path: OpenBLAS, then the epilogue as a separate pass */
static void gemm_blas(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                      const float *bias, int acc, int ep, const float *mask, int ldm) {
    if (!acc && bias)
        for (int i = 0; i < M; i++) memcpy(C + (size_t)i * ldc, bias, (size_t)N * sizeof(float));
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, M, N, K, 1.0f, A, lda, B, ldb, acc || bias ? 1.0f : 0.0f,
                C, ldc);
    if (ep == MDL_EP_NONE) return;
    for (int i = 0; i < M; i++) {
        float *restrict c = C + (size_t)i * ldc;
        if (ep == MDL_EP_RELU)
            for (int j = 0; j < N; j++) c[j] = c[j] > 0 ? c[j] : 0;
        else
            for (int j = 0; j < N; j++) c[j] = mask[(size_t)i * ldm + j] > 0 ? c[j] : 0;
    }
}

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#define MDL_KERN_X86 1
#include <immintrin.h>

#define TGT __attribute__((target("avx2,fma")))
#define AI __attribute__((always_inline)) inline

/* MR rows x 16 columns (two vectors); m0/m1: column masks of the two vectors. */
static TGT AI void k16(int MR, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                       const float *bias, int acc, int ep, const float *mask, int ldm, __m256i m0, __m256i m1) {
    __m256 c0[6], c1[6];
#pragma GCC unroll 6
    for (int r = 0; r < MR; r++) {
        if (acc) {
            c0[r] = _mm256_maskload_ps(C + (size_t)r * ldc, m0);
            c1[r] = _mm256_maskload_ps(C + (size_t)r * ldc + 8, m1);
        } else if (bias) {
            c0[r] = _mm256_maskload_ps(bias, m0);
            c1[r] = _mm256_maskload_ps(bias + 8, m1);
        } else {
            c0[r] = _mm256_setzero_ps();
            c1[r] = _mm256_setzero_ps();
        }
    }
    for (int k = 0; k < K; k++) {
        const float *b = B + (size_t)k * ldb;
        __m256 b0 = _mm256_maskload_ps(b, m0), b1 = _mm256_maskload_ps(b + 8, m1);
#pragma GCC unroll 6
        for (int r = 0; r < MR; r++) {
            __m256 a = _mm256_broadcast_ss(A + (size_t)r * lda + k);
            c0[r] = _mm256_fmadd_ps(a, b0, c0[r]);
            c1[r] = _mm256_fmadd_ps(a, b1, c1[r]);
        }
    }
    const __m256 z = _mm256_setzero_ps();
#pragma GCC unroll 6
    for (int r = 0; r < MR; r++) {
        if (ep == MDL_EP_RELU) {
            c0[r] = _mm256_max_ps(c0[r], z);
            c1[r] = _mm256_max_ps(c1[r], z);
        } else if (ep == MDL_EP_MASK) {
            __m256 q0 = _mm256_maskload_ps(mask + (size_t)r * ldm, m0), q1 = _mm256_maskload_ps(mask + (size_t)r * ldm + 8, m1);
            c0[r] = _mm256_and_ps(c0[r], _mm256_cmp_ps(q0, z, _CMP_GT_OQ));
            c1[r] = _mm256_and_ps(c1[r], _mm256_cmp_ps(q1, z, _CMP_GT_OQ));
        }
        _mm256_maskstore_ps(C + (size_t)r * ldc, m0, c0[r]);
        _mm256_maskstore_ps(C + (size_t)r * ldc + 8, m1, c1[r]);
    }
}

/* Full 16-column panels without masks (the common case). */
static TGT AI void k16f(int MR, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                        const float *bias, int acc, int ep, const float *mask, int ldm) {
    __m256 c0[6], c1[6];
#pragma GCC unroll 6
    for (int r = 0; r < MR; r++) {
        if (acc) {
            c0[r] = _mm256_loadu_ps(C + (size_t)r * ldc);
            c1[r] = _mm256_loadu_ps(C + (size_t)r * ldc + 8);
        } else if (bias) {
            c0[r] = _mm256_loadu_ps(bias);
            c1[r] = _mm256_loadu_ps(bias + 8);
        } else {
            c0[r] = _mm256_setzero_ps();
            c1[r] = _mm256_setzero_ps();
        }
    }
    for (int k = 0; k < K; k++) {
        const float *b = B + (size_t)k * ldb;
        __m256 b0 = _mm256_loadu_ps(b), b1 = _mm256_loadu_ps(b + 8);
#pragma GCC unroll 6
        for (int r = 0; r < MR; r++) {
            __m256 a = _mm256_broadcast_ss(A + (size_t)r * lda + k);
            c0[r] = _mm256_fmadd_ps(a, b0, c0[r]);
            c1[r] = _mm256_fmadd_ps(a, b1, c1[r]);
        }
    }
    const __m256 z = _mm256_setzero_ps();
#pragma GCC unroll 6
    for (int r = 0; r < MR; r++) {
        if (ep == MDL_EP_RELU) {
            c0[r] = _mm256_max_ps(c0[r], z);
            c1[r] = _mm256_max_ps(c1[r], z);
        } else if (ep == MDL_EP_MASK) {
            __m256 q0 = _mm256_loadu_ps(mask + (size_t)r * ldm), q1 = _mm256_loadu_ps(mask + (size_t)r * ldm + 8);
            c0[r] = _mm256_and_ps(c0[r], _mm256_cmp_ps(q0, z, _CMP_GT_OQ));
            c1[r] = _mm256_and_ps(c1[r], _mm256_cmp_ps(q1, z, _CMP_GT_OQ));
        }
        _mm256_storeu_ps(C + (size_t)r * ldc, c0[r]);
        _mm256_storeu_ps(C + (size_t)r * ldc + 8, c1[r]);
    }
}

/* MR rows x up to 8 columns (one masked vector): narrow panels (the last columns of an
 * odd-width layer, the 2x2 outputs of the last conv). */
static TGT AI void k8(int MR, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                      const float *bias, int acc, int ep, const float *mask, int ldm, __m256i m0) {
    __m256 c0[12];
#pragma GCC unroll 12
    for (int r = 0; r < MR; r++)
        c0[r] = acc ? _mm256_maskload_ps(C + (size_t)r * ldc, m0) : bias ? _mm256_maskload_ps(bias, m0) : _mm256_setzero_ps();
    for (int k = 0; k < K; k++) {
        __m256 b0 = _mm256_maskload_ps(B + (size_t)k * ldb, m0);
#pragma GCC unroll 12
        for (int r = 0; r < MR; r++) c0[r] = _mm256_fmadd_ps(_mm256_broadcast_ss(A + (size_t)r * lda + k), b0, c0[r]);
    }
    const __m256 z = _mm256_setzero_ps();
#pragma GCC unroll 12
    for (int r = 0; r < MR; r++) {
        if (ep == MDL_EP_RELU) c0[r] = _mm256_max_ps(c0[r], z);
        else if (ep == MDL_EP_MASK)
            c0[r] = _mm256_and_ps(c0[r], _mm256_cmp_ps(_mm256_maskload_ps(mask + (size_t)r * ldm, m0), z, _CMP_GT_OQ));
        _mm256_maskstore_ps(C + (size_t)r * ldc, m0, c0[r]);
    }
}

static TGT void gemm_avx2(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                          const float *bias, int acc, int ep, const float *mask, int ldm) {
    /* column panels outermost: a K x 16 panel of B stays in L1 while all rows stream past */
    for (int j = 0; j < N; j += 16) {
        int nr = N - j < 16 ? N - j : 16;
        const float *Bj = B + j, *bj = bias ? bias + j : NULL, *mj = mask ? mask + j : NULL;
        float *Cj = C + j;
        if (nr <= 8) {
            int32_t lane[8];
            for (int t = 0; t < 8; t++) lane[t] = t < nr ? -1 : 0;
            __m256i m0 = _mm256_loadu_si256((const __m256i *)lane);
            int i = 0;
            for (; i + 12 <= M; i += 12)
                k8(12, K, A + (size_t)i * lda, lda, Bj, ldb, Cj + (size_t)i * ldc, ldc, bj, acc, ep,
                   mj ? mj + (size_t)i * ldm : NULL, ldm, m0);
            for (; i + 4 <= M; i += 4)
                k8(4, K, A + (size_t)i * lda, lda, Bj, ldb, Cj + (size_t)i * ldc, ldc, bj, acc, ep,
                   mj ? mj + (size_t)i * ldm : NULL, ldm, m0);
            for (; i < M; i++)
                k8(1, K, A + (size_t)i * lda, lda, Bj, ldb, Cj + (size_t)i * ldc, ldc, bj, acc, ep,
                   mj ? mj + (size_t)i * ldm : NULL, ldm, m0);
        } else if (nr == 16) {
            int i = 0;
            for (; i + 6 <= M; i += 6)
                k16f(6, K, A + (size_t)i * lda, lda, Bj, ldb, Cj + (size_t)i * ldc, ldc, bj, acc, ep,
                     mj ? mj + (size_t)i * ldm : NULL, ldm);
            const float *Ai = A + (size_t)i * lda, *Mi = mj ? mj + (size_t)i * ldm : NULL;
            float *Ci = Cj + (size_t)i * ldc;
            switch (M - i) {
            case 5: k16f(5, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm); break;
            case 4: k16f(4, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm); break;
            case 3: k16f(3, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm); break;
            case 2: k16f(2, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm); break;
            case 1: k16f(1, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm); break;
            default: break;
            }
        } else {
            int32_t lane[16];
            for (int t = 0; t < 16; t++) lane[t] = t < nr ? -1 : 0;
            __m256i m0 = _mm256_loadu_si256((const __m256i *)lane), m1 = _mm256_loadu_si256((const __m256i *)(lane + 8));
            int i = 0;
            for (; i + 6 <= M; i += 6)
                k16(6, K, A + (size_t)i * lda, lda, Bj, ldb, Cj + (size_t)i * ldc, ldc, bj, acc, ep,
                    mj ? mj + (size_t)i * ldm : NULL, ldm, m0, m1);
            const float *Ai = A + (size_t)i * lda, *Mi = mj ? mj + (size_t)i * ldm : NULL;
            float *Ci = Cj + (size_t)i * ldc;
            switch (M - i) {
            case 5: k16(5, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm, m0, m1); break;
            case 4: k16(4, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm, m0, m1); break;
            case 3: k16(3, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm, m0, m1); break;
            case 2: k16(2, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm, m0, m1); break;
            case 1: k16(1, K, Ai, lda, Bj, ldb, Ci, ldc, bj, acc, ep, Mi, ldm, m0, m1); break;
            default: break;
            }
        }
    }
}
#endif

static atomic_int kern_mode = -1;   /* -1 unknown, 0 portable, 1 AVX2/FMA */

int mdl_kern_avx2(void) {
    int mode = atomic_load_explicit(&kern_mode, memory_order_relaxed);
    if (mode < 0) {
        mode = 0;
#ifdef MDL_KERN_X86
        __builtin_cpu_init();
        mode = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#endif
        if (getenv("SOOC_NO_AVX2")) mode = 0;
        atomic_store_explicit(&kern_mode, mode, memory_order_relaxed);
    }
    return mode;
}

void mdl_gemm(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
              const float *bias, int acc, int ep, const float *mask, int ldm) {
    if (M <= 0 || N <= 0) return;
#ifdef MDL_KERN_X86
    if (mdl_kern_avx2()) {
        gemm_avx2(M, N, K, A, lda, B, ldb, C, ldc, bias, acc, ep, mask, ldm);
        return;
    }
#endif
    gemm_blas(M, N, K, A, lda, B, ldb, C, ldc, bias, acc, ep, mask, ldm);
}

/* ---------------------------------------------------------------- task pool
 *
 * The inference passes (decode forward / backward without weight gradients,
 * aux inputs, refinement convs) run through a small pthread pool instead of
 * OpenMP parallel regions: tasks are claimed one at a time from a counter
 * tagged with the job's generation, and the caller waits only for tasks a
 * helper has claimed. On a loaded machine a helper that the OS has not
 * scheduled yet claims nothing, so the caller does not wait for it (an
 * OpenMP region ends with a barrier that every thread must reach). Which
 * thread runs a task never changes its result. Serial without OpenMP
 * (SOOC_OPENMP=OFF), like the rest of the module. */
#define MDL_POOL_MAX 16

typedef struct mdl_pool_arg {
    struct mdl_pool *p;
    int tid;
} mdl_pool_arg;

struct mdl_pool {
    int nthr, nstarted, stop;
    pthread_t th[MDL_POOL_MAX];
    mdl_pool_arg arg[MDL_POOL_MAX];
    pthread_mutex_t mu;
    pthread_cond_t wake, fin;
    uint32_t gen;                 /* job generation (under mu)                        */
    mdl_task_fn fn;               /* the job (under mu)                               */
    void *ctx;
    int n;
    _Atomic uint64_t claim;       /* gen << 32 | next unclaimed task                  */
    atomic_int done;              /* tasks of the current job finished                */
};

static int pool_claim(struct mdl_pool *p, uint32_t gen, int n) {
    uint64_t c = atomic_load_explicit(&p->claim, memory_order_acquire);
    for (;;) {
        if ((uint32_t)(c >> 32) != gen || (int)(c & 0xffffffffu) >= n) return -1;
        if (atomic_compare_exchange_weak_explicit(&p->claim, &c, c + 1, memory_order_acq_rel, memory_order_acquire))
            return (int)(c & 0xffffffffu);
    }
}

static void *pool_helper(void *arg) {
    mdl_pool_arg *a = arg;
    struct mdl_pool *p = a->p;
    uint32_t seen = 0;
    for (;;) {
        pthread_mutex_lock(&p->mu);
        while (!p->stop && p->gen == seen) pthread_cond_wait(&p->wake, &p->mu);
        if (p->stop) {
            pthread_mutex_unlock(&p->mu);
            return NULL;
        }
        seen = p->gen;
        mdl_task_fn fn = p->fn;
        void *ctx = p->ctx;
        int n = p->n;
        pthread_mutex_unlock(&p->mu);
        int t;
        while ((t = pool_claim(p, seen, n)) >= 0) {
            fn(ctx, t, a->tid);
            if (atomic_fetch_add_explicit(&p->done, 1, memory_order_acq_rel) + 1 == n) {
                pthread_mutex_lock(&p->mu);
                pthread_cond_signal(&p->fin);
                pthread_mutex_unlock(&p->mu);
            }
        }
    }
}

void mdl_pool_free(sooc_model *m) {
    struct mdl_pool *p = m->pool;
    if (!p) return;
    pthread_mutex_lock(&p->mu);
    p->stop = 1;
    pthread_cond_broadcast(&p->wake);
    pthread_mutex_unlock(&p->mu);
    for (int i = 0; i < p->nstarted; i++) pthread_join(p->th[i], NULL);
    pthread_cond_destroy(&p->wake);
    pthread_cond_destroy(&p->fin);
    pthread_mutex_destroy(&p->mu);
    sooc_free(p);
    m->pool = NULL;
}

int mdl_par_threads(sooc_model *m) {
    int nt = 1;
#ifdef SOOC_HAVE_OPENMP
    nt = m->threads > 0 ? m->threads : omp_get_max_threads();
#endif
    if (nt > MDL_POOL_MAX) nt = MDL_POOL_MAX;
    if (nt < 2) return 1;
    if (m->pool && m->pool->nthr == nt) return nt;
    mdl_pool_free(m);
    struct mdl_pool *p = sooc_calloc(1, sizeof *p);
    if (!p) return 1;   /* serial */
    if (pthread_mutex_init(&p->mu, NULL)) {
        sooc_free(p);
        return 1;
    }
    pthread_cond_init(&p->wake, NULL);
    pthread_cond_init(&p->fin, NULL);
    atomic_init(&p->claim, 0);
    atomic_init(&p->done, 0);
    m->pool = p;
    for (int i = 0; i < nt - 1; i++) {
        p->arg[i].p = p;
        p->arg[i].tid = i + 1;
        if (pthread_create(&p->th[i], NULL, pool_helper, &p->arg[i])) break;
        p->nstarted++;
    }
    p->nthr = nt;
    return p->nstarted + 1;
}

void mdl_par_run(sooc_model *m, int n, mdl_task_fn fn, void *ctx) {
    struct mdl_pool *p = n > 1 && mdl_par_threads(m) > 1 ? m->pool : NULL;
    if (!p || p->nstarted < 1) {
        for (int t = 0; t < n; t++) fn(ctx, t, 0);
        return;
    }
    pthread_mutex_lock(&p->mu);
    uint32_t gen = ++p->gen;
    p->fn = fn, p->ctx = ctx, p->n = n;
    atomic_store_explicit(&p->done, 0, memory_order_relaxed);
    atomic_store_explicit(&p->claim, (uint64_t)gen << 32, memory_order_release);
    pthread_cond_broadcast(&p->wake);
    pthread_mutex_unlock(&p->mu);
    int t;
    while ((t = pool_claim(p, gen, n)) >= 0) {
        fn(ctx, t, 0);
        atomic_fetch_add_explicit(&p->done, 1, memory_order_acq_rel);
    }
    if (atomic_load_explicit(&p->done, memory_order_acquire) < n) {
        pthread_mutex_lock(&p->mu);
        while (atomic_load_explicit(&p->done, memory_order_acquire) < n) pthread_cond_wait(&p->fin, &p->mu);
        pthread_mutex_unlock(&p->mu);
    }
}
