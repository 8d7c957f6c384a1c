/* bench_odometry: RGB-D odometry frames/s at the default 320x240 working
 * resolution (the bar: at least 30 frames/s). Frames come from
 * ../shared/real/7scenes_redkitchen (640x480, resized inside the odometry as
 * in the node) or, when it is absent, from a synthetic textured scene. All
 * frames are read first; the timed loop is sooc_odom_track only. Each
 * variant runs `rounds` times over the frames; the median round is
 * reported. The last line is a JSON object.
 *   bench_odometry [rounds=3] [dir] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sooc3d/slam.h"
#include "sooc3d/frame.h"

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* a synthetic 640x480 frame: a slanted textured plane seen by a moving camera */
static void synth(sooc_frame *f, int i) {
    f->K.width = 640;
    f->K.height = 480;
    f->K.fx = f->K.fy = 525;
    f->K.cx = 319.5;
    f->K.cy = 239.5;
    double tx = 0.004 * i;
    for (int y = 0; y < 480; y++)
        for (int x = 0; x < 640; x++) {
            double xn = (x - 319.5) / 525, yn = (y - 239.5) / 525;
            double z = 2.0 / (1 + 0.3 * yn);   /* plane tilted about x */
            double u = xn * z + tx, v = yn * z;
            size_t k = (size_t)y * 640 + x;
            f->depth[k] = (float)z;
            f->valid[k] = 1;
            double s = 0.5 + 0.25 * sin(23 * u) * cos(19 * v) + 0.2 * sin(57 * u + 31 * v);
            for (int c = 0; c < 3; c++) f->rgb[3 * k + c] = (uint8_t)(255 * fmin(1, fmax(0, s + 0.05 * c)));
        }
    f->t_ns = (int64_t)i * 33333333;
}

int main(int argc, char **argv) {
    int rounds = argc > 1 ? atoi(argv[1]) : 3;
    if (rounds < 1) rounds = 1;
    char dir[1024];
    const char *real = getenv("SOOC_SHARED_REAL");
    if (argc > 2) snprintf(dir, sizeof dir, "%s", argv[2]);
    else snprintf(dir, sizeof dir, "%s/7scenes_redkitchen", real ? real : "../shared/real");
    if (!sooc_cv_available()) {
        printf("{\"bench\": \"odometry\", \"error\": \"built without OpenCV\"}\n");
        return 1;
    }
    int n = 0;
    sooc_frame *frames = NULL;
    const char *source = "synthetic";
    sooc_seq *seq = NULL;
    if (sooc_dir_exists(dir) && sooc_seq_open(&seq, dir, NULL) == SOOC_OK) {
        n = (int)sooc_seq_count(seq);
        frames = calloc((size_t)n, sizeof *frames);
        for (int i = 0; i < n; i++)
            if (sooc_seq_read(seq, i, &frames[i])) {
                fprintf(stderr, "bench_odometry: %s\n", sooc_errmsg());
                return 1;
            }
        sooc_seq_close(seq);
        source = "7scenes_redkitchen";
    } else {
        n = 120;
        frames = calloc((size_t)n, sizeof *frames);
        for (int i = 0; i < n; i++) {
            if (sooc_frame_alloc(&frames[i], 640, 480, 0)) return 1;
            synth(&frames[i], i);
        }
    }
    /* as `sooc3d odometry`: 7-Scenes colour is resampled into the depth camera */
    int seven = sooc_odom_is_7scenes_depth_K(&frames[0].K, frames[0].width, frames[0].height);
    fprintf(stderr, "bench_odometry: %d frames (%s, %dx%d), %d rounds%s\n", n, source, frames[0].width,
            frames[0].height, rounds, seven ? ", 7-Scenes colour camera" : "");
    double fps[3];
    double *t = calloc((size_t)rounds, sizeof(double));
    for (int v = 0; v < 3; v++) {
        int tracked = 0;
        for (int r = 0; r < rounds; r++) {
            sooc_odom_params p;
            sooc_odom_params_default(&p);
            p.variant = (sooc_odom_variant)v;
            if (seven) sooc_odom_params_7scenes_color(&p, frames[0].width, frames[0].height);
            sooc_odom *o = NULL;
            if (sooc_odom_create(&o, &p)) {
                fprintf(stderr, "bench_odometry: %s\n", sooc_errmsg());
                return 1;
            }
            tracked = 0;
            double t0 = sooc_seconds();
            for (int i = 0; i < n; i++) {
                sooc_odom_result res;
                if (sooc_odom_track(o, &frames[i], &res)) {
                    fprintf(stderr, "bench_odometry: %s\n", sooc_errmsg());
                    return 1;
                }
                tracked += res.state == SOOC_ODOM_TRACKED || res.state == SOOC_ODOM_FIRST;
            }
            t[r] = sooc_seconds() - t0;
            sooc_odom_destroy(o);
        }
        qsort(t, (size_t)rounds, sizeof(double), cmp_d);
        fps[v] = n / t[rounds / 2];
        fprintf(stderr, "  %-8s %.1f frames/s (%.2f ms/frame), %d/%d tracked\n",
                sooc_odom_variant_name((sooc_odom_variant)v), fps[v], 1e3 / fps[v], tracked, n);
    }
    printf("{\"bench\": \"odometry\", \"source\": \"%s\", \"frames\": %d, \"input\": \"%dx%d\", \"working\": \"320x240\", "
           "\"rounds\": %d, \"color_resampled\": %s, \"fps_rgbd\": %.2f, \"fps_icp\": %.2f, \"fps_rgbd_icp\": %.2f, "
           "\"default\": \"rgbd_icp\"}\n",
           source, n, frames[0].width, frames[0].height, rounds, seven ? "true" : "false", fps[0], fps[1], fps[2]);
    for (int i = 0; i < n; i++) sooc_frame_free(&frames[i]);
    free(frames);
    free(t);
    return 0;
}
