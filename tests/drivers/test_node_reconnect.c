/* The node on the project's fake devices when the device goes away mid-stream
 * and comes back (docs/node.md "Faults"): for each driver the device is lost
 * after the 8th keyframe, cannot be opened for 3 attempts, then returns. The
 * node must say so once each way ("sensor lost", "sensor back"), reopen with
 * backoff (reconnect_s 0.02 doubling to 0.08: at least 0.02 + 0.04 + 0.08 +
 * 0.08 s pass), and the frames after it go into the same map (the fake
 * mapper's ids go on; the database holds every object of the map).
 *
 *   v4l2      a fake device at the ioctl level (sooc_v4l2_ops, passed by
 *             sooc_node_options.v4l2_ops): when lost, poll reports POLLERR and
 *             DQBUF fails with ENODEV, open fails with ENOENT;
 *   openni2   Debian's DummyDevice in a private driver folder (as
 *             test_openni2), with oniWaitForAnyStream failing and
 *             oniDeviceOpen answering ONI_STATUS_NO_DEVICE while it is lost;
 *   freenect  a fakenect dump under Debian's fakenect (as test_freenect), with
 *             freenect_process_events_timeout answering LIBUSB_ERROR_NO_DEVICE
 *             and freenect_open_device failing while it is lost.
 * The OpenNI2 and libfreenect calls are wrapped by this program (its
 * definitions bind first; the library's are reached with dlsym(RTLD_NEXT)).
 * Negative control: with reconnect_s 0 the run ends at the loss with an error. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "check.h"
#include "drv_testutil.h"
#include "sooc3d/driver.h"
#include "sooc3d/core.h"
#include "sooc3d/mapper.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"

#define LOSE_AFTER 8       /* keyframes before the device goes away */
#define OPEN_FAILS 3       /* reopen attempts that fail before it returns */

static atomic_int g_gone, g_open_fails, g_lost_lines, g_back_lines, g_still_lines;
static atomic_int g_pose_i;
static atomic_uint_fast64_t g_kf_at_loss;
static char g_tmp[256];

static void log_cb(void *user, sooc_log_level lv, const char *msg) {
    (void)user;
    if (strstr(msg, "node: sensor lost: ")) atomic_fetch_add(&g_lost_lines, 1);
    if (strstr(msg, "node: sensor back after")) atomic_fetch_add(&g_back_lines, 1);
    if (strstr(msg, "node: sensor still lost")) atomic_fetch_add(&g_still_lines, 1);
    if (strstr(msg, "node: sensor")) printf("    [log] %s\n", msg);
    else if (lv >= SOOC_LOG_WARN && getenv("SOOC_TEST_VERBOSE")) fprintf(stderr, "[log] %s\n", msg);
}

/* A device that is lost stays lost until OPEN_FAILS opens have been refused. */
static int open_refused(void) {
    if (!atomic_load(&g_gone)) return 0;
    if (atomic_fetch_sub(&g_open_fails, 1) > 0) return 1;
    atomic_store(&g_gone, 0);
    return 0;
}

static void on_kf(void *user, uint64_t keyframe, const sooc_map_entry *changed, size_t n_changed,
                  const uint64_t *removed, size_t n_removed, const sooc_node_stats *st) {
    (void)user, (void)changed, (void)n_changed, (void)removed, (void)n_removed, (void)st;
    if (keyframe == LOSE_AFTER && !atomic_load(&g_kf_at_loss)) {
        atomic_store(&g_open_fails, OPEN_FAILS);
        atomic_store(&g_kf_at_loss, keyframe);
        atomic_store(&g_gone, 1);
    }
}

/* Every frame gets a pose 0.15 m on from the last: each is a keyframe. */
static sooc_status pose_lookup(void *ctx, int64_t t_ns, int64_t tol, double T[16]) {
    (void)ctx, (void)t_ns, (void)tol;
    int i = atomic_fetch_add(&g_pose_i, 1);
    double R[9] = {-1, 0, 0, 0, -1, 0, 0, 0, 1}, t[3] = {0.15 * i, 1.2, 0};
    sooc_se3_from_rt(T, R, t);
    return SOOC_OK;
}

/* ------------------------------------------------------------ fake V4L2 */

typedef struct vnode {
    const char *path;
    int fd, opened, streaming, nbuf, w, h, bpp, is_depth;
    int ready;   /* a frame is waiting (one per poll) */
    uint8_t *buf[4];
    int queued[4];
    uint32_t seq;
} vnode;

