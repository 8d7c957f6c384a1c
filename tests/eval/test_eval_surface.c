/* The entries' observed surfaces (sooc_eval_surface_view, `sooc3d eval
 * --surface`; docs/geometric.md "The entries' observed surfaces").
 *
 * A generated tabletop scene with touching objects (gen --touch 1, 8 input
 * and 2 query views), the shipped tabletop model (skips without it), the
 * scene runner four times with the same seed:
 *   - the model's own labels (the reference run);
 *   - surfaces: every pixel of a view labelled with an entry shows an object
 *     voxel of the input views' clusters (the geometric render of the same
 *     map says object there), labels stay in the field's range, the view's
 *     depth and colour are the model's (unchanged from the reference run),
 *     and the query mIoU is a real segmentation's (> 0.3);
 *   - surfaces with a claim threshold above any density: no pixel is an
 *     entry's;
 *   - with fill, every object pixel of a cluster that any entry claims in the
 *     view is an entry's. */
#include "check.h"
#include "sooc3d/eval.h"
#include "sooc3d/gen.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define SHIPPED "models/sooc3d_tabletop/model.bin"
#define MAXV 32

typedef struct rec {
    const sooc_frame *fr;
    sooc_cluster_map *geo;   /* the input views' clusters, default parameters */
    int nv, n_query;
    double miou_q;
    float *depth[MAXV];
    int frame[MAXV];
    long n_ent, n_ent_off, n_bad_range, n_unfilled;
    int check_fill;
} rec;

static sooc_status on_view(void *u, const sooc_eval_view_info *v) {
    rec *r = u;
    if (v->online) return SOOC_OK;
    const sooc_frame *f = &r->fr[v->frame];
    int w = f->width, h = f->height;
    size_t np = (size_t)w * h;
    if (r->nv < MAXV) {
        r->frame[r->nv] = v->frame;
        r->depth[r->nv] = malloc(np * sizeof(float));
        if (r->depth[r->nv]) memcpy(r->depth[r->nv], v->render->depth, np * sizeof(float));
        r->nv++;
    }
    if (f->is_query) r->miou_q += v->metrics->miou_best, r->n_query++;
    int16_t *g = malloc(np * sizeof *g);
    if (!g) return SOOC_ENOMEM;
    sooc_status st = sooc_cluster_map_render(r->geo, f->T_wc, &f->K, w, h, g, NULL, NULL);
    /* clusters that some entry claims in this view */
    int claimed[256] = {0};
    for (size_t k = 0; k < np && !st; k++)
        if (v->render->label[k] > 0 && g[k] >= 0 && g[k] < 256) claimed[g[k]] = 1;
    for (size_t k = 0; k < np && !st; k++) {
        int l = v->render->label[k];
        r->n_bad_range += l < SOOC_RENDER_LABEL_NONE || l >= v->n_comp;
        if (l > 0) r->n_ent++, r->n_ent_off += g[k] < 0;
        if (r->check_fill && g[k] >= 0 && g[k] < 256 && claimed[g[k]]) r->n_unfilled += l <= 0;
    }
    free(g);
    return st;
}

static void rec_free(rec *r) {
    for (int i = 0; i < r->nv && i < MAXV; i++) free(r->depth[i]);
}

static void run(sooc_model *m, sooc_frame *fr, int n, const sooc_cluster_params *surf, const sooc_surface_params *sp,
                rec *r) {
    sooc_eval_run_opts o;
    sooc_eval_run_opts_default(&o);
    o.seed = 3;
    o.n_coarse = 24;
    o.n_fine = 0;
    o.threads = 1;
    o.surface = surf;
    if (sp) o.surface_p = *sp;
    r->check_fill = sp && sp->fill;
    sooc_eval_scene_result res;
    CHECK_OK(sooc_eval_run_scene(m, fr, n, NULL, 0, &o, on_view, NULL, r, &res));
    if (r->n_query) r->miou_q /= r->n_query;
}

