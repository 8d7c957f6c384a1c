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
#include "sooc3d/geom.h"
#include "sooc3d/log.h"
#include "sooc3d/map_entry.h"
#include "sooc3d/mapstore.h"

/* JSON schemas of the two Foxglove message types, written from the field
 * tables of Foxglove's schema documentation (only the fields used here are
 * spelled out; Foxglove recognises the types by their names). */
#define VEC3 "{\"type\": \"object\", \"properties\": {\"x\": {\"type\": \"number\"}, \"y\": {\"type\": \"number\"}, \"z\": {\"type\": \"number\"}}}"
#define QUAT "{\"type\": \"object\", \"properties\": {\"x\": {\"type\": \"number\"}, \"y\": {\"type\": \"number\"}, \"z\": {\"type\": \"number\"}, \"w\": {\"type\": \"number\"}}}"
#define TIME "{\"type\": \"object\", \"properties\": {\"sec\": {\"type\": \"integer\"}, \"nsec\": {\"type\": \"integer\"}}}"
#define POSE "{\"type\": \"object\", \"properties\": {\"position\": " VEC3 ", \"orientation\": " QUAT "}}"
#define COLOR "{\"type\": \"object\", \"properties\": {\"r\": {\"type\": \"number\"}, \"g\": {\"type\": \"number\"}, \"b\": {\"type\": \"number\"}, \"a\": {\"type\": \"number\"}}}"
static const char SCENE_SCHEMA[] =
    "{\"title\": \"foxglove.SceneUpdate\", \"type\": \"object\", \"properties\": {"
    "\"deletions\": {\"type\": \"array\", \"items\": {\"type\": \"object\"}}, "
    "\"entities\": {\"type\": \"array\", \"items\": {\"title\": \"foxglove.SceneEntity\", \"type\": \"object\", "
    "\"properties\": {\"timestamp\": " TIME ", \"frame_id\": {\"type\": \"string\"}, \"id\": {\"type\": \"string\"}, "
    "\"lifetime\": " TIME ", \"frame_locked\": {\"type\": \"boolean\"}, "
    "\"metadata\": {\"type\": \"array\", \"items\": {\"type\": \"object\", \"properties\": {\"key\": {\"type\": "
    "\"string\"}, \"value\": {\"type\": \"string\"}}}}, "
    "\"cubes\": {\"type\": \"array\", \"items\": {\"title\": \"foxglove.CubePrimitive\", \"type\": \"object\", "
    "\"properties\": {\"pose\": " POSE ", \"size\": " VEC3 ", \"color\": " COLOR "}}}, "
    "\"texts\": {\"type\": \"array\", \"items\": {\"title\": \"foxglove.TextPrimitive\", \"type\": \"object\", "
    "\"properties\": {\"pose\": " POSE ", \"billboard\": {\"type\": \"boolean\"}, \"font_size\": {\"type\": "
    "\"number\"}, \"scale_invariant\": {\"type\": \"boolean\"}, \"color\": " COLOR ", \"text\": {\"type\": "
    "\"string\"}}}}}}}}}";
static const char FRAME_SCHEMA[] =
    "{\"title\": \"foxglove.FrameTransform\", \"type\": \"object\", \"properties\": {\"timestamp\": " TIME
    ", \"parent_frame_id\": {\"type\": \"string\"}, \"child_frame_id\": {\"type\": \"string\"}, \"translation\": " VEC3
    ", \"rotation\": " QUAT "}}";

typedef struct ex_obj {
    sooc_cogmap_entry e;
    float ext[3];
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
    if ((c->st = sooc_mapstore_geom_get(c->s, e->id, x->ext, &g, &found))) return 1;
    sooc_map_entry me;
    sooc_map_entry_from_cogmap(e, found ? x->ext : NULL, &me);
    if (found) me.geom = g;
    sooc_map_entry_planner_cov(&me, x->cov);
    memcpy(x->ext, me.extent, sizeof x->ext);
    x->h = (g.flags & SOOC_GEOM_TIGHT) ? 2.0 * g.centre[1] : (double)me.extent[1];
    x->has_geom = found;
    c->n++;
    return 0;
}

