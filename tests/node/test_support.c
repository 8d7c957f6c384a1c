/* Support plane (include/sooc3d/frame.h): ray-cast depth frames of a floor,
 * a table with no floor in view, a table over a floor, and a shelf bin, in a
 * pose frame whose up axis is +z (like label-fusion); up from the hint, a
 * gravity vector and the cameras; a wrong hint fails with a message that
 * says what to check. `test_support real` runs on label-fusion and 7-Scenes
 * frames from ../shared/real (skipped when absent). */
#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/node.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define DEG (3.14159265358979323846 / 180.0)

#include "raycast_scene.h"

/* the support plane's height in the world (+y up) and its tilt from +y */
static void check_plane(const sooc_support *o, double want_y, double tol, double tol_deg, const char *what) {
    double Tsw[16];
    src_from_world(Tsw);
    /* plane in the world: n_w = R_sw^T n_s, d_w = d_s + n_s . t_sw */
    double nw[3] = {Tsw[0] * o->plane_src[0] + Tsw[4] * o->plane_src[1] + Tsw[8] * o->plane_src[2],
                    Tsw[1] * o->plane_src[0] + Tsw[5] * o->plane_src[1] + Tsw[9] * o->plane_src[2],
                    Tsw[2] * o->plane_src[0] + Tsw[6] * o->plane_src[1] + Tsw[10] * o->plane_src[2]};
    double dw = o->plane_src[3] + o->plane_src[0] * Tsw[3] + o->plane_src[1] * Tsw[7] + o->plane_src[2] * Tsw[11];
    double ang = acos(fmin(1, nw[1])) / DEG, y = -dw / nw[1];
    printf("  %s: plane y = %.3f (want %.3f), normal %.2f deg off, camera height %.3f m, %zu/%zu inliers, "
           "%d candidates, up from %s%s\n",
           what, y, want_y, ang, o->cam_height_m, o->n_inliers, o->n_points, o->n_candidates,
           sooc_up_source_name(o->up_source), o->height_warning ? ", height warning" : "");
    CHECK_MSG(ang < tol_deg, "%s: normal %.2f deg off", what, ang);
    CHECK_MSG(fabs(y - want_y) < tol, "%s: plane at y = %.3f, want %.3f", what, y, want_y);
    /* T_world_src puts the plane at y = 0 with +y up */
    double p[3] = {0, 0, 0}, q[3];
    double nrm[3] = {o->plane_src[0], o->plane_src[1], o->plane_src[2]};
    sooc_v3_scale(p, nrm, -o->plane_src[3]);   /* a point on the plane */
    sooc_se3_apply(q, o->T_world_src, p);
    CHECK_MSG(fabs(q[1]) < 1e-9, "%s: plane point at world y = %g", what, q[1]);
}

static sooc_status estimate(const scene *s, const double (*cams)[5], int nc, const sooc_support_params *p,
                            sooc_support *o) {
    sooc_frame fr[8];
    const sooc_frame *fp[8];
    memset(fr, 0, sizeof fr);
    for (int i = 0; i < nc; i++) {
        render(s, &fr[i], cams[i], cams[i][3] * DEG, cams[i][4] * DEG, 11 + (uint64_t)i);
        fp[i] = &fr[i];
    }
    sooc_status st = sooc_support_estimate(fp, nc, p, o);
    for (int i = 0; i < nc; i++) sooc_frame_free(&fr[i]);
    return st;
}

