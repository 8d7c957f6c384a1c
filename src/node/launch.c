/* Launch files: YAML (libyaml document API, walked with data/yaml_doc.h)
 * -> sooc_node_config. Sections are read through key tables (field, type,
 * range). Every error names the file, the line and the key (section.key). */
#include "sooc3d/node.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "sooc3d/frame.h"
#include "data/yaml_doc.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void sooc_node_config_default(sooc_node_config *c) {
    memset(c, 0, sizeof *c);
    c->pose_kind = SOOC_NODE_POSE_SENSOR;
    c->pose_tolerance_s = 0.02;
    c->kf_translation_m = 0.10;
    c->kf_rotation_deg = 10.0;
    c->kf_time_s = 2.0;
    c->shm_capacity = 1024;
    c->map_resume = 1;
    c->map_retry_s = 1.0;        /* a failed commit is retried after 1 s, 2 s, 4 s, ... up to 30 s */
    c->map_retry_max_s = 30.0;
    c->map_busy_timeout_ms = 200;
    c->reconnect_s = 1.0;        /* a lost live sensor is reopened after 1 s, 2 s, ... up to 10 s */
    c->reconnect_max_s = 10.0;
    c->time_jump_s = 5.0;
    c->up[1] = 1.0;
    c->floor_mode = SOOC_NODE_FLOOR_GIVEN;
    c->floor_ransac_threshold_m = 0.02;
    c->floor_ransac_iterations = 200;
    c->max_tilt_deg = 30.0;
    /* revisits refine instead of duplicating: the mapper's duplicate merge at the measured radius
     * (docs/cogmap.md "Revisits"; 0 turns it off as in `sooc3d infer/eval`) */
    c->merge_m = 0.35;
    {
        sooc_cluster_params cp;
        sooc_cluster_params_default(&cp);
        c->geo_voxel_m = cp.voxel_m, c->geo_join_m = cp.dist_m;
        c->geo_min_height_m = cp.min_height_m, c->geo_max_extent_m = cp.max_extent_m;
        c->geo_wall_m = cp.wall_m;
        c->geo_rest_m = cp.rest_m;
        c->geo_free_ratio = cp.free_ratio;
    }
    c->support_frames = 8;
    c->floor_switch = 1;
    c->cam_height_min_m = 0;   /* 0: the model's trained range (sooc_model_cam_heights_m) */
    c->cam_height_max_m = 0;
    c->ring_capacity = 8;
    c->stats_period_s = 5.0;
    c->min_depth_m = 0.1;
    c->max_depth_m = 10.0;
    c->log_level = SOOC_LOG_INFO;
    snprintf(c->view_bind, sizeof c->view_bind, "127.0.0.1");
    c->record_period_s = 1.0;
    c->depth_resample = SOOC_FRAMES_DEPTH_MIN;
    c->odom_variant = 2;                 /* sooc_odom_params_default (include/sooc3d/slam.h) */
    c->odom_width = 320;
    c->odom_height = 240;
    c->odom_kf_translation_m = 0.10;
    c->odom_kf_rotation_deg = 10.0;
    c->odom_max_failures = 10;
    c->odom_min_depth_m = 0.3;
    c->odom_max_depth_m = 4.0;
    c->odom_min_agreement = 0.3;
}

const char *sooc_node_param_get(const sooc_node_config *c, const char *key) {
    for (int i = 0; i < c->n_params; i++)
        if (!strcmp(c->params[i].key, key)) return c->params[i].value;
    return NULL;
}

/* ----------------------------------------------------------- yaml helpers */

typedef struct pctx {
    sooc_ydoc *d;
    const char *name;       /* the launch file (= d->name) */
    const char *section;    /* NULL at the top level */
} pctx;

static sooc_status bad(const pctx *p, const yaml_node_t *n, const char *key, const char *what,
                       const char *got) {
    if (got)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s%s%s: %s, got '%s'", p->name, sooc_yline(n),
                           p->section ? p->section : "", p->section ? "." : "", key, what, got);
    return sooc_seterr(SOOC_EINVAL, "%s:%d: %s%s%s: %s", p->name, sooc_yline(n), p->section ? p->section : "",
                       p->section ? "." : "", key, what);
}

static sooc_status get_scalar(const pctx *p, const yaml_node_t *v, const char *key, const char **out) {
    if (v->type != YAML_SCALAR_NODE) return bad(p, v, key, "expected a scalar value", NULL);
    *out = (const char *)v->data.scalar.value;
    return SOOC_OK;
}

static sooc_status get_str(const pctx *p, const yaml_node_t *v, const char *key, char *dst, size_t cap,
                           int allow_empty) {
    const char *s = "";
    sooc_status st = get_scalar(p, v, key, &s);
    if (st) return st;
    if (!allow_empty && !*s) return bad(p, v, key, "expected a non-empty string", s);
    if (strlen(s) >= cap) return bad(p, v, key, "value too long", s);
    memcpy(dst, s, strlen(s) + 1);
    return SOOC_OK;
}

static int parse_num(const char *s, double *out) {
    if (!*s) return 0;
    char *end;
    errno = 0;
    double x = strtod(s, &end);
    while (*end && isspace((unsigned char)*end)) end++;
    if (*end || errno || !isfinite(x)) return 0;
    *out = x;
    return 1;
}

static sooc_status get_num(const pctx *p, const yaml_node_t *v, const char *key, double lo, double hi,
                           double *out) {
    const char *s = "";
    sooc_status st = get_scalar(p, v, key, &s);
    if (st) return st;
    double x;
    if (!parse_num(s, &x)) return bad(p, v, key, "expected a number", s);
    if (x < lo || x > hi) {
        char what[128];
        snprintf(what, sizeof what, "out of range [%g, %g]", lo, hi);
        return bad(p, v, key, what, s);
    }
    *out = x;
    return SOOC_OK;
}

