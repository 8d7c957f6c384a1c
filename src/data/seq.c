/* RGB-D sequences: the format-name table, detection, the TUM/synthetic and
 * 7-Scenes/label-fusion readers, and the frame read every layout shares
 * (seq_list.c: slambook2, Replica; seq_ycb.c: YCB-Video; seq_apc.c: APC;
 * seq_write.c: the synthetic writer). */
#include "sooc3d/frame.h"
#include "sooc3d/core.h"
#include "sooc3d/gen.h"
#include "seq_impl.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The one table of sequence format names (docs/formats.md §Format names).
 * The launch parser, the CLI and the replay driver read names only through
 * sooc_seq_format_parse / sooc_seq_format_name / sooc_seq_formats. Row i
 * holds the enum value i. Depth defaults apply when neither the open
 * parameters nor the calibration give a value. */
static const sooc_seq_format_info g_formats[SOOC_SEQ_FORMAT_COUNT] = {
    {SOOC_SEQ_AUTO, "auto", "", "detect the layout (and the label-fusion depth encoding) from the files", 0, 0, 65535,
     0, 0},
    {SOOC_SEQ_TUM, "tum", "sooc|tum-rgbd",
     "TUM RGB-D and the sooc3d synthetic layout: rgb.txt, depth.txt, groundtruth.txt, calib.yaml", 0, 0, 65535, 0, 0},
    {SOOC_SEQ_7SCENES, "7scenes", "sevenscenes|7-scenes",
     "Microsoft 7-Scenes: frame-NNNNNN.{color.jpg|color.png, depth.png, pose.txt}; depth mm, 65535 invalid",
     0.001, 0, 65535, 0, 0},
    {SOOC_SEQ_SLAMBOOK, "slambook", "slambook2", "slambook2: pose.txt, color/N.png, depth/N.pgm; needs a calib YAML",
     0, 0, 65535, 0, 0},
    {SOOC_SEQ_REPLICA, "replica", "nice-slam", "Replica (NICE-SLAM): traj.txt, results/frameNNNNNN.jpg, depthNNNNNN.png",
     1.0 / 6553.5, 0, 65535, 0, 0},
    {SOOC_SEQ_LABELFUSION, "label-fusion", "labelfusion|label_fusion",
     "label-fusion: the 7-Scenes layout with depth (raw >> 3) * 1e-4 m", 1e-4, 3, 0, 0, 0},
    {SOOC_SEQ_YCB, "ycb-video", "ycb|ycbv|ycb_video",
     "YCB-Video: NNNNNN-{color.png, depth.png, label.png, meta.mat}; depth 1 / factor_depth m", 0, 0, 0, 0, 0},
    {SOOC_SEQ_APC, "apc", "apc-shelf|apc_shelf",
     "APC shelf&tote: cam.info.txt, frame-NNNNNN.{color,depth}.png, masks/ (predicted); depth rotated right 3, "
     "1e-4 m", 1e-4, 3, 0, 1, 1},
};

const sooc_seq_format_info *sooc_seq_formats(int *n) {
    if (n) *n = SOOC_SEQ_FORMAT_COUNT;
    return g_formats;
}

const sooc_seq_format_info *sooc_seq_format_info_of(sooc_seq_format f) {
    return (unsigned)f < SOOC_SEQ_FORMAT_COUNT ? &g_formats[f] : NULL;
}

const char *sooc_seq_format_name(sooc_seq_format f) {
    if (f == SOOC_SEQ_SOURCE) return "source";
    return (unsigned)f < SOOC_SEQ_FORMAT_COUNT ? g_formats[f].name : "?";
}

/* Case-insensitive equality of a and the `|`-separated item [q, q+m). */
static int name_eq(const char *a, const char *q, size_t m) {
    if (strlen(a) != m) return 0;
    for (size_t i = 0; i < m; i++) {
        char x = a[i], y = q[i];
        if (x >= 'A' && x <= 'Z') x = (char)(x - 'A' + 'a');
        if (x != y) return 0;
    }
    return 1;
}

static int in_names(const char *s, const char *list) {
    while (*list) {
        const char *e = strchr(list, '|');
        size_t m = e ? (size_t)(e - list) : strlen(list);
        if (m && name_eq(s, list, m)) return 1;
        if (!e) break;
        list = e + 1;
    }
    return 0;
}

size_t sooc_seq_format_list(char *buf, size_t cap) {
    size_t n = 0;
    char tmp[1024] = "";
    for (int i = 0; i < SOOC_SEQ_FORMAT_COUNT; i++) {
        const sooc_seq_format_info *f = &g_formats[i];
        char al[256] = "";
        size_t m = 0;
        for (const char *c = f->aliases; *c && m + 3 < sizeof al; c++) {
            if (*c == '|') { al[m++] = ','; al[m++] = ' '; }
            else al[m++] = *c;
        }
        al[m] = 0;
        int k = snprintf(tmp + n, sizeof tmp - n, "%s%s%s%s%s", i ? ", " : "", f->name, al[0] ? " (" : "", al,
                         al[0] ? ")" : "");
        if (k < 0 || (size_t)k >= sizeof tmp - n) break;
        n += (size_t)k;
    }
    if (buf && cap) snprintf(buf, cap, "%s", tmp);
    return n;
}

