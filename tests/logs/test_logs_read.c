/* The ROS bag and MCAP readers on every fixture of ../shared/bags
 * (SOOC_SHARED_BAGS; the test skips with exit 77 when it is absent), the
 * message decoders on the RealSense bag, and damaged copies written to a
 * temp dir: each fails with a message naming the file and the offset. */
#include "logs_util.h"

#include <math.h>

static sooc_logfile *open_ok(const char *path) {
    sooc_logfile *lf = NULL;
    CHECK_OK(sooc_logfile_open(&lf, path));
    return lf;
}

/* All messages of a log: the same bytes in every copy of example.bag. */
static uint32_t digest(sooc_logfile *lf, int64_t *n) {
    uint32_t crc = 0;
    *n = 0;
    for (int64_t k = 0; k < sooc_logfile_count(lf); k++) {
        sooc_logfile_msg m;
        sooc_status st = sooc_logfile_read(lf, k, &m);
        CHECK_MSG(st == SOOC_OK, "read %lld: %s", (long long)k, sooc_errmsg());
        if (st) break;
        const sooc_logfile_channel *c = sooc_logfile_channel_get(lf, m.channel);
        crc = sooc_crc32(crc, c->topic, strlen(c->topic));
        crc = sooc_crc32(crc, &m.t_ns, sizeof m.t_ns);
        crc = sooc_crc32(crc, m.data, m.size);
        (*n)++;
    }
    return crc;
}

static void test_turtlesim(const char *bags) {
    const char *names[3] = {"rosbag.js/example.bag", "rosbag.js/example-lz4.bag", "rosbag.js/example-bz2.bag"};
    const char *comp[3] = {"none", "lz4", "bz2"};
    uint32_t d0 = 0;
    for (int i = 0; i < 3; i++) {
        sooc_logfile *lf = open_ok(lu_path(bags, names[i]));
        if (!lf) continue;
        sooc_logfile_info in;
        sooc_logfile_get_info(lf, &in);
        CHECK(in.kind == SOOC_LOGFILE_ROSBAG && in.indexed);
        CHECK_MSG(!strcmp(in.compression, comp[i]), "%s: compression %s", names[i], in.compression);
        CHECK(sooc_logfile_count(lf) == 8647);
        int64_t n_tf = 0, n_static = 0, n_transforms = 0;
        sooc_ros_transform tf[4];
        for (int c = 0; c < sooc_logfile_channel_count(lf); c++) {
            const sooc_logfile_channel *ch = sooc_logfile_channel_get(lf, c);
            if (strcmp(ch->topic, "/tf") && strcmp(ch->topic, "/tf_static")) continue;
            int64_t nm;
            const int64_t *pos = sooc_logfile_channel_msgs(lf, c, &nm);
            if (!strcmp(ch->topic, "/tf")) n_tf += nm;
            else n_static += nm;
            for (int64_t k = 0; k < nm; k++) {
                sooc_logfile_msg m;
                int nt = 0;
                CHECK_OK(sooc_logfile_read(lf, pos[k], &m));
                CHECK_OK(sooc_ros_decode_tf(m.data, m.size, ch->enc, tf, 4, &nt));
                n_transforms += nt;
                if (!strcmp(ch->topic, "/tf_static")) {
                    CHECK(!strcmp(tf[0].header.frame_id, "turtle1") && !strcmp(tf[0].child, "carrot"));
                    CHECK(tf[0].t[0] == 1.0 && tf[0].q[3] == 1.0);
                    CHECK(tf[0].header.stamp_ns == 1396293887807552910LL);
                }
                if (!strcmp(ch->topic, "/tf") && m.t_ns == 1396293888056251251LL) {
                    CHECK(!strcmp(tf[0].header.frame_id, "world") && !strcmp(tf[0].child, "turtle2"));
                    CHECK(tf[0].t[0] == 4.0 && fabs(tf[0].t[1] - 9.088889122009277) < 1e-12);
                }
            }
        }
        CHECK_MSG(n_tf == 2688 && n_static == 1 && n_transforms == 2689, "%s: /tf %lld /tf_static %lld (%lld)",
                  names[i], (long long)n_tf, (long long)n_static, (long long)n_transforms);
        int64_t n;
        uint32_t d = digest(lf, &n);
        if (i == 0) d0 = d;
        CHECK_MSG(d == d0 && n == 8647, "%s: messages differ from example.bag", names[i]);
        CHECK_OK(sooc_logfile_verify(lf));
        printf("  %s: 8647 messages, %s chunks, /tf %lld, digest %08x\n", names[i], comp[i], (long long)n_tf, d);
        sooc_logfile_close(lf);
    }
}

