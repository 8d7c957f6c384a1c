/* The node's publisher: the shm table batch and the map database's
 * transaction of each keyframe (the database through its fault guard,
 * store_guard.h), and the resume of a stored map at start (docs/node.md
 * "Publisher", "Resume", "Faults"). Mapping thread only. */
#include "node/node_impl.h"

void sooc_node_table_record(const sooc_map_entry *e, sooc_table_record *r) {
    memset(r, 0, sizeof *r);
    r->object_id = e->id;
    r->flags = SOOC_TABLE_FLAG_VALID | (e->obs_count < 2 ? SOOC_TABLE_FLAG_TENTATIVE : 0u);
    r->obs_count = e->obs_count;
    r->presence = e->presence;
    r->x = (float)e->x;
    r->z = (float)e->z;
    r->yaw = (float)e->yaw;
    double cov[4];   /* the one uncertainty of an entry (cogmap.h; NaN yaw: symmetric) */
    sooc_map_entry_planner_cov(e, cov);
    r->cov_xzyaw[0] = (float)cov[0];
    r->cov_xzyaw[1] = (float)cov[1];
    r->cov_xzyaw[3] = (float)cov[2];
    r->cov_xzyaw[5] = (float)cov[3];
    double c[3], yaw;   /* the planner's box (cogmap.h) */
    sooc_map_entry_box(e, c, &yaw, r->extent);
    r->y = (float)c[1];
    const sooc_map_geometry *g = &e->geom;   /* the mapper's geometry (mapper.h; docs/shm.md) */
    if (g->flags & SOOC_GEOM_SYMMETRIC) r->flags |= SOOC_TABLE_FLAG_SYMMETRIC;
    if (g->flags & SOOC_GEOM_TIGHT) r->flags |= SOOC_TABLE_FLAG_BOX_TIGHT;   /* the box's quality */
    if (g->flags & SOOC_GEOM_CLIPPED) r->flags |= SOOC_TABLE_FLAG_BOX_CLIPPED;
    if (g->flags & SOOC_GEOM_EMPTY) r->flags |= SOOC_TABLE_FLAG_BOX_EMPTY;
    if (g->flags & SOOC_GEOM_FAINT) r->flags |= SOOC_TABLE_FLAG_BOX_FAINT;
    r->first_seen_ns = e->first_seen_ns;
    r->last_seen_ns = e->last_seen_ns;
    int d = e->latent_dim;
    if (d < 0) d = 0;
    if (d > (int)SOOC_TABLE_LATENT_MAX) d = SOOC_TABLE_LATENT_MAX;
    r->latent_dim = (uint32_t)d;
    memcpy(r->latent, e->what_mu, (size_t)d * sizeof(float));
}

typedef struct load_ctx_l {
    sooc_node *n;
    sooc_status st;
    size_t count;
} load_ctx_l;

static int load_block(void *user, int32_t bi, int32_t bj, const float *mu, const float *logvar) {
    load_ctx_l *L = user;
    L->st = sooc_mapper_load_layout(L->n->mapper, bi, bj, mu, logvar);
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
    if ((L->st = sooc__node_grow((void **)&n->prev, &n->cap_prev, n->n_prev + 1, sizeof *n->prev))) return 1;
    sooc_map_entry_from_cogmap(c, n->extent, &n->prev[n->n_prev]);
    n->n_prev++;
    return 0;
}

static void store_sync(sooc_node *n);

/* Open the database: an existing one with its own dims (checked against the
 * mapper's), or a new one with the mapper's latent and layout dims. */
