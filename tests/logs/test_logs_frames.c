/* Frames from synthetic logs (no fixtures): depth registered into the
 * colour camera through /tf_static with a known offset, TF interpolation at
 * the image stamp, CompressedImage colour (JPEG, PNG) and compressedDepth
 * (16UC1 PNG, 32FC1 quantised), topic selection and its errors, damaged
 * copies of a written file (chunk CRC, data-section CRC). */
#include "logs_util.h"
#include "sooc3d/core.h"

#include <math.h>

#define W 32
#define H 24

typedef struct wl {
    sooc_mcap_writer *w;
    sooc_ros_buf b;
    int sc_img, sc_cimg, sc_info, sc_tf;
} wl;

static int chan(wl *L, const char *type, const char *topic) {
    int *sc = strstr(type, "Compressed") ? &L->sc_cimg : strstr(type, "Info") ? &L->sc_info
            : strstr(type, "TF") ? &L->sc_tf : &L->sc_img;
    if (!*sc) {
        const char *def = sooc_ros_definition(type, SOOC_MSGENC_CDR);
        CHECK_OK(sooc_mcap_writer_schema(L->w, type, "ros2msg", def, strlen(def), sc));
    }
    int id = -1;
    CHECK_OK(sooc_mcap_writer_channel(L->w, *sc, topic, "cdr", &id));
    return id;
}
static void put(wl *L, int ch, int64_t t) {
    CHECK_OK(sooc_mcap_writer_message(L->w, ch, t, t, L->b.data, L->b.size));
    L->b.size = 0;
}
static void info(wl *L, int ch, int64_t t, const char *frame, double f) {
    sooc_ros_caminfo c;
    memset(&c, 0, sizeof c);
    c.header = lu_hdr(t, frame);
    c.width = W;
    c.height = H;
    double K[9] = {f, 0, 15.5, 0, f, 11.5, 0, 0, 1};
    memcpy(c.K, K, sizeof K);
    CHECK_OK(sooc_ros_encode_caminfo(&L->b, SOOC_MSGENC_CDR, &c));
    put(L, ch, t);
}
static void tf(wl *L, int ch, int64_t t, const char *parent, const char *child, double x) {
    sooc_ros_transform tr = {lu_hdr(t, parent), "", {x, 0, 0}, {0, 0, 0, 1}};
    snprintf(tr.child, sizeof tr.child, "%s", child);
    CHECK_OK(sooc_ros_encode_tf(&L->b, SOOC_MSGENC_CDR, &tr, 1));
    put(L, ch, t);
}

static wl open_log(const char *path, const char *comp) {
    sooc_mcap_writer_params p;
    sooc_mcap_writer_params_default(&p);
    p.compression = comp;
    p.profile = "ros2";
    wl L;
    memset(&L, 0, sizeof L);
    CHECK_OK(sooc_mcap_writer_open(&L.w, path, &p));
    return L;
}
static void close_log(wl *L) {
    CHECK_OK(sooc_mcap_writer_close(L->w));
    sooc_ros_buf_free(&L->b);
}

/* Depth camera (f = 20, frame cam_depth) 5 cm along +x of the colour camera
 * (f = 30, cam_color): one valid depth pixel at (10, 12), 1 m. */
