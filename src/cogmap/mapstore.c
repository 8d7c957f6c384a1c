/*
 * The persistent map in SQLite (see include/sooc3d/cogmap.h for the schema
 * and the contracts). Every error message starts with the database path.
 */
#include "sooc3d/cogmap.h"
#include "cogmap/mapstore_impl.h"

#include <math.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>



static const char *k_sql[ST_COUNT] = {
    "INSERT INTO entries(" ENTRY_COLS ") VALUES(?1,?2,?3,?4,?5,?6,?7,?8,?9,?10,?11,?12,?13,?14,?15) "
    "ON CONFLICT(id) DO UPDATE SET x=excluded.x, z=excluded.z, yaw=excluded.yaw, rho_t=excluded.rho_t, "
    "rho_yaw=excluded.rho_yaw, pres_logit=excluded.pres_logit, dim=excluded.dim, "
    "latent_version=excluded.latent_version, what_mu=excluded.what_mu, what_logvar=excluded.what_logvar, "
    "first_seen_ns=excluded.first_seen_ns, last_seen_ns=excluded.last_seen_ns, "
    "obs_count=excluded.obs_count, last_view=excluded.last_view",
    "DELETE FROM entries WHERE id = ?1",
    "INSERT OR REPLACE INTO layout(bi, bj, dim, latent_version, mu, logvar) VALUES(?1,?2,?3,?4,?5,?6)",
    "INSERT OR REPLACE INTO meta(key, value) VALUES(?1, ?2)",
    "INSERT INTO keyframes(t_ns, view, tx, ty, tz, qx, qy, qz, qw, n_changed, n_removed, n_entries) "
    "VALUES(?1,?2,?3,?4,?5,?6,?7,?8,?9,?10,?11,?12)",
    "SELECT " ENTRY_COLS " FROM entries WHERE id = ?1",
};

static const char *k_schema =
    "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);"
    "CREATE TABLE entries(id INTEGER PRIMARY KEY, x REAL NOT NULL, z REAL NOT NULL, yaw REAL NOT NULL,"
    " rho_t REAL NOT NULL, rho_yaw REAL NOT NULL, pres_logit REAL NOT NULL, dim INTEGER NOT NULL,"
    " latent_version INTEGER NOT NULL, what_mu BLOB NOT NULL, what_logvar BLOB NOT NULL,"
    " first_seen_ns INTEGER NOT NULL, last_seen_ns INTEGER NOT NULL, obs_count INTEGER NOT NULL,"
    " last_view INTEGER NOT NULL);"
    "CREATE VIRTUAL TABLE entries_rtree USING rtree(id, min_x, max_x, min_z, max_z);"
    "CREATE TRIGGER entries_ai AFTER INSERT ON entries BEGIN"
    " INSERT INTO entries_rtree VALUES(new.id, new.x, new.x, new.z, new.z); END;"
    "CREATE TRIGGER entries_au AFTER UPDATE OF x, z ON entries BEGIN"
    " UPDATE entries_rtree SET min_x = new.x, max_x = new.x, min_z = new.z, max_z = new.z"
    " WHERE id = new.id; END;"
    "CREATE TRIGGER entries_ad AFTER DELETE ON entries BEGIN"
    " DELETE FROM entries_rtree WHERE id = old.id; END;"
    "CREATE TABLE layout(bi INTEGER NOT NULL, bj INTEGER NOT NULL, dim INTEGER NOT NULL,"
    " latent_version INTEGER NOT NULL, mu BLOB NOT NULL, logvar BLOB NOT NULL, PRIMARY KEY(bi, bj));"
    "CREATE TABLE keyframes(seq INTEGER PRIMARY KEY, t_ns INTEGER, view INTEGER, tx REAL, ty REAL,"
    " tz REAL, qx REAL, qy REAL, qz REAL, qw REAL, n_changed INTEGER, n_removed INTEGER,"
    " n_entries INTEGER);";


/* ------------------------------------------------------------- meta */

/* Read meta[key] into buf; returns 1 if present, 0 if absent, <0 status on error. */
static int meta_get(sooc_mapstore *s, const char *key, char *buf, size_t cap, sooc_status *err) {
    sqlite3_stmt *st = NULL;
    int rc = sqlite3_prepare_v2(s->db, "SELECT value FROM meta WHERE key = ?1", -1, &st, NULL);
    if (rc != SQLITE_OK) {
        *err = sooc__mapstore_dberr(s, rc, "reading meta");
        return -1;
    }
    sqlite3_bind_text(st, 1, key, -1, SQLITE_STATIC);
    rc = sqlite3_step(st);
    int found = 0;
    if (rc == SQLITE_ROW) {
        const unsigned char *v = sqlite3_column_text(st, 0);
        snprintf(buf, cap, "%s", v ? (const char *)v : "");
        found = 1;
    } else if (rc != SQLITE_DONE) {
        *err = sooc__mapstore_dberr(s, rc, "reading meta");
        sqlite3_finalize(st);
        return -1;
    }
    sqlite3_finalize(st);
    return found;
}

static sooc_status meta_put(sooc_mapstore *s, const char *key, const char *value) {
    sqlite3_stmt *st = s->st[ST_PUT_META];
    sqlite3_bind_text(st, 1, key, -1, SQLITE_TRANSIENT);
    sqlite3_bind_text(st, 2, value, -1, SQLITE_TRANSIENT);
    return sooc__mapstore_step_done(s, st, "writing meta");
}

