/* libfreenect driver (Kinect v1), docs/drivers.md "freenect".
 *
 * Depth modes: on real hardware FREENECT_DEPTH_REGISTERED (mm, registered to
 * colour); under Debian's fakenect (FAKENECT_PATH set) only 11-bit raw
 * disparity works, and asking for anything else aborts inside fakenect, so
 * "auto" picks 11-bit there and converts it to metres here:
 *
 *     z [m] = 1 / (-0.0030711016 * raw + 3.3309495161)     (ROS kinect_calibration)
 *
 * with raw >= 1084 (and 2047, "no data") invalid. 11-bit depth is in the IR
 * camera's frame (not registered); intrinsics then default to the PS1080
 * depth values (f = 575.8, c = (314.5, 235.5)). Timestamps: the device's
 * 32-bit tick counter wraps, so frames carry host time at arrival
 * (CLOCK_REALTIME; the same clock as robot pose streams). */
#include <libfreenect.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>

#include "drivers_internal.h"

#define FN_W 640
#define FN_H 480

typedef struct fn {
    freenect_context *ctx;
    freenect_device *dev;
    sooc_sensor *s;
    int mode_11bit;
    int fake;
    int streaming;
    uint16_t dbuf[FN_W * FN_H];
    uint8_t cbuf[FN_W * FN_H * 3];
    int have_d, have_c;
    int64_t t_d, t_c;
    uint32_t ts_d;
    int64_t index;
    float lut[2048];
    double depth_scale;
} fn;

static void depth_cb(freenect_device *dev, void *data, uint32_t ts) {
    fn *f = freenect_get_user(dev);
    if (!f || !data) return;
    f->s->st.depth_in++;
    if (f->have_d) f->s->st.unpaired++;
    memcpy(f->dbuf, data, sizeof f->dbuf);
    f->have_d = 1;
    f->t_d = sooc_realtime_ns();
    f->ts_d = ts;
}

static void video_cb(freenect_device *dev, void *data, uint32_t ts) {
    fn *f = freenect_get_user(dev);
    (void)ts;
    if (!f || !data) return;
    f->s->st.color_in++;
    if (f->have_c) f->s->st.unpaired++;
    memcpy(f->cbuf, data, sizeof f->cbuf);
    f->have_c = 1;
    f->t_c = sooc_realtime_ns();
}

static void fn_close(sooc_sensor *s);

static sooc_status fn_open(sooc_sensor *s, const sooc_sensor_params *p) {
    fn *f = sooc_calloc(1, sizeof *f);
    if (!f) return SOOC_ENOMEM;
    s->impl = f;
    f->s = s;
    sooc_status st = SOOC_OK;
    f->fake = getenv("FAKENECT_PATH") != NULL;
    if ((p->width && p->width != FN_W) || (p->height && p->height != FN_H)) {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "freenect: only 640x480 is supported (asked %dx%d)", p->width, p->height);
        goto fail;
    }
    if (freenect_init(&f->ctx, NULL) < 0 || !f->ctx) {
        f->ctx = NULL;
        st = sooc_seterr(SOOC_EIO, "freenect: freenect_init failed (libusb?)");
        goto fail;
    }
    freenect_set_log_level(f->ctx, FREENECT_LOG_ERROR);
    freenect_select_subdevices(f->ctx, FREENECT_DEVICE_CAMERA);
    int idx = 0;
    if (p->uri && *p->uri) {
        char *end;
        long v = strtol(p->uri, &end, 10);
        if (*end || v < 0 || v > 64) {
            st = sooc_seterr(SOOC_EINVAL, "freenect: sensor.uri must be a device index, got '%s'", p->uri);
            goto fail;
        }
        idx = (int)v;
    }
    int nd = freenect_num_devices(f->ctx);
    if (nd <= idx) {
        st = sooc_seterr(SOOC_ENOTFOUND, "freenect: no Kinect #%d (%d device%s found)", idx, nd < 0 ? 0 : nd,
                         nd == 1 ? "" : "s");
        goto fail;
    }
    if (freenect_open_device(f->ctx, &f->dev, idx) < 0 || !f->dev) {
        f->dev = NULL;
        st = sooc_seterr(SOOC_ENOTFOUND, "freenect: cannot open Kinect #%d (permissions? udev group plugdev)", idx);
        goto fail;
    }
    const char *df = p->depth_format && *p->depth_format ? p->depth_format : "auto";
    if (!strcmp(df, "auto")) f->mode_11bit = f->fake;
    else if (!strcmp(df, "11bit")) f->mode_11bit = 1;
    else if (!strcmp(df, "registered") || !strcmp(df, "mm")) f->mode_11bit = 0;
    else {
        st = sooc_seterr(SOOC_EINVAL, "freenect: depth_format '%s' (auto|11bit|registered|mm)", df);
        goto fail;
    }
    if (!f->mode_11bit && f->fake) {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "freenect: Debian's fakenect replays only 11-bit disparity");
        goto fail;
    }
    freenect_frame_mode dm = freenect_find_depth_mode(
        FREENECT_RESOLUTION_MEDIUM, f->mode_11bit ? FREENECT_DEPTH_11BIT
                                                  : (!strcmp(df, "mm") ? FREENECT_DEPTH_MM : FREENECT_DEPTH_REGISTERED));
    freenect_frame_mode vm = freenect_find_video_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_VIDEO_RGB);
    if (!dm.is_valid || !vm.is_valid || freenect_set_depth_mode(f->dev, dm) < 0 ||
        freenect_set_video_mode(f->dev, vm) < 0) {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "freenect: cannot set the 640x480 depth/RGB modes");
        goto fail;
    }
    freenect_set_user(f->dev, f);
    freenect_set_depth_callback(f->dev, depth_cb);
    freenect_set_video_callback(f->dev, video_cb);
    f->depth_scale = p->depth_scale > 0 ? p->depth_scale : 0.001;
    for (int i = 0; i < 2048; i++) f->lut[i] = sooc_freenect_disparity_to_m((uint16_t)i);
    sooc_intrinsics K = {FN_W, FN_H, 525.0, 525.0, 319.5, 239.5, SOOC_DIST_NONE, {0}};
    if (f->mode_11bit) { K.fx = K.fy = 575.8157348632812; K.cx = 314.5; K.cy = 235.5; }
    s->info.K = K;
    s->info.has_intrinsics = 1;
    s->info.width = FN_W;
    s->info.height = FN_H;
    s->info.fps = 30;
    s->info.depth_registered = !f->mode_11bit && strcmp(df, "mm") != 0;
    snprintf(s->info.device, sizeof s->info.device, "%s #%d (%s)", f->fake ? "fakenect" : "Kinect", idx,
             f->mode_11bit ? "11-bit disparity" : "mm");
    return SOOC_OK;
