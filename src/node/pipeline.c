/* The node: capture thread -> frame ring -> (mapping thread = caller of
 * sooc_node_run) pose association, keyframe policy, preprocessing,
 * sooc3d_mapper_update, publisher (shm table batch + SQLite transaction per
 * keyframe) and periodic stats. */
#include "sooc3d/node.h"
#include "sooc3d/support.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

#if SOOC_NODE_HAVE_DRIVERS
#include "sooc3d/driver.h"
#include "sooc3d/pose.h"
#endif
#if SOOC_NODE_HAVE_TABLE
#include "sooc3d/table.h"
#endif
#if SOOC_NODE_HAVE_MAPSTORE
#include "sooc3d/mapstore.h"
#endif
#if SOOC_NODE_HAVE_CALIB
#include "sooc3d/calib.h"
#endif
#if SOOC_NODE_HAVE_CV
#include "sooc3d/cv.h"
#endif

struct sooc_node {
    sooc_node_config cfg;
    sooc_node_options opt;
    sooc3d_mapper *mapper;
    int own_mapper;
    int tw, th;

    sooc_node_source src;
    int have_src;
    sooc_node_pose_source pose;
    int have_pose;
#if SOOC_NODE_HAVE_CV
    sooc_odom *odom;               /* pose.source: odometry */
    int odom_lost;                 /* frames failed in a row (for the log) */
#endif
#if SOOC_NODE_HAVE_DRIVERS
    sooc_sensor *sensor;
    sooc_pose_src *psrc;
#endif
#if SOOC_NODE_HAVE_CALIB
    sooc_calib calib;
#endif
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
    int has_gravity;
    double gravity[3];             /* world.gravity (source frame, pointing down) */

#if SOOC_NODE_HAVE_TABLE
    sooc_table_writer *table;
#endif
#if SOOC_NODE_HAVE_MAPSTORE
    sooc_mapstore *store;
    int store_layout_dim;          /* 0: this database keeps no layout latents */
    int extent_stored;             /* meta "extent" written / read */
#endif
    float extent[3];               /* box extent from the database (resume of a mapper without one) */
    int db_exists;
    uint64_t model_id;       /* table latent_model_id: FNV-1a 64 of the checkpoint file */
    char model_id_str[64];   /* map.db model_id: "fnv1a64:<16 hex> bytes:<n>" ("" = injected mapper) */

    sooc_map_entry *prev;          /* start-up only: the map republished at create */
    size_t n_prev, cap_prev;
    sooc_map_entry changed[SOOC_MAPPER_CHANGED_MAX];   /* per keyframe: sooc3d_mapper_changed */
    uint64_t removed[SOOC_MAPPER_CHANGED_MAX];
    uint64_t kf_seq;               /* keyframe rows written */

    pthread_mutex_t mu;            /* guards st, lat_*, t_start and writes of T_world_src;
                                      lock order node -> ring (node.h) */
    sooc_node_stats st;
    sooc_latency lat_upd, lat_c2t, lat_pub;
    double t_start, t_last_stats;

    sooc_frame work, pre;
};

/* ------------------------------------------------------------- helpers */

static sooc_status grow(void **p, size_t *cap, size_t need, size_t elem) {
    if (need <= *cap) return SOOC_OK;
    size_t nc = *cap ? *cap : 64;
    while (nc < need) nc *= 2;
    void *q = sooc_realloc(*p, nc * elem);
    if (!q) return sooc_seterr(SOOC_ENOMEM, "node: out of memory (%zu entries)", nc);
    *p = q;
    *cap = nc;
    return SOOC_OK;
}

static void stats_refresh(sooc_node *n) {
    /* caller holds n->mu */
    n->st.update_p50_ms = sooc_latency_pct(&n->lat_upd, 0.5);
    n->st.update_p99_ms = sooc_latency_pct(&n->lat_upd, 0.99);
    n->st.c2t_p50_ms = sooc_latency_pct(&n->lat_c2t, 0.5);
    n->st.c2t_p99_ms = sooc_latency_pct(&n->lat_c2t, 0.99);
    n->st.publish_p50_ms = sooc_latency_pct(&n->lat_pub, 0.5);
    n->st.publish_p99_ms = sooc_latency_pct(&n->lat_pub, 0.99);
    if (n->ring) {
        uint64_t pushed, dropped;
        sooc_frame_ring_counts(n->ring, &pushed, &dropped, NULL);
        n->st.frames_dropped = dropped;
    }
    n->st.elapsed_s = sooc_seconds() - n->t_start;
    memcpy(n->st.T_world_src, n->T_world_src, sizeof n->T_world_src);
}

size_t sooc_node_stats_format(const sooc_node_stats *s, char *buf, size_t cap) {
    int w = snprintf(buf, cap,
                     "frames %llu dropped %llu no_pose %llu (untracked %llu) keyframes %llu (%.2f/s) objects %llu "
                     "update p50 %.1f ms p99 %.1f ms capture->table p50 %.1f ms p99 %.1f ms "
                     "publish p50 %.2f ms p99 %.2f ms",
                     (unsigned long long)s->frames_in, (unsigned long long)s->frames_dropped,
                     (unsigned long long)s->frames_no_pose, (unsigned long long)s->frames_untracked,
                     (unsigned long long)s->keyframes,
                     s->elapsed_s > 0 ? (double)s->keyframes / s->elapsed_s : 0.0,
                     (unsigned long long)s->n_objects, s->update_p50_ms, s->update_p99_ms, s->c2t_p50_ms,
                     s->c2t_p99_ms, s->publish_p50_ms, s->publish_p99_ms);
    return w > 0 ? (size_t)w : 0;
}

void sooc_node_get_stats(sooc_node *n, sooc_node_stats *out) {
    pthread_mutex_lock(&n->mu);
    stats_refresh(n);
    *out = n->st;
    pthread_mutex_unlock(&n->mu);
}

void sooc_node_request_stop(sooc_node *n) {
    atomic_store(&n->stop, 1);
#if SOOC_NODE_HAVE_DRIVERS
    if (n->sensor) sooc_sensor_interrupt(n->sensor);
#endif
    if (n->ring) sooc_frame_ring_close(n->ring);
}

int sooc_node_stop_requested(const sooc_node *n) { return atomic_load((atomic_int *)&n->stop); }

/* ------------------------------------------------ driver / pose adapters */

#if SOOC_NODE_HAVE_DRIVERS
static sooc_status drv_start(void *ctx) { return sooc_sensor_start(ctx); }
static sooc_status drv_read(void *ctx, sooc_frame *f, int t) { return sooc_sensor_read(ctx, f, t); }
static void drv_stop(void *ctx) { sooc_sensor_stop(ctx); }
static void drv_close(void *ctx) { (void)ctx; /* closed in destroy (after the thread is joined) */ }

static sooc_status pose_lookup_file(void *ctx, int64_t t, int64_t tol, double T[16]) {
    return sooc_pose_lookup(ctx, t, tol, T);
}
static sooc_status pose_lookup_socket(void *ctx, int64_t t, int64_t tol, double T[16]) {
    int wait_ms = (int)(tol / 1000000) + 50;
    return sooc_pose_wait_lookup(ctx, t, tol, wait_ms, T);
}
static void pose_close(void *ctx) { sooc_pose_close(ctx); }

/* launch key -> driver.h sooc_sensor_params_set key */
static const char *map_key(const char *driver, const char *key, const char **value) {
    if (!strcmp(key, "path") || !strcmp(key, "depth_device") || !strcmp(key, "index") ||
        !strcmp(key, "camera"))
        return "uri";
    if (!strcmp(key, "color_device")) return "uri2";
    if (!strcmp(key, "depth_mode")) return "depth_format";
    if (!strcmp(key, "speed")) {
        if (!strcmp(*value, "realtime")) *value = "1";
        else if (!strcmp(*value, "fast")) *value = "0";
        return "speed";
    }
    if (!strcmp(key, "format") && !strcmp(*value, "auto")) return NULL;   /* leave NULL = auto */
    (void)driver;
    return key;
}