static sooc_status meta_put_u64(sooc_mapstore *s, const char *key, uint64_t v) {
    char b[32];
    snprintf(b, sizeof b, "%llu", (unsigned long long)v);
    return meta_put(s, key, b);
}

static sooc_status meta_get_u64(sooc_mapstore *s, const char *key, uint64_t *v) {
    char b[64];
    sooc_status err = SOOC_OK;
    int r = meta_get(s, key, b, sizeof b, &err);
    if (r < 0) return err;
    if (!r) {
        *v = 0;
        return SOOC_OK;
    }
    char *end;
    *v = strtoull(b, &end, 10);
    if (end == b || *end) return sooc_seterr(SOOC_EFORMAT, "%s: meta '%s' = '%s' is not a number", s->path, key, b);
    return SOOC_OK;
}

/* -------------------------------------------------------------- open */

void sooc_mapstore_params_default(sooc_mapstore_params *p) {
    memset(p, 0, sizeof *p);
    p->create = 1;
}


void sooc_mapstore_close(sooc_mapstore *s) {
    if (!s) return;
    if (s->in_txn && s->db) sqlite3_exec(s->db, "ROLLBACK", NULL, NULL, NULL);
    for (int i = 0; i < ST_COUNT; i++) sqlite3_finalize(s->st[i]);
    if (s->db) sqlite3_close(s->db);
    sooc_free(s->path);
    sooc_free(s);
}

static sooc_status create_schema(sooc_mapstore *s, const sooc_mapstore_params *p) {
    sooc_status st;
    if ((st = sooc__mapstore_exec(s, "BEGIN IMMEDIATE", "begin"))) return st;
    if ((st = sooc__mapstore_exec(s, k_schema, "creating the schema"))) goto fail;
    if ((st = sooc__mapstore_exec(s, sooc__mapstore_ft_schema, "creating the schema"))) goto fail;
    if ((st = sooc__mapstore_exec(s, sooc__mapstore_geom_schema, "creating the schema"))) goto fail;
    for (int i = 0; i < ST_COUNT; i++)
        if (!s->st[i]) {
            int rc = sqlite3_prepare_v2(s->db, k_sql[i], -1, &s->st[i], NULL);
            if (rc != SQLITE_OK) { st = sooc__mapstore_dberr(s, rc, "preparing statements"); goto fail; }
        }
    char b[64];
    if ((st = meta_put(s, "app", "sooc3d-map"))) goto fail;
    snprintf(b, sizeof b, "%d", SOOC_MAPSTORE_SCHEMA_VERSION);
    if ((st = meta_put(s, "schema_version", b))) goto fail;
    if ((st = meta_put(s, "model_id", p->model_id ? p->model_id : ""))) goto fail;
    if ((st = meta_put_u64(s, "dim", (uint64_t)p->dim))) goto fail;
    if ((st = meta_put_u64(s, "layout_dim", (uint64_t)p->layout_dim))) goto fail;
    snprintf(b, sizeof b, "%.17g", p->block_size);
    if ((st = meta_put(s, "block_size", b))) goto fail;
    if ((st = meta_put_u64(s, "next_id", 1))) goto fail;
    if ((st = sooc__mapstore_exec(s, "COMMIT", "commit"))) goto fail;
    return SOOC_OK;
fail:
    sqlite3_exec(s->db, "ROLLBACK", NULL, NULL, NULL);
    return st;
}

/* "file:<path>?mode=ro[&immutable=1]" with the path percent-encoded (URI
 * filenames, https://sqlite.org/uri.html). 0 or -1 if it does not fit. */
static int ro_uri(char *buf, size_t cap, const char *path, int immutable) {
    static const char hex[] = "0123456789ABCDEF";
    size_t n = 0;
    const char *pre = "file:";
    for (const char *c = pre; *c; c++) buf[n++] = *c;
    for (const unsigned char *c = (const unsigned char *)path; *c; c++) {
        if (n + 4 >= cap) return -1;
        if ((*c >= 'A' && *c <= 'Z') || (*c >= 'a' && *c <= 'z') || (*c >= '0' && *c <= '9') ||
            strchr("/._-~", *c)) {
            buf[n++] = (char)*c;
        } else {
            buf[n++] = '%';
            buf[n++] = hex[*c >> 4];
            buf[n++] = hex[*c & 15];
        }
    }
    const char *q = immutable ? "?mode=ro&immutable=1" : "?mode=ro";
    if (n + strlen(q) + 1 > cap) return -1;
    memcpy(buf + n, q, strlen(q) + 1);
    return 0;
}

/* Read-only open that needs only read permission. A WAL database opened
 * read-only needs its -shm file, which SQLite must create (or write) when the
 * writer has gone: in a folder the reader cannot write that fails with
 * SQLITE_READONLY/CANTOPEN ("attempt to write a readonly database"). When no
 * -wal file with content is left (the writer checkpointed it on close), every
 * committed row is in the main file, so it is reopened as immutable (no
 * locking, no -shm). With a non-empty -wal (a writer is running or died
 * before checkpointing) the caller gets the error, naming the cause. */
