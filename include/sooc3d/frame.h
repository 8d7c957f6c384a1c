/*
 * sooc3d frames: the RGB-D frame and everything that brings one to the
 * mapper. The frame type; camera calibration files; pose sources; the
 * support plane (floor / table) estimate; reading recorded sequences; the
 * frame path (preprocessing, gravity / support alignment, the world).
 *
 * Sections: the RGB-D frame (frame); camera calibration files (calib); pose
 * sources (pose); the support plane (support); reading frame sequences
 * (seq); the frame path (framepath).
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
#ifndef SOOC3D_FRAME_H
#define SOOC3D_FRAME_H

#include <stddef.h>
#include <stdint.h>

#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== the RGB-D frame (frame) ============================================ */

/*
 * sooc3d frames: the one RGB-D frame type that crosses every seam
 * (readers -> node -> mapper -> eval), see docs/formats.md §2.7.
 *
 * A frame owns its pixel buffers (allocated with sooc_malloc by
 * sooc_frame_alloc and released by sooc_frame_free).
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

typedef struct sooc_frame {
    int width, height;
    uint8_t *rgb;          /* H*W*3, RGB8, row-major                                   */
    float *depth;          /* H*W metres along the optical axis (planar z); 0 = invalid */
    uint8_t *valid;        /* H*W, 1 where depth is valid (depth > 0 and finite)        */
    uint16_t *instance;    /* H*W instance ids (0 = floor/background), or NULL          */
    int64_t t_ns;          /* sensor clock, nanoseconds                                 */
    int has_pose;          /* 1 when T_wc holds a pose                                  */
    double T_wc[16];       /* camera-to-world, row-major, OpenCV camera axes            */
    sooc_intrinsics K;     /* intrinsics at this frame's resolution                     */
    int64_t index;         /* frame number within its sequence                          */
    int is_query;          /* synthetic data: 1 for a held-out query view               */
} sooc_frame;

/* Why a frame could not be read, for sources that skip a broken frame and go
 * on (the replay driver; the node counts them, docs/node.md "Faults"). */
typedef enum sooc_frame_fault {
    SOOC_FRAME_FAULT_NONE = 0,
    SOOC_FRAME_FAULT_COLOR,   /* colour image missing, truncated or corrupt      */
    SOOC_FRAME_FAULT_DEPTH,   /* depth image missing, truncated or corrupt       */
    SOOC_FRAME_FAULT_POSE,    /* its pose (file) does not parse                  */
    SOOC_FRAME_FAULT_SIZE,    /* wrong size: depth vs colour, or vs the camera   */
    SOOC_FRAME_FAULT_OTHER,
    SOOC_FRAME_FAULT_COUNT
} sooc_frame_fault;

/* "colour", "depth", "pose", "size", "other" ("none" for 0). */
static inline const char *sooc_frame_fault_name(sooc_frame_fault f) {
    static const char *const k[SOOC_FRAME_FAULT_COUNT] = {"none", "colour", "depth", "pose", "size", "other"};
    return (int)f >= 0 && f < SOOC_FRAME_FAULT_COUNT ? k[f] : "other";
}

/* Allocate buffers for a w x h frame (instance buffer only if with_instance).
 * Zeroes everything. On failure, the frame is left empty. */
sooc_status sooc_frame_alloc(sooc_frame *f, int w, int h, int with_instance);
void sooc_frame_free(sooc_frame *f);     /* NULL-safe; leaves *f zeroed */
sooc_status sooc_frame_copy(sooc_frame *dst, const sooc_frame *src); /* into dst's buffers when its size
                                                                       matches, else (re)allocated */

/* ==== camera calibration files (calib) =================================== */

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

/* ==== pose sources (pose) ================================================ */

/*
 * sooc3d pose sources: timestamped camera poses T_wc for frames.
 *
 *   file     a trajectory in TUM format (groundtruth.txt: `t tx ty tz qx qy qz qw`,
 *            t in seconds, '#' comments), camera-to-world.
 *   socket   a live stream on a UDP ("udp://127.0.0.1:5005", "udp://:5005") or UNIX
 *            datagram socket ("unix:/run/sooc3d/pose.sock"); a receiver thread
 *            inserts poses into the buffer. Datagrams hold one binary packet
 *            (below) or text lines `t tx ty tz qx qy qz qw` (t in seconds).
 *   buffer   no input; the caller pushes poses with sooc_pose_push.
 *
 * Poses of the camera are stored as given. Poses of the end effector
 * (T_base_effector from arm kinematics) are turned into camera poses with the
 * hand-eye extrinsic:  T_wc = T_world_base * T_base_effector * T_effector_camera.
 *
 * All sources keep a bounded ring sorted by time: out-of-order poses are
 * inserted in place, duplicates (same t_ns) are dropped, and when full the
 * oldest pose is dropped (a pose older than everything in a full ring is
 * rejected). sooc_pose_lookup interpolates between the two poses bracketing
 * t (SLERP on rotation, linear on translation, sooc_se3_interp).
 *
 * Thread-safety: every function may be called concurrently with the receiver
 * thread; lookups from several threads are fine.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

typedef struct sooc_pose_src sooc_pose_src;

typedef enum sooc_pose_kind {
    SOOC_POSE_CAMERA = 0,      /* pose is T_world_camera (OpenCV optical axes)  */
    SOOC_POSE_EFFECTOR = 1     /* pose is T_base_effector (needs hand-eye)      */
} sooc_pose_kind;

