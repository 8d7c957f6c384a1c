/* Support-plane clustering (mapper.h, docs/geometric.md): a voxel grid of the
 * keyframes' depth points in the world frame, connected components of the
 * voxels above the support plane, boxes, and a depth-tested render of the
 * grid into any view. */
#include "sooc3d/mapper.h"
#include "sooc3d/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct voxel {
    double s[3];     /* summed world coordinates */
    float c[3];      /* summed colour 0..1       */
    uint32_t n;
    uint32_t views;  /* frames that put a point in it */
    uint32_t thru;   /* frames whose depth lies behind it there: they saw through it */
    uint32_t last;   /* the last of them (1 + the count of frames added before it) */
    int32_t comp;    /* object label, -1 = background */
    uint8_t relabelled;   /* an object voxel of the segmentation labelled anew (sooc_cluster_map_relabel) */
    int32_t seg;          /* its segmentation label, when relabelled */
} voxel;

struct sooc_cluster_map {
    sooc_cluster_params p;
    uint64_t *keys;  /* open addressing, key 0 = empty (keys are stored + 1) */
    int32_t *slot;   /* voxel index of each key */
    size_t hcap;     /* power of two */
    voxel *vox;
    size_t n, cap;
    sooc_cluster_object *obj;
    int n_obj, obj_cap;
    int segmented;
    uint32_t n_frames;   /* frames added since the last clear */
};

void sooc_cluster_params_default(sooc_cluster_params *p) {
    p->voxel_m = 0.004;
    p->dist_m = 0.02;
    p->min_height_m = 0.012;
    p->max_height_m = 0.6;
    p->max_depth_m = 3.0;
    p->min_voxels = 12;
    p->max_extent_m = 0.5;
    p->wall_m = 0.3;
    p->pixel_step = 1;
    p->free_ratio = 1.0;
    p->rest_m = 0.06;
}

static sooc_status check_params(const sooc_cluster_params *p) {
    if (!(p->voxel_m > 0) || !(p->dist_m >= p->voxel_m) || !(p->max_height_m > p->min_height_m) ||
        !(p->max_depth_m > 0) || p->min_voxels < 1 || !(p->max_extent_m > 0) || p->pixel_step < 1 || !(p->wall_m >= 0) ||
        !(p->free_ratio >= 0 && p->free_ratio <= 1000) || !(p->rest_m >= 0) ||
        !isfinite(p->voxel_m + p->dist_m + p->min_height_m + p->max_height_m + p->max_depth_m + p->max_extent_m))
        return sooc_seterr(SOOC_EINVAL,
                           "cluster: bad parameters (voxel %g m, dist %g m, heights %g..%g m, depth %g m, "
                           "min voxels %d, extent %g m, step %d, wall %g m, free ratio %g, rest %g m)",
                           p->voxel_m, p->dist_m, p->min_height_m, p->max_height_m, p->max_depth_m, p->min_voxels,
                           p->max_extent_m, p->pixel_step, p->wall_m, p->free_ratio, p->rest_m);
    return SOOC_OK;
}

sooc_status sooc_cluster_map_create(sooc_cluster_map **out, const sooc_cluster_params *p) {
    if (!out) return sooc_seterr(SOOC_EINVAL, "cluster: no output");
    *out = NULL;
    sooc_cluster_params d;
    if (!p) sooc_cluster_params_default(&d), p = &d;
    sooc_status st = check_params(p);
    if (st) return st;
    sooc_cluster_map *m = sooc_calloc(1, sizeof *m);
    if (!m) return sooc_seterr(SOOC_ENOMEM, "cluster: out of memory");
    m->p = *p;
    *out = m;
    return SOOC_OK;
}

void sooc_cluster_map_destroy(sooc_cluster_map *m) {
    if (!m) return;
    sooc_free(m->keys);
    sooc_free(m->slot);
    sooc_free(m->vox);
    sooc_free(m->obj);
    sooc_free(m);
}

void sooc_cluster_map_clear(sooc_cluster_map *m) {
    if (!m) return;
    if (m->keys) memset(m->keys, 0, m->hcap * sizeof *m->keys);
    m->n = 0;
    m->n_obj = 0;
    m->segmented = 0;
    m->n_frames = 0;
}

/* 21 bits per axis, offset so that +-4 km at 4 mm fits */
static uint64_t pack(int64_t i, int64_t j, int64_t k) {
    const int64_t o = 1 << 20;
    return ((uint64_t)(i + o) & 0x1fffff) << 42 | ((uint64_t)(j + o) & 0x1fffff) << 21 | ((uint64_t)(k + o) & 0x1fffff);
}

static void unpack(uint64_t key, int64_t *i, int64_t *j, int64_t *k) {
    const int64_t o = 1 << 20;
    *i = (int64_t)((key >> 42) & 0x1fffff) - o, *j = (int64_t)((key >> 21) & 0x1fffff) - o, *k = (int64_t)(key & 0x1fffff) - o;
}

static size_t hash64(uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ULL;
    k ^= k >> 33;
    return (size_t)k;
}

