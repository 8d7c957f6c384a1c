/* The Atlas mesh metric (docs/mesh.md; include/sooc3d/render.h):
 * points sampled on the predicted mesh and on the generator's true surfaces,
 * both voxel-downsampled at 2 cm (centroid per voxel, as Open3D's
 * voxel_down_sample), then accuracy = mean distance from predicted points to
 * the nearest GT point, completeness = the reverse, precision / recall at
 * 5 cm; nearest neighbours through a k-d tree. */
#include "sooc3d/render.h"
#include "sooc3d/model.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define METRIC_VOXEL 0.02      /* m, Atlas */
#define METRIC_SAMPLES 50000   /* points per predicted mesh before downsampling */
#define METRIC_THRESH 0.05     /* m, precision / recall */
#define METRIC_MATCH 0.5       /* m, GT object <-> map entry on the floor */

/* ------------------------------------------------------------- sampling */

sooc_status sooc_mesh_sample(const sooc_mesh *m, size_t n, uint64_t seed, float *pts) {
    if (!m->n_tri) return sooc_seterr(SOOC_EINVAL, "mesh sample: the mesh has no triangles");
    double *cdf = sooc_malloc(m->n_tri * sizeof(double));
    if (!cdf) return SOOC_ENOMEM;
    double acc = 0;
    for (size_t t = 0; t < m->n_tri; t++) {
        const float *a = m->xyz + 3 * (size_t)m->tri[3 * t], *b = m->xyz + 3 * (size_t)m->tri[3 * t + 1],
                    *c = m->xyz + 3 * (size_t)m->tri[3 * t + 2];
        double u[3], w[3];
        for (int k = 0; k < 3; k++) u[k] = (double)b[k] - a[k], w[k] = (double)c[k] - a[k];
        double x = u[1] * w[2] - u[2] * w[1], y = u[2] * w[0] - u[0] * w[2], z = u[0] * w[1] - u[1] * w[0];
        acc += 0.5 * sqrt(x * x + y * y + z * z);
        cdf[t] = acc;
    }
    if (!(acc > 0)) {
        sooc_free(cdf);
        return sooc_seterr(SOOC_EINVAL, "mesh sample: the mesh has no area");
    }
    sooc_rng r;
    sooc_rng_seed(&r, seed, 0x6d657368);
    for (size_t i = 0; i < n; i++) {
        double q = sooc_rng_uniform(&r) * acc;
        size_t lo = 0, hi = m->n_tri - 1;
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (cdf[mid] < q) lo = mid + 1;
            else hi = mid;
        }
        const float *a = m->xyz + 3 * (size_t)m->tri[3 * lo], *b = m->xyz + 3 * (size_t)m->tri[3 * lo + 1],
                    *c = m->xyz + 3 * (size_t)m->tri[3 * lo + 2];
        double s = sooc_rng_uniform(&r), t = sooc_rng_uniform(&r);
        if (s + t > 1) s = 1 - s, t = 1 - t;
        for (int k = 0; k < 3; k++) pts[3 * i + k] = (float)(a[k] + s * ((double)b[k] - a[k]) + t * ((double)c[k] - a[k]));
    }
    sooc_free(cdf);
    return SOOC_OK;
}

/* Centroid per voxel of side v; compacts pts in place, returns the count. */
typedef struct vkey {
    uint64_t key;
    uint32_t i;
} vkey;

static int cmp_vkey(const void *x, const void *y) {
    const vkey *a = x, *b = y;
    if (a->key != b->key) return a->key < b->key ? -1 : 1;
    return a->i < b->i ? -1 : a->i > b->i;
}

static sooc_status voxel_down(float *pts, size_t n, double v, size_t *n_out) {
    *n_out = 0;
    if (!n) return SOOC_OK;
    vkey *k = sooc_malloc(n * sizeof *k);
    float *o = sooc_malloc(n * 3 * sizeof(float));
    if (!k || !o) {
        sooc_free(k);
        sooc_free(o);
        return SOOC_ENOMEM;
    }
    for (size_t i = 0; i < n; i++) {
        uint64_t key = 0;
        for (int d = 0; d < 3; d++) {
            int64_t c = (int64_t)floor(pts[3 * i + d] / v) + (1 << 20);   /* +-10 km at 2 cm */
            if (c < 0) c = 0;
            if (c > (1 << 21) - 1) c = (1 << 21) - 1;
            key = key << 21 | (uint64_t)c;
        }
        k[i].key = key, k[i].i = (uint32_t)i;
    }
    qsort(k, n, sizeof *k, cmp_vkey);
    size_t m = 0;
    for (size_t a = 0; a < n;) {
        size_t b = a;
        double s[3] = {0, 0, 0};
        while (b < n && k[b].key == k[a].key) {
            for (int d = 0; d < 3; d++) s[d] += pts[3 * k[b].i + d];
            b++;
        }
        for (int d = 0; d < 3; d++) o[3 * m + d] = (float)(s[d] / (double)(b - a));
        m++;
        a = b;
    }
    memcpy(pts, o, m * 3 * sizeof(float));
    sooc_free(k);
    sooc_free(o);
    *n_out = m;
    return SOOC_OK;
}

