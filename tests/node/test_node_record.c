/* The node's record: {mcap: FILE} (docs/logs.md "Foxglove"), with the fake
 * mapper and the synthetic stream of node_fixture.h (every frame a keyframe):
 *
 *  run     period_s 0, 20 keyframes: the file holds the /sooc3d/frames
 *          transforms (map -> world, and world -> source where the launch
 *          file's world put it) and 20 SceneUpdates in time order, the last with every
 *          object of the map; the project's reader verifies every CRC, and
 *          @mcap/core's indexed reader (tests/logs/npm/read_mcap.mjs, when
 *          node and the package are there) reads the same counts.
 *  killed  a node killed (SIGKILL) at keyframe 12 leaves a finished file with
 *          the 11 SceneUpdates written before it, summary and index included.
 *  exit    period_s 1e6: while the node runs the file holds no SceneUpdate
 *          (the empty file written at start); at exit all 20 are there.
 *  bad     a path in a folder that does not exist: sooc_node_create fails
 *          naming record.mcap.
 */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "check.h"
#include "node_fixture.h"
#include "sooc3d/log.h"
#include "sooc3d/mapper.h"
#include "sooc3d/node.h"
#include "sooc3d/frame.h"

static char g_tmp[256];

typedef struct src { int i, n; } src;

static sooc_status s_read(void *ctx, sooc_frame *f, int timeout_ms) {
    src *s = ctx;
    (void)timeout_ms;
    if (s->i >= s->n) return SOOC_EEOF;
    fx_fill(f, s->i++, 0.15);
    return SOOC_OK;
}
static sooc_frame_fault s_fault(void *ctx) {
    (void)ctx;
    return SOOC_FRAME_FAULT_NONE;
}

/* What a file holds: SceneUpdates, transforms, entities in the last update. */
typedef struct rec_read {
    int ok, scenes, frames, last_entities, ordered;
    int has_source;       /* a world -> source FrameTransform */
    double source_t[3];   /* its translation */
} rec_read;

static int count(const char *t, size_t n, const char *pat) {
    int k = 0;
    size_t m = strlen(pat);
    for (size_t i = 0; i + m <= n; i++) k += !memcmp(t + i, pat, m);
    return k;
}

static rec_read read_file(const char *path) {
    rec_read r = {0, 0, 0, -1, 1, 0, {0, 0, 0}};
    sooc_logfile *lf = NULL;
    if (sooc_logfile_open(&lf, path) || sooc_logfile_verify(lf)) {
        printf("  %s: %s\n", path, sooc_errmsg());
        sooc_logfile_close(lf);
        return r;
    }
    int obj = sooc_logfile_find(lf, "/sooc3d/objects"), frm = sooc_logfile_find(lf, "/sooc3d/frames");
    const sooc_logfile_channel *co = sooc_logfile_channel_get(lf, obj);
    r.ok = obj >= 0 && frm >= 0 && co && !strcmp(co->type, "foxglove.SceneUpdate") && !strcmp(co->encoding, "json");
    int64_t prev = INT64_MIN;
    for (int64_t k = 0; k < sooc_logfile_count(lf); k++) {
        sooc_logfile_msg m;
        if (sooc_logfile_read(lf, k, &m)) { r.ok = 0; break; }
        if (m.channel == frm) {
            r.frames++;
            char js[1024];
            snprintf(js, sizeof js, "%.*s", (int)(m.size < sizeof js - 1 ? m.size : sizeof js - 1), (const char *)m.data);
            const char *t = strstr(js, "\"parent_frame_id\": \"world\", \"child_frame_id\": \"source\"");
            if (t && (t = strstr(t, "\"translation\": ")) &&
                sscanf(t, "\"translation\": {\"x\": %lf, \"y\": %lf, \"z\": %lf}", &r.source_t[0], &r.source_t[1],
                       &r.source_t[2]) == 3)
                r.has_source = 1;
            continue;
        }
        r.scenes++;
        if (m.t_ns < prev) r.ordered = 0;
        prev = m.t_ns;
        r.last_entities = count((const char *)m.data, m.size, "\"frame_id\": \"world\"");
    }
    sooc_logfile_close(lf);
    return r;
}

