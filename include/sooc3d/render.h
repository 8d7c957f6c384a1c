/*
 * sooc3d dense volume renderer (docs/metrics.md "Rendering"; the composition of the SOOC3D paper).
 *
 * The renderer knows nothing about the model. It sees a "field": N
 * components (0 = layout/background, 1..K = objects), each answering batched
 * point queries with a raw density times presence sigma_hat in [0, 1] and a
 * colour in [0, 1]^3, plus an optional box per component outside of which the
 * component is known to be zero (the model's locality box).
 *
 * Composition at a point x (eps = 1e-8):
 *   S = sum_k sigma_hat_k + eps,   sbar_k = sigma_hat_k^2 / S,   Sbar = sum_k sbar_k
 *   sigma = sigma_max * Sbar,      c = sum_k (sigma_hat_k / S) * rgb_k
 *
 * Rays and depth. A pixel (u, v) casts the ray x(z) = o + z * r with r the
 * camera-frame direction through the pixel centre scaled so that r_z = 1:
 * the ray parameter z IS the planar depth (the same convention as
 * sooc_frame.depth). Samples lie on [t_near, d_clip] in planar depth; the
 * step used in alpha = 1 - exp(-sigma * delta) is the Euclidean length
 * delta = dz * |r|. Outputs (expected depth, d_clip fallback) are planar.
 *
 * Sampling: n_coarse stratified samples (midpoints of n_coarse equal bins, or
 * jittered within each bin when opts.jitter = 1), then, if n_fine > 0, an
 * importance pass: the coarse weights define a piecewise-constant pdf over the
 * gaps between coarse samples (and t_near, d_clip); each weight w_i goes 75 %
 * to the gap preceding sample i and 25 % to the gap following it (ObSuRF's
 * allocation: a surface first seen at z_i lies before z_i); n_fine samples are drawn by inverse CDF at stratified
 * quantiles (midpoints, or jittered) and merged with the coarse ones. The
 * field is evaluated at all n_coarse + n_fine samples and the final image is
 * composited from the merged, sorted set.
 *
 * Volume rendering on the merged samples z_1 < ... < z_N:
 *   delta_i = (z_{i+1} - z_i) |r|, delta_N = (d_clip - z_N) |r|
 *   alpha_i = 1 - exp(-sigma_i delta_i), T_i = prod_{j<i} (1 - alpha_j), w_i = T_i alpha_i
 *   A = sum w_i, RGB = sum w_i c_i + (1 - A) bg, D = sum w_i z_i + (1 - A) d_clip
 *   seg_k = sum_i w_i sbar_k(x_i) / Sbar(x_i);  label = argmax_k seg_k, or -1 if A < 0.5
 * Per-component image k: the same samples rendered with sigma_max * sbar_k and
 * rgb_k alone (premultiplied colour + opacity, no background).
 *
 * Culling: component k is evaluated only at samples inside its box (ray-box
 * slab test, padded by 1e-5 m so borderline samples are evaluated); elsewhere
 * sigma_hat_k = 0. Sample positions do not depend on culling, so when the
 * field is zero outside its boxes, culled and unculled images are identical.
 *
 * Threads and determinism: rays are processed in fixed chunks of
 * opts.chunk_rays consecutive pixels (row-major), so every eval batch holds
 * the same points whatever the thread count; jitter uses one RNG stream per
 * pixel (seed, pixel index). Results are bit-identical with OpenMP on or off
 * and for any thread count, provided the field's eval is deterministic per
 * batch. Scratch memory is allocated once per render call (per worker); there
 * is no allocation per ray.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_RENDER_H
#define SOOC3D_RENDER_H

#include "sooc3d/core.h"
#include "sooc3d/geom.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SOOC_RENDER_MAX_COMP 64   /* 1 layout + up to 63 objects per view */
#define SOOC_RENDER_LABEL_NONE (-1)

/* A box in the field's frame: points p (field frame) with
 * lo <= T_bf * p <= hi component-wise, where T_bf = inverse(T_fb). */
typedef struct sooc_render_box {
    int enabled;           /* 0: component is evaluated everywhere (no culling) */
    double T_fb[16];       /* box-local -> field frame, rigid, row-major        */
    double lo[3], hi[3];   /* extents in box-local coordinates                  */
} sooc_render_box;

/* The object locality box for a floor pose (p_x, p_z, yaw)
 * in a gravity-aligned frame G (y up, floor at y = -h):
 *   local origin b = (p_x, -h, p_z), rotation R_y(yaw),
 *   lo = (-R_h, 0, -R_h), hi = (R_h, H_b, R_h).
 * The box is in G, so the field's frame must be G (T_fc = T_gc). */
void sooc_render_box_object(sooc_render_box *b, double px, double pz, double yaw, double h,
                            double R_h, double H_b);
/* Axis-aligned box [lo, hi] in the field frame. */
void sooc_render_box_aabb(sooc_render_box *b, const double lo[3], const double hi[3]);