static sooc_status open_sensor(sooc_node *n) {
    const sooc_node_config *c = &n->cfg;
    sooc_sensor_params sp;
    sooc_sensor_params_default(&sp);
    for (int i = 0; i < c->n_params; i++) {
        const char *v = c->params[i].value;
        const char *k = map_key(c->driver, c->params[i].key, &v);
        if (!k) continue;
        sooc_status st = sooc_sensor_params_set(&sp, k, v);
        if (st)
            return sooc_adderr(st, "%s:%d: sensor.%s", c->path, c->params[i].line, c->params[i].key);
    }
    if (c->pose_kind == SOOC_NODE_POSE_TF) {   /* the log's TF gives the frames their poses */
        sp.pose_parent = c->pose_parent;
        sp.pose_child = c->pose_child[0] ? c->pose_child : NULL;
    }
    sp.depth_min = (float)c->min_depth_m;
    sp.depth_max = (float)c->max_depth_m;
#if SOOC_NODE_HAVE_CALIB
    if (n->have_calib && n->calib.depth_scale > 0 && !sooc_node_param_get(c, "depth_scale"))
        sp.depth_scale = n->calib.depth_scale;
    /* the calib's depth decoding keys, like depth_scale (replay; seq.h) */
    if (n->have_calib && n->calib.depth_shift >= 0 && !sooc_node_param_get(c, "depth_shift"))
        sp.depth_shift = n->calib.depth_shift;
    if (n->have_calib && n->calib.depth_invalid >= 0 && !sooc_node_param_get(c, "depth_invalid"))
        sp.depth_invalid = n->calib.depth_invalid;
#endif
    sooc_status st = sooc_sensor_open(&n->sensor, c->driver, &sp);
    if (st) return sooc_adderr(st, "%s: sensor (driver %s)", c->path, c->driver);
    n->src.ctx = n->sensor;
    n->src.start = drv_start;
    n->src.read = drv_read;
    n->src.stop = drv_stop;
    n->src.close = drv_close;
    n->have_src = 1;
    return SOOC_OK;
}

static sooc_status open_pose(sooc_node *n) {
    const sooc_node_config *c = &n->cfg;
    if (c->pose_kind == SOOC_NODE_POSE_SENSOR || c->pose_kind == SOOC_NODE_POSE_ODOMETRY ||
        c->pose_kind == SOOC_NODE_POSE_TF)
        return SOOC_OK;
    sooc_pose_params pp;
    sooc_pose_params_default(&pp);
    if (n->have_T_eff) {
        pp.has_hand_eye = 1;
        memcpy(pp.T_effector_camera, n->T_eff_cam, sizeof pp.T_effector_camera);
    } else if (c->pose_is_effector) {
        return sooc_seterr(SOOC_EINVAL, "%s: pose.frame: effector, but calib %s has no T_effector_camera",
                           c->path, c->calib_path);
    }
    pp.text_kind = c->pose_is_effector ? SOOC_POSE_EFFECTOR : SOOC_POSE_CAMERA;
    sooc_status st;
    if (c->pose_kind == SOOC_NODE_POSE_FILE) {
        st = sooc_pose_open_file(&n->psrc, c->pose_path, &pp);
        n->pose.lookup = pose_lookup_file;
    } else {
        st = sooc_pose_open_socket(&n->psrc, c->pose_path, &pp);
        n->pose.lookup = pose_lookup_socket;
    }
    if (st) return sooc_adderr(st, "%s: pose.path", c->path);
    n->pose.ctx = n->psrc;
    n->pose.close = pose_close;
    n->have_pose = 1;
    return SOOC_OK;
}
#endif

/* --------------------------------------------------------- conversions */

#if SOOC_NODE_HAVE_TABLE
static void to_record(const sooc_map_entry *e, sooc_table_record *r) {
    memset(r, 0, sizeof *r);
    r->object_id = e->id;
    r->flags = SOOC_TABLE_FLAG_VALID | (e->obs_count < 2 ? SOOC_TABLE_FLAG_TENTATIVE : 0u);
    r->obs_count = e->obs_count;
    r->presence = e->presence;
    r->x = (float)e->x;
    r->z = (float)e->z;
    r->yaw = (float)e->yaw;
    float vt = (float)(e->sigma_t * e->sigma_t), vy = (float)(e->sigma_yaw * e->sigma_yaw);
    r->cov_xzyaw[0] = vt;
    r->cov_xzyaw[3] = vt;
    r->cov_xzyaw[5] = vy;
    r->y = 0.5f * e->extent[1];   /* objects rest on the floor */
    memcpy(r->extent, e->extent, sizeof r->extent);
    const sooc_map_geometry *g = &e->geom;   /* the mapper's geometry (objgeom.h; docs/shm.md) */
    if (g->cov_xz[0] > 0 && g->cov_xz[2] > 0) {   /* calibrated spreads */
        r->cov_xzyaw[0] = (float)g->cov_xz[0];
        r->cov_xzyaw[1] = (float)g->cov_xz[1];
        r->cov_xzyaw[3] = (float)g->cov_xz[2];
        r->cov_xzyaw[5] = (float)g->var_yaw;   /* NaN when the shape is symmetric: yaw undefined */
    }
    if (g->flags & SOOC_GEOM_TIGHT) r->y = g->centre[1];   /* tight box centre above the floor */
    if (g->flags & SOOC_GEOM_SYMMETRIC) r->flags |= SOOC_TABLE_FLAG_SYMMETRIC;
    r->first_seen_ns = e->first_seen_ns;
    r->last_seen_ns = e->last_seen_ns;
    int d = e->latent_dim;
    if (d < 0) d = 0;
    if (d > (int)SOOC_TABLE_LATENT_MAX) d = SOOC_TABLE_LATENT_MAX;
    r->latent_dim = (uint32_t)d;
    memcpy(r->latent, e->what_mu, (size_t)d * sizeof(float));
}
#endif

#if SOOC_NODE_HAVE_MAPSTORE
typedef struct load_ctx_l {
    sooc_node *n;
    sooc_status st;
    size_t count;
} load_ctx_l;

static int load_block(void *user, int32_t bi, int32_t bj, const float *mu, const float *logvar) {
    load_ctx_l *L = user;
    L->st = sooc3d_mapper_load_layout(L->n->mapper, bi, bj, mu, logvar);
    if (!L->st) L->count++;
    return L->st != SOOC_OK;
}

typedef struct load_ctx {
    sooc_node *n;
    sooc_status st;
} load_ctx;

static int load_visit(void *user, const sooc_cogmap_entry *c) {
    load_ctx *L = user;
    sooc_node *n = L->n;
    if ((L->st = grow((void **)&n->prev, &n->cap_prev, n->n_prev + 1, sizeof *n->prev))) return 1;
    sooc_map_entry_from_cogmap(c, n->extent, &n->prev[n->n_prev]);
    n->n_prev++;
    return 0;
}

/* Open the database: an existing one with its own dims (checked against the
 * mapper's), or a new one with the mapper's latent and layout dims. */
