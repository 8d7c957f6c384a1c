/* Cognitive map tests: frame transforms (+ gradient transposes by finite
 * differences), the in-view test on crafted layouts, top-K with ties, the
 * grid query against brute force, id persistence / no reuse, bit-identical
 * out-of-view entries, registration rules, removal stress, layout blocks. */
#include "check.h"
#include "sooc3d/cogmap.h"
#include "cogmap_cam.h"

#include <math.h>
#include <string.h>

#define D 8

static void rand_entry(sooc_rng *r, sooc_cogmap_entry *e, double X, double Z) {
    memset(e, 0, sizeof *e);
    e->X = X;
    e->Z = Z;
    e->Theta = sooc_rng_range(r, -3, 3);
    e->rho_t = (float)sooc_rng_range(r, -4, 1);
    e->rho_theta = (float)sooc_rng_range(r, -4, 1);
    e->pres_logit = (float)sooc_rng_range(r, 0, 5);
    e->dim = D;
    for (int i = 0; i < D; i++) {
        e->what_mu[i] = (float)sooc_rng_normal(r);
        e->what_logvar[i] = (float)sooc_rng_range(r, -3, 0);
    }
    e->obs_count = 1;
}

static sooc_cogmap *new_map(double cell) {
    sooc_cogmap_params p;
    sooc_cogmap_params_default(&p);
    p.dim = D;
    p.layout_dim = 4;
    p.cell_size = cell;
    p.capacity = 4;  /* exercise growth */
    sooc_cogmap *m = NULL;
    CHECK_OK(sooc_cogmap_create(&m, &p));
    return m;
}

/* ------------------------------------------------------------------ */

