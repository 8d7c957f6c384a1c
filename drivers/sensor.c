/* The sensor front end: driver registry, parameters, shared conversions. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "drivers_internal.h"

static const sooc_sensor_vt *const g_drivers[] = {
    &sooc__replay_vt,
    &sooc__rosbag_vt,
    &sooc__mcap_vt,
#ifdef SOOC_HAVE_OPENNI2
    &sooc__openni2_vt,
#endif
#ifdef SOOC_HAVE_FREENECT
    &sooc__freenect_vt,
#endif
#ifdef SOOC_HAVE_V4L2
    &sooc__v4l2_vt,
#endif
#ifdef SOOC_HAVE_LIBCAMERA
    &sooc__libcamera_vt,
#endif
};
#define N_DRIVERS (sizeof g_drivers / sizeof g_drivers[0])

static const char *const g_names[] = {
    "replay",
    "rosbag",
    "mcap",
#ifdef SOOC_HAVE_OPENNI2
    "openni2",
#endif
#ifdef SOOC_HAVE_FREENECT
    "freenect",
#endif
#ifdef SOOC_HAVE_V4L2
    "v4l2",
#endif
#ifdef SOOC_HAVE_LIBCAMERA
    "libcamera",
#endif
    NULL};

const char *const *sooc_sensor_list_drivers(void) { return g_names; }

static const sooc_sensor_vt *find_vt(const char *name) {
    for (size_t i = 0; i < N_DRIVERS; i++)
        if (name && strcmp(g_drivers[i]->name, name) == 0) return g_drivers[i];
    return NULL;
}

int sooc_sensor_has_driver(const char *name) { return find_vt(name) != NULL; }

void sooc_sensor_params_default(sooc_sensor_params *p) {
    memset(p, 0, sizeof *p);
    p->speed = 1.0;
    p->stop_s = -1.0;
    p->depth_min = 0.1f;
    p->depth_max = 10.0f;
    p->registration = 1;
    p->depth_shift = -1;
    p->depth_invalid = -1;
}

static sooc_status parse_int(const char *key, const char *v, int lo, int hi, int *out) {
    char *end;
    errno = 0;
    long x = v ? strtol(v, &end, 10) : 0;
    if (!v || end == v || *end || errno || x < lo || x > hi)
        return sooc_seterr(SOOC_EINVAL, "sensor.%s: expected an integer in [%d, %d], got '%s'", key, lo, hi,
                           v ? v : "(null)");
    *out = (int)x;
    return SOOC_OK;
}

static sooc_status parse_dbl(const char *key, const char *v, double lo, double hi, double *out) {
    char *end;
    double x = v ? strtod(v, &end) : 0;
    if (!v || end == v || *end || !isfinite(x) || x < lo || x > hi)
        return sooc_seterr(SOOC_EINVAL, "sensor.%s: expected a number in [%g, %g], got '%s'", key, lo, hi,
                           v ? v : "(null)");
    *out = x;
    return SOOC_OK;
}

static sooc_status parse_bool(const char *key, const char *v, int *out) {
    if (v && (!strcmp(v, "1") || !strcmp(v, "true") || !strcmp(v, "yes") || !strcmp(v, "on"))) {
        *out = 1;
        return SOOC_OK;
    }
    if (v && (!strcmp(v, "0") || !strcmp(v, "false") || !strcmp(v, "no") || !strcmp(v, "off"))) {
        *out = 0;
        return SOOC_OK;
    }
    return sooc_seterr(SOOC_EINVAL, "sensor.%s: expected true/false, got '%s'", key, v ? v : "(null)");
}

sooc_status sooc_sensor_params_set(sooc_sensor_params *p, const char *key, const char *v) {
    double d;
    if (!key) return sooc_seterr(SOOC_EINVAL, "sensor: NULL key");
    if (!strcmp(key, "uri") || !strcmp(key, "device") || !strcmp(key, "path")) { p->uri = v; return SOOC_OK; }
    if (!strcmp(key, "uri2") || !strcmp(key, "color_device")) { p->uri2 = v; return SOOC_OK; }
    if (!strcmp(key, "format")) { p->format = v; return SOOC_OK; }
    if (!strcmp(key, "calib")) { p->calib = v; return SOOC_OK; }
    if (!strcmp(key, "color_topic")) { p->color_topic = v; return SOOC_OK; }
    if (!strcmp(key, "depth_topic")) { p->depth_topic = v; return SOOC_OK; }
    if (!strcmp(key, "pose_parent")) { p->pose_parent = v; return SOOC_OK; }
    if (!strcmp(key, "pose_child")) { p->pose_child = v; return SOOC_OK; }
    if (!strcmp(key, "width")) return parse_int(key, v, 0, 16384, &p->width);
    if (!strcmp(key, "height")) return parse_int(key, v, 0, 16384, &p->height);
    if (!strcmp(key, "fps")) return parse_int(key, v, 0, 1000, &p->fps);
    if (!strcmp(key, "speed")) return parse_dbl(key, v, 0, 1000, &p->speed);
    if (!strcmp(key, "loop")) return parse_bool(key, v, &p->loop);
    if (!strcmp(key, "start") || !strcmp(key, "start_s")) return parse_dbl(key, v, 0, 1e9, &p->start_s);
    if (!strcmp(key, "stop") || !strcmp(key, "stop_s")) return parse_dbl(key, v, -1, 1e9, &p->stop_s);
    if (!strcmp(key, "depth_scale")) return parse_dbl(key, v, 0, 100, &p->depth_scale);
    if (!strcmp(key, "depth_shift")) return parse_int(key, v, 0, 15, &p->depth_shift);
    if (!strcmp(key, "depth_invalid")) return parse_int(key, v, 0, 65535, &p->depth_invalid);
    if (!strcmp(key, "depth_min")) {
        sooc_status st = parse_dbl(key, v, 0, 1000, &d);
        if (!st) p->depth_min = (float)d;
        return st;
    }
    if (!strcmp(key, "depth_max")) {
        sooc_status st = parse_dbl(key, v, 0, 1000, &d);
        if (!st) p->depth_max = (float)d;
        return st;
    }
    if (!strcmp(key, "registration")) return parse_bool(key, v, &p->registration);
    if (!strcmp(key, "mirror")) return parse_bool(key, v, &p->mirror);
    if (!strcmp(key, "depth_format")) {
        if (!v || !(strcmp(v, "Z16") == 0 || strcmp(v, "Y16") == 0 || strcmp(v, "auto") == 0 ||
                    strcmp(v, "11bit") == 0 || strcmp(v, "registered") == 0 || strcmp(v, "mm") == 0))
            return sooc_seterr(SOOC_EINVAL, "sensor.depth_format: expected Z16|Y16|auto|11bit|registered|mm, got '%s'",
                               v ? v : "(null)");
        p->depth_format = v;
        return SOOC_OK;
    }
    if (!strcmp(key, "timebase")) {
        if (v && !strcmp(v, "sensor")) p->timebase = SOOC_TIMEBASE_SENSOR;
        else if (v && !strcmp(v, "realtime")) p->timebase = SOOC_TIMEBASE_REALTIME;
        else return sooc_seterr(SOOC_EINVAL, "sensor.timebase: expected sensor|realtime, got '%s'", v ? v : "(null)");
        return SOOC_OK;
    }
    if (!strcmp(key, "pair_tol_ms")) {
        sooc_status st = parse_dbl(key, v, 0, 10000, &d);
        if (!st) p->pair_tol_ns = (int64_t)llround(d * 1e6);
        return st;
    }
    return sooc_seterr(SOOC_EINVAL, "sensor.%s: unknown key", key);
}

sooc_status sooc_sensor_open(sooc_sensor **out, const char *driver_name, const sooc_sensor_params *p) {
    *out = NULL;
    const sooc_sensor_vt *vt = find_vt(driver_name);
    if (!vt) {
        static const char *known[] = {"replay", "rosbag", "mcap", "openni2", "freenect", "v4l2", "libcamera"};
        for (size_t i = 0; i < sizeof known / sizeof known[0]; i++)
            if (driver_name && !strcmp(driver_name, known[i]))
                return sooc_seterr(SOOC_EUNSUPPORTED,
                                   "sensor driver '%s' is not built in (its library was missing at build time)",
                                   driver_name);
        return sooc_seterr(SOOC_EINVAL, "unknown sensor driver '%s' (replay|rosbag|mcap|openni2|freenect|v4l2|libcamera)",
                           driver_name ? driver_name : "(null)");
    }
    sooc_sensor *s = sooc_calloc(1, sizeof *s);
    if (!s) return SOOC_ENOMEM;
    s->vt = vt;
    if (p) s->p = *p; else sooc_sensor_params_default(&s->p);
    if (s->p.depth_max <= 0) s->p.depth_max = 1e9f;
    s->info.driver = vt->name;
    s->info.n_frames = -1;
    s->info.has_color = s->info.has_depth = 1;
    atomic_init(&s->interrupted, 0);
    sooc_status st = vt->open(s, &s->p);
    if (st) {
        sooc_free(s);
        return st;
    }
    /* Strings in p are not owned; drop them so nothing dangles after open. */
    s->p.uri = s->p.uri2 = s->p.format = s->p.calib = s->p.depth_format = NULL;
    *out = s;
    return SOOC_OK;
}

