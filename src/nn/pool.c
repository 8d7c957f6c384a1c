/* Task pool (nn/nn_kern.h).
 *
 * The model's inference passes (decode forward / backward without weight
 * gradients, aux inputs, refinement convs) run through a small pthread pool
 * instead of OpenMP parallel regions: tasks are claimed one at a time from a
 * counter tagged with the job's generation, and the caller waits only for
 * tasks a helper has claimed. On a loaded machine a helper that the OS has not
 * scheduled yet claims nothing, so the caller does not wait for it (an OpenMP
 * region ends with a barrier that every thread must reach). Which thread runs
 * a task never changes its result. The helpers are started once, at create,
 * and sleep on a condition variable between jobs. */
#include "nn/nn_kern.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

typedef struct pool_arg {
    struct sooc_nn_pool *p;
    int tid;
} pool_arg;

struct sooc_nn_pool {
    int nthr, nstarted, stop;
    pthread_t th[SOOC_NN_POOL_MAX];
    pool_arg arg[SOOC_NN_POOL_MAX];
    pthread_mutex_t mu;
    pthread_cond_t wake, fin;
    uint32_t gen;                 /* job generation (under mu)                        */
    sooc_nn_task_fn fn;           /* the job (under mu)                               */
    void *ctx;
    int n;
    _Atomic uint64_t claim;       /* gen << 32 | next unclaimed task                  */
    atomic_int done;              /* tasks of the current job finished                */
};

static int pool_claim(sooc_nn_pool *p, uint32_t gen, int n) {
    uint64_t c = atomic_load_explicit(&p->claim, memory_order_acquire);
    for (;;) {
        if ((uint32_t)(c >> 32) != gen || (int)(c & 0xffffffffu) >= n) return -1;
        if (atomic_compare_exchange_weak_explicit(&p->claim, &c, c + 1, memory_order_acq_rel, memory_order_acquire))
            return (int)(c & 0xffffffffu);
    }
}

static void *pool_helper(void *arg) {
    pool_arg *a = arg;
    sooc_nn_pool *p = a->p;
    uint32_t seen = 0;
    for (;;) {
        pthread_mutex_lock(&p->mu);
        while (!p->stop && p->gen == seen) pthread_cond_wait(&p->wake, &p->mu);
        if (p->stop) {
            pthread_mutex_unlock(&p->mu);
            return NULL;
        }
        seen = p->gen;
        sooc_nn_task_fn fn = p->fn;
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

void sooc_nn_pool_destroy(sooc_nn_pool *p) {
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
}

sooc_status sooc_nn_pool_create(sooc_nn_pool **out, int nthr) {
    *out = NULL;
    if (nthr < 1 || nthr > SOOC_NN_POOL_MAX)
        return sooc_seterr(SOOC_EINVAL, "nn pool: %d threads (1..%d)", nthr, SOOC_NN_POOL_MAX);
    sooc_nn_pool *p = sooc_calloc(1, sizeof *p);
    if (!p) return sooc_seterr(SOOC_ENOMEM, "nn pool: out of memory");
    if (pthread_mutex_init(&p->mu, NULL)) {
        sooc_free(p);
        return sooc_seterr(SOOC_ENOMEM, "nn pool: pthread_mutex_init failed");
    }
    if (pthread_cond_init(&p->wake, NULL) || pthread_cond_init(&p->fin, NULL)) {
        pthread_mutex_destroy(&p->mu);
        sooc_free(p);
        return sooc_seterr(SOOC_ENOMEM, "nn pool: pthread_cond_init failed");
    }
    atomic_init(&p->claim, 0);
    atomic_init(&p->done, 0);
    for (int i = 0; i < nthr - 1; i++) {
        p->arg[i].p = p;
        p->arg[i].tid = i + 1;
        if (pthread_create(&p->th[i], NULL, pool_helper, &p->arg[i])) break;   /* run with fewer */
        p->nstarted++;
    }
    p->nthr = nthr;
    *out = p;
    return SOOC_OK;
}

int sooc_nn_pool_threads(const sooc_nn_pool *p) { return p ? p->nstarted + 1 : 1; }

int sooc_nn_pool_size(const sooc_nn_pool *p) { return p ? p->nthr : 0; }

void sooc_nn_pool_run(sooc_nn_pool *p, int n, sooc_nn_task_fn fn, void *ctx) {
    if (!p || p->nstarted < 1 || n < 2) {
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
