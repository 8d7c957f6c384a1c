/* V4L2 driver through a fake device at the ioctl level (sooc_v4l2_ops):
 * format negotiation, mmap buffers, padded strides, YUYV conversion, pairing
 * RGB and depth by timestamp, sequence gaps (dropped), EAGAIN/EINTR, and the
 * error paths (missing node, wrong formats, metadata node). */
#include <errno.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "check.h"
#include "sooc3d/driver.h"
#include "sooc3d/core.h"
/* MJPEG frames by sequence number, made by the test (hand-made JPEGs in memory) */
static void *g_jpg[32];
static size_t g_jpgn[32];

#define MAXEV 64
#define PERIOD_NS 33333333LL

typedef struct fev {
    uint32_t seq;
    int64_t t_ns;
    int spurious;   /* poll says ready but the first DQBUF gives EAGAIN */
} fev;

typedef struct fnode {
    const char *path;
    int fd;
    uint32_t caps;
    uint32_t fmts[4];
    int nfmt;
    int w, h, bpl, bpp;
    uint32_t cur_fmt;
    int nbuf;
    uint8_t *buf[4];
    size_t len;
    int queued[4];
    int streaming;
    fev ev[MAXEV];
    int nev, next;
    int opened;
} fnode;

typedef struct fake {
    fnode n[3];
    int nn;
    int eintr_once;
    int64_t vnow;   /* virtual clock: advanced by poll to the next event */
    int n_mmap, n_munmap, n_close;
} fake;

static fnode *by_fd(fake *fk, int fd) {
    for (int i = 0; i < fk->nn; i++)
        if (fk->n[i].opened && fk->n[i].fd == fd) return &fk->n[i];
    return NULL;
}

static int f_open(void *u, const char *path, int flags) {
    fake *fk = u;
    (void)flags;
    for (int i = 0; i < fk->nn; i++)
        if (!strcmp(fk->n[i].path, path)) {
            fk->n[i].opened = 1;
            fk->n[i].fd = 100 + i;
            return fk->n[i].fd;
        }
    errno = ENOENT;
    return -1;
}

static int f_close(void *u, int fd) {
    fake *fk = u;
    fnode *n = by_fd(fk, fd);
    if (!n) { errno = EBADF; return -1; }
    n->opened = 0;
    for (int i = 0; i < n->nbuf; i++) { free(n->buf[i]); n->buf[i] = NULL; }
    n->nbuf = 0;
    fk->n_close++;
    return 0;
}

/* The node whose next event is earliest (global time order), or NULL. */
static fnode *next_node(fake *fk) {
    fnode *best = NULL;
    for (int i = 0; i < fk->nn; i++) {
        fnode *n = &fk->n[i];
        if (!n->opened || !n->streaming || n->next >= n->nev) continue;
        if (!best || n->ev[n->next].t_ns < best->ev[best->next].t_ns) best = n;
    }
    return best;
}

static void fill(fnode *n, uint8_t *dst, uint32_t seq) {
    memset(dst, 0xEE, n->len);   /* padding bytes must never be read as pixels */
    for (int y = 0; y < n->h; y++) {
        uint8_t *row = dst + (size_t)y * n->bpl;
        for (int x = 0; x < n->w; x++) {
            if (n->cur_fmt == V4L2_PIX_FMT_Z16 || n->cur_fmt == V4L2_PIX_FMT_Y16) {
                uint16_t v = (uint16_t)(1000 + seq);
                if (x == 0 && y == 0) v = 0;
                memcpy(row + 2 * x, &v, 2);
            } else if (n->cur_fmt == V4L2_PIX_FMT_MJPEG) {
                if (x == 0 && y == 0 && seq < 32 && g_jpg[seq]) memcpy(dst, g_jpg[seq], g_jpgn[seq]);
                x = n->w; /* compressed: the whole frame is written once */
            } else if (n->cur_fmt == V4L2_PIX_FMT_YUYV) {
                row[2 * x] = (uint8_t)(16 + 5 * seq);     /* Y  */
                row[2 * x + 1] = 128;                      /* U or V */
            } else {
                row[3 * x] = (uint8_t)seq; row[3 * x + 1] = 1; row[3 * x + 2] = 2;
            }
        }
    }
}

