/* Vectors, rotations, SE(3), the pinhole camera and the gravity-aligned frame. */
#include "sooc3d/core.h"

#include <math.h>
#include <string.h>

void sooc_v3_sub(double o[3], const double a[3], const double b[3]) {
    o[0] = a[0] - b[0]; o[1] = a[1] - b[1]; o[2] = a[2] - b[2];
}
void sooc_v3_add(double o[3], const double a[3], const double b[3]) {
    o[0] = a[0] + b[0]; o[1] = a[1] + b[1]; o[2] = a[2] + b[2];
}
void sooc_v3_scale(double o[3], const double a[3], double s) {
    o[0] = a[0] * s; o[1] = a[1] * s; o[2] = a[2] * s;
}
double sooc_v3_dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
void sooc_v3_cross(double o[3], const double a[3], const double b[3]) {
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0];
    o[0] = x; o[1] = y; o[2] = z;
}
double sooc_v3_norm(const double a[3]) { return sqrt(sooc_v3_dot(a, a)); }
double sooc_v3_normalize(double a[3]) {
    double n = sooc_v3_norm(a);
    if (n > 0) sooc_v3_scale(a, a, 1.0 / n);
    return n;
}

void sooc_m3_identity(double R[9]) {
    memset(R, 0, 9 * sizeof *R);
    R[0] = R[4] = R[8] = 1;
}
void sooc_m3_mul(double o[9], const double A[9], const double B[9]) {
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            o[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}
void sooc_m3_transpose(double o[9], const double A[9]) {
    double t[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) t[3 * j + i] = A[3 * i + j];
    memcpy(o, t, sizeof t);
}
void sooc_m3_mulv(double o[3], const double R[9], const double v[3]) {
    double x = R[0] * v[0] + R[1] * v[1] + R[2] * v[2];
    double y = R[3] * v[0] + R[4] * v[1] + R[5] * v[2];
    double z = R[6] * v[0] + R[7] * v[1] + R[8] * v[2];
    o[0] = x; o[1] = y; o[2] = z;
}
void sooc_m3_tmulv(double o[3], const double R[9], const double v[3]) {
    double x = R[0] * v[0] + R[3] * v[1] + R[6] * v[2];
    double y = R[1] * v[0] + R[4] * v[1] + R[7] * v[2];
    double z = R[2] * v[0] + R[5] * v[1] + R[8] * v[2];
    o[0] = x; o[1] = y; o[2] = z;
}
double sooc_m3_det(const double R[9]) {
    return R[0] * (R[4] * R[8] - R[5] * R[7]) - R[1] * (R[3] * R[8] - R[5] * R[6]) +
           R[2] * (R[3] * R[7] - R[4] * R[6]);
}
int sooc_m3_is_rotation(const double R[9], double tol, double *err_out) {
    double err = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = R[3 * i] * R[3 * j] + R[3 * i + 1] * R[3 * j + 1] + R[3 * i + 2] * R[3 * j + 2];
            double e = fabs(d - (i == j ? 1.0 : 0.0));
            if (e > err) err = e;
        }
    double de = fabs(sooc_m3_det(R) - 1.0);
    if (de > err) err = de;
    if (!isfinite(err)) err = INFINITY;
    if (err_out) *err_out = err;
    return err <= tol;
}
void sooc_m3_rot_y(double R[9], double yaw) {
    double c = cos(yaw), s = sin(yaw);
    double t[9] = {c, 0, s, 0, 1, 0, -s, 0, c};
    memcpy(R, t, sizeof t);
}

