/* libcamera driver (colour only) through the C++ shim (lcshim.h). Frames
 * arrive on libcamera's thread and are copied into a one-slot mailbox; the
 * newest frame wins (older unread frames count as dropped). Depth is all
 * invalid: libcamera is for RGB cameras (e.g. CSI), docs/drivers.md. */
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "drivers_internal.h"
#include "lcshim.h"

/* DRM fourccs used by libcamera */
#define LC_FOURCC(a, b, c, d) ((uint32_t)(a) | ((uint32_t)(b) << 8) | ((uint32_t)(c) << 16) | ((uint32_t)(d) << 24))
#define LC_RGB888 LC_FOURCC('R', 'G', '2', '4') /* memory B G R */
#define LC_BGR888 LC_FOURCC('B', 'G', '2', '4') /* memory R G B */
#define LC_YUYV LC_FOURCC('Y', 'U', 'Y', 'V')

typedef struct lcam {
    sooc_lc *c;
    sooc_sensor *s;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int w, h, stride;
    uint32_t fourcc;
    uint8_t *rgb;        /* w*h*3, newest frame */
    int have;
    int64_t t_ns;
    uint32_t seq, last_seq;
    int have_seq;
    int64_t dropped, received;
    int64_t index;
} lcam;

static void on_frame(void *user, const uint8_t *data, size_t len, int w, int h, int stride, uint32_t fourcc,
                     int64_t ts_ns, uint32_t seq) {
    lcam *l = user;
    if (w != l->w || h != l->h || len < (size_t)stride * (size_t)(h - 1)) return;
    pthread_mutex_lock(&l->mu);
    l->received++;
    if (l->have) l->dropped++;
    if (l->have_seq && seq > l->last_seq + 1) l->dropped += seq - l->last_seq - 1;
    l->have_seq = 1;
    l->last_seq = seq;
    if (fourcc == LC_YUYV) sooc__yuyv_to_rgb(l->rgb, data, w, h, stride);
    else sooc__rgb_copy(l->rgb, data, w, h, stride, fourcc == LC_RGB888);
    l->have = 1;
    l->t_ns = ts_ns;
    l->seq = seq;
    pthread_cond_signal(&l->cv);
    pthread_mutex_unlock(&l->mu);
}

static void lc_close(sooc_sensor *s);

static sooc_status lc_open(sooc_sensor *s, const sooc_sensor_params *p) {
    lcam *l = sooc_calloc(1, sizeof *l);
    if (!l) return SOOC_ENOMEM;
    s->impl = l;
    l->s = s;
    pthread_mutex_init(&l->mu, NULL);
    pthread_cond_init(&l->cv, NULL);
    char err[256] = "";
    int r = sooc_lc_open(&l->c, p->uri, p->width, p->height, on_frame, l, err, sizeof err);
    if (r) {
        lc_close(s);
        return sooc_seterr(r == -2 ? SOOC_ENOTFOUND : SOOC_EIO, "%s", err[0] ? err : "libcamera: open failed");
    }
    char id[200];
    sooc_lc_format(l->c, &l->w, &l->h, &l->stride, &l->fourcc, id, sizeof id);
    l->rgb = sooc_calloc((size_t)l->w * (size_t)l->h, 3);
    if (!l->rgb) { lc_close(s); return SOOC_ENOMEM; }
    s->info.width = l->w;
    s->info.height = l->h;
    s->info.fps = p->fps > 0 ? p->fps : 30;
    s->info.has_depth = 0;
    s->info.has_intrinsics = 0;
    snprintf(s->info.device, sizeof s->info.device, "%s", id);
    return SOOC_OK;
}

static sooc_status lc_start(sooc_sensor *s) {
    lcam *l = s->impl;
    char err[256] = "";
    if (sooc_lc_start(l->c, err, sizeof err)) return sooc_seterr(SOOC_EIO, "%s", err);
    return SOOC_OK;
}

static sooc_status lc_read(sooc_sensor *s, sooc_frame *f, int timeout_ms) {
    lcam *l = s->impl;
    int64_t deadline = timeout_ms < 0 ? INT64_MAX : sooc_now_ns() + (int64_t)timeout_ms * 1000000;
    pthread_mutex_lock(&l->mu);
    while (!l->have) {
        if (sooc__interrupted(s)) {
            pthread_mutex_unlock(&l->mu);
            return sooc_seterr(SOOC_EINTERRUPTED, "libcamera: interrupted");
        }
        int64_t now = sooc_now_ns();
        if (now >= deadline) {
            pthread_mutex_unlock(&l->mu);
            return SOOC_ETIMEOUT;
        }
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        int64_t slice = deadline - now < 20000000 ? deadline - now : 20000000;
        int64_t ns = ts.tv_nsec + slice;
        ts.tv_sec += (time_t)(ns / 1000000000);
        ts.tv_nsec = (long)(ns % 1000000000);
        pthread_cond_timedwait(&l->cv, &l->mu, &ts);
    }
    sooc_status st = sooc__frame_ensure(f, l->w, l->h);
    if (!st) {
        memcpy(f->rgb, l->rgb, (size_t)l->w * (size_t)l->h * 3);
        memset(f->depth, 0, (size_t)l->w * (size_t)l->h * sizeof(float));
        memset(f->valid, 0, (size_t)l->w * (size_t)l->h);
        f->t_ns = sooc__timebase(s, l->t_ns);
        f->index = l->index++;
        l->have = 0;
    }
    s->st.color_in = l->received;
    s->st.dropped = l->dropped;
    pthread_mutex_unlock(&l->mu);
    return st;
}

static sooc_status lc_stop(sooc_sensor *s) {
    lcam *l = s->impl;
    if (l && l->c) sooc_lc_stop(l->c);
    return SOOC_OK;
}

static void lc_close(sooc_sensor *s) {
    lcam *l = s->impl;
    if (!l) return;
    sooc_lc_close(l->c);
    pthread_mutex_destroy(&l->mu);
    pthread_cond_destroy(&l->cv);
    sooc_free(l->rgb);
    sooc_free(l);
    s->impl = NULL;
}

const sooc_sensor_vt sooc__libcamera_vt = {"libcamera", lc_open, lc_start, lc_read, lc_stop, lc_close};
