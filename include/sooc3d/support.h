/*
 * sooc3d support plane: the map's world frame from posed depth frames
 * (docs/node.md "Support plane").
 *
 * The model works in a gravity-aligned world frame: +y up, the plane that
 * objects rest on at y = 0. A real pose source (7-Scenes, label-fusion, an
 * arm, odometry) has its own frame. sooc_support_estimate finds the support
 * plane (the floor, or a table, shelf or bin bottom when no floor is in
 * view) and returns T_world_src, the rigid transform from the pose source's
 * frame to the map's world frame.
 *
 * The up direction comes, in this order, from the caller's hint (launch file
 * `world.up`, CLI `--up`), a gravity file of the sequence (7-Scenes
 * gravity-direction.txt), or the camera's mean down direction over the frames
 * used. The estimate is stored in the map database when first made
 * (sooc_mapstore_frame_put) and read back from there by resume, render, eval
 * and map export.
 *
 * This header is a contract between the node, the CLI commands and eval.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_SUPPORT_H
#define SOOC3D_SUPPORT_H
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/geom.h"
#ifdef __cplusplus
extern "C" {
#endif

typedef enum sooc_up_source {
    SOOC_UP_GIVEN = 0,        /* the caller's hint (launch world.up, --up)            */
    SOOC_UP_GRAVITY_FILE = 1, /* the sequence's gravity file                          */
    SOOC_UP_CAMERA_MEAN = 2   /* minus the cameras' mean image-down direction          */
} sooc_up_source;

const char *sooc_up_source_name(sooc_up_source s); /* "given", "gravity file", "camera mean" */

typedef struct sooc_support_params {
    int has_up_hint;             /* 1: up_hint holds the up direction (source frame)       */
    double up_hint[3];
    int has_gravity;             /* 1: gravity (pointing down, source frame) is known      */
    double gravity[3];
    double max_tilt_deg;         /* plane normal within this angle of up (documented)      */
    double threshold_m;          /* RANSAC inlier distance                                 */
    int iterations;              /* RANSAC hypotheses per candidate plane                  */
    int max_frames;              /* frames used at most (spread over those given)          */
    int pixel_step;              /* back-projection stride in pixels                        */
    double cam_height_min_m;     /* the range of camera heights the model was trained on:  */
    double cam_height_max_m;     /* outside it the result's height_warning is set          */
    uint64_t seed;
    /* extensions (defaults from sooc_support_params_default) */
    double max_tilt_camera_deg;  /* tilt limit when up comes from the cameras (45)          */
    double min_support_frac;     /* a candidate plane holds at least this share of points   */
    double lower_support_ratio;  /* the lowest candidate with >= this share of the largest's
                                    inliers is chosen (0.15)                                */
    double min_clearance_m;      /* "below a camera": at least this far below its centre    */
    int max_points;              /* depth points used at most, over all frames (60000)      */
    double max_depth_m;          /* depth beyond this is not used (8 m)                     */
    double parallel_deg;         /* stage 2: planes within this of the level direction (5)  */
} sooc_support_params;

void sooc_support_params_default(sooc_support_params *p);

typedef struct sooc_support {
    double T_world_src[16];      /* p_world = T_world_src * p_src (row-major)              */
    double up_src[3];            /* unit up direction in the source frame                  */
    double plane_src[4];         /* n . p + d = 0 in the source frame, n = up_src          */
    sooc_up_source up_source;
    double tilt_deg;             /* angle between the plane normal and the up hint         */
    double cam_height_m;         /* mean camera height over the plane                      */
    int height_warning;          /* 1: cam_height_m outside the trained range              */
    size_t n_inliers, n_points;
    double rms_m;
    int frames_used;
    int n_candidates;            /* level planes found (the chosen one among them)         */
} sooc_support;

/* Estimate the support plane from n posed frames (metric depth, has_pose;
 * frames without a pose are skipped; at most max_frames, spread evenly).
 * The rule (docs/node.md "Support plane"):
 *  1. RANSAC finds up to 6 planes in turn within max_tilt_deg of up
 *     (max_tilt_camera_deg when up comes from the cameras); none: failure
 *     that names the up direction, its source and the inlier counts.
 *  2. The level direction is up itself (given, gravity file, or cameras that
 *     turned with under 2 deg rms roll), else the normal of the step-1 plane
 *     with the most support from planes parallel to it (parallel_deg).
 *  3. The level planes are the peaks of the point heights along it, each
 *     refitted by total least squares (normal within parallel_deg).
 *  4. Chosen: among level planes below every camera (min_clearance_m) with
 *     at least lower_support_ratio of the largest one's inliers, the lowest.
 *     So a floor in view wins over a larger table top; a table, shelf or bin
 *     bottom is taken when no floor is in view. */
sooc_status sooc_support_estimate(const sooc_frame *const *frames, int n, const sooc_support_params *p,
                                  sooc_support *out);

/* The same estimate from depth points already in the source frame (xyz,
 * row-major) and the cameras' poses T_src_c (n_cams row-major 4x4, camera to
 * source). For callers that gather points frame by frame (the node). */
