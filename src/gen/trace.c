/* The generator's CPU ray tracer: exact ray/primitive intersections (closed
 * form for sphere, box, cylinder, cone; sphere tracing on the exact SDF for
 * tori; bracketing + bisection on the gauge function for superquadrics),
 * Lambertian + ambient shading, optional cast shadows and Blinn-Phong
 * highlights, procedural floor textures. One allocation per view. */
#include "sooc3d/gen.h"

#include <math.h>
#include <string.h>
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

typedef struct tpart {
    sooc_shape prim;
    double c[3], d[5];
    double bmin[3], bmax[3];   /* AABB relative to c */
} tpart;

typedef struct tobj {
    int id;
    double x, z, cs, sn;       /* position and cos/sin of yaw */
    double bc[3], br;          /* world bounding sphere */
    int p0, np;
    float col[3], col2[3];
    sooc_obj_tex tex;
    double tex_scale, height;
} tobj;

typedef struct tworld {
    const sooc_scene *sc;
    tobj *objs;
    tpart *parts;
    int nobj;
} tworld;

typedef struct thit {
    double t;
    double n[3];               /* world normal (unnormalised ok) */
    int kind;                  /* 0 none, 1 floor (layout), 2 wall, 3 object, 4 ground, 5 support side */
    int obj;                   /* index into objs */
} thit;

#define T_EPS 1e-9

static void part_aabb(tpart *p) {
    const double *d = p->d;
    switch (p->prim) {
    case SOOC_SHAPE_SPHERE:
        for (int k = 0; k < 3; k++) { p->bmin[k] = -d[0]; p->bmax[k] = d[0]; }
        break;
    case SOOC_SHAPE_BOX: case SOOC_SHAPE_SUPERQUADRIC:
        for (int k = 0; k < 3; k++) { p->bmin[k] = -d[k]; p->bmax[k] = d[k]; }
        break;
    case SOOC_SHAPE_CYLINDER:
        p->bmin[0] = p->bmin[2] = -d[0]; p->bmax[0] = p->bmax[2] = d[0];
        p->bmin[1] = -d[1]; p->bmax[1] = d[1];
        break;
    case SOOC_SHAPE_CONE:
        p->bmin[0] = p->bmin[2] = -d[0]; p->bmax[0] = p->bmax[2] = d[0];
        p->bmin[1] = 0; p->bmax[1] = d[1];
        break;
    case SOOC_SHAPE_TORUS: {
        int ax = d[2] > 0.5 ? 2 : 1, ring = 3 - ax; /* the axis of the ring; the other in-plane axis */
        p->bmin[0] = p->bmin[ring] = -(d[0] + d[1]); p->bmax[0] = p->bmax[ring] = d[0] + d[1];
        p->bmin[ax] = -d[1]; p->bmax[ax] = d[1];
        if (d[3] > 0.5) p->bmin[0] = 0;
        break;
    }
    case SOOC_SHAPE_FRUSTUM: {
        double rm = d[0] > d[1] ? d[0] : d[1];
        p->bmin[0] = p->bmin[2] = -rm; p->bmax[0] = p->bmax[2] = rm;
        p->bmin[1] = 0; p->bmax[1] = d[2];
        break;
    }
    default:
        for (int k = 0; k < 3; k++) { p->bmin[k] = 0; p->bmax[k] = 0; }
    }
}

/* Slab test; returns 1 with [*t0, *t1] the overlap of the ray with the box. */
static int slab(const double o[3], const double d[3], const double bmin[3], const double bmax[3],
                double *t0, double *t1, int *axis0) {
    double lo = -1e300, hi = 1e300;
    int ax = 0;
    for (int k = 0; k < 3; k++) {
        if (fabs(d[k]) < 1e-300) {
            if (o[k] < bmin[k] || o[k] > bmax[k]) return 0;
            continue;
        }
        double inv = 1.0 / d[k], a = (bmin[k] - o[k]) * inv, b = (bmax[k] - o[k]) * inv;
        if (a > b) { double t = a; a = b; b = t; }
        if (a > lo) { lo = a; ax = k; }
        if (b < hi) hi = b;
        if (lo > hi) return 0;
    }
    *t0 = lo;
    *t1 = hi;
    if (axis0) *axis0 = ax;
    return 1;
}

