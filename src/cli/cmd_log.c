/* sooc3d log info FILE: what a ROS bag or MCAP file holds (channels, types,
 * counts, rates) and the camera streams, intrinsics, depth units,
 * registration and pose source the node would use (docs/logs.md). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "sooc3d/log.h"

static const char *const help =
    "usage: sooc3d log info FILE [options]\n"
    "\n"
    "Describe a ROS 1 bag (format 2.0) or an MCAP file: its channels (topic, type,\n"
    "encoding, messages, rate), and the RGB-D frames the node and the commands would\n"
    "read from it: the colour and depth topics, their intrinsics (CameraInfo), the\n"
    "depth units, whether depth is registered into the colour camera, the\n"
    "colour-depth pairs, and the pose source.\n"
    "\n"
    "options (the launch file's sensor/pose keys):\n"
    "  --color-topic T     colour image topic (default: the one there is)\n"
    "  --depth-topic T     depth image topic (default: the one there is)\n"
    "  --pair-tol-ms MS    colour-depth pairing tolerance on log time (20)\n"
    "  --pose-parent F     pose from TF: the world frame (default auto: the root of the\n"
    "                      camera frame's TF tree, as infer/eval/render/odometry read it)\n"
    "  --pose-child F      the camera frame (default: the colour image's frame_id)\n"
    "  --depth-scale S     metres per 16-bit depth unit (default: the log's, else 0.001)\n"
    "  --check             decompress every chunk and check every CRC\n";

typedef struct topic_row {
    const char *topic, *type, *encoding;
    int64_t count, t0, t1;
} topic_row;

static void print_channels(const sooc_logfile *lf) {
    int n = sooc_logfile_channel_count(lf);
    topic_row *rows = calloc((size_t)(n ? n : 1), sizeof *rows);
    int nr = 0;
    size_t wt = 5, wy = 4;
    if (!rows) return;
    for (int c = 0; c < n; c++) {   /* a bag may hold several connections on one topic */
        const sooc_logfile_channel *ch = sooc_logfile_channel_get(lf, c);
        int r = 0;
        while (r < nr && strcmp(rows[r].topic, ch->topic)) r++;
        if (r == nr) {
            rows[nr++] = (topic_row){ch->topic, ch->type, ch->encoding, 0, ch->t_first_ns, ch->t_last_ns};
            if (strlen(ch->topic) > wt) wt = strlen(ch->topic);
            if (strlen(ch->type) > wy) wy = strlen(ch->type);
        }
        if (ch->count) {
            if (!rows[r].count || ch->t_first_ns < rows[r].t0) rows[r].t0 = ch->t_first_ns;
            if (!rows[r].count || ch->t_last_ns > rows[r].t1) rows[r].t1 = ch->t_last_ns;
        }
        rows[r].count += ch->count;
    }
    printf("channels: %d topics\n", nr);
    printf("  %-*s  %-*s  %-8s %8s %9s\n", (int)wt, "topic", (int)wy, "type", "encoding", "messages", "rate (Hz)");
    for (int r = 0; r < nr; r++) {
        char rate[32] = "-";
        if (rows[r].count > 1 && rows[r].t1 > rows[r].t0)
            snprintf(rate, sizeof rate, "%.2f", (double)(rows[r].count - 1) / ((double)(rows[r].t1 - rows[r].t0) * 1e-9));
        printf("  %-*s  %-*s  %-8s %8lld %9s\n", (int)wt, rows[r].topic, (int)wy, rows[r].type, rows[r].encoding,
               (long long)rows[r].count, rate);
    }
    free(rows);
}

static void print_stream(const char *what, const sooc_logseq_stream *s) {
    printf("  %s: %s (%s, %s %dx%d), %lld images", what, s->topic, s->type, s->encoding, s->width, s->height,
           (long long)s->count);
    if (s->rate_hz > 0) printf(" at %.2f Hz", s->rate_hz);
    printf(", frame_id '%s'\n", s->frame_id);
    if (s->has_info) {
        const sooc_intrinsics *K = &s->K;
        printf("    intrinsics (%s): fx %.4f fy %.4f cx %.4f cy %.4f, distortion %s\n", s->info_topic, K->fx, K->fy,
               K->cx, K->cy, K->dist_model == SOOC_DIST_NONE ? "none" : K->dist_model == SOOC_DIST_RATIONAL ? "rational" : "plumb_bob");
    } else {
        printf("    intrinsics: none (no CameraInfo of this size; give a calibration)\n");
    }
}

