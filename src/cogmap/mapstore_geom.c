/* Object geometry in the map database (schema version 3;
 * include/sooc3d/cogmap.h "object geometry"). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cogmap/mapstore_impl.h"

const char *const sooc__mapstore_geom_schema =
    "CREATE TABLE IF NOT EXISTS entry_geometry(id INTEGER PRIMARY KEY, flags INTEGER NOT NULL,"
    " ext_x REAL NOT NULL, ext_y REAL NOT NULL, ext_z REAL NOT NULL,"
    " centre_x REAL NOT NULL, centre_y REAL NOT NULL, centre_z REAL NOT NULL, sym_score REAL NOT NULL,"
    " cov_xx REAL NOT NULL, cov_xz REAL NOT NULL, cov_zz REAL NOT NULL, var_yaw REAL,"
    " reg_n INTEGER NOT NULL, reg_mean_x REAL NOT NULL, reg_mean_z REAL NOT NULL,"
    " reg_m2_xx REAL NOT NULL, reg_m2_xz REAL NOT NULL, reg_m2_zz REAL NOT NULL,"
    " reg_cos REAL NOT NULL, reg_sin REAL NOT NULL);"
    "CREATE TRIGGER IF NOT EXISTS entries_ad_geom AFTER DELETE ON entries BEGIN"
    " DELETE FROM entry_geometry WHERE id = old.id; END;";

#define GEOM_COLS                                                                                          \
    "id, flags, ext_x, ext_y, ext_z, centre_x, centre_y, centre_z, sym_score, cov_xx, cov_xz, cov_zz, "   \
    "var_yaw, reg_n, reg_mean_x, reg_mean_z, reg_m2_xx, reg_m2_xz, reg_m2_zz, reg_cos, reg_sin"

static sooc_status gerr(sooc_mapstore *s, int rc, const char *what) { return sooc__mapstore_dberr(s, rc, what); }

/* 1 if the map has the geometry table (schema >= 3, or a read-only older map: 0) */
static int has_table(sooc_mapstore *s) {
    sqlite3_stmt *q = NULL;
    int ok = sqlite3_prepare_v2(sooc__mapstore_db(s),
                                "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'entry_geometry'", -1, &q,
                                NULL) == SQLITE_OK &&
             sqlite3_step(q) == SQLITE_ROW;
    sqlite3_finalize(q);
    return ok;
}

sooc_status sooc_mapstore_geom_put(sooc_mapstore *s, uint64_t id, const float extent[3], const sooc_map_geometry *g) {
    if (sooc__mapstore_readonly(s)) return sooc_seterr(SOOC_EINVAL, "%s: read-only map", sooc_mapstore_path(s));
    double v[19] = {extent[0],     extent[1],     extent[2],     g->centre[0],  g->centre[1], g->centre[2],
                    g->sym_iou,    g->cov_xz[0],  g->cov_xz[1],  g->cov_xz[2],  g->var_yaw,   (double)g->reg_n,
                    g->reg_mean[0], g->reg_mean[1], g->reg_m2[0], g->reg_m2[1], g->reg_m2[2], g->reg_cs[0],
                    g->reg_cs[1]};
    for (int i = 0; i < 19; i++)
        if (i != 10 && !isfinite(v[i]))
            return sooc_seterr(SOOC_ENUMERIC, "%s: geometry of entry %llu: value %d not finite", sooc_mapstore_path(s),
                               (unsigned long long)id, i);
    if (!has_table(s))
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: map schema without object geometry", sooc_mapstore_path(s));
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(sooc__mapstore_db(s),
                                "INSERT OR REPLACE INTO entry_geometry(" GEOM_COLS ") VALUES(?1,?2,?3,?4,?5,?6,?7,?8,"
                                "?9,?10,?11,?12,?13,?14,?15,?16,?17,?18,?19,?20,?21)",
                                -1, &q, NULL);
    if (rc != SQLITE_OK) return gerr(s, rc, "storing object geometry");
    sqlite3_bind_int64(q, 1, (sqlite3_int64)id);
    sqlite3_bind_int64(q, 2, (sqlite3_int64)g->flags);
    for (int i = 0; i < 19; i++) {
        if (i == 11) sqlite3_bind_int64(q, 14, (sqlite3_int64)g->reg_n);
        else if (i == 10 && !isfinite(v[i])) sqlite3_bind_null(q, 13);   /* yaw variance undefined */
        else sqlite3_bind_double(q, 3 + i, v[i]);
    }
    rc = sqlite3_step(q);
    sqlite3_finalize(q);
    return rc == SQLITE_DONE ? SOOC_OK : gerr(s, rc, "storing object geometry");
}

sooc_status sooc_mapstore_geom_get(sooc_mapstore *s, uint64_t id, float extent[3], sooc_map_geometry *g, int *found) {
    *found = 0;
    if (!has_table(s)) return SOOC_OK;
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(sooc__mapstore_db(s), "SELECT " GEOM_COLS " FROM entry_geometry WHERE id = ?1", -1,
                                &q, NULL);
    if (rc != SQLITE_OK) return gerr(s, rc, "reading object geometry");
    sqlite3_bind_int64(q, 1, (sqlite3_int64)id);
    rc = sqlite3_step(q);
    if (rc == SQLITE_ROW) {
        memset(g, 0, sizeof *g);
        g->flags = (uint32_t)sqlite3_column_int64(q, 1);
        for (int a = 0; a < 3; a++) {
            extent[a] = (float)sqlite3_column_double(q, 2 + a);
            g->centre[a] = (float)sqlite3_column_double(q, 5 + a);
        }
        g->sym_iou = (float)sqlite3_column_double(q, 8);
        for (int a = 0; a < 3; a++) g->cov_xz[a] = sqlite3_column_double(q, 9 + a);
        g->var_yaw = sqlite3_column_type(q, 12) == SQLITE_NULL ? NAN : sqlite3_column_double(q, 12);
        sqlite3_int64 n = sqlite3_column_int64(q, 13);
        g->reg_n = n < 0 ? 0 : n > (sqlite3_int64)UINT32_MAX ? UINT32_MAX : (uint32_t)n;
        g->reg_mean[0] = sqlite3_column_double(q, 14);
        g->reg_mean[1] = sqlite3_column_double(q, 15);
        for (int a = 0; a < 3; a++) g->reg_m2[a] = sqlite3_column_double(q, 16 + a);
        g->reg_cs[0] = sqlite3_column_double(q, 19);
        g->reg_cs[1] = sqlite3_column_double(q, 20);
        *found = 1;
        rc = SQLITE_DONE;
    }
    sqlite3_finalize(q);
    return rc == SQLITE_DONE ? SOOC_OK : gerr(s, rc, "reading object geometry");
}
