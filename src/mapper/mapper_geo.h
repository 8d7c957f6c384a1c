/* The geometric object map behind the mapper's interface (mapper_geo.c;
 * mapper.h SOOC_MAPPER_GEOMETRIC). Internal to src/model: mapper.c calls
 * it when the mapper was created with kind geometric. */
#ifndef SOOC3D_MODEL_MAPPER_GEO_H
#define SOOC3D_MODEL_MAPPER_GEO_H

#include "sooc3d/mapper.h"

typedef struct sooc_mdl_geo sooc_mdl_geo;

sooc_status sooc_mdl_geo_create(sooc_mdl_geo **out, const sooc_mapper_params *p);
void sooc_mdl_geo_destroy(sooc_mdl_geo *g);
void sooc_mdl_geo_input_size(const sooc_mdl_geo *g, int *w, int *h);
sooc_status sooc_mdl_geo_update(sooc_mdl_geo *g, const sooc_frame *f, sooc_update_stats *st);
sooc_status sooc_mdl_geo_entries(const sooc_mdl_geo *g, sooc_map_entry *out, size_t cap, size_t *n);
sooc_status sooc_mdl_geo_load_entries(sooc_mdl_geo *g, const sooc_map_entry *e, size_t n);
sooc_status sooc_mdl_geo_changed(const sooc_mdl_geo *g, sooc_map_entry *out, size_t cap, size_t *n, uint64_t *removed_ids,
                            size_t cap_r, size_t *n_removed);
void sooc_mdl_geo_clear(sooc_mdl_geo *g);   /* entries and clusters; ids go on */
uint64_t sooc_mdl_geo_next_id(const sooc_mdl_geo *g);
void sooc_mdl_geo_reserve_ids(sooc_mdl_geo *g, uint64_t next_id);

#endif