sooc_status sooc_seq_format_parse(const char *s, sooc_seq_format *out) {
    for (int i = 0; s && i < SOOC_SEQ_FORMAT_COUNT; i++)
        if (name_eq(s, g_formats[i].name, strlen(g_formats[i].name)) || in_names(s, g_formats[i].aliases)) {
            *out = g_formats[i].format;
            return SOOC_OK;
        }
    char list[1024];
    sooc_seq_format_list(list, sizeof list);
    return sooc_seterr(SOOC_EINVAL, "unknown sequence format '%s' (one of %s)", s ? s : "", list);
}

void sooc_seq_open_params_default(sooc_seq_open_params *p) {
    memset(p, 0, sizeof *p);
    p->max_dt = 0.02;
    p->rot_tol = 1e-3;
    p->depth_shift = -1;
    p->depth_invalid = -1;
}

/* Decimal seconds -> ns without double rounding for plain decimals. */
static int parse_time_ns(const char *t, int64_t *ns) {
    const char *p = t;
    int neg = 0;
    if (*p == '-') { neg = 1; p++; }
    int64_t ip = 0, fp = 0;
    int nd = 0, fd = 0;
    while (*p >= '0' && *p <= '9') {
        if (ip > 9000000000LL) return 0;
        ip = ip * 10 + (*p++ - '0');
        nd++;
    }
    if (*p == '.') {
        p++;
        while (*p >= '0' && *p <= '9') {
            if (fd < 9) { fp = fp * 10 + (*p - '0'); fd++; }
            p++;
            nd++;
        }
    }
    if (*p || nd == 0) {
        double v;
        if (!sooc_seqi_parse_double(t, &v) || fabs(v) > 9e9) return 0;
        *ns = (int64_t)llround(v * 1e9);
        return 1;
    }
    while (fd < 9) { fp *= 10; fd++; }
    *ns = (neg ? -1 : 1) * (ip * 1000000000LL + fp);
    return 1;
}

/* ------------------------------------------------------------------ TUM */

typedef struct tlist {
    int64_t *t;
    char **path;
    int *line;
    double *T;       /* groundtruth poses (16 each) */
    int n, cap;
    const char *file, *dir;
    int is_gt;
    double tol;
} tlist;

static sooc_status tlist_line(void *user, int lineno, char *line) {
    tlist *L = user;
    char *tok[10];
    int nt = sooc_seqi_tokenize(line, tok, 9);
    int want = L->is_gt ? 8 : 2;
    if (nt != want)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected %d columns (%s), got %d", L->file, lineno, want,
                           L->is_gt ? "t tx ty tz qx qy qz qw" : "timestamp filename", nt);
    int64_t t;
    if (!parse_time_ns(tok[0], &t))
        return sooc_seterr(SOOC_EINVAL, "%s:%d: timestamp '%s' is not a number", L->file, lineno, tok[0]);
    if (L->n > 0 && t <= L->t[L->n - 1])
        return sooc_seterr(SOOC_EINVAL, "%s:%d: timestamp %s is not after the previous one (line %d): "
                           "timestamps must increase", L->file, lineno, tok[0], L->line[L->n - 1]);
    if (L->n == L->cap) {
        int cap = L->cap ? L->cap * 2 : 256;
        int64_t *nt2 = sooc_realloc(L->t, sizeof(int64_t) * (size_t)cap);
        if (!nt2) return SOOC_ENOMEM;
        L->t = nt2;
        int *nl = sooc_realloc(L->line, sizeof(int) * (size_t)cap);
        if (!nl) return SOOC_ENOMEM;
        L->line = nl;
        if (L->is_gt) {
            double *nT = sooc_realloc(L->T, sizeof(double) * 16 * (size_t)cap);
            if (!nT) return SOOC_ENOMEM;
            L->T = nT;
        } else {
            char **np = sooc_realloc(L->path, sizeof(char *) * (size_t)cap);
            if (!np) return SOOC_ENOMEM;
            L->path = np;
        }
        L->cap = cap;
    }
    if (L->is_gt) {
        sooc_status s = sooc_seqi_quat_pose(L->file, lineno, tok + 1, L->T + 16 * L->n, L->tol);
        if (s) return s;
    } else {
        char *full = sooc_seqi_join_dup(L->dir, tok[1]);
        if (!full) return sooc_seterr(SOOC_ENOMEM, "%s:%d: path too long", L->file, lineno);
        sooc_status s = sooc_seqi_need_file(L->file, lineno, full);
        if (s) { sooc_free(full); return s; }
        L->path[L->n] = full;
    }
    L->t[L->n] = t;
    L->line[L->n] = lineno;
    L->n++;
    return SOOC_OK;
}

