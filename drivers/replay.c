/* Replay driver: recorded sequences at recorded speed or as fast as possible,
 * with loop and start/stop times.
 *
 * Frames come from the data module's sequence readers (sooc3d/frame.h, every
 * format it reads, named by sooc_seq_format_parse) and from ROS bags and MCAP
 * files through the logs module (docs/logs.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers_internal.h"
#include "sooc3d/frame.h"

#include "sooc3d/core.h"
#include "sooc3d/log.h"

typedef struct replay {
    sooc_seq *seq;
    int64_t count;            /* frames in the sequence */
    int64_t i0, i1;           /* [i0, i1) frames between start and stop */
    int64_t next;             /* next frame index within the sequence */
    int64_t pass;             /* loop pass */
    int64_t pass_shift_ns;    /* added to t_ns per pass */
    int64_t t_first_ns;       /* stamp of frame i0 */
    int64_t wall0;            /* monotonic time when frame i0 of this pass is due */
    int64_t delivered;
    sooc_frame tmp;
} replay;

/* ------------------------------------------------------------ backend */

static sooc_status src_read(replay *r, int64_t i, sooc_frame *f, const sooc_sensor_params *p) {
    sooc_status st = sooc_seq_read(r->seq, i, f);
    if (st) return st;
    if (p->depth_min > 0 || p->depth_max < 1e9f) sooc__depth_finish(f, p->depth_min, p->depth_max);
    return SOOC_OK;
}

/* Why frame i could not be read (the node counts broken frames by reason):
 * each image is decoded again on its own, keeping the failure's message. */
static sooc_frame_fault frame_fault_of(replay *r, int64_t i, const sooc_sensor_info *info) {
    if (sooc_seq_pose_bad(r->seq, i)) return SOOC_FRAME_FAULT_POSE;
    const char *cp = sooc_seq_color_path(r->seq, i), *dp = sooc_seq_depth_path(r->seq, i);
    if (!cp || !dp) return SOOC_FRAME_FAULT_OTHER;   /* a layout without image files (a log) */
    char msg[1024];
    snprintf(msg, sizeof msg, "%s", sooc_errmsg());
    sooc_image a = {0}, b = {0};
    sooc_frame_fault f = SOOC_FRAME_FAULT_OTHER;
    if (sooc_image_read(cp, &a) || a.fmt != SOOC_PIX_RGB8) f = SOOC_FRAME_FAULT_COLOR;
    else if (sooc_image_read(dp, &b) || b.fmt != SOOC_PIX_GRAY16) f = SOOC_FRAME_FAULT_DEPTH;
    else if (a.width != b.width || a.height != b.height || (info->width > 0 && a.width != info->width) ||
             (info->height > 0 && a.height != info->height))
        f = SOOC_FRAME_FAULT_SIZE;
    sooc_image_free(&a);
    sooc_image_free(&b);
    sooc_seterr(SOOC_ERR, "%s", msg);
    return f;
}

/* Stamp of frame i (from the sequence's index: no image is decoded). */
static sooc_status src_stamp(replay *r, int64_t i, int64_t *t, const sooc_sensor_params *p) {
    (void)p;
    *t = sooc_seq_frame_time(r->seq, i);
    if (*t == INT64_MIN) return sooc_seterr(SOOC_EINVAL, "replay: frame %lld out of range", (long long)i);
    return SOOC_OK;
}

/* First index in [0, count) with stamp >= t (count if none); stamps ascend. */
static sooc_status lower_bound_t(replay *r, int64_t t, int64_t *out, const sooc_sensor_params *p) {
    int64_t lo = 0, hi = r->count;
    while (lo < hi) {
        int64_t mid = lo + (hi - lo) / 2, tm;
        sooc_status st = src_stamp(r, mid, &tm, p);
        if (st) return st;
        if (tm < t) lo = mid + 1; else hi = mid;
    }
    *out = lo;
    return SOOC_OK;
}

