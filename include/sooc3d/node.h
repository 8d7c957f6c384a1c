/*
 * sooc3d node: the live mapping pipeline (docs/node.md).
 *
 *   driver thread ─► frame ring (bounded, drop-oldest) ─► pose association
 *     ─► keyframe policy ─► preprocess ─► sooc_mapper_update ─► publisher
 *        (shm table batch + SQLite transaction per keyframe) ─► stats
 *
 * The launch file (YAML) configures all of it; see docs/node.md. The library
 * never prints and never installs signal handlers: the CLI (`sooc3d node`)
 * blocks SIGINT/SIGTERM before any thread exists, waits for them on a
 * dedicated thread and calls sooc_node_request_stop().
 *
 * Threads and locks: the capture thread (driver reads, ring push), the mapping
 * thread (the caller of sooc_node_run: everything after the ring), the shm
 * table's heartbeat thread, and any thread of the caller's that reads
 * sooc_node_get_stats or calls sooc_node_request_stop. The node's mutex guards
 * the stats, the latency windows, the run's start time and every write of the
 * world frame (T_world_src: set once by the floor estimate, read by stats).
 * Lock order: node -> ring. get_stats holds the node's mutex while it reads the
 * ring's counters (the ring's mutex), so no code may take the node's mutex
 * while it holds the ring's; the ring calls back into nothing. The mapper and
 * the publisher run on the mapping thread only; the publisher takes the node's
 * mutex only to update the stats (never while holding another lock). The
 * table's writer lock and the SQLite connection are the mapping thread's.
 * scripts/test.sh runs the node and table tests under ThreadSanitizer.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_NODE_H
#define SOOC3D_NODE_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/mapper.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------ launch file */

#define SOOC_NODE_PATH_MAX 1024
#define SOOC_NODE_PARAMS_MAX 32

/* A driver parameter from the launch file's `sensor:` block, passed through
 * verbatim (after validation against the driver's known keys). */
typedef struct sooc_node_param {
    char key[64];
    char value[256];
    int line;                      /* 1-based line in the launch file */
} sooc_node_param;

typedef enum sooc_node_pose_kind {
    SOOC_NODE_POSE_SENSOR = 0,     /* the sensor's frames carry poses (replay of a posed sequence) */
    SOOC_NODE_POSE_FILE = 1,       /* a trajectory file (TUM groundtruth format) */
    SOOC_NODE_POSE_SOCKET = 2,     /* live stream: unix:/path or udp:host:port */
    SOOC_NODE_POSE_ODOMETRY = 3,   /* RGB-D odometry on the frames (OpenCV rgbd, include/sooc3d/slam.h) */
    SOOC_NODE_POSE_TF = 4          /* the TF of a replayed log (drivers rosbag, mcap; docs/logs.md) */
} sooc_node_pose_kind;

typedef enum sooc_node_floor_mode {
    SOOC_NODE_FLOOR_GIVEN = 0,     /* `floor: <height>` along the up axis */
    SOOC_NODE_FLOOR_ESTIMATE = 1   /* `floor: estimate`: RANSAC plane fit on depth */
} sooc_node_floor_mode;