static sooc_status open_readonly(sooc_mapstore *s, const char *path) {
    size_t cap = 3 * strlen(path) + 64;
    char *uri = sooc_malloc(cap);
    if (!uri) return SOOC_ENOMEM;
    sooc_status st = SOOC_OK;
    int flags = SQLITE_OPEN_READONLY | SQLITE_OPEN_URI | SQLITE_OPEN_NOMUTEX;
    for (int immutable = 0; immutable < 2; immutable++) {
        if (ro_uri(uri, cap, path, immutable)) { st = sooc_seterr(SOOC_EINVAL, "%s: path too long", path); break; }
        if (s->db) { sqlite3_close_v2(s->db); s->db = NULL; }
        int rc = sqlite3_open_v2(uri, &s->db, flags, NULL);
        if (rc != SQLITE_OK) { st = sooc__mapstore_dberr(s, rc, "cannot open read-only"); break; }
        sqlite3_extended_result_codes(s->db, 1);
        sqlite3_busy_timeout(s->db, 5000);
        rc = sqlite3_exec(s->db, "SELECT count(*) FROM sqlite_master", NULL, NULL, NULL);
        if (rc == SQLITE_OK) break;
        int prim = rc & 0xff;
        char wal[4096];
        snprintf(wal, sizeof wal, "%s-wal", path);
        struct stat sb;
        int wal_has_data = stat(wal, &sb) == 0 && sb.st_size > 0;
        if (immutable || (prim != SQLITE_READONLY && prim != SQLITE_CANTOPEN)) {
            st = sooc__mapstore_dberr(s, rc, "reading the schema");
            break;
        }
        if (wal_has_data) {
            st = sooc_seterr(SOOC_EIO,
                             "%s: cannot read it without write access to its folder: %s holds "
                             "transactions not yet checkpointed (a writer is running or died), and "
                             "reading them needs the -shm file (%s)",
                             path, wal, sqlite3_errmsg(s->db));
            break;
        }
        sooc_log(SOOC_LOG_DEBUG, "%s: %s; no -wal left, reopening immutable", path, sqlite3_errmsg(s->db));
    }
    sooc_free(uri);
    return st;
}

