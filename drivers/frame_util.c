/* Conversions and timing shared by the sensor drivers (drivers_internal.h):
 * frame buffers, depth to metres, YUYV and RGB copies, the time base,
 * interruptible sleeps, and time strings. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "drivers_internal.h"

int sooc__interrupted(sooc_sensor *s) { return atomic_load(&s->interrupted) != 0; }

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
