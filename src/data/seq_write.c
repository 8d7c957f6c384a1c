/* The sooc3d synthetic-layout writer (TUM lists + calib.yaml [+ instance/]),
 * docs/formats.md section 2.1. */
#include "sooc3d/frame.h"
#include "sooc3d/core.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct sooc_seq_writer {
    char dir[2048];
    sooc_calib calib;
    int64_t n;
    uint8_t *done;
    int64_t *t_ns;
    double *T;
    int *has_pose;
};

sooc_status sooc_seq_writer_create(sooc_seq_writer **out, const char *dir, const sooc_calib *calib,
                                   int64_t n_frames) {
    *out = NULL;
    if (!(calib->depth_scale > 0)) return sooc_seterr(SOOC_EINVAL, "%s: writer needs depth_scale > 0", dir);
    if (n_frames <= 0 || n_frames > 100000000) return sooc_seterr(SOOC_EINVAL, "%s: bad frame count", dir);
    if (strlen(dir) >= 2000) return sooc_seterr(SOOC_EINVAL, "%s: path too long", dir);
    sooc_seq_writer *w = sooc_calloc(1, sizeof *w);
    if (!w) return SOOC_ENOMEM;
    snprintf(w->dir, sizeof w->dir, "%s", dir);
    w->calib = *calib;
    w->n = n_frames;
    w->done = sooc_calloc((size_t)n_frames, 1);
    w->t_ns = sooc_calloc((size_t)n_frames, sizeof(int64_t));
    w->T = sooc_calloc((size_t)n_frames * 16, sizeof(double));
    w->has_pose = sooc_calloc((size_t)n_frames, sizeof(int));
    if (!w->done || !w->t_ns || !w->T || !w->has_pose) { sooc_seq_writer_destroy(w); return SOOC_ENOMEM; }
    static const char *sub[] = {"rgb", "depth"};
    for (int k = 0; k < 2; k++) {
        char p[4096];
        sooc_status s = sooc_path_join(p, sizeof p, dir, sub[k]);
        if (!s) s = sooc_mkdirs(p);
        if (s) { sooc_seq_writer_destroy(w); return s; }
    }
    *out = w;
    return SOOC_OK;
}

sooc_status sooc_seq_writer_put(sooc_seq_writer *w, int64_t i, const sooc_frame *f) {
    if (i < 0 || i >= w->n) return sooc_seterr(SOOC_EINVAL, "%s: writer slot %lld out of range", w->dir, (long long)i);
    if (f->width != w->calib.K.width || f->height != w->calib.K.height)
        return sooc_seterr(SOOC_EINVAL, "%s: frame %lld is %dx%d, calibration %dx%d", w->dir, (long long)i,
                           f->width, f->height, w->calib.K.width, w->calib.K.height);
    char name[64], path[4096];
    sooc_image img = {0};
    sooc_status s = sooc_image_alloc(&img, f->width, f->height, SOOC_PIX_RGB8);
    size_t np = (size_t)f->width * (size_t)f->height;
    if (!s) {
        memcpy(img.data, f->rgb, np * 3);
        snprintf(name, sizeof name, "rgb/%06lld.png", (long long)i);
        s = sooc_path_join(path, sizeof path, w->dir, name);
        if (!s) s = sooc_png_write(path, &img, 6);
    }
    if (!s) s = sooc_image_alloc(&img, f->width, f->height, SOOC_PIX_GRAY16);
    if (!s) {
        uint16_t *d = img.data;
        for (size_t k = 0; k < np; k++) {
            double q = f->valid[k] && f->depth[k] > 0 ? floor(f->depth[k] / w->calib.depth_scale + 0.5) : 0;
            d[k] = q > 65535 ? 0 : (uint16_t)q;
        }
        snprintf(name, sizeof name, "depth/%06lld.png", (long long)i);
        s = sooc_path_join(path, sizeof path, w->dir, name);
        if (!s) s = sooc_png_write(path, &img, 6);
    }
    if (!s && f->instance) {
        memcpy(img.data, f->instance, np * sizeof(uint16_t));
        s = sooc_path_join(path, sizeof path, w->dir, "instance");
        if (!s) s = sooc_mkdirs(path); /* safe to race: EEXIST is fine */
        snprintf(name, sizeof name, "instance/%06lld.png", (long long)i);
        if (!s) s = sooc_path_join(path, sizeof path, w->dir, name);
        if (!s) s = sooc_png_write(path, &img, 6);
    }
    sooc_image_free(&img);
    if (s) return s;
    w->t_ns[i] = f->t_ns;
    w->has_pose[i] = f->has_pose;
    memcpy(w->T + 16 * i, f->T_wc, sizeof f->T_wc);
    w->done[i] = 1;
    return SOOC_OK;
}

sooc_status sooc_seq_writer_finish(sooc_seq_writer *w) {
    for (int64_t i = 0; i < w->n; i++) {
        if (!w->done[i]) return sooc_seterr(SOOC_EINVAL, "%s: frame %lld was never written", w->dir, (long long)i);
        if (i > 0 && w->t_ns[i] <= w->t_ns[i - 1])
            return sooc_seterr(SOOC_EINVAL, "%s: frame %lld: timestamps must increase", w->dir, (long long)i);
    }
    static const char *files[] = {"rgb.txt", "depth.txt", "groundtruth.txt"};
    sooc_status s = SOOC_OK;
    size_t cap = 256 + (size_t)w->n * 160;
    char *b = sooc_malloc(cap);
    if (!b) return SOOC_ENOMEM;
    for (int k = 0; k < 3 && !s; k++) {
        size_t n = 0;
        n += (size_t)snprintf(b + n, cap - n, "# %s\n# written by sooc3d (synthetic layout, docs/formats.md)\n# %s\n",
                              files[k], k == 2 ? "timestamp tx ty tz qx qy qz qw (camera-to-world)" : "timestamp filename");
        for (int64_t i = 0; i < w->n; i++) {
            int64_t t = w->t_ns[i];
            char ts[48];
            snprintf(ts, sizeof ts, "%s%lld.%06lld", t < 0 ? "-" : "", llabs(t) / 1000000000LL,
                     (llabs(t) % 1000000000LL) / 1000);
            if (k < 2) {
                n += (size_t)snprintf(b + n, cap - n, "%s %s/%06lld.png\n", ts, k ? "depth" : "rgb", (long long)i);
            } else if (w->has_pose[i]) {
                double R[9], t3[3], q[4];
                sooc_se3_to_rt(R, t3, w->T + 16 * i);
                sooc_m3_to_quat(q, R);
                n += (size_t)snprintf(b + n, cap - n, "%s %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", ts, t3[0], t3[1],
                                      t3[2], q[0], q[1], q[2], q[3]);
            }
        }
        char path[4096];
        s = sooc_path_join(path, sizeof path, w->dir, files[k]);
        if (!s) s = sooc_file_write_bulk(path, b, n);
    }
    sooc_free(b);
    if (!s) {
        char path[4096];
        s = sooc_path_join(path, sizeof path, w->dir, "calib.yaml");
        if (!s) s = sooc_calib_save(path, &w->calib);
    }
    return s;
}

void sooc_seq_writer_destroy(sooc_seq_writer *w) {
    if (!w) return;
    sooc_free(w->done);
    sooc_free(w->t_ns);
    sooc_free(w->T);
    sooc_free(w->has_pose);
    sooc_free(w);
}