static void test_small_bags(const char *bags) {
    /* chunks whose time ranges are out of order: read back in time order */
    sooc_logfile *lf = open_ok(lu_path(bags, "rosbag.js/example-unsorted-chunks.bag"));
    if (lf) {
        sooc_logfile_info in;
        sooc_logfile_get_info(lf, &in);
        CHECK(sooc_logfile_count(lf) == 3 && in.n_chunks == 3);
        for (int k = 0; k < 3; k++) {
            sooc_logfile_msg m;
            CHECK_OK(sooc_logfile_read(lf, k, &m));
            CHECK(m.t_ns == (k + 1) * 1000000000LL);
            CHECK(m.size == 5 && m.data[4] == '1' + k);
        }
        sooc_logfile_close(lf);
    }
    lf = open_ok(lu_path(bags, "rosbag.js/no-messages.bag"));
    if (lf) {
        CHECK(sooc_logfile_count(lf) == 0);
        sooc_logfile_msg m;
        CHECK(sooc_logfile_read(lf, 0, &m) == SOOC_EINVAL);
        sooc_logfile_close(lf);
    }
    lu_open_fails(lu_path(bags, "rosbag.js/empty-file.bag"), SOOC_EFORMAT, "empty file", NULL);
    CHECK(sooc_logfile_detect(lu_path(bags, "rosbag.js/empty-file.bag")) == SOOC_LOGFILE_NONE);
    CHECK(sooc_logfile_detect(lu_path(bags, "rosbag.js/example.bag")) == SOOC_LOGFILE_ROSBAG);
    CHECK(sooc_logfile_detect(lu_path(bags, "rosbag2/talker.mcap")) == SOOC_LOGFILE_MCAP);
    CHECK(sooc_logfile_detect(bags) == SOOC_LOGFILE_NONE);
}