static void test_synthetic(void) {
    sooc_support_params p;
    sooc_support o;
    const double upz[3] = {0, 0, 1};

    /* 1. a room: floor, two walls, a box; cameras at 1.5 m looking down 30 deg */
    scene room = {0};
    add(&room, 1, 0.0, -4, 4, -4, 4);
    add(&room, 2, 4.0, -4, 4, 0, 2.5);
    add(&room, 0, -4.0, 0, 2.5, -4, 4);
    add_box(&room, 0.5, 0, 1.5, 1.0, 0.5, 2.0);
    const double room_cams[3][5] = {{0, 1.5, 0, 0, 30}, {0.5, 1.4, -0.5, 40, 25}, {-0.5, 1.6, 0.2, -30, 35}};
    sooc_support_params_default(&p);
    p.has_up_hint = 1;
    memcpy(p.up_hint, upz, sizeof upz);
    CHECK_OK(estimate(&room, room_cams, 3, &p, &o));
    check_plane(&o, 0.0, 0.02, 1.0, "floor, up given");
    CHECK(o.up_source == SOOC_UP_GIVEN && !o.height_warning);
    CHECK_CLOSE(o.cam_height_m, 1.5, 0.03, 0);

    /* the same from a gravity vector and from the cameras (three headings) */
    sooc_support_params_default(&p);
    p.has_gravity = 1;
    p.gravity[2] = -1;
    CHECK_OK(estimate(&room, room_cams, 3, &p, &o));
    check_plane(&o, 0.0, 0.02, 1.0, "floor, gravity");
    CHECK(o.up_source == SOOC_UP_GRAVITY_FILE);
    sooc_support_params_default(&p);
    CHECK_OK(estimate(&room, room_cams, 3, &p, &o));
    check_plane(&o, 0.0, 0.02, 1.0, "floor, camera mean (3 headings)");
    CHECK(o.up_source == SOOC_UP_CAMERA_MEAN);
    /* one heading, pitched down 35 deg: the camera prior is 35 deg off; the tilt limit of this source covers it */
    const double one_heading[2][5] = {{0, 1.5, 0, 10, 35}, {0.3, 1.5, 0.1, 10, 35}};
    CHECK_OK(estimate(&room, one_heading, 2, &p, &o));
    check_plane(&o, 0.0, 0.02, 1.0, "floor, camera mean (1 heading)");

    /* a wrong up hint (+y of the source = a wall's normal direction) fails and says what to check */
    sooc_support_params_default(&p);
    p.has_up_hint = 1;
    p.up_hint[0] = 1;
    sooc_status st = estimate(&room, room_cams, 3, &p, &o);
    CHECK(st == SOOC_ENOTFOUND);
    CHECK_MSG(strstr(sooc_errmsg(), "world.up") != NULL, "%s", sooc_errmsg());
    printf("  wrong up hint: %s\n", sooc_errmsg());

    /* 2. a table with no floor in view: the table top (0.75 m), camera 0.55 m above it */
    scene table = {0};
    add_box(&table, -0.8, 0, -0.5, 0.8, 0.75, 0.5);
    add_box(&table, -0.2, 0.75, -0.1, 0.0, 0.95, 0.1);   /* a cup-like box on it */
    const double table_cams[3][5] = {{0, 1.3, -0.6, 0, 50}, {0.2, 1.3, -0.6, -15, 55}, {-0.2, 1.25, -0.55, 15, 50}};
    sooc_support_params_default(&p);
    p.has_up_hint = 1;
    memcpy(p.up_hint, upz, sizeof upz);
    CHECK_OK(estimate(&table, table_cams, 3, &p, &o));
    check_plane(&o, 0.75, 0.02, 1.0, "table top, no floor");
    CHECK(o.height_warning);   /* 0.55 m is below the trained 1.2-2.0 m */

    /* 3. the same table on a floor, seen from farther: the floor (lowest level plane) wins over the table top */
    scene tf = table;
    add(&tf, 1, 0.0, -4, 4, -4, 4);
    const double tf_cams[3][5] = {{0, 1.6, -2.0, 0, 30}, {0.5, 1.6, -2.0, -10, 35}, {-0.5, 1.6, -2.0, 10, 30}};
    CHECK_OK(estimate(&tf, tf_cams, 3, &p, &o));
    check_plane(&o, 0.0, 0.02, 1.0, "table on a floor");
    CHECK(o.n_candidates >= 2);

    /* 4. a shelf bin: bottom at 0.9 m, walls 0.25 m high, a shelf board above; arm camera 0.45 m over the bottom */
    scene bin = {0};
    add(&bin, 1, 0.9, -0.3, 0.3, -0.2, 0.2);          /* bottom */
    add(&bin, 0, -0.3, 0.9, 1.15, -0.2, 0.2);          /* left / right walls */
    add(&bin, 0, 0.3, 0.9, 1.15, -0.2, 0.2);
    add(&bin, 2, 0.2, -0.3, 0.3, 0.9, 1.6);            /* back wall up to the next shelf */
    add(&bin, 2, -0.2, -0.3, 0.3, 0.9, 1.0);           /* low front lip */
    add(&bin, 1, 1.6, -0.5, 0.5, -0.2, 0.3);           /* the shelf board above */
    add_box(&bin, -0.15, 0.9, -0.05, -0.02, 1.05, 0.08);   /* two objects */
    add_box(&bin, 0.05, 0.9, -0.1, 0.15, 0.98, 0.0);
    const double bin_cams[3][5] = {{0, 1.35, -0.45, 0, 40}, {0.1, 1.35, -0.45, -10, 45}, {-0.1, 1.3, -0.4, 10, 40}};
    CHECK_OK(estimate(&bin, bin_cams, 3, &p, &o));
    check_plane(&o, 0.9, 0.02, 2.5, "bin bottom");
    CHECK(o.height_warning);
    sooc_support_params_default(&p);   /* camera mean */
    CHECK_OK(estimate(&bin, bin_cams, 3, &p, &o));
    check_plane(&o, 0.9, 0.02, 2.5, "bin bottom, camera mean");

    /* no frame with a pose */
    sooc_frame f;
    memset(&f, 0, sizeof f);
    const sooc_frame *fp1[1] = {&f};
    CHECK(sooc_support_estimate(fp1, 1, &p, &o) == SOOC_EINVAL);
}

