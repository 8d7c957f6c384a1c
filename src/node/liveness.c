/* Live sources under faults (docs/node.md "Faults"): a sensor that fails is
 * reopened with backoff (capture thread); a pose source that goes silent and
 * frame stamps that jump are named once (mapping thread). */
#include "node/node_impl.h"

#include <time.h>

/* Sleep s seconds in slices that a stop request cuts short; 1 if stopped. */
static int sleep_or_stop(sooc_node *n, double s) {
    double t_end = sooc_seconds() + s;
    while (!atomic_load(&n->stop)) {
        double left = t_end - sooc_seconds();
        if (left <= 0) return 0;
        if (left > 0.05) left = 0.05;
        struct timespec ts = {0, (long)(left * 1e9)};
        nanosleep(&ts, NULL);
    }
    return 1;
}

static void sensor_state(sooc_node *n, int down, int back) {
    pthread_mutex_lock(&n->mu);
    n->st.sensor_down = down;
    if (down) n->st.sensor_lost++;
    if (back) n->st.sensor_reconnects++;
    pthread_mutex_unlock(&n->mu);
}

sooc_status sooc__node_reconnect(sooc_node *n, sooc_status st) {
    if (!n->src.reopen || n->cfg.reconnect_s <= 0 || st == SOOC_ENOMEM || atomic_load(&n->stop)) return st;
    char why[512];
    snprintf(why, sizeof why, "%s", sooc_errmsg());
    double delay = n->cfg.reconnect_s, cap = n->cfg.reconnect_max_s > delay ? n->cfg.reconnect_max_s : delay;
    double t0 = sooc_seconds();
    sooc_log(SOOC_LOG_WARN,
             "node: sensor lost: %s. Reopening it in %.3g s, backing off to %.3g s; the map and the table stay, "
             "mapping goes on when frames return",
             why, delay, cap);
    sensor_state(n, 1, 0);
    char last[512] = "";
    for (int tries = 1;; tries++) {
        if (sleep_or_stop(n, delay)) return SOOC_EINTERRUPTED;   /* stopped while it was lost: a clean end */
        sooc_status s2 = n->src.reopen(n->src.ctx);
        if (!s2) {
            sooc_log(SOOC_LOG_WARN, "node: sensor back after %d attempt%s over %.1f s: frames go on into the same map",
                     tries, tries > 1 ? "s" : "", sooc_seconds() - t0);
            sensor_state(n, 0, 1);
            return SOOC_OK;
        }
        if (strcmp(last, sooc_errmsg())) {   /* a new reason is said once */
            snprintf(last, sizeof last, "%s", sooc_errmsg());
            sooc_log(tries == 1 ? SOOC_LOG_INFO : SOOC_LOG_WARN, "node: sensor still lost (attempt %d): %s", tries,
                     last);
        }
        sooc_clearerr();
        delay = delay * 2 < cap ? delay * 2 : cap;
    }
}

void sooc__node_pose_seen(sooc_node *n, const sooc_frame *f, int found) {
    if (found) {
        if (n->pose_silent)
            sooc_log(SOOC_LOG_WARN, "node: poses back at frame %lld after %llu frames without (%.1f s): mapping goes on",
                     (long long)f->index, (unsigned long long)n->pose_miss, (double)(f->t_ns - n->pose_miss_t0) * 1e-9);
        n->pose_miss = 0;
        n->pose_silent = 0;
        return;
    }
    if (!n->pose_miss++) n->pose_miss_t0 = f->t_ns;
    if (!n->pose_silent && n->pose_miss >= 2 &&
        (double)(f->t_ns - n->pose_miss_t0) * 1e-9 >= SOOC_NODE_POSE_SILENT_S) {
        n->pose_silent = 1;
        pthread_mutex_lock(&n->mu);
        n->st.pose_gaps++;
        pthread_mutex_unlock(&n->mu);
        sooc_log(SOOC_LOG_WARN,
                 "node: no pose from %s for %llu frames (%.1f s, since frame stamp %lld ns): they are counted "
                 "no_pose and not mapped until poses return",
                 n->cfg.pose_path[0] ? n->cfg.pose_path : "the pose source", (unsigned long long)n->pose_miss,
                 (double)(f->t_ns - n->pose_miss_t0) * 1e-9, (long long)n->pose_miss_t0);
    }
}

void sooc__node_time_check(sooc_node *n, const sooc_frame *f) {
    int64_t prev = n->t_prev_ns;
    int had = n->have_t_prev;
    n->t_prev_ns = f->t_ns;
    n->have_t_prev = 1;
    if (!had) return;
    double dt = (double)(f->t_ns - prev) * 1e-9;
    if (dt >= 0 && dt < n->cfg.time_jump_s) return;
    pthread_mutex_lock(&n->mu);
    n->st.time_jumps++;
    pthread_mutex_unlock(&n->mu);
    sooc_log(SOOC_LOG_WARN,
             "node: frame %lld: the sensor clock jumped %s by %.3f s (stamp %lld ns after %lld ns); the keyframe "
             "rule's time now counts from this frame",
             (long long)f->index, dt < 0 ? "back" : "forward", dt < 0 ? -dt : dt, (long long)f->t_ns, (long long)prev);
    /* the time rule measures from the new clock: neither stalled by a clock
     * that went back nor triggered by the jump itself */
    if (n->kf.have_last) n->kf.t_last_ns = f->t_ns;
}