typedef struct sooc_node_config {
    char path[SOOC_NODE_PATH_MAX];           /* the launch file itself */

    /* sensor: */
    char driver[32];                         /* replay | rosbag | mcap | openni2 | freenect | v4l2 | libcamera */
    int n_params;
    sooc_node_param params[SOOC_NODE_PARAMS_MAX];

    /* pose: */
    sooc_node_pose_kind pose_kind;
    char pose_path[SOOC_NODE_PATH_MAX];      /* file path, or socket address "unix:/p" | "udp:h:p" */
    double pose_tolerance_s;                 /* default 0.02 */
    int pose_is_effector;                    /* pose.frame: effector -> apply T_effector_camera */
    char pose_parent[128], pose_child[128];  /* pose.source: tf: the world frame, the camera frame
                                                ("" = the colour image's frame_id) */

    /* odometry: (pose.source: odometry; sooc_odom_params) */
    int odom_variant;                        /* 0 rgbd, 1 icp, 2 rgbd_icp (default 2) */
    int odom_width, odom_height;             /* working resolution (default 320x240) */
    double odom_kf_translation_m;            /* odometry keyframe rule (default 0.10 m, 10 deg, */
    double odom_kf_rotation_deg;             /* no frame count)                                  */
    int odom_kf_frames;
    int odom_max_failures;                   /* re-anchor after this many failures (default 10) */
    double odom_min_depth_m, odom_max_depth_m;   /* depths used (default 0.3 .. 4) */
    double odom_min_agreement;               /* depth agreement below this = failure (0.3) */
    double odom_color_fx, odom_color_fy;     /* colour camera when colour is not registered to */
    double odom_color_cx, odom_color_cy;     /* depth (sooc_odom_params.color_K; 0 = registered) */
    double odom_color_tx, odom_color_ty, odom_color_tz;   /* p_color = p_depth + t (metres) */
    /* SLAM (include/sooc3d/slam.h, docs/slam.md): any of these runs the
     * tracker on its own thread between the sensor ring and the mapper */
    int odom_thread;                         /* tracking thread, odometry only (0)              */
    int odom_loop_closure;                   /* + place recognition and pose graph (0)          */
    int odom_relocalise;                     /* + relocalise into map.db's keyframes at start
                                                (map.resume) and when lost (0)                  */

    /* calib: (optional for sources that carry intrinsics) */
    char calib_path[SOOC_NODE_PATH_MAX];

    /* model: */
    int model_kind;                          /* model.kind: SOOC_MAPPER_LEARNT (learnt, default) or
                                                SOOC_MAPPER_GEOMETRIC (geometric: the support plane
                                                and Euclidean clustering, docs/geometric.md) */
    double geo_voxel_m, geo_join_m;          /* geometric: model.voxel_m (0.004), model.join_m (0.02) */
    double geo_min_height_m, geo_max_extent_m; /* geometric: model.min_height_m (0.012), max_extent_m (0.5) */
    double geo_wall_m;                         /* geometric: model.wall_m (0.3; 0 = no wall test)          */
    double geo_rest_m;                         /* geometric: model.rest_m (0.06; 0 = keep floating clusters) */
    double geo_min_presence;                   /* geometric: model.min_presence, the presence an entry needs
                                                  to be in the table and the store (0 = every entry)      */
    double geo_support_m;                      /* learnt: model.geo_support_m, the margin of the geometric
                                                  support of entries (sooc_mapper_set_support; 0 = off)   */
    int proposals;                             /* learnt: model.proposals, padded slots on the keyframe's
                                                  support-plane clusters (sooc_mapper_set_proposals)       */
    double prop_join_m, prop_logit;            /* model.prop_join_m (0 = the clusters' 0.02), model.prop_logit
                                                  (presence logit of a placed slot; 0 = the prior's)       */
    int prop_only;                             /* model.prop_only: only placed slots make new entries       */
    int surface_boxes;                         /* learnt, with geo_support_m: model.surface_boxes, planner
                                                  boxes of the observed surfaces (sooc_mapper_set_surface_boxes) */
    double geo_free_ratio;                     /* geometric: model.free_ratio (1; 0 = no free-space test)   */
    char model_path[SOOC_NODE_PATH_MAX];
    int input_width, input_height;           /* 0 = ask the model */
    int iterations, threads;
    uint64_t seed;
    sooc_frames_depth_resample depth_resample;
    double clip_m;                           /* model clip depth; 0 = the model's (default 0) */
    double merge_m;                          /* duplicate merge radius (sooc_mapper_params.
                                                merge_radius): default 0.35 m (revisits refine
                                                the mapped entry, docs/cogmap.md); 0 = never */
    int latents;                             /* SOOC_LATENTS_MEAN (default) / _SAMPLE */
    int slots;                               /* object slots per keyframe (sooc_mapper_params.
                                                slots): 0 = the model's K (default) */
    int invalid_depth;                       /* model.invalid_depth: 0 = the model's (default),
                                                1 = free, 2 = unknown (sooc_mapper_params) */
    double gate_min_rays, gate_ratio, gate_part;   /* model.gate_*: the creation gate of the
                                                revisit rules (sooc_mapper_params.gate_*):
                                                0 = default, < 0 = that test off */

    /* keyframe: */
    double kf_translation_m;                 /* default 0.10 */
    double kf_rotation_deg;                  /* default 10 */
    double kf_time_s;                        /* default 2.0 (0 disables the time rule) */

    /* shm: */
    char shm_name[64];                       /* "" = no shm table */
    uint32_t shm_capacity;                   /* default 1024 */
    int shm_unlink_on_exit;                  /* default 0 */

    /* map: */
    char map_db[SOOC_NODE_PATH_MAX];         /* "" = no persistent map */
    int map_resume;                          /* default 1 */
    double map_retry_s;                      /* map.retry_s: first retry after a failed commit (1 s;
                                                0 = at every keyframe and idle tick); doubles */
    double map_retry_max_s;                  /* map.retry_max_s: the backoff's cap (30 s) */
    int map_busy_timeout_ms;                 /* map.busy_timeout_ms: wait for a lock another process
                                                holds before a commit counts as failed (200) */

    /* world: */
    double up[3];                            /* up axis of the pose source's frame (unit) */
    int up_given;
    sooc_node_floor_mode floor_mode;
    double floor_height;                     /* floor coordinate along `up` */
    double floor_ransac_threshold_m;         /* default 0.02 */
    int floor_ransac_iterations;             /* default 200 */
    /* support plane (floor: estimate; include/sooc3d/frame.h, docs/node.md "Support plane") */
    char gravity_path[SOOC_NODE_PATH_MAX];   /* world.gravity: "" = auto (replay: <sensor.path>/
                                                gravity-direction.txt when present), "none", or a file */
    double max_tilt_deg;                     /* world.max_tilt_deg, default 30 */
    int support_frames;                      /* world.support_frames: frames the estimate uses (8) */
    int floor_switch;                        /* world.floor_switch: move to a lower level plane (the
                                                floor) that comes into view later (1; docs/node.md) */
    double cam_height_min_m, cam_height_max_m; /* world.camera_height_min_m / _max_m: the heights the
                                                model was trained for; 0 (default) = the model's own
                                                range (config cam_h_min / cam_h_max) */

    /* pipeline: */
    int ring_capacity;                       /* default 8 */
    int block_when_full;                     /* 0 (default): drop-oldest; 1: capture waits
                                                (deterministic replay as fast as possible) */
    double stats_period_s;                   /* default 5 */
    double min_depth_m, max_depth_m;         /* valid depth range, default 0.1 .. 10 */
    int strict;                              /* pipeline.strict (`--strict`): a broken frame stops
                                                the run (0: it is skipped and counted) */
    double reconnect_s, reconnect_max_s;     /* pipeline.reconnect_s / _max_s: a live sensor that
                                                fails is reopened after reconnect_s, doubling up to
                                                reconnect_max_s (1, 10; 0 = the run ends instead) */
    double time_jump_s;                      /* pipeline.time_jump_s: a frame stamp this much past the
                                                previous one, or before it, is a clock jump (5) */

    /* log: */
    sooc_log_level log_level;                /* default info */

    /* view: the live view in a browser (include/sooc3d/render.h) */
    int view_port;                           /* 0 = off (default)                        */
    char view_bind[64];                      /* IPv4 address to listen on (127.0.0.1)    */
    char record_mcap[512];                   /* record.mcap: the Foxglove SceneUpdate channel
                                                written while the node runs ("" = off)   */
    double record_period_s;                  /* record.period_s: the file is rewritten at most
                                                this often (1 s; 0 = every keyframe)     */
} sooc_node_config;

