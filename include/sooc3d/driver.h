/*
 * sooc3d sensor drivers: one interface in front of every RGB-D source.
 *
 *   rosbag,    a ROS 1 bag or an MCAP file through the replay driver, frames
 *   mcap       made by the logs module (log.h, docs/logs.md); the replay
 *              driver itself also opens a log given as its path.
 *   replay     a recorded sequence in any format the data module reads (TUM,
 *              Replica, ScanNet, klg, our synthetic layout, ...), at recorded
 *              speed or as fast as possible, optionally looping, with start and
 *              stop times; frames carry the sequence's ground-truth pose.
 *   openni2    OpenNI2 C API (PrimeSense/Xtion/Astra, "Dummy", .oni files).
 *   freenect   libfreenect (Kinect v1; Debian's fakenect for tests).
 *   v4l2       raw V4L2 mmap streaming, a depth node (Z16/Y16) paired with an
 *              optional colour node (RGB24/BGR24/YUYV), e.g. a RealSense D4xx
 *              under uvcvideo (docs/drivers.md).
 *   libcamera  colour only, through a small C++ shim (depth is all invalid).
 *
 * Drivers whose library was missing at build time are left out;
 * sooc_sensor_list_drivers() names the compiled-in ones, and opening a
 * missing one fails with SOOC_EUNSUPPORTED. A missing device fails with
 * SOOC_ENOTFOUND and a message naming the device.
 *
 * Threading: one thread owns a sensor (open/start/read/stop/close).
 * sooc_sensor_interrupt() may be called from any thread (or a signal
 * handler): a blocked sooc_sensor_read() then returns SOOC_EINTERRUPTED
 * within ~50 ms.
 *
 * Typical use (the node's driver thread):
 *
 *   sooc_sensor_params p; sooc_sensor_params_default(&p);
 *   p.uri = "/data/rgbd_dataset_freiburg1_desk"; p.speed = 1.0;
 *   sooc_sensor *s; if (sooc_sensor_open(&s, "replay", &p)) fail(sooc_errmsg());
 *   sooc_sensor_start(s);
 *   sooc_frame f = {0};
 *   for (;;) {
 *       sooc_status st = sooc_sensor_read(s, &f, 100);
 *       if (st == SOOC_ETIMEOUT) continue;
 *       if (st == SOOC_EEOF || st == SOOC_EINTERRUPTED) break;
 *       if (st) fail(sooc_errmsg());
 *       use(&f);            // f's buffers are reused by the next read
 *   }
 *   sooc_sensor_stop(s); sooc_sensor_close(s); sooc_frame_free(&f);
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_DRIVER_H
#define SOOC3D_DRIVER_H

#include <stddef.h>
#include <stdint.h>

#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_sensor sooc_sensor;
struct sooc_v4l2_ops;

/* Where a frame's t_ns comes from. */
typedef enum sooc_timebase {
    SOOC_TIMEBASE_SENSOR = 0,   /* the source's own clock: recorded stamps (replay), the
                                   device clock (OpenNI2 µs, V4L2 buffer timestamps,
                                   libcamera sensor ns); freenect: host CLOCK_REALTIME at
                                   arrival (its 32-bit tick counter wraps)                 */
    SOOC_TIMEBASE_REALTIME = 1  /* sensor stamps rebased so the first frame carries the
                                   CLOCK_REALTIME of its arrival (pose streams from a robot
                                   use that clock); intervals stay the sensor's            */
} sooc_timebase;

