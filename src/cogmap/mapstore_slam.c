/* The SLAM keyframe tables of the map database
 * (include/sooc3d/cogmap.h). */
#include <math.h>
#include <string.h>

#include "cogmap/mapstore_impl.h"
#include "sooc3d/cogmap.h"

static const char *const slam_schema =
    "CREATE TABLE IF NOT EXISTS slam_keyframes(id INTEGER PRIMARY KEY, run INTEGER NOT NULL,"
    " frame INTEGER NOT NULL, t_ns INTEGER NOT NULL, pose BLOB NOT NULL, feat BLOB, depth BLOB);"
    "CREATE TABLE IF NOT EXISTS slam_edges(a INTEGER NOT NULL, b INTEGER NOT NULL, kind INTEGER NOT NULL,"
    " rel BLOB NOT NULL, w_t REAL NOT NULL, w_r REAL NOT NULL, PRIMARY KEY(a, b, kind));";

static int has_tables(sooc_mapstore *s) {
    sqlite3_stmt *q = NULL;
    int ok = sqlite3_prepare_v2(sooc__mapstore_db(s),
                                "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name IN "
                                "('slam_keyframes', 'slam_edges')",
                                -1, &q, NULL) == SQLITE_OK &&
             sqlite3_step(q) == SQLITE_ROW && sqlite3_column_int(q, 0) == 2;
    sqlite3_finalize(q);
    return ok;
}

static sooc_status ensure(sooc_mapstore *s) {
    if (sooc__mapstore_readonly(s)) return sooc_seterr(SOOC_EINVAL, "%s: read-only map", sooc_mapstore_path(s));
    if (has_tables(s)) return SOOC_OK;
    return sooc__mapstore_exec(s, slam_schema, "creating the SLAM keyframe tables");
}

static void pose_to_le(const double T[16], unsigned char out[128]) {
    for (int i = 0; i < 16; i++) {
        uint64_t u;
        memcpy(&u, &T[i], 8);
        for (int b = 0; b < 8; b++) out[8 * i + b] = (unsigned char)(u >> (8 * b));
    }
}

static int pose_from_le(const void *blob, int bytes, double T[16]) {
    if (!blob || bytes != 128) return 0;
    const unsigned char *p = blob;
    for (int i = 0; i < 16; i++) {
        uint64_t u = 0;
        for (int b = 0; b < 8; b++) u |= (uint64_t)p[8 * i + b] << (8 * b);
        memcpy(&T[i], &u, 8);
        if (!isfinite(T[i])) return 0;
    }
    return 1;
}

static int pose_finite(const double T[16]) {
    for (int i = 0; i < 16; i++)
        if (!isfinite(T[i])) return 0;
    return 1;
}

/* run fn inside the open transaction or a new one */
static sooc_status wrap_begin(sooc_mapstore *s, int *own) {
    *own = 0;
    if (s->in_txn) return SOOC_OK;
    sooc_status st = sooc_mapstore_begin(s);
    if (!st) *own = 1;
    return st;
}

static sooc_status wrap_end(sooc_mapstore *s, int own, sooc_status st) {
    if (!own) return st;
    if (st) {
        sooc_mapstore_rollback(s);
        return st;
    }
    return sooc_mapstore_commit(s);
}