void sooc_node_config_default(sooc_node_config *c);
/* Parse a launch file. Unknown keys and bad values fail with SOOC_EINVAL and a
 * message "<file>:<line>: <section>.<key>: ...". */
sooc_status sooc_node_config_load(sooc_node_config *c, const char *path);
/* Same from a string (`name` is used in messages). */
sooc_status sooc_node_config_parse(sooc_node_config *c, const char *text, size_t n, const char *name);
/* The same, then the overrides sets[0..n_sets) in order, each
 * "SECTION.KEY=VALUE" read as the file's `SECTION: {KEY: VALUE}` would be
 * (the same keys, ranges and messages, named "--set ..."), before the
 * checks across keys (`sooc3d node --set`). */
sooc_status sooc_node_config_load_sets(sooc_node_config *c, const char *path, const char *const *sets, int n_sets);
sooc_status sooc_node_config_parse_sets(sooc_node_config *c, const char *text, size_t n, const char *name,
                                        const char *const *sets, int n_sets);
/* Look up a sensor parameter (NULL if absent). */
const char *sooc_node_param_get(const sooc_node_config *c, const char *key);
/* Write the effective config as YAML text (for the INFO log). snprintf-style:
 * returns the full length whatever `cap` is; `buf` may be NULL when cap is 0. */
