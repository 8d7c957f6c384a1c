/* The APC layout of the apc-vision-toolbox (Amazon Picking Challenge shelf
 * and tote scenes): cam.info.txt, frame-NNNNNN.{color,depth}.png with the
 * depth's 16 bits rotated, and the segmentation network's predicted masks
 * masks/frame-NNNNNN.<object>.mask.png with masks/<object>.thresh.txt;
 * docs/formats.md section 2.9. */
#include "seq_impl.h"
#include "sooc3d/core.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define APC_MAX_OBJ 64
#define APC_NAME_MAX 128

typedef struct apc_priv {
    int n_obj;
    char name[APC_MAX_OBJ][APC_NAME_MAX];
    double thr[APC_MAX_OBJ];     /* the object's threshold in confidence units (0..65535) */
    char mdir[4096];             /* <dir>/masks */
    sooc_image mask;             /* scratch: one object's confidence map */
    uint16_t *best;              /* scratch: the winning confidence per pixel */
    size_t best_n;
} apc_priv;

static void apc_free(void *p) {
    apc_priv *a = p;
    if (!a) return;
    sooc_image_free(&a->mask);
    sooc_free(a->best);
    sooc_free(a);
}

static const char *apc_label_name(const sooc_seq *s, int id) {
    const apc_priv *a = s->priv;
    return a && id >= 1 && id <= a->n_obj ? a->name[id - 1] : NULL;
}

/* ------------------------------------------------------- cam.info.txt */

typedef enum { SEC_NONE = 0, SEC_KC, SEC_KD, SEC_EXT, SEC_BIN, SEC_POSE } sec_kind;

typedef struct apc_pose {
    int64_t number;
    int line;        /* the heading's line */
    double T[16];
} apc_pose;

typedef struct cam_info {
    const char *file;
    double tol;
    /* the section being read */
    sec_kind kind;
    int head_line, rows, row_line[4];
    int64_t number;
    double v[16];
    /* results */
    int have_kc;
    double kc[9];
    int kc_line;
    apc_pose *pose;
    int n_pose, cap_pose;
    apc_priv *a;
    int have_objects;
} cam_info;

static const char *sec_name(sec_kind k) {
    switch (k) {
    case SEC_KC: return "colour camera intrinsic matrix";
    case SEC_KD: return "depth camera intrinsic matrix";
    case SEC_EXT: return "depth-to-colour extrinsic matrix";
    case SEC_BIN: return "bin-to-world matrix";
    case SEC_POSE: return "camera pose";
    default: return "?";
    }
}

static int sec_rows(sec_kind k) { return k == SEC_KC || k == SEC_KD ? 3 : 4; }

/* Case-insensitive substring. */
static const char *find_ci(const char *h, const char *n) {
    size_t m = strlen(n);
    for (; *h; h++) {
        size_t i = 0;
        while (i < m && h[i] && tolower((unsigned char)h[i]) == tolower((unsigned char)n[i])) i++;
        if (i == m) return h;
    }
    return NULL;
}

static sooc_status check_k(const char *file, int line, const double *K, const char *what) {
    if (!(K[0] > 0) || !(K[4] > 0) || K[1] != 0 || K[3] != 0 || K[6] != 0 || K[7] != 0 || K[8] != 1)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: the %s must be [fx 0 cx; 0 fy cy; 0 0 1] with fx, fy > 0", file, line,
                           what);
    return SOOC_OK;
}

/* The section just read is complete: check and keep it. */
static sooc_status sec_end(cam_info *c) {
    sec_kind k = c->kind;
    c->kind = SEC_NONE;
    if (k == SEC_NONE) return SOOC_OK;
    int want = sec_rows(k);
    if (c->rows != want)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: the %s%s has %d rows, expected %d", c->file, c->head_line,
                           sec_name(k), k == SEC_POSE ? " under this heading" : "", c->rows, want);
    if (k == SEC_KC || k == SEC_KD) {
        sooc_status st = check_k(c->file, c->row_line[0], c->v, sec_name(k));
        if (st) return st;
        if (k == SEC_KC) {
            memcpy(c->kc, c->v, sizeof c->kc);
            c->have_kc = 1;
            c->kc_line = c->head_line;
        }
        return SOOC_OK;
    }
    sooc_status st = sooc_seqi_check_pose4(c->file, c->row_line[0], c->row_line[3], c->v, c->tol);
    if (st || k != SEC_POSE) return st;
    if (c->n_pose && c->number <= c->pose[c->n_pose - 1].number)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: frame-%06lld comes after frame-%06lld: frames must increase", c->file,
                           c->head_line, (long long)c->number, (long long)c->pose[c->n_pose - 1].number);
    if (c->n_pose == c->cap_pose) {
        int cap = c->cap_pose ? 2 * c->cap_pose : 64;
        apc_pose *np = sooc_realloc(c->pose, sizeof *np * (size_t)cap);
        if (!np) return SOOC_ENOMEM;
        c->pose = np;
        c->cap_pose = cap;
    }
    apc_pose *p = &c->pose[c->n_pose++];
    p->number = c->number;
    p->line = c->head_line;
    memcpy(p->T, c->v, sizeof p->T);
    return SOOC_OK;
}

