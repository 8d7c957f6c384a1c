/* sooc3d map export --db MAP --mcap FILE: the stored map as an MCAP file
 * Foxglove opens (docs/logs.md "Foxglove"): foxglove.SceneUpdate messages in
 * JSON on /sooc3d/objects, one entity per object (a cube of its box, its id
 * as a text label, its presence and covariance as metadata), one message per
 * time an object was first seen and the last one holding every object; and
 * foxglove.FrameTransform on /sooc3d/frames: map (z up, REP 103) -> world (the
 * map's +y-up frame) -> source (the pose source's frame, when the map stores
 * it). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "sooc3d/log.h"
#include "sooc3d/cogmap.h"

typedef struct ex_obj {
    sooc_cogmap_entry e;
    sooc_map_entry me;   /* the entry with its stored box: what the entity shows */
    double cov[4], h;
    int has_geom;
} ex_obj;

typedef struct ex_ctx {
    sooc_mapstore *s;
    ex_obj *o;
    size_t n, cap;
    sooc_status st;
} ex_ctx;

static int collect(void *u, const sooc_cogmap_entry *e) {
    ex_ctx *c = u;
    if (c->n == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 64;
        ex_obj *o = realloc(c->o, cap * sizeof *o);
        if (!o) {
            c->st = SOOC_ENOMEM;
            return 1;
        }
        c->o = o;
        c->cap = cap;
    }
    ex_obj *x = &c->o[c->n];
    memset(x, 0, sizeof *x);
    x->e = *e;
    sooc_map_geometry g;
    memset(&g, 0, sizeof g);
    int found = 0;
    float ext[3] = {0, 0, 0};
    if ((c->st = sooc_mapstore_geom_get(c->s, e->id, ext, &g, &found))) return 1;
    sooc_map_entry *me = &x->me;
    sooc_map_entry_from_cogmap(e, found ? ext : NULL, me);
    if (found) me->geom = g;
    sooc_map_entry_planner_cov(me, x->cov);
    x->h = sooc_map_entry_height(me);
    x->has_geom = found;
    c->n++;
    return 0;
}

static int by_first_seen(const void *a, const void *b) {
    const ex_obj *x = a, *y = b;
    if (x->e.first_seen_ns != y->e.first_seen_ns) return x->e.first_seen_ns < y->e.first_seen_ns ? -1 : 1;
    return x->e.id < y->e.id ? -1 : x->e.id > y->e.id;
}

/* At most this many SceneUpdates: objects first seen close together share one. */
#define MAX_UPDATES 200

int sooc_cli_map_export_mcap(const char *db, const char *out) {
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    mp.readonly = 1;
    ex_ctx c = {0};
    sooc_status st = sooc_mapstore_open(&c.s, db, &mp);
    if (st) return sooc_cli_fail("map export", st);
    st = sooc_mapstore_foreach(c.s, collect, &c);
    if (!st) st = c.st;
    sooc_map_frame fr;
    int has_frame = 0;
    if (!st) st = sooc_mapstore_frame_get(c.s, &fr, &has_frame);
    sooc_mapstore_close(c.s);
    if (st) {
        free(c.o);
        return sooc_cli_fail("map export", st);
    }
    qsort(c.o, c.n, sizeof *c.o, by_first_seen);
    int64_t t0 = c.n ? c.o[0].e.first_seen_ns : 0, t1 = t0;
    for (size_t i = 0; i < c.n; i++)
        if (c.o[i].e.last_seen_ns > t1) t1 = c.o[i].e.last_seen_ns;
    sooc_mcap_writer_params wp;
    sooc_mcap_writer_params_default(&wp);
    sooc_mcap_writer *w = NULL;
    sooc_ros_buf b = {0};
    int sc_scene, sc_frame, ch_scene, ch_frame;
    st = sooc_mcap_writer_open(&w, out, &wp);
    if (!st) st = sooc_mcap_writer_schema(w, "foxglove.SceneUpdate", "jsonschema", sooc_foxglove_scene_schema, strlen(sooc_foxglove_scene_schema), &sc_scene);
    if (!st) st = sooc_mcap_writer_schema(w, "foxglove.FrameTransform", "jsonschema", sooc_foxglove_frame_schema, strlen(sooc_foxglove_frame_schema), &sc_frame);
    if (!st) st = sooc_mcap_writer_channel(w, sc_frame, "/sooc3d/frames", "json", &ch_frame);
    if (!st) st = sooc_mcap_writer_channel(w, sc_scene, "/sooc3d/objects", "json", &ch_scene);
    double Tws[16];
    if (!st) {
        sooc_foxglove_frame(&b, t0, "map", "world", sooc_foxglove_T_map_world);
        st = b.oom ? SOOC_ENOMEM : sooc_mcap_writer_message(w, ch_frame, t0, t0, b.data, b.size);
        b.size = 0;
    }
    if (!st && has_frame) {
        memcpy(Tws, fr.T_world_src, sizeof Tws);
        sooc_foxglove_frame(&b, t0, "world", "source", Tws);
        st = b.oom ? SOOC_ENOMEM : sooc_mcap_writer_message(w, ch_frame, t0, t0, b.data, b.size);
        b.size = 0;
    }
    /* cumulative updates in first-seen order; the last holds every object */
    size_t step = c.n > MAX_UPDATES ? (c.n + MAX_UPDATES - 1) / MAX_UPDATES : 1;
    size_t n_msgs = 0;
    for (size_t upto = c.n ? (step < c.n ? step : c.n) : 0; !st;) {
        int64_t t = upto ? c.o[upto - 1].e.first_seen_ns : t0;
        if (upto == c.n && t1 > t) t = t1;
        sooc_foxglove_printf(&b, "{\"deletions\": [], \"entities\": [");
        for (size_t i = 0; i < upto; i++) {
            if (i) sooc_foxglove_printf(&b, ", ");
            sooc_foxglove_entity(&b, &c.o[i].me, c.o[i].cov, c.o[i].h, t);
        }
        sooc_foxglove_printf(&b, "]}");
        st = b.oom ? SOOC_ENOMEM : sooc_mcap_writer_message(w, ch_scene, t, t, b.data, b.size);
        b.size = 0;
        n_msgs++;
        if (upto >= c.n) break;
        upto = upto + step < c.n ? upto + step : c.n;
    }
    sooc_ros_buf_free(&b);
    free(c.o);
    if (st) {
        sooc_mcap_writer_abort(w);
        return sooc_cli_fail("map export", st);
    }
    if ((st = sooc_mcap_writer_close(w))) return sooc_cli_fail("map export", st);
    fprintf(stderr, "wrote %zu object(s) in %zu SceneUpdate message(s) to %s (frames map, world%s)\n", c.n, n_msgs,
            out, has_frame ? ", source" : "");
    return 0;
}
