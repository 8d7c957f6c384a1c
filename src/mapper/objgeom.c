/* Object geometry for planners: tight boxes of an object's own density,
 * symmetry, calibrated spreads, and the mapper's cache (include/sooc3d/mapper.h). */
#include "sooc3d/mapper.h"

#include <math.h>
#include <string.h>

#include "sooc3d/render.h"
#include "sooc3d/model.h"

#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

#define OG_BATCH 1024
#define OG_COLS 12      /* bisected columns per face */
#define OG_SYM_RAYS 16  /* symmetry test: rays per slice */
#define OG_SYM_SLICES 2
#define OG_SYM_MARCH 8  /* inward samples per ray before bisection */

void sooc_objgeom_opts_default(sooc_objgeom_opts *o) {
    o->res = 8;
    o->refine = 5;
    o->level = SOOC_MESH_LEVEL;
    o->symmetry = 1;
}

/* ------------------------------------------------------------ sampling */

typedef struct og_ctx {
    const sooc_field *f;
    int comp;
    const sooc_render_box *box;
    float level;
    float peak[16];           /* per worker: largest sigma_hat of the coarse grid */
    int nw;
    float *pts, *sig, *rgb;   /* nw x OG_BATCH each (x3 for pts, rgb) */
    long n_eval;
} og_ctx;

/* sigma_hat >= level at n box-local points p (n <= OG_BATCH) on worker w. */
static void og_eval(og_ctx *C, int w, const double *p, int n, uint8_t *inside) {
    float *pts = C->pts + (size_t)w * OG_BATCH * 3, *sig = C->sig + (size_t)w * OG_BATCH;
    float *rgb = C->rgb + (size_t)w * OG_BATCH * 3;
    const double *T = C->box->T_fb;
    for (int i = 0; i < n; i++) {
        const double *q = p + 3 * (size_t)i;
        pts[3 * i + 0] = (float)(T[0] * q[0] + T[1] * q[1] + T[2] * q[2] + T[3]);
        pts[3 * i + 1] = (float)(T[4] * q[0] + T[5] * q[1] + T[6] * q[2] + T[7]);
        pts[3 * i + 2] = (float)(T[8] * q[0] + T[9] * q[1] + T[10] * q[2] + T[11]);
    }
    C->f->eval(C->f->user, w, C->comp, pts, n, sig, rgb);
    for (int i = 0; i < n; i++) {
        inside[i] = sig[i] >= C->level;
        if (sig[i] > C->peak[w]) C->peak[w] = sig[i];
    }
}

/* Evaluate a list of points in batches (serial; small lists). */
static void og_eval_list(og_ctx *C, const double *p, int n, uint8_t *inside) {
    for (int b = 0; b < n; b += OG_BATCH) og_eval(C, 0, p + 3 * (size_t)b, n - b < OG_BATCH ? n - b : OG_BATCH, inside + b);
    C->n_eval += n;
}

static double og_coord(const sooc_render_box *b, int a, int i, int N) {
    return b->lo[a] + (i + 0.5) * (b->hi[a] - b->lo[a]) / N;
}

/* One column of a face search: along axis a towards side s at lateral
 * coordinates (l1, l2) on axes (a+1)%3, (a+2)%3; in_t is inside, out_t
 * outside (NaN: not known yet). */
typedef struct og_col {
    int a, s, face;
    double l1, l2, in_t, out_t;
    int at_wall;
} og_col;

#define OG_MAXCOL (6 * OG_COLS)

static void og_col_point(const og_col *c, double t, double *p) {
    p[c->a] = t, p[(c->a + 1) % 3] = c->l1, p[(c->a + 2) % 3] = c->l2;
}

/* The crossings of n columns, in lockstep (one batched evaluation per step):
 * columns without a known outside point march outwards by `step` (the box
 * wall: at_wall = 1 if inside there), then `refine` halvings. Afterwards
 * in_t is the crossing (the wall when at_wall). */
