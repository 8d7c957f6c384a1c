/* Training configuration: defaults and the YAML loader.
 *
 * The file is a YAML mapping of training keys (sooc_train_config field names)
 * with an optional nested `model:` mapping of sooc_model_config field names.
 * The loader is table-driven: every key maps to a typed field, so unknown keys
 * and bad values are reported with the file, the line and the key. */
#include "sooc3d/train.h"
#include "data/yaml_doc.h"

#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

void sooc_train_config_default(sooc_train_config *c) {
    memset(c, 0, sizeof *c);
    c->steps = 20000;
    c->seed = 1;
    c->init_seed = 1;
    c->lr = 2e-4f;
    c->warmup = 1000;
    c->lr_final_frac = 0.1f;
    c->cosine = 1;
    c->clip = 5.0f;
    c->tau_start = 1.0f;
    c->tau_end = 0.7f;
    c->tau_frac = 0.2f;
    c->kl_warmup = 1000;
    c->burnin = 0;
    c->st_retrieved = 0;
    c->phase_a = 0.15f;
    c->phase_b = 0.5f;
    c->t_min_b = 2;
    c->t_max_b = 3;
    c->t_min_c = 2;
    c->t_max_c = 5;
    c->q_a = 1;
    c->q_bc = 2;
    c->query_held_out = 0;
    c->accum = 1;
    c->threads = 0;
    c->log_every = 10;
    c->ckpt_every = 250;
    c->val_every = 500;
    c->val_scenes = 8;
    c->val_max_seconds = 0;
    c->view_min_cm = (float)SOOC_DATASET_VIEW_MIN_CM;
    c->view_min_deg = (float)SOOC_DATASET_VIEW_MIN_DEG;
    c->recorded_frac = 0;
}

typedef enum { F_INT, F_I64, F_U64, F_FLOAT, F_INT4 } ftype;
typedef struct { const char *name; ftype type; size_t off; double lo, hi; } field;

#define TF(n, t, lo, hi) {#n, t, offsetof(sooc_train_config, n), lo, hi}
static const field g_train_fields[] = {
    TF(steps, F_I64, 1, 1e9), TF(seed, F_U64, 0, 1.8e19), TF(init_seed, F_U64, 0, 1.8e19),
    TF(lr, F_FLOAT, 0, 1), TF(warmup, F_I64, 0, 1e9), TF(lr_final_frac, F_FLOAT, 0, 1),
    TF(cosine, F_INT, 0, 1), TF(clip, F_FLOAT, 0, 1e9), TF(tau_start, F_FLOAT, 0.01, 10),
    TF(tau_end, F_FLOAT, 0.01, 10), TF(tau_frac, F_FLOAT, 0, 1), TF(kl_warmup, F_I64, 0, 1e9),
    TF(burnin, F_I64, 0, 1e9), TF(st_retrieved, F_INT, 0, 1), TF(phase_a, F_FLOAT, 0, 1),
    TF(phase_b, F_FLOAT, 0, 1), TF(t_min_b, F_INT, 1, 64), TF(t_max_b, F_INT, 1, 64),
    TF(t_min_c, F_INT, 1, 64), TF(t_max_c, F_INT, 1, 64), TF(q_a, F_INT, 0, 16), TF(q_bc, F_INT, 0, 16),
    TF(query_held_out, F_INT, 0, 1),
    TF(accum, F_INT, 1, 64), TF(threads, F_INT, 0, 256), TF(log_every, F_I64, 1, 1e9),
    TF(ckpt_every, F_I64, 1, 1e9), TF(val_every, F_I64, 0, 1e9), TF(val_scenes, F_INT, 1, 100000),
    TF(val_max_seconds, F_FLOAT, 0, 1e9),
    TF(view_min_cm, F_FLOAT, 0, 1e4), TF(view_min_deg, F_FLOAT, 0, 180), TF(recorded_frac, F_FLOAT, 0, 1),
    TF(proposals, F_INT, 0, 1), TF(prop_join_m, F_FLOAT, 0, 1), TF(prop_logit, F_FLOAT, -20, 20),
};
#define MF(n, t, lo, hi) {#n, t, offsetof(sooc_model_config, n), lo, hi}
static const field g_model_fields[] = {
    MF(K, F_INT, 1, SOOC_MODEL_K_MAX), MF(d_what, F_INT, 1, SOOC_MODEL_D_MAX), MF(d_layout, F_INT, 1, 64),
    MF(L, F_INT, 0, 16), MF(img_w, F_INT, 8, 4096), MF(img_h, F_INT, 8, 4096), MF(ray_w, F_INT, 4, 4096),
    MF(ray_h, F_INT, 4, 4096), MF(dec_width, F_INT, 4, 1024), MF(dec_color_width, F_INT, 4, 1024),
    MF(n_freq, F_INT, 0, 16), MF(n_freq_layout, F_INT, 0, 16), MF(dens_bias_init, F_FLOAT, -20, 20),
    MF(ref_ch, F_INT4, 1, 1024), MF(ref_fc, F_INT, 1, 4096), MF(ref_hidden, F_INT, 1, 4096),
    MF(sigma_max, F_FLOAT, 0.01, 1e4), MF(sigma_c, F_FLOAT, 1e-3, 10), MF(air_cut, F_FLOAT, 0, 1),
    MF(delta_s, F_FLOAT, 0, 1), MF(eps_sigma_rel, F_FLOAT, 0, 1), MF(d_clip, F_FLOAT, 0.1, 1000),
    MF(t_near, F_FLOAT, 0, 100), MF(box_rh, F_FLOAT, 0.01, 100), MF(box_hb, F_FLOAT, 0.01, 100),
    MF(gauss_s, F_FLOAT, 0.001, 100), MF(block_size, F_FLOAT, 0.1, 1000), MF(use_box, F_INT, 0, 1),
    MF(rho_min, F_FLOAT, -30, 30), MF(rho_max, F_FLOAT, -30, 30), MF(prior_sigma_t, F_FLOAT, 1e-3, 100),
    MF(prior_near, F_FLOAT, 0, 100), MF(prior_far, F_FLOAT, 0, 100), MF(prior_pres_logit, F_FLOAT, -20, 20),
    MF(global_frame, F_INT, 0, 1), MF(global_radius, F_FLOAT, 0.01, 1000), MF(slots, F_INT, 0, SOOC_MODEL_K_MAX),
    MF(invalid_depth, F_INT, 0, 1), MF(unit_m, F_FLOAT, 1e-3, 1e3),
};

