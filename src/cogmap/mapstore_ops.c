/* Storage faults and maintenance of the map database
 * (include/sooc3d/cogmap.h "storage faults"): what the last failure met,
 * the lock wait, WAL checkpoints and SQLite's integrity check. */
#include <stdio.h>
#include <string.h>

#include "cogmap/mapstore_impl.h"

static _Thread_local int g_open_rc;   /* SQLite result of this thread's last failed open */

static sooc_mapstore_fault fault_of(int rc) {
    if (!rc) return SOOC_MAPSTORE_FAULT_NONE;
    switch (rc & 0xff) {
    case SQLITE_FULL: return SOOC_MAPSTORE_FAULT_FULL;
    case SQLITE_IOERR:
    case SQLITE_CANTOPEN:
    case SQLITE_READONLY:
    case SQLITE_PROTOCOL: return SOOC_MAPSTORE_FAULT_IO;
    case SQLITE_BUSY:
    case SQLITE_LOCKED: return SOOC_MAPSTORE_FAULT_BUSY;
    case SQLITE_CORRUPT:
    case SQLITE_NOTADB: return SOOC_MAPSTORE_FAULT_CORRUPT;
    case SQLITE_NOMEM: return SOOC_MAPSTORE_FAULT_NOMEM;
    default: return SOOC_MAPSTORE_FAULT_OTHER;
    }
}

sooc_mapstore_fault sooc_mapstore_last_fault(const sooc_mapstore *s) { return s ? fault_of(s->last_rc) : SOOC_MAPSTORE_FAULT_NONE; }

void sooc__mapstore_note_open(const sooc_mapstore *s) { g_open_rc = s ? s->last_rc : 0; }

sooc_mapstore_fault sooc_mapstore_open_fault(void) { return fault_of(g_open_rc); }

const char *sooc_mapstore_fault_name(sooc_mapstore_fault f) {
    switch (f) {
    case SOOC_MAPSTORE_FAULT_NONE: return "none";
    case SOOC_MAPSTORE_FAULT_FULL: return "disk full";
    case SOOC_MAPSTORE_FAULT_IO: return "I/O error";
    case SOOC_MAPSTORE_FAULT_BUSY: return "locked by another connection";
    case SOOC_MAPSTORE_FAULT_CORRUPT: return "corrupt";
    case SOOC_MAPSTORE_FAULT_NOMEM: return "out of memory";
    default: return "other SQLite error";
    }
}

sooc_status sooc_mapstore_file_empty(const char *path, int *empty) {
    *empty = 0;
    sqlite3 *db = NULL;
    int rc = sqlite3_open_v2(path, &db, SQLITE_OPEN_READONLY, NULL), n = -1;
    sqlite3_stmt *q = NULL;
    if (rc == SQLITE_OK) rc = sqlite3_prepare_v2(db, "SELECT count(*) FROM sqlite_master", -1, &q, NULL);
    if (rc == SQLITE_OK && (rc = sqlite3_step(q)) == SQLITE_ROW) {
        n = sqlite3_column_int(q, 0);
        rc = SQLITE_OK;
    }
    sooc_status st = rc == SQLITE_OK ? SOOC_OK
                                     : sooc_seterr(SOOC_EIO, "%s: %s", path, db ? sqlite3_errmsg(db) : sqlite3_errstr(rc));
    sqlite3_finalize(q);
    sqlite3_close(db);
    *empty = n == 0;
    return st;
}

sooc_status sooc_mapstore_set_busy_timeout(sooc_mapstore *s, int ms) {
    if (ms < 0) return sooc_seterr(SOOC_EINVAL, "%s: busy timeout %d ms < 0", s->path, ms);
    int rc = sqlite3_busy_timeout(s->db, ms);
    return rc == SQLITE_OK ? SOOC_OK : sooc__mapstore_dberr(s, rc, "setting the busy timeout");
}

sooc_status sooc_mapstore_checkpoint(sooc_mapstore *s, int truncate) {
    if (s->readonly) return SOOC_OK;
    if (s->in_txn) return sooc_seterr(SOOC_EINVAL, "%s: checkpoint inside a transaction", s->path);
    int log = 0, done = 0;
    int rc = sqlite3_wal_checkpoint_v2(s->db, NULL, truncate ? SQLITE_CHECKPOINT_TRUNCATE : SQLITE_CHECKPOINT_PASSIVE,
                                       &log, &done);
    return rc == SQLITE_OK ? SOOC_OK : sooc__mapstore_dberr(s, rc, "checkpoint");
}
