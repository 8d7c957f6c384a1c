/* The node's map database under storage faults (docs/node.md "Faults"), with
 * the fake mapper and the synthetic stream of node_fixture.h:
 *
 *   vfs    writes failed by a shim VFS (faulty_vfs.h): one failed write at
 *          every position of a run (disk full, I/O error), a window of failed
 *          writes across many keyframes, the backoff, and the database locked
 *          by another connection. After each run: the run succeeded, SQLite's
 *          integrity check passes, the database holds exactly the mapper's map
 *          (objects, layout blocks, id counter) and one row per keyframe, and
 *          each failure episode was logged once when it began and once when it
 *          ended. A run whose writes fail for good (negative control) ends
 *          with the store failing, the map and the database apart (the same
 *          comparison reports it), and the database as it was committed
 *          before the failure.
 *   tmpfs  the same on a real file system that fills: a 256 KB tmpfs mounted
 *          here (skipped when mounting is not allowed), filled up by a file
 *          the test removes later (or never: negative control).
 */
#include <errno.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "check.h"
#include "faulty_vfs.h"
#include "node_fixture.h"
#include "sooc3d/mapper.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"
#include "sooc3d/table.h"

int fake_mapper_get_block(const sooc_mapper *m, int32_t bi, int32_t bj, float *mu);

static char g_tmp[256], g_shm[64];
static atomic_int g_log_failing, g_log_still, g_log_back, g_log_end;

static void log_cb(void *user, sooc_log_level lv, const char *msg) {
    (void)user;
    if (strstr(msg, "map store failing")) atomic_fetch_add(&g_log_failing, 1);
    if (strstr(msg, "map store still failing, now")) atomic_fetch_add(&g_log_still, 1);
    if (strstr(msg, "map store writable again")) atomic_fetch_add(&g_log_back, 1);
    if (strstr(msg, "still failing at the end of the run")) atomic_fetch_add(&g_log_end, 1);
    if (lv >= SOOC_LOG_WARN && getenv("SOOC_TEST_VERBOSE")) fprintf(stderr, "[log] %s\n", msg);
}

static void logs_reset(void) {
    atomic_store(&g_log_failing, 0);
    atomic_store(&g_log_still, 0);
    atomic_store(&g_log_back, 0);
    atomic_store(&g_log_end, 0);
}

/* ------------------------------------------------------ database checks */

/* SQLite's own integrity check through the plain SQLite API. */
static int sql_integrity_ok(const char *db, char *detail, size_t cap) {
    sqlite3 *h = NULL;
    int ok = 0;
    snprintf(detail, cap, "cannot open");
    if (sqlite3_open_v2(db, &h, SQLITE_OPEN_READONLY, NULL) == SQLITE_OK) {
        sqlite3_stmt *q = NULL;
        if (sqlite3_prepare_v2(h, "PRAGMA integrity_check", -1, &q, NULL) == SQLITE_OK &&
            sqlite3_step(q) == SQLITE_ROW) {
            const char *t = (const char *)sqlite3_column_text(q, 0);
            snprintf(detail, cap, "%s", t ? t : "");
            ok = t && !strcmp(t, "ok");
        }
        sqlite3_finalize(q);
    }
    sqlite3_close(h);
    return ok;
}

typedef struct dbrow {
    uint64_t id;
    double x, z;
    uint32_t obs;
} dbrow;

typedef struct dbmap {
    dbrow r[1024];
    size_t n;
    uint64_t next_id, n_keyframes, n_layout;
} dbmap;

static int visit_row(void *u, const sooc_cogmap_entry *e) {
    dbmap *m = u;
    if (m->n < 1024) m->r[m->n++] = (dbrow){e->id, e->X, e->Z, e->obs_count};
    return 0;
}

static int db_read(const char *db, dbmap *m) {
    memset(m, 0, sizeof *m);
    sooc_mapstore *s = NULL;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    if (sooc_mapstore_open(&s, db, &p)) return -1;
    sooc_mapstore_info info;
    int rc = sooc_mapstore_foreach(s, visit_row, m) || sooc_mapstore_info_get(s, &info) ? -1 : 0;
    if (!rc) {
        m->next_id = info.next_id;
        m->n_keyframes = info.n_keyframes;
        m->n_layout = info.n_layout;
    }
    sooc_mapstore_close(s);
    return rc;
}

