/* Real frames through robot logs and back (docs/logs.md "Round trips"):
 *  - 20 frames of 7-Scenes redkitchen written as a ROS 1 bag by Debian's
 *    python3-rosbag (LZ4 chunks, /tf, JPEG CompressedImage, 16UC1 depth;
 *    tests/logs/write_bag.py serialises them itself, independently of sooc3d);
 *  - the 15 label-fusion frames written as a ROS 2 MCAP file by the project's
 *    writer (CDR, zstd chunks, /tf, rgb8 and 32FC1 images);
 * each read through the frame path and mapped by `sooc3d infer` next to the
 * same frames read from a folder: the frames are identical (pixels exactly,
 * poses within 1e-12) and the maps hold the same objects (count, positions
 * within 1 cm). The bag is also replayed through the launch file's rosbag
 * driver with pose.source tf. A quaternion cannot hold a recorded rotation
 * that is not exactly orthonormal, so each folder holds the rotation its
 * log's quaternion stands for. Needs ../shared/real, the sooc3d binary and
 * python3-rosbag; skips (77) with the reason when one is missing. */
#include "logs_util.h"
#include "sooc3d/driver.h"
#include "sooc3d/frame.h"
#include "sooc3d/core.h"
#include "sooc3d/node.h"

#include <math.h>
#include <sys/wait.h>

static const char *g_model = "models/sooc3d_tabletop/model.bin";

/* Frames of two paths through the frame path, compared. */
static void same_frames(const char *a, const char *b, int64_t n) {
    sooc_framepath_params p;
    sooc_framepath_params_default(&p);
    p.world = SOOC_WORLD_IDENTITY;
    sooc_framepath *fa = NULL, *fb = NULL;
    CHECK_OK(sooc_framepath_open(&fa, a, &p));
    CHECK_OK(sooc_framepath_open(&fb, b, &p));
    if (!fa || !fb) goto done;
    CHECK_MSG(sooc_framepath_count(fa) == n && sooc_framepath_count(fb) == n, "%lld / %lld frames, expected %lld",
              (long long)sooc_framepath_count(fa), (long long)sooc_framepath_count(fb), (long long)n);
    sooc_frame x = {0}, y = {0};
    int64_t bad_px = 0;
    double dT = 0;
    for (int64_t i = 0; i < n && i < sooc_framepath_count(fb); i++) {
        CHECK_OK(sooc_framepath_read_raw(fa, i, &x));
        CHECK_OK(sooc_framepath_read_raw(fb, i, &y));
        CHECK(x.width == y.width && x.height == y.height && x.has_pose && y.has_pose);
        if (x.width != y.width || x.height != y.height) break;
        CHECK(!memcmp(&x.K, &y.K, sizeof x.K) && x.t_ns == y.t_ns);
        size_t np = (size_t)x.width * (size_t)x.height;
        bad_px += memcmp(x.rgb, y.rgb, np * 3) != 0;
        for (size_t k = 0; k < np; k++) bad_px += x.depth[k] != y.depth[k] || x.valid[k] != y.valid[k];
        for (int k = 0; k < 16; k++) dT = fmax(dT, fabs(x.T_wc[k] - y.T_wc[k]));
    }
    CHECK_MSG(bad_px == 0 && dT < 1e-12, "%s vs %s: %lld pixels differ, poses by %.3g", a, b, (long long)bad_px, dT);
    printf("  %s = %s: %lld frames, pixels identical, poses within %.1g\n", b, a, (long long)n, dT);
    sooc_frame_free(&x);
    sooc_frame_free(&y);
done:
    sooc_framepath_close(fa);
    sooc_framepath_close(fb);
}

/* `sooc3d infer` on both, the maps compared: same count, each object within 1 cm. */
static void same_maps(const char *bin, const char *a, const char *b, const char *tmp, const char *tag,
                      const char *label) {
    char oa[700], ob[700];
    snprintf(oa, sizeof oa, "%s/map_%s_folder", tmp, tag);
    snprintf(ob, sizeof ob, "%s/map_%s_log", tmp, tag);
    int na, nb;
    double worst;
    lu_infer_maps(bin, g_model, a, oa, b, ob, 0, &na, &nb, &worst);
    CHECK_MSG(na > 0 && na == nb, "%s: %d objects from the folder, %d from the log", label, na, nb);
    CHECK_MSG(worst <= 0.01, "%s: an object moved %.4f m", label, worst);
    printf("  %s: infer maps %d objects from the folder and %d from the log, largest offset %.2g m\n", label, na, nb,
           worst);
}

