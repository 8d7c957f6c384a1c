/* Internals of the node (include/sooc3d/node.h) shared by its files:
 * pipeline.c (create, capture, mapping loop), publish.c (the shm table, the
 * map database and resume), skip.c (broken frames, the stats line). */
#ifndef SOOC3D_NODE_IMPL_H
#define SOOC3D_NODE_IMPL_H

#include "sooc3d/node.h"
#include "node/node_parts.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

#include "sooc3d/driver.h"
#include "sooc3d/table.h"
#include "node/store_guard.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/slam.h"

#include "sooc3d/render.h"

/* After a keyframe: the map, the frame and the counters to the live view (view_hook.c). */
sooc_status sooc__node_view_publish(sooc_node *n, const sooc_frame *f);
/* record: {mcap: FILE} (record.c): opened with the node, a SceneUpdate of the
 * map after each keyframe, the file rewritten (atomically, with its summary and
 * index) at most every record.period_s and when the node is destroyed. */
typedef struct sooc__recorder sooc__recorder;
sooc_status sooc__node_record_open(sooc_node *n);
void sooc__node_record_keyframe(sooc_node *n, int64_t t_ns);
void sooc__node_record_close(sooc_node *n);

struct sooc_node {
    sooc_view *view;               /* view: {port} (NULL = off) */
    sooc__recorder *rec;           /* record: {mcap} (NULL = off) */
    sooc_map_entry *view_entries;  /* its buffers, view_cap entries each */
    sooc_view_object *view_objects;
    size_t view_cap;
    sooc_node_config cfg;
    sooc_node_options opt;
    sooc_mapper *mapper;
    int own_mapper;
    int tw, th;

    sooc_node_source src;
    int have_src;
    sooc_node_pose_source pose;
    int have_pose;
    sooc_odom *odom;               /* pose.source: odometry */
    int odom_lost;                 /* frames failed in a row (for the log) */
    sooc_odom_params odom_params;  /* for the tracking thread, started by sooc_node_run */
    sooc_slam_tracker *trk;        /* odometry.thread/loop_closure/relocalise (tracking.c) */
    sooc_mapstore *trk_store;      /* its own connection to map.db (keyframe tables)       */
    uint64_t trk_version;          /* the graph version the map entries follow             */
    sooc_sensor *sensor;           /* swapped by a reconnect under sensor_mu */
    sooc_sensor_params sensor_params;   /* to open it again */
    sooc_pose_src *psrc;
    pthread_mutex_t sensor_mu;     /* guards the sensor pointer: a reconnect (capture thread) against
                                      sooc_node_request_stop (any thread); a leaf lock */
    sooc_calib calib;
    int have_calib;
    sooc_intrinsics Kc;            /* calib intrinsics (colour) */
    int calib_registered;          /* -1 unknown, 0 needs registration, 1 registered */
    int have_T_cd;
    double T_cd[16], T_eff_cam[16];
    int have_T_eff;
    float *reg_buf;
    size_t reg_cap;

    sooc_frame_ring *ring;
    pthread_t cap_thread;
    int cap_started;
    atomic_int stop;
    sooc_status cap_status;
    char cap_err[512];
    uint64_t skip_limit;           /* broken frames in a row that end a run without one good frame
                                      (a looped replay's length; 0 = none) */
    char last_skip[512];           /* the latest broken frame's message */
    uint64_t map_skips;            /* frames the mapping thread skipped (size) */
    /* mapping thread: the pose source's silences and the frames' clock (liveness.c) */
    uint64_t pose_miss;            /* frames in a row without a pose */
    int64_t pose_miss_t0;          /* stamp of the first of them */
    int pose_silent;               /* the silence was logged */
    int64_t t_prev_ns;             /* stamp of the previous frame */
    int have_t_prev;

    sooc_kf_policy kf;
    double T_world_src[16];        /* written by the mapping thread under mu (stats read it) */
    int world_ready;
    uint64_t floor_attempts;
    /* world.floor: estimate: the first posed frames wait here for the support
     * plane, then are mapped (start-up only; no allocation once mapping runs) */
    sooc_frame *sup_f;
    double *sup_T;                 /* their T_src_c */
    int64_t *sup_tcap;
    int n_sup, cap_sup;
    /* world.floor_switch (floor_watch.c): the last fw_cap keyframes, a ring
     * (keyframe k in slot k % fw_cap), for the estimate again */
    sooc_frame *fw_f;
    int fw_cap, fw_told;
    uint64_t fw_total;             /* keyframes put in the ring */
    int has_gravity;
    double gravity[3];             /* world.gravity (source frame, pointing down) */

    sooc_table_writer *table;
    sooc_mapstore *store;
    sooc_sg *sg;                   /* its writes, queued and retried under faults (store_guard.h) */
    int store_layout_dim;          /* 0: this database keeps no layout latents */
    int extent_stored;             /* meta "extent" written / read */
    float extent[3];               /* box extent from the database (resume of a mapper without one) */
    int db_exists;
    uint64_t model_id;       /* table latent_model_id: FNV-1a 64 of the checkpoint file */
    char model_id_str[96];   /* map.db model_id: "fnv1a64:<16 hex> bytes:<n>" ("" = injected mapper) */

