/* Internals shared by the data module's files (not public API). */
#ifndef SOOC3D_DATA_IMPL_H
#define SOOC3D_DATA_IMPL_H

#include "sooc3d/core.h"

#include <string.h>
#include <yaml.h>

/* Write `buf` to "<path>.tmp" then rename it over `path` (no fsync): bulk
 * dataset files (frames, meshes, pictures). */
sooc_status sooc_data_write_file(const char *path, const void *buf, size_t n);

/* YAML forbids duplicate mapping keys but libyaml does not check them. Returns
 * the 1-based line of a pair before `p` in mapping `m` whose scalar key equals
 * `key`, or 0 if there is none. The loaders call it before acting on a key and
 * reject unknown keys, so every earlier key is a distinct known key and the scan
 * stays short. */
static inline int sooc_data_yaml_dup_line(yaml_document_t *doc, const yaml_node_t *m,
                                          const yaml_node_pair_t *p, const char *key) {
    for (const yaml_node_pair_t *q = m->data.mapping.pairs.start; q < p; q++) {
        const yaml_node_t *k = yaml_document_get_node(doc, q->key);
        if (k && k->type == YAML_SCALAR_NODE && !strcmp((const char *)k->data.scalar.value, key))
            return (int)k->start_mark.line + 1;
    }
    return 0;
}

#endif
