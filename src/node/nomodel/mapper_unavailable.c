/* Linked into sooc3d_node only when the model module does not implement the
 * mapper yet: every call fails with a clear message instead of a link error. */
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"

#include <string.h>

void sooc3d_mapper_params_default(sooc3d_mapper_params *p) { memset(p, 0, sizeof *p); }
sooc_status sooc3d_mapper_create(sooc3d_mapper **out, const sooc3d_mapper_params *p) {
    (void)p;
    *out = NULL;
    return sooc_seterr(SOOC_EUNSUPPORTED, "the model module (sooc3d_mapper_*) is not built in this version");
}
void sooc3d_mapper_destroy(sooc3d_mapper *m) { (void)m; }
void sooc3d_mapper_input_size(const sooc3d_mapper *m, int *w, int *h) { (void)m; *w = *h = 0; }
void sooc3d_mapper_cam_heights(const sooc3d_mapper *m, double *lo_m, double *hi_m) {
    (void)m;
    *lo_m = SOOC_MODEL_CAM_H_MIN, *hi_m = SOOC_MODEL_CAM_H_MAX;   /* a default model's, at unit 1 */
}
sooc_status sooc3d_mapper_update(sooc3d_mapper *m, const sooc_frame *f, sooc3d_update_stats *st) {
    (void)m; (void)f; (void)st;
    return sooc_seterr(SOOC_EUNSUPPORTED, "no model");
}
sooc_status sooc3d_mapper_entries(const sooc3d_mapper *m, sooc_map_entry *out, size_t cap, size_t *n) {
    (void)m; (void)out; (void)cap; *n = 0;
    return SOOC_OK;
}
sooc_status sooc3d_mapper_load_entries(sooc3d_mapper *m, const sooc_map_entry *e, size_t n) {
    (void)m; (void)e; (void)n;
    return sooc_seterr(SOOC_EUNSUPPORTED, "no model");
}
sooc_status sooc3d_mapper_changed(const sooc3d_mapper *m, sooc_map_entry *out, size_t cap, size_t *n,
                                  uint64_t *removed_ids, size_t cap_r, size_t *n_removed) {
    (void)m; (void)out; (void)cap; (void)removed_ids; (void)cap_r;
    if (n) *n = 0;
    if (n_removed) *n_removed = 0;
    return SOOC_OK;
}
int sooc3d_mapper_layout_dim(const sooc3d_mapper *m) { (void)m; return 0; }
int sooc3d_mapper_latent_dim(const sooc3d_mapper *m) { (void)m; return 0; }
sooc_status sooc3d_mapper_last_layout(const sooc3d_mapper *m, int32_t *bi, int32_t *bj, float *mu, float *logvar) {
    (void)m; (void)bi; (void)bj; (void)mu; (void)logvar;
    return SOOC_ENOTFOUND;
}
sooc_status sooc3d_mapper_load_layout(sooc3d_mapper *m, int32_t bi, int32_t bj, const float *mu,
                                      const float *logvar) {
    (void)m; (void)bi; (void)bj; (void)mu; (void)logvar;
    return sooc_seterr(SOOC_EUNSUPPORTED, "no model");
}
void sooc3d_mapper_reserve_ids(sooc3d_mapper *m, uint64_t next_id) { (void)m; (void)next_id; }
uint64_t sooc3d_mapper_next_id(const sooc3d_mapper *m) { (void)m; return 1; }
