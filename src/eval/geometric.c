/* The geometric baseline (eval.h: sooc_eval_geometric_scene,
 * sooc_eval_geometric_run; docs/geometric.md): the mapped frames go into one
 * support-plane cluster map, every scored view is rendered from it and
 * scored as a learnt map's render is (sooc_metric_view: the same valid mask,
 * the same best-match IoU, L2 over the objects' floor positions), and its
 * objects are the entries. */
#include "sooc3d/mapper.h"
#include "sooc3d/eval.h"
#include "sooc3d/render.h"

#include <math.h>
#include <string.h>

/* A cluster map and what scoring its renders needs. */
typedef struct geo_run {
    sooc_cluster_map *cm;
    int n_obj, nk;                       /* objects; labels in a render (background + objects) */
    uint64_t ids[SOOC_METRIC_MAX_PRED];  /* per label: 0 the background, k object k - 1 + 1   */
    double xz[2 * SOOC_METRIC_MAX_PRED];
    sooc_render_out ro;
    double d_clip;
} geo_run;

static void geo_free(geo_run *g) {
    sooc_cluster_map_destroy(g->cm);
    sooc_render_out_free(&g->ro);
}

/* Map frames[i] for which use(i) (NULL: all), segment, and set up the labels. */
static sooc_status geo_map(geo_run *g, const sooc_frame *frames, int n, const uint8_t *use,
                           const sooc_cluster_params *cp, double d_clip) {
    memset(g, 0, sizeof *g);
    g->d_clip = d_clip;
    sooc_status st = sooc_eval_cluster_map(cp, frames, n, use, &g->cm);
    if (!st) st = sooc_cluster_map_objects(g->cm, NULL, 0, &g->n_obj);
    if (st) return st;
    /* labels as a learnt map renders them: 0 the background (the plane and the surround), 1.. objects */
    g->nk = g->n_obj + 1 < SOOC_METRIC_MAX_PRED ? g->n_obj + 1 : SOOC_METRIC_MAX_PRED;
    sooc_cluster_object *obj = sooc_calloc((size_t)g->n_obj + 1, sizeof *obj);
    if (!obj) return sooc_seterr(SOOC_ENOMEM, "eval geometric: out of memory");
    int n_obj = 0;
    st = sooc_cluster_map_objects(g->cm, obj, g->n_obj, &n_obj);
    g->ids[0] = 0, g->xz[0] = g->xz[1] = NAN;
    for (int k = 1; k < g->nk && !st; k++) g->ids[k] = (uint64_t)k, g->xz[2 * k] = obj[k - 1].x, g->xz[2 * k + 1] = obj[k - 1].z;
    sooc_free(obj);
    return st;
}

/* Render frame f from the map and score it. */
static sooc_status geo_view(geo_run *g, const sooc_frame *f, const sooc_gt_object *gt, int n_gt,
                            sooc_view_metrics *vm, sooc_iou_match *match) {
    sooc_render_out *ro = &g->ro;
    int w = f->width, h = f->height;
    size_t np = (size_t)w * h;
    if (ro->width != w || ro->height != h) {
        sooc_render_out_free(ro);
        ro->width = w, ro->height = h;
        ro->rgb = sooc_malloc(np * 3 * sizeof *ro->rgb);
        ro->depth = sooc_malloc(np * sizeof *ro->depth);
        ro->alpha = sooc_malloc(np * sizeof *ro->alpha);
        ro->label = sooc_malloc(np * sizeof *ro->label);
        if (!ro->rgb || !ro->depth || !ro->alpha || !ro->label)
            return sooc_seterr(SOOC_ENOMEM, "eval geometric: out of memory for %dx%d", w, h);
    }
    sooc_status st = sooc_cluster_map_render(g->cm, f->T_wc, &f->K, w, h, ro->label, ro->depth, ro->rgb);
    if (st) return st;
    for (size_t k = 0; k < np; k++) {
        int l = ro->label[k] >= 0 ? ro->label[k] + 1 : ro->depth[k] > 0 ? 0 : -1;
        ro->label[k] = (int16_t)(l < g->nk ? l : 0);   /* beyond the metric's label range: background */
        ro->alpha[k] = ro->label[k] >= 0;
        if (!(ro->depth[k] > 0)) ro->depth[k] = (float)g->d_clip;   /* nothing there: the clip, as a render */
    }
    ro->n_comp = g->nk;
    sooc_view_eval_in in = {f, ro, g->d_clip, g->nk, g->xz, gt, n_gt, NULL};
    return sooc_metric_view(&in, vm, match);
}

/* The clusters' boxes against the labelled objects (sooc_eval_box_fit), as a learnt map's entries */
static sooc_status geo_box_fit(const geo_run *g, const sooc_frame *frames, int n_frames, sooc_eval_real_result *res) {
    int n = 0;
    sooc_cluster_object *obj = sooc_calloc((size_t)g->n_obj + 1, sizeof *obj);
    sooc_map_entry *e = sooc_calloc((size_t)g->n_obj + 1, sizeof *e);
    sooc_status st = !obj || !e ? sooc_seterr(SOOC_ENOMEM, "eval geometric: out of memory")
                                        : sooc_cluster_map_objects(g->cm, obj, g->n_obj, &n);
    for (int k = 0; k < n && !st; k++) {
        e[k].id = (uint64_t)k + 1;
        e[k].x = obj[k].x, e[k].z = obj[k].z, e[k].yaw = obj[k].yaw;
        for (int a = 0; a < 3; a++) e[k].extent[a] = (float)obj[k].extent[a];
        e[k].geom.flags = SOOC_GEOM_TIGHT;
        e[k].geom.centre[1] = (float)obj[k].centre_y;
    }
    for (int k = 0; k < res->obj.n && !st; k++)   /* from every labelled frame: the objects' truth */
        st = sooc_eval_box_fit(e, (size_t)n, frames, n_frames, NULL, res->obj.id[k], &res->obj_box[k]);
    sooc_free(obj);
    sooc_free(e);
    return st;
}

