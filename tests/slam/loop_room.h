/* A closed walk through the ray-cast test room of tests/cv/room.h: the
 * camera circles the room's middle looking outwards and turns once, so the
 * last frames see what the first ones saw (a loop). */
#ifndef SOOC3D_TEST_SLAM_LOOP_ROOM_H
#define SOOC3D_TEST_SLAM_LOOP_ROOM_H

#include "cv/room.h"

/* room.h's own walk is not used here */
static inline void loop_room_unused(void) { (void)walk_pose; }

static inline void loop_pose(int i, int n, double T[16]) {
    double s = 2 * M_PI * i / n;
    double pos[3] = {0.7 * sin(s) - 0.5, 1.4 + 0.05 * sin(3 * s), 0.7 * cos(s) - 0.2};
    double yaw = 2.4 + s, pitch = 0.1 * sin(2 * s);
    double Ry[9], R[9];
    sooc_m3_rot_y(Ry, yaw);
    double c = cos(pitch), sn = sin(pitch);
    double Rx[9] = {1, 0, 0, 0, c, -sn, 0, sn, c};
    sooc_m3_mul(R, Ry, Rx);
    double F[9] = {1, 0, 0, 0, -1, 0, 0, 0, -1}, Rc[9];
    sooc_m3_mul(Rc, R, F);
    sooc_se3_from_rt(T, Rc, pos);
}

static inline void room_K(sooc_intrinsics *K) {
    memset(K, 0, sizeof *K);
    K->width = W;
    K->height = H;
    K->fx = K->fy = 262.5;
    K->cx = 159.5;
    K->cy = 119.5;
}

/* frame i of an n-frame loop, rendered into f (allocated by the caller) */
static inline void loop_frame(int i, int n, sooc_frame *f) {
    sooc_intrinsics K;
    room_K(&K);
    double T[16];
    loop_pose(i, n, T);
    render(T, &K, f);
    f->t_ns = (int64_t)i * 33333333;
    f->index = i;
}

/* translation and rotation (degrees) between two poses */
static inline void pose_diff(const double A[16], const double B[16], double *dt, double *dr) {
    double inv[16], D[16];
    sooc_se3_inverse(inv, A);
    sooc_se3_mul(D, inv, B);
    *dt = sqrt(D[3] * D[3] + D[7] * D[7] + D[11] * D[11]);
    double c = (D[0] + D[5] + D[10] - 1) * 0.5;
    c = c > 1 ? 1 : (c < -1 ? -1 : c);
    *dr = acos(c) * 180 / M_PI;
}

#endif