    sooc_map_entry *prev;          /* start-up only: the map republished at create */
    size_t n_prev, cap_prev;
    sooc_map_entry changed[SOOC_MAPPER_CHANGED_MAX];   /* per keyframe: sooc_mapper_changed */
    uint64_t removed[SOOC_MAPPER_CHANGED_MAX];
    uint64_t kf_seq;               /* keyframe rows written */

    pthread_mutex_t mu;            /* guards st, lat_*, t_start and writes of T_world_src;
                                      lock order node -> ring (node.h) */
    sooc_node_stats st;
    sooc_latency lat_upd, lat_c2t, lat_pub;
    double t_start, t_last_stats;

    sooc_frame work, pre;
};

/* Publish `chg` / `rem`: one table batch and one SQLite transaction (changed
 * entries, removed ids, the active layout block, the id counter and a keyframe
 * row). Its cost depends on nc + nr, not on the map size. `kf` = NULL for the
 * start-up batch (no keyframe row); to_db = 0 when the entries came from the
 * database itself (resume). */
typedef struct sooc_kf_info {
    int64_t stamp_ns;
    const double *T_wc;
    int64_t t_cap_mono;
} sooc_kf_info;

sooc_status sooc__node_grow(void **p, size_t *cap, size_t need, size_t elem);
/* Caller holds n->mu. */
void sooc__node_stats_refresh(sooc_node *n);

/* floor_watch.c: the support plane's parameters from the launch file and the
 * model; the watch for a lower level plane after start-up (rule 4). Both the
 * start-up buffer and the watch hold world.support_frames frames (1-32). */
static inline int sooc__node_support_cap(const sooc_node_config *c) {
    return c->support_frames > 0 ? (c->support_frames < 32 ? c->support_frames : 32) : 8;
}
void sooc__node_support_params(sooc_node *n, sooc_support_params *sp);
sooc_status sooc__node_floor_watch_init(sooc_node *n, int from_store);
sooc_status sooc__node_floor_watch(sooc_node *n, const sooc_frame *f, const double T_src_c[16]);
void sooc__node_floor_watch_free(sooc_node *n);

/* publish.c */
sooc_status sooc__node_publish(sooc_node *n, const sooc_map_entry *chg, size_t nc, const uint64_t *rem, size_t nr,
                               int clear_first, int to_db, const sooc_kf_info *kf);
sooc_status sooc__node_publish_keyframe(sooc_node *n, int64_t stamp_ns, const double T_wc[16], int64_t t_cap);
/* map.db: open (a new database when absent) and resume its map into the
 * mapper (*resumed = 1), or nothing without map.db. */
sooc_status sooc__node_store_resume(sooc_node *n, int *resumed);
sooc_status sooc__node_store_world(sooc_node *n, const sooc_map_frame *mf);
sooc_status sooc__node_store_retry(sooc_node *n, int force);
sooc_status sooc__node_store_final(sooc_node *n, sooc_status result);

/* liveness.c: a live sensor that fails is reopened with backoff (capture
 * thread; SOOC_OK when it is back, else the status that ends the run); the
 * pose source's silences and the frames' clock jumps (mapping thread). */
sooc_status sooc__node_reconnect(sooc_node *n, sooc_status st);
void sooc__node_pose_seen(sooc_node *n, const sooc_frame *f, int found);
void sooc__node_time_check(sooc_node *n, const sooc_frame *f);

/* skip.c */
sooc_status sooc__node_capture_skip(sooc_node *n, sooc_status st);
int sooc__node_frame_size_skip(sooc_node *n, const sooc_frame *f, sooc_status *result);

/* tracking.c: the tracking thread of pose.source odometry with
 * odometry.thread / loop_closure / relocalise. wanted: 1 if the config asks
 * for it. start: after the capture thread; pop: the mapping loop's source
 * instead of the ring (frames carry has_pose, T_wc in the odometry frame);
 * stop: after the capture thread ended. register: pipeline.c's intrinsics
 * fix and depth registration, run on the tracking thread. */
int sooc__node_tracking_wanted(const sooc_node *n);
sooc_status sooc__node_tracking_start(sooc_node *n);
sooc_status sooc__node_tracking_pop(sooc_node *n, sooc_frame *f, int64_t *t_cap, int timeout_ms);
void sooc__node_tracking_log(sooc_node *n);
/* After an optimisation on the tracking thread: the mapper's entries move
 * with the keyframes nearest in time to their last sighting, and the whole
 * map is published in one batch (table and store). */
sooc_status sooc__node_tracking_follow(sooc_node *n);
void sooc__node_tracking_stop(sooc_node *n);
sooc_status sooc__node_register_frame(sooc_node *n, sooc_frame *f);

#endif
