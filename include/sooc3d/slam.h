/*
 * sooc3d SLAM for a camera without a pose source (src/slam, docs/slam.md):
 * the RGB-D odometry of cv.h plus a keyframe database, place recognition,
 * geometric verification, relocalisation and a pose graph.
 *
 *   keyframes     every odometry keyframe becomes a graph node: its pose,
 *                 up to n_features OpenCV ORB features of its grey image
 *                 (the depth camera's view) with their depth-backprojected
 *                 3D points, and its depth at depth_w x depth_h. With a map
 *                 store they are written to its SLAM tables
 *                 (mapstore_slam.h), one transaction per keyframe.
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
#ifndef SOOC3D_SLAM_H
#define SOOC3D_SLAM_H

#include "sooc3d/cv.h"
#include "sooc3d/map_entry.h"
#include "sooc3d/mapstore.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_slam_params {
    sooc_odom_params odom;      /* the tracker (cv.h); not the icp variant (no grey)   */
    int loop_closure;           /* place recognition + pose graph (1)                   */
    int relocalise;             /* start lost over stored keyframes, relocalise when lost (1) */
    int n_features;             /* ORB features per keyframe (800)                      */
    int recent_window;          /* newest keyframes skipped by loop search (6)          */
    int local_edges;            /* also verify a new keyframe against the recent window's
                                   keyframes (besides the previous one): local edges (0) */
    int max_candidates;         /* candidates verified per query (3)                    */
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

/* Keyframe blobs of the map store (mapstore_slam.h). Features: "SLF1", u32
 * version 1, u32 n, then n records (u, v, x, y, z float32; 32-byte ORB
 * descriptor; NaN xyz = no depth), u32 CRC-32 of all before it. Depth:
 * "SLD1", u32 version 1, u32 w, u32 h, float64 fx fy cx cy, w*h uint16
 * millimetres (0 = invalid), u32 CRC-32. Little-endian. */
#define SOOC_SLAM_BLOB_VERSION 1

#ifdef __cplusplus
}
#endif
#endif