static double sq_g(const double *d, double x, double y, double z) {
    double xz = pow(fabs(x / d[0]), 2 / d[4]) + pow(fabs(z / d[2]), 2 / d[4]);
    return pow(pow(xz, d[4] / d[3]) + pow(fabs(y / d[1]), 2 / d[3]), d[3] / 2);
}

static double torus_sdf(const double *d, const double p[3]) {
    return hypot(hypot(p[0], p[2]) - d[0], p[1]) - d[1];
}

/* Solve x^2 + z^2 = (a + k y)^2 along o + t r; fills up to two roots. */
static int cone_roots(const double o[3], const double r[3], double a, double k, double ts[2]) {
    double w0 = a + k * o[1];
    double A = r[0] * r[0] + r[2] * r[2] - k * k * r[1] * r[1];
    double B = o[0] * r[0] + o[2] * r[2] - k * w0 * r[1];
    double C = o[0] * o[0] + o[2] * o[2] - w0 * w0;
    if (fabs(A) > 1e-14) {
        double disc = B * B - A * C;
        if (disc < 0) return 0;
        double sq = sqrt(disc);
        ts[0] = (-B - sq) / A;
        ts[1] = (-B + sq) / A;
        return 2;
    }
    if (fabs(B) > 1e-14) { ts[0] = -C / (2 * B); return 1; }
    return 0;
}

/* Horizontal disc or annulus rmin <= rho <= rmax at height y. */
static void disc_hit(const double o[3], const double r[3], double y, double rmin, double rmax, double tmin,
                     double *best, int *hit, double n[3]) {
    if (fabs(r[1]) < 1e-18) return;
    double t = (y - o[1]) / r[1];
    if (!(t > tmin && t < *best)) return;
    double x = o[0] + t * r[0], z = o[2] + t * r[2], rho2 = x * x + z * z;
    if (rho2 > rmax * rmax || rho2 < rmin * rmin) return;
    *best = t;
    *hit = 1;
    n[0] = 0; n[1] = 1; n[2] = 0;
}

/* Intersect a ray (part-relative origin o, unit direction r) with a part.
 * Returns 1 and the nearest t in (tmin, tmax) with the normal. */