static int by_first_seen(const void *a, const void *b) {
    const ex_obj *x = a, *y = b;
    if (x->e.first_seen_ns != y->e.first_seen_ns) return x->e.first_seen_ns < y->e.first_seen_ns ? -1 : 1;
    return x->e.id < y->e.id ? -1 : x->e.id > y->e.id;
}

/* Appends printf output to b (JSON text). */
static void jp(sooc_ros_buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void jp(sooc_ros_buf *b, const char *fmt, ...) {
    va_list ap;
    for (int pass = 0; pass < 2 && !b->oom; pass++) {
        size_t room = b->cap - b->size;
        va_start(ap, fmt);
        int k = vsnprintf((char *)b->data + b->size, room, fmt, ap);
        va_end(ap);
        if (k < 0) { b->oom = 1; return; }
        if ((size_t)k < room) { b->size += (size_t)k; return; }
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->size + (size_t)k + 1) cap *= 2;
        uint8_t *p = sooc_realloc(b->data, cap);
        if (!p) { b->oom = 1; return; }
        b->data = p;
        b->cap = cap;
    }
}

static void j_time(sooc_ros_buf *b, int64_t t) {
    if (t < 0) t = 0;
    jp(b, "{\"sec\": %lld, \"nsec\": %lld}", (long long)(t / 1000000000), (long long)(t % 1000000000));
}

/* One entity: the box (centre at half its height, turned by yaw about +y), the label, the metadata. */
static void j_entity(sooc_ros_buf *b, const ex_obj *x, int64_t t) {
    const sooc_cogmap_entry *e = &x->e;
    double p = 1.0 / (1.0 + exp(-e->pres_logit)), qy = sin(0.5 * e->Theta), qw = cos(0.5 * e->Theta);
    uint64_t hsh = e->id * 0x9e3779b97f4a7c15ULL;
    double col[3] = {0.25 + 0.75 * (double)((hsh >> 8) & 0xff) / 255, 0.25 + 0.75 * (double)((hsh >> 16) & 0xff) / 255,
                     0.25 + 0.75 * (double)((hsh >> 24) & 0xff) / 255};
    jp(b, "{\"timestamp\": ");
    j_time(b, t);
    jp(b, ", \"frame_id\": \"world\", \"id\": \"object %llu\", \"lifetime\": {\"sec\": 0, \"nsec\": 0}, "
          "\"frame_locked\": false, \"metadata\": [", (unsigned long long)e->id);
    jp(b, "{\"key\": \"id\", \"value\": \"%llu\"}, {\"key\": \"presence\", \"value\": \"%.4f\"}, "
          "{\"key\": \"sigma_t_m\", \"value\": \"%.4g\"}, {\"key\": \"sigma_yaw_rad\", \"value\": \"%.4g\"}, "
          "{\"key\": \"cov_xx\", \"value\": \"%.6g\"}, {\"key\": \"cov_xz\", \"value\": \"%.6g\"}, "
          "{\"key\": \"cov_zz\", \"value\": \"%.6g\"}, {\"key\": \"var_yaw\", \"value\": \"%.6g\"}, "
          "{\"key\": \"obs_count\", \"value\": \"%u\"}, {\"key\": \"first_seen_ns\", \"value\": \"%lld\"}, "
          "{\"key\": \"last_seen_ns\", \"value\": \"%lld\"}], ",
       (unsigned long long)e->id, p, sqrt(0.5 * (x->cov[0] + x->cov[2])), sqrt(x->cov[3]), x->cov[0], x->cov[1],
       x->cov[2], isfinite(x->cov[3]) ? x->cov[3] : -1.0, e->obs_count, (long long)e->first_seen_ns,
       (long long)e->last_seen_ns);
    jp(b, "\"cubes\": [{\"pose\": {\"position\": {\"x\": %.6f, \"y\": %.6f, \"z\": %.6f}, \"orientation\": {\"x\": 0, "
          "\"y\": %.9f, \"z\": 0, \"w\": %.9f}}, \"size\": {\"x\": %.4f, \"y\": %.4f, \"z\": %.4f}, \"color\": {\"r\": "
          "%.3f, \"g\": %.3f, \"b\": %.3f, \"a\": %.3f}}], ",
       e->X, 0.5 * x->h, e->Z, qy, qw, x->ext[0], x->h > 0 ? x->h : x->ext[1], x->ext[2], col[0], col[1], col[2],
       0.25 + 0.5 * p);
    jp(b, "\"texts\": [{\"pose\": {\"position\": {\"x\": %.6f, \"y\": %.6f, \"z\": %.6f}, \"orientation\": {\"x\": 0, "
          "\"y\": 0, \"z\": 0, \"w\": 1}}, \"billboard\": true, \"font_size\": 14, \"scale_invariant\": true, "
          "\"color\": {\"r\": 1, \"g\": 1, \"b\": 1, \"a\": 1}, \"text\": \"%llu\"}]}",
       e->X, x->h + 0.05, e->Z, (unsigned long long)e->id);
}

