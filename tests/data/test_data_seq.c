/* Sequence readers: a crafted good sequence per format, then one crafted bad
 * file per reader check; every message must name the file and the line. */
#include "util.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <sys/stat.h>

#define W 16
#define H 12

static void put_png(const char *dir, const char *name, sooc_pixfmt fmt, int w, int h, int val) {
    sooc_image img = {0};
    if (sooc_image_alloc(&img, w, h, fmt)) exit(1);
    size_t n = (size_t)w * h;
    for (size_t i = 0; i < n; i++) {
        if (fmt == SOOC_PIX_GRAY16) ((uint16_t *)img.data)[i] = (uint16_t)(val + i);
        else if (fmt == SOOC_PIX_GRAY8) ((uint8_t *)img.data)[i] = (uint8_t)val;
        else for (int k = 0; k < 3; k++) ((uint8_t *)img.data)[3 * i + k] = (uint8_t)(val + k);
    }
    char path[900];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (sooc_png_write(path, &img, 1)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    sooc_image_free(&img);
}

static void calib_file(const char *dir, const char *name, double scale) {
    tu_write(dir, name, "%%YAML 1.2\n---\nimage_width: %d\nimage_height: %d\n"
             "camera_matrix: {rows: 3, cols: 3, data: [20, 0, 8, 0, 20, 6, 0, 0, 1]}\ndepth_scale: %g\n", W, H, scale);
}

static char *make_tum(void) {
    char *d = tu_tmpdir("tum");
    char p[900];
    snprintf(p, sizeof p, "%s/rgb", d); mkdir(p, 0755);
    snprintf(p, sizeof p, "%s/depth", d); mkdir(p, 0755);
    for (int i = 0; i < 3; i++) {
        char n[64];
        snprintf(n, sizeof n, "rgb/%d.png", i); put_png(d, n, SOOC_PIX_RGB8, W, H, 10 * i);
        snprintf(n, sizeof n, "depth/%d.png", i); put_png(d, n, SOOC_PIX_GRAY16, W, H, 5000);
    }
    tu_write(d, "rgb.txt", "0.000000 rgb/0.png\n0.100000 rgb/1.png\n0.200000 rgb/2.png\n");
    tu_write(d, "depth.txt", "# depth\n0.001000 depth/0.png\n0.101000 depth/1.png\n0.201000 depth/2.png\n");
    tu_write(d, "groundtruth.txt", "0.0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0.7071068 0 0.7071068\n0.2 0 0 0 0 0 0 1\n");
    calib_file(d, "calib.yaml", 2e-4);
    return d;
}

static void test_tum(void) {
    char *d = make_tum();
    sooc_seq *s = NULL;
    sooc_frame f = {0};
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    CHECK(s && sooc_seq_count(s) == 3);
    if (s) {
        CHECK_OK(sooc_seq_read(s, 1, &f));
        CHECK(f.width == W && f.has_pose && f.instance == NULL);
        CHECK_CLOSE(f.depth[0], 5000 * 2e-4, 1e-6, 0);
        CHECK_CLOSE(f.depth[5], 5005 * 2e-4, 1e-6, 0);
        CHECK_CLOSE(f.T_wc[3], 1, 1e-12, 0);
        CHECK_CLOSE(f.T_wc[2], 1, 1e-6, 0); /* 90 deg about y: R[0][2] = 1 */
        CHECK(f.t_ns == 100000000);
        sooc_seq_close(s);
        s = NULL;
    }
    char rgbtxt[700], dtxt[700], gt[700];
    snprintf(rgbtxt, sizeof rgbtxt, "%s/rgb.txt", d);
    snprintf(dtxt, sizeof dtxt, "%s/depth.txt", d);
    snprintf(gt, sizeof gt, "%s/groundtruth.txt", d);
    /* missing file */
    tu_write(d, "rgb.txt", "0.000000 rgb/0.png\n0.100000 rgb/nope.png\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "rgb.txt:2", "nope.png", "missing file");
    CHECK(s == NULL);
    tu_write(d, "rgb.txt", "0.000000 rgb/0.png\n0.100000 rgb/1.png\n0.200000 rgb/2.png\n");
    /* unparsable numbers */
    tu_write(d, "groundtruth.txt", "0.0 1 2 3 0 0 0 1\n0.1 1 2 zz 0 0 0 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "groundtruth.txt:2", "'zz'");
    tu_write(d, "depth.txt", "0.0x depth/0.png\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "depth.txt:1", "0.0x");
    /* non-monotonic timestamps */
    tu_write(d, "depth.txt", "0.001000 depth/0.png\n0.201000 depth/2.png\n0.101000 depth/1.png\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "depth.txt:3", "increase");
    tu_write(d, "depth.txt", "0.001000 depth/0.png\n0.101000 depth/1.png\n0.201000 depth/2.png\n");
    /* non-orthonormal rotation */
    tu_write(d, "groundtruth.txt", "0.0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0.5 0 0.5\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "groundtruth.txt:2", "orthonormal");
    tu_write(d, "groundtruth.txt", "0.0 1 2 3 0 0 0 1\n0.1 1 2 3 0 0 0 1\n0.2 1 2 3 0 0 0 1\n");
    /* missing list file */
    char cmd[2000];
    snprintf(cmd, sizeof cmd, "mv '%s' '%s.bak'", gt, gt);
    if (system(cmd)) {}
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "groundtruth.txt", "missing");
    snprintf(cmd, sizeof cmd, "mv '%s.bak' '%s'", gt, gt);
    if (system(cmd)) {}
    /* mismatched image sizes and wrong depth bit depth: found at read */
    put_png(d, "depth/1.png", SOOC_PIX_GRAY16, W / 2, H, 100);
    put_png(d, "depth/2.png", SOOC_PIX_GRAY8, W, H, 100);
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK_OK(sooc_seq_read(s, 0, &f));
        CHECK_ERR_HAS(sooc_seq_read(s, 1, &f), "rgb.txt:2", "depth/1.png", "8x12", "16x12");
        CHECK_ERR_HAS(sooc_seq_read(s, 2, &f), "rgb.txt:3", "depth/2.png", "16-bit");
        sooc_seq_close(s);
        s = NULL;
    }
    put_png(d, "rgb/0.png", SOOC_PIX_RGB8, W, H + 2, 1);
    put_png(d, "depth/0.png", SOOC_PIX_GRAY16, W, H + 2, 1);
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK_ERR_HAS(sooc_seq_read(s, 0, &f), "rgb.txt:1", "calibration says 16x12");
        sooc_seq_close(s);
        s = NULL;
    }
    /* calibration without depth_scale, and an explicit override */
    tu_write(d, "calib.yaml", "%%YAML 1.2\n---\nimage_width: %d\nimage_height: %d\n"
             "camera_matrix: {rows: 3, cols: 3, data: [20, 0, 8, 0, 20, 6, 0, 0, 1]}\n", W, H);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "depth_scale");
    sooc_seq_open_params op;
    sooc_seq_open_params_default(&op);
    op.depth_scale = 0.001;
    CHECK_OK(sooc_seq_open(&s, d, &op));
    sooc_seq_close(s);
    s = NULL;
    sooc_frame_free(&f);
    tu_rm_rf(d);
}

static const char *POSE4 = "1 0 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";

static void test_7scenes(void) {
    char *d = tu_tmpdir("7s");
    for (int i = 0; i < 2; i++) {
        char n[64];
        snprintf(n, sizeof n, "frame-%06d.color.png", i); put_png(d, n, SOOC_PIX_RGB8, W, H, 1);
        snprintf(n, sizeof n, "frame-%06d.depth.png", i); put_png(d, n, SOOC_PIX_GRAY16, W, H, 1000);
        snprintf(n, sizeof n, "frame-%06d.pose.txt", i); tu_write(d, n, "%s", POSE4);
    }
    tu_write(d, "camera-intrinsics.color.txt", "20 0 8\n0 20 6\n0 0 1\n");
    sooc_seq *s = NULL;
    sooc_frame f = {0};
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK(sooc_seq_count(s) == 2 && sooc_seq_get_format(s) == SOOC_SEQ_7SCENES);
        CHECK_OK(sooc_seq_read(s, 1, &f));
        CHECK_CLOSE(f.depth[0], 1.0, 1e-6, 0);
        CHECK_CLOSE(f.T_wc[3], 0.5, 1e-12, 0);
        CHECK(f.K.fx == 20 && f.K.cy == 6);
        double g[3] = {7, 7, 7};
        CHECK(sooc_seq_gravity(s, g) == 0 && g[0] == 7); /* no gravity-direction.txt */
        sooc_seq_close(s);
        s = NULL;
    }
    /* gravity-direction.txt: normalised; malformed files fail the open */
    tu_write(d, "gravity-direction.txt", "0\n3\n4\n");
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        double g[3] = {0};
        CHECK(sooc_seq_gravity(s, g) == 1);
        CHECK_CLOSE(g[0], 0, 1e-12, 0);
        CHECK_CLOSE(g[1], 0.6, 1e-12, 0);
        CHECK_CLOSE(g[2], 0.8, 1e-12, 0);
        sooc_seq_close(s);
        s = NULL;
    }
    tu_write(d, "gravity-direction.txt", "0 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "gravity-direction.txt", "expected 3 numbers");
    tu_write(d, "gravity-direction.txt", "0\n0\n0\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "gravity-direction.txt", "zero length");
    tu_write(d, "gravity-direction.txt", "0\nx\n1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "gravity-direction.txt:2", "'x'");
    char gp[900];
    snprintf(gp, sizeof gp, "%s/gravity-direction.txt", d);
    remove(gp);
    tu_write(d, "frame-000001.pose.txt", "1 0 0 0.5\n0 1 0 0 q\n0 0 1 0\n0 0 0 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "frame-000001.pose.txt:2");
    tu_write(d, "frame-000001.pose.txt", "1 0 0 0.5\n0 1 0 zz\n0 0 1 0\n0 0 0 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "frame-000001.pose.txt:2", "'zz'");
    tu_write(d, "frame-000001.pose.txt", "1 0.3 0 0.5\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "frame-000001.pose.txt:1", "orthonormal");
    tu_write(d, "frame-000001.pose.txt", "%s", POSE4);
    char p[900];
    snprintf(p, sizeof p, "%s/frame-000001.depth.png", d);
    remove(p);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "frame-000001.depth.png", "missing file");
    put_png(d, "frame-000001.depth.png", SOOC_PIX_GRAY8, W, H, 3);
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK_ERR_HAS(sooc_seq_read(s, 1, &f), "frame-000001.depth.png", "16-bit");
        sooc_seq_close(s);
        s = NULL;
    }
    tu_write(d, "camera-intrinsics.color.txt", "20 0 8\n0 20\n0 0 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "camera-intrinsics.color.txt:2");
    sooc_frame_free(&f);
    tu_rm_rf(d);
}

static void put_jpg(const char *dir, const char *name, int w, int h, int val) {
    sooc_image img = {0};
    if (sooc_image_alloc(&img, w, h, SOOC_PIX_RGB8)) exit(1);
    memset(img.data, val, (size_t)w * h * 3);
    char path[900];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (sooc_jpeg_write(path, &img, 95)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    sooc_image_free(&img);
}

/* A 16-bit depth PNG holding `v` everywhere except pixel 1 (= v2). */
static void put_depth(const char *dir, const char *name, uint16_t v, uint16_t v2) {
    sooc_image img = {0};
    if (sooc_image_alloc(&img, W, H, SOOC_PIX_GRAY16)) exit(1);
    for (int k = 0; k < W * H; k++) ((uint16_t *)img.data)[k] = v;
    ((uint16_t *)img.data)[1] = v2;
    char path[900];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (sooc_png_write(path, &img, 1)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    sooc_image_free(&img);
}

/* 7-Scenes as shipped: JPEG colour, camera-intrinsics.txt, millimetres with
 * 65535 = invalid; numbering that starts at 40 with gaps; the label-fusion
 * encoding (auto-detected, by name, by calib keys, by parameters); a
 * truncated JPEG names the file and leaves the sequence readable. */
static void test_7scenes_shipped(void) {
    char *d = tu_tmpdir("7sj");
    static const int nums[] = {40, 42, 47};
    for (int i = 0; i < 3; i++) {
        char n[64];
        snprintf(n, sizeof n, "frame-%06d.color.jpg", nums[i]); put_jpg(d, n, W, H, 100 + 20 * i);
        snprintf(n, sizeof n, "frame-%06d.depth.png", nums[i]); put_depth(d, n, 1234, 65535);
        snprintf(n, sizeof n, "frame-%06d.pose.txt", nums[i]); tu_write(d, n, "%s", POSE4);
    }
    tu_write(d, "frame-000100.segm.png", "not a frame");      /* other files are ignored */
    tu_write(d, "camera-intrinsics.txt", "30 0 8\n0 30 6\n0 0 1\n");
    sooc_seq *s = NULL;
    sooc_frame f = {0};
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK(sooc_seq_get_format(s) == SOOC_SEQ_7SCENES && sooc_seq_count(s) == 3);
        for (int i = 0; i < 3 && i < sooc_seq_count(s); i++) {
            CHECK_OK(sooc_seq_read(s, i, &f));
            CHECK_MSG(f.index == nums[i] && sooc_seq_frame_number(s, i) == nums[i], "frame %d: index %lld", i,
                      (long long)f.index);
            CHECK(f.t_ns == nums[i] * 33333333LL && sooc_seq_frame_time(s, i) == f.t_ns);
            CHECK(abs(f.rgb[0] - (100 + 20 * i)) <= 2);          /* JPEG of a flat colour */
        }
        CHECK(f.K.fx == 30 && f.K.width == W && f.K.height == H);
        CHECK_CLOSE(f.depth[0], 1.234, 1e-6, 0);
        CHECK(f.valid[1] == 0 && f.depth[1] == 0);               /* 65535 = invalid */
        double sc; int sh, inv;
        sooc_seq_depth_decoding(s, &sc, &sh, &inv);
        CHECK(sc == 0.001 && sh == 0 && inv == 65535);
        CHECK(strstr(sooc_seq_color_path(s, 2), "frame-000047.color.jpg") != NULL);
        CHECK(sooc_seq_color_path(s, 3) == NULL && sooc_seq_frame_number(s, -1) == -1);
        CHECK(sooc_seq_frame_time(s, 3) == INT64_MIN && sooc_seq_depth_path(s, -1) == NULL);
        sooc_seq_close(s);
        s = NULL;
    }
    /* every name of the format opens it */
    static const char *names7[] = {"7scenes", "sevenscenes", "7-Scenes", "auto"};
    for (int k = 0; k < 4; k++) {
        sooc_seq_open_params p;
        sooc_seq_open_params_default(&p);
        CHECK_OK(sooc_seq_format_parse(names7[k], &p.format));
        CHECK_OK(sooc_seq_open(&s, d, &p));
        CHECK(s && sooc_seq_get_format(s) == SOOC_SEQ_7SCENES);
        sooc_seq_close(s);
        s = NULL;
    }
    /* a truncated JPEG: the error names the file; other frames still read */
    char jp[900];
    snprintf(jp, sizeof jp, "%s/frame-000042.color.jpg", d);
    void *buf;
    size_t n;
    CHECK_OK(sooc_file_read_all(jp, 1 << 20, &buf, &n));
    FILE *fp = fopen(jp, "wb");
    if (fp) { fwrite(buf, 1, n / 2, fp); fclose(fp); }
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK_ERR_HAS(sooc_seq_read(s, 1, &f), "frame-000042.color.jpg", "corrupt JPEG");
        CHECK_OK(sooc_seq_read(s, 2, &f));
        CHECK(f.index == 47 && f.valid[0]);
        sooc_seq_close(s);
        s = NULL;
    }
    fp = fopen(jp, "wb");
    if (fp) { fwrite(buf, 1, n, fp); fclose(fp); }
    sooc_free(buf);
    /* camera-intrinsics.color.txt wins over camera-intrinsics.txt */
    tu_write(d, "camera-intrinsics.color.txt", "25 0 8\n0 25 6\n0 0 1\n");
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) { CHECK(sooc_seq_calib(s)->K.fx == 25); sooc_seq_close(s); s = NULL; }
    tu_write(d, "camera-intrinsics.txt", "30 0 8\n0 30\n0 0 1\n");
    tu_write(d, "camera-intrinsics.color.txt", "");
    snprintf(jp, sizeof jp, "%s/camera-intrinsics.color.txt", d);
    remove(jp);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "camera-intrinsics.txt:2", "expected 3 numbers");
    tu_write(d, "camera-intrinsics.txt", "30 0 8\n0 30 6\n0 0 1\n");

    /* label-fusion encoding: depth << 3 in 0.1 mm units */
    for (int i = 0; i < 3; i++) {
        char nm[64];
        snprintf(nm, sizeof nm, "frame-%06d.depth.png", nums[i]);
        put_depth(d, nm, (uint16_t)(4560 << 3), (uint16_t)(4560 << 3));
    }
    CHECK_OK(sooc_seq_open(&s, d, NULL));        /* auto: multiples of 8 -> label-fusion */
    if (s) {
        CHECK(sooc_seq_get_format(s) == SOOC_SEQ_LABELFUSION);
        CHECK_OK(sooc_seq_read(s, 0, &f));
        CHECK_CLOSE(f.depth[0], 0.456, 1e-6, 0);
        sooc_seq_close(s);
        s = NULL;
    }
    static const char *namesl[] = {"label-fusion", "labelfusion", "LABEL_FUSION"};
    for (int k = 0; k < 3; k++) {
        sooc_seq_open_params p;
        sooc_seq_open_params_default(&p);
        CHECK_OK(sooc_seq_format_parse(namesl[k], &p.format));
        CHECK(p.format == SOOC_SEQ_LABELFUSION);
        CHECK_OK(sooc_seq_open(&s, d, &p));
        if (s) {
            CHECK_OK(sooc_seq_read(s, 2, &f));
            CHECK_CLOSE(f.depth[5], 0.456, 1e-6, 0);
            sooc_seq_close(s);
            s = NULL;
        }
    }
    /* forced 7scenes reads the same files as millimetres */
    sooc_seq_open_params p;
    sooc_seq_open_params_default(&p);
    p.format = SOOC_SEQ_7SCENES;
    CHECK_OK(sooc_seq_open(&s, d, &p));
    if (s) {
        CHECK_OK(sooc_seq_read(s, 0, &f));
        CHECK_CLOSE(f.depth[0], (4560 << 3) * 1e-3, 1e-4, 0);
        sooc_seq_close(s);
        s = NULL;
    }
    /* calib keys depth_shift / depth_invalid, then parameters over the calib */
    tu_write(d, "calib.yaml", "%%YAML 1.2\n---\nimage_width: %d\nimage_height: %d\n"
             "camera_matrix: {rows: 3, cols: 3, data: [20, 0, 8, 0, 20, 6, 0, 0, 1]}\n"
             "depth_scale: 0.001\ndepth_shift: 2\ndepth_invalid: %d\n", W, H, 4560 << 3);
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK_OK(sooc_seq_read(s, 0, &f));
        CHECK(f.valid[0] == 0 && f.depth[0] == 0);               /* the calib's invalid value */
        sooc_seq_close(s);
        s = NULL;
    }
    p.format = SOOC_SEQ_AUTO;
    p.depth_invalid = 0;
    CHECK_OK(sooc_seq_open(&s, d, &p));
    if (s) {
        CHECK_OK(sooc_seq_read(s, 0, &f));
        CHECK_CLOSE(f.depth[0], (4560 << 1) * 1e-3, 1e-4, 0);   /* shift 2, scale 1e-3 from calib */
        sooc_seq_close(s);
        s = NULL;
    }
    p.depth_shift = 16;
    CHECK_ERR_HAS(sooc_seq_open(&s, d, &p), "depth_shift 16");
    tu_write(d, "calib.yaml", "%%YAML 1.2\n---\nimage_width: %d\nimage_height: %d\n"
             "camera_matrix: {rows: 3, cols: 3, data: [20, 0, 8, 0, 20, 6, 0, 0, 1]}\ndepth_shift: 17\n", W, H);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "calib.yaml:6", "depth_shift");
    sooc_frame_free(&f);
    tu_rm_rf(d);
}

static void test_format_names(void) {
    int n = 0;
    const sooc_seq_format_info *t = sooc_seq_formats(&n);
    CHECK(n == SOOC_SEQ_FORMAT_COUNT && t);
    char list[1024];
    size_t len = sooc_seq_format_list(list, sizeof list);
    CHECK(len == strlen(list));
    for (int i = 0; i < n; i++) {
        sooc_seq_format f = (sooc_seq_format)-1;
        CHECK(t[i].format == (sooc_seq_format)i);
        CHECK(!strcmp(sooc_seq_format_name(t[i].format), t[i].name));
        CHECK(sooc_seq_format_info_of(t[i].format) == &t[i]);
        CHECK_OK(sooc_seq_format_parse(t[i].name, &f));
        CHECK(f == t[i].format);
        CHECK_MSG(strstr(list, t[i].name) != NULL, "'%s' not in the list '%s'", t[i].name, list);
        char al[128];
        snprintf(al, sizeof al, "%s", t[i].aliases);
        for (char *tok = strtok(al, "|"); tok; tok = strtok(NULL, "|")) {
            f = (sooc_seq_format)-1;
            CHECK_OK(sooc_seq_format_parse(tok, &f));
            CHECK_MSG(f == t[i].format, "alias %s", tok);
            CHECK_MSG(strstr(list, tok) != NULL, "alias '%s' not in the list", tok);
        }
    }
    sooc_seq_format f;
    CHECK_ERR_HAS(sooc_seq_format_parse("scannet", &f), "unknown sequence format 'scannet'", "7scenes (sevenscenes");
    CHECK(sooc_seq_format_parse(NULL, &f) != SOOC_OK);
    CHECK(sooc_seq_format_info_of((sooc_seq_format)SOOC_SEQ_FORMAT_COUNT) == NULL);
}

static void test_slambook(void) {
    char *d = tu_tmpdir("sb");
    char p[900];
    snprintf(p, sizeof p, "%s/color", d); mkdir(p, 0755);
    snprintf(p, sizeof p, "%s/depth", d); mkdir(p, 0755);
    for (int i = 1; i <= 2; i++) {
        char n[64];
        snprintf(n, sizeof n, "color/%d.png", i); put_png(d, n, SOOC_PIX_RGB8, W, H, 1);
        sooc_image img = {0};
        sooc_image_alloc(&img, W, H, SOOC_PIX_GRAY16);
        for (int k = 0; k < W * H; k++) ((uint16_t *)img.data)[k] = 1500;
        snprintf(p, sizeof p, "%s/depth/%d.pgm", d, i);
        CHECK_OK(sooc_pgm_write(p, &img));
        sooc_image_free(&img);
    }
    tu_write(d, "pose.txt", "0 0 0 0 0 0 1\n1 2 3 0 0 0 1");   /* no final newline, like the real file */
    sooc_seq *s = NULL;
    sooc_frame f = {0};
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "calib.yaml", "missing");
    calib_file(d, "calib.yaml", 0.001);
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK(sooc_seq_count(s) == 2 && sooc_seq_get_format(s) == SOOC_SEQ_SLAMBOOK);
        CHECK_OK(sooc_seq_read(s, 1, &f));
        CHECK_CLOSE(f.depth[3], 1.5, 1e-6, 0);
        CHECK_CLOSE(f.T_wc[11], 3, 1e-12, 0);
        sooc_seq_close(s);
        s = NULL;
    }
    tu_write(d, "pose.txt", "0 0 0 0 0 0 1\n1 2 3 0 0 x 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "pose.txt:2", "'x'");
    tu_write(d, "pose.txt", "0 0 0 0 0 0 1\n1 2 3 0 0 0 1.1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "pose.txt:2", "orthonormal");
    /* a listed frame with neither image is a trimmed copy: skipped; with only one, an error */
    tu_write(d, "pose.txt", "0 0 0 0 0 0 1\n1 2 3 0 0 0 1\n0 0 0 0 0 0 1\n");
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK(sooc_seq_count(s) == 2 && sooc_seq_frame_number(s, 1) == 2);
        sooc_seq_close(s);
        s = NULL;
    }
    put_png(d, "depth/3.png", SOOC_PIX_GRAY16, W, H, 1000);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "pose.txt:3", "color/3.png", "missing file");
    snprintf(p, sizeof p, "%s/depth/3.png", d);
    remove(p);
    tu_write(d, "pose.txt", "0 0 0 0 0 0 1\n1 2 3 0 0 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "pose.txt:2", "expected 7 numbers");
    sooc_frame_free(&f);
    tu_rm_rf(d);
}

