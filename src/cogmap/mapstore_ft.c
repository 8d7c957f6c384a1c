/* Finetuned decoders in the map database (schema version 2;
 * include/sooc3d/cogmap.h "finetuned decoders"). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cogmap/mapstore_impl.h"

/* Schema version 2: finetuned decoders per entry and per layout
 * block (payloads of cogmap.h, include/sooc3d/train.h). A version-1 map
 * gets these on its first read-write open (one transaction). */
const char *const sooc__mapstore_ft_schema =
    "CREATE TABLE IF NOT EXISTS ft_objects(id INTEGER PRIMARY KEY, version INTEGER NOT NULL,"
    " n INTEGER NOT NULL, crc INTEGER NOT NULL, data BLOB NOT NULL, steps INTEGER NOT NULL, loss REAL);"
    "CREATE TABLE IF NOT EXISTS ft_layout(bi INTEGER NOT NULL, bj INTEGER NOT NULL, version INTEGER NOT NULL,"
    " n INTEGER NOT NULL, crc INTEGER NOT NULL, data BLOB NOT NULL, steps INTEGER NOT NULL, loss REAL,"
    " PRIMARY KEY(bi, bj));"
    "CREATE TRIGGER IF NOT EXISTS entries_ad_ft AFTER DELETE ON entries BEGIN"
    " DELETE FROM ft_objects WHERE id = old.id; END;";
#define FT_BLOB_VERSION 1   /* data: n little-endian float32, crc = CRC-32 of those bytes */


static sooc_status ft_need(const sooc_mapstore *s) {
    if (s->schema < 2)
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: schema version 1 map opened read-only: no finetuned decoders "
                           "(open it read-write once to migrate it)", s->path);
    return SOOC_OK;
}

static sooc_status ft_put_row(sooc_mapstore *s, int is_block, uint64_t id, int32_t bi, int32_t bj, const float *v,
                              size_t n, int steps, double loss) {
    if (!n || !v || n > (size_t)INT32_MAX / sizeof(float))
        return sooc_seterr(SOOC_EINVAL, "%s: finetuned decoder: bad size %zu", s->path, n);
    for (size_t i = 0; i < n; i++)
        if (!isfinite(v[i]))
            return sooc_seterr(SOOC_ENUMERIC, "%s: finetuned decoder of %s %lld: non-finite value", s->path,
                               is_block ? "block" : "entry", (long long)(is_block ? bi : (int64_t)id));
    sqlite3_stmt *q = NULL;
    const char *sql = is_block ? "INSERT OR REPLACE INTO ft_layout(bi, bj, version, n, crc, data, steps, loss) "
                                 "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8)"
                               : "INSERT OR REPLACE INTO ft_objects(id, version, n, crc, data, steps, loss) "
                                 "VALUES(?1, ?3, ?4, ?5, ?6, ?7, ?8)";
    int rc = sqlite3_prepare_v2(s->db, sql, -1, &q, NULL);
    if (rc != SQLITE_OK) return sooc__mapstore_dberr(s, rc, "writing a finetuned decoder");
    if (is_block) {
        sqlite3_bind_int(q, 1, bi);
        sqlite3_bind_int(q, 2, bj);
    } else {
        sqlite3_bind_int64(q, 1, (sqlite3_int64)id);
    }
    sqlite3_bind_int(q, 3, FT_BLOB_VERSION);
    sqlite3_bind_int64(q, 4, (sqlite3_int64)n);
    sqlite3_bind_int64(q, 5, (sqlite3_int64)sooc_crc32(0, v, n * sizeof(float)));
    sqlite3_bind_blob(q, 6, v, (int)(n * sizeof(float)), SQLITE_STATIC);
    sqlite3_bind_int(q, 7, steps);
    if (isfinite(loss)) sqlite3_bind_double(q, 8, loss);
    else sqlite3_bind_null(q, 8);
    rc = sqlite3_step(q);
    sqlite3_finalize(q);
    return rc == SQLITE_DONE ? SOOC_OK : sooc__mapstore_dberr(s, rc, "writing a finetuned decoder");
}

