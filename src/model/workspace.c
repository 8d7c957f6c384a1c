/* A runner's workspace (sooc3d/model.h sooc_model_ws; docs/model.md
 * "Layers"): the parts each layer runs on, made by that layer and gathered
 * here, in the step layer, the lowest one that knows them all. The weights
 * (struct sooc_model) own none of it. */
#include "model/step.h"

sooc_status sooc_model_ws_create(sooc_model_ws **out, sooc_model *m) {
    *out = NULL;
    if (!m) return sooc_seterr(SOOC_EINVAL, "model workspace: no model");
    sooc_model_ws *w = sooc_calloc(1, sizeof *w);
    if (!w) return SOOC_ENOMEM;
    w->m = m;
    sooc_status st;
    if ((st = sooc_mdl_dec_ws_create(m, &w->dec)) || (st = sooc_mdl_ref_ws_create(m, &w->ref))) {
        sooc_model_ws_destroy(w);
        return sooc_adderr(st, "model workspace");
    }
    *out = w;
    return SOOC_OK;
}

void sooc_model_ws_destroy(sooc_model_ws *w) {
    if (!w) return;
    sooc_mdl_step_free(w->step);
    sooc_mdl_ref_ws_destroy(w->ref);
    sooc_mdl_dec_ws_destroy(w->dec);
    sooc_mdl_pool_free(w);
    sooc_free(w);
}