typedef struct run_ctx {
    int kill_at;          /* raise SIGKILL in on_keyframe at this keyframe (0 = no) */
    const char *peek;     /* read this file at keyframe 10 */
    rec_read peeked;
} run_ctx;

static void on_kf(void *user, uint64_t keyframe, const sooc_map_entry *changed, size_t n_changed,
                  const uint64_t *removed, size_t n_removed, const sooc_node_stats *st) {
    run_ctx *c = user;
    (void)changed, (void)n_changed, (void)removed, (void)n_removed, (void)st;
    if (c->kill_at && keyframe == (uint64_t)c->kill_at) raise(SIGKILL);
    if (c->peek && keyframe == 10) c->peeked = read_file(c->peek);
}

/* Runs the node over n frames with record: {mcap: path, period_s: period};
 * returns the create/run status; *objects gets the map's size at the end. */
static sooc_status run(const char *path, double period, int n, run_ctx *rc, size_t *objects) {
    char text[2048], db[400];
    snprintf(db, sizeof db, "%s/map.db", g_tmp);
    unlink(db);
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: /nonexistent}\npose: {source: sensor}\nmodel: {path: fake.bin}\n"
             "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\nmap: {db: '%s', resume: false}\n"
             "world: {up: +y, floor: 0.25}\npipeline: {ring_capacity: 4, block_when_full: true, stats_period_s: 0}\n"
             "record: {mcap: '%s', period_s: %g}\nlog: {level: warn}\n",
             db, path, period);
    sooc_node_config c;
    sooc_status st = sooc_node_config_parse(&c, text, strlen(text), "record.yaml");
    CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
    if (st) return st;
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    sooc_mapper *m = NULL;
    CHECK_OK(sooc_mapper_create(&m, &mp));
    src s = {0, n};
    sooc_node_source so;
    memset(&so, 0, sizeof so);
    so.ctx = &s;
    so.read = s_read;
    so.frame_fault = s_fault;
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.source = &so;
    o.mapper = m;
    o.on_keyframe = on_kf;
    o.user = rc;
    sooc_node *node = NULL;
    st = sooc_node_create(&node, &c, &o);
    if (!st) st = sooc_node_run(node);
    sooc_node_destroy(node);
    *objects = 0;
    sooc_mapper_entries(m, NULL, 0, objects);
    sooc_mapper_destroy(m);
    return st;
}

static void npm_check(const char *path, int scenes, size_t objects) {
    const char *node = getenv("SOOC_NODE"), *srcdir = getenv("SOOC_SRC") ? getenv("SOOC_SRC") : ".";
    if (!node || !*node || access(node, X_OK)) {
        printf("  (no node (Node.js): @mcap/core's reader not run)\n");
        return;
    }
    char cmd[2048], want[256];
    snprintf(cmd, sizeof cmd, "'%s' '%s/tests/logs/npm/read_mcap.mjs' '%s'", node, srcdir, path);
    FILE *p = popen(cmd, "r");
    char line[8192] = "";
    if (p && !fgets(line, sizeof line, p)) line[0] = 0;
    int rc = p ? pclose(p) : -1;
    if (WIFEXITED(rc) && WEXITSTATUS(rc) == 77) {
        printf("  (@mcap/core is not installed: bash scripts/install-deps.sh runs npm ci in tests/logs/npm)\n");
        return;
    }
    snprintf(want, sizeof want, "\"/sooc3d/objects\":{\"id\":1,\"schema\":\"foxglove.SceneUpdate\",\"encoding\":\"json\","
                                "\"count\":%d,\"last_entities\":%zu}", scenes, objects);
    CHECK_MSG(rc == 0 && strstr(line, want) && strstr(line, "\"/sooc3d/frames\""),
              "@mcap/core on %s: %s (want %s)", path, line, want);
    printf("  @mcap/core's indexed reader: %d SceneUpdates, %zu entities in the last\n", scenes, objects);
}