sooc_status sooc_mapstore_ft_put(sooc_mapstore *s, int is_block, uint64_t id, int32_t bi, int32_t bj, const float *v,
                                 size_t n, int steps, double loss) {
    sooc_status st = ft_need(s);
    if (st) return st;
    if (!is_block) {   /* only for a stored entry */
        sooc_cogmap_entry e;
        if ((st = sooc_mapstore_get(s, id, &e))) return st;
    }
    int own = !s->in_txn;
    if (own && (st = sooc_mapstore_begin(s))) return st;
    st = ft_put_row(s, is_block, id, bi, bj, v, n, steps, loss);
    if (!own) return st;
    if (st) {
        sooc_mapstore_rollback(s);
        return st;
    }
    return sooc_mapstore_commit(s);
}

sooc_status sooc_mapstore_ft_get(sooc_mapstore *s, int is_block, uint64_t id, int32_t bi, int32_t bj, int *found,
                                 int *steps, double *loss) {
    *found = 0;
    if (s->schema < 2) return SOOC_OK;
    sqlite3_stmt *q = NULL;
    const char *sql = is_block ? "SELECT steps, loss FROM ft_layout WHERE bi = ?1 AND bj = ?2"
                               : "SELECT steps, loss FROM ft_objects WHERE id = ?3";
    int rc = sqlite3_prepare_v2(s->db, sql, -1, &q, NULL);
    if (rc != SQLITE_OK) return sooc__mapstore_dberr(s, rc, "reading a finetuned decoder");
    if (is_block) {
        sqlite3_bind_int(q, 1, bi);
        sqlite3_bind_int(q, 2, bj);
    } else {
        sqlite3_bind_int64(q, 3, (sqlite3_int64)id);
    }
    rc = sqlite3_step(q);
    if (rc == SQLITE_ROW) {
        *found = 1;
        if (steps) *steps = sqlite3_column_int(q, 0);
        if (loss) *loss = sqlite3_column_type(q, 1) == SQLITE_NULL ? NAN : sqlite3_column_double(q, 1);
    }
    sqlite3_finalize(q);
    return rc == SQLITE_ROW || rc == SQLITE_DONE ? SOOC_OK : sooc__mapstore_dberr(s, rc, "reading a finetuned decoder");
}

static sooc_status count_rows(sooc_mapstore *s, const char *sql, uint64_t *n) {
    sqlite3_stmt *q = NULL;
    int rc = sqlite3_prepare_v2(s->db, sql, -1, &q, NULL);
    if (rc == SQLITE_OK) rc = sqlite3_step(q);
    if (rc == SQLITE_ROW) *n = (uint64_t)sqlite3_column_int64(q, 0);
    sqlite3_finalize(q);
    return rc == SQLITE_ROW ? SOOC_OK : sooc__mapstore_dberr(s, rc, "counting finetuned decoders");
}

sooc_status sooc_mapstore_ft_count(sooc_mapstore *s, uint64_t *n_objects, uint64_t *n_blocks) {
    *n_objects = *n_blocks = 0;
    if (s->schema < 2) return SOOC_OK;
    sooc_status st = count_rows(s, "SELECT count(*) FROM ft_objects", n_objects);
    return st ? st : count_rows(s, "SELECT count(*) FROM ft_layout", n_blocks);
}

sooc_status sooc_mapstore_ft_clear(sooc_mapstore *s) {
    sooc_status st = ft_need(s);
    if (st) return st;
    return sooc__mapstore_exec(s, "DELETE FROM ft_objects; DELETE FROM ft_layout;", "clearing finetuned decoders");
}