/* `# Objects: ["a","b",...]`: the names in order (id = position + 1). */
static sooc_status parse_objects(cam_info *c, int line, const char *t) {
    apc_priv *a = c->a;
    c->have_objects = 1;
    const char *q = strchr(t, '[');
    if (!q || !strchr(q, ']'))
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected '# Objects: [\"name\", ...]'", c->file, line);
    for (q = strchr(q, '"'); q; q = strchr(q, '"')) {
        const char *e = strchr(q + 1, '"');
        if (!e) return sooc_seterr(SOOC_EFORMAT, "%s:%d: unterminated object name", c->file, line);
        size_t m = (size_t)(e - q - 1);
        if (m == 0 || m >= APC_NAME_MAX || memchr(q + 1, '/', m))
            return sooc_seterr(SOOC_EINVAL, "%s:%d: object name '%.*s' is empty, has a '/' or is longer than %d "
                               "characters", c->file, line, (int)m, q + 1, APC_NAME_MAX - 1);
        if (a->n_obj == APC_MAX_OBJ)
            return sooc_seterr(SOOC_EINVAL, "%s:%d: more than %d objects", c->file, line, APC_MAX_OBJ);
        snprintf(a->name[a->n_obj++], APC_NAME_MAX, "%.*s", (int)m, q + 1);
        q = e + 1;
    }
    return SOOC_OK;
}

static sooc_status heading(cam_info *c, int line, const char *t) {
    sooc_status st = sec_end(c);
    if (st) return st;
    if (find_ci(t, "objects:") == t) return parse_objects(c, line, t + 8);
    sec_kind k = SEC_NONE;
    if (find_ci(t, "color camera intrinsic")) k = SEC_KC;
    else if (find_ci(t, "depth camera intrinsic")) k = SEC_KD;
    else if (find_ci(t, "depth-to-color")) k = SEC_EXT;
    else if (find_ci(t, "bin-to-world")) k = SEC_BIN;
    else if (find_ci(t, "camera-to-world")) {
        const char *f = find_ci(t, "frame-");
        char *end = NULL;
        long long num = f ? strtoll(f + 6, &end, 10) : -1;
        if (!f || end == f + 6 || num < 0)
            return sooc_seterr(SOOC_EFORMAT, "%s:%d: camera pose heading names no frame-NNNNNN", c->file, line);
        if (num > SOOC_SEQI_FRAME_MAX)
            return sooc_seterr(SOOC_EFORMAT, "%s:%d: frame number '%.*s' is above %lld", c->file, line,
                               (int)(end - (f + 6)), f + 6, SOOC_SEQI_FRAME_MAX);
        c->number = num;
        k = SEC_POSE;
    }
    c->kind = k;
    c->head_line = line;
    c->rows = 0;
    return SOOC_OK;
}

static sooc_status numbers(cam_info *c, int line, char *t) {
    if (c->kind == SEC_NONE)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: numbers under no known heading (expected '# Color camera intrinsic "
                           "matrix', '# Camera-to-world extrinsic matrix (camera pose) for frame-NNNNNN', ...)",
                           c->file, line);
    int want = sec_rows(c->kind);
    if (c->rows >= want)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: the %s has more than %d rows", c->file, line, sec_name(c->kind), want);
    char *tok[8];
    int nt = sooc_seqi_tokenize(t, tok, 4);
    if (nt != want)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected %d numbers (a row of the %s), got %d", c->file, line, want,
                           sec_name(c->kind), nt > 4 ? 5 : nt);
    for (int k = 0; k < nt; k++)
        if (!sooc_seqi_parse_double(tok[k], &c->v[c->rows * want + k]))
            return sooc_seterr(SOOC_EINVAL, "%s:%d: '%s' is not a finite number", c->file, line, tok[k]);
    c->row_line[c->rows++] = line;
    return SOOC_OK;
}

