/* Reading frames from a log against reading them from their folder: N frames
 * of 7-Scenes redkitchen (../shared/real, or argv[1]) written as MCAP files
 * (the JPEG bytes as CompressedImage, 16UC1 depth, CameraInfo; chunks
 * uncompressed, lz4 and zstd), then every frame read back through
 * sooc_seq_read from the folder and from each file, best of 3 passes.
 * Prints frames/s per source and the log/folder time ratios; the last line
 * is a JSON object. usage: bench_logs [REDKITCHEN_DIR [N]] */
#include "sooc3d/core.h"
#include "sooc3d/log.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static sooc_status write_log(sooc_seq *s, int64_t n, const char *path, const char *comp) {
    sooc_mcap_writer_params wp;
    sooc_mcap_writer_params_default(&wp);
    wp.compression = comp;
    sooc_mcap_writer *w = NULL;
    sooc_status st = sooc_mcap_writer_open(&w, path, &wp);
    if (st) return st;
    int sc[3], ch[4];
    const char *types[3] = {"sensor_msgs/msg/CompressedImage", "sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo"};
    for (int k = 0; k < 3 && !st; k++) {
        const char *def = sooc_ros_definition(types[k], SOOC_MSGENC_CDR);
        st = sooc_mcap_writer_schema(w, types[k], "ros2msg", def, strlen(def), &sc[k]);
    }
    if (!st) st = sooc_mcap_writer_channel(w, sc[0], "/color/compressed", "cdr", &ch[0]);
    if (!st) st = sooc_mcap_writer_channel(w, sc[1], "/depth/image_raw", "cdr", &ch[1]);
    if (!st) st = sooc_mcap_writer_channel(w, sc[2], "/color/camera_info", "cdr", &ch[2]);
    sooc_ros_buf b = {0};
    sooc_image dep = {0};
    const sooc_calib *cal = sooc_seq_calib(s);
    for (int64_t i = 0; i < n && !st; i++) {
        int64_t t = sooc_seq_frame_time(s, i);
        void *jpg = NULL;
        size_t nj = 0;
        sooc_ros_header h = {t, "cam"};
        if ((st = sooc_file_read_all(sooc_seq_color_path(s, i), 1 << 26, &jpg, &nj))) break;
        sooc_ros_cimage c = {h, "jpeg", jpg, nj};
        b.size = 0;
        if (!(st = sooc_ros_encode_cimage(&b, SOOC_MSGENC_CDR, &c))) st = sooc_mcap_writer_message(w, ch[0], t, t, b.data, b.size);
        sooc_free(jpg);
        if (!st) st = sooc_png_read(sooc_seq_depth_path(s, i), &dep);
        if (st) break;
        sooc_ros_image d = {h, dep.width, dep.height, (size_t)dep.width * 2, "16UC1", 0, dep.data,
                            (size_t)dep.width * dep.height * 2};
        b.size = 0;
        if (!(st = sooc_ros_encode_image(&b, SOOC_MSGENC_CDR, &d))) st = sooc_mcap_writer_message(w, ch[1], t, t, b.data, b.size);
        sooc_ros_caminfo k;
        memset(&k, 0, sizeof k);
        k.header = h;
        k.width = cal->K.width;
        k.height = cal->K.height;
        double K[9] = {cal->K.fx, 0, cal->K.cx, 0, cal->K.fy, cal->K.cy, 0, 0, 1};
        memcpy(k.K, K, sizeof K);
        b.size = 0;
        if (!st && !(st = sooc_ros_encode_caminfo(&b, SOOC_MSGENC_CDR, &k)))
            st = sooc_mcap_writer_message(w, ch[2], t, t, b.data, b.size);
    }
    sooc_ros_buf_free(&b);
    sooc_image_free(&dep);
    if (st) {
        sooc_mcap_writer_abort(w);
        return st;
    }
    return sooc_mcap_writer_close(w);
}

/* Best of 3: open + read every frame; frames/s. */
static double read_all(const char *path, int64_t n) {
    double best = 0;
    sooc_frame f = {0};
    for (int pass = 0; pass < 3; pass++) {
        double t0 = sooc_seconds();
        sooc_seq *s = NULL;
        sooc_seq_open_params sp;
        sooc_seq_open_params_default(&sp);
        sooc_logseq_params lp;
        sooc_logseq_params_default(&lp);
        lp.depth_scale = 0.001;
        if (sooc_log_seq_open(&s, path, &sp, &lp)) {
            fprintf(stderr, "bench_logs: %s\n", sooc_errmsg());
            exit(1);
        }
        int64_t m = sooc_seq_count(s) < n ? sooc_seq_count(s) : n;
        for (int64_t i = 0; i < m; i++)
            if (sooc_seq_read(s, i, &f)) {
                fprintf(stderr, "bench_logs: %s\n", sooc_errmsg());
                exit(1);
            }
        sooc_seq_close(s);
        double fps = (double)m / (sooc_seconds() - t0);
        if (fps > best) best = fps;
    }
    sooc_frame_free(&f);
    return best;
}

int main(int argc, char **argv) {
    const char *dir = argc > 1 ? argv[1] : "../shared/real/7scenes_redkitchen";
    int64_t n = argc > 2 ? atoll(argv[2]) : 100;
    sooc_seq *s = NULL;
    if (sooc_seq_open(&s, dir, NULL)) {
        fprintf(stderr, "bench_logs: %s\n", sooc_errmsg());
        return 1;
    }
    if (sooc_seq_count(s) < n) n = sooc_seq_count(s);
    const char *comps[3] = {"", "lz4", "zstd"}, *names[3] = {"none", "lz4", "zstd"};
    char paths[3][512];
    const char *tmp = getenv("TMPDIR") && *getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
    for (int c = 0; c < 3; c++) {
        snprintf(paths[c], sizeof paths[c], "%s/bench_logs_%d_%s.mcap", tmp, (int)getpid(), names[c]);
        if (write_log(s, n, paths[c], comps[c])) {
            fprintf(stderr, "bench_logs: %s\n", sooc_errmsg());
            return 1;
        }
    }
    sooc_seq_close(s);
    double folder = read_all(dir, n), fps[3];
    printf("folder (JPEG + 16-bit PNG): %.1f frames/s over %lld frames\n", folder, (long long)n);
    for (int c = 0; c < 3; c++) {
        fps[c] = read_all(paths[c], n);
        printf("MCAP, %-4s chunks (JPEG CompressedImage + 16UC1): %.1f frames/s, time %.2fx the folder's\n", names[c],
               fps[c], folder / fps[c]);
        remove(paths[c]);
    }
    printf("{\"bench\": \"logs\", \"frames\": %lld, \"folder_fps\": %.1f, \"mcap_none_fps\": %.1f, \"mcap_lz4_fps\": %.1f, "
           "\"mcap_zstd_fps\": %.1f, \"time_ratio_none\": %.3f, \"time_ratio_lz4\": %.3f, \"time_ratio_zstd\": %.3f}\n",
           (long long)n, folder, fps[0], fps[1], fps[2], folder / fps[0], folder / fps[1], folder / fps[2]);
    return 0;
}
