/* YAML walking shared by the four loaders (calib.c and scene.c here, the
 * node's launch.c and the trainer's config.c, which link sooc3d_data; the
 * internal interface of src/data, docs/architecture.md "Layers"):
 * parse one document from memory, lines and scalars of nodes, and the key
 * checks made on every mapping pair. Each loader keeps its own value parsing
 * (ranges, wording). Internal: include as "data/yaml_doc.h"; not public API.
 *
 * Every message starts "<file>:<line>: " and names the key (section.key). */
#ifndef SOOC3D_DATA_YAML_DOC_H
#define SOOC3D_DATA_YAML_DOC_H

#include "sooc3d/core.h"

#include <stddef.h>
#include <yaml.h>

typedef struct sooc_ydoc {
    yaml_document_t doc;
    const char *name;     /* the file named in messages (borrowed) */
} sooc_ydoc;

/* Parses text[0..n) as one YAML document. An OpenCV "%YAML:1.0" first line
 * (after an optional UTF-8 BOM), which libyaml refuses, is blanked first
 * (line numbers are kept). Errors: SOOC_EFORMAT "<name>:<line>: YAML error:
 * <problem> <context>", SOOC_ENOMEM. On success free with sooc_ydoc_free. */
sooc_status sooc_ydoc_parse(sooc_ydoc *d, const void *text, size_t n, const char *name);
/* NULL-safe after a failed parse too. */
void sooc_ydoc_free(sooc_ydoc *d);

/* The root node; NULL for an empty document. */
static inline yaml_node_t *sooc_ydoc_root(sooc_ydoc *d) { return yaml_document_get_root_node(&d->doc); }

/* 1-based line of a node. */
static inline int sooc_yline(const yaml_node_t *n) { return (int)n->start_mark.line + 1; }

/* The node's text if it is a scalar, else NULL (also for n == NULL). */
static inline const char *sooc_yscalar(const yaml_node_t *n) {
    return n && n->type == YAML_SCALAR_NODE ? (const char *)n->data.scalar.value : NULL;
}

/* Number of items of a sequence node (0 for other nodes). */
static inline int sooc_yseq_len(const yaml_node_t *n) {
    return n->type == YAML_SEQUENCE_NODE ? (int)(n->data.sequence.items.top - n->data.sequence.items.start) : 0;
}

/* Item i (0 <= i < sooc_yseq_len) of a sequence node. */
static inline yaml_node_t *sooc_yseq_item(sooc_ydoc *d, const yaml_node_t *n, int i) {
    return yaml_document_get_node(&d->doc, n->data.sequence.items.start[i]);
}

/* One pair of a mapping, as the loaders walk it. */
typedef struct sooc_ypair {
    yaml_node_t *k, *v;
    const char *key;      /* the key's text */
} sooc_ypair;

/* Reads pair p of mapping m into *out. The key must be a scalar ("<ctx>: keys
 * must be plain strings") and, if check_dup, must not repeat an earlier key of
 * m ("<ctx>.<key>: duplicate key (first given at line N)"; YAML forbids them,
 * libyaml keeps both). ctx names the mapping in messages (NULL or "" at the
 * top level). */
sooc_status sooc_ymap_pair(sooc_ydoc *d, const yaml_node_t *m, const yaml_node_pair_t *p, const char *ctx,
                           int check_dup, sooc_ypair *out);

#endif
