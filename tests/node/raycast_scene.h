/* Ray-cast depth frames of scenes made of axis-aligned rectangles (tests of
 * the support plane: test_support.c, test_floor_switch.c). World +y up; the
 * frames are posed in a source frame whose up axis is +z (like label-fusion).
 * Include after check.h. Header-only. */
#ifndef SOOC3D_TEST_RAYCAST_SCENE_H
#define SOOC3D_TEST_RAYCAST_SCENE_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#include <math.h>

/* ------------------------------------------------------- ray-cast scenes */

typedef struct rect {   /* axis-aligned rectangle in the world (+y up): coordinate `axis` = c */
    int axis;
    double c, lo[2], hi[2];   /* bounds on the other two axes, in increasing axis order */
} rect;

typedef struct scene {
    rect r[16];
    int n;
} scene;

static inline void add(scene *s, int axis, double c, double lo0, double hi0, double lo1, double hi1) {
    rect *r = &s->r[s->n++];
    r->axis = axis;
    r->c = c;
    r->lo[0] = lo0; r->hi[0] = hi0;
    r->lo[1] = lo1; r->hi[1] = hi1;
}

/* (the bin bottom's fit leans up to 2 deg: its inliers include the foot of the walls) */
/* a closed box (5 faces, no bottom) from (x0, y0, z0) to (x1, y1, z1) */
static inline void add_box(scene *s, double x0, double y0, double z0, double x1, double y1, double z1) {
    add(s, 1, y1, x0, x1, z0, z1);
    add(s, 0, x0, y0, y1, z0, z1);
    add(s, 0, x1, y0, y1, z0, z1);
    add(s, 2, z0, x0, x1, y0, y1);
    add(s, 2, z1, x0, x1, y0, y1);
}

static inline double cast(const scene *s, const double o[3], const double d[3]) {
    double best = INFINITY;
    for (int i = 0; i < s->n; i++) {
        const rect *r = &s->r[i];
        int a = r->axis, b = (a + 1) % 3, c = (a + 2) % 3;
        if (b > c) { int t = b; b = c; c = t; }
        if (fabs(d[a]) < 1e-12) continue;
        double t = (r->c - o[a]) / d[a];
        if (t <= 1e-6 || t >= best) continue;
        double pb = o[b] + t * d[b], pc = o[c] + t * d[c];
        if (pb >= r->lo[0] && pb <= r->hi[0] && pc >= r->lo[1] && pc <= r->hi[1]) best = t;
    }
    return best;
}

/* world (+y up) to the pose source's frame (+z up), with an offset */
static inline void src_from_world(double T[16]) {
    double R[9] = {1, 0, 0, 0, 0, -1, 0, 1, 0};   /* y -> z, z -> -y */
    double t[3] = {0.3, -0.2, 0.1};
    sooc_se3_from_rt(T, R, t);
}

/* A w x h depth frame from a camera at `pos` (world) looking along yaw/pitch
 * (pitch > 0 looks down), posed in the source frame. */
static inline void render(const scene *s, sooc_frame *f, const double pos[3], double yaw, double pitch, uint64_t seed) {
    const int w = 160, h = 120;
    if (!f->depth) CHECK_OK(sooc_frame_alloc(f, w, h, 0));
    f->K = (sooc_intrinsics){.width = w, .height = h, .fx = 110, .fy = 110, .cx = 80, .cy = 60};
    double fw[3] = {sin(yaw) * cos(pitch), -sin(pitch), cos(yaw) * cos(pitch)}, upw[3] = {0, 1, 0}, x[3], y[3];
    sooc_v3_cross(x, fw, upw);
    sooc_v3_normalize(x);
    sooc_v3_cross(y, fw, x);
    double R[9] = {x[0], y[0], fw[0], x[1], y[1], fw[1], x[2], y[2], fw[2]}, Twc[16], Tsw[16];
    sooc_se3_from_rt(Twc, R, pos);
    src_from_world(Tsw);
    sooc_se3_mul(f->T_wc, Tsw, Twc);
    f->has_pose = 1;
    sooc_rng rng;
    sooc_rng_seed(&rng, seed, 3);
    for (int v = 0; v < h; v++)
        for (int u = 0; u < w; u++) {
            double dc[3] = {((u + 0.5) - f->K.cx) / f->K.fx, ((v + 0.5) - f->K.cy) / f->K.fy, 1}, dw[3];
            sooc_m3_mulv(dw, R, dc);
            double t = cast(s, pos, dw);   /* dc has z = 1: t is the planar depth */
            size_t i = (size_t)v * w + u;
            double z = isfinite(t) && t < 10 ? t * (1 + 0.003 * sooc_rng_normal(&rng)) : 0;
            f->depth[i] = (float)z;
            f->valid[i] = z > 0;
        }
}

#endif
