/* Object geometry for planners (include/sooc3d/mapper.h) on crafted fields
 * with known boxes: tight boxes of a sphere, a rotated-frame box, a cone, a
 * cylinder cut by the locality box and an empty field; the symmetry flag;
 * registration statistics and spreads; the cache (observe, budgeted
 * refresh, invalidate, remove). */
#include <math.h>
#include <string.h>

#include "check.h"
#include "sooc3d/render.h"
#include "sooc3d/mapper.h"

/* Analytic fields in the field frame: component 1 is a solid with density
 * 1 inside (sigma_hat 1) and 0 outside. The box frame maps into the field
 * frame by a rotation about y and a translation (like an object's box). */
typedef enum { SH_SPHERE, SH_BOX, SH_CONE, SH_CYL, SH_EMPTY } shape;
typedef struct afield {
    shape sh;
    double c[3];      /* centre (box: centre; cone: base centre) in the BOX frame */
    double d[3];      /* sphere r; box half extents; cone r, h; cylinder r, half height */
    double T_bf[16];  /* field -> box frame */
    float dens;       /* sigma_hat inside (0 = 1) */
    long evals;
} afield;

static int inside(const afield *a, const double p[3]) {
    double x = p[0] - a->c[0], y = p[1] - a->c[1], z = p[2] - a->c[2];
    switch (a->sh) {
    case SH_SPHERE: return x * x + y * y + z * z <= a->d[0] * a->d[0];
    case SH_BOX: return fabs(x) <= a->d[0] && fabs(y) <= a->d[1] && fabs(z) <= a->d[2];
    case SH_CONE: return y >= 0 && y <= a->d[1] && hypot(x, z) <= a->d[0] * (1 - y / a->d[1]);
    case SH_CYL: return fabs(y) <= a->d[1] && hypot(x, z) <= a->d[0];
    default: return 0;
    }
}

static void a_eval(void *user, int worker, int comp, const float *pts, int n, float *sig, float *rgb) {
    afield *a = user;
    (void)worker;
#ifdef _OPENMP
#pragma omp atomic
#endif
    a->evals += n;
    for (int i = 0; i < n; i++) {
        double p[3] = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]}, q[3];
        sooc_se3_apply(q, a->T_bf, p);
        sig[i] = comp == 1 && inside(a, q) ? (a->dens > 0 ? a->dens : 1.0f) : 0.0f;
        rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = 0.5f;
    }
}

/* box frame: yaw 0.7 about y, at (1.5, -1.2, 3.0) in the field frame (G of a camera 1.2 m up) */
static void setup(afield *a, sooc_field *f, sooc_render_box *boxes) {
    double R[9], t[3] = {1.5, -1.2, 3.0};
    sooc_m3_rot_y(R, 0.7);
    memset(boxes, 0, 2 * sizeof *boxes);
    boxes[1].enabled = 1;
    sooc_se3_from_rt(boxes[1].T_fb, R, t);
    sooc_se3_inverse(a->T_bf, boxes[1].T_fb);
    boxes[1].lo[0] = -0.6, boxes[1].lo[1] = 0, boxes[1].lo[2] = -0.6;
    boxes[1].hi[0] = 0.6, boxes[1].hi[1] = 1.2, boxes[1].hi[2] = 0.6;
    memset(f, 0, sizeof *f);
    f->n_comp = 2;
    f->boxes = boxes;
    f->sigma_max = 30;
    f->eval = a_eval;
    f->user = a;
}

static void check_box(const char *what, const sooc_objgeom_box *b, const double lo[3], const double hi[3],
                      double tol) {
    for (int k = 0; k < 3; k++) {
        CHECK_MSG(fabs(b->lo[k] - lo[k]) <= tol, "%s lo[%d] = %.4f, want %.4f", what, k, b->lo[k], lo[k]);
        CHECK_MSG(fabs(b->hi[k] - hi[k]) <= tol, "%s hi[%d] = %.4f, want %.4f", what, k, b->hi[k], hi[k]);
    }
}