/* A folder, a ROS bag or an MCAP file; the rosbag and mcap drivers insist on their kind. */
static sooc_status open_log(replay *r, const sooc_sensor *s, const sooc_sensor_params *p, sooc_seq_open_params *sp) {
    const char *dn = s->vt->name;
    sooc_logfile_kind want = !strcmp(dn, "rosbag") ? SOOC_LOGFILE_ROSBAG
                           : !strcmp(dn, "mcap")   ? SOOC_LOGFILE_MCAP
                                                   : SOOC_LOGFILE_NONE;
    sooc_logfile_kind got = sooc_logfile_detect(p->uri);
    if (want && got != want)
        return sooc_seterr(SOOC_EINVAL, "%s: %s: not a%s %s file (%s)", dn, p->uri, want == SOOC_LOGFILE_MCAP ? "n" : "",
                           want == SOOC_LOGFILE_MCAP ? "MCAP" : "ROS bag",
                           got == SOOC_LOGFILE_MCAP     ? "it is an MCAP file: driver mcap"
                           : got == SOOC_LOGFILE_ROSBAG ? "it is a ROS bag: driver rosbag"
                                                        : "neither a ROS bag nor an MCAP file");
    sooc_logseq_params lp;
    sooc_logseq_params_default(&lp);
    lp.color_topic = p->color_topic;
    lp.depth_topic = p->depth_topic;
    lp.pose_parent = p->pose_parent;
    lp.pose_child = p->pose_child;
    if (p->pair_tol_ns > 0) lp.pair_tol_s = (double)p->pair_tol_ns * 1e-9;
    return sooc_log_seq_open(&r->seq, p->uri, sp, &lp);
}

static sooc_status replay_open(sooc_sensor *s, const sooc_sensor_params *p) {
    if (!p->uri || !*p->uri) return sooc_seterr(SOOC_EINVAL, "replay: no sequence path (sensor.uri)");
    if (p->speed < 0 || !isfinite(p->speed)) return sooc_seterr(SOOC_EINVAL, "replay: speed must be >= 0");
    if (!sooc_file_exists(p->uri) && !sooc_dir_exists(p->uri))
        return sooc_seterr(SOOC_ENOTFOUND, "replay: %s: no such file or directory", p->uri);
    replay *r = sooc_calloc(1, sizeof *r);
    if (!r) return SOOC_ENOMEM;
    s->impl = r;
    sooc_status st;
    sooc_seq_open_params sp;
    sooc_seq_open_params_default(&sp);
    if (p->format && *p->format && (st = sooc_seq_format_parse(p->format, &sp.format)))
        goto fail;
    if (p->depth_scale > 0) sp.depth_scale = p->depth_scale;
    sp.depth_shift = p->depth_shift;      /* -1 = calib, else the format's default */
    sp.depth_invalid = p->depth_invalid;
    if (p->calib && *p->calib) sp.calib_path = p->calib;
    sp.keep_bad_frames = 1;   /* a broken frame fails when read: the node skips and counts it */
    if ((st = open_log(r, s, p, &sp))) goto fail;
    r->count = sooc_seq_count(r->seq);
    if (r->count <= 0) { st = sooc_seterr(SOOC_EFORMAT, "replay %s: empty sequence", p->uri); goto fail; }
    int64_t t0;
    if ((st = src_stamp(r, 0, &t0, p))) goto fail;
    r->i0 = 0;
    r->i1 = r->count;
    if (p->start_s > 0 && (st = lower_bound_t(r, t0 + (int64_t)llround(p->start_s * 1e9), &r->i0, p))) goto fail;
    if (p->stop_s >= 0 && (st = lower_bound_t(r, t0 + (int64_t)llround(p->stop_s * 1e9) + 1, &r->i1, p))) goto fail;
    if (r->i1 <= r->i0) {
        st = sooc_seterr(SOOC_EINVAL, "replay %s: no frames between start %.3f s and stop %.3f s", p->uri,
                         p->start_s, p->stop_s);
        goto fail;
    }
    /* Size, intrinsics and pose flag from the first frame that reads (a broken
     * one before it still comes as a failed read, for the caller to count) */
    for (int64_t k = r->i0; (st = src_read(r, k, &r->tmp, p)) && st != SOOC_ENOMEM && k + 1 < r->i1;) k++;
    if (st) goto fail;
    if ((st = src_stamp(r, r->i0, &r->t_first_ns, p))) goto fail;
    int64_t t_last;
    if ((st = src_stamp(r, r->i1 - 1, &t_last, p))) goto fail;
    int64_t n = r->i1 - r->i0;
    int64_t period = n > 1 ? (t_last - r->t_first_ns) / (n - 1) : 33333333;
    r->pass_shift_ns = (t_last - r->t_first_ns) + (period > 0 ? period : 1);
    s->info.width = r->tmp.width;
    s->info.height = r->tmp.height;
    s->info.fps = period > 0 ? (int)llround(1e9 / (double)period) : 0;
    s->info.has_intrinsics = r->tmp.K.fx > 0;
    s->info.K = r->tmp.K;
    s->info.has_pose = r->tmp.has_pose;
    s->info.depth_registered = 1;
    s->info.n_frames = n;
    snprintf(s->info.device, sizeof s->info.device, "%s", p->uri);
    r->next = r->i0;
    return SOOC_OK;
fail:
    s->vt->close(s);
    s->impl = NULL;
    return st;
}

