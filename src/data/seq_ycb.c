/* YCB-Video as shipped (the layout of PoseCNN, DenseFusion and BOP's YCB-V):
 * NNNNNN-color.png, NNNNNN-depth.png, NNNNNN-label.png and NNNNNN-meta.mat
 * (MATLAB v5, read with libmatio); docs/formats.md section 2.8. */
#include "seq_impl.h"
#include "sooc3d/core.h"

#include <dirent.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <matio.h>

/* The 21 YCB-Video classes; label value k (1..21) is class k - 1 here
 * (the dataset's classes.txt). */
static const char *const k_ycb_classes[21] = {
    "002_master_chef_can", "003_cracker_box",   "004_sugar_box",       "005_tomato_soup_can", "006_mustard_bottle",
    "007_tuna_fish_can",   "008_pudding_box",   "009_gelatin_box",     "010_potted_meat_can", "011_banana",
    "019_pitcher_base",    "021_bleach_cleanser", "024_bowl",          "025_mug",             "035_power_drill",
    "036_wood_block",      "037_scissors",      "040_large_marker",    "051_large_clamp",     "052_extra_large_clamp",
    "061_foam_brick"};

static const char *ycb_label_name(const sooc_seq *s, int id) {
    (void)s;
    return id >= 1 && id <= 21 ? k_ycb_classes[id - 1] : NULL;
}

/* ------------------------------------------------------------- libmatio */

/* libmatio reports problems (a truncated file reads as garbage plus a
 * warning) through one process-wide log callback. The callback keeps the
 * calling thread's first message, so every read below can check that none
 * came and put it into its own error message; nothing is printed. */
static _Thread_local char t_mat_msg[256];
static _Thread_local int t_mat_n;
static pthread_once_t g_mat_once = PTHREAD_ONCE_INIT;

static void mat_log(int level, char *msg) {
    if (!(level & (MATIO_LOG_LEVEL_ERROR | MATIO_LOG_LEVEL_CRITICAL | MATIO_LOG_LEVEL_WARNING))) return;
    if (!t_mat_n++) {
        snprintf(t_mat_msg, sizeof t_mat_msg, "%s", msg ? msg : "");
        size_t n = strlen(t_mat_msg);
        while (n && (t_mat_msg[n - 1] == '\n' || t_mat_msg[n - 1] == '\r')) t_mat_msg[--n] = 0;
    }
}

static void mat_log_init(void) { Mat_LogInitFunc("sooc3d", mat_log); }

static void mat_msg_clear(void) {
    t_mat_n = 0;
    t_mat_msg[0] = 0;
}

/* The 128-byte header of a MATLAB v5 file: text, subsystem offset, version
 * 0x0100 and the endian indicator "IM" / "MI" (MAT-File Format, p. 1-6). */
static sooc_status mat_check_header(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return sooc_seterr(SOOC_EIO, "%s: cannot open", path);
    unsigned char h[128];
    size_t n = fread(h, 1, sizeof h, f);
    fclose(f);
    if (n < sizeof h)
        return sooc_seterr(SOOC_EFORMAT, "%s: truncated MAT-file: %zu bytes, the header alone is 128", path, n);
    int le = h[126] == 'I' && h[127] == 'M', be = h[126] == 'M' && h[127] == 'I';
    if (!le && !be) return sooc_seterr(SOOC_EFORMAT, "%s: not a MATLAB v5 MAT-file (no endian indicator)", path);
    unsigned ver = le ? (unsigned)h[124] | (unsigned)h[125] << 8 : (unsigned)h[125] | (unsigned)h[124] << 8;
    if (ver == 0x0200)
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: MATLAB v7.3 (HDF5) MAT-file; YCB-Video's meta.mat is v5 "
                           "(save with -v7)", path);
    if (ver != 0x0100) return sooc_seterr(SOOC_EFORMAT, "%s: MAT-file version 0x%04x, expected v5 (0x0100)", path, ver);
    return SOOC_OK;
}

