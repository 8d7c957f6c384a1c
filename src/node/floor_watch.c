/* The support plane after start-up (docs/node.md "Support plane", rule 4):
 * with world.floor: estimate, the map's world frame comes from the first
 * frames, whose plane may be a table top when no floor is in view. The last
 * world.support_frames keyframes are kept, and each time that many more were
 * mapped the estimate runs on them again with the map's up. When it finds a
 * level plane at least SWITCH_MIN_M below the map's (the floor came into
 * view) and the camera's height above it lies within the heights the model
 * was trained for (the launch file's, else the model's; the geometric map has
 * none), the map moves to that plane: the world frame drops by the
 * difference, the map restarts in it (its entries are removed and published
 * as removals, the new frame goes to the table header and the store), and the
 * next keyframes map the scene again. A resumed map (its frame came from the
 * store) and a given floor never switch; nor does world.floor_switch: false.
 * The kept frames are the mapper's input frames, copied into buffers that
 * are reused once the ring is full (sooc_frame_copy: no allocation per
 * keyframe after that). */
#include "node/node_impl.h"

#include <math.h>
#include <string.h>

#define SWITCH_MIN_M 0.10      /* a lower plane is another surface, not the same one refitted */
#define SWITCH_MAX_DEG 5.0     /* its normal agrees with the map's up */

void sooc__node_support_params(sooc_node *n, sooc_support_params *sp) {
    const sooc_node_config *c = &n->cfg;
    sooc_support_params_default(sp);
    if (c->up_given) {
        sp->has_up_hint = 1;
        memcpy(sp->up_hint, c->up, sizeof sp->up_hint);
    }
    if (n->has_gravity) {
        sp->has_gravity = 1;
        memcpy(sp->gravity, n->gravity, sizeof sp->gravity);
    }
    sp->max_tilt_deg = c->max_tilt_deg;
    sp->threshold_m = c->floor_ransac_threshold_m;
    sp->iterations = c->floor_ransac_iterations;
    if (c->cam_height_min_m > 0) {   /* the launch file's (both given, min < max: launch.c) */
        sp->cam_height_min_m = c->cam_height_min_m;
        sp->cam_height_max_m = c->cam_height_max_m;
    } else {   /* the model's trained range */
        sooc_mapper_cam_heights(n->mapper, &sp->cam_height_min_m, &sp->cam_height_max_m);
    }
    sp->seed = c->seed + 1;
}

sooc_status sooc__node_floor_watch_init(sooc_node *n, int from_store) {
    const sooc_node_config *c = &n->cfg;
    if (c->floor_mode != SOOC_NODE_FLOOR_ESTIMATE || !c->floor_switch || from_store) return SOOC_OK;
    n->fw_cap = sooc__node_support_cap(c);
    n->fw_f = sooc_calloc((size_t)n->fw_cap, sizeof *n->fw_f);
    if (!n->fw_f) return sooc_seterr(SOOC_ENOMEM, "node: out of memory (floor watch)");
    n->fw_total = 0;
    return SOOC_OK;
}

void sooc__node_floor_watch_free(sooc_node *n) {
    for (int i = 0; i < n->fw_cap; i++) sooc_frame_free(&n->fw_f[i]);
    sooc_free(n->fw_f);
    n->fw_f = NULL;
    n->fw_cap = 0;
    n->fw_total = 0;
}