static void test_transforms(void) {
    sooc_rng r;
    sooc_rng_seed(&r, 1, 0);
    const int S = SOOC_LAM_SIZE(D);
    for (int it = 0; it < 200; it++) {
        sooc_floor_frame f = {sooc_rng_range(&r, -50, 50), sooc_rng_range(&r, -50, 50), sooc_rng_range(&r, -M_PI, M_PI)};
        sooc_cogmap_entry e, w;
        rand_entry(&r, &e, f.X + sooc_rng_range(&r, -8, 8), f.Z + sooc_rng_range(&r, -8, 8));
        float lam[SOOC_LAM_MAX];
        sooc_cogmap_lam_to_local(&f, &e, lam);
        /* matches geom's conversion */
        double wv[3] = {e.X, e.Z, e.Theta}, lv[3];
        sooc_floor_to_local(&f, wv, lv);
        CHECK_CLOSE(lam[0], lv[0], 1e-5, 1e-6);
        CHECK_CLOSE(lam[1], lv[1], 1e-5, 1e-6);
        CHECK_CLOSE(lam[2], lv[2], 1e-5, 1e-6);
        CHECK(lam[2] > -M_PI - 1e-6 && lam[2] <= M_PI + 1e-6);
        CHECK(lam[SOOC_LAM_RHO_T] == e.rho_t && lam[SOOC_LAM_RHO_TH] == e.rho_theta);
        CHECK(lam[SOOC_LAM_PRES(D)] == e.pres_logit);
        CHECK(!memcmp(lam + SOOC_LAM_WHAT_MU, e.what_mu, D * sizeof(float)));
        CHECK(!memcmp(lam + SOOC_LAM_WHAT_LV(D), e.what_logvar, D * sizeof(float)));
        /* round trip world -> G -> world */
        w = e;
        sooc_cogmap_lam_to_world(&f, D, lam, &w);
        CHECK_CLOSE(w.X, e.X, 2e-5, 0);
        CHECK_CLOSE(w.Z, e.Z, 2e-5, 0);
        CHECK_CLOSE(sooc_wrap_angle(w.Theta - e.Theta), 0, 2e-6, 0);
        CHECK(!memcmp(w.what_mu, e.what_mu, sizeof e.what_mu) && w.rho_t == e.rho_t && w.pres_logit == e.pres_logit);
        /* G -> world -> G */
        float lam2[SOOC_LAM_MAX];
        sooc_cogmap_lam_to_local(&f, &w, lam2);
        for (int i = 0; i < S; i++) CHECK_CLOSE(lam2[i], lam[i], 2e-5, 1e-6);
    }

    /* gradient transposes by central differences (the maps are affine in the
     * means, so differences are exact up to rounding) */
    for (int it = 0; it < 20; it++) {
        sooc_floor_frame fq = {sooc_rng_range(&r, -5, 5), sooc_rng_range(&r, -5, 5), sooc_rng_range(&r, -3, 3)};
        sooc_floor_frame fr = {sooc_rng_range(&r, -5, 5), sooc_rng_range(&r, -5, 5), sooc_rng_range(&r, -3, 3)};
        float rq[SOOC_LAM_MAX], g[SOOC_LAM_MAX];
        for (int i = 0; i < S; i++) rq[i] = (float)sooc_rng_normal(&r);
        /* (1) query: local = Q(world). L = <rq, Q(W)> ; dL/dW = J^T rq */
        sooc_cogmap_entry e;
        rand_entry(&r, &e, fq.X + 2, fq.Z + 3);
        e.Theta = sooc_wrap_angle(fq.psi + 0.3); /* keep away from the wrap seam */
        memset(g, 0, sizeof g);
        sooc_cogmap_grad_local_to_world(&fq, D, rq, g);
        const double h = 1e-2;
        for (int j = 0; j < 3; j++) {
            double Lp = 0, Lm = 0;
            for (int sgn = -1; sgn <= 1; sgn += 2) {
                sooc_cogmap_entry x = e;
                double *v = j == 0 ? &x.X : j == 1 ? &x.Z : &x.Theta;
                *v += sgn * h;
                float l[SOOC_LAM_MAX];
                sooc_cogmap_lam_to_local(&fq, &x, l);
                double L = 0;
                for (int i = 0; i < S; i++) L += (double)rq[i] * l[i];
                if (sgn > 0) Lp = L; else Lm = L;
            }
            CHECK_CLOSE(g[j], (Lp - Lm) / (2 * h), 1e-3, 1e-3);
        }
        for (int j = 3; j < S; j++) CHECK(g[j] == rq[j]);
        /* accumulation: a second call doubles */
        float g2[SOOC_LAM_MAX];
        memcpy(g2, g, sizeof g);
        sooc_cogmap_grad_local_to_world(&fq, D, rq, g2);
        for (int j = 0; j < S; j++) CHECK_CLOSE(g2[j], 2 * g[j], 1e-6, 1e-6);

        /* (2) registration: W = Reg(local). L = <rw, Reg(l)> */
        float lam0[SOOC_LAM_MAX];
        sooc_cogmap_lam_to_local(&fr, &e, lam0);
        memset(g, 0, sizeof g);
        sooc_cogmap_grad_world_to_local(&fr, D, rq, g);
        for (int j = 0; j < 3; j++) {
            double L[2];
            for (int k = 0; k < 2; k++) {
                float l[SOOC_LAM_MAX];
                memcpy(l, lam0, sizeof l);
                l[j] += (float)(k ? h : -h);
                sooc_cogmap_entry x = e;
                sooc_cogmap_lam_to_world(&fr, D, l, &x);
                double th = sooc_wrap_angle(x.Theta - e.Theta);
                L[k] = rq[0] * x.X + rq[1] * x.Z + rq[2] * th;
            }
            CHECK_CLOSE(g[j], (L[1] - L[0]) / (2 * h), 1e-3, 1e-3);
        }

        /* (3) route: local_q = Q_fq(Reg_fr(l)) */
        memset(g, 0, sizeof g);
        sooc_cogmap_grad_route(&fr, &fq, D, rq, g);
        for (int j = 0; j < 3; j++) {
            double L[2];
            for (int k = 0; k < 2; k++) {
                float l[SOOC_LAM_MAX], lq[SOOC_LAM_MAX];
                memcpy(l, lam0, sizeof l);
                l[j] += (float)(k ? h : -h);
                sooc_cogmap_entry x = e;
                sooc_cogmap_lam_to_world(&fr, D, l, &x);
                sooc_cogmap_lam_to_local(&fq, &x, lq);
                double dth = sooc_wrap_angle(lq[2] - (e.Theta - fq.psi));
                L[k] = rq[0] * lq[0] + rq[1] * lq[1] + rq[2] * dth;
            }
            CHECK_CLOSE(g[j], (L[1] - L[0]) / (2 * h), 1e-3, 1e-3);
        }
        for (int j = 3; j < S; j++) CHECK(g[j] == rq[j]);
    }
}

static void test_inview(void) {
    sooc_cogmap_camera c;
    sooc_cogmap_entry e;
    sooc_rng r;
    sooc_rng_seed(&r, 2, 0);
    cogmap_test_cam(&c, 0, 1.5, 0, 0, 0); /* looking along +z */
    rand_entry(&r, &e, 0, 3);
    CHECK(sooc_cogmap_in_view(&c, &e));          /* in front */
    e.Z = -3;
    CHECK(!sooc_cogmap_in_view(&c, &e));         /* behind */
    e.X = 5; e.Z = 3;
    CHECK(!sooc_cogmap_in_view(&c, &e));         /* outside the FOV */
    e.X = 0; e.Z = 9;
    CHECK(!sooc_cogmap_in_view(&c, &e));         /* beyond d_clip */
    e.Z = 7.9;
    CHECK(sooc_cogmap_in_view(&c, &e));          /* just inside d_clip */
    e.Z = 0.05;
    CHECK(!sooc_cogmap_in_view(&c, &e));         /* nearer than t_near */
    /* camera right is world -x at yaw 0; half-FOV at z = 3 is 1.92 m */
    e.X = -1.8; e.Z = 3;
    CHECK(sooc_cogmap_in_view(&c, &e));
    e.X = -2.2;
    CHECK(!sooc_cogmap_in_view(&c, &e));         /* centre outside ... */
    c.mode = SOOC_INVIEW_CORNERS;
    CHECK(sooc_cogmap_in_view(&c, &e));          /* ... but a corner inside */
    e.X = -3.5;
    CHECK(!sooc_cogmap_in_view(&c, &e));
    e.X = 0; e.Z = -1;                           /* behind: no corner in front */
    CHECK(!sooc_cogmap_in_view(&c, &e));
    c.mode = SOOC_INVIEW_CENTRE;
    /* yawed camera: psi = pi/2 looks along +x */
    cogmap_test_cam(&c, 10, 1.5, 10, M_PI / 2, 0);
    e.X = 13; e.Z = 10;
    CHECK(sooc_cogmap_in_view(&c, &e));
    e.X = 7;
    CHECK(!sooc_cogmap_in_view(&c, &e));
    e.X = 10; e.Z = 13;
    CHECK(!sooc_cogmap_in_view(&c, &e));
    /* pitched down 45 deg from 1.5 m: the floor right below-ahead is in view, far objects are not */
    cogmap_test_cam(&c, 0, 1.5, 0, 0, 45 * M_PI / 180);
    e.X = 0; e.Z = 1.0;
    CHECK(sooc_cogmap_in_view(&c, &e));
    e.Z = 7;
    CHECK(!sooc_cogmap_in_view(&c, &e));         /* centre projects above the image */
}

