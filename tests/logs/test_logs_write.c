/* The MCAP writer and the message encoders read back by the readers (no
 * fixtures needed): every compression, with and without a summary, ROS 1
 * and CDR; a hand-made CDR message checks the alignment rules; frames from a
 * synthetic log: image encodings, compressedDepth, depth registration with a
 * known transform, TF interpolation, topic selection and its errors; damaged
 * copies of a written file. */
#include "logs_util.h"
#include "sooc3d/core.h"

#include <math.h>

#define W 32
#define H 24


static sooc_ros_caminfo caminfo(int64_t t, const char *frame, double f, double cx, double cy) {
    sooc_ros_caminfo c;
    memset(&c, 0, sizeof c);
    c.header = lu_hdr(t, frame);
    c.width = W;
    c.height = H;
    snprintf(c.distortion_model, sizeof c.distortion_model, "plumb_bob");
    c.nD = 5;
    double K[9] = {f, 0, cx, 0, f, cy, 0, 0, 1};
    memcpy(c.K, K, sizeof K);
    c.R[0] = c.R[4] = c.R[8] = 1;
    c.P[0] = c.P[5] = f;
    c.P[2] = cx;
    c.P[6] = cy;
    c.P[10] = 1;
    return c;
}

typedef struct wlog {
    sooc_mcap_writer *w;
    int sc[8], ch[16];
    sooc_msg_encoding enc;
    sooc_ros_buf b;
} wlog;

static int channel(wlog *L, int slot, const char *type, const char *topic) {
    if (!L->sc[slot]) {
        const char *def = sooc_ros_definition(type, L->enc);
        CHECK_OK(sooc_mcap_writer_schema(L->w, type, L->enc == SOOC_MSGENC_CDR ? "ros2msg" : "ros1msg", def,
                                         strlen(def), &L->sc[slot]));
    }
    int id = -1;
    CHECK_OK(sooc_mcap_writer_channel(L->w, L->sc[slot], topic, L->enc == SOOC_MSGENC_CDR ? "cdr" : "ros1", &id));
    return id;
}

static void put(wlog *L, int ch, int64_t t) {
    CHECK_OK(sooc_mcap_writer_message(L->w, ch, t, t, L->b.data, L->b.size));
    L->b.size = 0;
}

/* A colour pattern and a depth ramp for frame k. */
static uint8_t pix(int k, int x, int y, int c) { return (uint8_t)(17 * k + 3 * x + 5 * y + 60 * c); }
static float dep(int k, int x, int y) { return 1.0f + 0.01f * (float)(k + x + 2 * y); }

/* Frames of a synthetic camera log: colour in `color_enc`, depth 16UC1 (mm,
 * big-endian when be) or 32FC1, CameraInfos, /tf world -> cam moving along x. */