static void test_gravity_file(void) {
    char dir[] = "/tmp/sooc_support_XXXXXX", path[300];
    if (!mkdtemp(dir)) return;
    snprintf(path, sizeof path, "%s/gravity-direction.txt", dir);
    double g[3];
    CHECK(sooc_support_read_gravity(path, g) == SOOC_ENOTFOUND);
    FILE *fp = fopen(path, "w");
    fprintf(fp, "0.0\n-2.0\n0.0\n");
    fclose(fp);
    CHECK_OK(sooc_support_read_gravity(path, g));
    CHECK(g[0] == 0 && g[1] == -1 && g[2] == 0);
    fp = fopen(path, "w");
    fprintf(fp, "0.0 x 1\n");
    fclose(fp);
    CHECK(sooc_support_read_gravity(path, g) == SOOC_EFORMAT);
    CHECK(strstr(sooc_errmsg(), path) != NULL);
    fp = fopen(path, "w");
    fprintf(fp, "0 0 0\n");
    fclose(fp);
    CHECK(sooc_support_read_gravity(path, g) == SOOC_EINVAL);
    unlink(path);
    rmdir(dir);
}

/* ------------------------------------------------------------ real data */

static const char *real_dir(void) {
    static char buf[1024];
    const char *e = getenv("SOOC_SHARED_REAL");
    snprintf(buf, sizeof buf, "%s", e && *e ? e : "../shared/real");
    char probe[1100];
    snprintf(probe, sizeof probe, "%s/README.md", buf);
    return access(probe, R_OK) == 0 ? buf : NULL;
}

/* 7-Scenes frame i: depth (16-bit mm, 65535 invalid) and pose, without the colour */
static int read_7scenes(const char *dir, int i, sooc_frame *f) {
    char path[1300];
    sooc_image img = {0};
    snprintf(path, sizeof path, "%s/frame-%06d.depth.png", dir, i);
    if (sooc_png_read(path, &img)) return 0;
    if (!f->depth) CHECK_OK(sooc_frame_alloc(f, img.width, img.height, 0));
    const uint16_t *d = (const uint16_t *)img.data;
    for (int k = 0; k < img.width * img.height; k++) {
        f->depth[k] = d[k] && d[k] != 65535 ? (float)(d[k] * 1e-3) : 0.0f;
        f->valid[k] = f->depth[k] > 0;
    }
    sooc_image_free(&img);
    f->K = (sooc_intrinsics){.width = 640, .height = 480, .fx = 585, .fy = 585, .cx = 320, .cy = 240};
    snprintf(path, sizeof path, "%s/frame-%06d.pose.txt", dir, i);
    FILE *fp = fopen(path, "r");
    if (!fp) return 0;
    int ok = 1;
    for (int k = 0; k < 16; k++) ok &= fscanf(fp, "%lf", &f->T_wc[k]) == 1;
    fclose(fp);
    f->has_pose = ok;
    return ok;
}