static sooc_status get_int(const pctx *p, const yaml_node_t *v, const char *key, long lo, long hi,
                           long *out) {
    const char *s = "";
    sooc_status st = get_scalar(p, v, key, &s);
    if (st) return st;
    char *end;
    errno = 0;
    long x = strtol(s, &end, 10);
    if (!*s || *end || errno) return bad(p, v, key, "expected an integer", s);
    if (x < lo || x > hi) {
        char what[128];
        snprintf(what, sizeof what, "out of range [%ld, %ld]", lo, hi);
        return bad(p, v, key, what, s);
    }
    *out = x;
    return SOOC_OK;
}

static int parse_bool(const char *s, int *out) {
    static const char *t[] = {"true", "yes", "on", "1", "True", "TRUE", "Yes"};
    static const char *f[] = {"false", "no", "off", "0", "False", "FALSE", "No"};
    for (size_t i = 0; i < sizeof t / sizeof *t; i++)
        if (!strcmp(s, t[i])) { *out = 1; return 1; }
    for (size_t i = 0; i < sizeof f / sizeof *f; i++)
        if (!strcmp(s, f[i])) { *out = 0; return 1; }
    return 0;
}

static sooc_status get_bool(const pctx *p, const yaml_node_t *v, const char *key, int *out) {
    const char *s = "";
    sooc_status st = get_scalar(p, v, key, &s);
    if (st) return st;
    if (!parse_bool(s, out)) return bad(p, v, key, "expected true or false", s);
    return SOOC_OK;
}

/* Iterate a mapping: for each pair call fn(key string, key node, value node).
 * Keys must be plain strings and must not repeat. */
typedef sooc_status (*pair_fn)(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u);

static sooc_status walk_map(pctx *p, yaml_node_t *m, const char *what, pair_fn fn, void *u) {
    if (m->type != YAML_MAPPING_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a mapping (key: value lines)", p->name,
                           sooc_yline(m), what);
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; pr++) {
        sooc_ypair kv;
        sooc_status st = sooc_ymap_pair(p->d, m, pr, p->section, 1, &kv);
        if (!st) st = fn(p, kv.key, kv.k, kv.v, u);
        if (st) return st;
    }
    return SOOC_OK;
}

static sooc_status unknown(pctx *p, const yaml_node_t *kn, const char *key, const char *known) {
    return bad(p, kn, key, known, NULL);
}

/* ------------------------------------------------------------ sensor keys */

typedef enum { PT_STR, PT_INT, PT_NUM, PT_POS, PT_BOOL, PT_ENUM, PT_SPEED, PT_FORMAT, PT_U16, PT_SHIFT } ptype;
typedef struct pspec {
    const char *driver, *key;
    ptype type;
    const char *enums;      /* "a|b|c" for PT_ENUM */
} pspec;

static const pspec g_pspecs[] = {
    {"replay", "path", PT_STR, NULL},
    {"replay", "format", PT_FORMAT, NULL},          /* names: sooc_seq_format_parse (frame.h) */
    {"replay", "speed", PT_SPEED, NULL},
    {"replay", "loop", PT_BOOL, NULL},
    {"replay", "start_s", PT_NUM, NULL},
    {"replay", "stop_s", PT_NUM, NULL},
    {"replay", "depth_scale", PT_POS, NULL},
    {"replay", "depth_shift", PT_SHIFT, NULL},
    {"replay", "depth_invalid", PT_U16, NULL},
    {"openni2", "uri", PT_STR, NULL},
    {"openni2", "width", PT_INT, NULL},
    {"openni2", "height", PT_INT, NULL},
    {"openni2", "fps", PT_INT, NULL},
    {"openni2", "registration", PT_BOOL, NULL},
    {"openni2", "mirror", PT_BOOL, NULL},
    {"openni2", "depth_scale", PT_POS, NULL},
    {"openni2", "timebase", PT_ENUM, "sensor|realtime"},
    {"openni2", "pair_tol_ms", PT_POS, NULL},
    {"freenect", "index", PT_INT, NULL},
    {"freenect", "depth_mode", PT_ENUM, "auto|11bit|registered"},
    {"freenect", "timebase", PT_ENUM, "sensor|realtime"},
    {"v4l2", "depth_device", PT_STR, NULL},
    {"v4l2", "color_device", PT_STR, NULL},
    {"v4l2", "width", PT_INT, NULL},
    {"v4l2", "height", PT_INT, NULL},
    {"v4l2", "fps", PT_INT, NULL},
    {"v4l2", "depth_format", PT_ENUM, "Z16|Y16"},
    {"v4l2", "depth_scale", PT_POS, NULL},
    {"v4l2", "timebase", PT_ENUM, "sensor|realtime"},
    {"v4l2", "pair_tol_ms", PT_POS, NULL},
    /* robot logs (docs/logs.md) */
#define LOG_KEYS(d)                                                                                          \
    {d, "path", PT_STR, NULL}, {d, "color_topic", PT_STR, NULL}, {d, "depth_topic", PT_STR, NULL},           \
        {d, "speed", PT_SPEED, NULL}, {d, "loop", PT_BOOL, NULL}, {d, "start_s", PT_NUM, NULL},              \
        {d, "stop_s", PT_NUM, NULL}, {d, "depth_scale", PT_POS, NULL}, {d, "pair_tol_ms", PT_POS, NULL}
    LOG_KEYS("rosbag"),
    LOG_KEYS("mcap"),
#undef LOG_KEYS
    {"libcamera", "camera", PT_STR, NULL},
    {"libcamera", "width", PT_INT, NULL},
    {"libcamera", "height", PT_INT, NULL},
    {"libcamera", "fps", PT_INT, NULL},
};
static const char *g_drivers = "replay|rosbag|mcap|openni2|freenect|v4l2|libcamera";

static int in_enum(const char *s, const char *list) {
    size_t n = strlen(s);
    const char *q = list;
    while (*q) {
        const char *e = strchr(q, '|');
        size_t m = e ? (size_t)(e - q) : strlen(q);
        if (m == n && !strncmp(q, s, n)) return 1;
        if (!e) break;
        q = e + 1;
    }
    return 0;
}