sooc_status sooc_sensor_start(sooc_sensor *s) {
    if (s->started) return SOOC_OK;
    sooc_status st = s->vt->start ? s->vt->start(s) : SOOC_OK;
    if (st) return st;
    s->started = 1;
    s->t_start_mono = sooc_now_ns();
    return SOOC_OK;
}

sooc_status sooc_sensor_read(sooc_sensor *s, sooc_frame *f, int timeout_ms) {
    if (sooc__interrupted(s)) return sooc_seterr(SOOC_EINTERRUPTED, "%s: interrupted", s->vt->name);
    if (!s->started) {
        sooc_status st = sooc_sensor_start(s);
        if (st) return st;
    }
    s->frame_fault = SOOC_FRAME_FAULT_NONE;
    sooc_status st = s->vt->read(s, f, timeout_ms);
    if (st == SOOC_OK) {
        s->st.frames++;
    } else if (st == SOOC_ETIMEOUT) {
        s->st.timeouts++;
    }
    return st;
}

sooc_frame_fault sooc_sensor_frame_fault(const sooc_sensor *s) { return s ? s->frame_fault : SOOC_FRAME_FAULT_NONE; }

void sooc_sensor_interrupt(sooc_sensor *s) {
    if (s) atomic_store(&s->interrupted, 1);
}