sooc_status sooc_mapstore_open(sooc_mapstore **out, const char *path, const sooc_mapstore_params *pp) {
    *out = NULL;
    sooc_mapstore_params p;
    if (pp) p = *pp;
    else sooc_mapstore_params_default(&p);
    sooc__mapstore_note_open(NULL);
    if (!path || !*path) return sooc_seterr(SOOC_EINVAL, "mapstore: empty database path");
    if (p.dim < 0 || p.dim > SOOC_COGMAP_DIM_MAX || p.layout_dim < 0 || p.layout_dim > SOOC_COGMAP_DIM_MAX)
        return sooc_seterr(SOOC_EINVAL, "%s: bad dims %d / %d", path, p.dim, p.layout_dim);
    int exists = sooc_file_exists(path);
    if (!exists && (p.readonly || !p.create))
        return sooc_seterr(SOOC_ENOTFOUND, "%s: map database not found", path);

    sooc_mapstore *s = sooc_calloc(1, sizeof *s);
    if (!s) return SOOC_ENOMEM;
    s->path = sooc_strdup(path);
    if (!s->path) { sooc_free(s); return SOOC_ENOMEM; }
    s->readonly = p.readonly;
    sooc_status st = SOOC_OK;
    int rc;
    if (p.readonly) {
        if ((st = open_readonly(s, path))) goto fail;
    } else {
        int flags = SQLITE_OPEN_READWRITE | (p.create ? SQLITE_OPEN_CREATE : 0);
        if (p.create) {   /* a missing folder is made (a new run's out/<name>/map.sqlite) */
            char dir[4096];
            sooc_path_parent(path, dir, sizeof dir);   /* "." and "/" exist */
            if (!sooc_dir_exists(dir) && (st = sooc_mkdirs(dir))) {
                sooc_adderr(st, "%s: cannot make the map database's folder %s", path, dir);
                goto fail;
            }
        }
        rc = sqlite3_open_v2(path, &s->db, flags | SQLITE_OPEN_NOMUTEX, NULL);
        if (rc != SQLITE_OK) { st = sooc__mapstore_dberr(s, rc, "cannot open"); goto fail; }
        sqlite3_extended_result_codes(s->db, 1);
        sqlite3_busy_timeout(s->db, 5000);
    }

    /* touches the file header: a non-database fails here with SQLITE_NOTADB */
    int n_tables = 0, has_meta = 0;
    {
        sqlite3_stmt *q = NULL;
        rc = sqlite3_prepare_v2(s->db, "SELECT name FROM sqlite_master WHERE type = 'table'", -1, &q, NULL);
        if (rc != SQLITE_OK) { st = sooc__mapstore_dberr(s, rc, "reading the schema"); goto fail; }
        while ((rc = sqlite3_step(q)) == SQLITE_ROW) {
            n_tables++;
            const char *nm = (const char *)sqlite3_column_text(q, 0);
            if (nm && !strcmp(nm, "meta")) has_meta = 1;
        }
        sqlite3_finalize(q);
        if (rc != SQLITE_DONE) { st = sooc__mapstore_dberr(s, rc, "reading the schema"); goto fail; }
    }
    if (!p.readonly) {
        sqlite3_stmt *q = NULL;
        rc = sqlite3_prepare_v2(s->db, "PRAGMA journal_mode = WAL", -1, &q, NULL);
        if (rc == SQLITE_OK) rc = sqlite3_step(q);
        int wal = rc == SQLITE_ROW && !strcmp((const char *)sqlite3_column_text(q, 0), "wal");
        sqlite3_finalize(q);
        if (rc != SQLITE_ROW) { st = sooc__mapstore_dberr(s, rc, "setting WAL mode"); goto fail; }
        if (!wal) { st = sooc_seterr(SOOC_EIO, "%s: the database refused WAL journal mode", path); goto fail; }
        if ((st = sooc__mapstore_exec(s, "PRAGMA synchronous = NORMAL", "pragma"))) goto fail;
    }
    if (n_tables == 0) {
        if (p.readonly) { st = sooc_seterr(SOOC_EFORMAT, "%s: empty database, not a sooc3d map", path); goto fail; }
        if (p.dim < 1) { st = sooc_seterr(SOOC_EINVAL, "%s: creating a map needs its latent dim", path); goto fail; }
        if ((st = create_schema(s, &p))) goto fail;
    } else if (!has_meta) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: not a sooc3d map (SQLite database without a meta table)", path);
        goto fail;
    }

    /* check identity and versions */
    char b[160];
    int r = meta_get(s, "app", b, sizeof b, &st);
    if (r < 0) goto fail;
    if (!r || strcmp(b, "sooc3d-map")) { st = sooc_seterr(SOOC_EFORMAT, "%s: not a sooc3d map (meta app)", path); goto fail; }
    uint64_t v = 0;
    if ((st = meta_get_u64(s, "schema_version", &v))) goto fail;
    if (v < 1 || v > SOOC_MAPSTORE_SCHEMA_VERSION) {
        st = sooc_seterr(SOOC_EVERSION, "%s: map schema version %llu, this build reads versions 1 to %d", path,
                         (unsigned long long)v, SOOC_MAPSTORE_SCHEMA_VERSION);
        goto fail;
    }
    s->schema = (int)v;
    if (v == 1 && !p.readonly) {   /* migrate 1 -> 2: add the finetuned-decoder tables */
        if ((st = sooc__mapstore_exec(s, "BEGIN IMMEDIATE", "begin"))) goto fail;
        st = sooc__mapstore_exec(s, sooc__mapstore_ft_schema, "migrating schema 1 -> 2");
        if (!st) st = sooc__mapstore_exec(s, "INSERT OR REPLACE INTO meta(key, value) VALUES('schema_version', '2')",
                           "migrating schema 1 -> 2");
        if (!st) st = sooc__mapstore_exec(s, "COMMIT", "migrating schema 1 -> 2");
        if (st) {
            sqlite3_exec(s->db, "ROLLBACK", NULL, NULL, NULL);
            goto fail;
        }
        s->schema = 2;
        sooc_log(SOOC_LOG_INFO, "%s: map schema migrated from version 1 to 2 (finetuned decoders)", path);
    }
    if (s->schema == 2 && !p.readonly) {   /* migrate 2 -> 3: add the object geometry table (mapstore_geom.c) */
        if ((st = sooc__mapstore_exec(s, "BEGIN IMMEDIATE", "begin"))) goto fail;
        st = sooc__mapstore_exec(s, sooc__mapstore_geom_schema, "migrating schema 2 -> 3");
        if (!st) st = sooc__mapstore_exec(s, "INSERT OR REPLACE INTO meta(key, value) VALUES('schema_version', '3')",
                           "migrating schema 2 -> 3");
        if (!st) st = sooc__mapstore_exec(s, "COMMIT", "migrating schema 2 -> 3");
        if (st) {
            sqlite3_exec(s->db, "ROLLBACK", NULL, NULL, NULL);
            goto fail;
        }
        s->schema = 3;
        sooc_log(SOOC_LOG_INFO, "%s: map schema migrated from version 2 to 3 (object geometry)", path);
    }
    /* range-check the u64 before narrowing: "-1" or 2^32 + 5 must not wrap into range */
    uint64_t vd = 0, vl = 0;
    if ((st = meta_get_u64(s, "dim", &vd))) goto fail;
    if ((st = meta_get_u64(s, "layout_dim", &vl))) goto fail;
    if (vd > SOOC_COGMAP_DIM_MAX || vl > SOOC_COGMAP_DIM_MAX) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: stored dims %llu / %llu out of range 0..%d", path,
                         (unsigned long long)vd, (unsigned long long)vl, SOOC_COGMAP_DIM_MAX);
        goto fail;
    }
    s->dim = (int)vd;
    s->layout_dim = (int)vl;
    if ((p.dim && p.dim != s->dim) || (p.layout_dim && p.layout_dim != s->layout_dim)) {
        st = sooc_seterr(SOOC_EVERSION, "%s: map has latent dims %d / %d (object / layout), expected %d / %d", path,
                         s->dim, s->layout_dim, p.dim, p.layout_dim);
        goto fail;
    }
    if (p.model_id) {
        r = meta_get(s, "model_id", b, sizeof b, &st);
        if (r < 0) goto fail;
        if (r && b[0] && strcmp(b, p.model_id)) {
            st = sooc_seterr(SOOC_EVERSION, "%s: map was built by model '%s', not '%s'", path, b, p.model_id);
            goto fail;
        }
    }
    for (int i = 0; i < ST_COUNT; i++)
        if (!s->st[i]) {
            rc = sqlite3_prepare_v2(s->db, k_sql[i], -1, &s->st[i], NULL);
            if (rc != SQLITE_OK) { st = sooc__mapstore_dberr(s, rc, "preparing statements (schema mismatch?)"); goto fail; }
        }
    /* a map written without a model id (an older schema) takes this one */
    if (p.model_id && p.model_id[0] && !p.readonly) {
        r = meta_get(s, "model_id", b, sizeof b, &st);
        if (r < 0) goto fail;
        if ((!r || !b[0]) && (st = meta_put(s, "model_id", p.model_id))) goto fail;
    }
    *out = s;
    return SOOC_OK;