static sooc_status sensor_param(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn,
                                sooc_node_config *c) {
    const pspec *sp = NULL;
    char known[512] = "";
    for (size_t i = 0; i < sizeof g_pspecs / sizeof *g_pspecs; i++) {
        if (strcmp(g_pspecs[i].driver, c->driver)) continue;
        if (!strcmp(g_pspecs[i].key, key)) sp = &g_pspecs[i];
        size_t l = strlen(known);
        snprintf(known + l, sizeof known - l, "%s%s", l ? ", " : "", g_pspecs[i].key);
    }
    if (!sp) {
        char what[640];
        snprintf(what, sizeof what, "unknown key for driver '%s' (known: driver, %s)", c->driver, known);
        return unknown(p, kn, key, what);
    }
    const char *s = "";
    sooc_status st = get_scalar(p, vn, key, &s);
    if (st) return st;
    double x;
    long li;
    int b;
    switch (sp->type) {
    case PT_STR:   /* openni2 uri "" = any device */
        if (!*s && strcmp(key, "uri")) return bad(p, vn, key, "expected a non-empty string", s);
        break;
    case PT_INT:
        if ((st = get_int(p, vn, key, 0, 1000000, &li))) return st;
        break;
    case PT_NUM:
        if ((st = get_num(p, vn, key, 0, 1e12, &x))) return st;
        break;
    case PT_POS:
        if ((st = get_num(p, vn, key, 0, 1e12, &x))) return st;
        if (x <= 0) return bad(p, vn, key, "must be > 0", s);
        break;
    case PT_BOOL:
        if ((st = get_bool(p, vn, key, &b))) return st;
        break;
    case PT_ENUM:
        if (!in_enum(s, sp->enums)) {
            char what[256];
            snprintf(what, sizeof what, "expected one of %s", sp->enums);
            return bad(p, vn, key, what, s);
        }
        break;
    case PT_SPEED:
        if (strcmp(s, "realtime") && strcmp(s, "fast") && (!parse_num(s, &x) || x <= 0))
            return bad(p, vn, key, "expected realtime, fast or a factor > 0", s);
        break;
    case PT_FORMAT: {
        sooc_seq_format f;
        if (sooc_seq_format_parse(s, &f)) {
            char what[1100], list[1024];
            sooc_seq_format_list(list, sizeof list);
            snprintf(what, sizeof what, "unknown sequence format (one of %s)", list);
            return bad(p, vn, key, what, s);
        }
        break;
    }
    case PT_U16:
        if ((st = get_int(p, vn, key, 0, 65535, &li))) return st;
        break;
    case PT_SHIFT:
        if ((st = get_int(p, vn, key, 0, 15, &li))) return st;
        break;
    }
    if (c->n_params >= SOOC_NODE_PARAMS_MAX) return bad(p, kn, key, "too many sensor parameters", NULL);
    if (strlen(s) >= sizeof c->params[0].value) return bad(p, vn, key, "value too long", s);
    sooc_node_param *pp = &c->params[c->n_params++];
    snprintf(pp->key, sizeof pp->key, "%s", key);
    snprintf(pp->value, sizeof pp->value, "%s", s);
    pp->line = sooc_yline(vn);
    return SOOC_OK;
}

static sooc_status sec_sensor(pctx *p, yaml_node_t *m, sooc_node_config *c) {
    if (m->type != YAML_MAPPING_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: sensor: expected a mapping", p->name, sooc_yline(m));
    /* driver first: the other keys depend on it */
    yaml_node_t *dv = NULL, *dk = NULL;
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; pr++) {
        yaml_node_t *kn = yaml_document_get_node(&p->d->doc, pr->key);
        if (kn && kn->type == YAML_SCALAR_NODE && !strcmp((char *)kn->data.scalar.value, "driver")) {
            /* the first driver decides; a second one is an error, not "last one wins" */
            if (dk) return bad(p, kn, "driver", "duplicate key", NULL);
            dk = kn;
            dv = yaml_document_get_node(&p->d->doc, pr->value);
        }
    }
    if (!dv) return sooc_seterr(SOOC_EINVAL, "%s:%d: sensor.driver: missing (one of %s)", p->name,
                                sooc_yline(m), g_drivers);
    sooc_status st = get_str(p, dv, "driver", c->driver, sizeof c->driver, 0);
    if (st) return st;
    if (!in_enum(c->driver, g_drivers)) {
        char what[128];
        snprintf(what, sizeof what, "unknown driver (expected one of %s)", g_drivers);
        return bad(p, dv, "driver", what, c->driver);
    }
    c->n_params = 0;
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; pr++) {
        sooc_ypair kv;
        if ((st = sooc_ymap_pair(p->d, m, pr, p->section, 1, &kv))) return st;
        if (!strcmp(kv.key, "driver")) continue;
        if ((st = sensor_param(p, kv.key, kv.k, kv.v, c))) return st;
    }
    if ((!strcmp(c->driver, "replay") || !strcmp(c->driver, "rosbag") || !strcmp(c->driver, "mcap")) &&
        !sooc_node_param_get(c, "path"))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: sensor.path: missing (the recording to replay)", p->name,
                           sooc_yline(m));
    return SOOC_OK;
}

/* -------------------------------------------------------------- sections */

/* Keys that need more than a typed field (KV_FN). */
typedef sooc_status (*key_fn)(pctx *p, const char *key, yaml_node_t *vn, sooc_node_config *c);

static sooc_status f_shm_name(pctx *p, const char *key, yaml_node_t *vn, sooc_node_config *c) {
    sooc_status st = get_str(p, vn, key, c->shm_name, sizeof c->shm_name, 1);
    if (st) return st;
    for (const char *q = c->shm_name; *q; q++)
        if (!isalnum((unsigned char)*q) && *q != '_' && *q != '-' && *q != '.')
            return bad(p, vn, key, "only letters, digits, '_', '-' and '.' are allowed", c->shm_name);
    if (strlen(c->shm_name) > 40) return bad(p, vn, key, "at most 40 characters", c->shm_name);
    return SOOC_OK;
}

