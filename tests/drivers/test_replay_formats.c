/* Every documented sequence format name (docs/formats.md §2.0, checked
 * against the one table in src/data/seq.c) through the launch parser and the
 * replay driver, each on a small sequence of its own layout written here;
 * plus the launch keys depth_shift / depth_invalid and the errors for an
 * unknown name. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "check.h"
#include "sooc3d/driver.h"
#include "sooc3d/core.h"
#include "sooc3d/node.h"
#include "sooc3d/frame.h"

#include <matio.h>

#define W 32
#define H 24

static char g_tmp[512];

static void wtext(const char *path, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void wtext(const char *path, const char *fmt, ...) {
    FILE *f = fopen(path, "wb");
    if (!f) { perror(path); exit(1); }
    va_list ap;
    va_start(ap, fmt);
    vfprintf(f, fmt, ap);
    va_end(ap);
    fclose(f);
}

static void put_rgb(const char *path, int val, int jpeg) {
    sooc_image img = {0};
    if (sooc_image_alloc(&img, W, H, SOOC_PIX_RGB8)) exit(1);
    memset(img.data, val, (size_t)W * H * 3);
    sooc_status st = jpeg ? sooc_jpeg_write(path, &img, 95) : sooc_png_write(path, &img, 1);
    if (st) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    sooc_image_free(&img);
}

static void put_depth(const char *path, uint16_t v, int pgm) {
    sooc_image img = {0};
    if (sooc_image_alloc(&img, W, H, SOOC_PIX_GRAY16)) exit(1);
    for (int k = 0; k < W * H; k++) ((uint16_t *)img.data)[k] = v;
    sooc_status st = pgm ? sooc_pgm_write(path, &img) : sooc_png_write(path, &img, 1);
    if (st) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    sooc_image_free(&img);
}

static void calib_yaml(const char *path, const char *extra) {
    wtext(path, "%%YAML 1.2\n---\nimage_width: %d\nimage_height: %d\n"
          "camera_matrix: {rows: 3, cols: 3, data: [30, 0, 16, 0, 30, 12, 0, 0, 1]}\n%s", W, H, extra);
}

/* One small sequence per format; returns its directory. Expected depth of
 * every pixel of the first frame in *z. */