static void write_camera_log(const char *path, const char *comp, int summary, sooc_msg_encoding enc,
                             const char *color_enc, const char *depth_enc, int be, int nframes) {
    sooc_mcap_writer_params wp;
    sooc_mcap_writer_params_default(&wp);
    wp.compression = comp;
    wp.summary = summary;
    wp.chunk_size = 3000;   /* several chunks */
    wlog L = {0};
    L.enc = enc;
    CHECK_OK(sooc_mcap_writer_open(&L.w, path, &wp));
    if (!L.w) return;
    int cimg = channel(&L, 0, "sensor_msgs/msg/Image", "/cam/color/image_raw");
    int dimg = channel(&L, 0, "sensor_msgs/msg/Image", "/cam/depth/image_raw");
    int cinf = channel(&L, 1, "sensor_msgs/msg/CameraInfo", "/cam/color/camera_info");
    int dinf = channel(&L, 1, "sensor_msgs/msg/CameraInfo", "/cam/depth/camera_info");
    int tf = channel(&L, 2, "tf2_msgs/msg/TFMessage", "/tf");
    int tfs = channel(&L, 2, "tf2_msgs/msg/TFMessage", "/tf_static");
    static uint8_t cbuf[W * H * 4], dbuf[W * H * 4];
    int bpp = !strcmp(color_enc, "mono8") ? 1 : strstr(color_enc, "a8") ? 4 : 3;
    int bgr = color_enc[0] == 'b';
    sooc_ros_transform st = {lu_hdr(0, "map"), "world", {0, 0, 0}, {0, 0, 0, 1}};
    CHECK_OK(sooc_ros_encode_tf(&L.b, enc, &st, 1));
    put(&L, tfs, 0);
    for (int k = 0; k < nframes; k++) {
        int64_t t = 1000000000LL + k * 100000000LL;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                uint8_t *c = cbuf + (y * W + x) * bpp;
                if (bpp == 1) c[0] = pix(k, x, y, 1);
                else
                    for (int q = 0; q < 3; q++) c[bgr ? 2 - q : q] = pix(k, x, y, q);
                if (bpp == 4) c[3] = 255;
                float z = dep(k, x, y);
                if (!strcmp(depth_enc, "32FC1")) {
                    if (x == 0) z = NAN;   /* invalid */
                    uint32_t u;
                    memcpy(&u, &z, 4);
                    for (int q = 0; q < 4; q++) dbuf[(y * W + x) * 4 + q] = (uint8_t)(u >> (8 * (be ? 3 - q : q)));
                } else {
                    uint16_t mm = (uint16_t)lround(z * 1000);
                    dbuf[(y * W + x) * 2 + (be ? 1 : 0)] = (uint8_t)mm;
                    dbuf[(y * W + x) * 2 + (be ? 0 : 1)] = (uint8_t)(mm >> 8);
                }
            }
        int dbpp = !strcmp(depth_enc, "32FC1") ? 4 : 2;
        /* the camera 0.1 m further along x each frame; TF at t and half-way to the next */
        for (int h = 0; h < 2; h++) {
            sooc_ros_transform tr = {lu_hdr(t + h * 50000000LL, "world"), "cam_optical", {0.1 * k + 0.05 * h, 0, 0}, {0, 0, 0, 1}};
            CHECK_OK(sooc_ros_encode_tf(&L.b, enc, &tr, 1));
            put(&L, tf, t + h * 50000000LL);
        }
        sooc_ros_caminfo ci = caminfo(t, "cam_optical", 30, 15.5, 11.5);
        CHECK_OK(sooc_ros_encode_caminfo(&L.b, enc, &ci));
        put(&L, cinf, t);
        CHECK_OK(sooc_ros_encode_caminfo(&L.b, enc, &ci));
        put(&L, dinf, t + 1000);
        sooc_ros_image im = {lu_hdr(t, "cam_optical"), W, H, (size_t)W * bpp, "", 0, cbuf, (size_t)W * H * bpp};
        snprintf(im.encoding, sizeof im.encoding, "%s", color_enc);
        CHECK_OK(sooc_ros_encode_image(&L.b, enc, &im));
        put(&L, cimg, t);
        sooc_ros_image dm = {lu_hdr(t, "cam_optical"), W, H, (size_t)W * dbpp, "", be, dbuf, (size_t)W * H * dbpp};
        snprintf(dm.encoding, sizeof dm.encoding, "%s", depth_enc);
        CHECK_OK(sooc_ros_encode_image(&L.b, enc, &dm));
        put(&L, dimg, t + 3000000);   /* depth logged 3 ms after colour */
    }
    CHECK_OK(sooc_mcap_writer_close(L.w));
    sooc_ros_buf_free(&L.b);
}

