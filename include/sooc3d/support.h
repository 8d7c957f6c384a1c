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
 */
#ifndef SOOC3D_SUPPORT_H
#define SOOC3D_SUPPORT_H
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
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

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_SUPPORT_H */
