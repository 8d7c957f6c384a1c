/* Calibration YAML: ROS and OpenCV styles, extensions, round trip, and
 * errors naming file, line and key. */
#include "util.h"
#include "sooc3d/frame.h"

#include <math.h>

static const char *ROS =
    "%%YAML 1.2\n---\n"
    "camera_name: xtion_rgb\n"
    "image_width: 640\n"
    "image_height: 480\n"
    "camera_matrix: {rows: 3, cols: 3, data: [575.82, 0, 319.5, 0, 575.82, 239.5, 0, 0, 1]}\n"
    "distortion_model: plumb_bob\n"
    "distortion_coefficients: {rows: 1, cols: 5, data: [0.1, -0.2, 0, 0, 0.05]}\n"
    "rectification_matrix: {rows: 3, cols: 3, data: [1,0,0, 0,1,0, 0,0,1]}\n"
    "projection_matrix: {rows: 3, cols: 4, data: [575.82,0,319.5,0, 0,575.82,239.5,0, 0,0,1,0]}\n"
    "depth_scale: 0.001\n"
    "depth_registered: true\n"
    "T_color_depth: {rows: 4, cols: 4, data: [1,0,0,0.025, 0,1,0,0, 0,0,1,0, 0,0,0,1]}\n"
    "T_effector_camera: {rows: 4, cols: 4, data: [0,-1,0,0.1, 1,0,0,0, 0,0,1,0.05, 0,0,0,1], parent: tool0, child: cam}\n";

static const char *OPENCV =
    "%%YAML:1.0\n---\n"
    "image_width: 64\n"
    "image_height: 48\n"
    "camera_matrix: !!opencv-matrix\n"
    "   rows: 3\n"
    "   cols: 3\n"
    "   dt: d\n"
    "   data: [ 50., 0., 32., 0., 51., 24., 0., 0., 1. ]\n"
    "depth_scale: 2.0e-4\n";