static sooc_status store_open(sooc_node *n, int create) {
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = create;
    mp.dim = create ? sooc_mapper_latent_dim(n->mapper) : 0;
    mp.layout_dim = create ? sooc_mapper_layout_dim(n->mapper) : 0;
    mp.model_id = n->model_id_str[0] ? n->model_id_str : NULL; /* stored, and checked on resume */
    if (create && mp.dim <= 0)
        return sooc_seterr(SOOC_EINVAL, "%s: map.db: the mapper reports latent dim %d", n->cfg.path, mp.dim);
    sooc_status st = sooc_mapstore_open(&n->store, n->cfg.map_db, &mp);
    if (st) return sooc_adderr(st, "%s: map.db", n->cfg.path);
    sooc_mapstore_info info;
    if ((st = sooc_mapstore_info_get(n->store, &info))) return sooc_adderr(st, "%s: map.db", n->cfg.path);
    int md = sooc_mapper_latent_dim(n->mapper);
    if (md > 0 && info.dim != md)
        return sooc_seterr(SOOC_EVERSION, "%s: map.db %s holds latents of dim %d, the model produces %d", n->cfg.path,
                           n->cfg.map_db, info.dim, md);
    /* a database written without layout latents (or with other ones) keeps none */
    n->store_layout_dim = info.layout_dim == sooc_mapper_layout_dim(n->mapper) ? info.layout_dim : 0;
    if (info.layout_dim && !n->store_layout_dim)
        sooc_log(SOOC_LOG_WARN, "%s: map.db layout dim %d differs from the model's %d: layout not persisted",
                 n->cfg.map_db, info.layout_dim, sooc_mapper_layout_dim(n->mapper));
    char b[128];
    if (!sooc_mapstore_meta_get(n->store, "extent", b, sizeof b) &&
        sscanf(b, "%f %f %f", &n->extent[0], &n->extent[1], &n->extent[2]) == 3)
        n->extent_stored = 1;
    if ((st = sooc_mapstore_set_busy_timeout(n->store, n->cfg.map_busy_timeout_ms)))
        return sooc_adderr(st, "%s: map.db", n->cfg.path);
    /* the schema (or a WAL an earlier run left) into the database file: on a
     * nearly full disk a large WAL would hold the space the map needs */
    if (sooc_mapstore_checkpoint(n->store, 1)) sooc_clearerr();
    return SOOC_OK;
}

/* The guard's opener: a new database that could not be created at start. */
static sooc_status store_create_later(void *ctx, sooc_mapstore **out) {
    sooc_node *n = ctx;
    sooc_status st = store_open(n, 1);
    if (st) {
        sooc_mapstore_close(n->store);
        n->store = NULL;
    }
    *out = n->store;
    return st;
}

/* The store's guard; a new database that cannot be created for a reason of
 * the storage (a full disk, ...) is created by a later retry. */
static sooc_status store_guard(sooc_node *n, int create) {
    sooc_status st = store_open(n, create);
    if (st) {
        sooc_mapstore_close(n->store);
        n->store = NULL;
        if (!create || !sooc_mapstore_open_fault() || st == SOOC_EINVAL || st == SOOC_EVERSION) return st;
        n->store_layout_dim = sooc_mapper_layout_dim(n->mapper);   /* what the new database will keep */
    }
    if ((st = sooc_sg_create(&n->sg, n->store, n->cfg.map_db, n->store_layout_dim, n->cfg.map_retry_s,
                             n->cfg.map_retry_max_s, store_create_later, n)))
        return sooc_adderr(st, "%s: map.db", n->cfg.path);
    store_sync(n);
    return SOOC_OK;
}

/* ------------------------------------------------------------ publisher */


/* The store's state into the stats and the table header (store block). */
static void store_sync(sooc_node *n) {
    sooc_sg_status s;
    sooc_sg_status_get(n->sg, &s);
    pthread_mutex_lock(&n->mu);
    n->st.store_state = s.state;
    n->st.store_fault = s.fault;
    n->st.store_pending = s.pending;
    n->st.store_pending_kf = s.pending_kf;
    n->st.store_failures = s.failures;
    n->st.store_recoveries = s.recoveries;
    n->st.store_kf_dropped = s.kf_dropped;
    n->st.store_committed_ns = s.committed_ns;
    pthread_mutex_unlock(&n->mu);
    if (n->table) {
        sooc_table_store ts = {(uint32_t)s.state, (uint32_t)s.fault, s.pending, s.pending_kf, s.committed_ns};
        sooc_table_set_store(n->table, &ts);
    }
}

/* Queue one publish for the database (changed entries when to_db, removed
 * ids, the box extent once, the active layout block, the id counter, the
 * keyframe row) and write it: one transaction, or, while the store fails,
 * kept for the next retry (store_guard.h). */