fail:
    sooc__mapstore_note_open(s);
    sooc_mapstore_close(s);
    return st;
}

sooc_status sooc_mapstore_info_get(sooc_mapstore *s, sooc_mapstore_info *o) {
    memset(o, 0, sizeof *o);
    sooc_status st = SOOC_OK;
    uint64_t v = 0;
    o->schema_version = s->schema;
    o->dim = s->dim;
    o->layout_dim = s->layout_dim;
    if (meta_get(s, "model_id", o->model_id, sizeof o->model_id, &st) < 0) return st;
    char b[64];
    int r = meta_get(s, "block_size", b, sizeof b, &st);
    if (r < 0) return st;
    o->block_size = r ? atof(b) : 0;
    if ((st = meta_get_u64(s, "next_id", &v))) return st;
    o->next_id = v;
    static const char *counts[3] = {"SELECT count(*) FROM entries", "SELECT count(*) FROM layout",
                                    "SELECT count(*) FROM keyframes"};
    uint64_t *dst[3] = {&o->n_entries, &o->n_layout, &o->n_keyframes};
    for (int i = 0; i < 3; i++) {
        sqlite3_stmt *q = NULL;
        int rc = sqlite3_prepare_v2(s->db, counts[i], -1, &q, NULL);
        if (rc == SQLITE_OK) rc = sqlite3_step(q);
        if (rc != SQLITE_ROW) {
            sqlite3_finalize(q);
            return sooc__mapstore_dberr(s, rc, "counting rows");
        }
        *dst[i] = (uint64_t)sqlite3_column_int64(q, 0);
        sqlite3_finalize(q);
    }
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(s->db, "PRAGMA journal_mode", -1, &q, NULL);
    if (rc == SQLITE_OK) rc = sqlite3_step(q);
    if (rc == SQLITE_ROW) snprintf(o->journal_mode, sizeof o->journal_mode, "%s", sqlite3_column_text(q, 0));
    sqlite3_finalize(q);
    return rc == SQLITE_ROW ? SOOC_OK : sooc__mapstore_dberr(s, rc, "journal mode");
}

/* ------------------------------------------------------------- writes */

static sooc_status put_one(sooc_mapstore *s, const sooc_cogmap_entry *e) {
    if (e->dim != s->dim)
        return sooc_seterr(SOOC_EINVAL, "%s: entry %llu has dim %d, map has %d", s->path, (unsigned long long)e->id,
                           e->dim, s->dim);
    if (!e->id || e->id > (uint64_t)INT64_MAX)
        return sooc_seterr(SOOC_EINVAL, "%s: bad entry id %llu", s->path, (unsigned long long)e->id);
    sqlite3_stmt *st = s->st[ST_PUT_ENTRY];
    sqlite3_bind_int64(st, 1, (sqlite3_int64)e->id);
    sqlite3_bind_double(st, 2, e->X);
    sqlite3_bind_double(st, 3, e->Z);
    sqlite3_bind_double(st, 4, e->Theta);
    sqlite3_bind_double(st, 5, e->rho_t);
    sqlite3_bind_double(st, 6, e->rho_theta);
    sqlite3_bind_double(st, 7, e->pres_logit);
    sqlite3_bind_int(st, 8, e->dim);
    sqlite3_bind_int(st, 9, SOOC_MAPSTORE_LATENT_VERSION);
    /* latent_version 1: little-endian float32 (all supported hosts are little-endian) */
    sqlite3_bind_blob(st, 10, e->what_mu, e->dim * (int)sizeof(float), SQLITE_STATIC);
    sqlite3_bind_blob(st, 11, e->what_logvar, e->dim * (int)sizeof(float), SQLITE_STATIC);
    sqlite3_bind_int64(st, 12, e->first_seen_ns);
    sqlite3_bind_int64(st, 13, e->last_seen_ns);
    sqlite3_bind_int64(st, 14, e->obs_count);
    sqlite3_bind_int(st, 15, e->last_view);
    return sooc__mapstore_step_done(s, st, "writing an entry");
}

static sooc_status del_one(sooc_mapstore *s, uint64_t id) {
    sqlite3_stmt *st = s->st[ST_DEL_ENTRY];
    sqlite3_bind_int64(st, 1, (sqlite3_int64)id);
    return sooc__mapstore_step_done(s, st, "deleting an entry");
}

sooc_status sooc_mapstore_put_entries(sooc_mapstore *s, const sooc_cogmap_entry *e, size_t n) {
    for (size_t i = 0; i < n; i++) {
        sooc_status st = put_one(s, &e[i]);
        if (st) return st;
    }
    return SOOC_OK;
}

