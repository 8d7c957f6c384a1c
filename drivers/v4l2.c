/* V4L2 driver: raw mmap streaming from a depth node (Z16, or Y16 when
 * configured) paired by timestamp with an optional colour node (RGB24, BGR24,
 * YUYV, or MJPEG decoded with libjpeg-turbo through the data module's
 * sooc_jpeg_decode), docs/drivers.md "v4l2". A corrupt or
 * truncated MJPEG frame is counted in stats.errors and dropped; the stream
 * goes on. All syscalls go through a sooc_v4l2_ops table so
 * tests can replace the device with a fake (tests/drivers/test_v4l2.c).
 *
 * Pairing: the newest image of each node is kept; a pair is emitted when the
 * two buffer timestamps are within pair_tol (default half a frame period);
 * otherwise the older image is discarded (counted as unpaired). Sequence
 * gaps reported by the driver count as dropped. V4L2 does not expose
 * intrinsics (RealSense keeps them in extension units): give a calib file. */
#include <errno.h>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include "drivers_internal.h"
#include "sooc3d/core.h"

#define V4L_MAX_BUFS 8

/* ---- real syscalls ---- */
static int r_open(void *u, const char *path, int flags) { (void)u; return open(path, flags); }
static int r_close(void *u, int fd) { (void)u; return close(fd); }
static int r_ioctl(void *u, int fd, unsigned long req, void *arg) { (void)u; return ioctl(fd, req, arg); }
static void *r_mmap(void *u, void *addr, size_t len, int prot, int flags, int fd, int64_t off) {
    (void)u;
    return mmap(addr, len, prot, flags, fd, (off_t)off);
}
static int r_munmap(void *u, void *addr, size_t len) { (void)u; return munmap(addr, len); }
static int r_poll(void *u, struct pollfd *fds, unsigned long n, int t) { (void)u; return poll(fds, (nfds_t)n, t); }
static const sooc_v4l2_ops g_real_ops = {NULL, r_open, r_close, r_ioctl, r_mmap, r_munmap, r_poll};

typedef struct v4l_node {
    char path[256];
    int fd;
    int is_depth;
    uint32_t fourcc;
    int w, h, bpl;
    int nbuf;
    void *start[V4L_MAX_BUFS];
    size_t len[V4L_MAX_BUFS];
    int streaming;
    int have_seq;
    uint32_t last_seq;
    /* newest image */
    int have;
    int64_t t_ns;
    uint32_t seq;
} v4l_node;

typedef struct v4l {
    const sooc_v4l2_ops *ops;
    v4l_node n[2];      /* 0 depth, 1 colour */
    int nn;
    uint16_t *dbuf;     /* depth w*h */
    uint8_t *cbuf;      /* colour resampled to depth size */
    sooc_image jimg;    /* decoded MJPEG frame (buffer reused while the size stays) */
    int64_t jpeg_errors;
    int64_t tol_ns;
    double depth_scale;
    int64_t index;
} v4l;

static const char *fourcc_str(uint32_t f, char out[5]) {
    for (int i = 0; i < 4; i++) {
        char c = (char)((f >> (8 * i)) & 0xff);
        out[i] = (c >= 32 && c < 127) ? c : '?';
    }
    out[4] = '\0';
    return out;
}

static int xioctl(v4l *v, int fd, unsigned long req, void *arg) {
    int r;
    do r = v->ops->ioctl(v->ops->user, fd, req, arg);
    while (r < 0 && errno == EINTR);
    return r;
}

/* A zeroed memory-mapped capture buffer descriptor for QUERYBUF/QBUF/DQBUF. */
static void mmap_buf_init(struct v4l2_buffer *b, int index) {
    memset(b, 0, sizeof *b);
    b->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b->memory = V4L2_MEMORY_MMAP;
    b->index = (uint32_t)index;
}