/* ------------------------------------------------------- true surfaces */

static double obj_dist(const sooc_scene_object *o, const double p[3]) { return sooc_scene_object_distance(o, p); }

/* Points on the object's analytic surface: random points in its padded box
 * that lie within a shell of the surface are pulled onto it by Newton steps
 * on the distance (p <- p - d grad d, central differences); points that end
 * within 0.5 mm of the surface are kept. Dense enough that every 2 cm voxel
 * of the surface gets several points before downsampling. */
sooc_status sooc_mesh_gt_points(const sooc_scene_object *o, double voxel, uint64_t seed, float **pts, size_t *n_out) {
    *pts = NULL, *n_out = 0;
    if (!(voxel > 0)) return sooc_seterr(SOOC_EINVAL, "mesh gt points: voxel must be > 0");
    const double pad = 0.05, shell = 0.04;
    double r = 0.5 * sqrt(o->size[0] * o->size[0] + o->size[2] * o->size[2]) + pad;   /* any yaw */
    double lo[3] = {o->x - r, -pad, o->z - r}, hi[3] = {o->x + r, o->size[1] + pad, o->z + r};
    double vol = (hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    /* about 8 shell points per voxel-sized patch of surface */
    double want = 8.0 * vol / (voxel * voxel * 2 * shell);
    size_t n0 = want < 2e4 ? 20000 : want > 2e6 ? 2000000 : (size_t)want;
    float *P = sooc_malloc(n0 * 3 * sizeof(float));
    if (!P) return SOOC_ENOMEM;
    sooc_rng rg;
    sooc_rng_seed(&rg, seed, (uint64_t)o->id);
    size_t n = 0;
    const double h = 1e-4;
    for (size_t i = 0; i < n0; i++) {
        double p[3];
        for (int d = 0; d < 3; d++) p[d] = lo[d] + sooc_rng_uniform(&rg) * (hi[d] - lo[d]);
        double dist = obj_dist(o, p);
        if (!(dist < shell)) continue;
        for (int it = 0; it < 6 && dist > 2e-5; it++) {
            double g[3], gn = 0;
            for (int d = 0; d < 3; d++) {
                double a[3] = {p[0], p[1], p[2]}, b[3] = {p[0], p[1], p[2]};
                a[d] += h, b[d] -= h;
                g[d] = (obj_dist(o, a) - obj_dist(o, b)) / (2 * h);
                gn += g[d] * g[d];
            }
            if (!(gn > 1e-8)) break;
            for (int d = 0; d < 3; d++) p[d] -= dist * g[d] / gn;
            dist = obj_dist(o, p);
        }
        if (!(dist < 5e-4)) continue;
        for (int d = 0; d < 3; d++) P[3 * n + d] = (float)p[d];
        n++;
    }
    size_t m = 0;
    sooc_status st = voxel_down(P, n, voxel, &m);
    if (st || !m) {
        sooc_free(P);
        return st ? st : sooc_seterr(SOOC_ERR, "mesh gt points: no surface points for object %d", o->id);
    }
    *pts = P, *n_out = m;
    return SOOC_OK;
}

/* ------------------------------------------------------------ k-d tree */

typedef struct kdtree {
    const float *p;
    uint32_t *idx;   /* points permuted so every subtree is a contiguous range */
    size_t n;
} kdtree;

static _Thread_local const float *g_sort_pts;   /* qsort has no context argument */
static _Thread_local int g_sort_axis;
static int cmp_axis(const void *a, const void *b) {
    float x = g_sort_pts[3 * (size_t)*(const uint32_t *)a + g_sort_axis];
    float y = g_sort_pts[3 * (size_t)*(const uint32_t *)b + g_sort_axis];
    return x < y ? -1 : x > y;
}

/* Median split on the axis of largest spread, recursively (depth-first on
 * an explicit range; the split axis of a range is recomputed at query time
 * from the same rule, so nothing else is stored). */
static int range_axis(const kdtree *T, size_t a, size_t b) {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = a; i < b; i++)
        for (int d = 0; d < 3; d++) {
            float v = T->p[3 * (size_t)T->idx[i] + d];
            if (v < lo[d]) lo[d] = v;
            if (v > hi[d]) hi[d] = v;
        }
    int ax = 0;
    for (int d = 1; d < 3; d++)
        if (hi[d] - lo[d] > hi[ax] - lo[ax]) ax = d;
    return ax;
}