static void j_frame(sooc_ros_buf *b, int64_t t, const char *parent, const char *child, const double T[16]) {
    double R[9], tr[3], q[4];
    sooc_se3_to_rt(R, tr, T);
    sooc_m3_to_quat(q, R);
    jp(b, "{\"timestamp\": ");
    j_time(b, t);
    jp(b, ", \"parent_frame_id\": \"%s\", \"child_frame_id\": \"%s\", \"translation\": {\"x\": %.9g, \"y\": %.9g, "
          "\"z\": %.9g}, \"rotation\": {\"x\": %.9g, \"y\": %.9g, \"z\": %.9g, \"w\": %.9g}}",
       parent, child, tr[0], tr[1], tr[2], q[0], q[1], q[2], q[3]);
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
    if (!st) st = sooc_mcap_writer_schema(w, "foxglove.SceneUpdate", "jsonschema", SCENE_SCHEMA, strlen(SCENE_SCHEMA), &sc_scene);
    if (!st) st = sooc_mcap_writer_schema(w, "foxglove.FrameTransform", "jsonschema", FRAME_SCHEMA, strlen(FRAME_SCHEMA), &sc_frame);
    if (!st) st = sooc_mcap_writer_channel(w, sc_frame, "/sooc3d/frames", "json", &ch_frame);
    if (!st) st = sooc_mcap_writer_channel(w, sc_scene, "/sooc3d/objects", "json", &ch_scene);
    /* map (REP 103: x forward, y left, z up) <- world (+y up): x = -z_w, y = -x_w, z = y_w (table.h) */
    double Tmw[16] = {0, 0, -1, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1}, Tws[16];
    if (!st) {
        j_frame(&b, t0, "map", "world", Tmw);
        st = b.oom ? SOOC_ENOMEM : sooc_mcap_writer_message(w, ch_frame, t0, t0, b.data, b.size);
        b.size = 0;
    }
    if (!st && has_frame) {
        memcpy(Tws, fr.T_world_src, sizeof Tws);
        j_frame(&b, t0, "world", "source", Tws);
        st = b.oom ? SOOC_ENOMEM : sooc_mcap_writer_message(w, ch_frame, t0, t0, b.data, b.size);
        b.size = 0;
    }
    /* cumulative updates in first-seen order; the last holds every object */
    size_t step = c.n > MAX_UPDATES ? (c.n + MAX_UPDATES - 1) / MAX_UPDATES : 1;
    size_t n_msgs = 0;
    for (size_t upto = c.n ? (step < c.n ? step : c.n) : 0; !st;) {
        int64_t t = upto ? c.o[upto - 1].e.first_seen_ns : t0;
        if (upto == c.n && t1 > t) t = t1;
        jp(&b, "{\"deletions\": [], \"entities\": [");
        for (size_t i = 0; i < upto; i++) {
            if (i) jp(&b, ", ");
            j_entity(&b, &c.o[i], t);
        }
        jp(&b, "]}");
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