typedef struct blkchk {
    int bad, n;
    sooc_mapper *m;
} blkchk;

static int block_visit(void *u, int32_t bi, int32_t bj, const float *mu, const float *lv) {
    (void)lv;
    blkchk *b = u;
    float want[8];
    if (fake_mapper_get_block(b->m, bi, bj, want) || want[0] != mu[0]) b->bad++;
    b->n++;
    return 0;
}

/* 1 when the database holds exactly the mapper's map: the same objects
 * (id, x, z, obs_count), its layout blocks, an id counter at least the
 * mapper's, and `keyframes` rows. why gets the first difference. */
static int db_equals_map(const char *db, sooc_mapper *m, uint64_t keyframes, char *why, size_t cap) {
    static dbmap d;
    if (db_read(db, &d)) {
        snprintf(why, cap, "cannot read %s: %s", db, sooc_errmsg());
        return 0;
    }
    size_t ne = 0;
    sooc_mapper_entries(m, NULL, 0, &ne);
    sooc_map_entry *e = calloc(ne + 1, sizeof *e);
    sooc_mapper_entries(m, e, ne, &ne);
    int ok = 1;
    if (d.n != ne) {
        snprintf(why, cap, "database has %zu objects, the map %zu", d.n, ne);
        ok = 0;
    }
    for (size_t i = 0; i < ne && ok; i++) {
        size_t k = 0;
        while (k < d.n && d.r[k].id != e[i].id) k++;
        if (k == d.n) {
            snprintf(why, cap, "object %llu of the map is not in the database", (unsigned long long)e[i].id);
            ok = 0;
        } else if (fabs(d.r[k].x - e[i].x) > 1e-9 || fabs(d.r[k].z - e[i].z) > 1e-9 || d.r[k].obs != e[i].obs_count) {
            snprintf(why, cap, "object %llu differs (obs %u in the database, %u in the map)",
                     (unsigned long long)e[i].id, d.r[k].obs, e[i].obs_count);
            ok = 0;
        }
    }
    free(e);
    if (ok && d.next_id < sooc_mapper_next_id(m)) {
        snprintf(why, cap, "id counter %llu below the map's %llu", (unsigned long long)d.next_id,
                 (unsigned long long)sooc_mapper_next_id(m));
        ok = 0;
    }
    if (ok && d.n_keyframes != keyframes) {
        snprintf(why, cap, "%llu keyframe rows for %llu keyframes", (unsigned long long)d.n_keyframes,
                 (unsigned long long)keyframes);
        ok = 0;
    }
    if (ok) {   /* layout blocks: the mapper's latest value of each */
        sooc_mapstore *s = NULL;
        sooc_mapstore_params p;
        sooc_mapstore_params_default(&p);
        p.create = 0;
        p.readonly = 1;
        blkchk b = {0, 0, m};
        if (!sooc_mapstore_open(&s, db, &p)) {
            sooc_mapstore_foreach_layout(s, block_visit, &b);
            sooc_mapstore_close(s);
        }
        if (b.bad || b.n == 0) {
            snprintf(why, cap, "%d of %d layout blocks differ from the map's", b.bad, b.n);
            ok = 0;
        }
    }
    return ok;
}

/* ------------------------------------------------------------ the runs */

typedef struct run_ctx {
    const char *db;
    /* seen through the keyframe callback */
    int saw_failing, saw_ok_after, table_failing, table_pending, table_ok_after;
    uint64_t kf_first_failing, failures_at_first;
    uint64_t pending_max;
    int snap_taken, was_failing;
    dbmap snap;                  /* the database when the store last began to fail */
    /* actions */
    uint64_t lock_at, unlock_at; /* hold the write lock from another connection */
    sqlite3 *locker;
    uint64_t free_after;         /* tmpfs: remove the filler this many keyframes after the failure */
    const char *filler;
    int freed;
    uint64_t failures_after_first_kf;   /* backoff: failures seen at later keyframes */
    sooc_table_reader *tr;
} run_ctx;

