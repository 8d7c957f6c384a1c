/* Calibration YAML load/save with the libyaml document API. */
#include "sooc3d/frame.h"
#include "data/yaml_doc.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void sooc_calib_init(sooc_calib *c) {
    memset(c, 0, sizeof *c);
    snprintf(c->camera_name, sizeof c->camera_name, "unknown");
    sooc_m3_identity(c->R_rect);
    c->depth_registered = -1;
    c->depth_shift = -1;
    c->depth_invalid = -1;
    sooc_se3_identity(c->T_color_depth);
    sooc_se3_identity(c->T_effector_camera);
}

void sooc_calib_pinhole(sooc_calib *c, int w, int h, double fx, double fy, double cx, double cy) {
    sooc_calib_init(c);
    c->K.width = w;
    c->K.height = h;
    c->K.fx = fx;
    c->K.fy = fy;
    c->K.cx = cx;
    c->K.cy = cy;
    c->K.dist_model = SOOC_DIST_NONE;
    memset(c->P, 0, sizeof c->P);
    c->P[0] = fx; c->P[2] = cx; c->P[5] = fy; c->P[6] = cy; c->P[10] = 1;
}


static sooc_status parse_num(sooc_ydoc *c, const yaml_node_t *n, const char *key, double *out) {
    const char *s = sooc_yscalar(n);
    if (!s) return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a number", c->name, sooc_yline(n), key);
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end != '\0' || !isfinite(v))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: '%s' is not a finite number", c->name,
                           sooc_yline(n), key, s);
    *out = v;
    return SOOC_OK;
}

static sooc_status parse_int(sooc_ydoc *c, const yaml_node_t *n, const char *key, int *out) {
    double v = 0;
    sooc_status s = parse_num(c, n, key, &v);
    if (s) return s;
    if (v != floor(v) || v < -1e9 || v > 1e9)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected an integer", c->name, sooc_yline(n), key);
    *out = (int)v;
    return SOOC_OK;
}

static sooc_status parse_bool(sooc_ydoc *c, const yaml_node_t *n, const char *key, int *out) {
    const char *s = sooc_yscalar(n);
    if (s && (!strcmp(s, "true") || !strcmp(s, "True") || !strcmp(s, "1"))) { *out = 1; return SOOC_OK; }
    if (s && (!strcmp(s, "false") || !strcmp(s, "False") || !strcmp(s, "0"))) { *out = 0; return SOOC_OK; }
    return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected true or false", c->name, sooc_yline(n), key);
}

/* A matrix node: {rows, cols, [dt], data: [...]} (ROS or !!opencv-matrix).
 * Fills up to `cap` values and returns rows and cols. The keys parent and child
 * (T_effector_camera only) are copied when parent/child are non-NULL. */
static sooc_status parse_matrix(sooc_ydoc *c, yaml_node_t *n, const char *key, double *vals, int cap,
                                int *rows, int *cols, char *parent, char *child) {
    if (n->type != YAML_MAPPING_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a mapping {rows, cols, data}", c->name,
                           sooc_yline(n), key);
    int r = -1, cl = -1, nd = -1;
    yaml_node_t *data = NULL;
    for (yaml_node_pair_t *p = n->data.mapping.pairs.start; p < n->data.mapping.pairs.top; p++) {
        sooc_ypair pr;
        sooc_status s = sooc_ymap_pair(c, n, p, key, 1, &pr);
        if (s) return s;
        yaml_node_t *k = pr.k, *v = pr.v;
        const char *ks = pr.key;
        char sub[96];
        snprintf(sub, sizeof sub, "%s.%s", key, ks);
        if (!strcmp(ks, "rows")) s = parse_int(c, v, sub, &r);
        else if (!strcmp(ks, "cols")) s = parse_int(c, v, sub, &cl);
        else if (!strcmp(ks, "dt")) {
            const char *dt = sooc_yscalar(v);
            if (!dt || (strcmp(dt, "d") && strcmp(dt, "f") && strcmp(dt, "i")))
                return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: dt must be d, f or i", c->name, sooc_yline(v),
                                   sub);
        } else if (!strcmp(ks, "data")) {
            data = v;
        } else if (parent && !strcmp(ks, "parent") && sooc_yscalar(v)) {
            snprintf(parent, 64, "%s", sooc_yscalar(v));
        } else if (child && !strcmp(ks, "child") && sooc_yscalar(v)) {
            snprintf(child, 64, "%s", sooc_yscalar(v));
        } else {
            return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: unknown key '%s'", c->name, sooc_yline(k), key, ks);
        }
        if (s) return s;
    }
    if (r < 1 || cl < 1)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: rows and cols must be given and >= 1", c->name,
                           sooc_yline(n), key);
    /* every calibration matrix has at most 16 values; bounding rows and cols
     * keeps r * cl from overflowing */
    if (r > 16 || cl > 16)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: rows and cols must be <= 16 (got %dx%d)", c->name,
                           sooc_yline(n), key, r, cl);
    if (!data || data->type != YAML_SEQUENCE_NODE)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: missing data: [...] list", c->name, sooc_yline(n), key);
    nd = sooc_yseq_len(data);
    if (nd != r * cl)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected %d numbers (%dx%d), got %d", c->name,
                           sooc_yline(data), key, r * cl, r, cl, nd);
    if (nd > cap)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: too many values (%d > %d)", c->name, sooc_yline(data),
                           key, nd, cap);
    for (int i = 0; i < nd; i++) {
        yaml_node_t *it = sooc_yseq_item(c, data, i);
        char sub[96];
        snprintf(sub, sizeof sub, "%s.data[%d]", key, i);
        sooc_status s = parse_num(c, it, sub, &vals[i]);
        if (s) return s;
    }
    *rows = r;
    *cols = cl;
    return SOOC_OK;
}

