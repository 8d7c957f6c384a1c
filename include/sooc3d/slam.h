/*
 * sooc3d tracking: camera odometry, trajectories and their metrics,
 * calibration boards (OpenCV), and the SLAM pose graph over the odometry
 * with its map-store records.
 *
 * Sections: camera tracking and calibration (OpenCV) (cv); the pose graph
 * (slam).
 *
 * Contract (CONTRIBUTING.md "Coding rules"), for every section below where
 * the section does not say otherwise. Ownership: the caller owns what it
 * creates and releases it with the matching _destroy / _free / _close
 * (NULL-safe); pointers a getter returns are borrowed and live as long as
 * their object. Threads: an object is used by one thread at a time;
 * functions without an object are reentrant. Errors: a status other than
 * SOOC_OK comes with a message naming the file, key or line (sooc_errmsg);
 * nothing here prints or exits.
 */
#ifndef SOOC3D_SLAM_H
#define SOOC3D_SLAM_H

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== camera tracking and calibration (OpenCV) (cv) ====================== */

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

/* ==== the pose graph (slam) ============================================== */

/*
 * sooc3d SLAM for a camera without a pose source (src/slam, docs/slam.md):
 * the RGB-D odometry of the cv section plus a keyframe database, place
 * recognition, geometric verification, relocalisation and a pose graph.
 *
 *   keyframes     every odometry keyframe becomes a graph node: its pose,
 *                 up to n_features OpenCV ORB features of its grey image
 *                 (the depth camera's view) with their depth-backprojected
 *                 3D points, and its depth at depth_w x depth_h. With a map
 *                 store they are written to its SLAM tables
 *                 (cogmap.h), one transaction per keyframe.
 *   recognition   descriptor voting: the query's ORB descriptors are matched
 *                 (Hamming <= 64, Lowe ratio 0.8) against every keyframe
 *                 outside the recent window (for loop search: whose pose
 *                 lies within loop_max_dist_m / loop_max_angle_deg of the
 *                 new keyframe's; relocalisation tries all); the
 *                 max_candidates keyframes with the most matches
 *                 (>= min_matches) are verified.
 *   verification  matches with a depth point in the candidate -> OpenCV
 *                 solvePnPRansac (reproj_px, >= min_inliers inliers) ->
 *                 depth-only ICP between the two stored depth images from
 *                 the PnP pose (>= min_overlap of the query's depth points
 *                 land on the candidate's depth, >= min_icp_agree of those
 *                 within 4 cm of it, and ICP moves PnP's pose by no more
 *                 than max_jump_m / max_jump_deg).
 *   loop closure  a verified candidate of a new keyframe adds a loop edge;
 *                 the pose graph (odometry, loop and relocalisation edges;
 *                 Ceres, Huber loss on loop edges) is optimised and the
 *                 keyframe poses are updated in one store transaction.
 *   relocalise    with stored keyframes the tracker starts lost, and it is
 *                 lost again after the odometry's max_failures: each frame
 *                 is matched against all keyframes; until one verifies the
 *                 frames are untracked.
 *
 * Threading: one sooc_slam per thread. The library never prints.
 */

typedef struct sooc_slam_params {
    sooc_odom_params odom;      /* the tracker (cv section); not the icp variant (no grey) */
    int loop_closure;           /* place recognition + pose graph (1)                   */
    int relocalise;             /* start lost over stored keyframes, relocalise when lost (1) */
    int n_features;             /* ORB features per keyframe (800)                      */
    int recent_window;          /* newest keyframes skipped by loop search (6)          */
    int local_edges;            /* also verify a new keyframe against the recent window's
                                   keyframes (besides the previous one): local edges (0) */
    int max_candidates;         /* candidates verified per query (3)                    */
    int loop_verify_per_frame;  /* a new keyframe's candidates are verified on the tracked
                                   frames after it, this many per frame (1); the graph is
                                   optimised once they all are. 0: all of them on the
                                   keyframe's own frame                                  */
    double loop_max_dist_m;     /* loop search: only keyframes whose current pose lies
                                   within this distance of the new one's (1.0; 0 = all) */
    double loop_max_angle_deg;  /* ... and whose viewing direction is within this (60)   */
    int min_matches;            /* descriptor matches for a candidate (40)              */
    int min_inliers;            /* PnP RANSAC inliers (30)                              */
    double reproj_px;           /* PnP inlier threshold at the working resolution (2.0) */
    double min_icp_agree;       /* of the query's depth points that land on the candidate's
                                   depth, the fraction within 4 cm after ICP (0.6)      */
    double min_overlap;         /* the fraction of the query's depth points that land on
                                   the candidate's depth at all (0.3)                   */
    double max_jump_m, max_jump_deg;   /* ICP vs PnP disagreement bound (0.05 m, 5 deg) */
    double sigma_odom_m, sigma_odom_rad;   /* odometry edges (0.01 m, 0.01 rad)         */
    double sigma_loop_m, sigma_loop_rad;   /* loop and relocalisation edges (0.01, 0.01) */
    int depth_w, depth_h;       /* stored keyframe depth (160 x 120)                    */
    int pgo_iterations;         /* Ceres iterations per optimisation (50)               */
} sooc_slam_params;

