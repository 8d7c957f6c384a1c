/* OpenNI2 driver through the C API (docs/drivers.md "openni2").
 *
 * - OniCAPI.h is C++-only as shipped: the typedefs below make it C11.
 * - Depth DEPTH_1_MM + colour RGB888, registration depth->colour when the
 *   device supports it, depth/colour frame sync, mirroring off.
 * - Intrinsics from the stream FOV (f = size / (2 tan(fov/2))); when the
 *   property is NOT_IMPLEMENTED (DummyDevice, some forks) the PS1080 defaults
 *   of calib/xtion.yaml are used, scaled to the resolution.
 * - Depth and colour are paired by arrival time within half a frame period
 *   (device stamps of the two streams need not share an origin); t_ns is
 *   the depth frame's device stamp.
 * - Teardown: the DummyDevice does not join its threads, so we wait 100 ms
 *   after oniStreamStop before destroying the streams (finding 0.2). */
typedef struct _OniDevice _OniDevice;
typedef struct _OniStream _OniStream;
typedef struct _OniRecorder _OniRecorder;
#include <OniCAPI.h>

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "drivers_internal.h"

#define ONI_TEARDOWN_DELAY_MS 100

static pthread_mutex_t g_oni_mu = PTHREAD_MUTEX_INITIALIZER;
static int g_oni_refs = 0;

typedef struct oni_img {
    int have;
    int64_t t_ns;       /* device stamp (µs -> ns) */
    int64_t t_host;     /* arrival, CLOCK_MONOTONIC: used for pairing */
    int index;
} oni_img;

typedef struct oni {
    OniDeviceHandle dev;
    OniStreamHandle ds, cs;   /* cs may be NULL (depth-only device) */
    OniVideoMode dmode, cmode;
    int streaming;
    int64_t tol_ns;
    double depth_scale;
    uint16_t *dbuf;           /* latest depth, w*h */
    uint8_t *cbuf;            /* latest colour at depth resolution, w*h*3 */
    oni_img dimg, cimg;
    int w, h;
} oni;

static sooc_status oni_err(sooc_status st, const char *what) {
    const char *e = oniGetExtendedError();
    return sooc_seterr(st, "openni2: %s: %s", what, e && *e ? e : "failed");
}

static void oni_release_global(void) {
    pthread_mutex_lock(&g_oni_mu);
    if (--g_oni_refs == 0) oniShutdown();
    pthread_mutex_unlock(&g_oni_mu);
}

/* Pick the supported mode of `fmt` closest to w x h @ fps. */
static int pick_mode(OniStreamHandle s, OniPixelFormat fmt, int w, int h, int fps, OniVideoMode *out) {
    const OniSensorInfo *si = oniStreamGetSensorInfo(s);
    if (!si) return 0;
    double best = 1e300;
    int found = 0;
    for (int i = 0; i < si->numSupportedVideoModes; i++) {
        const OniVideoMode *m = &si->pSupportedVideoModes[i];
        if (m->pixelFormat != fmt) continue;
        double cost = fabs((double)m->resolutionX * m->resolutionY - (double)w * h) +
                      1000.0 * fabs((double)m->fps - fps);
        if (cost < best) { best = cost; *out = *m; found = 1; }
    }
    return found;
}

static void fov_intrinsics(OniStreamHandle s, int w, int h, int registered, sooc_intrinsics *K, int *from_fov) {
    float hfov = 0, vfov = 0;
    int n1 = sizeof hfov, n2 = sizeof vfov;
    memset(K, 0, sizeof *K);
    K->width = w;
    K->height = h;
    K->cx = w / 2.0 - 0.5;
    K->cy = h / 2.0 - 0.5;
    *from_fov = 0;
    if (s && oniStreamGetProperty(s, ONI_STREAM_PROPERTY_HORIZONTAL_FOV, &hfov, &n1) == ONI_STATUS_OK &&
        oniStreamGetProperty(s, ONI_STREAM_PROPERTY_VERTICAL_FOV, &vfov, &n2) == ONI_STATUS_OK && hfov > 0.1f &&
        vfov > 0.1f && hfov < 3.0f && vfov < 3.0f) {
        K->fx = w / (2.0 * tan(hfov / 2.0));
        K->fy = h / (2.0 * tan(vfov / 2.0));
        *from_fov = 1;
        return;
    }
    /* PS1080 defaults at 640x480 (calib/xtion.yaml): depth/IR f = 575.8, colour 525. */
    double f = (registered ? 525.0 : 575.8157348632812) * (double)w / 640.0;
    K->fx = K->fy = f;
}