static void tlist_free(tlist *L) {
    for (int i = 0; L->path && i < L->n; i++) sooc_free(L->path[i]);
    sooc_free(L->path);
    sooc_free(L->t);
    sooc_free(L->line);
    sooc_free(L->T);
    memset(L, 0, sizeof *L);
}

static int nearest(const int64_t *t, int n, int64_t x) {
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (t[mid] < x) lo = mid + 1;
        else hi = mid;
    }
    int best = -1;
    int64_t bd = INT64_MAX;
    for (int k = lo - 1; k <= lo; k++)
        if (k >= 0 && k < n) {
            int64_t d = t[k] > x ? t[k] - x : x - t[k];
            if (d < bd) { bd = d; best = k; }
        }
    return best;
}

static sooc_status open_tum(sooc_seq *s, const sooc_seq_open_params *p) {
    tlist L[3];
    memset(L, 0, sizeof L);
    static const char *names[3] = {"rgb.txt", "depth.txt", "groundtruth.txt"};
    char files[3][4096];
    sooc_status st = SOOC_OK;
    for (int k = 0; k < 3 && !st; k++) {
        st = sooc_path_join(files[k], sizeof files[k], s->dir, names[k]);
        if (st) break;
        if (!sooc_file_exists(files[k])) { st = sooc_seterr(SOOC_ENOTFOUND, "%s: missing file", files[k]); break; }
        L[k].file = files[k];
        L[k].dir = s->dir;
        L[k].is_gt = k == 2;
        L[k].tol = p->rot_tol;
        st = sooc_seqi_for_lines(files[k], tlist_line, &L[k]);
        if (!st && L[k].n == 0 && k < 2) st = sooc_seterr(SOOC_EFORMAT, "%s: no entries", files[k]);
    }
    if (!st) st = sooc_seqi_load_calib(s, p, 1);
    snprintf(s->srcname[0], sizeof s->srcname[0], "%s", files[0]);
    snprintf(s->srcname[1], sizeof s->srcname[1], "%s", files[1]);
    int64_t tol = (int64_t)llround(p->max_dt * 1e9);
    char idir[4096] = "";
    int have_inst = 0;
    if (!st) {
        st = sooc_path_join(idir, sizeof idir, s->dir, "instance");
        have_inst = !st && sooc_dir_exists(idir);
    }
    for (int i = 0; i < L[0].n && !st; i++) {
        int jd = nearest(L[1].t, L[1].n, L[0].t[i]);
        int64_t dd = jd < 0 ? INT64_MAX : llabs(L[1].t[jd] - L[0].t[i]);
        if (dd > tol) { s->dropped++; continue; }
        sooc_seqi_entry *e;
        st = sooc_seqi_push(s, &e);
        if (st) break;
        e->rgb = L[0].path[i];
        L[0].path[i] = NULL;
        e->depth = sooc_strdup(L[1].path[jd]);
        e->t_ns = L[0].t[i];
        e->number = s->n - 1;
        e->line = L[0].line[i];
        e->src = s->srcname[0];
        int jp = nearest(L[2].t, L[2].n, L[0].t[i]);
        if (jp >= 0 && llabs(L[2].t[jp] - L[0].t[i]) <= tol) {
            e->has_pose = 1;
            memcpy(e->T, L[2].T + 16 * jp, sizeof e->T);
        }
        if (have_inst) {
            const char *base = strrchr(e->rgb, '/');
            e->inst = sooc_seqi_join_dup(idir, base ? base + 1 : e->rgb);
            if (!e->inst) { st = SOOC_ENOMEM; break; }
            st = sooc_seqi_need_file(s->srcname[0], e->line, e->inst);
        }
        if (!e->depth) st = SOOC_ENOMEM;
    }
    if (!st && s->n == 0)
        st = sooc_seterr(SOOC_EFORMAT, "%s: no rgb frame has a depth frame within %.3f s", files[0], p->max_dt);
    /* scene.yaml: mark query views (synthetic layout) */
    char spath[4096];
    if (!st && !sooc_path_join(spath, sizeof spath, s->dir, "scene.yaml") && sooc_file_exists(spath)) {
        sooc_scene sc;
        sooc_scene_init(&sc);
        st = sooc_scene_load(spath, &sc);
        if (!st && sc.n_views != s->n)
            st = sooc_seterr(SOOC_EINVAL, "%s: lists %d views but the sequence has %lld frames", spath,
                             sc.n_views, (long long)s->n);
        for (int64_t i = 0; !st && i < s->n; i++) s->e[i].is_query = sc.view_is_query[i];
        sooc_scene_free(&sc);
    }
    for (int k = 0; k < 3; k++) tlist_free(&L[k]);
    return st;
}

/* ------------------------------------------------------------- 7-Scenes */

typedef struct mat_ctx {
    double v[16];
    int rows;
    const char *file;
    int lines[4];
    int ncols;
} mat_ctx;