/* Read the frames back and compare with the pattern. */
static void check_frames(const char *path, const char *color_enc, const char *depth_enc, int nframes) {
    sooc_logseq *s = lu_open_frames(path, "map");
    if (!s) return;
    const sooc_logseq_desc *d = sooc_logseq_describe(s);
    CHECK_MSG(sooc_logseq_count(s) == nframes, "%s: %lld frames", path, (long long)sooc_logseq_count(s));
    CHECK(!d->registered && d->has_pose && !strcmp(d->pose_child, "cam_optical") && d->n_unposed == 0);
    CHECK(d->color.has_info && d->color.K.fx == 30 && d->color.K.cx == 15.5);
    int mono = !strcmp(color_enc, "mono8"), f32 = !strcmp(depth_enc, "32FC1");
    sooc_frame f = {0};
    int bad_rgb = 0, bad_z = 0;
    for (int k = 0; k < sooc_logseq_count(s); k++) {
        CHECK_OK(sooc_logseq_read(s, k, &f));
        CHECK(f.width == W && f.height == H && f.has_pose && f.K.fx == 30);
        CHECK_CLOSE(f.T_wc[3], 0.1 * k, 1e-12, 0);
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                for (int q = 0; q < 3; q++) bad_rgb += f.rgb[(y * W + x) * 3 + q] != pix(k, x, y, mono ? 1 : q);
                float want = f32 ? (x == 0 ? 0.0f : dep(k, x, y)) : (float)(lround(dep(k, x, y) * 1000) * 0.001);
                bad_z += fabsf(f.depth[y * W + x] - want) > 1e-6f || f.valid[y * W + x] != (want > 0);
            }
    }
    CHECK_MSG(bad_rgb == 0 && bad_z == 0, "%s (%s, %s): %d colour and %d depth samples differ", path, color_enc,
              depth_enc, bad_rgb, bad_z);
    /* TF between two samples: interpolated */
    sooc_frame_free(&f);
    sooc_logseq_close(s);
}

/* Every message of two files identical (channel topic, time, bytes). */
static void same_messages(const char *a, const char *b) {
    sooc_logfile *x = NULL, *y = NULL;
    CHECK_OK(sooc_logfile_open(&x, a));
    CHECK_OK(sooc_logfile_open(&y, b));
    if (!x || !y) goto done;
    CHECK(sooc_logfile_count(x) == sooc_logfile_count(y));
    for (int64_t k = 0; k < sooc_logfile_count(x) && k < sooc_logfile_count(y); k++) {
        sooc_logfile_msg m, n;
        CHECK_OK(sooc_logfile_read(x, k, &m));
        uint32_t cm = sooc_crc32(0, m.data, m.size);
        const char *tm = sooc_logfile_channel_get(x, m.channel)->topic;
        int64_t t = m.t_ns;
        size_t sz = m.size;
        CHECK_OK(sooc_logfile_read(y, k, &n));
        CHECK(n.t_ns == t && n.size == sz && sooc_crc32(0, n.data, n.size) == cm &&
              !strcmp(sooc_logfile_channel_get(y, n.channel)->topic, tm));
    }
    CHECK_OK(sooc_logfile_verify(x));
    CHECK_OK(sooc_logfile_verify(y));
done:
    sooc_logfile_close(x);
    sooc_logfile_close(y);
}

static void test_writer(const char *tmp) {
    const char *comps[3] = {"", "lz4", "zstd"};
    char ref[600];
    snprintf(ref, sizeof ref, "%s/ref.mcap", tmp);
    write_camera_log(ref, "zstd", 1, SOOC_MSGENC_CDR, "rgb8", "16UC1", 0, 6);
    for (int c = 0; c < 3; c++)
        for (int summary = 0; summary < 2; summary++) {
            char p[600];
            snprintf(p, sizeof p, "%s/w_%s_%d.mcap", tmp, comps[c][0] ? comps[c] : "none", summary);
            write_camera_log(p, comps[c], summary, SOOC_MSGENC_CDR, "rgb8", "16UC1", 0, 6);
            sooc_logfile *lf = NULL;
            CHECK_OK(sooc_logfile_open(&lf, p));
            if (lf) {
                sooc_logfile_info in;
                sooc_logfile_get_info(lf, &in);
                CHECK_MSG(in.indexed == summary && in.n_chunks > 2, "%s: indexed %d, %lld chunks", p, in.indexed,
                          (long long)in.n_chunks);
                CHECK(!strcmp(in.compression, comps[c][0] ? comps[c] : "none"));
                sooc_logfile_close(lf);
            }
            same_messages(ref, p);
        }
    printf("  writer: none/lz4/zstd chunks, with and without a summary: the same messages\n");
}