sooc_status sooc_mapstore_remove_entries(sooc_mapstore *s, const uint64_t *ids, size_t n) {
    for (size_t i = 0; i < n; i++) {
        sooc_status st = del_one(s, ids[i]);
        if (st) return st;
    }
    return SOOC_OK;
}

sooc_status sooc_mapstore_put_layout(sooc_mapstore *s, int32_t bi, int32_t bj, const float *mu,
                                     const float *logvar) {
    if (!s->layout_dim) return sooc_seterr(SOOC_EINVAL, "%s: map has no layout latents", s->path);
    sqlite3_stmt *st = s->st[ST_PUT_LAYOUT];
    sqlite3_bind_int(st, 1, bi);
    sqlite3_bind_int(st, 2, bj);
    sqlite3_bind_int(st, 3, s->layout_dim);
    sqlite3_bind_int(st, 4, SOOC_MAPSTORE_LATENT_VERSION);
    sqlite3_bind_blob(st, 5, mu, s->layout_dim * (int)sizeof(float), SQLITE_STATIC);
    sqlite3_bind_blob(st, 6, logvar, s->layout_dim * (int)sizeof(float), SQLITE_STATIC);
    return sooc__mapstore_step_done(s, st, "writing a layout block");
}

sooc_status sooc_mapstore_set_next_id(sooc_mapstore *s, uint64_t next_id) {
    uint64_t cur = 0;
    sooc_status st = meta_get_u64(s, "next_id", &cur);
    if (st) return st;
    if (next_id <= cur) return SOOC_OK;
    return meta_put_u64(s, "next_id", next_id);
}

static sooc_status check_map(const sooc_mapstore *s, const sooc_cogmap *map) {
    if (sooc_cogmap_dim(map) != s->dim || sooc_cogmap_layout_dim(map) != s->layout_dim)
        return sooc_seterr(SOOC_EVERSION, "%s: map dims %d / %d, cogmap dims %d / %d", s->path, s->dim,
                           s->layout_dim, sooc_cogmap_dim(map), sooc_cogmap_layout_dim(map));
    return SOOC_OK;
}

/* Append a keyframe row; n_entries < 0 stores NULL (unknown). */
static sooc_status kf_row(sooc_mapstore *s, const sooc_mapstore_keyframe *kf, size_t n_changed, size_t n_removed,
                          int64_t n_entries) {
    double R[9], t[3], q[4];
    sooc_se3_to_rt(R, t, kf->T_wc);
    sooc_m3_to_quat(q, R);
    sqlite3_stmt *k = s->st[ST_ADD_KF];
    sqlite3_bind_int64(k, 1, kf->t_ns);
    sqlite3_bind_int(k, 2, kf->view);
    for (int i = 0; i < 3; i++) sqlite3_bind_double(k, 3 + i, t[i]);
    for (int i = 0; i < 4; i++) sqlite3_bind_double(k, 6 + i, q[i]);
    sqlite3_bind_int64(k, 10, (sqlite3_int64)n_changed);
    sqlite3_bind_int64(k, 11, (sqlite3_int64)n_removed);
    if (n_entries >= 0) sqlite3_bind_int64(k, 12, n_entries);
    else sqlite3_bind_null(k, 12);
    return sooc__mapstore_step_done(s, k, "writing a keyframe");
}

sooc_status sooc_mapstore_add_keyframe(sooc_mapstore *s, const sooc_mapstore_keyframe *kf, int64_t n_entries) {
    size_t nc = 0;
    for (size_t i = 0; i < kf->n_changed; i++) nc += kf->changed && kf->changed[i] != 0;
    return kf_row(s, kf, nc, kf->n_removed, n_entries);
}

sooc_status sooc_mapstore_commit_keyframe(sooc_mapstore *s, const sooc_cogmap *map, const sooc_mapstore_keyframe *kf) {
    sooc_status st = check_map(s, map);
    if (st) return st;
    if ((st = sooc_mapstore_begin(s))) return st;
    size_t n_changed = 0;
    for (size_t i = 0; i < kf->n_changed; i++) {
        if (!kf->changed[i]) continue;
        sooc_cogmap_entry e;
        if ((st = sooc_cogmap_get(map, kf->changed[i], &e))) {
            sooc_adderr(st, "%s: keyframe commit", s->path);
            goto fail;
        }
        if ((st = put_one(s, &e))) goto fail;
        n_changed++;
    }
    if ((st = sooc_mapstore_remove_entries(s, kf->removed, kf->n_removed))) goto fail;
    if (kf->has_block && s->layout_dim) {
        float mu[SOOC_COGMAP_DIM_MAX], lv[SOOC_COGMAP_DIM_MAX];
        st = sooc_cogmap_layout_get(map, kf->bi, kf->bj, mu, lv);
        if (st == SOOC_OK) st = sooc_mapstore_put_layout(s, kf->bi, kf->bj, mu, lv);
        else if (st == SOOC_ENOTFOUND) st = SOOC_OK;
        if (st) goto fail;
    }
    if ((st = sooc_mapstore_set_next_id(s, sooc_cogmap_next_id(map)))) goto fail;
    if ((st = kf_row(s, kf, n_changed, kf->n_removed, (int64_t)sooc_cogmap_count(map)))) goto fail;
    return sooc_mapstore_commit(s);
fail:
    sooc_mapstore_rollback(s);
    return st;
}

