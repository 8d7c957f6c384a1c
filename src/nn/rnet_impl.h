/* Private helpers of the refinement-network kernels (rconv.c, rcell.c). */
#ifndef SOOC3D_NN_RNET_IMPL_H
#define SOOC3D_NN_RNET_IMPL_H
#include "nn_impl.h"
#include "sooc3d/nn_refine.h"

/* C[M x N] = (acc ? C : 0) + A[M x K] B[K x N], row-major with leading
 * dimensions; every C element one FMA chain over k = 0..K-1 in order (AVX2/FMA
 * kernel), or OpenBLAS when the CPU lacks AVX2/FMA or SOOC_NO_AVX2 is set. */
void sooc_nn_r_gemm(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                    int acc);
/* y[j] = elu(y[j] + bias) over n values (the Cephes-polynomial ELU of nn_refine.h). */
void sooc_nn_r_elu_bias(float *y, int64_t n, float bias);
float sooc_nn_r_elu1(float x);
#endif