static int mat_value(const matvar_t *v, size_t k, double *out) {
    const void *d = v->data;
    switch (v->class_type) {
    case MAT_C_DOUBLE: *out = ((const double *)d)[k]; return 1;
    case MAT_C_SINGLE: *out = ((const float *)d)[k]; return 1;
    case MAT_C_INT8: *out = ((const int8_t *)d)[k]; return 1;
    case MAT_C_UINT8: *out = ((const uint8_t *)d)[k]; return 1;
    case MAT_C_INT16: *out = ((const int16_t *)d)[k]; return 1;
    case MAT_C_UINT16: *out = ((const uint16_t *)d)[k]; return 1;
    case MAT_C_INT32: *out = ((const int32_t *)d)[k]; return 1;
    case MAT_C_UINT32: *out = ((const uint32_t *)d)[k]; return 1;
    case MAT_C_INT64: *out = (double)((const int64_t *)d)[k]; return 1;
    case MAT_C_UINT64: *out = (double)((const uint64_t *)d)[k]; return 1;
    default: return 0;
    }
}

/* Variable `key` of m as a rows x cols real matrix, row-major in out. */
static sooc_status mat_get(mat_t *m, const char *path, const char *key, int rows, int cols, double *out) {
    mat_msg_clear();
    matvar_t *v = Mat_VarRead(m, key);
    sooc_status st = SOOC_OK;
    if (t_mat_n)
        st = sooc_seterr(SOOC_EFORMAT, "%s: truncated or corrupt MAT-file while reading '%s' (libmatio: %s)", path,
                         key, t_mat_msg);
    else if (!v)
        st = sooc_seterr(SOOC_ENOTFOUND, "%s: missing key '%s' (a YCB-Video meta.mat holds intrinsic_matrix, "
                         "factor_depth and rotation_translation_matrix)", path, key);
    else if (v->rank != 2 || v->dims[0] != (size_t)rows || v->dims[1] != (size_t)cols || v->isComplex || !v->data)
        st = sooc_seterr(SOOC_EFORMAT, "%s: '%s' is %s%dx%d, expected a real %dx%d matrix", path, key,
                         v->isComplex ? "complex " : "", v->rank >= 1 ? (int)v->dims[0] : 0,
                         v->rank >= 2 ? (int)v->dims[1] : 0, rows, cols);
    for (int r = 0; r < rows && !st; r++)
        for (int c = 0; c < cols && !st; c++) {
            double x;
            if (!mat_value(v, (size_t)r + (size_t)rows * (size_t)c, &x)) /* column-major */
                st = sooc_seterr(SOOC_EFORMAT, "%s: '%s' is not numeric (matio class %d)", path, key,
                                 (int)v->class_type);
            else if (!isfinite(x))
                st = sooc_seterr(SOOC_EINVAL, "%s: '%s'(%d,%d) is not finite", path, key, r + 1, c + 1);
            else out[r * cols + c] = x;
        }
    Mat_VarFree(v);
    return st;
}

typedef struct ycb_meta {
    double K[9];
    double factor;
    double T_wc[16];
} ycb_meta;

