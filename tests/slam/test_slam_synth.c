/* SLAM on a ray-cast room with known truth (loop_room.h): the camera walks a
 * closed loop and turns once.
 *  1. Loop: every frame is tracked, a loop is closed, the last keyframe
 *     verifies against the first with the true relative pose, a keyframe
 *     facing the other way is rejected by verification, and the optimised
 *     trajectory is no worse than the odometry's.
 *  2. Lost tracking: blank frames in the middle make the tracker lose the
 *     camera (FAILED, then LOST); it relocalises into its own keyframes and
 *     its poses afterwards are right.
 *  3. Restart: a first run over half of the loop stores its keyframes in a
 *     map database; a second run starts where the first never looked: its
 *     frames are LOST (untracked) until it comes round to the first run's
 *     start, relocalises, and continues in the first run's frame. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/slam.h"

#include "loop_room.h"

#define N 120

static sooc_frame g_frames[N];

static void params(sooc_slam_params *p) {
    sooc_slam_params_default(p);
    p->odom.width = p->odom.height = 0;   /* the frames are 320x240 already */
}

static double traj_ate(const sooc_slam *s) {
    sooc_traj est = {0}, gt = {0};
    if (sooc_slam_trajectory(s, &est)) return 1e9;
    for (int64_t i = 0; i < est.n; i++) {
        double T[16];
        loop_pose((int)sooc_slam_trajectory_frame(s, i), N, T);
        sooc_traj_push(&gt, est.t[i], T);
    }
    sooc_traj_metrics m;
    double r = sooc_traj_evaluate(&est, &gt, 1e-4, 0, 1, &m) ? 1e9 : m.ate_rmse;
    sooc_traj_free(&est);
    sooc_traj_free(&gt);
    return r;
}

/* the keyframe whose frame index is nearest to `frame` */
static int64_t kf_near(const sooc_slam *s, int64_t frame) {
    int64_t best = -1, bd = INT64_MAX;
    for (int64_t k = 0; k < sooc_slam_keyframe_count(s); k++) {
        int64_t fr;
        sooc_slam_keyframe(s, k, NULL, NULL, &fr, NULL);
        int64_t d = llabs(fr - frame);
        if (d < bd) { bd = d; best = k; }
    }
    return best;
}

static void test_loop(void) {
    /* 0: odometry only; 1: loop closure, candidates verified one per frame
     * after their keyframe (the default); 2: all on the keyframe's frame */
    double ate[3] = {0, 0, 0};
    int64_t loops[3] = {0, 0, 0};
    for (int run = 0; run < 3; run++) {
        int lc = run > 0;
        sooc_slam_params p;
        params(&p);
        p.loop_closure = lc;
        if (run == 2) p.loop_verify_per_frame = 0;
        sooc_slam *s = NULL;
        CHECK_OK(sooc_slam_create(&s, &p, NULL));
        double T0[16];
        loop_pose(0, N, T0);
        sooc_slam_set_initial_pose(s, T0);
        int tracked = 0, deferred = 0, fast = 1;
        for (int i = 0; i < N; i++) {
            sooc_slam_result r;
            int before = sooc_slam_pending(s);
            CHECK_OK(sooc_slam_track(s, &g_frames[i], &r));
            tracked += r.state == SOOC_SLAM_FIRST || r.state == SOOC_SLAM_TRACKED;
            int after = sooc_slam_pending(s);
            if (r.new_keyframe && after > before) deferred++;
            /* a frame verifies at most one candidate (none on a keyframe's own frame) */
            if (run == 1 && after < before - (r.new_keyframe ? 0 : 1)) fast = 0;
            if (run == 2 && after) fast = 0;
        }
        CHECK_MSG(fast, "run %d: more candidates verified on one frame than asked", run);
        if (run == 1) CHECK_MSG(deferred > 0, "no keyframe's candidates were left for the frames after it");
        CHECK_OK(sooc_slam_flush(s, NULL));
        CHECK(sooc_slam_pending(s) == 0);
        sooc_slam_stats st;
        sooc_slam_get_stats(s, &st);
        CHECK_MSG(tracked == N, "run %d: %d of %d frames tracked", run, tracked, N);
        ate[run] = traj_ate(s);
        loops[run] = st.loops;
        printf("run %d (loop closure %d): %lld keyframes, %lld loops (%lld candidates, %lld rejected), ATE %.4f m\n",
               run, lc, (long long)st.keyframes, (long long)st.loops, (long long)st.loop_candidates,
               (long long)st.loop_rejected, ate[run]);
        CHECK_MSG(ate[run] < 0.01, "ATE %.4f m", ate[run]);
        if (run == 1) {
            CHECK_MSG(st.loops >= 1 && st.optimisations >= 1, "no loop closed (%lld)", (long long)st.loops);
            /* the last keyframe against the first: the true relative pose */
            int64_t nk = sooc_slam_keyframe_count(s), fa, fb;
            sooc_slam_keyframe(s, nk - 1, NULL, NULL, &fa, NULL);
            sooc_slam_keyframe(s, 0, NULL, NULL, &fb, NULL);
            int ok = 0, inl = 0;
            double T[16], Ta[16], Tb[16], inv[16], Ttrue[16], dt, dr;
            CHECK_OK(sooc_slam_verify_pair(s, nk - 1, 0, &ok, T, &inl));
            loop_pose((int)fa, N, Ta);
            loop_pose((int)fb, N, Tb);
            sooc_se3_inverse(inv, Tb);
            sooc_se3_mul(Ttrue, inv, Ta);
            pose_diff(T, Ttrue, &dt, &dr);
            printf("verify frame %lld vs frame %lld: accepted %d, %d inliers, error %.4f m %.2f deg\n", (long long)fa,
                   (long long)fb, ok, inl, dt, dr);
            CHECK(ok);
            CHECK_MSG(dt < 0.02 && dr < 1.0, "loop edge off by %.4f m, %.2f deg", dt, dr);
            /* a keyframe half a turn away sees other walls: rejected */
            int64_t kh = kf_near(s, N / 2);
            CHECK_OK(sooc_slam_verify_pair(s, kh, 0, &ok, T, &inl));
            printf("verify the keyframe half a turn away: accepted %d (%d inliers)\n", ok, inl);
            CHECK_MSG(!ok, "a keyframe facing the other way was accepted");
        }
        sooc_slam_destroy(s);
    }
    CHECK_MSG(ate[1] <= ate[0] + 0.002, "loop closure made the trajectory worse: %.4f vs %.4f", ate[1], ate[0]);
    /* verifying later finds the same loops */
    CHECK_MSG(loops[1] == loops[2] && fabs(ate[1] - ate[2]) < 0.002, "deferred: %lld loops, ATE %.4f; at once: %lld, %.4f",
              (long long)loops[1], ate[1], (long long)loops[2], ate[2]);
}