static void test_shapes(void) {
    afield a;
    sooc_field f;
    sooc_render_box boxes[2];
    sooc_objgeom_opts o;
    sooc_objgeom_opts_default(&o);
    CHECK(o.level == SOOC_MESH_LEVEL);   /* the project's one surface level */
    sooc_objgeom_box b;
    /* a grid step is 1.2 / 8 = 15 cm; 5 halvings leave < 0.5 cm */
    const double tol = 0.006;

    memset(&a, 0, sizeof a);
    setup(&a, &f, boxes);
    a.sh = SH_SPHERE, a.c[0] = 0.1, a.c[1] = 0.35, a.c[2] = -0.05, a.d[0] = 0.3;
    CHECK_OK(sooc_objgeom_field_box(&f, 1, &boxes[1], &o, &b));
    {
        double lo[3] = {-0.2, 0.05, -0.35}, hi[3] = {0.4, 0.65, 0.25};
        check_box("sphere", &b, lo, hi, tol);
    }
    CHECK(b.flags & SOOC_GEOM_TIGHT);
    CHECK(!(b.flags & (SOOC_GEOM_CLIPPED | SOOC_GEOM_EMPTY)));
    CHECK_MSG(b.flags & SOOC_GEOM_SYMMETRIC, "sphere symmetry score %.3f", b.sym_iou);
    CHECK(b.n_eval > 0 && b.n_eval < 2500);
    long ev = a.evals;
    CHECK(ev == b.n_eval);

    /* a box 0.5 x 0.4 x 0.2 (full) standing on the floor: not symmetric */
    memset(&a, 0, sizeof a);
    setup(&a, &f, boxes);
    a.sh = SH_BOX, a.c[0] = -0.1, a.c[1] = 0.2, a.c[2] = 0.15, a.d[0] = 0.25, a.d[1] = 0.2, a.d[2] = 0.1;
    CHECK_OK(sooc_objgeom_field_box(&f, 1, &boxes[1], &o, &b));
    {
        double lo[3] = {-0.35, 0.0, 0.05}, hi[3] = {0.15, 0.4, 0.25};
        check_box("box", &b, lo, hi, tol);
    }
    CHECK_MSG(!(b.flags & SOOC_GEOM_SYMMETRIC), "box symmetry score %.3f", b.sym_iou);
    /* resting on the floor (y = 0, the box's bottom wall) is not a cut */
    CHECK(!(b.flags & SOOC_GEOM_CLIPPED));

    /* a square footprint is not symmetric either (90-degree symmetric only) */
    a.d[0] = a.d[2] = 0.2;
    CHECK_OK(sooc_objgeom_field_box(&f, 1, &boxes[1], &o, &b));
    CHECK_MSG(!(b.flags & SOOC_GEOM_SYMMETRIC) && b.sym_iou < 0.8, "square symmetry score %.3f", b.sym_iou);

    /* a cone r 0.35, h 0.5 on a raised base at y 0.1: tight box and symmetric */
    memset(&a, 0, sizeof a);
    setup(&a, &f, boxes);
    a.sh = SH_CONE, a.c[0] = 0.0, a.c[1] = 0.1, a.c[2] = 0.0, a.d[0] = 0.35, a.d[1] = 0.5;
    CHECK_OK(sooc_objgeom_field_box(&f, 1, &boxes[1], &o, &b));
    {
        /* the base rim lies between two sample rows and the apex between sample
         * columns: the lateral pattern search finds them to within 1 cm */
        double lo[3] = {-0.35, 0.1, -0.35}, hi[3] = {0.35, 0.6, 0.35};
        check_box("cone", &b, lo, hi, 0.01);
    }
    CHECK_MSG(b.flags & SOOC_GEOM_SYMMETRIC, "cone symmetry score %.3f", b.sym_iou);

    /* a cylinder wider than the locality box: cut by the walls (CLIPPED), box = the walls in x/z */
    memset(&a, 0, sizeof a);
    setup(&a, &f, boxes);
    a.sh = SH_CYL, a.c[1] = 0.6, a.d[0] = 0.9, a.d[1] = 0.3;
    CHECK_OK(sooc_objgeom_field_box(&f, 1, &boxes[1], &o, &b));
    {
        double lo[3] = {-0.6, 0.3, -0.6}, hi[3] = {0.6, 0.9, 0.6};
        check_box("clipped cylinder", &b, lo, hi, tol);
    }
    CHECK(b.flags & SOOC_GEOM_CLIPPED);

    /* a faint sphere (sigma_hat 0.3 < the level): the box at half its peak, flagged FAINT */
    memset(&a, 0, sizeof a);
    setup(&a, &f, boxes);
    a.sh = SH_SPHERE, a.c[1] = 0.4, a.d[0] = 0.25, a.dens = 0.3f;
    CHECK_OK(sooc_objgeom_field_box(&f, 1, &boxes[1], &o, &b));
    {
        double lo[3] = {-0.25, 0.15, -0.25}, hi[3] = {0.25, 0.65, 0.25};
        check_box("faint sphere", &b, lo, hi, tol);
    }
    CHECK(b.flags & SOOC_GEOM_TIGHT);
    CHECK(b.flags & SOOC_GEOM_FAINT);
    a.dens = 0.01f;   /* below SOOC_OBJGEOM_FAINT_MIN: empty */
    CHECK_OK(sooc_objgeom_field_box(&f, 1, &boxes[1], &o, &b));
    CHECK(b.flags == SOOC_GEOM_EMPTY);

    /* nothing at the level: EMPTY, no TIGHT */
    memset(&a, 0, sizeof a);
    setup(&a, &f, boxes);
    a.sh = SH_EMPTY;
    CHECK_OK(sooc_objgeom_field_box(&f, 1, &boxes[1], &o, &b));
    CHECK(b.flags == SOOC_GEOM_EMPTY);
    /* bad arguments */
    CHECK(sooc_objgeom_field_box(&f, 2, &boxes[1], &o, &b) == SOOC_EINVAL);
    sooc_render_box bad = boxes[1];
    bad.hi[1] = bad.lo[1];
    CHECK(sooc_objgeom_field_box(&f, 1, &bad, &o, &b) == SOOC_EINVAL);
    sooc_clearerr();
}