typedef struct vfake {
    vnode n[2];
    int64_t t0;
} vfake;

static vnode *v_by_fd(vfake *f, int fd) {
    for (int i = 0; i < 2; i++)
        if (f->n[i].opened && f->n[i].fd == fd) return &f->n[i];
    return NULL;
}

static int v_open(void *u, const char *path, int flags) {
    vfake *f = u;
    (void)flags;
    if (open_refused()) { errno = ENOENT; return -1; }
    for (int i = 0; i < 2; i++)
        if (!strcmp(f->n[i].path, path)) {
            f->n[i].opened = 1;
            f->n[i].fd = 200 + i;
            return f->n[i].fd;
        }
    errno = ENOENT;
    return -1;
}

static int v_close(void *u, int fd) {
    vnode *n = v_by_fd(u, fd);
    if (!n) { errno = EBADF; return -1; }
    for (int i = 0; i < n->nbuf; i++) { free(n->buf[i]); n->buf[i] = NULL; }
    n->nbuf = 0;
    n->opened = n->streaming = 0;
    return 0;
}

static int v_ioctl(void *u, int fd, unsigned long req, void *arg) {
    vfake *f = u;
    vnode *n = v_by_fd(f, fd);
    if (!n) { errno = EBADF; return -1; }
    switch (req) {
    case VIDIOC_QUERYCAP: {
        struct v4l2_capability *c = arg;
        memset(c, 0, sizeof *c);
        strcpy((char *)c->driver, "fake");
        c->device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
        c->capabilities = c->device_caps | V4L2_CAP_DEVICE_CAPS;
        return 0;
    }
    case VIDIOC_ENUM_FMT: {
        struct v4l2_fmtdesc *d = arg;
        if (d->index > 0) { errno = EINVAL; return -1; }
        d->pixelformat = n->is_depth ? V4L2_PIX_FMT_Z16 : V4L2_PIX_FMT_RGB24;
        return 0;
    }
    case VIDIOC_S_FMT: {
        struct v4l2_format *fm = arg;
        fm->fmt.pix.pixelformat = n->is_depth ? V4L2_PIX_FMT_Z16 : V4L2_PIX_FMT_RGB24;
        fm->fmt.pix.width = (uint32_t)n->w;
        fm->fmt.pix.height = (uint32_t)n->h;
        fm->fmt.pix.bytesperline = (uint32_t)(n->w * n->bpp);
        fm->fmt.pix.sizeimage = (uint32_t)(n->w * n->bpp * n->h);
        return 0;
    }
    case VIDIOC_S_PARM: return 0;
    case VIDIOC_REQBUFS: {
        struct v4l2_requestbuffers *r = arg;
        n->nbuf = r->count > 4 ? 4 : (int)r->count;
        r->count = (uint32_t)n->nbuf;
        for (int i = 0; i < n->nbuf; i++) { n->buf[i] = calloc(1, (size_t)n->w * n->h * n->bpp); n->queued[i] = 0; }
        return 0;
    }
    case VIDIOC_QUERYBUF: {
        struct v4l2_buffer *b = arg;
        if (b->index >= (uint32_t)n->nbuf) { errno = EINVAL; return -1; }
        b->length = (uint32_t)(n->w * n->h * n->bpp);
        b->m.offset = b->index * 4096u;
        return 0;
    }
    case VIDIOC_QBUF: {
        struct v4l2_buffer *b = arg;
        if (atomic_load(&g_gone)) { errno = ENODEV; return -1; }
        if (b->index >= (uint32_t)n->nbuf) { errno = EINVAL; return -1; }
        n->queued[b->index] = 1;
        return 0;
    }
    case VIDIOC_DQBUF: {
        struct v4l2_buffer *b = arg;
        if (atomic_load(&g_gone)) { errno = ENODEV; return -1; }
        int idx = -1;
        for (int i = 0; i < n->nbuf; i++) if (n->queued[i]) { idx = i; break; }
        if (idx < 0 || !n->streaming || !n->ready) { errno = EAGAIN; return -1; }
        n->queued[idx] = 0;
        n->ready = 0;
        size_t np = (size_t)n->w * n->h;
        for (size_t k = 0; k < np; k++) {
            if (n->is_depth) { uint16_t v = 2000; memcpy(n->buf[idx] + 2 * k, &v, 2); }
            else { n->buf[idx][3 * k] = (uint8_t)n->seq; n->buf[idx][3 * k + 1] = 80; n->buf[idx][3 * k + 2] = 160; }
        }
        /* device time: 30 Hz by sequence number, on from the first open (a reopened device counts on) */
        int64_t t = f->t0 + (int64_t)n->seq * 33333333LL;
        b->index = (uint32_t)idx;
        b->bytesused = (uint32_t)(np * n->bpp);
        b->sequence = n->seq++;
        b->flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
        b->timestamp.tv_sec = t / 1000000000;
        b->timestamp.tv_usec = (t % 1000000000) / 1000;
        return 0;
    }
    case VIDIOC_STREAMON: n->streaming = 1; return 0;
    case VIDIOC_STREAMOFF: n->streaming = 0; return 0;
    default: errno = ENOTTY; return -1;
    }
}

