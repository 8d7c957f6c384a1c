/* Synthetic scene description: object parts, analytic distances, PLY meshes,
 * and scene.yaml load/save (libyaml document API). */
#include "sooc3d/gen.h"
#include "data/yaml_doc.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *g_shape_names[SOOC_SHAPE_COUNT] = {
    "sphere", "box", "cylinder", "cone", "torus", "superquadric", "table", "chair", "shelf",
    "frustum", "cup", "bowl", "bottle", "can"};
static const int g_shape_nparams[SOOC_SHAPE_COUNT] = {1, 3, 2, 2, 2, 5, 5, 6, 5, 3, 4, 4, 4, 2};

const char *sooc_shape_name(sooc_shape s) {
    return (s >= 0 && s < SOOC_SHAPE_COUNT) ? g_shape_names[s] : "unknown";
}

sooc_status sooc_shape_parse(const char *name, sooc_shape *out) {
    for (int i = 0; i < SOOC_SHAPE_COUNT; i++)
        if (name && !strcmp(name, g_shape_names[i])) { *out = (sooc_shape)i; return SOOC_OK; }
    return sooc_seterr(SOOC_EINVAL, "unknown shape '%s'", name ? name : "");
}

void sooc_scene_init(sooc_scene *sc) {
    memset(sc, 0, sizeof *sc);
    snprintf(sc->preset, sizeof sc->preset, "unity");
    snprintf(sc->scale, sizeof sc->scale, "s");
    sc->room_size = 4;
    sc->clip_depth = 8;
    sc->wall_height = 0.5;
    sc->tex_scale = 0.5;
    sc->light_dir[1] = 1;
    sc->ambient = 0.35;
    sc->shininess = 32;
    sc->width = sc->height = 64;
    sc->fov_deg = 60;
}

void sooc_scene_free(sooc_scene *sc) {
    if (!sc) return;
    sooc_free(sc->objects);
    sooc_free(sc->view_is_query);
    sooc_free(sc->view_T_wc);
    sooc_scene_init(sc);
}

/* ---------------------------------------------------------------- parts */

static int add_box(sooc_scene_part *p, int n, int cap, double cx, double cy, double cz, double hx,
                   double hy, double hz) {
    if (n >= cap) return n;
    p[n].prim = SOOC_SHAPE_BOX;
    p[n].c[0] = cx; p[n].c[1] = cy; p[n].c[2] = cz;
    memset(p[n].d, 0, sizeof p[n].d);
    p[n].d[0] = hx; p[n].d[1] = hy; p[n].d[2] = hz;
    return n + 1;
}

static int add_part(sooc_scene_part *p, int n, int cap, sooc_shape prim, double cx, double cy, double cz,
                    double d0, double d1, double d2, double d3, double d4) {
    if (n >= cap) return n;
    p[n].prim = prim;
    p[n].c[0] = cx; p[n].c[1] = cy; p[n].c[2] = cz;
    p[n].d[0] = d0; p[n].d[1] = d1; p[n].d[2] = d2; p[n].d[3] = d3; p[n].d[4] = d4;
    return n + 1;
}

/* The cup's handle: a standing half torus on +x, its cut ends inside the
 * wall (centre half a wall thickness inside the outer surface at 55% of the
 * height). Shared with the generator's size computation. */
void sooc_scene_cup_handle(const double *q, double c[3], double *R, double *r) {
    double rt = q[0], rb = q[1], h = q[2], t = q[3], yc = 0.55 * h;
    *R = 0.28 * h;
    *r = fmax(0.05 * h, 0.003);
    c[0] = rb + (rt - rb) * 0.55 - t / 2;
    c[1] = yc;
    c[2] = 0;
}

