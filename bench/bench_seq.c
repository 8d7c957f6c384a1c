/* Sequence reading speed: libjpeg-turbo decode of one 640x480
 * 7-Scenes colour frame from memory, and sooc_seq_read (JPEG colour + 16-bit
 * PNG depth + depth decoding) over the first frames of 7-Scenes redkitchen
 * and of label-fusion. Reads ../shared/real (or SOOC_SHARED_REAL); without it
 * a generated 640x480 JPEG is decoded and the sequence figures are null.
 * Run from the repository root. Last line: a JSON object. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sooc3d/core.h"
#include "sooc3d/frame.h"

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Median ms per sooc_jpeg_decode over `reps` runs. */
static double jpeg_ms(const void *buf, size_t n, int reps, int *w, int *h) {
    sooc_image img = {0};
    double *t = malloc(sizeof(double) * (size_t)reps);
    if (!t) return -1;
    for (int r = 0; r < reps; r++) {
        double t0 = sooc_seconds();
        if (sooc_jpeg_decode(buf, n, "bench.jpg", &img)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
        t[r] = (sooc_seconds() - t0) * 1e3;
    }
    *w = img.width;
    *h = img.height;
    qsort(t, (size_t)reps, sizeof *t, cmp_d);
    double m = t[reps / 2];
    free(t);
    sooc_image_free(&img);
    return m;
}

/* Frames per second of sooc_seq_read over the first `nmax` frames. */
static double seq_fps(const char *dir, int nmax, int *nread) {
    sooc_seq *s = NULL;
    *nread = 0;
    if (sooc_seq_open(&s, dir, NULL)) { fprintf(stderr, "%s\n", sooc_errmsg()); return -1; }
    sooc_frame f = {0};
    int64_t n = sooc_seq_count(s) < nmax ? sooc_seq_count(s) : nmax;
    if (sooc_seq_read(s, 0, &f)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); } /* warm-up, allocation */
    double t0 = sooc_seconds();
    for (int64_t i = 0; i < n; i++)
        if (sooc_seq_read(s, i, &f)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    double dt = sooc_seconds() - t0;
    *nread = (int)n;
    sooc_frame_free(&f);
    sooc_seq_close(s);
    return n / dt;
}

int main(void) {
    const char *env = getenv("SOOC_SHARED_REAL");
    char real[1024], p[1200];
    snprintf(real, sizeof real, "%s", env && *env ? env : "../shared/real");
    snprintf(p, sizeof p, "%s/7scenes_redkitchen/frame-000000.color.jpg", real);
    void *buf = NULL;
    size_t n = 0;
    int have_real = sooc_file_read_all(p, 1 << 24, &buf, &n) == SOOC_OK;
    if (!have_real) {
        /* a 640x480 test pattern with texture, q90 */
        sooc_image img = {0};
        if (sooc_image_alloc(&img, 640, 480, SOOC_PIX_RGB8)) return 1;
        uint8_t *d = img.data;
        uint32_t r = 12345;
        for (int i = 0; i < 640 * 480 * 3; i++) {
            r = r * 1664525u + 1013904223u;
            d[i] = (uint8_t)((i / 3 % 640) / 3 + (r >> 28));
        }
        if (sooc_jpeg_encode(&img, 90, &buf, &n)) return 1;
        sooc_image_free(&img);
    }
    int w = 0, h = 0;
    double ms = jpeg_ms(buf, n, 100, &w, &h);
    printf("JPEG decode (%s, %dx%d, %zu bytes): %.2f ms median of 100\n", have_real ? "7-Scenes frame 0" : "generated",
           w, h, n, ms);
    sooc_free(buf);
    double fps7 = -1, fpslf = -1;
    int n7 = 0, nlf = 0;
    if (have_real) {
        snprintf(p, sizeof p, "%s/7scenes_redkitchen", real);
        fps7 = seq_fps(p, 60, &n7);
        snprintf(p, sizeof p, "%s/label_fusion/data/labels", real);
        fpslf = seq_fps(p, 15, &nlf);
        printf("sooc_seq_read: 7-Scenes %.1f frames/s (%d frames, JPEG + PNG depth), label-fusion %.1f frames/s "
               "(%d frames, PNG + PNG)\n", fps7, n7, fpslf, nlf);
    }
    char a[64], b[64];
    if (fps7 > 0) snprintf(a, sizeof a, "%.1f", fps7); else snprintf(a, sizeof a, "null");
    if (fpslf > 0) snprintf(b, sizeof b, "%.1f", fpslf); else snprintf(b, sizeof b, "null");
    printf("{\"bench\": \"seq\", \"jpeg_source\": \"%s\", \"jpeg_w\": %d, \"jpeg_h\": %d, \"jpeg_decode_ms\": %.3f, "
           "\"seq_read_fps_7scenes\": %s, \"seq_read_fps_labelfusion\": %s}\n",
           have_real ? "7scenes" : "generated", w, h, ms, a, b);
    return 0;
}
