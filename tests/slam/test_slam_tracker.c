/* The tracking thread (sooc_slam_tracker): frames of the room loop
 * (loop_room.h) come from a source callback; a consumer that keeps up gets
 * every frame with its pose; a consumer slower than the tracker makes the
 * tracker drop queued frames (counted) but never slows the tracking: every
 * source frame is still tracked, and popped + dropped = tracked. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/slam.h"

#include "loop_room.h"

#define N 60
#define NLOOP 120

static sooc_frame g_frames[N];

typedef struct src {
    int next;
} src;

static sooc_status pop_src(void *ctx, sooc_frame *f, int64_t *t_mono, int timeout_ms) {
    (void)timeout_ms;
    src *s = ctx;
    if (s->next >= N) return SOOC_EEOF;
    if (!f->rgb) {
        sooc_status st = sooc_frame_alloc(f, W, H, 0);
        if (st) return st;
    }
    const sooc_frame *g = &g_frames[s->next++];
    memcpy(f->rgb, g->rgb, (size_t)W * H * 3);
    memcpy(f->depth, g->depth, sizeof(float) * W * H);
    memcpy(f->valid, g->valid, (size_t)W * H);
    f->K = g->K;
    f->t_ns = g->t_ns;
    f->index = g->index;
    f->has_pose = 0;
    *t_mono = g->t_ns;
    return SOOC_OK;
}

static void run(int consumer_sleep_us, int qcap, sooc_slam_tracker_stats *out, int *popped, int *bad) {
    sooc_slam_params p;
    sooc_slam_params_default(&p);
    p.odom.width = p.odom.height = 0;
    sooc_slam *s = NULL;
    CHECK_OK(sooc_slam_create(&s, &p, NULL));
    double T0[16];
    loop_pose(0, NLOOP, T0);
    sooc_slam_set_initial_pose(s, T0);
    src sc = {0};
    sooc_slam_tracker *t = NULL;
    CHECK_OK(sooc_slam_tracker_start(&t, s, pop_src, &sc, qcap));
    sooc_frame f;
    memset(&f, 0, sizeof f);
    *popped = *bad = 0;
    for (;;) {
        int64_t tm;
        sooc_status st = sooc_slam_tracker_pop(t, &f, &tm, 1000);
        if (st == SOOC_ETIMEOUT) continue;
        if (st == SOOC_EEOF) break;
        CHECK_OK(st);
        if (st) break;
        (*popped)++;
        double T[16], dt, dr;
        loop_pose((int)f.index, NLOOP, T);
        pose_diff(T, f.T_wc, &dt, &dr);
        if (!f.has_pose || dt > 0.01 || dr > 0.5) (*bad)++;
        if (consumer_sleep_us) usleep((useconds_t)consumer_sleep_us);
    }
    sooc_slam_tracker_get_stats(t, out);
    char line[512];
    sooc_slam_tracker_stats_format(out, line, sizeof line);
    printf("consumer sleeping %d us, queue %d: popped %d; %s\n", consumer_sleep_us, qcap, *popped, line);
    sooc_frame_free(&f);
    sooc_slam_tracker_destroy(t);
}

int main(void) {
    if (!sooc_cv_available()) {
        printf("test_slam_tracker: SKIP: built without OpenCV (libopencv-contrib-dev, SOOC_WITH_OPENCV)\n");
        return SOOC_TEST_SKIP;
    }
    for (int i = 0; i < N; i++) {
        if (sooc_frame_alloc(&g_frames[i], W, H, 0)) return 1;
        loop_frame(i, NLOOP, &g_frames[i]);
    }
    sooc_slam_tracker_stats st;
    int popped, bad;
    /* a consumer that keeps up: every frame, in order, with its pose */
    run(0, 4, &st, &popped, &bad);
    CHECK(st.frames_in == N && st.tracked == N && popped == N && st.dropped_queue_full == 0 && bad == 0);
    /* a consumer far slower than tracking (300 ms per frame): frames are
     * dropped from the queue, none is left untracked */
    run(300000, 2, &st, &popped, &bad);
    CHECK(st.frames_in == N && st.tracked == N);
    CHECK_MSG(st.dropped_queue_full > 0, "nothing dropped with a slow consumer");
    CHECK_MSG(popped + st.dropped_queue_full == st.tracked, "popped %d + dropped %lld != tracked %lld", popped,
              (long long)st.dropped_queue_full, (long long)st.tracked);
    CHECK(bad == 0);
    for (int i = 0; i < N; i++) sooc_frame_free(&g_frames[i]);
    printf("test_slam_tracker: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail ? 1 : 0;
}
