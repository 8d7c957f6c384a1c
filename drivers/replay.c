/* Replay driver: recorded sequences at recorded speed or as fast as possible,
 * with loop and start/stop times.
 *
 * Frames come from the data module's sequence readers (sooc3d/seq.h, every
 * format it reads, named by sooc_seq_format_parse) when it is built
 * (SOOC_HAVE_SEQ). Without it, a built-in TUM RGB-D reader (rgb.txt,
 * depth.txt, optional groundtruth.txt, PNGs; no depth_shift/depth_invalid)
 * is used, so the driver works on its own. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "drivers_internal.h"
#include "sooc3d/pose.h"

#ifdef SOOC_HAVE_SEQ
#include "sooc3d/image.h"
#include "sooc3d/seq.h"
#ifdef SOOC_HAVE_LOGS
#include "sooc3d/log.h"
#endif
#else
#include <png.h>
#endif

typedef struct replay {
#ifdef SOOC_HAVE_SEQ
    sooc_seq *seq;
#else
    /* built-in TUM reader */
    char dir[1024];
    int n_all;
    int64_t *t_all;           /* depth stamps (frame stamps) */
    char **rgb_path, **depth_path;
    sooc_pose_src *gt;
    double depth_scale;
    sooc_intrinsics K;
    int has_K;
    uint8_t *rowbuf;
    size_t rowbuf_cap;
#endif
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

/* ------------------------------------------------ built-in TUM reader */
#ifndef SOOC_HAVE_SEQ

typedef struct stamp_list {
    int n;
    int64_t *t;
    char **path;
} stamp_list;

static void stamp_list_free(stamp_list *l) {
    for (int i = 0; i < l->n; i++) sooc_free(l->path[i]);
    sooc_free(l->t);
    sooc_free(l->path);
    memset(l, 0, sizeof *l);
}

static sooc_status read_list(const char *dir, const char *name, stamp_list *l) {
    memset(l, 0, sizeof *l);
    char path[1200];
    sooc_status st = sooc_path_join(path, sizeof path, dir, name);
    if (st) return st;
    void *buf;
    size_t n;
    if ((st = sooc_file_read_all(path, (size_t)1 << 28, &buf, &n))) return st;
    int cap = 1;
    for (size_t i = 0; i < n; i++) cap += ((char *)buf)[i] == '\n';
    l->t = sooc_calloc((size_t)cap, sizeof *l->t);
    l->path = sooc_calloc((size_t)cap, sizeof *l->path);
    if (!l->t || !l->path) { sooc_free(buf); stamp_list_free(l); return SOOC_ENOMEM; }
    char *cur = buf, *line;
    int lineno = 0;
    while ((line = sooc__next_line(&cur))) {
        lineno++;
        char *c = line;
        while (*c == ' ' || *c == '\t') c++;
        if (*c && *c != '#' && *c != '\r') {
            char *end;
            int64_t t;
            char fn[1024];
            if (sooc__parse_seconds_ns(c, &end, &t) || sscanf(end, " %1023s", fn) != 1) {
                sooc_free(buf);
                stamp_list_free(l);
                return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected 'timestamp filename'", path, lineno);
            }
            char full[2100];
            if ((st = sooc_path_join(full, sizeof full, dir, fn))) { sooc_free(buf); stamp_list_free(l); return st; }
            l->t[l->n] = t;
            l->path[l->n] = sooc_strdup(full);
            l->n++;
        }
    }
    sooc_free(buf);
    if (l->n == 0) return sooc_seterr(SOOC_EFORMAT, "%s: no entries", path);
    return SOOC_OK;
}