static void on_kf(void *user, uint64_t kf, const sooc_map_entry *chg, size_t nc, const uint64_t *rem, size_t nr,
                  const sooc_node_stats *st) {
    (void)chg, (void)nc, (void)rem, (void)nr;
    run_ctx *r = user;
    if (!r->tr) sooc_table_open_reader(g_shm, &r->tr);
    sooc_table_store ts;
    memset(&ts, 0, sizeof ts);
    if (r->tr) sooc_table_get_store(r->tr, &ts);
    if (st->store_state == SOOC_NODE_STORE_FAILING) {
        if (!r->was_failing) r->snap_taken = db_read(r->db, &r->snap) == 0;
        if (!r->saw_failing) {
            r->saw_failing = 1;
            r->kf_first_failing = kf;
            r->failures_at_first = st->store_failures;
        } else {
            r->failures_after_first_kf = st->store_failures;
        }
        if (st->store_pending > r->pending_max) r->pending_max = st->store_pending;
        if (ts.state == SOOC_TABLE_STORE_FAILING) r->table_failing = 1;
        if (ts.state == SOOC_TABLE_STORE_FAILING && ts.pending == st->store_pending && ts.pending > 0)
            r->table_pending = 1;
    } else if (r->saw_failing && st->store_state == SOOC_NODE_STORE_OK) {
        r->saw_ok_after = 1;
        if (ts.state == SOOC_TABLE_STORE_OK && ts.pending == 0) r->table_ok_after = 1;
    }
    r->was_failing = st->store_state == SOOC_NODE_STORE_FAILING;
    if (r->lock_at && kf == r->lock_at && !r->locker) {
        CHECK(sqlite3_open_v2(r->db, &r->locker, SQLITE_OPEN_READWRITE, NULL) == SQLITE_OK);
        CHECK(sqlite3_exec(r->locker, "BEGIN IMMEDIATE", NULL, NULL, NULL) == SQLITE_OK);
    }
    if (r->locker && kf == r->unlock_at) {
        CHECK(sqlite3_exec(r->locker, "COMMIT", NULL, NULL, NULL) == SQLITE_OK);
        sqlite3_close(r->locker);
        r->locker = NULL;
    }
    if (r->filler && !r->freed && r->saw_failing && kf >= r->kf_first_failing + r->free_after) {
        CHECK(unlink(r->filler) == 0);
        r->freed = 1;
    }
}

static void make_cfg(sooc_node_config *c, const char *db, double retry_s, int busy_ms) {
    char text[2048];
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: /nonexistent}\n"
             "pose: {source: sensor}\n"
             "model: {path: fake.bin}\n"
             "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
             "shm: {name: %s, capacity: 1024}\n"
             "map: {db: '%s', resume: true, retry_s: %g, retry_max_s: %g, busy_timeout_ms: %d}\n"
             "world: {up: +y, floor: 0.0}\n"
             "pipeline: {ring_capacity: 4, block_when_full: true, stats_period_s: 0}\n"
             "log: {level: warn}\n",
             g_shm, db, retry_s, retry_s > 1 ? retry_s : 4 * retry_s, busy_ms);
    sooc_status st = sooc_node_config_parse(c, text, strlen(text), "faults.yaml");
    CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
}

typedef struct run_out {
    sooc_status create_st, run_st;
    sooc_node_stats st;
    int64_t writes_after_create;
} run_out;