void sooc_quat_to_m3(double R[9], const double q_in[4]) {
    double n = sqrt(q_in[0] * q_in[0] + q_in[1] * q_in[1] + q_in[2] * q_in[2] + q_in[3] * q_in[3]);
    double x = q_in[0] / n, y = q_in[1] / n, z = q_in[2] / n, w = q_in[3] / n;
    R[0] = 1 - 2 * (y * y + z * z); R[1] = 2 * (x * y - z * w);     R[2] = 2 * (x * z + y * w);
    R[3] = 2 * (x * y + z * w);     R[4] = 1 - 2 * (x * x + z * z); R[5] = 2 * (y * z - x * w);
    R[6] = 2 * (x * z - y * w);     R[7] = 2 * (y * z + x * w);     R[8] = 1 - 2 * (x * x + y * y);
}
void sooc_m3_to_quat(double q[4], const double R[9]) {
    double tr = R[0] + R[4] + R[8], x, y, z, w;
    if (tr > 0) {
        double s = sqrt(tr + 1.0) * 2;
        w = 0.25 * s; x = (R[7] - R[5]) / s; y = (R[2] - R[6]) / s; z = (R[3] - R[1]) / s;
    } else if (R[0] > R[4] && R[0] > R[8]) {
        double s = sqrt(1.0 + R[0] - R[4] - R[8]) * 2;
        w = (R[7] - R[5]) / s; x = 0.25 * s; y = (R[1] + R[3]) / s; z = (R[2] + R[6]) / s;
    } else if (R[4] > R[8]) {
        double s = sqrt(1.0 + R[4] - R[0] - R[8]) * 2;
        w = (R[2] - R[6]) / s; x = (R[1] + R[3]) / s; y = 0.25 * s; z = (R[5] + R[7]) / s;
    } else {
        double s = sqrt(1.0 + R[8] - R[0] - R[4]) * 2;
        w = (R[3] - R[1]) / s; x = (R[2] + R[6]) / s; y = (R[5] + R[7]) / s; z = 0.25 * s;
    }
    if (w < 0) { x = -x; y = -y; z = -z; w = -w; }
    double n = sqrt(x * x + y * y + z * z + w * w);
    q[0] = x / n; q[1] = y / n; q[2] = z / n; q[3] = w / n;
}
void sooc_quat_slerp(double o[4], const double a[4], const double b_in[4], double t) {
    double b[4] = {b_in[0], b_in[1], b_in[2], b_in[3]};
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    if (d < 0) { for (int i = 0; i < 4; i++) b[i] = -b[i]; d = -d; }
    double wa, wb;
    if (d > 0.9995) { wa = 1 - t; wb = t; }
    else {
        double th = acos(d), s = sin(th);
        wa = sin((1 - t) * th) / s;
        wb = sin(t * th) / s;
    }
    double n = 0;
    for (int i = 0; i < 4; i++) { o[i] = wa * a[i] + wb * b[i]; n += o[i] * o[i]; }
    n = sqrt(n);
    for (int i = 0; i < 4; i++) o[i] /= n;
}

void sooc_se3_identity(double T[16]) {
    memset(T, 0, 16 * sizeof *T);
    T[0] = T[5] = T[10] = T[15] = 1;
}
void sooc_se3_from_rt(double T[16], const double R[9], const double t[3]) {
    for (int i = 0; i < 3; i++) {
        T[4 * i] = R[3 * i]; T[4 * i + 1] = R[3 * i + 1]; T[4 * i + 2] = R[3 * i + 2]; T[4 * i + 3] = t[i];
    }
    T[12] = T[13] = T[14] = 0; T[15] = 1;
}
void sooc_se3_to_rt(double R[9], double t[3], const double T[16]) {
    for (int i = 0; i < 3; i++) {
        if (R) { R[3 * i] = T[4 * i]; R[3 * i + 1] = T[4 * i + 1]; R[3 * i + 2] = T[4 * i + 2]; }
        if (t) t[i] = T[4 * i + 3];
    }
}
void sooc_se3_mul(double o[16], const double A[16], const double B[16]) {
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += A[4 * i + k] * B[4 * k + j];
            o[4 * i + j] = s;
        }
}
void sooc_se3_inverse(double o[16], const double T[16]) {
    double R[9], t[3], Rt[9], ti[3];
    sooc_se3_to_rt(R, t, T);
    sooc_m3_transpose(Rt, R);
    sooc_m3_mulv(ti, Rt, t);
    sooc_v3_scale(ti, ti, -1);
    sooc_se3_from_rt(o, Rt, ti);
}
void sooc_se3_apply(double o[3], const double T[16], const double p[3]) {
    double x = T[0] * p[0] + T[1] * p[1] + T[2] * p[2] + T[3];
    double y = T[4] * p[0] + T[5] * p[1] + T[6] * p[2] + T[7];
    double z = T[8] * p[0] + T[9] * p[1] + T[10] * p[2] + T[11];
    o[0] = x; o[1] = y; o[2] = z;
}
void sooc_se3_rotate(double o[3], const double T[16], const double v[3]) {
    double x = T[0] * v[0] + T[1] * v[1] + T[2] * v[2];
    double y = T[4] * v[0] + T[5] * v[1] + T[6] * v[2];
    double z = T[8] * v[0] + T[9] * v[1] + T[10] * v[2];
    o[0] = x; o[1] = y; o[2] = z;
}
void sooc_se3_interp(double o[16], const double A[16], const double B[16], double t) {
    double Ra[9], Rb[9], ta[3], tb[3], qa[4], qb[4], q[4], R[9], tt[3];
    sooc_se3_to_rt(Ra, ta, A);
    sooc_se3_to_rt(Rb, tb, B);
    sooc_m3_to_quat(qa, Ra);
    sooc_m3_to_quat(qb, Rb);
    sooc_quat_slerp(q, qa, qb, t);
    sooc_quat_to_m3(R, q);
    for (int i = 0; i < 3; i++) tt[i] = (1 - t) * ta[i] + t * tb[i];
    sooc_se3_from_rt(o, R, tt);
}