static sooc_status tum_open(replay *r, sooc_sensor *s, const sooc_sensor_params *p) {
    const char *dir = p->uri;
    snprintf(r->dir, sizeof r->dir, "%s", dir);
    stamp_list rgb, dep;
    sooc_status st = read_list(dir, "rgb.txt", &rgb);
    if (st) return sooc_adderr(st == SOOC_EIO ? SOOC_ENOTFOUND : st, "replay %s (built-in TUM reader)", dir);
    if ((st = read_list(dir, "depth.txt", &dep))) {
        stamp_list_free(&rgb);
        return sooc_adderr(st == SOOC_EIO ? SOOC_ENOTFOUND : st, "replay %s", dir);
    }
    /* Associate each depth image with the nearest colour image within 20 ms
     * (TUM associate.py defaults). */
    r->t_all = sooc_calloc((size_t)dep.n, sizeof *r->t_all);
    r->rgb_path = sooc_calloc((size_t)dep.n, sizeof(char *));
    r->depth_path = sooc_calloc((size_t)dep.n, sizeof(char *));
    if (!r->t_all || !r->rgb_path || !r->depth_path) st = SOOC_ENOMEM;
    int j = 0;
    for (int i = 0; !st && i < dep.n; i++) {
        while (j + 1 < rgb.n && llabs(rgb.t[j + 1] - dep.t[i]) <= llabs(rgb.t[j] - dep.t[i])) j++;
        if (llabs(rgb.t[j] - dep.t[i]) > 20000000) continue;
        r->t_all[r->n_all] = dep.t[i];
        r->rgb_path[r->n_all] = sooc_strdup(rgb.path[j]);
        r->depth_path[r->n_all] = sooc_strdup(dep.path[i]);
        r->n_all++;
    }
    stamp_list_free(&rgb);
    stamp_list_free(&dep);
    if (st) return st;
    if (r->n_all == 0) return sooc_seterr(SOOC_EFORMAT, "replay %s: no depth/colour pairs within 20 ms", dir);
    char gt[1200];
    if (!sooc_path_join(gt, sizeof gt, dir, "groundtruth.txt") && sooc_file_exists(gt)) {
        if ((st = sooc_pose_open_file(&r->gt, gt, NULL))) return st;
    }
    r->depth_scale = p->depth_scale > 0 ? p->depth_scale : 1.0 / 5000.0;
    /* Intrinsics by TUM camera (docs/formats.md §2.1), "ROS default" otherwise. */
    sooc_intrinsics K = {640, 480, 525.0, 525.0, 319.5, 239.5, SOOC_DIST_NONE, {0}};
    if (strstr(dir, "freiburg1")) { K.fx = 517.3; K.fy = 516.5; K.cx = 318.6; K.cy = 255.3; }
    else if (strstr(dir, "freiburg2")) { K.fx = 520.9; K.fy = 521.0; K.cx = 325.1; K.cy = 249.7; }
    else if (strstr(dir, "freiburg3")) { K.fx = 535.4; K.fy = 539.2; K.cx = 320.1; K.cy = 247.6; }
    r->K = K;
    r->has_K = 1;
    r->count = r->n_all;
    s->info.has_pose = r->gt != NULL;
    return SOOC_OK;
}

static void tum_close(replay *r) {
    for (int i = 0; i < r->n_all; i++) {
        sooc_free(r->rgb_path[i]);
        sooc_free(r->depth_path[i]);
    }
    sooc_free(r->rgb_path);
    sooc_free(r->depth_path);
    sooc_free(r->t_all);
    sooc_free(r->rowbuf);
    sooc_pose_close(r->gt);
}

