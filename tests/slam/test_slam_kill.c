/* The SLAM keyframe database across a SIGKILL: a child process tracks the
 * room loop (loop_room.h) into a map database, keyframe after keyframe, and
 * is killed mid-run once a few keyframes are stored. The database must open
 * again, hold whole keyframes only (every record decodes: the SLAM tracker
 * loads them all), every edge must name stored keyframes, and a new run must
 * relocalise into them. */
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/slam.h"

#include "loop_room.h"

#define N 120

static int child(const char *path) {
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 1;
    mp.dim = 1;
    sooc_mapstore *store = NULL;
    if (sooc_mapstore_open(&store, path, &mp)) return 2;
    sooc_slam_params p;
    sooc_slam_params_default(&p);
    p.odom.width = p.odom.height = 0;
    sooc_slam *s = NULL;
    if (sooc_slam_create(&s, &p, store)) return 3;
    sooc_frame f;
    memset(&f, 0, sizeof f);
    if (sooc_frame_alloc(&f, W, H, 0)) return 4;
    for (int j = 0;; j++) {   /* round and round until killed */
        loop_frame(j % N, N, &f);
        f.index = j;
        f.t_ns = (int64_t)j * 33333333;
        sooc_slam_result r;
        if (sooc_slam_track(s, &f, &r)) return 5;
    }
}

typedef struct chk {
    int64_t n;
    int64_t ids[4096];
} chk;

static int count_kf(const sooc_slamdb_kf *k, void *user) {
    chk *c = user;
    if (c->n < 4096) c->ids[c->n] = k->id;
    c->n++;
    return 0;
}

int main(void) {
    if (!sooc_cv_available()) {
        printf("test_slam_kill: SKIP: built without OpenCV (libopencv-contrib-dev, SOOC_WITH_OPENCV)\n");
        return SOOC_TEST_SKIP;
    }
    char dir[] = "/tmp/sooc_slamkill_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char path[256];
    snprintf(path, sizeof path, "%s/map.sqlite", dir);
    pid_t pid = fork();
    if (pid == 0) _exit(child(path));
    CHECK(pid > 0);
    /* wait until the child has stored some keyframes (read through WAL) */
    int64_t nk = 0, ne = 0;
    int32_t run = -1;
    for (int t = 0; t < 1200 && nk < 12; t++) {
        usleep(100000);
        int status;
        if (waitpid(pid, &status, WNOHANG) == pid) {
            fprintf(stderr, "the child ended early (status %d)\n", status);
            CHECK(0);
            return 1;
        }
        sooc_mapstore_params rp;
        sooc_mapstore_params_default(&rp);
        rp.create = 0;
        sooc_mapstore *st = NULL;
        if (sooc_mapstore_open(&st, path, &rp)) continue;
        if (sooc_mapstore_slam_count(st, &nk, &ne, &run)) nk = 0;
        sooc_mapstore_close(st);
    }
    usleep(150000);   /* somewhere inside the next keyframe or two */
    CHECK(kill(pid, SIGKILL) == 0);
    int status = 0;
    CHECK(waitpid(pid, &status, 0) == pid);
    CHECK(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
    /* the database opens, holds whole keyframes, and edges name them */
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    sooc_mapstore *store = NULL;
    CHECK_OK(sooc_mapstore_open(&store, path, &mp));
    CHECK_OK(sooc_mapstore_slam_count(store, &nk, &ne, &run));
    static chk c;
    CHECK_OK(sooc_mapstore_slam_foreach_keyframe(store, count_kf, &c));
    printf("after SIGKILL: %lld keyframes, %lld edges stored (run %d)\n", (long long)nk, (long long)ne, run);
    CHECK(nk >= 12 && c.n == nk && run == 0);
    CHECK_MSG(ne == nk - 1, "%lld edges for %lld keyframes (odometry chain, no loop yet)", (long long)ne,
              (long long)nk);
    sooc_slam_params p;
    sooc_slam_params_default(&p);
    p.odom.width = p.odom.height = 0;
    sooc_slam *s = NULL;
    CHECK_OK(sooc_slam_create(&s, &p, store));   /* decodes every record (CRC) and every edge */
    sooc_slam_stats st;
    sooc_slam_get_stats(s, &st);
    CHECK(st.stored_keyframes == nk);
    /* a new run relocalises at the loop's start */
    sooc_frame f;
    memset(&f, 0, sizeof f);
    CHECK_OK(sooc_frame_alloc(&f, W, H, 0));
    int reloc = 0;
    for (int i = 0; i < 5 && !reloc; i++) {
        loop_frame(i, N, &f);
        sooc_slam_result r;
        CHECK_OK(sooc_slam_track(s, &f, &r));
        reloc = r.state == SOOC_SLAM_RELOCALISED;
    }
    CHECK_MSG(reloc, "no relocalisation into the keyframes left by the killed run");
    sooc_frame_free(&f);
    sooc_slam_destroy(s);
    sooc_mapstore_close(store);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    CHECK(system(cmd) == 0);
    printf("test_slam_kill: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail ? 1 : 0;
}