static int part_hit(const tpart *p, const double o[3], const double r[3], double tmin, double tmax,
                    double *tout, double n[3]) {
    const double *d = p->d;
    double t0, t1;
    int ax;
    if (!slab(o, r, p->bmin, p->bmax, &t0, &t1, &ax)) return 0;
    if (t1 < tmin || t0 > tmax) return 0;
    switch (p->prim) {
    case SOOC_SHAPE_SPHERE: {
        double b = sooc_v3_dot(o, r), c = sooc_v3_dot(o, o) - d[0] * d[0], disc = b * b - c;
        if (disc < 0) return 0;
        double sq = sqrt(disc), t = -b - sq;
        if (t <= tmin) t = -b + sq;
        if (t <= tmin || t >= tmax) return 0;
        for (int k = 0; k < 3; k++) n[k] = o[k] + t * r[k];
        *tout = t;
        return 1;
    }
    case SOOC_SHAPE_BOX: {
        double t = t0;
        int a = ax;
        if (t <= tmin) return 0; /* origin inside the box: not needed for cameras outside objects */
        if (t >= tmax) return 0;
        n[0] = n[1] = n[2] = 0;
        n[a] = r[a] > 0 ? -1 : 1;
        *tout = t;
        return 1;
    }
    case SOOC_SHAPE_CYLINDER: {
        double best = tmax;
        int hit = 0;
        double a = r[0] * r[0] + r[2] * r[2];
        if (a > 1e-18) {
            double b = o[0] * r[0] + o[2] * r[2], c = o[0] * o[0] + o[2] * o[2] - d[0] * d[0];
            double disc = b * b - a * c;
            if (disc >= 0) {
                double sq = sqrt(disc);
                for (int s = -1; s <= 1; s += 2) {
                    double t = (-b + s * sq) / a, y = o[1] + t * r[1];
                    if (t > tmin && t < best && fabs(y) <= d[1]) {
                        best = t; hit = 1;
                        n[0] = o[0] + t * r[0]; n[1] = 0; n[2] = o[2] + t * r[2];
                        break;
                    }
                }
            }
        }
        if (fabs(r[1]) > 1e-18)
            for (int s = -1; s <= 1; s += 2) {
                double t = (s * d[1] - o[1]) / r[1];
                double x = o[0] + t * r[0], z = o[2] + t * r[2];
                if (t > tmin && t < best && x * x + z * z <= d[0] * d[0]) {
                    best = t; hit = 1;
                    n[0] = 0; n[1] = s; n[2] = 0;
                }
            }
        if (hit) *tout = best;
        return hit;
    }
    case SOOC_SHAPE_CONE: {
        double best = tmax;
        int hit = 0;
        double k = d[0] / d[1], k2 = k * k, H = d[1];
        double hy = H - o[1];
        double a = r[0] * r[0] + r[2] * r[2] - k2 * r[1] * r[1];
        double b = o[0] * r[0] + o[2] * r[2] + k2 * hy * r[1];
        double c = o[0] * o[0] + o[2] * o[2] - k2 * hy * hy;
        double ts[2];
        int nt = 0;
        if (fabs(a) > 1e-14) {
            double disc = b * b - a * c;
            if (disc >= 0) {
                double sq = sqrt(disc);
                ts[0] = (-b - sq) / a;
                ts[1] = (-b + sq) / a;
                if (ts[0] > ts[1]) { double t = ts[0]; ts[0] = ts[1]; ts[1] = t; }
                nt = 2;
            }
        } else if (fabs(b) > 1e-14) {
            ts[0] = -c / (2 * b);
            nt = 1;
        }
        for (int i = 0; i < nt; i++) {
            double t = ts[i], y = o[1] + t * r[1];
            if (t > tmin && t < best && y >= 0 && y <= H) {
                double x = o[0] + t * r[0], z = o[2] + t * r[2], rho = hypot(x, z);
                best = t; hit = 1;
                if (rho > 1e-12) { n[0] = x / rho; n[2] = z / rho; } else { n[0] = n[2] = 0; }
                n[1] = k;
                break;
            }
        }
        if (fabs(r[1]) > 1e-18) {
            double t = -o[1] / r[1], x = o[0] + t * r[0], z = o[2] + t * r[2];
            if (t > tmin && t < best && x * x + z * z <= d[0] * d[0]) {
                best = t; hit = 1;
                n[0] = 0; n[1] = -1; n[2] = 0;
            }
        }
        if (hit) *tout = best;
        return hit;
    }
    case SOOC_SHAPE_TORUS: {
        /* standing tori (d[2]) trace with y and z swapped; half tori (d[3])
         * trace max(torus, -x), a lower bound of the distance, so the march
         * stays safe */
        int sw = d[2] > 0.5, half = d[3] > 0.5;
        double t = t0 > tmin ? t0 : tmin, end = t1 < tmax ? t1 : tmax;
        for (int it = 0; it < 400 && t <= end; it++) {
            double q[3] = {o[0] + t * r[0], o[1] + t * r[1], o[2] + t * r[2]};
            if (sw) { double tmp = q[1]; q[1] = q[2]; q[2] = tmp; }
            double s = torus_sdf(d, q);
            if (half && -q[0] > s) s = -q[0];
            if (s < 1e-7) {
                if (half && -q[0] >= torus_sdf(d, q)) { n[0] = -1; n[1] = n[2] = 0; *tout = t; return 1; }
                double rho = hypot(q[0], q[2]);
                double f = rho > 1e-12 ? (rho - d[0]) / rho : 0;
                n[0] = q[0] * f; n[1] = q[1]; n[2] = q[2] * f;
                if (sw) { double tmp = n[1]; n[1] = n[2]; n[2] = tmp; }
                *tout = t;
                return 1;
            }
            t += s;
        }
        return 0;
    }
    case SOOC_SHAPE_FRUSTUM: {
        /* lateral surfaces rho = a + k y: the outer one (a = rb, 0 <= y <= h)
         * and, for vessels, the inner one (a = rb - tw, bb <= y <= h); then
         * the bottom disc, and the top disc (solid) or rim + inner bottom */
        double rb = d[0], rt = d[1], h = d[2], tw = d[3], bb = d[4], k = (rt - rb) / h;
        double best = tmax;
        int hit = 0;
        for (int side = 0; side < (tw > 0 ? 2 : 1); side++) {
            double a = side ? rb - tw : rb, ylo = side ? bb : 0, ts[2];
            int nt = cone_roots(o, r, a, k, ts);
            for (int i = 0; i < nt; i++) {
                double t = ts[i], y = o[1] + t * r[1];
                if (!(t > tmin && t < best && y >= ylo && y <= h)) continue;
                best = t;
                hit = 1;
                n[0] = o[0] + t * r[0]; n[1] = -k * (a + k * y); n[2] = o[2] + t * r[2];
            }
        }
        disc_hit(o, r, 0, 0, rb, tmin, &best, &hit, n);
        if (tw > 0) {
            disc_hit(o, r, h, rt - tw, rt, tmin, &best, &hit, n);
            disc_hit(o, r, bb, 0, rb - tw + k * bb, tmin, &best, &hit, n);
        } else {
            disc_hit(o, r, h, 0, rt, tmin, &best, &hit, n);
        }
        if (hit) *tout = best;
        return hit;
    }
    case SOOC_SHAPE_SUPERQUADRIC: {
        double ta = t0 > tmin ? t0 : tmin, tb = t1 < tmax ? t1 : tmax;
        if (tb <= ta) return 0;
        const int N = 96;
        double dt = (tb - ta) / N, tp = ta;
        double gp = sq_g(d, o[0] + ta * r[0], o[1] + ta * r[1], o[2] + ta * r[2]);
        if (gp <= 1) return 0; /* starts inside */
        for (int i = 1; i <= N; i++) {
            double t = ta + dt * i;
            double g = sq_g(d, o[0] + t * r[0], o[1] + t * r[1], o[2] + t * r[2]);
            if (g <= 1) {
                double lo = tp, hi = t;
                for (int b = 0; b < 60 && hi - lo > 1e-10; b++) {
                    double m = 0.5 * (lo + hi);
                    if (sq_g(d, o[0] + m * r[0], o[1] + m * r[1], o[2] + m * r[2]) <= 1) hi = m;
                    else lo = m;
                }
                double th = hi, q[3] = {o[0] + th * r[0], o[1] + th * r[1], o[2] + th * r[2]};
                double h = 1e-5 * (d[0] + d[1] + d[2]);
                for (int k = 0; k < 3; k++) {
                    double qa[3] = {q[0], q[1], q[2]}, qb[3] = {q[0], q[1], q[2]};
                    qa[k] += h; qb[k] -= h;
                    n[k] = sq_g(d, qa[0], qa[1], qa[2]) - sq_g(d, qb[0], qb[1], qb[2]);
                }
                *tout = th;
                return 1;
            }
            tp = t;
        }
        return 0;
    }
    default: return 0;
    }
}

