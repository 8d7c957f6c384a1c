/* The tracking thread (include/sooc3d/slam.h "tracking thread"): pops frames
 * from the source, tracks them and queues the tracked ones for the mapper,
 * never waiting for it. */
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "slam/slam_impl.h"

struct sooc_slam_tracker {
    sooc_slam *slam;
    sooc_slam_source_fn pop;
    void *ctx;
    pthread_t thread;
    int started;
    atomic_int stop;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int cap, head, count, eof;
    sooc_status error;
    char errmsg[512];
    sooc_frame *slot;
    int64_t *t_mono;
    sooc_frame work;
    sooc_slam_tracker_stats st;
    double ms_sum;
    uint64_t version;              /* graph version of chg */
    sooc_slam_kf_change *chg;
    size_t n_chg, cap_chg;
};

static void swap_frames(sooc_frame *a, sooc_frame *b) {
    sooc_frame t = *a;
    *a = *b;
    *b = t;
}

/* under t->mu: when the graph moved, keep its changes for the mapping side */
static void keep_changes(sooc_slam_tracker *t) {
    uint64_t v = sooc_slam_graph_version(t->slam);
    if (v == t->version) return;
    size_t nc = 0;
    sooc_slam_last_changes(t->slam, NULL, 0, &nc);
    if (nc > t->cap_chg) {
        sooc_free(t->chg);
        t->chg = sooc_malloc(nc * sizeof *t->chg);
        t->cap_chg = t->chg ? nc : 0;
    }
    t->n_chg = t->chg ? nc : 0;
    if (t->chg) sooc_slam_last_changes(t->slam, t->chg, t->cap_chg, &nc);
    t->version = v;
}

static void *tracker_main(void *arg) {
    sooc_slam_tracker *t = arg;
    while (!atomic_load(&t->stop)) {
        int64_t tm = 0;
        sooc_status st = t->pop(t->ctx, &t->work, &tm, 100);
        if (st == SOOC_ETIMEOUT) continue;
        /* the last keyframes' loop candidates, before the end is told */
        if (st == SOOC_EEOF && sooc_slam_flush(t->slam, NULL))
            sooc_log(SOOC_LOG_WARN, "tracking: loop closure at the end of the stream: %s", sooc_errmsg());
        pthread_mutex_lock(&t->mu);
        if (st == SOOC_EEOF || st) {
            if (st == SOOC_EEOF) {
                sooc_slam_stats ss;
                sooc_slam_get_stats(t->slam, &ss);
                keep_changes(t);
                t->st.loops = ss.loops;
            } else {
                t->error = st;
                snprintf(t->errmsg, sizeof t->errmsg, "%s", sooc_errmsg());
            }
            t->eof = 1;
            pthread_cond_broadcast(&t->cv);
            pthread_mutex_unlock(&t->mu);
            break;
        }
        t->st.frames_in++;
        pthread_mutex_unlock(&t->mu);
        sooc_slam_result r;
        st = sooc_slam_track(t->slam, &t->work, &r);
        sooc_slam_stats ss;
        sooc_slam_get_stats(t->slam, &ss);
        pthread_mutex_lock(&t->mu);
        keep_changes(t);
        t->st.keyframes = ss.keyframes;
        t->st.loops = ss.loops;
        t->st.relocalised = ss.relocalised;
        if (st) {   /* a bad frame: counted, the stream goes on */
            t->st.errors++;
            sooc_log(SOOC_LOG_WARN, "tracking: frame %lld refused: %s", (long long)t->work.index, sooc_errmsg());
            pthread_mutex_unlock(&t->mu);
            continue;
        }
        t->ms_sum += r.ms;
        if (r.ms > t->st.ms_track_max) t->st.ms_track_max = r.ms;
        int64_t n = t->st.tracked + t->st.untracked_failed + t->st.untracked_lost + 1;
        t->st.ms_track_mean = t->ms_sum / (double)n;
        if (r.state == SOOC_SLAM_FAILED) t->st.untracked_failed++;
        else if (r.state == SOOC_SLAM_LOST) t->st.untracked_lost++;
        else {
            t->st.tracked++;
            t->work.has_pose = 1;
            memcpy(t->work.T_wc, r.T_wc, sizeof r.T_wc);
            int idx;
            if (t->count == t->cap) {   /* the consumer is behind: drop the oldest */
                idx = t->head;
                t->head = (t->head + 1) % t->cap;
                t->count--;
                t->st.dropped_queue_full++;
            }
            idx = (t->head + t->count) % t->cap;
            swap_frames(&t->slot[idx], &t->work);
            t->t_mono[idx] = tm;
            t->count++;
            pthread_cond_signal(&t->cv);
        }
        pthread_mutex_unlock(&t->mu);
    }
    pthread_mutex_lock(&t->mu);
    t->eof = 1;
    pthread_cond_broadcast(&t->cv);
    pthread_mutex_unlock(&t->mu);
    return NULL;
}

