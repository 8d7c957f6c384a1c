/* Private helpers shared by the nn sources. */
#ifndef SOOC3D_NN_IMPL_H
#define SOOC3D_NN_IMPL_H
#include "nn/nn.h"
#include <cblas.h>
#include <math.h>
#undef I /* complex.h (pulled in by OpenBLAS) defines I; we use it as a size */
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#else
/* Without OpenMP the `#pragma omp` lines are simply ignored (llm.c style);
 * every loop is written so that its result does not depend on that. */
#pragma GCC diagnostic ignored "-Wunknown-pragmas"
#endif

/* Row-major C[M,N] = alpha op(A) op(B) + beta C, split into a FIXED number of
 * blocks along M or N (whichever is larger; never along K) that OpenMP
 * threads take; each block is a single-threaded OpenBLAS sgemm. The blocking
 * does not depend on the thread count, and no output element's K summation is
 * split, so results are bitwise identical for any thread count and with
 * OpenMP off. Avoids mixing OpenBLAS' own threads with OpenMP threads
 * (measured: oversubscription made the conv encoder 50x slower on a loaded
 * 2-core machine). */
void sooc_nn_sgemm(int transa, int transb, int M, int N, int K, float alpha, const float *A,
                   int lda, const float *B, int ldb, float beta, float *C, int ldc);

/* Minimum elements before an elementwise loop goes parallel. */
#define SOOC_NN_PAR_MIN 262144
/* Threshold for memory-bound loops with little work per element (copies):
 * below it a parallel region costs more than it saves, and on a loaded
 * machine every extra OpenMP barrier can cost a scheduler time slice. */
#define SOOC_NN_PAR_BIG 2097152

/* Logistic sigmoid, stable for both signs. */
static inline float sooc_nn_sigm(float x) {
    if (x >= 0.f) return 1.f / (1.f + expf(-x));
    float e = expf(x);
    return e / (1.f + e);
}

/* The activations fused into linear / conv / MLP layers (NONE, RELU, ELU,
 * SIGMOID, TANH); the callers validate the choice, anything else asserts. */
static inline float sooc_nn_act_apply(sooc_nn_act a, float v) {
    switch (a) {
    case SOOC_NN_ACT_NONE: return v;
    case SOOC_NN_ACT_RELU: return v > 0.f ? v : 0.f;
    case SOOC_NN_ACT_ELU: return v > 0.f ? v : expm1f(v);
    case SOOC_NN_ACT_SIGMOID: return sooc_nn_sigm(v);
    case SOOC_NN_ACT_TANH: return tanhf(v);
    default: SOOC_ASSERT(!"fused activation must be NONE/RELU/ELU/SIGMOID/TANH");
    }
    return v;
}

#endif