static int f_ioctl(void *u, int fd, unsigned long req, void *arg) {
    fake *fk = u;
    fnode *n = by_fd(fk, fd);
    if (!n) { errno = EBADF; return -1; }
    switch (req) {
    case VIDIOC_QUERYCAP: {
        struct v4l2_capability *c = arg;
        memset(c, 0, sizeof *c);
        strcpy((char *)c->driver, "fake");
        strcpy((char *)c->bus_info, "usb-0000:00:14.0-1");
        c->capabilities = n->caps | V4L2_CAP_DEVICE_CAPS;
        c->device_caps = n->caps;
        return 0;
    }
    case VIDIOC_ENUM_FMT: {
        struct v4l2_fmtdesc *d = arg;
        if (d->index >= (uint32_t)n->nfmt) { errno = EINVAL; return -1; }
        d->pixelformat = n->fmts[d->index];
        return 0;
    }
    case VIDIOC_S_FMT: {
        struct v4l2_format *f = arg;
        int ok = 0;
        for (int i = 0; i < n->nfmt; i++) ok |= n->fmts[i] == f->fmt.pix.pixelformat;
        n->cur_fmt = ok ? f->fmt.pix.pixelformat : n->fmts[0];
        n->bpp = n->cur_fmt == V4L2_PIX_FMT_RGB24 || n->cur_fmt == V4L2_PIX_FMT_BGR24 ||
                 n->cur_fmt == V4L2_PIX_FMT_MJPEG ? 3 : 2;
        n->bpl = n->w * n->bpp + 16;   /* padded rows */
        f->fmt.pix.pixelformat = n->cur_fmt;
        f->fmt.pix.width = (uint32_t)n->w;    /* the device has one size */
        f->fmt.pix.height = (uint32_t)n->h;
        /* compressed formats report bytesperline 0 and a worst-case sizeimage */
        f->fmt.pix.bytesperline = n->cur_fmt == V4L2_PIX_FMT_MJPEG ? 0 : (uint32_t)n->bpl;
        f->fmt.pix.sizeimage = (uint32_t)(n->bpl * n->h);
        return 0;
    }
    case VIDIOC_S_PARM: return 0;
    case VIDIOC_REQBUFS: {
        struct v4l2_requestbuffers *r = arg;
        if (r->memory != V4L2_MEMORY_MMAP) { errno = EINVAL; return -1; }
        n->nbuf = r->count > 4 ? 4 : (int)r->count;
        r->count = (uint32_t)n->nbuf;
        n->len = (size_t)n->bpl * n->h;
        for (int i = 0; i < n->nbuf; i++) { n->buf[i] = calloc(1, n->len); n->queued[i] = 0; }
        return 0;
    }
    case VIDIOC_QUERYBUF: {
        struct v4l2_buffer *b = arg;
        if (b->index >= (uint32_t)n->nbuf) { errno = EINVAL; return -1; }
        b->length = (uint32_t)n->len;
        b->m.offset = b->index * 4096u;
        return 0;
    }
    case VIDIOC_QBUF: {
        struct v4l2_buffer *b = arg;
        if (b->index >= (uint32_t)n->nbuf || n->queued[b->index]) { errno = EINVAL; return -1; }
        n->queued[b->index] = 1;
        return 0;
    }
    case VIDIOC_DQBUF: {
        struct v4l2_buffer *b = arg;
        if (!n->streaming || n->next >= n->nev || n->ev[n->next].t_ns > fk->vnow) { errno = EAGAIN; return -1; }
        fev *e = &n->ev[n->next];
        if (e->spurious) { e->spurious = 0; errno = EAGAIN; return -1; }
        int idx = -1;
        for (int i = 0; i < n->nbuf; i++) if (n->queued[i]) { idx = i; break; }
        if (idx < 0) { errno = EAGAIN; return -1; }
        n->queued[idx] = 0;
        fill(n, n->buf[idx], e->seq);
        b->index = (uint32_t)idx;
        b->bytesused = (uint32_t)n->len;
        if (n->cur_fmt == V4L2_PIX_FMT_MJPEG) b->bytesused = e->seq < 32 ? (uint32_t)g_jpgn[e->seq] : 0;
        b->sequence = e->seq;
        b->flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
        b->timestamp.tv_sec = e->t_ns / 1000000000;
        b->timestamp.tv_usec = (e->t_ns % 1000000000) / 1000;
        n->next++;
        return 0;
    }
    case VIDIOC_STREAMON: n->streaming = 1; return 0;
    case VIDIOC_STREAMOFF: n->streaming = 0; return 0;
    default: errno = ENOTTY; return -1;
    }
}

