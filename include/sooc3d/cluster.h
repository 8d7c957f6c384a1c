/*
 * sooc3d support-plane clustering: the geometric object map (docs/geometric.md).
 *
 * The floor every learnt map must beat, and a mode users can pick
 * (`model: {kind: geometric}`, `sooc3d eval --baseline geometric`): in the
 * map's world frame (+y up, the support plane at y = 0; support.h), the depth
 * points of every keyframe are merged into a voxel grid; the voxels between
 * min_height_m and max_height_m above the plane are joined when their
 * centroids lie within dist_m of each other (single linkage: connected
 * components in 3D), and each component of at least min_voxels voxels and
 * at most max_extent_m across is an object with its box. The other voxels
 * (the plane, the surround, what is too small or too large) stay in the grid
 * as background, so a rendered view is occluded by them as the camera saw it.
 *
 * The same code gives the learnt mapper its proposals: the objects of a map
 * made of one keyframe.
 *
 * Ownership: a sooc_cluster_map owns its grid; create / destroy. Results are
 * written to caller buffers. Threading: one map per thread; no globals.
 * Errors: sooc_status codes with a message (core.h); nothing prints.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_CLUSTER_H
#define SOOC3D_CLUSTER_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_cluster_params {
    double voxel_m;        /* grid cell: points of all keyframes merged per cell (0.004)    */
    double dist_m;         /* two voxels join when their centroids are closer (0.02)         */
    double min_height_m;   /* above the plane by at least this to be an object point (0.012) */
    double max_height_m;   /* higher points are the surround (0.6)                           */
    double max_depth_m;    /* depth beyond this is not used (3.0)                            */
    int min_voxels;        /* smaller components are noise (12)                              */
    double max_extent_m;   /* a component wider than this in x or z is the surround (0.5)    */
    int pixel_step;        /* back-projection stride in pixels (1)                           */
    double wall_m;         /* vertical planes running on this far are walls, not objects (0.3;
                              0 = keep them)                                                  */
    double free_ratio;     /* free space: a voxel that later frames saw through (their depth
                              lies behind it) at least this many times per frame that put a
                              point in it is not an object voxel: mixed pixels at depth
                              edges, reflections (1; 0 = keep every voxel)                  */
} sooc_cluster_params;
void sooc_cluster_params_default(sooc_cluster_params *p);

/* One object: a box on the floor (world frame, metres). */
typedef struct sooc_cluster_object {
    int label;             /* 0..n-1, the value sooc_cluster_render writes             */
    double x, z, yaw;      /* box centre on the floor; heading of the smallest floor rectangle */
    double extent[3];      /* box size along its own x, y (height), z                   */
    double centre_y;       /* box centre height above the plane                         */
    double rgb[3];         /* mean colour, 0..1                                          */
    int n_voxels;
} sooc_cluster_object;

typedef struct sooc_cluster_map sooc_cluster_map;

sooc_status sooc_cluster_map_create(sooc_cluster_map **out, const sooc_cluster_params *p);
void sooc_cluster_map_destroy(sooc_cluster_map *m);   /* NULL-safe */
void sooc_cluster_map_clear(sooc_cluster_map *m);

/* Add a posed depth frame (world frame; frames without a pose are refused).
 * Invalidates the last segmentation. */
sooc_status sooc_cluster_map_add_frame(sooc_cluster_map *m, const sooc_frame *f);

/* Connected components over the grid; *n_objects gets the object count.
 * Objects are numbered by decreasing size. */
sooc_status sooc_cluster_map_segment(sooc_cluster_map *m, int *n_objects);

/* Objects of the last segmentation: up to cap into out, the count in *n. */
sooc_status sooc_cluster_map_objects(const sooc_cluster_map *m, sooc_cluster_object *out, int cap, int *n);

/* Render the grid into a view (camera-to-world T_wc, intrinsics K at w x h):
 * each voxel centroid goes to its pixel with a depth test; pixels that no
 * centroid reached take the nearest in depth of their 8 neighbours. label
 * (w*h) gets the object label or -1 (background or nothing); depth (w*h)
 * planar metres or 0, and rgb (w*h*3) the voxels' mean colour 0..1 or 0 may
 * be NULL. */
sooc_status sooc_cluster_map_render(const sooc_cluster_map *m, const double T_wc[16], const sooc_intrinsics *K,
                                    int w, int h, int16_t *label, float *depth, float *rgb);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_CLUSTER_H */