sooc_status sooc_eval_geometric_run(const sooc_frame *frames, int n_frames, const sooc_eval_real_opts *o,
                                    const sooc_cluster_params *cp, double d_clip, sooc_eval_view_fn view_cb,
                                    void *user, sooc_eval_real_result *res) {
    if (!frames || n_frames < 1 || !o || !res || !(d_clip > 0))
        return sooc_seterr(SOOC_EINVAL, "eval geometric: bad arguments");
    if (o->query_every < 2)
        return sooc_seterr(SOOC_EINVAL, "eval geometric: query rule N = %d, must be >= 2", o->query_every);
    memset(res, 0, sizeof *res);
    res->pos_spread_m = res->yaw_spread_deg = res->never_behind_med_m = NAN;
    uint8_t *use = sooc_malloc((size_t)n_frames);
    if (!use) return sooc_seterr(SOOC_ENOMEM, "eval geometric: out of memory");
    int n_lab = 0;
    for (int i = 0; i < n_frames; i++) {
        use[i] = !sooc_eval_real_is_query(i, o->query_every);
        if (use[i]) res->n_mapped++;
        else res->n_query++, n_lab += frames[i].instance != NULL;
    }
    res->n_frames = n_frames;
    res->has_labels = n_lab == res->n_query;
    geo_run g;
    double t0 = sooc_seconds();
    sooc_status st = !res->n_mapped || !res->n_query
                         ? sooc_seterr(SOOC_EINVAL, "eval geometric: %d frames give %d mapped and %d query frames "
                                                    "with N = %d", n_frames, res->n_mapped, res->n_query, o->query_every)
                         : geo_map(&g, frames, n_frames, use, cp, d_clip);
    sooc_free(use);
    if (st) {
        if (res->n_mapped && res->n_query) geo_free(&g);
        return sooc_adderr(st, "eval geometric");
    }
    res->update_s = sooc_seconds() - t0;
    res->entries_final = res->entries_pass2 = (size_t)g.n_obj;
    res->churn.created = g.n_obj;
    res->churn.updates = res->n_mapped;
    for (int i = 0; i < n_frames && !st; i++) {
        const sooc_frame *f = &frames[i];
        if (!sooc_eval_real_is_query(i, o->query_every)) continue;
        double t1 = sooc_seconds();
        sooc_view_metrics vm;
        sooc_iou_match match;
        st = geo_view(&g, f, NULL, 0, &vm, &match);
        res->render_s += sooc_seconds() - t1;
        if (st) break;
        vm.is_query = 1;
        sooc_metric_sums_add_view(&res->query, &vm);
        if (f->instance && (st = sooc_obj_iou_add(&res->obj, &match))) break;
        if (view_cb) {
            sooc_eval_view_info vi = {i, f, 0, res->n_mapped, &g.ro, &vm, f->instance ? &match : NULL, g.nk, g.ids, g.xz};
            st = view_cb(user, &vi);
        }
    }
    if (!st && res->has_labels) st = geo_box_fit(&g, frames, n_frames, res);
    geo_free(&g);
    return st;
}

sooc_status sooc_eval_geometric_scene(const sooc_frame *frames, int n_frames, const sooc_gt_object *gt, int n_gt,
                                      const sooc_cluster_params *cp, double d_clip, sooc_eval_scene_result *res) {
    if (!frames || n_frames < 1 || !res || !(d_clip > 0) || n_gt < 0 || (n_gt && !gt))
        return sooc_seterr(SOOC_EINVAL, "eval geometric: bad arguments");
    memset(res, 0, sizeof *res);
    uint8_t *use = sooc_malloc((size_t)n_frames);
    if (!use) return sooc_seterr(SOOC_ENOMEM, "eval geometric: out of memory");
    for (int i = 0; i < n_frames; i++) use[i] = !frames[i].is_query, res->n_mapped += use[i];
    res->n_query = n_frames - res->n_mapped;
    geo_run g;
    double t0 = sooc_seconds();
    sooc_status st = geo_map(&g, frames, n_frames, use, cp, d_clip);
    sooc_free(use);
    res->update_s = sooc_seconds() - t0;
    res->n_entries = (size_t)g.n_obj;
    t0 = sooc_seconds();
    for (int i = 0; i < n_frames && !st; i++) {
        sooc_view_metrics vm;
        if ((st = geo_view(&g, &frames[i], gt, n_gt, &vm, NULL))) break;
        vm.is_query = frames[i].is_query;
        sooc_metric_sums_add_view(vm.is_query ? &res->query : &res->input_final, &vm);
    }
    res->render_s = sooc_seconds() - t0;
    geo_free(&g);
    return st ? sooc_adderr(st, "eval geometric") : SOOC_OK;
}
