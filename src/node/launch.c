/* Launch files: YAML (libyaml document API) -> sooc_node_config.
 * Every error names the file, the line and the key (section.key). */
#include "sooc3d/node.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <yaml.h>

void sooc_node_config_default(sooc_node_config *c) {
    memset(c, 0, sizeof *c);
    c->pose_kind = SOOC_NODE_POSE_SENSOR;
    c->pose_tolerance_s = 0.02;
    c->kf_translation_m = 0.10;
    c->kf_rotation_deg = 10.0;
    c->kf_time_s = 2.0;
    c->shm_capacity = 1024;
    c->map_resume = 1;
    c->up[1] = 1.0;
    c->floor_mode = SOOC_NODE_FLOOR_GIVEN;
    c->floor_ransac_threshold_m = 0.02;
    c->floor_ransac_iterations = 200;
    c->ring_capacity = 8;
    c->stats_period_s = 5.0;
    c->min_depth_m = 0.1;
    c->max_depth_m = 10.0;
    c->log_level = SOOC_LOG_INFO;
    c->depth_resample = SOOC_NODE_DEPTH_MIN;
}

const char *sooc_node_param_get(const sooc_node_config *c, const char *key) {
    for (int i = 0; i < c->n_params; i++)
        if (!strcmp(c->params[i].key, key)) return c->params[i].value;
    return NULL;
}

/* ----------------------------------------------------------- yaml helpers */

typedef struct pctx {
    yaml_document_t *doc;
    const char *name;
    const char *section;
} pctx;

static int line_of(const yaml_node_t *n) { return (int)n->start_mark.line + 1; }

static sooc_status bad(const pctx *p, const yaml_node_t *n, const char *key, const char *what,
                       const char *got) {
    if (got)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s%s%s: %s, got '%s'", p->name, line_of(n),
                           p->section ? p->section : "", p->section ? "." : "", key, what, got);
    return sooc_seterr(SOOC_EINVAL, "%s:%d: %s%s%s: %s", p->name, line_of(n), p->section ? p->section : "",
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

/* Iterate a mapping: for each pair call fn(key string, key node, value node). */
typedef sooc_status (*pair_fn)(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u);

static sooc_status walk_map(pctx *p, yaml_node_t *m, const char *what, pair_fn fn, void *u) {
    if (m->type != YAML_MAPPING_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a mapping (key: value lines)", p->name,
                           line_of(m), what);
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; pr++) {
        yaml_node_t *kn = yaml_document_get_node(p->doc, pr->key);
        yaml_node_t *vn = yaml_document_get_node(p->doc, pr->value);
        if (!kn || !vn || kn->type != YAML_SCALAR_NODE)
            return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: keys must be plain strings", p->name,
                               kn ? line_of(kn) : 0, what);
        const char *key = (const char *)kn->data.scalar.value;
        /* duplicate keys are errors (YAML says so; libyaml does not check) */
        for (yaml_node_pair_t *q = m->data.mapping.pairs.start; q < pr; q++) {
            yaml_node_t *k2 = yaml_document_get_node(p->doc, q->key);
            if (k2 && k2->type == YAML_SCALAR_NODE && !strcmp((const char *)k2->data.scalar.value, key))
                return bad(p, kn, key, "duplicate key", NULL);
        }
        sooc_status st = fn(p, key, kn, vn, u);
        if (st) return st;
    }
    return SOOC_OK;
}

static sooc_status unknown(pctx *p, const yaml_node_t *kn, const char *key, const char *known) {
    return bad(p, kn, key, known, NULL);
}

/* ------------------------------------------------------------ sensor keys */

typedef enum { PT_STR, PT_INT, PT_NUM, PT_POS, PT_BOOL, PT_ENUM, PT_SPEED } ptype;
typedef struct pspec {
    const char *driver, *key;
    ptype type;
    const char *enums;      /* "a|b|c" for PT_ENUM */
} pspec;