static void og_cross_many(og_ctx *C, og_col *c, int n, double step, int refine) {
    double p[OG_MAXCOL * 3];
    uint8_t in[OG_MAXCOL];
    int idx[OG_MAXCOL], wallp[OG_MAXCOL];
    for (int guard = 0; guard < 256; guard++) {   /* march */
        int m = 0;
        for (int k = 0; k < n; k++) {
            if (!isnan(c[k].out_t) || c[k].at_wall) continue;
            const double wall = c[k].s ? C->box->hi[c[k].a] : C->box->lo[c[k].a];
            double t = c[k].in_t + (c[k].s ? step : -step);
            wallp[m] = c[k].s ? t >= wall : t <= wall;
            og_col_point(&c[k], wallp[m] ? wall : t, p + 3 * m);
            idx[m++] = k;
        }
        if (!m) break;
        og_eval_list(C, p, m, in);
        for (int j = 0; j < m; j++) {
            og_col *q = &c[idx[j]];
            double t = p[3 * j + q->a];
            if (in[j] && wallp[j]) q->at_wall = 1, q->in_t = t;
            else if (in[j]) q->in_t = t;
            else q->out_t = t;
        }
    }
    for (int it = 0; it < refine; it++) {   /* bisection */
        int m = 0;
        for (int k = 0; k < n; k++) {
            if (c[k].at_wall) continue;
            og_col_point(&c[k], 0.5 * (c[k].in_t + c[k].out_t), p + 3 * m);
            idx[m++] = k;
        }
        if (!m) break;
        og_eval_list(C, p, m, in);
        for (int j = 0; j < m; j++) {
            og_col *q = &c[idx[j]];
            if (in[j]) q->in_t = p[3 * j + q->a];
            else q->out_t = p[3 * j + q->a];
        }
    }
    for (int k = 0; k < n; k++)
        if (!c[k].at_wall) c[k].in_t = 0.5 * (c[k].in_t + c[k].out_t);
}

/* The six faces of the tight box. For each face (axis a, side s) the grid
 * columns whose extreme inside sample is the face's extreme index (at most
 * OG_COLS of them) are bisected between that sample and the next one out
 * (or the box wall); then a lateral pattern search moves from the best
 * column by half and a quarter of a grid step on each lateral axis to where
 * the face reaches further (e.g. a cone's base rim between two sample rows,
 * or its apex between two columns). All faces run in lockstep, so every
 * step is one batched evaluation. clipped[f] = the face is the box wall. */