static sooc_status mat_line(void *user, int lineno, char *line) {
    mat_ctx *m = user;
    char *tok[20];
    int nt = sooc_seqi_tokenize(line, tok, 16);
    if (m->rows >= 4 || (m->rows >= 1 && m->ncols == 3 && m->rows >= 3))
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: too many rows", m->file, lineno);
    if (nt != m->ncols)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected %d numbers, got %d", m->file, lineno, m->ncols, nt);
    for (int k = 0; k < nt; k++)
        if (!sooc_seqi_parse_double(tok[k], &m->v[m->rows * m->ncols + k]))
            return sooc_seterr(SOOC_EINVAL, "%s:%d: '%s' is not a finite number", m->file, lineno, tok[k]);
    m->lines[m->rows] = lineno;
    m->rows++;
    return SOOC_OK;
}

static sooc_status read_pose4(const char *file, double T[16], double tol) {
    mat_ctx m;
    memset(&m, 0, sizeof m);
    m.file = file;
    m.ncols = 4;
    sooc_status s = sooc_seqi_for_lines(file, mat_line, &m);
    if (s) return s;
    if (m.rows != 4) return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected 4 rows of 4 numbers, got %d", file, m.rows ? m.lines[m.rows - 1] : 1, m.rows);
    memcpy(T, m.v, sizeof m.v);
    s = sooc_seqi_check_pose4(file, m.lines[0], m.lines[3], T, tol);
    if (s) return s;
    T[12] = T[13] = T[14] = 0;
    T[15] = 1;
    return SOOC_OK;
}

/* A 7-Scenes colour file name: frame-<digits>.color.{png,jpg,jpeg} (any
 * case of the extension). Returns the number, or -1. */
static int64_t scenes_color_number(const char *name, int *ext) {
    if (strncmp(name, "frame-", 6)) return -1;
    const char *p = name + 6;
    int64_t k = 0;
    int nd = 0;
    while (*p >= '0' && *p <= '9') {
        if (nd >= SOOC_SEQI_FRAME_DIGITS) return -1;
        k = k * 10 + (*p++ - '0');
        nd++;
    }
    if (nd == 0 || strncmp(p, ".color.", 7)) return -1;
    p += 7;
    static const char *exts[] = {"png", "jpg", "jpeg"};
    for (int e = 0; e < 3; e++) {
        size_t m = strlen(exts[e]);
        if (strlen(p) != m) continue;
        int eq = 1;
        for (size_t i = 0; i < m; i++) {
            char c = p[i];
            if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
            if (c != exts[e][i]) eq = 0;
        }
        if (eq) {
            *ext = e;
            return k;
        }
    }
    return -1;
}

typedef struct scenes_file {
    int64_t number;
    int ext;
    char name[256];
} scenes_file;

static int cmp_scenes(const void *a, const void *b) {
    const scenes_file *x = a, *y = b;
    if (x->number != y->number) return x->number < y->number ? -1 : 1;
    return x->ext - y->ext; /* png before jpg for the same number */
}

/* Scan dir for frame-NNNNNN.color.*: a sorted list (caller frees). */
static sooc_status scenes_scan(const char *dir, scenes_file **out, int *nout) {
    *out = NULL;
    *nout = 0;
    DIR *d = opendir(dir);
    if (!d) return sooc_seterr(SOOC_ENOTFOUND, "%s: cannot open directory", dir);
    scenes_file *f = NULL;
    int n = 0, cap = 0;
    struct dirent *de;
    sooc_status st = SOOC_OK;
    while ((de = readdir(d))) {
        int ext = 0;
        int64_t k = scenes_color_number(de->d_name, &ext);
        if (k < 0 || strlen(de->d_name) >= sizeof f->name) continue;
        if (n == cap) {
            cap = cap ? cap * 2 : 256;
            scenes_file *nf = sooc_realloc(f, sizeof *f * (size_t)cap);
            if (!nf) { st = SOOC_ENOMEM; break; }
            f = nf;
        }
        f[n].number = k;
        f[n].ext = ext;
        snprintf(f[n].name, sizeof f[n].name, "%s", de->d_name);
        n++;
    }
    closedir(d);
    if (st) { sooc_free(f); return st; }
    if (n) qsort(f, (size_t)n, sizeof *f, cmp_scenes);
    /* the same number twice (frame-7.color.png and frame-000007.color.jpg):
     * keep the first after sorting, drop the rest */
    int m = 0;
    for (int i = 0; i < n; i++)
        if (m == 0 || f[m - 1].number != f[i].number) f[m++] = f[i];
    *out = f;
    *nout = m;
    return SOOC_OK;
}

/* Label-fusion stores depth << 3: nearly every nonzero sample is a multiple
 * of 8 (99.1% on the shipped frames), against ~1/8 for millimetre data. */
