/* Object geometry for planners: tight boxes of an object's own density,
 * symmetry, calibrated spreads, and the mapper's cache (include/sooc3d/objgeom.h). */
#include "sooc3d/objgeom.h"

#include <math.h>
#include <string.h>

#include "sooc3d/mesh.h"
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

/* 1 if the point with coordinate t on axis a and (l1, l2) on the lateral axes is inside */
static int og_inside_at(og_ctx *C, int a, double t, double l1, double l2) {
    double p[3];
    uint8_t in;
    p[a] = t, p[(a + 1) % 3] = l1, p[(a + 2) % 3] = l2;
    og_eval_list(C, p, 1, &in);
    return in;
}

/* Along axis a at lateral (l1, l2), from a coordinate `in_t` known inside,
 * the crossing towards side s: march outwards by `step` until outside (the
 * wall: *at_wall = 1 if inside there), then `refine` halvings. */
static double og_cross(og_ctx *C, int a, int s, double l1, double l2, double in_t, double step, int refine,
                       int *at_wall) {
    const double wall = s ? C->box->hi[a] : C->box->lo[a], dir = s ? 1.0 : -1.0;
    double out_t = in_t;
    *at_wall = 0;
    for (;;) {
        out_t = in_t + dir * step;
        if (s ? out_t >= wall : out_t <= wall) {
            if (og_inside_at(C, a, wall, l1, l2)) {
                *at_wall = 1;
                return wall;
            }
            out_t = wall;
            break;
        }
        if (!og_inside_at(C, a, out_t, l1, l2)) break;
        in_t = out_t;
    }
    for (int it = 0; it < refine; it++) {
        double m = 0.5 * (in_t + out_t);
        if (og_inside_at(C, a, m, l1, l2)) in_t = m;
        else out_t = m;
    }
    return 0.5 * (in_t + out_t);
}

/* One face: axis a, side s (0 = min, 1 = max). first[] holds, per lateral
 * column (u, v), the index of the extreme inside sample along a (or -1).
 * The columns at the extreme index are bisected (batched); then a pattern
 * search moves laterally from the best column (steps of a half, a quarter
 * and an eighth of a grid step on each lateral axis) to where the face
 * reaches further, e.g. a cone's base rim between two sample rows. */
