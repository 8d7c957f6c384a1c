/* BLAS thread control. */
#include "nn_impl.h"

/* OpenBLAS extensions (declared in OpenBLAS's cblas.h). */
int sooc_nn_blas_set_threads(int n) {
    int prev = openblas_get_num_threads();
    if (n >= 1 && n != prev) openblas_set_num_threads(n);
    return prev;
}

/* Put OpenBLAS in single-thread mode (process-global; all nn parallelism is
 * OpenMP). Measured: restoring OpenBLAS' threads after every call left its
 * workers spinning against the OpenMP threads, making the conv encoder up to
 * 50x slower on a loaded machine. */
static void sooc_nn_blas_single(void) {
    if (openblas_get_num_threads() != 1) openblas_set_num_threads(1);
}

#define SGEMM_BLOCKS 8
#define SGEMM_MIN_FLOPS 64.0e6 /* below this (~1 ms single-thread): one call, no threading */

void sooc_nn_sgemm(int transa, int transb, int M, int N, int K, float alpha, const float *A,
                   int lda, const float *B, int ldb, float beta, float *C, int ldc) {
    if (M <= 0 || N <= 0) return;
    enum CBLAS_TRANSPOSE ta = transa ? CblasTrans : CblasNoTrans;
    enum CBLAS_TRANSPOSE tb = transb ? CblasTrans : CblasNoTrans;
    sooc_nn_blas_single();
    double flops = 2.0 * M * (double)N * K;
    int split_m = M >= N;
    int dim = split_m ? M : N;
    int nb = flops < SGEMM_MIN_FLOPS ? 1 : SGEMM_BLOCKS;
    if (nb > (dim + 15) / 16) nb = (dim + 15) / 16;
    if (nb < 1) nb = 1;
#pragma omp parallel for schedule(static) if (nb > 1)
    for (int b = 0; b < nb; b++) {
        int lo = (int)((int64_t)dim * b / nb), hi = (int)((int64_t)dim * (b + 1) / nb);
        if (hi <= lo) continue;
        if (split_m) {
            /* rows lo..hi of op(A) and C */
            const float *Ab = transa ? A + lo : A + (int64_t)lo * lda;
            cblas_sgemm(CblasRowMajor, ta, tb, hi - lo, N, K, alpha, Ab, lda, B, ldb, beta,
                        C + (int64_t)lo * ldc, ldc);
        } else {
            /* columns lo..hi of op(B) and C */
            const float *Bb = transb ? B + (int64_t)lo * ldb : B + lo;
            cblas_sgemm(CblasRowMajor, ta, tb, M, hi - lo, K, alpha, A, lda, Bb, ldb, beta,
                        C + lo, ldc);
        }
    }
}