typedef struct sooc_sensor_params {
    /* What to open. replay: the sequence directory (or file, e.g. .klg).
     * openni2: NULL/"" = any device, "Dummy", a device URI or a .oni path.
     * freenect: device index ("0" default). v4l2: the depth node, "/dev/video0".
     * libcamera: camera index ("0") or libcamera camera id. */
    const char *uri;
    const char *uri2;          /* v4l2: the colour node (NULL = depth only)               */
    const char *format;        /* replay: a format name or alias of sooc_seq_format_parse
                                  (frame.h, docs/formats.md §Format names; NULL = auto)     */
    const char *calib;         /* replay: calib YAML overriding <dir>/calib.yaml (NULL)    */
    int width, height;         /* requested mode (0 = driver default, usually 640x480)    */
    int fps;                   /* requested rate (0 = driver default, 30)                 */
    /* replay */
    double speed;              /* 1.0 = recorded rate (default); 0 = as fast as possible;
                                  2.0 = twice as fast                                     */
    int loop;                  /* 1 = start again at start_s after stop_s/end; t_ns keeps
                                  increasing (each pass is shifted by its duration + one
                                  frame period) and f->index keeps counting              */
    double start_s, stop_s;    /* seconds relative to the first frame's stamp; frames with
                                  t < start_s are skipped; stop_s < 0 = to the end       */
    /* depth */
    double depth_scale;        /* metres per raw depth unit; 0 = the driver/format default
                                  (OpenNI2/freenect mm: 0.001, V4L2 Z16: 0.001)           */
    float depth_min, depth_max;/* metres; outside -> invalid (defaults 0.1 and 10)        */
    int depth_shift;           /* replay: raw >> depth_shift before depth_scale; -1 (the
                                  default) = the calib YAML's, else the format's          */
    int depth_invalid;         /* replay: raw value meaning "no depth" besides 0 (0 =
                                  none); -1 (the default) = calib YAML, else the format's */
    /* device options */
    int registration;          /* 1 = register depth to colour when the device can (default) */
    int mirror;                /* 0 = mirroring off (default)                             */
    const char *depth_format;  /* v4l2: "Z16" (default) or "Y16"; freenect: "auto",
                                  "11bit" or "registered"                                 */
    sooc_timebase timebase;    /* default SOOC_TIMEBASE_SENSOR                            */
    int64_t pair_tol_ns;       /* v4l2/openni2 pairing tolerance (0 = half a frame period);
                                  logs: colour-depth pairing by log time (0 = 20 ms)      */
    /* rosbag / mcap (log.h sooc_logseq_params; NULL = the default) */
    const char *color_topic, *depth_topic;   /* NULL = the one topic of that kind         */
    const char *pose_parent, *pose_child;    /* pose from the log's TF (parent NULL = none;
                                                child NULL = the colour image's frame_id) */
    /* Test hook: replace open/ioctl/mmap/poll/close of the v4l2 driver (NULL = the
     * real syscalls). See struct sooc_v4l2_ops below. */
    const struct sooc_v4l2_ops *v4l2_ops;
} sooc_sensor_params;

/* Defaults: everything 0/NULL except speed 1.0, stop_s -1, depth_min 0.1,
 * depth_max 10, registration 1, depth_shift and depth_invalid -1. */
void sooc_sensor_params_default(sooc_sensor_params *p);

/* Set one parameter from text, for launch files. Keys: uri (aliases device,
 * path), uri2 (alias color_device), format, calib, width, height, fps, speed, loop,
 * start (alias start_s), stop (alias stop_s), depth_scale, depth_shift (0..15),
 * depth_invalid (0..65535), depth_min, depth_max, registration, mirror,
 * depth_format, timebase ("sensor" |
 * "realtime"), pair_tol_ms, color_topic, depth_topic, pose_parent, pose_child. String values are NOT copied: they must outlive
 * the sensor's open call. Unknown key or bad value -> SOOC_EINVAL naming it. */
sooc_status sooc_sensor_params_set(sooc_sensor_params *p, const char *key, const char *value);

/* Compiled-in driver names, NULL-terminated, e.g. {"replay", "openni2", NULL}. */
const char *const *sooc_sensor_list_drivers(void);
int sooc_sensor_has_driver(const char *name);

/* Open a sensor. Fails with SOOC_EUNSUPPORTED for a driver not built in,
 * SOOC_ENOTFOUND for a missing device/file/camera, SOOC_EINVAL for bad params,
 * always with a message. On failure *out is NULL. */
sooc_status sooc_sensor_open(sooc_sensor **out, const char *driver_name, const sooc_sensor_params *p);
sooc_status sooc_sensor_start(sooc_sensor *s);