static const pspec g_pspecs[] = {
    {"replay", "path", PT_STR, NULL},
    {"replay", "format", PT_ENUM, "auto|sooc|tum|replica|scannet|klg|fakenect|sevenscenes"},
    {"replay", "speed", PT_SPEED, NULL},
    {"replay", "loop", PT_BOOL, NULL},
    {"replay", "start_s", PT_NUM, NULL},
    {"replay", "stop_s", PT_NUM, NULL},
    {"replay", "depth_scale", PT_POS, NULL},
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
    {"libcamera", "camera", PT_STR, NULL},
    {"libcamera", "width", PT_INT, NULL},
    {"libcamera", "height", PT_INT, NULL},
    {"libcamera", "fps", PT_INT, NULL},
};
static const char *g_drivers = "replay|openni2|freenect|v4l2|libcamera";

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
    }
    if (c->n_params >= SOOC_NODE_PARAMS_MAX) return bad(p, kn, key, "too many sensor parameters", NULL);
    if (strlen(s) >= sizeof c->params[0].value) return bad(p, vn, key, "value too long", s);
    sooc_node_param *pp = &c->params[c->n_params++];
    snprintf(pp->key, sizeof pp->key, "%s", key);
    snprintf(pp->value, sizeof pp->value, "%s", s);
    pp->line = line_of(vn);
    return SOOC_OK;
}

static sooc_status sec_sensor(pctx *p, yaml_node_t *m, sooc_node_config *c) {
    if (m->type != YAML_MAPPING_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: sensor: expected a mapping", p->name, line_of(m));
    /* driver first: the other keys depend on it */
    yaml_node_t *dv = NULL, *dk = NULL;
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; pr++) {
        yaml_node_t *kn = yaml_document_get_node(p->doc, pr->key);
        if (kn && kn->type == YAML_SCALAR_NODE && !strcmp((char *)kn->data.scalar.value, "driver")) {
            /* the first driver decides; a second one is an error, not "last one wins" */
            if (dk) return bad(p, kn, "driver", "duplicate key", NULL);
            dk = kn;
            dv = yaml_document_get_node(p->doc, pr->value);
        }
    }
    if (!dv) return sooc_seterr(SOOC_EINVAL, "%s:%d: sensor.driver: missing (one of %s)", p->name,
                                line_of(m), g_drivers);
    sooc_status st = get_str(p, dv, "driver", c->driver, sizeof c->driver, 0);
    if (st) return st;
    if (!in_enum(c->driver, g_drivers)) {
        char what[128];
        snprintf(what, sizeof what, "unknown driver (expected one of %s)", g_drivers);
        return bad(p, dv, "driver", what, c->driver);
    }
    c->n_params = 0;
    for (yaml_node_pair_t *pr = m->data.mapping.pairs.start; pr < m->data.mapping.pairs.top; pr++) {
        yaml_node_t *kn = yaml_document_get_node(p->doc, pr->key);
        yaml_node_t *vn = yaml_document_get_node(p->doc, pr->value);
        if (!kn || kn->type != YAML_SCALAR_NODE)
            return sooc_seterr(SOOC_EINVAL, "%s:%d: sensor: keys must be plain strings", p->name, line_of(m));
        const char *key = (const char *)kn->data.scalar.value;
        for (yaml_node_pair_t *q = m->data.mapping.pairs.start; q < pr; q++) {
            yaml_node_t *k2 = yaml_document_get_node(p->doc, q->key);
            if (k2 && k2->type == YAML_SCALAR_NODE && !strcmp((const char *)k2->data.scalar.value, key))
                return bad(p, kn, key, "duplicate key", NULL);
        }
        if (!strcmp(key, "driver")) continue;
        if ((st = sensor_param(p, key, kn, vn, c))) return st;
    }
    if (!strcmp(c->driver, "replay") && !sooc_node_param_get(c, "path"))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: sensor.path: missing (the recording to replay)", p->name,
                           line_of(m));
    return SOOC_OK;
}

/* -------------------------------------------------------------- sections */