static const char *make_seq(sooc_seq_format f, double *z) {
    static char dirs[SOOC_SEQ_FORMAT_COUNT][700];
    static double zs[SOOC_SEQ_FORMAT_COUNT];
    char *d = dirs[f];
    char p[4400];
    if (d[0]) { *z = zs[f]; return d; }
    snprintf(d, sizeof dirs[0], "%s/%s", g_tmp, sooc_seq_format_name(f));
    mkdir(d, 0755);
    static const char *pose4 = "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
    switch (f) {
    case SOOC_SEQ_AUTO:
    case SOOC_SEQ_TUM:
        snprintf(p, sizeof p, "%s/rgb", d); mkdir(p, 0755);
        snprintf(p, sizeof p, "%s/depth", d); mkdir(p, 0755);
        for (int i = 0; i < 2; i++) {
            snprintf(p, sizeof p, "%s/rgb/%d.png", d, i); put_rgb(p, 50 + i, 0);
            snprintf(p, sizeof p, "%s/depth/%d.png", d, i); put_depth(p, 5000, 0);
        }
        snprintf(p, sizeof p, "%s/rgb.txt", d); wtext(p, "0.0 rgb/0.png\n0.1 rgb/1.png\n");
        snprintf(p, sizeof p, "%s/depth.txt", d); wtext(p, "0.0 depth/0.png\n0.1 depth/1.png\n");
        snprintf(p, sizeof p, "%s/groundtruth.txt", d); wtext(p, "0.0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0 1\n");
        snprintf(p, sizeof p, "%s/calib.yaml", d); calib_yaml(p, "depth_scale: 0.0002\n");
        *z = 1.0;
        break;
    case SOOC_SEQ_7SCENES:
    case SOOC_SEQ_LABELFUSION: {
        int lf = f == SOOC_SEQ_LABELFUSION;
        for (int i = 3; i <= 5; i += 2) {
            snprintf(p, sizeof p, "%s/frame-%06d.color.%s", d, i, lf ? "png" : "jpg"); put_rgb(p, 60, !lf);
            snprintf(p, sizeof p, "%s/frame-%06d.depth.png", d, i); put_depth(p, lf ? 5000 << 3 : 1500, 0);
            snprintf(p, sizeof p, "%s/frame-%06d.pose.txt", d, i); wtext(p, "%s", pose4);
        }
        snprintf(p, sizeof p, "%s/camera-intrinsics%s.txt", d, lf ? ".color" : "");
        wtext(p, "30 0 16\n0 30 12\n0 0 1\n");
        *z = lf ? 0.5 : 1.5;
        break;
    }
    case SOOC_SEQ_SLAMBOOK:
        snprintf(p, sizeof p, "%s/color", d); mkdir(p, 0755);
        snprintf(p, sizeof p, "%s/depth", d); mkdir(p, 0755);
        snprintf(p, sizeof p, "%s/color/1.png", d); put_rgb(p, 70, 0);
        snprintf(p, sizeof p, "%s/depth/1.pgm", d); put_depth(p, 2000, 1);
        snprintf(p, sizeof p, "%s/pose.txt", d); wtext(p, "0 0 0 0 0 0 1\n");
        snprintf(p, sizeof p, "%s/calib.yaml", d); calib_yaml(p, "depth_scale: 0.001\n");
        *z = 2.0;
        break;
    case SOOC_SEQ_REPLICA:
        snprintf(p, sizeof p, "%s/results", d); mkdir(p, 0755);
        snprintf(p, sizeof p, "%s/results/frame000000.jpg", d); put_rgb(p, 80, 1);
        snprintf(p, sizeof p, "%s/results/depth000000.png", d); put_depth(p, 5243, 0);
        snprintf(p, sizeof p, "%s/traj.txt", d); wtext(p, "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n");
        snprintf(p, sizeof p, "%s/calib.yaml", d); calib_yaml(p, ""); /* depth: the format default */
        *z = 5243 / 6553.5;
        break;
    case SOOC_SEQ_YCB: {   /* meta.mat written with libmatio (column-major), depth / factor_depth */
        snprintf(p, sizeof p, "%s/000001-color.png", d); put_rgb(p, 90, 0);
        snprintf(p, sizeof p, "%s/000001-depth.png", d); put_depth(p, 5000, 0);
        snprintf(p, sizeof p, "%s/000001-meta.mat", d);
        mat_t *m = Mat_CreateVer(p, NULL, MAT_FT_MAT5);
        if (!m) exit(1);
        size_t d33[2] = {3, 3}, d11[2] = {1, 1}, d34[2] = {3, 4};
        double K[9] = {30, 0, 0, 0, 30, 0, 16, 12, 1}, fd = 10000, RT[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
        matvar_t *v = Mat_VarCreate("intrinsic_matrix", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, d33, K, 0);
        Mat_VarWrite(m, v, MAT_COMPRESSION_NONE);
        Mat_VarFree(v);
        v = Mat_VarCreate("factor_depth", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, d11, &fd, 0);
        Mat_VarWrite(m, v, MAT_COMPRESSION_NONE);
        Mat_VarFree(v);
        v = Mat_VarCreate("rotation_translation_matrix", MAT_C_DOUBLE, MAT_T_DOUBLE, 2, d34, RT, 0);
        Mat_VarWrite(m, v, MAT_COMPRESSION_NONE);
        Mat_VarFree(v);
        Mat_Close(m);
        *z = 0.5;
        break;
    }
    case SOOC_SEQ_APC:   /* 9000 (0.9 m) rotated left by 3 on 16 bits is 6465 */
        snprintf(p, sizeof p, "%s/frame-000000.color.png", d); put_rgb(p, 100, 0);
        snprintf(p, sizeof p, "%s/frame-000000.depth.png", d); put_depth(p, 6465, 0);
        snprintf(p, sizeof p, "%s/cam.info.txt", d);
        wtext(p, "# Color camera intrinsic matrix\n30 0 16\n0 30 12\n0 0 1\n\n"
                 "# Camera-to-world extrinsic matrix (camera pose) for frame-000000\n%s", pose4);
        *z = 0.9;
        break;
    case SOOC_SEQ_SOURCE:   /* frames from another reader (a log): not a layout of the table */
        break;
    }
    zs[f] = *z;
    return d;
}

/* Launch text -> config -> sensor params (the node's mapping: path -> uri,
 * format auto -> NULL) -> replay -> first frame; returns its depth[5] or -1. */
static double via_launch(const char *dir, const char *fmt, const char *extra, char *err, size_t errcap) {
    char text[2048];
    snprintf(text, sizeof text, "sensor: {driver: replay, path: '%s', format: '%s', speed: fast%s}\n"
             "model: {path: fake.bin}\n", dir, fmt, extra);
    sooc_node_config c;
    err[0] = 0;
    if (sooc_node_config_parse(&c, text, strlen(text), "formats.yaml")) {
        snprintf(err, errcap, "launch: %s", sooc_errmsg());
        return -1;
    }
    sooc_sensor_params sp;
    sooc_sensor_params_default(&sp);
    for (int i = 0; i < c.n_params; i++) {
        const char *k = c.params[i].key, *v = c.params[i].value;
        if (!strcmp(k, "path")) k = "uri";
        if (!strcmp(k, "speed")) v = "0";
        if (sooc_sensor_params_set(&sp, k, v)) {
            snprintf(err, errcap, "params: %s", sooc_errmsg());
            return -1;
        }
    }
    sooc_sensor *s = NULL;
    if (sooc_sensor_open(&s, "replay", &sp)) {
        snprintf(err, errcap, "replay: %s", sooc_errmsg());
        return -1;
    }
    sooc_frame f = {0};
    double z = -1;
    if (sooc_sensor_start(s) || sooc_sensor_read(s, &f, 1000)) snprintf(err, errcap, "read: %s", sooc_errmsg());
    else z = f.depth[5];
    sooc_sensor_close(s);
    sooc_frame_free(&f);
    return z;
}

/* The documented table: rows between the format-names markers of
 * docs/formats.md, `name` | `alias`, `alias` | ... */
typedef struct docrow {
    char name[64];
    char aliases[256]; /* '|'-separated like the code table */
} docrow;

static int read_doc_rows(docrow *rows, int cap) {
    void *buf;
    size_t n;
    if (sooc_file_read_all("docs/formats.md", 1 << 22, &buf, &n)) return -1;
    char *t = buf;
    t[n - 1] = 0;
    char *a = strstr(t, "<!-- format-names"), *b = a ? strstr(a, "<!-- /format-names") : NULL;
    int k = 0;
    if (a && b) {
        *b = 0;
        for (char *line = strtok(a, "\n"); line && k < cap; line = strtok(NULL, "\n")) {
            if (strncmp(line, "| `", 3)) continue;
            char *c1 = line + 3, *e1 = strchr(c1, '`');
            if (!e1) continue;
            *e1 = 0;
            snprintf(rows[k].name, sizeof rows[k].name, "%s", c1);
            rows[k].aliases[0] = 0;
            char *c2 = strchr(e1 + 1, '|');
            char *end = c2 ? strchr(c2 + 1, '|') : NULL;
            if (c2 && end) {
                *end = 0;
                for (char *q = strchr(c2, '`'); q; q = strchr(q, '`')) {
                    char *qe = strchr(q + 1, '`');
                    if (!qe) break;
                    *qe = 0;
                    size_t l = strlen(rows[k].aliases);
                    snprintf(rows[k].aliases + l, sizeof rows[k].aliases - l, "%s%s", l ? "|" : "", q + 1);
                    q = qe + 1;
                }
            }
            k++;
        }
    }
    sooc_free(buf);
    return k;
}

int main(void) {
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc_fmtnames_XXXXXX");
    if (!mkdtemp(g_tmp)) return 1;
    int nt = 0;
    const sooc_seq_format_info *t = sooc_seq_formats(&nt);

    /* the documentation and the code table name the same formats and aliases */
    docrow rows[32];
    int nd = read_doc_rows(rows, 32);
    CHECK_MSG(nd == nt, "docs/formats.md §2.0 lists %d formats, the table in seq.c %d", nd, nt);
    for (int i = 0; i < nd; i++) {
        sooc_seq_format f;
        CHECK_OK(sooc_seq_format_parse(rows[i].name, &f));
        const sooc_seq_format_info *fi = sooc_seq_format_info_of(f);
        CHECK_MSG(fi && !strcmp(fi->name, rows[i].name), "documented '%s' is not a canonical name", rows[i].name);
        CHECK_MSG(fi && !strcmp(fi->aliases, rows[i].aliases), "%s: documented aliases '%s', table '%s'",
                  rows[i].name, rows[i].aliases, fi ? fi->aliases : "?");
    }

    /* every name and alias: launch parser -> replay driver -> the right decoding */
    int runs = 0;
    for (int i = 0; i < nt; i++) {
        double z = 0;
        const char *dir = make_seq(t[i].format, &z);
        char names[320];
        snprintf(names, sizeof names, "%s%s%s", t[i].name, t[i].aliases[0] ? "|" : "", t[i].aliases);
        for (char *nm = strtok(names, "|"); nm; nm = strtok(NULL, "|")) {
            char err[1200];
            double got = via_launch(dir, nm, "", err, sizeof err);
            CHECK_MSG(fabs(got - z) < 1e-3, "format '%s' on %s: depth %.4f, expected %.4f %s", nm, dir, got, z, err);
            runs++;
        }
    }
    /* auto on every layout, and the label-fusion layout read by each */
    for (int i = 1; i < nt; i++) {
        double z = 0;
        const char *dir = make_seq(t[i].format, &z);
        char err[1200];
        double got = via_launch(dir, "auto", "", err, sizeof err);
        CHECK_MSG(fabs(got - z) < 1e-3, "auto on %s: depth %.4f, expected %.4f %s", dir, got, z, err);
        runs++;
    }
    printf("test_replay_formats: %d launch -> replay runs over %d formats\n", runs, nt);

    /* launch keys depth_shift / depth_invalid reach the reader */
    double z;
    sooc_sensor_params sp;
    const char *lf = make_seq(SOOC_SEQ_LABELFUSION, &z);
    char err[1200];
    double got = via_launch(lf, "7scenes", ", depth_shift: 3, depth_scale: 0.0001", err, sizeof err);
    CHECK_MSG(fabs(got - 0.5) < 1e-3, "7scenes + depth_shift 3: %.4f %s", got, err);
    got = via_launch(lf, "7scenes", ", depth_scale: 0.0001", err, sizeof err);
    CHECK_MSG(fabs(got - 4.0) < 1e-3, "7scenes without shift: %.4f (40000 x 1e-4) %s", got, err);
    got = via_launch(lf, "label-fusion", ", depth_invalid: 96000", err, sizeof err);
    CHECK_MSG(got == -1 && strstr(err, "depth_invalid"), "depth_invalid out of range: %s", err);
    got = via_launch(lf, "label-fusion", ", depth_invalid: 65535, depth_shift: 16", err, sizeof err);
    CHECK_MSG(got == -1 && strstr(err, "depth_shift") && strstr(err, "formats.yaml:1"), "%s", err);
    /* depth_invalid equal to every sample: the reader marks them invalid */
    got = via_launch(lf, "label-fusion", ", depth_invalid: 40000", err, sizeof err);
    CHECK_MSG(got == 0, "label-fusion with depth_invalid = the samples: %.4f %s", got, err);
    got = via_launch(lf, "label-fusion", ", depth_invalid: 40001", err, sizeof err);
    CHECK_MSG(fabs(got - 0.5) < 1e-3, "label-fusion with another invalid value: %.4f %s", got, err);

    /* a truncated JPEG in the middle: that read names the file, the next read goes on */
    {
        const char *d7 = make_seq(SOOC_SEQ_7SCENES, &z);
        char jp[1200];
        snprintf(jp, sizeof jp, "%s/frame-000003.color.jpg", d7);
        void *jb;
        size_t jn;
        CHECK_OK(sooc_file_read_all(jp, 1 << 20, &jb, &jn));
        FILE *fp = fopen(jp, "wb");
        if (fp) { fwrite(jb, 1, jn / 2, fp); fclose(fp); }
        sooc_sensor_params_default(&sp);
        sp.uri = d7;
        sp.speed = 0;
        sooc_sensor *s7 = NULL;
        /* frame 3 is the first: open reads it for the size, so it fails naming the file */
        CHECK(sooc_sensor_open(&s7, "replay", &sp) == SOOC_EFORMAT && strstr(sooc_errmsg(), "frame-000003.color.jpg"));
        fp = fopen(jp, "wb");
        if (fp) { fwrite(jb, 1, jn, fp); fclose(fp); }
        snprintf(jp, sizeof jp, "%s/frame-000005.color.jpg", d7);
        fp = fopen(jp, "wb");
        if (fp) { fwrite(jb, 1, jn / 3, fp); fclose(fp); }
        snprintf(jp, sizeof jp, "%s/frame-000007.color.jpg", d7);
        fp = fopen(jp, "wb");
        if (fp) { fwrite(jb, 1, jn, fp); fclose(fp); }
        snprintf(jp, sizeof jp, "%s/frame-000007.depth.png", d7);
        put_depth(jp, 1500, 0);
        snprintf(jp, sizeof jp, "%s/frame-000007.pose.txt", d7);
        wtext(jp, "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n");
        sooc_free(jb);
        CHECK_OK(sooc_sensor_open(&s7, "replay", &sp));
        if (s7) {
            sooc_frame f7 = {0};
            CHECK_OK(sooc_sensor_start(s7));
            CHECK_OK(sooc_sensor_read(s7, &f7, 100));                 /* frame 3 */
            sooc_status st7 = sooc_sensor_read(s7, &f7, 100);        /* frame 5: truncated */
            CHECK_MSG(st7 == SOOC_EFORMAT && strstr(sooc_errmsg(), "frame-000005.color.jpg") &&
                      strstr(sooc_errmsg(), "corrupt JPEG"), "%s", sooc_errmsg());
            CHECK_OK(sooc_sensor_read(s7, &f7, 100));                 /* frame 7 */
            CHECK(fabs(f7.depth[5] - 1.5) < 1e-6);
            CHECK(sooc_sensor_read(s7, &f7, 100) == SOOC_EEOF);
            sooc_sensor_close(s7);
            sooc_frame_free(&f7);
        }
    }

    /* unknown names: the launch parser and the driver both list the valid ones */
    got = via_launch(lf, "scannet", "", err, sizeof err);
    CHECK_MSG(got == -1 && strstr(err, "formats.yaml:1") && strstr(err, "sensor.format") &&
              strstr(err, "sevenscenes") && strstr(err, "label-fusion"), "%s", err);
    sooc_sensor_params_default(&sp);
    sp.uri = lf;
    sp.format = "klg";
    sooc_sensor *s = NULL;
    CHECK(sooc_sensor_open(&s, "replay", &sp) == SOOC_EINVAL && s == NULL);
    CHECK(strstr(sooc_errmsg(), "'klg'") && strstr(sooc_errmsg(), "7scenes"));
    /* a name for the wrong layout fails with the file it looked for */
    got = via_launch(lf, "tum", "", err, sizeof err);
    CHECK_MSG(got == -1 && strstr(err, "rgb.txt"), "%s", err);

    char cmd[700];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (system(cmd)) { /* ignore */ }
    return check_report("test_replay_formats");
}
