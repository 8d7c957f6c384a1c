/* The pose graph (src/slam/slamshim.cpp, Ceres):
 *  1. each edge residual is zero at poses that agree with the measurement,
 *     and its Jacobians (automatic differentiation) match central finite
 *     differences in double precision at random poses, for both nodes;
 *  2. a ring of 24 poses whose odometry edges carry a rotation and
 *     translation bias, closed by one loop edge: the optimised poses lie far
 *     closer to the truth than the dead-reckoned ones, node 0 stays fixed,
 *     and a wrong loop edge under the Huber loss moves them less than the
 *     same edge without it. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "slam/slamshim.h"
#include "sooc3d/core.h"

static uint64_t g_rng = 0x1234567;
static double urand(void) {
    g_rng = g_rng * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(g_rng >> 11) / 9007199254740992.0 * 2 - 1;
}

/* rotation vector -> matrix */
static void so3_exp(double R[9], const double w[3]) {
    double th = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]), s = th > 1e-12 ? sin(th / 2) / th : 0.5;
    double q[4] = {w[0] * s, w[1] * s, w[2] * s, cos(th / 2)};
    sooc_quat_to_m3(R, q);
}

static void rand_pose(double T[16], double scale) {
    double w[3] = {urand() * 1.5, urand() * 1.5, urand() * 1.5}, R[9], t[3] = {urand() * scale, urand() * scale, urand() * scale};
    so3_exp(R, w);
    sooc_se3_from_rt(T, R, t);
}

static void test_jacobians(void) {
    for (int trial = 0; trial < 20; trial++) {
        double Ti[16], Tj[16], Tij[16], inv[16];
        rand_pose(Ti, 2);
        rand_pose(Tj, 2);
        double w[2] = {50 + 50 * fabs(urand()), 20 + 50 * fabs(urand())};
        double ti[3], qi[4], tj[3], qj[4], r[6];
        sooc_slsh_T_to_tq(Ti, ti, qi);
        sooc_slsh_T_to_tq(Tj, tj, qj);
        /* zero at the measurement */
        sooc_se3_inverse(inv, Ti);
        sooc_se3_mul(Tij, inv, Tj);
        CHECK(sooc_slsh_pgo_residual(ti, qi, tj, qj, Tij, w, r, NULL, NULL) == 0);
        for (int k = 0; k < 6; k++) CHECK_CLOSE(r[k], 0.0, 1e-9, 0);
        /* another measurement: Jacobians against central differences */
        rand_pose(Tij, 0.5);
        double Ji[42], Jj[42];
        CHECK(sooc_slsh_pgo_residual(ti, qi, tj, qj, Tij, w, r, Ji, Jj) == 0);
        for (int node = 0; node < 2; node++)
            for (int c = 0; c < 7; c++) {
                double p[2][7];
                memcpy(p[0], ti, 24);
                memcpy(p[0] + 3, qi, 32);
                memcpy(p[1], tj, 24);
                memcpy(p[1] + 3, qj, 32);
                const double h = 1e-6;
                double rp[6], rm[6];
                p[node][c] += h;
                sooc_slsh_pgo_residual(p[0], p[0] + 3, p[1], p[1] + 3, Tij, w, rp, NULL, NULL);
                p[node][c] -= 2 * h;
                sooc_slsh_pgo_residual(p[0], p[0] + 3, p[1], p[1] + 3, Tij, w, rm, NULL, NULL);
                for (int k = 0; k < 6; k++) {
                    double ga = (node ? Jj : Ji)[k * 7 + c], gn = (rp[k] - rm[k]) / (2 * h);
                    CHECK_CLOSE(ga, gn, 1e-5, 1e-6);
                }
            }
    }
}

#define NR 24

static void ring_truth(int i, double T[16]) {
    double a = 2 * M_PI * i / NR, R[9], t[3] = {2 * cos(a), 0.1 * sin(3 * a), 2 * sin(a)};
    double w[3] = {0, -a, 0};
    so3_exp(R, w);
    sooc_se3_from_rt(T, R, t);
}