static sooc_status parse_num(const char *file, int line, const char *key, const char *v, const field *f,
                             void *base) {
    char *end = NULL;
    errno = 0;
    double x = strtod(v, &end);
    if (end == v || *end || errno || !isfinite(x))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: '%s' is not a number", file, line, key, v);
    if (x < f->lo || x > f->hi)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: %s is outside [%g, %g]", file, line, key, v, f->lo, f->hi);
    int is_int = f->type != F_FLOAT;
    if (is_int && x != floor(x))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: '%s' must be an integer", file, line, key, v);
    char *p = (char *)base + f->off;
    switch (f->type) {
    case F_INT: case F_INT4: *(int *)p = (int)x; break;
    case F_I64: *(int64_t *)p = (int64_t)x; break;
    case F_U64: *(uint64_t *)p = strtoull(v, NULL, 10); break;
    case F_FLOAT: *(float *)p = (float)x; break;
    }
    return SOOC_OK;
}

/* Applies the pairs of mapping `map` to the fields of `base`; at the top
 * level (allow_model) a `model:` mapping goes to mc. A repeated key is an
 * error naming both lines (YAML forbids them; silently taking the later one
 * hid typos in long configs). */
static sooc_status apply_mapping(sooc_ydoc *d, yaml_node_t *map, const field *fields, int nf, void *base,
                                 sooc_model_config *mc, int allow_model) {
    const char *file = d->name;
    for (yaml_node_pair_t *pr = map->data.mapping.pairs.start; pr < map->data.mapping.pairs.top; pr++) {
        sooc_ypair kv;
        sooc_status s = sooc_ymap_pair(d, map, pr, allow_model ? NULL : "model", 1, &kv);
        if (s) return s;
        yaml_node_t *v = kv.v;
        const char *key = kv.key;
        int line = sooc_yline(kv.k);
        if (allow_model && !strcmp(key, "model")) {
            if (v->type != YAML_MAPPING_NODE)
                return sooc_seterr(SOOC_EINVAL, "%s:%d: model: expected a mapping of model settings", file, line);
            s = apply_mapping(d, v, g_model_fields, (int)(sizeof g_model_fields / sizeof g_model_fields[0]), mc,
                              mc, 0);
            if (s) return s;
            continue;
        }
        const field *f = NULL;
        for (int i = 0; i < nf; i++)
            if (!strcmp(fields[i].name, key)) f = &fields[i];
        if (!f) return sooc_seterr(SOOC_EINVAL, "%s:%d: unknown key '%s'", file, line, key);
        if (f->type == F_INT4) {
            if (v->type != YAML_SEQUENCE_NODE || sooc_yseq_len(v) != 4)
                return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a list of 4 integers", file, line, key);
            for (int i = 0; i < 4; i++) {
                const char *it = sooc_yscalar(sooc_yseq_item(d, v, i));
                if (!it) return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected numbers", file, line, key);
                field fi = *f;
                fi.off += (size_t)i * sizeof(int);
                s = parse_num(file, line, key, it, &fi, base);
                if (s) return s;
            }
            continue;
        }
        if (!sooc_yscalar(v)) return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a number", file, line, key);
        s = parse_num(file, line, key, sooc_yscalar(v), f, base);
        if (s) return s;
    }
    return SOOC_OK;
}

sooc_status sooc_train_config_load(const char *path, sooc_train_config *c, sooc_model_config *mc) {
    void *buf = NULL;
    size_t n = 0;
    sooc_status s = sooc_file_read_all(path, 1 << 20, &buf, &n);
    if (s) return s;
    sooc_ydoc d;
    s = sooc_ydoc_parse(&d, buf, n, path);
    sooc_free(buf);
    if (s) return s;
    yaml_node_t *root = sooc_ydoc_root(&d);
    if (root && root->type == YAML_MAPPING_NODE) {
        s = apply_mapping(&d, root, g_train_fields, (int)(sizeof g_train_fields / sizeof g_train_fields[0]), c, mc,
                          1);
    } else if (root) {
        s = sooc_seterr(SOOC_EFORMAT, "%s:1: expected a mapping of training settings", path);
    }
    if (!s && c->phase_b < c->phase_a)
        s = sooc_seterr(SOOC_EINVAL, "%s: phase_b (%g) must not be below phase_a (%g)", path, c->phase_b, c->phase_a);
    if (!s && (c->t_min_b > c->t_max_b || c->t_min_c > c->t_max_c))
        s = sooc_seterr(SOOC_EINVAL, "%s: t_min_* must not exceed t_max_*", path);
    if (!s) {
        s = sooc_model_config_check(mc);
        if (s) sooc_adderr(s, "%s: model", path);
    }
    sooc_ydoc_free(&d);
    return s;
}