static sooc_status k_pose(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    const char *s = "";
    sooc_status st;
    if (!strcmp(key, "source")) {
        if ((st = get_scalar(p, vn, key, &s))) return st;
        if (!strcmp(s, "sensor")) c->pose_kind = SOOC_NODE_POSE_SENSOR;
        else if (!strcmp(s, "file")) c->pose_kind = SOOC_NODE_POSE_FILE;
        else if (!strcmp(s, "socket")) c->pose_kind = SOOC_NODE_POSE_SOCKET;
        else return bad(p, vn, key, "expected sensor, file or socket", s);
        return SOOC_OK;
    }
    if (!strcmp(key, "path") || !strcmp(key, "address"))
        return get_str(p, vn, key, c->pose_path, sizeof c->pose_path, 0);
    if (!strcmp(key, "tolerance_ms")) {
        double x;
        if ((st = get_num(p, vn, key, 0, 10000, &x))) return st;
        c->pose_tolerance_s = x * 1e-3;
        return SOOC_OK;
    }
    if (!strcmp(key, "frame")) {
        if ((st = get_scalar(p, vn, key, &s))) return st;
        if (!strcmp(s, "camera")) c->pose_is_effector = 0;
        else if (!strcmp(s, "effector")) c->pose_is_effector = 1;
        else return bad(p, vn, key, "expected camera or effector", s);
        return SOOC_OK;
    }
    return unknown(p, kn, key, "unknown key (known: source, path, address, tolerance_ms, frame)");
}

static sooc_status k_model(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    long li;
    sooc_status st;
    if (!strcmp(key, "path")) return get_str(p, vn, key, c->model_path, sizeof c->model_path, 0);
    if (!strcmp(key, "width") || !strcmp(key, "height")) {
        if ((st = get_int(p, vn, key, 0, 8192, &li))) return st;
        if (key[0] == 'w') c->input_width = (int)li;
        else c->input_height = (int)li;
        return SOOC_OK;
    }
    if (!strcmp(key, "iterations")) {
        if ((st = get_int(p, vn, key, 0, 1000, &li))) return st;
        c->iterations = (int)li;
        return SOOC_OK;
    }
    if (!strcmp(key, "threads")) {
        if ((st = get_int(p, vn, key, 0, 1024, &li))) return st;
        c->threads = (int)li;
        return SOOC_OK;
    }
    if (!strcmp(key, "seed")) {
        if ((st = get_int(p, vn, key, 0, 2147483647L, &li))) return st;
        c->seed = (uint64_t)li;
        return SOOC_OK;
    }
    if (!strcmp(key, "depth_resample")) {
        const char *s = "";
        if ((st = get_scalar(p, vn, key, &s))) return st;
        if (!strcmp(s, "min")) c->depth_resample = SOOC_NODE_DEPTH_MIN;
        else if (!strcmp(s, "nearest")) c->depth_resample = SOOC_NODE_DEPTH_NEAREST;
        else return bad(p, vn, key, "expected min or nearest", s);
        return SOOC_OK;
    }
    return unknown(p, kn, key,
                   "unknown key (known: path, width, height, iterations, threads, seed, depth_resample)");
}

static sooc_status k_keyframe(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    if (!strcmp(key, "translation_m")) return get_num(p, vn, key, 0, 1000, &c->kf_translation_m);
    if (!strcmp(key, "rotation_deg")) return get_num(p, vn, key, 0, 360, &c->kf_rotation_deg);
    if (!strcmp(key, "time_s")) return get_num(p, vn, key, 0, 86400, &c->kf_time_s);
    return unknown(p, kn, key, "unknown key (known: translation_m, rotation_deg, time_s)");
}

static sooc_status k_shm(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    sooc_status st;
    if (!strcmp(key, "name")) {
        if ((st = get_str(p, vn, key, c->shm_name, sizeof c->shm_name, 1))) return st;
        for (const char *q = c->shm_name; *q; q++)
            if (!isalnum((unsigned char)*q) && *q != '_' && *q != '-' && *q != '.')
                return bad(p, vn, key, "only letters, digits, '_', '-' and '.' are allowed", c->shm_name);
        if (strlen(c->shm_name) > 40) return bad(p, vn, key, "at most 40 characters", c->shm_name);
        return SOOC_OK;
    }
    if (!strcmp(key, "capacity")) {
        long li;
        if ((st = get_int(p, vn, key, 1, 1L << 20, &li))) return st;
        c->shm_capacity = (uint32_t)li;
        return SOOC_OK;
    }
    if (!strcmp(key, "unlink_on_exit")) return get_bool(p, vn, key, &c->shm_unlink_on_exit);
    return unknown(p, kn, key, "unknown key (known: name, capacity, unlink_on_exit)");
}