static double og_face(og_ctx *C, const sooc_objgeom_opts *o, int a, int s, int N, const int *first, int ext,
                      int *clipped) {
    const sooc_render_box *B = C->box;
    int a1 = (a + 1) % 3, a2 = (a + 2) % 3;
    int cols[OG_COLS][2], nc = 0, total = 0;
    for (int u = 0; u < N; u++)
        for (int v = 0; v < N; v++) total += first[u * N + v] == ext;
    int stride = total > OG_COLS ? (total + OG_COLS - 1) / OG_COLS : 1, seen = 0;
    for (int u = 0; u < N && nc < OG_COLS; u++)
        for (int v = 0; v < N && nc < OG_COLS; v++)
            if (first[u * N + v] == ext && seen++ % stride == 0) cols[nc][0] = u, cols[nc][1] = v, nc++;
    double in_c = og_coord(B, a, ext, N);
    double wall = s ? B->hi[a] : B->lo[a];
    double out_c = (s ? ext == N - 1 : ext == 0) ? wall : og_coord(B, a, s ? ext + 1 : ext - 1, N);
    double p[OG_COLS * 3], inc[OG_COLS], outc[OG_COLS];
    uint8_t ins[OG_COLS];
    for (int k = 0; k < nc; k++) {
        p[3 * k + a] = out_c;
        p[3 * k + a1] = og_coord(B, a1, cols[k][0], N);
        p[3 * k + a2] = og_coord(B, a2, cols[k][1], N);
        inc[k] = in_c;
        outc[k] = out_c;
    }
    if (out_c == wall) {   /* the grid's edge: is the density cut by the box wall? */
        og_eval_list(C, p, nc, ins);
        for (int k = 0; k < nc; k++)
            if (ins[k]) {
                *clipped = 1;
                return wall;
            }
    }
    for (int it = 0; it < o->refine; it++) {
        for (int k = 0; k < nc; k++) p[3 * k + a] = 0.5 * (inc[k] + outc[k]);
        og_eval_list(C, p, nc, ins);
        for (int k = 0; k < nc; k++) {
            if (ins[k]) inc[k] = p[3 * k + a];
            else outc[k] = p[3 * k + a];
        }
    }
    double best = in_c, bl1 = og_coord(B, a1, cols[0][0], N), bl2 = og_coord(B, a2, cols[0][1], N);
    for (int k = 0; k < nc; k++) {
        double b = 0.5 * (inc[k] + outc[k]);
        if (s ? b > best : b < best) best = b, bl1 = p[3 * k + a1], bl2 = p[3 * k + a2];
    }
    /* lateral pattern search */
    const double h1 = (B->hi[a1] - B->lo[a1]) / N, h2 = (B->hi[a2] - B->lo[a2]) / N, ha = (B->hi[a] - B->lo[a]) / N;
    for (int lev = 1; lev <= 3; lev++) {
        int moved = 1;
        for (int guard = 0; moved && guard < 4; guard++) {
            moved = 0;
            for (int d = 0; d < 4; d++) {
                double l1 = bl1 + (d == 0 ? h1 : d == 1 ? -h1 : 0) / (1 << lev);
                double l2 = bl2 + (d == 2 ? h2 : d == 3 ? -h2 : 0) / (1 << lev);
                if (l1 < B->lo[a1] || l1 > B->hi[a1] || l2 < B->lo[a2] || l2 > B->hi[a2]) continue;
                if (!og_inside_at(C, a, best, l1, l2)) continue;   /* does not reach the current face */
                int at_wall = 0;
                double b = og_cross(C, a, s, l1, l2, best, 0.5 * ha, o->refine, &at_wall);
                if (at_wall) {
                    *clipped = 1;
                    return wall;
                }
                if (s ? b > best : b < best) best = b, bl1 = l1, bl2 = l2, moved = 1;
            }
        }
    }
    return best;
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
    int *first = sooc_malloc((size_t)N * N * sizeof(int));
    sooc_status st = SOOC_OK;
    if (!C.pts || !grid || !pb || !first) {
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
    int clipped = 0;
    for (int a = 0; a < 3; a++) {
        int a1 = (a + 1) % 3, a2 = (a + 2) % 3;
        for (int s = 0; s < 2; s++) {
            /* per lateral column: the extreme inside index along a */
            for (int u = 0; u < N; u++)
                for (int v = 0; v < N; v++) {
                    int ext = -1;
                    for (int t = 0; t < N; t++) {
                        int i = s ? N - 1 - t : t, ix[3];
                        ix[a] = i, ix[a1] = u, ix[a2] = v;
                        if (grid[((size_t)ix[0] * N + ix[1]) * N + ix[2]]) {
                            ext = i;
                            break;
                        }
                    }
                    first[u * N + v] = ext;
                }
            int cl = 0;
            double b = og_face(&C, opt, a, s, N, first, s ? hi_i[a] : lo_i[a], &cl);
            if (a != 1 || s) clipped |= cl;   /* the floor (y = 0) is not a cut: objects rest on it */
            if (s) out->hi[a] = b;
            else out->lo[a] = b;
        }
    }
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
    sooc_free(first);
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
    double vy = exp(rho_theta);
    if (g->reg_n >= 2) {
        double R = hypot(g->reg_cs[0], g->reg_cs[1]) / g->reg_n;
        vy += R > 1e-12 ? -2.0 * log(R < 1 ? R : 1) : 2.0 * M_PI * M_PI / 3.0;
    }
    g->var_yaw = vy;
}

/* ---------------------------------------------------------------- cache */

typedef struct og_slot {
    uint64_t id;            /* 0 = free */
    int has_box, stale;
    float extent[3];
    float what_ref[SOOC_COGMAP_DIM_MAX];   /* z^what when the box was computed */
    float drift;            /* RMS change since then */
    sooc_map_geometry g;
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
    s->stale = !s->has_box;
    s->drift = s->has_box ? 0.0f : INFINITY;
    return SOOC_OK;
}

sooc_status sooc_objgeom_cache_refresh(sooc_objgeom_cache *c, sooc_model *m, const sooc_cogmap *map,
                                       const sooc_objgeom_opts *o, int max, int *n_done) {
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
    }
    sooc_objgeom_spread(e->rho_t, e->rho_theta, &g);
    out->geom = g;
}