/* Nearest object hit along a world ray; any_hit: stop at the first hit. */
static int objects_hit(const tworld *w, const double o[3], const double r[3], double tmin, double tmax,
                       thit *h, int any_hit) {
    int found = 0;
    for (int i = 0; i < w->nobj; i++) {
        const tobj *ob = &w->objs[i];
        double oc[3] = {o[0] - ob->bc[0], o[1] - ob->bc[1], o[2] - ob->bc[2]};
        double b = sooc_v3_dot(oc, r), c = sooc_v3_dot(oc, oc) - ob->br * ob->br, disc = b * b - c;
        if (disc < 0) continue;
        double sq = sqrt(disc);
        if (-b + sq < tmin || -b - sq > tmax) continue;
        /* to the object frame: q = R_y(yaw)^T (p - (x, 0, z)) */
        double dx = o[0] - ob->x, dz = o[2] - ob->z;
        double ol[3] = {ob->cs * dx - ob->sn * dz, o[1], ob->sn * dx + ob->cs * dz};
        double rl[3] = {ob->cs * r[0] - ob->sn * r[2], r[1], ob->sn * r[0] + ob->cs * r[2]};
        for (int k = 0; k < ob->np; k++) {
            const tpart *p = &w->parts[ob->p0 + k];
            double op[3] = {ol[0] - p->c[0], ol[1] - p->c[1], ol[2] - p->c[2]}, t, nl[3];
            if (part_hit(p, op, rl, tmin, tmax, &t, nl)) {
                tmax = t;
                found = 1;
                if (h) {
                    h->t = t;
                    h->kind = 3;
                    h->obj = i;
                    /* normal back to world: R_y(yaw) nl */
                    h->n[0] = ob->cs * nl[0] + ob->sn * nl[2];
                    h->n[1] = nl[1];
                    h->n[2] = -ob->sn * nl[0] + ob->cs * nl[2];
                }
                if (any_hit) return 1;
            }
        }
    }
    return found;
}