int sooc_scene_object_parts(const sooc_scene_object *o, sooc_scene_part *p, int cap) {
    const double *q = o->params;
    int n = 0;
    if (cap <= 0) return 0;
    switch (o->shape) {
    case SOOC_SHAPE_SPHERE: case SOOC_SHAPE_BOX: case SOOC_SHAPE_CYLINDER: case SOOC_SHAPE_CONE:
    case SOOC_SHAPE_TORUS: case SOOC_SHAPE_SUPERQUADRIC: {
        memset(&p[0], 0, sizeof p[0]);
        p[0].prim = o->shape;
        memcpy(p[0].d, q, sizeof(double) * 5);
        double cy = o->shape == SOOC_SHAPE_SPHERE ? q[0]
                  : o->shape == SOOC_SHAPE_CONE ? 0.0
                  : o->shape == SOOC_SHAPE_TORUS ? q[1] : q[1];
        p[0].c[1] = cy;
        return 1;
    }
    case SOOC_SHAPE_TABLE: {
        double w = q[0], d = q[1], h = q[2], t = q[3], l = q[4];
        n = add_box(p, n, cap, 0, h - t / 2, 0, w / 2, t / 2, d / 2);
        for (int i = 0; i < 4; i++)
            n = add_box(p, n, cap, (i & 1 ? 1 : -1) * (w / 2 - l / 2), (h - t) / 2,
                        (i & 2 ? 1 : -1) * (d / 2 - l / 2), l / 2, (h - t) / 2, l / 2);
        return n;
    }
    case SOOC_SHAPE_CHAIR: {
        double w = q[0], d = q[1], hs = q[2], hb = q[3], t = q[4], l = q[5];
        n = add_box(p, n, cap, 0, hs - t / 2, 0, w / 2, t / 2, d / 2);
        for (int i = 0; i < 4; i++)
            n = add_box(p, n, cap, (i & 1 ? 1 : -1) * (w / 2 - l / 2), (hs - t) / 2,
                        (i & 2 ? 1 : -1) * (d / 2 - l / 2), l / 2, (hs - t) / 2, l / 2);
        n = add_box(p, n, cap, 0, hs + (hb - hs) / 2, -(d / 2 - t / 2), w / 2, (hb - hs) / 2, t / 2);
        return n;
    }
    case SOOC_SHAPE_SHELF: {
        double w = q[0], d = q[1], h = q[2], t = q[4];
        int nb = (int)q[3];
        if (nb < 2) nb = 2;
        if (nb > 8) nb = 8;
        n = add_box(p, n, cap, -(w / 2 - t / 2), h / 2, 0, t / 2, h / 2, d / 2);
        n = add_box(p, n, cap, (w / 2 - t / 2), h / 2, 0, t / 2, h / 2, d / 2);
        for (int i = 0; i < nb; i++)
            n = add_box(p, n, cap, 0, t / 2 + i * (h - t) / (nb - 1), 0, w / 2 - t, t / 2, d / 2);
        n = add_box(p, n, cap, 0, h / 2, -(d / 2 - t / 4), w / 2 - t, h / 2, t / 4);
        return n;
    }
    case SOOC_SHAPE_FRUSTUM:
        return add_part(p, 0, cap, SOOC_SHAPE_FRUSTUM, 0, 0, 0, q[0], q[1], q[2], 0, 0);
    case SOOC_SHAPE_CUP: {
        double c[3], R, r;
        sooc_scene_cup_handle(q, c, &R, &r);
        n = add_part(p, 0, cap, SOOC_SHAPE_FRUSTUM, 0, 0, 0, q[1], q[0], q[2], q[3], q[3]);
        return add_part(p, n, cap, SOOC_SHAPE_TORUS, c[0], c[1], c[2], R, r, 1, 1, 0);
    }
    case SOOC_SHAPE_BOWL:
        return add_part(p, 0, cap, SOOC_SHAPE_FRUSTUM, 0, 0, 0, q[1], q[0], q[2], q[3], q[3]);
    case SOOC_SHAPE_BOTTLE: {
        double r = q[0], h = q[1], rn = q[2], hn = q[3];
        double hc = 0.06 * h, hs = 0.16 * h, hb = h - hn - hs - hc;
        n = add_part(p, 0, cap, SOOC_SHAPE_CYLINDER, 0, hb / 2, 0, r, hb / 2, 0, 0, 0);
        n = add_part(p, n, cap, SOOC_SHAPE_FRUSTUM, 0, hb, 0, r, rn, hs, 0, 0);
        n = add_part(p, n, cap, SOOC_SHAPE_CYLINDER, 0, hb + hs + hn / 2, 0, rn, hn / 2, 0, 0, 0);
        return add_part(p, n, cap, SOOC_SHAPE_CYLINDER, 0, h - hc / 2, 0, 1.15 * rn, hc / 2, 0, 0, 0);
    }
    case SOOC_SHAPE_CAN: {
        double r = q[0], h = q[1], hr = 0.07 * h;
        n = add_part(p, 0, cap, SOOC_SHAPE_CYLINDER, 0, (h - hr) / 2, 0, r, (h - hr) / 2, 0, 0, 0);
        return add_part(p, n, cap, SOOC_SHAPE_FRUSTUM, 0, h - hr, 0, r, 0.88 * r, hr, 0, 0);
    }
    default: return 0;
    }
}

double sooc_scene_object_footprint(const sooc_scene_object *o) {
    return 0.5 * sqrt(o->size[0] * o->size[0] + o->size[2] * o->size[2]);
}

void sooc_scene_object_center(const sooc_scene_object *o, double c[3]) {
    c[0] = o->x;
    c[1] = o->size[1] / 2;
    c[2] = o->z;
}

/* world -> object frame: R_y(yaw)^T (p - (x, 0, z)) */
static void to_object(const sooc_scene_object *o, const double pw[3], double q[3]) {
    double dx = pw[0] - o->x, dz = pw[2] - o->z, c = cos(o->yaw), s = sin(o->yaw);
    q[0] = c * dx - s * dz;
    q[1] = pw[1];
    q[2] = s * dx + c * dz;
}

static double seg_dist2(double px, double py, double ax, double ay, double bx, double by) {
    double vx = bx - ax, vy = by - ay, wx = px - ax, wy = py - ay;
    double t = (vx * wx + vy * wy) / (vx * vx + vy * vy);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double ex = wx - t * vx, ey = wy - t * vy;
    return ex * ex + ey * ey;
}

static double sgnpow(double v, double e) { return v < 0 ? -pow(-v, e) : pow(v, e); }

/* Homogeneous (degree 1) superquadric gauge: 1 on the surface. */
static double sq_gauge(const double *d, const double q[3]) {
    double a = d[0], b = d[1], c = d[2], e1 = d[3], e2 = d[4];
    double xz = pow(fabs(q[0] / a), 2 / e2) + pow(fabs(q[2] / c), 2 / e2);
    double f = pow(xz, e2 / e1) + pow(fabs(q[1] / b), 2 / e1);
    return pow(f, e1 / 2);
}