typedef struct sooc_pose_params {
    int capacity;                  /* ring size in poses (default 4096)                    */
    int has_hand_eye;              /* 1: T_effector_camera below is valid (required for
                                      effector poses; they are rejected and counted
                                      otherwise)                                           */
    double T_effector_camera[16];  /* hand-eye extrinsic (calib `T_effector_camera`)       */
    double T_world_base[16];       /* robot base in the world (default identity)           */
    sooc_pose_kind text_kind;      /* kind of text-form poses (default camera)             */
    int64_t max_gap_ns;            /* never interpolate across a gap longer than this
                                      (default 0 = no limit beyond the lookup tolerance)   */
    int rcvbuf_bytes;              /* socket SO_RCVBUF (0 = system default)                */
} sooc_pose_params;

void sooc_pose_params_default(sooc_pose_params *p);

sooc_status sooc_pose_open_file(sooc_pose_src **out, const char *path, const sooc_pose_params *p);
sooc_status sooc_pose_open_socket(sooc_pose_src **out, const char *address, const sooc_pose_params *p);
sooc_status sooc_pose_open_buffer(sooc_pose_src **out, const sooc_pose_params *p);
void sooc_pose_close(sooc_pose_src *src);  /* NULL-safe; joins the receiver thread */

/* Insert a pose (kind camera or effector, T row-major 4x4). Returns SOOC_OK,
 * or SOOC_EINVAL for a non-rigid T / an effector pose without hand-eye; a
 * duplicate or too-old pose returns SOOC_OK and is counted. */
sooc_status sooc_pose_push(sooc_pose_src *src, int64_t t_ns, sooc_pose_kind kind, const double T[16]);
/* Same with translation + unit quaternion (x, y, z, w). */
sooc_status sooc_pose_push_tq(sooc_pose_src *src, int64_t t_ns, sooc_pose_kind kind,
                              const double t[3], const double q[4]);

/* Camera pose at t_ns. Uses the poses p0 <= t <= p1 around t (an exact match
 * needs only one) and requires t - t0 <= tol_ns and t1 - t <= tol_ns (and
 * t1 - t0 <= max_gap_ns when set). Otherwise SOOC_ENOTFOUND, counted as a
 * skipped frame. Every call counts as one lookup. */
sooc_status sooc_pose_lookup(sooc_pose_src *src, int64_t t_ns, int64_t tol_ns, double T_wc_out[16]);
/* Like lookup, but for a live stream whose pose after t has not arrived yet:
 * waits up to timeout_ms for a pose newer than t before giving up. */
sooc_status sooc_pose_wait_lookup(sooc_pose_src *src, int64_t t_ns, int64_t tol_ns, int timeout_ms,
                                  double T_wc_out[16]);

typedef struct sooc_pose_stats {
    int64_t received;      /* poses accepted into the ring                        */
    int64_t packets;       /* datagrams received (socket)                         */
    int64_t bad_packets;   /* bad magic/version/CRC/size, unparsable text         */
    int64_t duplicates;    /* same t_ns as a stored pose: dropped                 */
    int64_t out_of_order;  /* inserted before the newest stored pose              */
    int64_t overflow;      /* dropped because the ring was full                   */
    int64_t rejected;      /* effector pose without hand-eye, non-rigid matrix    */
    int64_t seq_gaps;      /* packets missing according to the sender's seq       */
    int64_t lookups, hits, exact, skipped;  /* skipped = lookups returning ENOTFOUND */
    int count;             /* poses in the ring now                               */
    int64_t t_first_ns, t_last_ns;          /* range held (0 when empty)          */
} sooc_pose_stats;
void sooc_pose_get_stats(sooc_pose_src *src, sooc_pose_stats *out);