static void *f_mmap(void *u, void *addr, size_t len, int prot, int flags, int fd, int64_t off) {
    fake *fk = u;
    (void)addr; (void)len; (void)prot; (void)flags;
    fnode *n = by_fd(fk, fd);
    if (!n || off % 4096 || off / 4096 >= n->nbuf) { errno = EINVAL; return MAP_FAILED; }
    fk->n_mmap++;
    return n->buf[off / 4096];
}

static int f_munmap(void *u, void *addr, size_t len) {
    fake *fk = u;
    (void)addr; (void)len;
    fk->n_munmap++;
    return 0;
}

static int f_poll(void *u, struct pollfd *fds, unsigned long nfds, int timeout_ms) {
    fake *fk = u;
    (void)timeout_ms;
    if (fk->eintr_once) { fk->eintr_once = 0; errno = EINTR; return -1; }
    fnode *nx = next_node(fk);
    if (nx && nx->ev[nx->next].t_ns > fk->vnow) fk->vnow = nx->ev[nx->next].t_ns;   /* "wait" for it */
    int r = 0;
    for (unsigned long i = 0; i < nfds; i++) {
        fnode *n = by_fd(fk, fds[i].fd);
        fds[i].revents = 0;
        if (n && n->streaming && n->next < n->nev && n->ev[n->next].t_ns <= fk->vnow) { fds[i].revents = POLLIN; r++; }
    }
    return r;   /* nothing ready = timeout (returns at once: virtual time) */
}

static void setup(fake *fk, uint32_t depth_fmt, uint32_t color_fmt, int cw, int ch) {
    memset(fk, 0, sizeof *fk);
    fk->nn = 3;
    fnode *d = &fk->n[0], *c = &fk->n[1], *m = &fk->n[2];
    d->path = "/dev/video0";
    d->caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
    d->fmts[0] = v4l2_fourcc('G', 'R', 'E', 'Y');
    d->fmts[1] = depth_fmt;
    d->nfmt = 2;
    d->w = 64; d->h = 48;
    c->path = "/dev/video2";
    c->caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
    c->fmts[0] = V4L2_PIX_FMT_MJPEG;
    c->fmts[1] = color_fmt;
    c->nfmt = 2;
    c->w = cw; c->h = ch;
    m->path = "/dev/video1";
    m->caps = V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING;
    /* 20 frames at 30 Hz: depth loses 5 and 6, colour loses 12; colour is 2 ms late */
    for (uint32_t s = 0; s < 20; s++) {
        if (s != 5 && s != 6) d->ev[d->nev++] = (fev){s, 1000000000LL + s * PERIOD_NS, s == 10};
        if (s != 12) c->ev[c->nev++] = (fev){s, 1000000000LL + s * PERIOD_NS + 2000000, 0};
    }
}

static const sooc_v4l2_ops *ops_for(fake *fk) {
    static sooc_v4l2_ops ops;
    ops = (sooc_v4l2_ops){fk, f_open, f_close, f_ioctl, f_mmap, f_munmap, f_poll};
    return &ops;
}