static void *v_mmap(void *u, void *addr, size_t len, int prot, int flags, int fd, int64_t off) {
    (void)addr, (void)len, (void)prot, (void)flags;
    vnode *n = v_by_fd(u, fd);
    if (!n || off % 4096 || off / 4096 >= n->nbuf) { errno = EINVAL; return MAP_FAILED; }
    return n->buf[off / 4096];
}

static int v_munmap(void *u, void *addr, size_t len) {
    (void)u, (void)addr, (void)len;
    return 0;
}

/* Both nodes are ready at once (a frame every 5 ms of wall time); a lost device reports POLLERR. */
static int v_poll(void *u, struct pollfd *fds, unsigned long nfds, int timeout_ms) {
    vfake *f = u;
    (void)timeout_ms;
    usleep(5000);
    for (unsigned long i = 0; i < nfds; i++) {
        vnode *n = v_by_fd(f, fds[i].fd);
        if (n) n->ready = 1;
        fds[i].revents = atomic_load(&g_gone) ? POLLERR : POLLIN;
    }
    return (int)nfds;
}

/* ------------------------------------------------------------ OpenNI2 and libfreenect wrappers */

#ifdef SOOC_TEST_OPENNI2
/* OniCTypes.h names these C++ types; in C they need their typedefs first */
typedef struct _OniDevice _OniDevice;
typedef struct _OniStream _OniStream;
typedef struct _OniRecorder _OniRecorder;
#include <OniCAPI.h>
OniStatus oniWaitForAnyStream(OniStreamHandle *streams, int n, int *ready, int timeout) {
    static OniStatus (*real)(OniStreamHandle *, int, int *, int);
    if (!real) *(void **)&real = dlsym(RTLD_NEXT, "oniWaitForAnyStream");
    if (atomic_load(&g_gone)) return ONI_STATUS_ERROR;   /* the USB device is gone */
    return real(streams, n, ready, timeout);
}
OniStatus oniDeviceOpen(const char *uri, OniDeviceHandle *dev) {
    static OniStatus (*real)(const char *, OniDeviceHandle *);
    if (!real) *(void **)&real = dlsym(RTLD_NEXT, "oniDeviceOpen");
    if (open_refused()) return ONI_STATUS_NO_DEVICE;
    return real(uri, dev);
}
#endif

#ifdef SOOC_TEST_FREENECT
#include <libfreenect.h>
int freenect_process_events_timeout(freenect_context *ctx, struct timeval *tv) {
    static int (*real)(freenect_context *, struct timeval *);
    if (!real) *(void **)&real = dlsym(RTLD_NEXT, "freenect_process_events_timeout");
    if (atomic_load(&g_gone)) return -4;   /* LIBUSB_ERROR_NO_DEVICE: unplugged */
    return real(ctx, tv);
}
int freenect_open_device(freenect_context *ctx, freenect_device **dev, int index) {
    static int (*real)(freenect_context *, freenect_device **, int);
    if (!real) *(void **)&real = dlsym(RTLD_NEXT, "freenect_open_device");
    if (open_refused()) return -1;
    return real(ctx, dev, index);
}
#endif

/* ------------------------------------------------------------ the node */

static size_t db_count(const char *db) {
    sooc_mapstore *s = NULL;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    if (sooc_mapstore_open(&s, db, &p)) return (size_t)-1;
    sooc_mapstore_info info;
    size_t n = sooc_mapstore_info_get(s, &info) ? (size_t)-1 : (size_t)info.n_entries;
    sooc_mapstore_close(s);
    return n;
}

/* Runs the node on `sensor` (a launch sensor block) until max_kf keyframes or
 * the end of the recording; with reconnect 0 the run must end at the loss. */