int main(void) {
    char *dir = tu_tmpdir("calib");
    char path[700], path2[700];
    sooc_calib c, d;
    tu_write(dir, "ros.yaml", ROS);
    snprintf(path, sizeof path, "%s/ros.yaml", dir);
    CHECK_OK(sooc_calib_load(path, &c));
    CHECK(c.K.width == 640 && c.K.height == 480);
    CHECK_CLOSE(c.K.fx, 575.82, 1e-12, 0);
    CHECK_CLOSE(c.K.cy, 239.5, 1e-12, 0);
    CHECK(c.K.dist_model == SOOC_DIST_PLUMB_BOB && c.n_dist == 5);
    CHECK_CLOSE(c.K.dist[4], 0.05, 1e-12, 0);
    CHECK_CLOSE(c.depth_scale, 0.001, 1e-15, 0);
    CHECK(c.depth_registered == 1 && c.has_T_color_depth && c.has_T_effector_camera);
    CHECK(!strcmp(c.effector_parent, "tool0") && !strcmp(c.effector_child, "cam"));
    CHECK(!strcmp(c.camera_name, "xtion_rgb"));
    /* round trip */
    snprintf(path2, sizeof path2, "%s/saved.yaml", dir);
    CHECK_OK(sooc_calib_save(path2, &c));
    CHECK_OK(sooc_calib_load(path2, &d));
    CHECK(d.K.width == c.K.width && d.K.fx == c.K.fx && d.K.cx == c.K.cx && d.depth_scale == c.depth_scale);
    CHECK(d.n_dist == 5 && d.K.dist[1] == c.K.dist[1] && d.has_T_effector_camera);
    CHECK(memcmp(d.T_color_depth, c.T_color_depth, sizeof d.T_color_depth) == 0);
    CHECK(c.depth_shift == -1 && c.depth_invalid == -1 && d.depth_shift == -1 && d.depth_invalid == -1);
    /* depth decoding keys (label-fusion as a calibration): load, save, load */
    c.depth_shift = 3;
    c.depth_invalid = 0;
    CHECK_OK(sooc_calib_save(path2, &c));
    CHECK_OK(sooc_calib_load(path2, &d));
    CHECK(d.depth_shift == 3 && d.depth_invalid == 0);
    c.depth_shift = 0;
    c.depth_invalid = 65535;
    CHECK_OK(sooc_calib_save(path2, &c));
    CHECK_OK(sooc_calib_load(path2, &d));
    CHECK(d.depth_shift == 0 && d.depth_invalid == 65535);
    FILE *fp = fopen(path2, "r");
    char head[32] = {0};
    if (fp) { if (!fgets(head, sizeof head, fp)) head[0] = 0; fclose(fp); }
    CHECK(!strcmp(head, "%YAML 1.2\n"));
    /* OpenCV style with %YAML:1.0 and !!opencv-matrix */
    tu_write(dir, "cv.yaml", OPENCV);
    snprintf(path, sizeof path, "%s/cv.yaml", dir);
    CHECK_OK(sooc_calib_load(path, &c));
    CHECK(c.K.width == 64 && c.K.fy == 51 && c.K.cx == 32 && c.K.dist_model == SOOC_DIST_NONE);
    /* negative fy (ICL-NUIM) is accepted */
    tu_write(dir, "icl.yaml", "%%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\n"
             "camera_matrix: {rows: 3, cols: 3, data: [481.2, 0, 319.5, 0, -480, 239.5, 0, 0, 1]}\n");
    snprintf(path, sizeof path, "%s/icl.yaml", dir);
    CHECK_OK(sooc_calib_load(path, &c));
    CHECK(c.K.fy == -480);

    /* bad files: each error names file, line and key */
    struct { const char *name, *text, *needle1, *needle2; } bad[] = {
        {"unknown.yaml", "%%YAML 1.2\n---\nimage_width: 1\nimage_height: 1\nfocal: 3\n", "unknown.yaml:5", "'focal'"},
        {"nok.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\n", "nok.yaml:3", "camera_matrix: missing"},
        {"count.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0]}\n",
         "count.yaml:5", "camera_matrix: expected 9 numbers (3x3), got 8"},
        {"nan.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 6x4\n", "nan.yaml:4", "image_height"},
        {"num.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, abc, 0, 0, 0, 1]}\n",
         "num.yaml:5", "camera_matrix.data[4]"},
        {"rot.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, data: [50, 0, 32, 0, 50, 32, 0, 0, 1]}\n"
                     "T_color_depth: {rows: 4, cols: 4, data: [1,0.2,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}\n",
         "rot.yaml:6", "T_color_depth: rotation part is not orthonormal"},
        {"syntax.yaml", "%%YAML 1.2\n---\nimage_width: 64\n  image_height: [64\n", "syntax.yaml:", "YAML error"},
        {"scale.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, data: [50, 0, 32, 0, 50, 32, 0, 0, 1]}\ndepth_scale: -1\n",
         "scale.yaml:6", "depth_scale"},
        {"shift.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, data: [50, 0, 32, 0, 50, 32, 0, 0, 1]}\ndepth_shift: 16\n",
         "shift.yaml:6", "depth_shift: must be in [0, 15]"},
        {"shift2.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, data: [50, 0, 32, 0, 50, 32, 0, 0, 1]}\ndepth_shift: 2.5\n",
         "shift2.yaml:6", "depth_shift"},
        {"inval.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, data: [50, 0, 32, 0, 50, 32, 0, 0, 1]}\ndepth_invalid: 65536\n",
         "inval.yaml:6", "depth_invalid: must be a raw 16-bit value"},
        {"skew.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, data: [50, 1, 32, 0, 50, 32, 0, 0, 1]}\n",
         "skew.yaml:5", "camera_matrix"},
        {"sub.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 64\ncamera_matrix: {rows: 3, cols: 3, typ: x, data: [50, 0, 32, 0, 50, 32, 0, 0, 1]}\n",
         "sub.yaml:5", "unknown key 'typ'"},
        /* fuzz finding: rows * cols overflowed int */
        {"rows.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 48\ncamera_matrix: {rows: 3, cols: 3, data: [50, 0, 32, 0, 50, 24, 0, 0, 1]}\n"
                      "rectification_matrix: {rows: 936714640, cols: 3, data: [1]}\n",
         "rows.yaml:6", "rectification_matrix: rows and cols must be <= 16"},
        /* duplicate keys are errors (YAML forbids them; libyaml does not check) */
        {"dup.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 48\nimage_width: 32\n",
         "dup.yaml:5", "image_width: duplicate key (first given at line 3)"},
        {"dupsub.yaml", "%%YAML 1.2\n---\nimage_width: 64\nimage_height: 48\ncamera_matrix: {rows: 3, cols: 3, rows: 3, data: [50, 0, 32, 0, 50, 24, 0, 0, 1]}\n",
         "dupsub.yaml:5", "camera_matrix.rows: duplicate key"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        tu_write(dir, bad[i].name, bad[i].text);
        snprintf(path, sizeof path, "%s/%s", dir, bad[i].name);
        CHECK_ERR_HAS(sooc_calib_load(path, &c), bad[i].needle1, bad[i].needle2);
    }
    snprintf(path, sizeof path, "%s/none.yaml", dir);
    CHECK_ERR_HAS(sooc_calib_load(path, &c), "none.yaml");
    /* the shipped calibration loads */
    const char *src = getenv("SOOC_SRC");
    snprintf(path, sizeof path, "%s/calib/synthetic_64.yaml", src ? src : ".");
    CHECK_OK(sooc_calib_load(path, &c));
    CHECK(c.K.width == 64 && c.depth_scale > 0);
    tu_rm_rf(dir);
    return check_report("test_data_calib");
}