static void og_faces(og_ctx *C, const sooc_objgeom_opts *o, int N, const uint8_t *grid, const int lo_i[3],
                     const int hi_i[3], double lo[3], double hi[3], int clipped[6]) {
    const sooc_render_box *B = C->box;
    og_col col[OG_MAXCOL];
    int nc = 0;
    double best[6], bl1[6], bl2[6];
    for (int f = 0; f < 6; f++) {
        int a = f / 2, s = f % 2, a1 = (a + 1) % 3, a2 = (a + 2) % 3, ext = s ? hi_i[a] : lo_i[a];
        int total = 0, nf = 0;
        clipped[f] = 0;
        for (int pass = 0; pass < 2; pass++) {   /* count the extreme columns, then take up to OG_COLS evenly */
            int stride = total > OG_COLS ? (total + OG_COLS - 1) / OG_COLS : 1, seen = 0;
            for (int u = 0; u < N; u++)
                for (int v = 0; v < N; v++) {
                    int ix[3];
                    ix[a] = ext, ix[a1] = u, ix[a2] = v;
                    if (!grid[((size_t)ix[0] * N + ix[1]) * N + ix[2]]) continue;
                    int e2 = s ? ext + 1 : ext - 1, out_in = 0;
                    if (e2 >= 0 && e2 < N) {
                        ix[a] = e2;
                        out_in = grid[((size_t)ix[0] * N + ix[1]) * N + ix[2]];
                    }
                    if (out_in) continue;   /* cannot happen at the extreme index */
                    if (!pass) {
                        total++;
                        continue;
                    }
                    if (seen++ % stride || nf >= OG_COLS) continue;
                    og_col *q = &col[nc++];
                    q->a = a, q->s = s, q->face = f, q->at_wall = 0;
                    q->l1 = og_coord(B, a1, u, N), q->l2 = og_coord(B, a2, v, N);
                    q->in_t = og_coord(B, a, ext, N);
                    q->out_t = e2 >= 0 && e2 < N ? og_coord(B, a, e2, N) : NAN;
                    nf++;
                }
        }
        best[f] = og_coord(B, a, ext, N), bl1[f] = bl2[f] = NAN;
    }
    /* the step reaches the wall from an edge sample in one march */
    og_cross_many(C, col, nc, 0.5 * (B->hi[0] - B->lo[0]) / N + 0.5 * (B->hi[1] - B->lo[1]) / N +
                                  0.5 * (B->hi[2] - B->lo[2]) / N, o->refine);
    for (int k = 0; k < nc; k++) {
        int f = col[k].face, s = f % 2;
        if (col[k].at_wall) clipped[f] = 1;
        if (isnan(bl1[f]) || (s ? col[k].in_t > best[f] : col[k].in_t < best[f]))
            best[f] = col[k].in_t, bl1[f] = col[k].l1, bl2[f] = col[k].l2;
    }
    for (int f = 0; f < 6; f++)
        if (clipped[f]) best[f] = f % 2 ? B->hi[f / 2] : B->lo[f / 2];
    /* lateral pattern search, all faces in lockstep */
    for (int lev = 1; lev <= 2; lev++)
        for (int guard = 0; guard < 2; guard++) {
            double p[OG_MAXCOL * 3];
            uint8_t in[OG_MAXCOL];
            og_col pr[OG_MAXCOL];
            int np = 0;
            for (int f = 0; f < 6; f++) {
                if (clipped[f] || isnan(bl1[f])) continue;
                int a = f / 2, a1 = (a + 1) % 3, a2 = (a + 2) % 3;
                double h1 = (B->hi[a1] - B->lo[a1]) / N / (1 << lev), h2 = (B->hi[a2] - B->lo[a2]) / N / (1 << lev);
                for (int d = 0; d < 4; d++) {
                    double l1 = bl1[f] + (d == 0 ? h1 : d == 1 ? -h1 : 0), l2 = bl2[f] + (d == 2 ? h2 : d == 3 ? -h2 : 0);
                    if (l1 < B->lo[a1] || l1 > B->hi[a1] || l2 < B->lo[a2] || l2 > B->hi[a2]) continue;
                    og_col *q = &pr[np++];
                    q->a = a, q->s = f % 2, q->face = f, q->l1 = l1, q->l2 = l2, q->in_t = best[f], q->out_t = NAN;
                    q->at_wall = 0;
                }
            }
            if (!np) break;
            for (int k = 0; k < np; k++) og_col_point(&pr[k], pr[k].in_t, p + 3 * k);
            og_eval_list(C, p, np, in);   /* does the probe reach the current face? */
            int m = 0;
            for (int k = 0; k < np; k++)
                if (in[k]) pr[m++] = pr[k];
            if (!m) break;
            double hmin = B->hi[0] - B->lo[0];
            for (int a = 1; a < 3; a++) hmin = B->hi[a] - B->lo[a] < hmin ? B->hi[a] - B->lo[a] : hmin;
            og_cross_many(C, pr, m, 0.5 * hmin / N, o->refine);
            int moved = 0;
            for (int k = 0; k < m; k++) {
                int f = pr[k].face, s = f % 2;
                if (pr[k].at_wall) {
                    clipped[f] = 1, best[f] = pr[k].in_t;
                    continue;
                }
                if (s ? pr[k].in_t > best[f] : pr[k].in_t < best[f])
                    best[f] = pr[k].in_t, bl1[f] = pr[k].l1, bl2[f] = pr[k].l2, moved = 1;
            }
            if (!moved) break;
        }
    for (int f = 0; f < 6; f++) {
        if (f % 2) hi[f / 2] = best[f];
        else lo[f / 2] = best[f];
    }
}

/* Rotational symmetry about the vertical axis through the tight box's
 * centre (cx, cz): on OG_SYM_SLICES horizontal slices, the outer boundary
 * radius r(phi) along OG_SYM_RAYS rays (marched inwards from the circle
 * circumscribing the footprint, then bisected). Returns the smallest over
 * the slices of 1 - (max r - min r) / mean r (1 = a disc; a square 0.65). */
