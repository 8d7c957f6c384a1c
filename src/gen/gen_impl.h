/* Internals shared by the generator's files (not public API). */
#ifndef SOOC3D_GEN_IMPL_H
#define SOOC3D_GEN_IMPL_H

#include "sooc3d/core.h"

#include <string.h>

/* Sensor noise for one generated view (sensor_noise.c): writes the exact
 * depth to <scene_dir>/depth_gt/%06d.png (16-bit, depth_scale), then applies
 * the Kinect model of sensor_noise.h to f with stream (seed, scene, view). */
struct sooc_frame;
sooc_status sooc_gen_noise_view(struct sooc_frame *f, const char *scene_dir, int view, double depth_scale,
                                uint64_t seed, int scene);

#endif
