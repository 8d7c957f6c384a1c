/* Validation during training: online inference over each validation scene's
 * input views with a copy of the current model, then render the query views
 * (and the input views) from the final map and score them with the
 * evaluation path (sooc_eval_view). Returns the mean best-match mIoU over
 * query views, over input views, and the mean L2 error of matched objects. */
#include "sooc3d/eval.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "sooc3d/train.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

sooc_status sooc_train_validate(void *user, sooc_model *m, const sooc_dataset *val, double *miou,
                                double *miou_input, double *l2);

/* A private copy of the model for the mapper (which takes ownership), made
 * through an in-memory round trip of the checkpoint format. */
static sooc_status model_copy(sooc_model *m, sooc_model **out) {
    char path[64];
    snprintf(path, sizeof path, "/tmp/sooc3d_val_%ld.bin", (long)getpid());
    sooc_status s = sooc_model_save(m, path, NULL, 0);
    if (!s) s = sooc_model_load(out, path, NULL, NULL);
    unlink(path);
    return s;
}

sooc_status sooc_train_validate(void *user, sooc_model *m, const sooc_dataset *val, double *miou,
                                double *miou_input, double *l2) {
    const sooc_train_config *cfg = user;
    const sooc_model_config *mc = sooc_model_get_config(m);
    int n_sc = sooc_dataset_n_scenes(val);
    if (cfg && cfg->val_scenes < n_sc) n_sc = cfg->val_scenes;
    double sum_q = 0, sum_i = 0, sum_l2 = 0;
    long n_q = 0, n_i = 0, n_l2 = 0;
    sooc_render_opts ro;
    sooc_render_opts_default(&ro);
    ro.d_clip = mc->d_clip;
    ro.t_near = mc->t_near;
    ro.n_coarse = 64;
    ro.n_fine = 16;
    sooc_render_out rout;
    memset(&rout, 0, sizeof rout);
    sooc_status s = SOOC_OK;
    for (int sc = 0; sc < n_sc && !s; sc++) {
        sooc_model *copy = NULL;
        sooc3d_mapper *mp = NULL;
        if ((s = model_copy(m, &copy))) break;
        if ((s = sooc3d_mapper_create_with_model(&mp, copy, 0, 1000 + (uint64_t)sc, cfg ? cfg->threads : 0))) {
            sooc_model_destroy(copy);
            break;
        }
        int nv = sooc_dataset_n_views(val, sc), n_obj = sooc_dataset_n_objects(val, sc);
        for (int v = 0; v < nv && !s; v++) {
            const sooc_frame *f = sooc_dataset_view(val, sc, v);
            if (!f->is_query) s = sooc3d_mapper_update(mp, f, NULL);
        }
        sooc_gt_object gt[512];
        if (n_obj > 512) n_obj = 512;
        for (int i = 0; i < n_obj; i++) sooc_dataset_object(val, sc, i, &gt[i].id, &gt[i].x, &gt[i].z);
        const sooc_cogmap *map = sooc3d_mapper_cogmap(mp);
        for (int v = 0; v < nv && !s; v++) {
            const sooc_frame *f = sooc_dataset_view(val, sc, v);
            sooc_model_field *fld = NULL;
            if ((s = sooc_model_field_create(&fld, sooc3d_mapper_model(mp), map, f->T_wc, &f->K, mc->K, NULL)))
                break;
            const sooc_field *field = sooc_model_field_get(fld);
            double T_fc[16], xz[2 * (SOOC_MODEL_K_MAX + 1)];
            sooc_model_field_T_fc(fld, T_fc);
            for (int c = 0; c < field->n_comp && c <= SOOC_MODEL_K_MAX; c++) {
                sooc_cogmap_entry e;
                uint64_t id = sooc_model_field_comp_id(fld, c);
                if (id && sooc_cogmap_get(map, id, &e) == SOOC_OK) {
                    xz[2 * c] = e.X;
                    xz[2 * c + 1] = e.Z;
                } else {
                    xz[2 * c] = xz[2 * c + 1] = NAN;
                }
            }
            sooc_view_metrics vm;
            s = sooc_eval_view(field, T_fc, f, &ro, xz, gt, n_obj, &rout, &vm, NULL);
            sooc_model_field_destroy(fld);
            if (s || !isfinite(vm.miou_best)) continue;
            if (f->is_query) {
                sum_q += vm.miou_best;
                n_q++;
                sum_l2 += vm.l2_sum;
                n_l2 += vm.n_obj_matched;
            } else {
                sum_i += vm.miou_best;
                n_i++;
            }
        }
        sooc3d_mapper_destroy(mp);
    }
    sooc_render_out_free(&rout);
    *miou = n_q ? sum_q / (double)n_q : NAN;
    *miou_input = n_i ? sum_i / (double)n_i : NAN;
    *l2 = n_l2 ? sum_l2 / (double)n_l2 : NAN;
    return s;
}