size_t sooc_node_config_format(const sooc_node_config *c, char *buf, size_t cap);

/* ----------------------------------------------------------------- node */

/* Frame source (a sensor driver or a test feeder). read fills *f with a frame
 * (any size; the node reallocates as needed); returns SOOC_ETIMEOUT when no
 * frame is ready yet and SOOC_EEOF at the end of a recording. */
typedef struct sooc_node_source {
    void *ctx;
    sooc_status (*start)(void *ctx);
    sooc_status (*read)(void *ctx, sooc_frame *f, int timeout_ms);
    void (*stop)(void *ctx);
    void (*close)(void *ctx);
    /* Optional. After a failed read: why, when the failure was one broken
     * frame that the source has passed (the next read gives the frame after
     * it): SOOC_FRAME_FAULT_*; SOOC_FRAME_FAULT_NONE when the stream itself
     * failed. NULL: every failure is the stream's. */
    sooc_frame_fault (*frame_fault)(void *ctx);
    /* Optional. After a failed read that is the stream's: close the device
     * and open it again (SOOC_OK: reads go on). NULL: the failure ends the run. */
    sooc_status (*reopen)(void *ctx);
} sooc_node_source;

/* Pose source: camera (or effector) pose in the pose source's frame at t_ns,
 * interpolated; SOOC_ENOTFOUND when none within tol_ns. */
typedef struct sooc_node_pose_source {
    void *ctx;
    sooc_status (*lookup)(void *ctx, int64_t t_ns, int64_t tol_ns, double T[16]);
    void (*close)(void *ctx);
} sooc_node_pose_source;

typedef struct sooc_node_stats {
    uint64_t frames_in;          /* frames read from the sensor */
    uint64_t frames_dropped;     /* dropped by the ring (drop-oldest) */
    uint64_t frames_no_pose;     /* skipped: no pose within tolerance */
    uint64_t frames_untracked;   /* skipped: odometry failed on them (pose.source: odometry) */
    uint64_t frames_not_kf;      /* rejected by the keyframe policy */
    uint64_t frames_floor_wait;  /* consumed while estimating the floor */
    uint64_t keyframes;          /* mapper updates done */
    uint64_t update_errors;      /* failed mapper updates (frame skipped) */
    uint64_t published, removed; /* table rows upserted / flagged removed */
    uint64_t n_objects;          /* entries in the map after the last keyframe */
    uint64_t resumed;            /* entries loaded from the database at start */
    uint64_t resumed_blocks;     /* layout blocks loaded from the database at start */
    double update_p50_ms, update_p99_ms;     /* sooc_mapper_update */
    double c2t_p50_ms, c2t_p99_ms;           /* capture (ring push) -> table end_batch */
    double publish_p50_ms, publish_p99_ms;   /* publisher: table batch + SQLite transaction */
    double elapsed_s;
    int floor_estimated;
    uint64_t floor_switches;     /* times the support plane moved to a lower one (the floor) */
    double T_world_src[16];
    /* broken input frames (docs/node.md "Faults") */
    uint64_t frames_skipped;                      /* skipped: the source could not read them */
    uint64_t skipped_by[SOOC_FRAME_FAULT_COUNT];  /* by reason (index SOOC_FRAME_FAULT_*) */
    /* the map database under faults (docs/node.md "Faults") */
    int store_state;             /* SOOC_NODE_STORE_* */
    int store_fault;             /* sooc_mapstore_fault of the latest failure (0 = none yet) */
    uint64_t store_pending;      /* objects to write or delete that the database does not hold yet */
    uint64_t store_pending_kf;   /* keyframe rows not written yet */
    uint64_t store_failures;     /* failed commit attempts (each retry counts) */
    uint64_t store_recoveries;   /* times the store came back after failing */
    uint64_t store_kf_dropped;   /* keyframe rows given up: more than SOOC_NODE_STORE_ROWS_MAX waited */
    int64_t store_committed_ns;  /* stamp of the newest keyframe in the database (INT64_MIN: none) */
    /* live sources (docs/node.md "Faults") */
    uint64_t sensor_lost;        /* times the sensor failed and was reopened, or is being */
    uint64_t sensor_reconnects;  /* times it came back */
    int sensor_down;             /* 1 while it is lost */
    uint64_t pose_gaps;          /* times the pose source went silent (frames counted no_pose) */
    uint64_t time_jumps;         /* frame stamps before the previous one or time_jump_s past it */
} sooc_node_stats;

