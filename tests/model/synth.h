/* Tiny analytic RGB-D scenes for model tests and the keyframe bench: a
 * checkered floor (y = 0) and coloured spheres, exact planar depth, instance
 * ids; sky = depth 0 (invalid). Header-only. */
#ifndef SOOC3D_TEST_SYNTH_H
#define SOOC3D_TEST_SYNTH_H

#include <math.h>
#include <string.h>

#include "sooc3d/frame.h"
#include "sooc3d/core.h"
#include "sooc3d/model.h"

/* The tiny model of the gradient and step tests: K slots, d_what 4, d_layout
 * 3, L 2, 32x32 images with 16x16 rays, small decoders and refinement nets,
 * and a mild likelihood scale (sigma_max 5, d_clip 5, density bias 0): the
 * loss is piecewise smooth (ReLU kinks times large per-ray weights), so finite
 * differences need a gentle landscape. */
static inline void synth_tiny_cfg(sooc_model_config *c, int K, int use_box) {
    sooc_model_config_default(c);
    c->K = K, c->d_what = 4, c->d_layout = 3, c->L = 2;
    c->img_w = c->img_h = 32, c->ray_w = c->ray_h = 16;
    c->dec_width = 16, c->dec_color_width = 8, c->n_freq = 3, c->n_freq_layout = 3;
    c->ref_ch[0] = 4, c->ref_ch[1] = 4, c->ref_ch[2] = 6, c->ref_ch[3] = 6;
    c->ref_fc = 8, c->ref_hidden = 8;
    c->use_box = use_box;
    c->sigma_max = 5.0f;
    c->d_clip = 5.0f;
    c->dens_bias_init = 0.0f;
}

typedef struct synth_sphere {
    double c[3], r;
    float rgb[3];
} synth_sphere;

/* Camera at (x, y, z) with yaw (about +y, 0 = looking along +z) and pitch
 * (negative = down). Fills T_wc with OpenCV axes (x right, y down, z fwd). */
static inline void synth_pose(double T[16], double x, double y, double z, double yaw, double pitch) {
    double f[3] = {sin(yaw) * cos(pitch), sin(pitch), cos(yaw) * cos(pitch)};
    double d0[3] = {0, -1, 0}, xr[3], yd[3];
    sooc_v3_cross(xr, d0, f);
    sooc_v3_normalize(xr);
    sooc_v3_cross(yd, f, xr);
    double R[9] = {xr[0], yd[0], f[0], xr[1], yd[1], f[1], xr[2], yd[2], f[2]};
    double t[3] = {x, y, z};
    sooc_se3_from_rt(T, R, t);
}

static inline sooc_status synth_frame(sooc_frame *fr, int W, int H, double fov_deg, const double T_wc[16],
                                      const synth_sphere *sp, int ns) {
    sooc_status st = sooc_frame_alloc(fr, W, H, 1);
    if (st) return st;
    double fx = 0.5 * W / tan(0.5 * fov_deg * M_PI / 180.0);
    fr->K.width = W, fr->K.height = H;
    fr->K.fx = fr->K.fy = fx;
    fr->K.cx = 0.5 * W, fr->K.cy = 0.5 * H;
    fr->K.dist_model = SOOC_DIST_NONE;
    memcpy(fr->T_wc, T_wc, sizeof fr->T_wc);
    fr->has_pose = 1;
    double o[3] = {T_wc[3], T_wc[7], T_wc[11]};
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            double dc[3] = {(u + 0.5 - fr->K.cx) / fx, (v + 0.5 - fr->K.cy) / fx, 1.0}, dw[3];
            sooc_se3_rotate(dw, T_wc, dc);
            double best = 1e30;
            int hit = -1;
            if (dw[1] < -1e-9) {
                double t = -o[1] / dw[1];
                if (t > 0) best = t, hit = 0;
            }
            for (int i = 0; i < ns; i++) {
                double oc[3] = {o[0] - sp[i].c[0], o[1] - sp[i].c[1], o[2] - sp[i].c[2]};
                double a = sooc_v3_dot(dw, dw), b = 2 * sooc_v3_dot(oc, dw), c = sooc_v3_dot(oc, oc) - sp[i].r * sp[i].r;
                double disc = b * b - 4 * a * c;
                if (disc < 0) continue;
                double t = (-b - sqrt(disc)) / (2 * a);
                if (t > 1e-6 && t < best) best = t, hit = i + 1;
            }
            size_t p = (size_t)v * W + u;
            if (hit < 0) {
                fr->depth[p] = 0, fr->valid[p] = 0;
                fr->rgb[3 * p] = fr->rgb[3 * p + 1] = fr->rgb[3 * p + 2] = 0;
                fr->instance[p] = 0;
                continue;
            }
            fr->depth[p] = (float)best;   /* dc has z = 1: t is planar depth */
            fr->valid[p] = 1;
            fr->instance[p] = (uint16_t)hit;
            float col[3];
            if (hit == 0) {
                double X = o[0] + best * dw[0], Z = o[2] + best * dw[2];
                int chk = ((int)floor(X * 2) + (int)floor(Z * 2)) & 1;
                col[0] = chk ? 0.55f : 0.35f, col[1] = chk ? 0.5f : 0.3f, col[2] = chk ? 0.45f : 0.25f;
            } else
                memcpy(col, sp[hit - 1].rgb, sizeof col);
            for (int a = 0; a < 3; a++) fr->rgb[3 * p + a] = (uint8_t)(255.0f * col[a] + 0.5f);
        }
    return SOOC_OK;
}

#endif
