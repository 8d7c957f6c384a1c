/* Geometric support of a learnt mapper's entries (sooc_mapper_set_support,
 * docs/geometric.md "Geometric support"): a tiny model maps one view of two
 * balls on a floor, with three entries planted before it: on a ball (A), on
 * the bare floor in view (B) and on the bare floor behind the camera (C).
 * With the support on, B is removed and published as a removal, A's place has
 * a cluster and C is out of view: both stay. With it off (negative control)
 * B stays. With it and the observed-surface boxes on, the entries written by
 * the update get the boxes of the surfaces they claim (docs/geometric.md "The
 * entries' observed surfaces"): centred on the entry, reaching the balls and
 * no farther, as tall as a ball; none with the boxes off or the support off.
 * A margin out of range is an error. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "synth.h"

#define IMG 32

/* two balls on the floor about 1 m ahead of a camera 0.5 m up with a narrow
 * view (24 degrees: about 1.3 cm per pixel at 32 x 32) */
static const synth_sphere g_balls[2] = {{{0.08, 0.06, 1.30}, 0.06, {0.9f, 0.2f, 0.1f}},
                                        {{-0.09, 0.05, 1.40}, 0.05, {0.1f, 0.3f, 0.9f}}};

static void plant(sooc_map_entry *e, uint64_t id, double x, double z, int d) {
    memset(e, 0, sizeof *e);
    e->id = id;
    e->x = x, e->z = z;
    e->sigma_t = 0.05, e->sigma_yaw = 0.1;
    e->presence_logit = 3.0f;
    e->presence = 1.0f / (1.0f + expf(-3.0f));
    e->latent_dim = d;
    for (int k = 0; k < d; k++) e->what_logvar[k] = -2.0f;
    e->first_seen_ns = e->last_seen_ns = 1;
    e->obs_count = 3;
}

static int has(const sooc_map_entry *e, size_t n, uint64_t id) {
    for (size_t i = 0; i < n; i++)
        if (e[i].id == id) return 1;
    return 0;
}

/* A mapper around a fresh tiny model (seed 5); *d its latent size. */
static sooc_mapper *tiny_mapper(int *d) {
    sooc_model_config c;
    synth_tiny_cfg(&c, 4, 1);
    *d = c.d_what;
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_create(&m, &c, 5));
    sooc_mapper *mp = NULL;
    if (m) CHECK_OK(sooc_mapper_create_with_model(&mp, m, 0, 3, 1));
    return mp;
}

/* One update with the three planted entries; support on with margin > 0,
 * observed-surface boxes with surf.
 * *removed_b: B's id among the update's removals; *n_surface: published
 * entries with an observed-surface box. Returns the entries after. */