static sooc_status oni_open(sooc_sensor *s, const sooc_sensor_params *p) {
    pthread_mutex_lock(&g_oni_mu);
    OniStatus os = ONI_STATUS_OK;
    if (g_oni_refs == 0) os = oniInitialize(ONI_API_VERSION);
    if (os == ONI_STATUS_OK) g_oni_refs++;
    pthread_mutex_unlock(&g_oni_mu);
    if (os != ONI_STATUS_OK) return oni_err(SOOC_EIO, "oniInitialize");

    oni *o = sooc_calloc(1, sizeof *o);
    if (!o) { oni_release_global(); return SOOC_ENOMEM; }
    s->impl = o;
    sooc_status st = SOOC_OK;
    const char *uri = (p->uri && *p->uri) ? p->uri : NULL;
    if (oniDeviceOpen(uri, &o->dev) != ONI_STATUS_OK) {
        char what[300];
        snprintf(what, sizeof what, "cannot open device '%s'", uri ? uri : "(any)");
        st = oni_err(SOOC_ENOTFOUND, what);
        goto fail;
    }
    if (oniDeviceCreateStream(o->dev, ONI_SENSOR_DEPTH, &o->ds) != ONI_STATUS_OK) {
        st = oni_err(SOOC_EUNSUPPORTED, "device has no depth stream");
        goto fail;
    }
    if (oniDeviceCreateStream(o->dev, ONI_SENSOR_COLOR, &o->cs) != ONI_STATUS_OK) {
        o->cs = NULL;
        s->info.has_color = 0;
        sooc_log(SOOC_LOG_WARN, "openni2: device has no colour stream; rgb will be black");
    }
    int w = p->width > 0 ? p->width : 640, h = p->height > 0 ? p->height : 480, fps = p->fps > 0 ? p->fps : 30;
    if (!pick_mode(o->ds, ONI_PIXEL_FORMAT_DEPTH_1_MM, w, h, fps, &o->dmode)) {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "openni2: the depth stream offers no DEPTH_1_MM mode");
        goto fail;
    }
    if (oniStreamSetProperty(o->ds, ONI_STREAM_PROPERTY_VIDEO_MODE, &o->dmode, sizeof o->dmode) != ONI_STATUS_OK) {
        /* Some drivers (DummyDevice) do not implement setting the mode: keep
         * the current one if it is a depth format we read. */
        OniVideoMode cur;
        int n = sizeof cur;
        if (oniStreamGetProperty(o->ds, ONI_STREAM_PROPERTY_VIDEO_MODE, &cur, &n) != ONI_STATUS_OK ||
            (cur.pixelFormat != ONI_PIXEL_FORMAT_DEPTH_1_MM && cur.pixelFormat != ONI_PIXEL_FORMAT_DEPTH_100_UM)) {
            st = oni_err(SOOC_EUNSUPPORTED, "set depth video mode");
            goto fail;
        }
        o->dmode = cur;
    }
    if (o->cs) {
        if (!pick_mode(o->cs, ONI_PIXEL_FORMAT_RGB888, o->dmode.resolutionX, o->dmode.resolutionY, o->dmode.fps,
                       &o->cmode) ||
            oniStreamSetProperty(o->cs, ONI_STREAM_PROPERTY_VIDEO_MODE, &o->cmode, sizeof o->cmode) != ONI_STATUS_OK) {
            OniVideoMode cur;
            int n = sizeof cur;
            if (oniStreamGetProperty(o->cs, ONI_STREAM_PROPERTY_VIDEO_MODE, &cur, &n) != ONI_STATUS_OK ||
                cur.pixelFormat != ONI_PIXEL_FORMAT_RGB888) {
                st = oni_err(SOOC_EUNSUPPORTED, "colour stream: no usable RGB888 mode");
                goto fail;
            }
            o->cmode = cur;
        }
    }
    OniBool off = p->mirror ? 1 : 0;
    (void)oniStreamSetProperty(o->ds, ONI_STREAM_PROPERTY_MIRRORING, &off, sizeof off);
    if (o->cs) (void)oniStreamSetProperty(o->cs, ONI_STREAM_PROPERTY_MIRRORING, &off, sizeof off);
    int registered = 0;
    if (o->cs && p->registration &&
        oniDeviceIsImageRegistrationModeSupported(o->dev, ONI_IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
        int mode = ONI_IMAGE_REGISTRATION_DEPTH_TO_COLOR;
        registered = oniDeviceSetProperty(o->dev, ONI_DEVICE_PROPERTY_IMAGE_REGISTRATION, &mode, sizeof mode) ==
                     ONI_STATUS_OK;
    }
    if (o->cs && oniDeviceEnableDepthColorSync(o->dev) != ONI_STATUS_OK)
        sooc_log(SOOC_LOG_DEBUG, "openni2: depth/colour frame sync not available");
    /* Playback of .oni files: deterministic, no loop unless asked. */
    if (uri && oniDeviceIsPropertySupported(o->dev, ONI_DEVICE_PROPERTY_PLAYBACK_SPEED)) {
        float sp = (float)(p->speed > 0 ? p->speed : 0.0);
        OniBool rep = p->loop ? 1 : 0;
        (void)oniDeviceSetProperty(o->dev, ONI_DEVICE_PROPERTY_PLAYBACK_SPEED, &sp, sizeof sp);
        (void)oniDeviceSetProperty(o->dev, ONI_DEVICE_PROPERTY_PLAYBACK_REPEAT_ENABLED, &rep, sizeof rep);
    }
    o->w = o->dmode.resolutionX;
    o->h = o->dmode.resolutionY;
    o->dbuf = sooc_calloc((size_t)o->w * (size_t)o->h, sizeof(uint16_t));
    o->cbuf = sooc_calloc((size_t)o->w * (size_t)o->h, 3);
    if (!o->dbuf || !o->cbuf) { st = SOOC_ENOMEM; goto fail; }
    int from_fov;
    fov_intrinsics(registered ? o->cs : o->ds, o->w, o->h, registered, &s->info.K, &from_fov);
    if (!from_fov)
        sooc_log(SOOC_LOG_WARN, "openni2: FOV not reported by the device; using PS1080 default intrinsics f=%.1f",
                 s->info.K.fx);
    s->info.has_intrinsics = 1;
    s->info.width = o->w;
    s->info.height = o->h;
    s->info.fps = o->dmode.fps;
    s->info.depth_registered = registered;
    OniDeviceInfo di;
    if (oniDeviceGetInfo(o->dev, &di) == ONI_STATUS_OK)
        snprintf(s->info.device, sizeof s->info.device, "%.60s %.60s (%.120s)", di.vendor, di.name, di.uri);
    else
        snprintf(s->info.device, sizeof s->info.device, "%s", uri ? uri : "(any)");
    o->depth_scale = p->depth_scale > 0 ? p->depth_scale
                     : o->dmode.pixelFormat == ONI_PIXEL_FORMAT_DEPTH_100_UM ? 0.0001 : 0.001;
    o->tol_ns = p->pair_tol_ns > 0 ? p->pair_tol_ns : (int64_t)(0.5e9 / (o->dmode.fps > 0 ? o->dmode.fps : 30));
    return SOOC_OK;
fail:
    s->vt->close(s);
    return st;
}

