/* SIGTERM -> clean exit 0 with the final keyframe committed (the table and
 * the database agree, WRITER_EXITED set, shm kept as configured); a second
 * signal during a slow keyframe exits at once. Runs the `sooc3d node` command
 * linked with the fake mapper (sooc3d_node_fake) as a child process, replaying
 * a looping TUM sequence written here. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include "check.h"
#include "node_fixture.h"
#include "sooc3d/table.h"
#include "sooc3d/cogmap.h"

static char g_tmp[256], g_shm[64];

static int count_visit(void *u, const sooc_cogmap_entry *e) {
    (void)e;
    (*(size_t *)u)++;
    return 0;
}

/* exits_now: the child is expected to _exit() with its threads running (the
 * second signal, docs/node.md "Signals and shutdown"); under ThreadSanitizer (scripts/test.sh) its
 * thread-leak report at _exit is turned off for that child only. */
static pid_t spawn(const char *bin, const char *launch, const char *delay_ms, int exits_now) {
    pid_t pid = fork();
    if (pid == 0) {
        if (delay_ms) setenv("SOOC_FAKE_MAPPER_DELAY_MS", delay_ms, 1);
        if (exits_now) {
            char opts[1024];
            const char *t = getenv("TSAN_OPTIONS");
            snprintf(opts, sizeof opts, "%s%sreport_thread_leaks=0", t ? t : "", t && *t ? " " : "");
            setenv("TSAN_OPTIONS", opts, 1);
        }
        char logp[512];
        snprintf(logp, sizeof logp, "%s/node.log", g_tmp);
        if (!freopen(logp, "a", stderr) || !freopen("/dev/null", "w", stdout)) _exit(90);
        execl(bin, bin, launch, "--quiet", (char *)NULL);
        _exit(91);
    }
    return pid;
}

/* Waits until node.log holds `n` "node: resumed" lines: the child then has its
 * signal handlers installed and its database open. A fixed sleep raced a slow
 * start (ThreadSanitizer on a loaded machine took > 0.8 s to get there, so the
 * SIGINT killed it before it had a handler). */
static int wait_resumed(int n, double timeout_s) {
    char logp[512], line[1024];
    snprintf(logp, sizeof logp, "%s/node.log", g_tmp);
    double t0 = sooc_seconds();
    while (sooc_seconds() - t0 < timeout_s) {
        FILE *f = fopen(logp, "r");
        int c = 0;
        if (f) {
            while (fgets(line, sizeof line, f))
                if (strstr(line, "node: resumed ")) c++;
            fclose(f);
        }
        if (c >= n) return 0;
        usleep(20000);
    }
    return -1;
}

static void write_launch(const char *path, const char *db, int unlink_on_exit) {
    FILE *f = fopen(path, "w");
    fprintf(f,
            "sensor: {driver: replay, path: %s/tum, format: tum, speed: realtime, loop: true, depth_scale: 0.0002}\n"
            "pose: {source: sensor}\n"
            "model: {path: fake.bin}\n"
            "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
            "shm: {name: %s, capacity: 4096, unlink_on_exit: %s}\n"
            "map: {db: '%s'}\n"
            "world: {up: +y, floor: 0.0}\n"
            "log: {level: info}\n",
            g_tmp, g_shm, unlink_on_exit ? "true" : "false", db);
    fclose(f);
}

/* keyframe rows in the map database (0 when it cannot be read) */
static uint64_t keyframes_in(const char *db) {
    sooc_mapstore *s = NULL;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    sooc_mapstore_info info;
    uint64_t n = 0;
    if (sooc_mapstore_open(&s, db, &p) == SOOC_OK && sooc_mapstore_info_get(s, &info) == SOOC_OK) n = info.n_keyframes;
    sooc_mapstore_close(s);
    sooc_clearerr();
    return n;
}

