/* Test fixtures for tests/node: a synthetic posed RGB-D stream (in-process
 * source) and the same stream written as a TUM RGB-D sequence on disk. The
 * camera, 1.2 m above a floor (y = 0, +y up), looks along +z and slides along
 * +x by `step` metres per frame; a wall stands 4 m ahead. */
#ifndef SOOC3D_TEST_NODE_FIXTURE_H
#define SOOC3D_TEST_NODE_FIXTURE_H

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sooc3d/frame.h"
#include "sooc3d/core.h"
#include "sooc3d/node.h"

#define FX_W 64
#define FX_H 48

static inline void fx_pose(double T[16], int i, double step) {
    double R[9] = {-1, 0, 0, 0, -1, 0, 0, 0, 1}, t[3] = {step * i, 1.2, 0};
    sooc_se3_from_rt(T, R, t);
}

static inline float fx_depth(int u, int v, const sooc_intrinsics *K) {
    double dy = (v + 0.5 - K->cy) / K->fy;   /* camera y down */
    double z = 4.0;
    if (dy > 1e-6) {
        double zf = 1.2 / dy;                /* floor */
        if (zf < z) z = zf;
    }
    (void)u;
    return (float)z;
}

static inline void fx_fill(sooc_frame *f, int i, double step) {
    if (f->width != FX_W || f->height != FX_H) {
        sooc_frame_free(f);
        sooc_frame_alloc(f, FX_W, FX_H, 0);
    }
    f->K = (sooc_intrinsics){FX_W, FX_H, 50, 50, 32, 24, SOOC_DIST_NONE, {0}};
    for (int v = 0; v < FX_H; v++)
        for (int u = 0; u < FX_W; u++) {
            size_t k = (size_t)v * FX_W + u;
            f->depth[k] = fx_depth(u, v, &f->K);
            f->valid[k] = 1;
            f->rgb[3 * k] = (uint8_t)(4 * u);
            f->rgb[3 * k + 1] = (uint8_t)(5 * v);
            f->rgb[3 * k + 2] = (uint8_t)(i * 7);
        }
    f->t_ns = 1000000000000LL + (int64_t)i * 33333333LL;
    f->index = i;
    f->has_pose = 1;
    fx_pose(f->T_wc, i, step);
}

/* in-process source */
typedef struct fx_src {
    int i, n;
    double step;
    int realtime;
} fx_src;

static inline sooc_status fx_read(void *ctx, sooc_frame *f, int timeout_ms) {
    fx_src *s = ctx;
    (void)timeout_ms;
    if (s->i >= s->n) return SOOC_EEOF;
    fx_fill(f, s->i, s->step);
    s->i++;
    return SOOC_OK;
}

static inline sooc_node_source fx_source(fx_src *s) {
    sooc_node_source src;
    memset(&src, 0, sizeof src);
    src.ctx = s;
    src.read = fx_read;
    return src;
}

/* Write n frames as a TUM sequence under dir (640x480 is not needed: 64x48). */
static inline int fx_write_tum(const char *dir, int n, double step) {
    char p[1024];
    snprintf(p, sizeof p, "%s/rgb", dir);
    if (sooc_mkdirs(p)) return -1;
    snprintf(p, sizeof p, "%s/depth", dir);
    if (sooc_mkdirs(p)) return -1;
    FILE *fr, *fd, *fg, *fc;
    snprintf(p, sizeof p, "%s/calib.yaml", dir);
    fc = fopen(p, "w");
    if (!fc) return -1;
    fprintf(fc, "%%YAML 1.2\n---\nimage_width: %d\nimage_height: %d\n"
                "camera_matrix: {rows: 3, cols: 3, data: [50, 0, 31.5, 0, 50, 23.5, 0, 0, 1]}\n"
                "depth_scale: 0.0002\ndepth_registered: true\n", FX_W, FX_H);
    fclose(fc);
    snprintf(p, sizeof p, "%s/rgb.txt", dir);
    fr = fopen(p, "w");
    snprintf(p, sizeof p, "%s/depth.txt", dir);
    fd = fopen(p, "w");
    snprintf(p, sizeof p, "%s/groundtruth.txt", dir);
    fg = fopen(p, "w");
    if (!fr || !fd || !fg) return -1;
    fprintf(fr, "# color images\n# file: test\n# timestamp filename\n");
    fprintf(fd, "# depth maps\n# file: test\n# timestamp filename\n");
    fprintf(fg, "# ground truth trajectory\n# file: test\n# timestamp tx ty tz qx qy qz qw\n");
    sooc_frame f;
    memset(&f, 0, sizeof f);
    sooc_image rgb = {0}, dep = {0};
    sooc_image_alloc(&rgb, FX_W, FX_H, SOOC_PIX_RGB8);
    sooc_image_alloc(&dep, FX_W, FX_H, SOOC_PIX_GRAY16);
    int rc = 0;
    for (int i = 0; i < n && !rc; i++) {
        fx_fill(&f, i, step);
        double t = (double)f.t_ns * 1e-9;
        memcpy(rgb.data, f.rgb, (size_t)FX_W * FX_H * 3);
        uint16_t *d16 = dep.data;
        for (int k = 0; k < FX_W * FX_H; k++) d16[k] = (uint16_t)lrint(f.depth[k] * 5000.0);
        snprintf(p, sizeof p, "%s/rgb/%.6f.png", dir, t);
        if (sooc_png_write(p, &rgb, 1)) rc = -1;
        snprintf(p, sizeof p, "%s/depth/%.6f.png", dir, t);
        if (sooc_png_write(p, &dep, 1)) rc = -1;
        fprintf(fr, "%.6f rgb/%.6f.png\n", t, t);
        fprintf(fd, "%.6f depth/%.6f.png\n", t, t);
        /* quaternion of diag(-1,-1,1): 180 deg about z */
        fprintf(fg, "%.6f %.6f %.6f %.6f 0 0 1 0\n", t, f.T_wc[3], f.T_wc[7], f.T_wc[11]);
    }
    fclose(fr);
    fclose(fd);
    fclose(fg);
    sooc_frame_free(&f);
    sooc_image_free(&rgb);
    sooc_image_free(&dep);
    return rc;
}

#endif
