/*
 * fuzz_seeds <out_dir>: write the binary seeds of the fuzz corpus with the
 * project's own writers (nn/model checkpoints, a SQLite map, pose packets,
 * PNG/PGM images, a scene.yaml). Text seeds (calib, launch, train config,
 * TUM) are plain files committed in tests/fuzz/corpus/. Used once to make
 * tests/fuzz/corpus/; rerun after a format change:
 *   build/tests/fuzz_seeds tests/fuzz/corpus
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/gen.h"
#include "sooc3d/log.h"
#include "sooc3d/model.h"
#include "sooc3d/frame.h"

static const char *out_dir;

static const char *path(const char *target, const char *name) {
    static char p[4096];
    char d[4096];
    if (snprintf(d, sizeof d, "%s/%s", out_dir, target) >= (int)sizeof d) exit(1);
    if (sooc_mkdirs(d)) { fprintf(stderr, "mkdir %s: %s\n", d, sooc_errmsg()); exit(1); }
    if (snprintf(p, sizeof p, "%s/%s", d, name) >= (int)sizeof p) exit(1);
    return p;
}

#define OK(x) do { sooc_status s_ = (x); if (s_) { fprintf(stderr, "%s:%d: %s: %s\n", __FILE__, __LINE__, #x, sooc_errmsg()); exit(1); } } while (0)

int main(int argc, char **argv) {
    if (argc != 2) { fprintf(stderr, "usage: fuzz_seeds <out_dir>\n"); return 2; }
    out_dir = argv[1];

    /* a tiny model checkpoint (smallest sizes the config check accepts) */
    {
        sooc_model_config c;
        sooc_model_config_default(&c);
        c.K = 2; c.d_what = 2; c.d_layout = 1; c.L = 1;
        c.img_w = c.img_h = 16; c.ray_w = c.ray_h = 16;
        c.dec_width = 4; c.dec_color_width = 1; c.n_freq = 1; c.n_freq_layout = 0;
        for (int i = 0; i < 4; i++) c.ref_ch[i] = 1;
        c.ref_fc = 1; c.ref_hidden = 1;
        sooc_model *m;
        OK(sooc_model_create(&m, &c, 7));
        OK(sooc_model_save(m, path("model_ckpt", "tiny.ckpt"), NULL, 0));
        OK(sooc_model_save(m, path("model_ckpt", "tiny_blob.ckpt"), "blob", 4));
        sooc_model_destroy(m);
    }

    /* a map database with entries, a layout block and a keyframe */
    {
        const char *db = path("mapstore", "map.db");
        remove(db);
        sooc_cogmap_params cp;
        sooc_cogmap_params_default(&cp);
        cp.dim = 2; cp.layout_dim = 1;
        sooc_cogmap *map;
        OK(sooc_cogmap_create(&map, &cp));
        for (int i = 0; i < 3; i++) {
            sooc_cogmap_entry e;
            memset(&e, 0, sizeof e);
            e.X = i; e.Z = -i; e.Theta = 0.5 * i; e.pres_logit = 1.0f; e.dim = 2;
            e.what_mu[0] = 0.1f * (float)i; e.what_logvar[1] = -1;
            e.obs_count = 1;
            OK(sooc_cogmap_insert(map, &e, NULL));
        }
        sooc_mapstore_params mp;
        sooc_mapstore_params_default(&mp);
        mp.model_id = "fuzz"; mp.dim = 2; mp.layout_dim = 1; mp.block_size = 4;
        sooc_mapstore *s;
        OK(sooc_mapstore_open(&s, db, &mp));
        OK(sooc_mapstore_save_map(s, map));
        float mu[1] = {0.5f}, lv[1] = {-2};
        OK(sooc_mapstore_begin(s));
        OK(sooc_mapstore_put_layout(s, 0, 1, mu, lv));
        sooc_mapstore_keyframe kf;
        memset(&kf, 0, sizeof kf);
        kf.t_ns = 1000; kf.view = 0;
        for (int i = 0; i < 16; i++) kf.T_wc[i] = i % 5 == 0;
        OK(sooc_mapstore_add_keyframe(s, &kf, 3));
        OK(sooc_mapstore_commit(s));
        sooc_mapstore_close(s);
        sooc_cogmap_destroy(map);
    }

    /* pose packets: camera and effector */
    {
        sooc_pose_packet pk = {.seq = 7, .kind = SOOC_POSE_CAMERA, .t_ns = 1305031102175304000LL,
                               .t = {1, 2, 3}, .q = {0, 0, 0, 1}};
        uint8_t buf[SOOC_POSE_PACKET_SIZE];
        sooc_pose_packet_encode(buf, &pk);
        OK(sooc_file_write_atomic(path("pose_packet", "camera.bin"), buf, sizeof buf));
        pk.kind = SOOC_POSE_EFFECTOR; pk.q[0] = 0.5; pk.q[3] = 0.5;
        sooc_pose_packet_encode(buf, &pk);
        OK(sooc_file_write_atomic(path("pose_packet", "effector_unnormalised.bin"), buf, sizeof buf));
    }

    /* images */
    {
        sooc_image img = {0};
        OK(sooc_image_alloc(&img, 5, 3, SOOC_PIX_RGB8));
        for (int i = 0; i < 15 * 3; i++) ((uint8_t *)img.data)[i] = (uint8_t)(17 * i);
        OK(sooc_png_write(path("png", "rgb8.png"), &img, 9));
        OK(sooc_image_alloc(&img, 4, 4, SOOC_PIX_GRAY8));
        for (int i = 0; i < 16; i++) ((uint8_t *)img.data)[i] = (uint8_t)(16 * i);
        OK(sooc_png_write(path("png", "gray8.png"), &img, 9));
        OK(sooc_pgm_write(path("pgm", "gray8.pgm"), &img));
        OK(sooc_image_alloc(&img, 3, 2, SOOC_PIX_GRAY16));
        for (int i = 0; i < 6; i++) ((uint16_t *)img.data)[i] = (uint16_t)(5000 * i + 1);
        OK(sooc_png_write(path("png", "gray16.png"), &img, 9));
        OK(sooc_pgm_write(path("pgm", "gray16.pgm"), &img));
        sooc_image_free(&img);
        static const char p2[] = "P2\n# comment\n3 2\n255\n0 1 2\n253 254 255\n";
        OK(sooc_file_write_atomic(path("pgm", "ascii.pgm"), p2, sizeof p2 - 1));
    }

    /* JPEG: colour 4:2:0, grey, a Motion-JPEG frame without Huffman tables,
     * a truncated file, and a header claiming 65500x65500 pixels */
    {
        sooc_image img = {0};
        OK(sooc_image_alloc(&img, 24, 16, SOOC_PIX_RGB8));
        for (int i = 0; i < 24 * 16 * 3; i++) ((uint8_t *)img.data)[i] = (uint8_t)(7 * i);
        void *j;
        size_t n;
        OK(sooc_jpeg_encode(&img, 75, &j, &n));
        OK(sooc_file_write_atomic(path("jpeg", "rgb8_420.jpg"), j, n));
        OK(sooc_file_write_atomic(path("jpeg", "truncated.jpg"), j, n / 2));
        /* drop the DHT segments before SOS */
        uint8_t *b = j;
        size_t i = 2, o = 2;
        while (i + 4 <= n && b[i] == 0xFF && b[i + 1] != 0xDA) {
            size_t len = 2 + ((size_t)b[i + 2] << 8 | b[i + 3]);
            if (b[i + 1] != 0xC4) { memmove(b + o, b + i, len); o += len; }
            i += len;
        }
        memmove(b + o, b + i, n - i);
        OK(sooc_file_write_atomic(path("jpeg", "mjpeg_no_dht.jpg"), b, o + (n - i)));
        /* SOF0 height/width -> 65500 x 65500 */
        OK(sooc_jpeg_encode(&img, 75, &j, &n));
        b = j;
        for (size_t k = 2; k + 9 < n; k++)
            if (b[k] == 0xFF && b[k + 1] == 0xC0) {
                b[k + 5] = b[k + 7] = 0xFF;
                b[k + 6] = b[k + 8] = 0xDC;
                break;
            }
        OK(sooc_file_write_atomic(path("jpeg", "huge_header.jpg"), j, n));
        sooc_free(j);
        OK(sooc_image_alloc(&img, 9, 7, SOOC_PIX_GRAY8));
        for (int k = 0; k < 63; k++) ((uint8_t *)img.data)[k] = (uint8_t)(4 * k);
        OK(sooc_jpeg_encode(&img, 90, &j, &n));
        OK(sooc_file_write_atomic(path("jpeg", "gray8.jpg"), j, n));
        sooc_free(j);
        sooc_image_free(&img);
    }

    /* a generated scene.yaml (small scale) */
    {
        sooc_gen_params gp;
        sooc_gen_params_default(&gp);
        sooc_scene sc;
        sooc_scene_init(&sc);
        OK(sooc_gen_scene(&sc, &gp, 0));
        OK(sooc_scene_save(path("scene", "gen0.yaml"), &sc));
        sooc_scene_free(&sc);
    }
    /* robot logs: an 8x6 camera (rgb8, 16UC1, CameraInfo, /tf) as MCAP files and its messages */
    {
        static uint8_t rgb[8 * 6 * 3];
        static uint16_t mm[8 * 6];
        for (int k = 0; k < 48; k++) {
            rgb[3 * k] = (uint8_t)(5 * k);
            mm[k] = (uint16_t)(800 + k);
        }
        sooc_ros_image im = {{1000, "cam"}, 8, 6, 24, "rgb8", 0, rgb, sizeof rgb};
        sooc_ros_image dm = {{1000, "cam"}, 8, 6, 16, "16UC1", 0, (uint8_t *)mm, sizeof mm};
        sooc_ros_caminfo ci;
        memset(&ci, 0, sizeof ci);
        ci.header = im.header;
        ci.width = 8;
        ci.height = 6;
        ci.nD = 5;
        double K[9] = {6, 0, 3.5, 0, 6, 2.5, 0, 0, 1};
        memcpy(ci.K, K, sizeof K);
        sooc_ros_transform tf = {{1000, "map"}, "cam", {0.5, 0, 1}, {0, 0, 0, 1}};
        for (int e = 0; e < 2; e++) {   /* message seeds in both encodings */
            sooc_msg_encoding enc = e ? SOOC_MSGENC_CDR : SOOC_MSGENC_ROS1;
            const char *t = e ? "cdrmsg" : "ros1msg";
            sooc_ros_buf b = {0};
            OK(sooc_ros_encode_image(&b, enc, &im));
            OK(sooc_file_write_atomic(path(t, "image.bin"), b.data, b.size));
            b.size = 0;
            OK(sooc_ros_encode_caminfo(&b, enc, &ci));
            OK(sooc_file_write_atomic(path(t, "caminfo.bin"), b.data, b.size));
            b.size = 0;
            OK(sooc_ros_encode_tf(&b, enc, &tf, 1));
            OK(sooc_file_write_atomic(path(t, "tf.bin"), b.data, b.size));
            sooc_ros_buf_free(&b);
        }
        static const char *const comps[3] = {"", "lz4", "zstd"};
        for (int v = 0; v < 4; v++) {   /* none, lz4, zstd with a summary; zstd streamed */
            sooc_mcap_writer_params wp;
            sooc_mcap_writer_params_default(&wp);
            wp.compression = comps[v < 3 ? v : 2];
            wp.summary = v < 3;
            char name[64];
            snprintf(name, sizeof name, "camera_%s%s.mcap", v < 3 && v ? comps[v] : v ? "zstd" : "none",
                     v == 3 ? "_streamed" : "");
            sooc_mcap_writer *w;
            OK(sooc_mcap_writer_open(&w, path("mcap", name), &wp));
            const char *types[3] = {"sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo", "tf2_msgs/msg/TFMessage"};
            int sc[3], ch[4];
            for (int k = 0; k < 3; k++) OK(sooc_mcap_writer_schema(w, types[k], "ros2msg", "", 0, &sc[k]));
            OK(sooc_mcap_writer_channel(w, sc[0], "/color", "cdr", &ch[0]));
            OK(sooc_mcap_writer_channel(w, sc[0], "/depth", "cdr", &ch[1]));
            OK(sooc_mcap_writer_channel(w, sc[1], "/camera_info", "cdr", &ch[2]));
            OK(sooc_mcap_writer_channel(w, sc[2], "/tf", "cdr", &ch[3]));
            sooc_ros_buf b = {0};
            for (int f = 0; f < 2; f++) {
                b.size = 0;
                OK(sooc_ros_encode_tf(&b, SOOC_MSGENC_CDR, &tf, 1));
                OK(sooc_mcap_writer_message(w, ch[3], 1000 + f, 1000 + f, b.data, b.size));
                b.size = 0;
                OK(sooc_ros_encode_caminfo(&b, SOOC_MSGENC_CDR, &ci));
                OK(sooc_mcap_writer_message(w, ch[2], 1000 + f, 1000 + f, b.data, b.size));
                b.size = 0;
                OK(sooc_ros_encode_image(&b, SOOC_MSGENC_CDR, &im));
                OK(sooc_mcap_writer_message(w, ch[0], 1000 + f, 1000 + f, b.data, b.size));
                b.size = 0;
                OK(sooc_ros_encode_image(&b, SOOC_MSGENC_CDR, &dm));
                OK(sooc_mcap_writer_message(w, ch[1], 1000 + f, 1000 + f, b.data, b.size));
            }
            sooc_ros_buf_free(&b);
            OK(sooc_mcap_writer_close(w));
        }
    }
    printf("seeds written to %s\n", out_dir);
    return 0;
}