/* ---- wire format ---------------------------------------------------------
 * One binary packet per datagram, 88 bytes, little-endian:
 *   0  u32  magic 0x4F505353 ("SSPO" in memory order: 'S','S','P','O')
 *   4  u16  version (1)
 *   6  u16  flags: bit 0 = 1 for an end-effector pose, 0 for a camera pose
 *   8  u32  seq (sender's counter, for gap counting)
 *  12  u32  reserved (0)
 *  16  i64  t_ns (same clock as the frames, normally CLOCK_REALTIME)
 *  24  f64 x7  tx ty tz qx qy qz qw (metres; Hamilton quaternion, scalar last)
 *  80  u32  CRC-32 (zlib) of bytes 0..79
 *  84  u32  reserved (0)
 * Text form (one or more lines per datagram): `t tx ty tz qx qy qz qw`,
 * t in seconds (as in TUM files); '#' lines ignored; kind = params.text_kind. */
#define SOOC_POSE_PACKET_SIZE 88
#define SOOC_POSE_PACKET_MAGIC 0x4F505353u
#define SOOC_POSE_PACKET_VERSION 1

typedef struct sooc_pose_packet {
    uint32_t seq;
    sooc_pose_kind kind;
    int64_t t_ns;
    double t[3];
    double q[4];   /* x y z w */
} sooc_pose_packet;

void sooc_pose_packet_encode(uint8_t buf[SOOC_POSE_PACKET_SIZE], const sooc_pose_packet *pk);
/* SOOC_EFORMAT with a message on a bad size/magic/CRC, SOOC_EVERSION on a
 * newer version. */
sooc_status sooc_pose_packet_decode(const uint8_t *buf, size_t n, sooc_pose_packet *pk);

/* Send one packet (binary) or a text line to `address` (same syntax as
 * sooc_pose_open_socket). For tools and tests; opens and closes a socket per
 * call unless a sender is kept. */
typedef struct sooc_pose_sender sooc_pose_sender;
sooc_status sooc_pose_sender_open(sooc_pose_sender **out, const char *address);
sooc_status sooc_pose_sender_send(sooc_pose_sender *s, const sooc_pose_packet *pk);
sooc_status sooc_pose_sender_send_raw(sooc_pose_sender *s, const void *data, size_t n);
void sooc_pose_sender_close(sooc_pose_sender *s);

/* ==== the support plane (support) ======================================== */

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
 * This section is a contract between the node, the CLI commands and eval.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

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

typedef enum sooc_frames_depth_resample {
    SOOC_FRAMES_DEPTH_MIN = 0,       /* min of the valid samples in the footprint (default) */
    SOOC_FRAMES_DEPTH_NEAREST = 1    /* the sample nearest to the footprint centre */
} sooc_frames_depth_resample;

/* ---------------------------------------------------------- preprocessing */

/* Register a depth image (planar metres, 0 = invalid) from the depth camera
 * into the colour camera: each depth pixel is back-projected with Kd, moved by
 * T_color_depth and splatted into the colour image (Kc's size) keeping the
 * nearest surface. Holes stay 0. `out` has Kc->width * Kc->height floats. */
void sooc_frames_register_depth(const float *depth, const sooc_intrinsics *Kd,
                                const double T_color_depth[16], const sooc_intrinsics *Kc, float *out);

/* The centred crop of a (w, h) image with the aspect ratio of (tw, th). */
void sooc_frames_crop_for_aspect(int w, int h, int tw, int th, int *x0, int *y0, int *cw, int *ch);

/* Resize a crop (x0, y0, cw, ch) of an RGB8 image (w x h) to tw x th by area
 * averaging (exact fractional pixel coverage). */
void sooc_frames_resize_rgb_area(const uint8_t *src, int w, int h, int x0, int y0, int cw, int ch,
                                 uint8_t *dst, int tw, int th);
/* Resize a crop of a depth image without ever averaging across edges: each
 * target pixel takes the min of the valid samples in its footprint
 * (SOOC_FRAMES_DEPTH_MIN) or the sample nearest the footprint centre
 * (SOOC_FRAMES_DEPTH_NEAREST). Samples outside [dmin, dmax] or non-finite are
 * invalid (0); dmax <= 0 means no upper limit. */
void sooc_frames_resize_depth(const float *src, int w, int h, int x0, int y0, int cw, int ch,
                              float *dst, int tw, int th, sooc_frames_depth_resample mode,
                              double dmin, double dmax);
/* Resize a crop of an id image (row stride w) to tw x th: the sample nearest
 * each footprint's centre (ids are never mixed). */
void sooc_frames_resize_ids(const uint16_t *src, int w, int x0, int y0, int cw, int ch, uint16_t *dst, int tw,
                            int th);

/* Full preprocessing of one frame to the model's resolution: crop to the
 * target aspect, resize RGB (area) and depth (min/nearest), set `valid`,
 * adjust the intrinsics, copy t_ns/index/pose; instance ids (when src has
 * them) by nearest sampling. `dst` is (re)allocated. */
