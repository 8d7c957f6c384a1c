/* Faults on real frames (docs/node.md "Faults"): `sooc3d node` (SOOC_BIN)
 * with the shipped real model (models/sooc3d_real) on 7-Scenes redkitchen
 * frames copied here (SOOC_SHARED_REAL; the copies are damaged, never the
 * originals).
 *
 *  frames   a clean copy, and one with a truncated colour JPEG, a truncated
 *           depth PNG, a pose file that does not parse, a missing pose file
 *           and a frame of half the size: exit 0, each broken frame named in
 *           one log line, the stats count them by reason, every other frame
 *           is read and mapped; --strict stops at the first (exit 1, named);
 *           a copy without one good frame is an error.
 *  storage  the map database on a 256 KB tmpfs mounted here: a first run
 *           commits a map; the disk is then filled and a resumed run on the
 *           next frames meets a full disk at its first commit: exit 0, the
 *           reason in the log, the table live and its header FAILING with the
 *           objects waiting, integrity_check ok and every object committed
 *           before the disk filled still there, unchanged; a third run with
 *           the space freed writes the map again.
 * Skips (77) without the data, the binary, the model, or when mounting is
 * not allowed. */
#include <errno.h>
#include <sqlite3.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/wait.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/table.h"

#define MODEL "models/sooc3d_real/model.bin"
#define NFRAMES 160   /* frames 0, 2, ..., 318 of the recording */

static char g_tmp[256], g_src[1024], g_bin[1024], g_shm[64];