int sooc__interrupted(sooc_sensor *s) { return atomic_load(&s->interrupted) != 0; }

sooc_status sooc_sensor_stop(sooc_sensor *s) {
    if (!s || !s->started) return SOOC_OK;
    s->started = 0;
    return s->vt->stop ? s->vt->stop(s) : SOOC_OK;
}

void sooc_sensor_close(sooc_sensor *s) {
    if (!s) return;
    (void)sooc_sensor_stop(s);
    if (s->vt->close) s->vt->close(s);
    sooc_free(s);
}

void sooc_sensor_get_info(const sooc_sensor *s, sooc_sensor_info *out) { *out = s->info; }

void sooc_sensor_get_stats(const sooc_sensor *s, sooc_sensor_stats *out) {
    *out = s->st;
    double dt = s->t_start_mono ? (double)(sooc_now_ns() - s->t_start_mono) * 1e-9 : 0;
    out->fps = dt > 0 ? (double)s->st.frames / dt : 0;
}

/* ------------------------------------------------------------- helpers */

float sooc_freenect_disparity_to_m(uint16_t raw) {
    if (raw >= 1084) return 0.0f;
    double den = -0.0030711016 * (double)raw + 3.3309495161;
    if (den <= 0) return 0.0f;
    return (float)(1.0 / den);
}

sooc_status sooc__frame_ensure(sooc_frame *f, int w, int h) {
    if (!(f->width == w && f->height == h && f->rgb && f->depth && f->valid)) {
        sooc_frame_free(f);
        sooc_status st = sooc_frame_alloc(f, w, h, 0);
        if (st) return st;
    }
    f->has_pose = 0;
    f->is_query = 0;
    memset(&f->K, 0, sizeof f->K);
    return SOOC_OK;
}

void sooc__depth_finish(sooc_frame *f, float dmin, float dmax) {
    size_t n = (size_t)f->width * (size_t)f->height;
    for (size_t i = 0; i < n; i++) {
        float z = f->depth[i];
        int ok = isfinite(z) && z > 0 && z >= dmin && z <= dmax;
        if (!ok) f->depth[i] = 0.0f;
        f->valid[i] = (uint8_t)ok;
    }
}

void sooc__depth_u16_to_m(sooc_frame *f, const uint16_t *src, int stride_bytes, double scale, float dmin,
                          float dmax) {
    const int w = f->width, h = f->height;
    const float sc = (float)scale;
    for (int y = 0; y < h; y++) {
        const uint16_t *row = (const uint16_t *)((const uint8_t *)src + (size_t)y * (size_t)stride_bytes);
        float *d = f->depth + (size_t)y * (size_t)w;
        uint8_t *v = f->valid + (size_t)y * (size_t)w;
        for (int x = 0; x < w; x++) {
            float z = (float)row[x] * sc;
            int ok = row[x] != 0 && z >= dmin && z <= dmax;
            d[x] = ok ? z : 0.0f;
            v[x] = (uint8_t)ok;
        }
    }
}

