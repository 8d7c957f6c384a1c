/*
 * sooc3d persistent map: the cognitive map in an SQLite database
 * (docs/cogmap.md "Persistent store (SQLite)").
 *
 *  - WAL journal (readers never block the mapping thread), synchronous=NORMAL.
 *  - One transaction per keyframe: sooc_mapstore_commit_keyframe() writes the
 *    entries registered by the view, deletes the removed ones, stores the
 *    layout block, the id counter and a keyframe row, atomically. Lower-level
 *    begin/put/remove/commit calls exist for other uses.
 *  - An R*Tree virtual table `entries_rtree(id, min_x, max_x, min_z, max_z)`
 *    indexes the floor position; triggers on `entries` keep it in sync.
 *  - Restart: sooc_mapstore_load_map() puts every entry, layout block and the
 *    id counter back into a sooc_cogmap; new ids continue after the stored
 *    counter (ids of removed entries are never handed out again).
 *
 * Schema (version 1):
 *   meta(key TEXT PRIMARY KEY, value TEXT)  app='sooc3d-map', schema_version,
 *        model_id, dim, layout_dim, block_size, next_id
 *   entries(id INTEGER PRIMARY KEY, x, z, yaw, rho_t, rho_yaw, pres_logit REAL,
 *        dim, latent_version INTEGER, what_mu, what_logvar BLOB,
 *        first_seen_ns, last_seen_ns, obs_count, last_view INTEGER)
 *   entries_rtree  (R*Tree, see above)
 *   layout(bi, bj, dim, latent_version, mu BLOB, logvar BLOB, PRIMARY KEY(bi, bj))
 *   keyframes(seq INTEGER PRIMARY KEY, t_ns, view, tx, ty, tz, qx, qy, qz, qw,
 *        n_changed, n_removed, n_entries)
 * Latent blobs, latent_version 1: dim little-endian IEEE float32 values.
 *
 * Schema version 2 adds the finetuned decoders (finetune.h):
 *   ft_objects(id INTEGER PRIMARY KEY, version, n, crc, data BLOB, steps, loss)
 *   ft_layout(bi, bj, version, n, crc, data BLOB, steps, loss, PRIMARY KEY(bi, bj))
 *   trigger entries_ad_ft: deleting an entry deletes its decoder.
 * data: n little-endian float32 (a cogmap payload), crc = CRC-32 of its bytes,
 * version 1. A version-1 map is migrated on its first read-write open (one
 * transaction: the tables, then schema_version 2); opened read-only it reads
 * as a version-1 map, without finetuned decoders. load_map puts the stored decoders
 * into the map's payloads (cogmap.h); save_map stores the map's payloads.
 *
 * Schema version 3 adds the object geometry for planners
 * (include/sooc3d/objgeom.h, docs/shm.md):
 *   entry_geometry(id INTEGER PRIMARY KEY, flags, ext_x, ext_y, ext_z,
 *        centre_x, centre_y, centre_z, sym_score, cov_xx, cov_xz, cov_zz,
 *        var_yaw (NULL = undefined), reg_n, reg_mean_x, reg_mean_z, reg_m2_xx,
 *        reg_m2_xz, reg_m2_zz, reg_cos, reg_sin)
 *   trigger entries_ad_geom: deleting an entry deletes its geometry.
 * Migrations apply in order on a read-write open, one transaction each
 * (1 -> 2, then 2 -> 3); a read-only open of an older map reads no geometry.
 *
 * Errors: every failure message starts with the database path; a file that is
 * not an SQLite database, not a sooc3d map, or corrupt gives SOOC_EFORMAT, a
 * schema/dimension/model mismatch SOOC_EVERSION, a missing file (create = 0)
 * SOOC_ENOTFOUND.
 *
 * Thread-safety: one sooc_mapstore per thread. Other processes may read the
 * same file concurrently (WAL).
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_MAPSTORE_H
#define SOOC3D_MAPSTORE_H

#include "sooc3d/core.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/mapper.h"   /* sooc_map_geometry */

