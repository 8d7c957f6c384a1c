/* The entries' observed surfaces (eval.h: sooc_eval_surface_view;
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

#define SURF_BATCH 1024

/* 1 when field point p lies in box b (or b does not cull) */
static int in_box(const sooc_render_box *b, const float p[3]) {
    if (!b || !b->enabled) return 1;
    /* box-local = R^T (p - t) of T_fb */
    const double *T = b->T_fb;
    double d[3] = {p[0] - T[3], p[1] - T[7], p[2] - T[11]};
    for (int r = 0; r < 3; r++) {
        double q = T[r] * d[0] + T[4 + r] * d[1] + T[8 + r] * d[2];
        if (q < b->lo[r] || q > b->hi[r]) return 0;
    }
    return 1;
}

void sooc_surface_params_default(sooc_surface_params *p) {
    p->min_sigma = 0.01;
    p->min_share = 0;
    p->fill = 0;
}

/* Per segmentation cluster: claimants with less than min_share of the
 * cluster's claimed voxels give them to its largest claimant; with fill,
 * unclaimed voxels of a claimed cluster go to it too. */
static sooc_status consolidate(const int32_t *seg, int32_t *lab, size_t n, int nc, const sooc_surface_params *p) {
    int n_cl = 0;
    for (size_t i = 0; i < n; i++) n_cl = seg[i] + 1 > n_cl ? seg[i] + 1 : n_cl;
    if (!n_cl) return SOOC_OK;
    int *cnt = sooc_calloc((size_t)n_cl * (size_t)nc, sizeof *cnt), *top = sooc_malloc((size_t)n_cl * sizeof *top);
    if (!cnt || !top) {
        sooc_free(cnt), sooc_free(top);
        return sooc_seterr(SOOC_ENOMEM, "eval surface: out of memory for %d clusters", n_cl);
    }
    for (size_t i = 0; i < n; i++)
        if (seg[i] >= 0 && lab[i] > 0) cnt[(size_t)seg[i] * nc + lab[i]]++;
    for (int c = 0; c < n_cl; c++) {
        const int *q = cnt + (size_t)c * nc;
        int t = 0, tot = 0;
        for (int k = 1; k < nc; k++) {
            tot += q[k];
            if (q[k] > q[t]) t = k;
        }
        top[c] = t;
        cnt[(size_t)c * nc] = tot;   /* column 0 (unused by claimants): the claimed total */
    }
    for (size_t i = 0; i < n; i++) {
        int c = seg[i];
        if (c < 0 || !top[c]) continue;
        int tot = cnt[(size_t)c * nc];
        if (lab[i] > 0 ? cnt[(size_t)c * nc + lab[i]] < p->min_share * tot : p->fill) lab[i] = top[c];
    }
    sooc_free(cnt);
    sooc_free(top);
    return SOOC_OK;
}

sooc_status sooc_eval_surface_labels(sooc_model *m, const sooc_cogmap *map, sooc_cluster_map *cm,
                                     const sooc_frame *gt, int max_obj, const sooc_surface_params *sp,
                                     int *n_comp) {
    if (!m || !map || !cm || !gt || !n_comp) return sooc_seterr(SOOC_EINVAL, "eval surface: bad arguments");
    size_t n = 0;
    sooc_surface_params spd;
    if (!sp) sooc_surface_params_default(&spd), sp = &spd;
    sooc_status st = sooc_cluster_map_object_points(cm, NULL, NULL, 0, &n);
    if (st) return sooc_adderr(st, "eval surface");
    if (max_obj <= 0 || max_obj > SOOC_RENDER_MAX_COMP - 1) max_obj = SOOC_RENDER_MAX_COMP - 1;
    sooc_intrinsics K = gt->K;
    K.width = gt->width, K.height = gt->height;
    sooc_model_field *fld = NULL;
    if ((st = sooc_model_field_create(&fld, m, map, gt->T_wc, &K, max_obj, NULL)))
        return sooc_adderr(st, "eval surface: frame %lld", (long long)gt->index);
    const sooc_field *f = sooc_model_field_get(fld);
    *n_comp = f->n_comp;
    float *xyz = sooc_malloc((n ? n : 1) * 3 * sizeof *xyz), *best = sooc_malloc((n ? n : 1) * sizeof *best);
    int32_t *lab = sooc_malloc((n ? n : 1) * sizeof *lab), *seg = sooc_malloc((n ? n : 1) * sizeof *seg);
    float sig[SURF_BATCH], rgb[3 * SURF_BATCH];
    if (!xyz || !best || !lab || !seg) st = sooc_seterr(SOOC_ENOMEM, "eval surface: out of memory for %zu voxels", n);
    if (!st) st = sooc_cluster_map_object_points(cm, xyz, seg, n, &n);
    if (!st && f->prepare) st = f->prepare(f->user, 1, SURF_BATCH);
    if (!st) {
        /* world -> the field's frame: T_fc T_cw */
        double T_fc[16], T_cw[16], T_fw[16];
        sooc_model_field_T_fc(fld, T_fc);
        sooc_se3_inverse(T_cw, gt->T_wc);
        sooc_se3_mul(T_fw, T_fc, T_cw);
        for (size_t i = 0; i < n; i++) {
            double w[3] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]}, q[3];
            sooc_se3_apply(q, T_fw, w);
            for (int r = 0; r < 3; r++) xyz[3 * i + r] = (float)q[r];
            best[i] = (float)sp->min_sigma, lab[i] = -1;
        }
        for (int k = 1; k < f->n_comp; k++) {
            const sooc_render_box *b = f->boxes ? &f->boxes[k] : NULL;
            for (size_t i0 = 0; i0 < n; i0 += SURF_BATCH) {
                int nb = (int)(n - i0 < SURF_BATCH ? n - i0 : SURF_BATCH);
                f->eval(f->user, 0, k, xyz + 3 * i0, nb, sig, rgb);
                for (int j = 0; j < nb; j++) {
                    size_t i = i0 + (size_t)j;
                    if (sig[j] > best[i] && in_box(b, xyz + 3 * i)) best[i] = sig[j], lab[i] = k;
                }
            }
        }
        st = consolidate(seg, lab, n, f->n_comp, sp);
        if (!st) st = sooc_cluster_map_relabel(cm, lab, n);
    }
    sooc_free(xyz);
    sooc_free(best);
    sooc_free(lab);
    sooc_free(seg);
    sooc_model_field_destroy(fld);
    return st ? sooc_adderr(st, "eval surface: frame %lld", (long long)gt->index) : SOOC_OK;
}

sooc_status sooc_eval_surface_map(const sooc_cluster_params *cp, const sooc_frame *frames, int n,
                                  const uint8_t *use, sooc_cluster_map **out) {
    if (!cp || !out || n < 0 || (n && (!frames || !use))) return sooc_seterr(SOOC_EINVAL, "eval surface: bad arguments");
    *out = NULL;
    sooc_cluster_map *cm = NULL;
    sooc_status st = sooc_cluster_map_create(&cm, cp);
    for (int i = 0; i < n && !st; i++)
        if (use[i]) st = sooc_cluster_map_add_frame(cm, &frames[i]);
    int n_cl = 0;
    if (!st) st = sooc_cluster_map_segment(cm, &n_cl);
    if (st) {
        sooc_cluster_map_destroy(cm);
        return sooc_adderr(st, "eval surface: the mapped frames' clusters");
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
    int nc = 0;
    sooc_status st = sooc_eval_surface_labels(m, map, cm, gt, max_obj, sp, &nc);
    if (st) return st;
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
