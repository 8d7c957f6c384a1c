/* Helpers for tests that run the `sooc3d` binary (tests/cli, tests/eval). */
#ifndef SOOC3D_TEST_CLI_UTIL_H
#define SOOC3D_TEST_CLI_UTIL_H

#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/model.h"

#include <stdio.h>
#include <stdlib.h>
#include <sys/wait.h>

/* Echo and run a shell command; its exit status, or -1. */
static inline int tc_run(const char *cmd) {
    printf("+ %s\n", cmd);
    fflush(stdout);
    int rc = system(cmd);
    return rc == -1 ? -1 : WEXITSTATUS(rc);
}

/* A whole file (at most 16 MiB) as a NUL-terminated buffer to sooc_free, or NULL. */
static inline char *tc_slurp(const char *path) {
    void *t = NULL;
    size_t n = 0;
    if (sooc_file_read_all(path, (size_t)1 << 24, &t, &n)) {
        sooc_clearerr();
        return NULL;
    }
    return t;
}

/* An untrained model small enough for end-to-end CLI tests: K = 3, 32x32 input, 16x16 rays. */
static inline void tc_tiny_model(const char *path) {
    sooc_model_config c;
    sooc_model_config_default(&c);
    c.K = 3, c.d_what = 8, c.d_layout = 4, c.L = 1;
    c.img_w = c.img_h = 32;
    c.ray_w = c.ray_h = 16;
    c.dec_width = 16, c.dec_color_width = 8;
    c.ref_ch[0] = c.ref_ch[1] = c.ref_ch[2] = c.ref_ch[3] = 8;
    c.ref_fc = 16, c.ref_hidden = 16;
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_create(&m, &c, 3));
    if (m) CHECK_OK(sooc_model_save(m, path, NULL, 0));
    sooc_model_destroy(m);
}

#endif /* SOOC3D_TEST_CLI_UTIL_H */