int main(void) {
    const char *bin = getenv("SOOC_NODE_FAKE_BIN");
    if (!bin || access(bin, X_OK)) {
        fprintf(stderr, "test_node_signal: SOOC_NODE_FAKE_BIN not set/executable; skipped\n");
        return SOOC_TEST_SKIP;
    }
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_node_sig.%d", (int)getpid());
    snprintf(g_shm, sizeof g_shm, "node_sig_%d", (int)getpid());
    sooc_mkdirs(g_tmp);
    char dir[512], launch[512], db[512], shm_path[128];
    snprintf(dir, sizeof dir, "%s/tum", g_tmp);
    snprintf(launch, sizeof launch, "%s/sig.yaml", g_tmp);
    snprintf(db, sizeof db, "%s/map.sqlite", g_tmp);
    sooc_table_shm_name(g_shm, shm_path, sizeof shm_path);
    CHECK(fx_write_tum(dir, 20, 0.15) == 0);
    write_launch(launch, db, 0);

    /* 1. SIGTERM while running: exit 0, final keyframe committed */
    pid_t pid = spawn(bin, launch, NULL, 0);
    sooc_table_reader *r = NULL;
    double t0 = sooc_seconds();
    while (sooc_seconds() - t0 < 20) {
        if (!r && sooc_table_open_reader(g_shm, &r) != SOOC_TABLE_OK) r = NULL;
        if (r && sooc_table_epoch(r) >= 6) break;   /* a few keyframes published */
        usleep(5000);
    }
    CHECK_MSG(r != NULL, "table never appeared (see %s/node.log)", g_tmp);
    kill(pid, SIGTERM);
    int status = 0;
    waitpid(pid, &status, 0);
    CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "node exit status %d (signal %d)",
              WIFEXITED(status) ? WEXITSTATUS(status) : -1, WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    if (r) {
        static sooc_table_record recs[4096];
        uint32_t n = 0;
        uint64_t epoch = 0;
        CHECK(sooc_table_snapshot(r, recs, 4096, &n, &epoch) == SOOC_TABLE_OK);
        size_t live = 0;
        for (uint32_t i = 0; i < n; i++) live += !(recs[i].flags & SOOC_TABLE_FLAG_REMOVED);
        sooc_table_liveness lv;
        CHECK(sooc_table_writer_alive(r, &lv) == 0 && lv.exited);
        sooc_mapstore *s;
        sooc_mapstore_params p;
        sooc_mapstore_params_default(&p);
        p.create = 0;
        CHECK_OK(sooc_mapstore_open(&s, db, &p));
        size_t nd = 0;
        sooc_mapstore_foreach(s, count_visit, &nd);
        sooc_mapstore_close(s);
        printf("SIGTERM: %zu objects in the table, %zu in the database, epoch %llu\n", live, nd,
               (unsigned long long)epoch);
        CHECK(live > 0 && live == nd);
        sooc_table_close_reader(r);
    }
    CHECK_MSG(access("/dev/shm", F_OK) || shm_open(shm_path, O_RDONLY, 0) >= 0, "shm unlinked despite config");

    /* 2. second signal during a slow keyframe: immediate exit, non-zero, the keyframe under way not committed
     * (a node that waited for it would have written its keyframe row) */
    uint64_t kf_before = keyframes_in(db);
    pid = spawn(bin, launch, "3000", 1);
    CHECK_MSG(wait_resumed(1, 30) == 0, "second run never resumed (see %s/node.log)", g_tmp);
    usleep(500 * 1000);   /* the first (3 s) keyframe under way */
    kill(pid, SIGTERM);
    usleep(200 * 1000);
    kill(pid, SIGTERM);
    waitpid(pid, &status, 0);
    CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 128 + SIGTERM, "second signal: status %d",
              WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    uint64_t kf_after = keyframes_in(db);
    CHECK_MSG(kf_after == kf_before, "keyframes in the database: %llu before the run, %llu after the second signal",
              (unsigned long long)kf_before, (unsigned long long)kf_after);

    /* 3. unlink_on_exit: true removes the shm object on a clean exit */
    write_launch(launch, db, 1);
    pid = spawn(bin, launch, NULL, 0);
    CHECK_MSG(wait_resumed(2, 30) == 0, "third run never resumed (see %s/node.log)", g_tmp);
    usleep(300 * 1000);
    kill(pid, SIGINT);
    waitpid(pid, &status, 0);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    CHECK(shm_open(shm_path, O_RDONLY, 0) < 0);

    shm_unlink(shm_path);
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (g_check_fail) snprintf(cmd, sizeof cmd, "cat '%s/node.log' >&2; rm -rf '%s'", g_tmp, g_tmp);
    if (!getenv("SOOC_KEEP_TMP") && system(cmd)) fprintf(stderr, "cleanup failed\n");
    return check_report("test_node_signal");
}
