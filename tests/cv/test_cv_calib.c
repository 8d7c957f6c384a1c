/* Calibration against known truth, through the CLI: `sooc3d gen --board`
 * renders ChArUco and checkerboard views with known intrinsics and
 * hand-eye; `sooc3d calib intrinsics` must recover the focal length within
 * 0.5% and `sooc3d calib handeye` the hand-eye within 0.5 deg and 5 mm.
 * Too few views, no board and pure translations fail with a clear message
 * and write nothing. Every calibration YAML shipped in calib/ and every one
 * written here loads with libyaml (sooc_calib_load) and OpenCV FileStorage. */
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/frame.h"
#include "sooc3d/slam.h"
#include "sooc3d/core.h"

static char g_dir[64], g_bin[1024], g_log[256];

/* run `sooc3d <args>` with stdout/stderr to g_log; exit code */
static int run(const char *args) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s %s > %s 2>&1", g_bin, args, g_log);
    int r = system(cmd);
    return WIFEXITED(r) ? WEXITSTATUS(r) : -1;
}

static int log_has(const char *s) {
    void *buf = NULL;
    size_t n = 0;
    if (sooc_file_read_all(g_log, 1 << 20, &buf, &n)) return 0;
    int hit = strstr(buf, s) != NULL;
    if (!hit) fprintf(stderr, "log does not contain '%s':\n%s\n", s, (char *)buf);
    sooc_free(buf);
    return hit;
}

static void check_yaml_both(const char *path) {
    sooc_calib c;
    sooc_status st = sooc_calib_load(path, &c);
    CHECK_MSG(st == SOOC_OK, "libyaml: %s", sooc_errmsg());
    int w = 0, h = 0;
    double K[9];
    st = sooc_cv_calib_yaml_read(path, &w, &h, K);
    CHECK_MSG(st == SOOC_OK, "OpenCV: %s", sooc_errmsg());
    if (st == SOOC_OK) {
        CHECK_MSG(w == c.K.width && h == c.K.height, "%s: size %dx%d vs %dx%d", path, w, h, c.K.width, c.K.height);
        CHECK_MSG(fabs(K[0] - c.K.fx) < 1e-9 && fabs(K[4] - c.K.fy) < 1e-9 && fabs(K[2] - c.K.cx) < 1e-9,
                  "%s: OpenCV K differs", path);
    }
}

static double rot_err_deg(const double A[16], const double B[16]) {
    double Ra[9], Rb[9], ta[3], tb[3], RaT[9], R[9];
    sooc_se3_to_rt(Ra, ta, A);
    sooc_se3_to_rt(Rb, tb, B);
    sooc_m3_transpose(RaT, Ra);
    sooc_m3_mul(R, RaT, Rb);
    double c = (R[0] + R[4] + R[8] - 1) * 0.5;
    c = c > 1 ? 1 : (c < -1 ? -1 : c);
    return acos(c) * 180 / M_PI;
}