static double part_distance(const sooc_scene_part *p, const double qo[3]) {
    double q[3] = {qo[0] - p->c[0], qo[1] - p->c[1], qo[2] - p->c[2]};
    const double *d = p->d;
    switch (p->prim) {
    case SOOC_SHAPE_SPHERE: return fabs(sooc_v3_norm(q) - d[0]);
    case SOOC_SHAPE_BOX: {
        double e[3], out = 0, in = -1e30;
        for (int k = 0; k < 3; k++) {
            e[k] = fabs(q[k]) - d[k];
            if (e[k] > 0) out += e[k] * e[k];
            if (e[k] > in) in = e[k];
        }
        return out > 0 ? sqrt(out) : fabs(in);
    }
    case SOOC_SHAPE_CYLINDER: {
        double rho = hypot(q[0], q[2]);
        double ex = rho - d[0], ey = fabs(q[1]) - d[1];
        if (ex > 0 || ey > 0) return hypot(ex > 0 ? ex : 0, ey > 0 ? ey : 0);
        return fabs(ex > ey ? ex : ey);
    }
    case SOOC_SHAPE_CONE: {
        double rho = hypot(q[0], q[2]);
        double d1 = seg_dist2(rho, q[1], 0, 0, d[0], 0), d2 = seg_dist2(rho, q[1], d[0], 0, 0, d[1]);
        return sqrt(d1 < d2 ? d1 : d2);
    }
    case SOOC_SHAPE_TORUS: {
        /* d[2] = 1: ring in the x-y plane (swap y and z); d[3] = 1: x >= 0 half */
        double a = q[0], b = d[2] > 0.5 ? q[2] : q[1], c = d[2] > 0.5 ? q[1] : q[2];
        if (d[3] > 0.5 && a < 0) {
            /* nearest point on one of the two cut discs at x = 0, centres (0, +-R) in the ring plane */
            double e1 = hypot(c - d[0], b), e2 = hypot(c + d[0], b);
            double e = fmax(fmin(e1, e2) - d[1], 0);
            return hypot(a, e);
        }
        return fabs(hypot(hypot(a, c) - d[0], b) - d[1]);
    }
    case SOOC_SHAPE_FRUSTUM: {
        /* distance to the profile polyline in the (rho, y) half plane */
        double rho = hypot(q[0], q[2]), y = q[1], rb = d[0], rt = d[1], h = d[2], t = d[3], b = d[4];
        double P[6][2] = {{0, 0}, {rb, 0}, {rt, h}, {0, h}};
        int np = 4;
        if (t > 0) {
            double k = (rt - rb) / h;
            P[3][0] = rt - t; P[3][1] = h;
            P[4][0] = rb - t + k * b; P[4][1] = b;
            P[5][0] = 0; P[5][1] = b;
            np = 6;
        }
        double best = 1e30;
        for (int i = 0; i + 1 < np; i++) {
            double e = seg_dist2(rho, y, P[i][0], P[i][1], P[i + 1][0], P[i + 1][1]);
            if (e < best) best = e;
        }
        return sqrt(best);
    }
    case SOOC_SHAPE_SUPERQUADRIC: {
        double g = sq_gauge(d, q), n = sooc_v3_norm(q);
        if (!(g > 0)) return fmin(fmin(d[0], d[1]), d[2]);
        return n * fabs(1 - 1 / g);
    }
    default: return 1e30;
    }
}

double sooc_scene_object_distance(const sooc_scene_object *o, const double pw[3]) {
    sooc_scene_part parts[SOOC_SCENE_MAX_PARTS];
    int np = sooc_scene_object_parts(o, parts, SOOC_SCENE_MAX_PARTS);
    double q[3], best = 1e30;
    to_object(o, pw, q);
    for (int i = 0; i < np; i++) {
        double dd = part_distance(&parts[i], q);
        if (dd < best) best = dd;
    }
    return best;
}

/* ---------------------------------------------------------------- meshes */

typedef struct mesh {
    float *v;        /* xyz */
    int32_t *f;      /* triangles */
    int nv, nf, capv, capf;
    int oom;
} mesh;

static int mesh_vert(mesh *m, double x, double y, double z) {
    if (m->nv == m->capv) {
        int cap = m->capv ? m->capv * 2 : 1024;
        float *nv = sooc_realloc(m->v, sizeof(float) * 3 * (size_t)cap);
        if (!nv) { m->oom = 1; return 0; }
        m->v = nv;
        m->capv = cap;
    }
    m->v[3 * m->nv] = (float)x; m->v[3 * m->nv + 1] = (float)y; m->v[3 * m->nv + 2] = (float)z;
    return m->nv++;
}

static void mesh_tri(mesh *m, int a, int b, int c) {
    if (m->oom) return;
    if (m->nf == m->capf) {
        int cap = m->capf ? m->capf * 2 : 2048;
        int32_t *nf = sooc_realloc(m->f, sizeof(int32_t) * 3 * (size_t)cap);
        if (!nf) { m->oom = 1; return; }
        m->f = nf;
        m->capf = cap;
    }
    m->f[3 * m->nf] = a; m->f[3 * m->nf + 1] = b; m->f[3 * m->nf + 2] = c;
    m->nf++;
}

/* Grid of (nu+1) x (nv+1) vertices from a parametric function; u wraps. */
typedef void (*param_fn)(const sooc_scene_part *p, double u, double v, double out[3]);

static void mesh_grid(mesh *m, const sooc_scene_part *p, param_fn fn, int nu, int nv,
                      const sooc_scene_object *o) {
    int base = m->nv;
    double c = cos(o->yaw), s = sin(o->yaw);
    for (int j = 0; j <= nv; j++)
        for (int i = 0; i < nu; i++) {
            double q[3];
            fn(p, (double)i / nu, (double)j / nv, q);
            q[0] += p->c[0]; q[1] += p->c[1]; q[2] += p->c[2];
            /* object -> world: R_y(yaw) q + (x, 0, z) */
            mesh_vert(m, c * q[0] + s * q[2] + o->x, q[1], -s * q[0] + c * q[2] + o->z);
        }
    for (int j = 0; j < nv; j++)
        for (int i = 0; i < nu; i++) {
            int a = base + j * nu + i, b = base + j * nu + (i + 1) % nu;
            int cc = a + nu, d = b + nu;
            mesh_tri(m, a, cc, b);
            mesh_tri(m, b, cc, d);
        }
}

static void pf_sphere(const sooc_scene_part *p, double u, double v, double o[3]) {
    double th = 2 * M_PI * u, ph = M_PI * (v - 0.5), r = p->d[0];
    o[0] = r * cos(ph) * cos(th); o[1] = r * sin(ph); o[2] = r * cos(ph) * sin(th);
}
static void pf_sq(const sooc_scene_part *p, double u, double v, double o[3]) {
    double th = 2 * M_PI * u - M_PI, ph = M_PI * (v - 0.5);
    const double *d = p->d;
    double cp = sgnpow(cos(ph), d[3]);
    o[0] = d[0] * cp * sgnpow(cos(th), d[4]);
    o[1] = d[1] * sgnpow(sin(ph), d[3]);
    o[2] = d[2] * cp * sgnpow(sin(th), d[4]);
}
static void pf_torus(const sooc_scene_part *p, double u, double v, double o[3]) {
    /* half tori (d[3]) sweep theta over [-pi/2, pi/2] (x >= 0); standing ones (d[2]) swap y and z */
    double th = p->d[3] > 0.5 ? M_PI * (u - 0.5) : 2 * M_PI * u, ph = 2 * M_PI * v, R = p->d[0], r = p->d[1];
    double a = (R + r * cos(ph)) * cos(th), b = r * sin(ph), c = (R + r * cos(ph)) * sin(th);
    o[0] = a; o[1] = p->d[2] > 0.5 ? c : b; o[2] = p->d[2] > 0.5 ? b : c;
}
/* Lathe profiles: v in [0,1] walks a polyline (rho, y) from the axis and back. */
static void lathe(double rho, double y, double u, double o[3]) {
    double th = 2 * M_PI * u;
    o[0] = rho * cos(th); o[1] = y; o[2] = rho * sin(th);
}
static void pf_cyl(const sooc_scene_part *p, double u, double v, double o[3]) {
    double r = p->d[0], h = p->d[1];
    /* 3 segments: bottom cap, side, top cap */
    double s = v * 3;
    if (s < 1) lathe(r * s, -h, u, o);
    else if (s < 2) lathe(r, -h + 2 * h * (s - 1), u, o);
    else lathe(r * (3 - s), h, u, o);
}
static void pf_cone(const sooc_scene_part *p, double u, double v, double o[3]) {
    double r = p->d[0], h = p->d[1], s = v * 2;
    if (s < 1) lathe(r * s, 0, u, o);
    else lathe(r * (2 - s), h * (s - 1), u, o);
}