static int cmp_rank(const void *a, const void *b) {
    const sooc_cogmap_entry *x = a, *y = b;
    if (x->pres_logit != y->pres_logit) return x->pres_logit > y->pres_logit ? -1 : 1;
    return x->id < y->id ? -1 : x->id > y->id;
}

static void test_topk(void) {
    sooc_cogmap *m = new_map(2.0);
    sooc_rng r;
    sooc_rng_seed(&r, 3, 0);
    const float pres[10] = {1, 3, 3, 2, 5, 5, 0.5f, 3, -1, 5};
    for (int i = 0; i < 10; i++) {
        sooc_cogmap_entry e;
        rand_entry(&r, &e, -1 + 0.2 * i, 2 + 0.3 * i);
        e.pres_logit = pres[i];
        uint64_t id;
        CHECK_OK(sooc_cogmap_insert(m, &e, &id));
        CHECK(id == (uint64_t)i + 1);
    }
    /* out-of-view distractors with high presence */
    for (int i = 0; i < 5; i++) {
        sooc_cogmap_entry e;
        rand_entry(&r, &e, 0, -3 - i);
        e.pres_logit = 10;
        CHECK_OK(sooc_cogmap_insert(m, &e, NULL));
    }
    sooc_cogmap_camera c;
    cogmap_test_cam(&c, 0, 1.5, 0, 0, 0);
    sooc_cogmap_slot sl[SOOC_COGMAP_K_MAX];
    int n, nin;
    sooc_floor_frame gf;
    CHECK_OK(sooc_cogmap_query(m, &c, 4, sl, &n, &gf, &nin));
    CHECK(n == 4 && nin == 10);
    const uint64_t want4[4] = {5, 6, 10, 2};  /* 5.0 x3 by id, then the first 3.0 */
    for (int i = 0; i < n && i < 4; i++) CHECK_MSG(sl[i].id == want4[i], "slot %d id %llu", i, (unsigned long long)sl[i].id);
    CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, NULL, NULL));
    const uint64_t want7[7] = {5, 6, 10, 2, 3, 8, 4};
    CHECK(n == 7);
    for (int i = 0; i < n; i++) CHECK(sl[i].id == want7[i]);
    CHECK_OK(sooc_cogmap_query(m, &c, 20, sl, &n, NULL, NULL));
    CHECK(n == 10);
    CHECK(sl[9].id == 9);  /* logit -1 last */
    /* slot contents are the G-frame λ of the entry */
    sooc_cogmap_entry e;
    CHECK_OK(sooc_cogmap_get(m, sl[0].id, &e));
    float lam[SOOC_LAM_MAX] = {0};
    sooc_cogmap_lam_to_local(&gf, &e, lam);
    CHECK(!memcmp(lam, sl[0].lam, sizeof lam));
    CHECK_OK(sooc_cogmap_query(m, &c, 0, sl, &n, NULL, &nin));
    CHECK(n == 0 && nin == 10);
    CHECK(sooc_cogmap_query(m, &c, SOOC_COGMAP_K_MAX + 1, sl, &n, NULL, NULL) == SOOC_EINVAL);
    sooc_cogmap_destroy(m);
}