static void test_registration(const char *tmp) {
    char p[600];
    snprintf(p, sizeof p, "%s/reg.mcap", tmp);
    wl L = open_log(p, "");
    int ci = chan(&L, "sensor_msgs/msg/Image", "/cam/color"), di = chan(&L, "sensor_msgs/msg/Image", "/cam/depth");
    int cinf = chan(&L, "sensor_msgs/msg/CameraInfo", "/cam/color_info");
    int dinf = chan(&L, "sensor_msgs/msg/CameraInfo", "/cam/depth_info");
    int tfc = chan(&L, "tf2_msgs/msg/TFMessage", "/tf"), tfs = chan(&L, "tf2_msgs/msg/TFMessage", "/tf_static");
    static uint8_t rgb[W * H * 3];
    static uint16_t mm[W * H];
    tf(&L, tfs, 0, "cam_color", "cam_depth", 0.05);
    for (int k = 0; k < 3; k++) {
        int64_t t = 1000000000LL * (k + 1);
        tf(&L, tfc, t, "odom", "cam_color", 1.0 * k);
        info(&L, cinf, t, "cam_color", 30);
        info(&L, dinf, t, "cam_depth", 20);
        /* the colour header stamp a quarter of the way to the next pose: interpolated */
        sooc_ros_image im = {lu_hdr(t + 250000000LL, "cam_color"), W, H, W * 3, "rgb8", 0, rgb, sizeof rgb};
        CHECK_OK(sooc_ros_encode_image(&L.b, SOOC_MSGENC_CDR, &im));
        put(&L, ci, t);
        memset(mm, 0, sizeof mm);
        mm[12 * W + 10] = 1000;
        sooc_ros_image dm = {lu_hdr(t, "cam_depth"), W, H, W * 2, "16UC1", 0, (uint8_t *)mm, sizeof mm};
        CHECK_OK(sooc_ros_encode_image(&L.b, SOOC_MSGENC_CDR, &dm));
        put(&L, di, t + 5000000);
    }
    tf(&L, tfc, 4000000000LL, "odom", "cam_color", 3.0);
    close_log(&L);

    sooc_logseq *s = lu_open_frames(p, "odom");
    if (!s) return;
    const sooc_logseq_desc *d = sooc_logseq_describe(s);
    CHECK(sooc_logseq_count(s) == 3 && d->registered && strstr(d->extrinsics_source, "tf cam_color <- cam_depth"));
    CHECK_CLOSE(d->T_color_depth[3], 0.05, 1e-12, 0);
    sooc_frame f = {0};
    for (int k = 0; k < 3; k++) {
        CHECK_OK(sooc_logseq_read(s, k, &f));
        /* (10, 12) at 1 m -> x = -0.275 + 0.05, u = 30 x + 15.5 = 8.75, v = 12.25: footprint 0.95 px either side */
        int nz = 0;
        for (int i = 0; i < W * H; i++) nz += f.valid[i];
        CHECK_MSG(nz == 4 && f.depth[12 * W + 8] == 1.0f && f.depth[12 * W + 9] == 1.0f && f.depth[13 * W + 8] == 1.0f &&
                  f.depth[13 * W + 9] == 1.0f, "frame %d: %d valid pixels", k, nz);
        CHECK(f.has_pose && f.K.fx == 30);
        CHECK_CLOSE(f.T_wc[3], k + 0.25, 1e-12, 0);
    }
    sooc_frame_free(&f);
    sooc_logseq_close(s);
    /* registration off: the sizes match, the depth stays in its own camera */
    sooc_logseq_params lp;
    sooc_logseq_params_default(&lp);
    lp.registration = 0;
    CHECK_OK(sooc_logseq_open(&s, p, &lp));
    if (s) {
        CHECK(!sooc_logseq_describe(s)->registered);
        sooc_logseq_close(s);
    }
    printf("  registration: one depth pixel lands on the 4 colour pixels its footprint covers; TF interpolated\n");
}

