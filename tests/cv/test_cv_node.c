/* The node with pose.source: odometry (fake mapper, tests/node/fake_mapper.c):
 * frames of the ray-cast room arrive without poses; the odometry tracks
 * them, and the support plane (world.floor: estimate) anchors the map frame
 * as it does with the recorded poses (same run with pose.source: sensor);
 * two frames from elsewhere in the room are untracked: counted, never
 * mapped. Launch keys of
 * the odometry: section parse and bad values fail naming the key. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "sooc3d/slam.h"
#include "sooc3d/mapper.h"
#include "sooc3d/node.h"
#include "room.h"

#define NF 80

typedef struct feeder {
    sooc_frame *frames;
    int n, next, keep_pose;
} feeder;

static sooc_status fd_start(void *ctx) { (void)ctx; return SOOC_OK; }
static void fd_stop(void *ctx) { (void)ctx; }
static void fd_close(void *ctx) { (void)ctx; }
static sooc_status fd_read(void *ctx, sooc_frame *f, int timeout_ms) {
    (void)timeout_ms;
    feeder *d = ctx;
    if (d->next >= d->n) return SOOC_EEOF;
    sooc_status st = sooc_frame_copy(f, &d->frames[d->next++]);
    if (!d->keep_pose) f->has_pose = 0;   /* a camera without poses */
    return st;
}

static const char *g_launch =
    "sensor: {driver: replay, path: unused}\n"
    "pose: {source: odometry}\n"
    "odometry: {variant: rgbd_icp, width: 0, height: 0, keyframe_translation_m: 0.1, max_failures: 10}\n"
    "model: {path: fake}\n"
    "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
    "pipeline: {block_when_full: true, min_depth_m: 0.1, max_depth_m: 10}\n"
    "log: {level: info}\n";

static void log_cb(void *user, sooc_log_level level, const char *msg) {
    (void)user;
    if (level >= SOOC_LOG_INFO && strstr(msg, "support")) printf("  [log] %s\n", msg);
}

