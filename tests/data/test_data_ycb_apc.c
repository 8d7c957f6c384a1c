/* The YCB-Video and APC readers on the real recordings in ../shared/real
 * (SOOC_SHARED_REAL; skipped with exit 77 when the folder is absent), and
 * their errors on damaged copies in a temp dir: a truncated meta.mat, a
 * meta.mat without a key (written here with libmatio), a depth PNG of the
 * wrong size, a malformed cam.info.txt, a missing mask. The expected values
 * were read from the files outside sooc3d (a MAT v5 parser in Python over
 * zlib + struct; numpy + OpenCV for the PNGs and the masks). */
#include "util.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <stdlib.h>
#include <sys/stat.h>

#include <matio.h>

static char g_ycb[1200], g_apc[1200];

static int cmp_float(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static void cp_file(const char *src_dir, const char *dst_dir, const char *name) {
    char s[1400], d[1400];
    snprintf(s, sizeof s, "%s/%s", src_dir, name);
    snprintf(d, sizeof d, "%s/%s", dst_dir, name);
    void *buf;
    size_t n;
    if (sooc_file_read_all(s, (size_t)64 << 20, &buf, &n)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    FILE *f = fopen(d, "wb");
    if (!f || fwrite(buf, 1, n, f) != n) { perror(d); exit(1); }
    fclose(f);
    sooc_free(buf);
}

static void truncate_to(const char *path, long n) {
    if (truncate(path, n) != 0) { perror(path); exit(1); }
}

/* A 16-bit PNG of w x h, every sample v. */
static void put_gray16(const char *path, int w, int h, uint16_t v) {
    sooc_image img = {0};
    if (sooc_image_alloc(&img, w, h, SOOC_PIX_GRAY16)) exit(1);
    for (int k = 0; k < w * h; k++) ((uint16_t *)img.data)[k] = v;
    if (sooc_png_write(path, &img, 1)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    sooc_image_free(&img);
}

/* A meta.mat with libmatio's writer: K (row-major fx, fy, cx, cy),
 * factor_depth, and the world-to-camera 3x4 when rt != NULL (row-major). */
/* n bytes appended to the file at path */
static void append_bytes(const char *path, const uint8_t *d, size_t n) {
    FILE *f = fopen(path, "ab");
    CHECK(f && fwrite(d, 1, n, f) == n);
    if (f) fclose(f);
}

static void write_meta(const char *path, double fx, const double *rt) {
    mat_t *m = Mat_CreateVer(path, NULL, MAT_FT_MAT5);
    if (!m) { fprintf(stderr, "%s: Mat_CreateVer failed\n", path); exit(1); }
    size_t d33[2] = {3, 3}, d11[2] = {1, 1}, d34[2] = {3, 4};
    double K[9] = {fx, 0, 0, 0, 1067.487, 0, 312.9869, 241.3109, 1};   /* column-major */
    double fd = 10000, RT[12];
    matvar_t *v = Mat_VarCreate("intrinsic_matrix", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, d33, K, 0);
    Mat_VarWrite(m, v, MAT_COMPRESSION_ZLIB);
    Mat_VarFree(v);
    v = Mat_VarCreate("factor_depth", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, d11, &fd, 0);
    Mat_VarWrite(m, v, MAT_COMPRESSION_ZLIB);
    Mat_VarFree(v);
    if (rt) {
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++) RT[r + 3 * c] = rt[4 * r + c];
        v = Mat_VarCreate("rotation_translation_matrix", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, d34, RT, 0);
        Mat_VarWrite(m, v, MAT_COMPRESSION_ZLIB);
        Mat_VarFree(v);
    }
    Mat_Close(m);
}

/* The object poses ("poses", 3x4xN object-to-camera) of one meta.mat: the
 * object centres in the camera frame. Returns N. */
static int object_centres(const char *path, double c[][3], int max) {
    mat_t *m = Mat_Open(path, MAT_ACC_RDONLY);
    if (!m) return 0;
    matvar_t *v = Mat_VarRead(m, "poses");
    int n = 0;
    if (v && v->class_type == MAT_C_DOUBLE && v->rank == 3 && v->dims[0] == 3 && v->dims[1] == 4) {
        const double *d = v->data;
        for (n = 0; n < (int)v->dims[2] && n < max; n++)
            for (int r = 0; r < 3; r++) c[n][r] = d[r + 3 * 3 + 12 * n];   /* column 3 of object n */
    }
    Mat_VarFree(v);
    Mat_Close(m);
    return n;
}

/* -------------------------------------------------------------- YCB-Video */

static void test_ycb(void) {
    sooc_seq *s = NULL;
    sooc_frame f = {0}, g = {0};
    CHECK_OK(sooc_seq_open(&s, g_ycb, NULL));   /* auto */
    if (!s) return;
    CHECK(sooc_seq_get_format(s) == SOOC_SEQ_YCB);
    CHECK(sooc_seq_count(s) == 10 && sooc_seq_frame_number(s, 0) == 1 && sooc_seq_frame_number(s, 9) == 10);
    const sooc_intrinsics *K = &sooc_seq_calib(s)->K;
    CHECK(K->width == 640 && K->height == 480);
    CHECK_CLOSE(K->fx, 1066.778, 1e-9, 0);
    CHECK_CLOSE(K->fy, 1067.487, 1e-9, 0);
    CHECK_CLOSE(K->cx, 312.9869, 1e-9, 0);
    CHECK_CLOSE(K->cy, 241.3109, 1e-9, 0);
    double sc;
    int sh, inv;
    sooc_seq_depth_decoding(s, &sc, &sh, &inv);
    CHECK(sc == 1.0 / 10000 && sh == 0 && inv == 0 && !sooc_seq_depth_circular(s));
    CHECK(sooc_seq_has_labels(s) && !sooc_seq_labels_predicted(s));
    CHECK(!strcmp(sooc_seq_label_name(s, 8), "009_gelatin_box") && !strcmp(sooc_seq_label_name(s, 14), "025_mug") &&
          !strcmp(sooc_seq_label_name(s, 21), "061_foam_brick") && sooc_seq_label_name(s, 22) == NULL);

    CHECK_OK(sooc_seq_read(s, 0, &f));
    CHECK(f.index == 1 && f.has_pose && f.instance);
    /* depth: every pixel is raw / factor_depth */
    sooc_image raw = {0};
    char p[1400];
    snprintf(p, sizeof p, "%s/000001-depth.png", g_ycb);
    CHECK_OK(sooc_png_read(p, &raw));
    int bad = 0, nv = 0;
    static float zs[640 * 480];
    for (int k = 0; k < 640 * 480 && raw.data; k++) {
        uint16_t r = ((const uint16_t *)raw.data)[k];
        bad += f.depth[k] != (r ? (float)(r * 1e-4) : 0.0f);
        if (f.valid[k]) zs[nv++] = f.depth[k];
    }
    sooc_image_free(&raw);
    CHECK_MSG(bad == 0, "%d pixels are not raw / 10000", bad);
    qsort(zs, (size_t)nv, sizeof *zs, cmp_float);
    printf("YCB-Video 0000 frame 1: %.0f%% valid depth, median %.4f m\n", 100.0 * nv / (640 * 480), zs[nv / 2]);
    CHECK_CLOSE(zs[nv / 2], 0.6310, 1e-6, 0);   /* numpy: median of the nonzero raw values 6310 */
    /* labels: the three classes of cls_indexes (8, 14, 21) and background */
    int cnt[256] = {0};
    for (int k = 0; k < 640 * 480; k++) cnt[f.instance[k] & 255] += f.instance[k] < 256;
    int others = 640 * 480 - cnt[0] - cnt[8] - cnt[14] - cnt[21];
    printf("YCB-Video 0000 frame 1 labels: 8: %d, 14: %d, 21: %d px\n", cnt[8], cnt[14], cnt[21]);
    CHECK(others == 0 && cnt[8] > 10000 && cnt[14] > 10000 && cnt[21] > 10000);
    /* pose: rotation_translation_matrix is world-to-camera; T_wc its inverse,
     * so the camera centre is -R^T t = (-0.0893, -0.4545, 0.3914) */
    CHECK_CLOSE(f.T_wc[0], 0.998481, 1e-9, 0);          /* R^T: row 0 = column 0 of R */
    CHECK_CLOSE(f.T_wc[1], 0.00194755, 1e-9, 0);
    CHECK_CLOSE(f.T_wc[3], -0.0893, 1e-4, 0);
    CHECK_CLOSE(f.T_wc[7], -0.4545, 1e-4, 0);
    CHECK_CLOSE(f.T_wc[11], 0.3914, 1e-4, 0);

    /* the convention, checked on the data: the annotated objects stand still
     * in the world through T_wc (poses are object-to-camera), and do not
     * through the opposite reading of the matrix */
    double c0[8][3], w0[8][3], spread = 0, spread_wrong = 0;
    snprintf(p, sizeof p, "%s/000001-meta.mat", g_ycb);
    int no = object_centres(p, c0, 8);
    CHECK(no == 3);
    double T0[16], T0w[16];
    memcpy(T0, f.T_wc, sizeof T0);
    sooc_se3_inverse(T0w, T0);   /* the matrix as stored, read as camera-to-world */
    for (int k = 0; k < no; k++) sooc_se3_apply(w0[k], T0, c0[k]);
    for (int i = 1; i < 10; i++) {
        CHECK_OK(sooc_seq_read(s, i, &g));
        double ci[8][3], Tw[16];
        snprintf(p, sizeof p, "%s/%06d-meta.mat", g_ycb, i + 1);
        CHECK(object_centres(p, ci, 8) == no);
        sooc_se3_inverse(Tw, g.T_wc);
        for (int k = 0; k < no; k++) {
            double a[3], b[3], b0[3];
            sooc_se3_apply(a, g.T_wc, ci[k]);
            sooc_se3_apply(b, Tw, ci[k]);
            sooc_se3_apply(b0, T0w, c0[k]);
            double d = 0, dw = 0;
            for (int r = 0; r < 3; r++) {
                d += (a[r] - w0[k][r]) * (a[r] - w0[k][r]);
                dw += (b[r] - b0[r]) * (b[r] - b0[r]);
            }
            if (sqrt(d) > spread) spread = sqrt(d);
            if (sqrt(dw) > spread_wrong) spread_wrong = sqrt(dw);
        }
    }
    double e = tu_reproj_err(&f, &g);
    printf("YCB-Video 0000: object centres move %.2f mm in the world through T_wc = inverse(RT) over 10 frames, "
           "%.1f mm with RT read as camera-to-world; frames 1 -> 10 median reprojection depth error %.2f%%\n",
           1e3 * spread, 1e3 * spread_wrong, 100 * e);
    CHECK_MSG(spread < 0.001 && spread_wrong > 0.005, "object spread %.4f m, opposite reading %.4f m", spread,
              spread_wrong);
    CHECK_MSG(e >= 0 && e < 0.02, "reprojection %.4f", e);
    sooc_seq_close(s);

    /* the names: canonical and aliases */
    sooc_seq_open_params op;
    sooc_seq_open_params_default(&op);
    CHECK_OK(sooc_seq_format_parse("YCB", &op.format));
    CHECK(op.format == SOOC_SEQ_YCB);
    CHECK_OK(sooc_seq_format_parse("ycb-video", &op.format));
    s = NULL;
    CHECK_OK(sooc_seq_open(&s, g_ycb, &op));
    CHECK(s && sooc_seq_count(s) == 10);
    sooc_seq_close(s);
    sooc_frame_free(&f);
    sooc_frame_free(&g);
}

/* ------------------------------------------------------------------- APC */

static void test_apc(void) {
    sooc_seq *s = NULL;
    sooc_frame f = {0}, g = {0};
    CHECK_OK(sooc_seq_open(&s, g_apc, NULL));   /* auto: cam.info.txt, before the frame-*.color.png scan */
    if (!s) return;
    CHECK(sooc_seq_get_format(s) == SOOC_SEQ_APC);
    CHECK(sooc_seq_count(s) == 15 && sooc_seq_frame_number(s, 0) == 0 && sooc_seq_frame_number(s, 14) == 14);
    const sooc_intrinsics *K = &sooc_seq_calib(s)->K;   /* the colour camera's: depth is aligned to it */
    CHECK(K->width == 640 && K->height == 480);
    CHECK_CLOSE(K->fx, 615.195190, 1e-9, 0);
    CHECK_CLOSE(K->fy, 615.195251, 1e-9, 0);
    CHECK_CLOSE(K->cx, 298.442688, 1e-9, 0);
    CHECK_CLOSE(K->cy, 247.519196, 1e-9, 0);
    double sc;
    int sh, inv;
    sooc_seq_depth_decoding(s, &sc, &sh, &inv);
    CHECK(sc == 1e-4 && sh == 3 && inv == 0 && sooc_seq_depth_circular(s));
    CHECK(sooc_seq_has_labels(s) && sooc_seq_labels_predicted(s));
    static const char *objs[4] = {"creativity_chenille_stems", "i_am_a_bunny_book", "kleenex_tissue_box",
                                  "laugh_out_loud_joke_book"};
    for (int k = 0; k < 4; k++) CHECK(sooc_seq_label_name(s, k + 1) && !strcmp(sooc_seq_label_name(s, k + 1), objs[k]));
    CHECK(sooc_seq_label_name(s, 0) == NULL && sooc_seq_label_name(s, 5) == NULL);

    CHECK_OK(sooc_seq_read(s, 0, &f));
    CHECK(f.index == 0 && f.has_pose && f.instance);
    /* depth: the 16 bits rotated right by 3, x 1e-4 m (raw 33 -> 8196 -> 0.8196 m) */
    sooc_image raw = {0};
    char p[1400];
    snprintf(p, sizeof p, "%s/frame-000000.depth.png", g_apc);
    CHECK_OK(sooc_png_read(p, &raw));
    int bad = 0, nv = 0, n33 = 0, near = 0;
    static float zs[640 * 480];
    for (int k = 0; k < 640 * 480 && raw.data; k++) {
        unsigned r = ((const uint16_t *)raw.data)[k];
        unsigned v = ((r >> 3) | (r << 13)) & 0xffff;
        bad += f.depth[k] != (r ? (float)(v * 1e-4) : 0.0f);
        if (r == 33) n33 += f.depth[k] == (float)(8196 * 1e-4);
        if (f.valid[k]) zs[nv++] = f.depth[k], near += f.depth[k] < 0.15f;
    }
    sooc_image_free(&raw);
    CHECK_MSG(bad == 0, "%d pixels are not the rotated raw x 1e-4", bad);
    CHECK(n33 > 0);
    qsort(zs, (size_t)nv, sizeof *zs, cmp_float);
    printf("APC scene-0000 frame 0: %.1f%% valid depth, median %.4f m, %.1f%% of the valid pixels below 0.15 m\n",
           100.0 * nv / (640 * 480), zs[nv / 2], 100.0 * near / nv);
    CHECK_CLOSE(zs[nv / 2], 0.5496, 1e-6, 0);   /* numpy on the same decoding */
    /* pose: camera-to-world as written in cam.info.txt */
    static const double T0[12] = {4.35946526e-01, 3.73733732e-05, 8.99972569e-01, 1.17166368e+00,
                                  -8.99972541e-01, -2.35527389e-04, 4.35946522e-01, -1.63230649e-01,
                                  2.28260982e-04, -9.99999972e-01, -6.90423375e-05, 1.15679915e+00};
    for (int k = 0; k < 12; k++) CHECK_CLOSE(f.T_wc[k], T0[k], 1e-12, 0);
    /* labels: the thresholded masks, the most confident object per pixel;
     * counts from numpy on frames 0, 7 and 14 */
    static const int want[3][5] = {{280145, 3180, 15230, 8537, 108},
                                   {288360, 11248, 4963, 2230, 399},
                                   {280055, 90, 0, 9222, 17833}};
    static const int fr[3] = {0, 7, 14};
    for (int j = 0; j < 3; j++) {
        CHECK_OK(sooc_seq_read(s, fr[j], &g));
        int cnt[5] = {0}, other = 0;
        for (int k = 0; k < 640 * 480; k++)
            if (g.instance[k] < 5) cnt[g.instance[k]]++;
            else other++;
        CHECK_MSG(other == 0 && !memcmp(cnt, want[j], sizeof cnt), "frame %d labels %d %d %d %d %d", fr[j], cnt[0],
                  cnt[1], cnt[2], cnt[3], cnt[4]);
    }
    /* depth scale and poses agree across views */
    CHECK_OK(sooc_seq_read(s, 1, &g));
    double e = tu_reproj_err(&f, &g);
    printf("APC scene-0000: frames 0 -> 1 median reprojection depth error %.2f%%\n", 100 * e);
    CHECK_MSG(e >= 0 && e < 0.02, "reprojection %.4f", e);
    sooc_seq_close(s);
    sooc_frame_free(&f);
    sooc_frame_free(&g);
}

/* ----------------------------------------------------------- bad input */

static void test_ycb_errors(const char *tmp) {
    char d[1200], p[1400];
    snprintf(d, sizeof d, "%s/ycb", tmp);
    mkdir(d, 0755);
    static const char *kinds[] = {"color.png", "depth.png", "label.png", "meta.mat"};
    for (int i = 1; i <= 2; i++)
        for (int k = 0; k < 4; k++) {
            char name[64];
            snprintf(name, sizeof name, "%06d-%s", i, kinds[k]);
            cp_file(g_ycb, d, name);
        }
    sooc_seq *s = NULL;
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    CHECK(s && sooc_seq_count(s) == 2);
    sooc_seq_close(s);
    s = NULL;

    /* a truncated meta.mat: inside the data, and inside the header */
    snprintf(p, sizeof p, "%s/000002-meta.mat", d);
    truncate_to(p, 300);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "truncated or corrupt MAT-file");
    printf("truncated meta.mat: %s\n", sooc_errmsg());
    truncate_to(p, 100);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "truncated MAT-file: 100 bytes");
    CHECK(s == NULL);

    /* a meta.mat without rotation_translation_matrix */
    write_meta(p, 1066.778, NULL);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "missing key 'rotation_translation_matrix'");
    printf("missing key: %s\n", sooc_errmsg());
    /* complete but another camera, then a rotation that is not one */
    double rt[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.5};
    write_meta(p, 1000.0, rt);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "intrinsic_matrix differs", "000001-meta.mat");
    rt[0] = 1.2;
    write_meta(p, 1066.778, rt);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "rotation is not orthonormal");
    rt[0] = 1;
    write_meta(p, 1066.778, rt);
    CHECK_OK(sooc_seq_open(&s, d, NULL));   /* a meta.mat written by libmatio reads back */
    sooc_seq_close(s);
    s = NULL;
    /* an empty array element after the variables (0 bytes declared): libmatio would read an array's header
     * from the bytes after it (a name of 1.8 GB in the fuzz input tests/fuzz/corpus/ycb_meta/rss-1.8GB-*) */
    {
        static const uint8_t tail[40] = {14, 0, 0, 0, 0, 0, 0, 0, 6, 0, 0, 0, 8, 0, 0, 0, 6, 0, 0, 0, 0, 0, 0, 0,
                                         5, 0, 0, 0, 8, 0, 0, 0, 1, 0, 0, 0, 0x21, 0, 0, 0x6f};
        append_bytes(p, tail, sizeof tail);
        CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "an array element of 0 bytes");
        printf("an empty array element: %s\n", sooc_errmsg());
        write_meta(p, 1066.778, rt);
        /* an array whose flags element declares 0 bytes (libmatio reads 8 there whatever it declares) */
        static const uint8_t arr[56] = {14, 0, 0, 0, 48, 0, 0, 0, 6, 0, 0, 0, 0, 0, 0, 0, 5, 0, 0, 0, 8, 0, 0, 0,
                                        3, 0, 0, 0, 3, 0, 0, 0, 1, 0, 1, 0, 'a', 0, 0, 0, 9, 0, 0, 0, 8, 0, 0, 0,
                                        0, 0, 0, 0, 0, 0, 0xf0, 0x3f};
        append_bytes(p, arr, sizeof arr);
        CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "flags element has data type 6 and 0 bytes");
        printf("an array's flags of 0 bytes: %s\n", sooc_errmsg());
        write_meta(p, 1066.778, rt);
        /* a compressed array whose stream ends before its data tag (a 3x3 double named 'a', zlib stored
         * block): libmatio would take the tag from what follows and allocate what it declares */
        static const uint8_t zarr[67] = {
            0x0f, 0x00, 0x00, 0x00, 0x3b, 0x00, 0x00, 0x00, 0x78, 0x01, 0x01, 0x30, 0x00, 0xcf, 0xff, 0x0e, 0x00,
            0x00, 0x00, 0x64, 0x00, 0x00, 0x00, 0x06, 0x00, 0x00, 0x00, 0x08, 0x00, 0x00, 0x00, 0x06, 0x00, 0x00,
            0x00, 0x00, 0x00, 0x00, 0x00, 0x05, 0x00, 0x00, 0x00, 0x08, 0x00, 0x00, 0x00, 0x03, 0x00, 0x00, 0x00,
            0x03, 0x00, 0x00, 0x00, 0x01, 0x00, 0x01, 0x00, 0x61, 0x00, 0x00, 0x00, 0x19, 0xce, 0x00, 0xfd};
        append_bytes(p, zarr, sizeof zarr);
        CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "name and data run past its 40 bytes");
        printf("a compressed array without its data: %s\n", sooc_errmsg());
        write_meta(p, 1066.778, rt);
        /* a cell array beside the numeric ones (written by libmatio): refused by name of its class */
        mat_t *m = Mat_Open(p, MAT_ACC_RDWR);
        CHECK(m != NULL);
        if (m) {
            size_t d11[2] = {1, 1};
            double one = 1;
            matvar_t *cells[2] = {Mat_VarCreate(NULL, MAT_C_DOUBLE, MAT_T_DOUBLE, 2, d11, &one, 0), NULL};
            matvar_t *c = Mat_VarCreate("info", MAT_C_CELL, MAT_T_CELL, 2, d11, cells, 0);
            CHECK(c && Mat_VarWrite(m, c, MAT_COMPRESSION_NONE) == 0);
            Mat_VarFree(c);
            Mat_Close(m);
        }
        CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "MATLAB class 1 (cell)");
        printf("a cell array: %s\n", sooc_errmsg());
        write_meta(p, 1066.778, rt);
    }

    /* a depth PNG of the wrong size: open works, that frame's read names it */
    snprintf(p, sizeof p, "%s/000002-depth.png", d);
    put_gray16(p, 320, 240, 6000);
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        sooc_frame f = {0};
        CHECK_OK(sooc_seq_read(s, 0, &f));
        CHECK_ERR_HAS(sooc_seq_read(s, 1, &f), "000002-depth.png", "depth is 320x240", "640x480");
        printf("depth of the wrong size: %s\n", sooc_errmsg());
        sooc_frame_free(&f);
        sooc_seq_close(s);
        s = NULL;
    }
    /* a missing meta.mat */
    snprintf(p, sizeof p, "%s/000002-meta.mat", d);
    remove(p);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "000002-meta.mat", "missing file");
}