/* Colour as JPEG or PNG CompressedImage, depth as compressedDepth (16UC1 PNG or 32FC1 quantised). */
static void test_compressed(const char *tmp) {
    for (int v = 0; v < 2; v++) {
        char p[600];
        snprintf(p, sizeof p, "%s/comp%d.mcap", tmp, v);
        wl L = open_log(p, "zstd");
        int ci = chan(&L, "sensor_msgs/msg/CompressedImage", "/cam/color/compressed");
        int di = chan(&L, "sensor_msgs/msg/CompressedImage", "/cam/depth/compressedDepth");
        int inf = chan(&L, "sensor_msgs/msg/CameraInfo", "/cam/camera_info");
        sooc_image img = {0}, dimg = {0};
        CHECK_OK(sooc_image_alloc(&img, W, H, SOOC_PIX_RGB8));
        CHECK_OK(sooc_image_alloc(&dimg, W, H, SOOC_PIX_GRAY16));
        uint8_t *px = img.data;
        uint16_t *dv = dimg.data;
        for (int i = 0; i < W * H; i++) {
            px[3 * i] = (uint8_t)(4 * (i % W));   /* smooth: JPEG keeps it within a few levels */
            px[3 * i + 1] = (uint8_t)(6 * (i / W));
            px[3 * i + 2] = 200;
            /* 16UC1: millimetres; 32FC1: A / (v - B) with A = 1000, B = 0: v = 500 is 2 m */
            dv[i] = v == 0 ? (uint16_t)(1500 + i) : (i % 5 ? 500 : 0);
        }
        void *jpg, *png, *dpng;
        size_t nj, np, nd;
        CHECK_OK(v == 0 ? sooc_jpeg_encode(&img, 95, &jpg, &nj) : sooc_png_encode(&img, 3, &jpg, &nj));
        CHECK_OK(sooc_png_encode(&dimg, 3, &dpng, &nd));
        np = 12 + nd;
        png = malloc(np);
        int32_t fmt = 1;   /* compressed_depth_image_transport's PNG */
        float qa = 1000.0f, qb = 0.0f;
        memcpy(png, &fmt, 4);
        memcpy((uint8_t *)png + 4, &qa, 4);
        memcpy((uint8_t *)png + 8, &qb, 4);
        memcpy((uint8_t *)png + 12, dpng, nd);
        for (int k = 0; k < 2; k++) {
            int64_t t = 1000000000LL * (k + 1);
            info(&L, inf, t, "cam", 30);
            sooc_ros_cimage c = {lu_hdr(t, "cam"), "", jpg, nj};
            snprintf(c.format, sizeof c.format, "%s", v == 0 ? "rgb8; jpeg compressed bgr8" : "png");
            CHECK_OK(sooc_ros_encode_cimage(&L.b, SOOC_MSGENC_CDR, &c));
            put(&L, ci, t);
            sooc_ros_cimage dc = {lu_hdr(t, "cam"), "", png, np};
            snprintf(dc.format, sizeof dc.format, "%s", v == 0 ? "16UC1; compressedDepth png" : "32FC1; compressedDepth");
            CHECK_OK(sooc_ros_encode_cimage(&L.b, SOOC_MSGENC_CDR, &dc));
            put(&L, di, t);
        }
        close_log(&L);
        sooc_logseq *s = NULL;
        CHECK_OK(sooc_logseq_open(&s, p, NULL));
        if (s) {
            sooc_frame f = {0};
            CHECK(sooc_logseq_count(s) == 2);
            CHECK_OK(sooc_logseq_read(s, 1, &f));
            int bad_z = 0, max_drgb = 0;
            for (int i = 0; i < W * H; i++) {
                float want = v == 0 ? (float)((1500 + i) * 0.001) : (i % 5 ? 2.0f : 0.0f);
                bad_z += f.depth[i] != want;
                for (int q = 0; q < 3; q++) {
                    int dq = abs((int)f.rgb[3 * i + q] - (int)px[3 * i + q]);
                    if (dq > max_drgb) max_drgb = dq;
                }
            }
            CHECK_MSG(bad_z == 0, "compressedDepth %d: %d samples differ", v, bad_z);
            CHECK_MSG(v == 0 ? max_drgb <= 8 : max_drgb == 0, "colour %s differs by %d", v ? "png" : "jpeg", max_drgb);
            sooc_frame_free(&f);
            sooc_logseq_close(s);
        }
        sooc_free(jpg);
        sooc_free(dpng);
        free(png);
        sooc_image_free(&img);
        sooc_image_free(&dimg);
    }
    printf("  compressed: JPEG and PNG colour, compressedDepth 16UC1 PNG and 32FC1 quantised\n");
}