/* A table top or a bin (gen.h, sooc_support_kind) as up to five boxes over a
 * ground plane. An upward face at y = 0 is the layout (kind 1); the other
 * faces are support sides (kind 5); the ground is kind 4. */
static void support_hit(const sooc_scene *sc, const double o[3], const double r[3], double *tmax, thit *h) {
    double W = sc->support_size[0] / 2, D = sc->support_size[1] / 2, th = sc->support_thick;
    double g = -sc->support_height, rim = sc->rim_height;
    double box[5][6];
    int nb = 0;
    if (sc->support == SOOC_SUPPORT_TABLE) {
        double b[6] = {-W, -th, -D, W, 0, D};
        memcpy(box[nb++], b, sizeof b);
    } else {
        double b0[6] = {-W - th, g, -D - th, W + th, 0, D + th};
        double b1[6] = {W, g, -D - th, W + th, rim, D + th}, b2[6] = {-W - th, g, -D - th, -W, rim, D + th};
        double b3[6] = {-W, g, D, W, rim, D + th}, b4[6] = {-W, g, -D - th, W, rim, -D};
        memcpy(box[nb++], b0, sizeof b0);
        memcpy(box[nb++], b1, sizeof b1);
        memcpy(box[nb++], b2, sizeof b2);
        memcpy(box[nb++], b3, sizeof b3);
        memcpy(box[nb++], b4, sizeof b4);
    }
    for (int i = 0; i < nb; i++) {
        double t0, t1;
        int ax;
        if (!slab(o, r, box[i], box[i] + 3, &t0, &t1, &ax)) continue;
        if (t0 <= 1e-9 || t0 >= *tmax) continue;
        *tmax = t0;
        h->t = t0;
        h->n[0] = h->n[1] = h->n[2] = 0;
        h->n[ax] = r[ax] > 0 ? -1 : 1;
        h->kind = (ax == 1 && r[1] < 0 && box[i][4] == 0) ? 1 : 5;
    }
    if (r[1] < -1e-12 && o[1] > g) {
        double t = (g - o[1]) / r[1];
        if (t < *tmax) {
            *tmax = t; h->t = t; h->kind = 4;
            h->n[0] = 0; h->n[1] = 1; h->n[2] = 0;
        }
    }
}

static void trace(const tworld *w, const double o[3], const double r[3], thit *h) {
    const sooc_scene *sc = w->sc;
    double tmax = 1e30;
    h->kind = 0;
    h->t = tmax;
    if (sc->support != SOOC_SUPPORT_FLOOR) {
        support_hit(sc, o, r, &tmax, h);
    } else if (r[1] < -1e-12 && o[1] > 0) {
        double t = -o[1] / r[1];
        if (t < tmax) {
            tmax = t; h->t = t; h->kind = 1;
            h->n[0] = 0; h->n[1] = 1; h->n[2] = 0;
        }
    }
    if (sc->walls) {
        double half = sc->room_size / 2, y0 = sc->support != SOOC_SUPPORT_FLOOR ? -sc->support_height : 0;
        for (int ax = 0; ax < 3; ax += 2)
            for (int s = -1; s <= 1; s += 2) {
                if (r[ax] * s <= 1e-12) continue;
                double t = (s * half - o[ax]) / r[ax];
                if (t <= 1e-9 || t >= tmax) continue;
                double y = o[1] + t * r[1], other = o[2 - ax] + t * r[2 - ax];
                if (y < y0 || y > y0 + sc->wall_height || fabs(other) > half) continue;
                tmax = t; h->t = t; h->kind = 2;
                h->n[0] = h->n[1] = h->n[2] = 0;
                h->n[ax] = -s;
            }
    }
    objects_hit(w, o, r, 1e-6, tmax, h, 0);
}

/* ------------------------------------------------------------ textures */

static double hash2(int64_t x, int64_t z, uint64_t seed) {
    uint64_t h = (uint64_t)x * 0x9E3779B97F4A7C15ull ^ (uint64_t)z * 0xC2B2AE3D27D4EB4Full ^ seed;
    h ^= h >> 31; h *= 0xBF58476D1CE4E5B9ull; h ^= h >> 29; h *= 0x94D049BB133111EBull; h ^= h >> 32;
    return (double)(h >> 11) * (1.0 / 9007199254740992.0);
}