static sooc_status replay_start(sooc_sensor *s) {
    replay *r = s->impl;
    r->wall0 = sooc_now_ns();
    return SOOC_OK;
}

static sooc_status replay_read(sooc_sensor *s, sooc_frame *f, int timeout_ms) {
    replay *r = s->impl;
    if (r->next >= r->i1) {
        if (!s->p.loop) return sooc_seterr(SOOC_EEOF, "replay: end of sequence");
        r->next = r->i0;
        r->pass++;
        r->wall0 += s->p.speed > 0 ? (int64_t)((double)r->pass_shift_ns / s->p.speed) : 0;
    }
    int64_t t_seq;
    sooc_status st = src_stamp(r, r->next, &t_seq, &s->p);
    if (st) return st;
    if (s->p.speed > 0) {
        int64_t due = r->wall0 + (int64_t)((double)(t_seq - r->t_first_ns) / s->p.speed);
        int64_t now = sooc_now_ns();
        if (due > now) {
            if (timeout_ms >= 0 && due - now > (int64_t)timeout_ms * 1000000) {
                if ((st = sooc__sleep_until(s, now + (int64_t)timeout_ms * 1000000))) return st;
                return SOOC_ETIMEOUT;
            }
            if ((st = sooc__sleep_until(s, due))) return st;
        }
    }
    if ((st = src_read(r, r->next, f, &s->p))) {
        s->frame_fault = frame_fault_of(r, r->next, &s->info);
        r->next++; /* a frame that cannot be read (corrupt JPEG, ...) is skipped if the caller reads on */
        return st;
    }
    f->t_ns = sooc__timebase(s, f->t_ns + r->pass * r->pass_shift_ns);
    f->index = r->delivered++;
    r->next++;
    return SOOC_OK;
}

static void replay_close(sooc_sensor *s) {
    replay *r = s->impl;
    if (!r) return;
    sooc_seq_close(r->seq);
    sooc_frame_free(&r->tmp);
    sooc_free(r);
    s->impl = NULL;
}

const sooc_sensor_vt sooc__replay_vt = {"replay", replay_open, replay_start, replay_read, NULL, replay_close};
const sooc_sensor_vt sooc__rosbag_vt = {"rosbag", replay_open, replay_start, replay_read, NULL, replay_close};
const sooc_sensor_vt sooc__mcap_vt = {"mcap", replay_open, replay_start, replay_read, NULL, replay_close};