static sooc_status k_map(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    if (!strcmp(key, "db")) return get_str(p, vn, key, c->map_db, sizeof c->map_db, 1);
    if (!strcmp(key, "resume")) return get_bool(p, vn, key, &c->map_resume);
    return unknown(p, kn, key, "unknown key (known: db, resume)");
}

static sooc_status k_world(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    sooc_status st;
    const char *s = "";
    if (!strcmp(key, "up")) {
        double v[3] = {0, 0, 0};
        if (vn->type == YAML_SCALAR_NODE) {
            s = (const char *)vn->data.scalar.value;
            static const char *ax[] = {"+x", "-x", "+y", "-y", "+z", "-z"};
            int k = -1;
            for (int i = 0; i < 6; i++)
                if (!strcmp(s, ax[i]) || (s[0] == ax[i][1] && !s[1] && ax[i][0] == '+')) k = i;
            if (k < 0) return bad(p, vn, key, "expected +x, -x, +y, -y, +z, -z or [x, y, z]", s);
            v[k / 2] = (k % 2) ? -1.0 : 1.0;
        } else if (vn->type == YAML_SEQUENCE_NODE) {
            int n = (int)(vn->data.sequence.items.top - vn->data.sequence.items.start);
            if (n != 3) return bad(p, vn, key, "expected 3 numbers", NULL);
            for (int i = 0; i < 3; i++) {
                yaml_node_t *e = yaml_document_get_node(p->doc, vn->data.sequence.items.start[i]);
                if ((st = get_num(p, e, key, -1e6, 1e6, &v[i]))) return st;
            }
            if (sooc_v3_normalize(v) < 1e-9) return bad(p, vn, key, "zero vector", NULL);
        } else {
            return bad(p, vn, key, "expected an axis or [x, y, z]", NULL);
        }
        memcpy(c->up, v, sizeof v);
        c->up_given = 1;
        return SOOC_OK;
    }
    if (!strcmp(key, "floor")) {
        if ((st = get_scalar(p, vn, key, &s))) return st;
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
    if (!strcmp(key, "ransac_threshold_m")) return get_num(p, vn, key, 1e-4, 1.0, &c->floor_ransac_threshold_m);
    if (!strcmp(key, "ransac_iterations")) {
        long li;
        if ((st = get_int(p, vn, key, 1, 100000, &li))) return st;
        c->floor_ransac_iterations = (int)li;
        return SOOC_OK;
    }
    return unknown(p, kn, key, "unknown key (known: up, floor, ransac_threshold_m, ransac_iterations)");
}

static sooc_status k_pipeline(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    sooc_status st;
    if (!strcmp(key, "ring_capacity")) {
        long li;
        if ((st = get_int(p, vn, key, 1, 1024, &li))) return st;
        c->ring_capacity = (int)li;
        return SOOC_OK;
    }
    if (!strcmp(key, "block_when_full")) return get_bool(p, vn, key, &c->block_when_full);
    if (!strcmp(key, "stats_period_s")) return get_num(p, vn, key, 0, 86400, &c->stats_period_s);
    if (!strcmp(key, "min_depth_m")) return get_num(p, vn, key, 0, 100, &c->min_depth_m);
    if (!strcmp(key, "max_depth_m")) return get_num(p, vn, key, 0, 1000, &c->max_depth_m);
    return unknown(p, kn, key, "unknown key (known: ring_capacity, block_when_full, stats_period_s, min_depth_m, max_depth_m)");
}

static sooc_status k_log(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    if (!strcmp(key, "level")) {
        const char *s = "";
        sooc_status st = get_scalar(p, vn, key, &s);
        if (st) return st;
        if (sooc_log_level_parse(s, &c->log_level)) return bad(p, vn, key, "expected debug, info, warn or error", s);
        return SOOC_OK;
    }
    return unknown(p, kn, key, "unknown key (known: level)");
}

static sooc_status k_root(pctx *p, const char *key, yaml_node_t *kn, yaml_node_t *vn, void *u) {
    sooc_node_config *c = u;
    pctx q = *p;
    q.section = key;
    if (!strcmp(key, "sensor")) return sec_sensor(&q, vn, c);
    if (!strcmp(key, "pose")) return walk_map(&q, vn, key, k_pose, c);
    if (!strcmp(key, "model")) return walk_map(&q, vn, key, k_model, c);
    if (!strcmp(key, "keyframe")) return walk_map(&q, vn, key, k_keyframe, c);
    if (!strcmp(key, "shm")) return walk_map(&q, vn, key, k_shm, c);
    if (!strcmp(key, "map")) return walk_map(&q, vn, key, k_map, c);
    if (!strcmp(key, "world")) return walk_map(&q, vn, key, k_world, c);
    if (!strcmp(key, "pipeline")) return walk_map(&q, vn, key, k_pipeline, c);
    if (!strcmp(key, "log")) return walk_map(&q, vn, key, k_log, c);
    if (!strcmp(key, "calib")) {
        q.section = NULL;
        return get_str(&q, vn, key, c->calib_path, sizeof c->calib_path, 1);
    }
    q.section = NULL;
    return unknown(&q, kn, key,
                   "unknown key (known: sensor, pose, calib, model, keyframe, shm, map, world, pipeline, log)");
}

sooc_status sooc_node_config_parse(sooc_node_config *c, const char *text, size_t n, const char *name) {
    sooc_node_config_default(c);
    snprintf(c->path, sizeof c->path, "%s", name);
    /* libyaml refuses OpenCV's "%YAML:1.0" header line: skip it (node.md finding 6). */
    if (n >= 6 && !strncmp(text, "%YAML:", 6)) {
        const char *nl = memchr(text, '\n', n);
        size_t skip = nl ? (size_t)(nl - text) : n;
        /* keep line numbers: replace by a comment of equal length */
        char *t = sooc_malloc(n + 1);
        if (!t) return SOOC_ENOMEM;
        memcpy(t, text, n);
        t[n] = 0;
        t[0] = '#';
        (void)skip;
        sooc_status st = sooc_node_config_parse(c, t, n, name);
        sooc_free(t);
        return st;
    }
    yaml_parser_t parser;
    yaml_document_t doc;
    if (!yaml_parser_initialize(&parser)) return sooc_seterr(SOOC_ENOMEM, "%s: yaml parser init failed", name);
    yaml_parser_set_input_string(&parser, (const unsigned char *)text, n);
    if (!yaml_parser_load(&parser, &doc)) {
        sooc_status st = sooc_seterr(SOOC_EFORMAT, "%s:%d: YAML error: %s%s%s", name,
                                     (int)parser.problem_mark.line + 1,
                                     parser.problem ? parser.problem : "parse error",
                                     parser.context ? " " : "", parser.context ? parser.context : "");
        yaml_parser_delete(&parser);
        return st;
    }
    sooc_status st = SOOC_OK;
    yaml_node_t *root = yaml_document_get_root_node(&doc);
    pctx p = {&doc, name, NULL};
    if (!root) st = sooc_seterr(SOOC_EINVAL, "%s: empty launch file", name);
    else st = walk_map(&p, root, "launch file", k_root, c);
    if (!st && !c->driver[0])
        st = sooc_seterr(SOOC_EINVAL, "%s: sensor: missing section (sensor.driver is required)", name);
    if (!st && c->pose_kind != SOOC_NODE_POSE_SENSOR && !c->pose_path[0])
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.path: missing (needed for pose.source %s)", name,
                         c->pose_kind == SOOC_NODE_POSE_FILE ? "file" : "socket");
    if (!st && c->pose_kind == SOOC_NODE_POSE_SOCKET && strncmp(c->pose_path, "unix:", 5) &&
        strncmp(c->pose_path, "udp://", 6))
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.address: expected unix:/path or udp://host:port, got '%s'",
                         name, c->pose_path);
    if (!st && c->pose_is_effector && !c->calib_path[0])
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.frame: effector poses need calib (T_effector_camera)", name);
    if (!st && c->min_depth_m >= c->max_depth_m)
        st = sooc_seterr(SOOC_EINVAL, "%s: pipeline.min_depth_m: must be below max_depth_m", name);
    if (!st && (c->input_width > 0) != (c->input_height > 0))
        st = sooc_seterr(SOOC_EINVAL, "%s: model.width/height: give both or neither", name);
    if (!st && strcmp(c->driver, "replay") && c->pose_kind == SOOC_NODE_POSE_SENSOR)
        st = sooc_seterr(SOOC_EINVAL, "%s: pose.source: live driver '%s' carries no poses; use file or socket",
                         name, c->driver);
    yaml_document_delete(&doc);
    yaml_parser_delete(&parser);
    return st;
}