static void test_lost(void) {
    sooc_slam_params p;
    params(&p);
    p.loop_closure = 0;
    p.odom.max_failures = 3;
    sooc_slam *s = NULL;
    CHECK_OK(sooc_slam_create(&s, &p, NULL));
    double T0[16];
    loop_pose(0, N, T0);
    sooc_slam_set_initial_pose(s, T0);
    sooc_frame blank;
    memset(&blank, 0, sizeof blank);
    CHECK_OK(sooc_frame_alloc(&blank, W, H, 0));
    blank.K = g_frames[0].K;
    int n_failed = 0, n_lost = 0, reloc_at = -1, bad = 0;
    for (int i = 0; i < 50; i++) {
        sooc_slam_result r;
        if (i >= 30 && i < 36) {   /* six blank frames: no colour, no depth */
            blank.index = 1000 + i;
            blank.t_ns = g_frames[i].t_ns;
            CHECK_OK(sooc_slam_track(s, &blank, &r));
            n_failed += r.state == SOOC_SLAM_FAILED;
            n_lost += r.state == SOOC_SLAM_LOST;
            continue;
        }
        CHECK_OK(sooc_slam_track(s, &g_frames[i], &r));
        if (i > 36 && r.state == SOOC_SLAM_LOST) n_lost++;
        if (r.state == SOOC_SLAM_RELOCALISED && reloc_at < 0) reloc_at = i;
        if (i >= 36 && r.state <= SOOC_SLAM_RELOCALISED) {
            double T[16], dt, dr;
            loop_pose(i, N, T);
            pose_diff(T, r.T_wc, &dt, &dr);
            if (dt > 0.03 || dr > 2) {
                bad++;
                fprintf(stderr, "frame %d (%s): %.4f m, %.2f deg from the truth\n", i, sooc_slam_state_name(r.state),
                        dt, dr);
            }
        }
    }
    sooc_slam_stats st;
    sooc_slam_get_stats(s, &st);
    printf("lost tracking: %d failed, %d lost, relocalised at frame %d, %d bad poses after\n", n_failed, n_lost,
           reloc_at, bad);
    CHECK(n_failed >= 2 && n_lost >= 1);
    CHECK_MSG(reloc_at == 36, "relocalised at frame %d (expected 36)", reloc_at);
    CHECK(st.relocalised == 1);
    CHECK(bad == 0);
    sooc_frame_free(&blank);
    sooc_slam_destroy(s);
}

