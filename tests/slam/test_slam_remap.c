/* Map entries follow their keyframes when the pose graph moves them
 * (sooc_slam_move_entries):
 *  1. a known motion of one keyframe (a turn about +y and a shift): an entry
 *     last seen next to it moves by exactly that (position, yaw, the xz
 *     covariance turned with it, the registrations' mean); an entry nearest
 *     an unchanged keyframe and one seen outside the keyframes' time span do
 *     not move;
 *  2. the tracker on the room loop (loop_room.h) with loop closure: after an
 *     optimisation the changes cover this run's keyframes, and an entry
 *     placed at a keyframe's camera before lands at its camera after. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/slam.h"

#include "loop_room.h"

static void test_known(void) {
    sooc_slam_kf_change chg[3];
    memset(chg, 0, sizeof chg);
    for (int k = 0; k < 3; k++) {
        chg[k].t_ns = (int64_t)k * 1000000000;
        loop_pose(10 * k, 120, chg[k].T_before);
        memcpy(chg[k].T_after, chg[k].T_before, sizeof chg[k].T_after);
    }
    const double th = 0.2, t[3] = {0.3, 0, -0.1};
    double R[9], D[16], A[16];
    sooc_m3_rot_y(R, th);
    sooc_se3_from_rt(D, R, t);
    sooc_se3_mul(A, D, chg[1].T_before);   /* keyframe 1 moved by D in the world */
    memcpy(chg[1].T_after, A, sizeof A);
    double Wid[16];
    sooc_se3_identity(Wid);
    sooc_map_entry e[3];
    memset(e, 0, sizeof e);
    for (int i = 0; i < 3; i++) {
        e[i].x = 1.0 + i;
        e[i].z = -0.5;
        e[i].yaw = 0.4;
        e[i].geom.centre[1] = 0.5f;
        e[i].geom.cov_xz[0] = 0.04;
        e[i].geom.cov_xz[2] = 0.01;
        e[i].geom.reg_n = 3;
        e[i].geom.reg_mean[0] = e[i].x;
        e[i].geom.reg_mean[1] = e[i].z;
    }
    e[0].last_seen_ns = 1100000000;   /* next to keyframe 1 */
    e[1].last_seen_ns = 1800000000;   /* nearest keyframe 2: unchanged */
    e[2].last_seen_ns = 9000000000;   /* outside the span */
    size_t moved = sooc_slam_move_entries(chg, 3, Wid, 500000000, e, 3);
    CHECK(moved == 2);
    double c = cos(th), s = sin(th);
    CHECK_CLOSE(e[0].x, c * 1.0 + s * -0.5 + 0.3, 1e-12, 0);
    CHECK_CLOSE(e[0].z, -s * 1.0 + c * -0.5 - 0.1, 1e-12, 0);
    CHECK_CLOSE(e[0].yaw, 0.4 + th, 1e-12, 0);
    CHECK_CLOSE(e[0].geom.reg_mean[0], e[0].x, 1e-12, 0);
    CHECK_CLOSE(e[0].geom.reg_mean[1], e[0].z, 1e-12, 0);
    /* the covariance's principal axis (x) turned by th: the trace stays, xz = -cs (xx - zz) */
    CHECK_CLOSE(e[0].geom.cov_xz[0] + e[0].geom.cov_xz[2], 0.05, 1e-12, 0);
    CHECK_CLOSE(e[0].geom.cov_xz[1], -c * s * 0.03, 1e-12, 0);
    CHECK_CLOSE(e[1].x, 2.0, 1e-12, 0);
    CHECK_CLOSE(e[1].yaw, 0.4, 1e-12, 0);
    CHECK(e[2].x == 3.0 && e[2].yaw == 0.4);
    /* a world frame other than the tracker's: the same motion seen in it */
    double Ry[9], tw[3] = {1, 0.2, -2}, Wt[16], Wi[16], Dw[16], B[16];
    sooc_m3_rot_y(Ry, 0.7);
    sooc_se3_from_rt(Wt, Ry, tw);
    sooc_se3_inverse(Wi, Wt);
    sooc_se3_mul(B, Wt, D);
    sooc_se3_mul(Dw, B, Wi);
    sooc_map_entry f = {0};
    f.x = 0.5;
    f.z = 0.25;
    f.geom.centre[1] = 0.3f;
    f.last_seen_ns = 1000000000;
    CHECK(sooc_slam_move_entries(chg, 3, Wt, 0, &f, 1) == 1);
    double p[3] = {0.5, 0.3, 0.25}, q[3];
    sooc_se3_apply(q, Dw, p);
    CHECK_CLOSE(f.x, q[0], 1e-12, 0);
    CHECK_CLOSE(f.z, q[2], 1e-12, 0);
    CHECK_CLOSE(f.yaw, th, 1e-12, 0);
}

static void test_tracker(void) {
    if (!sooc_cv_available()) return;
    const int N = 120;
    sooc_slam_params p;
    sooc_slam_params_default(&p);
    p.odom.width = p.odom.height = 0;
    sooc_slam *s = NULL;
    CHECK_OK(sooc_slam_create(&s, &p, NULL));
    sooc_frame f;
    memset(&f, 0, sizeof f);
    CHECK_OK(sooc_frame_alloc(&f, W, H, 0));
    uint64_t v0 = sooc_slam_graph_version(s);
    int checked = 0;
    for (int i = 0; i < N; i++) {
        loop_frame(i, N, &f);
        sooc_slam_result r;
        CHECK_OK(sooc_slam_track(s, &f, &r));
        if (!r.loop_closed) continue;
        size_t n = 0;
        CHECK_OK(sooc_slam_last_changes(s, NULL, 0, &n));
        CHECK((int64_t)n == sooc_slam_keyframe_count(s));
        static sooc_slam_kf_change chg[256];
        CHECK_OK(sooc_slam_last_changes(s, chg, 256, &n));
        double I[16];
        sooc_se3_identity(I);
        for (size_t k = 0; k < n && k < 256; k += 5) {
            sooc_map_entry e = {0};
            e.x = chg[k].T_before[3];
            e.z = chg[k].T_before[11];
            e.geom.centre[1] = (float)chg[k].T_before[7];
            e.last_seen_ns = chg[k].t_ns;
            CHECK(sooc_slam_move_entries(chg, n, I, 0, &e, 1) == 1);
            CHECK_CLOSE(e.x, chg[k].T_after[3], 1e-5, 0);
            CHECK_CLOSE(e.z, chg[k].T_after[11], 1e-5, 0);
            checked++;
        }
    }
    printf("graph version %llu -> %llu, %d entries checked\n", (unsigned long long)v0,
           (unsigned long long)sooc_slam_graph_version(s), checked);
    CHECK(sooc_slam_graph_version(s) > v0 && checked > 0);
    sooc_frame_free(&f);
    sooc_slam_destroy(s);
}

int main(void) {
    test_known();
    test_tracker();
    printf("test_slam_remap: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail ? 1 : 0;
}
