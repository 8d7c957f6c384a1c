/* bench_cogmap: cognitive-map query time against map size at constant object
 * density (the scene grows with the number of entries), plus registration
 * and an SQLite keyframe commit.
 *
 *   bench_cogmap [--max-exp E] [--queries Q] [--density RHO] [--db-entries N] [--cell M]
 *
 * Scene: N entries uniform in a square of side sqrt(N / RHO) (RHO = 0.25
 * objects per m^2 by default), d = 32, NSLOT = 7, a 64x64 camera with fx = 50,
 * t_near 0.1, d_clip 8, 1.5 m high, looking 0.2 rad down. Query poses: a
 * random walk through the scene (0.5 m steps, random turns) and, separately,
 * uniformly random poses (worst case for caches). Validates the grid query
 * against a brute-force scan before timing. Last line: JSON. */
#include "sooc3d/cogmap.h"
#include "../tests/cogmap/cogmap_cam.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define D 32
#define NSLOT 7

/* bench cameras: 1.5 m high, 0.2 rad down */
static void make_cam(sooc_cogmap_camera *c, double x, double z, double psi) { cogmap_test_cam(c, x, 1.5, z, psi, 0.2); }

static void rand_entry(sooc_rng *r, sooc_cogmap_entry *e, double side) {
    memset(e, 0, sizeof *e);
    e->X = sooc_rng_range(r, 0, side);
    e->Z = sooc_rng_range(r, 0, side);
    e->Theta = sooc_rng_range(r, -M_PI, M_PI);
    e->rho_t = -2;
    e->rho_theta = -1;
    e->pres_logit = (float)sooc_rng_range(r, 0, 4);
    e->dim = D;
    for (int i = 0; i < D; i++) e->what_mu[i] = (float)sooc_rng_normal(r);
    e->obs_count = 1;
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double pct(double *v, int n, double p) {
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    int i = (int)(p * (n - 1) + 0.5);
    return v[i];
}

typedef struct walker {
    double x, z, psi, side;
} walker;

static void walk_step(walker *w, sooc_rng *r) {
    w->psi = sooc_wrap_angle(w->psi + sooc_rng_range(r, -0.4, 0.4));
    w->x += 0.5 * sin(w->psi);
    w->z += 0.5 * cos(w->psi);
    /* bounce off the scene border */
    if (w->x < 2 || w->x > w->side - 2 || w->z < 2 || w->z > w->side - 2) {
        w->psi = sooc_wrap_angle(w->psi + M_PI);
        w->x = fmin(fmax(w->x, 2), w->side - 2);
        w->z = fmin(fmax(w->z, 2), w->side - 2);
    }
}

typedef struct res {
    double walk_med, walk_p99, rand_med, inview_mean, reg_med;
    uint64_t checksum;
} res;

static int brute_check(const sooc_cogmap *m, sooc_rng *r, double side) {
    size_t n;
    sooc_cogmap_entries(m, NULL, 0, &n);
    sooc_cogmap_entry *all = malloc(n * sizeof *all);
    sooc_cogmap_entries(m, all, n, &n);
    int bad = 0;
    for (int it = 0; it < 50; it++) {
        sooc_cogmap_camera c;
        make_cam(&c, sooc_rng_range(r, 0, side), sooc_rng_range(r, 0, side), sooc_rng_range(r, -M_PI, M_PI));
        int nin_bf = 0;
        float bp[NSLOT];
        uint64_t bid[NSLOT];
        int nb = 0;
        for (size_t i = 0; i < n; i++) {
            if (!sooc_cogmap_in_view(&c, &all[i])) continue;
            nin_bf++;
            float p = all[i].pres_logit;
            uint64_t id = all[i].id;
            if (nb == NSLOT && !(p > bp[NSLOT - 1] || (p == bp[NSLOT - 1] && id < bid[NSLOT - 1]))) continue;
            int j = nb < NSLOT ? nb++ : NSLOT - 1;
            while (j > 0 && (p > bp[j - 1] || (p == bp[j - 1] && id < bid[j - 1]))) {
                bp[j] = bp[j - 1];
                bid[j] = bid[j - 1];
                j--;
            }
            bp[j] = p;
            bid[j] = id;
        }
        sooc_cogmap_slot sl[NSLOT];
        int ns, nin;
        if (sooc_cogmap_query(m, &c, NSLOT, sl, &ns, NULL, &nin)) return -1;
        if (nin != nin_bf || ns != nb) bad++;
        else
            for (int i = 0; i < ns; i++)
                if (sl[i].id != bid[i]) bad++;
    }
    free(all);
    return bad;
}

static double g_cell = 4.0;

static int run_size(size_t N, double density, int Q, res *out) {
    double side = sqrt((double)N / density);
    sooc_cogmap_params p;
    sooc_cogmap_params_default(&p);
    p.dim = D;
    p.capacity = N + 64;
    p.cell_size = g_cell;
    sooc_cogmap *m;
    if (sooc_cogmap_create(&m, &p)) return 1;
    sooc_rng r;
    sooc_rng_seed(&r, 42, N);
    for (size_t i = 0; i < N; i++) {
        sooc_cogmap_entry e;
        rand_entry(&r, &e, side);
        if (sooc_cogmap_insert(m, &e, NULL)) return 1;
    }
    if (N <= 10000) {
        int bad = brute_check(m, &r, side);
        if (bad) {
            fprintf(stderr, "validation failed at N=%zu: %d mismatches\n", N, bad);
            return 1;
        }
    }
    double *t = malloc((size_t)Q * sizeof *t);
    sooc_cogmap_slot sl[NSLOT];
    int ns, nin;
    uint64_t ck = 0, nin_sum = 0;
    walker w = {side / 2, side / 2, 0, side};
    for (int i = 0; i < Q / 10; i++) { /* warm-up */
        sooc_cogmap_camera c;
        walk_step(&w, &r);
        make_cam(&c, w.x, w.z, w.psi);
        sooc_cogmap_query(m, &c, NSLOT, sl, &ns, NULL, &nin);
    }
    for (int i = 0; i < Q; i++) {
        sooc_cogmap_camera c;
        walk_step(&w, &r);
        make_cam(&c, w.x, w.z, w.psi);
        int64_t t0 = sooc_now_ns();
        sooc_cogmap_query(m, &c, NSLOT, sl, &ns, NULL, &nin);
        t[i] = (sooc_now_ns() - t0) * 1e-3;
        nin_sum += (uint64_t)nin;
        for (int j = 0; j < ns; j++) ck = ck * 31 + sl[j].id;
    }
    out->walk_med = pct(t, Q, 0.5);
    out->walk_p99 = pct(t, Q, 0.99);
    out->inview_mean = (double)nin_sum / Q;
    for (int i = 0; i < Q; i++) {
        sooc_cogmap_camera c;
        make_cam(&c, sooc_rng_range(&r, 0, side), sooc_rng_range(&r, 0, side), sooc_rng_range(&r, -M_PI, M_PI));
        int64_t t0 = sooc_now_ns();
        sooc_cogmap_query(m, &c, NSLOT, sl, &ns, NULL, &nin);
        t[i] = (sooc_now_ns() - t0) * 1e-3;
    }
    out->rand_med = pct(t, Q, 0.5);
    /* registration: retrieved slots nudged, one dropped, padded slots: one new */
    int R = Q < 2000 ? Q : 2000;
    const int S = SOOC_LAM_SIZE(D);
    float lam[NSLOT * SOOC_LAM_MAX];
    for (int i = 0; i < R; i++) {
        sooc_cogmap_camera c;
        walk_step(&w, &r);
        make_cam(&c, w.x, w.z, w.psi);
        sooc_floor_frame gf;
        sooc_cogmap_query(m, &c, NSLOT, sl, &ns, &gf, &nin);
        uint64_t src[NSLOT];
        for (int j = 0; j < NSLOT; j++) {
            if (j < ns) {
                memcpy(lam + j * S, sl[j].lam, S * sizeof(float));
                src[j] = sl[j].id;
                lam[j * S] += 0.01f;
                lam[j * S + SOOC_LAM_PRES(D)] = j == 0 ? -1.0f : 1.0f;
            } else {
                memset(lam + j * S, 0, S * sizeof(float));
                src[j] = 0;
                lam[j * S + SOOC_LAM_Z] = 3;
                lam[j * S + SOOC_LAM_PRES(D)] = j == ns ? 1.0f : -1.0f;
            }
        }
        int64_t t0 = sooc_now_ns();
        if (sooc_cogmap_register(m, &gf, NSLOT, lam, src, i, i, NULL, NULL, NULL)) return 1;
        t[i] = (sooc_now_ns() - t0) * 1e-3;
    }
    out->reg_med = pct(t, R, 0.5);
    out->checksum = ck;
    free(t);
    sooc_cogmap_destroy(m);
    return 0;
}

/* SQLite: a map of n entries saved once, then keyframe commits of NSLOT changed ids. */
static int bench_store(size_t n, int kfs, double *commit_med, double *commit_p99, double *save_s, double *load_s) {
    char path[] = "/tmp/bench_cogmap_XXXXXX";
    if (!mkdtemp(path)) return 1;
    char db[128];
    snprintf(db, sizeof db, "%s/map.sqlite", path);
    sooc_cogmap_params p;
    sooc_cogmap_params_default(&p);
    p.dim = D;
    sooc_cogmap *m;
    if (sooc_cogmap_create(&m, &p)) return 1;
    sooc_rng r;
    sooc_rng_seed(&r, 7, 0);
    double side = sqrt((double)n / 0.25);
    for (size_t i = 0; i < n; i++) {
        sooc_cogmap_entry e;
        rand_entry(&r, &e, side);
        sooc_cogmap_insert(m, &e, NULL);
    }
    sooc_mapstore_params sp;
    sooc_mapstore_params_default(&sp);
    sp.dim = D;
    sp.layout_dim = 16;
    sooc_mapstore *s;
    if (sooc_mapstore_open(&s, db, &sp)) { fprintf(stderr, "%s\n", sooc_errmsg()); return 1; }
    double t0 = sooc_seconds();
    if (sooc_mapstore_save_map(s, m)) { fprintf(stderr, "%s\n", sooc_errmsg()); return 1; }
    *save_s = sooc_seconds() - t0;
    double *t = malloc((size_t)kfs * sizeof *t);
    walker w = {side / 2, side / 2, 0, side};
    const int S = SOOC_LAM_SIZE(D);
    float lam[NSLOT * SOOC_LAM_MAX];
    sooc_cogmap_slot sl[NSLOT];
    for (int i = 0; i < kfs; i++) {
        sooc_cogmap_camera c;
        walk_step(&w, &r);
        make_cam(&c, w.x, w.z, w.psi);
        sooc_floor_frame gf;
        int ns, nin;
        sooc_cogmap_query(m, &c, NSLOT, sl, &ns, &gf, &nin);
        uint64_t src[NSLOT], ids[NSLOT], rem[NSLOT];
        for (int j = 0; j < NSLOT; j++) {
            memset(lam + j * S, 0, S * sizeof(float));
            if (j < ns) memcpy(lam + j * S, sl[j].lam, S * sizeof(float));
            src[j] = j < ns ? sl[j].id : 0;
            lam[j * S + SOOC_LAM_PRES(D)] = (j == 0 && ns) ? -1.0f : (j == ns ? 1.0f : (j < ns ? 1.0f : -1.0f));
        }
        sooc_cogmap_reg_stats st;
        sooc_cogmap_register(m, &gf, NSLOT, lam, src, i, i, ids, rem, &st);
        sooc_mapstore_keyframe kf = {.t_ns = i, .view = i, .changed = ids, .n_changed = NSLOT, .removed = rem,
                                     .n_removed = (size_t)st.n_removed};
        memcpy(kf.T_wc, c.T_wc, sizeof kf.T_wc);
        int64_t a = sooc_now_ns();
        if (sooc_mapstore_commit_keyframe(s, m, &kf)) { fprintf(stderr, "%s\n", sooc_errmsg()); return 1; }
        t[i] = (sooc_now_ns() - a) * 1e-6;
    }
    *commit_med = pct(t, kfs, 0.5);
    *commit_p99 = pct(t, kfs, 0.99);
    sooc_mapstore_close(s);
    /* restart: load everything back */
    if (sooc_mapstore_open(&s, db, &sp)) return 1;
    sooc_cogmap *m2;
    sooc_cogmap_create(&m2, &p);
    t0 = sooc_seconds();
    if (sooc_mapstore_load_map(s, m2)) { fprintf(stderr, "%s\n", sooc_errmsg()); return 1; }
    *load_s = sooc_seconds() - t0;
    int ok = sooc_cogmap_count(m2) == sooc_cogmap_count(m);
    sooc_mapstore_close(s);
    sooc_cogmap_destroy(m);
    sooc_cogmap_destroy(m2);
    free(t);
    char cmd[256];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", path);
    if (system(cmd)) fprintf(stderr, "could not remove %s\n", path);
    return ok ? 0 : 1;
}

int main(int argc, char **argv) {
    int max_exp = 6, Q = 5000;
    double density = 0.25;
    size_t db_n = 100000;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--max-exp") && i + 1 < argc) max_exp = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--queries") && i + 1 < argc) Q = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--density") && i + 1 < argc) density = atof(argv[++i]);
        else if (!strcmp(argv[i], "--db-entries") && i + 1 < argc) db_n = (size_t)atoll(argv[++i]);
        else if (!strcmp(argv[i], "--cell") && i + 1 < argc) g_cell = atof(argv[++i]);
        else {
            fprintf(stderr, "usage: bench_cogmap [--max-exp E] [--queries Q] [--density RHO] [--db-entries N] [--cell M]\n");
            return 2;
        }
    }
    if (max_exp < 3) max_exp = 3;
    if (max_exp > 7) max_exp = 7;
    res rs[8];
    printf("cogmap query, d=%d K=%d, density %.3g objects/m^2, grid cell %.2g m, %d queries per size\n", D, NSLOT, density, g_cell, Q);
    printf("%10s %12s %12s %12s %12s %12s %10s\n", "entries", "walk_med_us", "walk_p99_us", "rand_med_us",
           "in_view_avg", "register_us", "checksum");
    for (int e = 3; e <= max_exp; e++) {
        size_t N = (size_t)pow(10, e);
        if (run_size(N, density, Q, &rs[e])) {
            fprintf(stderr, "bench_cogmap: failed at N=%zu: %s\n", N, sooc_errmsg());
            return 1;
        }
        printf("%10zu %12.3f %12.3f %12.3f %12.2f %12.3f %10llu\n", N, rs[e].walk_med, rs[e].walk_p99, rs[e].rand_med,
               rs[e].inview_mean, rs[e].reg_med, (unsigned long long)(rs[e].checksum % 100000));
        fflush(stdout);
    }
    double cmed = 0, cp99 = 0, save_s = 0, load_s = 0;
    if (db_n && bench_store(db_n, 500, &cmed, &cp99, &save_s, &load_s)) {
        fprintf(stderr, "bench_cogmap: store bench failed\n");
        return 1;
    }
    printf("sqlite: %zu entries saved in %.2f s, loaded in %.2f s; keyframe commit median %.3f ms, p99 %.3f ms\n", db_n,
           save_s, load_s, cmed, cp99);
    printf("{");
    for (int e = 3; e <= max_exp; e++) printf("\"query_us_1e%d\": %.3f, ", e, rs[e].walk_med);
    for (int e = 3; e <= max_exp; e++) printf("\"query_rand_us_1e%d\": %.3f, ", e, rs[e].rand_med);
    printf("\"ratio_1e%d_vs_1e3\": %.3f, \"ratio_rand_1e%d_vs_1e3\": %.3f, \"query_p99_us_1e%d\": %.3f, "
           "\"inview_mean\": %.2f, \"register_us_1e%d\": %.3f, \"commit_ms_median\": %.3f, \"commit_ms_p99\": %.3f, "
           "\"db_entries\": %zu, \"db_load_s\": %.3f}\n",
           max_exp, rs[max_exp].walk_med / rs[3].walk_med, max_exp, rs[max_exp].rand_med / rs[3].rand_med, max_exp,
           rs[max_exp].walk_p99, rs[max_exp].inview_mean, max_exp, rs[max_exp].reg_med, cmed, cp99, db_n, load_s);
    return 0;
}
