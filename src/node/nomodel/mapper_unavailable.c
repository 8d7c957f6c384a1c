/* Linked into sooc3d_node only when the model module does not implement the
 * mapper yet: every call fails with a clear message instead of a link error. */
#include "sooc3d/mapper.h"

#include <string.h>

void sooc3d_mapper_params_default(sooc3d_mapper_params *p) { memset(p, 0, sizeof *p); }
sooc_status sooc3d_mapper_create(sooc3d_mapper **out, const sooc3d_mapper_params *p) {
    (void)p;
    *out = NULL;
    return sooc_seterr(SOOC_EUNSUPPORTED, "the model module (sooc3d_mapper_*) is not built in this version");
}
void sooc3d_mapper_destroy(sooc3d_mapper *m) { (void)m; }
void sooc3d_mapper_input_size(const sooc3d_mapper *m, int *w, int *h) { (void)m; *w = *h = 0; }
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