sooc_status sooc_node_config_load(sooc_node_config *c, const char *path) {
    void *buf = NULL;
    size_t n = 0;
    sooc_status st = sooc_file_read_all(path, 1 << 20, &buf, &n);
    if (st) {
        sooc_node_config_default(c);
        return sooc_adderr(st, "launch file %s", path);
    }
    st = sooc_node_config_parse(c, buf, n, path);
    sooc_free(buf);
    return st;
}

size_t sooc_node_config_format(const sooc_node_config *c, char *buf, size_t cap) {
    static const char *pk[] = {"sensor", "file", "socket"};
    size_t k = 0;
#define OUT(...)                                                                    \
    do {                                                                            \
        int w_ = snprintf(k < cap ? buf + k : NULL, k < cap ? cap - k : 0, __VA_ARGS__); \
        if (w_ > 0) k += (size_t)w_;                                                \
    } while (0)
    OUT("sensor: {driver: %s", c->driver);
    for (int i = 0; i < c->n_params; i++) OUT(", %s: %s", c->params[i].key, c->params[i].value);
    OUT("}\npose: {source: %s, path: '%s', tolerance_ms: %g, frame: %s}\n", pk[c->pose_kind], c->pose_path,
        c->pose_tolerance_s * 1e3, c->pose_is_effector ? "effector" : "camera");
    OUT("calib: '%s'\nmodel: {path: '%s', width: %d, height: %d, iterations: %d, threads: %d, seed: %llu, "
        "depth_resample: %s}\n",
        c->calib_path, c->model_path, c->input_width, c->input_height, c->iterations, c->threads,
        (unsigned long long)c->seed, c->depth_resample == SOOC_NODE_DEPTH_MIN ? "min" : "nearest");
    OUT("keyframe: {translation_m: %g, rotation_deg: %g, time_s: %g}\n", c->kf_translation_m,
        c->kf_rotation_deg, c->kf_time_s);
    OUT("shm: {name: '%s', capacity: %u, unlink_on_exit: %s}\n", c->shm_name, c->shm_capacity,
        c->shm_unlink_on_exit ? "true" : "false");
    OUT("map: {db: '%s', resume: %s}\n", c->map_db, c->map_resume ? "true" : "false");
    if (c->floor_mode == SOOC_NODE_FLOOR_ESTIMATE)
        OUT("world: {up: [%g, %g, %g], floor: estimate}\n", c->up[0], c->up[1], c->up[2]);
    else
        OUT("world: {up: [%g, %g, %g], floor: %g}\n", c->up[0], c->up[1], c->up[2], c->floor_height);
    OUT("pipeline: {ring_capacity: %d, block_when_full: %s, stats_period_s: %g, min_depth_m: %g, "
        "max_depth_m: %g}\n", c->ring_capacity, c->block_when_full ? "true" : "false", c->stats_period_s,
        c->min_depth_m, c->max_depth_m);
    static const char *lv[] = {"debug", "info", "warn", "error", "fatal"};
    OUT("log: {level: %s}\n", lv[c->log_level]);
#undef OUT
    return k;
}