static void test_replica(void) {
    char *d = tu_tmpdir("rep");
    char p[900];
    snprintf(p, sizeof p, "%s/results", d); mkdir(p, 0755);
    for (int i = 0; i < 2; i++) {
        char n[64];
        snprintf(n, sizeof n, "results/frame%06d.png", i); put_png(d, n, SOOC_PIX_RGB8, W, H, 1);
        snprintf(n, sizeof n, "results/depth%06d.png", i); put_png(d, n, SOOC_PIX_GRAY16, W, H, 6553);
    }
    calib_file(d, "calib.yaml", 1 / 6553.5);
    const char *good = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n";
    tu_write(d, "traj.txt", "%s%s", good, good);
    sooc_seq *s = NULL;
    sooc_frame f = {0};
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK(sooc_seq_count(s) == 2 && sooc_seq_get_format(s) == SOOC_SEQ_REPLICA);
        CHECK_OK(sooc_seq_read(s, 1, &f));
        CHECK_CLOSE(f.depth[0], 6553 / 6553.5, 1e-5, 0);
        sooc_seq_close(s);
        s = NULL;
    }
    tu_write(d, "traj.txt", "%s1 0 0 0 0 1 0 0 0 0 1 0 0 0 0\n", good);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "traj.txt:2", "expected 16 numbers");
    tu_write(d, "traj.txt", "%s1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1e\n", good);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "traj.txt:2", "'1e'");
    tu_write(d, "traj.txt", "1 0 0 0 0 2 0 0 0 0 1 0 0 0 0 1\n");
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "traj.txt:1", "orthonormal");
    /* trimmed: frame 0 removed, a pose line past the last frame: 1 frame, number 1 */
    tu_write(d, "traj.txt", "%s%s%s", good, good, good);
    snprintf(p, sizeof p, "%s/results/frame000000.png", d);
    remove(p);
    snprintf(p, sizeof p, "%s/results/depth000000.png", d);
    remove(p);
    CHECK_OK(sooc_seq_open(&s, d, NULL));
    if (s) {
        CHECK(sooc_seq_count(s) == 1 && sooc_seq_frame_number(s, 0) == 1);
        CHECK_OK(sooc_seq_read(s, 0, &f));
        CHECK(f.index == 1 && f.t_ns == 33333333LL);
        sooc_seq_close(s);
        s = NULL;
    }
    put_png(d, "results/depth000002.png", SOOC_PIX_GRAY16, W, H, 6553);
    CHECK_ERR_HAS(sooc_seq_open(&s, d, NULL), "traj.txt:3", "frame000002", "missing file");
    sooc_frame_free(&f);
    tu_rm_rf(d);
}

int main(void) {
    test_tum();
    test_7scenes();
    test_7scenes_shipped();
    test_format_names();
    test_slambook();
    test_replica();
    sooc_seq *s = NULL;
    CHECK_ERR_HAS(sooc_seq_open(&s, "/nonexistent/seq", NULL), "/nonexistent/seq");
    return check_report("test_data_seq");
}