typedef struct save_ctx {
    sooc_mapstore *s;
    sooc_status st;
} save_ctx;

static int save_entry_cb(void *u, const sooc_cogmap_entry *e) {
    save_ctx *c = u;
    c->st = put_one(c->s, e);
    return c->st != SOOC_OK;
}
static int save_block_cb(void *u, int32_t bi, int32_t bj, const float *mu, const float *lv) {
    save_ctx *c = u;
    c->st = sooc_mapstore_put_layout(c->s, bi, bj, mu, lv);
    return c->st != SOOC_OK;
}

sooc_status sooc_mapstore_save_map(sooc_mapstore *s, const sooc_cogmap *map) {
    sooc_status st = check_map(s, map);
    if (st) return st;
    if ((st = sooc_mapstore_begin(s))) return st;
    save_ctx c = {s, SOOC_OK};
    if ((st = sooc__mapstore_exec(s, "DELETE FROM entries; DELETE FROM layout;", "clearing the map"))) goto fail;
    sooc_cogmap_foreach(map, save_entry_cb, &c);
    if ((st = c.st)) goto fail;
    sooc_cogmap_layout_foreach(map, save_block_cb, &c);
    if ((st = c.st)) goto fail;
    if ((st = sooc__mapstore_ft_save(s, map))) goto fail;
    if ((st = sooc_mapstore_set_next_id(s, sooc_cogmap_next_id(map)))) goto fail;
    return sooc_mapstore_commit(s);
fail:
    sooc_mapstore_rollback(s);
    return st;
}

typedef struct load_ctx {
    sooc_cogmap_entry *e;
    size_t n, cap;
    sooc_status st;
} load_ctx;

static int load_cb(void *u, const sooc_cogmap_entry *e) {
    load_ctx *c = u;
    if (c->n == c->cap) {
        size_t nc = c->cap ? c->cap * 2 : 256;
        sooc_cogmap_entry *p = sooc_realloc(c->e, nc * sizeof *p);
        if (!p) {
            c->st = SOOC_ENOMEM;
            return 1;
        }
        c->e = p;
        c->cap = nc;
    }
    c->e[c->n++] = *e;
    return 0;
}

/* ------------------------------------------------- layout / meta (node) */

typedef struct load_block_ctx {
    sooc_cogmap *map;
    sooc_status st;
} load_block_ctx;

static int load_block_cb(void *user, int32_t bi, int32_t bj, const float *mu, const float *logvar) {
    load_block_ctx *c = user;
    c->st = sooc_cogmap_layout_set(c->map, bi, bj, mu, logvar);
    return c->st != SOOC_OK;
}

sooc_status sooc_mapstore_foreach_layout(sooc_mapstore *s, sooc_cogmap_block_fn fn, void *user) {
    if (!s->layout_dim) return SOOC_OK;
    sqlite3_stmt *q = NULL;
    sooc_status st = SOOC_OK;
    int rc = sqlite3_prepare_v2(s->db, "SELECT bi, bj, dim, latent_version, mu, logvar FROM layout ORDER BY bi, bj",
                                -1, &q, NULL);
    if (rc != SQLITE_OK) return sooc__mapstore_dberr(s, rc, "reading layout");
    size_t nb = (size_t)s->layout_dim * sizeof(float);
    while ((rc = sqlite3_step(q)) == SQLITE_ROW) {
        int bi = sqlite3_column_int(q, 0), bj = sqlite3_column_int(q, 1);
        if (sqlite3_column_int(q, 2) != s->layout_dim || sqlite3_column_int(q, 3) != SOOC_MAPSTORE_LATENT_VERSION ||
            (size_t)sqlite3_column_bytes(q, 4) != nb || (size_t)sqlite3_column_bytes(q, 5) != nb) {
            st = sooc_seterr(SOOC_EFORMAT, "%s: layout block (%d, %d) has a bad latent", s->path, bi, bj);
            break;
        }
        float mu[SOOC_COGMAP_DIM_MAX], lv[SOOC_COGMAP_DIM_MAX];
        memcpy(mu, sqlite3_column_blob(q, 4), nb);
        memcpy(lv, sqlite3_column_blob(q, 5), nb);
        if (fn(user, bi, bj, mu, lv)) {   /* stopped by the callback */
            rc = SQLITE_DONE;
            break;
        }
    }
    if (!st && rc != SQLITE_DONE) st = sooc__mapstore_dberr(s, rc, "reading layout");
    sqlite3_finalize(q);
    return st;
}

sooc_status sooc_mapstore_meta_set(sooc_mapstore *s, const char *key, const char *value) {
    static const char *reserved[] = {"app", "schema_version", "model_id", "dim", "layout_dim", "block_size", "next_id"};
    for (size_t i = 0; i < sizeof reserved / sizeof *reserved; i++)
        if (!strcmp(key, reserved[i]))
            return sooc_seterr(SOOC_EINVAL, "%s: meta key '%s' is reserved", s->path, key);
    return meta_put(s, key, value);
}

sooc_status sooc_mapstore_meta_get(sooc_mapstore *s, const char *key, char *buf, size_t cap) {
    sooc_status err = SOOC_OK;
    int r = meta_get(s, key, buf, cap, &err);
    if (r < 0) return err;
    if (!r) return SOOC_ENOTFOUND;
    return SOOC_OK;
}