/* The grid query equals a brute-force scan (in-view set, top-K order). */
static void test_query_vs_bruteforce(void) {
    sooc_rng r;
    sooc_rng_seed(&r, 4, 0);
    for (int cs = 0; cs < 3; cs++) {
        double cell = cs == 0 ? 0.7 : cs == 1 ? 2.0 : 5.0;
        sooc_cogmap *m = new_map(cell);
        const int N = 4000;
        for (int i = 0; i < N; i++) {
            sooc_cogmap_entry e;
            rand_entry(&r, &e, sooc_rng_range(&r, -30, 30), sooc_rng_range(&r, -30, 30));
            e.pres_logit = (float)(sooc_rng_below(&r, 8)) * 0.5f; /* many ties */
            CHECK_OK(sooc_cogmap_insert(m, &e, NULL));
        }
        sooc_cogmap_entry *all = sooc_malloc(N * sizeof *all), *in = sooc_malloc(N * sizeof *in);
        size_t n_all;
        CHECK_OK(sooc_cogmap_entries(m, all, N, &n_all));
        CHECK(n_all == (size_t)N);
        int bad = 0;
        for (int it = 0; it < 200; it++) {
            sooc_cogmap_camera c;
            cogmap_test_cam(&c, sooc_rng_range(&r, -25, 25), sooc_rng_range(&r, 0.3, 2.5), sooc_rng_range(&r, -25, 25),
                     sooc_rng_range(&r, -M_PI, M_PI), sooc_rng_range(&r, -0.3, 1.0));
            c.mode = (it & 1) ? SOOC_INVIEW_CORNERS : SOOC_INVIEW_CENTRE;
            int k = 1 + (int)sooc_rng_below(&r, 20);
            size_t nin_bf = 0;
            for (size_t i = 0; i < n_all; i++)
                if (sooc_cogmap_in_view(&c, &all[i])) in[nin_bf++] = all[i];
            qsort(in, nin_bf, sizeof *in, cmp_rank);
            sooc_cogmap_slot sl[SOOC_COGMAP_K_MAX];
            int n, nin;
            CHECK_OK(sooc_cogmap_query(m, &c, k, sl, &n, NULL, &nin));
            if (nin != (int)nin_bf || n != (int)(nin_bf < (size_t)k ? nin_bf : (size_t)k)) bad++;
            else
                for (int i = 0; i < n; i++)
                    if (sl[i].id != in[i].id) bad++;
        }
        CHECK_MSG(bad == 0, "cell %g: %d mismatches against brute force", cell, bad);
        sooc_free(all);
        sooc_free(in);
        sooc_cogmap_destroy(m);
    }
}

static void fill_slot(float *lam, double x, double z, float a) {
    memset(lam, 0, SOOC_LAM_SIZE(D) * sizeof(float));
    lam[SOOC_LAM_X] = (float)x;
    lam[SOOC_LAM_Z] = (float)z;
    lam[SOOC_LAM_RHO_T] = -2;
    lam[SOOC_LAM_PRES(D)] = a;
}