static void run_pairing(uint32_t depth_fmt, const char *depth_format, uint32_t color_fmt, int cw, int ch) {
    fake fk;
    setup(&fk, depth_fmt, color_fmt, cw, ch);
    fk.eintr_once = 1;
    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    p.uri = "/dev/video0";
    p.uri2 = "/dev/video2";
    p.depth_format = depth_format;
    p.v4l2_ops = ops_for(&fk);
    sooc_sensor *s = NULL;
    CHECK_OK(sooc_sensor_open(&s, "v4l2", &p));
    if (!s) return;
    sooc_sensor_info info;
    sooc_sensor_get_info(s, &info);
    CHECK(info.width == 64 && info.height == 48 && !info.has_intrinsics);
    CHECK(fk.n_mmap == 8);
    CHECK_OK(sooc_sensor_start(s));
    sooc_frame f = {0};
    int n = 0, ok_pair = 1, ok_rgb = 1;
    uint32_t seqs[32];
    double t0 = sooc_seconds();
    sooc_status st;
    while ((st = sooc_sensor_read(s, &f, 30)) == SOOC_OK && n < 32) {
        uint32_t dseq = (uint32_t)(f.depth[1] * 1000.0f + 0.5f) - 1000;
        CHECK(f.valid[0] == 0 && f.valid[1] == 1);
        int64_t want_t = 1000000000LL + (int64_t)dseq * PERIOD_NS;
        if (llabs(f.t_ns - want_t) > 1000) ok_pair = 0;
        /* colour must come from the same sequence number */
        if (color_fmt == V4L2_PIX_FMT_YUYV) {
            int Y = 16 + 5 * (int)dseq;
            int g = (298 * (Y - 16) + 128) >> 8;
            if (g > 255) g = 255;
            if (f.rgb[0] != g || f.rgb[1] != g || f.rgb[2] != g) ok_rgb = 0;
        } else {
            if (f.rgb[0] != dseq || f.rgb[1] != 1 || f.rgb[2] != 2) ok_rgb = 0;
        }
        seqs[n++] = dseq;
    }
    double dt = sooc_seconds() - t0;
    CHECK_MSG(st == SOOC_ETIMEOUT, "end: %s %s", sooc_status_str(st), sooc_errmsg());
    CHECK_MSG(n == 17, "paired %d frames, expected 17", n);
    if (n != 17) {
        for (int i = 0; i < n; i++) fprintf(stderr, " %u", seqs[i]);
        fprintf(stderr, "\n");
    }
    CHECK(ok_pair);
    CHECK_MSG(ok_rgb, "colour not from the paired sequence number");
    int has5 = 0, has12 = 0;
    for (int i = 0; i < n; i++) { has5 |= seqs[i] == 5 || seqs[i] == 6; has12 |= seqs[i] == 12; }
    CHECK(!has5 && !has12);
    sooc_sensor_stats ss;
    sooc_sensor_get_stats(s, &ss);
    CHECK_MSG(ss.dropped == 3, "dropped %lld", (long long)ss.dropped);
    CHECK_MSG(ss.unpaired == 3, "unpaired %lld", (long long)ss.unpaired);
    CHECK(ss.depth_in == 18 && ss.color_in == 19);
    CHECK_MSG(ss.errors >= 1, "EINTR not counted");
    printf("  v4l2 fake (%s depth, %dx%d %s colour): %d pairs, dropped %lld, unpaired %lld, transient %lld, "
           "%.0f frames/s through the driver\n",
           depth_format ? depth_format : "Z16", cw, ch, color_fmt == V4L2_PIX_FMT_YUYV ? "YUYV" : "RGB3", n,
           (long long)ss.dropped, (long long)ss.unpaired, (long long)ss.errors, n / dt);
    sooc_sensor_close(s);
    CHECK(fk.n_munmap == 8 && fk.n_close == 2);
    sooc_frame_free(&f);
}

static void test_errors(void) {
    fake fk;
    setup(&fk, v4l2_fourcc('Y', '1', '6', ' '), V4L2_PIX_FMT_YUYV, 64, 48);
    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    p.v4l2_ops = ops_for(&fk);
    sooc_sensor *s = NULL;
    p.uri = "/dev/video9";
    CHECK(sooc_sensor_open(&s, "v4l2", &p) == SOOC_ENOTFOUND);
    CHECK(strstr(sooc_errmsg(), "/dev/video9") != NULL);
    p.uri = "/dev/video0";   /* offers GREY + Y16, default wants Z16 */
    CHECK(sooc_sensor_open(&s, "v4l2", &p) == SOOC_EUNSUPPORTED);
    CHECK_MSG(strstr(sooc_errmsg(), "Y16") != NULL, "msg: %s", sooc_errmsg());
    printf("  wrong format: %s\n", sooc_errmsg());
    CHECK(fk.n_close == 1);  /* the node was closed on failure */
    p.uri = "/dev/video1";   /* metadata node */
    CHECK(sooc_sensor_open(&s, "v4l2", &p) == SOOC_EUNSUPPORTED);
    CHECK(strstr(sooc_errmsg(), "metadata") != NULL);
    /* real syscalls: a missing node */
    p.v4l2_ops = NULL;
    p.uri = "/dev/sooc3d-no-such-video";
    CHECK(sooc_sensor_open(&s, "v4l2", &p) == SOOC_ENOTFOUND);
    printf("  missing node: %s\n", sooc_errmsg());
    CHECK(s == NULL);
}

/* Remove the DHT segments (before SOS), as Motion-JPEG cameras send frames. */
static size_t strip_dht(uint8_t *b, size_t n) {
    size_t i = 2, o = 2;
    while (i + 4 <= n && b[i] == 0xFF && b[i + 1] != 0xDA) {
        size_t len = 2 + ((size_t)b[i + 2] << 8 | b[i + 3]);
        if (i + len > n) break;
        if (b[i + 1] != 0xC4) { memmove(b + o, b + i, len); o += len; }
        i += len;
    }
    memmove(b + o, b + i, n - i);
    return o + (n - i);
}