/* One run of nf keyframes into db (removed first) with the mapper m. */
static void run_node(const char *db, sooc_mapper *m, int nf, double retry_s, int busy_ms, run_ctx *rc,
                     run_out *out, const char *filler, int64_t filler_keep) {
    char p[600];
    snprintf(p, sizeof p, "%s-wal", db);
    unlink(p);
    snprintf(p, sizeof p, "%s-shm", db);
    unlink(p);
    unlink(db);
    memset(out, 0, sizeof *out);
    logs_reset();
    sooc_node_config c;
    make_cfg(&c, db, retry_s, busy_ms);
    fx_src s = {0, nf, 0.15, 0};
    sooc_node_source src = fx_source(&s);
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.source = &src;
    o.mapper = m;
    o.on_keyframe = on_kf;
    o.user = rc;
    rc->db = db;
    sooc_node *n = NULL;
    out->create_st = sooc_node_create(&n, &c, &o);
    out->writes_after_create = fvfs_writes();
    if (out->create_st) {
        sooc_node_destroy(n);
        return;
    }
    if (filler) {   /* fill the file system, leaving filler_keep bytes */
        struct statvfs vs;
        CHECK(statvfs(filler, &vs) == 0 || errno == ENOENT);
        char dir[600];
        snprintf(dir, sizeof dir, "%s", filler);
        *strrchr(dir, '/') = 0;
        CHECK(statvfs(dir, &vs) == 0);
        int64_t freeb = (int64_t)vs.f_bavail * (int64_t)vs.f_frsize, want = freeb - filler_keep;
        FILE *f = fopen(filler, "wb");
        CHECK(f != NULL);
        static char zero[4096];
        for (int64_t k = 0; f && k + (int64_t)sizeof zero <= want; k += (int64_t)sizeof zero)
            if (fwrite(zero, 1, sizeof zero, f) != sizeof zero) break;
        if (f) fclose(f);
        rc->filler = filler;
    }
    out->run_st = sooc_node_run(n);
    if (out->run_st) fprintf(stderr, "run: %s\n", sooc_errmsg());
    sooc_node_get_stats(n, &out->st);
    sooc_node_destroy(n);
    if (rc->tr) sooc_table_close_reader(rc->tr);
    rc->tr = NULL;
    if (rc->locker) sqlite3_close(rc->locker);
    rc->locker = NULL;
}

/* The checks every recovered run passes. */
static void check_recovered(const char *what, const char *db, sooc_mapper *m, const run_out *o) {
    char why[512];
    CHECK_MSG(o->run_st == SOOC_OK, "%s: run failed", what);
    CHECK_MSG(sql_integrity_ok(db, why, sizeof why), "%s: integrity_check: %s", what, why);
    CHECK_MSG(db_equals_map(db, m, o->st.keyframes, why, sizeof why), "%s: %s", what, why);
    CHECK_MSG(o->st.store_state == SOOC_NODE_STORE_OK && o->st.store_pending == 0 && o->st.store_pending_kf == 0,
              "%s: store state %d, %llu pending", what, o->st.store_state, (unsigned long long)o->st.store_pending);
    /* one line when an episode began, one when it ended */
    CHECK_MSG((uint64_t)atomic_load(&g_log_failing) == o->st.store_recoveries &&
                  (uint64_t)atomic_load(&g_log_back) == o->st.store_recoveries && atomic_load(&g_log_end) == 0,
              "%s: %d 'failing' and %d 'writable again' lines for %llu recoveries", what,
              atomic_load(&g_log_failing), atomic_load(&g_log_back), (unsigned long long)o->st.store_recoveries);
}

#define NF 40

/* A fresh fake mapper run over NF keyframes with the writes numbered [from,
 * to) failing with `code` (from = INT64_MAX: none), rc preset by the caller
 * except that it is cleared when clear_rc; returns the mapper (the caller
 * destroys it). */
static sooc_mapper *faulted_run(const char *db, int64_t from, int64_t to, int code, double retry_s, int busy_ms,
                                  run_ctx *rc, int clear_rc, run_out *o) {
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    sooc_mapper *m = NULL;
    CHECK_OK(sooc_mapper_create(&m, &mp));
    if (clear_rc) memset(rc, 0, sizeof *rc);
    fvfs_reset_count();
    fvfs_fail(from, to, code);
    run_node(db, m, NF, retry_s, busy_ms, rc, o, NULL, 0);
    fvfs_off();
    return m;
}