fail:
    fn_close(s);
    return st;
}

static sooc_status fn_start(sooc_sensor *s) {
    fn *f = s->impl;
    if (freenect_start_depth(f->dev) < 0) return sooc_seterr(SOOC_EIO, "freenect: start_depth failed");
    if (freenect_start_video(f->dev) < 0) {
        freenect_stop_depth(f->dev);
        return sooc_seterr(SOOC_EIO, "freenect: start_video failed");
    }
    f->streaming = 1;
    return SOOC_OK;
}

static sooc_status fn_read(sooc_sensor *s, sooc_frame *fr, int timeout_ms) {
    fn *f = s->impl;
    int64_t deadline = timeout_ms < 0 ? INT64_MAX : sooc_now_ns() + (int64_t)timeout_ms * 1000000;
    while (!(f->have_d && f->have_c)) {
        if (sooc__interrupted(s)) return sooc_seterr(SOOC_EINTERRUPTED, "freenect: interrupted");
        int64_t now = sooc_now_ns();
        if (now >= deadline) return SOOC_ETIMEOUT;
        int64_t slice = deadline - now;
        if (slice > 50000000) slice = 50000000;
        struct timeval tv = {0, (suseconds_t)(slice / 1000)};
        int r = freenect_process_events_timeout(f->ctx, &tv);
        if (r < 0) {
            /* fakenect answers -1 at the end of its dump; a lost device is a libusb error */
            if (f->fake && r == -1) return sooc_seterr(SOOC_EEOF, "freenect: end of the fakenect recording");
            return sooc_seterr(SOOC_EIO, "freenect: process_events failed (%d); device unplugged?", r);
        }
    }
    sooc_status st = sooc__frame_ensure(fr, FN_W, FN_H);
    if (st) return st;
    if (f->mode_11bit) {
        for (int i = 0; i < FN_W * FN_H; i++) fr->depth[i] = f->lut[f->dbuf[i] & 2047];
        sooc__depth_finish(fr, s->p.depth_min, s->p.depth_max);
    } else {
        sooc__depth_u16_to_m(fr, f->dbuf, FN_W * 2, f->depth_scale, s->p.depth_min, s->p.depth_max);
    }
    memcpy(fr->rgb, f->cbuf, sizeof f->cbuf);
    fr->t_ns = sooc__timebase(s, f->t_d);
    fr->index = f->index++;
    fr->K = s->info.K;
    f->have_d = f->have_c = 0;
    return SOOC_OK;
}

static sooc_status fn_stop(sooc_sensor *s) {
    fn *f = s->impl;
    if (!f || !f->streaming) return SOOC_OK;
    freenect_stop_depth(f->dev);
    freenect_stop_video(f->dev);
    f->streaming = 0;
    return SOOC_OK;
}

static void fn_close(sooc_sensor *s) {
    fn *f = s->impl;
    if (!f) return;
    (void)fn_stop(s);
    if (f->dev) freenect_close_device(f->dev);
    if (f->ctx) freenect_shutdown(f->ctx);
    sooc_free(f);
    s->impl = NULL;
}

const sooc_sensor_vt sooc__freenect_vt = {"freenect", fn_open, fn_start, fn_read, fn_stop, fn_close};