static void test_restart(void) {
    char dir[] = "/tmp/sooc_slam_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char path[256];
    snprintf(path, sizeof path, "%s/map.sqlite", dir);
    sooc_slam_params p;
    params(&p);
    /* run 1: the first half of the loop */
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 1;
    mp.dim = 1;
    sooc_mapstore *store = NULL;
    CHECK_OK(sooc_mapstore_open(&store, path, &mp));
    sooc_slam *s = NULL;
    CHECK_OK(sooc_slam_create(&s, &p, store));
    double T0[16];
    loop_pose(0, N, T0);
    sooc_slam_set_initial_pose(s, T0);
    for (int i = 0; i < N / 2; i++) {
        sooc_slam_result r;
        CHECK_OK(sooc_slam_track(s, &g_frames[i], &r));
    }
    int64_t nk1 = sooc_slam_keyframe_count(s);
    sooc_slam_destroy(s);
    sooc_mapstore_close(store);
    /* run 2: from three quarters round (never seen) on to the start */
    mp.dim = 0;
    CHECK_OK(sooc_mapstore_open(&store, path, &mp));
    int64_t nk, ne;
    int32_t run;
    CHECK_OK(sooc_mapstore_slam_count(store, &nk, &ne, &run));
    CHECK_MSG(nk == nk1 && run == 0 && ne == nk1 - 1, "stored %lld keyframes, %lld edges, run %d (made %lld)",
              (long long)nk, (long long)ne, run, (long long)nk1);
    CHECK_OK(sooc_slam_create(&s, &p, store));
    int lost = 0, reloc_at = -1, bad = 0, tracked_before = 0;
    for (int j = 3 * N / 4; j < N + 20; j++) {
        int i = j % N;
        sooc_slam_result r;
        CHECK_OK(sooc_slam_track(s, &g_frames[i], &r));
        if (reloc_at < 0) {
            lost += r.state == SOOC_SLAM_LOST;
            tracked_before += r.state != SOOC_SLAM_LOST && r.state != SOOC_SLAM_RELOCALISED;
            if (r.state == SOOC_SLAM_RELOCALISED) reloc_at = i;
        }
        if (r.state <= SOOC_SLAM_RELOCALISED) {
            double T[16], dt, dr;
            loop_pose(i, N, T);
            pose_diff(T, r.T_wc, &dt, &dr);
            if (dt > 0.03 || dr > 2) {
                bad++;
                fprintf(stderr, "run 2 frame %d (%s): %.4f m, %.2f deg from the truth\n", i,
                        sooc_slam_state_name(r.state), dt, dr);
            }
        }
    }
    sooc_slam_stats st;
    sooc_slam_get_stats(s, &st);
    printf("restart: %lld stored keyframes, %d frames lost, relocalised at frame %d, %d bad poses\n",
           (long long)st.stored_keyframes, lost, reloc_at, bad);
    CHECK(st.stored_keyframes == nk1);
    CHECK_MSG(lost >= 5 && tracked_before == 0, "%d lost, %d tracked before relocalising", lost, tracked_before);
    CHECK_MSG(reloc_at >= 0 && (reloc_at > 3 * N / 4 || reloc_at < 10), "relocalised at frame %d", reloc_at);
    CHECK(bad == 0);
    sooc_traj tr = {0};
    CHECK_OK(sooc_slam_trajectory(s, &tr));
    CHECK_MSG(tr.n == (N + 20 - 3 * N / 4) - lost, "trajectory %lld poses, %d lost", (long long)tr.n, lost);
    sooc_traj_free(&tr);
    sooc_slam_destroy(s);
    CHECK_OK(sooc_mapstore_slam_count(store, &nk, &ne, &run));
    CHECK(nk > nk1 && run == 1);
    sooc_mapstore_close(store);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    CHECK(system(cmd) == 0);
}

int main(void) {
    if (!sooc_cv_available()) {
        printf("test_slam_synth: SKIP: built without OpenCV (libopencv-contrib-dev, SOOC_WITH_OPENCV)\n");
        return SOOC_TEST_SKIP;
    }
    for (int i = 0; i < N; i++) {
        if (sooc_frame_alloc(&g_frames[i], W, H, 0)) return 1;
        loop_frame(i, N, &g_frames[i]);
    }
    test_loop();
    test_lost();
    test_restart();
    for (int i = 0; i < N; i++) sooc_frame_free(&g_frames[i]);
    printf("test_slam_synth: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail ? 1 : 0;
}