static void run_node(const char *label, const char *sensor, const char *calib, int reconnect, uint64_t max_kf,
                     const sooc_v4l2_ops *ops) {
    char db[400], text[2048];
    snprintf(db, sizeof db, "%s/%s.db", g_tmp, label);
    unlink(db);
    snprintf(text, sizeof text,
             "sensor: %s\n%s%s%s"
             "pose: {source: file, path: unused-the-test-gives-poses.txt}\nmodel: {path: fake.bin}\n"
             "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
             "shm: {name: sooc_reconn_%d_%s, capacity: 256}\n"
             "map: {db: '%s', resume: false}\nworld: {up: +y, floor: 0.0}\n"
             "pipeline: {ring_capacity: 4, block_when_full: true, stats_period_s: 0, reconnect_s: %s, "
             "reconnect_max_s: 0.08}\nlog: {level: info}\n",
             sensor, calib ? "calib: '" : "", calib ? calib : "", calib ? "'\n" : "", (int)getpid(), label, db,
             reconnect ? "0.02" : "0");
    sooc_node_config c;
    sooc_status st = sooc_node_config_parse(&c, text, strlen(text), "reconnect.yaml");
    CHECK_MSG(st == SOOC_OK, "%s: %s", label, sooc_errmsg());
    if (st) return;
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    sooc_mapper *m = NULL;
    CHECK_OK(sooc_mapper_create(&m, &mp));
    sooc_node_pose_source ps = {NULL, pose_lookup, NULL};
    sooc_node_options opt;
    memset(&opt, 0, sizeof opt);
    opt.mapper = m;
    opt.pose = &ps;
    opt.max_keyframes = max_kf;
    opt.on_keyframe = on_kf;
    opt.v4l2_ops = ops;
    c.pose_kind = SOOC_NODE_POSE_FILE;
    atomic_store(&g_gone, 0), atomic_store(&g_kf_at_loss, 0), atomic_store(&g_pose_i, 0);
    atomic_store(&g_lost_lines, 0), atomic_store(&g_back_lines, 0), atomic_store(&g_still_lines, 0);
    sooc_node *n = NULL;
    st = sooc_node_create(&n, &c, &opt);
    CHECK_MSG(st == SOOC_OK, "%s: create: %s", label, sooc_errmsg());
    if (st) {
        sooc_mapper_destroy(m);
        return;
    }
    double t0 = sooc_seconds();
    st = sooc_node_run(n);
    double dt = sooc_seconds() - t0;
    sooc_node_stats s;
    sooc_node_get_stats(n, &s);
    sooc_node_destroy(n);
    size_t ne = 0;
    sooc_mapper_entries(m, NULL, 0, &ne);
    uint64_t next_id = sooc_mapper_next_id(m);
    sooc_mapper_destroy(m);
    if (!reconnect) {
        CHECK_MSG(st != SOOC_OK && s.keyframes <= LOSE_AFTER + 4 && s.sensor_reconnects == 0,
                  "%s, reconnect_s 0: status %s, %llu keyframes (the run should end at the loss)", label,
                  sooc_status_str(st), (unsigned long long)s.keyframes);
        printf("  %s, reconnect_s 0: the run ends at the loss (%s) after %llu keyframes\n", label,
               sooc_status_str(st), (unsigned long long)s.keyframes);
        return;
    }
    uint64_t after = s.keyframes > LOSE_AFTER ? s.keyframes - LOSE_AFTER : 0;
    CHECK_MSG(st == SOOC_OK, "%s: run: %s %s", label, sooc_status_str(st), sooc_errmsg());
    CHECK_MSG(s.sensor_lost == 1 && s.sensor_reconnects == 1 && !s.sensor_down, "%s: lost %llu, back %llu, down %d",
              label, (unsigned long long)s.sensor_lost, (unsigned long long)s.sensor_reconnects, s.sensor_down);
    CHECK_MSG(atomic_load(&g_lost_lines) == 1 && atomic_load(&g_back_lines) == 1 && atomic_load(&g_still_lines) == 1,
              "%s: %d 'lost', %d 'back', %d 'still lost' lines (want 1 each)", label, atomic_load(&g_lost_lines),
              atomic_load(&g_back_lines), atomic_load(&g_still_lines));
    CHECK_MSG(after >= 4, "%s: %llu keyframes in all, %llu after the device came back", label,
              (unsigned long long)s.keyframes, (unsigned long long)after);
    /* one map: the mapper's ids went on through the loss, the database holds every object */
    CHECK_MSG(next_id == s.keyframes + 1 && db_count(db) == ne && ne > 0,
              "%s: next id %llu after %llu keyframes, %zu objects in the map, %zu in the database", label,
              (unsigned long long)next_id, (unsigned long long)s.keyframes, ne, db_count(db));
    /* the backoff: 0.02 + 0.04 + 0.08 + 0.08 s of waiting at least */
    CHECK_MSG(dt >= 0.22, "%s: the run took %.3f s, less than the backoff's 0.22 s", label, dt);
    printf("  %s: lost after keyframe %d, back at the %dth reopen; %llu keyframes (%llu after), one map of %zu "
           "objects (ids up to %llu, all in the database), %.2f s\n",
           label, LOSE_AFTER, OPEN_FAILS + 1, (unsigned long long)s.keyframes, (unsigned long long)after, ne,
           (unsigned long long)(next_id - 1), dt);
    unlink(db);
}