sooc_status sooc_frames_preprocess(const sooc_frame *src, sooc_frame *dst, int tw, int th,
                                   sooc_frames_depth_resample mode, double dmin, double dmax);

/* The rigid transform T_world_src that rotates the pose source's frame so that
 * `up` (unit, source coordinates) becomes +y and the floor (up . p = floor_h)
 * lands on y = 0. The rotation is the smallest one taking up to +y. */
void sooc_frames_world_from_up(const double up[3], double floor_h, double T_world_src[16]);

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
size_t sooc_frames_depth_points(const sooc_frame *f, const double T_src_c[16], int step, double *pts,
                                size_t cap);

/* ==== reading frame sequences (seq) ====================================== */

/*
 * sooc3d RGB-D sequence readers and the synthetic-layout writer
 * (docs/formats.md §Sequences).
 *
 * Formats (forced, or detected: rgb.txt -> TUM, traj.txt -> Replica,
 * pose.txt -> slambook2, cam.info.txt -> APC, then the first of
 * frame-NNNNNN.color.* -> 7-Scenes / label-fusion and NNNNNN-color.png ->
 * YCB-Video in the directory):
 *  - TUM / sooc3d synthetic: rgb.txt, depth.txt, groundtruth.txt
 *    (`t tx ty tz qx qy qz qw`, camera-to-world), rgb/, depth/ (16-bit PNG),
 *    calib.yaml (depth_scale); optional instance/ (16-bit ids) and
 *    scene.yaml (query views). Streams are associated by nearest timestamp
 *    within max_dt; rgb frames without a depth match are dropped, frames
 *    without a pose match get has_pose = 0.
 *  - 7-Scenes / label-fusion: frame-NNNNNN.{color.jpg | color.png, depth.png,
 *    pose.txt}, camera-intrinsics.color.txt or camera-intrinsics.txt (3x3),
 *    or calib.yaml. The directory is scanned for frame-NNNNNN.color.*: the
 *    numbers may start anywhere and have gaps (trimmed or subsampled
 *    recordings); frames are read in numeric order and sooc_frame.index is
 *    the file's number. Optional gravity-direction.txt (sooc_seq_gravity).
 *  - slambook2: pose.txt (`tx ty tz qx qy qz qw` per line, line i = frame
 *    i+1), color/N.png, depth/N.{pgm,png}; intrinsics and depth_scale must
 *    come from p->calib_path or <dir>/calib.yaml.
 *  - Replica (NICE-SLAM): traj.txt (16 floats per line, row-major c2w),
 *    results/frame%06d.jpg (or .png), results/depth%06d.png.
 *  slambook2 and Replica name frame i after line i of their pose list; a
 *  line whose colour and depth files are both absent is skipped (a trimmed
 *  copy), one with only one of them is an error.
 *  - YCB-Video as shipped (PoseCNN, DenseFusion, BOP YCB-V): NNNNNN-color.png,
 *    NNNNNN-depth.png (metres = value / factor_depth), NNNNNN-label.png
 *    (8-bit class index = instance id, ground truth; optional) and
 *    NNNNNN-meta.mat (MATLAB v5, read with libmatio: intrinsic_matrix,
 *    factor_depth, rotation_translation_matrix = world-to-camera 3x4; T_wc is
 *    its inverse); a calibration YAML, when given, overrides its intrinsics
 *    and depth scale.
 *  - APC (apc-vision-toolbox): cam.info.txt (colour and depth intrinsics,
 *    depth-to-colour, bin-to-world, then one camera-to-world 4x4 per frame,
 *    which lists the frames), frame-NNNNNN.color.png, frame-NNNNNN.depth.png
 *    (aligned to colour; the 16 bits rotated right by 3, then 1e-4 m), and
 *    optional masks/frame-NNNNNN.<object>.mask.png (16-bit confidence) with
 *    masks/<object>.thresh.txt: the instance label of a pixel is the object
 *    whose confidence passes its threshold, the highest when several do;
 *    object k of the "# Objects:" line has id k + 1 (sooc_seq_label_name).
 *    These labels are predictions (sooc_seq_labels_predicted).
 *
 * Colour may be PNG or JPEG whatever the extension (read by content).
 * Depth: metres = (raw >> depth_shift) * depth_scale (APC: a right rotation
 * of the 16 bits instead of the shift); raw 0 and raw ==
 * depth_invalid (before the shift) are invalid. Each of the three comes from
 * the open parameters, else the calibration YAML, else the format's default
 * (sooc_seq_formats(): 7-Scenes mm with 65535 invalid, label-fusion
 * (raw >> 3) * 1e-4 m, Replica 1/6553.5 m), else it is an error (scale) or
 * 0 / 65535 (shift / invalid).
 *
 * Every reader validates at open: missing files, unparsable numbers,
 * non-monotonic timestamps, non-orthonormal rotations; and at read: image
 * sizes against the calibration and each other, depth bit depth (must be
 * 16-bit). Messages name the file and the line, e.g.
 * "seq/groundtruth.txt:7: rotation is not orthonormal (error 0.02)".
 *
 * A camera with fy < 0 (ICL-NUIM) is converted to fy > 0 by mirroring the
 * world y axis: T_wc' = S T_wc S with S = diag(1, -1, 1, 1), cy unchanged
 * (the image is not flipped).
 *
 * Thread safety: a sooc_seq may be used by one thread at a time; distinct
 * sequences are independent.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

typedef enum sooc_seq_format {
    SOOC_SEQ_AUTO = 0,
    SOOC_SEQ_TUM,        /* TUM RGB-D and the sooc3d synthetic layout */
    SOOC_SEQ_7SCENES,    /* frame-%06d.* (7-Scenes)                  */
    SOOC_SEQ_SLAMBOOK,   /* pose.txt + color/ + depth/               */
    SOOC_SEQ_REPLICA,    /* NICE-SLAM Replica traj.txt + results/    */
    SOOC_SEQ_LABELFUSION,/* the 7-Scenes layout, label-fusion depth  */
    SOOC_SEQ_YCB,        /* YCB-Video: %06d-{color,depth,label}.png, -meta.mat */
    SOOC_SEQ_APC,        /* APC: cam.info.txt, frame-%06d.*, masks/  */
    /* Not a directory layout and not in the format table: frames from
     * another reader through sooc_seq_open_source (a robot log, log.h). */
    SOOC_SEQ_SOURCE = 64
} sooc_seq_format;
#define SOOC_SEQ_FORMAT_COUNT 8

