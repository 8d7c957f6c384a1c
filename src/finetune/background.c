/* The background test of finetuning (docs/finetune.md "The support plane"):
 * the views' depth goes into one support-plane clustering (src/cluster, the
 * rule of docs/geometric.md on 1 cm voxels: the model's frames are coarse);
 * once every view is in, each view is rendered from it, and a surface ray
 * whose depth meets a voxel that the clustering calls background (the plane,
 * a wall, the surround, a speck or a sliver) is the layout's (surf 2). */
#include "finetune/finetune_impl.h"

#include <math.h>
#include <string.h>

#define BG_VOXEL_M 0.01

sooc_status sooc_ft_bg_add(sooc_finetune *ft, const sooc_frame *f) {
    if (!ft->bg) {
        const sooc_model_config *c = &ft->m->cfg;
        sooc_cluster_params cp;
        sooc_cluster_params_default(&cp);
        cp.voxel_m = BG_VOXEL_M;
        double clip = c->d_clip * c->unit_m;
        if (clip > 0 && clip < cp.max_depth_m) cp.max_depth_m = clip;
        sooc_status st = sooc_cluster_map_create(&ft->bg, &cp);
        if (st) return sooc_adderr(st, "finetune: background clustering");
    }
    return sooc_cluster_map_add_frame(ft->bg, f);
}

sooc_status sooc_ft_bg_mark(sooc_finetune *ft) {
    int nobj = 0;
    sooc_status st = sooc_cluster_map_segment(ft->bg, &nobj);
    if (st) return sooc_adderr(st, "finetune: background clustering");
    size_t cap = 0;
    int16_t *lab = NULL;
    float *dep = NULL;
    double u = ft->m->cfg.unit_m;
    for (int vi = 0; vi < ft->nv && !st; vi++) {
        const sooc_ft_view *v = &ft->views[vi];
        int w = v->K.width, h = v->K.height;
        size_t np = (size_t)w * h;
        if (np > cap) {
            sooc_free(lab), sooc_free(dep);
            lab = sooc_malloc(np * sizeof *lab), dep = sooc_malloc(np * sizeof *dep), cap = np;
            if (!lab || !dep) {
                st = SOOC_ENOMEM;
                break;
            }
        }
        if ((st = sooc_cluster_map_render(ft->bg, v->T_wc, &v->K, w, h, lab, dep, NULL))) {
            sooc_adderr(st, "finetune: background of view %d", vi);
            break;
        }
        size_t r1 = vi + 1 < ft->nv ? ft->views[vi + 1].r0 : ft->nr;
        for (size_t r = v->r0; r < r1; r++) {
            uint32_t pix = ft->rpix[r];
            if (ft->surf[r] != 1 || lab[pix] >= 0 || !(dep[pix] > 0)) continue;
            double dc[3];
            double uz = sooc_cam_ray(&v->K, (double)(pix % (uint32_t)w), (double)(pix / (uint32_t)w), dc);
            double z = (double)ft->depth[r] * u * uz;   /* the ray's planar depth, metres */
            /* the voxel met is the ray's own surface: within two voxels and 1% */
            if (fabs(dep[pix] - z) <= 2 * BG_VOXEL_M + 0.01 * z) ft->surf[r] = 2;
        }
    }
    sooc_free(lab);
    sooc_free(dep);
    return st;
}