static void write_calib(const char *path, int w, int h) {
    FILE *f = fopen(path, "w");
    if (!f) return;
    fprintf(f, "%%YAML 1.2\n---\ncamera_name: fake\nimage_width: %d\nimage_height: %d\n"
               "camera_matrix: {rows: 3, cols: 3, data: [%g, 0, %g, 0, %g, %g, 0, 0, 1]}\n"
               "distortion_model: plumb_bob\ndistortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n"
               "depth_scale: 0.001\n",
            w, h, 50.0 * w / 64, w / 2.0 - 0.5, 50.0 * w / 64, h / 2.0 - 0.5);
    fclose(f);
}

static void test_v4l2(void) {
    vfake fk;
    memset(&fk, 0, sizeof fk);
    fk.t0 = 1000000000LL;
    fk.n[0] = (vnode){.path = "/dev/video0", .w = 64, .h = 48, .bpp = 2, .is_depth = 1};
    fk.n[1] = (vnode){.path = "/dev/video2", .w = 64, .h = 48, .bpp = 3};
    sooc_v4l2_ops ops = {&fk, v_open, v_close, v_ioctl, v_mmap, v_munmap, v_poll};
    char calib[400];
    snprintf(calib, sizeof calib, "%s/v4l2_calib.yaml", g_tmp);
    write_calib(calib, 64, 48);
    const char *sensor = "{driver: v4l2, depth_device: /dev/video0, color_device: /dev/video2}";
    run_node("v4l2", sensor, calib, 1, 24, &ops);
    fk.n[0].seq = fk.n[1].seq = 0;
    run_node("v4l2", sensor, calib, 0, 24, &ops);
}

#ifdef SOOC_TEST_OPENNI2
static int oni_child(void) {
    run_node("openni2", "{driver: openni2, uri: Dummy}", NULL, 1, 20, NULL);
    run_node("openni2", "{driver: openni2, uri: Dummy}", NULL, 0, 20, NULL);
    return check_report("test_node_reconnect (openni2)");
}

static int test_openni2(char **argv) {
    char lib[1024], dummy[1024];
    snprintf(lib, sizeof lib, "%s/libOpenNI2.so.0", SOOC_OPENNI2_LIBDIR);
    snprintf(dummy, sizeof dummy, "%s/OpenNI2/Drivers/libDummyDevice.so.0", SOOC_OPENNI2_LIBDIR);
    if (access(lib, R_OK) || access(dummy, R_OK)) {
        printf("  openni2: skipped, libOpenNI2.so.0 or its DummyDevice driver is not installed\n");
        return 0;
    }
    char dir[300], cmd[4000];
    snprintf(dir, sizeof dir, "%s/oni", g_tmp);
    snprintf(cmd, sizeof cmd, "mkdir -p '%s/OpenNI2/Drivers' && cp '%s' '%s/' && cp '%s' '%s/OpenNI2/Drivers/'", dir,
             lib, dir, dummy, dir);
    if (system(cmd)) {
        CHECK_MSG(0, "cannot set up the private OpenNI2 folder: %s", cmd);
        return 1;
    }
    static char e1[1200], e2[600];
    const char *old = getenv("LD_LIBRARY_PATH");
    snprintf(e1, sizeof e1, "LD_LIBRARY_PATH=%s%s%s", dir, old ? ":" : "", old ? old : "");
    snprintf(e2, sizeof e2, "SOOC_RC_TMP=%s", g_tmp);
    const char *env[] = {e1, e2, "SOOC_RC_CHILD=openni2", "LSAN_OPTIONS=detect_leaks=0", NULL};
    return tu_reexec(env, argv);
}
#endif