static double max_err(const double *T) {
    double m = 0;
    for (int i = 0; i < NR; i++) {
        double G[16];
        ring_truth(i, G);
        double d = sqrt(pow(T[16 * i + 3] - G[3], 2) + pow(T[16 * i + 7] - G[7], 2) + pow(T[16 * i + 11] - G[11], 2));
        if (d > m) m = d;
    }
    return m;
}

/* edges: NR - 1 biased odometry edges, the true loop edge (NR-1 -> 0), and
 * optionally a wrong loop edge; returns the max position error after */
static double solve_ring(int wrong, int robust_wrong, double *before) {
    static double T[16 * NR], Tij[16 * (NR + 1)], w[2 * (NR + 1)];
    int ij[2 * (NR + 1)];
    uint8_t fixed[NR] = {1}, robust[NR + 1];
    double bias[16], bw[3] = {0.002, 0.01, -0.003}, bR[9], bt[3] = {0.01, -0.005, 0.008};
    so3_exp(bR, bw);
    sooc_se3_from_rt(bias, bR, bt);
    int ne = 0;
    ring_truth(0, T);
    for (int i = 1; i < NR; i++) {
        double A[16], B[16], inv[16], rel[16];
        ring_truth(i - 1, A);
        ring_truth(i, B);
        sooc_se3_inverse(inv, A);
        sooc_se3_mul(rel, inv, B);
        sooc_se3_mul(Tij + 16 * ne, rel, bias);   /* biased measurement */
        sooc_se3_mul(T + 16 * i, T + 16 * (i - 1), Tij + 16 * ne);   /* dead reckoning */
        ij[2 * ne] = i - 1;
        ij[2 * ne + 1] = i;
        w[2 * ne] = 100;
        w[2 * ne + 1] = 100;
        robust[ne] = 0;
        ne++;
    }
    *before = max_err(T);
    for (int e = 0; e < 1 + wrong; e++) {
        double A[16], B[16], inv[16];
        ring_truth(NR - 1, A);
        ring_truth(e ? NR / 2 : 0, B);
        sooc_se3_inverse(inv, A);
        sooc_se3_mul(Tij + 16 * ne, inv, B);
        if (e) {   /* the wrong one claims node NR/2 sits where node 0 is */
            ring_truth(0, B);
            sooc_se3_mul(Tij + 16 * ne, inv, B);
        }
        ij[2 * ne] = NR - 1;
        ij[2 * ne + 1] = e ? NR / 2 : 0;
        w[2 * ne] = 100;
        w[2 * ne + 1] = 100;
        robust[ne] = e ? (uint8_t)robust_wrong : 1;
        ne++;
    }
    double c0, c1, T0[16];
    int it;
    char err[256];
    memcpy(T0, T, sizeof T0);
    CHECK(sooc_slsh_pgo(NR, T, fixed, ne, ij, Tij, w, robust, 100, &c0, &c1, &it, err, sizeof err) == 0);
    CHECK(c1 < c0);
    for (int k = 0; k < 16; k++) CHECK_CLOSE(T[k], T0[k], 1e-12, 0);   /* node 0 fixed */
    return max_err(T);
}

int main(void) {
    if (!sooc_slsh_have_ceres()) {
        printf("test_slam_pgo: SKIP: built without Ceres (libceres-dev)\n");
        return SOOC_TEST_SKIP;
    }
    test_jacobians();
    double before, after = solve_ring(0, 1, &before);
    printf("ring: max position error %.4f m dead-reckoned, %.4f m optimised\n", before, after);
    CHECK_MSG(after < before / 4, "optimised %.4f vs %.4f", after, before);
    double b2, huber = solve_ring(1, 1, &b2), plain = solve_ring(1, 0, &b2);
    printf("with a wrong loop edge: max error %.4f m under Huber, %.4f m without\n", huber, plain);
    CHECK(huber < plain);
    printf("test_slam_pgo: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail ? 1 : 0;
}