sooc_status sooc_support_estimate_points(const double *pts, size_t n_pts, const double *T_src_c, int n_cams,
                                         const sooc_support_params *p, sooc_support *out);

/* Read a gravity file (7-Scenes gravity-direction.txt: three numbers, gravity
 * in the pose source's frame) into g, normalised. SOOC_ENOTFOUND when the file
 * is absent; SOOC_EFORMAT / SOOC_EINVAL naming the file when malformed. */
sooc_status sooc_support_read_gravity(const char *path, double g[3]);

/* The preprocessing and floor fit below are the frame path's
 * (src/frames): the node and the offline commands share them. */

typedef enum sooc_node_depth_resample {
    SOOC_NODE_DEPTH_MIN = 0,       /* min of the valid samples in the footprint (default) */
    SOOC_NODE_DEPTH_NEAREST = 1    /* the sample nearest to the footprint centre */
} sooc_node_depth_resample;

/* ---------------------------------------------------------- preprocessing */

/* Register a depth image (planar metres, 0 = invalid) from the depth camera
 * into the colour camera: each depth pixel is back-projected with Kd, moved by
 * T_color_depth and splatted into the colour image (Kc's size) keeping the
 * nearest surface. Holes stay 0. `out` has Kc->width * Kc->height floats. */
void sooc_node_register_depth(const float *depth, const sooc_intrinsics *Kd,
                              const double T_color_depth[16], const sooc_intrinsics *Kc, float *out);

/* The centred crop of a (w, h) image with the aspect ratio of (tw, th). */
void sooc_node_crop_for_aspect(int w, int h, int tw, int th, int *x0, int *y0, int *cw, int *ch);

/* Resize a crop (x0, y0, cw, ch) of an RGB8 image (w x h) to tw x th by area
 * averaging (exact fractional pixel coverage). */
void sooc_node_resize_rgb_area(const uint8_t *src, int w, int h, int x0, int y0, int cw, int ch,
                               uint8_t *dst, int tw, int th);
/* Resize a crop of a depth image without ever averaging across edges: each
 * target pixel takes the min of the valid samples in its footprint
 * (SOOC_NODE_DEPTH_MIN) or the sample nearest the footprint centre
 * (SOOC_NODE_DEPTH_NEAREST). Samples outside [dmin, dmax] or non-finite are
 * invalid (0); dmax <= 0 means no upper limit. */
void sooc_node_resize_depth(const float *src, int w, int h, int x0, int y0, int cw, int ch,
                            float *dst, int tw, int th, sooc_node_depth_resample mode,
                            double dmin, double dmax);
/* Resize a crop of an id image (row stride w) to tw x th: the sample nearest
 * each footprint's centre (ids are never mixed). */
void sooc_node_resize_ids(const uint16_t *src, int w, int x0, int y0, int cw, int ch, uint16_t *dst, int tw,
                          int th);

/* Full preprocessing of one frame to the model's resolution: crop to the
 * target aspect, resize RGB (area) and depth (min/nearest), set `valid`,
 * adjust the intrinsics, copy t_ns/index/pose; instance ids (when src has
 * them) by nearest sampling. `dst` is (re)allocated. */
sooc_status sooc_node_preprocess(const sooc_frame *src, sooc_frame *dst, int tw, int th,
                                 sooc_node_depth_resample mode, double dmin, double dmax);

/* The rigid transform T_world_src that rotates the pose source's frame so that
 * `up` (unit, source coordinates) becomes +y and the floor (up . p = floor_h)
 * lands on y = 0. The rotation is the smallest one taking up to +y. */
void sooc_node_world_from_up(const double up[3], double floor_h, double T_world_src[16]);

/* -------------------------------------------------------------- floor fit */

typedef struct sooc_floor_fit_params {
    double threshold_m;      /* inlier distance, default 0.02 */
    int iterations;          /* RANSAC hypotheses, default 200 */
    double min_inlier_frac;  /* of the points, default 0.15 */
    uint64_t seed;
    double max_tilt_deg;     /* with hint_up: normal within this angle of it, default 30 */
} sooc_floor_fit_params;

void sooc_floor_fit_params_default(sooc_floor_fit_params *p);

/* RANSAC plane fit on n points (xyz, row-major), refined by a total least
 * squares fit on the inliers (LAPACKE SVD of the centred inlier matrix), then
 * a second inlier pass. Plane: n . p + d = 0, |n| = 1. When `hint_up` is given
 * the normal is oriented along it and planes more than max_tilt_deg away from it
 * are rejected; otherwise n points to `viewpoint` (may be NULL). */
sooc_status sooc_floor_fit(const double *pts, size_t n, const sooc_floor_fit_params *p,
                           const double *hint_up, const double *viewpoint, double plane[4],
                           size_t *n_inliers, double *rms);

/* Back-project valid depth pixels (stride `step`) into the pose source's frame
 * with T_src_c. Returns the number of points written (<= cap). */
size_t sooc_node_depth_points(const sooc_frame *f, const double T_src_c[16], int step, double *pts,
                              size_t cap);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_SUPPORT_H */
