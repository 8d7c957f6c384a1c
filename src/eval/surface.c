/* The entries' observed surfaces (eval.h: sooc_eval_cluster_map,
 * sooc_eval_surface_view;
 * docs/geometric.md "The entries' observed surfaces"): the mapped frames'
 * object voxels above the support plane, each given to the map entry whose
 * density is highest there, rendered into a view as the geometric baseline
 * renders its clusters. The learnt map says which object a point belongs
 * to; the depth says where the object's surface is. */
#include "sooc3d/eval.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "sooc3d/render.h"

#include <math.h>
#include <string.h>

sooc_status sooc_eval_cluster_map(const sooc_cluster_params *cp, const sooc_frame *frames, int n,
                                  const uint8_t *use, sooc_cluster_map **out) {
    if (!out || n < 0 || (n && !frames)) return sooc_seterr(SOOC_EINVAL, "eval: clusters: bad arguments");
    *out = NULL;
    sooc_cluster_map *cm = NULL;
    sooc_status st = sooc_cluster_map_create(&cm, cp);
    for (int i = 0; i < n && !st; i++)
        if (!use || use[i]) st = sooc_cluster_map_add_frame(cm, &frames[i]);
    int n_cl = 0;
    if (!st) st = sooc_cluster_map_segment(cm, &n_cl);
    if (st) {
        sooc_cluster_map_destroy(cm);
        return sooc_adderr(st, "eval: the mapped frames' clusters");
    }
    *out = cm;
    return SOOC_OK;
}

sooc_status sooc_eval_surface_view(sooc_model *m, const sooc_cogmap *map, sooc_cluster_map *cm,
                                   const sooc_frame *gt, const sooc_gt_object *gt_obj, int n_gt, int max_obj,
                                   const sooc_surface_params *sp, double d_clip, const double *comp_xz,
                                   sooc_render_out *out, sooc_view_metrics *vm, sooc_iou_match *match) {
    if (!out || !out->label || out->width != gt->width || out->height != gt->height || !vm)
        return sooc_seterr(SOOC_EINVAL, "eval surface: no render of the view to relabel");
    sooc_model_field *fld = NULL;
    sooc_surface_claims cl;
    sooc_status st = sooc_surface_claim_frame(m, map, gt, max_obj, cm, sp, &fld, &cl);
    if (st) return sooc_adderr(st, "eval");
    int nc = sooc_model_field_get(fld)->n_comp;
    sooc_surface_claims_free(&cl);
    sooc_model_field_destroy(fld);
    size_t np = (size_t)gt->width * gt->height;
    int16_t *lab = sooc_malloc(np * sizeof *lab);
    float *z = sooc_malloc(np * sizeof *z);
    if (!lab || !z) st = sooc_seterr(SOOC_ENOMEM, "eval surface: out of memory");
    if (!st) st = sooc_cluster_map_render(cm, gt->T_wc, &gt->K, gt->width, gt->height, lab, z, NULL);
    if (!st) {
        for (size_t k = 0; k < np; k++) out->label[k] = (int16_t)(lab[k] > 0 ? lab[k] : z[k] > 0 ? 0 : -1);
        sooc_view_eval_in in = {gt, out, d_clip, nc, comp_xz, gt_obj, n_gt, NULL};
        st = sooc_metric_view(&in, vm, match);
    }
    sooc_free(lab);
    sooc_free(z);
    return st ? sooc_adderr(st, "eval surface: frame %lld", (long long)gt->index) : SOOC_OK;
}
