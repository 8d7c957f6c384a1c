/*
 * sooc3d camera calibration: the calib YAML (docs/formats.md §Calibration).
 *
 * The file is a ROS camera_info YAML that starts with `%YAML 1.2` then `---`
 * (so that OpenCV FileStorage reads it too: no comment after a value, booleans
 * come back as the strings "true"/"false", matrices are {rows, cols, data}
 * maps read element by element, not .mat(); docs/formats.md "Reading the
 * files elsewhere"), plus sooc3d extensions:
 *
 *   camera_name, image_width, image_height,
 *   camera_matrix {rows: 3, cols: 3, data: [9]},
 *   distortion_model (plumb_bob | rational_polynomial | equidistant | none),
 *   distortion_coefficients {rows: 1, cols: N, data: [N]},
 *   rectification_matrix {3x3}, projection_matrix {3x4},
 *   depth_scale        metres per depth unit (TUM 0.0002, mm 0.001),
 *   depth_shift        bits to drop from each raw depth sample before scaling:
 *                      metres = (raw >> depth_shift) * depth_scale (0..15;
 *                      label-fusion 3),
 *   depth_invalid      a raw depth value (before the shift) that means "no
 *                      depth" besides 0 (0..65535; 7-Scenes 65535; 0 = none),
 *   depth_registered   true if depth is already in the colour camera frame,
 *   T_color_depth      {rows: 4, cols: 4, data: [16]}  (p_color = T * p_depth),
 *   T_effector_camera  {rows: 4, cols: 4, data: [16], parent: ..., child: ...}.
 *
 * Matrices may also be OpenCV style (`!!opencv-matrix` with rows/cols/dt/data).
 * A leading `%YAML:1.0` line (OpenCV) is blanked before parsing. Unknown
 * keys are errors. Every error message names the file, the line and the key,
 * e.g. "calib/x.yaml:7: camera_matrix: expected 9 numbers, got 8".
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_CALIB_H
#define SOOC3D_CALIB_H

#include "sooc3d/core.h"
#include "sooc3d/geom.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_calib {
    char camera_name[64];
    sooc_intrinsics K;            /* width, height, fx, fy, cx, cy, distortion        */
    int n_dist;                   /* number of distortion coefficients given (0..8)    */
    double R_rect[9];             /* rectification (identity if absent)                */
    double P[12];                 /* projection 3x4 ([K|0] if absent)                  */
    double depth_scale;           /* metres per depth unit; 0 = not given              */
    int depth_shift;              /* raw >> depth_shift before scaling; -1 = not given */
    int depth_invalid;            /* raw value meaning "no depth" (besides 0), 0 = none;
                                     -1 = not given                                    */
    int depth_registered;         /* 1 yes, 0 no, -1 not given                         */
    int has_T_color_depth;
    double T_color_depth[16];
    int has_T_effector_camera;
    double T_effector_camera[16];
    char effector_parent[64], effector_child[64];
} sooc_calib;

/* Defaults: everything absent (width = height = 0), R = I, depth_scale 0,
 * depth_registered, depth_shift and depth_invalid -1, camera_name "unknown". */
void sooc_calib_init(sooc_calib *c);
/* A pinhole calib with no distortion: fx = fy = f, principal point given. */
void sooc_calib_pinhole(sooc_calib *c, int w, int h, double fx, double fy, double cx, double cy);

/* Load and validate `path`. Required keys: image_width, image_height,
 * camera_matrix. Checks: K = [fx 0 cx; 0 fy cy; 0 0 1] with fx, fy nonzero
 * and finite (fy may be negative, e.g. ICL-NUIM), positive sizes,
 * depth_scale > 0, T_* rigid (rotation part orthonormal, last row 0 0 0 1).
 * Errors: ENOTFOUND (file), EFORMAT (YAML syntax), EINVAL (values/keys). */
sooc_status sooc_calib_load(const char *path, sooc_calib *out);
/* Parse from memory; `name` is used in messages in place of the path. */
sooc_status sooc_calib_parse(const char *text, size_t n, const char *name, sooc_calib *out);
/* Save atomically as `%YAML 1.2` + `---` + ROS keys + extensions that are set. */
sooc_status sooc_calib_save(const char *path, const sooc_calib *c);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_CALIB_H */