int main(void) {
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc_record_XXXXXX");
    if (!mkdtemp(g_tmp)) return 1;
    char path[400];
    size_t objects = 0;

    /* run */
    snprintf(path, sizeof path, "%s/run.mcap", g_tmp);
    run_ctx rc = {0, NULL, {0}};
    CHECK_OK(run(path, 0, 20, &rc, &objects));
    rec_read r = read_file(path);
    CHECK_MSG(r.ok && r.scenes == 20 && r.frames == 2 && r.ordered && r.last_entities == (int)objects && objects > 0,
              "run: ok %d, %d SceneUpdates, %d transforms (want map -> world, world -> source), %d entities in the "
              "last for %zu objects", r.ok, r.scenes, r.frames, r.last_entities, objects);
    /* world -> source is where the launch file's world put the pose source's frame: floor 0.25 below it */
    double up[3] = {0, 1, 0}, Tws[16];
    sooc_frames_world_from_up(up, 0.25, Tws);
    CHECK_MSG(r.has_source && fabs(r.source_t[0] - Tws[3]) < 1e-6 && fabs(r.source_t[1] - Tws[7]) < 1e-6 &&
                  fabs(r.source_t[2] - Tws[11]) < 1e-6 && fabs(Tws[7]) > 0.2,
              "world -> source: %s (%.4f, %.4f, %.4f), want (%.4f, %.4f, %.4f)", r.has_source ? "found" : "missing",
              r.source_t[0], r.source_t[1], r.source_t[2], Tws[3], Tws[7], Tws[11]);
    printf("run: %d SceneUpdates in time order, the last with all %zu objects; world -> source (%.2f, %.2f, %.2f); "
           "CRCs verified\n", r.scenes, objects, r.source_t[0], r.source_t[1], r.source_t[2]);
    npm_check(path, 20, objects);

    /* killed at keyframe 12 */
    snprintf(path, sizeof path, "%s/killed.mcap", g_tmp);
    pid_t pid = fork();
    if (pid == 0) {
        run_ctx kc = {12, NULL, {0}};
        size_t o2;
        run(path, 0, 30, &kc, &o2);
        _exit(0);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    CHECK_MSG(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL, "the child was not killed (status %d)", status);
    r = read_file(path);
    CHECK_MSG(r.ok && r.scenes == 11 && r.last_entities > 0, "killed: ok %d, %d SceneUpdates (want 11), %d entities",
              r.ok, r.scenes, r.last_entities);
    printf("killed at keyframe 12: the file holds the 11 SceneUpdates written before, summary and CRCs intact\n");
    npm_check(path, 11, (size_t)r.last_entities);

    /* finalised at exit */
    snprintf(path, sizeof path, "%s/exit.mcap", g_tmp);
    run_ctx ec = {0, path, {0}};
    CHECK_OK(run(path, 86400, 20, &ec, &objects));
    r = read_file(path);
    CHECK_MSG(ec.peeked.ok && ec.peeked.scenes == 0 && r.ok && r.scenes == 20 && r.last_entities == (int)objects,
              "exit: %d SceneUpdates while running, %d at the end", ec.peeked.scenes, r.scenes);
    printf("period_s 86400: no SceneUpdate while running, %d at exit\n", r.scenes);

    /* a path that cannot be written */
    run_ctx bc = {0, NULL, {0}};
    sooc_status st = run("/nonexistent-sooc-dir/x.mcap", 0, 5, &bc, &objects);
    CHECK_MSG(st != SOOC_OK && strstr(sooc_errmsg(), "record.mcap"), "bad path: %s", sooc_errmsg());
    printf("bad path: %s\n", sooc_errmsg());

    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (!g_check_fail && system(cmd)) { /* ignore */ }
    return check_report("test_node_record");
}