static void test_spreads(void) {
    sooc_map_geometry g;
    memset(&g, 0, sizeof g);
    /* registrations scattered around (2, -1): Welford equals the direct sums */
    const double X[5] = {2.0, 2.1, 1.95, 2.05, 1.9}, Z[5] = {-1.0, -0.9, -1.1, -1.05, -0.95};
    const double Y[5] = {0.1, 0.2, 0.15, 0.05, 0.12};
    for (int i = 0; i < 5; i++) sooc_objgeom_observe(&g, X[i], Z[i], Y[i]);
    double mx = 0, mz = 0;
    for (int i = 0; i < 5; i++) mx += X[i] / 5, mz += Z[i] / 5;
    double sxx = 0, sxz = 0, szz = 0;
    for (int i = 0; i < 5; i++) sxx += (X[i] - mx) * (X[i] - mx), sxz += (X[i] - mx) * (Z[i] - mz), szz += (Z[i] - mz) * (Z[i] - mz);
    CHECK(g.reg_n == 5);
    CHECK_CLOSE(g.reg_mean[0], mx, 1e-12, 0);
    CHECK_CLOSE(g.reg_m2[0], sxx, 1e-12, 1e-9);
    CHECK_CLOSE(g.reg_m2[1], sxz, 1e-12, 1e-9);
    CHECK_CLOSE(g.reg_m2[2], szz, 1e-12, 1e-9);
    double rho_t = log(0.01 * 0.01), rho_th = log(0.2 * 0.2);
    sooc_objgeom_spread(rho_t, rho_th, &g);
    double s0 = SOOC_OBJGEOM_SIGMA0 * SOOC_OBJGEOM_SIGMA0;
    CHECK_CLOSE(g.cov_xz[0], SOOC_OBJGEOM_K_POST * 1e-4 + SOOC_OBJGEOM_K_REG * sxx / 4 + s0, 1e-12, 1e-9);
    CHECK_CLOSE(g.cov_xz[1], SOOC_OBJGEOM_K_REG * sxz / 4, 1e-12, 1e-9);
    CHECK_CLOSE(g.cov_xz[2], SOOC_OBJGEOM_K_POST * 1e-4 + SOOC_OBJGEOM_K_REG * szz / 4 + s0, 1e-12, 1e-9);
    double c = 0, s = 0;
    for (int i = 0; i < 5; i++) c += cos(Y[i]), s += sin(Y[i]);
    CHECK_CLOSE(g.var_yaw, 0.04 - 2 * log(hypot(c, s) / 5), 1e-12, 1e-9);
    CHECK(g.var_yaw > 0.04);
    /* the yaw variance is bounded by a uniform angle's, and consistent registrations do not grow it */
    {
        sooc_map_geometry gu, gc;
        memset(&gu, 0, sizeof gu);
        memset(&gc, 0, sizeof gc);
        for (int i = 0; i < 12; i++) sooc_objgeom_observe(&gu, 0, 0, 2 * M_PI * i / 12);   /* all around */
        sooc_objgeom_spread(rho_t, log(50.0), &gu);
        CHECK_MSG(gu.var_yaw <= SOOC_MAP_YAW_VAR_MAX && gu.var_yaw > 3.0, "uniform yaws: %g", gu.var_yaw);
        double prev = INFINITY;
        for (int i = 0; i < 40; i++) {
            sooc_objgeom_observe(&gc, 0, 0, 0.3 + 0.05 * ((i % 3) - 1));   /* the same heading, +-0.05 */
            if (gc.reg_n < 3) continue;
            sooc_objgeom_spread(rho_t, rho_th, &gc);
            CHECK_MSG(gc.var_yaw <= prev + 1e-3, "%u consistent yaws: %g after %g", gc.reg_n, gc.var_yaw, prev);
            prev = gc.var_yaw;
        }
        CHECK(prev < 0.05);
    }
    /* one registration: the posterior plus SIGMA_NEW^2 */
    sooc_map_geometry g1;
    memset(&g1, 0, sizeof g1);
    sooc_objgeom_observe(&g1, 1, 1, 0);
    sooc_objgeom_observe(&g1, NAN, 1, 0);   /* ignored */
    CHECK(g1.reg_n == 1);
    sooc_objgeom_spread(rho_t, rho_th, &g1);
    CHECK_CLOSE(g1.cov_xz[0], 1e-4 + SOOC_OBJGEOM_SIGMA_NEW * SOOC_OBJGEOM_SIGMA_NEW, 1e-12, 1e-9);
    CHECK(g1.cov_xz[1] == 0);
    /* a symmetric object: yaw undefined */
    g.flags = SOOC_GEOM_TIGHT | SOOC_GEOM_SYMMETRIC;
    sooc_objgeom_spread(rho_t, rho_th, &g);
    CHECK(isnan(g.var_yaw));
    /* box -> entry fields */
    sooc_objgeom_box b;
    memset(&b, 0, sizeof b);
    b.flags = SOOC_GEOM_TIGHT;
    b.lo[0] = -0.2, b.lo[1] = 0.0, b.lo[2] = -0.1, b.hi[0] = 0.3, b.hi[1] = 0.5, b.hi[2] = 0.1;
    b.sym_iou = 0.5;
    float ext[3];
    sooc_map_geometry ga;
    memset(&ga, 0, sizeof ga);
    sooc_objgeom_apply_box(&b, ext, &ga);
    CHECK_CLOSE(ext[0], 0.5, 1e-6, 0);
    CHECK_CLOSE(ext[1], 0.5, 1e-6, 0);
    CHECK_CLOSE(ga.centre[0], 0.05, 1e-6, 0);
    CHECK_CLOSE(ga.centre[1], 0.25, 1e-6, 0);
    CHECK(ga.flags == SOOC_GEOM_TIGHT);
}

