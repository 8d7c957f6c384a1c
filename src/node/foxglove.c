/* Foxglove messages of the map (include/sooc3d/log.h). */
#include "sooc3d/log.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "sooc3d/core.h"

/* JSON schemas of the two Foxglove message types, written from the field
 * tables of Foxglove's schema documentation (only the fields used here are
 * spelled out; Foxglove recognises the types by their names). */
#define VEC3 "{\"type\": \"object\", \"properties\": {\"x\": {\"type\": \"number\"}, \"y\": {\"type\": \"number\"}, \"z\": {\"type\": \"number\"}}}"
#define QUAT "{\"type\": \"object\", \"properties\": {\"x\": {\"type\": \"number\"}, \"y\": {\"type\": \"number\"}, \"z\": {\"type\": \"number\"}, \"w\": {\"type\": \"number\"}}}"
#define TIME "{\"type\": \"object\", \"properties\": {\"sec\": {\"type\": \"integer\"}, \"nsec\": {\"type\": \"integer\"}}}"
#define POSE "{\"type\": \"object\", \"properties\": {\"position\": " VEC3 ", \"orientation\": " QUAT "}}"
#define COLOR "{\"type\": \"object\", \"properties\": {\"r\": {\"type\": \"number\"}, \"g\": {\"type\": \"number\"}, \"b\": {\"type\": \"number\"}, \"a\": {\"type\": \"number\"}}}"
const char sooc_foxglove_scene_schema[] =
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
const char sooc_foxglove_frame_schema[] =
    "{\"title\": \"foxglove.FrameTransform\", \"type\": \"object\", \"properties\": {\"timestamp\": " TIME
    ", \"parent_frame_id\": {\"type\": \"string\"}, \"child_frame_id\": {\"type\": \"string\"}, \"translation\": " VEC3
    ", \"rotation\": " QUAT "}}";

const double sooc_foxglove_T_map_world[16] = {0, 0, -1, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1};

/* Appends printf output to b (JSON text). */
void sooc_foxglove_printf(sooc_ros_buf *b, const char *fmt, ...) {
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
    sooc_foxglove_printf(b, "{\"sec\": %lld, \"nsec\": %lld}", (long long)(t / 1000000000), (long long)(t % 1000000000));
}

/* One entity: the box (centre at half its height, turned by yaw about +y), the label, the metadata. */
void sooc_foxglove_entity(sooc_ros_buf *b, const sooc_map_entry *e, const double cov[4], double h, int64_t t) {
    double p = 1.0 / (1.0 + exp(-e->presence_logit)), qy = sin(0.5 * e->yaw), qw = cos(0.5 * e->yaw);
    uint64_t hsh = e->id * 0x9e3779b97f4a7c15ULL;
    double col[3] = {0.25 + 0.75 * (double)((hsh >> 8) & 0xff) / 255, 0.25 + 0.75 * (double)((hsh >> 16) & 0xff) / 255,
                     0.25 + 0.75 * (double)((hsh >> 24) & 0xff) / 255};
    sooc_foxglove_printf(b, "{\"timestamp\": ");
    j_time(b, t);
    sooc_foxglove_printf(b, ", \"frame_id\": \"world\", \"id\": \"object %llu\", \"lifetime\": {\"sec\": 0, \"nsec\": 0}, "
          "\"frame_locked\": false, \"metadata\": [", (unsigned long long)e->id);
    sooc_foxglove_printf(b, "{\"key\": \"id\", \"value\": \"%llu\"}, {\"key\": \"presence\", \"value\": \"%.4f\"}, "
          "{\"key\": \"sigma_t_m\", \"value\": \"%.4g\"}, {\"key\": \"sigma_yaw_rad\", \"value\": \"%.4g\"}, "
          "{\"key\": \"cov_xx\", \"value\": \"%.6g\"}, {\"key\": \"cov_xz\", \"value\": \"%.6g\"}, "
          "{\"key\": \"cov_zz\", \"value\": \"%.6g\"}, {\"key\": \"var_yaw\", \"value\": \"%.6g\"}, "
          "{\"key\": \"obs_count\", \"value\": \"%u\"}, {\"key\": \"first_seen_ns\", \"value\": \"%lld\"}, "
          "{\"key\": \"last_seen_ns\", \"value\": \"%lld\"}], ",
       (unsigned long long)e->id, p, sqrt(cov[0]), sqrt(cov[3]), cov[0], cov[1],
       cov[2], isfinite(cov[3]) ? cov[3] : -1.0, e->obs_count, (long long)e->first_seen_ns,
       (long long)e->last_seen_ns);
    sooc_foxglove_printf(b, "\"cubes\": [{\"pose\": {\"position\": {\"x\": %.6f, \"y\": %.6f, \"z\": %.6f}, \"orientation\": {\"x\": 0, "
          "\"y\": %.9f, \"z\": 0, \"w\": %.9f}}, \"size\": {\"x\": %.4f, \"y\": %.4f, \"z\": %.4f}, \"color\": {\"r\": "
          "%.3f, \"g\": %.3f, \"b\": %.3f, \"a\": %.3f}}], ",
       e->x, 0.5 * h, e->z, qy, qw, e->extent[0], h > 0 ? h : e->extent[1], e->extent[2], col[0], col[1], col[2],
       0.25 + 0.5 * p);
    sooc_foxglove_printf(b, "\"texts\": [{\"pose\": {\"position\": {\"x\": %.6f, \"y\": %.6f, \"z\": %.6f}, \"orientation\": {\"x\": 0, "
          "\"y\": 0, \"z\": 0, \"w\": 1}}, \"billboard\": true, \"font_size\": 14, \"scale_invariant\": true, "
          "\"color\": {\"r\": 1, \"g\": 1, \"b\": 1, \"a\": 1}, \"text\": \"%llu\"}]}",
       e->x, h + 0.05, e->z, (unsigned long long)e->id);
}

void sooc_foxglove_frame(sooc_ros_buf *b, int64_t t, const char *parent, const char *child, const double T[16]) {
    double R[9], tr[3], q[4];
    sooc_se3_to_rt(R, tr, T);
    sooc_m3_to_quat(q, R);
    sooc_foxglove_printf(b, "{\"timestamp\": ");
    j_time(b, t);
    sooc_foxglove_printf(b, ", \"parent_frame_id\": \"%s\", \"child_frame_id\": \"%s\", \"translation\": {\"x\": %.9g, \"y\": %.9g, "
          "\"z\": %.9g}, \"rotation\": {\"x\": %.9g, \"y\": %.9g, \"z\": %.9g, \"w\": %.9g}}",
       parent, child, tr[0], tr[1], tr[2], q[0], q[1], q[2], q[3]);
}