/* One row of the format-name table: the only place format names live. The
 * launch parser, the CLI and the replay driver use the functions below. */
typedef struct sooc_seq_format_info {
    sooc_seq_format format;
    const char *name;         /* canonical name, e.g. "7scenes"                      */
    const char *aliases;      /* other accepted names, '|'-separated ("" = none)     */
    const char *layout;       /* one line for help texts                             */
    double depth_scale;       /* default metres per (shifted) unit; 0 = from calib   */
    int depth_shift;          /* default right shift of raw depth                    */
    int depth_invalid;        /* default raw "no depth" value besides 0 (0 = none)   */
    int depth_circular;       /* 1: the shift rotates the 16 bits right (APC)        */
    int labels_predicted;     /* 1: the layout's labels are a network's predictions
                                 (scores against them measure agreement)           */
} sooc_seq_format_info;

/* The table (SOOC_SEQ_FORMAT_COUNT rows, row i = enum value i). */
const sooc_seq_format_info *sooc_seq_formats(int *n);
/* The row of f, or NULL when f is out of range. */
const sooc_seq_format_info *sooc_seq_format_info_of(sooc_seq_format f);
/* Canonical name: "auto", "tum", "7scenes", "slambook", "replica",
 * "label-fusion", "ycb-video", "apc" ("?" when out of range). */
const char *sooc_seq_format_name(sooc_seq_format f);
/* Any name or alias, case-insensitive: auto; tum, sooc, tum-rgbd; 7scenes,
 * sevenscenes, 7-scenes; slambook, slambook2; replica, nice-slam;
 * label-fusion, labelfusion, label_fusion; ycb-video, ycb, ycbv, ycb_video;
 * apc, apc-shelf, apc_shelf. Unknown -> EINVAL listing them. */
sooc_status sooc_seq_format_parse(const char *s, sooc_seq_format *out);
/* Writes "auto, tum (sooc, tum-rgbd), 7scenes (...), ..." for messages and
 * help texts; returns the full length (like snprintf). */
size_t sooc_seq_format_list(char *buf, size_t cap);

typedef struct sooc_seq_open_params {
    sooc_seq_format format;   /* AUTO = detect                                         */
    const char *calib_path;   /* calib YAML overriding <dir>/calib.yaml (may be NULL)  */
    double depth_scale;       /* > 0 overrides the calibration's depth_scale (m/unit)  */
    int depth_shift;          /* >= 0: right-shift raw depth before scaling; -1 (the
                                 default) = calibration, else the format's default    */
    int depth_invalid;        /* >= 0: raw value that means "no depth" besides 0 (0 =
                                 none); -1 (the default) = calibration, else format   */
    double max_dt;            /* TUM association tolerance in seconds (default 0.02)   */
    double rot_tol;           /* orthonormality tolerance (default 1e-3)               */
    double max_depth;         /* depths beyond this are invalid (0 = no limit)         */
    int keep_bad_frames;      /* 7-Scenes layout: 1 = a frame whose depth or pose file is
                                 missing, or whose pose file does not parse, still opens
                                 and reading it fails with that message (the replay
                                 driver skips such frames); 0 = the open fails        */
} sooc_seq_open_params;