/* Frustum profile: bottom, outer side, top (solid) or rim, inner side, inner
 * bottom (vessel); v walks the segments, one per grid row. */
static void pf_frustum(const sooc_scene_part *p, double u, double v, double o[3]) {
    double rb = p->d[0], rt = p->d[1], h = p->d[2], t = p->d[3], b = p->d[4];
    double P[6][2] = {{0, 0}, {rb, 0}, {rt, h}, {0, h}};
    int ns = 3;
    if (t > 0) {
        double k = (rt - rb) / h;
        P[3][0] = rt - t; P[3][1] = h;
        P[4][0] = rb - t + k * b; P[4][1] = b;
        P[5][0] = 0; P[5][1] = b;
        ns = 5;
    }
    double s = v * ns;
    int i = (int)s;
    if (i >= ns) i = ns - 1;
    double f = s - i;
    lathe(P[i][0] + f * (P[i + 1][0] - P[i][0]), P[i][1] + f * (P[i + 1][1] - P[i][1]), u, o);
}

static void mesh_box(mesh *m, const sooc_scene_part *p, const sooc_scene_object *o) {
    double c = cos(o->yaw), s = sin(o->yaw);
    int base = m->nv;
    for (int k = 0; k < 8; k++) {
        double q[3] = {p->c[0] + (k & 1 ? 1 : -1) * p->d[0], p->c[1] + (k & 2 ? 1 : -1) * p->d[1],
                       p->c[2] + (k & 4 ? 1 : -1) * p->d[2]};
        mesh_vert(m, c * q[0] + s * q[2] + o->x, q[1], -s * q[0] + c * q[2] + o->z);
    }
    static const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                     {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int f = 0; f < 6; f++) {
        mesh_tri(m, base + quads[f][0], base + quads[f][1], base + quads[f][2]);
        mesh_tri(m, base + quads[f][0], base + quads[f][2], base + quads[f][3]);
    }
}

static sooc_status write_ply(const char *path, const mesh *m, const float col[3]) {
    char hdr[512];
    int hl = snprintf(hdr, sizeof hdr,
                      "ply\nformat binary_little_endian 1.0\ncomment sooc3d synthetic object, world "
                      "coordinates (m), y up\nelement vertex %d\nproperty float x\nproperty float "
                      "y\nproperty float z\nproperty uchar red\nproperty uchar green\nproperty uchar "
                      "blue\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n",
                      m->nv, m->nf);
    size_t n = (size_t)hl + (size_t)m->nv * 15 + (size_t)m->nf * 13;
    unsigned char *b = sooc_malloc(n), *w = b;
    if (!b) return SOOC_ENOMEM;
    memcpy(w, hdr, (size_t)hl);
    w += hl;
    unsigned char rgb[3];
    for (int k = 0; k < 3; k++) rgb[k] = (unsigned char)lround(fmin(fmax(col[k], 0), 1) * 255);
    /* little-endian output (x86/ARM hosts are little-endian; byte-swap otherwise) */
    const uint16_t one = 1;
    int le = *(const uint8_t *)&one == 1;
    for (int i = 0; i < m->nv; i++) {
        for (int k = 0; k < 3; k++) {
            uint32_t u;
            memcpy(&u, &m->v[3 * i + k], 4);
            if (!le) u = __builtin_bswap32(u);
            memcpy(w, &u, 4);
            w += 4;
        }
        memcpy(w, rgb, 3);
        w += 3;
    }
    for (int i = 0; i < m->nf; i++) {
        *w++ = 3;
        for (int k = 0; k < 3; k++) {
            uint32_t u = (uint32_t)m->f[3 * i + k];
            if (!le) u = __builtin_bswap32(u);
            memcpy(w, &u, 4);
            w += 4;
        }
    }
    sooc_status s = sooc_file_write_bulk(path, b, n);
    sooc_free(b);
    return s;
}

sooc_status sooc_scene_write_meshes(const char *dir, const sooc_scene *sc) {
    sooc_status s = sooc_mkdirs(dir);
    if (s) return s;
    mesh m = {0};
    for (int i = 0; i < sc->n_objects && !s; i++) {
        const sooc_scene_object *o = &sc->objects[i];
        sooc_scene_part parts[SOOC_SCENE_MAX_PARTS];
        int np = sooc_scene_object_parts(o, parts, SOOC_SCENE_MAX_PARTS);
        m.nv = m.nf = 0;
        for (int k = 0; k < np; k++) {
            switch (parts[k].prim) {
            case SOOC_SHAPE_SPHERE: mesh_grid(&m, &parts[k], pf_sphere, 24, 12, o); break;
            case SOOC_SHAPE_SUPERQUADRIC: mesh_grid(&m, &parts[k], pf_sq, 32, 16, o); break;
            case SOOC_SHAPE_TORUS: mesh_grid(&m, &parts[k], pf_torus, 32, 16, o); break;
            case SOOC_SHAPE_CYLINDER: mesh_grid(&m, &parts[k], pf_cyl, 24, 3, o); break;
            case SOOC_SHAPE_CONE: mesh_grid(&m, &parts[k], pf_cone, 24, 2, o); break;
            case SOOC_SHAPE_FRUSTUM: mesh_grid(&m, &parts[k], pf_frustum, 24, parts[k].d[3] > 0 ? 5 : 3, o); break;
            default: mesh_box(&m, &parts[k], o); break;
            }
        }
        if (m.oom) { s = SOOC_ENOMEM; break; }
        char name[64], path[4096];
        snprintf(name, sizeof name, "object_%04d.ply", o->id);
        s = sooc_path_join(path, sizeof path, dir, name);
        if (!s) s = write_ply(path, &m, o->color);
    }
    sooc_free(m.v);
    sooc_free(m.f);
    return s;
}