static sooc_status store_open(sooc_node *n, int create) {
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = create;
    mp.dim = create ? sooc3d_mapper_latent_dim(n->mapper) : 0;
    mp.layout_dim = create ? sooc3d_mapper_layout_dim(n->mapper) : 0;
    mp.model_id = n->model_id_str[0] ? n->model_id_str : NULL; /* stored, and checked on resume */
    if (create && mp.dim <= 0)
        return sooc_seterr(SOOC_EINVAL, "%s: map.db: the mapper reports latent dim %d", n->cfg.path, mp.dim);
    sooc_status st = sooc_mapstore_open(&n->store, n->cfg.map_db, &mp);
    if (st) return sooc_adderr(st, "%s: map.db", n->cfg.path);
    sooc_mapstore_info info;
    if ((st = sooc_mapstore_info_get(n->store, &info))) return sooc_adderr(st, "%s: map.db", n->cfg.path);
    int md = sooc3d_mapper_latent_dim(n->mapper);
    if (md > 0 && info.dim != md)
        return sooc_seterr(SOOC_EVERSION, "%s: map.db %s holds latents of dim %d, the model produces %d", n->cfg.path,
                           n->cfg.map_db, info.dim, md);
    /* a database written without layout latents (or with other ones) keeps none */
    n->store_layout_dim = info.layout_dim == sooc3d_mapper_layout_dim(n->mapper) ? info.layout_dim : 0;
    if (info.layout_dim && !n->store_layout_dim)
        sooc_log(SOOC_LOG_WARN, "%s: map.db layout dim %d differs from the model's %d: layout not persisted",
                 n->cfg.map_db, info.layout_dim, sooc3d_mapper_layout_dim(n->mapper));
    char b[128];
    if (!sooc_mapstore_meta_get(n->store, "extent", b, sizeof b) &&
        sscanf(b, "%f %f %f", &n->extent[0], &n->extent[1], &n->extent[2]) == 3)
        n->extent_stored = 1;
    return SOOC_OK;
}
#endif

/* ------------------------------------------------------------ publisher */

/* Publish `chg` / `rem`: one table batch and one SQLite transaction (changed
 * entries, removed ids, the active layout block, the id counter and a keyframe
 * row). Its cost depends on nc + nr, not on the map size. `kf` = NULL for the
 * start-up batch (no keyframe row); to_db = 0 when the entries came from the
 * database itself (resume). */
typedef struct kf_info {
    int64_t stamp_ns;
    const double *T_wc;
    int64_t t_cap_mono;
} kf_info;

static sooc_status publish(sooc_node *n, const sooc_map_entry *chg, size_t nc, const uint64_t *rem, size_t nr,
                           int clear_first, int to_db, const kf_info *kf) {
    sooc_status st = SOOC_OK;
    double t0 = sooc_seconds();
    size_t n_entries = 0;
    if ((st = sooc3d_mapper_entries(n->mapper, NULL, 0, &n_entries))) return sooc_adderr(st, "mapper entries");
#if SOOC_NODE_HAVE_TABLE
    if (n->table) {
        int rc = sooc_table_begin_batch(n->table);
        if (clear_first && !rc) rc = sooc_table_clear(n->table);
        uint32_t ld = (uint32_t)sooc3d_mapper_latent_dim(n->mapper);
        double T_src_map[16];
        sooc_se3_inverse(T_src_map, n->T_world_src);
        /* T_src_map (and HFLAG_FLOOR_SET) only once the world frame is known:
         * given, stored, or estimated; not the identity placeholder before an estimate */
        if (!rc)
            rc = sooc_table_set_meta(n->table, ld, n->model_id, kf ? kf->stamp_ns : 0,
                                     n->world_ready ? T_src_map : NULL);
        for (size_t i = 0; i < nc && !rc; i++) {
            sooc_table_record r;
            to_record(&chg[i], &r);
            rc = sooc_table_upsert(n->table, &r);
        }
        for (size_t i = 0; i < nr && !rc; i++) {
            int r2 = sooc_table_remove(n->table, rem[i]);
            if (r2 && r2 != SOOC_TABLE_ENOENT) rc = r2;
        }
        int rc2 = sooc_table_end_batch(n->table);
        if (!rc) rc = rc2;
        if (rc) st = sooc_seterr(SOOC_EIO, "shm table '%s': %s", n->cfg.shm_name, sooc_table_strerror(rc));
    }
#else
    (void)clear_first;
#endif
    if (kf && kf->t_cap_mono > 0) {
        double ms = (double)(sooc_now_ns() - kf->t_cap_mono) * 1e-6;
        pthread_mutex_lock(&n->mu);
        sooc_latency_add(&n->lat_c2t, ms);
        pthread_mutex_unlock(&n->mu);
    }
#if SOOC_NODE_HAVE_MAPSTORE
    if (!st && n->store && (kf || (to_db && nc))) {
        st = sooc_mapstore_begin(n->store);
        sooc_cogmap_entry ce;
        for (size_t i = 0; i < nc && !st && to_db; i++) {
            sooc_map_entry_to_cogmap(&chg[i], &ce);
            st = sooc_mapstore_put_entries(n->store, &ce, 1);
            if (!st && (chg[i].geom.flags || chg[i].geom.reg_n))   /* object geometry (schema 3) */
                st = sooc_mapstore_geom_put(n->store, chg[i].id, chg[i].extent, &chg[i].geom);
        }
        if (!st && nr) st = sooc_mapstore_remove_entries(n->store, rem, nr);
        if (!st && !n->extent_stored && nc && chg[0].extent[0] > 0) {
            char b[96];
            snprintf(b, sizeof b, "%.9g %.9g %.9g", chg[0].extent[0], chg[0].extent[1], chg[0].extent[2]);
            if (!(st = sooc_mapstore_meta_set(n->store, "extent", b))) {
                memcpy(n->extent, chg[0].extent, sizeof n->extent);
                n->extent_stored = 1;
            }
        }
        int32_t bi = 0, bj = 0;
        int has_block = 0;
        if (!st && kf && n->store_layout_dim) {
            float mu[SOOC_MAP_LATENT_MAX], lv[SOOC_MAP_LATENT_MAX];
            sooc_status s2 = sooc3d_mapper_last_layout(n->mapper, &bi, &bj, mu, lv);
            if (!s2) {
                has_block = 1;
                st = sooc_mapstore_put_layout(n->store, bi, bj, mu, lv);
            } else if (s2 != SOOC_ENOTFOUND) {
                st = s2;
            }
        }
        if (!st) st = sooc_mapstore_set_next_id(n->store, sooc3d_mapper_next_id(n->mapper));
        if (!st && kf) {
            sooc_mapstore_keyframe k;
            memset(&k, 0, sizeof k);
            k.t_ns = kf->stamp_ns;
            k.view = (int32_t)n->kf_seq;
            memcpy(k.T_wc, kf->T_wc, sizeof k.T_wc);
            uint64_t ids[SOOC_MAPPER_CHANGED_MAX];
            size_t m = nc < SOOC_MAPPER_CHANGED_MAX ? nc : SOOC_MAPPER_CHANGED_MAX;
            for (size_t i = 0; i < m; i++) ids[i] = chg[i].id;
            k.changed = ids;
            k.n_changed = m;
            k.removed = rem;
            k.n_removed = nr;
            k.has_block = has_block;
            k.bi = bi;
            k.bj = bj;
            st = sooc_mapstore_add_keyframe(n->store, &k, (int64_t)n_entries);
        }
        if (!st) st = sooc_mapstore_commit(n->store);
        else sooc_mapstore_rollback(n->store);
        if (!st && kf) n->kf_seq++;
    }
#else
    (void)to_db;
#endif
    double ms = (sooc_seconds() - t0) * 1e3;
    pthread_mutex_lock(&n->mu);
    if (kf) sooc_latency_add(&n->lat_pub, ms);
    n->st.published += nc;
    n->st.removed += nr;
    n->st.n_objects = n_entries;
    pthread_mutex_unlock(&n->mu);
    return st;
}