void sooc_seq_open_params_default(sooc_seq_open_params *p);

typedef struct sooc_seq sooc_seq;

/* Open and validate a sequence directory. p may be NULL (defaults). On
 * failure *out = NULL and the message names the file and line. */
sooc_status sooc_seq_open(sooc_seq **out, const char *dir, const sooc_seq_open_params *p);
int64_t sooc_seq_count(const sooc_seq *s);
/* Read frame i (0 <= i < count) into f. f must be zero-initialised or hold a
 * frame from an earlier call (its buffers are reused when the size matches).
 * Fills rgb, depth (planar metres, 0 = invalid), valid, instance (synthetic
 * layout, YCB-Video label.png, APC masks; else NULL), t_ns, has_pose/T_wc, K, index (the frame's number
 * in its file names, = i for TUM), is_query. On error (a missing, truncated
 * or corrupt image, named in the message) f may hold a partial frame: do not
 * use it; nothing else changes and later frames can still be read. */
sooc_status sooc_seq_read(sooc_seq *s, int64_t i, sooc_frame *f);
/* The format actually read (never AUTO once open). */
sooc_seq_format sooc_seq_get_format(const sooc_seq *s);
/* Frame i's number in its file names (7-Scenes frame-000042.* -> 42; TUM:
 * i), and its colour and depth image paths; -1 / NULL when i is out of range. */
int64_t sooc_seq_frame_number(const sooc_seq *s, int64_t i);
/* Frame i's t_ns as sooc_seq_read would give it, without reading any image
 * (known at open); INT64_MIN when i is out of range. */
int64_t sooc_seq_frame_time(const sooc_seq *s, int64_t i);
const char *sooc_seq_color_path(const sooc_seq *s, int64_t i);
const char *sooc_seq_depth_path(const sooc_seq *s, int64_t i);
/* The depth decoding in use: metres = (raw >> shift) * scale, raw 0 and raw ==
 * invalid (when > 0) are invalid. With sooc_seq_depth_circular(s) == 1 the
 * shift is a right rotation of the 16 bits: (raw >> shift) | (raw << (16 -
 * shift)) on 16 bits (APC). */
void sooc_seq_depth_decoding(const sooc_seq *s, double *scale, int *shift, int *invalid);
/* 1 when frame i was kept with a pose file that is missing or does not parse
 * (keep_bad_frames): sooc_seq_read of it fails with that file's message. */
int sooc_seq_pose_bad(const sooc_seq *s, int64_t i);
int sooc_seq_depth_circular(const sooc_seq *s);
/* 1 when the frames carry instance ids (sooc_seq_read fills f->instance). */
int sooc_seq_has_labels(const sooc_seq *s);
/* 1 when those ids are predictions (APC: a segmentation network's masks), not
 * ground truth: scores against them measure agreement, not accuracy. 0 for
 * ground truth or no labels. */
int sooc_seq_labels_predicted(const sooc_seq *s);
/* The name of label id (APC: the object of the "# Objects:" line; YCB-Video:
 * the class, e.g. "025_mug"), or NULL when the layout names none. */
const char *sooc_seq_label_name(const sooc_seq *s, int id);
const sooc_calib *sooc_seq_calib(const sooc_seq *s);
/* Gravity direction in the world frame (the frame of T_wc), from
 * <dir>/gravity-direction.txt (7-Scenes: three numbers, one per line or on
 * one line). Returns 1 and g normalised to unit length when the sequence has
 * one, 0 (g untouched) otherwise. A malformed or zero-length file fails
 * sooc_seq_open (EFORMAT/EINVAL naming the file). */
int sooc_seq_gravity(const sooc_seq *s, double g[3]);
void sooc_seq_close(sooc_seq *s);   /* NULL-safe */

/* A sequence whose frames another reader makes (sooc_log_seq_open in log.h
 * reads ROS bags and MCAP files this way): n frames with stamps t_ns[i]
 * (ascending, copied), read(user, i, f) fills frame i as sooc_seq_read would
 * (the sequence applies max_depth after it), close(user) runs at
 * sooc_seq_close (also when this call fails). calib is copied: its K is what
 * sooc_seq_calib returns. name stands for the directory in messages. The
 * format is SOOC_SEQ_SOURCE ("source"). */
typedef struct sooc_seq_source {
    const char *name;
    int64_t n;
    const int64_t *t_ns;
    const sooc_calib *calib;
    double max_depth;          /* 0 = no limit */
    void *user;
    sooc_status (*read)(void *user, int64_t i, sooc_frame *f);
    void (*close)(void *user);
} sooc_seq_source;
sooc_status sooc_seq_open_source(sooc_seq **out, const sooc_seq_source *src);

