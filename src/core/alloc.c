/* Counted, 64-byte aligned allocator with fault injection for tests.
 * Each block carries a 64-byte header that stores its size, so sooc_free can
 * keep the live-byte count exact. */
#include "sooc3d/core.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define HDR 64

static _Atomic uint64_t g_live, g_peak, g_nalloc, g_nfree;
static _Atomic uint64_t g_fault_ok, g_fault_fail;
static _Atomic int g_fault_on;

void sooc_alloc_fault_inject(uint64_t n_ok, uint64_t n_fail) {
    atomic_store(&g_fault_ok, n_ok);
    atomic_store(&g_fault_fail, n_fail);
    atomic_store(&g_fault_on, (n_ok || n_fail) ? 1 : 0);
}

static int fault_now(void) {
    if (!atomic_load(&g_fault_on)) return 0;
    uint64_t ok = atomic_load(&g_fault_ok);
    while (ok > 0) {
        if (atomic_compare_exchange_weak(&g_fault_ok, &ok, ok - 1)) return 0;
    }
    uint64_t f = atomic_load(&g_fault_fail);
    while (f > 0) {
        if (atomic_compare_exchange_weak(&g_fault_fail, &f, f - 1)) return 1;
    }
    atomic_store(&g_fault_on, 0);
    return 0;
}

void *sooc_malloc(size_t n) {
    if (n > SIZE_MAX - HDR || fault_now()) {
        sooc_seterr(SOOC_ENOMEM, "out of memory allocating %zu bytes", n);
        return NULL;
    }
    void *raw = NULL;
    if (posix_memalign(&raw, 64, n + HDR) != 0) {
        sooc_seterr(SOOC_ENOMEM, "out of memory allocating %zu bytes", n);
        return NULL;
    }
    *(size_t *)raw = n;
    uint64_t live = atomic_fetch_add(&g_live, n) + n;
    uint64_t peak = atomic_load(&g_peak);
    while (live > peak && !atomic_compare_exchange_weak(&g_peak, &peak, live)) {}
    atomic_fetch_add(&g_nalloc, 1);
    return (char *)raw + HDR;
}

void *sooc_calloc(size_t count, size_t size) {
    if (size && count > SIZE_MAX / size) {
        sooc_seterr(SOOC_ENOMEM, "allocation size overflow (%zu x %zu)", count, size);
        return NULL;
    }
    void *p = sooc_malloc(count * size);
    if (p) memset(p, 0, count * size);
    return p;
}

void sooc_free(void *p) {
    if (!p) return;
    void *raw = (char *)p - HDR;
    atomic_fetch_sub(&g_live, *(size_t *)raw);
    atomic_fetch_add(&g_nfree, 1);
    free(raw);
}

void *sooc_realloc(void *p, size_t n) {
    if (!p) return sooc_malloc(n);
    size_t old = *(size_t *)((char *)p - HDR);
    void *q = sooc_malloc(n);
    if (!q) return NULL;
    memcpy(q, p, old < n ? old : n);
    sooc_free(p);
    return q;
}

char *sooc_strdup(const char *s) {
    size_t n = strlen(s) + 1;
    char *d = sooc_malloc(n);
    if (d) memcpy(d, s, n);
    return d;
}

void sooc_alloc_get_stats(sooc_alloc_stats *out) {
    out->live_bytes = atomic_load(&g_live);
    out->peak_bytes = atomic_load(&g_peak);
    out->n_alloc = atomic_load(&g_nalloc);
    out->n_free = atomic_load(&g_nfree);
}
