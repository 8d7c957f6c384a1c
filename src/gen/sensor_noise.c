/* Structured-light sensor noise on rendered RGB-D frames (sensor_noise.h):
 * range limits, projector shadows, edge and speckle dropout, axial noise
 * that grows with z^2 and with the incidence angle (Nguyen et al. 2012),
 * disparity quantisation, white
 * balance, exposure drift and colour noise. One scratch buffer per frame. */
#include "gen/sensor_noise.h"
#include "sooc3d/core.h"
#include "gen/gen_impl.h"

#include <stdio.h>

#include <math.h>
#include <string.h>

void sooc_noise_params_kinect(sooc_noise_params *p) {
    memset(p, 0, sizeof *p);
    p->sigma0 = 0.0012;
    p->sigma_k = 0.0019;
    p->z0 = 0.4;
    p->sigma_a = 0.0001;
    p->theta_max = 80 * M_PI / 180;
    p->quantise = 1;
    p->baseline = 0.075;
    p->f_ref = 580;
    p->subpixel_inv = 8;
    p->z_min = 0.2;
    p->z_max = 3.5;
    p->shadow = 1;
    p->edge_rel = 0.03;
    p->edge_drop = 0.5;
    p->speckle_drop = 0.002;
    p->wb_sigma = 0.04;
    p->exposure_sigma = 0.15;
    p->rgb_read = 0.006;
    p->rgb_shot = 0.0004;
}

double sooc_noise_sigma_z(const sooc_noise_params *p, double z) {
    double e = z - p->z0;
    return p->sigma0 + p->sigma_k * e * e;
}

double sooc_noise_sigma_zt(const sooc_noise_params *p, double z, double theta) {
    double t = theta < 0 ? 0 : theta > p->theta_max ? p->theta_max : theta, g = M_PI / 2 - t;
    return sooc_noise_sigma_z(p, z) + (z > 0 ? p->sigma_a / sqrt(z) * t * t / (g * g) : 0);
}

/* Camera-frame point of pixel (u, v) at planar depth z (pixel centres). */
static void backproject(const sooc_intrinsics *K, double fx, double fy, int u, int v, double z, double P[3]) {
    P[0] = (u + 0.5 - K->cx) / fx * z;
    P[1] = (v + 0.5 - K->cy) / fy * z;
    P[2] = z;
}

/* Angle between the optical axis and the surface normal (the plane angle of
 * Nguyen et al.'s experiment), the normal from the exact depth's neighbours
 * (central differences, one-sided at borders or next to an invalid pixel);
 * 0 when a direction has no valid neighbour. */
static double incidence(const float *z, const sooc_intrinsics *K, double fx, double fy, int W, int H, int u, int v) {
    size_t i = (size_t)v * (size_t)W + (size_t)u;
    double P[3], A[3], B[3], du[3], dv[3];
    backproject(K, fx, fy, u, v, z[i], P);
    int ul = u > 0 && z[i - 1] > 0, ur = u < W - 1 && z[i + 1] > 0;
    int vu = v > 0 && z[i - (size_t)W] > 0, vd = v < H - 1 && z[i + (size_t)W] > 0;
    if (!(ul || ur) || !(vu || vd)) return 0;
    if (ur) backproject(K, fx, fy, u + 1, v, z[i + 1], A); else memcpy(A, P, sizeof P);
    if (ul) backproject(K, fx, fy, u - 1, v, z[i - 1], B); else memcpy(B, P, sizeof P);
    for (int k = 0; k < 3; k++) du[k] = A[k] - B[k];
    if (vd) backproject(K, fx, fy, u, v + 1, z[i + (size_t)W], A); else memcpy(A, P, sizeof P);
    if (vu) backproject(K, fx, fy, u, v - 1, z[i - (size_t)W], B); else memcpy(B, P, sizeof P);
    for (int k = 0; k < 3; k++) dv[k] = A[k] - B[k];
    double n[3] = {du[1] * dv[2] - du[2] * dv[1], du[2] * dv[0] - du[0] * dv[2], du[0] * dv[1] - du[1] * dv[0]};
    double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(nn > 0)) return 0;
    double c = fabs(n[2]) / nn;
    return acos(c > 1 ? 1 : c);
}

/* Second difference of 1/z along one axis, relative: zero on any plane
 * (1/z is affine in the pixel coordinates of a plane), large at a depth
 * discontinuity. Returns 1 for an edge (also when a neighbour is invalid). */
static int edge_axis(const float *z, size_t i, size_t step, int has_lo, int has_hi, double rel) {
    if (!has_lo || !has_hi) {
        /* image border: only an invalid neighbour on the inside marks an edge */
        if (has_lo && !(z[i - step] > 0)) return 1;
        if (has_hi && !(z[i + step] > 0)) return 1;
        return 0;
    }
    double za = z[i - step], zb = z[i + step], zc = z[i];
    if (!(za > 0) || !(zb > 0)) return 1;
    return fabs(1 / za - 2 / zc + 1 / zb) * zc > rel;
}

static double clamp01(double v) { return v < 0 ? 0 : v > 1 ? 1 : v; }

