/* Bounded frame ring: single producer (capture), single consumer (mapping).
 * push never blocks; when full, the oldest frame is dropped and counted.
 * Frames move by swapping sooc_frame structs, so no pixel copies happen. */
#include "sooc3d/node.h"
#include "node/node_parts.h"

#include <pthread.h>
#include <string.h>
#include <time.h>

struct sooc_frame_ring {
    pthread_mutex_t mu;
    pthread_cond_t cv, cv_space;
    int cap, head, count, closed, blocking;
    sooc_frame *slot;
    int64_t *t_mono;
    uint64_t pushed, dropped;
};

sooc_status sooc_frame_ring_create(sooc_frame_ring **out, int capacity) {
    *out = NULL;
    if (capacity < 1) return sooc_seterr(SOOC_EINVAL, "frame ring: capacity %d < 1", capacity);
    sooc_frame_ring *r = sooc_calloc(1, sizeof *r);
    if (!r) return SOOC_ENOMEM;
    r->slot = sooc_calloc((size_t)capacity, sizeof *r->slot);
    r->t_mono = sooc_calloc((size_t)capacity, sizeof *r->t_mono);
    if (!r->slot || !r->t_mono) {
        sooc_free(r->slot);
        sooc_free(r->t_mono);
        sooc_free(r);
        return SOOC_ENOMEM;
    }
    r->cap = capacity;
    pthread_mutex_init(&r->mu, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&r->cv, &ca);
    pthread_cond_init(&r->cv_space, &ca);
    pthread_condattr_destroy(&ca);
    *out = r;
    return SOOC_OK;
}

void sooc_frame_ring_destroy(sooc_frame_ring *r) {
    if (!r) return;
    for (int i = 0; i < r->cap; i++) sooc_frame_free(&r->slot[i]);
    pthread_cond_destroy(&r->cv);
    pthread_cond_destroy(&r->cv_space);
    pthread_mutex_destroy(&r->mu);
    sooc_free(r->slot);
    sooc_free(r->t_mono);
    sooc_free(r);
}

static void swap_frames(sooc_frame *a, sooc_frame *b) {
    sooc_frame t = *a;
    *a = *b;
    *b = t;
}

void sooc_frame_ring_push(sooc_frame_ring *r, sooc_frame *f, int64_t t_mono_ns) {
    pthread_mutex_lock(&r->mu);
    while (r->blocking && !r->closed && r->count == r->cap) pthread_cond_wait(&r->cv_space, &r->mu);
    int idx;
    if (r->count == r->cap) {          /* full: overwrite the oldest */
        idx = r->head;
        r->head = (r->head + 1) % r->cap;
        r->dropped++;
    } else {
        idx = (r->head + r->count) % r->cap;
        r->count++;
    }
    swap_frames(&r->slot[idx], f);     /* f gets the dropped/spare buffers back */
    r->t_mono[idx] = t_mono_ns;
    r->pushed++;
    pthread_cond_signal(&r->cv);
    pthread_mutex_unlock(&r->mu);
}

sooc_status sooc_frame_ring_pop(sooc_frame_ring *r, sooc_frame *f, int64_t *t_mono_ns, int timeout_ms) {
    struct timespec dl;
    if (timeout_ms >= 0) {
        clock_gettime(CLOCK_MONOTONIC, &dl);
        dl.tv_sec += timeout_ms / 1000;
        dl.tv_nsec += (long)(timeout_ms % 1000) * 1000000L;
        if (dl.tv_nsec >= 1000000000L) { dl.tv_sec++; dl.tv_nsec -= 1000000000L; }
    }
    pthread_mutex_lock(&r->mu);
    while (r->count == 0 && !r->closed) {
        if (timeout_ms < 0) pthread_cond_wait(&r->cv, &r->mu);
        else if (pthread_cond_timedwait(&r->cv, &r->mu, &dl)) {
            if (r->count == 0) {
                pthread_mutex_unlock(&r->mu);
                return SOOC_ETIMEOUT;
            }
        }
    }
    if (r->count == 0) {
        pthread_mutex_unlock(&r->mu);
        return SOOC_EEOF;
    }
    int idx = r->head;
    r->head = (r->head + 1) % r->cap;
    r->count--;
    swap_frames(&r->slot[idx], f);
    if (t_mono_ns) *t_mono_ns = r->t_mono[idx];
    pthread_cond_signal(&r->cv_space);
    pthread_mutex_unlock(&r->mu);
    return SOOC_OK;
}

void sooc_frame_ring_close(sooc_frame_ring *r) {
    pthread_mutex_lock(&r->mu);
    r->closed = 1;
    pthread_cond_broadcast(&r->cv);
    pthread_cond_broadcast(&r->cv_space);
    pthread_mutex_unlock(&r->mu);
}

void sooc_frame_ring_set_blocking(sooc_frame_ring *r, int on) {
    pthread_mutex_lock(&r->mu);
    r->blocking = on;
    pthread_cond_broadcast(&r->cv_space);
    pthread_mutex_unlock(&r->mu);
}

void sooc_frame_ring_counts(sooc_frame_ring *r, uint64_t *pushed, uint64_t *dropped, int *fill) {
    pthread_mutex_lock(&r->mu);
    if (pushed) *pushed = r->pushed;
    if (dropped) *dropped = r->dropped;
    if (fill) *fill = r->count;
    pthread_mutex_unlock(&r->mu);
}
