/* The node with pose.source: odometry and the tracking thread (fake mapper,
 * tests/node/fake_mapper.c), on the room loop (loop_room.h):
 *  1. odometry.loop_closure: every frame is tracked on the tracking thread
 *     (its stats line says so), the map gets keyframes, the keyframes of the
 *     tracker go into map.db's SLAM tables, and when a loop closes the map
 *     entries follow their keyframes (logged);
 *  2. a restart with map.resume and odometry.relocalise over part of the
 *     loop again: it relocalises into the stored keyframes, and tracks on
 *     in the stored map's frame (every frame accounted for).
 * Launch keys: odometry.thread / loop_closure / relocalise parse and dump. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/mapper.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"
#include "sooc3d/slam.h"

#include "loop_room.h"

#define NLOOP 120

typedef struct feeder {
    const int *order;
    int n, next;
    sooc_frame *frames;
} feeder;

static sooc_status fd_start(void *ctx) { (void)ctx; return SOOC_OK; }
static void fd_stop(void *ctx) { (void)ctx; }
static void fd_close(void *ctx) { (void)ctx; }
static sooc_status fd_read(void *ctx, sooc_frame *f, int timeout_ms) {
    (void)timeout_ms;
    feeder *d = ctx;
    if (d->next >= d->n) return SOOC_EEOF;
    int i = d->order[d->next];
    sooc_status st = sooc_frame_copy(f, &d->frames[i]);
    f->index = d->next;
    f->t_ns = (int64_t)d->next * 33333333;
    d->next++;
    f->has_pose = 0;   /* a camera without poses */
    return st;
}

static char g_track_line[1024];
static int g_follow;

static void log_cb(void *user, sooc_log_level level, const char *msg) {
    (void)user;
    if (level >= SOOC_LOG_INFO && strstr(msg, "tracking:")) snprintf(g_track_line, sizeof g_track_line, "%s", msg);
    if (level >= SOOC_LOG_INFO && strstr(msg, "map entries follow them")) {
        if (!g_follow) printf("  [log] %s\n", msg);
        g_follow++;
    }
    if (level >= SOOC_LOG_WARN) printf("  [log] %s\n", msg);
}

static long long field(const char *line, const char *name) {
    const char *p = strstr(line, name);
    if (!p) return -1;
    while (p > line && p[-1] == ' ') p--;
    while (p > line && p[-1] != ' ' && p[-1] != ',') p--;
    return atoll(p);
}

static void run_node(const char *db, int resume, const int *order, int n, sooc_frame *frames, sooc_node_stats *out) {
    char launch[2048];
    snprintf(launch, sizeof launch,
             "sensor: {driver: replay, path: unused}\n"
             "pose: {source: odometry}\n"
             "odometry: {variant: rgbd_icp, width: 0, height: 0, thread: true, loop_closure: true, relocalise: true}\n"
             "model: {path: fake}\n"
             "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
             "map: {db: '%s', resume: %s}\n"
             "pipeline: {block_when_full: true, min_depth_m: 0.1, max_depth_m: 10}\n"
             "log: {level: info}\n",
             db, resume ? "true" : "false");
    sooc_node_config c;
    CHECK_OK(sooc_node_config_parse(&c, launch, strlen(launch), "slam.yaml"));
    CHECK(c.odom_thread && c.odom_loop_closure && c.odom_relocalise);
    feeder fd = {order, n, 0, frames};
    sooc_node_source src = {&fd, fd_start, fd_read, fd_stop, fd_close, NULL, NULL};
    sooc_mapper *m = NULL;
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    CHECK_OK(sooc_mapper_create(&m, &mp));
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.source = &src;
    o.mapper = m;
    sooc_node *nd = NULL;
    g_track_line[0] = 0;
    sooc_status st = sooc_node_create(&nd, &c, &o);
    CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
    if (!st) {
        CHECK_MSG(sooc_node_run(nd) == SOOC_OK, "%s", sooc_errmsg());
        sooc_node_get_stats(nd, out);
        sooc_node_destroy(nd);
    }
    sooc_mapper_destroy(m);
}

