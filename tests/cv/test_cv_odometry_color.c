/* RGB-D odometry with colour not registered to depth (7-Scenes: the depth
 * camera has f = 585, the colour camera f = 525, and the dataset ships one
 * intrinsics file, the depth camera's). The test room (room.h) is ray-cast
 * twice per pose: depth from a depth camera (f 292.5 at 320x240), colour from
 * a colour camera with another focal length (262.5) and 2.5 cm to its side
 * (p_color = T_color_depth * p_depth). Given the colour camera
 * (sooc_odom_params.color_K, T_color_depth), rgbd and rgbd_icp must track
 * the depth camera as well as on registered frames (ATE under 1 cm / 2 mm);
 * taking the colour as registered must be measurably worse. Bad colour
 * parameters are EINVAL. The 7-Scenes helpers recognise the depth
 * intrinsics and set the colour camera. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "sooc3d/slam.h"
#include "sooc3d/core.h"

#include "room.h"

static double run(const sooc_frame *frames, int n, const sooc_traj *gt, sooc_odom_variant v, const double *color_K,
                  const double *T_cd, int *tracked) {
    sooc_odom_params p;
    sooc_odom_params_default(&p);
    p.variant = v;
    p.width = p.height = 0;
    if (color_K) {
        memcpy(p.color_K, color_K, sizeof p.color_K);
        memcpy(p.T_color_depth, T_cd, sizeof p.T_color_depth);
    }
    sooc_odom *o = NULL;
    if (sooc_odom_create(&o, &p) != SOOC_OK) return 1e9;
    sooc_odom_set_initial_pose(o, frames[0].T_wc);
    sooc_traj est = {0};
    *tracked = 0;
    for (int i = 0; i < n; i++) {
        sooc_odom_result r;
        if (sooc_odom_track(o, &frames[i], &r) != SOOC_OK) break;
        if (r.state == SOOC_ODOM_FIRST || r.state == SOOC_ODOM_TRACKED) {
            (*tracked)++;
            sooc_traj_push(&est, i / 30.0, r.T_wc);
        }
    }
    sooc_traj_metrics m;
    double ate = sooc_traj_evaluate(&est, gt, 0.001, 0, 10, &m) ? 1e9 : m.ate_rmse;
    sooc_traj_free(&est);
    sooc_odom_destroy(o);
    return ate;
}

int main(void) {
    if (!sooc_cv_available()) {
        printf("test_cv_odometry_color: SKIP: built without OpenCV (libopencv-contrib-dev, SOOC_WITH_OPENCV)\n");
        return SOOC_TEST_SKIP;
    }
    /* the 7-Scenes helpers */
    sooc_intrinsics K7 = {0};
    K7.width = 640;
    K7.height = 480;
    K7.fx = K7.fy = 585;
    K7.cx = 320;
    K7.cy = 240;
    CHECK(sooc_odom_is_7scenes_depth_K(&K7, 640, 480));
    K7.fx = K7.fy = 525;
    CHECK(!sooc_odom_is_7scenes_depth_K(&K7, 640, 480));
    K7.fx = K7.fy = 292.5;
    K7.cx = 160;
    K7.cy = 120;
    CHECK(sooc_odom_is_7scenes_depth_K(&K7, 320, 240));
    sooc_odom_params p7;
    sooc_odom_params_default(&p7);
    CHECK(p7.color_K[0] == 0 && p7.T_color_depth[0] == 1 && p7.T_color_depth[15] == 1);
    sooc_odom_params_7scenes_color(&p7, 640, 480);
    CHECK(p7.color_K[0] == 525 && p7.color_K[1] == 525 && p7.color_K[2] == 320 && p7.color_K[3] == 240);

    /* bad colour parameters */
    sooc_odom *bad = NULL;
    sooc_odom_params pb;
    sooc_odom_params_default(&pb);
    pb.color_K[0] = -1;
    pb.color_K[1] = 300;
    CHECK(sooc_odom_create(&bad, &pb) == SOOC_EINVAL && bad == NULL);
    printf("bad colour K: %s\n", sooc_errmsg());
    pb.color_K[0] = 300;
    pb.T_color_depth[0] = 2;   /* not a rotation */
    CHECK(sooc_odom_create(&bad, &pb) == SOOC_EINVAL && bad == NULL);
    printf("bad T_color_depth: %s\n", sooc_errmsg());

    /* the two cameras */
    sooc_intrinsics Kd = {0}, Kc = {0};
    Kd.width = Kc.width = W;
    Kd.height = Kc.height = H;
    Kd.fx = Kd.fy = 292.5;
    Kd.cx = 159.5;
    Kd.cy = 119.5;
    Kc.fx = Kc.fy = 262.5;
    Kc.cx = 161.0;
    Kc.cy = 118.5;
    double T_cd[16], T_dc[16];
    sooc_se3_identity(T_cd);
    T_cd[3] = 0.025;   /* the colour camera sits 2.5 cm to the depth camera's -x */
    sooc_se3_inverse(T_dc, T_cd);
    const int N = 60;
    sooc_frame *frames = calloc((size_t)N, sizeof *frames);
    sooc_frame col = {0};
    CHECK(frames && sooc_frame_alloc(&col, W, H, 0) == SOOC_OK);
    sooc_traj gt = {0};
    for (int i = 0; i < N; i++) {
        CHECK(sooc_frame_alloc(&frames[i], W, H, 0) == SOOC_OK);
        double T[16], Tc[16];
        walk_pose(i, T);
        sooc_se3_mul(Tc, T, T_dc);   /* T_w_color = T_w_depth * T_depth_color */
        render(Tc, &Kc, &col);
        render(T, &Kd, &frames[i]);   /* the frame: depth camera pose, depth K */
        memcpy(frames[i].rgb, col.rgb, (size_t)W * H * 3);
        frames[i].t_ns = (int64_t)i * 33333333;
        frames[i].index = i;
        CHECK(sooc_traj_push(&gt, i / 30.0, T) == SOOC_OK);
    }
    double cK[4] = {Kc.fx, Kc.fy, Kc.cx, Kc.cy};
    for (int v = 0; v < 3; v += 2) {   /* rgbd, rgbd_icp */
        int tr_given = 0, tr_reg = 0;
        double a_given = run(frames, N, &gt, (sooc_odom_variant)v, cK, T_cd, &tr_given);
        double a_reg = run(frames, N, &gt, (sooc_odom_variant)v, NULL, NULL, &tr_reg);
        printf("%-8s unregistered colour: ATE %.2f mm (%d/%d tracked) with the colour camera, %.2f mm (%d/%d) taken as "
               "registered\n", sooc_odom_variant_name((sooc_odom_variant)v), a_given * 1e3, tr_given, N, a_reg * 1e3,
               tr_reg, N);
        CHECK(tr_given == N);
        CHECK_MSG(a_given < (v == SOOC_ODOM_RGBD ? 0.01 : 0.002), "ATE %.4f m", a_given);
        CHECK_MSG(a_reg > 2 * a_given, "registered %.4f m vs %.4f m", a_reg, a_given);
    }
    for (int i = 0; i < N; i++) sooc_frame_free(&frames[i]);
    free(frames);
    sooc_frame_free(&col);
    sooc_traj_free(&gt);
    printf("test_cv_odometry_color: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail != 0;
}