static double og_symmetry(og_ctx *C, const double lo[3], const double hi[3], int refine, double *pbuf,
                          uint8_t *ibuf) {
    double cx = 0.5 * (lo[0] + hi[0]), cz = 0.5 * (lo[2] + hi[2]);
    double R = 0.5 * hypot(hi[0] - lo[0], hi[2] - lo[2]) * 1.02;
    if (!(R > 0)) return 1.0;
    const int NR = OG_SYM_RAYS * OG_SYM_SLICES;
    double rin[OG_SYM_RAYS * OG_SYM_SLICES], rout[OG_SYM_RAYS * OG_SYM_SLICES];
    for (int k = 0; k < NR; k++) rin[k] = -1, rout[k] = R;
    /* march: radii R (1 - (t + 1) / OG_SYM_MARCH), t = 0.. */
    for (int t = 0; t < OG_SYM_MARCH; t++) {
        double r = R * (1.0 - (t + 1.0) / (OG_SYM_MARCH + 1.0));
        int n = 0;
        for (int k = 0; k < NR; k++) {
            int sl = k / OG_SYM_RAYS;
            double a = 2.0 * M_PI * (k % OG_SYM_RAYS) / OG_SYM_RAYS;
            pbuf[3 * n] = cx + r * cos(a), pbuf[3 * n + 1] = lo[1] + (hi[1] - lo[1]) * (sl + 1) / (OG_SYM_SLICES + 1.0);
            pbuf[3 * n + 2] = cz + r * sin(a);
            n++;
        }
        og_eval_list(C, pbuf, n, ibuf);
        for (int k = 0; k < NR; k++) {
            if (rin[k] >= 0) continue;
            if (ibuf[k]) rin[k] = r;
            else rout[k] = r;
        }
    }
    for (int it = 0; it < refine; it++) {
        for (int k = 0; k < NR; k++) {
            int sl = k / OG_SYM_RAYS;
            double a = 2.0 * M_PI * (k % OG_SYM_RAYS) / OG_SYM_RAYS, r = rin[k] >= 0 ? 0.5 * (rin[k] + rout[k]) : 0;
            pbuf[3 * k] = cx + r * cos(a), pbuf[3 * k + 1] = lo[1] + (hi[1] - lo[1]) * (sl + 1) / (OG_SYM_SLICES + 1.0);
            pbuf[3 * k + 2] = cz + r * sin(a);
        }
        og_eval_list(C, pbuf, NR, ibuf);
        for (int k = 0; k < NR; k++) {
            if (rin[k] < 0) continue;
            double r = 0.5 * (rin[k] + rout[k]);
            if (ibuf[k]) rin[k] = r;
            else rout[k] = r;
        }
    }
    double worst = 1.0;
    for (int sl = 0; sl < OG_SYM_SLICES; sl++) {
        double mn = INFINITY, mx = 0, sum = 0;
        for (int j = 0; j < OG_SYM_RAYS; j++) {
            int k = sl * OG_SYM_RAYS + j;
            double r = rin[k] >= 0 ? 0.5 * (rin[k] + rout[k]) : 0;
            mn = r < mn ? r : mn;
            mx = r > mx ? r : mx;
            sum += r;
        }
        double sc = sum > 0 ? 1.0 - (mx - mn) / (sum / OG_SYM_RAYS) : 1.0;
        if (sc < worst) worst = sc;
    }
    return worst;
}