static sooc_status oni_start(sooc_sensor *s) {
    oni *o = s->impl;
    if (oniStreamStart(o->ds) != ONI_STATUS_OK) return oni_err(SOOC_EIO, "start depth stream");
    if (o->cs && oniStreamStart(o->cs) != ONI_STATUS_OK) {
        oniStreamStop(o->ds);
        return oni_err(SOOC_EIO, "start colour stream");
    }
    o->streaming = 1;
    o->dimg.have = o->cimg.have = 0;
    return SOOC_OK;
}

static void store_frame(sooc_sensor *s, oni *o, OniFrame *fr) {
    int64_t t = (int64_t)fr->timestamp * 1000;   /* µs -> ns */
    if (fr->sensorType == ONI_SENSOR_DEPTH) {
        s->st.depth_in++;
        if (o->dimg.have) s->st.unpaired++;
        if (fr->width == o->w && fr->height == o->h) {
            for (int y = 0; y < o->h; y++)
                memcpy(o->dbuf + (size_t)y * (size_t)o->w, (const uint8_t *)fr->data + (size_t)y * (size_t)fr->stride,
                       (size_t)o->w * 2);
        }
        if (o->dimg.have && fr->frameIndex > o->dimg.index + 1) s->st.dropped += fr->frameIndex - o->dimg.index - 1;
        o->dimg.have = 1;
        o->dimg.t_ns = t;
        o->dimg.t_host = sooc_now_ns();
        o->dimg.index = fr->frameIndex;
    } else {
        s->st.color_in++;
        if (o->cimg.have) s->st.unpaired++;
        /* nearest-neighbour resample to the depth resolution if needed */
        for (int y = 0; y < o->h; y++) {
            int sy = (int)((int64_t)y * fr->height / o->h);
            const uint8_t *row = (const uint8_t *)fr->data + (size_t)sy * (size_t)fr->stride;
            uint8_t *d = o->cbuf + (size_t)y * (size_t)o->w * 3;
            if (fr->width == o->w) {
                memcpy(d, row, (size_t)o->w * 3);
            } else {
                for (int x = 0; x < o->w; x++) {
                    int sx = (int)((int64_t)x * fr->width / o->w);
                    memcpy(d + 3 * x, row + 3 * sx, 3);
                }
            }
        }
        o->cimg.have = 1;
        o->cimg.t_ns = t;
        o->cimg.t_host = sooc_now_ns();
        o->cimg.index = fr->frameIndex;
    }
}