static inline uint8_t clamp_u8(int v) { return (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v); }

void sooc__yuyv_to_rgb(uint8_t *dst, const uint8_t *src, int w, int h, int stride_bytes) {
    for (int y = 0; y < h; y++) {
        const uint8_t *s = src + (size_t)y * (size_t)stride_bytes;
        uint8_t *d = dst + (size_t)y * (size_t)w * 3;
        for (int x = 0; x + 1 < w; x += 2) {
            int y0 = s[0] - 16, u = s[1] - 128, y1 = s[2] - 16, v = s[3] - 128;
            int c0 = 298 * y0, c1 = 298 * y1;
            int rr = 409 * v, gg = -100 * u - 208 * v, bb = 516 * u;
            d[0] = clamp_u8((c0 + rr + 128) >> 8);
            d[1] = clamp_u8((c0 + gg + 128) >> 8);
            d[2] = clamp_u8((c0 + bb + 128) >> 8);
            d[3] = clamp_u8((c1 + rr + 128) >> 8);
            d[4] = clamp_u8((c1 + gg + 128) >> 8);
            d[5] = clamp_u8((c1 + bb + 128) >> 8);
            s += 4;
            d += 6;
        }
    }
}

void sooc__rgb_copy(uint8_t *dst, const uint8_t *src, int w, int h, int stride_bytes, int bgr) {
    for (int y = 0; y < h; y++) {
        const uint8_t *s = src + (size_t)y * (size_t)stride_bytes;
        uint8_t *d = dst + (size_t)y * (size_t)w * 3;
        if (!bgr) {
            memcpy(d, s, (size_t)w * 3);
        } else {
            for (int x = 0; x < w; x++) {
                d[3 * x] = s[3 * x + 2];
                d[3 * x + 1] = s[3 * x + 1];
                d[3 * x + 2] = s[3 * x];
            }
        }
    }
}

int64_t sooc__timebase(sooc_sensor *s, int64_t sensor_ns) {
    if (s->p.timebase != SOOC_TIMEBASE_REALTIME) return sensor_ns;
    if (!s->rebased) {
        s->rebased = 1;
        s->rebase_off = sooc_realtime_ns() - sensor_ns;
    }
    return sensor_ns + s->rebase_off;
}

sooc_status sooc__sleep_until(sooc_sensor *s, int64_t deadline) {
    for (;;) {
        if (sooc__interrupted(s)) return sooc_seterr(SOOC_EINTERRUPTED, "%s: interrupted", s->vt->name);
        int64_t now = sooc_now_ns();
        if (now >= deadline) return SOOC_OK;
        int64_t d = deadline - now;
        if (d > 20000000) d = 20000000;
        struct timespec ts = {.tv_sec = 0, .tv_nsec = (long)d};
        nanosleep(&ts, NULL);
    }
}

int sooc__parse_seconds_ns(const char *s, char **end, int64_t *ns) {
    const char *c = s;
    while (*c == ' ' || *c == '\t') c++;
    const char *start = c;
    /* exponent or other exotic forms: fall back to strtod */
    const char *q = c;
    int neg = 0;
    if (*q == '-' || *q == '+') { neg = *q == '-'; q++; }
    if (!isdigit((unsigned char)*q) && *q != '.') return -1;
    int64_t ip = 0;
    int nd = 0;
    while (isdigit((unsigned char)*q)) {
        if (ip > (INT64_MAX / 10 - 10) / 1000000000) return -1;
        ip = ip * 10 + (*q - '0');
        q++;
        nd++;
    }
    int64_t frac = 0;
    int nf = 0;
    if (*q == '.') {
        q++;
        while (isdigit((unsigned char)*q)) {
            if (nf < 9) { frac = frac * 10 + (*q - '0'); nf++; }
            else if (nf == 9 && *q >= '5' && nd >= 0) { frac++; nf = 10; } /* round once */
            q++;
        }
    }
    if (*q == 'e' || *q == 'E') {
        char *e2;
        double d = strtod(start, &e2);
        if (e2 == start || !(fabs(d) < 9.2e9)) return -1;   /* |t| * 1e9 must fit in int64 */
        *ns = (int64_t)llround(d * 1e9);
        *end = e2;
        return 0;
    }
    int nfd = nf > 9 ? 9 : nf;
    for (int k = nfd; k < 9; k++) frac *= 10;
    if (ip > (INT64_MAX - frac) / 1000000000) return -1;   /* beyond ~292 years of ns */
    int64_t v = ip * 1000000000 + frac;
    *ns = neg ? -v : v;
    *end = (char *)q;
    return 0;
}