/* The map restarts in the world frame T (the old one moved up by dy). */
static sooc_status switch_world(sooc_node *n, const double T[16], double dy, const sooc_support *sup,
                                const sooc_frame *f) {
    size_t ne = 0;
    sooc_status st = sooc_mapper_entries(n->mapper, NULL, 0, &ne);
    sooc_map_entry *e = st ? NULL : sooc_malloc((ne ? ne : 1) * sizeof *e);
    uint64_t *ids = st ? NULL : sooc_malloc((ne ? ne : 1) * sizeof *ids);
    if (!st && (!e || !ids)) st = sooc_seterr(SOOC_ENOMEM, "node: out of memory (floor switch)");
    if (!st) st = sooc_mapper_entries(n->mapper, e, ne, &ne);
    for (size_t i = 0; !st && i < ne; i++) ids[i] = e[i].id;
    if (!st) st = sooc_mapper_clear(n->mapper);
    if (!st) {
        pthread_mutex_lock(&n->mu);
        memcpy(n->T_world_src, T, 16 * sizeof(double));
        n->st.floor_switches++;
        pthread_mutex_unlock(&n->mu);
        sooc_map_frame mf;
        memset(&mf, 0, sizeof mf);
        memcpy(mf.T_world_src, T, sizeof mf.T_world_src);
        memcpy(mf.up_src, sup->up_src, sizeof mf.up_src);
        memcpy(mf.plane_src, sup->plane_src, sizeof mf.plane_src);
        mf.cam_height_m = sup->cam_height_m;
        mf.up_source = (int)sup->up_source;
        st = sooc__node_store_world(n, &mf);
    }
    /* the removals and the new T_src_map in one table batch and one transaction */
    if (!st) st = sooc__node_publish(n, NULL, 0, ids, ne, 0, 1, NULL);
    if (!st)
        sooc_log(SOOC_LOG_INFO,
                 "node: a level plane %.2f m below the map's came into view (frame %lld): the support plane is now "
                 "that one (the floor), the camera %.2f m above it; the map restarts in the new frame (%zu "
                 "entries removed, mapped again as the keyframes see them)",
                 dy, (long long)f->index, sup->cam_height_m, ne);
    sooc_free(e);
    sooc_free(ids);
    return st;
}

sooc_status sooc__node_floor_watch(sooc_node *n, const sooc_frame *f, const double T_src_c[16]) {
    if (!n->fw_f) return SOOC_OK;
    sooc_frame *d = &n->fw_f[n->fw_total % (uint64_t)n->fw_cap];
    if (sooc_frame_copy(d, f)) return sooc_seterr(SOOC_ENOMEM, "node: out of memory (floor watch)");
    d->has_pose = 1;
    memcpy(d->T_wc, T_src_c, 16 * sizeof(double));
    /* every fw_cap keyframes, on the last fw_cap of them */
    if (++n->fw_total % (uint64_t)n->fw_cap) return SOOC_OK;
    int nf = n->fw_cap;

    sooc_support_params sp;
    sooc__node_support_params(n, &sp);
    /* the map's up (the world's +y in the source frame) is the hint */
    const double *T = n->T_world_src;
    double up[3] = {T[4], T[5], T[6]};
    sp.has_up_hint = 1;
    memcpy(sp.up_hint, up, sizeof up);
    sp.has_gravity = 0;
    sp.max_frames = nf;
    const sooc_frame *fp[32];
    for (int i = 0; i < nf; i++) fp[i] = &n->fw_f[i];
    sooc_support sup;
    double t0 = sooc_seconds();
    sooc_status est = sooc_support_estimate(fp, nf, &sp, &sup);
    sooc_log(SOOC_LOG_DEBUG, "node: floor watch at frame %lld: %s, %.1f ms", (long long)f->index,
             est ? "no level plane" : "estimated", (sooc_seconds() - t0) * 1e3);
    if (est) {   /* no level plane: nothing to say */
        sooc_clearerr();
        return SOOC_OK;
    }
    double cosang = up[0] * sup.up_src[0] + up[1] * sup.up_src[1] + up[2] * sup.up_src[2];
    /* how far below the map's plane the new one lies: a point of it, -d n, in the map */
    const double *q = sup.plane_src;
    double dy = -(T[4] * -q[3] * q[0] + T[5] * -q[3] * q[1] + T[6] * -q[3] * q[2] + T[7]);
    if (cosang < cos(SWITCH_MAX_DEG * 3.14159265358979323846 / 180.0) || dy < SWITCH_MIN_M) return SOOC_OK;
    int ranged = sp.cam_height_max_m > sp.cam_height_min_m;
    if (ranged && (sup.cam_height_m < sp.cam_height_min_m || sup.cam_height_m > sp.cam_height_max_m)) {
        if (!n->fw_told)
            sooc_log(SOOC_LOG_INFO,
                     "node: a level plane %.2f m below the map's is in view (frame %lld), but the camera's %.2f m "
                     "above it lie outside the %.2f-%.2f m the model was trained for: the support plane stays",
                     dy, (long long)f->index, sup.cam_height_m, sp.cam_height_min_m, sp.cam_height_max_m);
        n->fw_told = 1;
        return SOOC_OK;
    }
    double Tn[16];
    memcpy(Tn, T, sizeof Tn);
    Tn[7] += dy;   /* y_new = y_old + dy: the new plane is y_new = 0 */
    return switch_world(n, Tn, dy, &sup, f);
}
