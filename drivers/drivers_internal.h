/* Internal glue shared by the sensor drivers (not installed). */
#ifndef SOOC3D_DRIVERS_INTERNAL_H
#define SOOC3D_DRIVERS_INTERNAL_H

#include <stdatomic.h>
#include <stdint.h>
#include <string.h>

#include "sooc3d/driver.h"

typedef struct sooc_sensor_vt {
    const char *name;
    /* open: fill s->impl and s->info (width/height/K/...); may not touch hardware
     * streams yet. start/stop may be NULL. */
    sooc_status (*open)(sooc_sensor *s, const sooc_sensor_params *p);
    sooc_status (*start)(sooc_sensor *s);
    sooc_status (*read)(sooc_sensor *s, sooc_frame *f, int timeout_ms);
    sooc_status (*stop)(sooc_sensor *s);
    void (*close)(sooc_sensor *s);
} sooc_sensor_vt;

struct sooc_sensor {
    const sooc_sensor_vt *vt;
    void *impl;
    sooc_sensor_params p;
    sooc_sensor_info info;
    sooc_sensor_stats st;
    atomic_int interrupted;
    int started;
    int64_t t_start_mono;      /* sooc_now_ns at start */
    int rebased;
    int64_t rebase_off;        /* SOOC_TIMEBASE_REALTIME offset */
    sooc_frame_fault frame_fault;   /* of the last failed read (sooc_sensor_frame_fault) */
};

extern const sooc_sensor_vt sooc__replay_vt;
extern const sooc_sensor_vt sooc__rosbag_vt, sooc__mcap_vt;   /* replay of a ROS bag / MCAP file */
#ifdef SOOC_HAVE_OPENNI2
extern const sooc_sensor_vt sooc__openni2_vt;
#endif
#ifdef SOOC_HAVE_FREENECT
extern const sooc_sensor_vt sooc__freenect_vt;
#endif
#ifdef SOOC_HAVE_V4L2
extern const sooc_sensor_vt sooc__v4l2_vt;
#endif
#ifdef SOOC_HAVE_LIBCAMERA
extern const sooc_sensor_vt sooc__libcamera_vt;
#endif

/* The built-in driver of that name (registry.c), NULL if there is none. */
const sooc_sensor_vt *sooc__driver_find(const char *name);

/* Make f a w x h frame (reuses buffers when the size matches). Clears pose/K. */
sooc_status sooc__frame_ensure(sooc_frame *f, int w, int h);
/* Raw 16-bit depth (stride in bytes) -> metres + valid mask, with range check. */
void sooc__depth_u16_to_m(sooc_frame *f, const uint16_t *src, int stride_bytes, double scale, float dmin,
                          float dmax);
/* Apply depth_min/max to metres already in f->depth and rebuild the mask. */
void sooc__depth_finish(sooc_frame *f, float dmin, float dmax);
/* Packed YUYV (YUY2) -> RGB8 (BT.601 limited range). */
void sooc__yuyv_to_rgb(uint8_t *dst, const uint8_t *src, int w, int h, int stride_bytes);
/* Copy an RGB or BGR image with a stride into f->rgb. */
void sooc__rgb_copy(uint8_t *dst, const uint8_t *src, int w, int h, int stride_bytes, int bgr);

/* Sensor stamp -> frame t_ns under the sensor's timebase. */
int64_t sooc__timebase(sooc_sensor *s, int64_t sensor_ns);
/* Sleep until the monotonic deadline, waking every <= 20 ms to check for an
 * interrupt. Returns SOOC_EINTERRUPTED if interrupted. */
sooc_status sooc__sleep_until(sooc_sensor *s, int64_t deadline_mono_ns);
int sooc__interrupted(sooc_sensor *s);

/* Parse a decimal seconds value ("1305031102.175304") to exact int64 ns.
 * Returns -1 for a non-number or a value whose ns do not fit in int64. */
int sooc__parse_seconds_ns(const char *s, char **end, int64_t *ns);

/* Split the next line off a NUL-terminated text buffer in place (its '\n'
 * becomes '\0') and advance *cur; NULL once the text is used up. For the
 * TUM-style text readers (pose file, pose datagrams, replay stamp lists). */
static inline char *sooc__next_line(char **cur) {
    char *line = *cur;
    if (!line || !*line) return NULL;
    char *nl = strchr(line, '\n');
    if (nl) *nl = '\0';
    *cur = nl ? nl + 1 : NULL;
    return line;
}

#endif
