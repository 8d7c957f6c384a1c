/* The node's map database under storage faults: see store_guard.h. */
#include "node/store_guard.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/statvfs.h>

#include "sooc3d/mapper.h"   /* SOOC_MAPPER_CHANGED_MAX */
#include "sooc3d/node.h"     /* SOOC_NODE_STORE_*, SOOC_NODE_STORE_ROWS_MAX */

#define SG_META_MAX 4
#define SG_LOW_SPACE_COMMITS 1000   /* commits after a full disk that each checkpoint and cut the WAL */
#define SG_LOW_SPACE_BYTES (16.0 * 1024 * 1024)   /* free space below which the WAL is cut after each commit */

typedef struct pend_ent {
    uint64_t id;
    int del;                  /* 1: delete the id; 0: write e */
    uint32_t slot;            /* its slot in the hash index */
    sooc_map_entry e;
} pend_ent;

typedef struct pend_blk {
    int32_t bi, bj;
    float mu[SOOC_MAP_LATENT_MAX], lv[SOOC_MAP_LATENT_MAX];
} pend_blk;

struct sooc_sg {
    sooc_mapstore *s;         /* NULL until open() succeeds */
    sooc_sg_open_fn open;
    void *open_ctx;
    char path[1024];
    int layout_dim;
    double retry_s, retry_max_s;

    pend_ent *pe;             /* queued objects, one per id (its latest state) */
    size_t n_pe, cap_pe;
    uint32_t *hash;           /* id -> pe index + 1 (0 = empty), linear probing */
    size_t hcap;
    pend_blk *pb;
    size_t n_pb, cap_pb;
    uint64_t next_id;
    int has_next_id;
    char meta_key[SG_META_MAX][32], meta_val[SG_META_MAX][256];
    int n_meta;
    sooc_map_frame world;
    int has_world;
    sooc_sg_row *rows;        /* ring of queued keyframe rows */
    size_t r_head, n_rows, cap_rows;
    uint64_t ones[SOOC_MAPPER_CHANGED_MAX];   /* stand-in ids: a row stores counts only */

    int state, fault;
    int consecutive;          /* failed attempts in a row */
    int low_space;            /* commits left in low-space mode (after a full disk): the WAL is cut after each */
    double next_try, since;
    uint64_t failures, recoveries, kf_dropped;
    int64_t committed_ns;
    char reason[600];
    char dir[1024];           /* the database's folder (free-space checks) */
    int low_logged;
};

static uint64_t mix64(uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdull;
    k ^= k >> 33;
    return k;
}

static void fail_state(sooc_sg *g, sooc_mapstore_fault f, double now, size_t n_obj);

sooc_status sooc_sg_create(sooc_sg **out, sooc_mapstore *s, const char *path, int layout_dim, double retry_s,
                           double retry_max_s, sooc_sg_open_fn open, void *ctx) {
    *out = NULL;
    sooc_sg *g = sooc_calloc(1, sizeof *g);
    if (!g) return sooc_seterr(SOOC_ENOMEM, "node: map store queue: out of memory");
    g->s = s;
    g->layout_dim = layout_dim > SOOC_MAP_LATENT_MAX ? SOOC_MAP_LATENT_MAX : layout_dim;
    g->retry_s = retry_s > 0 ? retry_s : 0;
    g->retry_max_s = retry_max_s > g->retry_s ? retry_max_s : g->retry_s;
    for (int i = 0; i < SOOC_MAPPER_CHANGED_MAX; i++) g->ones[i] = 1;
    g->state = SOOC_NODE_STORE_OK;
    g->committed_ns = INT64_MIN;
    g->since = sooc_seconds();
    g->open = open;
    g->open_ctx = ctx;
    snprintf(g->path, sizeof g->path, "%s", path);
    snprintf(g->dir, sizeof g->dir, "%s", path);
    char *slash = strrchr(g->dir, '/');
    if (slash) *slash = 0;
    else snprintf(g->dir, sizeof g->dir, ".");
    if (!g->dir[0]) snprintf(g->dir, sizeof g->dir, "/");
    if (!s) {   /* could not be created: failing from the start, the reason is the open's */
        sooc_mapstore_fault f = sooc_mapstore_open_fault();
        fail_state(g, f ? f : SOOC_MAPSTORE_FAULT_OTHER, g->since, 0);
    }
    *out = g;
    return SOOC_OK;
}

void sooc_sg_destroy(sooc_sg *g) {
    if (!g) return;
    sooc_free(g->pe);
    sooc_free(g->hash);
    sooc_free(g->pb);
    sooc_free(g->rows);
    sooc_free(g);
}