sooc_status sooc_noise_apply(sooc_frame *f, const sooc_noise_params *p, uint64_t seed, uint64_t scene, int view) {
    if (!f || !f->depth || !f->valid || !f->rgb || f->width <= 0 || f->height <= 0)
        return sooc_seterr(SOOC_EINVAL, "sensor noise: empty frame");
    if (!(p->sigma0 >= 0 && p->sigma_k >= 0 && p->baseline > 0 && p->f_ref > 0 && p->subpixel_inv > 0 &&
          p->z_max > p->z_min && p->edge_drop >= 0 && p->edge_drop <= 1 && p->speckle_drop >= 0 &&
          p->speckle_drop <= 1))
        return sooc_seterr(SOOC_EINVAL, "sensor noise: bad parameters");
    int W = f->width, H = f->height;
    size_t np = (size_t)W * (size_t)H;
    float *z0 = sooc_malloc(sizeof(float) * np);
    if (!z0) return SOOC_ENOMEM;
    memcpy(z0, f->depth, sizeof(float) * np);
    /* every (seed, scene, view) has its own stream; the per-scene colour
     * terms come from stream (seed, scene) so they are shared by the views */
    sooc_rng rs, rv;
    sooc_rng_seed(&rs, seed ^ 0x5e4503a1c0ffee11ull, scene);
    sooc_rng_seed(&rv, seed ^ 0x5e4503a1c0ffee11ull, (scene << 20) ^ (uint64_t)(uint32_t)view ^ 0x8000000000000000ull);
    double fx = fabs(f->K.fx) > 0 ? fabs(f->K.fx) : W / (2 * tan(M_PI / 6));
    double F = p->f_ref * p->baseline;

    /* 1-4: invalid pixels, decided on the exact depth */
    for (size_t i = 0; i < np; i++)
        if (z0[i] > 0 && (z0[i] < p->z_min || z0[i] > p->z_max)) f->depth[i] = 0;
    if (p->shadow) {
        for (int v = 0; v < H; v++) {
            const float *zr = z0 + (size_t)v * (size_t)W;
            float *dr = f->depth + (size_t)v * (size_t)W;
            double m = -1e300; /* max over pixels to the right of d(u) - u */
            for (int u = W - 1; u >= 0; u--) {
                if (zr[u] > 0) {
                    double d = fx * p->baseline / zr[u];
                    if (m > d - u) dr[u] = 0;
                    if (d - u > m) m = d - u;
                }
            }
        }
    }
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            size_t i = (size_t)v * (size_t)W + (size_t)u;
            /* draw both numbers for every pixel so the stream does not depend on the scene content */
            double a = sooc_rng_uniform(&rv), b = sooc_rng_uniform(&rv);
            if (!(z0[i] > 0)) continue;
            int edge = edge_axis(z0, i, 1, u > 0, u < W - 1, p->edge_rel) ||
                       edge_axis(z0, i, (size_t)W, v > 0, v < H - 1, p->edge_rel);
            if ((edge && a < p->edge_drop) || b < p->speckle_drop) f->depth[i] = 0;
        }
    /* 5-6: axial noise and disparity quantisation */
    double fy = fabs(f->K.fy) > 0 ? fabs(f->K.fy) : fx;
    for (size_t i = 0; i < np; i++) {
        double g = sooc_rng_normal(&rv);
        double z = f->depth[i];
        if (!(z > 0)) continue;
        double th = p->sigma_a > 0 ? incidence(z0, &f->K, fx, fy, W, H, (int)(i % (size_t)W), (int)(i / (size_t)W)) : 0;
        double sz = sooc_noise_sigma_zt(p, z, th), var = sz * sz;
        if (p->quantise) {
            double q = z * z / (F * p->subpixel_inv);
            var -= q * q / 12;
            if (var < 0) var = 0;
        }
        double zn = z + sqrt(var) * g;
        if (p->quantise && zn > 0) {
            double k = floor(F * p->subpixel_inv / zn + 0.5);
            zn = k > 0 ? F * p->subpixel_inv / k : 0;
        }
        f->depth[i] = zn > 0 && zn <= p->z_max * 1.5 ? (float)zn : 0;
    }
    for (size_t i = 0; i < np; i++) f->valid[i] = f->depth[i] > 0;

    /* colour: white balance (per scene), exposure (per view), pixel noise */
    double wb[3], ph1 = sooc_rng_range(&rs, 0, 2 * M_PI), ph2 = sooc_rng_range(&rs, 0, 2 * M_PI);
    for (int k = 0; k < 3; k++) wb[k] = exp(p->wb_sigma * sooc_rng_normal(&rs));
    double e = p->exposure_sigma * (sin(2 * M_PI * view / 23.0 + ph1) + sin(2 * M_PI * view / 9.0 + ph2));
    double gain = exp(e);
    for (size_t i = 0; i < np * 3; i++) {
        double I = clamp01(f->rgb[i] / 255.0 * gain * wb[i % 3]);
        double s = sqrt(p->rgb_read * p->rgb_read + p->rgb_shot * I);
        double o = clamp01(I + s * sooc_rng_normal(&rv));
        f->rgb[i] = (uint8_t)floor(o * 255 + 0.5);
    }
    sooc_free(z0);
    return SOOC_OK;
}

/* The noise of one generated view: gen_impl.h. */
sooc_status sooc_gen_noise_view(sooc_frame *f, const char *scene_dir, int view, double depth_scale, uint64_t seed,
                                int scene) {
    sooc_image img = {0};
    sooc_status s = sooc_image_alloc(&img, f->width, f->height, SOOC_PIX_GRAY16);
    if (s) return s;
    uint16_t *d = img.data;
    size_t np = (size_t)f->width * (size_t)f->height;
    for (size_t k = 0; k < np; k++) {
        double q = f->valid[k] && f->depth[k] > 0 ? floor(f->depth[k] / depth_scale + 0.5) : 0;
        d[k] = q > 65535 ? 0 : (uint16_t)q;
    }
    char name[64], path[4096];
    snprintf(name, sizeof name, "depth_gt/%06d.png", view);
    s = sooc_path_join(path, sizeof path, scene_dir, name);
    if (!s) s = sooc_png_write(path, &img, 6);
    sooc_image_free(&img);
    if (s) return s;
    sooc_noise_params np_;
    sooc_noise_params_kinect(&np_);
    return sooc_noise_apply(f, &np_, seed, (uint64_t)scene, view);
}