static int depth_looks_shifted(const char *path) {
    sooc_image img = {0};
    if (sooc_image_read(path, &img) || img.fmt != SOOC_PIX_GRAY16) { sooc_image_free(&img); return 0; }
    const uint16_t *d = img.data;
    size_t np = (size_t)img.width * (size_t)img.height, nz = 0, m8 = 0;
    for (size_t k = 0; k < np; k++)
        if (d[k]) { nz++; m8 += (d[k] & 7) == 0; }
    sooc_image_free(&img);
    return nz >= 64 && m8 >= nz * 95 / 100;
}

/* A 3x3 intrinsics text file -> a pinhole calib of size w x h. */
static sooc_status read_intrinsics_txt(sooc_seq *s, const char *kpath, int w, int h) {
    mat_ctx m;
    memset(&m, 0, sizeof m);
    m.file = kpath;
    m.ncols = 3;
    sooc_status st = sooc_seqi_for_lines(kpath, mat_line, &m);
    if (st) return st;
    if (m.rows != 3) return sooc_seterr(SOOC_EFORMAT, "%s: expected a 3x3 matrix, got %d rows", kpath, m.rows);
    if (m.v[0] == 0 || m.v[4] == 0 || m.v[1] != 0 || m.v[3] != 0 || m.v[6] != 0 || m.v[7] != 0 || m.v[8] != 1)
        return sooc_seterr(SOOC_EINVAL, "%s:%d: expected [fx 0 cx; 0 fy cy; 0 0 1]", kpath, m.lines[0]);
    sooc_calib_pinhole(&s->calib, w, h, m.v[0], m.v[4], m.v[2], m.v[5]);
    return SOOC_OK;
}

static sooc_status open_7scenes(sooc_seq *s, const sooc_seq_open_params *p) {
    scenes_file *fl = NULL;
    int n = 0;
    sooc_status st = scenes_scan(s->dir, &fl, &n);
    if (!st && n == 0)
        st = sooc_seterr(SOOC_ENOTFOUND, "%s: no frames (expected frame-NNNNNN.color.jpg or .color.png)", s->dir);
    for (int i = 0; i < n && !st; i++) {
        sooc_seqi_entry *e;
        st = sooc_seqi_push(s, &e);
        if (st) break;
        e->rgb = sooc_seqi_join_dup(s->dir, fl[i].name);
        e->depth = sooc_seqi_frame_path(s->dir, "frame-", 6, fl[i].number, ".depth.png", NULL);
        char *pose = sooc_seqi_frame_path(s->dir, "frame-", 6, fl[i].number, ".pose.txt", NULL);
        if (!e->rgb || !e->depth || !pose) { sooc_free(pose); st = SOOC_ENOMEM; break; }
        st = p->keep_bad_frames ? SOOC_OK : sooc_seqi_need_file(NULL, 0, e->depth);   /* kept: reading fails */
        if (!st) st = sooc_seqi_need_file(NULL, 0, pose);
        if (!st) st = read_pose4(pose, e->T, p->rot_tol);
        sooc_free(pose);
        if (st && st != SOOC_ENOMEM && p->keep_bad_frames) {   /* this frame fails when read, the others go on */
            if (!(e->pose_err = sooc_strdup(sooc_errmsg()))) { st = SOOC_ENOMEM; break; }
            sooc_clearerr();
            st = SOOC_OK;
        }
        e->has_pose = !e->pose_err;
        e->number = fl[i].number;
        e->t_ns = fl[i].number * SOOC_SEQI_FRAME_NS; /* no timestamps in this layout: 30 Hz by frame number */
    }
    sooc_free(fl);
    if (st) return st;
    if (p->format == SOOC_SEQ_AUTO && depth_looks_shifted(s->e[0].depth)) {
        s->fmt = SOOC_SEQ_LABELFUSION;
        sooc_log(SOOC_LOG_INFO, "%s: depth samples are multiples of 8: reading as label-fusion "
                 "((raw >> 3) * 1e-4 m; give format 7scenes to override)", s->dir);
    }
    st = sooc_seqi_load_calib(s, p, 0);
    if (st != SOOC_ENOTFOUND) return st;
    int w, h;
    sooc_pixfmt fmt;
    st = sooc_image_info(s->e[0].rgb, &w, &h, &fmt);
    if (st) return st;
    static const char *knames[] = {"camera-intrinsics.color.txt", "camera-intrinsics.txt"};
    for (int k = 0; k < 2; k++) {
        char kpath[4096];
        st = sooc_path_join(kpath, sizeof kpath, s->dir, knames[k]);
        if (st) return st;
        if (sooc_file_exists(kpath)) return read_intrinsics_txt(s, kpath, w, h);
    }
    /* 7-Scenes published intrinsics (Kinect v1, 640x480) */
    sooc_calib_pinhole(&s->calib, w, h, 585.0 * w / 640.0, 585.0 * h / 480.0, w / 2.0, h / 2.0);
    sooc_log(SOOC_LOG_WARN, "%s: no calib.yaml or camera-intrinsics(.color).txt: using the 7-Scenes intrinsics f=585",
             s->dir);
    return SOOC_OK;
}


