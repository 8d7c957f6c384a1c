/*
 * sooc3d camera tracking and calibration (docs/node.md "Your own camera").
 *
 *   odometry     frame-to-keyframe RGB-D odometry with OpenCV's contrib
 *                `rgbd` module (RgbdOdometry, ICPOdometry, RgbdICPOdometry):
 *                a pose source for rigs without external poses.
 *   trajectories TUM-format trajectories, ATE and RPE with the TUM RGB-D
 *                benchmark definitions (Horn alignment via LAPACKE SVD).
 *   calibration  ChArUco / checkerboard boards: render (for tests with known
 *                truth), detect, calibrateCamera, calibrateHandEye.
 *
 * OpenCV is optional at build time (CMake SOOC_WITH_OPENCV, off when
 * libopencv-contrib-dev is missing). Without it the odometry and
 * calibration functions fail with SOOC_EUNSUPPORTED and a message; the
 * trajectory metrics are plain C and always available.
 *
 * Conventions: poses are camera-to-world T_wc, row-major 4x4, OpenCV camera
 * axes. Board images and the calibration YAML use OpenCV/ROS pixel
 * coordinates (pixel (0, 0) has its centre at (0, 0)).
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_CV_H
#define SOOC3D_CV_H

#include "sooc3d/calib.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/image.h"

#ifdef __cplusplus
extern "C" {
#endif

/* 1 if the library was built with OpenCV. */
int sooc_cv_available(void);

/* ------------------------------------------------------------- odometry */

typedef enum sooc_odom_variant {
    SOOC_ODOM_RGBD = 0,      /* photometric + depth (RgbdOdometry)       */
    SOOC_ODOM_ICP = 1,       /* depth only, point-to-plane (ICPOdometry) */
    SOOC_ODOM_RGBD_ICP = 2   /* both terms (RgbdICPOdometry)             */
} sooc_odom_variant;

const char *sooc_odom_variant_name(sooc_odom_variant v);          /* "rgbd", "icp", "rgbd_icp" */
sooc_status sooc_odom_variant_parse(const char *s, sooc_odom_variant *out);

typedef struct sooc_odom_params {
    sooc_odom_variant variant;     /* default SOOC_ODOM_RGBD_ICP                                 */
    int width, height;             /* working resolution; frames are resized (default 320x240;
                                      0 = the frames' own)                                        */
    double min_depth_m, max_depth_m;   /* depth used (default 0.3 .. 4)                         */
    double max_depth_diff_m;       /* correspondence depth gate (default 0.07)                    */
    double max_points_part;        /* fraction of pixels used (default 0.07, OpenCV's)           */
    /* tracking failure: OpenCV's compute() fails, or the motion since the
     * keyframe exceeds these bounds (default 0.3 m, 30 deg) */
    double max_translation_m, max_rotation_deg;
    /* keyframe rule: a tracked frame becomes the keyframe when it moved this
     * far from the current one, or after kf_max_frames frames (0 = never by
     * count). Defaults 0.10 m, 10 deg, 0. */
    double kf_translation_m, kf_rotation_deg;
    int kf_max_frames;
    /* after this many consecutive failures the tracker re-anchors: the next
     * frame becomes a keyframe at the last tracked pose (default 10; 0 = never) */
    int max_failures;
    /* a result is also a failure when less than this fraction of the
     * frame's depth pixels, moved into the keyframe, agree with its depth
     * within max_depth_diff_m (default 0.3; 0 = no check) */
    double min_agreement;
    /* Colour not registered to depth (7-Scenes: the frames' K is the depth
     * camera's, f = 585; its colour camera has f = 525,
     * SOOC_ODOM_7SCENES_COLOR_F): the colour camera's fx, fy, cx, cy at the
     * frames' resolution, and p_color = T_color_depth * p_depth (rigid).
     * The odometry then samples the colour at each depth pixel's projection
     * into the colour camera and tracks the depth camera (the frames' K).
     * Default color_K all 0 = colour registered to depth (T_color_depth
     * unused, identity). */
    double color_K[4];
    double T_color_depth[16];
} sooc_odom_params;

/* Focal length of the 7-Scenes colour camera at 640x480 (the dataset's
 * camera-intrinsics are the depth camera's, f = 585; its colour images are
 * not registered to depth: Brachmann et al., DSAC/LessMore 7-Scenes
 * calibration, principal point 320, 240). */
#define SOOC_ODOM_7SCENES_COLOR_F 525.0

/* 1 if K (at width x height) is the 7-Scenes depth camera's published
 * intrinsics (f = 585, principal point at the centre, 640x480 scaled). */
int sooc_odom_is_7scenes_depth_K(const sooc_intrinsics *K, int width, int height);
/* Set p's colour camera to 7-Scenes' (f = 525 scaled to width x height,
 * principal point at the centre, T_color_depth identity). */
