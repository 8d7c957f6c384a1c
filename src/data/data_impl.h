/* Internals shared by the data module's files (not public API). */
#ifndef SOOC3D_DATA_IMPL_H
#define SOOC3D_DATA_IMPL_H

#include "sooc3d/core.h"

#include <string.h>

/* Write `buf` to "<path>.tmp" then rename it over `path` (no fsync): bulk
 * dataset files (frames, meshes, pictures). */
sooc_status sooc_data_write_file(const char *path, const void *buf, size_t n);

/* The cup's half-torus handle (scene.c): centre c (object frame), ring
 * radius R and tube radius r for cup params q = rt rb h t. */
void sooc_scene_cup_handle(const double *q, double c[3], double *R, double *r);

/* Sensor noise for one generated view (gen_tabletop.c): writes the exact
 * depth to <scene_dir>/depth_gt/%06d.png (16-bit, depth_scale), then applies
 * the Kinect model of sensor_noise.h to f with stream (seed, scene, view). */
struct sooc_frame;
sooc_status sooc_gen_noise_view(struct sooc_frame *f, const char *scene_dir, int view, double depth_scale,
                                uint64_t seed, int scene);

#endif