static void test_cache(void) {
    sooc_objgeom_cache *c = NULL;
    CHECK_OK(sooc_objgeom_cache_create(&c));
    if (!c) return;
    sooc_cogmap_entry e;
    memset(&e, 0, sizeof e);
    e.dim = 4;
    /* 200 entries (the table grows), each registered twice */
    for (int r = 0; r < 2; r++)
        for (uint64_t id = 1; id <= 200; id++) {
            e.id = id;
            e.X = (double)id + 0.01 * r, e.Z = -(double)id, e.Theta = 0.1;
            CHECK_OK(sooc_objgeom_cache_observe(c, &e));
        }
    CHECK(sooc_objgeom_cache_count(c) == 200);
    for (uint64_t id = 1; id <= 200; id += 2) sooc_objgeom_cache_remove(c, id);
    sooc_objgeom_cache_remove(c, 9999);   /* absent: nothing */
    CHECK(sooc_objgeom_cache_count(c) == 100);
    /* what is left is still found after the backward-shift deletions */
    int all = 1;
    for (uint64_t id = 2; id <= 200; id += 2) {
        e.id = id;
        sooc_map_entry me;
        memset(&me, 0, sizeof me);
        me.extent[0] = 1.2f;
        sooc_objgeom_cache_fill(c, &e, &me);
        all &= me.geom.reg_n == 2 && me.geom.flags == 0 && me.extent[0] == 1.2f && me.geom.cov_xz[0] > 0;
    }
    CHECK(all);
    /* a resumed entry's stored box is taken as is and is not stale */
    sooc_map_entry st;
    memset(&st, 0, sizeof st);
    st.id = 500, st.latent_dim = 4, st.what_mu[0] = 0.3f;
    st.extent[0] = 0.4f, st.extent[1] = 0.5f, st.extent[2] = 0.6f;
    st.geom.flags = SOOC_GEOM_TIGHT;
    st.geom.centre[1] = 0.25f;
    st.geom.reg_n = 7;
    CHECK_OK(sooc_objgeom_cache_seed(c, &st));
    e.id = 500;
    e.what_mu[0] = 0.3f;
    sooc_map_entry me;
    memset(&me, 0, sizeof me);
    sooc_objgeom_cache_fill(c, &e, &me);
    CHECK(me.extent[1] == 0.5f && me.geom.centre[1] == 0.25f && me.geom.reg_n == 7 && (me.geom.flags & SOOC_GEOM_TIGHT));
    /* a small latent change keeps it, a drift beyond SOOC_OBJGEOM_DRIFT makes it stale (the extent
     * stays published until recomputed) */
    e.what_mu[0] = 0.3f + 0.5f * (float)SOOC_OBJGEOM_DRIFT;
    CHECK_OK(sooc_objgeom_cache_observe(c, &e));
    memset(&me, 0, sizeof me);
    sooc_objgeom_cache_fill(c, &e, &me);
    CHECK(me.geom.reg_n == 8 && me.extent[1] == 0.5f);
    sooc_objgeom_cache_invalidate(c);
    sooc_objgeom_cache_fill(c, &e, &me);
    CHECK(me.extent[1] == 0.5f);   /* stale boxes stay published */
    sooc_objgeom_cache_clear(c);
    CHECK(sooc_objgeom_cache_count(c) == 0);
    sooc_objgeom_cache_destroy(c);
    sooc_objgeom_cache_destroy(NULL);
}

int main(void) {
    test_shapes();
    test_spreads();
    test_cache();
    return check_report("test_objgeom");
}
