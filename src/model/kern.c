/* The task pool of a runner's workspace on the engine's (src/nn/pool.c,
 * nn/nn_kern.h): made on first use with the model's m->threads threads
 * (OpenMP's default when 0; serial without OpenMP), remade when the thread
 * count changes. The GEMM wrappers (mdl_gemm, mdl_kern_avx2) are inline in
 * weights.h. Layer 0 (docs/model.md "Layers"). */
#include "model/weights.h"

#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

#ifdef MDL_PROFILE
double mdl_prof[MDL_PR_N];
#endif

void sooc_mdl_pool_free(sooc_model_ws *w) {
    sooc_nn_pool_destroy(w->pool);
    w->pool = NULL;
}

int sooc_mdl_par_threads(sooc_model_ws *w) {
    int nt = 1;
#ifdef SOOC_HAVE_OPENMP
    nt = w->m->threads > 0 ? w->m->threads : omp_get_max_threads();
#endif
    if (nt > SOOC_NN_POOL_MAX) nt = SOOC_NN_POOL_MAX;
    if (nt < 2) return 1;
    if (sooc_nn_pool_size(w->pool) == nt) return sooc_nn_pool_threads(w->pool);
    sooc_mdl_pool_free(w);
    if (sooc_nn_pool_create(&w->pool, nt)) return 1;   /* serial */
    return sooc_nn_pool_threads(w->pool);
}

void sooc_mdl_par_run(sooc_model_ws *w, int n, sooc_mdl_task_fn fn, void *ctx) {
    sooc_nn_pool_run(n > 1 && sooc_mdl_par_threads(w) > 1 ? w->pool : NULL, n, fn, ctx);
}