static double vnoise(double x, double z, uint64_t seed) {
    double fx = floor(x), fz = floor(z), u = x - fx, v = z - fz;
    int64_t ix = (int64_t)fx, iz = (int64_t)fz;
    u = u * u * (3 - 2 * u);
    v = v * v * (3 - 2 * v);
    double a = hash2(ix, iz, seed), b = hash2(ix + 1, iz, seed), c = hash2(ix, iz + 1, seed),
           d = hash2(ix + 1, iz + 1, seed);
    return (a * (1 - u) + b * u) * (1 - v) + (c * (1 - u) + d * u) * v;
}

static void floor_albedo(const sooc_scene *sc, double x, double z, double out[3]) {
    double t = 0, s = sc->tex_scale > 0 ? sc->tex_scale : 0.5;
    uint64_t seed = sc->seed * 1315423911ull + (uint64_t)sc->index;
    switch (sc->floor_tex) {
    case SOOC_FLOOR_CHECKER: t = (((int64_t)floor(x / s) + (int64_t)floor(z / s)) & 1) ? 1 : 0; break;
    case SOOC_FLOOR_WOOD: {
        double pz = z / s, plank = floor(pz), u = pz - plank;
        double off = hash2((int64_t)plank, 7, seed) * 20;
        double g = 0.5 + 0.5 * sin(30 * (u + 0.15 * vnoise(x * 1.3 + off, plank * 3.7, seed)) + off);
        t = 0.65 * g * g + 0.35 * vnoise(x * 6 + off, z * 40, seed + 1);
        if (u < 0.03 || u > 0.97) t = 1;
        double seg = floor(x / (4 * s) + hash2((int64_t)plank, 3, seed));
        t = 0.85 * t + 0.15 * hash2((int64_t)plank, (int64_t)seg, seed + 2);
        break;
    }
    case SOOC_FLOOR_NOISE:
        t = 0.5 * vnoise(x / s, z / s, seed) + 0.3 * vnoise(2.1 * x / s, 2.1 * z / s, seed + 5) +
            0.2 * vnoise(4.3 * x / s, 4.3 * z / s, seed + 9);
        t = (t - 0.2) / 0.6;
        break;
    default: t = 0;
    }
    if (t < 0) t = 0;
    if (t > 1) t = 1;
    for (int k = 0; k < 3; k++) out[k] = sc->floor_color[k] * (1 - t) + sc->floor_color2[k] * t;
}

/* Procedural object texture (gen.h, sooc_obj_tex) at world point p. */
static void object_albedo(const tobj *ob, const double p[3], double out[3]) {
    const float *c = ob->col;
    int second = 0;
    double dark = 0;
    if (ob->tex != SOOC_TEX_PLAIN) {
        double dx = p[0] - ob->x, dz = p[2] - ob->z, s = ob->tex_scale > 1e-6 ? ob->tex_scale : 1e-6;
        double qx = ob->cs * dx - ob->sn * dz, qy = p[1], qz = ob->sn * dx + ob->cs * dz;
        if (ob->tex == SOOC_TEX_STRIPES) {
            second = ((int64_t)floor(qy / s)) & 1;
        } else if (ob->tex == SOOC_TEX_CHECKS) {
            second = ((int64_t)floor(qx / s) + (int64_t)floor(qy / s) + (int64_t)floor(qz / s)) & 1;
        } else {
            double y0 = 0.3 * ob->height, y1 = 0.75 * ob->height;
            if (qy >= y0 && qy <= y1) {
                second = 1;
                /* text-like dashes: rows 1, 3, 5 of 7, 24 cells around the axis */
                double fy = (qy - y0) / (y1 - y0) * 7, fu = (atan2(qz, qx) / (2 * M_PI) + 0.5) * 24;
                int row = (int)fy, cell = (int)fu;
                if ((row & 1) && fy - row > 0.2 && fy - row < 0.8 && fu - cell < 0.75 &&
                    hash2(row, cell, (uint64_t)ob->id * 77) < 0.6)
                    dark = 0.7;
            }
        }
    }
    const float *a = second ? ob->col2 : c;
    for (int k = 0; k < 3; k++) out[k] = a[k] * (1 - dark) + c[k] * dark * 0.4;
}

static uint8_t to8(double v) {
    if (!(v > 0)) return 0;
    if (v >= 1) return 255;
    return (uint8_t)lround(v * 255);
}

/* ------------------------------------------------------------ render */