static void test_registration_and_ids(void) {
    sooc_cogmap *m = new_map(2.0);
    const int S = SOOC_LAM_SIZE(D);
    sooc_cogmap_camera c;
    cogmap_test_cam(&c, 0, 1.5, 0, 0, 0);
    sooc_cogmap_slot sl[8];
    int n;
    sooc_floor_frame gf;
    CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, &gf, NULL));
    CHECK(n == 0); /* first view: only priors */
    /* view 0: 4 padded slots, one below 0.5, one exactly 0.5 */
    float lam[8 * SOOC_LAM_MAX];
    uint64_t src[8] = {0}, ids[8], rem[8];
    fill_slot(lam + 0 * S, 0.5, 3, 2.0f);
    fill_slot(lam + 1 * S, -0.5, 4, -0.1f);
    fill_slot(lam + 2 * S, 1.0, 5, 0.0f);
    fill_slot(lam + 3 * S, -1.0, 2, 1.0f);
    sooc_cogmap_reg_stats st;
    CHECK_OK(sooc_cogmap_register(m, &gf, 4, lam, src, 100, 0, ids, rem, &st));
    CHECK(st.n_registered == 3 && st.n_new == 3 && st.n_removed == 0 && st.n_updated == 0);
    CHECK(ids[0] == 1 && ids[1] == 0 && ids[2] == 2 && ids[3] == 3);
    CHECK(sooc_cogmap_count(m) == 3);
    sooc_cogmap_entry e;
    CHECK_OK(sooc_cogmap_get(m, 2, &e));
    CHECK_CLOSE(e.X, 1.0, 1e-6, 0); /* G x = world x at yaw 0 */
    CHECK_CLOSE(e.Z, 5.0, 1e-6, 0);
    CHECK(e.first_seen_ns == 100 && e.last_seen_ns == 100 && e.obs_count == 1 && e.last_view == 0);

    /* view 1 from another pose: retrieve, update id 1, drop id 2, keep 3, add one */
    cogmap_test_cam(&c, 0.3, 1.5, -0.5, -0.2, 0.1);
    CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, &gf, NULL));
    CHECK(n == 3);
    for (int i = 0; i < n; i++) {
        memcpy(lam + i * S, sl[i].lam, S * sizeof(float));
        src[i] = sl[i].id;
        CHECK(sl[i].last_view == 0);
    }
    int i2 = -1;
    for (int i = 0; i < n; i++)
        if (src[i] == 2) i2 = i;
    CHECK(i2 >= 0);
    if (i2 >= 0) lam[i2 * S + SOOC_LAM_PRES(D)] = -0.5f;
    fill_slot(lam + 3 * S, 0, 6, 3.0f);
    src[3] = 0;
    CHECK_OK(sooc_cogmap_register(m, &gf, 4, lam, src, 200, 1, ids, rem, &st));
    CHECK(st.n_registered == 3 && st.n_new == 1 && st.n_updated == 2 && st.n_removed == 1);
    CHECK(rem[0] == 2);
    CHECK(ids[3] == 4);  /* fresh id: 2 is not reused */
    CHECK(sooc_cogmap_get(m, 2, &e) == SOOC_ENOTFOUND);
    CHECK_OK(sooc_cogmap_get(m, 1, &e));
    CHECK(e.first_seen_ns == 100 && e.last_seen_ns == 200 && e.obs_count == 2 && e.last_view == 1);
    CHECK_CLOSE(e.X, 0.5, 1e-5, 0);  /* unchanged λ -> same world position */
    CHECK_CLOSE(e.Z, 3.0, 1e-5, 0);

    /* validation: unknown or repeated source id, non-finite -> error, map unchanged */
    size_t before = sooc_cogmap_count(m);
    src[0] = 2;  /* removed */
    CHECK(sooc_cogmap_register(m, &gf, 1, lam, src, 300, 2, ids, rem, &st) == SOOC_ENOTFOUND);
    src[0] = 1;
    src[1] = 1;
    CHECK(sooc_cogmap_register(m, &gf, 2, lam, src, 300, 2, ids, rem, &st) == SOOC_EINVAL);
    src[1] = 0;
    lam[S + 4] = NAN;
    CHECK(sooc_cogmap_register(m, &gf, 2, lam, src, 300, 2, ids, rem, &st) == SOOC_ENUMERIC);
    CHECK(sooc_cogmap_count(m) == before);

    /* a re-registered entry moves through the grid */
    cogmap_test_cam(&c, 0, 1.5, 0, 0, 0);
    CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, &gf, NULL));
    sooc_floor_frame far = {40, 40, 0};
    uint64_t one = 1;
    float l1[SOOC_LAM_MAX];
    fill_slot(l1, 0, 3, 1.0f);
    CHECK_OK(sooc_cogmap_register(m, &far, 1, l1, &one, 400, 3, ids, rem, &st));
    CHECK_OK(sooc_cogmap_get(m, 1, &e));
    CHECK_CLOSE(e.Z, 43, 1e-6, 0);
    int nin;
    CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, NULL, &nin));
    for (int i = 0; i < n; i++) CHECK(sl[i].id != 1);
    cogmap_test_cam(&c, 40, 1.5, 40, 0, 0);
    CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, NULL, NULL));
    CHECK(n == 1 && sl[0].id == 1);

    /* clear without reset keeps the id counter; load continues after max */
    uint64_t next = sooc_cogmap_next_id(m);
    sooc_cogmap_clear(m, 0);
    CHECK(sooc_cogmap_count(m) == 0 && sooc_cogmap_next_id(m) == next);
    sooc_cogmap_entry le[2];
    sooc_rng rr;
    sooc_rng_seed(&rr, 9, 0);
    rand_entry(&rr, &le[0], 1, 1);
    rand_entry(&rr, &le[1], 2, 2);
    le[0].id = 100;
    le[1].id = 50;
    CHECK_OK(sooc_cogmap_load(m, le, 2));
    CHECK(sooc_cogmap_next_id(m) == 101);
    le[1].id = 100;
    CHECK(sooc_cogmap_load(m, le, 2) == SOOC_EINVAL);
    sooc_cogmap_clear(m, 1);
    CHECK(sooc_cogmap_next_id(m) == 1);
    sooc_cogmap_destroy(m);
}

static void test_out_of_view_identical(void) {
    sooc_rng r;
    sooc_rng_seed(&r, 5, 0);
    sooc_cogmap *m = new_map(2.0);
    const int N = 3000, S = SOOC_LAM_SIZE(D);
    for (int i = 0; i < N; i++) {
        sooc_cogmap_entry e;
        rand_entry(&r, &e, sooc_rng_range(&r, -20, 20), sooc_rng_range(&r, -20, 20));
        CHECK_OK(sooc_cogmap_insert(m, &e, NULL));
    }
    sooc_cogmap_entry *a = sooc_malloc(2 * N * sizeof *a), *b = sooc_malloc(2 * N * sizeof *b);
    int bad = 0, touched_total = 0;
    for (int v = 0; v < 20; v++) {
        size_t na, nb;
        CHECK_OK(sooc_cogmap_entries(m, a, 2 * N, &na));
        sooc_cogmap_camera c;
        cogmap_test_cam(&c, sooc_rng_range(&r, -15, 15), 1.5, sooc_rng_range(&r, -15, 15), sooc_rng_range(&r, -3, 3), 0.2);
        sooc_cogmap_slot sl[7];
        int n;
        sooc_floor_frame gf;
        CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, &gf, NULL));
        float lam[7 * SOOC_LAM_MAX];
        uint64_t src[7];
        for (int i = 0; i < 7; i++) {
            if (i < n) {
                memcpy(lam + i * S, sl[i].lam, S * sizeof(float));
                lam[i * S] += 0.1f;
                lam[i * S + SOOC_LAM_PRES(D)] = (i % 3 == 0) ? -1.0f : 1.0f;
                src[i] = sl[i].id;
            } else {
                fill_slot(lam + i * S, 0, 2 + i, 1.0f);
                src[i] = 0;
            }
        }
        CHECK_OK(sooc_cogmap_register(m, &gf, 7, lam, src, v, v, NULL, NULL, NULL));
        CHECK_OK(sooc_cogmap_entries(m, b, 2 * N, &nb));
        /* every entry that was not retrieved is bit-identical */
        size_t j = 0;
        for (size_t i = 0; i < na; i++) {
            int retrieved = 0;
            for (int s = 0; s < n; s++)
                if (src[s] == a[i].id) retrieved = 1;
            if (retrieved) { touched_total++; continue; }
            while (j < nb && b[j].id < a[i].id) j++;
            if (j >= nb || b[j].id != a[i].id || memcmp(&a[i], &b[j], sizeof a[i])) bad++;
        }
    }
    CHECK_MSG(bad == 0, "%d out-of-view entries changed", bad);
    CHECK(touched_total > 20);
    sooc_free(a);
    sooc_free(b);
    sooc_cogmap_destroy(m);
}