/* ------------------------------------------------------------ scene.yaml */

static const char *g_tex_names[] = {"uniform", "checker", "wood", "noise"};
static const char *g_support_names[] = {"floor", "table", "bin"};
static const char *g_otex_names[] = {"plain", "stripes", "checks", "label"};

static void sb_f3(sooc_strbuf *b, const char *key, const float v[3]) {
    sooc_strbuf_printf(b, "%s: [%.6g, %.6g, %.6g]\n", key, v[0], v[1], v[2]);
}

sooc_status sooc_scene_save(const char *path, const sooc_scene *sc) {
    sooc_strbuf b = {0};
    sooc_strbuf_printf(&b, "%%YAML 1.2\n---\n# sooc3d synthetic scene (docs/formats.md). World: +y up, floor y = 0,\n"
                  "# room = [-room_size/2, room_size/2]^2; object pose = floor (x, z, yaw about +y).\n");
    sooc_strbuf_printf(&b, "format: sooc3d-scene\nversion: 1\npreset: %s\nscale: %s\nseed: %llu\nindex: %d\n",
              sc->preset, sc->scale, (unsigned long long)sc->seed, sc->index);
    sooc_strbuf_printf(&b, "room_size: %.12g\nclip_depth: %.12g\nwalls: %s\nwall_height: %.12g\n", sc->room_size,
              sc->clip_depth, sc->walls ? "true" : "false", sc->wall_height);
    sb_f3(&b, "wall_color", sc->wall_color);
    sooc_strbuf_printf(&b, "floor_texture: %s\n", g_tex_names[sc->floor_tex]);
    sb_f3(&b, "floor_color", sc->floor_color);
    sb_f3(&b, "floor_color2", sc->floor_color2);
    sooc_strbuf_printf(&b, "texture_scale: %.12g\n", sc->tex_scale);
    if (sc->support != SOOC_SUPPORT_FLOOR) {
        sooc_strbuf_printf(&b, "support: %s\nsupport_size: [%.12g, %.12g]\nsupport_height: %.12g\n"
                      "support_thickness: %.12g\nrim_height: %.12g\n", g_support_names[sc->support],
                  sc->support_size[0], sc->support_size[1], sc->support_height, sc->support_thick, sc->rim_height);
        sb_f3(&b, "support_color", sc->support_color);
        sb_f3(&b, "ground_color", sc->ground_color);
    }
    if (sc->sensor_noise[0]) sooc_strbuf_printf(&b, "sensor_noise: %s\n", sc->sensor_noise);
    sb_f3(&b, "sky_color", sc->sky_color);
    sooc_strbuf_printf(&b, "light_dir: [%.12g, %.12g, %.12g]\nambient: %.12g\nshadows: %s\nspecular: %.12g\nshininess: %.12g\n",
              sc->light_dir[0], sc->light_dir[1], sc->light_dir[2], sc->ambient,
              sc->shadows ? "true" : "false", sc->specular, sc->shininess);
    sooc_strbuf_printf(&b, "width: %d\nheight: %d\nfov_deg: %.12g\n", sc->width, sc->height, sc->fov_deg);
    for (int pass = 0; pass < 2; pass++) {
        sooc_strbuf_printf(&b, "%s: [", pass ? "query_views" : "input_views");
        int first = 1;
        for (int i = 0; i < sc->n_views; i++)
            if ((sc->view_is_query && sc->view_is_query[i]) == pass) {
                sooc_strbuf_printf(&b, first ? "%d" : ", %d", i);
                first = 0;
            }
        sooc_strbuf_printf(&b, "]\n");
    }
    sooc_strbuf_printf(&b, "objects:%s\n", sc->n_objects ? "" : " []");
    for (int i = 0; i < sc->n_objects; i++) {
        const sooc_scene_object *o = &sc->objects[i];
        sooc_strbuf_printf(&b, "  - {id: %d, shape: %s, x: %.12g, z: %.12g, yaw: %.12g, size: [%.12g, %.12g, %.12g], params: [",
                  o->id, sooc_shape_name(o->shape), o->x, o->z, o->yaw, o->size[0], o->size[1], o->size[2]);
        for (int k = 0; k < g_shape_nparams[o->shape]; k++) sooc_strbuf_printf(&b, k ? ", %.12g" : "%.12g", o->params[k]);
        sooc_strbuf_printf(&b, "], color: [%.6g, %.6g, %.6g]", o->color[0], o->color[1], o->color[2]);
        if (o->tex != SOOC_TEX_PLAIN)
            sooc_strbuf_printf(&b, ", texture: %s, color2: [%.6g, %.6g, %.6g], texture_scale: %.12g", g_otex_names[o->tex],
                      o->color2[0], o->color2[1], o->color2[2], o->tex_scale);
        sooc_strbuf_printf(&b, "}\n");
    }
    if (b.oom) { sooc_free(b.p); return SOOC_ENOMEM; }
    sooc_status s = sooc_file_write_bulk(path, b.p, b.n);
    sooc_free(b.p);
    return s;
}


static sooc_status ynum(sooc_ydoc *c, const yaml_node_t *n, const char *key, double *out) {
    const char *s = sooc_yscalar(n);
    char *end = NULL;
    double v = s ? strtod(s, &end) : 0;
    if (!s || end == s || *end || !isfinite(v))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a finite number", c->name, sooc_yline(n), key);
    *out = v;
    return SOOC_OK;
}