/* One frame's meta.mat: intrinsics, depth factor and camera pose. */
static sooc_status read_meta(const char *path, double rot_tol, ycb_meta *out) {
    pthread_once(&g_mat_once, mat_log_init);
    sooc_status st = mat_check_header(path);
    if (st) return st;
    void *raw = NULL;
    size_t nraw = 0;
    if ((st = sooc_file_read_all(path, (size_t)1 << 30, &raw, &nraw))) return st;
    st = sooc_seqi_mat_check_sizes(path, raw, nraw);
    sooc_free(raw);
    if (st) return st;
    mat_msg_clear();
    mat_t *m = Mat_Open(path, MAT_ACC_RDONLY);
    if (!m || t_mat_n) {
        if (m) Mat_Close(m);
        return sooc_seterr(SOOC_EFORMAT, "%s: cannot read the MAT-file (libmatio: %s)", path,
                           t_mat_n ? t_mat_msg : "open failed");
    }
    /* every variable's header, so a file cut short anywhere is reported */
    matvar_t *v;
    while ((v = Mat_VarReadNextInfo(m))) Mat_VarFree(v);
    if (t_mat_n)
        st = sooc_seterr(SOOC_EFORMAT, "%s: truncated or corrupt MAT-file (libmatio: %s)", path, t_mat_msg);
    double RT[12];
    if (!st) st = mat_get(m, path, "intrinsic_matrix", 3, 3, out->K);
    if (!st) st = mat_get(m, path, "factor_depth", 1, 1, &out->factor);
    if (!st) st = mat_get(m, path, "rotation_translation_matrix", 3, 4, RT);
    Mat_Close(m);
    if (st) return st;
    const double *K = out->K;
    if (!(K[0] > 0) || !(K[4] > 0) || K[1] != 0 || K[3] != 0 || K[6] != 0 || K[7] != 0 || K[8] != 1)
        return sooc_seterr(SOOC_EINVAL, "%s: intrinsic_matrix is [%g %g %g; %g %g %g; %g %g %g], expected "
                           "[fx 0 cx; 0 fy cy; 0 0 1] with fx, fy > 0", path, K[0], K[1], K[2], K[3], K[4], K[5],
                           K[6], K[7], K[8]);
    if (!(out->factor > 0))
        return sooc_seterr(SOOC_EINVAL, "%s: factor_depth is %g, expected > 0 (depth units per metre)", path,
                           out->factor);
    double R[9], t[3], T_cw[16], err;
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) R[3 * r + c] = RT[4 * r + c];
        t[r] = RT[4 * r + 3];
    }
    if (!sooc_m3_is_rotation(R, rot_tol, &err))
        return sooc_seterr(SOOC_EINVAL, "%s: rotation_translation_matrix: rotation is not orthonormal (error %.3g > "
                           "%.3g)", path, err, rot_tol);
    /* world-to-camera (p_cam = R p_world + t): the frame's T_wc is its inverse */
    sooc_se3_from_rt(T_cw, R, t);
    sooc_se3_inverse(out->T_wc, T_cw);
    return SOOC_OK;
}

/* ---------------------------------------------------------------- open */

int64_t sooc_seqi_ycb_color_number(const char *name) {
    int64_t k = 0;
    int nd = 0;
    const char *p = name;
    while (*p >= '0' && *p <= '9') {
        if (nd >= SOOC_SEQI_FRAME_DIGITS) return -1;
        k = k * 10 + (*p++ - '0');
        nd++;
    }
    return nd > 0 && !strcmp(p, "-color.png") ? k : -1;
}

typedef struct ycb_file {
    int64_t number;
    char prefix[16];   /* the digits as written */
} ycb_file;

static int cmp_ycb(const void *a, const void *b) {
    const ycb_file *x = a, *y = b;
    if (x->number != y->number) return x->number < y->number ? -1 : 1;
    return strcmp(x->prefix, y->prefix);
}

static sooc_status ycb_scan(const char *dir, ycb_file **out, int *nout) {
    *out = NULL;
    *nout = 0;
    DIR *d = opendir(dir);
    if (!d) return sooc_seterr(SOOC_ENOTFOUND, "%s: cannot open directory", dir);
    ycb_file *f = NULL;
    int n = 0, cap = 0;
    struct dirent *de;
    sooc_status st = SOOC_OK;
    while ((de = readdir(d))) {
        int64_t k = sooc_seqi_ycb_color_number(de->d_name);
        if (k < 0) continue;
        if (n == cap) {
            cap = cap ? cap * 2 : 256;
            ycb_file *nf = sooc_realloc(f, sizeof *f * (size_t)cap);
            if (!nf) { st = SOOC_ENOMEM; break; }
            f = nf;
        }
        f[n].number = k;
        snprintf(f[n].prefix, sizeof f[n].prefix, "%.*s", (int)(strchr(de->d_name, '-') - de->d_name), de->d_name);
        n++;
    }
    closedir(d);
    if (st) { sooc_free(f); return st; }
    if (n) qsort(f, (size_t)n, sizeof *f, cmp_ycb);
    for (int i = 1; i < n; i++)
        if (f[i].number == f[i - 1].number) {
            st = sooc_seterr(SOOC_EINVAL, "%s: frame %lld twice (%s-color.png and %s-color.png)", dir,
                             (long long)f[i].number, f[i - 1].prefix, f[i].prefix);
            sooc_free(f);
            return st;
        }
    *out = f;
    *nout = n;
    return SOOC_OK;
}