void sooc_gen_intrinsics(sooc_intrinsics *K, int w, int h, double fov_deg) {
    memset(K, 0, sizeof *K);
    K->width = w;
    K->height = h;
    K->fx = K->fy = (w / 2.0) / tan(fov_deg * M_PI / 360.0);
    K->cx = w / 2.0;
    K->cy = h / 2.0;
    K->dist_model = SOOC_DIST_NONE;
}

static void render_pixel(const tworld *w, const double T[16], const sooc_intrinsics *K, int u, int v,
                         uint8_t rgb[3], float *depth, uint16_t *inst) {
    const sooc_scene *sc = w->sc;
    double dc[3];
    double dz = sooc_cam_ray(K, u, v, dc);
    double r[3] = {T[0] * dc[0] + T[1] * dc[1] + T[2] * dc[2], T[4] * dc[0] + T[5] * dc[1] + T[6] * dc[2],
                   T[8] * dc[0] + T[9] * dc[1] + T[10] * dc[2]};
    sooc_v3_normalize(r);
    double o[3] = {T[3], T[7], T[11]};
    thit h;
    trace(w, o, r, &h);
    double z = h.kind ? h.t * dz : 0;
    double col[3];
    if (!h.kind || z > sc->clip_depth) {
        double a = r[1] > 0 ? (r[1] < 0.5 ? r[1] * 2 : 1) : 0;
        for (int k = 0; k < 3; k++) col[k] = (0.92 - 0.1 * k) * (1 - a) + sc->sky_color[k] * a;
        *depth = 0;
        *inst = 0;
    } else {
        double p[3] = {o[0] + h.t * r[0], o[1] + h.t * r[1], o[2] + h.t * r[2]}, alb[3];
        double n[3] = {h.n[0], h.n[1], h.n[2]};
        sooc_v3_normalize(n);
        if (sooc_v3_dot(n, r) > 0) sooc_v3_scale(n, n, -1);
        *depth = (float)z;
        *inst = h.kind == 3 ? (uint16_t)w->objs[h.obj].id : 0;
        if (h.kind == 1) floor_albedo(sc, p[0], p[2], alb);
        else if (h.kind == 2) for (int k = 0; k < 3; k++) alb[k] = sc->wall_color[k];
        else if (h.kind == 4) for (int k = 0; k < 3; k++) alb[k] = sc->ground_color[k];
        else if (h.kind == 5) for (int k = 0; k < 3; k++) alb[k] = sc->support_color[k];
        else object_albedo(&w->objs[h.obj], p, alb);
        const double *L = sc->light_dir;
        double lam = sooc_v3_dot(n, L);
        double vis = lam > 0 ? 1 : 0;
        if (sc->shadows && lam > 0) {
            double ps[3] = {p[0] + 1e-6 * n[0], p[1] + 1e-6 * n[1], p[2] + 1e-6 * n[2]};
            if (objects_hit(w, ps, L, 1e-6, 1e30, NULL, 1)) vis = 0;
            if (vis > 0 && sc->support != SOOC_SUPPORT_FLOOR) { /* table tops and bin walls cast shadows too */
                thit sh;
                double tm = 1e30;
                sh.kind = 0;
                support_hit(sc, ps, L, &tm, &sh);
                if (sh.kind) vis = 0;
            }
        }
        double diff = sc->ambient + (1 - sc->ambient) * (lam > 0 ? lam : 0) * vis, spec = 0;
        if (sc->specular > 0 && vis > 0 && h.kind == 3) {
            double hv[3] = {L[0] - r[0], L[1] - r[1], L[2] - r[2]};
            sooc_v3_normalize(hv);
            double nh = sooc_v3_dot(n, hv);
            if (nh > 0) spec = sc->specular * pow(nh, sc->shininess);
        }
        for (int k = 0; k < 3; k++) col[k] = alb[k] * diff + spec;
    }
    for (int k = 0; k < 3; k++) rgb[k] = to8(col[k]);
}

