/* Marching cubes on a render.h field component (include/sooc3d/render.h,
 * docs/mesh.md), plus the mesh container and its checks.
 *
 * The cube table is generated, not typed in: for each of the 256 corner
 * configurations, every cube face contributes one segment per maximal run of
 * inside corners around the face (walked counter-clockwise seen from
 * outside), from the edge where the run is left to the edge where it was
 * entered. A face is cut the same way from both cells sharing it, so the
 * mesh is watertight; segments chain into closed loops on the cube surface,
 * each fanned into triangles. */
#include "sooc3d/render.h"
#include "sooc3d/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

/* ------------------------------------------------------------ container */

void sooc_mesh_free(sooc_mesh *m) {
    if (!m) return;
    sooc_free(m->xyz);
    sooc_free(m->rgb);
    sooc_free(m->tri);
    memset(m, 0, sizeof *m);
}

static sooc_status reserve_vert(sooc_mesh *m, size_t n) {
    if (n <= m->cap_vert) return SOOC_OK;
    size_t cap = m->cap_vert ? m->cap_vert : 1024;
    while (cap < n) cap *= 2;
    if (cap > (size_t)UINT32_MAX) return sooc_seterr(SOOC_EINVAL, "mesh: more than 2^32 vertices");
    float *x = sooc_realloc(m->xyz, cap * 3 * sizeof(float));
    if (!x) return SOOC_ENOMEM;
    m->xyz = x;
    uint8_t *c = sooc_realloc(m->rgb, cap * 3);
    if (!c) return SOOC_ENOMEM;
    m->rgb = c;
    m->cap_vert = cap;
    return SOOC_OK;
}

static sooc_status reserve_tri(sooc_mesh *m, size_t n) {
    if (n <= m->cap_tri) return SOOC_OK;
    size_t cap = m->cap_tri ? m->cap_tri : 2048;
    while (cap < n) cap *= 2;
    uint32_t *t = sooc_realloc(m->tri, cap * 3 * sizeof(uint32_t));
    if (!t) return SOOC_ENOMEM;
    m->tri = t;
    m->cap_tri = cap;
    return SOOC_OK;
}

sooc_status sooc_mesh_append(sooc_mesh *dst, const sooc_mesh *src) {
    if (dst->n_vert + src->n_vert > (size_t)UINT32_MAX) return sooc_seterr(SOOC_EINVAL, "mesh: more than 2^32 vertices");
    sooc_status s = reserve_vert(dst, dst->n_vert + src->n_vert);
    if (!s) s = reserve_tri(dst, dst->n_tri + src->n_tri);
    if (s) return s;
    if (src->n_vert) {
        memcpy(dst->xyz + dst->n_vert * 3, src->xyz, src->n_vert * 3 * sizeof(float));
        memcpy(dst->rgb + dst->n_vert * 3, src->rgb, src->n_vert * 3);
    }
    uint32_t off = (uint32_t)dst->n_vert;
    for (size_t i = 0; i < src->n_tri * 3; i++) dst->tri[dst->n_tri * 3 + i] = src->tri[i] + off;
    dst->n_vert += src->n_vert;
    dst->n_tri += src->n_tri;
    return SOOC_OK;
}