static void test_realsense(const char *bags) {
    sooc_logfile *lf = open_ok(lu_path(bags, "librealsense/single_depth_color_640x480.bag"));
    if (!lf) return;
    sooc_logfile_info in;
    sooc_logfile_get_info(lf, &in);
    CHECK(in.n_channels == 70 && in.n_messages == 135 && !strcmp(in.compression, "lz4"));
    int d = sooc_logfile_find(lf, "/device_0/sensor_0/Depth_0/image/data");
    int c = sooc_logfile_find(lf, "/device_0/sensor_1/Color_0/image/data");
    int di = sooc_logfile_find(lf, "/device_0/sensor_0/Depth_0/info/camera_info");
    int ci = sooc_logfile_find(lf, "/device_0/sensor_1/Color_0/info/camera_info");
    int du = sooc_logfile_find(lf, "/device_0/sensor_0/option/Depth Units/value");
    int ex = sooc_logfile_find(lf, "/device_0/sensor_1/Color_0/tf/0");
    CHECK(d >= 0 && c >= 0 && di >= 0 && ci >= 0 && du >= 0 && ex >= 0);
    if (d < 0 || c < 0 || di < 0 || ci < 0 || du < 0 || ex < 0) {
        sooc_logfile_close(lf);
        return;
    }
    int64_t n;
    const int64_t *pos = sooc_logfile_channel_msgs(lf, d, &n);
    CHECK(n == 2 && !strcmp(sooc_logfile_channel_get(lf, d)->type, "sensor_msgs/Image"));
    sooc_logfile_msg m;
    sooc_ros_image im;
    CHECK_OK(sooc_logfile_read(lf, pos[0], &m));
    CHECK_OK(sooc_ros_decode_image(m.data, m.size, SOOC_MSGENC_ROS1, &im));
    CHECK(im.width == 640 && im.height == 480 && !strcmp(im.encoding, "mono16") && im.step == 1280 &&
          im.size == 614400 && !im.bigendian);
    CHECK(im.header.stamp_ns == 360815089000LL && !strcmp(im.header.frame_id, "0"));
    pos = sooc_logfile_channel_msgs(lf, c, &n);
    CHECK(n == 1);
    CHECK_OK(sooc_logfile_read(lf, pos[0], &m));
    CHECK_OK(sooc_ros_decode_image(m.data, m.size, SOOC_MSGENC_ROS1, &im));
    CHECK(im.width == 640 && im.height == 480 && !strcmp(im.encoding, "rgb8") && im.step == 1920);
    sooc_ros_caminfo k;
    pos = sooc_logfile_channel_msgs(lf, di, &n);
    CHECK_OK(sooc_logfile_read(lf, pos[0], &m));
    CHECK_OK(sooc_ros_decode_caminfo(m.data, m.size, SOOC_MSGENC_ROS1, &k));
    CHECK(k.width == 640 && k.height == 480 && k.nD == 5 && !strcmp(k.distortion_model, "Brown Conrady"));
    CHECK_CLOSE(k.K[0], 390.43145751953125, 1e-9, 0);
    CHECK_CLOSE(k.K[2], 331.38787841796875, 1e-9, 0);
    CHECK_CLOSE(k.K[5], 242.18734741210938, 1e-9, 0);
    pos = sooc_logfile_channel_msgs(lf, ci, &n);
    CHECK_OK(sooc_logfile_read(lf, pos[0], &m));
    CHECK_OK(sooc_ros_decode_caminfo(m.data, m.size, SOOC_MSGENC_ROS1, &k));
    CHECK_CLOSE(k.K[0], 613.2036743164062, 1e-9, 0);
    CHECK_CLOSE(k.K[4], 613.4193115234375, 1e-9, 0);
    double units = 0;
    pos = sooc_logfile_channel_msgs(lf, du, &n);
    CHECK_OK(sooc_logfile_read(lf, pos[0], &m));
    CHECK_OK(sooc_ros_decode_float(sooc_logfile_channel_get(lf, du)->type, m.data, m.size, SOOC_MSGENC_ROS1, &units));
    CHECK_CLOSE(units, 0.001, 1e-9, 0);
    sooc_ros_transform t;
    pos = sooc_logfile_channel_msgs(lf, ex, &n);
    CHECK_OK(sooc_logfile_read(lf, pos[0], &m));
    CHECK_OK(sooc_ros_decode_pose(sooc_logfile_channel_get(lf, ex)->type, m.data, m.size, SOOC_MSGENC_ROS1, &t));
    CHECK_CLOSE(t.t[0], 0.01431131362915039, 1e-12, 0);
    CHECK_CLOSE(t.q[3], 0.9999658465385437, 1e-12, 0);
    /* a decoder given too few bytes names the type and the byte */
    CHECK(sooc_ros_decode_image(m.data, 10, SOOC_MSGENC_ROS1, &im) == SOOC_EFORMAT);
    CHECK_MSG(strstr(sooc_errmsg(), "truncated sensor_msgs/Image") != NULL, "%s", sooc_errmsg());
    printf("  realsense: depth 640x480 mono16, colour rgb8, K %.2f / %.2f, depth units %g\n", 390.43, 613.20, units);
    sooc_logfile_close(lf);
}

