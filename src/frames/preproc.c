/* Preprocessing: depth registration, crop + resize to the model resolution
 * (area-averaged RGB; min-of-valid or nearest depth, never averaged across
 * edges), intrinsics adjustment and the world frame from the launch file. */
#include "sooc3d/frame.h"

#include <math.h>
#include <string.h>

void sooc_frames_register_depth(const float *depth, const sooc_intrinsics *Kd, const double T_cd[16],
                                const sooc_intrinsics *Kc, float *out) {
    int W = Kc->width, H = Kc->height;
    for (int i = 0; i < W * H; i++) out[i] = 0.0f;
    for (int v = 0; v < Kd->height; v++) {
        for (int u = 0; u < Kd->width; u++) {
            float z = depth[(size_t)v * Kd->width + u];
            if (!(z > 0.0f) || !isfinite(z)) continue;
            double pd[3] = {((u + 0.5) - Kd->cx) / Kd->fx * z, ((v + 0.5) - Kd->cy) / Kd->fy * z, z};
            double pc[3];
            sooc_se3_apply(pc, T_cd, pd);
            if (pc[2] <= 1e-6) continue;
            double uc = Kc->fx * pc[0] / pc[2] + Kc->cx, vc = Kc->fy * pc[1] / pc[2] + Kc->cy;
            int iu = (int)floor(uc), iv = (int)floor(vc);
            if (iu < 0 || iv < 0 || iu >= W || iv >= H) continue;
            float zc = (float)pc[2];
            float *o = &out[(size_t)iv * W + iu];
            if (*o == 0.0f || zc < *o) *o = zc;   /* z-buffer: nearest surface wins */
        }
    }
}

void sooc_frames_crop_for_aspect(int w, int h, int tw, int th, int *x0, int *y0, int *cw, int *ch) {
    /* compare w/h with tw/th in integers */
    long lw = (long)w * th, lh = (long)h * tw;
    if (lw > lh) {            /* too wide: crop columns */
        *ch = h;
        *cw = (int)((long)h * tw / th);
        if (*cw < 1) *cw = 1;
        *x0 = (w - *cw) / 2;
        *y0 = 0;
    } else {                  /* too tall (or equal): crop rows */
        *cw = w;
        *ch = (int)((long)w * th / tw);
        if (*ch < 1) *ch = 1;
        *x0 = 0;
        *y0 = (h - *ch) / 2;
    }
}

void sooc_frames_resize_rgb_area(const uint8_t *src, int w, int h, int x0, int y0, int cw, int ch,
                                 uint8_t *dst, int tw, int th) {
    (void)h;
    double sx = (double)cw / tw, sy = (double)ch / th;
    for (int ty = 0; ty < th; ty++) {
        double fy0 = ty * sy, fy1 = (ty + 1) * sy;
        int iy0 = (int)floor(fy0), iy1 = (int)ceil(fy1);
        if (iy1 > ch) iy1 = ch;
        for (int tx = 0; tx < tw; tx++) {
            double fx0 = tx * sx, fx1 = (tx + 1) * sx;
            int ix0 = (int)floor(fx0), ix1 = (int)ceil(fx1);
            if (ix1 > cw) ix1 = cw;
            double acc[3] = {0, 0, 0}, wsum = 0;
            for (int y = iy0; y < iy1; y++) {
                double wy = fmin(fy1, y + 1.0) - fmax(fy0, (double)y);
                if (wy <= 0) continue;
                const uint8_t *row = src + ((size_t)(y0 + y) * w + x0) * 3;
                for (int x = ix0; x < ix1; x++) {
                    double wx = fmin(fx1, x + 1.0) - fmax(fx0, (double)x);
                    if (wx <= 0) continue;
                    double wgt = wx * wy;
                    acc[0] += wgt * row[3 * x];
                    acc[1] += wgt * row[3 * x + 1];
                    acc[2] += wgt * row[3 * x + 2];
                    wsum += wgt;
                }
            }
            uint8_t *o = dst + ((size_t)ty * tw + tx) * 3;
            for (int c = 0; c < 3; c++) {
                double v = wsum > 0 ? acc[c] / wsum : 0;
                o[c] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : lrint(v));
            }
        }
    }
}