static sooc_status f_world_up(pctx *p, const char *key, yaml_node_t *vn, sooc_node_config *c) {
    double v[3] = {0, 0, 0};
    if (vn->type == YAML_SCALAR_NODE) {
        const char *s = (const char *)vn->data.scalar.value;
        static const char *ax[] = {"+x", "-x", "+y", "-y", "+z", "-z"};
        int k = -1;
        for (int i = 0; i < 6; i++)
            if (!strcmp(s, ax[i]) || (s[0] == ax[i][1] && !s[1] && ax[i][0] == '+')) k = i;
        if (k < 0) return bad(p, vn, key, "expected +x, -x, +y, -y, +z, -z or [x, y, z]", s);
        v[k / 2] = (k % 2) ? -1.0 : 1.0;
    } else if (vn->type == YAML_SEQUENCE_NODE) {
        if (sooc_yseq_len(vn) != 3) return bad(p, vn, key, "expected 3 numbers", NULL);
        for (int i = 0; i < 3; i++) {
            sooc_status st = get_num(p, sooc_yseq_item(p->d, vn, i), key, -1e6, 1e6, &v[i]);
            if (st) return st;
        }
        if (sooc_v3_normalize(v) < 1e-9) return bad(p, vn, key, "zero vector", NULL);
    } else {
        return bad(p, vn, key, "expected an axis or [x, y, z]", NULL);
    }
    memcpy(c->up, v, sizeof v);
    c->up_given = 1;
    return SOOC_OK;
}

static sooc_status f_world_floor(pctx *p, const char *key, yaml_node_t *vn, sooc_node_config *c) {
    const char *s = "";
    sooc_status st = get_scalar(p, vn, key, &s);
    if (st) return st;
    if (!strcmp(s, "estimate")) {
        c->floor_mode = SOOC_NODE_FLOOR_ESTIMATE;
        return SOOC_OK;
    }
    double x;
    if (!parse_num(s, &x)) return bad(p, vn, key, "expected a height in metres or 'estimate'", s);
    c->floor_mode = SOOC_NODE_FLOOR_GIVEN;
    c->floor_height = x;
    return SOOC_OK;
}

static sooc_status f_log_level(pctx *p, const char *key, yaml_node_t *vn, sooc_node_config *c) {
    const char *s = "";
    sooc_status st = get_scalar(p, vn, key, &s);
    if (st) return st;
    if (sooc_log_level_parse(s, &c->log_level)) return bad(p, vn, key, "expected debug, info, warn or error", s);
    return SOOC_OK;
}

/* How a key's value is read and where it goes (a field of sooc_node_config). */
typedef enum {
    KV_NUM,      /* double in [lo, hi] */
    KV_MS,       /* milliseconds in [lo, hi], stored as seconds (double) */
    KV_INT,      /* int in [lo, hi] */
    KV_U32,      /* uint32_t in [lo, hi] */
    KV_U64,      /* uint64_t in [lo, hi] */
    KV_BOOL,     /* int 0/1 */
    KV_STR,      /* char[], non-empty */
    KV_STR0,     /* char[], may be empty */
    KV_CHOICE,   /* int or enum field: index of the value in choices "a|b|c" */
    KV_FN        /* fn reads and checks it */
} kv_kind;

typedef struct kspec {
    const char *section, *key;
    kv_kind kind;
    size_t off, size;       /* the field's offsetof and sizeof */
    double lo, hi;
    const char *choices;
    key_fn fn;
} kspec;

#define FIELD(f) offsetof(sooc_node_config, f), sizeof(((sooc_node_config *)0)->f)
#define KV(sec, key, kind, f, lo, hi) {sec, key, kind, FIELD(f), lo, hi, NULL, NULL}
#define KV_CH(sec, key, f, choices) {sec, key, KV_CHOICE, FIELD(f), 0, 0, choices, NULL}
#define KV_F(sec, key, fn) {sec, key, KV_FN, 0, 0, 0, 0, NULL, fn}

/* KV_CHOICE stores through an int lvalue: the enum fields must be int-sized. */
_Static_assert(sizeof(sooc_node_pose_kind) == sizeof(int) && sizeof(sooc_frames_depth_resample) == sizeof(int),
               "enum fields read as int");

/* Every key of every section but sensor (g_pspecs) and the top-level calib;
 * "unknown key (known: ...)" lists a section's keys in this order. */