#define KD_LEAF 8

static void kd_build(kdtree *T, size_t a, size_t b, uint8_t *axes, size_t node) {
    if (b - a <= KD_LEAF) return;
    int ax = range_axis(T, a, b);
    axes[node] = (uint8_t)ax;
    g_sort_pts = T->p, g_sort_axis = ax;
    qsort(T->idx + a, b - a, sizeof(uint32_t), cmp_axis);
    size_t mid = (a + b) / 2;
    kd_build(T, a, mid, axes, 2 * node + 1);
    kd_build(T, mid + 1, b, axes, 2 * node + 2);
}

static void kd_nn(const kdtree *T, const uint8_t *axes, size_t a, size_t b, size_t node, const float q[3],
                  double *best) {
    if (b - a <= KD_LEAF) {
        for (size_t i = a; i < b; i++) {
            const float *p = T->p + 3 * (size_t)T->idx[i];
            double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2], d = dx * dx + dy * dy + dz * dz;
            if (d < *best) *best = d;
        }
        return;
    }
    size_t mid = (a + b) / 2;
    int ax = axes[node];
    const float *pm = T->p + 3 * (size_t)T->idx[mid];
    double dx = pm[0] - q[0], dy = pm[1] - q[1], dz = pm[2] - q[2], d = dx * dx + dy * dy + dz * dz;
    if (d < *best) *best = d;
    double diff = (double)q[ax] - pm[ax];
    if (diff < 0) {
        kd_nn(T, axes, a, mid, 2 * node + 1, q, best);
        if (diff * diff < *best) kd_nn(T, axes, mid + 1, b, 2 * node + 2, q, best);
    } else {
        kd_nn(T, axes, mid + 1, b, 2 * node + 2, q, best);
        if (diff * diff < *best) kd_nn(T, axes, a, mid, 2 * node + 1, q, best);
    }
}

/* Mean distance from each of q[0..nq) to the nearest of p[0..np), and the
 * fraction within thresh. */
static sooc_status mean_nn(const float *p, size_t np, const float *q, size_t nq, double thresh, double *mean,
                           double *frac) {
    kdtree T = {p, sooc_malloc(np * sizeof(uint32_t)), np};
    size_t nodes = 1;
    while (nodes < 4 * np + 16) nodes *= 2;   /* > every node index of a median-split tree */
    uint8_t *axes = sooc_calloc(nodes, 1);
    if (!T.idx || !axes) {
        sooc_free(T.idx);
        sooc_free(axes);
        return SOOC_ENOMEM;
    }
    for (size_t i = 0; i < np; i++) T.idx[i] = (uint32_t)i;
    kd_build(&T, 0, np, axes, 0);
    double s = 0;
    size_t hit = 0;
    for (size_t i = 0; i < nq; i++) {
        double best = INFINITY;
        kd_nn(&T, axes, 0, np, 0, q + 3 * i, &best);
        double d = sqrt(best);
        s += d;
        hit += d < thresh;
    }
    *mean = s / (double)nq;
    *frac = (double)hit / (double)nq;
    sooc_free(T.idx);
    sooc_free(axes);
    return SOOC_OK;
}

sooc_status sooc_mesh_acc_comp(const float *pred, size_t n_pred, const float *gt, size_t n_gt, sooc_mesh_metric *out) {
    memset(out, 0, sizeof *out);
    if (!n_pred || !n_gt) return sooc_seterr(SOOC_EINVAL, "mesh metric: empty point set (%zu predicted, %zu GT)", n_pred, n_gt);
    double acc, comp, prec, rec;
    sooc_status st = mean_nn(gt, n_gt, pred, n_pred, METRIC_THRESH, &acc, &prec);
    if (!st) st = mean_nn(pred, n_pred, gt, n_gt, METRIC_THRESH, &comp, &rec);
    if (st) return st;
    out->acc_cm = 100 * acc, out->comp_cm = 100 * comp;
    out->precision = prec, out->recall = rec;
    out->fscore = prec + rec > 0 ? 2 * prec * rec / (prec + rec) : 0;
    out->n_objects = 1;
    return SOOC_OK;
}