int main(void) {
    if (!sooc_cv_available()) {
        printf("test_cv_calib: SKIP: built without OpenCV (libopencv-contrib-dev, SOOC_WITH_OPENCV)\n");
        return SOOC_TEST_SKIP;
    }
    const char *bin = getenv("SOOC_BIN");
    if (!bin || !sooc_file_exists(bin)) {
        printf("test_cv_calib: SKIP: SOOC_BIN (the sooc3d binary) not set or missing\n");
        return SOOC_TEST_SKIP;
    }
    snprintf(g_bin, sizeof g_bin, "%s", bin);
    snprintf(g_dir, sizeof g_dir, "/tmp/sooc_calib_XXXXXX");
    if (!mkdtemp(g_dir)) return 1;
    snprintf(g_log, sizeof g_log, "%s/log.txt", g_dir);
    char a[4096], p[512], q[512];
    const char *ch = "charuco:7x5:0.04:0.03";

    /* ---- ChArUco: intrinsics and hand-eye ---- */
    snprintf(a, sizeof a, "gen --board %s --out %s/ch --views 15 --seed 3", ch, g_dir);
    CHECK(run(a) == 0);
    snprintf(p, sizeof p, "%s/ch/truth.yaml", g_dir);
    sooc_calib truth;
    CHECK(sooc_calib_load(p, &truth) == SOOC_OK);
    snprintf(a, sizeof a, "calib intrinsics --board %s --images %s/ch/images --out %s/ch/intr.yaml", ch, g_dir, g_dir);
    CHECK(run(a) == 0);
    CHECK(log_has("reprojection RMS"));
    snprintf(p, sizeof p, "%s/ch/intr.yaml", g_dir);
    sooc_calib est;
    CHECK(sooc_calib_load(p, &est) == SOOC_OK);
    printf("charuco: fx %.3f fy %.3f (truth %.1f), cx %.2f cy %.2f (truth %.1f %.1f)\n", est.K.fx, est.K.fy,
           truth.K.fx, est.K.cx, est.K.cy, truth.K.cx, truth.K.cy);
    CHECK_CLOSE(est.K.fx, truth.K.fx, 0, 0.005);
    CHECK_CLOSE(est.K.fy, truth.K.fy, 0, 0.005);
    CHECK(est.K.width == 640 && est.K.height == 480);
    check_yaml_both(p);

    snprintf(a, sizeof a,
             "calib handeye --board %s --images %s/ch/images --poses %s/ch/arm_poses.txt --calib %s/ch/intr.yaml "
             "--out %s/ch/he.yaml",
             ch, g_dir, g_dir, g_dir, g_dir);
    CHECK(run(a) == 0);
    snprintf(q, sizeof q, "%s/ch/he.yaml", g_dir);
    sooc_calib he;
    CHECK(sooc_calib_load(q, &he) == SOOC_OK);
    CHECK(he.has_T_effector_camera);
    double re = rot_err_deg(he.T_effector_camera, truth.T_effector_camera);
    double dt[3] = {he.T_effector_camera[3] - truth.T_effector_camera[3],
                    he.T_effector_camera[7] - truth.T_effector_camera[7],
                    he.T_effector_camera[11] - truth.T_effector_camera[11]};
    double te = sooc_v3_norm(dt);
    printf("hand-eye: rotation error %.4f deg, translation error %.2f mm\n", re, te * 1e3);
    CHECK(re < 0.5);
    CHECK(te < 0.005);
    CHECK_CLOSE(he.K.fx, est.K.fx, 1e-9, 0);   /* the intrinsics are kept */
    check_yaml_both(q);

    /* ---- checkerboard intrinsics ---- */
    snprintf(a, sizeof a, "gen --board checker:9x7:0.03 --out %s/cb --views 12 --seed 4 --focal 600", g_dir);
    CHECK(run(a) == 0);
    snprintf(a, sizeof a, "calib intrinsics --board checker:9x7:0.03 --images %s/cb/images --out %s/cb/intr.yaml "
             "--dist 0", g_dir, g_dir);
    CHECK(run(a) == 0);
    snprintf(p, sizeof p, "%s/cb/intr.yaml", g_dir);
    CHECK(sooc_calib_load(p, &est) == SOOC_OK);
    printf("checkerboard: fx %.3f fy %.3f (truth 600)\n", est.K.fx, est.K.fy);
    CHECK_CLOSE(est.K.fx, 600, 0, 0.005);
    CHECK_CLOSE(est.K.fy, 600, 0, 0.005);
    /* hand-eye refuses a checkerboard (its frame flips between views) */
    snprintf(a, sizeof a, "calib handeye --board checker:9x7:0.03 --images %s/cb/images --poses %s/cb/arm_poses.txt "
             "--calib %s/cb/intr.yaml --out %s/cb/he.yaml", g_dir, g_dir, g_dir, g_dir);
    CHECK(run(a) == 1);
    CHECK(log_has("ChArUco"));
    snprintf(p, sizeof p, "%s/cb/he.yaml", g_dir);
    CHECK(!sooc_file_exists(p));

    /* ---- degenerate input: clear error, nothing written ---- */
    snprintf(p, sizeof p, "%s/none.yaml", g_dir);
    /* too few views */
    snprintf(a, sizeof a, "calib intrinsics --board %s --images %s/ch/images/view-000.png %s/ch/images/view-001.png "
             "%s/ch/images/view-002.png --out %s", ch, g_dir, g_dir, g_dir, p);
    CHECK(run(a) == 1);
    CHECK(log_has("need at least 5"));
    CHECK(!sooc_file_exists(p));
    /* no board: blank and noise images */
    snprintf(q, sizeof q, "%s/blank", g_dir);
    CHECK(sooc_mkdirs(q) == SOOC_OK);
    sooc_image img = {0};
    CHECK(sooc_image_alloc(&img, 640, 480, SOOC_PIX_RGB8) == SOOC_OK);
    sooc_rng rng;
    sooc_rng_seed(&rng, 1, 1);
    for (int k = 0; k < 6; k++) {
        uint8_t *px = img.data;
        for (int i = 0; i < 640 * 480 * 3; i++) px[i] = (uint8_t)(k < 3 ? 128 : sooc_rng_below(&rng, 256));
        char ip[600];
        snprintf(ip, sizeof ip, "%s/img-%d.png", q, k);
        CHECK(sooc_png_write(ip, &img, 1) == SOOC_OK);
    }
    sooc_image_free(&img);
    snprintf(a, sizeof a, "calib intrinsics --board %s --images %s --out %s", ch, q, p);
    CHECK(run(a) == 1);
    CHECK(log_has("found in 0 of 6 images"));
    CHECK(log_has("img-0.png"));
    CHECK(!sooc_file_exists(p));
    /* wrong board spec for the images: no board either */
    snprintf(a, sizeof a, "calib intrinsics --board charuco:5x5:0.04:0.03:6x6_250 --images %s/ch/images --out %s",
             g_dir, p);
    CHECK(run(a) == 1);
    CHECK(!sooc_file_exists(p));
    /* pure translations of the arm */
    snprintf(a, sizeof a, "gen --board %s --out %s/pt --views 8 --seed 5 --pure-translation", ch, g_dir);
    CHECK(run(a) == 0);
    snprintf(a, sizeof a, "calib handeye --board %s --images %s/pt/images --poses %s/pt/arm_poses.txt "
             "--calib %s/ch/intr.yaml --out %s", ch, g_dir, g_dir, g_dir, p);
    CHECK(run(a) == 1);
    CHECK(log_has("degenerate motions"));
    CHECK(!sooc_file_exists(p));
    /* pose count mismatch */
    snprintf(a, sizeof a, "calib handeye --board %s --images %s/ch/images --poses %s/pt/arm_poses.txt "
             "--calib %s/ch/intr.yaml --out %s", ch, g_dir, g_dir, g_dir, p);
    CHECK(run(a) == 1);
    CHECK(log_has("one pose per image"));
    CHECK(!sooc_file_exists(p));
    /* an existing output is left alone by a failing run */
    FILE *f = fopen(p, "w");
    fputs("keep\n", f);
    fclose(f);
    snprintf(a, sizeof a, "calib intrinsics --board %s --images %s --out %s", ch, q, p);
    CHECK(run(a) == 1);
    void *buf = NULL;
    size_t n = 0;
    CHECK(sooc_file_read_all(p, 1024, &buf, &n) == SOOC_OK && n == 5 && !memcmp(buf, "keep\n", 5));
    sooc_free(buf);
    /* bad board specs */
    sooc_board b;
    CHECK(sooc_board_parse("charuco:7x5:0.04", &b) == SOOC_EINVAL);
    CHECK(sooc_board_parse("charuco:7x5:0.04:0.05", &b) == SOOC_EINVAL);
    CHECK(sooc_board_parse("checker:2x5:0.04", &b) == SOOC_EINVAL);
    CHECK(sooc_board_parse("charuco:7x5:0.04:0.03:7x7_9", &b) == SOOC_EINVAL);
    CHECK(sooc_board_parse("checker:9x6:0.025", &b) == SOOC_OK && b.squares_x == 9 && b.kind == SOOC_BOARD_CHECKER);

    /* ---- the shipped camera models load in libyaml and OpenCV ---- */
    const char *src = getenv("SOOC_SRC");
    char cdir[1200];
    snprintf(cdir, sizeof cdir, "%s/calib", src ? src : ".");
    DIR *d = opendir(cdir);
    CHECK(d != NULL);
    int nyaml = 0;
    struct dirent *e;
    while (d && (e = readdir(d))) {
        size_t L = strlen(e->d_name);
        if (L < 6 || strcmp(e->d_name + L - 5, ".yaml")) continue;
        char yp[1500];
        snprintf(yp, sizeof yp, "%s/%s", cdir, e->d_name);
        check_yaml_both(yp);
        nyaml++;
    }
    if (d) closedir(d);
    CHECK(nyaml >= 3);
    printf("shipped calibration files loaded by libyaml and OpenCV: %d\n", nyaml);

    snprintf(a, sizeof a, "rm -rf %s", g_dir);
    if (system(a)) fprintf(stderr, "could not remove %s\n", g_dir);
    printf("test_cv_calib: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail != 0;
}
