/* Helpers of the log tests: the fixtures folder, temp dirs, damaged copies. */
#ifndef SOOC3D_TEST_LOGS_UTIL_H
#define SOOC3D_TEST_LOGS_UTIL_H

#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/log.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ../shared/bags (SOOC_SHARED_BAGS), or NULL after printing why the test skips. */
static inline const char *lu_bags(const char *test) {
    const char *d = getenv("SOOC_SHARED_BAGS");
    static char buf[1024];
    if (!d || !*d) d = "../shared/bags";
    snprintf(buf, sizeof buf, "%s/librealsense/single_depth_color_640x480.bag", d);
    struct stat sb;
    if (stat(buf, &sb) != 0) {
        printf("%s: SKIP: the log fixtures are not at %s (set SOOC_SHARED_BAGS)\n", test, d);
        return NULL;
    }
    return d;
}

static inline char *lu_path(const char *a, const char *b) {
    static char bufs[16][1024];
    static int k = 0;
    char *p = bufs[k++ % 16];
    snprintf(p, 1024, "%s/%s", a, b);
    return p;
}

static inline char *lu_tmpdir(const char *tag) {
    static char b[512];
    const char *t = getenv("TMPDIR");
    snprintf(b, sizeof b, "%s/sooc_%s_XXXXXX", t && *t ? t : "/tmp", tag);
    if (!mkdtemp(b)) { perror("mkdtemp"); exit(1); }
    return b;
}

static inline uint8_t *lu_read(const char *path, size_t *n) {
    void *d = NULL;
    if (sooc_file_read_all(path, (size_t)1 << 30, &d, n)) return NULL;
    return d;
}

static inline void lu_write(const char *path, const void *d, size_t n) {
    FILE *f = fopen(path, "wb");
    if (!f || (n && fwrite(d, 1, n, f) != n)) { perror(path); exit(1); }
    fclose(f);
}

/* Offset of the first occurrence of needle (n bytes) in d, or -1. */
static inline long lu_find(const uint8_t *d, size_t nd, const void *needle, size_t n) {
    for (size_t i = 0; i + n <= nd; i++)
        if (!memcmp(d + i, needle, n)) return (long)i;
    return -1;
}

static inline uint32_t logs_u32_le(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static inline uint64_t logs_u64_le(const uint8_t *p) { return logs_u32_le(p) | ((uint64_t)logs_u32_le(p + 4) << 32); }

static inline sooc_ros_header lu_hdr(int64_t t, const char *frame) {
    sooc_ros_header h;
    memset(&h, 0, sizeof h);
    h.stamp_ns = t;
    snprintf(h.frame_id, sizeof h.frame_id, "%s", frame);
    return h;
}

/* Frames of a log with the pose from TF below pose_parent (NULL = none); NULL after a failed check. */
static inline sooc_logseq *lu_open_frames(const char *path, const char *pose_parent) {
    sooc_logseq_params p;
    sooc_logseq_params_default(&p);
    p.pose_parent = pose_parent;
    sooc_logseq *s = NULL;
    CHECK_OK(sooc_logseq_open(&s, path, &p));
    return s;
}

/* Open must fail with status st and a message containing every given piece. */
static inline void lu_open_fails(const char *path, sooc_status st, const char *a, const char *b) {
    sooc_logfile *lf = NULL;
    sooc_status got = sooc_logfile_open(&lf, path);
    CHECK_MSG(got == st, "%s: opened with %s, expected %s (%s)", path, sooc_status_str(got), sooc_status_str(st),
              sooc_errmsg());
    CHECK(lf == NULL);
    CHECK_MSG(strstr(sooc_errmsg(), path) != NULL, "message does not name the file: %s", sooc_errmsg());
    if (a) CHECK_MSG(strstr(sooc_errmsg(), a) != NULL, "message lacks '%s': %s", a, sooc_errmsg());
    if (b) CHECK_MSG(strstr(sooc_errmsg(), b) != NULL, "message lacks '%s': %s", b, sooc_errmsg());
    printf("  %s -> %s\n", sooc_status_str(got), sooc_errmsg());
    sooc_logfile_close(lf);
}

/* An object of a map.csv (`sooc3d infer --out`): its floor position. */
typedef struct lu_obj { double x, z; } lu_obj;

static inline int lu_read_map(const char *csv, lu_obj *o, int cap) {
    FILE *f = fopen(csv, "r");
    if (!f) return -1;
    char line[512];
    int n = 0;
    while (fgets(line, sizeof line, f)) {
        double x, z;
        if (sscanf(line, "%*d,%lf,%lf", &x, &z) == 2 && n < cap) o[n++] = (lu_obj){x, z};
    }
    fclose(f);
    return n;
}

/* `sooc3d infer` (binary bin, model) on sequence a into out_a and on b into
 * out_b (b skipped when reuse_b and out_b exists: a map made once), then the
 * two maps compared in order: *na, *nb objects, *worst the largest offset (m). */
static inline void lu_infer_maps(const char *bin, const char *model, const char *a, const char *out_a, const char *b,
                                 const char *out_b, int reuse_b, int *na, int *nb, double *worst) {
    const char *outs[2] = {out_a, out_b}, *ins[2] = {a, b};
    char cmd[4096];
    for (int k = 0; k < 2; k++) {
        struct stat sb;
        if (k == 1 && reuse_b && stat(out_b, &sb) == 0) continue;
        snprintf(cmd, sizeof cmd, "'%s' infer --model %s --seq '%s' --out '%s' --no-render --threads 1 > '%s.log' 2>&1",
                 bin, model, ins[k], outs[k], outs[k]);
        int rc = system(cmd);
        CHECK_MSG(rc == 0, "%s failed (%d): see %s.log", cmd, rc, outs[k]);
    }
    static lu_obj A[4096], B[4096];
    char ca[1100], cb[1100];
    snprintf(ca, sizeof ca, "%s/map.csv", out_a);
    snprintf(cb, sizeof cb, "%s/map.csv", out_b);
    *na = lu_read_map(ca, A, 4096), *nb = lu_read_map(cb, B, 4096);
    *worst = 0;
    for (int i = 0; i < *na && i < *nb; i++) {
        double d = hypot(A[i].x - B[i].x, A[i].z - B[i].z);
        if (d > *worst) *worst = d;
    }
}

#endif
