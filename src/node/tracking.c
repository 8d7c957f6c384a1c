/* pose.source: odometry with odometry.thread / loop_closure / relocalise:
 * the tracker (include/sooc3d/slam.h) on its own thread between the sensor
 * ring and the mapping loop (docs/slam.md "The node"). */
#include <stdio.h>
#include <string.h>

#include "node/node_impl.h"

int sooc__node_tracking_wanted(const sooc_node *n) {
    const sooc_node_config *c = &n->cfg;
    return c->pose_kind == SOOC_NODE_POSE_ODOMETRY && !n->opt.pose &&
           (c->odom_thread || c->odom_loop_closure || c->odom_relocalise);
}

/* the tracker's source: the sensor ring, frames registered to colour */
static sooc_status ring_source(void *ctx, sooc_frame *f, int64_t *t_mono, int timeout_ms) {
    sooc_node *n = ctx;
    for (;;) {
        sooc_status st = sooc_frame_ring_pop(n->ring, f, t_mono, timeout_ms);
        if (st) return st;
        st = sooc__node_register_frame(n, f);
        if (!st) return SOOC_OK;
        if (st == SOOC_ENOMEM) return st;
        /* a frame the calibration does not fit: counted by the tracker's log, skipped */
        sooc_log(SOOC_LOG_WARN, "node: tracking: frame %lld skipped: %s", (long long)f->index, sooc_errmsg());
    }
}

sooc_status sooc__node_tracking_start(sooc_node *n) {
    const sooc_node_config *c = &n->cfg;
    sooc_slam_params p;
    sooc_slam_params_default(&p);
    p.odom = n->odom_params;
    p.loop_closure = c->odom_loop_closure;
    p.relocalise = c->odom_relocalise && c->map_resume;
    sooc_status st;
    if (c->map_db[0] && sooc_file_exists(c->map_db)) {
        /* a connection of its own: one sooc_mapstore per thread */
        sooc_mapstore_params mp;
        sooc_mapstore_params_default(&mp);
        mp.create = 0;
        if ((st = sooc_mapstore_open(&n->trk_store, c->map_db, &mp)) ||
            (st = sooc_mapstore_set_busy_timeout(n->trk_store, c->map_busy_timeout_ms)))
            return sooc_adderr(st, "%s: odometry: keyframes in map.db", c->path);
    } else if (c->map_db[0]) {
        sooc_log(SOOC_LOG_WARN, "%s: odometry: map.db %s does not exist yet: tracking keyframes are not stored",
                 c->path, c->map_db);
    }
    sooc_slam *s = NULL;
    if ((st = sooc_slam_create(&s, &p, n->trk_store))) return sooc_adderr(st, "%s: odometry", c->path);
    sooc_slam_stats ss;
    sooc_slam_get_stats(s, &ss);
    if (ss.stored_keyframes)
        sooc_log(SOOC_LOG_INFO, "node: %lld tracking keyframes in %s%s", (long long)ss.stored_keyframes, c->map_db,
                 p.relocalise ? ": frames are untracked until one relocalises into them" : "");
    if ((st = sooc_slam_tracker_start(&n->trk, s, ring_source, n, c->ring_capacity > 1 ? c->ring_capacity : 2))) {
        sooc_slam_destroy(s);
        return sooc_adderr(st, "%s: odometry", c->path);
    }
    return SOOC_OK;
}

sooc_status sooc__node_tracking_pop(sooc_node *n, sooc_frame *f, int64_t *t_cap, int timeout_ms) {
    return sooc_slam_tracker_pop(n->trk, f, t_cap, timeout_ms);
}

sooc_status sooc__node_tracking_follow(sooc_node *n) {
    if (!n->trk || !n->world_ready) return SOOC_OK;
    uint64_t v = 0;
    size_t nc = 0, ne = 0;
    sooc_slam_tracker_changes(n->trk, &v, NULL, 0, &nc);
    if (v == n->trk_version) return SOOC_OK;
    sooc_slam_kf_change *chg = sooc_malloc((nc ? nc : 1) * sizeof *chg);
    sooc_status st = chg ? SOOC_OK : sooc_seterr(SOOC_ENOMEM, "node: out of memory (pose changes)");
    if (!st) st = sooc_slam_tracker_changes(n->trk, &v, chg, nc, &nc);
    if (!st) st = sooc_mapper_entries(n->mapper, NULL, 0, &ne);
    sooc_map_entry *e = NULL;
    if (!st && ne) {
        e = sooc_malloc(ne * sizeof *e);
        if (!e) st = sooc_seterr(SOOC_ENOMEM, "node: out of memory (moving entries)");
        else st = sooc_mapper_entries(n->mapper, e, ne, &ne);
    }
    size_t moved = 0;
    if (!st && ne) {
        /* entries last seen within 2 s of this run's keyframes follow them */
        moved = sooc_slam_move_entries(chg, nc, n->T_world_src, 2000000000, e, ne);
        if (moved) {
            uint64_t next = sooc_mapper_next_id(n->mapper);
            st = sooc_mapper_load_entries(n->mapper, e, ne);
            if (!st) sooc_mapper_reserve_ids(n->mapper, next);
            if (!st) st = sooc__node_publish(n, e, ne, NULL, 0, 0, 1, NULL);
            if (!st)
                sooc_log(SOOC_LOG_INFO, "node: the pose graph moved %zu keyframes: %zu map entries follow them",
                         nc, moved);
        }
    }
    n->trk_version = v;
    sooc_free(e);
    sooc_free(chg);
    return st;
}

void sooc__node_tracking_log(sooc_node *n) {
    if (!n->trk) return;
    sooc_slam_tracker_stats s;
    sooc_slam_tracker_get_stats(n->trk, &s);
    char line[512];
    sooc_slam_tracker_stats_format(&s, line, sizeof line);
    uint64_t pushed = 0, dropped = 0;
    int fill = 0;
    sooc_frame_ring_counts(n->ring, &pushed, &dropped, &fill);
    sooc_log(SOOC_LOG_INFO, "node: %s; sensor ring: %llu in, %llu dropped before tracking", line,
             (unsigned long long)pushed, (unsigned long long)dropped);
}

void sooc__node_tracking_stop(sooc_node *n) {
    sooc_slam_tracker_destroy(n->trk);
    n->trk = NULL;
    sooc_mapstore_close(n->trk_store);
    n->trk_store = NULL;
}
