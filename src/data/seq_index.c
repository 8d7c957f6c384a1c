/* The frame index every sequence layout fills (seq_impl.h): entries, close,
 * and the list, pose and calibration parsing the layout readers share. */
#include "sooc3d/frame.h"
#include "sooc3d/core.h"
#include "seq_impl.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void sooc_seq_close(sooc_seq *s) {
    if (!s) return;
    for (int64_t i = 0; i < s->n; i++) {
        sooc_free(s->e[i].rgb);
        sooc_free(s->e[i].depth);
        sooc_free(s->e[i].inst);
        sooc_free(s->e[i].pose_err);
    }
    sooc_free(s->e);
    sooc_image_free(&s->img_rgb);
    sooc_image_free(&s->img_depth);
    sooc_image_free(&s->img_inst);
    if (s->priv_free) s->priv_free(s->priv);
    sooc_free(s);
}

char *sooc_seqi_join_dup(const char *a, const char *b) {
    char buf[4096];
    if (sooc_path_join(buf, sizeof buf, a, b)) return NULL;
    return sooc_strdup(buf);
}

sooc_status sooc_seqi_push(sooc_seq *s, sooc_seqi_entry **out) {
    if (s->n == s->cap) {
        int64_t cap = s->cap ? s->cap * 2 : 256;
        sooc_seqi_entry *e = sooc_realloc(s->e, sizeof *e * (size_t)cap);
        if (!e) return SOOC_ENOMEM;
        s->e = e;
        s->cap = cap;
    }
    *out = &s->e[s->n++];
    memset(*out, 0, sizeof **out);
    sooc_se3_identity((*out)->T);
    return SOOC_OK;
}

/* Split `line` in place into at most `max` whitespace-separated tokens. */
int sooc_seqi_tokenize(char *line, char **tok, int max) {
    int n = 0;
    char *p = line;
    while (*p) {
        while (*p == ' ' || *p == '\t' || *p == '\r' || *p == ',') p++;
        if (!*p) break;
        if (n == max) return max + 1;
        tok[n++] = p;
        while (*p && *p != ' ' && *p != '\t' && *p != '\r' && *p != ',') p++;
        if (*p) *p++ = 0;
    }
    return n;
}

int sooc_seqi_parse_double(const char *t, double *v) {
    char *end;
    *v = strtod(t, &end);
    return end != t && *end == 0 && isfinite(*v);
}

/* Iterate the lines of a text file: calls fn(user, lineno, line) for each
 * line that is not empty and not a # comment. */
sooc_status sooc_seqi_for_lines(const char *path, sooc_seqi_line_fn fn, void *user) {
    void *buf;
    size_t n;
    sooc_status s = sooc_file_read_all(path, (size_t)256 << 20, &buf, &n);
    if (s) return s;
    char *p = buf, *end = p + n;
    int lineno = 0;
    while (p < end && !s) {
        char *nl = memchr(p, '\n', (size_t)(end - p));
        char *le = nl ? nl : end;
        *le = 0;
        lineno++;
        char *q = p;
        while (*q == ' ' || *q == '\t' || *q == '\r') q++;
        if (*q && *q != '#') s = fn(user, lineno, q);
        p = le + 1;
    }
    sooc_free(buf);
    return s;
}

static sooc_status check_rotation(const char *file, int line, const double R[9], double tol) {
    double err;
    for (int i = 0; i < 9; i++)
        if (!isfinite(R[i])) return sooc_seterr(SOOC_EINVAL, "%s:%d: non-finite rotation", file, line);
    if (!sooc_m3_is_rotation(R, tol, &err))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: rotation is not orthonormal (error %.3g > %.3g)", file,
                           line, err, tol);
    return SOOC_OK;
}

/* A 4x4 row-major pose from a file: rotation block orthonormal (reported at
 * line_r), last row 0 0 0 1 (reported at line_last). */
sooc_status sooc_seqi_check_pose4(const char *file, int line_r, int line_last, const double T[16], double tol) {
    double R[9], t[3];
    sooc_se3_to_rt(R, t, T);
    sooc_status s = check_rotation(file, line_r, R, tol);
    if (s) return s;
    if (fabs(T[12]) > 1e-6 || fabs(T[13]) > 1e-6 || fabs(T[14]) > 1e-6 || fabs(T[15] - 1) > 1e-6)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: last row must be 0 0 0 1", file, line_last);
    return SOOC_OK;
}

sooc_status sooc_seqi_quat_pose(const char *file, int line, char **tok, double T[16], double tol) {
    double v[7];
    for (int k = 0; k < 7; k++)
        if (!sooc_seqi_parse_double(tok[k], &v[k]))
            return sooc_seterr(SOOC_EINVAL, "%s:%d: '%s' is not a number", file, line, tok[k]);
    double qn = sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
    if (fabs(qn - 1) > tol)
        return sooc_seterr(SOOC_EINVAL,
                           "%s:%d: quaternion norm %.6g is not 1: rotation is not orthonormal", file,
                           line, qn);
    double R[9];
    sooc_quat_to_m3(R, v + 3);
    sooc_se3_from_rt(T, R, v);
    return SOOC_OK;
}

sooc_status sooc_seqi_need_file(const char *list, int line, const char *path) {
    if (!sooc_file_exists(path)) {
        if (line > 0) return sooc_seterr(SOOC_ENOTFOUND, "%s:%d: %s: missing file", list, line, path);
        return sooc_seterr(SOOC_ENOTFOUND, "%s: missing file", path);
    }
    return SOOC_OK;
}

/* <dir>/<prefix><i zero-padded to width digits><ext>; when that file does
 * not exist and alt_ext is given, the same name with alt_ext instead if that
 * one exists (else the first name, which sooc_seqi_need_file then reports). NULL if
 * out of memory or too long. */
char *sooc_seqi_frame_path(const char *dir, const char *prefix, int width, int64_t i, const char *ext,
                           const char *alt_ext) {
    char name[128];
    snprintf(name, sizeof name, "%s%0*lld%s", prefix, width, (long long)i, ext);
    char *path = sooc_seqi_join_dup(dir, name);
    if (path && alt_ext && !sooc_file_exists(path)) {
        snprintf(name, sizeof name, "%s%0*lld%s", prefix, width, (long long)i, alt_ext);
        char *alt = sooc_seqi_join_dup(dir, name);
        if (alt && sooc_file_exists(alt)) {
            sooc_free(path);
            return alt;
        }
        sooc_free(alt);
    }
    return path;
}

/* Load calibration: explicit path, else <dir>/calib.yaml. Returns
 * ENOTFOUND (without error text) when neither exists and !required. */
sooc_status sooc_seqi_load_calib(sooc_seq *s, const sooc_seq_open_params *p, int required) {
    char path[4096];
    if (p->calib_path) return sooc_calib_load(p->calib_path, &s->calib);
    sooc_status st = sooc_path_join(path, sizeof path, s->dir, "calib.yaml");
    if (st) return st;
    if (sooc_file_exists(path)) return sooc_calib_load(path, &s->calib);
    if (required)
        return sooc_seterr(SOOC_ENOTFOUND, "%s: missing file (give the intrinsics and depth_scale "
                           "in a calib YAML, or pass one with --calib)", path);
    return SOOC_ENOTFOUND;
}