static void test_encodings(const char *tmp) {
    static const struct { const char *color, *depth; int be; sooc_msg_encoding enc; } v[] = {
        {"rgb8", "16UC1", 0, SOOC_MSGENC_CDR},   {"bgr8", "16UC1", 1, SOOC_MSGENC_ROS1},
        {"rgba8", "32FC1", 0, SOOC_MSGENC_CDR},  {"bgra8", "32FC1", 1, SOOC_MSGENC_ROS1},
        {"mono8", "mono16", 0, SOOC_MSGENC_CDR},
    };
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++) {
        char p[600];
        snprintf(p, sizeof p, "%s/enc%zu.mcap", tmp, i);
        write_camera_log(p, "lz4", 1, v[i].enc, v[i].color, v[i].depth, v[i].be, 4);
        check_frames(p, v[i].color, v[i].depth, 4);
    }
    printf("  frames: rgb8 bgr8 rgba8 bgra8 mono8 colour, 16UC1 mono16 (both byte orders) 32FC1 depth, ROS 1 and CDR\n");
}

/* CDR written by hand: a TFMessage whose doubles need padding after the strings. */
static void test_cdr_alignment(void) {
    static const uint8_t m[] = {
        0x00, 0x01, 0x00, 0x00,                          /* CDR little endian                */
        0x01, 0x00, 0x00, 0x00,                          /* 1 transform (offset 0)           */
        0x05, 0x00, 0x00, 0x00, 0x07, 0x00, 0x00, 0x00,  /* stamp 5 s 7 ns (offsets 4, 8)    */
        0x02, 0x00, 0x00, 0x00, 'm', 0x00,               /* "m" (offset 12: length 2, NUL)   */
        0x00, 0x00,                                      /* pad to 4 (offset 18)             */
        0x03, 0x00, 0x00, 0x00, 'c', 'a', 0x00,          /* "ca" (offset 20)                 */
        0x00, 0x00, 0x00, 0x00, 0x00,                    /* pad to 8 (offsets 27..31)        */
        0, 0, 0, 0, 0, 0, 0xf0, 0x3f,                    /* x = 1.0 (offset 32)              */
        0, 0, 0, 0, 0, 0, 0, 0x40,                       /* y = 2.0                          */
        0, 0, 0, 0, 0, 0, 0x08, 0x40,                    /* z = 3.0                          */
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, 0, 0, 0, 0, 0, 0xf0, 0x3f,                    /* w = 1.0                          */
    };
    sooc_ros_transform t[2];
    int n = 0;
    CHECK_OK(sooc_ros_decode_tf(m, sizeof m, SOOC_MSGENC_CDR, t, 2, &n));
    CHECK(n == 1 && t[0].header.stamp_ns == 5000000007LL && !strcmp(t[0].header.frame_id, "m") &&
          !strcmp(t[0].child, "ca") && t[0].t[0] == 1 && t[0].t[1] == 2 && t[0].t[2] == 3 && t[0].q[3] == 1);
    sooc_ros_buf b = {0};
    CHECK_OK(sooc_ros_encode_tf(&b, SOOC_MSGENC_CDR, t, 1));
    CHECK_MSG(b.size == sizeof m && !memcmp(b.data, m, sizeof m), "encoded %zu bytes, expected %zu", b.size, sizeof m);
    CHECK(sooc_ros_decode_tf(m, sizeof m - 1, SOOC_MSGENC_CDR, t, 2, &n) == SOOC_EFORMAT);
    CHECK(strstr(sooc_errmsg(), "truncated tf2_msgs/TFMessage") != NULL);
    sooc_ros_buf_free(&b);
}

int main(void) {
    char *tmp = lu_tmpdir("logs_write");
    test_cdr_alignment();
    test_writer(tmp);
    test_encodings(tmp);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd) != 0) printf("could not remove %s\n", tmp);
    return check_report("test_logs_write");
}