static int test_real(void) {
    const char *root = real_dir();
    if (!root) {
        printf("test_support_real: SKIP: %s absent\n", "../shared/real");
        return 0;
    }
    char dir[1200];
    sooc_support_params p;
    sooc_support o;
    /* label-fusion: a shelf bin seen by an arm camera, poses with +z up; depth (raw >> 3) * 1e-4 m */
    snprintf(dir, sizeof dir, "%s/label_fusion/data/labels", root);
    sooc_seq_open_params sp;
    sooc_seq_open_params_default(&sp);
    sp.depth_scale = 1e-4;
    sp.depth_shift = 3;
    sooc_seq *s = NULL;
    CHECK_OK(sooc_seq_open(&s, dir, &sp));
    if (!s) return 1;
    sooc_frame fr[15];
    const sooc_frame *fp[15];
    memset(fr, 0, sizeof fr);
    int n = (int)sooc_seq_count(s);
    if (n > 15) n = 15;
    for (int i = 0; i < n; i++) {
        CHECK_OK(sooc_seq_read(s, i, &fr[i]));
        fp[i] = &fr[i];
    }
    sooc_seq_close(s);
    double n_hint[3];
    sooc_support_params_default(&p);
    p.has_up_hint = 1;
    p.up_hint[2] = 1;
    CHECK_OK(sooc_support_estimate(fp, n, &p, &o));
    printf("  label-fusion, up +z: n = (%.3f %.3f %.3f) d = %.3f, tilt %.1f deg, camera height %.3f m, "
           "%zu/%zu inliers, rms %.4f, %d candidates%s\n",
           o.plane_src[0], o.plane_src[1], o.plane_src[2], o.plane_src[3], o.tilt_deg, o.cam_height_m, o.n_inliers,
           o.n_points, o.rms_m, o.n_candidates, o.height_warning ? ", height warning" : "");
    CHECK(o.tilt_deg < 10);
    CHECK(o.cam_height_m > 0.1 && o.cam_height_m < 1.2);
    CHECK(o.height_warning);
    memcpy(n_hint, o.plane_src, sizeof n_hint);
    double h_hint = o.cam_height_m;
    sooc_support_params_default(&p);   /* no hint: the cameras */
    CHECK_OK(sooc_support_estimate(fp, n, &p, &o));
    printf("  label-fusion, camera mean: n = (%.3f %.3f %.3f), camera height %.3f m\n", o.plane_src[0],
           o.plane_src[1], o.plane_src[2], o.cam_height_m);
    CHECK(o.up_source == SOOC_UP_CAMERA_MEAN);
    CHECK(sooc_v3_dot(o.plane_src, n_hint) > cos(2 * DEG));
    CHECK_CLOSE(o.cam_height_m, h_hint, 0.02, 0);
    p.has_up_hint = 1;   /* a wrong hint: +y */
    p.up_hint[1] = 1;
    CHECK(sooc_support_estimate(fp, n, &p, &o) == SOOC_ENOTFOUND);
    printf("  label-fusion, up +y: %s\n", sooc_errmsg());
    for (int i = 0; i < n; i++) sooc_frame_free(&fr[i]);

    /* 7-Scenes redkitchen: gravity file; the floor, not the table top */
    snprintf(dir, sizeof dir, "%s/7scenes_redkitchen", root);
    char gpath[1300];
    snprintf(gpath, sizeof gpath, "%s/gravity-direction.txt", dir);
    sooc_support_params_default(&p);
    CHECK_OK(sooc_support_read_gravity(gpath, p.gravity));
    p.has_gravity = 1;
    memset(fr, 0, sizeof fr);
    int m = 0;
    for (int i = 0; i < 8; i++) {
        if (!read_7scenes(dir, 80 * i, &fr[m])) break;
        fp[m] = &fr[m];
        m++;
    }
    CHECK(m == 8);
    CHECK_OK(sooc_support_estimate(fp, m, &p, &o));
    printf("  7-Scenes, gravity file: n = (%.3f %.3f %.3f) d = %.3f, tilt %.1f deg, camera height %.3f m, "
           "%zu/%zu inliers, %d candidates\n",
           o.plane_src[0], o.plane_src[1], o.plane_src[2], o.plane_src[3], o.tilt_deg, o.cam_height_m, o.n_inliers,
           o.n_points, o.n_candidates);
    CHECK(o.up_source == SOOC_UP_GRAVITY_FILE && o.tilt_deg < 5);
    CHECK(o.cam_height_m > 1.0 && o.cam_height_m < 2.0);
    double g_n[3] = {o.plane_src[0], o.plane_src[1], o.plane_src[2]}, g_h = o.cam_height_m;
    sooc_support_params_default(&p);
    CHECK_OK(sooc_support_estimate(fp, m, &p, &o));
    printf("  7-Scenes, camera mean: n = (%.3f %.3f %.3f), camera height %.3f m\n", o.plane_src[0], o.plane_src[1],
           o.plane_src[2], o.cam_height_m);
    CHECK(sooc_v3_dot(o.plane_src, g_n) > cos(3 * DEG));
    CHECK_CLOSE(o.cam_height_m, g_h, 0.05, 0);
    for (int i = 0; i < m; i++) sooc_frame_free(&fr[i]);
    return 1;
}

static void log_stderr(void *user, sooc_log_level level, const char *msg) {
    (void)user;
    (void)level;
    fprintf(stderr, "    log: %s\n", msg);
}

int main(int argc, char **argv) {
    if (getenv("SOOC_TEST_DEBUG")) {   /* the candidate planes */
        sooc_log_set_level(SOOC_LOG_DEBUG);
        sooc_log_set_callback(log_stderr, NULL);
    }
    if (argc > 1 && !strcmp(argv[1], "real")) {
        int ran = test_real();
        int rc = check_report("test_support_real");
        return (!rc && !ran) ? SOOC_TEST_SKIP : rc;
    }
    test_synthetic();
    test_gravity_file();
    return check_report("test_support");
}