/* ------------------------------------------------------------- the queue */

static int rehash(sooc_sg *g, size_t cap) {
    uint32_t *h = sooc_calloc(cap, sizeof *h);
    if (!h) return -1;
    for (size_t i = 0; i < g->n_pe; i++) {
        size_t k = mix64(g->pe[i].id) & (cap - 1);
        while (h[k]) k = (k + 1) & (cap - 1);
        h[k] = (uint32_t)(i + 1);
        g->pe[i].slot = (uint32_t)k;
    }
    sooc_free(g->hash);
    g->hash = h;
    g->hcap = cap;
    return 0;
}

/* The queued record of id, created (del = 0, e zeroed) when absent. */
static pend_ent *ent_of(sooc_sg *g, uint64_t id) {
    if (g->hcap) {
        size_t k = mix64(id) & (g->hcap - 1);
        while (g->hash[k]) {
            pend_ent *p = &g->pe[g->hash[k] - 1];
            if (p->id == id) return p;
            k = (k + 1) & (g->hcap - 1);
        }
    }
    if (g->n_pe + 1 > g->cap_pe) {
        size_t nc = g->cap_pe ? 2 * g->cap_pe : 64;
        pend_ent *q = sooc_realloc(g->pe, nc * sizeof *q);
        if (!q) return NULL;
        g->pe = q;
        g->cap_pe = nc;
    }
    if (2 * (g->n_pe + 1) > g->hcap && rehash(g, g->hcap ? 2 * g->hcap : 128)) return NULL;
    pend_ent *p = &g->pe[g->n_pe];
    memset(p, 0, sizeof *p);
    p->id = id;
    size_t k = mix64(id) & (g->hcap - 1);
    while (g->hash[k]) k = (k + 1) & (g->hcap - 1);
    g->hash[k] = (uint32_t)(++g->n_pe);
    p->slot = (uint32_t)k;
    return p;
}

sooc_status sooc_sg_put(sooc_sg *g, const sooc_map_entry *e) {
    pend_ent *p = ent_of(g, e->id);
    if (!p) return sooc_seterr(SOOC_ENOMEM, "node: map store queue: out of memory");
    p->del = 0;
    p->e = *e;
    return SOOC_OK;
}

sooc_status sooc_sg_remove(sooc_sg *g, uint64_t id) {
    pend_ent *p = ent_of(g, id);
    if (!p) return sooc_seterr(SOOC_ENOMEM, "node: map store queue: out of memory");
    p->del = 1;
    return SOOC_OK;
}

sooc_status sooc_sg_layout(sooc_sg *g, int32_t bi, int32_t bj, const float *mu, const float *logvar) {
    if (!g->layout_dim) return SOOC_OK;
    pend_blk *b = NULL;
    for (size_t i = 0; i < g->n_pb && !b; i++)
        if (g->pb[i].bi == bi && g->pb[i].bj == bj) b = &g->pb[i];
    if (!b) {
        if (g->n_pb == g->cap_pb) {
            size_t nc = g->cap_pb ? 2 * g->cap_pb : 16;
            pend_blk *q = sooc_realloc(g->pb, nc * sizeof *q);
            if (!q) return sooc_seterr(SOOC_ENOMEM, "node: map store queue: out of memory");
            g->pb = q;
            g->cap_pb = nc;
        }
        b = &g->pb[g->n_pb++];
        b->bi = bi;
        b->bj = bj;
    }
    memcpy(b->mu, mu, (size_t)g->layout_dim * sizeof(float));
    memcpy(b->lv, logvar, (size_t)g->layout_dim * sizeof(float));
    return SOOC_OK;
}

void sooc_sg_next_id(sooc_sg *g, uint64_t next_id) {
    if (!g->has_next_id || next_id > g->next_id) g->next_id = next_id;
    g->has_next_id = 1;
}

sooc_status sooc_sg_meta(sooc_sg *g, const char *key, const char *value) {
    int i = 0;
    while (i < g->n_meta && strcmp(g->meta_key[i], key)) i++;
    if (i == SG_META_MAX || strlen(key) >= sizeof g->meta_key[0] || strlen(value) >= sizeof g->meta_val[0])
        return sooc_seterr(SOOC_EINVAL, "node: map store queue: meta '%s' does not fit", key);
    snprintf(g->meta_key[i], sizeof g->meta_key[i], "%s", key);
    snprintf(g->meta_val[i], sizeof g->meta_val[i], "%s", value);
    if (i == g->n_meta) g->n_meta++;
    return SOOC_OK;
}

void sooc_sg_world(sooc_sg *g, const sooc_map_frame *f) {
    g->world = *f;
    g->has_world = 1;
}