static void test_mcap(const char *bags) {
    sooc_logfile *lf = open_ok(lu_path(bags, "rosbag2/talker.mcap"));
    if (lf) {
        sooc_logfile_info in;
        sooc_logfile_get_info(lf, &in);
        CHECK(in.kind == SOOC_LOGFILE_MCAP && in.indexed && !strcmp(in.compression, "zstd"));
        int ch = sooc_logfile_find(lf, "/topic");
        CHECK(ch >= 0 && sooc_logfile_channel_get(lf, ch)->enc == SOOC_MSGENC_CDR);
        CHECK(!strcmp(sooc_logfile_channel_get(lf, ch)->type, "std_msgs/msg/String"));
        int64_t n;
        const int64_t *pos = sooc_logfile_channel_msgs(lf, ch, &n);
        CHECK(n == 10);
        for (int64_t k = 0; k < n; k++) {
            sooc_logfile_msg m;
            char want[32];
            snprintf(want, sizeof want, "Hello, world! %d", (int)k);
            CHECK_OK(sooc_logfile_read(lf, pos[k], &m));
            /* CDR string: 4-byte header, uint32 length counting the NUL, the bytes */
            CHECK(m.size >= 8 && logs_u32_le(m.data + 4) == strlen(want) + 1 && !memcmp(m.data + 8, want, strlen(want)));
        }
        CHECK_OK(sooc_logfile_verify(lf));
        sooc_logfile_close(lf);
    }
    lf = open_ok(lu_path(bags, "rosbag2/cdr_test_0.mcap"));
    if (lf) {
        CHECK(sooc_logfile_count(lf) == 7 && sooc_logfile_channel_count(lf) == 2);
        int64_t n;
        CHECK_OK(sooc_logfile_verify(lf));
        digest(lf, &n);
        CHECK(n == 7);
        sooc_logfile_close(lf);
    }
}