double sooc_mesh_volume(const sooc_mesh *m) {
    double v = 0;
    for (size_t t = 0; t < m->n_tri; t++) {
        const float *a = m->xyz + 3 * (size_t)m->tri[3 * t], *b = m->xyz + 3 * (size_t)m->tri[3 * t + 1],
                    *c = m->xyz + 3 * (size_t)m->tri[3 * t + 2];
        v += (double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
             (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
             (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    return v / 6.0;
}

static double tri_area(const float *a, const float *b, const float *c) {
    double u[3], w[3];
    for (int k = 0; k < 3; k++) u[k] = (double)b[k] - a[k], w[k] = (double)c[k] - a[k];
    double x = u[1] * w[2] - u[2] * w[1], y = u[2] * w[0] - u[0] * w[2], z = u[0] * w[1] - u[1] * w[0];
    return 0.5 * sqrt(x * x + y * y + z * z);
}

double sooc_mesh_area(const sooc_mesh *m) {
    double a = 0;
    for (size_t t = 0; t < m->n_tri; t++)
        a += tri_area(m->xyz + 3 * (size_t)m->tri[3 * t], m->xyz + 3 * (size_t)m->tri[3 * t + 1],
                      m->xyz + 3 * (size_t)m->tri[3 * t + 2]);
    return a;
}

/* Directed edges (a -> b) packed as a 64-bit key, sorted: a closed, consistently
 * wound mesh has every directed edge once and its reverse once. */
static int cmp_u64(const void *x, const void *y) {
    uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return a < b ? -1 : a > b;
}

static int has_key(const uint64_t *k, size_t n, uint64_t key) {
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (k[mid] < key) lo = mid + 1;
        else hi = mid;
    }
    return lo < n && k[lo] == key;
}

int sooc_mesh_is_closed(const sooc_mesh *m, size_t *n_bad) {
    size_t ne = m->n_tri * 3, bad = 0;
    if (n_bad) *n_bad = 0;
    if (!ne) return 1;
    uint64_t *k = sooc_malloc(ne * sizeof(uint64_t));
    if (!k) {
        if (n_bad) *n_bad = (size_t)-1;
        return 0;
    }
    for (size_t t = 0; t < m->n_tri; t++)
        for (int e = 0; e < 3; e++) {
            uint32_t a = m->tri[3 * t + e], b = m->tri[3 * t + (e + 1) % 3];
            if (a == b) bad++;
            k[3 * t + e] = (uint64_t)a << 32 | b;
        }
    qsort(k, ne, sizeof *k, cmp_u64);
    for (size_t i = 0; i < ne; i++) {
        if (i + 1 < ne && k[i + 1] == k[i]) bad++;   /* a directed edge used twice */
        uint64_t rev = (k[i] << 32) | (k[i] >> 32);
        if (!has_key(k, ne, rev)) bad++;              /* no triangle on the other side */
    }
    sooc_free(k);
    if (n_bad) *n_bad = bad;
    return bad == 0;
}

/* ----------------------------------------------------------- cube table */

/* Corner c = (c & 1, c >> 1 & 1, c >> 2 & 1) in (x, y, z). Edges 0-3 run
 * along x from corners 0 2 4 6, 4-7 along y from 0 1 4 5, 8-11 along z from
 * 0 1 2 3. */
static const int g_edge_base[12] = {0, 2, 4, 6, 0, 1, 4, 5, 0, 1, 2, 3};
/* Faces, corners counter-clockwise seen from outside the cube. */
static const int g_face[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                 {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};

static int edge_of(int a, int b) {
    int d = a ^ b, lo = a < b ? a : b;
    if (d == 1) return lo >> 1;
    if (d == 2) return 4 + (lo & 1) + ((lo >> 2) & 1) * 2;
    return 8 + lo;
}

/* Bit f set if cube edge e lies on face f. */
static int edge_faces(int e) {
    int a = g_edge_base[e], b = a | 1 << (e >> 2), m = 0;
    for (int f = 0; f < 6; f++) {
        int ha = 0, hb = 0;
        for (int j = 0; j < 4; j++) ha |= g_face[f][j] == a, hb |= g_face[f][j] == b;
        if (ha && hb) m |= 1 << f;
    }
    return m;
}

typedef struct mc_table {
    int8_t n[256];          /* triangles per configuration */
    int8_t e[256][30];      /* edge triples                */
} mc_table;

static void build_table(mc_table *T) {
    for (int cfg = 0; cfg < 256; cfg++) {
        int next[12];
        for (int e = 0; e < 12; e++) next[e] = -1;
        for (int f = 0; f < 6; f++) {
            const int *q = g_face[f];
            int s[4];
            for (int j = 0; j < 4; j++) s[j] = (cfg >> q[j]) & 1;
            for (int j = 0; j < 4; j++) {
                if (!s[j] || s[(j + 1) & 3]) continue;   /* not the end of an inside run */
                int st = j;
                while (s[(st + 3) & 3]) st = (st + 3) & 3;
                int ex = edge_of(q[j], q[(j + 1) & 3]), en = edge_of(q[(st + 3) & 3], q[st]);
                next[ex] = en;
            }
        }
        int used[12] = {0}, nt = 0;
        for (int e0 = 0; e0 < 12; e0++) {
            if (next[e0] < 0 || used[e0]) continue;
            int loop[12], nl = 0;
            for (int e = e0; !used[e]; e = next[e]) {
                used[e] = 1;
                loop[nl++] = e;
            }
            /* Fan from an apex whose diagonals all cross the cube's interior:
             * a diagonal between two edges of one face could coincide with
             * the neighbouring cell's (an ambiguous face whose two segments
             * belong to one loop here), making the mesh non-manifold. Every
             * loop of this table has such an apex (checked in build). */
            int ap = 0;
            for (int a = 0; a < nl; a++) {
                int ok = 1;
                for (int i = 2; i + 1 < nl && ok; i++) ok = !(edge_faces(loop[a]) & edge_faces(loop[(a + i) % nl]));
                if (ok) {
                    ap = a;
                    break;
                }
            }
            /* The loop runs with the inside on its left seen from outside the
             * cube, i.e. clockwise seen from the low-density side: reverse
             * it so that triangles are counter-clockwise from outside. */
            for (int i = 1; i + 1 < nl; i++) {
                T->e[cfg][3 * nt] = (int8_t)loop[ap];
                T->e[cfg][3 * nt + 1] = (int8_t)loop[(ap + i + 1) % nl];
                T->e[cfg][3 * nt + 2] = (int8_t)loop[(ap + i) % nl];
                nt++;
            }
        }
        T->n[cfg] = (int8_t)nt;
    }
}

/* ------------------------------------------------------------ extraction */

#define MC_BATCH 4096
#define MC_NONE UINT32_MAX

static void xform(const double T[16], const double p[3], double o[3]) {
    for (int r = 0; r < 3; r++) o[r] = T[4 * r] * p[0] + T[4 * r + 1] * p[1] + T[4 * r + 2] * p[2] + T[4 * r + 3];
}

typedef struct mc_ctx {
    const sooc_mesh_grid *g;
    const float *val;
    int nx, ny, nz;
    float level;
    double step[3];
    sooc_mesh *out;
} mc_ctx;

static inline int mc_inside(const mc_ctx *c, int i, int j, int k) {
    if (i < 0 || j < 0 || k < 0 || i >= c->nx || j >= c->ny || k >= c->nz) return 0;
    return c->val[(size_t)i + (size_t)c->nx * ((size_t)j + (size_t)c->ny * k)] >= c->level;
}

/* The vertex on the grid edge from sample a along axis `ax`: linear
 * interpolation of the level; a sample outside the grid is "outside" and the
 * vertex then sits on the grid's border sample. */
static sooc_status mc_vertex(mc_ctx *c, int i, int j, int k, int ax, uint32_t *idx) {
    int a[3] = {i, j, k}, b[3] = {i, j, k};
    b[ax]++;
    double t;
    int ain = a[0] >= 0 && a[1] >= 0 && a[2] >= 0 && a[0] < c->nx && a[1] < c->ny && a[2] < c->nz;
    int bin = b[0] >= 0 && b[1] >= 0 && b[2] >= 0 && b[0] < c->nx && b[1] < c->ny && b[2] < c->nz;
    if (!ain) t = 1;
    else if (!bin) t = 0;
    else {
        float va = c->val[(size_t)a[0] + (size_t)c->nx * ((size_t)a[1] + (size_t)c->ny * a[2])];
        float vb = c->val[(size_t)b[0] + (size_t)c->nx * ((size_t)b[1] + (size_t)c->ny * b[2])];
        t = ((double)c->level - va) / ((double)vb - va);
        if (!(t >= 0)) t = 0;
        if (t > 1) t = 1;
    }
    sooc_mesh *m = c->out;
    sooc_status s = reserve_vert(m, m->n_vert + 1);
    if (s) return s;
    float *p = m->xyz + 3 * m->n_vert;
    for (int d = 0; d < 3; d++) {
        double x = a[d] + (d == ax ? t : 0);
        p[d] = (float)(c->g->lo[d] + x * c->step[d]);
    }
    *idx = (uint32_t)m->n_vert++;
    return SOOC_OK;
}

/* Evaluate the field on the grid (sigma_hat into val) and, afterwards, the
 * colour at the vertices. */
typedef struct eval_job {
    const sooc_field *f;
    int comp;
    int nw;
    float *scratch;   /* nw x (MC_BATCH x (3 + 3 + 1)) */
} eval_job;

static void eval_batch(const eval_job *J, int w, const float *pts, int n, float *sig, float *rgb) {
    J->f->eval(J->f->user, w, J->comp, pts, n, sig, rgb);
}

static sooc_status eval_grid(const eval_job *J, const sooc_mesh_grid *g, const double step[3], float *val) {
    size_t nx = (size_t)g->res[0], ny = (size_t)g->res[1], n = nx * ny * (size_t)g->res[2];
    long nb = (long)((n + MC_BATCH - 1) / MC_BATCH);
#ifdef SOOC_HAVE_OPENMP
#pragma omp parallel for schedule(dynamic, 4) num_threads(J->nw)
#endif
    for (long b = 0; b < nb; b++) {
        int w = 0;
#ifdef SOOC_HAVE_OPENMP
        w = omp_get_thread_num();
#endif
        float *pts = J->scratch + (size_t)w * MC_BATCH * 7, *rgb = pts + 3 * MC_BATCH;
        size_t i0 = (size_t)b * MC_BATCH, cnt = n - i0 < MC_BATCH ? n - i0 : MC_BATCH;
        for (size_t q = 0; q < cnt; q++) {
            size_t id = i0 + q, ix = id % nx, iy = (id / nx) % ny, iz = id / (nx * ny);
            double p[3] = {g->lo[0] + ix * step[0], g->lo[1] + iy * step[1], g->lo[2] + iz * step[2]}, e[3];
            xform(g->T_eg, p, e);
            for (int d = 0; d < 3; d++) pts[3 * q + d] = (float)e[d];
        }
        eval_batch(J, w, pts, (int)cnt, val + i0, rgb);
    }
    for (size_t i = 0; i < n; i++)
        if (!isfinite(val[i])) return sooc_seterr(SOOC_ENUMERIC, "mesh: the field returned a non-finite density");
    return SOOC_OK;
}

static void eval_colours(const eval_job *J, const sooc_mesh_grid *g, sooc_mesh *m) {
    long nb = (long)((m->n_vert + MC_BATCH - 1) / MC_BATCH);
#ifdef SOOC_HAVE_OPENMP
#pragma omp parallel for schedule(dynamic, 4) num_threads(J->nw)
#endif
    for (long b = 0; b < nb; b++) {
        int w = 0;
#ifdef SOOC_HAVE_OPENMP
        w = omp_get_thread_num();
#endif
        float *pts = J->scratch + (size_t)w * MC_BATCH * 7, *rgb = pts + 3 * MC_BATCH, *sig = rgb + 3 * MC_BATCH;
        size_t i0 = (size_t)b * MC_BATCH, cnt = m->n_vert - i0 < MC_BATCH ? m->n_vert - i0 : MC_BATCH;
        for (size_t q = 0; q < cnt; q++) {
            const float *v = m->xyz + 3 * (i0 + q);
            double p[3] = {v[0], v[1], v[2]}, e[3];
            xform(g->T_eg, p, e);
            for (int d = 0; d < 3; d++) pts[3 * q + d] = (float)e[d];
        }
        eval_batch(J, w, pts, (int)cnt, sig, rgb);
        for (size_t q = 0; q < cnt; q++)
            for (int d = 0; d < 3; d++) {
                float x = rgb[3 * q + d];
                x = x > 0 ? (x < 1 ? x : 1) : 0;   /* also maps NaN to 0 */
                m->rgb[3 * (i0 + q) + d] = (uint8_t)lrintf(x * 255.0f);
            }
    }
}

sooc_status sooc_mesh_extract(const sooc_field *f, int comp, const sooc_mesh_grid *g, float level, int threads,
                              sooc_mesh *out) {
    out->n_vert = out->n_tri = 0;
    if (!f || !f->eval || comp < 0 || comp >= f->n_comp)
        return sooc_seterr(SOOC_EINVAL, "mesh: bad field or component %d", comp);
    for (int d = 0; d < 3; d++)
        if (g->res[d] < 2 || g->res[d] > 1024 || !(g->hi[d] > g->lo[d]))
            return sooc_seterr(SOOC_EINVAL, "mesh: grid axis %d needs 2..1024 samples and hi > lo (res %d, %g..%g)",
                               d, g->res[d], g->lo[d], g->hi[d]);
    if (!isfinite(level)) return sooc_seterr(SOOC_EINVAL, "mesh: the level must be finite");
    int nx = g->res[0], ny = g->res[1], nz = g->res[2];
    size_t n = (size_t)nx * ny * nz;
    if (n > (size_t)256 * 1024 * 1024)
        return sooc_seterr(SOOC_EINVAL, "mesh: grid of %dx%dx%d samples is too large", nx, ny, nz);
    int nw = 1;
#ifdef SOOC_HAVE_OPENMP
    nw = threads > 0 ? threads : omp_get_max_threads();
#else
    (void)threads;
#endif
    if (nw < 1) nw = 1;
    double step[3];
    for (int d = 0; d < 3; d++) step[d] = (g->hi[d] - g->lo[d]) / (g->res[d] - 1);
    sooc_status s = SOOC_OK;
    if (f->prepare && (s = f->prepare(f->user, nw, MC_BATCH))) return s;
    eval_job J = {f, comp, nw, sooc_malloc((size_t)nw * MC_BATCH * 7 * sizeof(float))};
    float *val = sooc_malloc(n * sizeof(float));
    size_t plane = (size_t)(nx + 2) * (ny + 2);
    uint32_t *eidx = sooc_malloc(plane * 5 * sizeof(uint32_t));   /* x, y edges of 2 planes + z edges */
    mc_table *T = sooc_malloc(sizeof *T);
    if (!J.scratch || !val || !eidx || !T) {
        s = SOOC_ENOMEM;
        goto done;
    }
    build_table(T);
    if ((s = eval_grid(&J, g, step, val))) goto done;
    mc_ctx c = {g, val, nx, ny, nz, level, {step[0], step[1], step[2]}, out};
    uint32_t *xe[2] = {eidx, eidx + plane}, *ye[2] = {eidx + 2 * plane, eidx + 3 * plane}, *ze = eidx + 4 * plane;
    for (size_t i = 0; i < 4 * plane; i++) eidx[i] = MC_NONE;
    /* cells (i, j, k) span samples i..i+1 etc., i from -1 (outside) to n-1 */
    for (int k = -1; k < nz && !s; k++) {
        for (size_t i = 0; i < plane; i++) ze[i] = MC_NONE;
        for (int j = -1; j < ny && !s; j++)
            for (int i = -1; i < nx && !s; i++) {
                int cfg = 0;
                for (int q = 0; q < 8; q++) cfg |= mc_inside(&c, i + (q & 1), j + (q >> 1 & 1), k + (q >> 2 & 1)) << q;
                int nt = T->n[cfg];
                if (!nt) continue;
                uint32_t v[12];
                for (int e = 0; e < 12; e++) v[e] = MC_NONE;
                if ((s = reserve_tri(out, out->n_tri + (size_t)nt))) break;
                for (int t = 0; t < 3 * nt && !s; t++) {
                    int e = T->e[cfg][t];
                    if (v[e] == MC_NONE) {
                        int bc = g_edge_base[e], ax = e >> 2;
                        int si = i + (bc & 1), sj = j + (bc >> 1 & 1), dk = bc >> 2 & 1;
                        size_t slot = (size_t)(si + 1) + (size_t)(nx + 2) * (size_t)(sj + 1);
                        uint32_t *cell = ax == 0 ? &xe[dk][slot] : ax == 1 ? &ye[dk][slot] : &ze[slot];
                        if (*cell == MC_NONE) s = mc_vertex(&c, si, sj, k + dk, ax, cell);
                        v[e] = *cell;
                    }
                    out->tri[3 * out->n_tri + t] = v[e];
                }
                out->n_tri += (size_t)nt;
            }
        /* plane k + 1 becomes the low plane of the next layer */
        uint32_t *tx = xe[0], *ty = ye[0];
        xe[0] = xe[1], ye[0] = ye[1], xe[1] = tx, ye[1] = ty;
        for (size_t i = 0; i < plane; i++) xe[1][i] = ye[1][i] = MC_NONE;
    }
    if (s) goto done;
    eval_colours(&J, g, out);
    /* grid-local -> output frame */
    for (size_t i = 0; i < out->n_vert; i++) {
        float *v = out->xyz + 3 * i;
        double p[3] = {v[0], v[1], v[2]}, o[3];
        xform(g->T_og, p, o);
        for (int d = 0; d < 3; d++) v[d] = (float)o[d];
    }
done:
    if (s) out->n_vert = out->n_tri = 0;
    sooc_free(J.scratch);
    sooc_free(val);
    sooc_free(eidx);
    sooc_free(T);
    return s;
}