sooc_status sooc_objgeom_field_box(const sooc_field *f, int comp, const sooc_render_box *box,
                                   const sooc_objgeom_opts *opt, sooc_objgeom_box *out) {
    sooc_objgeom_opts od;
    if (!opt) {
        sooc_objgeom_opts_default(&od);
        opt = &od;
    }
    memset(out, 0, sizeof *out);
    out->sym_iou = 1.0;
    if (!f || !f->eval || !box || comp < 0 || comp >= f->n_comp)
        return sooc_seterr(SOOC_EINVAL, "objgeom: bad field, component %d or box", comp);
    for (int a = 0; a < 3; a++)
        if (!(box->hi[a] > box->lo[a])) return sooc_seterr(SOOC_EINVAL, "objgeom: empty box on axis %d", a);
    const int N = opt->res < 4 ? 4 : opt->res > 64 ? 64 : opt->res;
    int nw = 1;
#ifdef SOOC_HAVE_OPENMP
    nw = omp_get_max_threads();
    if (nw < 1) nw = 1;
    if (nw > 16) nw = 16;
#endif
    og_ctx C = {f, comp, box, opt->level, {0}, nw, NULL, NULL, NULL, 0};
    int faint = 0;
    size_t NN = (size_t)N * N * N, nsym = (size_t)OG_SYM_SLICES * OG_SYM_RAYS;
    C.pts = sooc_malloc((size_t)nw * OG_BATCH * 7 * sizeof(float));
    uint8_t *grid = sooc_malloc(NN + 2 * nsym);
    double *pb = sooc_malloc((size_t)nw * OG_BATCH * 3 * sizeof(double) + 2 * nsym * 3 * sizeof(double));
    sooc_status st = SOOC_OK;
    if (!C.pts || !grid || !pb) {
        st = sooc_seterr(SOOC_ENOMEM, "objgeom: out of memory (grid %d^3)", N);
        goto done;
    }
    C.sig = C.pts + (size_t)nw * OG_BATCH * 3;
    C.rgb = C.sig + (size_t)nw * OG_BATCH;
    if (f->prepare && (st = f->prepare(f->user, nw, OG_BATCH))) goto done;
    /* coarse grid, in batches of OG_BATCH consecutive cells */
grid:;
    long nb = (long)((NN + OG_BATCH - 1) / OG_BATCH);
#ifdef SOOC_HAVE_OPENMP
#pragma omp parallel for num_threads(nw) schedule(dynamic, 1)
#endif
    for (long b = 0; b < nb; b++) {
        int w = 0;
#ifdef SOOC_HAVE_OPENMP
        w = omp_get_thread_num();
#endif
        double *p = pb + (size_t)w * OG_BATCH * 3;
        size_t i0 = (size_t)b * OG_BATCH, n = NN - i0 < OG_BATCH ? NN - i0 : OG_BATCH;
        for (size_t k = 0; k < n; k++) {
            size_t id = i0 + k;
            int ix = (int)(id / ((size_t)N * N)), iy = (int)(id / N % N), iz = (int)(id % N);
            p[3 * k] = og_coord(box, 0, ix, N), p[3 * k + 1] = og_coord(box, 1, iy, N), p[3 * k + 2] = og_coord(box, 2, iz, N);
        }
        og_eval(&C, w, p, (int)n, grid + i0);
    }
    C.n_eval += (long)NN;
    int lo_i[3] = {N, N, N}, hi_i[3] = {-1, -1, -1};
    for (size_t id = 0; id < NN; id++) {
        if (!grid[id]) continue;
        int ix[3] = {(int)(id / ((size_t)N * N)), (int)(id / N % N), (int)(id % N)};
        for (int a = 0; a < 3; a++) {
            if (ix[a] < lo_i[a]) lo_i[a] = ix[a];
            if (ix[a] > hi_i[a]) hi_i[a] = ix[a];
        }
    }
    if (hi_i[0] < 0) {
        /* nothing reaches the level: a faint object gets the box at half its
         * peak density (SOOC_GEOM_FAINT), if that peak is not negligible */
        float peak = 0;
        for (int w = 0; w < nw; w++) peak = C.peak[w] > peak ? C.peak[w] : peak;
        if (!faint && peak >= SOOC_OBJGEOM_FAINT_MIN) {
            faint = 1;
            C.level = 0.5f * peak;
            goto grid;
        }
        out->flags = SOOC_GEOM_EMPTY;
        out->n_eval = C.n_eval;
        goto done;
    }
    int cl[6], clipped = 0;
    og_faces(&C, opt, N, grid, lo_i, hi_i, out->lo, out->hi, cl);
    for (int f = 0; f < 6; f++) clipped |= f != 2 && cl[f];   /* the floor (y min) is not a cut: objects rest on it */
    out->flags = SOOC_GEOM_TIGHT | (clipped ? SOOC_GEOM_CLIPPED : 0u) | (faint ? SOOC_GEOM_FAINT : 0u);
    if (opt->symmetry) {
        out->sym_iou = og_symmetry(&C, out->lo, out->hi, opt->refine, pb, grid);
        if (out->sym_iou >= SOOC_OBJGEOM_SYM_IOU) out->flags |= SOOC_GEOM_SYMMETRIC;
    }
    out->n_eval = C.n_eval;
done:
    sooc_free(C.pts);
    sooc_free(grid);
    sooc_free(pb);
    return st;
}

/* ------------------------------------------------------- a map's entry */

sooc_status sooc_objgeom_entry_box(sooc_model *m, const sooc_cogmap *map, uint64_t id, const sooc_objgeom_opts *o,
                                   sooc_objgeom_box *out) {
    memset(out, 0, sizeof *out);
    sooc_cogmap_entry e;
    sooc_status st = sooc_cogmap_get(map, id, &e);
    if (st) return st;
    const sooc_model_config *c = sooc_model_get_config(m);
    double u = c->unit_m, R = c->box_rh * u, Hb = c->box_hb * u;
    sooc_intrinsics K;
    memset(&K, 0, sizeof K);
    K.width = K.height = 64;
    K.fx = K.fy = 32;
    K.cx = K.cy = 32;
    /* a virtual camera 3 R_h in front of the entry, level, at half the box
     * height: the whole box is in view (90 degree field of view); if the map
     * has more in-view entries than a field holds, try the other sides */
    for (int side = 0; side < 4; side++) {
        double a = e.Theta + side * M_PI / 2, D = 3.0 * R + c->t_near * u;
        double fw[3] = {-sin(a), 0, -cos(a)};   /* looking along fw, from (X, Z) - D fw */
        double dn[3] = {0, -1, 0}, rt[3] = {dn[1] * fw[2] - dn[2] * fw[1], dn[2] * fw[0] - dn[0] * fw[2],
                                           dn[0] * fw[1] - dn[1] * fw[0]};
        double T[16] = {rt[0], dn[0], fw[0], e.X - D * fw[0], rt[1], dn[1], fw[1], 0.5 * Hb,
                        rt[2], dn[2], fw[2], e.Z - D * fw[2], 0, 0, 0, 1};
        sooc_model_field *F = NULL;
        if ((st = sooc_model_field_create(&F, m, map, T, &K, SOOC_RENDER_MAX_COMP - 1, NULL))) return st;
        const sooc_field *f = sooc_model_field_get(F);
        int k = 1;
        while (k < f->n_comp && sooc_model_field_comp_id(F, k) != id) k++;
        if (k < f->n_comp) {
            st = f->boxes ? sooc_objgeom_field_box(f, k, &f->boxes[k], o, out)
                          : sooc_seterr(SOOC_EINVAL, "objgeom: the model's field has no boxes");
            sooc_model_field_destroy(F);
            return st;
        }
        sooc_model_field_destroy(F);
    }
    return sooc_seterr(SOOC_ENOTFOUND, "objgeom: entry %llu is not in the field of a camera in front of it",
                       (unsigned long long)id);
}