/* Random insert/remove/move against a plain array model (hash deletion, swap-remove, cell moves). */
static void test_stress(void) {
    sooc_rng r;
    sooc_rng_seed(&r, 6, 0);
    sooc_cogmap *m = new_map(1.0);
    enum { CAP = 3000 };
    static uint64_t live[CAP];
    static double lx[CAP];
    int nl = 0, bad = 0;
    for (int it = 0; it < 40000; it++) {
        uint32_t op = sooc_rng_below(&r, 10);
        if ((op < 5 && nl < CAP) || nl == 0) {
            sooc_cogmap_entry e;
            rand_entry(&r, &e, sooc_rng_range(&r, -10, 10), sooc_rng_range(&r, -10, 10));
            uint64_t id;
            CHECK_OK(sooc_cogmap_insert(m, &e, &id));
            live[nl] = id;
            lx[nl++] = e.X;
        } else if (op < 8) {
            uint32_t k = sooc_rng_below(&r, (uint32_t)nl);
            if (sooc_cogmap_remove(m, live[k])) bad++;
            live[k] = live[nl - 1];
            lx[k] = lx[--nl];
        } else {
            uint32_t k = sooc_rng_below(&r, (uint32_t)nl);
            sooc_cogmap_entry e;
            if (sooc_cogmap_get(m, live[k], &e)) { bad++; continue; }
            e.X = sooc_rng_range(&r, -10, 10);
            CHECK_OK(sooc_cogmap_insert(m, &e, NULL));
            lx[k] = e.X;
        }
    }
    CHECK(sooc_cogmap_count(m) == (size_t)nl);
    for (int i = 0; i < nl; i++) {
        sooc_cogmap_entry e;
        if (sooc_cogmap_get(m, live[i], &e) || e.X != lx[i]) bad++;
    }
    /* the grid agrees: a wide top-down camera sees every entry exactly once */
    sooc_cogmap_camera c;
    cogmap_test_cam(&c, 0, 30, 0, 0, 1.55);
    c.d_clip = 100;
    c.K.fx = c.K.fy = 5;
    int n, nin;
    sooc_cogmap_slot sl[1];
    CHECK_OK(sooc_cogmap_query(m, &c, 1, sl, &n, NULL, &nin));
    CHECK_MSG(nin == nl, "wide view sees %d of %d", nin, nl);
    CHECK(bad == 0);
    CHECK(sooc_cogmap_remove(m, 999999) == SOOC_ENOTFOUND);
    sooc_cogmap_destroy(m);
}

static void test_layout_and_alloc(void) {
    sooc_cogmap *m = new_map(2.0);
    int32_t bi, bj;
    double ol[2];
    sooc_cogmap_camera c;
    cogmap_test_cam(&c, 1, 1.5, 1, 0, 0.2);
    CHECK_OK(sooc_cogmap_active_block(m, c.T_wc, 8, &bi, &bj, ol));
    /* ground point 4 m ahead along +z from (1, 1): (1, 5) -> block (0, 1) with B_s = 4 */
    CHECK(bi == 0 && bj == 1);
    CHECK_CLOSE(ol[0], 1, 1e-9, 0);  /* origin (2, 6); G's x axis is world +x at yaw 0 */
    CHECK_CLOSE(ol[1], 5, 1e-9, 0);
    float mu[4] = {1, 2, 3, 4}, lv[4] = {-1, -2, -3, -4}, mu2[4], lv2[4];
    CHECK(sooc_cogmap_layout_get(m, bi, bj, mu2, lv2) == SOOC_ENOTFOUND);
    CHECK_OK(sooc_cogmap_layout_set(m, bi, bj, mu, lv));
    CHECK_OK(sooc_cogmap_layout_set(m, -3, 7, lv, mu));
    CHECK_OK(sooc_cogmap_layout_get(m, bi, bj, mu2, lv2));
    CHECK(!memcmp(mu, mu2, sizeof mu) && !memcmp(lv, lv2, sizeof lv));
    CHECK_OK(sooc_cogmap_layout_get(m, -3, 7, mu2, lv2));
    CHECK(!memcmp(lv, mu2, sizeof mu));
    CHECK(sooc_cogmap_layout_count(m) == 2);
    sooc_cogmap_block_of(m, -0.1, 4.0, &bi, &bj);
    CHECK(bi == -1 && bj == 1);

    /* query does not allocate */
    sooc_rng r;
    sooc_rng_seed(&r, 7, 0);
    for (int i = 0; i < 500; i++) {
        sooc_cogmap_entry e;
        rand_entry(&r, &e, sooc_rng_range(&r, -10, 10), sooc_rng_range(&r, -10, 10));
        CHECK_OK(sooc_cogmap_insert(m, &e, NULL));
    }
    sooc_alloc_stats s0, s1;
    sooc_alloc_get_stats(&s0);
    sooc_cogmap_slot sl[7];
    int n;
    for (int i = 0; i < 100; i++) {
        cogmap_test_cam(&c, sooc_rng_range(&r, -10, 10), 1.5, sooc_rng_range(&r, -10, 10), sooc_rng_range(&r, -3, 3), 0.1);
        CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, NULL, NULL));
    }
    sooc_alloc_get_stats(&s1);
    CHECK(s1.n_alloc == s0.n_alloc);
    /* bad camera */
    cogmap_test_cam(&c, 0, 1.5, 0, 0, M_PI / 2);
    CHECK(sooc_cogmap_query(m, &c, 7, sl, &n, NULL, NULL) == SOOC_EINVAL);
    sooc_cogmap_destroy(m);
}

