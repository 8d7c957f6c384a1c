/* Broken input frames (docs/node.md "Faults"): skipped, counted by reason
 * and named, or the end of the run under pipeline.strict; and the stats line
 * that shows them. */
#include "node/node_impl.h"

/* Count one broken frame (by reason) and name it in one log line. Either
 * thread. Returns the broken frames so far and the good ones read. */
static uint64_t count_skip(sooc_node *n, sooc_frame_fault why, const char *msg, uint64_t *good) {
    pthread_mutex_lock(&n->mu);
    uint64_t k = ++n->st.frames_skipped;
    n->st.skipped_by[why]++;
    *good = n->st.frames_in;
    pthread_mutex_unlock(&n->mu);
    sooc_log(SOOC_LOG_WARN, "node: frame skipped (%s): %s", sooc_frame_fault_name(why), msg);
    return k;
}

/* A read that failed on one broken frame the source has passed: skipped and
 * counted (SOOC_OK), unless pipeline.strict, or the source never gave a good
 * frame in skip_limit tries (a looped replay of broken frames). Any other
 * failure is returned as it is. */
sooc_status sooc__node_capture_skip(sooc_node *n, sooc_status st) {
    sooc_frame_fault why = n->src.frame_fault ? n->src.frame_fault(n->src.ctx) : SOOC_FRAME_FAULT_NONE;
    if (why <= SOOC_FRAME_FAULT_NONE || why >= SOOC_FRAME_FAULT_COUNT || st == SOOC_ENOMEM) return st;
    if (n->cfg.strict)
        return sooc_adderr(st, "broken frame (%s; pipeline.strict stops here)", sooc_frame_fault_name(why));
    snprintf(n->last_skip, sizeof n->last_skip, "%s", sooc_errmsg());
    uint64_t good = 0, k = count_skip(n, why, n->last_skip, &good);
    if (!good && n->skip_limit && k >= n->skip_limit)
        return sooc_seterr(SOOC_EFORMAT, "none of the %llu frames of the recording could be read (the last: %s)",
                           (unsigned long long)k, n->last_skip);
    sooc_clearerr();
    return SOOC_OK;
}

/* A frame whose size the calibration cannot describe (another aspect ratio):
 * skipped as a broken frame (size), or the end of the run under
 * pipeline.strict. Returns 1 when the frame is not to be mapped. */
int sooc__node_frame_size_skip(sooc_node *n, const sooc_frame *f, sooc_status *result) {
    if (!n->have_calib || (long)n->Kc.width * f->height == (long)n->Kc.height * f->width) return 0;
    if (n->cfg.strict) {
        *result = sooc_seterr(SOOC_EINVAL, "%s: calib is for %dx%d but frame %lld is %dx%d (pipeline.strict stops here)",
                              n->cfg.calib_path, n->Kc.width, n->Kc.height, (long long)f->index, f->width, f->height);
        return 1;
    }
    char msg[SOOC_NODE_PATH_MAX + 96];
    snprintf(msg, sizeof msg, "%s: calib is for %dx%d but frame %lld is %dx%d", n->cfg.calib_path, n->Kc.width,
             n->Kc.height, (long long)f->index, f->width, f->height);
    uint64_t good;
    count_skip(n, SOOC_FRAME_FAULT_SIZE, msg, &good);
    n->map_skips++;
    return 1;
}

/* Append text at buf[k] (snprintf rules: k counts what did not fit too). */
static size_t append(char *buf, size_t cap, size_t k, const char *text) {
    size_t m = strlen(text);
    if (buf && k < cap) snprintf(buf + k, cap - k, "%s", text);
    return k + m;
}

size_t sooc_node_stats_format(const sooc_node_stats *s, char *buf, size_t cap) {
    int w = snprintf(buf, cap,
                     "frames %llu dropped %llu no_pose %llu (untracked %llu) keyframes %llu (%.2f/s) objects %llu "
                     "update p50 %.1f ms p99 %.1f ms capture->table p50 %.1f ms p99 %.1f ms "
                     "publish p50 %.2f ms p99 %.2f ms",
                     (unsigned long long)s->frames_in, (unsigned long long)s->frames_dropped,
                     (unsigned long long)s->frames_no_pose, (unsigned long long)s->frames_untracked,
                     (unsigned long long)s->keyframes,
                     s->elapsed_s > 0 ? (double)s->keyframes / s->elapsed_s : 0.0,
                     (unsigned long long)s->n_objects, s->update_p50_ms, s->update_p99_ms, s->c2t_p50_ms,
                     s->c2t_p99_ms, s->publish_p50_ms, s->publish_p99_ms);
    size_t k = w > 0 ? (size_t)w : 0;
    char t[320];
    if (s->frames_skipped) {   /* broken frames, by reason */
        int m = snprintf(t, sizeof t, " skipped %llu (", (unsigned long long)s->frames_skipped);
        for (int r = 1, first = 1; r < SOOC_FRAME_FAULT_COUNT && m > 0 && (size_t)m < sizeof t; r++) {
            if (!s->skipped_by[r]) continue;
            m += snprintf(t + m, sizeof t - (size_t)m, "%s%s %llu", first ? "" : ", ",
                          sooc_frame_fault_name((sooc_frame_fault)r), (unsigned long long)s->skipped_by[r]);
            first = 0;
        }
        if (m > 0 && (size_t)m < sizeof t) snprintf(t + m, sizeof t - (size_t)m, ")");
        k = append(buf, cap, k, t);
    }
    if (s->sensor_lost || s->pose_gaps || s->time_jumps) {   /* live sources */
        snprintf(t, sizeof t, " sensor lost %llu (back %llu%s) pose gaps %llu clock jumps %llu",
                 (unsigned long long)s->sensor_lost, (unsigned long long)s->sensor_reconnects,
                 s->sensor_down ? ", down now" : "", (unsigned long long)s->pose_gaps, (unsigned long long)s->time_jumps);
        k = append(buf, cap, k, t);
    }
    if (s->floor_switches) {
        snprintf(t, sizeof t, " floor switches %llu", (unsigned long long)s->floor_switches);
        k = append(buf, cap, k, t);
    }
    if (s->store_state == SOOC_NODE_STORE_FAILING || s->store_failures) {
        snprintf(t, sizeof t, " store %s: %llu objects %llu keyframes pending, %llu failed commits, %llu recoveries",
                 s->store_state == SOOC_NODE_STORE_FAILING ? "FAILING" : "ok", (unsigned long long)s->store_pending,
                 (unsigned long long)s->store_pending_kf, (unsigned long long)s->store_failures,
                 (unsigned long long)s->store_recoveries);
        k = append(buf, cap, k, t);
    }
    return k;
}
