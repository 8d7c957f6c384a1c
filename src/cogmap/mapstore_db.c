/* The map store's connection (mapstore_impl.h): SQLite errors as statuses,
 * statements without rows, transactions and the connection's accessors; the
 * other files of the store build on these. */
#include "sooc3d/cogmap.h"
#include "cogmap/mapstore_impl.h"

#include <sqlite3.h>
#include <stdio.h>
#include <string.h>

/* ------------------------------------------------------------- errors */

static sooc_status map_rc(int rc) {
    switch (rc & 0xff) {
    case SQLITE_NOMEM: return SOOC_ENOMEM;
    case SQLITE_NOTADB:
    case SQLITE_CORRUPT:
    case SQLITE_FORMAT: return SOOC_EFORMAT;
    case SQLITE_BUSY:
    case SQLITE_LOCKED: return SOOC_EBUSY;
    case SQLITE_CANTOPEN: return SOOC_EIO;
    case SQLITE_READONLY: return SOOC_EIO;
    default: return SOOC_EIO;
    }
}

sooc_status sooc__mapstore_dberr(sooc_mapstore *s, int rc, const char *what) {
    s->last_rc = rc;
    const char *msg = s->db ? sqlite3_errmsg(s->db) : sqlite3_errstr(rc);
    sooc_status st = map_rc(rc);
    if (st == SOOC_EFORMAT)
        return sooc_seterr(st, "%s: not a valid sooc3d map database (%s: %s)", s->path, what, msg);
    return sooc_seterr(st, "%s: %s: %s", s->path, what, msg);
}

sooc_status sooc__mapstore_exec(sooc_mapstore *s, const char *sql, const char *what) {
    int rc = sqlite3_exec(s->db, sql, NULL, NULL, NULL);
    return rc == SQLITE_OK ? SOOC_OK : sooc__mapstore_dberr(s, rc, what);
}

/* Run a statement that returns no rows (or ignore its rows). */
sooc_status sooc__mapstore_step_done(sooc_mapstore *s, sqlite3_stmt *st, const char *what) {
    int rc;
    while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
    }
    sqlite3_reset(st);
    sqlite3_clear_bindings(st);
    return rc == SQLITE_DONE ? SOOC_OK : sooc__mapstore_dberr(s, rc, what);
}

/* ------------------------------------------------------- transactions */

sooc_status sooc_mapstore_begin(sooc_mapstore *s) {
    if (s->in_txn) return sooc_seterr(SOOC_EINVAL, "%s: transaction already open", s->path);
    s->last_rc = 0;
    sooc_status st = sooc__mapstore_exec(s, "BEGIN IMMEDIATE", "begin");
    if (!st) s->in_txn = 1;
    return st;
}

sooc_status sooc_mapstore_commit(sooc_mapstore *s) {
    if (!s->in_txn) return sooc_seterr(SOOC_EINVAL, "%s: no transaction open", s->path);
    sooc_status st = sooc__mapstore_exec(s, "COMMIT", "commit");
    if (st) sooc_mapstore_rollback(s);
    s->in_txn = 0;
    return st;
}

void sooc_mapstore_rollback(sooc_mapstore *s) {
    if (s->in_txn) sqlite3_exec(s->db, "ROLLBACK", NULL, NULL, NULL);
    s->in_txn = 0;
}

/* ------------------------------------------------------------ accessors */

const char *sooc_mapstore_path(const sooc_mapstore *s) { return s->path; }
sqlite3 *sooc__mapstore_db(sooc_mapstore *s) { return s->db; }
int sooc__mapstore_readonly(const sooc_mapstore *s) { return s->readonly; }
