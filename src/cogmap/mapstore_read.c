/* Reading entries from the map store (include/sooc3d/cogmap.h): one entry
 * by id, every entry, and the entries in a box (through the R*Tree). */
#include "sooc3d/cogmap.h"
#include "cogmap/mapstore_impl.h"

#include <sqlite3.h>
#include <stdio.h>
#include <string.h>

/* -------------------------------------------------------------- reads */

static sooc_status row_to_entry(sooc_mapstore *s, sqlite3_stmt *q, sooc_cogmap_entry *e) {
    memset(e, 0, sizeof *e);
    e->id = (uint64_t)sqlite3_column_int64(q, 0);
    e->X = sqlite3_column_double(q, 1);
    e->Z = sqlite3_column_double(q, 2);
    e->Theta = sqlite3_column_double(q, 3);
    e->rho_t = (float)sqlite3_column_double(q, 4);
    e->rho_theta = (float)sqlite3_column_double(q, 5);
    e->pres_logit = (float)sqlite3_column_double(q, 6);
    e->dim = sqlite3_column_int(q, 7);
    int ver = sqlite3_column_int(q, 8);
    if (e->dim != s->dim)
        return sooc_seterr(SOOC_EFORMAT, "%s: entry %llu has dim %d, map has %d", s->path, (unsigned long long)e->id,
                           e->dim, s->dim);
    if (ver != SOOC_MAPSTORE_LATENT_VERSION)
        return sooc_seterr(SOOC_EVERSION, "%s: entry %llu latent version %d, this build reads %d", s->path,
                           (unsigned long long)e->id, ver, SOOC_MAPSTORE_LATENT_VERSION);
    size_t nb = (size_t)e->dim * sizeof(float);
    const void *mu = sqlite3_column_blob(q, 9);
    int nmu = sqlite3_column_bytes(q, 9);
    const void *lv = sqlite3_column_blob(q, 10);
    int nlv = sqlite3_column_bytes(q, 10);
    if ((size_t)nmu != nb || (size_t)nlv != nb || (nb && (!mu || !lv)))
        return sooc_seterr(SOOC_EFORMAT, "%s: entry %llu latent blobs have %d / %d bytes, expected %zu", s->path,
                           (unsigned long long)e->id, nmu, nlv, nb);
    if (nb) {
        memcpy(e->what_mu, mu, nb);
        memcpy(e->what_logvar, lv, nb);
    }
    e->first_seen_ns = sqlite3_column_int64(q, 11);
    e->last_seen_ns = sqlite3_column_int64(q, 12);
    e->obs_count = (uint32_t)sqlite3_column_int64(q, 13);
    e->last_view = sqlite3_column_int(q, 14);
    return SOOC_OK;
}

static sooc_status walk(sooc_mapstore *s, const char *sql, const double *box, sooc_cogmap_visit_fn fn, void *user) {
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(s->db, sql, -1, &q, NULL);
    if (rc != SQLITE_OK) return sooc__mapstore_dberr(s, rc, "reading entries");
    if (box)
        for (int i = 0; i < 4; i++) sqlite3_bind_double(q, i + 1, box[i]);
    sooc_status st = SOOC_OK;
    while ((rc = sqlite3_step(q)) == SQLITE_ROW) {
        sooc_cogmap_entry e;
        if ((st = row_to_entry(s, q, &e))) break;
        if (fn(user, &e)) break;
    }
    if (!st && rc != SQLITE_ROW && rc != SQLITE_DONE) st = sooc__mapstore_dberr(s, rc, "reading entries");
    sqlite3_finalize(q);
    return st;
}

sooc_status sooc_mapstore_foreach(sooc_mapstore *s, sooc_cogmap_visit_fn fn, void *user) {
    return walk(s, "SELECT " ENTRY_COLS " FROM entries ORDER BY id", NULL, fn, user);
}

sooc_status sooc_mapstore_query_box(sooc_mapstore *s, double x0, double z0, double x1, double z1,
                                    sooc_cogmap_visit_fn fn, void *user) {
    if (!(x0 <= x1) || !(z0 <= z1))
        return sooc_seterr(SOOC_EINVAL, "%s: bad box [%g, %g] x [%g, %g]", s->path, x0, x1, z0, z1);
    double box[4] = {x0, z0, x1, z1};
    /* the R*Tree stores float32 bounds rounded outwards: it selects a superset,
     * the exact test on entries.x / entries.z then filters it */
    return walk(s,
                "SELECT e.id, e.x, e.z, e.yaw, e.rho_t, e.rho_yaw, e.pres_logit, e.dim, e.latent_version, "
                "e.what_mu, e.what_logvar, e.first_seen_ns, e.last_seen_ns, e.obs_count, e.last_view "
                "FROM entries_rtree r JOIN entries e ON e.id = r.id "
                "WHERE r.max_x >= ?1 AND r.min_x <= ?3 AND r.max_z >= ?2 AND r.min_z <= ?4 "
                "AND e.x >= ?1 AND e.x <= ?3 AND e.z >= ?2 AND e.z <= ?4 ORDER BY e.id",
                box, fn, user);
}

sooc_status sooc_mapstore_get(sooc_mapstore *s, uint64_t id, sooc_cogmap_entry *out) {
    sqlite3_stmt *q = s->st[ST_GET_ENTRY];
    sqlite3_bind_int64(q, 1, (sqlite3_int64)id);
    int rc = sqlite3_step(q);
    sooc_status st;
    if (rc == SQLITE_ROW) st = row_to_entry(s, q, out);
    else if (rc == SQLITE_DONE) st = sooc_seterr(SOOC_ENOTFOUND, "%s: no entry %llu", s->path, (unsigned long long)id);
    else st = sooc__mapstore_dberr(s, rc, "reading an entry");
    sqlite3_reset(q);
    sqlite3_clear_bindings(q);
    return st;
}