/* dmax <= 0 means no upper limit (a range of [0, 0] never empties a frame) */
static inline int depth_ok(float z, double dmin, double dmax) {
    return isfinite(z) && z > 0.0f && z >= dmin && (dmax <= 0 || z <= dmax);
}

void sooc_frames_resize_ids(const uint16_t *src, int w, int x0, int y0, int cw, int ch, uint16_t *dst, int tw,
                            int th) {
    double sx = (double)cw / tw, sy = (double)ch / th;
    for (int ty = 0; ty < th; ty++) {
        int y = (int)floor((ty + 0.5) * sy);
        if (y >= ch) y = ch - 1;
        for (int tx = 0; tx < tw; tx++) {
            int x = (int)floor((tx + 0.5) * sx);
            if (x >= cw) x = cw - 1;
            dst[(size_t)ty * tw + tx] = src[(size_t)(y0 + y) * w + x0 + x];
        }
    }
}

void sooc_frames_resize_depth(const float *src, int w, int h, int x0, int y0, int cw, int ch, float *dst,
                              int tw, int th, sooc_frames_depth_resample mode, double dmin, double dmax) {
    (void)h;
    double sx = (double)cw / tw, sy = (double)ch / th;
    for (int ty = 0; ty < th; ty++) {
        double fy0 = ty * sy, fy1 = (ty + 1) * sy;
        for (int tx = 0; tx < tw; tx++) {
            double fx0 = tx * sx, fx1 = (tx + 1) * sx;
            float out = 0.0f;
            if (mode == SOOC_FRAMES_DEPTH_NEAREST) {
                int x = (int)floor(0.5 * (fx0 + fx1)), y = (int)floor(0.5 * (fy0 + fy1));
                if (x >= cw) x = cw - 1;
                if (y >= ch) y = ch - 1;
                float z = src[(size_t)(y0 + y) * w + x0 + x];
                out = depth_ok(z, dmin, dmax) ? z : 0.0f;
            } else {
                /* pixels whose centres fall inside the footprint (at least one) */
                int ix0 = (int)ceil(fx0 - 0.5), ix1 = (int)ceil(fx1 - 0.5);
                int iy0 = (int)ceil(fy0 - 0.5), iy1 = (int)ceil(fy1 - 0.5);
                if (ix1 <= ix0) ix1 = ix0 + 1;
                if (iy1 <= iy0) iy1 = iy0 + 1;
                if (ix1 > cw) ix1 = cw;
                if (iy1 > ch) iy1 = ch;
                if (ix0 >= ix1) ix0 = ix1 - 1;
                if (iy0 >= iy1) iy0 = iy1 - 1;
                for (int y = iy0; y < iy1; y++) {
                    const float *row = src + (size_t)(y0 + y) * w + x0;
                    for (int x = ix0; x < ix1; x++) {
                        float z = row[x];
                        if (depth_ok(z, dmin, dmax) && (out == 0.0f || z < out)) out = z;
                    }
                }
            }
            dst[(size_t)ty * tw + tx] = out;
        }
    }
}