static const kspec g_keys[] = {
    KV_CH("pose", "source", pose_kind, "sensor|file|socket|odometry|tf"),   /* order of sooc_node_pose_kind */
    KV("pose", "path", KV_STR, pose_path, 0, 0),
    KV("pose", "address", KV_STR, pose_path, 0, 0),
    KV("pose", "tolerance_ms", KV_MS, pose_tolerance_s, 0, 10000),
    KV_CH("pose", "frame", pose_is_effector, "camera|effector"),
    KV("pose", "parent", KV_STR, pose_parent, 0, 0),
    KV("pose", "child", KV_STR0, pose_child, 0, 0),
    KV_CH("odometry", "variant", odom_variant, "rgbd|icp|rgbd_icp"),   /* order of sooc_odom_variant */
    KV("odometry", "width", KV_INT, odom_width, 0, 8192),
    KV("odometry", "height", KV_INT, odom_height, 0, 8192),
    KV("odometry", "keyframe_translation_m", KV_NUM, odom_kf_translation_m, 0, 10),
    KV("odometry", "keyframe_rotation_deg", KV_NUM, odom_kf_rotation_deg, 0, 180),
    KV("odometry", "keyframe_frames", KV_INT, odom_kf_frames, 0, 1000000),
    KV("odometry", "max_failures", KV_INT, odom_max_failures, 0, 1000000),
    KV("odometry", "min_depth_m", KV_NUM, odom_min_depth_m, 0, 100),
    KV("odometry", "max_depth_m", KV_NUM, odom_max_depth_m, 0.01, 100),
    KV("odometry", "min_agreement", KV_NUM, odom_min_agreement, 0, 1),
    KV("odometry", "color_fx", KV_NUM, odom_color_fx, 0, 1e5),
    KV("odometry", "color_fy", KV_NUM, odom_color_fy, 0, 1e5),
    KV("odometry", "color_cx", KV_NUM, odom_color_cx, -1e5, 1e5),
    KV("odometry", "color_cy", KV_NUM, odom_color_cy, -1e5, 1e5),
    KV("odometry", "color_tx", KV_NUM, odom_color_tx, -1, 1),
    KV("odometry", "color_ty", KV_NUM, odom_color_ty, -1, 1),
    KV("odometry", "color_tz", KV_NUM, odom_color_tz, -1, 1),
    KV("odometry", "thread", KV_BOOL, odom_thread, 0, 0),
    KV("odometry", "loop_closure", KV_BOOL, odom_loop_closure, 0, 0),
    KV("odometry", "relocalise", KV_BOOL, odom_relocalise, 0, 0),
    KV_CH("model", "kind", model_kind, "learnt|geometric"),   /* order of SOOC_MAPPER_* */
    KV("model", "voxel_m", KV_NUM, geo_voxel_m, 0.0005, 1),
    KV("model", "join_m", KV_NUM, geo_join_m, 0.0005, 1),
    KV("model", "min_height_m", KV_NUM, geo_min_height_m, 0, 10),
    KV("model", "max_extent_m", KV_NUM, geo_max_extent_m, 0.01, 100),
    KV("model", "wall_m", KV_NUM, geo_wall_m, 0, 100),
    KV("model", "rest_m", KV_NUM, geo_rest_m, 0, 10),
    KV("model", "min_presence", KV_NUM, geo_min_presence, 0, 1),
    KV("model", "free_ratio", KV_NUM, geo_free_ratio, 0, 1000),
    KV("model", "geo_support_m", KV_NUM, geo_support_m, 0, 1),
    KV("model", "proposals", KV_BOOL, proposals, 0, 0),
    KV("model", "prop_join_m", KV_NUM, prop_join_m, 0, 1),
    KV("model", "prop_logit", KV_NUM, prop_logit, -20, 20),
    KV("model", "prop_only", KV_BOOL, prop_only, 0, 0),
    KV("model", "surface_boxes", KV_BOOL, surface_boxes, 0, 0),
    KV("model", "path", KV_STR, model_path, 0, 0),
    KV("model", "width", KV_INT, input_width, 0, 8192),
    KV("model", "height", KV_INT, input_height, 0, 8192),
    KV("model", "iterations", KV_INT, iterations, 0, 1000),
    KV("model", "threads", KV_INT, threads, 0, 1024),
    KV("model", "seed", KV_U64, seed, 0, 2147483647L),
    KV_CH("model", "depth_resample", depth_resample, "min|nearest"),   /* order of sooc_frames_depth_resample */
    KV("model", "clip_m", KV_NUM, clip_m, 0, 1000),
    KV("model", "merge_m", KV_NUM, merge_m, 0, 100),
    KV_CH("model", "latents", latents, "mean|sample"),   /* order of SOOC_LATENTS_* */
    KV("model", "slots", KV_INT, slots, 0, SOOC_MODEL_K_MAX),
    KV_CH("model", "invalid_depth", invalid_depth, "model|free|unknown"),   /* 1 + SOOC_INVALID_DEPTH_* */
    KV("model", "gate_min_rays", KV_NUM, gate_min_rays, -1, 1),   /* sooc_mapper_params.gate_* */
    KV("model", "gate_ratio", KV_NUM, gate_ratio, -1, 100),
    KV("model", "gate_part", KV_NUM, gate_part, -1, 1),
    KV("keyframe", "translation_m", KV_NUM, kf_translation_m, 0, 1000),
    KV("keyframe", "rotation_deg", KV_NUM, kf_rotation_deg, 0, 360),
    KV("keyframe", "time_s", KV_NUM, kf_time_s, 0, 86400),
    KV_F("shm", "name", f_shm_name),
    KV("shm", "capacity", KV_U32, shm_capacity, 1, 1L << 20),
    KV("shm", "unlink_on_exit", KV_BOOL, shm_unlink_on_exit, 0, 0),
    KV("map", "db", KV_STR0, map_db, 0, 0),
    KV("map", "resume", KV_BOOL, map_resume, 0, 0),
    KV("map", "retry_s", KV_NUM, map_retry_s, 0, 3600),
    KV("map", "retry_max_s", KV_NUM, map_retry_max_s, 0, 86400),
    KV("map", "busy_timeout_ms", KV_INT, map_busy_timeout_ms, 0, 600000),
    KV_F("world", "up", f_world_up),
    KV_F("world", "floor", f_world_floor),
    KV("world", "ransac_threshold_m", KV_NUM, floor_ransac_threshold_m, 1e-4, 1.0),
    KV("world", "ransac_iterations", KV_INT, floor_ransac_iterations, 1, 100000),
    KV("world", "gravity", KV_STR, gravity_path, 0, 0),
    KV("world", "max_tilt_deg", KV_NUM, max_tilt_deg, 1, 60),
    KV("world", "support_frames", KV_INT, support_frames, 1, 32),
    KV("world", "floor_switch", KV_BOOL, floor_switch, 0, 0),
    KV("world", "camera_height_min_m", KV_NUM, cam_height_min_m, 0, 100),
    KV("world", "camera_height_max_m", KV_NUM, cam_height_max_m, 0, 100),
    KV("pipeline", "ring_capacity", KV_INT, ring_capacity, 1, 1024),
    KV("pipeline", "block_when_full", KV_BOOL, block_when_full, 0, 0),
    KV("pipeline", "strict", KV_BOOL, strict, 0, 0),
    KV("pipeline", "reconnect_s", KV_NUM, reconnect_s, 0, 3600),
    KV("pipeline", "reconnect_max_s", KV_NUM, reconnect_max_s, 0, 86400),
    KV("pipeline", "time_jump_s", KV_NUM, time_jump_s, 0.001, 1e6),
    KV("pipeline", "stats_period_s", KV_NUM, stats_period_s, 0, 86400),
    KV("pipeline", "min_depth_m", KV_NUM, min_depth_m, 0, 100),
    KV("pipeline", "max_depth_m", KV_NUM, max_depth_m, 0, 1000),
    KV_F("log", "level", f_log_level),
    KV("view", "port", KV_INT, view_port, 0, 65535),
    KV("view", "bind", KV_STR, view_bind, 0, 0),
    KV("record", "mcap", KV_STR0, record_mcap, 0, 0),
    KV("record", "period_s", KV_NUM, record_period_s, 0, 86400),
};
#define N_KEYS (sizeof g_keys / sizeof *g_keys)