sooc_status sooc__mapstore_ft_load(sooc_mapstore *s, sooc_cogmap *map) {
    if (s->schema < 2) return SOOC_OK;
    sooc_status st = SOOC_OK;
    for (int blk = 0; blk < 2 && !st; blk++) {
        sqlite3_stmt *q = NULL;
        const char *sql = blk ? "SELECT 0, bi, bj, version, n, crc, data FROM ft_layout ORDER BY bi, bj"
                              : "SELECT id, 0, 0, version, n, crc, data FROM ft_objects ORDER BY id";
        int rc = sqlite3_prepare_v2(s->db, sql, -1, &q, NULL);
        if (rc != SQLITE_OK) return sooc__mapstore_dberr(s, rc, "reading finetuned decoders");
        while ((rc = sqlite3_step(q)) == SQLITE_ROW) {
            uint64_t id = (uint64_t)sqlite3_column_int64(q, 0);
            int bi = sqlite3_column_int(q, 1), bj = sqlite3_column_int(q, 2);
            int64_t n = sqlite3_column_int64(q, 4);
            const void *data = sqlite3_column_blob(q, 6);
            int nb = sqlite3_column_bytes(q, 6);
            char what[64];
            if (blk) snprintf(what, sizeof what, "layout block (%d, %d)", bi, bj);
            else snprintf(what, sizeof what, "entry %llu", (unsigned long long)id);
            if (sqlite3_column_int(q, 3) != FT_BLOB_VERSION) {
                st = sooc_seterr(SOOC_EVERSION, "%s: finetuned decoder of %s has version %d, this build reads %d",
                                 s->path, what, sqlite3_column_int(q, 3), FT_BLOB_VERSION);
                break;
            }
            if (n <= 0 || !data || (int64_t)nb != n * (int64_t)sizeof(float) ||
                (uint32_t)sqlite3_column_int64(q, 5) != sooc_crc32(0, data, (size_t)nb)) {
                st = sooc_seterr(SOOC_EFORMAT, "%s: finetuned decoder of %s is corrupt (size or CRC mismatch)",
                                 s->path, what);
                break;
            }
            sooc_cogmap_entry e;
            if (!blk && sooc_cogmap_get(map, id, &e) != SOOC_OK) {   /* entry gone: ignore its decoder */
                sooc_clearerr();
                continue;
            }
            float *v = sooc_malloc((size_t)nb);
            if (!v) {
                st = SOOC_ENOMEM;
                break;
            }
            memcpy(v, data, (size_t)nb);
            st = blk ? sooc_cogmap_block_payload_set(map, bi, bj, v, (size_t)n)
                     : sooc_cogmap_payload_set(map, id, v, (size_t)n);
            sooc_free(v);
            if (st) {
                sooc_adderr(st, "%s: finetuned decoder of %s", s->path, what);
                break;
            }
        }
        if (!st && rc != SQLITE_DONE) st = sooc__mapstore_dberr(s, rc, "reading finetuned decoders");
        sqlite3_finalize(q);
    }
    return st;
}

typedef struct ft_save_ctx {
    sooc_mapstore *s;
    const sooc_cogmap *map;
    sooc_status st;
} ft_save_ctx;

static int ft_save_cb(void *u, int is_block, uint64_t id, int32_t bi, int32_t bj, const float *v, size_t n) {
    ft_save_ctx *c = u;
    sooc_cogmap_entry e;
    if (!is_block && sooc_cogmap_get(c->map, id, &e) != SOOC_OK) {
        sooc_clearerr();
        return 0;
    }
    c->st = ft_put_row(c->s, is_block, id, bi, bj, v, n, 0, NAN);
    return c->st != SOOC_OK;
}

sooc_status sooc__mapstore_ft_save(sooc_mapstore *s, const sooc_cogmap *map) {
    if (s->schema < 2) return SOOC_OK;
    sooc_status st = sooc__mapstore_exec(s, "DELETE FROM ft_objects; DELETE FROM ft_layout;", "clearing finetuned decoders");
    if (st) return st;
    ft_save_ctx c = {s, map, SOOC_OK};
    sooc_cogmap_payload_foreach(map, ft_save_cb, &c);
    return c.st;
}

