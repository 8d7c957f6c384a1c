/* Internal: what the files of the map store share (mapstore_db.c: the
 * connection and errors; mapstore_read.c: entry reads; mapstore.c: open,
 * schema, writes). */
#ifndef SOOC3D_MAPSTORE_IMPL_H
#define SOOC3D_MAPSTORE_IMPL_H

#include <sqlite3.h>

#include "sooc3d/cogmap.h"

/* The entry columns in the order row readers expect (mapstore_read.c). */
#define ENTRY_COLS                                                                                         \
    "id, x, z, yaw, rho_t, rho_yaw, pres_logit, dim, latent_version, what_mu, what_logvar, first_seen_ns, " \
    "last_seen_ns, obs_count, last_view"

enum {
    ST_PUT_ENTRY, ST_DEL_ENTRY, ST_PUT_LAYOUT, ST_PUT_META, ST_ADD_KF, ST_GET_ENTRY, ST_COUNT
};

struct sooc_mapstore {
    sqlite3 *db;
    char *path;
    int readonly, in_txn;
    int dim, layout_dim;
    int schema;           /* stored schema version (1: no finetuned decoders, read-only open of an old map) */
    int last_rc;          /* SQLite result of the last failed call (0 after a begin); sooc_mapstore_last_fault */
    sqlite3_stmt *st[ST_COUNT];
};

/* The store's connection, path, read-only flag and stored schema version. */
sqlite3 *sooc__mapstore_db(sooc_mapstore *s);
int sooc__mapstore_readonly(const sooc_mapstore *s);

/* The status for SQLite result rc, with the message "<path>: <what>: <SQLite's
 * reason>"; remembers rc for sooc_mapstore_last_fault. */
sooc_status sooc__mapstore_dberr(sooc_mapstore *s, int rc, const char *what);
/* Remember the fault of an open that fails (NULL: none) for
 * sooc_mapstore_open_fault. */
void sooc__mapstore_note_open(const sooc_mapstore *s);
/* sqlite3_exec of sql (no rows), failures through sooc__mapstore_dberr. */
sooc_status sooc__mapstore_exec(sooc_mapstore *s, const char *sql, const char *what);
/* Step a statement to its end (rows ignored), then reset and clear it. */
sooc_status sooc__mapstore_step_done(sooc_mapstore *s, sqlite3_stmt *st, const char *what);

/* Schema version 2 (mapstore_ft.c): the finetuned-decoder tables and their
 * delete trigger; executed on creation and by the 1 -> 2 migration. */
extern const char *const sooc__mapstore_ft_schema;
/* Every stored decoder (of an entry the map holds) into the map's payloads. */
sooc_status sooc__mapstore_ft_load(sooc_mapstore *s, sooc_cogmap *map);
/* Inside save_map's transaction: the map's payloads replace the stored decoders. */
sooc_status sooc__mapstore_ft_save(sooc_mapstore *s, const sooc_cogmap *map);

/* Schema version 3 (mapstore_geom.c): the object geometry table and its
 * delete trigger; executed on creation and by the 2 -> 3 migration. */
extern const char *const sooc__mapstore_geom_schema;

#endif
