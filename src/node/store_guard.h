/* The node's map database under storage faults (docs/node.md "Faults").
 * Internal to the node; runs on the mapping thread only.
 *
 * Every change the publisher makes (entries written or removed, layout
 * blocks, the id counter, meta values, the world frame, keyframe rows) is
 * queued here, then written in one transaction by sooc_sg_flush. When that
 * transaction fails for a reason of the storage (disk full, I/O error, the
 * database locked by another process, ...), it is rolled back, the queue is
 * kept and the guard turns FAILING: the node maps on in memory and publishes
 * the table; the queue keeps only the latest state of each object (so it is
 * bounded by the map, not by the time spent failing) and at most
 * SOOC_NODE_STORE_ROWS_MAX keyframe rows (the oldest are dropped first).
 * Retries follow an exponential backoff (retry_s, doubling up to
 * retry_max_s); the first one that commits writes everything queued and turns
 * the guard OK again. Each change of state is logged once, with the database
 * path and SQLite's reason. After a full disk, each retry first checkpoints
 * the WAL into the database and cuts the WAL file; so does each of the next
 * 1000 commits, and every commit while less than 16 MB are free on the
 * database's file system, so that the WAL (which SQLite lets grow to about
 * 4 MB before its own checkpoint) does not hold the space the map needs. A transaction either commits whole or leaves the
 * database as it was, so nothing committed is ever lost. */
#ifndef SOOC3D_NODE_STORE_GUARD_H
#define SOOC3D_NODE_STORE_GUARD_H

#include "sooc3d/cogmap.h"

typedef struct sooc_sg sooc_sg;

/* One keyframe row (mapstore keyframes table). */
typedef struct sooc_sg_row {
    int64_t t_ns;
    int32_t view;
    double T_wc[16];
    uint32_t n_changed, n_removed;
    int64_t n_entries;
} sooc_sg_row;

typedef struct sooc_sg_status {
    int state;                 /* SOOC_NODE_STORE_OK or _FAILING (node.h) */
    int fault;                 /* sooc_mapstore_fault of the latest failure (0: none yet) */
    uint64_t pending;          /* objects to write or delete */
    uint64_t pending_kf;       /* keyframe rows */
    uint64_t failures, recoveries, kf_dropped;
    int64_t committed_ns;      /* t_ns of the newest keyframe row committed (INT64_MIN: none) */
    double since;              /* sooc_seconds() of the latest change of state */
} sooc_sg_status;

/* Opens (creates) the store for a guard that has none yet. */
typedef sooc_status (*sooc_sg_open_fn)(void *ctx, sooc_mapstore **out);

/* The guard of the store at `path`: s, open (not owned: the caller closes
 * it after sooc_sg_destroy), or NULL when it could not be created for a
 * reason of the storage: the guard then starts FAILING (logged once, with
 * the reason left by the failed open) and each retry first calls
 * open(ctx, &s). layout_dim: size of the layout latents queued (0: none). */
sooc_status sooc_sg_create(sooc_sg **out, sooc_mapstore *s, const char *path, int layout_dim, double retry_s,
                           double retry_max_s, sooc_sg_open_fn open, void *ctx);
void sooc_sg_destroy(sooc_sg *g);

/* Queue changes (copied). */
sooc_status sooc_sg_put(sooc_sg *g, const sooc_map_entry *e);
sooc_status sooc_sg_remove(sooc_sg *g, uint64_t id);
sooc_status sooc_sg_layout(sooc_sg *g, int32_t bi, int32_t bj, const float *mu, const float *logvar);
void sooc_sg_next_id(sooc_sg *g, uint64_t next_id);
sooc_status sooc_sg_meta(sooc_sg *g, const char *key, const char *value);
void sooc_sg_world(sooc_sg *g, const sooc_map_frame *f);
void sooc_sg_row_add(sooc_sg *g, const sooc_sg_row *r);
int sooc_sg_pending(const sooc_sg *g);   /* 1 when anything waits */

/* Write everything queued in one transaction: at once when the store works
 * or force = 1, else only once the backoff since the last failure has passed
 * (now: sooc_seconds()). A storage fault is absorbed (SOOC_OK, state
 * FAILING, logged on a change of state); an error is returned only for a
 * failure that no retry can mend (a value the database refuses: SOOC_EINVAL,
 * SOOC_ENUMERIC; or no memory for the queue). */
sooc_status sooc_sg_flush(sooc_sg *g, double now, int force);
void sooc_sg_status_get(const sooc_sg *g, sooc_sg_status *out);
/* The database path and SQLite's reason of the latest failure ("" if none). */
const char *sooc_sg_reason(const sooc_sg *g);

#endif
