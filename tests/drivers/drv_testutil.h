/* Helpers for the driver tests: write a tiny TUM RGB-D sequence, re-exec a
 * test under a changed environment. */
#ifndef SOOC3D_DRV_TESTUTIL_H
#define SOOC3D_DRV_TESTUTIL_H

#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

static inline int tu_png_write(const char *path, int w, int h, int depth16, const void *data) {
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png_create_info_struct(png);
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        fclose(fp);
        return -1;
    }
    png_init_io(png, fp);
    png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, depth16 ? 16 : 8,
                 depth16 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    int one = 1;
    if (depth16 && *(char *)&one) png_set_swap(png);
    size_t rb = (size_t)w * (depth16 ? 2 : 3);
    for (int y = 0; y < h; y++) png_write_row(png, (png_const_bytep)data + rb * (size_t)y);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    fclose(fp);
    return 0;
}

/* TUM sequence: n frames, w x h, frame i at t0 + i*period_s; depth of frame i
 * is (1 + 0.1 i) m everywhere except pixel (0,0) = 0 (invalid); colour
 * R = 10 i, G = x, B = y. Ground truth at 4x the frame rate: camera moves
 * along +x at 1 m/s with identity rotation. */
static inline int tu_write_tum(const char *dir, int n, int w, int h, double t0, double period_s) {
    char p[4096];
    if (strlen(dir) > 1000) return -1;
    snprintf(p, sizeof p, "mkdir -p %s/rgb %s/depth", dir, dir);
    if (system(p)) return -1;
    snprintf(p, sizeof p, "%s/rgb.txt", dir);
    FILE *fr = fopen(p, "w");
    snprintf(p, sizeof p, "%s/depth.txt", dir);
    FILE *fd = fopen(p, "w");
    snprintf(p, sizeof p, "%s/groundtruth.txt", dir);
    FILE *fg = fopen(p, "w");
    if (!fr || !fd || !fg) return -1;
    fprintf(fr, "# color images\n# file: test\n# timestamp filename\n");
    fprintf(fd, "# depth maps\n# file: test\n# timestamp filename\n");
    fprintf(fg, "# ground truth trajectory\n# file: test\n# timestamp tx ty tz qx qy qz qw\n");
    uint8_t *rgb = malloc((size_t)w * h * 3);
    uint16_t *dep = malloc((size_t)w * h * 2);
    for (int i = 0; i < n; i++) {
        double t = t0 + i * period_s;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                uint8_t *px = rgb + 3 * ((size_t)y * w + x);
                px[0] = (uint8_t)(10 * i);
                px[1] = (uint8_t)x;
                px[2] = (uint8_t)y;
                dep[(size_t)y * w + x] = (uint16_t)(5000.0 * (1.0 + 0.1 * i) + 0.5);
            }
        dep[0] = 0;
        char name[64];
        snprintf(name, sizeof name, "%.6f.png", t);
        snprintf(p, sizeof p, "%s/rgb/%s", dir, name);
        if (tu_png_write(p, w, h, 0, rgb)) return -1;
        snprintf(p, sizeof p, "%s/depth/%s", dir, name);
        if (tu_png_write(p, w, h, 1, dep)) return -1;
        fprintf(fr, "%.6f rgb/%s\n", t, name);
        fprintf(fd, "%.6f depth/%s\n", t, name);
    }
    for (int k = -4; k < 4 * n + 4; k++) {
        double t = t0 + k * period_s / 4;
        fprintf(fg, "%.6f %.6f 0.000000 0.000000 0 0 0 1\n", t, t - t0);
    }
    free(rgb);
    free(dep);
    /* calibration (the data module's readers require it; the built-in reader ignores it) */
    snprintf(p, sizeof p, "%s/calib.yaml", dir);
    FILE *fc = fopen(p, "w");
    if (!fc) return -1;
    fprintf(fc, "%%YAML 1.2\n---\ncamera_name: test\nimage_width: %d\nimage_height: %d\n"
                "camera_matrix: {rows: 3, cols: 3, data: [%g, 0, %g, 0, %g, %g, 0, 0, 1]}\n"
                "distortion_model: plumb_bob\n"
                "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n"
                "depth_scale: 0.0002\n",
            w, h, 52.5 * w / 64.0, w / 2.0 - 0.5, 52.5 * w / 64.0, h / 2.0 - 0.5);
    fclose(fc);
    fclose(fr);
    fclose(fd);
    fclose(fg);
    return 0;
}

/* Run argv0 again as a child with extra env entries (NULL-terminated list of
 * "K=V"); returns its exit code (or 1 on failure to run). */
static inline int tu_reexec(const char *const *extra_env, char *const argv[]) {
    pid_t pid = fork();
    if (pid < 0) return 1;
    if (pid == 0) {
        for (const char *const *e = extra_env; *e; e++) putenv((char *)*e);
        execv("/proc/self/exe", argv);
        _exit(127);
    }
    int status = 0;
    if (waitpid(pid, &status, 0) < 0) return 1;
    if (WIFSIGNALED(status)) {
        fprintf(stderr, "child died with signal %d\n", WTERMSIG(status));
        return 1;
    }
    return WEXITSTATUS(status);
}

#endif