/* A depth node and an MJPEG-only colour node (64x48 colour, like a USB camera
 * at the depth size; and 128x96, resampled). Frame s is a flat colour
 * (8 s, 100, 200); frame 3 has no Huffman tables; frame 8 is truncated
 * (dropped, counted in errors); frame 9 is not a JPEG at all. */
static void run_mjpeg(int cw, int ch) {
    for (uint32_t s = 0; s < 20; s++) {
        sooc_image img = {0};
        if (sooc_image_alloc(&img, cw, ch, SOOC_PIX_RGB8)) exit(1);
        uint8_t *p = img.data;
        for (int i = 0; i < cw * ch; i++) { p[3 * i] = (uint8_t)(8 * s); p[3 * i + 1] = 100; p[3 * i + 2] = 200; }
        CHECK_OK(sooc_jpeg_encode(&img, 90, &g_jpg[s], &g_jpgn[s]));
        sooc_image_free(&img);
    }
    size_t with_dht = g_jpgn[3];
    g_jpgn[3] = strip_dht(g_jpg[3], g_jpgn[3]);
    CHECK_MSG(g_jpgn[3] + 400 < with_dht, "DHT not stripped: %zu -> %zu bytes", with_dht, g_jpgn[3]);
    g_jpgn[8] /= 2;
    memset(g_jpg[9], 0x55, g_jpgn[9]);
    fake fk;
    setup(&fk, V4L2_PIX_FMT_Z16, V4L2_PIX_FMT_MJPEG, cw, ch);
    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    p.uri = "/dev/video0";
    p.uri2 = "/dev/video2";
    p.v4l2_ops = ops_for(&fk);
    sooc_sensor *s = NULL;
    CHECK_OK(sooc_sensor_open(&s, "v4l2", &p));
    if (s) {
        CHECK(fk.n[1].cur_fmt == V4L2_PIX_FMT_MJPEG);
        CHECK_OK(sooc_sensor_start(s));
        sooc_frame f = {0};
        int n = 0, ok_rgb = 1, has8 = 0, has9 = 0, has3 = 0;
        while (sooc_sensor_read(s, &f, 30) == SOOC_OK && n < 32) {
            uint32_t dseq = (uint32_t)(f.depth[1] * 1000.0f + 0.5f) - 1000;
            for (int k = 0; k < 64 * 48; k += 97)
                if (abs(f.rgb[3 * k] - (int)(8 * dseq)) > 3 || abs(f.rgb[3 * k + 1] - 100) > 3 ||
                    abs(f.rgb[3 * k + 2] - 200) > 3)
                    ok_rgb = 0;
            has8 |= dseq == 8;
            has9 |= dseq == 9;
            has3 |= dseq == 3;
            n++;
        }
        sooc_sensor_stats ss;
        sooc_sensor_get_stats(s, &ss);
        CHECK_MSG(ok_rgb, "MJPEG colour differs from the encoded frame");
        CHECK_MSG(n == 15 && has3 && !has8 && !has9, "MJPEG %dx%d: %d pairs (expected 15: 17 less the corrupt 8 and 9)",
                  cw, ch, n);
        CHECK_MSG(ss.errors >= 2, "corrupt MJPEG frames not counted: errors %lld", (long long)ss.errors);
        printf("  v4l2 fake (Z16 depth, %dx%d MJPEG colour): %d pairs, errors %lld (a truncated frame and a "
               "non-JPEG frame dropped; a frame without DHT decoded)\n", cw, ch, n, (long long)ss.errors);
        sooc_sensor_close(s);
        sooc_frame_free(&f);
    }
    for (int i = 0; i < 20; i++) { sooc_free(g_jpg[i]); g_jpg[i] = NULL; }
}

int main(void) {
    test_errors();
    run_mjpeg(64, 48);
    run_mjpeg(128, 96);
    run_pairing(V4L2_PIX_FMT_Z16, NULL, V4L2_PIX_FMT_YUYV, 64, 48);
    run_pairing(v4l2_fourcc('Y', '1', '6', ' '), "Y16", V4L2_PIX_FMT_RGB24, 64, 48);
    run_pairing(V4L2_PIX_FMT_Z16, "Z16", V4L2_PIX_FMT_RGB24, 32, 24);   /* colour resampled */
    return check_report("test_v4l2");
}