#undef KV_F
#undef KV_CH
#undef KV
#undef FIELD

/* "expected a, b or c" from "a|b|c". */
static void choices_what(const char *choices, char *what, size_t cap) {
    size_t n = (size_t)snprintf(what, cap, "expected ");
    for (const char *q = choices; *q && n < cap;) {
        const char *e = strchr(q, '|');
        size_t m = e ? (size_t)(e - q) : strlen(q);
        const char *sep = q == choices ? "" : e ? ", " : " or ";
        n += (size_t)snprintf(what + n, cap - n, "%s%.*s", sep, (int)m, q);
        q = e ? e + 1 : q + m;
    }
}

/* Reads one key of section p->section (a section of g_keys). */
static sooc_status k_section(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    const kspec *k = NULL;
    char what[512];
    size_t n = (size_t)snprintf(what, sizeof what, "unknown key (known: ");
    const char *sep = "";
    for (size_t i = 0; i < N_KEYS; i++) {
        if (strcmp(g_keys[i].section, p->section)) continue;
        if (!strcmp(g_keys[i].key, key)) k = &g_keys[i];
        if (n < sizeof what) n += (size_t)snprintf(what + n, sizeof what - n, "%s%s", sep, g_keys[i].key);
        sep = ", ";
    }
    if (!k) {
        if (n < sizeof what) snprintf(what + n, sizeof what - n, ")");
        return unknown(p, kn, key, what);
    }
    char *dst = (char *)c + k->off;
    sooc_status st = SOOC_OK;
    double x;
    long li;
    switch (k->kind) {
    case KV_NUM: return get_num(p, vn, key, k->lo, k->hi, (double *)dst);
    case KV_MS:
        if ((st = get_num(p, vn, key, k->lo, k->hi, &x))) return st;
        *(double *)dst = x * 1e-3;
        return SOOC_OK;
    case KV_INT: case KV_U32: case KV_U64:
        if ((st = get_int(p, vn, key, (long)k->lo, (long)k->hi, &li))) return st;
        if (k->kind == KV_INT) *(int *)dst = (int)li;
        else if (k->kind == KV_U32) *(uint32_t *)dst = (uint32_t)li;
        else *(uint64_t *)dst = (uint64_t)li;
        return SOOC_OK;
    case KV_BOOL: return get_bool(p, vn, key, (int *)dst);
    case KV_STR: case KV_STR0: return get_str(p, vn, key, dst, k->size, k->kind == KV_STR0);
    case KV_CHOICE: {
        const char *s = "";
        if ((st = get_scalar(p, vn, key, &s))) return st;
        const char *q = k->choices;
        for (int i = 0;; i++) {
            const char *e = strchr(q, '|');
            size_t m = e ? (size_t)(e - q) : strlen(q);
            if (strlen(s) == m && !strncmp(q, s, m)) {
                *(int *)dst = i;
                return SOOC_OK;
            }
            if (!e) break;
            q = e + 1;
        }
        char what[256];
        choices_what(k->choices, what, sizeof what);
        return bad(p, vn, key, what, s);
    }
    case KV_FN: return k->fn(p, key, vn, c);
    }
    return SOOC_OK;
}

static sooc_status k_root(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    pctx q = *p;
    q.section = key;
    if (!strcmp(key, "sensor")) return sec_sensor(&q, vn, c);
    for (size_t i = 0; i < N_KEYS; i++)
        if (!strcmp(key, g_keys[i].section)) return walk_map(&q, vn, key, k_section, c);
    q.section = NULL;
    if (!strcmp(key, "calib")) return get_str(&q, vn, key, c->calib_path, sizeof c->calib_path, 1);
    return unknown(&q, kn, key,
                   "unknown key (known: sensor, pose, odometry, calib, model, keyframe, shm, map, world, pipeline, log, view, "
                   "record)");
}

/* One --set override, "section.key=value", read as the launch file's own
 * `section: {key: value}` would be (the same keys, checks and messages). */
static sooc_status apply_set(sooc_node_config *c, const char *set) {
    const char *dot = strchr(set, '.'), *eq = strchr(set, '=');
    if (!dot || !eq || dot > eq || dot == set || eq == dot + 1)
        return sooc_seterr(SOOC_EINVAL, "--set '%s': expected SECTION.KEY=VALUE (e.g. shm.name=table)", set);
    char text[8192], name[600];
    int w = snprintf(text, sizeof text, "%.*s:\n  %.*s: %s\n", (int)(dot - set), set, (int)(eq - dot - 1), dot + 1,
                     eq + 1);
    if (!strncmp(set, "sensor.", 7) && strncmp(set, "sensor.driver=", 14) && c->driver[0]) {
        /* the sensor section is read whole (its keys depend on the driver): the file's, with this key set */
        size_t k = (size_t)(eq - dot - 1), o = (size_t)snprintf(text, sizeof text, "sensor:\n  driver: %s\n", c->driver);
        for (int i = 0; i < c->n_params && o < sizeof text; i++)
            if (strlen(c->params[i].key) != k || strncmp(c->params[i].key, dot + 1, k))
                o += (size_t)snprintf(text + o, sizeof text - o, "  %s: '%s'\n", c->params[i].key, c->params[i].value);
        if (o < sizeof text) o += (size_t)snprintf(text + o, sizeof text - o, "  %.*s: %s\n", (int)k, dot + 1, eq + 1);
        w = (int)o;
    }
    if (w < 0 || (size_t)w >= sizeof text) return sooc_seterr(SOOC_EINVAL, "--set '%.64s...': too long", set);
    snprintf(name, sizeof name, "--set %s", set);
    sooc_ydoc d;
    sooc_status st = sooc_ydoc_parse(&d, text, (size_t)w, name);
    if (st) return st;
    yaml_node_t *root = sooc_ydoc_root(&d);
    pctx p = {&d, name, NULL};
    st = root ? walk_map(&p, root, "override", k_root, c) : sooc_seterr(SOOC_EINVAL, "%s: empty", name);
    sooc_ydoc_free(&d);
    return st;
}