sooc_status sooc_frames_preprocess(const sooc_frame *src, sooc_frame *dst, int tw, int th,
                                   sooc_frames_depth_resample mode, double dmin, double dmax) {
    if (!src->rgb || !src->depth || tw <= 0 || th <= 0 || src->width <= 0 || src->height <= 0)
        return sooc_seterr(SOOC_EINVAL, "preprocess: empty frame or bad target size %dx%d", tw, th);
    int with_ids = src->instance != NULL;
    if (dst->width != tw || dst->height != th || !dst->rgb || with_ids != (dst->instance != NULL)) {
        sooc_frame_free(dst);
        sooc_status st = sooc_frame_alloc(dst, tw, th, with_ids);
        if (st) return st;
    }
    int x0, y0, cw, ch;
    sooc_frames_crop_for_aspect(src->width, src->height, tw, th, &x0, &y0, &cw, &ch);
    sooc_frames_resize_rgb_area(src->rgb, src->width, src->height, x0, y0, cw, ch, dst->rgb, tw, th);
    sooc_frames_resize_depth(src->depth, src->width, src->height, x0, y0, cw, ch, dst->depth, tw, th, mode,
                             dmin, dmax);
    for (int i = 0; i < tw * th; i++) dst->valid[i] = dst->depth[i] > 0.0f;
    if (with_ids) sooc_frames_resize_ids(src->instance, src->width, x0, y0, cw, ch, dst->instance, tw, th);
    sooc_intrinsics K = src->K;
    if (K.width <= 0 || K.height <= 0) {
        K.width = src->width;
        K.height = src->height;
    }
    if (K.width != src->width || K.height != src->height)
        return sooc_seterr(SOOC_EINVAL, "preprocess: intrinsics are for %dx%d but the frame is %dx%d", K.width,
                           K.height, src->width, src->height);
    sooc_cam_crop_resize(&dst->K, &K, x0, y0, cw, ch, tw, th);
    dst->t_ns = src->t_ns;
    dst->has_pose = src->has_pose;
    memcpy(dst->T_wc, src->T_wc, sizeof dst->T_wc);
    dst->index = src->index;
    dst->is_query = src->is_query;
    return SOOC_OK;
}

void sooc_frames_world_from_up(const double up_in[3], double floor_h, double T[16]) {
    double u[3] = {up_in[0], up_in[1], up_in[2]};
    if (sooc_v3_normalize(u) < 1e-12) { u[0] = 0; u[1] = 1; u[2] = 0; }
    const double ey[3] = {0, 1, 0};
    double R[9];
    double ax[3];
    sooc_v3_cross(ax, u, ey);
    double s = sooc_v3_norm(ax), c = sooc_v3_dot(u, ey);
    if (s < 1e-12) {
        if (c > 0) sooc_m3_identity(R);
        else { /* up = -y: half turn about x */
            double Rx[9] = {1, 0, 0, 0, -1, 0, 0, 0, -1};
            memcpy(R, Rx, sizeof R);
        }
    } else {
        /* Rodrigues: R = I + [k]x sin + [k]x^2 (1 - cos), k = ax / s */
        double k[3] = {ax[0] / s, ax[1] / s, ax[2] / s};
        double Kx[9] = {0, -k[2], k[1], k[2], 0, -k[0], -k[1], k[0], 0};
        double K2[9];
        sooc_m3_mul(K2, Kx, Kx);
        sooc_m3_identity(R);
        for (int i = 0; i < 9; i++) R[i] += s * Kx[i] + (1 - c) * K2[i];
    }
    double t[3] = {0, -floor_h, 0};   /* y_world = up . p - floor_h */
    sooc_se3_from_rt(T, R, t);
}

size_t sooc_frames_depth_points(const sooc_frame *f, const double T_src_c[16], int step, double *pts,
                                size_t cap) {
    size_t n = 0;
    if (step < 1) step = 1;
    for (int v = 0; v < f->height && n < cap; v += step)
        for (int u = 0; u < f->width && n < cap; u += step) {
            float z = f->depth[(size_t)v * f->width + u];
            if (!(z > 0.0f) || !isfinite(z)) continue;
            double pc[3] = {((u + 0.5) - f->K.cx) / f->K.fx * z, ((v + 0.5) - f->K.cy) / f->K.fy * z, z};
            sooc_se3_apply(pts + 3 * n, T_src_c, pc);
            n++;
        }
    return n;
}