static sooc_status rehash(sooc_cluster_map *m, size_t cap) {
    uint64_t *k = sooc_calloc(cap, sizeof *k);
    int32_t *s = sooc_malloc(cap * sizeof *s);
    if (!k || !s) {
        sooc_free(k), sooc_free(s);
        return sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %zu grid cells", cap);
    }
    for (size_t i = 0; i < m->hcap; i++) {
        if (!m->keys[i]) continue;
        size_t h = hash64(m->keys[i]) & (cap - 1);
        while (k[h]) h = (h + 1) & (cap - 1);
        k[h] = m->keys[i], s[h] = m->slot[i];
    }
    sooc_free(m->keys), sooc_free(m->slot);
    m->keys = k, m->slot = s, m->hcap = cap;
    return SOOC_OK;
}

/* the table position of key: where it is, or the empty one where it would go */
static size_t probe(const sooc_cluster_map *m, uint64_t key) {
    uint64_t kk = key + 1;
    size_t h = hash64(kk) & (m->hcap - 1);
    while (m->keys[h] && m->keys[h] != kk) h = (h + 1) & (m->hcap - 1);
    return h;
}

/* the voxel of key, -1 when the grid has none there */
static int32_t voxel_find(const sooc_cluster_map *m, uint64_t key) {
    size_t h = probe(m, key);
    return m->keys[h] ? m->slot[h] : -1;
}

/* the voxel of key (created empty when absent), -1 on allocation failure */
static int32_t voxel_of(sooc_cluster_map *m, uint64_t key) {
    size_t h = probe(m, key);
    if (m->keys[h]) return m->slot[h];
    if (m->n == m->cap) {
        size_t nc = m->cap ? 2 * m->cap : 4096;
        voxel *v = sooc_realloc(m->vox, nc * sizeof *v);
        if (!v) return -1;
        m->vox = v, m->cap = nc;
    }
    voxel *v = &m->vox[m->n];
    memset(v, 0, sizeof *v);
    v->comp = -1;
    m->keys[h] = key + 1, m->slot[h] = (int32_t)m->n;
    return (int32_t)m->n++;
}

/* Free-space evidence: every voxel above the plane that this frame's depth
 * shows free (the surface at its pixel lies more than SEE_TOL_VOX voxels + 1%
 * of the depth behind it) is counted as seen through. Noise of one frame (mixed
 * pixels at a depth edge, a reflection) lies where the other frames see
 * through; a surface does not. */
#define SEE_TOL_VOX 2.0
static void see_through(sooc_cluster_map *m, const sooc_frame *f) {
    const sooc_cluster_params *p = &m->p;
    const double *T = f->T_wc;
    for (size_t i = 0; i < m->n; i++) {
        voxel *vx = &m->vox[i];
        double c[3] = {vx->s[0] / vx->n, vx->s[1] / vx->n, vx->s[2] / vx->n};
        if (!(c[1] >= p->min_height_m && c[1] <= p->max_height_m)) continue;
        double q[3] = {c[0] - T[3], c[1] - T[7], c[2] - T[11]};
        double z = T[2] * q[0] + T[6] * q[1] + T[10] * q[2];
        if (!(z > 0.05) || z > p->max_depth_m) continue;
        double x = T[0] * q[0] + T[4] * q[1] + T[8] * q[2], y = T[1] * q[0] + T[5] * q[1] + T[9] * q[2];
        double u = f->K.fx * x / z + f->K.cx, v = f->K.fy * y / z + f->K.cy;
        if (!(u >= 0 && v >= 0 && u < f->width && v < f->height)) continue;
        size_t k = (size_t)v * f->width + (size_t)u;
        float d = f->depth[k];
        if ((f->valid && !f->valid[k]) || !(d > 0)) continue;
        if (d > z + SEE_TOL_VOX * p->voxel_m + 0.01 * z) vx->thru++;
    }
}

