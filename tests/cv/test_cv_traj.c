/* Trajectory metrics against known truth: Horn alignment recovers a known
 * rigid transform, ATE equals the injected noise, RPE sees a known drift,
 * TUM files round-trip and bad files fail naming the line. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/slam.h"
#include "sooc3d/core.h"

/* a smooth walk: position on a Lissajous curve, yaw and pitch turning */
static void truth_pose(int i, double T[16]) {
    double s = i * 0.05;
    double R[9], Ry[9], Rx[9], t[3] = {1.5 * sin(s), 0.3 * sin(2.1 * s), 2.0 * cos(0.7 * s)};
    sooc_m3_rot_y(Ry, 0.4 * s);
    double c = cos(0.2 * sin(s)), sn = sin(0.2 * sin(s));
    double Rx_[9] = {1, 0, 0, 0, c, -sn, 0, sn, c};
    memcpy(Rx, Rx_, sizeof Rx);
    sooc_m3_mul(R, Ry, Rx);
    sooc_se3_from_rt(T, R, t);
}

int main(void) {
    sooc_rng rng;
    sooc_rng_seed(&rng, 5, 0);
    /* 1. alignment recovers a known transform exactly without noise */
    {
        double A[16], R[9], q[4] = {0.2, -0.4, 0.1, 0.9}, t[3] = {3, -1, 0.5};
        sooc_quat_to_m3(R, q);
        sooc_se3_from_rt(A, R, t);
        double a[300], b[300];
        for (int i = 0; i < 100; i++) {
            for (int k = 0; k < 3; k++) a[3 * i + k] = sooc_rng_range(&rng, -2, 2);
            sooc_se3_apply(b + 3 * i, A, a + 3 * i);
        }
        double T[16];
        CHECK(sooc_align_rigid(a, b, 100, T) == SOOC_OK);
        double md = 0;
        for (int k = 0; k < 16; k++) md = fmax(md, fabs(T[k] - A[k]));
        CHECK_MSG(md < 1e-9, "alignment error %g", md);
        /* collinear points are rejected */
        for (int i = 0; i < 10; i++) a[3 * i] = i, a[3 * i + 1] = 2 * i, a[3 * i + 2] = -i;
        CHECK(sooc_align_rigid(a, a, 10, T) == SOOC_EINVAL);
        CHECK(sooc_align_rigid(a, b, 2, T) == SOOC_EINVAL);
    }
    /* 2. ATE: est = A^-1 * truth + isotropic noise sigma -> RMSE ~ sigma sqrt(3) */
    sooc_traj gt = {0}, est = {0};
    double A[16], Ai[16], R[9], q[4] = {0.1, 0.7, -0.2, 0.6}, t[3] = {-2, 0.4, 1};
    sooc_quat_to_m3(R, q);
    sooc_se3_from_rt(A, R, t);
    sooc_se3_inverse(Ai, A);
    const int n = 2000;
    const double sigma = 0.01;
    for (int i = 0; i < n; i++) {
        double T[16], E[16];
        truth_pose(i, T);
        CHECK(sooc_traj_push(&gt, i / 30.0, T) == SOOC_OK);
        sooc_se3_mul(E, Ai, T);
        for (int k = 0; k < 3; k++) E[4 * k + 3] += sigma * sooc_rng_normal(&rng);
        /* est timestamps are off by 3 ms: association must tolerate it */
        CHECK(sooc_traj_push(&est, i / 30.0 + 0.003, E) == SOOC_OK);
    }
    sooc_traj_metrics m;
    CHECK(sooc_traj_evaluate(&est, &gt, 0.02, 1.0, 0, &m) == SOOC_OK);
    CHECK(m.pairs == n);
    CHECK_CLOSE(m.ate_rmse, sigma * sqrt(3.0), 0, 0.05);
    double md = 0;
    for (int k = 0; k < 16; k++) md = fmax(md, fabs(m.T_align[k] - A[k]));
    CHECK_MSG(md < 2e-3, "T_align error %g", md);
    /* RPE of pure position noise: |e_j - e_i| has RMSE sigma * sqrt(6) */
    CHECK_CLOSE(m.rpe_trans_rmse, sigma * sqrt(6.0), 0, 0.1);
    CHECK(m.rpe_rot_rmse_deg < 1e-6);
    CHECK(m.rpe_pairs > n - 40 && m.rpe_pairs < n);
    /* association tolerance: with 1 ms nothing associates */
    CHECK(sooc_traj_evaluate(&est, &gt, 0.001, 1.0, 0, &m) == SOOC_EINVAL);

    /* 3. RPE of a known drift in the world frame, P_i = S^i Q_i: then
     * E = Q_j^-1 S^(j-i) Q_j, whose rotation angle is that of S^(j-i) and,
     * for a pure translation S, whose translation norm is |j - i| |t_S|.
     * 1 mm per frame -> 30 mm per 30 frames (1 s); 0.01 deg -> 0.3 deg. */
    sooc_traj drift = {0}, gt300 = {0};
    for (int i = 0; i < 300; i++) CHECK(sooc_traj_push(&gt300, gt.t[i], gt.T + 16 * i) == SOOC_OK);
    for (int pass = 0; pass < 2; pass++) {
        double S[16], W[16], Rs[9], ts[3] = {0, 0, 0};
        sooc_m3_identity(Rs);
        if (pass == 0) ts[0] = 0.001;
        else sooc_m3_rot_y(Rs, 0.01 * M_PI / 180);
        sooc_se3_from_rt(S, Rs, ts);
        sooc_se3_identity(W);
        sooc_traj_free(&drift);
        for (int i = 0; i < 300; i++) {
            double E[16], tmp[16];
            sooc_se3_mul(E, W, gt.T + 16 * i);
            CHECK(sooc_traj_push(&drift, gt.t[i], E) == SOOC_OK);
            sooc_se3_mul(tmp, S, W);
            memcpy(W, tmp, sizeof W);
        }
        CHECK(sooc_traj_evaluate(&drift, &gt300, 0.02, 0, 30, &m) == SOOC_OK);
        CHECK(m.rpe_pairs == 270);
        if (pass == 0) {
            CHECK_CLOSE(m.rpe_trans_mean, 0.030, 1e-9, 0);
            CHECK_CLOSE(m.rpe_trans_rmse, 0.030, 1e-9, 0);
            CHECK(m.rpe_rot_mean_deg < 1e-6);
        } else {
            CHECK_CLOSE(m.rpe_rot_mean_deg, 0.30, 1e-6, 0);
        }
        /* the same by time: 1 s = 30 frames */
        CHECK(sooc_traj_evaluate(&drift, &gt300, 0.02, 1.0, 0, &m) == SOOC_OK);
        CHECK(m.rpe_pairs == 270);
        if (pass == 0) CHECK_CLOSE(m.rpe_trans_mean, 0.030, 1e-9, 0);
        else CHECK_CLOSE(m.rpe_rot_mean_deg, 0.30, 1e-6, 0);
    }

    /* 4. TUM round trip */
    char dir[] = "/tmp/sooc_traj_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char path[256], bad[256];
    snprintf(path, sizeof path, "%s/est.txt", dir);
    CHECK(sooc_traj_save_tum(path, &drift) == SOOC_OK);
    sooc_traj back = {0};
    CHECK(sooc_traj_load_tum(path, &back) == SOOC_OK);
    CHECK(back.n == drift.n);
    md = 0;
    for (int64_t i = 0; i < back.n && back.n == drift.n; i++) {
        md = fmax(md, fabs(back.t[i] - drift.t[i]));
        for (int k = 0; k < 16; k++) md = fmax(md, fabs(back.T[16 * i + k] - drift.T[16 * i + k]));
    }
    CHECK_MSG(md < 2e-6, "round trip error %g", md);
    sooc_traj_free(&back);
    /* bad files: messages name the file and the line */
    snprintf(bad, sizeof bad, "%s/bad.txt", dir);
    const char *cases[][2] = {
        {"# c\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1\n", ":3:"},
        {"0 0 0 0 0 0 0 1\n0 0 0 0 0 0 0 1\n", "not after"},
        {"0 0 0 0 0 0 0 2\n", "quaternion norm"},
        {"0 0 0 0 0 0 0 1\n1 0 0 x 0 0 0 1\n", ":2:"},
        {"# nothing\n", "no poses"},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        FILE *f = fopen(bad, "w");
        fputs(cases[c][0], f);
        fclose(f);
        sooc_status st = sooc_traj_load_tum(bad, &back);
        CHECK(st == SOOC_EFORMAT);
        CHECK_MSG(strstr(sooc_errmsg(), cases[c][1]) && strstr(sooc_errmsg(), "bad.txt"), "case %zu: %s", c,
                  sooc_errmsg());
        CHECK(back.n == 0);
    }
    remove(bad);
    remove(path);
    rmdir(dir);
    sooc_traj_free(&gt);
    sooc_traj_free(&gt300);
    sooc_traj_free(&est);
    sooc_traj_free(&drift);
    printf("test_cv_traj: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail != 0;
}