/* <dir>/cam.info.txt: the real one cut before frame `stop`'s pose, with
 * line `bad_line` (1-based; 0 = none) replaced by `bad`. */
static void write_cam_info(const char *dir, int stop, int bad_line, const char *bad) {
    char p[1400], key[64];
    snprintf(p, sizeof p, "%s/cam.info.txt", g_apc);
    void *buf;
    size_t n;
    if (sooc_file_read_all(p, 1 << 20, &buf, &n)) exit(1);
    char *t = buf;
    snprintf(key, sizeof key, "for frame-%06d", stop);
    char *cut = strstr(t, key);
    if (cut) {
        while (cut > t && cut[-1] != '\n') cut--;
        *cut = 0;
    }
    snprintf(p, sizeof p, "%s/cam.info.txt", dir);
    FILE *f = fopen(p, "wb");
    if (!f) exit(1);
    int line = 1;
    for (char *q = t; *q; line++) {
        char *e = strchr(q, '\n');
        size_t m = e ? (size_t)(e - q) : strlen(q);
        if (line == bad_line) fprintf(f, "%s\n", bad);
        else fprintf(f, "%.*s\n", (int)m, q);
        q += m + (e != NULL);
    }
    fclose(f);
    sooc_free(buf);
}

/* The 1-based line of the heading of frame `frame`'s pose in the real file. */
static int pose_heading_line(int frame) {
    char p[1400], key[64];
    snprintf(p, sizeof p, "%s/cam.info.txt", g_apc);
    void *buf;
    size_t n;
    if (sooc_file_read_all(p, 1 << 20, &buf, &n)) exit(1);
    snprintf(key, sizeof key, "for frame-%06d", frame);
    char *at = strstr(buf, key);
    int line = 1;
    for (char *q = buf; at && q < at; q++) line += *q == '\n';
    sooc_free(buf);
    return at ? line : -1;
}