sooc_status sooc_gen_render_view(const sooc_scene *sc, const double T_wc[16], const sooc_intrinsics *K,
                                 sooc_frame *f) {
    int W = K->width, H = K->height;
    if (W <= 0 || H <= 0 || !(K->fx != 0) || !(K->fy != 0))
        return sooc_seterr(SOOC_EINVAL, "render: bad intrinsics %dx%d", W, H);
    if (!f->rgb || f->width != W || f->height != H || !f->instance) {
        sooc_frame_free(f);
        sooc_status s = sooc_frame_alloc(f, W, H, 1);
        if (s) return s;
    }
    /* Cull objects against the view frustum (margin for shadows). */
    double margin = sc->shadows ? 2.0 : 0.05;
    double Rt[9], t[3];
    sooc_se3_to_rt(Rt, t, T_wc);
    double txl = K->cx / fabs(K->fx), txr = (W - K->cx) / fabs(K->fx);
    double tyt = K->cy / fabs(K->fy), tyb = (H - K->cy) / fabs(K->fy);
    double planes[4][3] = {{1, 0, -txr}, {-1, 0, -txl}, {0, 1, -tyb}, {0, -1, -tyt}};
    for (int i = 0; i < 4; i++) {
        double nn = sooc_v3_norm(planes[i]);
        sooc_v3_scale(planes[i], planes[i], 1 / nn);
    }
    tworld w = {sc, NULL, NULL, 0};
    int n = sc->n_objects, ncull = 0;
    /* pass 1: count objects in the (widened) frustum */
    for (int pass = 0; pass < 2; pass++) {
    if (pass == 1) {
        w.objs = sooc_malloc(sizeof(tobj) * (size_t)(ncull + 1));
        w.parts = sooc_malloc(sizeof(tpart) * (size_t)(ncull + 1) * SOOC_SCENE_MAX_PARTS);
        if (!w.objs || !w.parts) {
            sooc_free(w.objs);
            sooc_free(w.parts);
            return SOOC_ENOMEM;
        }
    }
    int np = 0;
    for (int i = 0; i < n; i++) {
        const sooc_scene_object *o = &sc->objects[i];
        double bc[3];
        sooc_scene_object_center(o, bc);
        double br = 0.5 * sqrt(o->size[0] * o->size[0] + o->size[1] * o->size[1] + o->size[2] * o->size[2]) + 1e-6;
        double dlt[3], pc[3];
        sooc_v3_sub(dlt, bc, t);
        sooc_m3_tmulv(pc, Rt, dlt);
        if (pc[2] < -br - margin || pc[2] - br > sc->clip_depth + margin) continue;
        int out = 0;
        for (int k = 0; k < 4 && !out; k++)
            if (sooc_v3_dot(planes[k], pc) > br + margin) out = 1;
        if (out) continue;
        if (pass == 0) { ncull++; continue; }
        tobj *ob = &w.objs[w.nobj++];
        ob->id = o->id;
        ob->x = o->x;
        ob->z = o->z;
        ob->cs = cos(o->yaw);
        ob->sn = sin(o->yaw);
        memcpy(ob->bc, bc, sizeof bc);
        ob->br = br;
        memcpy(ob->col, o->color, sizeof ob->col);
        memcpy(ob->col2, o->color2, sizeof ob->col2);
        ob->tex = o->tex;
        ob->tex_scale = o->tex_scale;
        ob->height = o->size[1];
        sooc_scene_part parts[SOOC_SCENE_MAX_PARTS];
        int k = sooc_scene_object_parts(o, parts, SOOC_SCENE_MAX_PARTS);
        ob->p0 = np;
        ob->np = k;
        for (int j = 0; j < k; j++) {
            tpart *tp = &w.parts[np++];
            tp->prim = parts[j].prim;
            memcpy(tp->c, parts[j].c, sizeof tp->c);
            memcpy(tp->d, parts[j].d, sizeof tp->d);
            part_aabb(tp);
        }
    }
    }
    int rows_parallel = 1;
#ifdef SOOC_HAVE_OPENMP
    rows_parallel = omp_get_level() == 0 && (int64_t)W * H >= 16384;
#endif
    (void)rows_parallel;
#ifdef SOOC_HAVE_OPENMP
#pragma omp parallel for schedule(dynamic, 4) if (rows_parallel)
#endif
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            size_t i = (size_t)v * (size_t)W + (size_t)u;
            render_pixel(&w, T_wc, K, u, v, f->rgb + 3 * i, f->depth + i, f->instance + i);
            f->valid[i] = f->depth[i] > 0;
        }
    sooc_free(w.objs);
    sooc_free(w.parts);
    memcpy(f->T_wc, T_wc, sizeof f->T_wc);
    f->has_pose = 1;
    f->K = *K;
    return SOOC_OK;
}