static char *ycb_path(const char *dir, const char *prefix, const char *suffix) {
    char name[64];
    snprintf(name, sizeof name, "%s%s", prefix, suffix);
    return sooc_seqi_join_dup(dir, name);
}

static int same(double a, double b) { return fabs(a - b) <= 1e-9 * (fabs(a) + fabs(b)) + 1e-12; }

sooc_status sooc_seqi_open_ycb(sooc_seq *s, const sooc_seq_open_params *p) {
    ycb_file *fl = NULL;
    int n = 0;
    sooc_status st = ycb_scan(s->dir, &fl, &n);
    if (!st && n == 0) st = sooc_seterr(SOOC_ENOTFOUND, "%s: no frames (expected NNNNNN-color.png)", s->dir);
    ycb_meta m0, m;
    char meta0[4096] = "";
    int with_labels = 0;
    for (int i = 0; i < n && !st; i++) {
        sooc_seqi_entry *e;
        if ((st = sooc_seqi_push(s, &e))) break;
        e->rgb = ycb_path(s->dir, fl[i].prefix, "-color.png");
        e->depth = ycb_path(s->dir, fl[i].prefix, "-depth.png");
        char *meta = ycb_path(s->dir, fl[i].prefix, "-meta.mat");
        char *label = ycb_path(s->dir, fl[i].prefix, "-label.png");
        if (!e->rgb || !e->depth || !meta || !label) st = SOOC_ENOMEM;
        if (!st && i == 0) with_labels = sooc_file_exists(label);
        if (!st) st = sooc_seqi_need_file(NULL, 0, e->depth);
        if (!st) st = sooc_seqi_need_file(NULL, 0, meta);
        if (!st && with_labels && !(st = sooc_seqi_need_file(NULL, 0, label))) {
            e->inst = label;
            label = NULL;
        }
        if (!st) st = read_meta(meta, p->rot_tol, i ? &m : &m0);
        if (!st && i == 0) snprintf(meta0, sizeof meta0, "%s", meta);
        if (!st && i > 0) {
            for (int k = 0; k < 9 && !st; k++)
                if (!same(m.K[k], m0.K[k]))
                    st = sooc_seterr(SOOC_EINVAL, "%s: intrinsic_matrix differs from %s's (fx %g fy %g cx %g cy %g "
                                     "against %g %g %g %g): one sequence has one camera", meta, meta0, m.K[0], m.K[4],
                                     m.K[2], m.K[5], m0.K[0], m0.K[4], m0.K[2], m0.K[5]);
            if (!st && !same(m.factor, m0.factor))
                st = sooc_seterr(SOOC_EINVAL, "%s: factor_depth %g differs from %s's %g", meta, m.factor, meta0,
                                 m0.factor);
        }
        if (!st) memcpy(e->T, i ? m.T_wc : m0.T_wc, sizeof e->T);
        e->has_pose = 1;
        e->number = fl[i].number;
        e->t_ns = fl[i].number * SOOC_SEQI_FRAME_NS; /* no timestamps in this layout: 30 Hz by frame number */
        sooc_free(meta);
        sooc_free(label);
    }
    sooc_free(fl);
    if (st) return st;
    s->label_name_fn = ycb_label_name;
    /* intrinsics and depth scale: a calibration YAML when given, else meta.mat */
    st = sooc_seqi_load_calib(s, p, 0);
    if (st && st != SOOC_ENOTFOUND) return st;
    if (st == SOOC_ENOTFOUND) {
        int w, h;
        sooc_pixfmt fmt;
        if ((st = sooc_image_info(s->e[0].rgb, &w, &h, &fmt))) return st;
        sooc_calib_pinhole(&s->calib, w, h, m0.K[0], m0.K[4], m0.K[2], m0.K[5]);
    }
    if (!(s->calib.depth_scale > 0)) s->calib.depth_scale = 1.0 / m0.factor;
    return SOOC_OK;
}
