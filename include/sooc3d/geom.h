/*
 * sooc3d geometry: small dense vectors and matrices in double, SE(3) poses,
 * quaternions, the pinhole camera, and the gravity-aligned camera frame G_t.
 *
 * Conventions (docs/formats.md §1):
 *  - Matrices are row-major double[9] (3x3) or double[16] (4x4).
 *  - A pose T_ab maps points in frame b to frame a: p_a = T_ab * p_b.
 *    Camera poses are T_wc (camera-to-world).
 *  - Camera optical axes are OpenCV's: x right, y down, z forward.
 *  - The world is gravity-aligned with +y up and the floor at y = 0.
 *  - Quaternions are Hamilton, stored (x, y, z, w) as in TUM and ROS.
 *  - Floor poses (x, z, yaw): yaw is a rotation about +y with
 *    R_y(yaw) = [[cos, 0, sin], [0, 1, 0], [-sin, 0, cos]].
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_GEOM_H
#define SOOC3D_GEOM_H

#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- 3-vectors ---- */
void sooc_v3_sub(double out[3], const double a[3], const double b[3]);
void sooc_v3_add(double out[3], const double a[3], const double b[3]);
void sooc_v3_scale(double out[3], const double a[3], double s);
double sooc_v3_dot(const double a[3], const double b[3]);
void sooc_v3_cross(double out[3], const double a[3], const double b[3]);
double sooc_v3_norm(const double a[3]);
/* Normalise in place; returns the old norm (0 leaves the vector unchanged). */
double sooc_v3_normalize(double a[3]);

/* ---- 3x3 ---- */
void sooc_m3_identity(double R[9]);
void sooc_m3_mul(double out[9], const double A[9], const double B[9]);  /* out may alias neither */
void sooc_m3_transpose(double out[9], const double A[9]);
void sooc_m3_mulv(double out[3], const double R[9], const double v[3]);
void sooc_m3_tmulv(double out[3], const double R[9], const double v[3]); /* R^T v */
double sooc_m3_det(const double R[9]);
/* max |R R^T - I| entry and |det R - 1|; a rotation passes at tol ~1e-4 for
 * values read from 6-decimal text files. */
int sooc_m3_is_rotation(const double R[9], double tol, double *err_out);
void sooc_m3_rot_y(double R[9], double yaw);

/* ---- quaternions (x, y, z, w) ---- */
void sooc_quat_to_m3(double R[9], const double q[4]);   /* q need not be unit; it is normalised */
void sooc_m3_to_quat(double q[4], const double R[9]);   /* w >= 0 */
void sooc_quat_slerp(double out[4], const double a[4], const double b[4], double t);

/* ---- SE(3) 4x4 ---- */
void sooc_se3_identity(double T[16]);
void sooc_se3_from_rt(double T[16], const double R[9], const double t[3]);
void sooc_se3_to_rt(double R[9], double t[3], const double T[16]);
void sooc_se3_mul(double out[16], const double A[16], const double B[16]); /* out aliases neither */
void sooc_se3_inverse(double out[16], const double T[16]);
void sooc_se3_apply(double out[3], const double T[16], const double p[3]);
void sooc_se3_rotate(double out[3], const double T[16], const double v[3]);
/* Interpolate poses: SLERP on rotation, linear on translation. */
void sooc_se3_interp(double out[16], const double A[16], const double B[16], double t);

/* ---- pinhole camera ---- */
typedef enum sooc_distortion {
    SOOC_DIST_NONE = 0, SOOC_DIST_PLUMB_BOB = 1, SOOC_DIST_RATIONAL = 2, SOOC_DIST_EQUIDISTANT = 3
} sooc_distortion;

typedef struct sooc_intrinsics {
    int width, height;
    double fx, fy, cx, cy;
    sooc_distortion dist_model;
    double dist[8];          /* OpenCV order: k1 k2 p1 p2 k3 [k4 k5 k6] */
} sooc_intrinsics;

/* Unit ray direction (camera frame) through pixel centre (u + 0.5, v + 0.5)
 * for an undistorted camera; returns the z component of the unnormalised ray
 * (1/|ray|), used to convert planar depth z to Euclidean distance. */
double sooc_cam_ray(const sooc_intrinsics *K, double u, double v, double dir[3]);
/* Project a camera-frame point; returns 0 if z <= 0. Pixel coordinates are
 * continuous (pixel i covers [i, i+1)). */
int sooc_cam_project(const sooc_intrinsics *K, const double p[3], double *u, double *v);
/* Scale intrinsics for a resize from (K->width, K->height) to (w, h), after an
 * optional crop (x0, y0, cw, ch) in source pixels. */
void sooc_cam_crop_resize(sooc_intrinsics *out, const sooc_intrinsics *K, int x0, int y0, int cw,
                          int ch, int w, int h);

/* ---- gravity-aligned camera frame G_t (the SOOC3D paper) ---- */
/* Given a camera pose T_wc in a +y-up world with the floor at y = 0, fill
 * T_wg (G-to-world: origin at the camera centre, y = world up, z = camera
 * forward projected on the floor plane) and the camera height h (y of the
 * centre). Also returns pitch (rad, negative when looking down) and roll.
 * Fails with SOOC_EINVAL if the camera looks straight up or down. */
sooc_status sooc_gframe(const double T_wc[16], double T_wg[16], double *h, double *pitch, double *roll);

/* Floor pose (x, z, yaw) conversions between world and a G frame with
 * ground position (Xc, Zc) and yaw psi:
 *   (px, pz) = R2(psi)^T ((X, Z) - (Xc, Zc)),  theta = Theta - psi.
 * R2 uses the same sign convention as R_y. */
typedef struct sooc_floor_frame { double X, Z, psi; } sooc_floor_frame;
void sooc_floor_frame_of(sooc_floor_frame *f, const double T_wg[16]);
void sooc_floor_to_local(const sooc_floor_frame *f, const double world[3], double local[3]);
void sooc_floor_to_world(const sooc_floor_frame *f, const double local[3], double world[3]);
/* Wrap an angle to (-pi, pi]. */
double sooc_wrap_angle(double a);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_GEOM_H */
