/* SQLite map store tests: WAL on, keyframe commits, restart (clean and after
 * a killed writer) loses and duplicates nothing and never reuses ids, the
 * R*Tree box query equals a brute-force filter, bad files give errors that
 * name the file. */
#include "check.h"
#include "sooc3d/cogmap.h"

#include <sqlite3.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#define D 6
#define DL 4

static char g_dir[256];

static void path_in(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/%s", g_dir, name); }

static sooc_cogmap *new_map(void) {
    sooc_cogmap_params p;
    sooc_cogmap_params_default(&p);
    p.dim = D;
    p.layout_dim = DL;
    sooc_cogmap *m = NULL;
    CHECK_OK(sooc_cogmap_create(&m, &p));
    return m;
}

static sooc_status open_store(sooc_mapstore **s, const char *path) {
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.dim = D;
    p.layout_dim = DL;
    p.model_id = "test-model";
    p.block_size = 4;
    return sooc_mapstore_open(s, path, &p);
}

/* One simulated keyframe: query at a random pose, perturb/drop retrieved
 * slots, add new ones, register, then commit to the store. */
static void keyframe(sooc_rng *r, sooc_cogmap *m, sooc_mapstore *s, int view) {
    const int S = SOOC_LAM_SIZE(D), K = 7;
    sooc_cogmap_camera c;
    memset(&c, 0, sizeof c);
    double psi = sooc_rng_range(r, -3, 3);
    double base[9] = {-1, 0, 0, 0, -1, 0, 0, 0, 1}, Ry[9], R[9], t[3] = {sooc_rng_range(r, -10, 10), 1.5,
                                                                        sooc_rng_range(r, -10, 10)};
    sooc_m3_rot_y(Ry, psi);
    sooc_m3_mul(R, Ry, base);
    sooc_se3_from_rt(c.T_wc, R, t);
    c.K = (sooc_intrinsics){.width = 64, .height = 64, .fx = 50, .fy = 50, .cx = 32, .cy = 32};
    c.t_near = 0.1;
    c.d_clip = 8;
    c.R_h = 0.6;
    c.H_b = 1.2;
    sooc_cogmap_slot sl[7];
    int n;
    sooc_floor_frame gf;
    CHECK_OK(sooc_cogmap_query(m, &c, K, sl, &n, &gf, NULL));
    float lam[7 * SOOC_LAM_MAX];
    uint64_t src[7], ids[7], rem[7];
    for (int i = 0; i < K; i++) {
        float *l = lam + i * S;
        if (i < n) {
            memcpy(l, sl[i].lam, S * sizeof(float));
            src[i] = sl[i].id;
            l[0] += (float)sooc_rng_range(r, -0.1, 0.1);
            l[SOOC_LAM_PRES(D)] = sooc_rng_uniform(r) < 0.2 ? -1.0f : 2.0f;
        } else {
            src[i] = 0;
            for (int j = 0; j < S; j++) l[j] = (float)sooc_rng_normal(r);
            l[SOOC_LAM_X] = (float)sooc_rng_range(r, -2, 2);
            l[SOOC_LAM_Z] = (float)sooc_rng_range(r, 1, 7);
        }
    }
    sooc_cogmap_reg_stats st;
    CHECK_OK(sooc_cogmap_register(m, &gf, K, lam, src, 1000 * (int64_t)view, view, ids, rem, &st));
    int32_t bi, bj;
    CHECK_OK(sooc_cogmap_active_block(m, c.T_wc, 8, &bi, &bj, NULL));
    float mu[DL], lv[DL];
    for (int j = 0; j < DL; j++) { mu[j] = (float)sooc_rng_normal(r); lv[j] = -1; }
    CHECK_OK(sooc_cogmap_layout_set(m, bi, bj, mu, lv));
    sooc_mapstore_keyframe kf = {.t_ns = 1000 * (int64_t)view, .view = view, .changed = ids, .n_changed = K,
                                 .removed = rem, .n_removed = (size_t)st.n_removed, .has_block = 1, .bi = bi, .bj = bj};
    memcpy(kf.T_wc, c.T_wc, sizeof kf.T_wc);
    CHECK_OK(sooc_mapstore_commit_keyframe(s, m, &kf));
}

/* Compare a map with the store's contents, entry by entry (bitwise). */
static int same_entries(const sooc_cogmap *a, const sooc_cogmap *b) {
    size_t na, nb;
    sooc_cogmap_entries(a, NULL, 0, &na);
    sooc_cogmap_entries(b, NULL, 0, &nb);
    if (na != nb) {
        fprintf(stderr, "count %zu vs %zu\n", na, nb);
        return 0;
    }
    sooc_cogmap_entry *x = sooc_malloc((na + 1) * sizeof *x), *y = sooc_malloc((na + 1) * sizeof *y);
    sooc_cogmap_entries(a, x, na, &na);
    sooc_cogmap_entries(b, y, nb, &nb);
    int ok = 1;
    for (size_t i = 0; i < na; i++)
        if (memcmp(&x[i], &y[i], sizeof x[i])) {
            fprintf(stderr, "entry %zu differs (ids %llu %llu)\n", i, (unsigned long long)x[i].id,
                    (unsigned long long)y[i].id);
            ok = 0;
            break;
        }
    sooc_free(x);
    sooc_free(y);
    return ok;
}

typedef struct collect {
    sooc_cogmap_entry *e;
    size_t n, cap;
} collect;
static int collect_cb(void *u, const sooc_cogmap_entry *e) {
    collect *c = u;
    if (c->n < c->cap) c->e[c->n] = *e;
    c->n++;
    return 0;
}

static void test_restart(void) {
    char db[512];
    path_in(db, sizeof db, "map.sqlite");
    sooc_rng r;
    sooc_rng_seed(&r, 11, 0);
    sooc_cogmap *m = new_map();
    sooc_mapstore *s = NULL;
    CHECK_OK(open_store(&s, db));
    if (!s) return;
    sooc_mapstore_info info;
    CHECK_OK(sooc_mapstore_info_get(s, &info));
    CHECK_MSG(!strcmp(info.journal_mode, "wal"), "journal mode %s", info.journal_mode);
    CHECK(info.dim == D && info.layout_dim == DL && !strcmp(info.model_id, "test-model"));
    for (int v = 0; v < 40; v++) keyframe(&r, m, s, v);
    CHECK_OK(sooc_mapstore_info_get(s, &info));
    CHECK(info.n_keyframes == 40);
    CHECK(info.n_entries == sooc_cogmap_count(m));
    CHECK(info.next_id == sooc_cogmap_next_id(m));
    sooc_mapstore_close(s);

    /* restart: everything back, ids continue after the counter */
    s = NULL;
    CHECK_OK(open_store(&s, db));
    sooc_cogmap *m2 = new_map();
    CHECK_OK(sooc_mapstore_load_map(s, m2));
    CHECK(same_entries(m, m2));
    CHECK(sooc_cogmap_next_id(m2) == sooc_cogmap_next_id(m));
    CHECK(sooc_cogmap_layout_count(m2) == sooc_cogmap_layout_count(m));
    /* removing the largest id then restarting must not hand it out again */
    size_t n;
    sooc_cogmap_entries(m2, NULL, 0, &n);
    sooc_cogmap_entry *all = sooc_malloc(n * sizeof *all);
    sooc_cogmap_entries(m2, all, n, &n);
    uint64_t maxid = all[n - 1].id;
    CHECK_OK(sooc_cogmap_remove(m2, maxid));
    sooc_mapstore_keyframe kf = {.t_ns = 1, .view = 99, .removed = &maxid, .n_removed = 1};
    sooc_se3_identity(kf.T_wc);
    CHECK_OK(sooc_mapstore_commit_keyframe(s, m2, &kf));
    sooc_mapstore_close(s);
    s = NULL;
    CHECK_OK(open_store(&s, db));
    sooc_cogmap *m3 = new_map();
    CHECK_OK(sooc_mapstore_load_map(s, m3));
    CHECK(same_entries(m2, m3));
    CHECK(sooc_cogmap_next_id(m3) > maxid);
    sooc_cogmap_entry e = all[0];
    e.id = 0;
    uint64_t nid;
    CHECK_OK(sooc_cogmap_insert(m3, &e, &nid));
    CHECK(nid > maxid);
    /* get by id and foreach */
    sooc_cogmap_entry g;
    CHECK_OK(sooc_mapstore_get(s, all[0].id, &g));
    CHECK(!memcmp(&g, &all[0], sizeof g));
    CHECK(sooc_mapstore_get(s, maxid, &g) == SOOC_ENOTFOUND);
    /* low-level keyframe row inside an explicit transaction */
    sooc_mapstore_info i0, i1;
    CHECK_OK(sooc_mapstore_info_get(s, &i0));
    CHECK_OK(sooc_mapstore_begin(s));
    CHECK(sooc_mapstore_begin(s) == SOOC_EINVAL);
    CHECK_OK(sooc_mapstore_add_keyframe(s, &kf, -1));
    CHECK_OK(sooc_mapstore_commit(s));
    CHECK_OK(sooc_mapstore_info_get(s, &i1));
    CHECK(i1.n_keyframes == i0.n_keyframes + 1 && i1.n_entries == i0.n_entries);
    CHECK_OK(sooc_mapstore_begin(s));
    CHECK_OK(sooc_mapstore_add_keyframe(s, &kf, 5));
    sooc_mapstore_rollback(s);
    CHECK_OK(sooc_mapstore_info_get(s, &i1));
    CHECK(i1.n_keyframes == i0.n_keyframes + 1);

    /* R*Tree box query == brute force */
    collect all_c = {sooc_malloc(n * sizeof(sooc_cogmap_entry)), 0, n};
    CHECK_OK(sooc_mapstore_foreach(s, collect_cb, &all_c));
    CHECK(all_c.n == n - 1);
    int bad = 0;
    collect bc = {sooc_malloc(n * sizeof(sooc_cogmap_entry)), 0, n};
    for (int it = 0; it < 200; it++) {
        double x0 = sooc_rng_range(&r, -20, 20), z0 = sooc_rng_range(&r, -20, 20);
        double x1 = x0 + sooc_rng_range(&r, 0, 10), z1 = z0 + sooc_rng_range(&r, 0, 10);
        if (it == 0) { /* a box whose edges sit exactly on stored positions */
            x0 = all_c.e[0].X; z0 = all_c.e[0].Z; x1 = x0 + 3; z1 = z0 + 3;
        }
        bc.n = 0;
        CHECK_OK(sooc_mapstore_query_box(s, x0, z0, x1, z1, collect_cb, &bc));
        size_t k = 0;
        for (size_t i = 0; i < all_c.n; i++) {
            const sooc_cogmap_entry *q = &all_c.e[i];
            if (q->X >= x0 && q->X <= x1 && q->Z >= z0 && q->Z <= z1) {
                if (k >= bc.n || bc.e[k].id != q->id) bad++;
                k++;
            }
        }
        if (k != bc.n) bad++;
    }
    CHECK_MSG(bad == 0, "%d box-query mismatches", bad);
    CHECK(sooc_mapstore_query_box(s, 1, 0, 0, 1, collect_cb, &bc) == SOOC_EINVAL);
    sooc_free(bc.e);
    sooc_free(all_c.e);
    sooc_free(all);
    sooc_mapstore_close(s);
    sooc_cogmap_destroy(m);
    sooc_cogmap_destroy(m2);
    sooc_cogmap_destroy(m3);
}

/* A writer killed without closing: the WAL is recovered, the committed
 * keyframes are all there. */
static void test_killed_writer(void) {
    char db[512];
    path_in(db, sizeof db, "killed.sqlite");
    pid_t pid = fork();
    if (pid == 0) {
        sooc_rng r;
        sooc_rng_seed(&r, 12, 0);
        sooc_cogmap *m = new_map();
        sooc_mapstore *s = NULL;
        if (open_store(&s, db)) _exit(3);
        for (int v = 0; v < 25; v++) keyframe(&r, m, s, v);
        /* leave an uncommitted transaction behind, then die */
        sooc_mapstore_begin(s);
        uint64_t one = 1;
        sooc_mapstore_remove_entries(s, &one, 1);
        _exit(g_check_fail ? 4 : 0);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    /* replay the same keyframes in memory to know the expected map */
    char ref[512];
    path_in(ref, sizeof ref, "ref.sqlite");
    sooc_rng r;
    sooc_rng_seed(&r, 12, 0);
    sooc_cogmap *m = new_map();
    sooc_mapstore *s = NULL;
    CHECK_OK(open_store(&s, ref));
    for (int v = 0; v < 25; v++) keyframe(&r, m, s, v);
    sooc_mapstore_close(s);
    s = NULL;
    CHECK_OK(open_store(&s, db));
    sooc_cogmap *m2 = new_map();
    CHECK_OK(sooc_mapstore_load_map(s, m2));
    CHECK(same_entries(m, m2));
    CHECK(sooc_cogmap_next_id(m2) == sooc_cogmap_next_id(m));
    sooc_mapstore_close(s);
    sooc_cogmap_destroy(m);
    sooc_cogmap_destroy(m2);
}

static void expect_error_naming(sooc_status got, sooc_status want, const char *path) {
    CHECK_MSG(got == want, "got %s want %s: %s", sooc_status_str(got), sooc_status_str(want), sooc_errmsg());
    CHECK_MSG(strstr(sooc_errmsg(), path) != NULL, "message does not name the file: %s", sooc_errmsg());
}

static void test_bad_files(void) {
    char p[512];
    sooc_mapstore *s = NULL;
    /* garbage */
    path_in(p, sizeof p, "garbage.sqlite");
    FILE *f = fopen(p, "wb");
    for (int i = 0; i < 8192; i++) fputc((i * 7919) & 0xff, f);
    fclose(f);
    expect_error_naming(open_store(&s, p), SOOC_EFORMAT, p);
    CHECK(s == NULL);
    /* missing with create = 0 */
    path_in(p, sizeof p, "missing.sqlite");
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    expect_error_naming(sooc_mapstore_open(&s, p, &mp), SOOC_ENOTFOUND, p);
    /* an SQLite database that is not a map */
    path_in(p, sizeof p, "other.sqlite");
    sqlite3 *db;
    sqlite3_open(p, &db);
    sqlite3_exec(db, "CREATE TABLE t(a); INSERT INTO t VALUES(1);", NULL, NULL, NULL);
    sqlite3_close(db);
    expect_error_naming(open_store(&s, p), SOOC_EFORMAT, p);
    /* schema version mismatch */
    path_in(p, sizeof p, "future.sqlite");
    CHECK_OK(open_store(&s, p));
    sooc_mapstore_close(s);
    s = NULL;
    sqlite3_open(p, &db);
    sqlite3_exec(db, "UPDATE meta SET value = '99' WHERE key = 'schema_version'", NULL, NULL, NULL);
    sqlite3_close(db);
    expect_error_naming(open_store(&s, p), SOOC_EVERSION, p);
    /* dimension and model mismatch */
    path_in(p, sizeof p, "dims.sqlite");
    CHECK_OK(open_store(&s, p));
    sooc_mapstore_close(s);
    s = NULL;
    sooc_mapstore_params_default(&mp);
    mp.dim = D + 1;
    expect_error_naming(sooc_mapstore_open(&s, p, &mp), SOOC_EVERSION, p);
    sooc_mapstore_params_default(&mp);
    mp.model_id = "other-model";
    expect_error_naming(sooc_mapstore_open(&s, p, &mp), SOOC_EVERSION, p);
    /* a valid map whose pages are then overwritten (corrupt after open) */
    path_in(p, sizeof p, "corrupt.sqlite");
    {
        sooc_rng r;
        sooc_rng_seed(&r, 13, 0);
        sooc_cogmap *m = new_map();
        CHECK_OK(open_store(&s, p));
        for (int v = 0; v < 30; v++) keyframe(&r, m, s, v);
        sooc_mapstore_close(s);
        s = NULL;
        sooc_cogmap_destroy(m);
        /* fold the WAL into the main file */
        sqlite3_open(p, &db);
        sqlite3_exec(db, "PRAGMA wal_checkpoint(TRUNCATE); PRAGMA journal_mode = DELETE;", NULL, NULL, NULL);
        sqlite3_close(db);
        f = fopen(p, "r+b");
        fseek(f, 0, SEEK_END);
        long sz = ftell(f);
        for (long o = 1024; o < sz; o += 3) {
            fseek(f, o, SEEK_SET);
            fputc(0xA5, f);
        }
        fclose(f);
        sooc_status st = open_store(&s, p);
        if (st == SOOC_OK) {
            sooc_cogmap *m2 = new_map();
            st = sooc_mapstore_load_map(s, m2);
            sooc_cogmap_destroy(m2);
            sooc_mapstore_close(s);
            s = NULL;
        }
        CHECK_MSG(st != SOOC_OK, "corrupt map accepted");
        CHECK_MSG(strstr(sooc_errmsg(), p) != NULL, "message does not name the file: %s", sooc_errmsg());
    }
}

int main(void) {
    snprintf(g_dir, sizeof g_dir, "/tmp/sooc_mapstore_XXXXXX");
    if (!mkdtemp(g_dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_restart();
    test_killed_writer();
    test_bad_files();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_dir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
    sooc_alloc_stats st;
    sooc_alloc_get_stats(&st);
    CHECK_MSG(st.live_bytes == 0, "%llu bytes leaked", (unsigned long long)st.live_bytes);
    return check_report("test_mapstore");
}
