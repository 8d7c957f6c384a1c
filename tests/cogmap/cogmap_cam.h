/* A camera for the cognitive-map tests and bench/bench_cogmap.c: 64x64 pinhole
 * (f = 50 px, centred), at (x, h, z) with yaw psi (G forward = (sin psi, 0,
 * cos psi)) looking down by `down` rad, OpenCV axes; t_near 0.1, d_clip 8 m,
 * locality box R_h 0.6 m x H_b 1.2 m, centre in-view test. Header-only. */
#ifndef SOOC3D_TEST_COGMAP_CAM_H
#define SOOC3D_TEST_COGMAP_CAM_H

#include <math.h>
#include <string.h>

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"

static inline void cogmap_test_cam(sooc_cogmap_camera *c, double x, double h, double z, double psi,
                                   double down) {
    memset(c, 0, sizeof *c);
    double base[9] = {-1, 0, 0, 0, -1, 0, 0, 0, 1}, Rx[9] = {1, 0, 0, 0, cos(down), -sin(down), 0, sin(down), cos(down)};
    double Ry[9], t1[9], R[9], t[3] = {x, h, z};
    sooc_m3_rot_y(Ry, psi);
    sooc_m3_mul(t1, Rx, base);
    sooc_m3_mul(R, Ry, t1);
    sooc_se3_from_rt(c->T_wc, R, t);
    c->K.width = c->K.height = 64;
    c->K.fx = c->K.fy = 50;
    c->K.cx = c->K.cy = 32;
    c->t_near = 0.1;
    c->d_clip = 8;
    c->R_h = 0.6;
    c->H_b = 1.2;
    c->mode = SOOC_INVIEW_CENTRE;
}

#endif