/* A label-fusion folder as MCAP (CDR, zstd, /tf) and as the folder of the same frames. */
static int write_mcap(const char *src, const char *mcap, const char *folder) {
    sooc_seq *s = NULL;
    CHECK_OK(sooc_seq_open(&s, src, NULL));
    if (!s) return -1;
    sooc_mcap_writer_params wp;
    sooc_mcap_writer_params_default(&wp);
    wp.profile = "ros2";
    sooc_mcap_writer *w = NULL;
    CHECK_OK(sooc_mcap_writer_open(&w, mcap, &wp));
    int sc_img, sc_info, sc_tf, ci, di, ii, tf, tfs;
    const char *types[3] = {"sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo", "tf2_msgs/msg/TFMessage"};
    int *scs[3] = {&sc_img, &sc_info, &sc_tf};
    for (int k = 0; k < 3; k++) {
        const char *def = sooc_ros_definition(types[k], SOOC_MSGENC_CDR);
        CHECK_OK(sooc_mcap_writer_schema(w, types[k], "ros2msg", def, strlen(def), scs[k]));
    }
    CHECK_OK(sooc_mcap_writer_channel(w, sc_img, "/camera/color/image_raw", "cdr", &ci));
    CHECK_OK(sooc_mcap_writer_channel(w, sc_img, "/camera/aligned_depth_to_color/image_raw", "cdr", &di));
    CHECK_OK(sooc_mcap_writer_channel(w, sc_info, "/camera/color/camera_info", "cdr", &ii));
    CHECK_OK(sooc_mcap_writer_channel(w, sc_tf, "/tf", "cdr", &tf));
    CHECK_OK(sooc_mcap_writer_channel(w, sc_tf, "/tf_static", "cdr", &tfs));
    sooc_ros_buf b = {0};
    sooc_frame f = {0};
    float *z = NULL;
    char p[1400], q[1400];
    int64_t n = sooc_seq_count(s);
    const char *cam = "camera_color_optical_frame";
    sooc_ros_transform st = {{0, "map"}, "world", {0, 0, 0}, {0, 0, 0, 1}};
    CHECK_OK(sooc_ros_encode_tf(&b, SOOC_MSGENC_CDR, &st, 1));
    CHECK_OK(sooc_mcap_writer_message(w, tfs, 0, 0, b.data, b.size));
    for (int64_t i = 0; i < n; i++) {
        CHECK_OK(sooc_seq_read(s, i, &f));
        int64_t t = f.t_ns;
        size_t np = (size_t)f.width * (size_t)f.height;
        if (!z) z = malloc(np * sizeof *z);
        for (size_t k = 0; k < np; k++) z[k] = f.valid[k] ? f.depth[k] : NAN;
        double R[9], tr[3], Rq[9];
        sooc_se3_to_rt(R, tr, f.T_wc);
        sooc_ros_transform pose = {{t, "world"}, "", {tr[0], tr[1], tr[2]}, {0, 0, 0, 1}};
        snprintf(pose.child, sizeof pose.child, "%s", cam);
        sooc_m3_to_quat(pose.q, R);
        b.size = 0;
        CHECK_OK(sooc_ros_encode_tf(&b, SOOC_MSGENC_CDR, &pose, 1));
        CHECK_OK(sooc_mcap_writer_message(w, tf, t, t, b.data, b.size));
        sooc_ros_caminfo k;
        memset(&k, 0, sizeof k);
        k.header = (sooc_ros_header){t, ""};
        snprintf(k.header.frame_id, sizeof k.header.frame_id, "%s", cam);
        k.width = f.width;
        k.height = f.height;
        double K[9] = {f.K.fx, 0, f.K.cx, 0, f.K.fy, f.K.cy, 0, 0, 1};
        memcpy(k.K, K, sizeof K);
        b.size = 0;
        CHECK_OK(sooc_ros_encode_caminfo(&b, SOOC_MSGENC_CDR, &k));
        CHECK_OK(sooc_mcap_writer_message(w, ii, t, t, b.data, b.size));
        sooc_ros_image im = {k.header, f.width, f.height, (size_t)f.width * 3, "rgb8", 0, f.rgb, np * 3};
        b.size = 0;
        CHECK_OK(sooc_ros_encode_image(&b, SOOC_MSGENC_CDR, &im));
        CHECK_OK(sooc_mcap_writer_message(w, ci, t, t, b.data, b.size));
        sooc_ros_image dm = {k.header, f.width, f.height, (size_t)f.width * 4, "32FC1", 0, (uint8_t *)z, np * 4};
        b.size = 0;
        CHECK_OK(sooc_ros_encode_image(&b, SOOC_MSGENC_CDR, &dm));
        CHECK_OK(sooc_mcap_writer_message(w, di, t + 1000000, t + 1000000, b.data, b.size));
        /* the folder: the same images, the rotation the quaternion stands for */
        int64_t num = sooc_seq_frame_number(s, i);
        const char *ext[2] = {"color.png", "depth.png"};
        for (int e = 0; e < 2; e++) {
            snprintf(p, sizeof p, "%s/frame-%06lld.%s", src, (long long)num, ext[e]);
            snprintf(q, sizeof q, "%s/frame-%06lld.%s", folder, (long long)num, ext[e]);
            CHECK(symlink(p, q) == 0);
        }
        sooc_quat_to_m3(Rq, pose.q);
        snprintf(q, sizeof q, "%s/frame-%06lld.pose.txt", folder, (long long)num);
        FILE *pf = fopen(q, "w");
        for (int r = 0; r < 3; r++) fprintf(pf, "%.17g %.17g %.17g %.17g\n", Rq[3 * r], Rq[3 * r + 1], Rq[3 * r + 2], tr[r]);
        fprintf(pf, "0 0 0 1\n");
        fclose(pf);
    }
    snprintf(p, sizeof p, "%s/camera-intrinsics.color.txt", src);
    snprintf(q, sizeof q, "%s/camera-intrinsics.color.txt", folder);
    CHECK(symlink(p, q) == 0);
    CHECK_OK(sooc_mcap_writer_close(w));
    sooc_ros_buf_free(&b);
    sooc_frame_free(&f);
    free(z);
    sooc_seq_close(s);
    return (int)n;
}