static int run(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int run(const char *fmt, ...) {
    char cmd[4096];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(cmd, sizeof cmd, fmt, ap);
    va_end(ap);
    int rc = system(cmd);
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

/* A sequence folder with frames [0, n) of the recording (every one listed,
 * step 2 in its numbering): symbolic links to the originals. */
static int make_seq(const char *dir, int first, int n) {
    if (run("rm -rf '%s' && mkdir -p '%s' && ln -s '%s/camera-intrinsics.txt' '%s/gravity-direction.txt' '%s/'",
            dir, dir, g_src, g_src, dir))
        return -1;
    for (int i = first; i < first + n; i++)
        if (run("for k in color.jpg depth.png pose.txt; do ln -s '%s/frame-%06d.'$k '%s/'; done", g_src, 2 * i, dir))
            return -1;
    return 0;
}

/* Replace a link by a copy of its first `keep` bytes (0 < keep < 1: that
 * fraction of the file). */
static int truncate_copy(const char *dir, const char *name, double keep) {
    char p[1400], q[1400];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    snprintf(q, sizeof q, "%s/%s", g_src, name);
    void *b = NULL;
    size_t n = 0;
    if (sooc_file_read_all(q, (size_t)1 << 26, &b, &n)) return -1;
    unlink(p);
    FILE *f = fopen(p, "wb");
    size_t k = (size_t)((double)n * keep);
    int rc = f && fwrite(b, 1, k, f) == k ? 0 : -1;
    if (f) fclose(f);
    sooc_free(b);
    return rc;
}

/* Frame `num` at half size (PNG content under the usual names). */
static int half_size(const char *dir, int num) {
    static const char *kind[2] = {"color.jpg", "depth.png"};
    for (int k = 0; k < 2; k++) {
        char p[1400], q[1400];
        snprintf(q, sizeof q, "%s/frame-%06d.%s", g_src, num, kind[k]);
        snprintf(p, sizeof p, "%s/frame-%06d.%s", dir, num, kind[k]);
        sooc_image a = {0}, b = {0};
        if (sooc_image_read(q, &a) || sooc_image_alloc(&b, a.width / 2, a.height / 2, a.fmt)) return -1;
        size_t bpp = a.fmt == SOOC_PIX_RGB8 ? 3 : 2;
        for (int y = 0; y < b.height; y++)
            for (int x = 0; x < b.width; x++)
                memcpy((char *)b.data + ((size_t)y * (size_t)b.width + (size_t)x) * bpp,
                       (char *)a.data + ((size_t)(2 * y) * (size_t)a.width + (size_t)(2 * x)) * bpp, bpp);
        unlink(p);
        int rc = sooc_png_write(p, &b, 1);
        sooc_image_free(&a);
        sooc_image_free(&b);
        if (rc) return -1;
    }
    return 0;
}

static void write_launch(const char *path, const char *seq, const char *db) {
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f) return;
    fprintf(f,
            "sensor: {driver: replay, path: '%s', format: 7scenes, speed: fast}\n"
            "pose: {source: sensor}\n"
            "model: {path: " MODEL "}\n"
            "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
            "shm: {name: %s}\n"
            "map: {db: '%s', resume: true}\n"
            "world: {floor: estimate}\n"
            "pipeline: {block_when_full: true, stats_period_s: 0}\n"
            "log: {level: info}\n",
            seq, g_shm, db);
    fclose(f);
}

/* Run the node; the log goes to `log`; returns the exit status. */
static int node(const char *launch, const char *extra, const char *log) {
    return run("'%s' node '%s' --quiet %s > '%s' 2>&1", g_bin, launch, extra ? extra : "", log);
}

static char *slurp(const char *path) {
    void *b = NULL;
    size_t n = 0;
    if (sooc_file_read_all(path, (size_t)1 << 26, &b, &n)) return NULL;
    char *s = sooc_malloc(n + 1);
    if (s) {
        memcpy(s, b, n);
        s[n] = 0;
    }
    sooc_free(b);
    return s;
}

static int count_of(const char *hay, const char *needle) {
    int k = 0;
    for (const char *p = hay; (p = strstr(p, needle)); p += strlen(needle)) k++;
    return k;
}

/* A number after `key` in the last "done:" line of the log (-1 if absent). */
static long long stat_of(const char *log, const char *key) {
    const char *d = NULL;
    for (const char *p = log; (p = strstr(p, "done: ")); p++) d = p;
    const char *k = d ? strstr(d, key) : NULL;
    return k ? atoll(k + strlen(key)) : -1;
}

/* ------------------------------------------------------------ frames */

static void test_frames(void) {
    char clean[600], bad[600], allbad[600], launch[600], log[600], name[800];
    snprintf(clean, sizeof clean, "%s/clean", g_tmp);
    snprintf(bad, sizeof bad, "%s/broken", g_tmp);
    snprintf(allbad, sizeof allbad, "%s/allbroken", g_tmp);
    snprintf(launch, sizeof launch, "%s/frames.yaml", g_tmp);
    snprintf(log, sizeof log, "%s/frames.log", g_tmp);
    CHECK(make_seq(clean, 0, NFRAMES) == 0 && make_seq(bad, 0, NFRAMES) == 0 && make_seq(allbad, 0, 4) == 0);

    write_launch(launch, clean, "");
    CHECK(node(launch, NULL, log) == 0);
    char *t = slurp(log);
    long long kf_clean = t ? stat_of(t, "keyframes ") : -1, fr_clean = t ? stat_of(t, "frames ") : -1;
    sooc_free(t);
    CHECK_MSG(fr_clean == NFRAMES && kf_clean > 10, "clean: %lld frames, %lld keyframes", fr_clean, kf_clean);

    /* damage: frame numbers 40 (colour), 80 (depth), 120 (pose), 160 (no pose), 200 (half size) */
    CHECK(truncate_copy(bad, "frame-000040.color.jpg", 0.5) == 0);
    CHECK(truncate_copy(bad, "frame-000080.depth.png", 0.5) == 0);
    snprintf(name, sizeof name, "%s/frame-000120.pose.txt", bad);
    unlink(name);
    FILE *f = fopen(name, "w");
    CHECK(f != NULL);
    if (f) {
        fputs("1 0 0 0.5\n0 1 0 x\n0 0 1 0\n0 0 0 1\n", f);
        fclose(f);
    }
    snprintf(name, sizeof name, "%s/frame-000160.pose.txt", bad);
    CHECK(unlink(name) == 0);
    CHECK(half_size(bad, 200) == 0);
    write_launch(launch, bad, "");
    int rc = node(launch, NULL, log);
    t = slurp(log);
    CHECK_MSG(rc == 0 && t, "broken frames: exit %d", rc);
    if (t) {
        static const char *named[5][2] = {{"(colour)", "frame-000040.color.jpg"}, {"(depth)", "frame-000080.depth.png"},
                                          {"(pose)", "frame-000120.pose.txt"}, {"(pose)", "frame-000160.pose.txt"},
                                          {"(size)", "frame-000200"}};
        for (int i = 0; i < 5; i++) {   /* each named once, with its reason */
            char line[200];
            snprintf(line, sizeof line, "frame skipped %s: ", named[i][0]);
            int k = 0;
            for (const char *p = t; (p = strstr(p, line)); p++) {
                char one[1024];
                const char *e = strchr(p, '\n');
                size_t len = e ? (size_t)(e - p) : strlen(p);
                snprintf(one, sizeof one, "%.*s", (int)(len < sizeof one ? len : sizeof one - 1), p);
                k += strstr(one, named[i][1]) != NULL;
            }
            CHECK_MSG(k == 1, "'%s %s' named %d times", named[i][0], named[i][1], k);
        }
        CHECK_MSG(count_of(t, "frame skipped") == 5, "%d skip lines", count_of(t, "frame skipped"));
        CHECK_MSG(strstr(t, "skipped 5 (colour 1, depth 1, pose 2, size 1)") != NULL, "no skip counts in the stats");
        long long fr = stat_of(t, "frames "), kf = stat_of(t, "keyframes ");
        CHECK_MSG(fr == NFRAMES - 5 && kf >= kf_clean - 5 && kf <= kf_clean + 1,
                  "broken: %lld frames read, %lld keyframes (clean: %lld)", fr, kf, kf_clean);
        printf("frames: clean copy %lld frames, %lld keyframes; with 5 broken frames %lld frames read, %lld keyframes, "
               "exit 0\n", fr_clean, kf_clean, fr, kf);
    }
    sooc_free(t);

    /* --strict: the first broken frame ends the run, named */
    rc = node(launch, "--strict", log);
    t = slurp(log);
    CHECK_MSG(rc == 1 && t && strstr(t, "frame-000040.color.jpg") && strstr(t, "strict") &&
                  !strstr(t, "frame skipped"),
              "--strict: exit %d", rc);
    sooc_free(t);

    /* a sequence without one good frame is an error */
    for (int i = 0; i < 4; i++) {
        snprintf(name, sizeof name, "frame-%06d.color.jpg", 2 * i);
        CHECK(truncate_copy(allbad, name, 0.3) == 0);
    }
    write_launch(launch, allbad, "");
    rc = node(launch, NULL, log);
    t = slurp(log);
    CHECK_MSG(rc == 1 && t && (strstr(t, "none of the") || strstr(t, "corrupt")), "all broken: exit %d", rc);
    sooc_free(t);
}

/* ----------------------------------------------------------- storage */

typedef struct row {
    long long id, obs;
    double x, z;
} row;

/* The entries of a database (id, obs_count, x, z) and integrity_check. */
static int db_rows(const char *db, row *r, int cap, int *n, char *integrity, size_t icap) {
    sqlite3 *h = NULL;
    *n = 0;
    snprintf(integrity, icap, "cannot open");
    if (sqlite3_open_v2(db, &h, SQLITE_OPEN_READONLY, NULL) != SQLITE_OK) {
        sqlite3_close(h);
        return -1;
    }
    sqlite3_stmt *q = NULL;
    if (sqlite3_prepare_v2(h, "PRAGMA integrity_check", -1, &q, NULL) == SQLITE_OK && sqlite3_step(q) == SQLITE_ROW)
        snprintf(integrity, icap, "%s", (const char *)sqlite3_column_text(q, 0));
    sqlite3_finalize(q);
    int rc = -1;
    if (sqlite3_prepare_v2(h, "SELECT id, obs_count, x, z FROM entries ORDER BY id", -1, &q, NULL) == SQLITE_OK) {
        while (sqlite3_step(q) == SQLITE_ROW && *n < cap)
            r[(*n)++] = (row){sqlite3_column_int64(q, 0), sqlite3_column_int64(q, 1), sqlite3_column_double(q, 2),
                              sqlite3_column_double(q, 3)};
        rc = 0;
    }
    sqlite3_finalize(q);
    sqlite3_close(h);
    return rc;
}

static int test_storage(void) {
    char mnt[600], db[700], filler[700], first[600], second[600], launch[600], log[600], integ[256];
    snprintf(mnt, sizeof mnt, "%s/mnt", g_tmp);
    sooc_mkdirs(mnt);
    if (mount("tmpfs", mnt, "tmpfs", 0, "size=256k")) {
        printf("SKIP storage: mount -t tmpfs -o size=256k on %s: %s (needs root or CAP_SYS_ADMIN)\n", mnt,
               strerror(errno));
        return SOOC_TEST_SKIP;
    }
    snprintf(db, sizeof db, "%s/map.sqlite", mnt);
    snprintf(filler, sizeof filler, "%s/filler", mnt);
    snprintf(first, sizeof first, "%s/first", g_tmp);
    snprintf(second, sizeof second, "%s/second", g_tmp);
    snprintf(launch, sizeof launch, "%s/store.yaml", g_tmp);
    snprintf(log, sizeof log, "%s/store.log", g_tmp);
    CHECK(make_seq(first, 0, NFRAMES / 2) == 0 && make_seq(second, NFRAMES / 2, NFRAMES / 2) == 0);

    /* 1. a map committed on the small disk */
    write_launch(launch, first, db);
    CHECK(node(launch, NULL, log) == 0);
    static row before[1024], after[1024];
    int nb = 0, na = 0;
    CHECK(db_rows(db, before, 1024, &nb, integ, sizeof integ) == 0 && !strcmp(integ, "ok") && nb > 0);

    /* 2. the disk filled (a file takes all but 4 KB), a resumed run on the next frames */
    struct statvfs vs;
    CHECK(statvfs(mnt, &vs) == 0);
    long long freeb = (long long)vs.f_bavail * (long long)vs.f_frsize;
    CHECK(run("head -c %lld /dev/zero > '%s'", freeb - 4096, filler) == 0);
    write_launch(launch, second, db);
    int rc = node(launch, NULL, log);
    char *t = slurp(log);
    CHECK_MSG(rc == 0 && t, "full disk: exit %d", rc);
    if (t) {
        CHECK_MSG(count_of(t, "map store failing: ") == 1 && strstr(t, "database or disk is full (disk full)") &&
                      strstr(t, db) && count_of(t, "still failing at the end of the run") == 1,
                  "full disk: the log does not say so once");
        CHECK_MSG(stat_of(t, "keyframes ") > 5, "full disk: %lld keyframes mapped", stat_of(t, "keyframes "));
    }
    sooc_free(t);
    CHECK(db_rows(db, after, 1024, &na, integ, sizeof integ) == 0);
    CHECK_MSG(!strcmp(integ, "ok"), "full disk: integrity_check: %s", integ);
    CHECK_MSG(na == nb && !memcmp(before, after, (size_t)nb * sizeof *before),
              "full disk: %d objects before, %d after (or changed)", nb, na);
    /* the table: live objects of the whole map, its header says the store fails */
    sooc_table_reader *r = NULL;
    CHECK(sooc_table_open_reader(g_shm, &r) == SOOC_TABLE_OK);
    if (r) {
        static sooc_table_record recs[1024];
        uint32_t n = 0, live = 0;
        sooc_table_store ts;
        CHECK(sooc_table_snapshot(r, recs, 1024, &n, NULL) == SOOC_TABLE_OK);
        for (uint32_t i = 0; i < n; i++) live += !(recs[i].flags & SOOC_TABLE_FLAG_REMOVED);
        CHECK(sooc_table_get_store(r, &ts) == SOOC_TABLE_OK);
        CHECK_MSG(ts.state == SOOC_TABLE_STORE_FAILING && ts.fault == SOOC_TABLE_STORE_FAULT_FULL && ts.pending > 0 &&
                      ts.pending_kf > 0 && live > 0,
                  "table: store state %u fault %u, %llu objects and %llu keyframes pending, %u live objects", ts.state,
                  ts.fault, (unsigned long long)ts.pending, (unsigned long long)ts.pending_kf, live);
        printf("storage: %d objects committed on the 256 KB disk; disk filled: exit 0, the same %d objects in the "
               "database (integrity_check %s), the table live with %u objects and FAILING, %llu objects and %llu "
               "keyframes waiting\n",
               nb, na, integ, live, (unsigned long long)ts.pending, (unsigned long long)ts.pending_kf);
        sooc_table_close_reader(r);
    }
    /* both example planners say so */
    char planner[1100], out[700];
    snprintf(planner, sizeof planner, "%s", g_bin);
    char *slash = strrchr(planner, '/');
    snprintf(slash ? slash + 1 : planner, sizeof planner - (size_t)(slash ? slash + 1 - planner : 0),
             "sooc3d-planner-example");
    snprintf(out, sizeof out, "%s/planner.txt", g_tmp);
    if (!access(planner, X_OK)) {
        CHECK(run("'%s' %s --once > '%s' 2>&1", planner, g_shm, out) == 0);
        t = slurp(out);
        CHECK_MSG(t && strstr(t, "map database failing (disk full): "), "C planner: %s", t ? t : "(no output)");
        sooc_free(t);
    }
    if (!run("python3 -c 'import mmap' 2>/dev/null")) {
        CHECK(run("python3 scripts/planner_example.py %s --once > '%s' 2>&1", g_shm, out) == 0);
        t = slurp(out);
        CHECK_MSG(t && strstr(t, "map database failing (disk full): "), "Python planner: %s", t ? t : "(no output)");
        sooc_free(t);
    }

    /* 3. the space freed: the same run writes its map */
    CHECK(unlink(filler) == 0);
    rc = node(launch, NULL, log);
    t = slurp(log);
    CHECK_MSG(rc == 0 && t && !strstr(t, "map store failing"), "freed: exit %d", rc);
    sooc_free(t);
    CHECK(db_rows(db, after, 1024, &na, integ, sizeof integ) == 0 && !strcmp(integ, "ok"));
    int kept = 0;
    for (int i = 0; i < nb; i++)
        for (int k = 0; k < na; k++) kept += after[k].id == before[i].id;
    CHECK_MSG(na >= nb && kept > 0, "freed: %d objects (%d of the first %d)", na, kept, nb);
    printf("storage: space freed, the resumed run leaves %d objects (%d of the first run's) in the database\n", na,
           kept);
    CHECK(sooc_table_open_reader(g_shm, &r) == SOOC_TABLE_OK);
    if (r) {
        sooc_table_store ts;
        CHECK(sooc_table_get_store(r, &ts) == SOOC_TABLE_OK && ts.state == SOOC_TABLE_STORE_OK && ts.pending == 0);
        sooc_table_close_reader(r);
    }
    if (umount2(mnt, MNT_DETACH)) fprintf(stderr, "umount %s: %s\n", mnt, strerror(errno));
    return 0;
}

int main(void) {
    const char *real = getenv("SOOC_SHARED_REAL"), *bin = getenv("SOOC_BIN");
    snprintf(g_src, sizeof g_src, "%s/7scenes_redkitchen", real ? real : "../shared/real");
    if (!sooc_file_exists(g_src) && !sooc_dir_exists(g_src)) {
        printf("SKIP: %s is absent (the 7-Scenes redkitchen frames; SOOC_SHARED_REAL)\n", g_src);
        return SOOC_TEST_SKIP;
    }
    if (!bin || access(bin, X_OK)) {
        printf("SKIP: SOOC_BIN (the sooc3d binary) is not set or not executable\n");
        return SOOC_TEST_SKIP;
    }
    if (!sooc_file_exists(MODEL)) {
        printf("SKIP: %s is absent (run from the source tree)\n", MODEL);
        return SOOC_TEST_SKIP;
    }
    snprintf(g_bin, sizeof g_bin, "%s", bin);
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_faults_real.%d", (int)getpid());
    snprintf(g_shm, sizeof g_shm, "faults_real_%d", (int)getpid());
    sooc_mkdirs(g_tmp);
    test_frames();
    int st = test_storage();
    char name[128];
    sooc_table_shm_name(g_shm, name, sizeof name);
    shm_unlink(name);
    if (!getenv("SOOC_TEST_KEEP")) run("rm -rf '%s'", g_tmp);
    if (st == SOOC_TEST_SKIP) printf("(the storage part was skipped, see above)\n");
    return check_report("test_node_faults_real");
}