/* --------------------------------------------------------------- fields */

void sooc_objgeom_apply_box(const sooc_objgeom_box *b, float extent[3], sooc_map_geometry *g) {
    g->flags = b->flags;
    g->sym_iou = (float)b->sym_iou;
    for (int a = 0; a < 3; a++) {
        extent[a] = (float)(b->hi[a] - b->lo[a]);
        g->centre[a] = (float)(0.5 * (b->hi[a] + b->lo[a]));
    }
}

void sooc_objgeom_observe(sooc_map_geometry *g, double X, double Z, double yaw) {
    if (!isfinite(X) || !isfinite(Z) || !isfinite(yaw)) return;
    if (g->reg_n < UINT32_MAX) g->reg_n++;
    double n = g->reg_n, dx = X - g->reg_mean[0], dz = Z - g->reg_mean[1];
    g->reg_mean[0] += dx / n;
    g->reg_mean[1] += dz / n;
    double ex = X - g->reg_mean[0], ez = Z - g->reg_mean[1];
    g->reg_m2[0] += dx * ex;
    g->reg_m2[1] += dx * ez;
    g->reg_m2[2] += dz * ez;
    g->reg_cs[0] += cos(yaw);
    g->reg_cs[1] += sin(yaw);
}

void sooc_objgeom_spread(double rho_t, double rho_theta, sooc_map_geometry *g) {
    double vp = SOOC_OBJGEOM_K_POST * exp(rho_t);
    if (g->reg_n >= 2) {
        double k = SOOC_OBJGEOM_K_REG / (g->reg_n - 1.0), s0 = SOOC_OBJGEOM_SIGMA0 * SOOC_OBJGEOM_SIGMA0;
        g->cov_xz[0] = vp + k * g->reg_m2[0] + s0;
        g->cov_xz[1] = k * g->reg_m2[1];
        g->cov_xz[2] = vp + k * g->reg_m2[2] + s0;
    } else {
        double s1 = SOOC_OBJGEOM_SIGMA_NEW * SOOC_OBJGEOM_SIGMA_NEW;
        g->cov_xz[0] = g->cov_xz[2] = vp + s1;
        g->cov_xz[1] = 0;
    }
    if (g->flags & SOOC_GEOM_SYMMETRIC) {
        g->var_yaw = NAN;
        return;
    }
    /* the posterior's variance plus the registrations' circular spread -2 ln R (R: mean resultant length),
     * at most that of a uniform angle: consistent registrations keep R near 1, more of them do not grow it */
    double vy = exp(rho_theta);
    if (g->reg_n >= 2) {
        double R = hypot(g->reg_cs[0], g->reg_cs[1]) / g->reg_n;
        vy += R > 1e-12 ? -2.0 * log(R < 1 ? R : 1) : SOOC_MAP_YAW_VAR_MAX;
    }
    g->var_yaw = vy < SOOC_MAP_YAW_VAR_MAX ? vy : SOOC_MAP_YAW_VAR_MAX;
}

/* ---------------------------------------------------------------- cache */

typedef struct og_slot {
    uint64_t id;            /* 0 = free */
    int has_box, stale;
    float extent[3];
    float what_ref[SOOC_COGMAP_DIM_MAX];   /* z^what when the box was computed */
    float drift;            /* RMS change since then */
    sooc_map_geometry g;
    int has_surf;           /* the box of its observed surface (sooc_objgeom_cache_set_surface) */
    float surf_extent[3], surf_centre[3];
} og_slot;