/* Allocation failures: every operation either succeeds or returns ENOMEM,
 * and the map stays consistent (every counted entry retrievable and found
 * by a wide query). */
static void test_fault_injection(void) {
    int bad = 0, failures = 0;
    for (uint64_t n_ok = 0; n_ok < 80; n_ok++) {
        sooc_cogmap *m = NULL;
        sooc_alloc_fault_inject(n_ok, 1);
        sooc_cogmap_params p;
        sooc_cogmap_params_default(&p);
        p.dim = D;
        p.capacity = 2;
        p.cell_size = 1.0;
        sooc_status st = sooc_cogmap_create(&m, &p);
        if (st) {
            sooc_alloc_fault_inject(0, 0);
            if (st != SOOC_ENOMEM || m) bad++;
            failures++;
            continue;
        }
        sooc_rng r;
        sooc_rng_seed(&r, 77, n_ok);
        for (int i = 0; i < 40; i++) {
            sooc_cogmap_entry e;
            rand_entry(&r, &e, sooc_rng_range(&r, -6, 6), sooc_rng_range(&r, -6, 6));
            st = sooc_cogmap_insert(m, &e, NULL);
            if (st && st != SOOC_ENOMEM) bad++;
            if (st) failures++;
        }
        sooc_floor_frame gf = {0, 0, 0.3};
        float lam[4 * SOOC_LAM_MAX];
        for (int i = 0; i < 4; i++) fill_slot(lam + i * SOOC_LAM_SIZE(D), 9 + i, 9, 1.0f);
        st = sooc_cogmap_register(m, &gf, 4, lam, NULL, 0, 0, NULL, NULL, NULL);
        if (st && st != SOOC_ENOMEM) bad++;
        sooc_alloc_fault_inject(0, 0);
        size_t n = sooc_cogmap_count(m), nn;
        sooc_cogmap_entry *all = sooc_malloc((n + 1) * sizeof *all);
        sooc_cogmap_entries(m, all, n, &nn);
        for (size_t i = 0; i < nn; i++) {
            sooc_cogmap_entry e;
            if (sooc_cogmap_get(m, all[i].id, &e) || memcmp(&e, &all[i], sizeof e)) bad++;
        }
        sooc_free(all);
        sooc_cogmap_camera c;
        cogmap_test_cam(&c, 0, 30, 0, 0, 1.55);
        c.d_clip = 100;
        c.K.fx = c.K.fy = 5;
        int ns, nin;
        sooc_cogmap_slot sl[1];
        CHECK_OK(sooc_cogmap_query(m, &c, 1, sl, &ns, NULL, &nin));
        if ((size_t)nin != n) bad++;
        sooc_cogmap_destroy(m);
    }
    CHECK_MSG(bad == 0, "%d inconsistencies under allocation failures", bad);
    CHECK(failures > 10);
}

/* Duplicate merge among one view's registered entries: pairs closer than the
 * radius keep the better-observed entry (tie: smaller id), chains collapse to
 * one, entries not in the list are bit-identical even when they are close,
 * radius <= 0 and unknown ids do nothing. */