void sooc_odom_params_7scenes_color(sooc_odom_params *p, int width, int height);

void sooc_odom_params_default(sooc_odom_params *p);

typedef enum sooc_odom_state {
    SOOC_ODOM_FIRST = 0,     /* first frame: the origin (or the initial pose)              */
    SOOC_ODOM_TRACKED = 1,   /* pose valid                                                  */
    SOOC_ODOM_FAILED = 2,    /* tracking failed: no pose for this frame                     */
    SOOC_ODOM_REANCHORED = 3 /* lost for max_failures frames; this frame became a keyframe at
                                the last tracked pose (pose uncertain: not usable)           */
} sooc_odom_state;

typedef struct sooc_odom_result {
    sooc_odom_state state;
    int new_keyframe;          /* this frame became the keyframe                 */
    double T_wc[16];           /* valid when state is FIRST or TRACKED           */
    double ms;                 /* time spent in this call                        */
    double agreement;          /* depth agreement with the keyframe (see params) */
} sooc_odom_result;

typedef struct sooc_odom_stats {
    int64_t frames, tracked, failed, keyframes, reanchors;
    double ms_total;
} sooc_odom_stats;

typedef struct sooc_odom sooc_odom;

/* The intrinsics come from the first frame (f->K, at f's size; every later
 * frame must have the same size). */
sooc_status sooc_odom_create(sooc_odom **out, const sooc_odom_params *p);
/* World pose of the first frame (default identity). Call before tracking. */
void sooc_odom_set_initial_pose(sooc_odom *o, const double T_wc[16]);
/* Track one frame (rgb + metric depth). A failure to track is not an error:
 * it returns SOOC_OK with r->state FAILED; errors are bad frames. */
sooc_status sooc_odom_track(sooc_odom *o, const sooc_frame *f, sooc_odom_result *r);
void sooc_odom_get_stats(const sooc_odom *o, sooc_odom_stats *s);
/* The frame of the last sooc_odom_track call as the tracker saw it, at the
 * working resolution *w x *h in the depth camera: grey (colour resampled into
 * the depth camera when not registered; w*h bytes) and depth (metres, 0 =
 * invalid; w*h floats). gray and depth may be NULL (size and K only).
 * K = fx fy cx cy at the working resolution (OpenCV pixel centres). The icp
 * variant keeps no grey image: SOOC_EUNSUPPORTED when gray is asked for. */
sooc_status sooc_odom_current_frame(const sooc_odom *o, uint8_t *gray, float *depth, int *w, int *h, double K[4]);
void sooc_odom_destroy(sooc_odom *o);    /* NULL-safe */

/* --------------------------------------------------------- trajectories */

typedef struct sooc_traj {
    int64_t n, cap;
    double *t;          /* seconds                       */
    double *T;          /* 16 per pose, T_wc, row-major  */
} sooc_traj;

/* Append a pose (grows the arrays). */
sooc_status sooc_traj_push(sooc_traj *tr, double t, const double T[16]);
void sooc_traj_free(sooc_traj *tr);   /* leaves it empty */
/* TUM format: `t tx ty tz qx qy qz qw` per line, '#' comments. Errors name
 * the file and the line. */
sooc_status sooc_traj_load_tum(const char *path, sooc_traj *out);
/* Save atomically in TUM format (t with 6 decimals). */
sooc_status sooc_traj_save_tum(const char *path, const sooc_traj *tr);

typedef struct sooc_traj_metrics {
    int64_t pairs;                 /* associated poses (ATE)                          */
    double ate_rmse, ate_mean, ate_median, ate_max;   /* metres, after alignment  */
    double T_align[16];            /* gt ~ T_align * est (rigid, Horn)                */
    int64_t rpe_pairs;             /* pose pairs (i, i + delta)                       */
    double rpe_trans_rmse, rpe_trans_mean;  /* metres per delta                     */
    double rpe_rot_rmse_deg, rpe_rot_mean_deg;
    double rpe_delta;              /* the delta used                                  */
} sooc_traj_metrics;

/* ATE: associate est and gt by nearest timestamp within max_dt seconds,
 * align est to gt with the closed-form rigid (no scale) least squares
 * (Horn / Umeyama, SVD through LAPACKE), then the translational error
 * statistics. RPE (TUM evaluate_rpe): over associated pairs (i, j) with
 * t_j - t_i closest to delta_s seconds (delta_s > 0), or j = i + delta_frames
 * when delta_s = 0: E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), its translation norm
 * and rotation angle. Fails if fewer than 3 pairs associate. */