/* Wait up to timeout_ms (0 = poll, <0 = forever) for the next RGB-D frame and
 * fill *f: rgb, depth (planar metres, 0 = invalid), valid, t_ns, index,
 * K (fx == 0 when the intrinsics are unknown), has_pose/T_wc when the source
 * has a pose (replay of a sequence with ground truth). *f must be zeroed or
 * hold a frame from a previous read: buffers are reused when the size matches
 * and reallocated otherwise; free with sooc_frame_free.
 * Returns SOOC_OK, SOOC_ETIMEOUT, SOOC_EEOF (replay end without loop, fakenect
 * end), SOOC_EINTERRUPTED (after sooc_sensor_interrupt), or an error. */
sooc_status sooc_sensor_read(sooc_sensor *s, sooc_frame *f, int timeout_ms);
/* After a read that failed: SOOC_FRAME_FAULT_* when the failure was one
 * broken frame the sensor has passed (replay: an image missing, truncated or
 * corrupt, a pose that does not parse, a wrong size; the next read gives the
 * frame after it), SOOC_FRAME_FAULT_NONE when the stream itself failed. */
sooc_frame_fault sooc_sensor_frame_fault(const sooc_sensor *s);

/* Make a blocked or future read return SOOC_EINTERRUPTED. Async-signal-safe. */
void sooc_sensor_interrupt(sooc_sensor *s);
sooc_status sooc_sensor_stop(sooc_sensor *s);
void sooc_sensor_close(sooc_sensor *s);   /* NULL-safe; stops first if needed */

typedef struct sooc_sensor_info {
    const char *driver;        /* "replay", ...                                     */
    char device[256];          /* what was opened (path, URI, device name, camera id) */
    int width, height, fps;    /* delivered frame size and nominal rate (0 = unknown) */
    int has_intrinsics;        /* K below is meaningful                             */
    sooc_intrinsics K;
    int has_pose;              /* frames carry T_wc                                 */
    int depth_registered;      /* depth is in the colour camera's frame             */
    int has_color, has_depth;
    int64_t n_frames;          /* replay: frames between start and stop (-1 live)   */
} sooc_sensor_info;
void sooc_sensor_get_info(const sooc_sensor *s, sooc_sensor_info *out);

typedef struct sooc_sensor_stats {
    int64_t frames;            /* RGB-D frames delivered by sooc_sensor_read        */
    int64_t depth_in, color_in;/* raw images received from the device               */
    int64_t dropped;           /* images lost: sequence gaps reported by the device */
    int64_t unpaired;          /* images discarded without a partner in pair_tol    */
    int64_t timeouts;          /* reads that returned SOOC_ETIMEOUT                 */
    int64_t errors;            /* transient errors recovered from (EAGAIN, EINTR...) */
    double fps;                /* delivered frames/s since start                    */
} sooc_sensor_stats;
void sooc_sensor_get_stats(const sooc_sensor *s, sooc_sensor_stats *out);

/* ---- libfreenect 11-bit disparity ---------------------------------------
 * metres = 1 / (-0.0030711016 * raw + 3.3309495161)   (ROS kinect_calibration
 * fit); raw >= 1084 (including 2047 = no data) is invalid; returns 0 then.
 * Exposed for tests and tools. */
float sooc_freenect_disparity_to_m(uint16_t raw);

/* ---- V4L2 syscall table (test hook) --------------------------------------
 * All functions follow their POSIX counterparts (return -1 and set errno on
 * failure). `user` is passed back unchanged. */
struct pollfd;
typedef struct sooc_v4l2_ops {
    void *user;
    int (*open)(void *user, const char *path, int flags);
    int (*close)(void *user, int fd);
    int (*ioctl)(void *user, int fd, unsigned long request, void *arg);
    void *(*mmap)(void *user, void *addr, size_t len, int prot, int flags, int fd, int64_t off);
    int (*munmap)(void *user, void *addr, size_t len);
    int (*poll)(void *user, struct pollfd *fds, unsigned long nfds, int timeout_ms);
} sooc_v4l2_ops;

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_DRIVER_H */
