/* The driver registry: the one table of built-in sensor drivers (the
 * backends of drivers_internal.h), looked up by name. The front end
 * (sensor.c) opens drivers only through it, and the drivers call only the
 * shared conversions of frame_util.c, so no driver and the front end call
 * each other. */
#include <string.h>

#include "drivers_internal.h"

static const sooc_sensor_vt *const g_drivers[] = {
    &sooc__replay_vt,
    &sooc__rosbag_vt,
    &sooc__mcap_vt,
#ifdef SOOC_HAVE_OPENNI2
    &sooc__openni2_vt,
#endif
#ifdef SOOC_HAVE_FREENECT
    &sooc__freenect_vt,
#endif
#ifdef SOOC_HAVE_V4L2
    &sooc__v4l2_vt,
#endif
#ifdef SOOC_HAVE_LIBCAMERA
    &sooc__libcamera_vt,
#endif
};
#define N_DRIVERS (sizeof g_drivers / sizeof g_drivers[0])

static const char *const g_names[] = {
    "replay",
    "rosbag",
    "mcap",
#ifdef SOOC_HAVE_OPENNI2
    "openni2",
#endif
#ifdef SOOC_HAVE_FREENECT
    "freenect",
#endif
#ifdef SOOC_HAVE_V4L2
    "v4l2",
#endif
#ifdef SOOC_HAVE_LIBCAMERA
    "libcamera",
#endif
    NULL};

const char *const *sooc_sensor_list_drivers(void) { return g_names; }

const sooc_sensor_vt *sooc__driver_find(const char *name) {
    for (size_t i = 0; i < N_DRIVERS; i++)
        if (name && strcmp(g_drivers[i]->name, name) == 0) return g_drivers[i];
    return NULL;
}

int sooc_sensor_has_driver(const char *name) { return sooc__driver_find(name) != NULL; }