static void print_frames(const sooc_logseq *s, double tol_ms) {
    const sooc_logseq_desc *d = sooc_logseq_describe(s);
    printf("camera streams:\n");
    print_stream("colour", &d->color);
    print_stream("depth", &d->depth);
    if (d->depth_scale > 0) printf("  depth units: %g m per unit (%s)\n", d->depth_scale, d->depth_scale_source);
    else printf("  depth units: metres (%s)\n", d->depth_scale_source);
    if (d->registered)
        printf("  registration: depth reprojected into the colour camera, extrinsics %s, t = (%.4f, %.4f, %.4f) m\n",
               d->extrinsics_source, d->T_color_depth[3], d->T_color_depth[7], d->T_color_depth[11]);
    else
        printf("  registration: none needed (depth is in the colour camera)\n");
    printf("  frames: %lld colour-depth pairs within %g ms of log time", (long long)d->n_frames, tol_ms);
    if (d->n_unpaired)
        printf(", %lld colour images unpaired (nearest depth %.1f ms away: raise --pair-tol-ms / sensor.pair_tol_ms)",
               (long long)d->n_unpaired, d->nearest_unpaired_s * 1e3);
    printf("\n");
    if (d->has_pose)
        printf("  pose: TF %s <- %s, %lld transforms in /tf and /tf_static, %lld frames without a pose\n", d->pose_parent,
               d->pose_child, (long long)d->tf_transforms, (long long)d->n_unposed);
    else
        printf("  pose: none (%lld transforms in /tf and /tf_static; --pose-parent / pose: {source: tf, parent: F})\n",
               (long long)d->tf_transforms);
}

static int cmd_info(int argc, char **argv) {
    const char *file = NULL;
    int check = 0;
    sooc_logseq_params lp;
    sooc_logseq_params_default(&lp);
    lp.pose_parent = "auto";   /* as the commands read a log */
    double tol_ms = 20;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int has = i + 1 < argc;
        if (!strcmp(a, "--check")) check = 1;
        else if (!strcmp(a, "--color-topic") && has) lp.color_topic = argv[++i];
        else if (!strcmp(a, "--depth-topic") && has) lp.depth_topic = argv[++i];
        else if (!strcmp(a, "--pose-parent") && has) lp.pose_parent = argv[++i];
        else if (!strcmp(a, "--pose-child") && has) lp.pose_child = argv[++i];
        else if (!strcmp(a, "--pair-tol-ms") && has) {
            if (!sooc_cli_double_opt("log", a, argv[++i], 0.001, 1e6, &tol_ms)) return 2;
        } else if (!strcmp(a, "--depth-scale") && has) {
            if (!sooc_cli_double_opt("log", a, argv[++i], 1e-9, 100, &lp.depth_scale)) return 2;
        } else if (a[0] == '-') {
            fprintf(stderr, "sooc3d log info: unknown option '%s' (or its value is missing)\n%s", a, help);
            return 2;
        } else if (!file) file = a;
        else {
            fprintf(stderr, "sooc3d log info: one file only ('%s', '%s')\n", file, a);
            return 2;
        }
    }
    if (!file) {
        fprintf(stderr, "%s", help);
        return 2;
    }
    lp.pair_tol_s = tol_ms * 1e-3;
    sooc_logfile *lf = NULL;
    sooc_status st = sooc_logfile_open(&lf, file);
    if (st) return sooc_cli_fail("log info", st);
    sooc_logfile_info in;
    sooc_logfile_get_info(lf, &in);
    printf("%s: %s, %lld bytes, %lld chunks (%s), messages located %s\n", file, sooc_logfile_kind_name(in.kind),
           (long long)in.file_size, (long long)in.n_chunks, in.compression,
           in.indexed ? "from its index" : "by scanning it");
    printf("messages: %lld", (long long)in.n_messages);
    if (in.n_messages)
        printf(" over %.3f s (log time %.9f .. %.9f)", (double)(in.t_last_ns - in.t_first_ns) * 1e-9,
               (double)in.t_first_ns * 1e-9, (double)in.t_last_ns * 1e-9);
    printf("\n");
    print_channels(lf);
    if (check) {
        st = sooc_logfile_verify(lf);
        printf("check: %s\n", st ? sooc_errmsg() : "every chunk decompresses, every stored CRC matches");
    }
    sooc_logfile_close(lf);
    if (st) return 1;
    sooc_logseq *s = NULL;
    sooc_status fs = sooc_logseq_open(&s, file, &lp);
    if (fs) {
        printf("camera streams: %s\n", sooc_errmsg());
        /* a topic named that does not exist, or two candidates with none named, is the user's to fix */
        return fs == SOOC_ENOTFOUND || fs == SOOC_EINVAL ? 1 : 0;
    }
    print_frames(s, tol_ms);
    sooc_logseq_close(s);
    return 0;
}

int sooc_cmd_log(int argc, char **argv) {
    if (argc < 2 || sooc_cli_wants_help(2, argv)) {
        printf("%s", help);
        return argc < 2 ? 2 : 0;
    }
    if (!strcmp(argv[1], "info")) {
        if (sooc_cli_wants_help(argc, argv)) {
            printf("%s", help);
            return 0;
        }
        return cmd_info(argc - 1, argv + 1);
    }
    fprintf(stderr, "sooc3d log: unknown subcommand '%s' (info)\n", argv[1]);
    return 2;
}