struct sooc_objgeom_cache {
    og_slot *s;
    size_t cap, n;          /* cap: power of two */
};

sooc_status sooc_objgeom_cache_create(sooc_objgeom_cache **out) {
    *out = NULL;
    sooc_objgeom_cache *c = sooc_calloc(1, sizeof *c);
    if (!c) return SOOC_ENOMEM;
    c->cap = 64;
    c->s = sooc_calloc(c->cap, sizeof *c->s);
    if (!c->s) {
        sooc_free(c);
        return SOOC_ENOMEM;
    }
    *out = c;
    return SOOC_OK;
}

void sooc_objgeom_cache_destroy(sooc_objgeom_cache *c) {
    if (!c) return;
    sooc_free(c->s);
    sooc_free(c);
}

void sooc_objgeom_cache_clear(sooc_objgeom_cache *c) {
    memset(c->s, 0, c->cap * sizeof *c->s);
    c->n = 0;
}

size_t sooc_objgeom_cache_count(const sooc_objgeom_cache *c) { return c->n; }

static size_t og_hash(uint64_t id, size_t cap) {
    id *= 0x9e3779b97f4a7c15ULL;
    return (size_t)(id >> 17) & (cap - 1);
}

static og_slot *og_find(const sooc_objgeom_cache *c, uint64_t id) {
    for (size_t i = og_hash(id, c->cap);; i = (i + 1) & (c->cap - 1)) {
        if (c->s[i].id == id) return &c->s[i];
        if (!c->s[i].id) return NULL;
    }
}

static og_slot *og_insert(sooc_objgeom_cache *c, uint64_t id) {
    og_slot *e = og_find(c, id);
    if (e) return e;
    if (2 * (c->n + 1) > c->cap) {   /* grow: load factor <= 1/2 */
        size_t nc = c->cap * 2;
        og_slot *ns = sooc_calloc(nc, sizeof *ns);
        if (!ns) return NULL;
        for (size_t i = 0; i < c->cap; i++) {
            if (!c->s[i].id) continue;
            size_t j = og_hash(c->s[i].id, nc);
            while (ns[j].id) j = (j + 1) & (nc - 1);
            ns[j] = c->s[i];
        }
        sooc_free(c->s);
        c->s = ns;
        c->cap = nc;
    }
    size_t j = og_hash(id, c->cap);
    while (c->s[j].id) j = (j + 1) & (c->cap - 1);
    memset(&c->s[j], 0, sizeof c->s[j]);
    c->s[j].id = id;
    c->n++;
    return &c->s[j];
}

void sooc_objgeom_cache_remove(sooc_objgeom_cache *c, uint64_t id) {
    og_slot *e = og_find(c, id);
    if (!e) return;
    size_t i = (size_t)(e - c->s);
    memset(&c->s[i], 0, sizeof c->s[i]);
    c->n--;
    /* backward-shift deletion: re-place the run after the hole */
    for (size_t j = (i + 1) & (c->cap - 1); c->s[j].id; j = (j + 1) & (c->cap - 1)) {
        og_slot t = c->s[j];
        memset(&c->s[j], 0, sizeof c->s[j]);
        size_t k = og_hash(t.id, c->cap);
        while (c->s[k].id) k = (k + 1) & (c->cap - 1);
        c->s[k] = t;
    }
}

int sooc_objgeom_cache_has(const sooc_objgeom_cache *c, uint64_t id) { return og_find(c, id) != NULL; }

void sooc_objgeom_cache_invalidate(sooc_objgeom_cache *c) {
    for (size_t i = 0; i < c->cap; i++)
        if (c->s[i].id) c->s[i].stale = 1, c->s[i].drift = INFINITY;
}

static float og_drift(const float *a, const float *b, int d) {
    double s = 0;
    for (int i = 0; i < d; i++) s += ((double)a[i] - b[i]) * ((double)a[i] - b[i]);
    return d > 0 ? (float)sqrt(s / d) : 0.0f;
}

sooc_status sooc_objgeom_cache_observe(sooc_objgeom_cache *c, const sooc_cogmap_entry *e) {
    og_slot *s = og_insert(c, e->id);
    if (!s) return sooc_seterr(SOOC_ENOMEM, "objgeom: cache out of memory (%zu entries)", c->n);
    sooc_objgeom_observe(&s->g, e->X, e->Z, e->Theta);
    int d = e->dim < 0 ? 0 : e->dim > SOOC_COGMAP_DIM_MAX ? SOOC_COGMAP_DIM_MAX : e->dim;
    s->drift = s->has_box ? og_drift(e->what_mu, s->what_ref, d) : INFINITY;
    s->stale = !s->has_box || s->drift > SOOC_OBJGEOM_DRIFT;
    return SOOC_OK;
}