static size_t run(double margin, int surf, sooc_map_entry *out, size_t cap, int *removed_b, int *n_surface) {
    int d = 0;
    sooc_mapper *mp = tiny_mapper(&d);
    if (!mp) return 0;
    if (margin > 0) CHECK_OK(sooc_mapper_set_support(mp, margin));
    sooc_mapper_set_surface_boxes(mp, surf);
    sooc_map_entry e[3];
    plant(&e[0], 1, g_balls[0].c[0], g_balls[0].c[2], d);   /* A: on a ball         */
    plant(&e[1], 2, 0.13, 1.55, d);                          /* B: bare floor        */
    plant(&e[2], 3, 0.0, -2.0, d);                           /* C: behind the camera */
    CHECK_OK(sooc_mapper_load_entries(mp, e, 3));
    double T[16];
    synth_pose(T, 0.0, 0.5, 0.5, 0.0, -0.49);
    sooc_frame f;
    CHECK_OK(synth_frame(&f, IMG, IMG, 24, T, g_balls, 2));
    f.index = 0, f.t_ns = 1000;
    sooc_update_stats st;
    CHECK_OK(sooc_mapper_update(mp, &f, &st));
    sooc_frame_free(&f);
    uint64_t rem[64];
    size_t nc = 0, nr = 0;
    sooc_map_entry chg[64];
    CHECK_OK(sooc_mapper_changed(mp, chg, 64, &nc, rem, 64, &nr));
    *removed_b = 0;
    for (size_t i = 0; i < nr; i++) *removed_b |= rem[i] == 2;
    /* observed-surface boxes: on the balls' seen surfaces (their union grown by 2 cm), as tall as the
     * taller ball under them (0.12 m, or 0.10), never the model's 1.2 m locality box */
    *n_surface = 0;
    for (size_t i = 0; i < nc; i++) {
        const sooc_map_entry *q = &chg[i];
        if (!(q->geom.flags & SOOC_GEOM_SURFACE)) continue;
        (*n_surface)++;
        double c = cos(q->yaw), s = sin(q->yaw), lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
        for (int k = 0; k < 4; k++) {   /* the box's floor corners in the world (R_y) */
            double a = q->geom.centre[0] + ((k & 1) ? 0.5 : -0.5) * q->extent[0];
            double b = q->geom.centre[2] + ((k & 2) ? 0.5 : -0.5) * q->extent[2];
            double wx = q->x + c * a + s * b, wz = q->z - s * a + c * b;
            lo[0] = fmin(lo[0], wx), hi[0] = fmax(hi[0], wx), lo[1] = fmin(lo[1], wz), hi[1] = fmax(hi[1], wz);
        }
        printf("entry %llu: observed-surface box %.3f x %.3f x %.3f, floor x %.3f..%.3f z %.3f..%.3f\n",
               (unsigned long long)q->id, q->extent[0], q->extent[1], q->extent[2], lo[0], hi[0], lo[1], hi[1]);
        double h = q->extent[1];
        CHECK_MSG((fabs(h - 0.12) < 0.012 || fabs(h - 0.10) < 0.012) && fabs(q->geom.centre[1] - 0.5 * h) < 1e-6,
                  "entry %llu: height %.3f", (unsigned long long)q->id, h);
        /* centred on the entry, it reaches its farthest claimed voxel: the balls' far side from it, and no
         * farther than that plus a voxel (0.01 m) */
        double far = 0;
        for (int bb = 0; bb < 2; bb++) {
            const synth_sphere *sp = &g_balls[bb];
            double dx = fabs(sp->c[0] - q->x) + sp->r, dz = fabs(sp->c[2] - q->z) + sp->r;
            far = fmax(far, fmax(dx, dz));
        }
        CHECK_MSG((q->geom.flags & SOOC_GEOM_TIGHT) && q->geom.centre[0] == 0 && q->geom.centre[2] == 0,
                  "entry %llu: flags 0x%x, centre offset", (unsigned long long)q->id, q->geom.flags);
        CHECK_MSG(0.5 * fmax(q->extent[0], q->extent[2]) <= far + 0.011, "entry %llu: half-width %.3f beyond the balls' %.3f",
                  (unsigned long long)q->id, 0.5 * fmax(q->extent[0], q->extent[2]), far);
        CHECK_MSG(0.5 * fmin(q->extent[0], q->extent[2]) >= 0.04, "entry %llu: box %.3f x %.3f narrower than a ball",
                  (unsigned long long)q->id, q->extent[0], q->extent[2]);
    }
    size_t n = 0;
    CHECK_OK(sooc_mapper_entries(mp, out, cap, &n));
    sooc_mapper_destroy(mp);
    return n < cap ? n : cap;
}

int main(void) {
    sooc_map_entry out[64];
    int rb = 0, ns = 0;
    size_t n = run(0.05, 0, out, 64, &rb, &ns);
    CHECK_MSG(ns == 0, "support on, surface boxes off: %d observed-surface boxes", ns);
    n = run(0.05, 1, out, 64, &rb, &ns);
    printf("support on: %zu entries, A %s, B %s (%s), C %s\n", n, has(out, n, 1) ? "kept" : "gone",
           has(out, n, 2) ? "kept" : "gone", rb ? "published as a removal" : "no removal", has(out, n, 3) ? "kept" : "gone");
    CHECK_MSG(!has(out, n, 2) && rb, "the entry on the bare floor in view stays with the support on");
    CHECK_MSG(has(out, n, 1), "the entry on a ball was removed");
    CHECK_MSG(has(out, n, 3), "the entry out of view was removed");
    CHECK_MSG(ns >= 1, "support on: %d entries with an observed-surface box", ns);
    n = run(0, 1, out, 64, &rb, &ns);
    printf("support off: %zu entries, B %s, %d observed-surface boxes\n", n, has(out, n, 2) ? "kept" : "gone", ns);
    CHECK_MSG(has(out, n, 2) && !rb, "negative control: the bare-floor entry is gone without the support too");
    CHECK_MSG(ns == 0, "negative control: %d observed-surface boxes without the support", ns);

    /* bad margin */
    int d = 0;
    sooc_mapper *mp = tiny_mapper(&d);
    CHECK(mp && sooc_mapper_set_support(mp, -1) == SOOC_EINVAL);
    CHECK_OK(sooc_mapper_set_support(mp, 0));   /* off */
    sooc_mapper_destroy(mp);
    printf("test_mapper_support: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail != 0;
}
