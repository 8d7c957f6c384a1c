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
} sooc_support;

/* Estimate the support plane from n posed frames (metric depth, has_pose;
 * frames without a pose are skipped). Candidate planes are fitted in turn
 * (RANSAC, then a least squares refit); the chosen one is the largest plane
 * below every camera whose normal lies within max_tilt_deg of up. Fails with
 * a message that names the reason (no pose, no depth, no plane within the
 * tilt, ...). */
sooc_status sooc_support_estimate(const sooc_frame *const *frames, int n, const sooc_support_params *p,
                                  sooc_support *out);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_SUPPORT_H */