/* Damaged copies: truncated, bad CRCs, unknown compressions, bad magic, corrupt data. */
static void test_damaged(const char *bags, const char *tmp) {
    sooc_logfile *lf = NULL;
    size_t n;
    uint8_t *d = lu_read(lu_path(bags, "rosbag.js/example-lz4.bag"), &n);
    CHECK(d != NULL);
    if (!d) return;
    char *p = lu_path(tmp, "truncated.bag");
    lu_write(p, d, n / 2);
    lu_open_fails(p, SOOC_EFORMAT, "truncated", "offset");
    p = lu_path(tmp, "header-only.bag");
    lu_write(p, d, 100);
    lu_open_fails(p, SOOC_EFORMAT, "truncated", "offset 13");
    /* unknown chunk compression */
    long at = lu_find(d, n, "compression=lz4", 15);
    CHECK(at > 0);
    uint8_t *e = malloc(n);
    memcpy(e, d, n);
    memcpy(e + at + 12, "xz4", 3);
    p = lu_path(tmp, "xz4.bag");
    lu_write(p, e, n);
    lu_open_fails(p, SOOC_EUNSUPPORTED, "unknown chunk compression 'xz4'", "offset");
    /* corrupt LZ4 data: opens (the index is intact), reading fails naming the chunk */
    memcpy(e, d, n);
    for (size_t i = n / 4; i < n / 4 + 64; i++) e[i] ^= 0x5a;
    p = lu_path(tmp, "corrupt-lz4.bag");
    lu_write(p, e, n);
    lf = NULL;
    CHECK_OK(sooc_logfile_open(&lf, p));
    if (lf) {
        sooc_logfile_msg m;
        sooc_status st = sooc_logfile_read(lf, 0, &m);
        CHECK(st == SOOC_EFORMAT && strstr(sooc_errmsg(), p) && strstr(sooc_errmsg(), "offset"));
        printf("  %s -> %s\n", sooc_status_str(st), sooc_errmsg());
        sooc_logfile_close(lf);
    }
    /* an older bag version and a non-log */
    memcpy(e, d, n);
    memcpy(e, "#ROSBAG V1.2\n", 13);
    p = lu_path(tmp, "v12.bag");
    lu_write(p, e, 200);
    lu_open_fails(p, SOOC_EVERSION, "1.2", NULL);
    p = lu_path(tmp, "text.bag");
    lu_write(p, "hello world, not a bag\n", 23);
    lu_open_fails(p, SOOC_EFORMAT, "bad magic", NULL);
    sooc_free(d);
    free(e);

    d = lu_read(lu_path(bags, "rosbag2/talker.mcap"), &n);
    CHECK(d != NULL);
    if (!d) return;
    e = malloc(n);
    p = lu_path(tmp, "truncated.mcap");
    lu_write(p, d, 1500);
    lu_open_fails(p, SOOC_EFORMAT, "truncated", "offset 45");
    /* cut inside the summary: the data section is whole, every message reads */
    p = lu_path(tmp, "no-summary.mcap");
    lu_write(p, d, n * 2 / 3);
    CHECK_OK(sooc_logfile_open(&lf, p));
    if (lf) {
        int64_t nm;
        digest(lf, &nm);
        CHECK(nm == 20 && sooc_logfile_count(lf) == 20);
        sooc_logfile_close(lf);
    }
    p = lu_path(tmp, "short.mcap");
    lu_write(p, d, 20);
    lu_open_fails(p, SOOC_EFORMAT, "truncated", NULL);
    /* the chunk record: opcode 0x06 after the header record */
    long chunk = 8 + 9 + (long)logs_u64_le(d + 9);
    CHECK(d[chunk] == 0x06);
    /* bad chunk CRC: opens from the summary, the read names the chunk's offset */
    memcpy(e, d, n);
    e[chunk + 33] ^= 0xff;
    p = lu_path(tmp, "badcrc.mcap");
    lu_write(p, e, n);
    CHECK_OK(sooc_logfile_open(&lf, p));
    if (lf) {
        sooc_logfile_msg m;
        char off[32];
        snprintf(off, sizeof off, "offset %ld", chunk);
        sooc_status st = sooc_logfile_read(lf, 0, &m);
        CHECK(st == SOOC_EFORMAT && strstr(sooc_errmsg(), "chunk CRC mismatch") && strstr(sooc_errmsg(), off));
        printf("  %s -> %s\n", sooc_status_str(st), sooc_errmsg());
        CHECK(sooc_logfile_verify(lf) == SOOC_EFORMAT);
        sooc_logfile_close(lf);
    }
    /* bad summary CRC */
    memcpy(e, d, n);
    e[n - 8 - 4] ^= 0x01;
    p = lu_path(tmp, "badsummary.mcap");
    lu_write(p, e, n);
    lu_open_fails(p, SOOC_EFORMAT, "summary CRC mismatch", "offset");
    /* unknown chunk compression */
    memcpy(e, d, n);
    CHECK(!memcmp(e + chunk + 41, "zstd", 4));
    memcpy(e + chunk + 41, "zstx", 4);
    p = lu_path(tmp, "zstx.mcap");
    lu_write(p, e, n);
    lu_open_fails(p, SOOC_EUNSUPPORTED, "unknown chunk compression 'zstx'", "offset 45");
    /* a major version this reader does not know */
    memcpy(e, d, n);
    e[5] = '1';
    p = lu_path(tmp, "v1.mcap");
    lu_write(p, e, n);
    lu_open_fails(p, SOOC_EVERSION, "major version", NULL);
    sooc_free(d);
    free(e);
}

int main(void) {
    const char *bags = lu_bags("test_logs_read");
    if (!bags) return SOOC_TEST_SKIP;
    char *tmp = lu_tmpdir("logs_read");
    test_turtlesim(bags);
    test_small_bags(bags);
    test_realsense(bags);
    test_mcap(bags);
    test_damaged(bags, tmp);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd) != 0) printf("could not remove %s\n", tmp);
    return check_report("test_logs_read");
}