sooc_status sooc_slam_tracker_start(sooc_slam_tracker **out, sooc_slam *slam, sooc_slam_source_fn pop, void *ctx,
                                    int queue_capacity) {
    *out = NULL;
    if (!slam || !pop || queue_capacity < 1)
        return sooc_seterr(SOOC_EINVAL, "tracking: needs a tracker, a source and a queue capacity >= 1");
    sooc_slam_tracker *t = sooc_calloc(1, sizeof *t);
    if (!t) return sooc_seterr(SOOC_ENOMEM, "tracking: out of memory");
    t->slot = sooc_calloc((size_t)queue_capacity, sizeof *t->slot);
    t->t_mono = sooc_calloc((size_t)queue_capacity, sizeof *t->t_mono);
    if (!t->slot || !t->t_mono) {
        sooc_free(t->slot);
        sooc_free(t->t_mono);
        sooc_free(t);
        return sooc_seterr(SOOC_ENOMEM, "tracking: out of memory");
    }
    t->cap = queue_capacity;
    t->slam = slam;
    t->pop = pop;
    t->ctx = ctx;
    pthread_mutex_init(&t->mu, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&t->cv, &ca);
    pthread_condattr_destroy(&ca);
    if (pthread_create(&t->thread, NULL, tracker_main, t)) {
        t->slam = NULL;   /* the caller keeps it */
        sooc_slam_tracker_destroy(t);
        return sooc_seterr(SOOC_ERR, "tracking: cannot start the thread");
    }
    t->started = 1;
    *out = t;
    return SOOC_OK;
}

sooc_status sooc_slam_tracker_pop(sooc_slam_tracker *t, sooc_frame *f, int64_t *t_mono_ns, int timeout_ms) {
    struct timespec dl;
    if (timeout_ms >= 0) {
        clock_gettime(CLOCK_MONOTONIC, &dl);
        dl.tv_sec += timeout_ms / 1000;
        dl.tv_nsec += (long)(timeout_ms % 1000) * 1000000L;
        if (dl.tv_nsec >= 1000000000L) {
            dl.tv_sec++;
            dl.tv_nsec -= 1000000000L;
        }
    }
    pthread_mutex_lock(&t->mu);
    while (t->count == 0 && !t->eof) {
        if (timeout_ms < 0) pthread_cond_wait(&t->cv, &t->mu);
        else if (pthread_cond_timedwait(&t->cv, &t->mu, &dl) && t->count == 0) {
            pthread_mutex_unlock(&t->mu);
            return SOOC_ETIMEOUT;
        }
    }
    if (t->count == 0) {
        sooc_status e = t->error;
        if (e) sooc_seterr(e, "tracking: %s", t->errmsg);
        pthread_mutex_unlock(&t->mu);
        return e ? e : SOOC_EEOF;
    }
    int idx = t->head;
    t->head = (t->head + 1) % t->cap;
    t->count--;
    swap_frames(&t->slot[idx], f);
    if (t_mono_ns) *t_mono_ns = t->t_mono[idx];
    pthread_mutex_unlock(&t->mu);
    return SOOC_OK;
}

void sooc_slam_tracker_get_stats(sooc_slam_tracker *t, sooc_slam_tracker_stats *st) {
    pthread_mutex_lock(&t->mu);
    *st = t->st;
    pthread_mutex_unlock(&t->mu);
}

sooc_status sooc_slam_tracker_changes(sooc_slam_tracker *t, uint64_t *version, sooc_slam_kf_change *out, size_t cap,
                                      size_t *n) {
    pthread_mutex_lock(&t->mu);
    *version = t->version;
    *n = t->n_chg;
    if (out) memcpy(out, t->chg, (cap < t->n_chg ? cap : t->n_chg) * sizeof *out);
    pthread_mutex_unlock(&t->mu);
    return SOOC_OK;
}

size_t sooc_slam_tracker_stats_format(const sooc_slam_tracker_stats *s, char *buf, size_t cap) {
    int n = snprintf(buf, cap,
                     "tracking: %lld in, %lld tracked, %lld failed, %lld lost, %lld dropped (queue full), %lld refused, "
                     "%lld keyframes, %lld loops, %lld relocalised, %.1f ms mean, %.1f ms max",
                     (long long)s->frames_in, (long long)s->tracked, (long long)s->untracked_failed,
                     (long long)s->untracked_lost, (long long)s->dropped_queue_full, (long long)s->errors,
                     (long long)s->keyframes, (long long)s->loops, (long long)s->relocalised, s->ms_track_mean,
                     s->ms_track_max);
    return n < 0 ? 0 : (size_t)n;
}

void sooc_slam_tracker_destroy(sooc_slam_tracker *t) {
    if (!t) return;
    atomic_store(&t->stop, 1);
    if (t->started) pthread_join(t->thread, NULL);
    for (int i = 0; i < t->cap; i++) sooc_frame_free(&t->slot[i]);
    sooc_frame_free(&t->work);
    sooc_free(t->slot);
    sooc_free(t->t_mono);
    sooc_free(t->chg);
    pthread_mutex_destroy(&t->mu);
    pthread_cond_destroy(&t->cv);
    sooc_slam_destroy(t->slam);
    sooc_free(t);
}