/* ------------------------------------------------------------- writer */

/* Writes the sooc3d synthetic layout (TUM + calib.yaml [+ instance/]):
 * rgb/%06d.png, depth/%06d.png (16-bit, round(z / depth_scale)),
 * instance/%06d.png when frames carry ids, and on finish rgb.txt, depth.txt,
 * groundtruth.txt (timestamps from frame t_ns, 6 decimals) and calib.yaml
 * (calib->depth_scale must be > 0; depths beyond 65535 units are stored as 0). */
typedef struct sooc_seq_writer sooc_seq_writer;

sooc_status sooc_seq_writer_create(sooc_seq_writer **out, const char *dir, const sooc_calib *calib,
                                   int64_t n_frames);
/* Write frame slot i (0 <= i < n_frames). Thread-safe for distinct i. */
sooc_status sooc_seq_writer_put(sooc_seq_writer *w, int64_t i, const sooc_frame *f);
/* Write the index files; fails if a slot was never put. */
sooc_status sooc_seq_writer_finish(sooc_seq_writer *w);
void sooc_seq_writer_destroy(sooc_seq_writer *w);  /* NULL-safe */

/* ==== the frame path (framepath) ========================================= */

/*
 * sooc3d frame path: the one way every command reads a recorded or synthetic
 * sequence (node replay, infer, render, eval, train; docs/formats.md
 * "One frame path").
 *
 *   sooc_framepath_open(dir, params)      the sequence reader (sooc_seq) with the
 *                                         same options everywhere: --calib,
 *                                         --format, --depth-scale, --depth-shift,
 *                                         depth range, --up, --world
 *   sooc_framepath_read(fp, i, frame)     frame i, already
 *                                           - cropped to the model's aspect and
 *                                             resized to its resolution (RGB by
 *                                             area, depth by min-of-valid, ids by
 *                                             nearest), intrinsics adjusted;
 *                                           - depth in metres (scale and invalid
 *                                             value from the calibration or the
 *                                             format's documented default), samples
 *                                             outside [min_depth_m, max_depth_m]
 *                                             invalid;
 *                                           - the pose in the map's world frame:
 *                                             T_wc = T_world_src * T_src_c.
 *
 * The world frame (+y up, the support plane at y = 0) is chosen at open:
 *   - a synthetic sequence (scene.yaml present): the identity;
 *   - a recorded one: the frame stored in the map database (p->map_db,
 *     sooc_mapstore_frame_get), else a fresh support-plane estimate
 *     (sooc_support_estimate over up to p->support_frames frames spread over
 *     the sequence; up from --up, else the sequence's gravity file, else the
 *     cameras' mean down direction);
 *   - or as forced by p->world.
 * The choice is logged (sooc_log INFO) and available from
 * sooc_framepath_world; the caller stores a fresh estimate in its own map
 * with sooc_mapstore_frame_put (sooc_framepath_map_frame fills the record).
 *
 * The preprocessing is sooc_frames_preprocess (include/sooc3d/frame.h), the
 * step the live node runs on every keyframe, with the same defaults as a
 * launch file (depth 0.1 .. 10 m, min-of-valid depth resampling).
 *
 * The estimate's figures come back as sooc_framepath_support_info, plain
 * fields that callers read without the support section's types.
 *
 * Thread safety: one thread at a time per sooc_framepath.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

typedef enum sooc_framepath_world {
    SOOC_WORLD_AUTO = 0,      /* scene.yaml: identity; else stored map frame; else estimate */
    SOOC_WORLD_IDENTITY = 1,  /* poses are already gravity-aligned (+y up, floor at 0)      */
    SOOC_WORLD_STORED = 2,    /* the map database's frame; fails if it has none            */
    SOOC_WORLD_ESTIMATE = 3,  /* a fresh support-plane estimate (ignores a stored frame)   */
    SOOC_WORLD_GIVEN = 4      /* p->T_world_src as given                                   */
} sooc_framepath_world;

/* "auto", "identity", "stored", "estimate", "given" */
const char *sooc_framepath_world_name(sooc_framepath_world w);
sooc_status sooc_framepath_world_parse(const char *s, sooc_framepath_world *out);