static sooc_status node_open(v4l *v, v4l_node *nd, const char *path, int is_depth, const sooc_sensor_params *p) {
    snprintf(nd->path, sizeof nd->path, "%s", path);
    nd->is_depth = is_depth;
    nd->fd = v->ops->open(v->ops->user, path, O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (nd->fd < 0) {
        int e = errno;
        return sooc_seterr(e == ENOENT || e == ENODEV || e == ENXIO ? SOOC_ENOTFOUND : SOOC_EIO, "v4l2: %s: %s%s", path,
                           strerror(e), e == EACCES ? " (add the user to group video)" : "");
    }
    struct v4l2_capability cap;
    memset(&cap, 0, sizeof cap);
    if (xioctl(v, nd->fd, VIDIOC_QUERYCAP, &cap) < 0)
        return sooc_seterr(SOOC_EUNSUPPORTED, "v4l2: %s: not a V4L2 device (QUERYCAP: %s)", path, strerror(errno));
    uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (caps & V4L2_CAP_META_CAPTURE && !(caps & V4L2_CAP_VIDEO_CAPTURE))
        return sooc_seterr(SOOC_EUNSUPPORTED, "v4l2: %s is a metadata node, not a video node", path);
    if (!(caps & V4L2_CAP_VIDEO_CAPTURE) || !(caps & V4L2_CAP_STREAMING))
        return sooc_seterr(SOOC_EUNSUPPORTED, "v4l2: %s: no video capture with streaming I/O", path);
    /* Pick the pixel format. */
    uint32_t want[4];
    int nwant = 0;
    if (is_depth) {
        const char *df = p->depth_format && *p->depth_format ? p->depth_format : "Z16";
        if (!strcmp(df, "Y16")) want[nwant++] = V4L2_PIX_FMT_Y16;
        else if (!strcmp(df, "Z16") || !strcmp(df, "auto")) want[nwant++] = V4L2_PIX_FMT_Z16;
        else return sooc_seterr(SOOC_EINVAL, "v4l2: depth_format '%s' (Z16|Y16)", df);
    } else {
        want[nwant++] = V4L2_PIX_FMT_RGB24;
        want[nwant++] = V4L2_PIX_FMT_BGR24;
        want[nwant++] = V4L2_PIX_FMT_YUYV;
        want[nwant++] = V4L2_PIX_FMT_MJPEG; /* last: uncompressed needs no decode */
    }
    uint32_t offered[64];
    int noff = 0;
    for (int i = 0; i < 64; i++) {
        struct v4l2_fmtdesc fd;
        memset(&fd, 0, sizeof fd);
        fd.index = (uint32_t)i;
        fd.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (xioctl(v, nd->fd, VIDIOC_ENUM_FMT, &fd) < 0) break;
        offered[noff++] = fd.pixelformat;
    }
    nd->fourcc = 0;
    for (int k = 0; k < nwant && !nd->fourcc; k++)
        for (int i = 0; i < noff; i++)
            if (offered[i] == want[k]) { nd->fourcc = want[k]; break; }
    if (!nd->fourcc) {
        char list[64 * 6] = "", t[5];
        for (int i = 0; i < noff; i++) {
            strcat(list, fourcc_str(offered[i], t));
            if (i + 1 < noff) strcat(list, ",");
        }
        return sooc_seterr(SOOC_EUNSUPPORTED, "v4l2: %s offers [%s], none of the %s formats we read (%s)", path, list,
                           is_depth ? "depth" : "colour", is_depth ? "Z16, or Y16 with depth_format=Y16"
                           : "RGB3,BGR3,YUYV,MJPG");
    }
    struct v4l2_format fmt;
    memset(&fmt, 0, sizeof fmt);
    fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    fmt.fmt.pix.width = (uint32_t)(p->width > 0 ? p->width : 640);
    fmt.fmt.pix.height = (uint32_t)(p->height > 0 ? p->height : 480);
    fmt.fmt.pix.pixelformat = nd->fourcc;
    fmt.fmt.pix.field = V4L2_FIELD_NONE;
    if (xioctl(v, nd->fd, VIDIOC_S_FMT, &fmt) < 0)
        return sooc_seterr(SOOC_EIO, "v4l2: %s: S_FMT: %s", path, strerror(errno));
    if (fmt.fmt.pix.pixelformat != nd->fourcc) {
        char a[5], b[5];
        return sooc_seterr(SOOC_EUNSUPPORTED, "v4l2: %s: asked %s, driver set %s", path, fourcc_str(nd->fourcc, a),
                           fourcc_str(fmt.fmt.pix.pixelformat, b));
    }
    nd->w = (int)fmt.fmt.pix.width;
    nd->h = (int)fmt.fmt.pix.height;
    int bpp = nd->fourcc == V4L2_PIX_FMT_RGB24 || nd->fourcc == V4L2_PIX_FMT_BGR24 ? 3 : 2;
    int compressed = nd->fourcc == V4L2_PIX_FMT_MJPEG;
    nd->bpl = compressed ? 0 : fmt.fmt.pix.bytesperline ? (int)fmt.fmt.pix.bytesperline : nd->w * bpp;
    if (nd->w <= 0 || nd->h <= 0 || (!compressed && nd->bpl < nd->w * bpp))
        return sooc_seterr(SOOC_EFORMAT, "v4l2: %s: bad format %dx%d bytesperline %d", path, nd->w, nd->h, nd->bpl);
    if (p->fps > 0) {
        struct v4l2_streamparm parm;
        memset(&parm, 0, sizeof parm);
        parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        parm.parm.capture.timeperframe.numerator = 1;
        parm.parm.capture.timeperframe.denominator = (uint32_t)p->fps;
        if (xioctl(v, nd->fd, VIDIOC_S_PARM, &parm) < 0)
            sooc_log(SOOC_LOG_WARN, "v4l2: %s: cannot set %d fps (%s)", path, p->fps, strerror(errno));
    }
    struct v4l2_requestbuffers rb;
    memset(&rb, 0, sizeof rb);
    rb.count = 4;
    rb.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    rb.memory = V4L2_MEMORY_MMAP;
    if (xioctl(v, nd->fd, VIDIOC_REQBUFS, &rb) < 0 || rb.count < 2)
        return sooc_seterr(SOOC_EIO, "v4l2: %s: REQBUFS mmap: %s", path, rb.count < 2 ? "too few buffers" : strerror(errno));
    nd->nbuf = rb.count > V4L_MAX_BUFS ? V4L_MAX_BUFS : (int)rb.count;
    for (int i = 0; i < nd->nbuf; i++) {
        struct v4l2_buffer b;
        mmap_buf_init(&b, i);
        if (xioctl(v, nd->fd, VIDIOC_QUERYBUF, &b) < 0)
            return sooc_seterr(SOOC_EIO, "v4l2: %s: QUERYBUF %d: %s", path, i, strerror(errno));
        void *m = v->ops->mmap(v->ops->user, NULL, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, nd->fd, b.m.offset);
        if (m == MAP_FAILED) return sooc_seterr(SOOC_EIO, "v4l2: %s: mmap buffer %d: %s", path, i, strerror(errno));
        nd->start[i] = m;
        nd->len[i] = b.length;
        if ((size_t)nd->bpl * (size_t)nd->h > b.length)
            return sooc_seterr(SOOC_EFORMAT, "v4l2: %s: buffer %u bytes < image %d bytes", path, b.length, nd->bpl * nd->h);
    }
    return SOOC_OK;
}

static void node_close(v4l *v, v4l_node *nd) {
    if (nd->fd < 0) return;
    if (nd->streaming) {
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        (void)xioctl(v, nd->fd, VIDIOC_STREAMOFF, &type);
        nd->streaming = 0;
    }
    for (int i = 0; i < nd->nbuf; i++)
        if (nd->start[i]) v->ops->munmap(v->ops->user, nd->start[i], nd->len[i]);
    nd->nbuf = 0;
    if (nd->fd >= 0) {
        /* release the buffers (count 0) before closing */
        v->ops->close(v->ops->user, nd->fd);
    }
    nd->fd = -1;
}

static void v4l_close(sooc_sensor *s);

static sooc_status v4l_open(sooc_sensor *s, const sooc_sensor_params *p) {
    v4l *v = sooc_calloc(1, sizeof *v);
    if (!v) return SOOC_ENOMEM;
    s->impl = v;
    v->ops = p->v4l2_ops ? p->v4l2_ops : &g_real_ops;
    v->n[0].fd = v->n[1].fd = -1;
    sooc_status st;
    if (!p->uri || !*p->uri) {
        st = sooc_seterr(SOOC_EINVAL, "v4l2: no depth node (sensor.uri, e.g. /dev/video0)");
        goto fail;
    }
    if ((st = node_open(v, &v->n[0], p->uri, 1, p))) goto fail;
    v->nn = 1;
    if (p->uri2 && *p->uri2) {
        if ((st = node_open(v, &v->n[1], p->uri2, 0, p))) goto fail;
        v->nn = 2;
    } else {
        s->info.has_color = 0;
    }
    int w = v->n[0].w, h = v->n[0].h;
    v->dbuf = sooc_calloc((size_t)w * (size_t)h, sizeof(uint16_t));
    v->cbuf = sooc_calloc((size_t)w * (size_t)h, 3);
    if (!v->dbuf || !v->cbuf) { st = SOOC_ENOMEM; goto fail; }
    int fps = p->fps > 0 ? p->fps : 30;
    v->tol_ns = p->pair_tol_ns > 0 ? p->pair_tol_ns : (int64_t)(0.5e9 / fps);
    v->depth_scale = p->depth_scale > 0 ? p->depth_scale : 0.001;
    s->info.width = w;
    s->info.height = h;
    s->info.fps = fps;
    s->info.has_intrinsics = 0;
    s->info.depth_registered = 0;
    snprintf(s->info.device, sizeof s->info.device, "%s%s%s", p->uri, v->nn > 1 ? " + " : "", v->nn > 1 ? p->uri2 : "");
    return SOOC_OK;
fail:
    v4l_close(s);
    return st;
}

static sooc_status v4l_start(sooc_sensor *s) {
    v4l *v = s->impl;
    for (int k = 0; k < v->nn; k++) {
        v4l_node *nd = &v->n[k];
        for (int i = 0; i < nd->nbuf; i++) {
            struct v4l2_buffer b;
            mmap_buf_init(&b, i);
            if (xioctl(v, nd->fd, VIDIOC_QBUF, &b) < 0)
                return sooc_seterr(SOOC_EIO, "v4l2: %s: QBUF: %s", nd->path, strerror(errno));
        }
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (xioctl(v, nd->fd, VIDIOC_STREAMON, &type) < 0)
            return sooc_seterr(SOOC_EIO, "v4l2: %s: STREAMON: %s", nd->path, strerror(errno));
        nd->streaming = 1;
        nd->have = 0;
        nd->have_seq = 0;
    }
    return SOOC_OK;
}

/* Dequeue every ready buffer of node k, keep the newest image. */
static sooc_status drain(sooc_sensor *s, v4l *v, int k) {
    v4l_node *nd = &v->n[k];
    for (;;) {
        struct v4l2_buffer b;
        mmap_buf_init(&b, 0);
        if (xioctl(v, nd->fd, VIDIOC_DQBUF, &b) < 0) {
            if (errno == EAGAIN) { return SOOC_OK; }
            if (errno == EIO) { s->st.errors++; return SOOC_OK; }  /* transient, buffer flagged error */
            return sooc_seterr(SOOC_EIO, "v4l2: %s: DQBUF: %s", nd->path, strerror(errno));
        }
        if (b.index >= (uint32_t)nd->nbuf) return sooc_seterr(SOOC_EIO, "v4l2: %s: DQBUF bad index %u", nd->path, b.index);
        if (k == 0) s->st.depth_in++; else s->st.color_in++;
        if (nd->have_seq && b.sequence > nd->last_seq + 1) s->st.dropped += b.sequence - nd->last_seq - 1;
        nd->have_seq = 1;
        nd->last_seq = b.sequence;
        int ok = !(b.flags & V4L2_BUF_FLAG_ERROR) && b.bytesused >= (uint32_t)(nd->bpl * (nd->h - 1)) &&
                 b.bytesused > 0 && b.bytesused <= nd->len[b.index];
        const uint8_t *src = nd->start[b.index];
        int W = v->n[0].w, H = v->n[0].h;
        if (ok && nd->fourcc == V4L2_PIX_FMT_MJPEG) {
            sooc_status js = sooc_jpeg_decode(src, b.bytesused, nd->path, &v->jimg);
            if (!js && (v->jimg.width != nd->w || v->jimg.height != nd->h))
                js = sooc_seterr(SOOC_EFORMAT, "%s: MJPEG frame is %dx%d, the format says %dx%d", nd->path,
                                 v->jimg.width, v->jimg.height, nd->w, nd->h);
            if (js) {
                if (v->jpeg_errors++ < 3) sooc_log(SOOC_LOG_WARN, "v4l2: frame %u dropped: %s", b.sequence, sooc_errmsg());
                ok = 0;
            }
        }
        if (!ok) {
            s->st.errors++;
        } else {
            if (nd->have) s->st.unpaired++;   /* the previous image was never paired */
            if (nd->fourcc == V4L2_PIX_FMT_MJPEG) {
                /* decoded RGB8 (or GRAY8) -> colour at the depth size, nearest neighbour */
                const uint8_t *img = v->jimg.data;
                int gray = v->jimg.fmt == SOOC_PIX_GRAY8, bp = gray ? 1 : 3;
                for (int y = 0; y < H; y++) {
                    const uint8_t *row = img + (size_t)((int64_t)y * nd->h / H) * (size_t)nd->w * (size_t)bp;
                    uint8_t *d = v->cbuf + (size_t)y * (size_t)W * 3;
                    for (int x = 0; x < W; x++) {
                        const uint8_t *px = row + (size_t)((int64_t)x * nd->w / W) * (size_t)bp;
                        d[3 * x] = px[0];
                        d[3 * x + 1] = px[gray ? 0 : 1];
                        d[3 * x + 2] = px[gray ? 0 : 2];
                    }
                }
            } else
            if (k == 0) {
                for (int y = 0; y < H; y++) memcpy(v->dbuf + (size_t)y * (size_t)W, src + (size_t)y * (size_t)nd->bpl, (size_t)W * 2);
            } else if (nd->w == W && nd->h == H) {
                if (nd->fourcc == V4L2_PIX_FMT_YUYV) sooc__yuyv_to_rgb(v->cbuf, src, W, H, nd->bpl);
                else sooc__rgb_copy(v->cbuf, src, W, H, nd->bpl, nd->fourcc == V4L2_PIX_FMT_BGR24);
            } else {
                /* nearest-neighbour resample to the depth size */
                for (int y = 0; y < H; y++) {
                    int sy = (int)((int64_t)y * nd->h / H);
                    const uint8_t *row = src + (size_t)sy * (size_t)nd->bpl;
                    uint8_t *d = v->cbuf + (size_t)y * (size_t)W * 3;
                    for (int x = 0; x < W; x++) {
                        int sx = (int)((int64_t)x * nd->w / W);
                        if (nd->fourcc == V4L2_PIX_FMT_YUYV) {
                            uint8_t px[4] = {row[2 * sx], row[4 * (sx / 2) + 1], row[2 * sx], row[4 * (sx / 2) + 3]};
                            uint8_t rgb2[6];
                            sooc__yuyv_to_rgb(rgb2, px, 2, 1, 4);
                            memcpy(d + 3 * x, rgb2, 3);
                        } else {
                            int bgr = nd->fourcc == V4L2_PIX_FMT_BGR24;
                            d[3 * x] = row[3 * sx + (bgr ? 2 : 0)];
                            d[3 * x + 1] = row[3 * sx + 1];
                            d[3 * x + 2] = row[3 * sx + (bgr ? 0 : 2)];
                        }
                    }
                }
            }
            nd->have = 1;
            nd->t_ns = (int64_t)b.timestamp.tv_sec * 1000000000 + (int64_t)b.timestamp.tv_usec * 1000;
            nd->seq = b.sequence;
        }
        if (xioctl(v, nd->fd, VIDIOC_QBUF, &b) < 0)
            return sooc_seterr(SOOC_EIO, "v4l2: %s: re-QBUF: %s", nd->path, strerror(errno));
    }
}

static sooc_status v4l_read(sooc_sensor *s, sooc_frame *f, int timeout_ms) {
    v4l *v = s->impl;
    int64_t deadline = timeout_ms < 0 ? INT64_MAX : sooc_now_ns() + (int64_t)timeout_ms * 1000000;
    for (;;) {
        int ready = v->n[0].have && (v->nn < 2 || v->n[1].have);
        if (ready && v->nn == 2) {
            int64_t dt = v->n[0].t_ns - v->n[1].t_ns;
            if (dt > v->tol_ns) { v->n[1].have = 0; s->st.unpaired++; ready = 0; }
            else if (-dt > v->tol_ns) { v->n[0].have = 0; s->st.unpaired++; ready = 0; }
        }
        if (ready) break;
        if (sooc__interrupted(s)) return sooc_seterr(SOOC_EINTERRUPTED, "v4l2: interrupted");
        int64_t now = sooc_now_ns();
        if (now >= deadline) return SOOC_ETIMEOUT;
        int slice = (int)((deadline - now + 999999) / 1000000);
        if (slice > 50) slice = 50;
        struct pollfd pfd[2];
        for (int k = 0; k < v->nn; k++) pfd[k] = (struct pollfd){.fd = v->n[k].fd, .events = POLLIN};
        int r = v->ops->poll(v->ops->user, pfd, (unsigned long)v->nn, slice);
        if (r < 0) {
            if (errno == EINTR || errno == EAGAIN) { s->st.errors++; continue; }
            return sooc_seterr(SOOC_EIO, "v4l2: poll: %s", strerror(errno));
        }
        for (int k = 0; k < v->nn; k++) {
            if (pfd[k].revents & (POLLERR | POLLHUP | POLLNVAL))
                return sooc_seterr(SOOC_EIO, "v4l2: %s: device error or unplugged", v->n[k].path);
            if (pfd[k].revents & POLLIN) {
                sooc_status st = drain(s, v, k);
                if (st) return st;
            }
        }
    }
    int W = v->n[0].w, H = v->n[0].h;
    sooc_status st = sooc__frame_ensure(f, W, H);
    if (st) return st;
    sooc__depth_u16_to_m(f, v->dbuf, W * 2, v->depth_scale, s->p.depth_min, s->p.depth_max);
    if (v->nn == 2) memcpy(f->rgb, v->cbuf, (size_t)W * (size_t)H * 3);
    else memset(f->rgb, 0, (size_t)W * (size_t)H * 3);
    f->t_ns = sooc__timebase(s, v->n[0].t_ns);
    f->index = v->index++;
    v->n[0].have = v->n[1].have = 0;
    return SOOC_OK;
}

static sooc_status v4l_stop(sooc_sensor *s) {
    v4l *v = s->impl;
    if (!v) return SOOC_OK;
    for (int k = 0; k < v->nn; k++) {
        v4l_node *nd = &v->n[k];
        if (!nd->streaming) continue;
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        (void)xioctl(v, nd->fd, VIDIOC_STREAMOFF, &type);
        nd->streaming = 0;
    }
    return SOOC_OK;
}

static void v4l_close(sooc_sensor *s) {
    v4l *v = s->impl;
    if (!v) return;
    for (int k = 0; k < 2; k++) node_close(v, &v->n[k]);
    sooc_free(v->dbuf);
    sooc_free(v->cbuf);
    sooc_image_free(&v->jimg);
    sooc_free(v);
    s->impl = NULL;
}

const sooc_sensor_vt sooc__v4l2_vt = {"v4l2", v4l_open, v4l_start, v4l_read, v4l_stop, v4l_close};
