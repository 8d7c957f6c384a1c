/* sooc3d calib intrinsics | handeye, and `sooc3d gen --board` (board views
 * with known intrinsics and hand-eye, for tests and for trying the tools).
 * The work is in include/sooc3d/slam.h; this file parses options, lists
 * images and writes the YAML (only when the calibration succeeded). */
#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "sooc3d/frame.h"
#include "sooc3d/slam.h"
#include "sooc3d/core.h"

#define NEEDV()                                                                 \
    do {                                                                        \
        if (!v) {                                                               \
            fprintf(stderr, "sooc3d %s: %s needs a value\n", cmd, a);           \
            return 2;                                                           \
        }                                                                       \
        i++;                                                                    \
    } while (0)

/* ------------------------------------------------------------ image lists */

typedef struct pathlist {
    char **p;
    int n, cap;
} pathlist;

static void pl_free(pathlist *l) {
    for (int i = 0; i < l->n; i++) free(l->p[i]);
    free(l->p);
    memset(l, 0, sizeof *l);
}

static int pl_add(pathlist *l, const char *s) {
    if (l->n == l->cap) {
        int nc = l->cap ? 2 * l->cap : 32;
        char **np = realloc(l->p, (size_t)nc * sizeof *np);
        if (!np) return 0;
        l->p = np;
        l->cap = nc;
    }
    l->p[l->n] = strdup(s);
    return l->p[l->n++] != NULL;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static int is_image(const char *name) {
    const char *e = strrchr(name, '.');
    return e && (!strcmp(e, ".png") || !strcmp(e, ".PNG") || !strcmp(e, ".jpg") || !strcmp(e, ".jpeg") ||
                 !strcmp(e, ".JPG") || !strcmp(e, ".pgm"));
}

/* A directory (its images, sorted by name) or an image file. */
static int pl_add_arg(pathlist *l, const char *cmd, const char *arg) {
    if (!sooc_dir_exists(arg)) {
        if (!sooc_file_exists(arg)) {
            fprintf(stderr, "sooc3d %s: %s: no such file or directory\n", cmd, arg);
            return 0;
        }
        return pl_add(l, arg);
    }
    DIR *d = opendir(arg);
    if (!d) {
        fprintf(stderr, "sooc3d %s: %s: cannot open the directory\n", cmd, arg);
        return 0;
    }
    int first = l->n;
    struct dirent *e;
    char path[4096];
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.' || !is_image(e->d_name)) continue;
        snprintf(path, sizeof path, "%s/%s", arg, e->d_name);
        if (!pl_add(l, path)) {
            closedir(d);
            return 0;
        }
    }
    closedir(d);
    qsort(l->p + first, (size_t)(l->n - first), sizeof(char *), cmp_str);
    return 1;
}

/* -------------------------------------------------------------- intrinsics */

static void usage_calib(FILE *f) {
    fprintf(f,
            "usage: sooc3d calib intrinsics --board SPEC --images DIR|IMG... --out calib.yaml [options]\n"
            "       sooc3d calib handeye --board SPEC --images DIR|IMG... --poses arm.txt --calib intr.yaml\n"
            "                            --out calib.yaml [--method tsai|park|horaud|andreff|daniilidis]\n\n"
            "Board SPEC: charuco:<sx>x<sy>:<square_m>:<marker_m>[:<dict>] (default dictionary 4x4_50)\n"
            "            or checker:<sx>x<sy>:<square_m> (squares, not inner corners).\n\n"
            "intrinsics: detects the board in every image (sorted by name when a directory is given), runs\n"
            "  OpenCV calibrateCamera and writes the calibration YAML the node reads (ROS camera_info keys,\n"
            "  also readable by OpenCV FileStorage) with the reprojection RMS in the log.\n"
            "  --dist 0|4|5         distortion coefficients to estimate (default 5, plumb_bob)\n"
            "  --min-views N        views with the board needed (default 5)\n"
            "  --name NAME          camera_name in the YAML\n"
            "  --depth-scale S      metres per depth unit to record (e.g. 0.001)\n"
            "handeye: one arm pose per image, in the same order: a TUM file (`t tx ty tz qx qy qz qw`,\n"
            "  T_base_effector from the arm's kinematics). The board is located in each image with the\n"
            "  intrinsics of --calib (solvePnP), then OpenCV calibrateHandEye gives T_effector_camera;\n"
            "  the output is --calib's content plus T_effector_camera (pose.frame: effector reads it).\n"
            "  The wrist must rotate about two different axes: pure translations are rejected.\n"
            "Nothing is written when a calibration fails (too few views, no board, degenerate motions).\n");
}