/* Decode a PNG as RGB8 (want_depth = 0) or 16-bit gray (1) into a sooc_malloc'd buffer. */
static sooc_status png_load(const char *path, int want_depth, void **out, int *w, int *h) {
    *out = NULL;
    FILE *fp = fopen(path, "rb");
    if (!fp) return sooc_seterr(SOOC_ENOTFOUND, "%s: cannot open", path);
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    uint8_t *volatile data = NULL;
    png_bytep *volatile rows = NULL;
    if (!png || !info || setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        sooc_free(data);
        sooc_free((void *)rows);
        return sooc_seterr(SOOC_EFORMAT, "%s: not a readable PNG", path);
    }
    png_init_io(png, fp);
    png_read_info(png, info);
    int ct = png_get_color_type(png, info), bd = png_get_bit_depth(png, info);
    if (ct == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (ct & PNG_COLOR_MASK_ALPHA) png_set_strip_alpha(png);
    if (want_depth) {
        if (ct != PNG_COLOR_TYPE_GRAY || bd != 16) {
            png_destroy_read_struct(&png, &info, NULL);
            fclose(fp);
            return sooc_seterr(SOOC_EFORMAT, "%s: depth must be a 16-bit gray PNG", path);
        }
        int one = 1;
        if (*(char *)&one) png_set_swap(png);   /* PNG is big-endian */
    } else {
        if (bd == 16) png_set_strip_16(png);
        if (bd < 8 && (ct == PNG_COLOR_TYPE_GRAY)) png_set_expand_gray_1_2_4_to_8(png);
        if (ct == PNG_COLOR_TYPE_GRAY || ct == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);
    }
    png_read_update_info(png, info);
    *w = (int)png_get_image_width(png, info);
    *h = (int)png_get_image_height(png, info);
    size_t rb = png_get_rowbytes(png, info);
    data = sooc_malloc(rb * (size_t)*h);
    rows = sooc_malloc(sizeof(png_bytep) * (size_t)*h);
    if (!data || !rows) png_error(png, "out of memory");
    for (int y = 0; y < *h; y++) rows[y] = data + rb * (size_t)y;
    png_read_image(png, rows);
    png_read_end(png, NULL);
    png_destroy_read_struct(&png, &info, NULL);
    fclose(fp);
    sooc_free((void *)rows);
    *out = data;
    return SOOC_OK;
}

static sooc_status tum_read(replay *r, int64_t i, sooc_frame *f, const sooc_sensor_params *p) {
    void *rgb = NULL, *dep = NULL;
    int w, h, w2, h2;
    sooc_status st = png_load(r->rgb_path[i], 0, &rgb, &w, &h);
    if (!st) st = png_load(r->depth_path[i], 1, &dep, &w2, &h2);
    if (!st && (w != w2 || h != h2))
        st = sooc_seterr(SOOC_EFORMAT, "%s: %dx%d, but the colour image is %dx%d", r->depth_path[i], w2, h2, w, h);
    if (!st) st = sooc__frame_ensure(f, w, h);
    if (!st) {
        memcpy(f->rgb, rgb, (size_t)w * (size_t)h * 3);
        sooc__depth_u16_to_m(f, dep, w * 2, r->depth_scale, p->depth_min, p->depth_max);
        f->t_ns = r->t_all[i];
        f->K = r->K;
        if (r->K.width != w || r->K.height != h) sooc_cam_crop_resize(&f->K, &r->K, 0, 0, r->K.width, r->K.height, w, h);
        f->has_pose = 0;
        if (r->gt && sooc_pose_lookup(r->gt, r->t_all[i], 50000000, f->T_wc) == SOOC_OK) f->has_pose = 1;
    }
    sooc_free(rgb);
    sooc_free(dep);
    return st;
}
#endif /* !SOOC_HAVE_SEQ */

/* ------------------------------------------------------------ backend */

static sooc_status src_read(replay *r, int64_t i, sooc_frame *f, const sooc_sensor_params *p) {
#ifdef SOOC_HAVE_SEQ
    sooc_status st = sooc_seq_read(r->seq, i, f);
    if (st) return st;
    if (p->depth_min > 0 || p->depth_max < 1e9f) sooc__depth_finish(f, p->depth_min, p->depth_max);
    return SOOC_OK;
#else
    return tum_read(r, i, f, p);
#endif
}

/* Why frame i could not be read (the node counts broken frames by reason):
 * each image is decoded again on its own, keeping the failure's message. */
static sooc_frame_fault frame_fault_of(replay *r, int64_t i, const sooc_sensor_info *info) {
#ifdef SOOC_HAVE_SEQ
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
#else
    (void)r, (void)i, (void)info;
    return SOOC_FRAME_FAULT_OTHER;
#endif
}

/* Stamp of frame i (from the sequence's index: no image is decoded). */
static sooc_status src_stamp(replay *r, int64_t i, int64_t *t, const sooc_sensor_params *p) {
#ifdef SOOC_HAVE_SEQ
    (void)p;
    *t = sooc_seq_frame_time(r->seq, i);
    if (*t == INT64_MIN) return sooc_seterr(SOOC_EINVAL, "replay: frame %lld out of range", (long long)i);
    return SOOC_OK;
#else
    (void)p;
    *t = r->t_all[i];
    return SOOC_OK;
#endif
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

#if defined(SOOC_HAVE_SEQ) && defined(SOOC_HAVE_LOGS)
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
#endif

static sooc_status replay_open(sooc_sensor *s, const sooc_sensor_params *p) {
    if (!p->uri || !*p->uri) return sooc_seterr(SOOC_EINVAL, "replay: no sequence path (sensor.uri)");
    if (p->speed < 0 || !isfinite(p->speed)) return sooc_seterr(SOOC_EINVAL, "replay: speed must be >= 0");
    if (!sooc_file_exists(p->uri) && !sooc_dir_exists(p->uri))
        return sooc_seterr(SOOC_ENOTFOUND, "replay: %s: no such file or directory", p->uri);
    replay *r = sooc_calloc(1, sizeof *r);
    if (!r) return SOOC_ENOMEM;
    s->impl = r;
    sooc_status st;
#ifdef SOOC_HAVE_SEQ
    sooc_seq_open_params sp;
    sooc_seq_open_params_default(&sp);
    if (p->format && *p->format && (st = sooc_seq_format_parse(p->format, &sp.format)))
        goto fail;
    if (p->depth_scale > 0) sp.depth_scale = p->depth_scale;
    sp.depth_shift = p->depth_shift;      /* -1 = calib, else the format's default */
    sp.depth_invalid = p->depth_invalid;
    if (p->calib && *p->calib) sp.calib_path = p->calib;
    sp.keep_bad_frames = 1;   /* a broken frame fails when read: the node skips and counts it */
#ifdef SOOC_HAVE_LOGS
    if ((st = open_log(r, s, p, &sp))) goto fail;
#else
    st = sooc_seq_open(&r->seq, p->uri, &sp);
    if (st) goto fail;
#endif
    r->count = sooc_seq_count(r->seq);
#else
    if (p->format && strcmp(p->format, "tum") && strcmp(p->format, "auto")) {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "replay: format '%s' needs the data module (not built); only tum here",
                         p->format);
        goto fail;
    }
    st = tum_open(r, s, p);
    if (st) goto fail;
#endif
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
#ifdef SOOC_HAVE_SEQ
    sooc_seq_close(r->seq);
#else
    tum_close(r);
#endif
    sooc_frame_free(&r->tmp);
    sooc_free(r);
    s->impl = NULL;
}

const sooc_sensor_vt sooc__replay_vt = {"replay", replay_open, replay_start, replay_read, NULL, replay_close};
#ifdef SOOC_HAVE_LOGS
const sooc_sensor_vt sooc__rosbag_vt = {"rosbag", replay_open, replay_start, replay_read, NULL, replay_close};
const sooc_sensor_vt sooc__mcap_vt = {"mcap", replay_open, replay_start, replay_read, NULL, replay_close};
#endif