/* gravity-direction.txt (7-Scenes): three numbers, the direction of gravity
 * in the world frame. Absent -> no gravity; malformed -> error. */
typedef struct grav_ctx {
    double v[3];
    int n;
    const char *file;
} grav_ctx;

static sooc_status grav_line(void *user, int lineno, char *line) {
    grav_ctx *g = user;
    char *tok[4];
    int nt = sooc_seqi_tokenize(line, tok, 3);
    for (int k = 0; k < nt; k++) {
        if (g->n >= 3 || nt > 3)
            return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected 3 numbers (gravity x y z), got more", g->file, lineno);
        if (!sooc_seqi_parse_double(tok[k], &g->v[g->n]))
            return sooc_seterr(SOOC_EFORMAT, "%s:%d: '%s' is not a finite number", g->file, lineno, tok[k]);
        g->n++;
    }
    return SOOC_OK;
}

static sooc_status load_gravity(sooc_seq *s) {
    char path[4096];
    sooc_status st = sooc_path_join(path, sizeof path, s->dir, "gravity-direction.txt");
    if (st || !sooc_file_exists(path)) return st;
    grav_ctx g;
    memset(&g, 0, sizeof g);
    g.file = path;
    st = sooc_seqi_for_lines(path, grav_line, &g);
    if (st) return st;
    if (g.n != 3) return sooc_seterr(SOOC_EFORMAT, "%s: expected 3 numbers (gravity x y z), got %d", path, g.n);
    double nrm = sqrt(g.v[0] * g.v[0] + g.v[1] * g.v[1] + g.v[2] * g.v[2]);
    if (!(nrm > 1e-9)) return sooc_seterr(SOOC_EINVAL, "%s: gravity direction has zero length", path);
    for (int k = 0; k < 3; k++) s->gravity[k] = g.v[k] / nrm;
    s->has_gravity = 1;
    return SOOC_OK;
}

int sooc_seq_gravity(const sooc_seq *s, double g[3]) {
    if (!s || !s->has_gravity) return 0;
    for (int k = 0; k < 3; k++) g[k] = s->gravity[k];
    if (s->flip_y) g[1] = -g[1]; /* the world y axis was mirrored with the poses */
    return 1;
}

/* ----------------------------------------------------------------- open */

static sooc_seq_format detect(const char *dir) {
    char p[4096];
    if (!sooc_path_join(p, sizeof p, dir, "rgb.txt") && sooc_file_exists(p)) return SOOC_SEQ_TUM;
    if (!sooc_path_join(p, sizeof p, dir, "traj.txt") && sooc_file_exists(p)) return SOOC_SEQ_REPLICA;
    if (!sooc_path_join(p, sizeof p, dir, "pose.txt") && sooc_file_exists(p)) return SOOC_SEQ_SLAMBOOK;
    if (!sooc_path_join(p, sizeof p, dir, "cam.info.txt") && sooc_file_exists(p)) return SOOC_SEQ_APC;
    sooc_seq_format f = SOOC_SEQ_AUTO;
    DIR *d = opendir(dir);
    if (d) {
        struct dirent *de;
        int ext;
        while (f == SOOC_SEQ_AUTO && (de = readdir(d))) {
            if (scenes_color_number(de->d_name, &ext) >= 0) f = SOOC_SEQ_7SCENES;
            else if (sooc_seqi_ycb_color_number(de->d_name) >= 0) f = SOOC_SEQ_YCB;
        }
        closedir(d);
    }
    return f;
}

