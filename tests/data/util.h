/* Helpers for the data module tests: temp dirs, small files, message checks,
 * the multi-view depth check of the real-data tests. */
#ifndef SOOC3D_TEST_DATA_UTIL_H
#define SOOC3D_TEST_DATA_UTIL_H

#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* mkdtemp under $TMPDIR or /tmp; returns a static-lifetime string. */
static inline char *tu_tmpdir(const char *tag) {
    static char bufs[16][512];
    static int k = 0;
    char *b = bufs[k++ % 16];
    const char *t = getenv("TMPDIR");
    snprintf(b, 512, "%s/sooc_%s_XXXXXX", t && *t ? t : "/tmp", tag);
    if (!mkdtemp(b)) { perror("mkdtemp"); exit(1); }
    return b;
}

static inline void tu_write(const char *dir, const char *name, const char *fmt, ...) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    if (!f) { perror(path); exit(1); }
    va_list ap;
    va_start(ap, fmt);
    vfprintf(f, fmt, ap);
    va_end(ap);
    fclose(f);
}

static inline void tu_rm_rf(const char *dir) {
    char cmd[1200];
    if (strncmp(dir, "/tmp/", 5) && !getenv("TMPDIR")) return;
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0) fprintf(stderr, "warning: could not remove %s\n", dir);
}

static inline void tu_cp_r(const char *src, const char *dst) {
    char cmd[2400];
    snprintf(cmd, sizeof cmd, "cp -r '%s/.' '%s/'", src, dst);
    if (system(cmd) != 0) { fprintf(stderr, "cp failed: %s\n", cmd); exit(1); }
}

/* Check that status is an error and the message contains every needle. */
#define CHECK_ERR_HAS(expr, ...)                                                              \
    do {                                                                                      \
        sooc_status st_ = (expr);                                                             \
        const char *nd_[] = {__VA_ARGS__, NULL};                                              \
        CHECK_MSG(st_ != SOOC_OK, "%s unexpectedly succeeded", #expr);                        \
        for (int k_ = 0; nd_[k_]; k_++)                                                       \
            CHECK_MSG(strstr(sooc_errmsg(), nd_[k_]) != NULL, "%s: message '%s' lacks '%s'", #expr, \
                      sooc_errmsg(), nd_[k_]);                                                \
    } while (0)

/* Real data folder or NULL. */
static inline const char *tu_real_dir(void) {
    static char buf[1024];
    const char *e = getenv("SOOC_SHARED_REAL");
    if (e && *e) snprintf(buf, sizeof buf, "%s", e);
    else snprintf(buf, sizeof buf, "../shared/real");
    char probe[1100];
    snprintf(probe, sizeof probe, "%s/README.md", buf);
    return access(probe, R_OK) == 0 ? buf : NULL;
}

/* Median |z_pred - z_meas| / z_meas when frame a's points are moved into
 * frame b: a multi-view check that the depth scale and poses agree. */
static inline double tu_reproj_err(const sooc_frame *a, const sooc_frame *b) {
    static float errs[640 * 480];
    int n = 0;
    double Tba[16], Tbw[16];
    sooc_se3_inverse(Tbw, b->T_wc);
    sooc_se3_mul(Tba, Tbw, a->T_wc);
    for (int v = 0; v < a->height; v += 4)
        for (int u = 0; u < a->width; u += 4) {
            size_t i = (size_t)v * a->width + u;
            if (!a->valid[i]) continue;
            double pa[3] = {(u - a->K.cx) / a->K.fx * a->depth[i], (v - a->K.cy) / a->K.fy * a->depth[i], a->depth[i]}, pb[3];
            sooc_se3_apply(pb, Tba, pa);
            if (pb[2] <= 0.1) continue;
            int ub = (int)lround(b->K.fx * pb[0] / pb[2] + b->K.cx), vb = (int)lround(b->K.fy * pb[1] / pb[2] + b->K.cy);
            if (ub < 0 || vb < 0 || ub >= b->width || vb >= b->height) continue;
            size_t j = (size_t)vb * b->width + ub;
            if (!b->valid[j]) continue;
            errs[n++] = (float)(fabs(pb[2] - b->depth[j]) / b->depth[j]);
        }
    if (n < 50) return -1;
    /* median by partial selection */
    for (int k = 0; k <= n / 2; k++) {
        int m = k;
        for (int j = k + 1; j < n; j++) if (errs[j] < errs[m]) m = j;
        float t = errs[k]; errs[k] = errs[m]; errs[m] = t;
        if (k == n / 2) break;
    }
    return errs[n / 2];
}

#endif