static void test_merge(void) {
    sooc_cogmap *m = new_map(1.0);
    sooc_rng r;
    sooc_rng_seed(&r, 11, 0);
    /* id: 1 (0,0) obs 3 | 2 (0.2,0) obs 5 | 3 (0.1,0.25) obs 5 | 4 (2,2) obs 1 |
     * 5 (2.3,2) obs 1 | 6 (0.1,-0.1) not in the view's list | 7 (5,5) */
    const double P[7][2] = {{0, 0}, {0.2, 0}, {0.1, 0.25}, {2, 2}, {2.3, 2}, {0.1, -0.1}, {5, 5}};
    const uint32_t obs[7] = {3, 5, 5, 1, 1, 9, 2};
    sooc_cogmap_entry e[7];
    for (int i = 0; i < 7; i++) {
        rand_entry(&r, &e[i], P[i][0], P[i][1]);
        e[i].obs_count = obs[i];
        uint64_t id;
        CHECK_OK(sooc_cogmap_insert(m, &e[i], &id));
        CHECK(id == (uint64_t)i + 1);
        e[i].id = id;
    }
    uint64_t ids[8] = {1, 0, 2, 3, 4, 5, 99, 7}, rem[8];
    int nr = -1;
    sooc_cogmap_merge(m, ids, 8, 0.0, rem, &nr);   /* radius 0: nothing */
    CHECK(nr == 0 && sooc_cogmap_count(m) == 7);
    sooc_cogmap_merge(m, ids, 8, 0.35, rem, &nr);
    /* 1-2 (0.2 m): 2 kept (obs 5 > 3); 2-3 (0.27 m): tie on obs, 2 kept (older);
     * 4-5 (0.3 m): tie, 4 kept; 6 is close to 1 and 2 but not in the list; 7 alone */
    CHECK_MSG(nr == 3, "removed %d", nr);
    CHECK(rem[0] == 1 && rem[1] == 3 && rem[2] == 5);
    CHECK(ids[0] == 0 && ids[2] == 2 && ids[3] == 0 && ids[4] == 4 && ids[5] == 0 && ids[6] == 99 && ids[7] == 7);
    CHECK(sooc_cogmap_count(m) == 4);
    sooc_cogmap_entry g;
    const int kept[4] = {1, 3, 5, 6};   /* indices of ids 2, 4, 6, 7 */
    for (int i = 0; i < 4; i++) {
        CHECK_OK(sooc_cogmap_get(m, e[kept[i]].id, &g));
        CHECK(!memcmp(&g, &e[kept[i]], sizeof g));
    }
    CHECK(sooc_cogmap_get(m, 1, &g) == SOOC_ENOTFOUND && sooc_cogmap_get(m, 3, &g) == SOOC_ENOTFOUND);
    /* the grid still agrees with a brute-force in-view count */
    sooc_cogmap_camera c;
    cogmap_test_cam(&c, 0, 1.5, -3, 0, 0.4);
    sooc_cogmap_slot sl[8];
    int n, nin;
    sooc_floor_frame gf;
    CHECK_OK(sooc_cogmap_query(m, &c, 7, sl, &n, &gf, &nin));
    int bf = 0;
    for (int i = 0; i < 4; i++) bf += sooc_cogmap_in_view(&c, &e[kept[i]]);
    CHECK_MSG(nin == bf && bf >= 1, "in view %d, brute force %d", nin, bf);
    sooc_cogmap_merge(m, ids, 8, 10.0, NULL, &nr);   /* everything left in the list: one survives */
    CHECK(nr == 2 && sooc_cogmap_count(m) == 2);
    sooc_cogmap_destroy(m);

    /* a new entry (obs 1) next to an entry the view did not register is a
     * duplicate of it: the new one goes, the other stays bit-identical; a
     * re-registered entry (obs > 1) next to it stays too. Grid cells of 1 m:
     * the neighbour search crosses a cell border. */
    m = new_map(1.0);
    const double Q[4][2] = {{-3.0, -3.0}, {-3.2, -3.0}, {-2.75, -3.0}, {-3.0, -1.0}};
    const uint32_t qobs[4] = {4, 1, 3, 1};   /* old, new, re-registered, new alone */
    sooc_cogmap_entry q[4];
    for (int i = 0; i < 4; i++) {
        rand_entry(&r, &q[i], Q[i][0], Q[i][1]);
        q[i].obs_count = qobs[i];
        CHECK_OK(sooc_cogmap_insert(m, &q[i], &q[i].id));
    }
    uint64_t vids[3] = {q[1].id, q[2].id, q[3].id};
    sooc_cogmap_merge(m, vids, 3, 0.35, rem, &nr);
    CHECK_MSG(nr == 1 && rem[0] == q[1].id && vids[0] == 0 && vids[1] == q[2].id && vids[2] == q[3].id,
              "removed %d", nr);
    CHECK(sooc_cogmap_count(m) == 3 && sooc_cogmap_get(m, q[1].id, &g) == SOOC_ENOTFOUND);
    for (int i = 0; i < 4; i++)
        if (i != 1) {
            CHECK_OK(sooc_cogmap_get(m, q[i].id, &g));
            CHECK(!memcmp(&g, &q[i], sizeof g));
        }
    sooc_cogmap_destroy(m);
}

int main(void) {
    test_transforms();
    test_inview();
    test_topk();
    test_query_vs_bruteforce();
    test_registration_and_ids();
    test_out_of_view_identical();
    test_merge();
    test_stress();
    test_layout_and_alloc();
    test_fault_injection();
    sooc_alloc_stats st;
    sooc_alloc_get_stats(&st);
    CHECK_MSG(st.live_bytes == 0, "%llu bytes leaked", (unsigned long long)st.live_bytes);
    return check_report("test_cogmap");
}