static sooc_status oni_read(sooc_sensor *s, sooc_frame *f, int timeout_ms) {
    oni *o = s->impl;
    if (!o->streaming) return sooc_seterr(SOOC_EINVAL, "openni2: not started");
    int64_t deadline = timeout_ms < 0 ? INT64_MAX : sooc_now_ns() + (int64_t)timeout_ms * 1000000;
    OniStreamHandle streams[2] = {o->ds, o->cs};
    int ns = o->cs ? 2 : 1;
    for (;;) {
        int ready = o->dimg.have && (!o->cs || o->cimg.have);
        if (ready && o->cs) {
            /* Pair by arrival time: device stamps of the two streams need not share
             * an origin (DummyDevice counts frames per stream from its own start). */
            int64_t dt = o->dimg.t_host - o->cimg.t_host;
            if (dt > o->tol_ns) { o->cimg.have = 0; s->st.unpaired++; ready = 0; }        /* colour too old */
            else if (-dt > o->tol_ns) { o->dimg.have = 0; s->st.unpaired++; ready = 0; }  /* depth too old  */
        }
        if (ready) break;
        if (sooc__interrupted(s)) return sooc_seterr(SOOC_EINTERRUPTED, "openni2: interrupted");
        int64_t now = sooc_now_ns();
        if (now >= deadline) return SOOC_ETIMEOUT;
        int slice = (int)((deadline - now) / 1000000);
        if (slice > 50) slice = 50;
        int idx = -1;
        OniStatus os = oniWaitForAnyStream(streams, ns, &idx, slice);
        if (os == ONI_STATUS_TIME_OUT) continue;
        if (os != ONI_STATUS_OK || idx < 0 || idx >= ns) return oni_err(SOOC_EIO, "oniWaitForAnyStream");
        OniFrame *fr = NULL;
        if (oniStreamReadFrame(streams[idx], &fr) != ONI_STATUS_OK || !fr) {
            s->st.errors++;
            continue;
        }
        store_frame(s, o, fr);
        oniFrameRelease(fr);
    }
    sooc_status st = sooc__frame_ensure(f, o->w, o->h);
    if (st) return st;
    sooc__depth_u16_to_m(f, o->dbuf, o->w * 2, o->depth_scale, s->p.depth_min, s->p.depth_max);
    memcpy(f->rgb, o->cbuf, (size_t)o->w * (size_t)o->h * 3);
    f->t_ns = sooc__timebase(s, o->dimg.t_ns);
    f->index = o->dimg.index;
    f->K = s->info.K;
    o->dimg.have = o->cimg.have = 0;
    return SOOC_OK;
}

static sooc_status oni_stop(sooc_sensor *s) {
    oni *o = s->impl;
    if (!o || !o->streaming) return SOOC_OK;
    if (o->cs) oniStreamStop(o->cs);
    oniStreamStop(o->ds);
    o->streaming = 0;
    /* DummyDevice: wait for its (never joined) threads to finish a frame. */
    struct timespec ts = {0, ONI_TEARDOWN_DELAY_MS * 1000000L};
    nanosleep(&ts, NULL);
    return SOOC_OK;
}

static void oni_close(sooc_sensor *s) {
    oni *o = s->impl;
    if (!o) return;
    (void)oni_stop(s);
    if (o->cs) oniStreamDestroy(o->cs);
    if (o->ds) oniStreamDestroy(o->ds);
    if (o->dev) oniDeviceClose(o->dev);
    sooc_free(o->dbuf);
    sooc_free(o->cbuf);
    sooc_free(o);
    s->impl = NULL;
    oni_release_global();
}

const sooc_sensor_vt sooc__openni2_vt = {"openni2", oni_open, oni_start, oni_read, oni_stop, oni_close};