void sooc_slam_params_default(sooc_slam_params *p);

typedef enum sooc_slam_state {
    SOOC_SLAM_FIRST = 0,        /* first frame of a new map: the origin                 */
    SOOC_SLAM_TRACKED = 1,      /* pose valid                                            */
    SOOC_SLAM_RELOCALISED = 2,  /* pose valid: found in the stored keyframes            */
    SOOC_SLAM_FAILED = 3,       /* odometry failed on this frame: no pose               */
    SOOC_SLAM_LOST = 4          /* lost: relocalisation failed on this frame: no pose   */
} sooc_slam_state;

const char *sooc_slam_state_name(sooc_slam_state s);

typedef struct sooc_slam_result {
    sooc_slam_state state;
    int new_keyframe;           /* this frame became a keyframe (graph node)            */
    int loop_closed;            /* a loop edge was added and the graph optimised        */
    int64_t keyframe_id;        /* the node this frame's pose hangs from (-1: none)     */
    double T_wc[16];            /* valid for FIRST, TRACKED, RELOCALISED                */
    double ms;
} sooc_slam_result;

typedef struct sooc_slam_stats {
    int64_t frames, tracked, failed, lost, relocalised, keyframes, stored_keyframes;
    int64_t loops, local_edges, loop_candidates, loop_rejected, reloc_attempts, optimisations;
    double ms_track, ms_features, ms_loop, ms_reloc, ms_pgo;   /* totals */
    double last_pgo_cost0, last_pgo_cost1;
} sooc_slam_stats;

typedef struct sooc_slam sooc_slam;

/* store: the map database (NULL: keyframes in memory only); its stored
 * keyframes and edges are loaded, new ones are appended with run number
 * (largest stored + 1). The store must outlive the tracker. */
sooc_status sooc_slam_create(sooc_slam **out, const sooc_slam_params *p, sooc_mapstore *store);
void sooc_slam_destroy(sooc_slam *s);   /* NULL-safe */
/* Initial pose of a new map's first frame (default identity); before tracking. */
void sooc_slam_set_initial_pose(sooc_slam *s, const double T_wc[16]);
/* Track one frame (rgb + metric depth). Not tracking is not an error. */
sooc_status sooc_slam_track(sooc_slam *s, const sooc_frame *f, sooc_slam_result *r);
/* Loop candidates still waiting for verification (loop_verify_per_frame),
 * and verifying them all now, optimising the graph if any was accepted:
 * at the end of a sequence, before the trajectory is read. */
int sooc_slam_pending(const sooc_slam *s);
sooc_status sooc_slam_flush(sooc_slam *s, int *loop_closed);
void sooc_slam_get_stats(const sooc_slam *s, sooc_slam_stats *st);
/* The tracked frames of this run with their current poses (after every
 * optimisation so far): t = frame t_ns in seconds. out is reset first. */
sooc_status sooc_slam_trajectory(const sooc_slam *s, sooc_traj *out);
/* The frame index (sooc_frame.index) of the i-th trajectory pose. */
int64_t sooc_slam_trajectory_frame(const sooc_slam *s, int64_t i);

/* Graph nodes: count, and node i's id, run, frame index and pose. */
int64_t sooc_slam_keyframe_count(const sooc_slam *s);
sooc_status sooc_slam_keyframe(const sooc_slam *s, int64_t i, int64_t *id, int32_t *run, int64_t *frame,
                               double T_wc[16]);
/* Geometric verification of node a (the query) against node b: 1 and
 * T_b_a (p_b = T * p_a) when it passes, 0 when it is rejected; *inliers =
 * the PnP inliers (0 when it never got there). */
sooc_status sooc_slam_verify_pair(sooc_slam *s, int64_t a, int64_t b, int *accepted, double T_b_a[16],
                                  int *inliers);

/* ------------------------------------------- moving what was mapped */

/* What the last pose-graph optimisation did to this run's keyframes, so that
 * what was mapped from them can follow: each keyframe's time and its pose
 * (tracker frame) before and after. */
typedef struct sooc_slam_kf_change {
    int64_t t_ns;
    double T_before[16], T_after[16];
} sooc_slam_kf_change;