/* Publish what the last update changed (sooc3d_mapper_changed): O(changes). */
static sooc_status publish_keyframe(sooc_node *n, int64_t stamp_ns, const double T_wc[16], int64_t t_cap) {
    size_t nc = 0, nr = 0;
    sooc_status st = sooc3d_mapper_changed(n->mapper, n->changed, SOOC_MAPPER_CHANGED_MAX, &nc, n->removed,
                                           SOOC_MAPPER_CHANGED_MAX, &nr);
    if (st) return sooc_adderr(st, "mapper changed");
    kf_info kf = {stamp_ns, T_wc, t_cap};
    st = publish(n, n->changed, nc, n->removed, nr, 0, 1, &kf);
    pthread_mutex_lock(&n->mu);
    stats_refresh(n);
    sooc_node_stats snap = n->st;
    pthread_mutex_unlock(&n->mu);
    if (n->opt.on_keyframe)
        n->opt.on_keyframe(n->opt.user, snap.keyframes + 1, n->changed, nc, n->removed, nr, &snap);
    return st;
}

/* ---------------------------------------------------------------- create */

static sooc_status load_calib(sooc_node *n) {
    if (!n->cfg.calib_path[0]) return SOOC_OK;
#if SOOC_NODE_HAVE_CALIB
    sooc_status st = sooc_calib_load(n->cfg.calib_path, &n->calib);
    if (st) return sooc_adderr(st, "%s: calib", n->cfg.path);
    n->have_calib = 1;
    n->Kc = n->calib.K;
    n->calib_registered = n->calib.depth_registered;
    if (n->calib.has_T_color_depth) {
        n->have_T_cd = 1;
        memcpy(n->T_cd, n->calib.T_color_depth, sizeof n->T_cd);
    }
    if (n->calib.has_T_effector_camera) {
        n->have_T_eff = 1;
        memcpy(n->T_eff_cam, n->calib.T_effector_camera, sizeof n->T_eff_cam);
    }
    if (n->calib_registered == 0 && !n->have_T_cd)
        return sooc_seterr(SOOC_EINVAL, "%s: depth_registered is false but T_color_depth is missing",
                           n->cfg.calib_path);
    return SOOC_OK;
#else
    return sooc_seterr(SOOC_EUNSUPPORTED, "%s: calib: the calibration loader is not built in", n->cfg.path);
#endif
}


/* ---------------------------------------------------------- world frame */

static void support_free(sooc_node *n);

static void set_world(sooc_node *n, const double T[16]) {
    pthread_mutex_lock(&n->mu);   /* stats_refresh reads T_world_src on other threads */
    memcpy(n->T_world_src, T, 16 * sizeof(double));
    n->st.floor_estimated = n->cfg.floor_mode == SOOC_NODE_FLOOR_ESTIMATE;
    pthread_mutex_unlock(&n->mu);
    n->world_ready = 1;
}

#if SOOC_NODE_HAVE_MAPSTORE
static sooc_status store_world(sooc_node *n, const sooc_map_frame *mf) {
    if (!n->store) return SOOC_OK;
    sooc_status st = sooc_mapstore_frame_put(n->store, mf);
    return st ? sooc_adderr(st, "%s: map.db: storing the world frame", n->cfg.path) : SOOC_OK;
}
#endif

/* The map's world frame at start-up. A database that holds one (written when
 * the frame was first estimated or given) fixes it on resume: the estimate
 * is skipped, and a given world.up/floor that disagrees is overridden with a
 * warning (the stored entries live in the stored frame). Otherwise a given
 * frame is stored now; an estimated one when it is made. */
static sooc_status world_from_store(sooc_node *n, int resumed) {
    const sooc_node_config *c = &n->cfg;
#if SOOC_NODE_HAVE_MAPSTORE
    if (n->store) {
        sooc_map_frame mf;
        int found = 0;
        sooc_status st = sooc_mapstore_frame_get(n->store, &mf, &found);
        if (st) return sooc_adderr(st, "%s: map.db", c->path);
        if (found && resumed) {
            if (n->world_ready) {
                double d = 0;
                for (int i = 0; i < 12; i++) d = fmax(d, fabs(mf.T_world_src[i] - n->T_world_src[i]));
                if (d > 1e-3)
                    sooc_log(SOOC_LOG_WARN,
                             "%s: world.up/floor differ from the world frame stored in %s (max element difference "
                             "%.3g); using the stored one, which the resumed map was built in",
                             c->path, c->map_db, d);
            }
            set_world(n, mf.T_world_src);
            sooc_log(SOOC_LOG_INFO,
                     "node: world frame from %s: up (%.3f %.3f %.3f) from %s, camera %.2f m above the support plane "
                     "when estimated",
                     c->map_db, mf.up_src[0], mf.up_src[1], mf.up_src[2],
                     mf.up_source >= 0 ? sooc_up_source_name((sooc_up_source)mf.up_source) : "world.floor (given)",
                     mf.cam_height_m);
            support_free(n);
            return SOOC_OK;
        }
        if (n->world_ready && !found) {   /* world.floor given: store it */
            memset(&mf, 0, sizeof mf);
            memcpy(mf.T_world_src, n->T_world_src, sizeof mf.T_world_src);
            memcpy(mf.up_src, c->up, sizeof mf.up_src);
            memcpy(mf.plane_src, c->up, 3 * sizeof(double));
            mf.plane_src[3] = -c->floor_height;
            mf.up_source = -1;
            return store_world(n, &mf);
        }
    }
#else
    (void)resumed;
    (void)c;
#endif
    return SOOC_OK;
}

/* Buffers for world.floor: estimate, and the gravity hint. */
static sooc_status support_init(sooc_node *n) {
    const sooc_node_config *c = &n->cfg;
    n->cap_sup = c->support_frames > 0 ? (c->support_frames < 32 ? c->support_frames : 32) : 8;
    n->sup_f = sooc_calloc((size_t)n->cap_sup, sizeof *n->sup_f);
    n->sup_T = sooc_malloc(16 * sizeof(double) * (size_t)n->cap_sup);
    n->sup_tcap = sooc_malloc(sizeof(int64_t) * (size_t)n->cap_sup);
    if (!n->sup_f || !n->sup_T || !n->sup_tcap) return sooc_seterr(SOOC_ENOMEM, "node: out of memory");
    char path[SOOC_NODE_PATH_MAX + 32];
    const char *rp = sooc_node_param_get(c, "path");
    int auto_g = !c->gravity_path[0] || !strcmp(c->gravity_path, "auto");
    if (!strcmp(c->gravity_path, "none")) return SOOC_OK;
    if (auto_g) {
        if (strcmp(c->driver, "replay") || !rp) return SOOC_OK;
        /* the file is in the recording's pose frame, not the odometry's */
        if (c->pose_kind == SOOC_NODE_POSE_ODOMETRY) return SOOC_OK;
        snprintf(path, sizeof path, "%s/gravity-direction.txt", rp);
        if (!sooc_file_exists(path)) return SOOC_OK;
    } else {
        snprintf(path, sizeof path, "%s", c->gravity_path);
    }
    sooc_status st = sooc_support_read_gravity(path, n->gravity);
    if (st) return sooc_adderr(st, "%s: world.gravity", c->path);
    n->has_gravity = 1;
    sooc_log(SOOC_LOG_INFO, "node: gravity (%.4f %.4f %.4f) from %s", n->gravity[0], n->gravity[1], n->gravity[2],
             path);
    return SOOC_OK;
}

static void support_free(sooc_node *n) {
    for (int i = 0; i < n->cap_sup; i++) sooc_frame_free(&n->sup_f[i]);
    sooc_free(n->sup_f);
    sooc_free(n->sup_T);
    sooc_free(n->sup_tcap);
    n->sup_f = NULL;
    n->sup_T = NULL;
    n->sup_tcap = NULL;
    n->n_sup = n->cap_sup = 0;
}