static sooc_status store_queue(sooc_node *n, const sooc_map_entry *chg, size_t nc, const uint64_t *rem, size_t nr,
                               int to_db, const sooc_kf_info *kf, size_t n_entries) {
    sooc_status st = SOOC_OK;
    for (size_t i = 0; i < nc && !st && to_db; i++) st = sooc_sg_put(n->sg, &chg[i]);
    for (size_t i = 0; i < nr && !st; i++) st = sooc_sg_remove(n->sg, rem[i]);
    if (!st && !n->extent_stored && nc && chg[0].extent[0] > 0) {
        char b[96];
        snprintf(b, sizeof b, "%.9g %.9g %.9g", chg[0].extent[0], chg[0].extent[1], chg[0].extent[2]);
        if (!(st = sooc_sg_meta(n->sg, "extent", b))) {
            memcpy(n->extent, chg[0].extent, sizeof n->extent);
            n->extent_stored = 1;
        }
    }
    if (!st && kf && n->store_layout_dim) {
        int32_t bi = 0, bj = 0;
        float mu[SOOC_MAP_LATENT_MAX], lv[SOOC_MAP_LATENT_MAX];
        sooc_status s2 = sooc_mapper_last_layout(n->mapper, &bi, &bj, mu, lv);
        if (!s2) st = sooc_sg_layout(n->sg, bi, bj, mu, lv);
        else if (s2 != SOOC_ENOTFOUND) st = s2;
    }
    if (!st) sooc_sg_next_id(n->sg, sooc_mapper_next_id(n->mapper));
    if (!st && kf) {
        sooc_sg_row r;
        memset(&r, 0, sizeof r);
        r.t_ns = kf->stamp_ns;
        r.view = (int32_t)n->kf_seq++;
        memcpy(r.T_wc, kf->T_wc, sizeof r.T_wc);
        r.n_changed = (uint32_t)(nc < SOOC_MAPPER_CHANGED_MAX ? nc : SOOC_MAPPER_CHANGED_MAX);
        r.n_removed = (uint32_t)nr;
        r.n_entries = (int64_t)n_entries;
        sooc_sg_row_add(n->sg, &r);
    }
    if (!st) st = sooc_sg_flush(n->sg, sooc_seconds(), 0);
    store_sync(n);
    return st;
}