sooc_status sooc_seq_open(sooc_seq **out, const char *dir, const sooc_seq_open_params *pp) {
    *out = NULL;
    sooc_seq_open_params p;
    if (pp) p = *pp;
    else sooc_seq_open_params_default(&p);
    if (!(p.max_dt > 0)) p.max_dt = 0.02;
    if (!(p.rot_tol > 0)) p.rot_tol = 1e-3;
    if (!sooc_dir_exists(dir)) return sooc_seterr(SOOC_ENOTFOUND, "%s: missing directory", dir);
    sooc_seq *s = sooc_calloc(1, sizeof *s);
    if (!s) return SOOC_ENOMEM;
    if (strlen(dir) >= sizeof s->dir) { sooc_free(s); return sooc_seterr(SOOC_EINVAL, "%s: path too long", dir); }
    snprintf(s->dir, sizeof s->dir, "%s", dir);
    sooc_calib_init(&s->calib);
    s->fmt = p.format == SOOC_SEQ_AUTO ? detect(dir) : p.format;
    sooc_status st;
    switch (s->fmt) {
    case SOOC_SEQ_TUM: st = open_tum(s, &p); break;
    case SOOC_SEQ_7SCENES:
    case SOOC_SEQ_LABELFUSION: st = open_7scenes(s, &p); break;
    case SOOC_SEQ_SLAMBOOK: st = sooc_seqi_open_slambook(s, &p); break;
    case SOOC_SEQ_REPLICA: st = sooc_seqi_open_replica(s, &p); break;
    case SOOC_SEQ_YCB: st = sooc_seqi_open_ycb(s, &p); break;
    case SOOC_SEQ_APC: st = sooc_seqi_open_apc(s, &p); break;
    default:
        st = sooc_seterr(SOOC_ENOTFOUND, "%s: no sequence found (need rgb.txt, traj.txt, pose.txt, cam.info.txt, "
                         "frame-NNNNNN.color.jpg/.png or NNNNNN-color.png)", dir);
    }
    if (!st) st = load_gravity(s);
    if (!st) {
        /* depth decoding: open parameters, else calibration, else the format's default */
        const sooc_seq_format_info *fi = sooc_seq_format_info_of(s->fmt);
        s->depth_scale = p.depth_scale > 0 ? p.depth_scale
                         : s->calib.depth_scale > 0 ? s->calib.depth_scale : fi->depth_scale;
        if (!(s->depth_scale > 0))
            st = sooc_seterr(SOOC_EINVAL, "%s: depth_scale: missing in the calibration (metres per depth unit)",
                             p.calib_path ? p.calib_path : dir);
        s->depth_shift = p.depth_shift >= 0 ? p.depth_shift
                         : s->calib.depth_shift >= 0 ? s->calib.depth_shift : fi->depth_shift;
        s->depth_invalid = p.depth_invalid >= 0 ? p.depth_invalid
                           : s->calib.depth_invalid >= 0 ? s->calib.depth_invalid : fi->depth_invalid;
        s->depth_circular = fi->depth_circular;
        if (!st && (s->depth_shift > 15 || s->depth_invalid > 65535))
            st = sooc_seterr(SOOC_EINVAL, "%s: depth_shift %d / depth_invalid %d out of range ([0, 15] / [0, 65535])",
                             dir, s->depth_shift, s->depth_invalid);
        s->max_depth = p.max_depth;
        if (s->calib.K.fy < 0) {
            s->flip_y = 1;
            s->calib.K.fy = -s->calib.K.fy;
        }
        if (s->calib.K.fx < 0)
            st = sooc_seterr(SOOC_EINVAL, "%s: fx < 0 is not supported", dir);
    }
    if (st) { sooc_seq_close(s); return st; }
    *out = s;
    return SOOC_OK;
}

int64_t sooc_seq_count(const sooc_seq *s) { return s ? s->n : 0; }
sooc_seq_format sooc_seq_get_format(const sooc_seq *s) { return s->fmt; }

int64_t sooc_seq_frame_number(const sooc_seq *s, int64_t i) {
    return s && i >= 0 && i < s->n ? s->e[i].number : -1;
}

int64_t sooc_seq_frame_time(const sooc_seq *s, int64_t i) {
    return s && i >= 0 && i < s->n ? s->e[i].t_ns : INT64_MIN;
}

const char *sooc_seq_color_path(const sooc_seq *s, int64_t i) {
    return s && i >= 0 && i < s->n ? s->e[i].rgb : NULL;
}

const char *sooc_seq_depth_path(const sooc_seq *s, int64_t i) {
    return s && i >= 0 && i < s->n ? s->e[i].depth : NULL;
}

void sooc_seq_depth_decoding(const sooc_seq *s, double *scale, int *shift, int *invalid) {
    if (scale) *scale = s->depth_scale;
    if (shift) *shift = s->depth_shift;
    if (invalid) *invalid = s->depth_invalid;
}
int sooc_seq_pose_bad(const sooc_seq *s, int64_t i) { return s && i >= 0 && i < s->n && s->e[i].pose_err; }
int sooc_seq_depth_circular(const sooc_seq *s) { return s ? s->depth_circular : 0; }
int sooc_seq_has_labels(const sooc_seq *s) { return s && (s->labels_fn || (s->n > 0 && s->e[0].inst)); }
int sooc_seq_labels_predicted(const sooc_seq *s) { return sooc_seq_has_labels(s) ? s->labels_predicted : 0; }
const char *sooc_seq_label_name(const sooc_seq *s, int id) {
    return s && s->label_name_fn ? s->label_name_fn(s, id) : NULL;
}
const sooc_calib *sooc_seq_calib(const sooc_seq *s) { return &s->calib; }


/* "<list>:<line>: " context for per-frame messages. */
static void ctx_of(const sooc_seqi_entry *e, char *buf, size_t n) {
    if (e->src && e->line > 0) snprintf(buf, n, "%s:%d: ", e->src, e->line);
    else buf[0] = 0;
}