sooc_status sooc_node_config_parse(sooc_node_config *c, const char *text, size_t n, const char *name) {
    return sooc_node_config_parse_sets(c, text, n, name, NULL, 0);
}

sooc_status sooc_node_config_parse_sets(sooc_node_config *c, const char *text, size_t n, const char *name,
                                        const char *const *sets, int n_sets) {
    sooc_node_config_default(c);
    snprintf(c->path, sizeof c->path, "%s", name);
    sooc_ydoc d;
    sooc_status st = sooc_ydoc_parse(&d, text, n, name);   /* also skips OpenCV's "%YAML:1.0" (docs/formats.md §3) */
    if (st) return st;
    yaml_node_t *root = sooc_ydoc_root(&d);
    pctx p = {&d, name, NULL};
    if (!root) st = sooc_seterr(SOOC_EINVAL, "%s: empty launch file", name);
    else st = walk_map(&p, root, "launch file", k_root, c);
    for (int i = 0; i < n_sets && !st; i++) st = apply_set(c, sets[i]);
    if (!st && !c->driver[0])
        st = sooc_seterr(SOOC_EINVAL, "%s: sensor: missing section (sensor.driver is required)", name);
    int is_log = !strcmp(c->driver, "rosbag") || !strcmp(c->driver, "mcap");
    if (!st && c->pose_kind == SOOC_NODE_POSE_TF && (!is_log || !c->pose_parent[0]))
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.source: tf %s", name,
                         is_log ? "needs pose.parent (the world frame; pose.child defaults to the image's frame_id)"
                                : "reads the TF of a log: sensor.driver rosbag or mcap");
    if (!st && is_log && c->pose_kind == SOOC_NODE_POSE_SENSOR)
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.source: a log's frames carry poses through its TF: pose: {source: tf, "
                         "parent: FRAME}, or file, socket, odometry", name);
    if (!st && c->pose_kind != SOOC_NODE_POSE_SENSOR && c->pose_kind != SOOC_NODE_POSE_ODOMETRY &&
        c->pose_kind != SOOC_NODE_POSE_TF && !c->pose_path[0])
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.path: missing (needed for pose.source %s)", name,
                         c->pose_kind == SOOC_NODE_POSE_FILE ? "file" : "socket");
    if (!st && c->pose_kind == SOOC_NODE_POSE_SOCKET && strncmp(c->pose_path, "unix:", 5) &&
        strncmp(c->pose_path, "udp://", 6))
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.address: expected unix:/path or udp://host:port, got '%s'",
                         name, c->pose_path);
    if (!st && c->pose_is_effector && !c->calib_path[0])
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.frame: effector poses need calib (T_effector_camera)", name);
    if (!st && (c->odom_width > 0) != (c->odom_height > 0))
        st = sooc_seterr(SOOC_EINVAL, "%s: odometry.width/height: give both or neither", name);
    if (!st && c->odom_min_depth_m >= c->odom_max_depth_m)
        st = sooc_seterr(SOOC_EINVAL, "%s: odometry.min_depth_m: must be below max_depth_m", name);
    if (!st && (c->odom_color_fx > 0) != (c->odom_color_fy > 0))
        st = sooc_seterr(SOOC_EINVAL, "%s: odometry.color_fx/color_fy: give both or neither", name);
    if (!st && c->min_depth_m >= c->max_depth_m)
        st = sooc_seterr(SOOC_EINVAL, "%s: pipeline.min_depth_m: must be below max_depth_m", name);
    if (!st && c->model_kind == SOOC_MAPPER_GEOMETRIC && c->geo_join_m < c->geo_voxel_m)
        st = sooc_seterr(SOOC_EINVAL, "%s: model.join_m %g: must be at least model.voxel_m %g", name, c->geo_join_m,
                         c->geo_voxel_m);
    if (!st && (c->input_width > 0) != (c->input_height > 0))
        st = sooc_seterr(SOOC_EINVAL, "%s: model.width/height: give both or neither", name);
    if (!st && (c->cam_height_min_m > 0) != (c->cam_height_max_m > 0))
        st = sooc_seterr(SOOC_EINVAL, "%s: world.camera_height_min_m/_max_m: give both or neither (neither: the "
                                      "model's trained range)", name);
    if (!st && c->cam_height_min_m > 0 && c->cam_height_min_m >= c->cam_height_max_m)
        st = sooc_seterr(SOOC_EINVAL, "%s: world.camera_height_min_m: must be below camera_height_max_m", name);
    if (!st && strcmp(c->driver, "replay") && !is_log && c->pose_kind == SOOC_NODE_POSE_SENSOR)
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.source: live driver '%s' carries no poses; use file, socket or odometry",
                         name, c->driver);
    sooc_ydoc_free(&d);
    return st;
}

sooc_status sooc_node_config_load(sooc_node_config *c, const char *path) {
    return sooc_node_config_load_sets(c, path, NULL, 0);
}

sooc_status sooc_node_config_load_sets(sooc_node_config *c, const char *path, const char *const *sets, int n_sets) {
    void *buf = NULL;
    size_t n = 0;
    sooc_status st = sooc_file_read_all(path, 1 << 20, &buf, &n);
    if (st) {
        sooc_node_config_default(c);
        return sooc_adderr(st, "launch file %s", path);
    }
    st = sooc_node_config_parse_sets(c, buf, n, path, sets, n_sets);
    sooc_free(buf);
    return st;
}

