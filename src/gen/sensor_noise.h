/*
 * sooc3d sensor noise: turns an exact rendered RGB-D frame into what a
 * structured-light depth camera (Kinect v1 / PrimeSense class) would give.
 * Used by `sooc3d gen` (--noise kinect; on by default for --preset tabletop);
 * the formulas and parameters are in docs/formats.md section 5.2.
 *
 * Depth, in this order, from the exact planar depth z (m):
 *   1. range: z < z_min or z > z_max is invalid;
 *   2. projector shadow: with the projector `baseline` m to the right of the
 *      camera (+x), a pixel u is invalid when some pixel v > u in its row
 *      has disparity d(v) - d(u) > v - u, d = fx * baseline / z in the
 *      frame's own pixels (the stereo occlusion test);
 *   3. edge dropout: a pixel whose 4-neighbour depth differs by more than
 *      edge_rel * z (or is invalid) is dropped with probability edge_drop;
 *   4. speckle dropout: any pixel with probability speckle_drop;
 *   5. axial noise: z' = z + N(0, s^2) with s^2 = sigma_z(z, theta)^2 - q(z)^2 / 12,
 *      sigma_z = sigma0 + sigma_k (z - z0)^2 + sigma_a / sqrt(z) theta^2 /
 *      (pi/2 - theta)^2 (Nguyen et al. 2012), theta the angle between the
 *      optical axis and the surface normal (from the exact depth's
 *      neighbours, at most theta_max; 0 where they are missing), then
 *   6. disparity quantisation: z'' = F / (round(F * subpixel_inv / z') /
 *      subpixel_inv), F = f_ref * baseline (the sensor's own focal length, not
 *      the frame's); its step is q(z) = z^2 / (F * subpixel_inv), so the total
 *      axial standard deviation is sigma_z(z) (the quantisation's share,
 *      q^2 / 12, is taken out of the Gaussian).
 * Colour: per-scene white balance (log-normal channel gains, std wb_sigma),
 * a per-view exposure gain exp(e) with e = exposure_sigma * (sin(2 pi v / 23
 * + a) + sin(2 pi v / 9 + b)) (a smooth auto-exposure drift over the walk),
 * then per-pixel Gaussian noise of variance rgb_read^2 + rgb_shot * I
 * (I in [0, 1]), rounded to 8 bits.
 *
 * Determinism: the noise of view `view` of scene `scene` depends only on
 * (seed, scene, view), never on threads. Instance ids are not touched.
 */
#ifndef SOOC3D_SENSOR_NOISE_H
#define SOOC3D_SENSOR_NOISE_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_noise_params {
    double sigma0, sigma_k, z0;    /* sigma_z = sigma0 + sigma_k (z - z0)^2: 0.0012, 0.0019, 0.4 m */
    double sigma_a, theta_max;     /* + sigma_a / sqrt(z) theta^2 / (pi/2 - theta)^2: 0.0001, 80 deg */
    int quantise;                  /* disparity quantisation on (1)                                */
    double baseline;               /* projector-camera baseline (m): 0.075                         */
    double f_ref;                  /* sensor focal length (px) of its disparity image: 580          */
    double subpixel_inv;           /* disparity steps per pixel: 8 (1/8 px)                        */
    double z_min, z_max;           /* valid range (m): 0.2, 3.5                                    */
    int shadow;                    /* projector shadow on (1)                                      */
    double edge_rel, edge_drop;    /* edge: relative jump 0.03, dropped with probability 0.5       */
    double speckle_drop;           /* random dropout: 0.002                                        */
    double wb_sigma;               /* white balance log-gain std per channel: 0.04                 */
    double exposure_sigma;         /* exposure log-gain std over the walk: 0.15                    */
    double rgb_read, rgb_shot;     /* colour noise: 0.006, 0.0004                                   */
} sooc_noise_params;

/* Kinect-class defaults (above). */
void sooc_noise_params_kinect(sooc_noise_params *p);

/* Axial standard deviation in m (the formula of step 5): sooc_noise_sigma_z
 * at normal incidence, sooc_noise_sigma_zt at angle theta (radians; clamped
 * to theta_max). */
double sooc_noise_sigma_z(const sooc_noise_params *p, double z);
double sooc_noise_sigma_zt(const sooc_noise_params *p, double z, double theta);

/* Apply the noise to f in place (rgb, depth, valid; instance untouched).
 * Allocates one scratch buffer per call. Errors: SOOC_EINVAL on an empty
 * frame or bad parameters, SOOC_ENOMEM. Thread-safe (no shared state). */
sooc_status sooc_noise_apply(sooc_frame *f, const sooc_noise_params *p, uint64_t seed, uint64_t scene, int view);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_SENSOR_NOISE_H */