/* --------------------------------------------------------------- scene */

typedef struct pair {
    double d;
    int g;
    size_t e;
} pair;

static int cmp_pair(const void *a, const void *b) {
    const pair *x = a, *y = b;
    if (x->d != y->d) return x->d < y->d ? -1 : 1;
    if (x->g != y->g) return x->g < y->g ? -1 : 1;
    return x->e < y->e ? -1 : x->e > y->e;
}

sooc_status sooc_mesh_eval_scene(struct sooc_model *m, const sooc_cogmap *map, const sooc_scene *sc,
                                 const sooc_mesh_opts *o, sooc_mesh_metric *out) {
    sooc_mesh_opts od;
    if (!o) sooc_mesh_opts_default(&od), o = &od;
    memset(out, 0, sizeof *out);
    out->acc_cm = out->comp_cm = out->precision = out->recall = out->fscore = NAN;
    out->n_gt = sc->n_objects;
    size_t ne = 0;
    sooc_status st = sooc_cogmap_entries(map, NULL, 0, &ne);
    if (st) return st;
    if (!ne || !sc->n_objects) return SOOC_OK;
    sooc_cogmap_entry *E = sooc_malloc(ne * sizeof *E);
    pair *P = sooc_malloc(ne * (size_t)sc->n_objects * sizeof *P);
    uint8_t *used_e = sooc_calloc(ne, 1), *used_g = sooc_calloc((size_t)sc->n_objects, 1);
    float *pred = sooc_malloc(METRIC_SAMPLES * 3 * sizeof(float));
    sooc_mesh mesh = {0};
    double sa = 0, sc_ = 0, sp = 0, sr = 0, sf = 0;
    int nobj = 0;
    if (!E || !P || !used_e || !used_g || !pred) {
        st = SOOC_ENOMEM;
        goto done;
    }
    if ((st = sooc_cogmap_entries(map, E, ne, &ne))) goto done;
    /* one-to-one, greedy by floor distance */
    size_t np = 0;
    for (int g = 0; g < sc->n_objects; g++)
        for (size_t e = 0; e < ne; e++) {
            double dx = E[e].X - sc->objects[g].x, dz = E[e].Z - sc->objects[g].z, d = sqrt(dx * dx + dz * dz);
            if (d < METRIC_MATCH) P[np].d = d, P[np].g = g, P[np].e = e, np++;
        }
    qsort(P, np, sizeof *P, cmp_pair);
    for (size_t k = 0; k < np && !st; k++) {
        if (used_g[P[k].g] || used_e[P[k].e]) continue;
        used_g[P[k].g] = used_e[P[k].e] = 1;
        const sooc_scene_object *ob = &sc->objects[P[k].g];
        if ((st = sooc_mesh_object(m, map, E[P[k].e].id, o, &mesh))) break;
        float *gt = NULL;
        size_t ngt = 0, npred = 0;
        if ((st = sooc_mesh_gt_points(ob, METRIC_VOXEL, (uint64_t)ob->id, &gt, &ngt))) break;
        sooc_mesh_metric mm;
        if (!mesh.n_tri) {   /* nothing above the level: counted in n_empty, not averaged */
            sooc_free(gt);
            out->n_empty++;
            continue;
        }
        st = sooc_mesh_sample(&mesh, METRIC_SAMPLES, E[P[k].e].id, pred);
        if (!st) st = voxel_down(pred, METRIC_SAMPLES, METRIC_VOXEL, &npred);
        if (!st) st = sooc_mesh_acc_comp(pred, npred, gt, ngt, &mm);
        sooc_free(gt);
        if (st) break;
        sa += mm.acc_cm, sp += mm.precision, sc_ += mm.comp_cm, sr += mm.recall, sf += mm.fscore;
        nobj++;
    }
    if (!st && nobj) {
        out->acc_cm = sa / nobj, out->comp_cm = sc_ / nobj;
        out->precision = sp / nobj, out->recall = sr / nobj, out->fscore = sf / nobj;
        out->n_objects = nobj;
    }
done:
    sooc_mesh_free(&mesh);
    sooc_free(E);
    sooc_free(P);
    sooc_free(used_e);
    sooc_free(used_g);
    sooc_free(pred);
    return st;
}