static sooc_sg_row *row_at(const sooc_sg *g, size_t i) { return &g->rows[(g->r_head + i) % g->cap_rows]; }

void sooc_sg_row_add(sooc_sg *g, const sooc_sg_row *r) {
    if (g->n_rows == g->cap_rows && g->cap_rows < SOOC_NODE_STORE_ROWS_MAX) {   /* grow, unrolling the ring */
        size_t nc = g->cap_rows ? 2 * g->cap_rows : 64;
        if (nc > SOOC_NODE_STORE_ROWS_MAX) nc = SOOC_NODE_STORE_ROWS_MAX;
        sooc_sg_row *q = sooc_malloc(nc * sizeof *q);
        if (q) {
            for (size_t i = 0; i < g->n_rows; i++) q[i] = *row_at(g, i);
            sooc_free(g->rows);
            g->rows = q;
            g->cap_rows = nc;
            g->r_head = 0;
        }
    }
    if (!g->cap_rows) {   /* no memory for even one row: the row is lost, the objects are not */
        g->kf_dropped++;
        return;
    }
    if (g->n_rows == g->cap_rows) {   /* full: the oldest row goes */
        g->r_head = (g->r_head + 1) % g->cap_rows;
        g->n_rows--;
        g->kf_dropped++;
    }
    *row_at(g, g->n_rows) = *r;
    g->n_rows++;
}

int sooc_sg_pending(const sooc_sg *g) {
    return g->n_pe || g->n_pb || g->has_next_id || g->n_meta || g->has_world || g->n_rows;
}

static void clear_queue(sooc_sg *g) {
    for (size_t i = 0; i < g->n_pe; i++) g->hash[g->pe[i].slot] = 0;
    g->n_pe = 0;
    g->n_pb = 0;
    g->has_next_id = 0;
    g->n_meta = 0;
    g->has_world = 0;
    g->n_rows = 0;
    g->r_head = 0;
}

/* ------------------------------------------------------------- writing */

static sooc_status write_all(sooc_sg *g) {
    sooc_mapstore *s = g->s;
    sooc_status st = sooc_mapstore_begin(s);
    if (st) return st;
    for (size_t i = 0; i < g->n_pe && !st; i++) {
        const pend_ent *p = &g->pe[i];
        if (p->del) {
            st = sooc_mapstore_remove_entries(s, &p->id, 1);
            continue;
        }
        sooc_cogmap_entry ce;
        sooc_map_entry_to_cogmap(&p->e, &ce);
        st = sooc_mapstore_put_entries(s, &ce, 1);
        if (!st && (p->e.geom.flags || p->e.geom.reg_n))   /* object geometry (schema 3) */
            st = sooc_mapstore_geom_put(s, p->id, p->e.extent, &p->e.geom);
    }
    for (int i = 0; i < g->n_meta && !st; i++) st = sooc_mapstore_meta_set(s, g->meta_key[i], g->meta_val[i]);
    for (size_t i = 0; i < g->n_pb && !st; i++) st = sooc_mapstore_put_layout(s, g->pb[i].bi, g->pb[i].bj, g->pb[i].mu, g->pb[i].lv);
    if (!st && g->has_next_id) st = sooc_mapstore_set_next_id(s, g->next_id);
    if (!st && g->has_world) st = sooc_mapstore_frame_put(s, &g->world);
    for (size_t i = 0; i < g->n_rows && !st; i++) {
        const sooc_sg_row *r = row_at(g, i);
        sooc_mapstore_keyframe k;
        memset(&k, 0, sizeof k);
        k.t_ns = r->t_ns;
        k.view = r->view;
        memcpy(k.T_wc, r->T_wc, sizeof k.T_wc);
        k.changed = g->ones;
        k.n_changed = r->n_changed < SOOC_MAPPER_CHANGED_MAX ? r->n_changed : SOOC_MAPPER_CHANGED_MAX;
        k.n_removed = r->n_removed;
        st = sooc_mapstore_add_keyframe(s, &k, r->n_entries);
    }
    if (st) {
        sooc_mapstore_rollback(s);
        return st;
    }
    return sooc_mapstore_commit(s);
}

static double backoff(const sooc_sg *g) {
    double d = g->retry_s;
    for (int i = 1; i < g->consecutive && d < g->retry_max_s; i++) d *= 2;
    return d < g->retry_max_s ? d : g->retry_max_s;
}

/* A failed attempt (the message of the failure is set): FAILING, logged when
 * the state or the fault changes, the next try after the backoff. */
