/* Births before finetuning (include/sooc3d/train.h "births") on the toy
 * scene of test_finetune_em: two spheres on a checkered floor, four views.
 * The tiny model's density biases are set so that what the map draws is
 * known: the layout draws nothing, and an object either nothing (bias -20) or
 * its whole locality box (+20).
 *  1. An empty map: one birth per sphere, near its centre; none on the floor.
 *  2. An entry that draws its box around sphere 0 explains it: one birth, at
 *     sphere 1.
 *  3. An entry that draws nothing near sphere 0: within dup_radius no birth
 *     there, outside it a birth.
 *  4. min_views above the number of views, or min_pixels above the points:
 *     no births. Bad parameters are refused.
 *  5. Deaths (sooc_birth_prune, _prune_all): entries that draw nothing are
 *     removed, those that draw their box are kept. */
#include "check.h"
#include "finetune/finetune_impl.h"
#include "toy_scene.h"
#include "sooc3d/train.h"

#include <math.h>
#include <string.h>

static sooc_cogmap *new_map(const sooc_model_config *cfg) {
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = cfg->d_what, cp.layout_dim = cfg->d_layout, cp.block_size = cfg->block_size;
    sooc_cogmap *map = NULL;
    CHECK_OK(sooc_cogmap_create(&map, &cp));
    return map;
}

static void put_entry(sooc_cogmap *map, int d, double X, double Z) {
    sooc_cogmap_entry e;
    memset(&e, 0, sizeof e);
    e.X = X, e.Z = Z, e.rho_t = -4, e.rho_theta = -2, e.pres_logit = 3, e.dim = d, e.obs_count = 1;
    CHECK_OK(sooc_cogmap_insert(map, &e, NULL));
}

/* Births on `map` from the four views; returns their number, positions in xz. */
static uint64_t g_ids[8];

static int births(sooc_model *m, sooc_cogmap *map, const sooc_frame *fr, const sooc_birth_params *p, double xz[][2],
                  size_t *n_pts) {
    sooc_birth *b = NULL;
    CHECK_OK(sooc_birth_create(&b, m, map, p, 1));
    if (!b) return -1;
    for (int v = 0; v < NV; v++) CHECK_OK(sooc_birth_add_view(b, &fr[v]));
    *n_pts = sooc_birth_n_points(b);
    uint64_t ids[8];
    int n = 0;
    CHECK_OK(sooc_birth_run(b, ids, 8, &n));
    sooc_birth_destroy(b);
    memcpy(g_ids, ids, sizeof ids);
    for (int i = 0; i < n && i < 8; i++) {
        sooc_cogmap_entry e;
        CHECK_OK(sooc_cogmap_get(map, ids[i], &e));
        xz[i][0] = e.X, xz[i][1] = e.Z;
        CHECK(e.pres_logit > 0 && e.dim == m->cfg.d_what && e.obs_count >= 2);
    }
    return n;
}

/* Index of the sphere whose centre is within r of (x, z) on the floor, or -1. */
static int near_sphere(const double xz[2], double r) {
    for (int s = 0; s < 2; s++)
        if (hypot(xz[0] - k_sp[s].c[0], xz[1] - k_sp[s].c[2]) < r) return s;
    return -1;
}