sooc_status sooc_node_create(sooc_node **out, const sooc_node_config *c, const sooc_node_options *o) {
    *out = NULL;
    sooc_node *n = sooc_calloc(1, sizeof *n);
    if (!n) return SOOC_ENOMEM;
    n->cfg = *c;
    if (o) n->opt = *o;
    pthread_mutex_init(&n->mu, NULL);
    atomic_init(&n->stop, 0);
    n->calib_registered = -1;
    n->t_start = n->t_last_stats = sooc_seconds();
    sooc_se3_identity(n->T_world_src);
    sooc_kf_policy_init(&n->kf, c->kf_translation_m, c->kf_rotation_deg, c->kf_time_s);
    n->model_id = sooc_crc32(0, c->model_path, strlen(c->model_path));
    sooc_status st = SOOC_OK;

    if (c->floor_mode == SOOC_NODE_FLOOR_GIVEN) {
        sooc_node_world_from_up(c->up, c->floor_height, n->T_world_src);
        n->world_ready = 1;
    }
    /* model */
    if (n->opt.mapper) {
        n->mapper = n->opt.mapper;
    } else {
        sooc3d_mapper_params mp;
        sooc3d_mapper_params_default(&mp);
        mp.model_path = c->model_path;
        mp.iterations = c->iterations;
        mp.seed = c->seed;
        mp.threads = c->threads;
        mp.d_clip = c->clip_m;
        mp.merge_radius = c->merge_m;
        mp.merge_neighbours = 1;   /* revisits refine the mapped entry (docs/cogmap.md "Revisits") */
        mp.latents = c->latents;
        mp.slots = c->slots;
        mp.invalid_depth = c->invalid_depth;
        mp.gate_min_rays = c->gate_min_rays;   /* the creation gate (revisit rule 5): 0 = default */
        mp.gate_ratio = c->gate_ratio;
        mp.gate_part = c->gate_part;
        if (c->model_kind == SOOC3D_MAPPER_GEOMETRIC) {   /* the geometric map (docs/geometric.md "In the node") */
            mp.kind = SOOC3D_MAPPER_GEOMETRIC;
            mp.cluster.voxel_m = c->geo_voxel_m, mp.cluster.dist_m = c->geo_join_m;
            mp.cluster.min_height_m = c->geo_min_height_m, mp.cluster.max_extent_m = c->geo_max_extent_m;
            mp.cluster.max_depth_m = c->max_depth_m < 3.0 ? c->max_depth_m : 3.0;
            if (c->input_width > 0) mp.input_width = c->input_width, mp.input_height = c->input_height;
            if ((st = sooc3d_mapper_create(&n->mapper, &mp))) {
                sooc_adderr(st, "%s: model.kind geometric", c->path);
                goto fail;
            }
            n->own_mapper = 1;
            /* the map's identity: the clustering that made it (voxel, join, min height, max extent in m) */
            snprintf(n->model_id_str, sizeof n->model_id_str,
                     "geometric %.4g %.4g %.4g %.4g", mp.cluster.voxel_m,
                     mp.cluster.dist_m, mp.cluster.min_height_m, mp.cluster.max_extent_m);
        } else {
            if (!c->model_path[0]) {
                st = sooc_seterr(SOOC_EINVAL, "%s: model.path: missing", c->path);
                goto fail;
            }
            if ((st = sooc3d_mapper_create(&n->mapper, &mp))) {
                sooc_adderr(st, "%s: model.path %s", c->path, c->model_path);
                goto fail;
            }
            n->own_mapper = 1;
            /* the model's identity is its checkpoint's content, not its path */
            void *buf = NULL;
            size_t nb = 0;
            if (sooc_file_read_all(c->model_path, (size_t)1 << 31, &buf, &nb) == SOOC_OK) {
                /* 64-bit FNV-1a of every byte. Not a CRC32 of the file: a checkpoint
                 * ends with its own CRC32, which makes that of the whole file a constant */
                uint64_t h = 0xcbf29ce484222325ull;
                for (size_t i = 0; i < nb; i++) h = (h ^ ((const unsigned char *)buf)[i]) * 0x100000001b3ull;
                sooc_free(buf);
                n->model_id = h;
                snprintf(n->model_id_str, sizeof n->model_id_str, "fnv1a64:%016llx bytes:%zu",
                         (unsigned long long)h, nb);
            } else { /* a mapper that does not read model.path as a file (tests): no model check */
                sooc_log(SOOC_LOG_DEBUG, "%s: model.path %s: %s: map.db model_id not set", c->path, c->model_path,
                         sooc_errmsg());
            }
        }
    }
    sooc3d_mapper_input_size(n->mapper, &n->tw, &n->th);
    if (c->input_width > 0 && (c->input_width != n->tw || c->input_height != n->th)) {
        st = sooc_seterr(SOOC_EINVAL, "%s: model.width/height: %dx%d, but the model takes %dx%d", c->path,
                         c->input_width, c->input_height, n->tw, n->th);
        goto fail;
    }
    if (n->tw <= 0 || n->th <= 0) {
        st = sooc_seterr(SOOC_EINVAL, "%s: model: input size %dx%d is invalid", c->path, n->tw, n->th);
        goto fail;
    }
    if ((st = load_calib(n))) goto fail;

    /* sources */
    if (n->opt.source) {
        n->src = *n->opt.source;
        n->have_src = 1;
    }
    if (n->opt.pose) {
        n->pose = *n->opt.pose;
        n->have_pose = 1;
    }
#if SOOC_NODE_HAVE_DRIVERS
    if (!n->have_src && (st = open_sensor(n))) goto fail;
    if (!n->have_pose && (st = open_pose(n))) goto fail;
#else
    if (!n->have_src) {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "%s: sensor: the drivers module is not built in", c->path);
        goto fail;
    }
#endif
    if (c->pose_kind == SOOC_NODE_POSE_ODOMETRY && !n->have_pose) {
#if SOOC_NODE_HAVE_CV
        sooc_odom_params op;
        sooc_odom_params_default(&op);
        op.variant = (sooc_odom_variant)c->odom_variant;
        op.width = c->odom_width;
        op.height = c->odom_height;
        op.kf_translation_m = c->odom_kf_translation_m;
        op.kf_rotation_deg = c->odom_kf_rotation_deg;
        op.kf_max_frames = c->odom_kf_frames;
        op.max_failures = c->odom_max_failures;
        op.min_depth_m = c->odom_min_depth_m;
        op.max_depth_m = c->odom_max_depth_m;
        op.min_agreement = c->odom_min_agreement;
        if (c->odom_color_fx > 0) {   /* colour not registered to depth (7-Scenes) */
            op.color_K[0] = c->odom_color_fx;
            op.color_K[1] = c->odom_color_fy;
            op.color_K[2] = c->odom_color_cx;
            op.color_K[3] = c->odom_color_cy;
            op.T_color_depth[3] = c->odom_color_tx;
            op.T_color_depth[7] = c->odom_color_ty;
            op.T_color_depth[11] = c->odom_color_tz;
        }
        if ((st = sooc_odom_create(&n->odom, &op))) {
            sooc_adderr(st, "%s: pose.source: odometry", c->path);
            goto fail;
        }
#else
        st = sooc_seterr(SOOC_EUNSUPPORTED, "%s: pose.source: odometry: the cv module is not built in", c->path);
        goto fail;
#endif
    } else if (c->pose_kind != SOOC_NODE_POSE_SENSOR && c->pose_kind != SOOC_NODE_POSE_TF && !n->have_pose) {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "%s: pose: no pose source available", c->path);
        goto fail;
    }
    if ((st = sooc_frame_ring_create(&n->ring, c->ring_capacity))) goto fail;
    sooc_frame_ring_set_blocking(n->ring, c->block_when_full);
    if (c->floor_mode == SOOC_NODE_FLOOR_ESTIMATE && (st = support_init(n))) goto fail;

    /* persistent map: resume */
    n->db_exists = c->map_db[0] && sooc_file_exists(c->map_db);
    int resumed = 0;