sooc_status sooc_mapstore_load_map(sooc_mapstore *s, sooc_cogmap *map) {
    sooc_status st = check_map(s, map);
    if (st) return st;
    load_ctx c = {0};
    if ((st = sooc_mapstore_foreach(s, load_cb, &c)) || (st = c.st)) goto done;
    if ((st = sooc_cogmap_load(map, c.e, c.n))) {
        sooc_adderr(st, "%s", s->path);
        goto done;
    }
    if (s->layout_dim) {
        load_block_ctx bc = {map, SOOC_OK};
        if ((st = sooc_mapstore_foreach_layout(s, load_block_cb, &bc)) || (st = bc.st)) goto done;
    }
    if ((st = sooc__mapstore_ft_load(s, map))) goto done;
    uint64_t next = 0;
    if ((st = meta_get_u64(s, "next_id", &next))) goto done;
    sooc_cogmap_reserve_ids(map, next);
done:
    sooc_free(c.e);
    return st;
}

/* ------------------------------------------------------- world frame */

#define FRAME_NVAL 24   /* T[16], up[3], plane[4], cam_height */

static void frame_pack(const sooc_map_frame *f, double v[FRAME_NVAL]) {
    memcpy(v, f->T_world_src, 16 * sizeof(double));
    memcpy(v + 16, f->up_src, 3 * sizeof(double));
    memcpy(v + 19, f->plane_src, 4 * sizeof(double));
    v[23] = f->cam_height_m;
}

/* Empty string if f is a valid frame, else what is wrong. */
static const char *frame_check(const sooc_map_frame *f) {
    double v[FRAME_NVAL];
    frame_pack(f, v);
    for (int i = 0; i < FRAME_NVAL; i++)
        if (!isfinite(v[i])) return "a value is not finite";
    if (f->up_source < -1 || f->up_source > 2) return "up_source is not -1, 0, 1 or 2";
    const double *T = f->T_world_src;
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double d = T[4 * a] * T[4 * b] + T[4 * a + 1] * T[4 * b + 1] + T[4 * a + 2] * T[4 * b + 2];
            if (fabs(d - (a == b)) > 1e-6) return "T_world_src is not a rigid transform";
        }
    if (T[12] != 0 || T[13] != 0 || T[14] != 0 || T[15] != 1) return "T_world_src's last row is not 0 0 0 1";
    return "";
}

sooc_status sooc_mapstore_frame_put(sooc_mapstore *s, const sooc_map_frame *f) {
    const char *bad = frame_check(f);
    if (*bad) return sooc_seterr(SOOC_EINVAL, "%s: world frame: %s", s->path, bad);
    double v[FRAME_NVAL];
    frame_pack(f, v);
    char b[FRAME_NVAL * 26 + 32];
    int k = snprintf(b, sizeof b, "v1 %d", f->up_source);
    for (int i = 0; i < FRAME_NVAL; i++) k += snprintf(b + k, sizeof b - (size_t)k, " %.17g", v[i]);
    return meta_put(s, "world_frame", b);
}

sooc_status sooc_mapstore_frame_get(sooc_mapstore *s, sooc_map_frame *f, int *found) {
    char b[1024];
    sooc_status err = SOOC_OK;
    *found = 0;
    int r = meta_get(s, "world_frame", b, sizeof b, &err);
    if (r < 0) return err;
    if (!r) return SOOC_OK;
    sooc_map_frame g;
    double v[FRAME_NVAL];
    const char *p = b;
    char *end;
    if (strncmp(p, "v1 ", 3)) goto bad;
    p += 3;
    long us = strtol(p, &end, 10);
    if (end == p) goto bad;
    g.up_source = (int)us;
    p = end;
    for (int i = 0; i < FRAME_NVAL; i++) {
        v[i] = strtod(p, &end);
        if (end == p) goto bad;
        p = end;
    }
    while (*p == ' ') p++;
    if (*p) goto bad;
    memcpy(g.T_world_src, v, 16 * sizeof(double));
    memcpy(g.up_src, v + 16, 3 * sizeof(double));
    memcpy(g.plane_src, v + 19, 4 * sizeof(double));
    g.cam_height_m = v[23];
    const char *why = frame_check(&g);
    if (*why) return sooc_seterr(SOOC_EFORMAT, "%s: meta 'world_frame': %s", s->path, why);
    *f = g;
    *found = 1;
    return SOOC_OK;
bad:
    return sooc_seterr(SOOC_EFORMAT, "%s: meta 'world_frame' is malformed (want 'v1 <up_source> <24 numbers>')",
                       s->path);
}

sooc_status sooc_mapstore_keyframe_views(sooc_mapstore *s, int64_t *views, size_t cap, size_t *n) {
    *n = 0;
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(s->db, "SELECT DISTINCT view FROM keyframes ORDER BY view", -1, &q, NULL);
    if (rc != SQLITE_OK) return sooc__mapstore_dberr(s, rc, "reading keyframes");
    while ((rc = sqlite3_step(q)) == SQLITE_ROW) {
        if (views && *n < cap) views[*n] = sqlite3_column_int64(q, 0);
        (*n)++;
    }
    sqlite3_finalize(q);
    return rc == SQLITE_DONE ? SOOC_OK : sooc__mapstore_dberr(s, rc, "reading keyframes");
}