sooc_status sooc_cluster_map_add_frame(sooc_cluster_map *m, const sooc_frame *f) {
    if (!m || !f || !f->depth || f->width < 1 || f->height < 1)
        return sooc_seterr(SOOC_EINVAL, "cluster: add_frame: bad arguments");
    if (!f->has_pose)
        return sooc_seterr(SOOC_EINVAL, "cluster: frame %lld has no pose", (long long)f->index);
    if (!(f->K.fx > 0) || !(f->K.fy > 0))
        return sooc_seterr(SOOC_EINVAL, "cluster: frame %lld has no intrinsics", (long long)f->index);
    const sooc_cluster_params *p = &m->p;
    size_t need = m->n + (size_t)f->width * (size_t)f->height / ((size_t)p->pixel_step * p->pixel_step) + 1;
    if (need > (size_t)INT32_MAX / 2) return sooc_seterr(SOOC_EINVAL, "cluster: grid over %d voxels", INT32_MAX / 2);
    size_t hc = m->hcap ? m->hcap : 8192;
    while (hc < 2 * need) hc *= 2;
    sooc_status st;
    if (hc != m->hcap && (st = rehash(m, hc))) return st;
    const double *T = f->T_wc, inv = 1.0 / p->voxel_m;
    if (p->free_ratio > 0) see_through(m, f);
    for (int v = 0; v < f->height; v += p->pixel_step) {
        for (int u = 0; u < f->width; u += p->pixel_step) {
            size_t k = (size_t)v * f->width + u;
            float d = f->depth[k];
            if ((f->valid && !f->valid[k]) || !(d > 0) || !(d <= p->max_depth_m)) continue;
            double xc = (u + 0.5 - f->K.cx) / f->K.fx * d, yc = (v + 0.5 - f->K.cy) / f->K.fy * d;
            double w[3];
            for (int r = 0; r < 3; r++) w[r] = T[4 * r] * xc + T[4 * r + 1] * yc + T[4 * r + 2] * d + T[4 * r + 3];
            int32_t i = voxel_of(m, pack((int64_t)floor(w[0] * inv), (int64_t)floor(w[1] * inv),
                                         (int64_t)floor(w[2] * inv)));
            if (i < 0) return sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %zu voxels", m->n + 1);
            voxel *vx = &m->vox[i];
            vx->s[0] += w[0], vx->s[1] += w[1], vx->s[2] += w[2];
            if (f->rgb)
                for (int c = 0; c < 3; c++) vx->c[c] += f->rgb[3 * k + c] * (1.0f / 255.0f);
            vx->n++;
            if (vx->last != m->n_frames + 1) vx->last = m->n_frames + 1, vx->views++;
        }
    }
    m->n_frames++;
    m->segmented = 0;
    return SOOC_OK;
}

/* ------------------------------------------------------------ components */

static int32_t uf_find(int32_t *par, int32_t i) {
    while (par[i] != i) {
        par[i] = par[par[i]];
        i = par[i];
    }
    return i;
}

typedef struct cell_ref {
    uint64_t key;
    int32_t vox;
    float c[3];      /* its centroid (float: mm-level, the join test's precision) */
} cell_ref;

static int cmp_cell(const void *a, const void *b) {
    const cell_ref *x = a, *y = b;
    return x->key < y->key ? -1 : x->key > y->key ? 1 : (x->vox > y->vox) - (x->vox < y->vox);
}