sooc_status sooc_seq_read(sooc_seq *s, int64_t i, sooc_frame *f) {
    if (!s || i < 0 || i >= s->n)
        return sooc_seterr(SOOC_EINVAL, "seq read: frame %lld out of range [0, %lld)", (long long)i,
                           (long long)(s ? s->n : 0));
    if (s->source_read) return sooc_seqi_source_read(s, i, f);
    const sooc_seqi_entry *e = &s->e[i];
    if (e->pose_err) return sooc_seterr(SOOC_EFORMAT, "%s", e->pose_err);
    char ctx[4400];
    ctx_of(e, ctx, sizeof ctx);
    sooc_status st = sooc_image_read(e->rgb, &s->img_rgb);
    if (st) return sooc_adderr(st, "%s", ctx[0] ? ctx : "seq");
    if (s->img_rgb.fmt != SOOC_PIX_RGB8)
        return sooc_seterr(SOOC_EFORMAT, "%s%s: colour image is %s, expected 8-bit RGB", ctx, e->rgb,
                           sooc_pixfmt_name(s->img_rgb.fmt));
    st = sooc_image_read(e->depth, &s->img_depth);
    if (st) return sooc_adderr(st, "%s", ctx[0] ? ctx : "seq");
    if (s->img_depth.fmt != SOOC_PIX_GRAY16)
        return sooc_seterr(SOOC_EFORMAT, "%s%s: depth image is %s, expected 16-bit single channel", ctx,
                           e->depth, sooc_pixfmt_name(s->img_depth.fmt));
    int W = s->img_rgb.width, H = s->img_rgb.height;
    if (s->img_depth.width != W || s->img_depth.height != H)
        return sooc_seterr(SOOC_EFORMAT, "%s%s: depth is %dx%d but colour %s is %dx%d", ctx, e->depth,
                           s->img_depth.width, s->img_depth.height, e->rgb, W, H);
    if (W != s->calib.K.width || H != s->calib.K.height)
        return sooc_seterr(SOOC_EFORMAT, "%s%s: image is %dx%d but the calibration says %dx%d", ctx, e->rgb,
                           W, H, s->calib.K.width, s->calib.K.height);
    int with_inst = e->inst != NULL || s->labels_fn != NULL;
    if (e->inst) {   /* 16-bit ids, or 8-bit (YCB-Video class indices) */
        st = sooc_png_read(e->inst, &s->img_inst);
        if (st) return sooc_adderr(st, "%s", ctx[0] ? ctx : "seq");
        if ((s->img_inst.fmt != SOOC_PIX_GRAY16 && s->img_inst.fmt != SOOC_PIX_GRAY8) || s->img_inst.width != W ||
            s->img_inst.height != H)
            return sooc_seterr(SOOC_EFORMAT, "%s%s: instance image is %s %dx%d, expected 8- or 16-bit %dx%d", ctx,
                               e->inst, sooc_pixfmt_name(s->img_inst.fmt), s->img_inst.width, s->img_inst.height, W, H);
    }
    if (!f->rgb || f->width != W || f->height != H || (with_inst != (f->instance != NULL))) {
        sooc_frame_free(f);
        st = sooc_frame_alloc(f, W, H, with_inst);
        if (st) return st;
    }
    size_t np = (size_t)W * (size_t)H;
    memcpy(f->rgb, s->img_rgb.data, np * 3);
    const uint16_t *dr = s->img_depth.data;
    const int inv = s->depth_invalid > 0 ? s->depth_invalid : -1, sh = s->depth_shift;
    const int rot = s->depth_circular && sh > 0;
    for (size_t k = 0; k < np; k++) {
        uint16_t raw = dr[k];
        unsigned v = rot ? ((unsigned)(raw >> sh) | ((unsigned)raw << (16 - sh))) & 0xffffu : (unsigned)(raw >> sh);
        float z = raw == 0 || raw == inv ? 0.0f : (float)((double)v * s->depth_scale);
        if (s->max_depth > 0 && z > s->max_depth) z = 0;
        f->depth[k] = z;
        f->valid[k] = z > 0;
    }
    if (e->inst && s->img_inst.fmt == SOOC_PIX_GRAY16) memcpy(f->instance, s->img_inst.data, np * sizeof(uint16_t));
    else if (e->inst)
        for (size_t k = 0; k < np; k++) f->instance[k] = ((const uint8_t *)s->img_inst.data)[k];
    else if (s->labels_fn && (st = s->labels_fn(s, i, f->instance, W, H))) return st;
    f->t_ns = e->t_ns;
    f->has_pose = e->has_pose;
    memcpy(f->T_wc, e->T, sizeof f->T_wc);
    if (s->flip_y && e->has_pose) {
        /* T' = S T S, S = diag(1, -1, 1, 1): negate entries with exactly one index equal to 1 */
        for (int r = 0; r < 4; r++)
            for (int c = 0; c < 4; c++)
                if ((r == 1) != (c == 1)) f->T_wc[4 * r + c] = -f->T_wc[4 * r + c];
    }
    f->K = s->calib.K;
    f->index = e->number;
    f->is_query = e->is_query;
    return SOOC_OK;
}