static void test_vfs(void) {
    char db[400];
    snprintf(db, sizeof db, "%s/vfs.db", g_tmp);
    /* a clean run: how many writes the create and the whole run make */
    run_ctx rc;
    run_out o;
    sooc_mapper *m = faulted_run(db, INT64_MAX, INT64_MAX, SQLITE_FULL, 0, 50, &rc, 1, &o);
    int64_t w0 = o.writes_after_create, w1 = fvfs_writes();
    check_recovered("clean run", db, m, &o);
    CHECK(o.st.keyframes == NF && o.st.store_failures == 0 && !rc.saw_failing);
    sooc_mapper_destroy(m);
    printf("clean run: %lld writes at create, %lld in all, %llu keyframes\n", (long long)w0, (long long)w1,
           (unsigned long long)o.st.keyframes);

    /* 1. one failed write at each position after the create (every other: disk full / I/O error) */
    int runs = 0, episodes = 0, stride = (int)((w1 - w0) / 80) + 1;
    for (int64_t k = w0 + 1; k <= w1; k += stride, runs++) {
        m = faulted_run(db, k, k + 1, runs % 2 ? SQLITE_IOERR_WRITE : SQLITE_FULL, 0, 50, &rc, 1, &o);
        char what[96];
        snprintf(what, sizeof what, "write %lld fails (%s)", (long long)k, runs % 2 ? "I/O error" : "disk full");
        check_recovered(what, db, m, &o);
        CHECK_MSG(o.st.keyframes == NF, "%s: %llu keyframes", what, (unsigned long long)o.st.keyframes);
        if (o.st.store_failures) {
            episodes++;
            CHECK_MSG(o.st.store_recoveries == 1 && rc.saw_failing && rc.table_failing && rc.table_pending,
                      "%s: recoveries %llu, failing seen %d, in the table %d / %d", what,
                      (unsigned long long)o.st.store_recoveries, rc.saw_failing, rc.table_failing, rc.table_pending);
            CHECK_MSG(o.st.store_fault == (runs % 2 ? SOOC_MAPSTORE_FAULT_IO : SOOC_MAPSTORE_FAULT_FULL),
                      "%s: fault %d", what, o.st.store_fault);
        }
        sooc_mapper_destroy(m);
    }
    printf("single failed writes: %d runs, %d of them failed a commit and recovered\n", runs, episodes);
    CHECK(episodes >= runs / 2);

    /* 2. a window of failed writes that spans many keyframes (retried at every keyframe) */
    m = faulted_run(db, w0 + (w1 - w0) / 4, w0 + (w1 - w0) / 4 + 25, SQLITE_FULL, 0, 50, &rc, 1, &o);
    check_recovered("25 failed writes", db, m, &o);
    CHECK_MSG(o.st.store_failures >= 3 && o.st.store_recoveries == 1 && rc.saw_ok_after && rc.table_ok_after &&
                  rc.pending_max >= 2,
              "window: %llu failures, %llu recoveries, ok after %d / table %d, pending max %llu",
              (unsigned long long)o.st.store_failures, (unsigned long long)o.st.store_recoveries, rc.saw_ok_after,
              rc.table_ok_after, (unsigned long long)rc.pending_max);
    printf("window of 25 failed writes: %llu failed commits from keyframe %llu, %llu objects waited at most, "
           "1 recovery\n", (unsigned long long)o.st.store_failures, (unsigned long long)rc.kf_first_failing,
           (unsigned long long)rc.pending_max);
    sooc_mapper_destroy(m);

    /* 3. backoff: with retry_s 3600 the run makes no second attempt; the end of the run writes it all */
    m = faulted_run(db, w0 + (w1 - w0) / 3, w0 + (w1 - w0) / 3 + 1, SQLITE_FULL, 3600, 50, &rc, 1, &o);
    check_recovered("backoff", db, m, &o);
    CHECK_MSG(rc.saw_failing && rc.failures_at_first == 1 && rc.failures_after_first_kf <= 1 &&
                  o.st.store_failures == 1 && o.st.store_recoveries == 1 && rc.pending_max > 5,
              "backoff: %llu failures (%llu later), pending max %llu", (unsigned long long)o.st.store_failures,
              (unsigned long long)rc.failures_after_first_kf, (unsigned long long)rc.pending_max);
    sooc_mapper_destroy(m);

    /* 4. the database locked by another connection for 10 keyframes */
    memset(&rc, 0, sizeof rc);
    rc.lock_at = 10;
    rc.unlock_at = 20;
    m = faulted_run(db, INT64_MAX, INT64_MAX, SQLITE_FULL, 0, 1, &rc, 0, &o);
    check_recovered("locked", db, m, &o);
    CHECK_MSG(rc.saw_failing && rc.kf_first_failing == 11 && o.st.store_fault == SOOC_MAPSTORE_FAULT_BUSY &&
                  o.st.store_recoveries == 1 && o.st.store_failures >= 9,
              "locked: failing from %llu, fault %d, %llu failures", (unsigned long long)rc.kf_first_failing,
              o.st.store_fault, (unsigned long long)o.st.store_failures);
    sooc_mapper_destroy(m);

    /* 5. negative control: the writes fail from the middle of the run on, for good */
    m = faulted_run(db, w0 + (w1 - w0) / 2, INT64_MAX, SQLITE_FULL, 0, 50, &rc, 1, &o);
    char why[512];
    CHECK_MSG(o.run_st == SOOC_OK, "negative control: the run itself must succeed");
    CHECK(o.st.store_state == SOOC_NODE_STORE_FAILING && o.st.store_pending > 0 && o.st.store_recoveries == 0);
    CHECK(atomic_load(&g_log_failing) == 1 && atomic_load(&g_log_back) == 0 && atomic_load(&g_log_end) == 1);
    CHECK_MSG(!db_equals_map(db, m, o.st.keyframes, why, sizeof why), "negative control: the check saw no loss");
    printf("negative control (writes fail for good from keyframe %llu): %s\n", (unsigned long long)rc.kf_first_failing,
           why);
    CHECK_MSG(sql_integrity_ok(db, why, sizeof why), "negative control: integrity_check: %s", why);
    static dbmap after;
    CHECK(rc.snap_taken && db_read(db, &after) == 0);
    CHECK_MSG(after.n == rc.snap.n && after.n_keyframes == rc.snap.n_keyframes &&
                  !memcmp(after.r, rc.snap.r, after.n * sizeof *after.r),
              "negative control: the database changed after the failure (%zu -> %zu objects)", rc.snap.n, after.n);
    sooc_mapper_destroy(m);

    /* negative control of the integrity check: a copy with a page overwritten fails it */
    char bad[500];
    snprintf(bad, sizeof bad, "%s/corrupt.db", g_tmp);
    sqlite3 *h = NULL;   /* everything into the main file, then a copy of it */
    CHECK(sqlite3_open_v2(db, &h, SQLITE_OPEN_READWRITE, NULL) == SQLITE_OK &&
          sqlite3_exec(h, "SELECT count(*) FROM entries", NULL, NULL, NULL) == SQLITE_OK &&
          sqlite3_wal_checkpoint_v2(h, NULL, SQLITE_CHECKPOINT_TRUNCATE, NULL, NULL) == SQLITE_OK);
    sqlite3_close(h);
    void *bytes = NULL;
    size_t nb = 0;
    CHECK_OK(sooc_file_read_all(db, (size_t)1 << 26, &bytes, &nb));
    FILE *fc = fopen(bad, "wb");
    CHECK_MSG(fc && nb > 5 * 4096 && fwrite(bytes, 1, nb, fc) == nb, "copy of %zu bytes", nb);
    if (fc) fclose(fc);
    sooc_free(bytes);
    FILE *f = fopen(bad, "r+b");
    CHECK(f != NULL);
    if (f) {
        static unsigned char junk[4096];
        memset(junk, 0xA5, sizeof junk);
        CHECK(fseek(f, 3 * 4096, SEEK_SET) == 0 && fwrite(junk, 1, sizeof junk, f) == sizeof junk);
        fclose(f);
    }
    CHECK_MSG(!sql_integrity_ok(bad, why, sizeof why), "a corrupt copy passed the integrity check");
}