double sooc_cam_ray(const sooc_intrinsics *K, double u, double v, double dir[3]) {
    dir[0] = (u + 0.5 - K->cx) / K->fx;
    dir[1] = (v + 0.5 - K->cy) / K->fy;
    dir[2] = 1.0;
    double n = sooc_v3_normalize(dir);
    return 1.0 / n;
}
int sooc_cam_project(const sooc_intrinsics *K, const double p[3], double *u, double *v) {
    if (p[2] <= 0) return 0;
    *u = K->fx * p[0] / p[2] + K->cx;
    *v = K->fy * p[1] / p[2] + K->cy;
    return 1;
}
void sooc_cam_crop_resize(sooc_intrinsics *o, const sooc_intrinsics *K, int x0, int y0, int cw, int ch,
                          int w, int h) {
    sooc_intrinsics r = *K;
    double sx = (double)w / cw, sy = (double)h / ch;
    /* Pixel-centre convention: continuous coordinate u maps to (u - x0) * sx. */
    r.fx = K->fx * sx;
    r.fy = K->fy * sy;
    r.cx = (K->cx - x0) * sx;
    r.cy = (K->cy - y0) * sy;
    r.width = w;
    r.height = h;
    *o = r;
}

sooc_status sooc_gframe(const double T_wc[16], double T_wg[16], double *h, double *pitch, double *roll) {
    double fwd[3] = {T_wc[2], T_wc[6], T_wc[10]};   /* camera z axis in world */
    double right[3] = {T_wc[0], T_wc[4], T_wc[8]};  /* camera x axis in world */
    double z[3] = {fwd[0], 0, fwd[2]}, y[3] = {0, 1, 0}, x[3];
    if (sooc_v3_normalize(z) < 1e-6)
        return sooc_seterr(SOOC_EINVAL, "camera looks straight up or down; its floor frame is undefined");
    sooc_v3_cross(x, y, z);
    double R[9] = {x[0], y[0], z[0], x[1], y[1], z[1], x[2], y[2], z[2]};
    double t[3] = {T_wc[3], T_wc[7], T_wc[11]};
    sooc_se3_from_rt(T_wg, R, t);
    if (h) *h = t[1];
    if (pitch) *pitch = asin(fwd[1] > 1 ? 1 : fwd[1] < -1 ? -1 : fwd[1]);
    if (roll) *roll = asin(right[1] > 1 ? 1 : right[1] < -1 ? -1 : right[1]);
    return SOOC_OK;
}

double sooc_wrap_angle(double a) {
    a = fmod(a + M_PI, 2 * M_PI);
    if (a <= 0) a += 2 * M_PI;
    return a - M_PI;
}

void sooc_floor_frame_of(sooc_floor_frame *f, const double T_wg[16]) {
    f->X = T_wg[3];
    f->Z = T_wg[11];
    f->psi = atan2(T_wg[2], T_wg[10]); /* G's z axis in world = (sin psi, 0, cos psi) */
}
/* R2(psi) acting on (x, z): x' = c x + s z, z' = -s x + c z (the xz block of R_y). */
void sooc_floor_to_local(const sooc_floor_frame *f, const double w[3], double l[3]) {
    double c = cos(f->psi), s = sin(f->psi), dx = w[0] - f->X, dz = w[1] - f->Z;
    l[0] = c * dx - s * dz;
    l[1] = s * dx + c * dz;
    l[2] = sooc_wrap_angle(w[2] - f->psi);
}
void sooc_floor_to_world(const sooc_floor_frame *f, const double l[3], double w[3]) {
    double c = cos(f->psi), s = sin(f->psi);
    double X = c * l[0] + s * l[1] + f->X, Z = -s * l[0] + c * l[1] + f->Z;
    w[0] = X;
    w[1] = Z;
    w[2] = sooc_wrap_angle(l[2] + f->psi);
}
