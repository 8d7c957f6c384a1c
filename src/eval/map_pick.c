/* Which object a camera sees at each pixel of a stored map: the planner's
 * boxes (any map) or the model's rendering (a map built with that model).
 * `sooc3d map at` and tests call these (include/sooc3d/eval.h). */
#include "sooc3d/eval.h"
#include "sooc3d/cogmap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static sooc_status check_args(const double *T_wc, const sooc_intrinsics *K, const uint64_t *ids) {
    if (!T_wc || !K || !ids) return sooc_seterr(SOOC_EINVAL, "map_pick: missing argument");
    if (K->width <= 0 || K->height <= 0 || !(K->fx > 0) || !(K->fy > 0))
        return sooc_seterr(SOOC_EINVAL, "map_pick: bad camera (%dx%d, fx %g, fy %g)", K->width, K->height, K->fx,
                           K->fy);
    return SOOC_OK;
}

sooc_status sooc_map_pick_boxes(const sooc_map_entry *e, size_t n, const double T_wc[16], const sooc_intrinsics *K,
                                uint64_t *ids, float *depth) {
    sooc_status st = check_args(T_wc, K, ids);
    if (st) return st;
    if (n && !e) return sooc_seterr(SOOC_EINVAL, "map_pick: missing entries");
    sooc_render_box *b = malloc((n ? n : 1) * sizeof *b);
    if (!b) return SOOC_ENOMEM;
    for (size_t k = 0; k < n; k++) {
        double c[3], yaw;
        float ext[3];
        sooc_map_entry_box(&e[k], c, &yaw, ext);
        const double cy = cos(yaw), sy = sin(yaw);
        const double T[16] = {cy, 0, sy, c[0], 0, 1, 0, c[1], -sy, 0, cy, c[2], 0, 0, 0, 1};
        double lo[3], hi[3];
        for (int a = 0; a < 3; a++) hi[a] = 0.5 * ext[a], lo[a] = -hi[a];
        sooc_render_box_aabb(&b[k], lo, hi);
        memcpy(b[k].T_fb, T, sizeof T);
    }
    const double o[3] = {T_wc[3], T_wc[7], T_wc[11]};
    for (int v = 0; v < K->height; v++)
        for (int u = 0; u < K->width; u++) {
            /* the ray through the pixel's centre, unit planar depth: x(z) = o + z r */
            const double dc[3] = {(u + 0.5 - K->cx) / K->fx, (v + 0.5 - K->cy) / K->fy, 1.0};
            double r[3];
            for (int i = 0; i < 3; i++) r[i] = T_wc[4 * i] * dc[0] + T_wc[4 * i + 1] * dc[1] + T_wc[4 * i + 2] * dc[2];
            uint64_t best = 0;
            double bz = INFINITY, z0, z1;
            for (size_t k = 0; k < n; k++)
                if (e[k].id && sooc_render_ray_box(&b[k], o, r, 0.0, INFINITY, &z0, &z1) && z0 < bz) bz = z0, best = e[k].id;
            size_t p = (size_t)v * (size_t)K->width + (size_t)u;
            ids[p] = best;
            if (depth) depth[p] = best ? (float)bz : NAN;
        }
    free(b);
    return SOOC_OK;
}

sooc_status sooc_map_pick_model(sooc_model *m, const sooc_cogmap *map, const double T_wc[16],
                                const sooc_intrinsics *K, const sooc_intrinsics *K_view, int threads, uint64_t *ids,
                                float *depth) {
    sooc_status st = check_args(T_wc, K, ids);
    if (st) return st;
    if (!K_view) K_view = K;
    if (!m || !map) return sooc_seterr(SOOC_EINVAL, "map_pick: missing model or map");
    const sooc_model_config *c = sooc_model_get_config(m);
    sooc_render_opts ro;
    sooc_render_opts_default(&ro);
    ro.n_coarse = 96;
    ro.n_fine = 0;
    ro.t_near = c->t_near * c->unit_m;   /* as the evaluation renders (eval.h) */
    ro.d_clip = c->d_clip * c->unit_m;
    ro.threads = threads;
    sooc_model_field *fld = NULL;
    if ((st = sooc_model_field_create(&fld, m, map, T_wc, K_view, SOOC_RENDER_MAX_COMP - 1, NULL)))
        return sooc_adderr(st, "map_pick");
    double T_fc[16];
    sooc_model_field_T_fc(fld, T_fc);
    sooc_render_out out;
    memset(&out, 0, sizeof out);
    st = sooc_render_view(sooc_model_field_get(fld), K, T_fc, &ro, &out);
    if (!st) {
        size_t np = (size_t)K->width * (size_t)K->height;
        for (size_t p = 0; p < np; p++) {
            int l = out.label[p];
            ids[p] = l == SOOC_RENDER_LABEL_NONE ? 0 : sooc_model_field_comp_id(fld, l);   /* 0: the layout */
            if (depth) depth[p] = ids[p] ? out.depth[p] : NAN;
        }
    }
    sooc_render_out_free(&out);
    sooc_model_field_destroy(fld);
    return st;
}