size_t sooc_node_config_format(const sooc_node_config *c, char *buf, size_t cap) {
    static const char *pk[] = {"sensor", "file", "socket", "odometry", "tf"};
    size_t k = 0;
#define OUT(...)                                                                    \
    do {                                                                            \
        int w_ = snprintf(k < cap ? buf + k : NULL, k < cap ? cap - k : 0, __VA_ARGS__); \
        if (w_ > 0) k += (size_t)w_;                                                \
    } while (0)
    OUT("sensor: {driver: %s", c->driver);
    for (int i = 0; i < c->n_params; i++) OUT(", %s: %s", c->params[i].key, c->params[i].value);
    OUT("}\npose: {source: %s, path: '%s', tolerance_ms: %g, frame: %s", pk[c->pose_kind], c->pose_path,
        c->pose_tolerance_s * 1e3, c->pose_is_effector ? "effector" : "camera");
    if (c->pose_kind == SOOC_NODE_POSE_TF) OUT(", parent: %s, child: '%s'", c->pose_parent, c->pose_child);
    OUT("}\n");
    if (c->pose_kind == SOOC_NODE_POSE_ODOMETRY) {
        static const char *ov[] = {"rgbd", "icp", "rgbd_icp"};
        OUT("odometry: {variant: %s, width: %d, height: %d, keyframe_translation_m: %g, keyframe_rotation_deg: %g, "
            "keyframe_frames: %d, max_failures: %d, min_depth_m: %g, max_depth_m: %g, min_agreement: %g, "
            "color_fx: %g, color_fy: %g, color_cx: %g, color_cy: %g, color_tx: %g, color_ty: %g, color_tz: %g, "
            "thread: %s, loop_closure: %s, relocalise: %s}\n",
            ov[c->odom_variant], c->odom_width, c->odom_height, c->odom_kf_translation_m, c->odom_kf_rotation_deg,
            c->odom_kf_frames, c->odom_max_failures, c->odom_min_depth_m, c->odom_max_depth_m, c->odom_min_agreement,
            c->odom_color_fx, c->odom_color_fy, c->odom_color_cx, c->odom_color_cy, c->odom_color_tx,
            c->odom_color_ty, c->odom_color_tz, c->odom_thread ? "true" : "false",
            c->odom_loop_closure ? "true" : "false", c->odom_relocalise ? "true" : "false");
    }
    OUT("calib: '%s'\nmodel: {kind: %s, voxel_m: %g, join_m: %g, min_height_m: %g, max_extent_m: %g, wall_m: %g, rest_m: %g, min_presence: %g, free_ratio: %g, geo_support_m: %g, proposals: %s, prop_join_m: %g, prop_logit: %g, prop_only: %s, surface_boxes: %s, path: '%s', width: %d, height: %d, iterations: %d, threads: %d, seed: %llu, "
        "depth_resample: %s, clip_m: %g, merge_m: %g, latents: %s, slots: %d, invalid_depth: %s, gate_min_rays: %g, "
        "gate_ratio: %g, gate_part: %g}\n",
        c->calib_path, c->model_kind == SOOC_MAPPER_GEOMETRIC ? "geometric" : "learnt", c->geo_voxel_m, c->geo_join_m,
        c->geo_min_height_m, c->geo_max_extent_m, c->geo_wall_m, c->geo_rest_m, c->geo_min_presence, c->geo_free_ratio, c->geo_support_m, c->proposals ? "true" : "false", c->prop_join_m, c->prop_logit,
        c->prop_only ? "true" : "false", c->surface_boxes ? "true" : "false", c->model_path, c->input_width, c->input_height, c->iterations, c->threads,
        (unsigned long long)c->seed, c->depth_resample == SOOC_FRAMES_DEPTH_MIN ? "min" : "nearest", c->clip_m, c->merge_m,
        c->latents == SOOC_LATENTS_SAMPLE ? "sample" : "mean", c->slots,
        c->invalid_depth == 2 ? "unknown" : c->invalid_depth == 1 ? "free" : "model", c->gate_min_rays,
        c->gate_ratio, c->gate_part);
    OUT("keyframe: {translation_m: %g, rotation_deg: %g, time_s: %g}\n", c->kf_translation_m,
        c->kf_rotation_deg, c->kf_time_s);
    OUT("shm: {name: '%s', capacity: %u, unlink_on_exit: %s}\n", c->shm_name, c->shm_capacity,
        c->shm_unlink_on_exit ? "true" : "false");
    OUT("map: {db: '%s', resume: %s, retry_s: %g, retry_max_s: %g, busy_timeout_ms: %d}\n", c->map_db,
        c->map_resume ? "true" : "false", c->map_retry_s, c->map_retry_max_s, c->map_busy_timeout_ms);
    if (c->floor_mode == SOOC_NODE_FLOOR_ESTIMATE)
        OUT("world: {up: [%g, %g, %g], floor: estimate, gravity: '%s', max_tilt_deg: %g, support_frames: %d, "
            "floor_switch: %s, camera_height_min_m: %g, camera_height_max_m: %g}\n",
            c->up[0], c->up[1], c->up[2], c->gravity_path[0] ? c->gravity_path : "auto",
            c->max_tilt_deg, c->support_frames, c->floor_switch ? "true" : "false", c->cam_height_min_m,
            c->cam_height_max_m);
    else
        OUT("world: {up: [%g, %g, %g], floor: %g}\n", c->up[0], c->up[1], c->up[2], c->floor_height);
    OUT("pipeline: {ring_capacity: %d, block_when_full: %s, stats_period_s: %g, min_depth_m: %g, "
        "max_depth_m: %g, strict: %s, reconnect_s: %g, reconnect_max_s: %g, time_jump_s: %g}\n", c->ring_capacity,
        c->block_when_full ? "true" : "false", c->stats_period_s, c->min_depth_m, c->max_depth_m,
        c->strict ? "true" : "false", c->reconnect_s, c->reconnect_max_s, c->time_jump_s);
    static const char *lv[] = {"debug", "info", "warn", "error", "fatal"};
    OUT("log: {level: %s}\n", lv[c->log_level]);
#undef OUT
    return k;
}