/* first index in r[0..n) with key >= k */
static size_t lower(const cell_ref *r, size_t n, uint64_t k) {
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (r[mid].key < k) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

typedef struct comp_acc {
    int32_t root;
    int n;
    size_t first;    /* its voxels: mem[first .. first + n) */
    double s[3], ymax, ymin;
    double c[3];
} comp_acc;

static int cmp_comp(const void *a, const void *b) {
    const comp_acc *x = a, *y = b;
    return (y->n > x->n) - (y->n < x->n);
}

static int cmp_pt(const void *a, const void *b) {
    const double *p = a, *q = b;
    return p[0] < q[0] ? -1 : p[0] > q[0] ? 1 : (p[1] > q[1]) - (p[1] < q[1]);
}

static double cross2(const double *o, const double *a, const double *b) {
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
}

/* Convex hull of n points (x, z pairs) in place (Andrew's monotone chain):
 * returns the hull's vertex count, its vertices first in p. */
static int hull2(double *p, int n) {
    if (n < 3) return n;
    qsort(p, (size_t)n, 2 * sizeof *p, cmp_pt);
    double *h = sooc_malloc((size_t)(2 * n) * 2 * sizeof *h);
    if (!h) return n;   /* out of memory: every point (the box is the same, the search slower) */
    int k = 0;
    for (int i = 0; i < n; i++) {
        while (k >= 2 && cross2(&h[2 * (k - 2)], &h[2 * (k - 1)], &p[2 * i]) <= 0) k--;
        h[2 * k] = p[2 * i], h[2 * k + 1] = p[2 * i + 1], k++;
    }
    for (int i = n - 2, t = k + 1; i >= 0; i--) {
        while (k >= t && cross2(&h[2 * (k - 2)], &h[2 * (k - 1)], &p[2 * i]) <= 0) k--;
        h[2 * k] = p[2 * i], h[2 * k + 1] = p[2 * i + 1], k++;
    }
    k--;   /* the last point is the first */
    memcpy(p, h, (size_t)k * 2 * sizeof *p);
    sooc_free(h);
    return k;
}

static void centroid(const voxel *v, double c[3]) {
    for (int r = 0; r < 3; r++) c[r] = v->s[r] / v->n;
}

static int cmp_float(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Walls: vertical planes through the object points whose inliers run on without a gap of more than
 * WALL_GAP_M for at least wall_m along the floor and WALL_MIN_H_M up (a bin's or shelf's side, a room's
 * wall). Their voxels are taken out of ref (they stay background), so objects that touch them are
 * joined to them no more. RANSAC over pairs of points (a vertical plane through two points), seeded:
 * the same grid gives the same walls; hypotheses are scored on every k-th point (at most
 * WALL_SCORE_PTS of them), the best one's inliers then counted over all. A row of objects whose faces line up leaves gaps between them and
 * is not a wall. */
#define WALL_TOL_M 0.012   /* a point on the plane                                    */
#define WALL_BAND_M 0.03   /* taken out with the wall: its noise and what sticks to it */
#define WALL_GAP_M 0.05
#define WALL_MIN_H_M 0.08
#define WALL_ITERS 300
#define WALL_MAX 4
#define WALL_SCORE_PTS 2048
#define WALL_TOP_TOL_M 0.03
#define SLIVER_THICK_M 0.025
#define SLIVER_RATIO 2.5
#define WALL_RUNS 64
static sooc_status remove_walls(cell_ref *ref, size_t *nr_io, double wall_m) {
    size_t nr = *nr_io;
    if (!(wall_m > 0) || nr < 64) return SOOC_OK;
    float *t = sooc_malloc(nr * sizeof *t);
    if (!t) return sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %zu points", nr);
    uint64_t rng = 0x9e3779b97f4a7c15ULL ^ nr;
    for (int w = 0; w < WALL_MAX && nr >= 64; w++) {
        double bn[2] = {0, 0}, bo[2] = {0, 0};
        size_t best = 0, stride = nr / WALL_SCORE_PTS + 1;
        for (int it = 0; it < WALL_ITERS; it++) {
            rng = rng * 6364136223846793005ULL + 1442695040888963407ULL;
            size_t a = (size_t)(rng >> 33) % nr;
            rng = rng * 6364136223846793005ULL + 1442695040888963407ULL;
            size_t b = (size_t)(rng >> 33) % nr;
            double dx = ref[b].c[0] - ref[a].c[0], dz = ref[b].c[2] - ref[a].c[2], l = hypot(dx, dz);
            if (l < 0.05) continue;
            double n[2] = {dz / l, -dx / l};   /* horizontal normal of the vertical plane through a and b */
            size_t cnt = 0;
            for (size_t i = 0; i < nr; i += stride)
                cnt += fabs(n[0] * (ref[i].c[0] - ref[a].c[0]) + n[1] * (ref[i].c[2] - ref[a].c[2])) < WALL_TOL_M;
            if (cnt > best) best = cnt, bn[0] = n[0], bn[1] = n[1], bo[0] = ref[a].c[0], bo[1] = ref[a].c[2];
        }
        if (!best) break;
        /* the inliers' positions along the plane; the longest run without a gap */
        size_t ni = 0;
        for (size_t i = 0; i < nr; i++) {
            double dx = ref[i].c[0] - bo[0], dz = ref[i].c[2] - bo[1];
            if (fabs(bn[0] * dx + bn[1] * dz) < WALL_TOL_M) t[ni++] = (float)(-bn[1] * dx + bn[0] * dz);
        }
        if (ni < 32) break;
        qsort(t, ni, sizeof *t, cmp_float);
        float r0 = t[0], r1 = t[0], b0 = 0, b1 = -1;
        for (size_t i = 1; i <= ni; i++) {
            if (i == ni || t[i] - t[i - 1] > WALL_GAP_M) {
                if (r1 - r0 > b1 - b0) b0 = r0, b1 = r1;
                if (i < ni) r0 = t[i];
            }
            if (i < ni) r1 = t[i];
        }
        if (b1 - b0 < wall_m) break;
        float ylo = INFINITY, yhi = -INFINITY;
        for (size_t i = 0; i < nr; i++) {
            double dx = ref[i].c[0] - bo[0], dz = ref[i].c[2] - bo[1], s = -bn[1] * dx + bn[0] * dz;
            if (fabs(bn[0] * dx + bn[1] * dz) < WALL_TOL_M && s >= b0 && s <= b1) {
                ylo = ref[i].c[1] < ylo ? ref[i].c[1] : ylo;
                yhi = ref[i].c[1] > yhi ? ref[i].c[1] : yhi;
            }
        }
        if (yhi - ylo < WALL_MIN_H_M) break;
        /* the same wall past its gaps (missing depth, a shelf's post): the other runs on its plane as tall
         * as it (their top within WALL_TOP_TOL_M of its top, at least WALL_MIN_H_M high) go with it */
        float keep_lo[WALL_RUNS], keep_hi[WALL_RUNS];
        int nk = 0;
        keep_lo[nk] = b0, keep_hi[nk++] = b1;
        for (size_t i = 0, s0 = 0; i <= ni && nk < WALL_RUNS; i++) {
            if (i < ni && (i == 0 || t[i] - t[i - 1] <= WALL_GAP_M)) continue;
            if (i > s0 && !(t[s0] == b0 && t[i - 1] == b1)) {   /* run t[s0 .. i) */
                float lo = t[s0], hi = t[i - 1], rlo = INFINITY, rhi = -INFINITY;
                for (size_t j = 0; j < nr; j++) {
                    double dx = ref[j].c[0] - bo[0], dz = ref[j].c[2] - bo[1], s = -bn[1] * dx + bn[0] * dz;
                    if (fabs(bn[0] * dx + bn[1] * dz) < WALL_TOL_M && s >= lo && s <= hi) {
                        rlo = ref[j].c[1] < rlo ? ref[j].c[1] : rlo;
                        rhi = ref[j].c[1] > rhi ? ref[j].c[1] : rhi;
                    }
                }
                if (rhi - rlo >= WALL_MIN_H_M && fabsf(rhi - yhi) < WALL_TOP_TOL_M) keep_lo[nk] = lo, keep_hi[nk++] = hi;
            }
            s0 = i;
        }
        size_t k = 0;
        for (size_t i = 0; i < nr; i++) {
            double dx = ref[i].c[0] - bo[0], dz = ref[i].c[2] - bo[1], s = -bn[1] * dx + bn[0] * dz;
            int on = 0;
            for (int r = 0; r < nk && !on; r++)
                on = fabs(bn[0] * dx + bn[1] * dz) < WALL_BAND_M && s >= keep_lo[r] - WALL_BAND_M &&
                     s <= keep_hi[r] + WALL_BAND_M;
            if (!on) ref[k++] = ref[i];
        }
        nr = k;
    }
    sooc_free(t);
    *nr_io = nr;
    return SOOC_OK;
}

/* Which components stand (rule 3, docs/geometric.md): a component whose lowest voxel lies within rest_m
 * of the plane, or one that rests on a standing component: one of its lowest voxels has a voxel of that
 * component under it (its column or the 8 around it) within REST_GAP of the join distance. The faces of a
 * box that the depth samples in bands a few cm apart (steep, far) rest on each other down to the plane; a
 * shelf's lip 10 cm above what stands under it does not. Components in order of their lowest voxel, so
 * those under one are decided first. out[k] = 1 where component k stands. */
#define REST_GAP 2.0
typedef struct comp_low {
    double ymin;
    size_t k;
} comp_low;

static int cmp_low(const void *a, const void *b) {
    const comp_low *x = a, *y = b;
    return x->ymin < y->ymin ? -1 : x->ymin > y->ymin ? 1 : (x->k > y->k) - (x->k < y->k);
}

static sooc_status standing(const sooc_cluster_map *m, const comp_acc *acc, size_t na, const int32_t *mem,
                            uint8_t *out) {
    const sooc_cluster_params *p = &m->p;
    int32_t *lab = sooc_malloc((m->n ? m->n : 1) * sizeof *lab);
    comp_low *ord = sooc_malloc((na ? na : 1) * sizeof *ord);
    if (!lab || !ord) {
        sooc_free(lab), sooc_free(ord);
        return sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %zu voxels", m->n);
    }
    for (size_t i = 0; i < m->n; i++) lab[i] = -1;
    for (size_t k = 0; k < na; k++) {
        for (int a = 0; a < acc[k].n; a++) lab[mem[acc[k].first + (size_t)a]] = (int32_t)k;
        ord[k].ymin = acc[k].ymin, ord[k].k = k;
    }
    qsort(ord, na, sizeof *ord, cmp_low);
    const double inv = 1.0 / p->voxel_m;
    const int64_t gap = (int64_t)ceil(REST_GAP * p->dist_m * inv);
    for (size_t o = 0; o < na; o++) {
        size_t k = ord[o].k;
        const comp_acc *c = &acc[k];
        out[k] = c->ymin <= p->rest_m;
        for (int a = 0; a < c->n && !out[k]; a++) {
            double w[3];
            centroid(&m->vox[mem[c->first + (size_t)a]], w);
            if (w[1] > c->ymin + 2 * p->voxel_m) continue;   /* its lowest voxels only */
            int64_t vi = (int64_t)floor(w[0] * inv), vj = (int64_t)floor(w[1] * inv), vk = (int64_t)floor(w[2] * inv);
            for (int64_t dj = 1; dj <= gap && !out[k]; dj++)
                for (int di = -1; di <= 1 && !out[k]; di++)
                    for (int dk = -1; dk <= 1 && !out[k]; dk++) {
                        int32_t v = voxel_find(m, pack(vi + di, vj - dj, vk + dk));
                        if (v >= 0 && lab[v] >= 0 && (size_t)lab[v] != k && out[lab[v]]) out[k] = 1;
                    }
        }
    }
    sooc_free(lab);
    sooc_free(ord);
    return SOOC_OK;
}

sooc_status sooc_cluster_map_segment(sooc_cluster_map *m, int *n_objects) {
    if (!m) return sooc_seterr(SOOC_EINVAL, "cluster: segment: no map");
    const sooc_cluster_params *p = &m->p;
    sooc_status st = SOOC_OK;
    size_t nf = 0;
    for (size_t i = 0; i < m->n; i++) {
        voxel *v = &m->vox[i];
        v->comp = -1, v->relabelled = 0;
        double y = v->s[1] / v->n;
        nf += y >= p->min_height_m && y <= p->max_height_m;
    }
    cell_ref *ref = sooc_malloc((nf ? nf : 1) * sizeof *ref);
    int32_t *par = sooc_malloc((m->n ? m->n : 1) * sizeof *par), *mem = NULL;
    double *pts = NULL;
    comp_acc *acc = NULL;
    uint8_t *stand = NULL;   /* components that stand on the plane (rest_m > 0) */
    if (!ref || !par) {
        st = sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %zu voxels", m->n);
        goto done;
    }
    const double inv = 1.0 / p->dist_m, d2 = p->dist_m * p->dist_m;
    size_t nr = 0;
    for (size_t i = 0; i < m->n; i++) {
        par[i] = (int32_t)i;
        double c[3];
        centroid(&m->vox[i], c);
        if (!(c[1] >= p->min_height_m && c[1] <= p->max_height_m)) continue;
        if (p->free_ratio > 0 && m->vox[i].thru >= p->free_ratio * m->vox[i].views) continue;   /* free space */
        ref[nr].key = pack((int64_t)floor(c[0] * inv), (int64_t)floor(c[1] * inv), (int64_t)floor(c[2] * inv));
        for (int q = 0; q < 3; q++) ref[nr].c[q] = (float)c[q];
        ref[nr++].vox = (int32_t)i;
    }
    if ((st = remove_walls(ref, &nr, p->wall_m))) goto done;
    qsort(ref, nr, sizeof *ref, cmp_cell);
    /* join every pair closer than dist_m: cell by cell (cells of side dist_m; ref is sorted by cell), the
     * pairs within the cell and with the 13 cells after it of its 26 neighbours (the other 13 see it as
     * theirs): every candidate pair once, one search per neighbour cell */
    static const int8_t fwd[13][3] = {{0, 0, 1},  {0, 1, -1}, {0, 1, 0},  {0, 1, 1},  {1, -1, -1}, {1, -1, 0}, {1, -1, 1},
                                      {1, 0, -1}, {1, 0, 0},  {1, 0, 1},  {1, 1, -1}, {1, 1, 0},   {1, 1, 1}};
    for (size_t s0 = 0, e0; s0 < nr; s0 = e0) {
        for (e0 = s0 + 1; e0 < nr && ref[e0].key == ref[s0].key;) e0++;
        int64_t gi, gj, gk;   /* the run's own cell (its key, not recomputed from a float centroid) */
        unpack(ref[s0].key, &gi, &gj, &gk);
        for (int nb = -1; nb < 13; nb++) {
            size_t b0 = s0, b1 = e0;   /* nb -1: the cell itself */
            if (nb >= 0) {
                uint64_t key = pack(gi + fwd[nb][0], gj + fwd[nb][1], gk + fwd[nb][2]);
                b0 = lower(ref, nr, key);
                for (b1 = b0; b1 < nr && ref[b1].key == key;) b1++;
                if (b0 == b1) continue;
            }
            for (size_t a = s0; a < e0; a++) {
                const float *ca = ref[a].c;
                for (size_t b = nb < 0 ? a + 1 : b0; b < b1; b++) {
                    const float *cb = ref[b].c;
                    double dx = ca[0] - cb[0], dy = ca[1] - cb[1], dz = ca[2] - cb[2];
                    if (dx * dx + dy * dy + dz * dz > d2) continue;
                    int32_t ra = uf_find(par, ref[a].vox), rb = uf_find(par, ref[b].vox);
                    if (ra != rb) par[ra > rb ? ra : rb] = ra < rb ? ra : rb;
                }
            }
        }
    }
    /* components: sizes and moments, keyed by root */
    size_t na = 0;
    if (!(acc = sooc_calloc(nr ? nr : 1, sizeof *acc))) {
        st = sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %zu components", nr);
        goto done;
    }
    for (size_t a = 0; a < nr; a++) {   /* ref[].key becomes the component slot of each voxel */
        int32_t i = ref[a].vox, r = uf_find(par, i);
        int32_t *slot = &m->vox[r].comp;   /* roots hold their accumulator index for now */
        if (*slot < 0) {
            *slot = (int32_t)na;
            acc[na].root = r;
            acc[na].ymax = -INFINITY;
            acc[na].ymin = INFINITY;
            na++;
        }
        comp_acc *c = &acc[*slot];
        ref[a].key = (uint64_t)*slot;
        double w[3];
        centroid(&m->vox[i], w);
        c->n++;
        for (int q = 0; q < 3; q++) c->s[q] += w[q], c->c[q] += m->vox[i].c[q] / m->vox[i].n;
        if (w[1] > c->ymax) c->ymax = w[1];
        if (w[1] < c->ymin) c->ymin = w[1];
    }
    /* each component's voxels together (counting sort by slot), floor points for its box */
    if (!(mem = sooc_malloc((nr ? nr : 1) * sizeof *mem)) || !(pts = sooc_malloc((nr ? nr : 1) * 2 * sizeof *pts))) {
        st = sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %zu voxels", nr);
        goto done;
    }
    {
        size_t off = 0;
        for (size_t k = 0; k < na; k++) acc[k].first = off, off += (size_t)acc[k].n, acc[k].n = 0;
        for (size_t a = 0; a < nr; a++) {
            comp_acc *c = &acc[ref[a].key];
            mem[c->first + (size_t)c->n++] = ref[a].vox;
        }
    }
    qsort(acc, na, sizeof *acc, cmp_comp);
    if (p->rest_m > 0) {
        if (!(stand = sooc_malloc(na ? na : 1))) {
            st = sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %zu components", na);
            goto done;
        }
        if ((st = standing(m, acc, na, mem, stand))) goto done;
    }
    m->n_obj = 0;
    for (size_t k = 0; k < na; k++) m->vox[acc[k].root].comp = -1;
    int cap_needed = (int)(na < 32768 ? na : 32768);
    if (cap_needed > m->obj_cap) {
        sooc_cluster_object *o = sooc_realloc(m->obj, (size_t)cap_needed * sizeof *o);
        if (!o) {
            st = sooc_seterr(SOOC_ENOMEM, "cluster: out of memory for %d objects", cap_needed);
            goto done;
        }
        m->obj = o, m->obj_cap = cap_needed;
    }
    for (size_t k = 0; k < na && m->n_obj < m->obj_cap; k++) {
        comp_acc *c = &acc[k];
        if (c->n < p->min_voxels) break;   /* sorted by size */
        /* floating: it stands on nothing here (a shelf's lip, the bin above, an overhang; `standing`) */
        if (stand && !stand[k]) continue;
        double mx = c->s[0] / c->n, mz = c->s[2] / c->n;
        /* the heading of the smallest-area floor rectangle around the voxels (1 degree steps over a
         * quarter turn: a rectangle repeats itself every 90 degrees), over their floor hull */
        for (int j = 0; j < c->n; j++) {
            double w[3];
            centroid(&m->vox[mem[c->first + (size_t)j]], w);
            pts[2 * j] = w[0] - mx, pts[2 * j + 1] = w[2] - mz;
        }
        int nh = hull2(pts, c->n);
        double th = 0, best = INFINITY, lo[2] = {0, 0}, hi[2] = {0, 0};
        for (int step = 0; step < 90; step++) {
            double t = step * (M_PI / 180.0), ca = cos(t), sa = sin(t);
            double l0 = INFINITY, l1 = INFINITY, h0 = -INFINITY, h1 = -INFINITY;
            for (int j = 0; j < nh; j++) {
                double s = pts[2 * j] * ca + pts[2 * j + 1] * sa, q = -pts[2 * j] * sa + pts[2 * j + 1] * ca;
                l0 = s < l0 ? s : l0, h0 = s > h0 ? s : h0;
                l1 = q < l1 ? q : l1, h1 = q > h1 ? q : h1;
            }
            double area = (h0 - l0) * (h1 - l1);
            if (area < best - 1e-12) best = area, th = t, lo[0] = l0, lo[1] = l1, hi[0] = h0, hi[1] = h1;
        }
        double ax = cos(th), az = sin(th);
        double ex = hi[0] - lo[0] + p->voxel_m, ez = hi[1] - lo[1] + p->voxel_m;
        if (ex > p->max_extent_m || ez > p->max_extent_m) continue;
        /* a sliver: a vertical strip no thicker than SLIVER_THICK_M and SLIVER_RATIO times as tall as it is
         * wide is a piece of a wall or a bin's side between gaps in the depth, not an object */
        double top = c->ymax + 0.5 * p->voxel_m;
        if (fmin(ex, ez) <= SLIVER_THICK_M + p->voxel_m && top > SLIVER_RATIO * fmax(ex, ez)) continue;
        sooc_cluster_object *o = &m->obj[m->n_obj];
        memset(o, 0, sizeof *o);
        o->label = m->n_obj;
        double s0 = 0.5 * (lo[0] + hi[0]), t0 = 0.5 * (lo[1] + hi[1]);
        o->x = mx + s0 * ax - t0 * az;
        o->z = mz + s0 * az + t0 * ax;
        /* the box's x axis in the world is (cos yaw, 0, -sin yaw) (R_y) */
        o->yaw = atan2(-az, ax);
        o->extent[0] = ex, o->extent[2] = ez;
        o->extent[1] = c->ymax + 0.5 * p->voxel_m;   /* objects stand on the plane */
        o->centre_y = 0.5 * o->extent[1];
        for (int q = 0; q < 3; q++) o->rgb[q] = c->c[q] / c->n;
        o->n_voxels = c->n;
        m->vox[c->root].comp = m->n_obj++;
    }
    /* every voxel takes its root's label */
    for (size_t a = 0; a < nr; a++) {
        int32_t i = ref[a].vox, r = uf_find(par, i);
        if (i != r) m->vox[i].comp = m->vox[r].comp;
    }
    m->segmented = 1;
    if (n_objects) *n_objects = m->n_obj;
done:
    sooc_free(mem);
    sooc_free(stand);
    sooc_free(pts);
    sooc_free(acc);
    sooc_free(ref);
    sooc_free(par);
    return st;
}

sooc_status sooc_cluster_map_objects(const sooc_cluster_map *m, sooc_cluster_object *out, int cap, int *n) {
    if (!m || !n || cap < 0 || (cap && !out)) return sooc_seterr(SOOC_EINVAL, "cluster: objects: bad arguments");
    if (!m->segmented) return sooc_seterr(SOOC_EINVAL, "cluster: objects before segment");
    int k = m->n_obj < cap ? m->n_obj : cap;
    if (k) memcpy(out, m->obj, (size_t)k * sizeof *out);
    *n = m->n_obj;
    return SOOC_OK;
}

sooc_status sooc_cluster_map_object_points(const sooc_cluster_map *m, float *xyz, int32_t *label, size_t cap,
                                           size_t *n) {
    if (!m || !n) return sooc_seterr(SOOC_EINVAL, "cluster: object points: bad arguments");
    if (!m->segmented) return sooc_seterr(SOOC_EINVAL, "cluster: object points before segment");
    size_t k = 0;
    for (size_t i = 0; i < m->n; i++) {
        if (m->vox[i].comp < 0 && !m->vox[i].relabelled) continue;
        if (k < cap && xyz) {
            double c[3];
            centroid(&m->vox[i], c);
            for (int r = 0; r < 3; r++) xyz[3 * k + r] = (float)c[r];
        }
        if (k < cap && label) label[k] = m->vox[i].relabelled ? m->vox[i].seg : m->vox[i].comp;
        k++;
    }
    *n = k;
    return SOOC_OK;
}

sooc_status sooc_cluster_map_relabel(sooc_cluster_map *m, const int32_t *label, size_t n) {
    if (!m || (n && !label)) return sooc_seterr(SOOC_EINVAL, "cluster: relabel: bad arguments");
    if (!m->segmented) return sooc_seterr(SOOC_EINVAL, "cluster: relabel before segment");
    size_t k = 0;
    for (size_t i = 0; i < m->n; i++) k += m->vox[i].comp >= 0 || m->vox[i].relabelled;
    if (k != n) return sooc_seterr(SOOC_EINVAL, "cluster: relabel: %zu labels for %zu object voxels", n, k);
    k = 0;
    for (size_t i = 0; i < m->n; i++) {
        voxel *v = &m->vox[i];
        if (v->comp < 0 && !v->relabelled) continue;
        if (!v->relabelled) v->seg = v->comp;
        v->relabelled = 1;
        v->comp = label[k] < 0 ? -1 : label[k];
        k++;
    }
    return SOOC_OK;
}

/* ------------------------------------------------------------ render */

sooc_status sooc_cluster_map_render(const sooc_cluster_map *m, const double T_wc[16], const sooc_intrinsics *K,
                                    int w, int h, int16_t *label, float *depth, float *rgb) {
    if (!m || !T_wc || !K || w < 1 || h < 1 || !label)
        return sooc_seterr(SOOC_EINVAL, "cluster: render: bad arguments");
    if (!m->segmented) return sooc_seterr(SOOC_EINVAL, "cluster: render before segment");
    size_t np = (size_t)w * h;
    float *z = sooc_malloc(np * sizeof *z);
    int32_t *vid = sooc_malloc(np * sizeof *vid);
    if (!z || !vid) {
        sooc_free(z), sooc_free(vid);
        return sooc_seterr(SOOC_ENOMEM, "cluster: render: out of memory for %dx%d", w, h);
    }
    for (size_t k = 0; k < np; k++) z[k] = INFINITY, vid[k] = -1;
    double T[16];
    sooc_se3_inverse(T, T_wc);
    for (size_t i = 0; i < m->n; i++) {
        double c[3], pc[3];
        centroid(&m->vox[i], c);
        for (int r = 0; r < 3; r++) pc[r] = T[4 * r] * c[0] + T[4 * r + 1] * c[1] + T[4 * r + 2] * c[2] + T[4 * r + 3];
        if (pc[2] < 0.05) continue;
        double u = K->fx * pc[0] / pc[2] + K->cx, v = K->fy * pc[1] / pc[2] + K->cy;
        if (!(u >= 0 && v >= 0 && u < w && v < h)) continue;
        size_t k = (size_t)(int)v * w + (size_t)(int)u;
        if (pc[2] < z[k]) z[k] = (float)pc[2], vid[k] = (int32_t)i;
    }
    /* holes: the nearest in depth of the 8 neighbours (from the splatted image only) */
    for (int v = 0; v < h; v++)
        for (int u = 0; u < w; u++) {
            size_t k = (size_t)v * w + u;
            float zk = z[k];
            int32_t ik = vid[k];
            if (ik < 0)
                for (int dv = -1; dv <= 1; dv++)
                    for (int du = -1; du <= 1; du++) {
                        int uu = u + du, vv = v + dv;
                        if (uu < 0 || vv < 0 || uu >= w || vv >= h) continue;
                        size_t q = (size_t)vv * w + uu;
                        if (vid[q] >= 0 && z[q] < zk) zk = z[q], ik = vid[q];
                    }
            const voxel *vx = ik >= 0 ? &m->vox[ik] : NULL;
            label[k] = vx ? (int16_t)vx->comp : -1;
            if (depth) depth[k] = vx ? zk : 0.0f;
            if (rgb)
                for (int c = 0; c < 3; c++) rgb[3 * k + c] = vx ? vx->c[c] / vx->n : 0.0f;
        }
    sooc_free(z);
    sooc_free(vid);
    return SOOC_OK;
}
