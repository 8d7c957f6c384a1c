/* Every entry of a stored map as a planner receives it (include/sooc3d/cogmap.h
 * "planner entries"): the entry with its stored box and spreads. */
#include <string.h>

#include "cogmap/mapstore_impl.h"
#include "sooc3d/cogmap.h"

typedef struct planner_ctx {
    sooc_mapstore *s;
    sooc_map_entry *e;
    size_t n, cap;
    sooc_status st;
} planner_ctx;

static int planner_cb(void *u, const sooc_cogmap_entry *c) {
    planner_ctx *a = u;
    if (a->n == a->cap) {
        size_t cap = a->cap ? 2 * a->cap : 64;
        sooc_map_entry *e = sooc_realloc(a->e, cap * sizeof *e);
        if (!e) {
            a->st = sooc_seterr(SOOC_ENOMEM, "mapstore: out of memory for %zu entries", cap);
            return 1;
        }
        a->e = e, a->cap = cap;
    }
    float ext[3] = {0, 0, 0};
    sooc_map_geometry g;
    memset(&g, 0, sizeof g);
    int found = 0;
    if ((a->st = sooc_mapstore_geom_get(a->s, c->id, ext, &g, &found))) return 1;
    sooc_map_entry *me = &a->e[a->n++];
    sooc_map_entry_from_cogmap(c, found ? ext : NULL, me);
    if (found) me->geom = g;
    return 0;
}

sooc_status sooc_mapstore_planner_entries(sooc_mapstore *s, sooc_map_entry **out, size_t *n) {
    if (!s || !out || !n) return sooc_seterr(SOOC_EINVAL, "mapstore: planner_entries: missing argument");
    *out = NULL, *n = 0;
    planner_ctx a = {s, NULL, 0, 0, SOOC_OK};
    sooc_status st = sooc_mapstore_foreach(s, planner_cb, &a);
    if (!st) st = a.st;
    if (st) {
        sooc_free(a.e);
        return st;
    }
    *out = a.e, *n = a.n;
    return SOOC_OK;
}