static int cmd_intrinsics(int argc, char **argv) {
    const char *cmd = "calib intrinsics";
    const char *board_s = NULL, *out = NULL, *name = NULL;
    int dist_n = 5, min_views = 5;
    double depth_scale = 0;
    pathlist imgs = {0};
    int rc = 2;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--board")) { NEEDV(); board_s = v; }
        else if (!strcmp(a, "--out")) { NEEDV(); out = v; if (sooc_cli_need_parent(cmd, a, v)) goto done; }
        else if (!strcmp(a, "--name")) { NEEDV(); name = v; }
        else if (!strcmp(a, "--dist")) {
            NEEDV();
            if (!sooc_cli_int_opt(cmd, a, v, 0, 5, &dist_n)) goto done;
            if (dist_n != 0 && dist_n != 4 && dist_n != 5) {
                fprintf(stderr, "sooc3d %s: --dist: expected 0, 4 or 5, got %s\n", cmd, v);
                goto done;
            }
        } else if (!strcmp(a, "--min-views")) {
            NEEDV();
            if (!sooc_cli_int_opt(cmd, a, v, 3, 10000, &min_views)) goto done;
        } else if (!strcmp(a, "--depth-scale")) {
            NEEDV();
            if (!sooc_cli_double_opt(cmd, a, v, 1e-9, 1, &depth_scale)) goto done;
        } else if (!strcmp(a, "--images")) {
            NEEDV();
            if (!pl_add_arg(&imgs, cmd, v)) goto done;
            while (i + 1 < argc && strncmp(argv[i + 1], "--", 2)) {
                if (!pl_add_arg(&imgs, cmd, argv[++i])) goto done;
            }
        } else {
            fprintf(stderr, "sooc3d %s: unknown option '%s'\n", cmd, a);
            goto done;
        }
    }
    if (!board_s || !out || !imgs.n) {
        fprintf(stderr, "sooc3d %s: --board, --images and --out are required\n", cmd);
        goto done;
    }
    sooc_board b;
    sooc_status st = sooc_board_parse(board_s, &b);
    if (st) { rc = sooc_cli_fail(cmd, st); goto done; }
    sooc_calib c;
    sooc_calib_init(&c);
    sooc_calib_report rep;
    st = sooc_calib_intrinsics(&b, (const char *const *)imgs.p, imgs.n, min_views, 6, dist_n, &c, &rep);
    if (st) { rc = sooc_cli_fail(cmd, st); goto done; }
    if (name) snprintf(c.camera_name, sizeof c.camera_name, "%s", name);
    if (depth_scale > 0) c.depth_scale = depth_scale;
    st = sooc_calib_save(out, &c);
    sooc_calib_report_free(&rep);
    if (st) { rc = sooc_cli_fail(cmd, st); goto done; }
    printf("calib intrinsics: %d of %d views used, reprojection RMS %.4f px\n", rep.views_used, rep.views_given,
           rep.rms_px);
    printf("  fx %.3f fy %.3f cx %.3f cy %.3f  dist [%g %g %g %g %g]\n", c.K.fx, c.K.fy, c.K.cx, c.K.cy, c.K.dist[0],
           c.K.dist[1], c.K.dist[2], c.K.dist[3], c.K.dist[4]);
    printf("{\"views_used\": %d, \"views\": %d, \"rms_px\": %.6f, \"fx\": %.6f, \"fy\": %.6f, \"cx\": %.6f, "
           "\"cy\": %.6f, \"out\": \"%s\"}\n",
           rep.views_used, rep.views_given, rep.rms_px, c.K.fx, c.K.fy, c.K.cx, c.K.cy, out);
    rc = 0;