static sooc_status read_cam_info(cam_info *c) {
    void *buf;
    size_t n;
    sooc_status st = sooc_file_read_all(c->file, (size_t)64 << 20, &buf, &n);
    if (st) return st;
    char *p = buf, *end = p + n;
    int lineno = 0;
    while (p < end && !st) {
        char *nl = memchr(p, '\n', (size_t)(end - p));
        char *le = nl ? nl : end;
        *le = 0;
        lineno++;
        while (*p == ' ' || *p == '\t' || *p == '\r') p++;
        if (*p == '#') {
            p++;
            while (*p == ' ' || *p == '\t') p++;
            st = heading(c, lineno, p);
        } else if (*p && *p != '\r') {
            st = numbers(c, lineno, p);
        }
        p = le + 1;
    }
    if (!st) st = sec_end(c);
    sooc_free(buf);
    if (st) return st;
    if (!c->have_kc)
        return sooc_seterr(SOOC_EFORMAT, "%s: no colour camera intrinsic matrix (a '# Color camera intrinsic matrix' "
                           "heading and 3 rows)", c->file);
    if (!c->n_pose)
        return sooc_seterr(SOOC_EFORMAT, "%s: no camera pose ('# Camera-to-world extrinsic matrix (camera pose) for "
                           "frame-NNNNNN' and 4 rows)", c->file);
    return SOOC_OK;
}

/* ------------------------------------------------------------ masks */

static sooc_status read_thresh(const char *path, double *t) {
    void *buf;
    size_t n;
    sooc_status st = sooc_file_read_all(path, 4096, &buf, &n);
    if (st) return st;
    char text[4097], *tok[3];
    snprintf(text, sizeof text, "%.*s", (int)n, (const char *)buf);
    sooc_free(buf);
    for (char *q = text; *q; q++)
        if (*q == '\n') *q = ' ';
    int nt = sooc_seqi_tokenize(text, tok, 2);
    if (nt != 1 || !sooc_seqi_parse_double(tok[0], t) || *t < 0 || *t > 1)
        return sooc_seterr(SOOC_EFORMAT, "%s: expected one confidence threshold in [0, 1]", path);
    return SOOC_OK;
}

static char *mask_path(const apc_priv *a, int64_t number, int k) {
    char name[256];
    snprintf(name, sizeof name, "frame-%06lld.%s.mask.png", (long long)number, a->name[k]);
    return sooc_seqi_join_dup(a->mdir, name);
}

/* Frame i's labels: per pixel, the object whose confidence passes its
 * threshold, the most confident when several do (ties: the lower id). */
static sooc_status apc_labels(sooc_seq *s, int64_t i, uint16_t *ids, int w, int h) {
    apc_priv *a = s->priv;
    size_t np = (size_t)w * (size_t)h;
    if (a->best_n < np) {
        sooc_free(a->best);
        a->best_n = 0;
        if (!(a->best = sooc_malloc(np * sizeof *a->best))) return SOOC_ENOMEM;
        a->best_n = np;
    }
    memset(ids, 0, np * sizeof *ids);
    memset(a->best, 0, np * sizeof *a->best);
    for (int k = 0; k < a->n_obj; k++) {
        char *path = mask_path(a, s->e[i].number, k);
        if (!path) return SOOC_ENOMEM;
        sooc_status st = sooc_png_read(path, &a->mask);
        if (!st && ((a->mask.fmt != SOOC_PIX_GRAY16 && a->mask.fmt != SOOC_PIX_GRAY8) || a->mask.width != w ||
                    a->mask.height != h))
            st = sooc_seterr(SOOC_EFORMAT, "%s: mask is %s %dx%d, expected a 16-bit (or 8-bit) confidence map of %dx%d",
                             path, sooc_pixfmt_name(a->mask.fmt), a->mask.width, a->mask.height, w, h);
        sooc_free(path);
        if (st) return st;
        const int wide = a->mask.fmt == SOOC_PIX_GRAY16;
        const uint16_t *m16 = a->mask.data;
        const uint8_t *m8 = a->mask.data;
        for (size_t p = 0; p < np; p++) {
            unsigned v = wide ? m16[p] : 257u * m8[p];
            if ((double)v > a->thr[k] && v > a->best[p]) {
                a->best[p] = (uint16_t)v;
                ids[p] = (uint16_t)(k + 1);
            }
        }
    }
    return SOOC_OK;
}