int main(void) {
    sooc_log_set_callback(log_cb, NULL);
    /* launch keys */
    sooc_node_config c;
    CHECK(sooc_node_config_parse(&c, g_launch, strlen(g_launch), "odo.yaml") == SOOC_OK);
    CHECK(c.pose_kind == SOOC_NODE_POSE_ODOMETRY && c.odom_variant == 2 && c.odom_width == 0);
    CHECK(c.odom_min_agreement == 0.3 && c.odom_max_failures == 10);
    CHECK(c.odom_color_fx == 0 && c.odom_color_fy == 0 && c.odom_color_tx == 0);   /* registered */
    const char *col = "sensor: {driver: replay, path: x}\npose: {source: odometry}\n"
                      "odometry: {color_fx: 525, color_fy: 526, color_cx: 320, color_cy: 241, color_tx: 0.02}\n";
    CHECK(sooc_node_config_parse(&c, col, strlen(col), "col.yaml") == SOOC_OK);
    CHECK(c.odom_color_fx == 525 && c.odom_color_fy == 526 && c.odom_color_cx == 320 && c.odom_color_cy == 241 &&
          c.odom_color_tx == 0.02 && c.odom_color_tz == 0);
    const char *bad[][2] = {
        {"sensor: {driver: replay, path: x}\npose: {source: odometry}\nodometry: {variant: orb}\n", "odometry.variant"},
        {"sensor: {driver: replay, path: x}\npose: {source: odometry}\nodometry: {min_agreement: 2}\n",
         "odometry.min_agreement"},
        {"sensor: {driver: replay, path: x}\npose: {source: odometry}\nodometry: {width: 320, height: 0}\n", "odometry.width"},
        {"sensor: {driver: replay, path: x}\npose: {source: odometry}\nodometry: {colour: 1}\n", "unknown key"},
        {"sensor: {driver: replay, path: x}\npose: {source: odometry}\nodometry: {color_fx: 525}\n", "odometry.color_fx"},
        {"sensor: {driver: replay, path: x}\npose: {source: odometry}\nodometry: {color_tx: 3}\n", "odometry.color_tx"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sooc_status st = sooc_node_config_parse(&c, bad[i][0], strlen(bad[i][0]), "bad.yaml");
        CHECK(st == SOOC_EINVAL);
        CHECK_MSG(strstr(sooc_errmsg(), bad[i][1]) != NULL, "case %zu: %s", i, sooc_errmsg());
    }
    /* a live driver may use odometry */
    const char *live = "sensor: {driver: v4l2}\npose: {source: odometry}\n";
    CHECK(sooc_node_config_parse(&c, live, strlen(live), "live.yaml") == SOOC_OK);
    char buf[4096];
    sooc_node_config_format(&c, buf, sizeof buf);
    CHECK(strstr(buf, "source: odometry") && strstr(buf, "odometry: {variant: rgbd_icp"));

    if (!sooc_cv_available()) {
        printf("test_cv_node: node run SKIP: built without OpenCV\n");
        return g_check_fail ? 1 : SOOC_TEST_SKIP;
    }
    /* frames: the walk looking 20 deg down (the floor in view), with two
     * frames from elsewhere at 30 and 31 */
    g_walk_pitch0 = 0.35;
    sooc_intrinsics K;
    memset(&K, 0, sizeof K);
    K.width = W;
    K.height = H;
    K.fx = K.fy = 262.5;
    K.cx = 159.5;
    K.cy = 119.5;
    sooc_frame *fr = calloc(NF, sizeof *fr);
    for (int i = 0, w = 0; i < NF; i++) {
        CHECK(sooc_frame_alloc(&fr[i], W, H, 0) == SOOC_OK);
        double T[16];
        if (i == 30 || i == 31) {
            double R[9], t[3], Ry[9], Rn[9];
            walk_pose(w, T);
            sooc_se3_to_rt(R, t, T);
            sooc_m3_rot_y(Ry, 2.1 + 0.3 * (i - 30));
            sooc_m3_mul(Rn, Ry, R);
            t[0] += 1.2;
            sooc_se3_from_rt(T, Rn, t);
        } else {
            walk_pose(w++, T);
        }
        render(T, &K, &fr[i]);
        fr[i].t_ns = (int64_t)i * 33333333;
        fr[i].index = i;
    }
    /* the same frames twice: recorded poses (pose.source: sensor, the two
     * frames from elsewhere dropped), then odometry alone */
    double up[3] = {0, 1, 0}, T0[16];
    walk_pose(0, T0);
    sooc_node_stats s_gt, s_odo;
    memset(&s_gt, 0, sizeof s_gt);
    memset(&s_odo, 0, sizeof s_odo);
    for (int run = 0; run < 2; run++) {
        char launch[2048];
        if (run == 0) {
            const char *q = strstr(g_launch, "pose:");
            snprintf(launch, sizeof launch, "sensor: {driver: replay, path: unused}\npose: {source: sensor}\n%s",
                     strstr(q, "\n") + 1);
        } else {
            /* world.up: the room's up in the first camera's frame (the odometry origin) */
            double yw[3] = {0, 1, 0};
            for (int k = 0; k < 3; k++) up[k] = T0[k] * yw[0] + T0[4 + k] * yw[1] + T0[8 + k] * yw[2];
            snprintf(launch, sizeof launch, "%s", g_launch);
        }
        size_t L = strlen(launch);
        snprintf(launch + L, sizeof launch - L, "world: {up: [%.6f, %.6f, %.6f], floor: estimate, support_frames: 8}\n",
                 up[0], up[1], up[2]);
        CHECK(sooc_node_config_parse(&c, launch, strlen(launch), "odo.yaml") == SOOC_OK);
        feeder fd = {fr, NF, 0, run == 0};
        if (run == 0) {   /* the two frames from elsewhere carry no recorded pose */
            fr[30].has_pose = fr[31].has_pose = 0;
        }
        sooc_node_source src = {&fd, fd_start, fd_read, fd_stop, fd_close, NULL, NULL};
        sooc_mapper *m = NULL;
        sooc_mapper_params mp;
        sooc_mapper_params_default(&mp);
        CHECK(sooc_mapper_create(&m, &mp) == SOOC_OK);
        sooc_node_options o;
        memset(&o, 0, sizeof o);
        o.source = &src;
        o.mapper = m;
        sooc_node *n = NULL;
        sooc_status st = sooc_node_create(&n, &c, &o);
        CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
        if (!st) {
            CHECK_MSG(sooc_node_run(n) == SOOC_OK, "%s", sooc_errmsg());
            sooc_node_get_stats(n, run ? &s_odo : &s_gt);
            char line[512];
            sooc_node_stats_format(run ? &s_odo : &s_gt, line, sizeof line);
            printf("node with %s: %s\n", run ? "odometry" : "recorded poses", line);
            if (run) CHECK(strstr(line, "untracked 2") != NULL);
            sooc_node_destroy(n);
        }
        sooc_mapper_destroy(m);
    }
    CHECK(s_odo.frames_in == NF);
    CHECK_MSG(s_odo.frames_untracked == 2 && s_odo.frames_no_pose == 2, "untracked %llu",
              (unsigned long long)s_odo.frames_untracked);
    CHECK(s_gt.frames_untracked == 0 && s_gt.frames_no_pose == 2);
    CHECK(s_odo.keyframes >= 5);
    CHECK_MSG(llabs((long long)s_odo.keyframes - (long long)s_gt.keyframes) <= 1, "keyframes %llu vs %llu",
              (unsigned long long)s_odo.keyframes, (unsigned long long)s_gt.keyframes);
    /* the support plane anchors both maps alike: the first camera's height
     * above the plane and its up axis in the map frame agree */
    double Tw_gt[16];
    sooc_se3_mul(Tw_gt, s_gt.T_world_src, T0);   /* first camera in the map from recorded poses */
    printf("first camera in the map frame: height %.4f m (odometry) vs %.4f m (recorded poses)\n",
           s_odo.T_world_src[7], Tw_gt[7]);
    CHECK(fabs(s_odo.T_world_src[7] - Tw_gt[7]) < 0.02);
    /* the map's up (+y) seen from the first camera agrees (the yaw about it
     * is free: each map takes the smallest rotation from its own frame):
     * row 1 of the camera's rotation in the map */
    double dup = 0;
    for (int k = 0; k < 3; k++) dup += fabs(s_odo.T_world_src[4 + k] - Tw_gt[4 + k]);
    CHECK_MSG(dup < 0.02, "up axis differs: %.4f", dup);
    for (int i = 0; i < NF; i++) sooc_frame_free(&fr[i]);
    free(fr);
    printf("test_cv_node: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail != 0;
}