/* The bag through the launch file's rosbag driver, pose from TF. */
static void via_launch(const char *bag, const char *folder, int n) {
    char text[2048];
    snprintf(text, sizeof text, "sensor: {driver: rosbag, path: '%s', speed: fast, pair_tol_ms: 10}\n"
                                "pose: {source: tf, parent: map}\nmodel: {path: fake.bin}\n", bag);
    sooc_node_config c;
    CHECK_OK(sooc_node_config_parse(&c, text, strlen(text), "bag.yaml"));
    sooc_sensor_params sp;
    sooc_sensor_params_default(&sp);
    for (int i = 0; i < c.n_params; i++) {
        const char *k = c.params[i].key, *v = c.params[i].value;
        if (!strcmp(k, "path")) k = "uri";
        if (!strcmp(k, "speed")) v = "0";
        CHECK_OK(sooc_sensor_params_set(&sp, k, v));
    }
    CHECK(c.pose_kind == SOOC_NODE_POSE_TF && !strcmp(c.pose_parent, "map"));
    sp.pose_parent = c.pose_parent;   /* as the node passes pose.source: tf */
    sooc_sensor *s = NULL;
    CHECK_OK(sooc_sensor_open(&s, "rosbag", &sp));
    sooc_seq *q = NULL;
    CHECK_OK(sooc_seq_open(&q, folder, NULL));
    if (s && q) {
        CHECK_OK(sooc_sensor_start(s));
        sooc_frame f = {0}, g = {0};
        int got = 0;
        double dT = 0;
        while (sooc_sensor_read(s, &f, 1000) == SOOC_OK) {
            CHECK_OK(sooc_seq_read(q, got, &g));
            CHECK(f.has_pose && !memcmp(f.rgb, g.rgb, (size_t)f.width * f.height * 3));
            for (int k = 0; k < 16; k++) dT = fmax(dT, fabs(f.T_wc[k] - g.T_wc[k]));
            got++;
        }
        CHECK_MSG(got == n && dT < 1e-12, "rosbag driver: %d frames (expected %d), poses within %.3g", got, n, dT);
        printf("  launch {driver: rosbag, pose: {source: tf, parent: map}}: %d frames, poses within %.1g\n", got, dT);
        sooc_frame_free(&f);
        sooc_frame_free(&g);
    }
    sooc_sensor_close(s);
    sooc_seq_close(q);
    /* the wrong driver for the file, and launch files that cannot work */
    CHECK(sooc_sensor_open(&s, "mcap", &sp) == SOOC_EINVAL && strstr(sooc_errmsg(), "driver rosbag"));
    printf("  EINVAL -> %s\n", sooc_errmsg());
    static const char *bad[3][2] = {
        {"sensor: {driver: replay, path: x}\npose: {source: tf, parent: map}\n", "sensor.driver rosbag or mcap"},
        {"sensor: {driver: mcap, path: x.mcap}\n", "source: tf"},
        {"sensor: {driver: rosbag, path: x.bag}\npose: {source: tf}\n", "needs pose.parent"}};
    for (int i = 0; i < 3; i++) {
        CHECK(sooc_node_config_parse(&c, bad[i][0], strlen(bad[i][0]), "bad.yaml") == SOOC_EINVAL);
        CHECK_MSG(strstr(sooc_errmsg(), bad[i][1]) != NULL, "%s", sooc_errmsg());
    }
}

