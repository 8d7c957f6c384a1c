/* A ray-cast test room for the odometry tests (test_cv_odometry.c,
 * test_cv_node.c): a 6 x 2.8 x 6 m room with five boxes, value-noise
 * textures, exact planar depth, and a smooth hand-held-like walk. */
#ifndef SOOC3D_TEST_CV_ROOM_H
#define SOOC3D_TEST_CV_ROOM_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "sooc3d/frame.h"
#include "sooc3d/core.h"

#define W 320
#define H 240

static const double g_room_lo[3] = {-3, 0, -3}, g_room_hi[3] = {3, 2.8, 3};
#define NBOX 5
static const double g_box_lo[NBOX][3] = {{0.4, 0, -1.6}, {-2.2, 0, 0.8}, {-1.0, 0.6, 2.2}, {1.8, 0, 1.0}, {-2.99, 1.0, -1.5}};
static const double g_box_hi[NBOX][3] = {{1.3, 0.9, -0.6}, {-1.4, 1.2, 1.6}, {0.2, 1.4, 2.99}, {2.6, 0.5, 2.2}, {-2.5, 1.6, -0.3}};

/* smooth value noise on a 6 cm lattice plus a coarse checker: gradients of
 * 10-30 grey levels per pixel at 1-3 m, like a real room's texture */
static double lattice(int i, int j, int ch) {
    uint64_t h = ((uint64_t)(int64_t)i * 73856093u) ^ ((uint64_t)(int64_t)j * 19349663u) ^ ((uint64_t)ch * 83492791u);
    h ^= h >> 13;
    h *= 0x9E3779B97F4A7C15ull;
    h ^= h >> 29;
    return (double)(h & 0xffff) / 65535.0;
}

static double tex(double u, double v, int ch) {
    double x = u / 0.06, y = v / 0.06;
    int i = (int)floor(x), j = (int)floor(y);
    double fx = x - i, fy = y - j;
    fx = fx * fx * (3 - 2 * fx);
    fy = fy * fy * (3 - 2 * fy);
    double n = (lattice(i, j, ch) * (1 - fx) + lattice(i + 1, j, ch) * fx) * (1 - fy) +
               (lattice(i, j + 1, ch) * (1 - fx) + lattice(i + 1, j + 1, ch) * fx) * fy;
    double s = 0.25 + 0.5 * n + 0.15 * (((int)floor(u * 2) + (int)floor(v * 2)) & 1) - 0.075;
    return s < 0 ? 0 : (s > 1 ? 1 : s);
}

/* cast one ray (world origin o, direction d): distance t along d and colour */
static double cast(const double o[3], const double d[3], double rgb[3]) {
    double t = 1e30;
    int axis = 0;
    for (int k = 0; k < 3; k++) {   /* room walls, from inside */
        if (d[k] > 1e-12) {
            double tk = (g_room_hi[k] - o[k]) / d[k];
            if (tk < t) { t = tk; axis = k; }
        } else if (d[k] < -1e-12) {
            double tk = (g_room_lo[k] - o[k]) / d[k];
            if (tk < t) { t = tk; axis = k; }
        }
    }
    for (int b = 0; b < NBOX; b++) {   /* the boxes: slab test */
        double t0 = 0, t1 = 1e30;
        int ax0 = 0;
        for (int k = 0; k < 3; k++) {
            if (fabs(d[k]) < 1e-12) {
                if (o[k] < g_box_lo[b][k] || o[k] > g_box_hi[b][k]) { t0 = 1e30; break; }
                continue;
            }
            double a = (g_box_lo[b][k] - o[k]) / d[k], c = (g_box_hi[b][k] - o[k]) / d[k];
            if (a > c) { double x = a; a = c; c = x; }
            if (a > t0) { t0 = a; ax0 = k; }
            if (c < t1) t1 = c;
        }
        if (t0 < t1 && t0 > 0 && t0 < t) { t = t0; axis = ax0 + 3; }
    }
    double p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
    int a = axis % 3;
    double u = p[(a + 1) % 3], v = p[(a + 2) % 3];
    for (int c = 0; c < 3; c++) rgb[c] = tex(u + 0.37 * axis, v, c) * (axis >= 3 ? 0.8 : 1.0);
    return t;
}

static void render(const double T_wc[16], const sooc_intrinsics *K, sooc_frame *f) {
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double dc[3] = {(x - K->cx) / K->fx, (y - K->cy) / K->fy, 1}, d[3], rgb[3];
            sooc_se3_rotate(d, T_wc, dc);
            double o[3] = {T_wc[3], T_wc[7], T_wc[11]};
            double t = cast(o, d, rgb);   /* d has camera z = 1: t is the planar depth */
            size_t i = (size_t)y * W + x;
            f->depth[i] = (float)t;
            f->valid[i] = 1;
            for (int c = 0; c < 3; c++) f->rgb[3 * i + c] = (uint8_t)(255 * rgb[c] + 0.5);
        }
    f->K = *K;
    memcpy(f->T_wc, T_wc, sizeof f->T_wc);
    f->has_pose = 1;
}

/* the walk: 1.5 cm and ~0.8 deg per frame, looking out towards the walls */
static double g_walk_pitch0 = 0;   /* extra downward pitch of the whole walk (rad) */

static void walk_pose(int i, double T[16]) {
    double s = i * 0.02;
    double pos[3] = {0.8 * sin(s) - 0.6, 1.4 + 0.1 * sin(3 * s), 0.8 * cos(s) - 0.2};
    double yaw = 2.4 + 0.8 * s, pitch = 0.15 * sin(2 * s) - g_walk_pitch0;
    double Ry[9], Rx[9], R[9];
    sooc_m3_rot_y(Ry, yaw);
    double c = cos(pitch), sn = sin(pitch);
    double Rx_[9] = {1, 0, 0, 0, c, -sn, 0, sn, c};
    memcpy(Rx, Rx_, sizeof Rx);
    sooc_m3_mul(R, Ry, Rx);
    /* camera axes: x right, y down, z forward: flip y and z of a y-up frame */
    double F[9] = {1, 0, 0, 0, -1, 0, 0, 0, -1}, Rc[9];
    sooc_m3_mul(Rc, R, F);
    sooc_se3_from_rt(T, Rc, pos);
}

#endif
