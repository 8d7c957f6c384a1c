/* The sensor front end (include/sooc3d/driver.h): parameters, open by driver
 * name (the registry, registry.c), start, read, stop, close, stats. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "drivers_internal.h"

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
    const sooc_sensor_vt *vt = sooc__driver_find(driver_name);
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
