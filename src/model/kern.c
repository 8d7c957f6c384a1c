/* The model's task pool on the engine's (src/nn/pool.c, sooc3d/nn_kern.h):
 * made on first use with m->threads threads (OpenMP's default when 0; serial
 * without OpenMP), remade when the thread count changes. The GEMM wrappers
 * (mdl_gemm, mdl_kern_avx2) are inline in model_internal.h. */
#include "model/model_internal.h"

#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

void mdl_pool_free(sooc_model *m) {
    sooc_nn_pool_destroy(m->pool);
    m->pool = NULL;
}

int mdl_par_threads(sooc_model *m) {
    int nt = 1;
#ifdef SOOC_HAVE_OPENMP
    nt = m->threads > 0 ? m->threads : omp_get_max_threads();
#endif
    if (nt > SOOC_NN_POOL_MAX) nt = SOOC_NN_POOL_MAX;
    if (nt < 2) return 1;
    if (sooc_nn_pool_size(m->pool) == nt) return sooc_nn_pool_threads(m->pool);
    mdl_pool_free(m);
    sooc_nn_blas_single_once();   /* the pool's threads split rows; BLAS runs serially inside */
    if (sooc_nn_pool_create(&m->pool, nt)) return 1;   /* serial */
    return sooc_nn_pool_threads(m->pool);
}

void mdl_par_run(sooc_model *m, int n, mdl_task_fn fn, void *ctx) {
    sooc_nn_pool_run(n > 1 && mdl_par_threads(m) > 1 ? m->pool : NULL, n, fn, ctx);
}