int main(void) {
    const char *bags = lu_bags("test_logs_roundtrip");
    const char *real = getenv("SOOC_SHARED_REAL"), *bin = getenv("SOOC_BIN"), *py = getenv("SOOC_PYTHON3");
    char rk[1024], lf[1024];
    snprintf(rk, sizeof rk, "%s/7scenes_redkitchen", real ? real : "../shared/real");
    snprintf(lf, sizeof lf, "%s/label_fusion/data/labels", real ? real : "../shared/real");
    if (!bags) return SOOC_TEST_SKIP;
    if (!sooc_dir_exists(rk) || !sooc_dir_exists(lf)) {
        printf("test_logs_roundtrip: SKIP: the real recordings are not at %s (SOOC_SHARED_REAL)\n", rk);
        return SOOC_TEST_SKIP;
    }
    if (!bin || !sooc_file_exists(bin) || !sooc_file_exists(g_model)) {
        printf("test_logs_roundtrip: SKIP: no sooc3d binary (SOOC_BIN) or no %s\n", g_model);
        return SOOC_TEST_SKIP;
    }
    char *tmp = lu_tmpdir("logs_roundtrip");
    char cmd[4096], bag[700], bagdir[700], mcap[700], mdir[700], src[1100];
    snprintf(bag, sizeof bag, "%s/redkitchen.bag", tmp);
    snprintf(bagdir, sizeof bagdir, "%s/redkitchen", tmp);
    snprintf(src, sizeof src, "%s/tests/logs/write_bag.py", getenv("SOOC_SRC") ? getenv("SOOC_SRC") : ".");
    snprintf(cmd, sizeof cmd, "'%s' '%s' '%s' '%s' 20 --compression lz4 --folder '%s'", py && *py ? py : "python3", src,
             rk, bag, bagdir);
    int rc = system(cmd);
    if (WIFEXITED(rc) && WEXITSTATUS(rc) == 77) {
        printf("test_logs_roundtrip: SKIP: python3-rosbag is not installed (tests/logs/write_bag.py)\n");
        return SOOC_TEST_SKIP;
    }
    CHECK_MSG(rc == 0, "%s failed (%d)", cmd, rc);
    if (rc == 0) {
        same_frames(bagdir, bag, 20);
        same_maps(bin, bagdir, bag, tmp, "bag", "redkitchen bag (python3-rosbag, LZ4, /tf)");
        via_launch(bag, bagdir, 20);
    }
    snprintf(mcap, sizeof mcap, "%s/labels.mcap", tmp);
    snprintf(mdir, sizeof mdir, "%s/labels", tmp);
    CHECK(mkdir(mdir, 0755) == 0);
    int n = write_mcap(lf, mcap, mdir);
    if (n > 0) {
        same_frames(mdir, mcap, n);
        same_maps(bin, mdir, mcap, tmp, "mcap", "label-fusion MCAP (sooc3d writer, CDR, zstd, /tf)");
    }
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (!g_check_fail && system(cmd) != 0) printf("could not remove %s\n", tmp);
    return check_report("test_logs_roundtrip");
}