/* ----------------------------------------------------------------- tmpfs */

static int test_tmpfs(void) {
    char mnt[400], db[500], filler[500];
    snprintf(mnt, sizeof mnt, "%s/mnt", g_tmp);
    sooc_mkdirs(mnt);
    if (mount("tmpfs", mnt, "tmpfs", 0, "size=256k")) {
        printf("SKIP: mount -t tmpfs -o size=256k on %s: %s (needs root or CAP_SYS_ADMIN)\n", mnt, strerror(errno));
        return SOOC_TEST_SKIP;
    }
    snprintf(db, sizeof db, "%s/map.db", mnt);
    snprintf(filler, sizeof filler, "%s/filler", mnt);
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    for (int freeit = 1; freeit >= 0; freeit--) {
        sooc_mapper *m = NULL;
        CHECK_OK(sooc_mapper_create(&m, &mp));
        run_ctx rc;
        memset(&rc, 0, sizeof rc);
        rc.free_after = freeit ? 10 : (uint64_t)1 << 40;
        run_out o;
        unlink(filler);
        run_node(db, m, 200, 0, 50, &rc, &o, filler, 48 * 1024);
        const char *what = freeit ? "tmpfs, freed" : "tmpfs, never freed";
        CHECK_MSG(rc.saw_failing, "%s: the disk never filled", what);
        char why[512];
        static dbmap d;
        CHECK(db_read(db, &d) == 0);
        printf("%s: the disk first filled at keyframe %llu; %zu objects and %llu keyframes were committed when it "
               "filled last; at the end "
               "%zu objects and %llu keyframes in the database, the map %llu objects after %llu keyframes; %llu failed "
               "commits, %llu recoveries\n",
               what, (unsigned long long)rc.kf_first_failing, rc.snap.n, (unsigned long long)rc.snap.n_keyframes, d.n,
               (unsigned long long)d.n_keyframes, (unsigned long long)o.st.n_objects,
               (unsigned long long)o.st.keyframes, (unsigned long long)o.st.store_failures,
               (unsigned long long)o.st.store_recoveries);
        {
            struct stat sb, sw;
            char wal[600];
            snprintf(wal, sizeof wal, "%s-wal", db);
            if (!stat(db, &sb) && !stat(wal, &sw))
                printf("%s: map.db %lld bytes, map.db-wal %lld bytes\n", what, (long long)sb.st_size,
                       (long long)sw.st_size);
        }
        CHECK_MSG(o.st.store_fault == SOOC_MAPSTORE_FAULT_FULL, "%s: fault %d", what, o.st.store_fault);
        if (freeit) {
            check_recovered(what, db, m, &o);
            CHECK(rc.freed && rc.saw_ok_after && rc.table_ok_after);
        } else {
            CHECK(o.run_st == SOOC_OK && o.st.store_state == SOOC_NODE_STORE_FAILING && atomic_load(&g_log_end) == 1);
            CHECK_MSG(!db_equals_map(db, m, o.st.keyframes, why, sizeof why), "%s: the check saw no loss", what);
            CHECK_MSG(sql_integrity_ok(db, why, sizeof why), "%s: integrity_check: %s", what, why);
            /* what was committed before the disk filled (for the last time) is all there, as it was */
            CHECK_MSG(rc.snap_taken && d.n == rc.snap.n && d.n_keyframes == rc.snap.n_keyframes &&
                          !memcmp(d.r, rc.snap.r, d.n * sizeof *d.r),
                      "%s: the database changed after the disk filled (%zu -> %zu objects)", what, rc.snap.n, d.n);
        }
        sooc_mapper_destroy(m);
    }
    unlink(filler);
    if (umount2(mnt, MNT_DETACH)) fprintf(stderr, "umount %s: %s\n", mnt, strerror(errno));
    return 0;
}

int main(int argc, char **argv) {
    const char *mode = argc > 1 ? argv[1] : "vfs";
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_store_faults.%d", (int)getpid());
    snprintf(g_shm, sizeof g_shm, "store_faults_%d", (int)getpid());
    sooc_mkdirs(g_tmp);
    sooc_log_set_callback(log_cb, NULL);
    sooc_log_set_level(SOOC_LOG_WARN);
    int rc = 0;
    if (!strcmp(mode, "tmpfs")) {
        rc = test_tmpfs();
    } else {
        CHECK(fvfs_install() == 0);
        test_vfs();
    }
    char name[128];
    sooc_table_shm_name(g_shm, name, sizeof name);
    shm_unlink(name);
    char cmd[512];
    if (!getenv("SOOC_TEST_KEEP")) snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    else snprintf(cmd, sizeof cmd, "true");
    if (system(cmd)) fprintf(stderr, "cleanup of %s failed\n", g_tmp);
    if (rc == SOOC_TEST_SKIP) return rc;
    return check_report(!strcmp(mode, "tmpfs") ? "test_node_store_faults tmpfs" : "test_node_store_faults vfs");
}