#ifdef __cplusplus
extern "C" {
#endif

#define SOOC_MAPSTORE_SCHEMA_VERSION 3
#define SOOC_MAPSTORE_LATENT_VERSION 1

typedef struct sooc_mapstore sooc_mapstore;

typedef struct sooc_mapstore_params {
    int create;            /* create the file if missing, and its folder          (1) */
    int readonly;          /* open read-only (the file must exist); needs only read
                              permission on the file: with no un-checkpointed -wal
                              left it opens immutable, so a folder the reader
                              cannot write is fine                              (0) */
    const char *model_id;  /* stored on creation; on open a non-empty stored id must
                              match (SOOC_EVERSION), an empty stored id is set to it
                              (read-write opens); NULL = no check              (NULL) */
    int dim, layout_dim;   /* 0 = take from the file; else stored / must match   (0) */
    double block_size;     /* layout block side stored on creation; 0 = not set  (0) */
} sooc_mapstore_params;

void sooc_mapstore_params_default(sooc_mapstore_params *p);

/* Open or create the database at `path`. On failure *out = NULL. */
sooc_status sooc_mapstore_open(sooc_mapstore **out, const char *path, const sooc_mapstore_params *p);
/* Close (rolls back an open transaction). NULL-safe. */
void sooc_mapstore_close(sooc_mapstore *s);
const char *sooc_mapstore_path(const sooc_mapstore *s);

typedef struct sooc_mapstore_info {
    int schema_version;
    char model_id[128];
    int dim, layout_dim;
    double block_size;
    uint64_t next_id;
    uint64_t n_entries, n_layout, n_keyframes;
    char journal_mode[16];  /* "wal" */
} sooc_mapstore_info;
sooc_status sooc_mapstore_info_get(sooc_mapstore *s, sooc_mapstore_info *out);

/* ---------------------------------------------------- keyframe commit */

typedef struct sooc_mapstore_keyframe {
    int64_t t_ns;
    int32_t view;
    double T_wc[16];
    const uint64_t *changed;   /* ids written by this view (0s are skipped), read from the map */
    size_t n_changed;
    const uint64_t *removed;   /* ids removed by this view */
    size_t n_removed;
    int has_block;             /* 1: also store layout block (bi, bj) from the map */
    int32_t bi, bj;
} sooc_mapstore_keyframe;

/* One transaction: upsert the changed entries (taken from `map`), delete the
 * removed ids, store the layout block and map->next_id, append a keyframe
 * row. On failure the database is unchanged. The dims of `map` must match. */
sooc_status sooc_mapstore_commit_keyframe(sooc_mapstore *s, const sooc_cogmap *map,
                                          const sooc_mapstore_keyframe *kf);

/* Replace the stored map by a full snapshot of `map` (one transaction). */
sooc_status sooc_mapstore_save_map(sooc_mapstore *s, const sooc_cogmap *map);
/* Load every entry, layout block and the id counter into `map` (its entries
 * are replaced; dims must match). */
sooc_status sooc_mapstore_load_map(sooc_mapstore *s, sooc_cogmap *map);

/* ----------------------------------------------------- low-level API */

sooc_status sooc_mapstore_begin(sooc_mapstore *s);
sooc_status sooc_mapstore_commit(sooc_mapstore *s);
void sooc_mapstore_rollback(sooc_mapstore *s);
/* Upsert entries (e[i].dim must equal the store's dim). */
sooc_status sooc_mapstore_put_entries(sooc_mapstore *s, const sooc_cogmap_entry *e, size_t n);
/* Delete ids (absent ids are ignored). */
sooc_status sooc_mapstore_remove_entries(sooc_mapstore *s, const uint64_t *ids, size_t n);
sooc_status sooc_mapstore_put_layout(sooc_mapstore *s, int32_t bi, int32_t bj, const float *mu,
                                     const float *logvar);
/* Append a keyframe row (t_ns, view, pose, counts from kf; changed ids are
 * only counted, not written). n_entries: map size after the keyframe, or -1
 * if unknown. Use inside begin/commit to keep one transaction per keyframe. */
sooc_status sooc_mapstore_add_keyframe(sooc_mapstore *s, const sooc_mapstore_keyframe *kf, int64_t n_entries);
/* Raise the stored id counter to at least `next_id`. */
sooc_status sooc_mapstore_set_next_id(sooc_mapstore *s, uint64_t next_id);

/* ---------------------------------------------------------- reading */

/* Visit entries in id order: all of them, or those whose (x, z) lies in the
 * closed box [x0, x1] x [z0, z1] (R*Tree lookup, exact filter). A non-zero
 * return from fn stops the walk (the function then returns SOOC_OK).
 * fn must not use the store. */
sooc_status sooc_mapstore_foreach(sooc_mapstore *s, sooc_cogmap_visit_fn fn, void *user);
sooc_status sooc_mapstore_query_box(sooc_mapstore *s, double x0, double z0, double x1, double z1,
                                    sooc_cogmap_visit_fn fn, void *user);
/* Visit every stored layout block, ordered by (bi, bj) (nothing if the map
 * has no layout latents). A non-zero return from fn stops the walk. */
sooc_status sooc_mapstore_foreach_layout(sooc_mapstore *s, sooc_cogmap_block_fn fn, void *user);

/* Application meta values (e.g. the node's box extent "0.6 1.2 0.6"). The
 * schema's own keys (app, schema_version, model_id, dim, layout_dim,
 * block_size, next_id) are refused. get: SOOC_ENOTFOUND if absent. */
sooc_status sooc_mapstore_meta_set(sooc_mapstore *s, const char *key, const char *value);
sooc_status sooc_mapstore_meta_get(sooc_mapstore *s, const char *key, char *buf, size_t cap);

/* ------------------------------------------- finetuned decoders (schema 2) */

/* Store (replace) the finetuned decoder of entry `id` (is_block 0; the entry
 * must be stored: SOOC_ENOTFOUND) or of layout block (bi, bj) (is_block 1):
 * v[0..n) as sooc_finetune_unit_payload gives it, the Adam steps it took and
 * its last loss (NAN: none). Its own transaction unless one is open, so a
 * finetuning run commits object by object. Non-finite values: SOOC_ENUMERIC.
 * A version-1 map opened read-only: SOOC_EUNSUPPORTED. */
sooc_status sooc_mapstore_ft_put(sooc_mapstore *s, int is_block, uint64_t id, int32_t bi, int32_t bj, const float *v,
                                 size_t n, int steps, double loss);
/* Is a decoder stored for this entry / block? *found = 0 or 1 (steps, loss
 * may be NULL). */
sooc_status sooc_mapstore_ft_get(sooc_mapstore *s, int is_block, uint64_t id, int32_t bi, int32_t bj, int *found,
                                 int *steps, double *loss);
sooc_status sooc_mapstore_ft_count(sooc_mapstore *s, uint64_t *n_objects, uint64_t *n_blocks);
/* Delete every stored decoder (sooc3d finetune --restart). */
sooc_status sooc_mapstore_ft_clear(sooc_mapstore *s);

/* The distinct view indices of the stored keyframes, ascending: *n = their
 * number; the first min(n, cap) go to views (may be NULL). */
sooc_status sooc_mapstore_keyframe_views(sooc_mapstore *s, int64_t *views, size_t cap, size_t *n);

/* ------------------------------------------- object geometry (schema 3) */

/* Store (replace) entry id's geometry: its extent (tight box, or the
 * locality box when g->flags has no SOOC_GEOM_TIGHT) and g (mapper.h).
 * Use inside the keyframe's transaction. Non-finite values other than an
 * undefined (NaN) yaw variance: SOOC_ENUMERIC. */
sooc_status sooc_mapstore_geom_put(sooc_mapstore *s, uint64_t id, const float extent[3], const sooc_map_geometry *g);
/* Read it back: *found = 0 (extent, g untouched) when none is stored or the
 * map predates schema 3. */
sooc_status sooc_mapstore_geom_get(sooc_mapstore *s, uint64_t id, float extent[3], sooc_map_geometry *g, int *found);

/* Planner entries: every entry of the map as a planner receives it (the
 * shm table, `sooc3d map list`, `map at`): sooc_map_entry_from_cogmap plus
 * its stored box and spreads where the map has them. *out (sooc_free) gets
 * *n entries in id order; on failure *out = NULL, *n = 0. */
sooc_status sooc_mapstore_planner_entries(sooc_mapstore *s, sooc_map_entry **out, size_t *n);

/* Fetch one entry by id (SOOC_ENOTFOUND if absent). */
sooc_status sooc_mapstore_get(sooc_mapstore *s, uint64_t id, sooc_cogmap_entry *out);

/* ------------------------------------------------------- world frame */

/* The map's world frame (support plane, include/sooc3d/support.h): how the
 * pose source's frame maps into the gravity-aligned world the map lives in.
 * Stored as meta key "world_frame" (text: "v1" then the values with %.17g,
 * so a round trip is exact). The node writes it when it first estimates (or
 * is given) the frame; resume, render, eval and map export read it back. */
typedef struct sooc_map_frame {
    double T_world_src[16];  /* p_world = T_world_src * p_src, row-major, rigid      */
    double up_src[3];        /* unit up direction in the source frame                */
    double plane_src[4];     /* support plane n . p + d = 0 in the source frame      */
    double cam_height_m;     /* mean camera height over the plane when estimated     */
    int up_source;           /* sooc_up_source (support.h): 0 given, 1 gravity file,
                                2 camera mean; -1 = world.floor: given (no estimate) */
} sooc_map_frame;

/* Store (replace) the world frame. Fails on a non-finite value or a
 * T_world_src that is not rigid (rotation part off orthonormal by > 1e-6). */
sooc_status sooc_mapstore_frame_put(sooc_mapstore *s, const sooc_map_frame *f);
/* Read the world frame: *found = 1 and *f filled, or *found = 0 (f untouched)
 * when the map has none. A malformed stored value is SOOC_EFORMAT naming the
 * database. */
sooc_status sooc_mapstore_frame_get(sooc_mapstore *s, sooc_map_frame *f, int *found);

/* ---------------------------------------------------- storage faults */

/* What a failed call met in SQLite, for callers that go on when the storage
 * fails (the node: docs/node.md "Faults"). */
typedef enum sooc_mapstore_fault {
    SOOC_MAPSTORE_FAULT_NONE = 0,   /* no SQLite failure since the last begin           */
    SOOC_MAPSTORE_FAULT_FULL,       /* SQLITE_FULL: the disk or file system is full     */
    SOOC_MAPSTORE_FAULT_IO,         /* SQLITE_IOERR, CANTOPEN, READONLY, PROTOCOL       */
    SOOC_MAPSTORE_FAULT_BUSY,       /* SQLITE_BUSY / LOCKED: another connection holds
                                       the lock longer than the busy timeout            */
    SOOC_MAPSTORE_FAULT_CORRUPT,    /* SQLITE_CORRUPT / NOTADB                          */
    SOOC_MAPSTORE_FAULT_NOMEM,      /* SQLITE_NOMEM                                     */
    SOOC_MAPSTORE_FAULT_OTHER
} sooc_mapstore_fault;

/* The fault of the last SQLite call that failed since the last
 * sooc_mapstore_begin (NONE if none did: a failure then came from the data,
 * e.g. a dimension mismatch or a non-finite value). */
sooc_mapstore_fault sooc_mapstore_last_fault(const sooc_mapstore *s);
/* The fault of this thread's last sooc_mapstore_open that failed in SQLite
 * (NONE when it failed for another reason: not a map, a version, a model). */
sooc_mapstore_fault sooc_mapstore_open_fault(void);
/* "disk full", "I/O error", "locked by another connection", ... */
const char *sooc_mapstore_fault_name(sooc_mapstore_fault f);
/* *empty = 1 when `path` is an SQLite file without any table (what a
 * creation that failed, e.g. on a full disk, leaves behind). */
sooc_status sooc_mapstore_file_empty(const char *path, int *empty);
/* How long a write waits for a lock another connection holds before it fails
 * with SOOC_EBUSY (opened with 5000 ms). */
sooc_status sooc_mapstore_set_busy_timeout(sooc_mapstore *s, int ms);
/* Copy the WAL into the database file (truncate = 1: and cut the WAL file to
 * zero bytes, which frees its space on a full disk). Not inside a transaction. */
sooc_status sooc_mapstore_checkpoint(sooc_mapstore *s, int truncate);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_MAPSTORE_H */