static sooc_status yint(sooc_ydoc *c, const yaml_node_t *n, const char *key, double lo, double hi,
                        long long *out) {
    double v = 0;
    sooc_status s = ynum(c, n, key, &v);
    if (s) return s;
    if (v != floor(v) || v < lo || v > hi)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected an integer in [%.0f, %.0f]", c->name,
                           sooc_yline(n), key, lo, hi);
    *out = (long long)v;
    return SOOC_OK;
}

static sooc_status ybool(sooc_ydoc *c, const yaml_node_t *n, const char *key, int *out) {
    const char *s = sooc_yscalar(n);
    if (s && !strcmp(s, "true")) { *out = 1; return SOOC_OK; }
    if (s && !strcmp(s, "false")) { *out = 0; return SOOC_OK; }
    return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected true or false", c->name, sooc_yline(n), key);
}

/* A flow list of numbers; *count is set; more than cap is an error. If
 * exact >= 0 the list must have exactly that many items. */
static sooc_status ylist(sooc_ydoc *c, const yaml_node_t *n, const char *key, double *out, int cap,
                         int exact, int *count) {
    if (!n || n->type != YAML_SEQUENCE_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a list", c->name, n ? sooc_yline(n) : 0, key);
    int k = sooc_yseq_len(n);
    if ((exact >= 0 && k != exact) || k > cap)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected %d numbers, got %d", c->name, sooc_yline(n), key,
                           exact >= 0 ? exact : cap, k);
    for (int i = 0; i < k; i++) {
        sooc_status s = ynum(c, sooc_yseq_item(c, n, i), key, &out[i]);
        if (s) return s;
    }
    if (count) *count = k;
    return SOOC_OK;
}

static sooc_status yf3(sooc_ydoc *c, const yaml_node_t *n, const char *key, float out[3]) {
    double v[3];
    sooc_status s = ylist(c, n, key, v, 3, 3, NULL);
    if (s) return s;
    for (int k = 0; k < 3; k++) out[k] = (float)v[k];
    return SOOC_OK;
}