done:
    pl_free(&imgs);
    return rc;
}

/* ----------------------------------------------------------------- handeye */

static int cmd_handeye(int argc, char **argv) {
    const char *cmd = "calib handeye";
    const char *board_s = NULL, *out = NULL, *poses = NULL, *calib_in = NULL;
    int method = 0, min_views = 5;
    static const char *methods[] = {"tsai", "park", "horaud", "andreff", "daniilidis"};
    pathlist imgs = {0};
    sooc_traj tr = {0};
    int rc = 2;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--board")) { NEEDV(); board_s = v; }
        else if (!strcmp(a, "--out")) { NEEDV(); out = v; if (sooc_cli_need_parent(cmd, a, v)) goto done; }
        else if (!strcmp(a, "--poses")) { NEEDV(); poses = v; }
        else if (!strcmp(a, "--calib")) { NEEDV(); calib_in = v; }
        else if (!strcmp(a, "--min-views")) {
            NEEDV();
            if (!sooc_cli_int_opt(cmd, a, v, 3, 10000, &min_views)) goto done;
        } else if (!strcmp(a, "--method")) {
            NEEDV();
            method = -1;
            for (int k = 0; k < 5; k++)
                if (!strcmp(v, methods[k])) method = k;
            if (method < 0) {
                fprintf(stderr, "sooc3d %s: --method: expected tsai|park|horaud|andreff|daniilidis, got '%s'\n", cmd,
                        v);
                goto done;
            }
        } else if (!strcmp(a, "--images")) {
            NEEDV();
            if (!pl_add_arg(&imgs, cmd, v)) goto done;
            while (i + 1 < argc && strncmp(argv[i + 1], "--", 2)) {
                if (!pl_add_arg(&imgs, cmd, argv[++i])) goto done;
            }
        } else {
            fprintf(stderr, "sooc3d %s: unknown option '%s'\n", cmd, a);
            goto done;
        }
    }
    if (!board_s || !out || !imgs.n || !poses || !calib_in) {
        fprintf(stderr, "sooc3d %s: --board, --images, --poses, --calib and --out are required\n", cmd);
        goto done;
    }
    sooc_board b;
    sooc_status st = sooc_board_parse(board_s, &b);
    if (st) { rc = sooc_cli_fail(cmd, st); goto done; }
    sooc_calib c;
    if ((st = sooc_calib_load(calib_in, &c))) { rc = sooc_cli_fail(cmd, st); goto done; }
    if ((st = sooc_traj_load_tum(poses, &tr))) { rc = sooc_cli_fail(cmd, st); goto done; }
    if (tr.n != imgs.n) {
        fprintf(stderr, "sooc3d %s: %s holds %lld arm poses but %d images were given (one pose per image, same order)\n",
                cmd, poses, (long long)tr.n, imgs.n);
        rc = 1;
        goto done;
    }
    double rms = 0;
    int used = 0;
    st = sooc_calib_handeye(&b, (const char *const *)imgs.p, tr.T, imgs.n, min_views, method, &c, &rms, &used);
    if (st) { rc = sooc_cli_fail(cmd, st); goto done; }
    if ((st = sooc_calib_save(out, &c))) { rc = sooc_cli_fail(cmd, st); goto done; }
    const double *X = c.T_effector_camera;
    printf("calib handeye (%s): %d of %d views used, mean PnP reprojection RMS %.4f px\n", methods[method], used,
           imgs.n, rms);
    printf("  T_effector_camera t = [%.5f %.5f %.5f] m\n", X[3], X[7], X[11]);
    printf("{\"views_used\": %d, \"views\": %d, \"pnp_rms_px\": %.6f, \"t\": [%.6f, %.6f, %.6f], \"out\": \"%s\"}\n",
           used, imgs.n, rms, X[3], X[7], X[11], out);
    rc = 0;
done:
    sooc_traj_free(&tr);
    pl_free(&imgs);
    return rc;
}

