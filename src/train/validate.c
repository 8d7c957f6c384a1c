/* Validation during training through the one evaluation path
 * (sooc_eval_run_scene): online inference over each validation scene's input
 * views with a private copy of the current model, then the query views and
 * the input views are rendered from the final map and scored. Returns the
 * mean best-match mIoU over query views, over input views, and the mean L2
 * error of matched objects in query views. */
#include "sooc3d/eval.h"
#include "sooc3d/model.h"
#include "sooc3d/train.h"

#include <math.h>
#include <string.h>

sooc_status sooc_train_validate(void *user, sooc_model *m, const sooc_dataset *val, double *miou,
                                double *miou_input, double *l2);

sooc_status sooc_train_validate(void *user, sooc_model *m, const sooc_dataset *val, double *miou,
                                double *miou_input, double *l2) {
    const sooc_train_config *cfg = user;
    int n_sc = sooc_dataset_n_scenes(val);
    if (cfg && cfg->val_scenes < n_sc) n_sc = cfg->val_scenes;
    sooc_eval_run_opts o;
    sooc_eval_run_opts_default(&o);
    o.n_coarse = 64;
    o.n_fine = 16;
    o.threads = cfg ? cfg->threads : 0;
    o.timing = SOOC_EVAL_FINAL;
    sooc_metric_sums q, in;
    memset(&q, 0, sizeof q);
    memset(&in, 0, sizeof in);
    sooc_status s = SOOC_OK;
    sooc_frame *fr = NULL;
    int fr_cap = 0;
    sooc_gt_object gt[512];
    for (int sc = 0; sc < n_sc && !s; sc++) {
        int nv = sooc_dataset_n_views(val, sc), n_obj = sooc_dataset_n_objects(val, sc);
        if (nv > fr_cap) {
            sooc_free(fr);
            fr_cap = nv;
            fr = sooc_malloc((size_t)nv * sizeof *fr);
            if (!fr) return SOOC_ENOMEM;
        }
        for (int v = 0; v < nv; v++) fr[v] = *sooc_dataset_view(val, sc, v);   /* shallow copies */
        if (n_obj > 512) n_obj = 512;
        for (int i = 0; i < n_obj; i++) sooc_dataset_object(val, sc, i, &gt[i].id, &gt[i].x, &gt[i].z);
        o.seed = 1000 + (uint64_t)sc;
        sooc_eval_scene_result r;
        s = sooc_eval_run_scene(m, fr, nv, gt, n_obj, &o, NULL, NULL, NULL, &r);
        if (s) break;
        sooc_metric_sums_merge(&q, &r.query);
        sooc_metric_sums_merge(&in, &r.input_final);
    }
    sooc_free(fr);
    sooc_metric_means mq, mi;
    sooc_metric_sums_means(&q, &mq);
    sooc_metric_sums_means(&in, &mi);
    *miou = mq.miou_best;
    *miou_input = mi.miou_best;
    *l2 = mq.l2;
    return s;
}