typedef struct sooc_framepath_params {
    /* reading (sooc_seq_open_params) */
    const char *calib_path;   /* --calib: calib YAML overriding <dir>/calib.yaml (NULL: none)       */
    sooc_seq_format format;   /* --format (default AUTO)                                          */
    double depth_scale;       /* --depth-scale: > 0 overrides the calibration / format (m per unit) */
    int depth_shift;          /* --depth-shift: >= 0 overrides; -1 (default) = calibration/format   */
    /* preprocessing */
    int width, height;        /* target resolution (the model's); 0 = keep each frame's own       */
    double min_depth_m;       /* valid depth range; defaults 0.1 and 10 (as a launch file).       */
    double max_depth_m;       /* max <= min is an error at open, never an all-invalid frame        */
    sooc_frames_depth_resample resample;  /* default SOOC_FRAMES_DEPTH_MIN                            */
    /* world frame */
    sooc_framepath_world world;
    int has_up;               /* --up: 1 = up (source frame) is the support estimate's hint        */
    double up[3];
    double T_world_src[16];   /* with world = GIVEN                                                */
    const char *map_db;       /* map database to read a stored frame from (NULL: none)            */
    int support_frames;       /* frames handed to sooc_support_estimate (default 30)              */
    double max_tilt_deg;      /* support plane within this angle of up (0 = the estimate's default) */
    double cam_height_min_m;  /* trained camera-height range for the warning (0 = the estimate's   */
    double cam_height_max_m;  /*   defaults, sooc_support_params_default)                          */
} sooc_framepath_params;

void sooc_framepath_params_default(sooc_framepath_params *p);

typedef struct sooc_framepath sooc_framepath;

/* Open dir with p (NULL = defaults) and settle the world frame (which may
 * read up to support_frames frames). On failure *out = NULL and the message
 * names the directory/file and the problem (e.g. "seq: no plane within 30 deg
 * of up (gravity file)"). */
sooc_status sooc_framepath_open(sooc_framepath **out, const char *dir, const sooc_framepath_params *p);
void sooc_framepath_close(sooc_framepath *fp);   /* NULL-safe */

int64_t sooc_framepath_count(const sooc_framepath *fp);
/* Read frame i (0 <= i < count) preprocessed into f (zero-initialised or from
 * an earlier call; buffers are reused). Fills rgb, depth, valid, instance
 * (when the sequence has ids; nearest-resized), K at f's resolution, t_ns,
 * index, is_query, has_pose and T_wc in the map's world frame. */
sooc_status sooc_framepath_read(sooc_framepath *fp, int64_t i, sooc_frame *f);
/* The same frame at the sequence's own resolution, pose in the world frame
 * (depth range applied, no crop/resize). */
sooc_status sooc_framepath_read_raw(sooc_framepath *fp, int64_t i, sooc_frame *f);

/* Resize an id image (w x h, 0 = none) of this sequence's frames with the
 * crop and nearest sampling sooc_framepath_read applies to depth, into dst
 * (width x height of the target). For labels kept outside the reader
 * (label-fusion segm.png). Fails if w x h is not the sequence's frame size
 * as last read. */
sooc_status sooc_framepath_resize_ids(const sooc_framepath *fp, const uint16_t *src, int w, int h, uint16_t *dst);

/* The world frame in use: T_world_src (p_world = T * p_src) and where it came
 * from (returned). */
sooc_framepath_world sooc_framepath_world_get(const sooc_framepath *fp, double T_world_src[16]);
/* The support estimate's figures (a copy of sooc_support's). */
typedef struct sooc_framepath_support_info {
    double T_world_src[16];
    double up_src[3];         /* unit up in the source frame                    */
    double plane_src[4];      /* n . p + d = 0 in the source frame              */
    int up_source;            /* sooc_up_source: 0 given, 1 gravity file, 2 camera mean */
    double tilt_deg, cam_height_m, rms_m;
    int height_warning, frames_used;
    size_t n_inliers, n_points;
} sooc_framepath_support_info;
/* 1 and *out filled when the world came from a support estimate, else 0. */
int sooc_framepath_support(const sooc_framepath *fp, sooc_framepath_support_info *out);
/* Fill a sooc_map_frame-compatible record (cogmap.h) for storing. Fields:
 * T_world_src, up_src, plane_src, cam_height_m, up_source (-1 when the
 * frame was given / identity). Declared with plain arrays so this header
 * does not need cogmap.h. */
void sooc_framepath_frame_record(const sooc_framepath *fp, double T_world_src[16], double up_src[3],
                                 double plane_src[4], double *cam_height_m, int *up_source);

int sooc_framepath_synthetic(const sooc_framepath *fp);   /* 1: the sequence has scene.yaml */
sooc_seq *sooc_framepath_seq(sooc_framepath *fp);         /* the underlying reader (borrowed) */
const char *sooc_framepath_dir(const sooc_framepath *fp);
/* Number of frames whose depth had no valid pixel after preprocessing so
 * far (a wrong depth scale or range shows up here; the commands warn). */
int64_t sooc_framepath_empty_depth(const sooc_framepath *fp);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_FRAME_H */