/* Incremented by every optimisation. */
uint64_t sooc_slam_graph_version(const sooc_slam *s);
/* The changes of the last optimisation: *n = their number (this run's
 * keyframes, by time); the first min(n, cap) go to out (may be NULL). */
sooc_status sooc_slam_last_changes(const sooc_slam *s, sooc_slam_kf_change *out, size_t cap, size_t *n);
/* Move map entries (world frame: +y up, floor y = 0; T_world_src maps the
 * tracker's frame into it) with the keyframe nearest in time to each
 * entry's last_seen_ns: C = W T_after T_before^-1 W^-1 moves the point
 * (x, geom.centre[1], z) and the registrations' mean floor position, turns
 * yaw by C's rotation about +y (sooc_m3_rot_y's sense) and the xz
 * covariance with it. Entries last seen outside the keyframes' time span
 * (more than max_gap_ns before the first or after the last) are left
 * alone. Returns the number moved. chg must be sorted by t_ns (as
 * sooc_slam_last_changes gives it). */
size_t sooc_slam_move_entries(const sooc_slam_kf_change *chg, size_t n_chg, const double T_world_src[16],
                              int64_t max_gap_ns, sooc_map_entry *e, size_t n);

/* ------------------------------------------------------ tracking thread */

/* The tracker on its own thread, between a frame source (the node's sensor
 * ring) and the mapper: it pops frames from `pop` (the same contract as
 * sooc_frame_ring_pop: SOOC_OK, SOOC_ETIMEOUT, SOOC_EEOF), tracks them with
 * the sooc_slam it is given (which it then owns until destroy), and queues
 * the tracked ones with their pose (has_pose = 1, T_wc) for the consumer.
 * It never waits for the consumer: when the output queue is full the oldest
 * queued frame is dropped and counted. Untracked frames are counted by
 * reason and not queued. Frames move by swapping sooc_frame structs. */
typedef sooc_status (*sooc_slam_source_fn)(void *ctx, sooc_frame *f, int64_t *t_mono_ns, int timeout_ms);

typedef struct sooc_slam_tracker_stats {
    int64_t frames_in;          /* frames popped from the source                         */
    int64_t tracked;            /* tracked and queued                                    */
    int64_t untracked_failed;   /* odometry failed on the frame                          */
    int64_t untracked_lost;     /* lost: not yet relocalised                             */
    int64_t dropped_queue_full; /* tracked, then dropped: the consumer was behind        */
    int64_t errors;             /* frames the tracker refused (bad frame)                */
    int64_t keyframes, loops, relocalised;
    double ms_track_mean, ms_track_max;   /* per frame on the tracking thread         */
} sooc_slam_tracker_stats;

typedef struct sooc_slam_tracker sooc_slam_tracker;

sooc_status sooc_slam_tracker_start(sooc_slam_tracker **out, sooc_slam *slam, sooc_slam_source_fn pop, void *ctx,
                                    int queue_capacity);
/* Next tracked frame (swapped into f): SOOC_ETIMEOUT after timeout_ms (< 0:
 * wait), SOOC_EEOF when the source ended and the queue is empty, or the
 * error that stopped the tracking thread. */
sooc_status sooc_slam_tracker_pop(sooc_slam_tracker *t, sooc_frame *f, int64_t *t_mono_ns, int timeout_ms);
void sooc_slam_tracker_get_stats(sooc_slam_tracker *t, sooc_slam_tracker_stats *st);
/* The graph version after the newest optimisation on the tracking thread and
 * its keyframe pose changes (sooc_slam_last_changes): *n of them, the first
 * min(n, cap) into out (may be NULL). */
sooc_status sooc_slam_tracker_changes(sooc_slam_tracker *t, uint64_t *version, sooc_slam_kf_change *out, size_t cap,
                                      size_t *n);
/* One line: "tracking: N in, N tracked, N failed, N lost, N dropped (queue
 * full), N keyframes, N loops, N relocalised, mean/max ms". */
size_t sooc_slam_tracker_stats_format(const sooc_slam_tracker_stats *st, char *buf, size_t cap);
/* Stop the thread (the source must return within its timeout), join, free
 * the queued frames and the sooc_slam. NULL-safe. */
void sooc_slam_tracker_destroy(sooc_slam_tracker *t);

/* Keyframe blobs of the map store (cogmap.h). Features: "SLF1", u32
 * version 1, u32 n, then n records (u, v, x, y, z float32; 32-byte ORB
 * descriptor; NaN xyz = no depth), u32 CRC-32 of all before it. Depth:
 * "SLD1", u32 version 1, u32 w, u32 h, float64 fx fy cx cy, w*h uint16
 * millimetres (0 = invalid), u32 CRC-32. Little-endian. */
#define SOOC_SLAM_BLOB_VERSION 1

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_SLAM_H */