static void fail_state(sooc_sg *g, sooc_mapstore_fault f, double now, size_t n_obj) {
    g->failures++;
    g->consecutive++;
    int changed = g->state != SOOC_NODE_STORE_FAILING || (int)f != g->fault;
    snprintf(g->reason, sizeof g->reason, "%s", sooc_errmsg());
    double delay = backoff(g);
    g->next_try = now + delay;
    if (changed) {
        sooc_log(SOOC_LOG_WARN,
                 "node: map store %s: %s (%s). Mapping goes on in memory and the table stays live; %zu objects "
                 "and %zu keyframes wait; retrying in %.3g s, backing off to %.3g s",
                 g->state == SOOC_NODE_STORE_FAILING ? "still failing, now" : "failing", g->reason,
                 sooc_mapstore_fault_name(f), n_obj, g->n_rows, delay, g->retry_max_s);
        if (g->state != SOOC_NODE_STORE_FAILING) g->since = now;
    } else {
        sooc_log(SOOC_LOG_DEBUG, "node: map store retry %d failed: %s", g->consecutive, g->reason);
    }
    g->state = SOOC_NODE_STORE_FAILING;
    g->fault = (int)f;
    if (f == SOOC_MAPSTORE_FAULT_FULL) g->low_space = SG_LOW_SPACE_COMMITS;
    sooc_clearerr();
}

sooc_status sooc_sg_flush(sooc_sg *g, double now, int force) {
    if (!sooc_sg_pending(g)) return SOOC_OK;
    if (g->state == SOOC_NODE_STORE_FAILING && !force && now < g->next_try) return SOOC_OK;
    if (!g->s) {   /* not created yet */
        sooc_status st = g->open(g->open_ctx, &g->s);
        if (st) {
            g->s = NULL;
            sooc_mapstore_fault f = sooc_mapstore_open_fault();
            if (f == SOOC_MAPSTORE_FAULT_NONE) return st;   /* not the storage's: no retry mends it */
            fail_state(g, f, now, g->n_pe);
            return SOOC_OK;
        }
    }
    if (g->state == SOOC_NODE_STORE_FAILING && g->fault == SOOC_MAPSTORE_FAULT_FULL) {
        /* a checkpoint that cuts the WAL file may free the space the next try needs */
        if (sooc_mapstore_checkpoint(g->s, 1)) sooc_clearerr();
    }
    struct statvfs vs;
    if (!g->low_space && !statvfs(g->dir, &vs) && (double)vs.f_bavail * (double)vs.f_frsize < SG_LOW_SPACE_BYTES) {
        g->low_space = SG_LOW_SPACE_COMMITS;
        if (!g->low_logged++)
            sooc_log(SOOC_LOG_INFO, "node: map store %s: %.0f KB left on its file system: the WAL is copied into "
                     "the database and cut after each commit", g->path,
                     (double)vs.f_bavail * (double)vs.f_frsize / 1024.0);
    }
    size_t n_obj = g->n_pe, n_kf = g->n_rows;
    sooc_status st = write_all(g);
    if (!st) {
        if (n_kf) g->committed_ns = row_at(g, n_kf - 1)->t_ns;
        clear_queue(g);
        if (g->low_space > 0) {   /* keep the WAL from taking the space the database needs */
            g->low_space--;
            if (sooc_mapstore_checkpoint(g->s, 1)) sooc_clearerr();
        }
        if (g->state == SOOC_NODE_STORE_FAILING) {
            sooc_log(SOOC_LOG_WARN,
                     "node: map store writable again: %s: wrote the %zu objects and %zu keyframes that waited, "
                     "after %d failed attempts over %.1f s",
                     g->path, n_obj, n_kf, g->consecutive, now - g->since);
            g->recoveries++;
            g->state = SOOC_NODE_STORE_OK;
            g->since = now;
        }
        g->consecutive = 0;
        return SOOC_OK;
    }
    sooc_mapstore_fault f = sooc_mapstore_last_fault(g->s);
    if (f == SOOC_MAPSTORE_FAULT_NONE || st == SOOC_EINVAL || st == SOOC_ENUMERIC) return st;   /* the data's */
    fail_state(g, f, now, n_obj);
    return SOOC_OK;
}

void sooc_sg_status_get(const sooc_sg *g, sooc_sg_status *o) {
    memset(o, 0, sizeof *o);
    o->state = g->state;
    o->fault = g->fault;
    o->pending = g->n_pe;
    o->pending_kf = g->n_rows;
    o->failures = g->failures;
    o->recoveries = g->recoveries;
    o->kf_dropped = g->kf_dropped;
    o->committed_ns = g->committed_ns;
    o->since = g->since;
}

const char *sooc_sg_reason(const sooc_sg *g) { return g->reason; }