static sooc_status parse_rigid(sooc_ydoc *c, yaml_node_t *n, const char *key, double T[16],
                               char *parent, char *child) {
    int r, cl;
    sooc_status s = parse_matrix(c, n, key, T, 16, &r, &cl, parent, child);
    if (s) return s;
    if (r != 4 || cl != 4)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a 4x4 matrix, got %dx%d", c->name,
                           sooc_yline(n), key, r, cl);
    double R[9], t[3], err;
    sooc_se3_to_rt(R, t, T);
    if (!sooc_m3_is_rotation(R, 1e-4, &err))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: rotation part is not orthonormal (error %.3g)",
                           c->name, sooc_yline(n), key, err);
    if (T[12] != 0 || T[13] != 0 || T[14] != 0 || T[15] != 1)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: %s: last row must be 0 0 0 1", c->name, sooc_yline(n), key);
    return SOOC_OK;
}

static sooc_status parse_doc(sooc_ydoc *c, sooc_calib *out) {
    yaml_node_t *root = sooc_ydoc_root(c);
    if (!root) return sooc_seterr(SOOC_EFORMAT, "%s: empty YAML document", c->name);
    if (root->type != YAML_MAPPING_NODE)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: top level must be a mapping", c->name, sooc_yline(root));
    sooc_calib_init(out);
    int have_w = 0, have_h = 0, have_K = 0, have_P = 0, have_model = 0, root_line = sooc_yline(root);
    double Km[9] = {0};
    int Kline = 0;
    for (yaml_node_pair_t *p = root->data.mapping.pairs.start; p < root->data.mapping.pairs.top; p++) {
        sooc_ypair pr;
        sooc_status s = sooc_ymap_pair(c, root, p, NULL, 1, &pr);
        if (s) return s;
        yaml_node_t *k = pr.k, *v = pr.v;
        const char *ks = pr.key;
        int r = 0, cl = 0;
        if (!strcmp(ks, "image_width")) { s = parse_int(c, v, ks, &out->K.width); have_w = 1;
            if (!s && out->K.width <= 0) s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: must be > 0", c->name, sooc_yline(v), ks);
        } else if (!strcmp(ks, "image_height")) { s = parse_int(c, v, ks, &out->K.height); have_h = 1;
            if (!s && out->K.height <= 0) s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: must be > 0", c->name, sooc_yline(v), ks);
        } else if (!strcmp(ks, "camera_name")) {
            if (!sooc_yscalar(v)) s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a string", c->name, sooc_yline(v), ks);
            else snprintf(out->camera_name, sizeof out->camera_name, "%s", sooc_yscalar(v));
        } else if (!strcmp(ks, "camera_matrix")) {
            s = parse_matrix(c, v, ks, Km, 9, &r, &cl, NULL, NULL);
            if (!s && (r != 3 || cl != 3))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected 3x3, got %dx%d", c->name, sooc_yline(v), ks, r, cl);
            have_K = 1;
            Kline = sooc_yline(v);
        } else if (!strcmp(ks, "distortion_model")) {
            const char *m = sooc_yscalar(v);
            have_model = 1;
            if (m && !strcmp(m, "plumb_bob")) out->K.dist_model = SOOC_DIST_PLUMB_BOB;
            else if (m && !strcmp(m, "rational_polynomial")) out->K.dist_model = SOOC_DIST_RATIONAL;
            else if (m && (!strcmp(m, "equidistant") || !strcmp(m, "fisheye"))) out->K.dist_model = SOOC_DIST_EQUIDISTANT;
            else if (m && !strcmp(m, "none")) out->K.dist_model = SOOC_DIST_NONE;
            else s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: unknown model '%s' (plumb_bob, rational_polynomial, equidistant, none)",
                                 c->name, sooc_yline(v), ks, m ? m : "?");
        } else if (!strcmp(ks, "distortion_coefficients")) {
            s = parse_matrix(c, v, ks, out->K.dist, 8, &r, &cl, NULL, NULL);
            if (!s && r != 1 && cl != 1)
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected a row or column vector", c->name, sooc_yline(v), ks);
            out->n_dist = r * cl;
        } else if (!strcmp(ks, "rectification_matrix")) {
            s = parse_matrix(c, v, ks, out->R_rect, 9, &r, &cl, NULL, NULL);
            if (!s && (r != 3 || cl != 3))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected 3x3, got %dx%d", c->name, sooc_yline(v), ks, r, cl);
        } else if (!strcmp(ks, "projection_matrix")) {
            s = parse_matrix(c, v, ks, out->P, 12, &r, &cl, NULL, NULL);
            if (!s && (r != 3 || cl != 4))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: expected 3x4, got %dx%d", c->name, sooc_yline(v), ks, r, cl);
            have_P = 1;
        } else if (!strcmp(ks, "depth_scale")) {
            s = parse_num(c, v, ks, &out->depth_scale);
            if (!s && !(out->depth_scale > 0))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: must be > 0 (metres per depth unit)", c->name, sooc_yline(v), ks);
        } else if (!strcmp(ks, "depth_shift")) {
            s = parse_int(c, v, ks, &out->depth_shift);
            if (!s && (out->depth_shift < 0 || out->depth_shift > 15))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: must be in [0, 15] (bits to drop from raw depth)", c->name,
                                sooc_yline(v), ks);
        } else if (!strcmp(ks, "depth_invalid")) {
            s = parse_int(c, v, ks, &out->depth_invalid);
            if (!s && (out->depth_invalid < 0 || out->depth_invalid > 65535))
                s = sooc_seterr(SOOC_EINVAL, "%s:%d: %s: must be a raw 16-bit value in [0, 65535]", c->name,
                                sooc_yline(v), ks);
        } else if (!strcmp(ks, "depth_registered")) {
            s = parse_bool(c, v, ks, &out->depth_registered);
        } else if (!strcmp(ks, "T_color_depth")) {
            s = parse_rigid(c, v, ks, out->T_color_depth, NULL, NULL);
            out->has_T_color_depth = 1;
        } else if (!strcmp(ks, "T_effector_camera")) {
            s = parse_rigid(c, v, ks, out->T_effector_camera, out->effector_parent, out->effector_child);
            out->has_T_effector_camera = 1;
        } else {
            s = sooc_seterr(SOOC_EINVAL, "%s:%d: unknown key '%s'", c->name, sooc_yline(k), ks);
        }
        if (s) return s;
    }
    if (!have_w) return sooc_seterr(SOOC_EINVAL, "%s:%d: image_width: missing", c->name, root_line);
    if (!have_h) return sooc_seterr(SOOC_EINVAL, "%s:%d: image_height: missing", c->name, root_line);
    if (!have_K) return sooc_seterr(SOOC_EINVAL, "%s:%d: camera_matrix: missing", c->name, root_line);
    if (Km[0] == 0 || Km[4] == 0 || Km[1] != 0 || Km[3] != 0 || Km[6] != 0 || Km[7] != 0 || Km[8] != 1)
        return sooc_seterr(SOOC_EINVAL,
                           "%s:%d: camera_matrix: must be [fx 0 cx; 0 fy cy; 0 0 1] with fx, fy != 0 (no skew)",
                           c->name, Kline);
    out->K.fx = Km[0];
    out->K.fy = Km[4];
    out->K.cx = Km[2];
    out->K.cy = Km[5];
    if (!have_P) {
        memset(out->P, 0, sizeof out->P);
        out->P[0] = Km[0]; out->P[2] = Km[2]; out->P[5] = Km[4]; out->P[6] = Km[5]; out->P[10] = 1;
    }
    if (out->n_dist > 0 && !have_model) out->K.dist_model = SOOC_DIST_PLUMB_BOB;
    int allzero = 1;
    for (int i = 0; i < out->n_dist; i++)
        if (out->K.dist[i] != 0) allzero = 0;
    if (allzero) out->K.dist_model = SOOC_DIST_NONE;
    return SOOC_OK;
}