static sooc_status parse_object(sooc_ydoc *c, yaml_node_t *n, sooc_scene_object *o) {
    if (n->type != YAML_MAPPING_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: objects: each item must be a mapping", c->name, sooc_yline(n));
    memset(o, 0, sizeof *o);
    unsigned seen = 0;
    int nparams = 0;
    yaml_node_t *params_node = NULL;
    for (yaml_node_pair_t *p = n->data.mapping.pairs.start; p < n->data.mapping.pairs.top; p++) {
        sooc_ypair pr;
        sooc_status s = sooc_ymap_pair(c, n, p, "objects", 1, &pr);
        if (s) return s;
        yaml_node_t *k = pr.k, *v = pr.v;
        const char *ks = pr.key;
        long long iv = 0;
        if (!strcmp(ks, "id")) { s = yint(c, v, "objects.id", 1, 65535, &iv); o->id = (int)iv; seen |= 1; }
        else if (!strcmp(ks, "shape")) {
            s = sooc_shape_parse(sooc_yscalar(v), &o->shape);
            if (s) s = sooc_seterr(SOOC_EINVAL, "%s:%d: objects.shape: unknown shape '%s'", c->name, sooc_yline(v),
                                   sooc_yscalar(v) ? sooc_yscalar(v) : "?");
            seen |= 2;
        } else if (!strcmp(ks, "x")) { s = ynum(c, v, "objects.x", &o->x); seen |= 4; }
        else if (!strcmp(ks, "z")) { s = ynum(c, v, "objects.z", &o->z); seen |= 8; }
        else if (!strcmp(ks, "yaw")) { s = ynum(c, v, "objects.yaw", &o->yaw); seen |= 16; }
        else if (!strcmp(ks, "size")) { s = ylist(c, v, "objects.size", o->size, 3, 3, NULL); seen |= 32; }
        else if (!strcmp(ks, "params")) { params_node = v; s = ylist(c, v, "objects.params", o->params, 6, -1, &nparams); seen |= 64; }
        else if (!strcmp(ks, "color")) { s = yf3(c, v, "objects.color", o->color); seen |= 128; }
        else if (!strcmp(ks, "texture")) {
            const char *ts = sooc_yscalar(v);
            int f = -1;
            for (int i = 0; i < 4; i++) if (ts && !strcmp(ts, g_otex_names[i])) f = i;
            if (f < 0) s = sooc_seterr(SOOC_EINVAL, "%s:%d: objects.texture: expected plain, stripes, checks or label", c->name, sooc_yline(v));
            else o->tex = (sooc_obj_tex)f;
        } else if (!strcmp(ks, "color2")) s = yf3(c, v, "objects.color2", o->color2);
        else if (!strcmp(ks, "texture_scale")) {
            s = ynum(c, v, "objects.texture_scale", &o->tex_scale);
            if (!s && !(o->tex_scale > 0)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: objects.texture_scale: must be > 0", c->name, sooc_yline(v));
        }
        else s = sooc_seterr(SOOC_EINVAL, "%s:%d: objects: unknown key '%s'", c->name, sooc_yline(k), ks);
        if (s) return s;
    }
    static const char *names[] = {"id", "shape", "x", "z", "yaw", "size", "params", "color"};
    for (int i = 0; i < 8; i++)
        if (!(seen & (1u << i)))
            return sooc_seterr(SOOC_EINVAL, "%s:%d: objects.%s: missing", c->name, sooc_yline(n), names[i]);
    if (nparams != g_shape_nparams[o->shape])
        return sooc_seterr(SOOC_EINVAL, "%s:%d: objects.params: shape %s needs %d params, got %d", c->name,
                           sooc_yline(params_node), sooc_shape_name(o->shape), g_shape_nparams[o->shape], nparams);
    if (o->tex != SOOC_TEX_PLAIN && !(o->tex_scale > 0))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: objects.texture_scale: missing (needed by texture %s)", c->name,
                           sooc_yline(n), g_otex_names[o->tex]);
    for (int i = 0; i < nparams; i++)
        if (!(o->params[i] > 0))
            return sooc_seterr(SOOC_EINVAL, "%s:%d: objects.params: values must be > 0", c->name, sooc_yline(params_node));
    return SOOC_OK;
}

static sooc_status parse_views(sooc_ydoc *c, yaml_node_t *v, const char *key, int **out, int *n) {
    if (v->type != YAML_SEQUENCE_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a list of view indices", c->name, sooc_yline(v), key);
    int k = sooc_yseq_len(v);
    sooc_free(*out); /* duplicate keys are rejected before this; never leak a previous list */
    *out = sooc_malloc(sizeof(int) * (size_t)(k + 1));
    if (!*out) return SOOC_ENOMEM;
    for (int i = 0; i < k; i++) {
        long long iv = 0;
        sooc_status s = yint(c, sooc_yseq_item(c, v, i), key, 0, 1e7, &iv);
        if (s) return s;
        (*out)[i] = (int)iv;
    }
    *n = k;
    return SOOC_OK;
}

static sooc_status parse_scene(sooc_ydoc *c, sooc_scene *sc) {
    yaml_node_t *root = sooc_ydoc_root(c);
    if (!root || root->type != YAML_MAPPING_NODE)
        return sooc_seterr(SOOC_EFORMAT, "%s:1: top level must be a mapping", c->name);
    int *iv_in = NULL, *iv_q = NULL, n_in = 0, n_q = 0, have_in = 0, have_q = 0, have_fmt = 0;
    sooc_status s = SOOC_OK;
    for (yaml_node_pair_t *p = root->data.mapping.pairs.start; p < root->data.mapping.pairs.top && !s; p++) {
        sooc_ypair pr;
        s = sooc_ymap_pair(c, root, p, NULL, 1, &pr);
        if (s) break;
        yaml_node_t *k = pr.k, *v = pr.v;
        const char *ks = pr.key, *vs = sooc_yscalar(v);
        long long iv = 0;
        double dv[3];
        if (!strcmp(ks, "format")) {
            have_fmt = 1;
            if (!vs || strcmp(vs, "sooc3d-scene"))
                s = sooc_seterr(SOOC_EFORMAT, "%s:%d: format: expected sooc3d-scene", c->name, sooc_yline(v));
        } else if (!strcmp(ks, "version")) {
            s = yint(c, v, ks, 0, 1e6, &iv);
            if (!s && iv != 1)
                s = sooc_seterr(SOOC_EVERSION, "%s:%d: version: %lld is not supported (this build reads 1)", c->name, sooc_yline(v), iv);
        } else if (!strcmp(ks, "preset")) {
            if (!vs || (strcmp(vs, "unity") && strcmp(vs, "blender") && strcmp(vs, "tabletop")))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: preset: expected unity, blender or tabletop", c->name, sooc_yline(v));
            else snprintf(sc->preset, sizeof sc->preset, "%s", vs);
        } else if (!strcmp(ks, "scale")) {
            if (!vs || (strcmp(vs, "s") && strcmp(vs, "m") && strcmp(vs, "l") && strcmp(vs, "xl")))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: scale: expected s, m, l or xl", c->name, sooc_yline(v));
            else snprintf(sc->scale, sizeof sc->scale, "%s", vs);
        } else if (!strcmp(ks, "seed")) {
            char *end = NULL;
            unsigned long long u = vs ? strtoull(vs, &end, 10) : 0;
            if (!vs || end == vs || *end) s = sooc_seterr(SOOC_EINVAL, "%s:%d: seed: expected an integer", c->name, sooc_yline(v));
            sc->seed = u;
        } else if (!strcmp(ks, "index")) { s = yint(c, v, ks, 0, 1e9, &iv); sc->index = (int)iv; }
        else if (!strcmp(ks, "room_size")) { s = ynum(c, v, ks, &sc->room_size);
            if (!s && !(sc->room_size > 0)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: room_size: must be > 0", c->name, sooc_yline(v)); }
        else if (!strcmp(ks, "clip_depth")) { s = ynum(c, v, ks, &sc->clip_depth);
            if (!s && !(sc->clip_depth > 0)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: clip_depth: must be > 0", c->name, sooc_yline(v)); }
        else if (!strcmp(ks, "walls")) s = ybool(c, v, ks, &sc->walls);
        else if (!strcmp(ks, "wall_height")) s = ynum(c, v, ks, &sc->wall_height);
        else if (!strcmp(ks, "wall_color")) s = yf3(c, v, ks, sc->wall_color);
        else if (!strcmp(ks, "floor_texture")) {
            int f = -1;
            for (int i = 0; i < 4; i++) if (vs && !strcmp(vs, g_tex_names[i])) f = i;
            if (f < 0) s = sooc_seterr(SOOC_EINVAL, "%s:%d: floor_texture: expected uniform, checker, wood or noise", c->name, sooc_yline(v));
            else sc->floor_tex = (sooc_floor_tex)f;
        } else if (!strcmp(ks, "floor_color")) s = yf3(c, v, ks, sc->floor_color);
        else if (!strcmp(ks, "floor_color2")) s = yf3(c, v, ks, sc->floor_color2);
        else if (!strcmp(ks, "texture_scale")) s = ynum(c, v, ks, &sc->tex_scale);
        else if (!strcmp(ks, "support")) {
            int f = -1;
            for (int i = 0; i < 3; i++) if (vs && !strcmp(vs, g_support_names[i])) f = i;
            if (f < 0) s = sooc_seterr(SOOC_EINVAL, "%s:%d: support: expected floor, table or bin", c->name, sooc_yline(v));
            else sc->support = (sooc_support_kind)f;
        } else if (!strcmp(ks, "support_size")) {
            s = ylist(c, v, ks, dv, 2, 2, NULL);
            if (!s && !(dv[0] > 0 && dv[1] > 0)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: support_size: must be > 0", c->name, sooc_yline(v));
            sc->support_size[0] = dv[0]; sc->support_size[1] = dv[1];
        } else if (!strcmp(ks, "support_height")) { s = ynum(c, v, ks, &sc->support_height);
            if (!s && !(sc->support_height >= 0)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: support_height: must be >= 0", c->name, sooc_yline(v)); }
        else if (!strcmp(ks, "support_thickness")) { s = ynum(c, v, ks, &sc->support_thick);
            if (!s && !(sc->support_thick >= 0)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: support_thickness: must be >= 0", c->name, sooc_yline(v)); }
        else if (!strcmp(ks, "rim_height")) { s = ynum(c, v, ks, &sc->rim_height);
            if (!s && !(sc->rim_height >= 0)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: rim_height: must be >= 0", c->name, sooc_yline(v)); }
        else if (!strcmp(ks, "support_color")) s = yf3(c, v, ks, sc->support_color);
        else if (!strcmp(ks, "ground_color")) s = yf3(c, v, ks, sc->ground_color);
        else if (!strcmp(ks, "sensor_noise")) {
            if (!vs || (strcmp(vs, "none") && strcmp(vs, "kinect")))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: sensor_noise: expected none or kinect", c->name, sooc_yline(v));
            else snprintf(sc->sensor_noise, sizeof sc->sensor_noise, "%s", strcmp(vs, "none") ? vs : "");
        } else if (!strcmp(ks, "sky_color")) s = yf3(c, v, ks, sc->sky_color);
        else if (!strcmp(ks, "light_dir")) {
            s = ylist(c, v, ks, dv, 3, 3, NULL);
            if (!s && sooc_v3_normalize(dv) == 0) s = sooc_seterr(SOOC_EINVAL, "%s:%d: light_dir: zero vector", c->name, sooc_yline(v));
            memcpy(sc->light_dir, dv, sizeof dv);
        } else if (!strcmp(ks, "ambient")) s = ynum(c, v, ks, &sc->ambient);
        else if (!strcmp(ks, "shadows")) s = ybool(c, v, ks, &sc->shadows);
        else if (!strcmp(ks, "specular")) s = ynum(c, v, ks, &sc->specular);
        else if (!strcmp(ks, "shininess")) s = ynum(c, v, ks, &sc->shininess);
        else if (!strcmp(ks, "width")) { s = yint(c, v, ks, 1, 32768, &iv); sc->width = (int)iv; }
        else if (!strcmp(ks, "height")) { s = yint(c, v, ks, 1, 32768, &iv); sc->height = (int)iv; }
        else if (!strcmp(ks, "fov_deg")) { s = ynum(c, v, ks, &sc->fov_deg);
            if (!s && !(sc->fov_deg > 1 && sc->fov_deg < 179)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: fov_deg: out of range", c->name, sooc_yline(v)); }
        else if (!strcmp(ks, "input_views")) { s = parse_views(c, v, ks, &iv_in, &n_in); have_in = 1; }
        else if (!strcmp(ks, "query_views")) { s = parse_views(c, v, ks, &iv_q, &n_q); have_q = 1; }
        else if (!strcmp(ks, "objects")) {
            if (v->type != YAML_SEQUENCE_NODE) { s = sooc_seterr(SOOC_EINVAL, "%s:%d: objects: expected a list", c->name, sooc_yline(v)); break; }
            int k2 = sooc_yseq_len(v);
            sooc_free(sc->objects);
            sc->objects = sooc_calloc((size_t)(k2 + 1), sizeof *sc->objects);
            if (!sc->objects) { s = SOOC_ENOMEM; break; }
            sc->n_objects = k2;
            for (int i = 0; i < k2 && !s; i++) {
                yaml_node_t *it = sooc_yseq_item(c, v, i);
                s = parse_object(c, it, &sc->objects[i]);
                for (int j = 0; j < i && !s; j++)
                    if (sc->objects[j].id == sc->objects[i].id)
                        s = sooc_seterr(SOOC_EINVAL, "%s:%d: objects.id: duplicate id %d", c->name, sooc_yline(it), sc->objects[i].id);
            }
        } else s = sooc_seterr(SOOC_EINVAL, "%s:%d: unknown key '%s'", c->name, sooc_yline(k), ks);
    }
    if (!s && sc->support != SOOC_SUPPORT_FLOOR && !(sc->support_size[0] > 0 && sc->support_size[1] > 0))
        s = sooc_seterr(SOOC_EINVAL, "%s:%d: support_size: missing (needed by support %s)", c->name, sooc_yline(root),
                        g_support_names[sc->support]);
    if (!s && !have_fmt) s = sooc_seterr(SOOC_EFORMAT, "%s:%d: format: missing (expected sooc3d-scene)", c->name, sooc_yline(root));
    if (!s && (!have_in || !have_q))
        s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: missing", c->name, sooc_yline(root), have_in ? "query_views" : "input_views");
    if (!s) {
        sc->n_views = n_in + n_q;
        sc->view_is_query = sooc_calloc((size_t)sc->n_views + 1, 1);
        uint8_t *seen = sooc_calloc((size_t)sc->n_views + 1, 1);
        if (!sc->view_is_query || !seen) s = SOOC_ENOMEM;
        for (int i = 0; i < n_in + n_q && !s; i++) {
            int vi = i < n_in ? iv_in[i] : iv_q[i - n_in];
            if (vi >= sc->n_views || seen[vi])
                s = sooc_seterr(SOOC_EINVAL, "%s: input_views/query_views: view %d is out of range or listed twice "
                                "(the lists must partition 0..%d)", c->name, vi, sc->n_views - 1);
            else { seen[vi] = 1; sc->view_is_query[vi] = i >= n_in; }
        }
        sooc_free(seen);
    }
    sooc_free(iv_in);
    sooc_free(iv_q);
    return s;
}

sooc_status sooc_scene_load(const char *path, sooc_scene *out) {
    void *buf;
    size_t n;
    sooc_status s = sooc_file_read_all(path, (size_t)64 << 20, &buf, &n);
    if (s) return s;
    sooc_ydoc d;
    s = sooc_ydoc_parse(&d, buf, n, path);
    sooc_free(buf);
    if (s) return s;
    sooc_scene sc;
    sooc_scene_init(&sc);
    s = parse_scene(&d, &sc);
    sooc_ydoc_free(&d);
    if (s) { sooc_scene_free(&sc); return s; }
    sooc_scene_free(out);
    *out = sc;
    return SOOC_OK;
}
