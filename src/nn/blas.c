/* BLAS thread control. */
#include "nn_impl.h"

/* OpenBLAS extensions (declared in OpenBLAS's cblas.h). */
int sooc_nn_blas_set_threads(int n) {
    int prev = openblas_get_num_threads();
    if (n >= 1 && n != prev) openblas_set_num_threads(n);
    return prev;
}