sooc_status sooc_mapstore_slam_put_keyframe(sooc_mapstore *s, const sooc_slamdb_kf *kf) {
    if (!pose_finite(kf->T_wc))
        return sooc_seterr(SOOC_ENUMERIC, "%s: SLAM keyframe %lld: pose not finite", sooc_mapstore_path(s),
                           (long long)kf->id);
    int own;
    sooc_status st = wrap_begin(s, &own);
    if (st) return st;
    if ((st = ensure(s))) return wrap_end(s, own, st);
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(sooc__mapstore_db(s),
                                "INSERT OR REPLACE INTO slam_keyframes(id, run, frame, t_ns, pose, feat, depth) "
                                "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                                -1, &q, NULL);
    if (rc != SQLITE_OK) return wrap_end(s, own, sooc__mapstore_dberr(s, rc, "storing a SLAM keyframe"));
    unsigned char pose[128];
    pose_to_le(kf->T_wc, pose);
    sqlite3_bind_int64(q, 1, kf->id);
    sqlite3_bind_int64(q, 2, kf->run);
    sqlite3_bind_int64(q, 3, kf->frame);
    sqlite3_bind_int64(q, 4, kf->t_ns);
    sqlite3_bind_blob(q, 5, pose, 128, SQLITE_TRANSIENT);
    if (kf->feat) sqlite3_bind_blob64(q, 6, kf->feat, kf->feat_bytes, SQLITE_STATIC);
    else sqlite3_bind_null(q, 6);
    if (kf->depth) sqlite3_bind_blob64(q, 7, kf->depth, kf->depth_bytes, SQLITE_STATIC);
    else sqlite3_bind_null(q, 7);
    rc = sqlite3_step(q);
    sqlite3_finalize(q);
    st = rc == SQLITE_DONE ? SOOC_OK : sooc__mapstore_dberr(s, rc, "storing a SLAM keyframe");
    return wrap_end(s, own, st);
}

sooc_status sooc_mapstore_slam_put_edge(sooc_mapstore *s, const sooc_slamdb_edge *e) {
    if (!pose_finite(e->T_ab) || !(e->w_t > 0 && e->w_r > 0 && isfinite(e->w_t) && isfinite(e->w_r)))
        return sooc_seterr(SOOC_ENUMERIC, "%s: SLAM edge %lld-%lld: pose or weights invalid", sooc_mapstore_path(s),
                           (long long)e->a, (long long)e->b);
    int own;
    sooc_status st = wrap_begin(s, &own);
    if (st) return st;
    if ((st = ensure(s))) return wrap_end(s, own, st);
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(sooc__mapstore_db(s),
                                "INSERT OR REPLACE INTO slam_edges(a, b, kind, rel, w_t, w_r) "
                                "VALUES(?1, ?2, ?3, ?4, ?5, ?6)",
                                -1, &q, NULL);
    if (rc != SQLITE_OK) return wrap_end(s, own, sooc__mapstore_dberr(s, rc, "storing a SLAM edge"));
    unsigned char rel[128];
    pose_to_le(e->T_ab, rel);
    sqlite3_bind_int64(q, 1, e->a);
    sqlite3_bind_int64(q, 2, e->b);
    sqlite3_bind_int64(q, 3, e->kind);
    sqlite3_bind_blob(q, 4, rel, 128, SQLITE_TRANSIENT);
    sqlite3_bind_double(q, 5, e->w_t);
    sqlite3_bind_double(q, 6, e->w_r);
    rc = sqlite3_step(q);
    sqlite3_finalize(q);
    st = rc == SQLITE_DONE ? SOOC_OK : sooc__mapstore_dberr(s, rc, "storing a SLAM edge");
    return wrap_end(s, own, st);
}

sooc_status sooc_mapstore_slam_set_poses(sooc_mapstore *s, const int64_t *ids, const double *T_wc, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (!pose_finite(T_wc + 16 * i))
            return sooc_seterr(SOOC_ENUMERIC, "%s: SLAM keyframe %lld: pose not finite", sooc_mapstore_path(s),
                               (long long)ids[i]);
    int own;
    sooc_status st = wrap_begin(s, &own);
    if (st) return st;
    if ((st = ensure(s))) return wrap_end(s, own, st);
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(sooc__mapstore_db(s), "UPDATE slam_keyframes SET pose = ?2 WHERE id = ?1", -1, &q,
                                NULL);
    if (rc != SQLITE_OK) return wrap_end(s, own, sooc__mapstore_dberr(s, rc, "updating SLAM keyframe poses"));
    for (size_t i = 0; i < n && !st; i++) {
        unsigned char pose[128];
        pose_to_le(T_wc + 16 * i, pose);
        sqlite3_bind_int64(q, 1, ids[i]);
        sqlite3_bind_blob(q, 2, pose, 128, SQLITE_TRANSIENT);
        rc = sqlite3_step(q);
        if (rc != SQLITE_DONE) st = sooc__mapstore_dberr(s, rc, "updating SLAM keyframe poses");
        sqlite3_reset(q);
        sqlite3_clear_bindings(q);
    }
    sqlite3_finalize(q);
    return wrap_end(s, own, st);
}

sooc_status sooc_mapstore_slam_foreach_keyframe(sooc_mapstore *s, sooc_slamdb_kf_fn fn, void *user) {
    if (!has_tables(s)) return SOOC_OK;
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(sooc__mapstore_db(s),
                                "SELECT id, run, frame, t_ns, pose, feat, depth FROM slam_keyframes ORDER BY id", -1,
                                &q, NULL);
    if (rc != SQLITE_OK) return sooc__mapstore_dberr(s, rc, "reading SLAM keyframes");
    sooc_status st = SOOC_OK;
    while ((rc = sqlite3_step(q)) == SQLITE_ROW) {
        sooc_slamdb_kf k;
        memset(&k, 0, sizeof k);
        k.id = sqlite3_column_int64(q, 0);
        k.run = (int32_t)sqlite3_column_int64(q, 1);
        k.frame = sqlite3_column_int64(q, 2);
        k.t_ns = sqlite3_column_int64(q, 3);
        if (!pose_from_le(sqlite3_column_blob(q, 4), sqlite3_column_bytes(q, 4), k.T_wc)) {
            st = sooc_seterr(SOOC_EFORMAT, "%s: SLAM keyframe %lld: bad pose record", sooc_mapstore_path(s),
                             (long long)k.id);
            break;
        }
        k.feat = sqlite3_column_blob(q, 5);
        k.feat_bytes = (size_t)sqlite3_column_bytes(q, 5);
        k.depth = sqlite3_column_blob(q, 6);
        k.depth_bytes = (size_t)sqlite3_column_bytes(q, 6);
        if (fn(&k, user)) break;
    }
    if (!st && rc != SQLITE_ROW && rc != SQLITE_DONE) st = sooc__mapstore_dberr(s, rc, "reading SLAM keyframes");
    sqlite3_finalize(q);
    return st;
}

sooc_status sooc_mapstore_slam_foreach_edge(sooc_mapstore *s, sooc_slamdb_edge_fn fn, void *user) {
    if (!has_tables(s)) return SOOC_OK;
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(sooc__mapstore_db(s),
                                "SELECT a, b, kind, rel, w_t, w_r FROM slam_edges ORDER BY rowid", -1, &q, NULL);
    if (rc != SQLITE_OK) return sooc__mapstore_dberr(s, rc, "reading SLAM edges");
    sooc_status st = SOOC_OK;
    while ((rc = sqlite3_step(q)) == SQLITE_ROW) {
        sooc_slamdb_edge e;
        e.a = sqlite3_column_int64(q, 0);
        e.b = sqlite3_column_int64(q, 1);
        e.kind = (int32_t)sqlite3_column_int64(q, 2);
        e.w_t = sqlite3_column_double(q, 4);
        e.w_r = sqlite3_column_double(q, 5);
        if (!pose_from_le(sqlite3_column_blob(q, 3), sqlite3_column_bytes(q, 3), e.T_ab)) {
            st = sooc_seterr(SOOC_EFORMAT, "%s: SLAM edge %lld-%lld: bad pose record", sooc_mapstore_path(s),
                             (long long)e.a, (long long)e.b);
            break;
        }
        if (fn(&e, user)) break;
    }
    if (!st && rc != SQLITE_ROW && rc != SQLITE_DONE) st = sooc__mapstore_dberr(s, rc, "reading SLAM edges");
    sqlite3_finalize(q);
    return st;
}

sooc_status sooc_mapstore_slam_count(sooc_mapstore *s, int64_t *n_keyframes, int64_t *n_edges, int32_t *max_run) {
    *n_keyframes = *n_edges = 0;
    *max_run = -1;
    if (!has_tables(s)) return SOOC_OK;
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(sooc__mapstore_db(s),
                                "SELECT (SELECT count(*) FROM slam_keyframes), (SELECT count(*) FROM slam_edges), "
                                "(SELECT coalesce(max(run), -1) FROM slam_keyframes)",
                                -1, &q, NULL);
    if (rc == SQLITE_OK && (rc = sqlite3_step(q)) == SQLITE_ROW) {
        *n_keyframes = sqlite3_column_int64(q, 0);
        *n_edges = sqlite3_column_int64(q, 1);
        *max_run = (int32_t)sqlite3_column_int64(q, 2);
        rc = SQLITE_DONE;
    }
    sqlite3_finalize(q);
    return rc == SQLITE_DONE ? SOOC_OK : sooc__mapstore_dberr(s, rc, "counting SLAM keyframes");
}