#if SOOC_NODE_HAVE_MAPSTORE
    if (n->db_exists) {
        if ((st = store_open(n, 0))) goto fail;
        sooc_mapstore_info info;
        if ((st = sooc_mapstore_info_get(n->store, &info))) goto fail;
        if (!c->map_resume && info.n_entries > 0) {
            st = sooc_seterr(SOOC_EINVAL,
                             "%s: map.resume: false, but %s already holds %llu entries (remove it or resume)",
                             c->path, c->map_db, (unsigned long long)info.n_entries);
            goto fail;
        }
        load_ctx L = {n, SOOC_OK};
        if ((st = sooc_mapstore_foreach(n->store, load_visit, &L)) || (st = L.st)) {
            sooc_adderr(st, "%s: resume from %s", c->path, c->map_db);
            goto fail;
        }
        for (size_t i = 0; i < n->n_prev; i++) {   /* stored object geometry (schema 3; none in older maps) */
            int found = 0;
            if ((st = sooc_mapstore_geom_get(n->store, n->prev[i].id, n->prev[i].extent, &n->prev[i].geom, &found))) {
                sooc_adderr(st, "%s: resume from %s", c->path, c->map_db);
                goto fail;
            }
        }
        if (n->n_prev && (st = sooc3d_mapper_load_entries(n->mapper, n->prev, n->n_prev))) {
            sooc_adderr(st, "%s: resume: mapper refused %zu stored entries", c->path, n->n_prev);
            goto fail;
        }
        load_ctx_l LB = {n, SOOC_OK, 0};
        if (n->store_layout_dim &&
            ((st = sooc_mapstore_foreach_layout(n->store, load_block, &LB)) || (st = LB.st))) {
            sooc_adderr(st, "%s: resume: layout blocks from %s", c->path, c->map_db);
            goto fail;
        }
        /* ids of entries removed before the restart are not handed out again */
        sooc3d_mapper_reserve_ids(n->mapper, info.next_id);
        n->st.resumed = n->n_prev;
        n->st.resumed_blocks = LB.count;
        resumed = 1;
    } else if (c->map_db[0]) {
        if ((st = store_open(n, 1))) goto fail;
    }
#else
    if (c->map_db[0])
        sooc_log(SOOC_LOG_WARN, "%s: map.db set but the SQLite map store is not built in; not persisting",
                 c->path);
#endif
    if ((st = world_from_store(n, resumed))) goto fail;
    /* what the mapper holds now (resumed, or preloaded by the caller) is republished at start */
    {
        size_t cnt = 0;
        if ((st = sooc3d_mapper_entries(n->mapper, NULL, 0, &cnt))) goto fail;
        if ((st = grow((void **)&n->prev, &n->cap_prev, cnt + 1, sizeof *n->prev))) goto fail;
        if ((st = sooc3d_mapper_entries(n->mapper, n->prev, n->cap_prev, &n->n_prev))) goto fail;
        for (size_t i = 0; i < n->n_prev; i++)   /* a mapper without a box extent: the stored one */
            if (n->prev[i].extent[0] <= 0) memcpy(n->prev[i].extent, n->extent, sizeof n->extent);
        n->st.n_objects = n->n_prev;
    }

    /* shm table */
    if (c->shm_name[0]) {
#if SOOC_NODE_HAVE_TABLE
        int rc = sooc_table_create_writer(c->shm_name, c->shm_capacity, 0, "map", &n->table);
        if (rc) {
            st = sooc_seterr(rc == SOOC_TABLE_ELOCKED ? SOOC_EBUSY : SOOC_EIO, "%s:shm.name: table '%s': %s",
                             c->path, c->shm_name, sooc_table_strerror(rc));
            goto fail;
        }
        sooc_table_start_heartbeat(n->table, 20.0);
        if ((uint64_t)n->n_prev > c->shm_capacity) {
            st = sooc_seterr(SOOC_EINVAL, "%s: shm.capacity: %u is below the %zu stored entries", c->path,
                             c->shm_capacity, n->n_prev);
            goto fail;
        }
#else
        sooc_log(SOOC_LOG_WARN, "%s: shm.name set but the table module is not built in", c->path);
#endif
    }
    /* republish the resumed map (and clear leftovers of an earlier run); a map
     * preloaded by the caller also goes to a new database */
    if ((st = publish(n, n->prev, n->n_prev, NULL, 0, 1, !resumed, NULL))) goto fail;
    sooc_free(n->prev);
    n->prev = NULL;
    n->cap_prev = 0;
    *out = n;
    return SOOC_OK;
fail:
    sooc_node_destroy(n);
    return st;
}

/* ------------------------------------------------------------- capture */

static void *capture_main(void *arg) {
    sooc_node *n = arg;
    sooc_frame f;
    memset(&f, 0, sizeof f);
    sooc_status st = n->src.start ? n->src.start(n->src.ctx) : SOOC_OK;
    while (!st && !atomic_load(&n->stop)) {
        st = n->src.read(n->src.ctx, &f, 100);
        if (st == SOOC_ETIMEOUT) { st = SOOC_OK; continue; }
        if (st) break;
        pthread_mutex_lock(&n->mu);
        n->st.frames_in++;
        pthread_mutex_unlock(&n->mu);
        sooc_frame_ring_push(n->ring, &f, sooc_now_ns());
    }
    if (st == SOOC_EEOF || st == SOOC_EINTERRUPTED) st = SOOC_OK;
    if (st && !atomic_load(&n->stop)) {
        n->cap_status = st;
        snprintf(n->cap_err, sizeof n->cap_err, "%s", sooc_errmsg());
    }
    if (n->src.stop) n->src.stop(n->src.ctx);
    sooc_frame_free(&f);
    sooc_frame_ring_close(n->ring);   /* mapping drains what is left, then sees EEOF */
    return NULL;
}

/* ------------------------------------------------------------- mapping */

/* world.floor: estimate. The frame (pose known) waits in the support
 * buffer; when it is full (or the stream ended: final = 1) the support plane
 * is estimated from the buffered frames. Returns 1 when the world frame is
 * ready (the buffered frames are then to be mapped), 0 to keep waiting (on a
 * failed estimate the older half of the buffer is dropped), < 0 on error. */