static void test_apc_errors(const char *tmp) {
    char d[1200], md[1300], src[1300], p[1400], msg[256];
    snprintf(d, sizeof d, "%s/apc", tmp);
    snprintf(md, sizeof md, "%s/masks", d);
    snprintf(src, sizeof src, "%s/masks", g_apc);
    mkdir(d, 0755);
    mkdir(md, 0755);
    static const char *objs[4] = {"creativity_chenille_stems", "i_am_a_bunny_book", "kleenex_tissue_box",
                                  "laugh_out_loud_joke_book"};
    for (int i = 0; i < 2; i++) {
        char name[160];
        snprintf(name, sizeof name, "frame-%06d.color.png", i);
        cp_file(g_apc, d, name);
        snprintf(name, sizeof name, "frame-%06d.depth.png", i);
        cp_file(g_apc, d, name);
        for (int k = 0; k < 4; k++) {
            snprintf(name, sizeof name, "frame-%06d.%s.mask.png", i, objs[k]);
            cp_file(src, md, name);
        }
    }
    for (int k = 0; k < 4; k++) {
        char name[160];
        snprintf(name, sizeof name, "%s.thresh.txt", objs[k]);
        cp_file(src, md, name);
    }
    write_cam_info(d, 2, 0, NULL);
    sooc_seq *s = NULL;
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    CHECK(s && sooc_seq_count(s) == 2 && sooc_seq_get_format(s) == SOOC_SEQ_APC && sooc_seq_labels_predicted(s));
    sooc_seq_close(s);
    s = NULL;

    /* cam.info.txt: a pose row of 3 numbers, a word, a pose without its
     * last row, no colour intrinsics */
    int h1 = pose_heading_line(1);
    CHECK(h1 > 0);
    write_cam_info(d, 2, h1 + 2, "1 2 3");
    snprintf(msg, sizeof msg, "cam.info.txt:%d: expected 4 numbers (a row of the camera pose), got 3", h1 + 2);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), msg);
    printf("malformed cam.info.txt: %s\n", sooc_errmsg());
    write_cam_info(d, 2, h1 + 1, "1 0 zero 0");
    snprintf(msg, sizeof msg, "cam.info.txt:%d: 'zero' is not a finite number", h1 + 1);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), msg);
    write_cam_info(d, 2, h1 + 4, "");
    snprintf(msg, sizeof msg, "cam.info.txt:%d: the camera pose under this heading has 3 rows, expected 4", h1);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), msg);
    write_cam_info(d, 2, h1 + 2, "0.5 0 0 0");
    snprintf(msg, sizeof msg, "cam.info.txt:%d: rotation is not orthonormal", h1 + 1);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), msg);
    /* a frame number whose 30 Hz time stamp would not fit int64 nanoseconds */
    write_cam_info(d, 2, h1, "# Camera-to-world extrinsic matrix (camera pose) for frame-922337203685477580");
    snprintf(msg, sizeof msg, "cam.info.txt:%d: frame number '922337203685477580' is above 99999999999", h1);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), msg);
    write_cam_info(d, 2, 5, "# Colour camera intrinsics, misspelt");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "cam.info.txt:6: numbers under no known heading");
    CHECK(s == NULL);

    /* a missing mask, a malformed threshold */
    write_cam_info(d, 2, 0, NULL);
    snprintf(p, sizeof p, "%s/frame-000001.kleenex_tissue_box.mask.png", md);
    remove(p);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "frame-000001.kleenex_tissue_box.mask.png", "missing file");
    cp_file(src, md, "frame-000001.kleenex_tissue_box.mask.png");
    tu_write(md, "i_am_a_bunny_book.thresh.txt", "high\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "i_am_a_bunny_book.thresh.txt", "one confidence threshold");
    cp_file(src, md, "i_am_a_bunny_book.thresh.txt");

    /* a depth PNG and a mask of the wrong size: the read names each */
    snprintf(p, sizeof p, "%s/frame-000001.depth.png", d);
    put_gray16(p, 640, 240, 4000);
    snprintf(p, sizeof p, "%s/frame-000000.laugh_out_loud_joke_book.mask.png", md);
    put_gray16(p, 320, 480, 65535);
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        sooc_frame f = {0};
        CHECK_ERR_HAS(sooc_seq_read(s, 0, &f), "frame-000000.laugh_out_loud_joke_book.mask.png", "320x480");
        CHECK_ERR_HAS(sooc_seq_read(s, 1, &f), "frame-000001.depth.png", "depth is 640x240");
        printf("APC depth of the wrong size: %s\n", sooc_errmsg());
        sooc_frame_free(&f);
        sooc_seq_close(s);
    }
}

int main(void) {
    const char *real = tu_real_dir();
    if (!real) {
        printf("test_data_ycb_apc: SKIP: real data folder not found (set SOOC_SHARED_REAL or place ../shared/real)\n");
        return SOOC_TEST_SKIP;
    }
    snprintf(g_ycb, sizeof g_ycb, "%s/ycb_video/data/0000", real);
    snprintf(g_apc, sizeof g_apc, "%s/apc_shelf/data/sample/scene-0000", real);
    if (!sooc_dir_exists(g_ycb) || !sooc_dir_exists(g_apc)) {
        printf("test_data_ycb_apc: SKIP: real data: %s or %s not found (SOOC_SHARED_REAL)\n", g_ycb, g_apc);
        return SOOC_TEST_SKIP;
    }
    char *tmp = tu_tmpdir("ycbapc");
    test_ycb();
    test_apc();
    test_ycb_errors(tmp);
    test_apc_errors(tmp);
    tu_rm_rf(tmp);
    return check_report("test_data_ycb_apc");
}