sooc_status sooc_traj_evaluate(const sooc_traj *est, const sooc_traj *gt, double max_dt, double delta_s,
                               int delta_frames, sooc_traj_metrics *out);
/* Closed-form rigid alignment of n point pairs: T minimises
 * sum |b_i - T a_i|^2 (a, b: 3 doubles per point). n >= 3, not collinear. */
sooc_status sooc_align_rigid(const double *a, const double *b, int64_t n, double T[16]);

/* ----------------------------------------------------------- calibration */

typedef enum sooc_board_kind { SOOC_BOARD_CHARUCO = 0, SOOC_BOARD_CHECKER = 1 } sooc_board_kind;

typedef struct sooc_board {
    sooc_board_kind kind;
    int squares_x, squares_y;      /* squares (corners = (sx-1) x (sy-1))     */
    double square_m, marker_m;     /* side lengths; marker only for ChArUco    */
    int dict;                      /* OpenCV predefined dictionary (DICT_4X4_50 = 0) */
} sooc_board;

/* "charuco:7x5:0.04:0.03" (default dictionary 4x4_50, or a fifth field
 * 4x4_50|5x5_100|6x6_250) or "checker:9x6:0.025". */
sooc_status sooc_board_parse(const char *spec, sooc_board *b);
size_t sooc_board_format(const sooc_board *b, char *buf, size_t cap);

/* Render the board as an RGB8 image seen by a pinhole camera (K, plumb-bob
 * distortion if set; OpenCV pixel centres) at T_cam_board (p_cam = T *
 * p_board; the board lies in its z = 0 plane, corners at multiples of
 * square_m from its origin as OpenCV defines them). A one-square white
 * margin surrounds the board, a grey wall the rest. ss x ss supersampling
 * per pixel, then Gaussian noise of std noise (0..255 units) from seed. */
sooc_status sooc_board_render(const sooc_board *b, const sooc_intrinsics *K, const double T_cam_board[16],
                              int ss, double noise, uint64_t seed, sooc_image *out);

/* Where the board lies in its own frame (as OpenCV defines it): the centre
 * of the printed squares, the side it reads correctly from (front_z = -1:
 * the camera is at z < 0 looking along +z; +1 the other side) and whether
 * board +y runs down the printed image (y_down = +1) or up (-1). */
sooc_status sooc_board_layout(const sooc_board *b, double center[3], double *front_z, double *y_down);

typedef struct sooc_board_view {
    int n;                 /* corners detected (0 = no board)  */
    double *obj, *img;     /* 3 and 2 doubles per corner        */
} sooc_board_view;

/* Detect the board in an image (RGB8 or gray). view->obj/img are
 * (re)allocated; free with sooc_board_view_free. */
sooc_status sooc_board_detect(const sooc_board *b, const sooc_image *img, sooc_board_view *view);
void sooc_board_view_free(sooc_board_view *v);

typedef struct sooc_calib_report {
    int views_given, views_used;
    double rms_px;                 /* reprojection RMS over the views used  */
    double (*T_cam_board)[16];     /* per used view (views_used), sooc_malloc'd; may be NULL */
    int *view_index;               /* index in the input list of each used view */
} sooc_calib_report;
void sooc_calib_report_free(sooc_calib_report *r);

/* Intrinsics from n images (paths) of the board. Views with fewer than
 * min_points corners are skipped; fewer than min_views usable views is
 * SOOC_EINVAL naming the views that failed. dist_n: 0, 4 or 5 distortion
 * coefficients. Fills calib (size, K, plumb_bob distortion). */
sooc_status sooc_calib_intrinsics(const sooc_board *b, const char *const *paths, int n, int min_views,
                                  int min_points, int dist_n, sooc_calib *calib, sooc_calib_report *rep);

/* Hand-eye: n images with arm poses T_base_ee (16 per image), the camera's
 * intrinsics in calib -> T_ee_cam (calib->T_effector_camera is set). The
 * board is located in each image with solvePnP. Fails (SOOC_EINVAL, clear
 * message) with fewer than min_views usable views or motions without enough
 * rotation (max pairwise rotation between arm poses below 5 deg, or all
 * rotation axes parallel). method: 0 Tsai, 1 Park, 2 Horaud, 3 Andreff,
 * 4 Daniilidis. rms_px: mean PnP reprojection RMS. */
sooc_status sooc_calib_handeye(const sooc_board *b, const char *const *paths, const double *T_base_ee, int n,
                               int min_views, int method, sooc_calib *calib, double *rms_px, int *views_used);

/* Load a calibration YAML with OpenCV's FileStorage (the node reads it with
 * libyaml, sooc_calib_load): image size and the 3x3 camera matrix. */
sooc_status sooc_cv_calib_yaml_read(const char *path, int *width, int *height, double K[9]);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_CV_H */