/* Frames in a row without a pose that cover this much sensor time make the
 * pose source "silent" (logged once, and once when poses return). */
#define SOOC_NODE_POSE_SILENT_S 1.0

/* sooc_node_stats.store_state */
#define SOOC_NODE_STORE_NONE 0      /* no map.db */
#define SOOC_NODE_STORE_OK 1        /* commits succeed; nothing pending */
#define SOOC_NODE_STORE_FAILING 2   /* commits fail: mapping goes on in memory, changes wait (retried) */
/* Keyframe rows kept while the store fails; older ones are dropped first
 * (counted). Objects are never dropped: their latest state is kept. */
#define SOOC_NODE_STORE_ROWS_MAX 65536

/* Called on the mapping thread after each keyframe is published: the changed
 * entries (upserted) and the ids removed. For the CLI's --print-table. */
typedef void (*sooc_node_kf_fn)(void *user, uint64_t keyframe, const sooc_map_entry *changed,
                                size_t n_changed, const uint64_t *removed, size_t n_removed,
                                const sooc_node_stats *st);

struct sooc_v4l2_ops;   /* driver.h */

typedef struct sooc_node_options {
    uint64_t max_keyframes;          /* 0 = unlimited */
    sooc_node_kf_fn on_keyframe;
    void *user;
    /* Overrides (tests): when set, used instead of opening the configured
     * sensor / pose source. The node takes ownership and calls close. */
    const sooc_node_source *source;
    const sooc_node_pose_source *pose;
    /* A ready mapper (tests/bench). When NULL the node creates one from the
     * config's model block and destroys it at the end. Not owned if given. */
    sooc_mapper *mapper;
    /* The V4L2 driver's syscall table (tests: a fake device), passed to the
     * configured sensor each time it is opened or reopened. NULL = the real
     * syscalls. Not owned; must outlive the node. */
    const struct sooc_v4l2_ops *v4l2_ops;
} sooc_node_options;

typedef struct sooc_node sooc_node;

/* Open everything (mapper, sensor, pose source, calib, shm table, map db;
 * resume from the db when configured). Nothing runs yet. */
sooc_status sooc_node_create(sooc_node **out, const sooc_node_config *c, const sooc_node_options *o);
/* Start the capture thread and run the mapping loop on the calling thread
 * until the recording ends, max_keyframes is reached or a stop is requested.
 * The keyframe in progress is finished and committed before returning. */
sooc_status sooc_node_run(sooc_node *n);
/* Async-safe enough for a signal thread: sets a flag and wakes the loops. */
void sooc_node_request_stop(sooc_node *n);
void sooc_node_get_stats(sooc_node *n, sooc_node_stats *out);
/* Closes the table (unlinking it only if configured) and the database. */
void sooc_node_destroy(sooc_node *n);

/* One-line stats summary for logs. */
size_t sooc_node_stats_format(const sooc_node_stats *s, char *buf, size_t cap);

/* The shm table record of a map entry, as the node publishes it (docs/shm.md):
 * pose, the planner's covariance and box (cogmap.h), presence, flags (VALID,
 * TENTATIVE below 2 observations, the box's quality). `sooc3d map list` and
 * `map export` print the same numbers from a stored map. */
struct sooc_table_record;
void sooc_node_table_record(const sooc_map_entry *e, struct sooc_table_record *r);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_NODE_H */