sooc_status sooc__node_publish(sooc_node *n, const sooc_map_entry *chg, size_t nc, const uint64_t *rem, size_t nr,
                           int clear_first, int to_db, const sooc_kf_info *kf) {
    sooc_status st = SOOC_OK;
    double t0 = sooc_seconds();
    size_t n_entries = 0;
    if ((st = sooc_mapper_entries(n->mapper, NULL, 0, &n_entries))) return sooc_adderr(st, "mapper entries");
    if (n->table) {
        int rc = sooc_table_begin_batch(n->table);
        if (clear_first && !rc) rc = sooc_table_clear(n->table);
        uint32_t ld = (uint32_t)sooc_mapper_latent_dim(n->mapper);
        double T_src_map[16];
        sooc_se3_inverse(T_src_map, n->T_world_src);
        /* T_src_map (and HFLAG_FLOOR_SET) only once the world frame is known:
         * given, stored, or estimated; not the identity placeholder before an estimate */
        if (!rc)
            rc = sooc_table_set_meta(n->table, ld, n->model_id, kf ? kf->stamp_ns : 0,
                                     n->world_ready ? T_src_map : NULL);
        for (size_t i = 0; i < nc && !rc; i++) {
            sooc_table_record r;
            sooc_node_table_record(&chg[i], &r);
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
    if (kf && kf->t_cap_mono > 0) {
        double ms = (double)(sooc_now_ns() - kf->t_cap_mono) * 1e-6;
        pthread_mutex_lock(&n->mu);
        sooc_latency_add(&n->lat_c2t, ms);
        pthread_mutex_unlock(&n->mu);
    }
    if (!st && n->sg && (kf || (to_db && (nc || nr)))) st = store_queue(n, chg, nc, rem, nr, to_db, kf, n_entries);
    double ms = (sooc_seconds() - t0) * 1e3;
    pthread_mutex_lock(&n->mu);
    if (kf) sooc_latency_add(&n->lat_pub, ms);
    n->st.published += nc;
    n->st.removed += nr;
    n->st.n_objects = n_entries;
    pthread_mutex_unlock(&n->mu);
    return st;
}

/* Publish what the last update changed (sooc_mapper_changed): O(changes). */
sooc_status sooc__node_publish_keyframe(sooc_node *n, int64_t stamp_ns, const double T_wc[16], int64_t t_cap) {
    size_t nc = 0, nr = 0;
    sooc_status st = sooc_mapper_changed(n->mapper, n->changed, SOOC_MAPPER_CHANGED_MAX, &nc, n->removed,
                                           SOOC_MAPPER_CHANGED_MAX, &nr);
    if (st) return sooc_adderr(st, "mapper changed");
    sooc_kf_info kf = {stamp_ns, T_wc, t_cap};
    st = sooc__node_publish(n, n->changed, nc, n->removed, nr, 0, 1, &kf);
    pthread_mutex_lock(&n->mu);
    sooc__node_stats_refresh(n);
    sooc_node_stats snap = n->st;
    pthread_mutex_unlock(&n->mu);
    if (n->opt.on_keyframe)
        n->opt.on_keyframe(n->opt.user, snap.keyframes + 1, n->changed, nc, n->removed, nr, &snap);
    return st;
}

sooc_status sooc__node_store_world(sooc_node *n, const sooc_map_frame *mf) {
    if (!n->sg) return SOOC_OK;
    sooc_sg_world(n->sg, mf);
    sooc_status st = sooc_sg_flush(n->sg, sooc_seconds(), 0);
    store_sync(n);
    return st ? sooc_adderr(st, "%s: map.db: storing the world frame", n->cfg.path) : SOOC_OK;
}

/* Retry the map store when it failed and its backoff has passed (force: now). */
sooc_status sooc__node_store_retry(sooc_node *n, int force) {
    if (!n->sg || !sooc_sg_pending(n->sg)) return SOOC_OK;
    sooc_status st = sooc_sg_flush(n->sg, sooc_seconds(), force);
    store_sync(n);
    return st;
}

/* The end of a run: one last try to write what waits; what still cannot be
 * written is named (the run itself succeeded: exit 0). */
sooc_status sooc__node_store_final(sooc_node *n, sooc_status result) {
    if (!n->sg || !sooc_sg_pending(n->sg)) return result;
    char saved[1024];
    snprintf(saved, sizeof saved, "%s", sooc_errmsg());
    sooc_status st = sooc__node_store_retry(n, 1);
    if (result) sooc_seterr(result, "%s", saved);   /* the flush must not hide the run's own error */
    else result = st;
    sooc_sg_status s;
    sooc_sg_status_get(n->sg, &s);
    char upto[96] = "no keyframe of this run";
    if (s.committed_ns != INT64_MIN) snprintf(upto, sizeof upto, "the keyframes up to stamp %lld ns", (long long)s.committed_ns);
    if (s.state == SOOC_NODE_STORE_FAILING)
        sooc_log(SOOC_LOG_ERROR,
                 "node: map store still failing at the end of the run: %s. %llu objects and %llu keyframes of this "
                 "run are not in the database; it holds %s (and what earlier runs committed)",
                 sooc_sg_reason(n->sg), (unsigned long long)s.pending, (unsigned long long)s.pending_kf, upto);
    return result;
}

sooc_status sooc__node_store_resume(sooc_node *n, int *resumed) {
    const sooc_node_config *c = &n->cfg;
    sooc_status st = SOOC_OK;
    *resumed = 0;
    n->db_exists = c->map_db[0] && sooc_file_exists(c->map_db);
    int empty = 0;   /* a file left by a creation that failed (full disk): created anew */
    if (n->db_exists && !sooc_mapstore_file_empty(c->map_db, &empty) && empty) n->db_exists = 0;
    sooc_clearerr();
    if (n->db_exists) {
        if ((st = store_guard(n, 0))) return st;
        sooc_mapstore_info info;
        if ((st = sooc_mapstore_info_get(n->store, &info))) return st;
        if (!c->map_resume && info.n_entries > 0) {
            st = sooc_seterr(SOOC_EINVAL,
                             "%s: map.resume: false, but %s already holds %llu entries (remove it or resume)",
                             c->path, c->map_db, (unsigned long long)info.n_entries);
            return st;
        }
        load_ctx L = {n, SOOC_OK};
        if ((st = sooc_mapstore_foreach(n->store, load_visit, &L)) || (st = L.st)) {
            return sooc_adderr(st, "%s: resume from %s", c->path, c->map_db);
        }
        for (size_t i = 0; i < n->n_prev; i++) {   /* stored object geometry (schema 3; none in older maps) */
            int found = 0;
            if ((st = sooc_mapstore_geom_get(n->store, n->prev[i].id, n->prev[i].extent, &n->prev[i].geom, &found))) {
                sooc_adderr(st, "%s: resume from %s", c->path, c->map_db);
                return st;
            }
        }
        if (n->n_prev && (st = sooc_mapper_load_entries(n->mapper, n->prev, n->n_prev))) {
            sooc_adderr(st, "%s: resume: mapper refused %zu stored entries", c->path, n->n_prev);
            return st;
        }
        load_ctx_l LB = {n, SOOC_OK, 0};
        if (n->store_layout_dim &&
            ((st = sooc_mapstore_foreach_layout(n->store, load_block, &LB)) || (st = LB.st))) {
            sooc_adderr(st, "%s: resume: layout blocks from %s", c->path, c->map_db);
            return st;
        }
        /* ids of entries removed before the restart are not handed out again */
        sooc_mapper_reserve_ids(n->mapper, info.next_id);
        n->st.resumed = n->n_prev;
        n->st.resumed_blocks = LB.count;
        *resumed = 1;
    } else if (c->map_db[0]) {
        if ((st = store_guard(n, 1))) return st;
    }
    return st;
}