sooc_status sooc_calib_parse(const char *text, size_t n, const char *name, sooc_calib *out) {
    sooc_ydoc d;
    sooc_status s = sooc_ydoc_parse(&d, text, n, name);
    if (s) return s;
    s = parse_doc(&d, out);
    sooc_ydoc_free(&d);
    return s;
}

sooc_status sooc_calib_load(const char *path, sooc_calib *out) {
    void *buf;
    size_t n;
    sooc_status s = sooc_file_read_all(path, 1 << 20, &buf, &n);
    if (s) return s;
    s = sooc_calib_parse(buf, n, path, out);
    sooc_free(buf);
    return s;
}

static int put_mat(char *b, size_t cap, const char *key, const double *v, int r, int c) {
    int len = snprintf(b, cap, "%s: {rows: %d, cols: %d, data: [", key, r, c);
    for (int i = 0; i < r * c && (size_t)len < cap; i++)
        len += snprintf(b + len, cap - (size_t)len, "%s%.17g", i ? ", " : "", v[i]);
    if ((size_t)len < cap) len += snprintf(b + len, cap - (size_t)len, "]}\n");
    return len;
}

sooc_status sooc_calib_save(const char *path, const sooc_calib *c) {
    char b[8192];
    size_t cap = sizeof b;
    int n = 0;
    const sooc_intrinsics *K = &c->K;
    static const char *models[] = {"none", "plumb_bob", "rational_polynomial", "equidistant"};
    n += snprintf(b + n, cap - n, "%%YAML 1.2\n---\ncamera_name: %s\nimage_width: %d\nimage_height: %d\n",
                  c->camera_name[0] ? c->camera_name : "unknown", K->width, K->height);
    double Km[9] = {K->fx, 0, K->cx, 0, K->fy, K->cy, 0, 0, 1};
    n += put_mat(b + n, cap - n, "camera_matrix", Km, 3, 3);
    int dm = (int)K->dist_model;
    n += snprintf(b + n, cap - n, "distortion_model: %s\n", dm >= 0 && dm <= 3 ? models[dm] : "none");
    double zero5[5] = {0};
    if (c->n_dist > 0) n += put_mat(b + n, cap - n, "distortion_coefficients", K->dist, 1, c->n_dist);
    else n += put_mat(b + n, cap - n, "distortion_coefficients", zero5, 1, 5);
    n += put_mat(b + n, cap - n, "rectification_matrix", c->R_rect, 3, 3);
    n += put_mat(b + n, cap - n, "projection_matrix", c->P, 3, 4);
    if (c->depth_scale > 0) n += snprintf(b + n, cap - n, "depth_scale: %.17g\n", c->depth_scale);
    if (c->depth_shift >= 0) n += snprintf(b + n, cap - n, "depth_shift: %d\n", c->depth_shift);
    if (c->depth_invalid >= 0) n += snprintf(b + n, cap - n, "depth_invalid: %d\n", c->depth_invalid);
    if (c->depth_registered >= 0)
        n += snprintf(b + n, cap - n, "depth_registered: %s\n", c->depth_registered ? "true" : "false");
    if (c->has_T_color_depth) n += put_mat(b + n, cap - n, "T_color_depth", c->T_color_depth, 4, 4);
    if (c->has_T_effector_camera) {
        n += put_mat(b + n, cap - n, "T_effector_camera", c->T_effector_camera, 4, 4);
        if (c->effector_parent[0] || c->effector_child[0]) {
            n -= 2; /* reopen the mapping: replace "}\n" */
            n += snprintf(b + n, cap - n, ", parent: %s, child: %s}\n",
                          c->effector_parent[0] ? c->effector_parent : "~",
                          c->effector_child[0] ? c->effector_child : "~");
        }
    }
    if ((size_t)n >= cap) return sooc_seterr(SOOC_EINVAL, "%s: calib text too long", path);
    return sooc_file_write_atomic(path, b, (size_t)n);
}