/* masks/: every object's threshold, and every frame's mask file. */
static sooc_status open_masks(sooc_seq *s, const cam_info *c) {
    apc_priv *a = s->priv;
    if (!c->have_objects || a->n_obj == 0)
        return sooc_seterr(SOOC_EFORMAT, "%s: masks/ is there but no '# Objects: [...]' line names its objects",
                           c->file);
    sooc_status st = SOOC_OK;
    for (int k = 0; k < a->n_obj && !st; k++) {
        char name[256];
        snprintf(name, sizeof name, "%s.thresh.txt", a->name[k]);
        char *tp = sooc_seqi_join_dup(a->mdir, name);
        if (!tp) return SOOC_ENOMEM;
        st = sooc_seqi_need_file(c->file, c->kc_line, tp);
        double t = 0;
        if (!st) st = read_thresh(tp, &t);
        a->thr[k] = t * 65535.0;
        sooc_free(tp);
    }
    for (int64_t i = 0; i < s->n && !st; i++)
        for (int k = 0; k < a->n_obj && !st; k++) {
            char *mp = mask_path(a, s->e[i].number, k);
            if (!mp) return SOOC_ENOMEM;
            st = sooc_seqi_need_file(c->file, s->e[i].line, mp);
            sooc_free(mp);
        }
    if (st) return st;
    s->labels_fn = apc_labels;
    s->labels_predicted = 1;
    return SOOC_OK;
}

/* ---------------------------------------------------------------- open */

sooc_status sooc_seqi_open_apc(sooc_seq *s, const sooc_seq_open_params *p) {
    apc_priv *a = sooc_calloc(1, sizeof *a);
    if (!a) return SOOC_ENOMEM;
    s->priv = a;
    s->priv_free = apc_free;
    s->label_name_fn = apc_label_name;
    sooc_status st = sooc_path_join(s->srcname[0], sizeof s->srcname[0], s->dir, "cam.info.txt");
    if (!st) st = sooc_seqi_need_file(NULL, 0, s->srcname[0]);
    if (st) return st;
    cam_info c;
    memset(&c, 0, sizeof c);
    c.file = s->srcname[0];
    c.tol = p->rot_tol;
    c.a = a;
    st = read_cam_info(&c);
    for (int i = 0; i < c.n_pose && !st; i++) {
        sooc_seqi_entry *e;
        if ((st = sooc_seqi_push(s, &e))) break;
        e->rgb = sooc_seqi_frame_path(s->dir, "frame-", 6, c.pose[i].number, ".color.png", NULL);
        e->depth = sooc_seqi_frame_path(s->dir, "frame-", 6, c.pose[i].number, ".depth.png", NULL);
        if (!e->rgb || !e->depth) { st = SOOC_ENOMEM; break; }
        e->line = c.pose[i].line;
        e->src = s->srcname[0];
        e->number = c.pose[i].number;
        e->t_ns = c.pose[i].number * SOOC_SEQI_FRAME_NS; /* no timestamps in this layout: 30 Hz by frame number */
        e->has_pose = 1;
        memcpy(e->T, c.pose[i].T, sizeof e->T);
        st = sooc_seqi_need_file(c.file, e->line, e->rgb);
        if (!st) st = sooc_seqi_need_file(c.file, e->line, e->depth);
    }
    if (!st) st = sooc_path_join(a->mdir, sizeof a->mdir, s->dir, "masks");
    if (!st && sooc_dir_exists(a->mdir)) st = open_masks(s, &c);
    /* intrinsics: a calibration YAML when given, else the colour camera's
     * (the depth images are aligned to colour) */
    if (!st) {
        st = sooc_seqi_load_calib(s, p, 0);
        if (st == SOOC_ENOTFOUND) {
            int w, h;
            sooc_pixfmt fmt;
            st = sooc_image_info(s->e[0].rgb, &w, &h, &fmt);
            if (!st) sooc_calib_pinhole(&s->calib, w, h, c.kc[0], c.kc[4], c.kc[2], c.kc[5]);
        }
    }
    sooc_free(c.pose);
    return st;
}