static int try_support(sooc_node *n, const sooc_frame *f, const double T_src_c[16], int64_t t_cap, int final,
                       sooc_status *err) {
    if (f) {
        if (n->n_sup == n->cap_sup || sooc_frame_copy(&n->sup_f[n->n_sup], f)) {
            *err = sooc_seterr(SOOC_ENOMEM, "node: support-plane frame buffer");
            return -1;
        }
        n->sup_f[n->n_sup].has_pose = 1;
        memcpy(n->sup_f[n->n_sup].T_wc, T_src_c, 16 * sizeof(double));
        memcpy(n->sup_T + 16 * n->n_sup, T_src_c, 16 * sizeof(double));
        n->sup_tcap[n->n_sup] = t_cap;
        n->n_sup++;
    }
    if (n->n_sup == 0 || (n->n_sup < n->cap_sup && !final)) return 0;
    const sooc_node_config *c = &n->cfg;
    sooc_support_params sp;
    sooc_support_params_default(&sp);
    if (c->up_given) {
        sp.has_up_hint = 1;
        memcpy(sp.up_hint, c->up, sizeof sp.up_hint);
    }
    if (n->has_gravity) {
        sp.has_gravity = 1;
        memcpy(sp.gravity, n->gravity, sizeof sp.gravity);
    }
    sp.max_tilt_deg = c->max_tilt_deg;
    sp.threshold_m = c->floor_ransac_threshold_m;
    sp.iterations = c->floor_ransac_iterations;
    sp.max_frames = n->n_sup;
    if (c->cam_height_min_m > 0) {   /* the launch file's (both given, min < max: launch.c) */
        sp.cam_height_min_m = c->cam_height_min_m;
        sp.cam_height_max_m = c->cam_height_max_m;
    } else {   /* the model's trained range */
        sooc3d_mapper_cam_heights(n->mapper, &sp.cam_height_min_m, &sp.cam_height_max_m);
    }
    sp.seed = c->seed + 1;
    const sooc_frame *fp[32];
    for (int i = 0; i < n->n_sup; i++) fp[i] = &n->sup_f[i];
    sooc_support sup;
    n->floor_attempts++;
    sooc_status st = sooc_support_estimate(fp, n->n_sup, &sp, &sup);
    if (st) {
        if (n->floor_attempts % 10 == 1 || final)
            sooc_log(SOOC_LOG_WARN, "node: support plane (world.floor: estimate) failed on frames %lld-%lld: %s",
                     (long long)n->sup_f[0].index, (long long)n->sup_f[n->n_sup - 1].index, sooc_errmsg());
        int drop = final ? n->n_sup : (n->n_sup + 1) / 2;
        for (int i = 0; i < n->n_sup; i++) {   /* keep the newer frames, swapping buffers */
            if (i + drop < n->n_sup) {
                sooc_frame t = n->sup_f[i];
                n->sup_f[i] = n->sup_f[i + drop];
                n->sup_f[i + drop] = t;
                memcpy(n->sup_T + 16 * i, n->sup_T + 16 * (i + drop), 16 * sizeof(double));
                n->sup_tcap[i] = n->sup_tcap[i + drop];
            }
        }
        n->n_sup -= drop;
        pthread_mutex_lock(&n->mu);
        n->st.frames_floor_wait += (uint64_t)drop;
        pthread_mutex_unlock(&n->mu);
        return 0;
    }
    set_world(n, sup.T_world_src);
    sooc_log(SOOC_LOG_INFO,
             "node: support plane from %d frames: n = (%.4f %.4f %.4f) d = %.4f, up from %s, tilt %.1f deg from it, "
             "%zu/%zu inliers, rms %.4f m, %d level planes; camera %.2f m above it",
             sup.frames_used, sup.plane_src[0], sup.plane_src[1], sup.plane_src[2], sup.plane_src[3],
             sooc_up_source_name(sup.up_source), sup.tilt_deg, sup.n_inliers, sup.n_points, sup.rms_m,
             sup.n_candidates, sup.cam_height_m);
    if (sup.height_warning)
        sooc_log(SOOC_LOG_WARN,
                 "node: the camera is %.2f m above the support plane, outside the %.2f-%.2f m the model was trained "
                 "for (world.camera_height_min_m / _max_m); objects may be mapped at the wrong scale",
                 sup.cam_height_m, sp.cam_height_min_m, sp.cam_height_max_m);
#if SOOC_NODE_HAVE_MAPSTORE
    sooc_map_frame mf;
    memset(&mf, 0, sizeof mf);
    memcpy(mf.T_world_src, sup.T_world_src, sizeof mf.T_world_src);
    memcpy(mf.up_src, sup.up_src, sizeof mf.up_src);
    memcpy(mf.plane_src, sup.plane_src, sizeof mf.plane_src);
    mf.cam_height_m = sup.cam_height_m;
    mf.up_source = (int)sup.up_source;
    if ((st = store_world(n, &mf))) {
        *err = st;
        return -1;
    }
#endif
    return 1;
}

static sooc_status fix_intrinsics_and_register(sooc_node *n, sooc_frame *f) {
    if (!n->have_calib) {
        if (f->K.fx == 0 || f->K.fy == 0)
            return sooc_seterr(SOOC_EINVAL, "%s: the sensor gives no intrinsics; set calib: to a calib file",
                               n->cfg.path);
        if (f->K.width <= 0) { f->K.width = f->width; f->K.height = f->height; }
        return SOOC_OK;
    }
    sooc_intrinsics Kc = n->Kc;
    if (Kc.width != f->width || Kc.height != f->height) {
        /* same aspect ratio: scale the calibration */
        if ((long)Kc.width * f->height != (long)Kc.height * f->width)
            return sooc_seterr(SOOC_EINVAL, "%s: calib is for %dx%d but the sensor gives %dx%d",
                               n->cfg.calib_path, Kc.width, Kc.height, f->width, f->height);
        sooc_intrinsics s;
        sooc_cam_crop_resize(&s, &Kc, 0, 0, Kc.width, Kc.height, f->width, f->height);
        Kc = s;
    }
    if (n->calib_registered == 0 && n->have_T_cd) {
        /* depth is in the depth camera: the frame's K is the depth camera's */
        sooc_intrinsics Kd = f->K;
        if (Kd.fx == 0) Kd = Kc;   /* no depth intrinsics reported: assume the colour ones */
        Kd.width = f->width;
        Kd.height = f->height;
        size_t np = (size_t)f->width * f->height;
        if (n->reg_cap < np) {
            sooc_free(n->reg_buf);
            n->reg_buf = sooc_malloc(np * sizeof(float));
            if (!n->reg_buf) { n->reg_cap = 0; return SOOC_ENOMEM; }
            n->reg_cap = np;
        }
        sooc_node_register_depth(f->depth, &Kd, n->T_cd, &Kc, n->reg_buf);
        memcpy(f->depth, n->reg_buf, np * sizeof(float));
        for (size_t i = 0; i < np; i++) f->valid[i] = f->depth[i] > 0.0f;
    }
    f->K = Kc;
    return SOOC_OK;
}

/* pose.source: odometry. 1: T_src_c holds the frame's pose; 0: untracked
 * (counted and skipped: the mapper never sees a frame without a trusted
 * pose); -1: error (message set). */
static int odom_pose(sooc_node *n, sooc_frame *f, double T_src_c[16]) {
#if SOOC_NODE_HAVE_CV
    sooc_odom_result r;
    if (sooc_odom_track(n->odom, f, &r)) return -1;
    if (r.state == SOOC_ODOM_FIRST || r.state == SOOC_ODOM_TRACKED) {
        if (n->odom_lost)
            sooc_log(SOOC_LOG_INFO, "node: odometry tracking again at frame %lld after %d untracked frames",
                     (long long)f->index, n->odom_lost);
        n->odom_lost = 0;
        memcpy(T_src_c, r.T_wc, 16 * sizeof(double));
        return 1;
    }
    if (!n->odom_lost)
        sooc_log(SOOC_LOG_WARN, "node: odometry lost tracking at frame %lld: frames are skipped until it recovers",
                 (long long)f->index);
    n->odom_lost++;
    if (r.state == SOOC_ODOM_REANCHORED)
        sooc_log(SOOC_LOG_WARN,
                 "node: odometry re-anchored at frame %lld after %d failures: poses continue from the last tracked "
                 "one (the map may be offset from here)",
                 (long long)f->index, n->odom_lost);
    pthread_mutex_lock(&n->mu);
    n->st.frames_untracked++;
    n->st.frames_no_pose++;
    pthread_mutex_unlock(&n->mu);
    return 0;
#else
    (void)n; (void)f; (void)T_src_c;
    sooc_seterr(SOOC_EUNSUPPORTED, "node: odometry is not built in");
    return -1;
#endif
}

static void log_stats(sooc_node *n) {
    sooc_node_stats s;
    sooc_node_get_stats(n, &s);
    char line[512];
    sooc_node_stats_format(&s, line, sizeof line);
    sooc_log(SOOC_LOG_INFO, "node: %s", line);
}

/* Keyframe policy, preprocessing, mapper update and publishing of one frame
 * whose pose in the source frame is known. Returns 1 when the run must stop
 * (*result: an error, or SOOC_OK after max_keyframes), else 0. */