#ifdef SOOC_TEST_FREENECT
#define FN_DIR "/usr/lib/x86_64-linux-gnu/fakenect"
#define FN_FRAMES 40
static int fn_child(void) {
    /* the dump is longer than the run: the run ends at max_keyframes */
    run_node("freenect", "{driver: freenect}", NULL, 1, 20, NULL);
    run_node("freenect", "{driver: freenect}", NULL, 0, 20, NULL);
    return check_report("test_node_reconnect (freenect)");
}

static int write_dump(const char *dir, int nf) {
    char p[1200];
    snprintf(p, sizeof p, "%s/INDEX.txt", dir);
    FILE *idx = fopen(p, "w");
    if (!idx) return -1;
    uint16_t *d = malloc((size_t)640 * 480 * 2);
    uint8_t *c = malloc((size_t)640 * 480 * 3);
    for (int j = 0; j < 640 * 480; j++) d[j] = 700;
    for (int i = 0; i < nf; i++) {
        double now = 1700000000.0 + i * 0.02;
        for (int j = 0; j < 640 * 480; j++) { c[3 * j] = (uint8_t)(5 * i); c[3 * j + 1] = 7; c[3 * j + 2] = 9; }
        char name[128];
        snprintf(name, sizeof name, "d-%.6f-%u.pgm", now, 1000u * (unsigned)i);
        snprintf(p, sizeof p, "%s/%s", dir, name);
        FILE *f = fopen(p, "wb");
        if (!f) return -1;
        fprintf(f, "P5 %d %d 65535\n", 640, 480);
        fwrite(d, 2, (size_t)640 * 480, f);
        fclose(f);
        fprintf(idx, "%s\n", name);
        snprintf(name, sizeof name, "r-%.6f-%u.ppm", now + 0.001, 1000u * (unsigned)i + 10);
        snprintf(p, sizeof p, "%s/%s", dir, name);
        f = fopen(p, "wb");
        if (!f) return -1;
        fprintf(f, "P6 %d %d 255\n", 640, 480);
        fwrite(c, 3, (size_t)640 * 480, f);
        fclose(f);
        fprintf(idx, "%s\n", name);
    }
    free(d);
    free(c);
    fclose(idx);
    return 0;
}

static int test_freenect(char **argv) {
    if (access(FN_DIR "/libfreenect.so.0.5", R_OK)) {
        printf("  freenect: skipped, Debian's fakenect (%s) is not installed\n", FN_DIR);
        return 0;
    }
    char dir[400];
    snprintf(dir, sizeof dir, "%s/dump", g_tmp);
    if (mkdir(dir, 0755) || write_dump(dir, FN_FRAMES)) {
        CHECK_MSG(0, "cannot write the fakenect dump in %s", dir);
        return 1;
    }
    static char e1[600], e2[600], e3[600];
    snprintf(e1, sizeof e1, "LD_LIBRARY_PATH=%s", FN_DIR);
    snprintf(e2, sizeof e2, "FAKENECT_PATH=%s", dir);
    snprintf(e3, sizeof e3, "SOOC_RC_TMP=%s", g_tmp);
    const char *env[] = {e1, e2, e3, "SOOC_RC_CHILD=freenect", NULL};
    return tu_reexec(env, argv);
}
#endif

int main(int argc, char **argv) {
    (void)argc;
    sooc_log_set_callback(log_cb, NULL);
    sooc_log_set_level(SOOC_LOG_INFO);
    const char *child = getenv("SOOC_RC_CHILD");
    if (child) {
        snprintf(g_tmp, sizeof g_tmp, "%.200s", getenv("SOOC_RC_TMP"));
#ifdef SOOC_TEST_OPENNI2
        if (!strcmp(child, "openni2")) return oni_child();
#endif
#ifdef SOOC_TEST_FREENECT
        if (!strcmp(child, "freenect")) return fn_child();
#endif
        return 1;
    }
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc_reconn_XXXXXX");
    if (!mkdtemp(g_tmp)) return 1;
    test_v4l2();
    int rc = 0;
#ifdef SOOC_TEST_OPENNI2
    rc |= test_openni2(argv);
#endif
#ifdef SOOC_TEST_FREENECT
    rc |= test_freenect(argv);
#endif
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (system(cmd)) { /* ignore */ }
    return check_report("test_node_reconnect") | rc;
}