/* Two colour topics: the choice is the user's, and the errors say so. */
static void test_topics(const char *tmp) {
    char p[600];
    snprintf(p, sizeof p, "%s/two.mcap", tmp);
    wl L = open_log(p, "lz4");
    int a = chan(&L, "sensor_msgs/msg/Image", "/left/image"), b = chan(&L, "sensor_msgs/msg/Image", "/right/image");
    int d = chan(&L, "sensor_msgs/msg/Image", "/depth/image");
    static uint8_t rgb[W * H * 3];
    static float z[W * H];
    for (int i = 0; i < W * H; i++) z[i] = 1.5f;
    sooc_ros_image im = {lu_hdr(5, "c"), W, H, W * 3, "rgb8", 0, rgb, sizeof rgb};
    sooc_ros_image dm = {lu_hdr(5, "c"), W, H, W * 4, "32FC1", 0, (uint8_t *)z, sizeof z};
    CHECK_OK(sooc_ros_encode_image(&L.b, SOOC_MSGENC_CDR, &im));
    put(&L, a, 5);
    CHECK_OK(sooc_ros_encode_image(&L.b, SOOC_MSGENC_CDR, &im));
    put(&L, b, 5);
    CHECK_OK(sooc_ros_encode_image(&L.b, SOOC_MSGENC_CDR, &dm));
    put(&L, d, 5);
    close_log(&L);
    sooc_logseq *s = NULL;
    sooc_logseq_params lp;
    sooc_logseq_params_default(&lp);
    CHECK(sooc_logseq_open(&s, p, &lp) == SOOC_EINVAL && !s);
    CHECK_MSG(strstr(sooc_errmsg(), "/left/image") && strstr(sooc_errmsg(), "/right/image") &&
              strstr(sooc_errmsg(), "color_topic"), "%s", sooc_errmsg());
    printf("  EINVAL -> %s\n", sooc_errmsg());
    lp.color_topic = "/nope";
    CHECK(sooc_logseq_open(&s, p, &lp) == SOOC_ENOTFOUND && strstr(sooc_errmsg(), "'/nope'"));
    printf("  ENOTFOUND -> %s\n", sooc_errmsg());
    lp.color_topic = "/depth/image";
    CHECK(sooc_logseq_open(&s, p, &lp) == SOOC_EINVAL && strstr(sooc_errmsg(), "holds depth images"));
    lp.color_topic = "/right/image";
    CHECK_OK(sooc_logseq_open(&s, p, &lp));
    if (s) {
        CHECK(!strcmp(sooc_logseq_describe(s)->color.topic, "/right/image") && sooc_logseq_count(s) == 1);
        CHECK(!sooc_logseq_describe(s)->color.has_info);
        sooc_logseq_close(s);
    }
    /* as a sequence: no CameraInfo and no calibration is an error naming the topic */
    sooc_seq *q = NULL;
    CHECK(sooc_log_seq_open(&q, p, NULL, &lp) == SOOC_EFORMAT && strstr(sooc_errmsg(), "no CameraInfo"));
    sooc_seq_close(q);
}

/* A file this writer made, damaged: a chunk CRC and the data-section CRC. */
static void test_damaged(const char *tmp) {
    char p[600], q[600];
    snprintf(p, sizeof p, "%s/reg.mcap", tmp);   /* uncompressed chunks */
    size_t n;
    uint8_t *d = lu_read(p, &n);
    CHECK(d != NULL);
    if (!d) return;
    long at = lu_find(d, n, "cam_depth", 9);   /* inside the first chunk's records */
    CHECK(at > 0);
    d[at] ^= 0x20;
    snprintf(q, sizeof q, "%s/reg-badchunk.mcap", tmp);
    lu_write(q, d, n);
    sooc_logfile *lf = NULL;
    CHECK_OK(sooc_logfile_open(&lf, q));
    if (lf) {
        sooc_logfile_msg m;
        CHECK(sooc_logfile_read(lf, 0, &m) == SOOC_EFORMAT && strstr(sooc_errmsg(), "chunk CRC mismatch"));
        printf("  EFORMAT -> %s\n", sooc_errmsg());
        sooc_logfile_close(lf);
    }
    d[at] ^= 0x20;
    /* the Data End record (opcode 0x0F, length 4) before the summary */
    static const uint8_t de[9] = {0x0F, 4, 0, 0, 0, 0, 0, 0, 0};
    long e = lu_find(d, n, de, 9);
    CHECK(e > 0);
    d[e + 9] ^= 0xff;
    snprintf(q, sizeof q, "%s/reg-baddata.mcap", tmp);
    lu_write(q, d, n);
    CHECK_OK(sooc_logfile_open(&lf, q));
    if (lf) {
        CHECK(sooc_logfile_verify(lf) == SOOC_EFORMAT && strstr(sooc_errmsg(), "data section CRC mismatch"));
        printf("  EFORMAT -> %s\n", sooc_errmsg());
        sooc_logfile_close(lf);
    }
    sooc_free(d);
}

int main(void) {
    char *tmp = lu_tmpdir("logs_frames");
    if (getenv("KEEP")) printf("tmp %s\n", tmp);
    test_registration(tmp);
    test_compressed(tmp);
    test_topics(tmp);
    test_damaged(tmp);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (!getenv("KEEP") && system(cmd) != 0) printf("could not remove %s\n", tmp);
    return check_report("test_logs_frames");
}