static int map_frame(sooc_node *n, sooc_frame *f, const double T_src_c[16], int64_t t_cap, sooc_status *result) {
    sooc_status st;
    double T_wc[16];
    sooc_se3_mul(T_wc, n->T_world_src, T_src_c);
    if (!sooc_kf_policy_check(&n->kf, T_wc, f->t_ns)) {
        pthread_mutex_lock(&n->mu);
        n->st.frames_not_kf++;
        pthread_mutex_unlock(&n->mu);
        return 0;
    }
    if ((st = sooc_node_preprocess(f, &n->pre, n->tw, n->th, n->cfg.depth_resample, n->cfg.min_depth_m,
                                   n->cfg.max_depth_m))) {
        *result = st;
        return 1;
    }
    memcpy(n->pre.T_wc, T_wc, sizeof T_wc);
    n->pre.has_pose = 1;
    sooc3d_update_stats us;
    memset(&us, 0, sizeof us);
    double t0 = sooc_seconds();
    st = sooc3d_mapper_update(n->mapper, &n->pre, &us);
    double ms = (sooc_seconds() - t0) * 1e3;
    if (st) {
        pthread_mutex_lock(&n->mu);
        n->st.update_errors++;
        pthread_mutex_unlock(&n->mu);
        sooc_log(SOOC_LOG_WARN, "node: mapper update failed on frame %lld: %s", (long long)f->index,
                 sooc_errmsg());
        /* a late failure may have changed the map already: keep table and database in step */
        size_t pc = 0, pr = 0;
        if (!sooc3d_mapper_changed(n->mapper, NULL, 0, &pc, NULL, 0, &pr) && (pc || pr)) {
            sooc_status s2 = publish_keyframe(n, f->t_ns, T_wc, t_cap);
            if (s2) { *result = s2; return 1; }
        }
        if (st == SOOC_ENOMEM) { *result = st; return 1; }
        return 0;
    }
    sooc_kf_policy_accept(&n->kf, T_wc, f->t_ns);
    pthread_mutex_lock(&n->mu);
    sooc_latency_add(&n->lat_upd, ms);
    pthread_mutex_unlock(&n->mu);
    if ((st = publish_keyframe(n, f->t_ns, T_wc, t_cap))) { *result = st; return 1; }
    pthread_mutex_lock(&n->mu);
    n->st.keyframes++;
    uint64_t k = n->st.keyframes;
    pthread_mutex_unlock(&n->mu);
    sooc_log(SOOC_LOG_DEBUG, "node: keyframe %llu (frame %lld): %d retrieved, %d new, %d removed, %.1f ms",
             (unsigned long long)k, (long long)f->index, us.n_retrieved, us.n_new, us.n_removed, ms);
    if (n->opt.max_keyframes && k >= n->opt.max_keyframes) return 1;
    return 0;
}

/* Map the frames that waited for the support plane, in order, then free them. */
static int map_buffered(sooc_node *n, sooc_status *result) {
    int stop = 0;
    for (int i = 0; i < n->n_sup && !stop; i++) stop = map_frame(n, &n->sup_f[i], n->sup_T + 16 * i, n->sup_tcap[i], result);
    support_free(n);
    return stop;
}

sooc_status sooc_node_run(sooc_node *n) {
    if (!n->have_src) return sooc_seterr(SOOC_EINVAL, "node: no frame source");
    pthread_mutex_lock(&n->mu);   /* sooc_node_get_stats may run on another thread already */
    n->t_start = n->t_last_stats = sooc_seconds();
    pthread_mutex_unlock(&n->mu);
    if (pthread_create(&n->cap_thread, NULL, capture_main, n))
        return sooc_seterr(SOOC_ERR, "node: cannot start the capture thread");
    n->cap_started = 1;
    sooc_status result = SOOC_OK;
    int eof = 0;
    const int64_t tol_ns = (int64_t)llround(n->cfg.pose_tolerance_s * 1e9);
    while (!atomic_load(&n->stop)) {
        if (n->cfg.stats_period_s > 0 && sooc_seconds() - n->t_last_stats >= n->cfg.stats_period_s) {
            n->t_last_stats = sooc_seconds();
            log_stats(n);
        }
        int64_t t_cap = 0;
        sooc_status st = sooc_frame_ring_pop(n->ring, &n->work, &t_cap, 100);
        if (st == SOOC_ETIMEOUT) continue;
        if (st == SOOC_EEOF) { eof = 1; break; }
        if (st) { result = st; break; }
        sooc_frame *f = &n->work;
        /* pose association */
        double T_src_c[16];
        int fixed = 0;
        if (n->cfg.pose_kind == SOOC_NODE_POSE_ODOMETRY && !n->opt.pose) {
            /* odometry tracks the colour-registered frame */
            if ((st = fix_intrinsics_and_register(n, f))) { result = st; break; }
            fixed = 1;
            int r = odom_pose(n, f, T_src_c);
            if (r < 0) { result = sooc_adderr(SOOC_ERR, "node: odometry"); break; }
            if (r == 0) continue;
        } else if ((n->cfg.pose_kind == SOOC_NODE_POSE_SENSOR || n->cfg.pose_kind == SOOC_NODE_POSE_TF) && !n->opt.pose) {
            if (!f->has_pose) {
                pthread_mutex_lock(&n->mu);
                n->st.frames_no_pose++;
                pthread_mutex_unlock(&n->mu);
                continue;
            }
            memcpy(T_src_c, f->T_wc, sizeof T_src_c);
        } else if (n->pose.lookup(n->pose.ctx, f->t_ns, tol_ns, T_src_c)) {
            pthread_mutex_lock(&n->mu);
            n->st.frames_no_pose++;
            pthread_mutex_unlock(&n->mu);
            continue;
        }
        if (!fixed && (st = fix_intrinsics_and_register(n, f))) { result = st; break; }
        if (!n->world_ready) {
            int r = try_support(n, f, T_src_c, t_cap, 0, &result);
            if (r < 0) break;
            if (r == 0) continue;
            if (map_buffered(n, &result)) break;
            continue;
        }
        if (map_frame(n, f, T_src_c, t_cap, &result)) break;
    }
    /* a stream that ended while frames waited for the support plane: estimate from those */
    if (!result && eof && !n->world_ready && n->n_sup > 0) {
        int r = try_support(n, NULL, NULL, 0, 1, &result);
        if (r > 0) map_buffered(n, &result);
    }
    /* shutdown: stop capture, join */
    atomic_store(&n->stop, 1);
#if SOOC_NODE_HAVE_DRIVERS
    if (n->sensor) sooc_sensor_interrupt(n->sensor);
#endif
    sooc_frame_ring_close(n->ring);
    if (n->cap_started) {
        pthread_join(n->cap_thread, NULL);
        n->cap_started = 0;
    }
    if (!result && n->cap_status) {
        result = sooc_seterr(n->cap_status, "node: capture failed: %s", n->cap_err);
    }
    log_stats(n);
    return result;
}

void sooc_node_destroy(sooc_node *n) {
    if (!n) return;
    if (n->cap_started) {
        atomic_store(&n->stop, 1);
#if SOOC_NODE_HAVE_DRIVERS
        if (n->sensor) sooc_sensor_interrupt(n->sensor);
#endif
        if (n->ring) sooc_frame_ring_close(n->ring);
        pthread_join(n->cap_thread, NULL);
    }
    if (n->have_src && n->src.close) n->src.close(n->src.ctx);
#if SOOC_NODE_HAVE_DRIVERS
    sooc_sensor_close(n->sensor);
#endif
    if (n->have_pose && n->pose.close) n->pose.close(n->pose.ctx);
#if SOOC_NODE_HAVE_CV
    sooc_odom_destroy(n->odom);
#endif
#if SOOC_NODE_HAVE_TABLE
    if (n->table) sooc_table_close_writer(n->table, n->cfg.shm_unlink_on_exit);
#endif
#if SOOC_NODE_HAVE_MAPSTORE
    sooc_mapstore_close(n->store);
#endif
    if (n->own_mapper) sooc3d_mapper_destroy(n->mapper);
    sooc_frame_ring_destroy(n->ring);
    sooc_frame_free(&n->work);
    sooc_frame_free(&n->pre);
    sooc_free(n->reg_buf);
    support_free(n);
    sooc_free(n->prev);
    pthread_mutex_destroy(&n->mu);
    sooc_free(n);
}