int sooc_cmd_calib(int argc, char **argv) {
    if (argc < 2 || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        usage_calib(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    if (!strcmp(argv[1], "intrinsics")) return cmd_intrinsics(argc - 1, argv + 1);
    if (!strcmp(argv[1], "handeye")) return cmd_handeye(argc - 1, argv + 1);
    fprintf(stderr, "sooc3d calib: unknown subcommand '%s' (intrinsics, handeye)\n\n", argv[1]);
    usage_calib(stderr);
    return 2;
}

/* ------------------------------------------------------------- gen --board */

/* R (rows = camera axes in board coordinates) from the optical axis z and a
 * reference image-down direction */
static void look_rot(const double z_in[3], const double yref[3], double roll, double R_bc[9]) {
    double z[3] = {z_in[0], z_in[1], z_in[2]}, x[3], y[3];
    sooc_v3_normalize(z);
    sooc_v3_cross(x, yref, z);
    sooc_v3_normalize(x);
    sooc_v3_cross(y, z, x);
    double c = cos(roll), s = sin(roll);
    for (int k = 0; k < 3; k++) {
        double xr = c * x[k] + s * y[k], yr = -s * x[k] + c * y[k];
        /* columns of R_board_cam are the camera axes in board coordinates */
        R_bc[3 * k + 0] = xr;
        R_bc[3 * k + 1] = yr;
        R_bc[3 * k + 2] = z[k];
    }
}

int sooc_cmd_gen_board(int argc, char **argv) {
    const char *cmd = "gen";
    const char *board_s = NULL, *out = NULL;
    int views = 15, w = 640, h = 480, pure_translation = 0;
    double f = 525, noise = 2.0;
    uint64_t seed = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--board")) { NEEDV(); board_s = v; }
        else if (!strcmp(a, "--out")) { NEEDV(); out = v; }
        else if (!strcmp(a, "--views")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 1, 1000, &views)) return 2; }
        else if (!strcmp(a, "--width")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 64, 8192, &w)) return 2; }
        else if (!strcmp(a, "--height")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 64, 8192, &h)) return 2; }
        else if (!strcmp(a, "--focal")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 10, 1e5, &f)) return 2; }
        else if (!strcmp(a, "--noise")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 0, 50, &noise)) return 2; }
        else if (!strcmp(a, "--seed")) { NEEDV(); if (!sooc_cli_u64_opt(cmd, a, v, UINT64_MAX, &seed)) return 2; }
        else if (!strcmp(a, "--pure-translation")) pure_translation = 1;
        else {
            fprintf(stderr, "sooc3d gen --board: unknown option '%s'\n", a);
            return 2;
        }
    }
    if (!board_s || !out) {
        fprintf(stderr, "sooc3d gen --board: --board SPEC and --out DIR are required\n"
                        "  [--views N] [--width W --height H] [--focal F] [--noise SIGMA] [--seed S]\n"
                        "  [--pure-translation]  (writes DIR/images/view-NNN.png, DIR/arm_poses.txt (T_base_effector,\n"
                        "  TUM), DIR/truth.yaml (the true intrinsics and T_effector_camera))\n");
        return 2;
    }
    sooc_board b;
    sooc_status st = sooc_board_parse(board_s, &b);
    if (st) return sooc_cli_fail(cmd, st);
    double center[3], front_z, y_down;
    if ((st = sooc_board_layout(&b, center, &front_z, &y_down))) return sooc_cli_fail(cmd, st);
    char dir[4096];
    snprintf(dir, sizeof dir, "%s/images", out);
    if ((st = sooc_mkdirs(dir))) return sooc_cli_fail(cmd, st);

    sooc_calib truth;
    sooc_calib_pinhole(&truth, w, h, f, f, 0.5 * (w - 1) + 3.5, 0.5 * (h - 1) - 2.5);
    snprintf(truth.camera_name, sizeof truth.camera_name, "gen_board");
    /* the true hand-eye: camera 6 cm ahead of the flange, 3 cm aside, turned */
    double q_ec[4] = {0.05, -0.03, 0.7, 0.7}, t_ec[3] = {0.03, -0.02, 0.06}, R_ec[9];
    sooc_quat_to_m3(R_ec, q_ec);
    sooc_se3_from_rt(truth.T_effector_camera, R_ec, t_ec);
    truth.has_T_effector_camera = 1;
    snprintf(truth.effector_parent, sizeof truth.effector_parent, "tool0");
    snprintf(truth.effector_child, sizeof truth.effector_child, "camera");
    /* the board in the robot base frame */
    double T_base_board[16], R_bb[9], q_bb[4] = {0.0, 0.0, 0.0, 1.0}, t_bb[3] = {0.6, 0.1, -0.2};
    sooc_quat_to_m3(R_bb, q_bb);
    sooc_se3_from_rt(T_base_board, R_bb, t_bb);
    double T_ce[16];
    sooc_se3_inverse(T_ce, truth.T_effector_camera);

    double bw = b.squares_x * b.square_m, bh = b.squares_y * b.square_m;
    double dist0 = f * fmax(bw / (0.65 * w), bh / (0.65 * h));
    sooc_rng rng;
    sooc_rng_seed(&rng, seed, 11);
    sooc_traj arm = {0};
    sooc_image img = {0};
    const double yref[3] = {0, y_down, 0};
    double fixed_roll = 0.1, fixed_tilt[2] = {0.35, 0.2};
    for (int k = 0; k < views && !st; k++) {
        /* viewing direction: tilted up to ~40 deg from the board normal */
        double ax = pure_translation ? fixed_tilt[0] : sooc_rng_range(&rng, -0.7, 0.7);
        double ay = pure_translation ? fixed_tilt[1] : sooc_rng_range(&rng, -0.7, 0.7);
        double d = dist0 * sooc_rng_range(&rng, 0.9, 1.3);
        double n[3] = {sin(ax), sin(ay), front_z * sqrt(fmax(0.05, 1 - sin(ax) * sin(ax) - sin(ay) * sin(ay)))};
        double target[3] = {center[0] + sooc_rng_range(&rng, -0.1, 0.1) * bw,
                            center[1] + sooc_rng_range(&rng, -0.1, 0.1) * bh, 0};
        double pos[3] = {target[0] + d * n[0], target[1] + d * n[1], target[2] + d * n[2]};
        double z[3] = {target[0] - pos[0], target[1] - pos[1], target[2] - pos[2]};
        if (pure_translation) { /* same orientation every time: optical axis fixed, only the position moves */
            z[0] = -n[0];
            z[1] = -n[1];
            z[2] = -n[2];
        }
        double roll = pure_translation ? fixed_roll : sooc_rng_range(&rng, -0.35, 0.35);
        double R_bc[9], T_board_cam[16], T_cam_board[16], T_base_cam[16], T_base_ee[16];
        look_rot(z, yref, roll, R_bc);
        sooc_se3_from_rt(T_board_cam, R_bc, pos);
        sooc_se3_inverse(T_cam_board, T_board_cam);
        sooc_se3_mul(T_base_cam, T_base_board, T_board_cam);
        sooc_se3_mul(T_base_ee, T_base_cam, T_ce);
        if ((st = sooc_board_render(&b, &truth.K, T_cam_board, 3, noise, seed * 1000 + (uint64_t)k, &img))) break;
        char path[4200];
        snprintf(path, sizeof path, "%s/view-%03d.png", dir, k);
        if ((st = sooc_png_write(path, &img, 6))) break;
        st = sooc_traj_push(&arm, (double)k, T_base_ee);
    }
    sooc_image_free(&img);
    char path[4200];
    if (!st) {
        snprintf(path, sizeof path, "%s/arm_poses.txt", out);
        st = sooc_traj_save_tum(path, &arm);
    }
    if (!st) {
        snprintf(path, sizeof path, "%s/truth.yaml", out);
        st = sooc_calib_save(path, &truth);
    }
    sooc_traj_free(&arm);
    if (st) return sooc_cli_fail(cmd, st);
    printf("gen --board: %d views of %s in %s/images (f = %g, %dx%d), arm_poses.txt, truth.yaml\n", views, board_s, out,
           f, w, h);
    return 0;
}