int main(void) {
    if (!sooc_cv_available()) {
        printf("test_slam_node: SKIP: built without OpenCV (libopencv-contrib-dev, SOOC_WITH_OPENCV)\n");
        return SOOC_TEST_SKIP;
    }
    sooc_log_set_callback(log_cb, NULL);
    /* keys: defaults off, dumped */
    sooc_node_config c;
    const char *base = "sensor: {driver: replay, path: unused}\npose: {source: odometry}\nmodel: {path: fake}\n";
    CHECK_OK(sooc_node_config_parse(&c, base, strlen(base), "a.yaml"));
    CHECK(!c.odom_thread && !c.odom_loop_closure && !c.odom_relocalise);
    char buf[8192];
    sooc_node_config_format(&c, buf, sizeof buf);
    CHECK(strstr(buf, "thread: false, loop_closure: false, relocalise: false") != NULL);
    const char *bad = "sensor: {driver: replay, path: unused}\npose: {source: odometry}\nmodel: {path: fake}\n"
                      "odometry: {loop_closure: maybe}\n";
    CHECK(sooc_node_config_parse(&c, bad, strlen(bad), "b.yaml") == SOOC_EINVAL);
    CHECK(strstr(sooc_errmsg(), "loop_closure") != NULL);

    sooc_frame *fr = calloc(NLOOP, sizeof *fr);
    for (int i = 0; i < NLOOP; i++) {
        CHECK_OK(sooc_frame_alloc(&fr[i], W, H, 0));
        loop_frame(i, NLOOP, &fr[i]);
    }
    char dir[] = "/tmp/sooc_slamnode_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char db[256];
    snprintf(db, sizeof db, "%s/map.sqlite", dir);
    /* 1. the whole loop */
    int order1[NLOOP];
    for (int i = 0; i < NLOOP; i++) order1[i] = i;
    sooc_node_stats s1;
    memset(&s1, 0, sizeof s1);
    run_node(db, 0, order1, NLOOP, fr, &s1);
    printf("run 1: %s\n", g_track_line);
    CHECK_MSG(field(g_track_line, "tracked") == NLOOP, "tracked %lld of %d", field(g_track_line, "tracked"), NLOOP);
    CHECK(field(g_track_line, "lost") == 0 && field(g_track_line, "failed") == 0);
    CHECK(field(g_track_line, "loops") >= 1);
    CHECK(s1.frames_in == NLOOP && s1.keyframes >= 5);
    /* the loop closures moved the map: entries followed their keyframes, published in one batch each */
    printf("run 1: %d times map entries followed the pose graph (%llu objects)\n", g_follow,
           (unsigned long long)s1.n_objects);
    CHECK(g_follow >= 1 && s1.n_objects > 0);
    /* the tracking keyframes are in the map database */
    sooc_mapstore *ms = NULL;
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    mp.readonly = 1;
    CHECK_OK(sooc_mapstore_open(&ms, db, &mp));
    int64_t nk = 0, ne = 0;
    int32_t run = -1;
    if (ms) CHECK_OK(sooc_mapstore_slam_count(ms, &nk, &ne, &run));
    sooc_mapstore_close(ms);
    printf("map.db: %lld tracking keyframes, %lld edges\n", (long long)nk, (long long)ne);
    CHECK(nk == field(g_track_line, "keyframes") && nk >= 10 && run == 0);
    /* 2. restart over frames 60-99 of the loop */
    int order2[40];
    for (int i = 0; i < 40; i++) order2[i] = (3 * NLOOP / 4 - 30 + i + NLOOP) % NLOOP;
    sooc_node_stats s2;
    memset(&s2, 0, sizeof s2);
    run_node(db, 1, order2, 40, fr, &s2);
    printf("run 2: %s\n", g_track_line);
    CHECK(field(g_track_line, "relocalised") == 1);
    CHECK(field(g_track_line, "tracked") + field(g_track_line, "lost") + field(g_track_line, "failed") == 40);
    for (int i = 0; i < NLOOP; i++) sooc_frame_free(&fr[i]);
    free(fr);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    CHECK(system(cmd) == 0);
    printf("test_slam_node: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail ? 1 : 0;
}