sooc_status sooc_objgeom_cache_seed(sooc_objgeom_cache *c, const sooc_map_entry *e) {
    og_slot *s = og_insert(c, e->id);
    if (!s) return sooc_seterr(SOOC_ENOMEM, "objgeom: cache out of memory (%zu entries)", c->n);
    s->g = e->geom;
    int d = e->latent_dim < 0 ? 0 : e->latent_dim > SOOC_COGMAP_DIM_MAX ? SOOC_COGMAP_DIM_MAX : e->latent_dim;
    memset(s->what_ref, 0, sizeof s->what_ref);
    memcpy(s->what_ref, e->what_mu, (size_t)d * sizeof(float));
    s->has_box = (e->geom.flags & (SOOC_GEOM_TIGHT | SOOC_GEOM_EMPTY)) != 0;
    memcpy(s->extent, e->extent, sizeof s->extent);
    s->has_surf = (e->geom.flags & SOOC_GEOM_SURFACE) != 0;
    if (s->has_surf) {
        memcpy(s->surf_extent, e->extent, sizeof s->surf_extent);
        memcpy(s->surf_centre, e->geom.centre, sizeof s->surf_centre);
    }
    s->stale = !s->has_box;
    s->drift = s->has_box ? 0.0f : INFINITY;
    return SOOC_OK;
}

sooc_status sooc_objgeom_cache_set_surface(sooc_objgeom_cache *c, uint64_t id, const float extent[3],
                                           const float centre[3]) {
    og_slot *s = og_insert(c, id);
    if (!s) return sooc_seterr(SOOC_ENOMEM, "objgeom: cache out of memory (%zu entries)", c->n);
    s->has_surf = 1;
    memcpy(s->surf_extent, extent, sizeof s->surf_extent);
    memcpy(s->surf_centre, centre, sizeof s->surf_centre);
    return SOOC_OK;
}

sooc_status sooc_objgeom_cache_refresh(sooc_objgeom_cache *c, sooc_model *m, const sooc_cogmap *map,
                                       const sooc_objgeom_opts *o, int max, int *n_done, uint64_t *done_ids) {
    int done = 0;
    if (n_done) *n_done = 0;
    while (max < 0 || done < max) {
        og_slot *best = NULL;
        for (size_t i = 0; i < c->cap; i++) {   /* O(cache) scan: ids only, no decoder work */
            og_slot *s = &c->s[i];
            if (!s->id || !s->stale) continue;
            if (!best || s->drift > best->drift || (s->drift == best->drift && s->id < best->id)) best = s;
        }
        if (!best) break;
        sooc_cogmap_entry e;
        if (sooc_cogmap_get(map, best->id, &e)) {   /* gone from the map */
            sooc_clearerr();
            sooc_objgeom_cache_remove(c, best->id);
            continue;
        }
        sooc_objgeom_box b;
        sooc_status st = sooc_objgeom_entry_box(m, map, best->id, o, &b);
        if (st == SOOC_ENOTFOUND) {   /* not reachable by a field now: try again later */
            sooc_clearerr();
            best->stale = 0;
            continue;
        }
        if (st) return st;
        sooc_objgeom_apply_box(&b, best->extent, &best->g);
        memcpy(best->what_ref, e.what_mu, sizeof best->what_ref);
        best->has_box = 1;
        best->stale = 0;
        best->drift = 0;
        if (done_ids && max >= 0) done_ids[done] = best->id;
        done++;
        if (n_done) *n_done = done;
    }
    return SOOC_OK;
}

void sooc_objgeom_cache_fill(const sooc_objgeom_cache *c, const sooc_cogmap_entry *e, sooc_map_entry *out) {
    const og_slot *s = og_find(c, e->id);
    sooc_map_geometry g;
    memset(&g, 0, sizeof g);
    if (s) {
        g = s->g;
        if (s->has_box) memcpy(out->extent, s->extent, sizeof out->extent);
        else g.flags = 0;
        if (s->has_surf) {   /* the observed surface's box replaces the density's */
            memcpy(out->extent, s->surf_extent, sizeof out->extent);
            memcpy(g.centre, s->surf_centre, sizeof g.centre);
            g.flags = (g.flags & SOOC_GEOM_SYMMETRIC) | SOOC_GEOM_TIGHT | SOOC_GEOM_SURFACE;
        }
    }
    sooc_objgeom_spread(e->rho_t, e->rho_theta, &g);
    out->geom = g;
}