int main(void) {
    FILE *t = fopen(SHIPPED, "rb");
    if (!t) {
        printf("test_eval_surface: SKIP: %s not found (run from the repository root)\n", SHIPPED);
        return SOOC_TEST_SKIP;
    }
    fclose(t);
    char tmp[256], scene[400];
    snprintf(tmp, sizeof tmp, "/tmp/sooc3d_test_eval_surface_%ld", (long)getpid());
    snprintf(scene, sizeof scene, "%s/scene_0000", tmp);
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.preset = SOOC_GEN_TABLETOP;
    gp.scale = SOOC_GEN_M;
    gp.seed = 3;
    gp.n_scenes = 1;
    gp.touch = 1;
    gp.n_views = 8;   /* 6 input + 2 query views: short enough for the sanitizer builds */
    gp.n_query = 2;
    gp.write_meshes = 0;
    gp.contact_sheet = 0;
    CHECK_OK(sooc_gen_run(&gp, tmp, NULL, NULL, NULL));
    sooc_seq *sq = NULL;
    CHECK_OK(sooc_seq_open(&sq, scene, NULL));
    if (!sq) return 1;
    int n = (int)sooc_seq_count(sq);
    sooc_frame *fr = calloc((size_t)n, sizeof *fr);
    for (int i = 0; i < n; i++) CHECK_OK(sooc_seq_read(sq, i, &fr[i]));
    sooc_seq_close(sq);
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_load(&m, SHIPPED, NULL, NULL));
    if (!m) return 1;

    sooc_cluster_params cp;
    sooc_cluster_params_default(&cp);
    rec a, b, c, d;
    memset(&a, 0, sizeof a), memset(&b, 0, sizeof b), memset(&c, 0, sizeof c), memset(&d, 0, sizeof d);
    sooc_cluster_map *geo = NULL;
    CHECK_OK(sooc_cluster_map_create(&geo, &cp));
    int n_in = 0, n_cl = 0;
    for (int i = 0; i < n; i++)
        if (!fr[i].is_query) {
            CHECK_OK(sooc_cluster_map_add_frame(geo, &fr[i]));
            n_in++;
        }
    CHECK_OK(sooc_cluster_map_segment(geo, &n_cl));
    a.fr = b.fr = c.fr = d.fr = fr;
    a.geo = b.geo = c.geo = d.geo = geo;

    run(m, fr, n, NULL, NULL, &a);
    run(m, fr, n, &cp, NULL, &b);
    sooc_surface_params none;
    sooc_surface_params_default(&none);
    none.min_sigma = 2;   /* densities (times presence) are at most 1 */
    run(m, fr, n, &cp, &none, &c);
    sooc_surface_params fill;
    sooc_surface_params_default(&fill);
    fill.fill = 1;
    run(m, fr, n, &cp, &fill, &d);

    printf("scene: %d frames (%d input), %d clusters; query mIoU: model's labels %.3f, surfaces %.3f, "
           "surfaces with fill %.3f\n", n, n_in, n_cl, a.miou_q, b.miou_q, d.miou_q);
    printf("surfaces: %ld entry pixels, %ld of them off the clusters' objects, %ld labels out of range; "
           "threshold above any density: %ld entry pixels; fill: %ld unfilled object pixels of claimed clusters\n",
           b.n_ent, b.n_ent_off, b.n_bad_range, c.n_ent, d.n_unfilled);
    CHECK(n_cl >= 2);
    CHECK(a.nv == b.nv && b.nv == c.nv && a.nv > 0 && b.n_query > 0);
    CHECK_MSG(b.n_ent > 100, "surfaces: %ld entry pixels", b.n_ent);
    CHECK_MSG(b.n_ent_off == 0, "%ld entry pixels off the clusters' objects", b.n_ent_off);
    CHECK(b.n_bad_range == 0 && c.n_bad_range == 0 && d.n_bad_range == 0);
    CHECK_MSG(c.n_ent == 0, "claim threshold 2: %ld entry pixels", c.n_ent);
    CHECK_MSG(d.n_unfilled == 0, "fill: %ld object pixels of claimed clusters left to the background", d.n_unfilled);
    CHECK_MSG(b.miou_q > 0.3, "surfaces: query mIoU %.3f", b.miou_q);
    /* the segmentation changes, the render does not */
    int same = 1;
    size_t np = (size_t)fr[0].width * fr[0].height;
    for (int i = 0; i < a.nv && i < MAXV; i++) {
        same &= a.frame[i] == b.frame[i] && a.depth[i] && b.depth[i];
        for (size_t k = 0; same && k < np; k++) same &= a.depth[i][k] == b.depth[i][k];
    }
    CHECK_MSG(same, "surfaces changed the rendered depth");

    rec_free(&a), rec_free(&b), rec_free(&c), rec_free(&d);
    sooc_cluster_map_destroy(geo);
    sooc_model_destroy(m);
    for (int i = 0; i < n; i++) sooc_frame_free(&fr[i]);
    free(fr);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmp);
    if (system(cmd) != 0) printf("test_eval_surface: could not remove %s\n", tmp);
    printf("test_eval_surface: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail != 0;
}