/* Batched evaluation of component `comp` at n points (n x 3 floats in the
 * field's frame, n <= the max_batch given to prepare). Writes sigma_hat[n]
 * (raw density times presence, in [0, 1]) and rgb[n x 3] (in [0, 1]).
 * Called concurrently from several workers; `worker` in [0, n_workers) is
 * stable within one render call, so per-worker scratch can be indexed by it.
 * Must not allocate per call if it wants to be fast; must be deterministic. */
typedef void (*sooc_field_eval_fn)(void *user, int worker, int comp, const float *pts, int n,
                                   float *sigma_hat, float *rgb);
/* Optional: called once per render call before any eval, on the calling
 * thread, so the field can size per-worker scratch. */
typedef sooc_status (*sooc_field_prepare_fn)(void *user, int n_workers, int max_batch);

typedef struct sooc_field {
    int n_comp;                       /* 1 + K, <= SOOC_RENDER_MAX_COMP        */
    const sooc_render_box *boxes;     /* n_comp boxes, or NULL = no culling     */
    float sigma_max;                  /* density scale (30 /m)                    */
    sooc_field_eval_fn eval;
    sooc_field_prepare_fn prepare;    /* may be NULL                           */
    void *user;
} sooc_field;

typedef struct sooc_render_opts {
    int n_coarse;          /* stratified samples per ray (default 96)             */
    int n_fine;            /* importance samples per ray (default 32; 0 = none)   */
    double t_near, d_clip; /* planar depth range in metres (default 0.1, 8)       */
    float bg_rgb[3];       /* colour behind the last sample (default 0, 0, 0)     */
    int jitter;            /* 0 = deterministic midpoints (default), 1 = jittered */
    uint64_t seed;         /* jitter seed                                         */
    int threads;           /* 0 = OpenMP default; 1 = serial                      */
    int cull;              /* 1 = ray-box culling (default), 0 = evaluate all     */
    int chunk_rays;        /* rays per work item / eval batch (default 16)        */
    int components;        /* 1 = also render per-component images (default 0)   */
    int soft_seg;          /* 1 = also keep seg_k per pixel (default 0)           */
} sooc_render_opts;

void sooc_render_opts_default(sooc_render_opts *o);

/* Render outputs, H x W row-major. Optional buffers are NULL when not asked. */
typedef struct sooc_render_out {
    int width, height, n_comp;
    float *rgb;            /* H*W*3                                                */
    float *depth;          /* H*W planar metres (expected depth, d_clip fallback)  */
    float *alpha;          /* H*W accumulated opacity A                            */
    int16_t *label;        /* H*W argmax component, SOOC_RENDER_LABEL_NONE if A<0.5 */
    float *seg;            /* optional H*W*n_comp seg_k (soft_seg)                 */
    float *comp_rgb;       /* optional n_comp*H*W*3 premultiplied (components)     */
    float *comp_alpha;     /* optional n_comp*H*W (components)                     */
    float *uncert;         /* optional H*W: sum over channels of RGB variance      */
    float *rgb_mean;       /* optional H*W*3: mean RGB over the posterior samples  */
} sooc_render_out;

void sooc_render_out_free(sooc_render_out *o);   /* NULL-safe, leaves *o zeroed */

/* Render one view. K gives the image size; T_fc maps camera (OpenCV optical)
 * coordinates to the field's frame (e.g. T_gc = inverse(T_wg) * T_wc for a
 * field in G_t). `out` is (re)allocated to K->width x K->height as needed.
 * Fails with SOOC_EINVAL on bad options, SOOC_ENOMEM, or the prepare status. */
sooc_status sooc_render_view(const sooc_field *f, const sooc_intrinsics *K, const double T_fc[16],
                             const sooc_render_opts *o, sooc_render_out *out);

/* Posterior sampling hook for the uncertainty map: fill *f with the field of
 * posterior sample m (0 <= m < M); `release` (may be NULL) is called after
 * sample m was rendered. */
typedef struct sooc_field_sampler {
    sooc_status (*get)(void *user, int m, sooc_field *f);
    void (*release)(void *user, int m, sooc_field *f);
    void *user;
} sooc_field_sampler;

/* Render M posterior samples and fill out->uncert (per-pixel variance of RGB,
 * population variance over the M samples, summed over channels; MulMON) and
 * out->rgb_mean. Other buffers of `out` are left as they are. Each sample uses
 * the same opts (jitter seeds are offset by m). M >= 2. */
sooc_status sooc_render_uncertainty(const sooc_field_sampler *s, int M, const sooc_intrinsics *K,
                                    const double T_fc[16], const sooc_render_opts *o,
                                    sooc_render_out *out);
/* Convenience: the same with M explicit fields. */
sooc_status sooc_render_uncertainty_fields(const sooc_field *fields, int M, const sooc_intrinsics *K,
                                           const double T_fc[16], const sooc_render_opts *o,
                                           sooc_render_out *out);

/* Ray-box slab test in planar-depth parameter: for the ray x(z) = o + z r,
 * returns 1 and [*z0, *z1] (clipped to [zmin, zmax]) if it meets the box. */
int sooc_render_ray_box(const sooc_render_box *b, const double o[3], const double r[3],
                        double zmin, double zmax, double *z0, double *z1);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_RENDER_H */