int main(void) {
    sooc_model_config cfg;
    synth_tiny_cfg(&cfg, 2, 1);
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_create(&m, &cfg, 3));
    float *w = sooc_model_params(m);
    w[m->dlay.bd] = -20.0f;   /* the layout draws nothing */
    w[m->dobj.bd] = -20.0f;   /* objects draw nothing (1, 3) */
    sooc_frame fr[NV];
    memset(fr, 0, sizeof fr);
    CHECK_OK(make_views(fr));
    if (g_check_fail) return check_report("test_birth");
    sooc_birth_params p;
    sooc_birth_params_default(&p);
    p.min_pixels = 20;
    double xz[8][2];
    size_t npts = 0;

    /* 1. nothing drawn: a birth at each sphere, within its radius + a bit
     * (the points are the spheres' near sides), none elsewhere */
    sooc_cogmap *map = new_map(&cfg);
    int n = births(m, map, fr, &p, xz, &npts);
    printf("empty map: %zu unexplained points, %d births", npts, n);
    for (int i = 0; i < n && i < 8; i++) printf(" (%.2f, %.2f)", xz[i][0], xz[i][1]);
    printf("\n");
    CHECK(n == 2);
    int hit[2] = {0, 0};
    for (int i = 0; i < n && i < 8; i++) {
        int s = near_sphere(xz[i], k_sp[0].r + 0.1);
        CHECK_MSG(s >= 0, "birth %d at (%.2f, %.2f) is near no sphere", i, xz[i][0], xz[i][1]);
        if (s >= 0) hit[s]++;
    }
    CHECK(hit[0] == 1 && hit[1] == 1);
    CHECK(sooc_cogmap_count(map) == 2);
    /* 5. they draw nothing: pruned */
    int nk = n, npr = 0;
    CHECK_OK(sooc_birth_prune(m, map, g_ids, &nk, &npr));
    CHECK(nk == 0 && npr == 2 && sooc_cogmap_count(map) == 0);
    sooc_cogmap_destroy(map);

    /* 2. an entry at sphere 0 drawing its whole box: sphere 0 is explained */
    w[m->dobj.bd] = 20.0f;
    map = new_map(&cfg);
    put_entry(map, cfg.d_what, k_sp[0].c[0], k_sp[0].c[2]);
    n = births(m, map, fr, &p, xz, &npts);
    printf("solid box at sphere 0: %zu unexplained points, %d births\n", npts, n);
    CHECK(n == 1);
    if (n == 1) CHECK(near_sphere(xz[0], k_sp[1].r + 0.1) == 1);
    /* 5. the born entry draws its box: kept */
    nk = n, npr = 0;
    CHECK_OK(sooc_birth_prune(m, map, g_ids, &nk, &npr));
    CHECK(nk == 1 && npr == 0 && sooc_cogmap_count(map) == 2);
    CHECK_OK(sooc_birth_prune_all(m, map, NULL, &npr));
    CHECK(npr == 0 && sooc_cogmap_count(map) == 2);
    sooc_cogmap_destroy(map);

    /* 3. an entry drawing nothing beside sphere 0: within dup_radius of the
     * cluster's centre it blocks the birth there, farther away it does not */
    w[m->dobj.bd] = -20.0f;
    map = new_map(&cfg);
    put_entry(map, cfg.d_what, k_sp[0].c[0], k_sp[0].c[2]);
    p.dup_radius = 0.6f;
    n = births(m, map, fr, &p, xz, &npts);
    printf("empty entry at sphere 0, dup radius 0.6: %d births\n", n);
    CHECK(n == 1);
    if (n == 1) CHECK(near_sphere(xz[0], k_sp[1].r + 0.1) == 1);
    /* 5. deaths over the whole map: the entry and the birth both draw nothing */
    uint64_t *gone = NULL;
    npr = 0;
    CHECK_OK(sooc_birth_prune_all(m, map, &gone, &npr));
    CHECK(npr == 2 && sooc_cogmap_count(map) == 0 && gone && gone[0] == 1 && gone[1] == g_ids[0]);
    sooc_free(gone);
    sooc_cogmap_destroy(map);
    map = new_map(&cfg);
    put_entry(map, cfg.d_what, k_sp[0].c[0] - 1.5, k_sp[0].c[2]);
    n = births(m, map, fr, &p, xz, &npts);
    CHECK(n == 2);
    sooc_cogmap_destroy(map);
    p.dup_radius = 0.15f;

    /* 4. support filters and parameter checks */
    map = new_map(&cfg);
    p.min_views = NV + 1;
    CHECK(births(m, map, fr, &p, xz, &npts) == 0);
    p.min_views = 2;
    p.min_pixels = (int)npts + 1;
    CHECK(births(m, map, fr, &p, xz, &npts) == 0);
    p.min_pixels = 20;
    p.max_births = 1;
    CHECK(births(m, map, fr, &p, xz, &npts) == 1);
    CHECK(sooc_cogmap_count(map) == 1);
    sooc_cogmap_destroy(map);
    sooc_birth_params bad = p;
    bad.cell = 0;
    sooc_birth *b = NULL;
    CHECK(sooc_birth_create(&b, m, NULL, &p, 1) == SOOC_EINVAL && !b);
    map = new_map(&cfg);
    CHECK(sooc_birth_create(&b, m, map, &bad, 1) == SOOC_EINVAL && !b);
    sooc_clearerr();
    sooc_cogmap_destroy(map);

    for (int v = 0; v < NV; v++) sooc_frame_free(&fr[v]);
    sooc_model_destroy(m);
    return check_report("test_birth");
}
