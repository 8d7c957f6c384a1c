/* sooc3d odometry: RGB-D odometry over a recorded sequence -> a TUM
 * trajectory, and ATE/RPE against the sequence's own poses when it has
 * them (or against any TUM file with --eval). */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "sooc3d/slam.h"
#include "sooc3d/core.h"
#include "sooc3d/log.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/frame.h"

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d odometry --seq DIR --out traj.txt [options]\n"
            "       sooc3d odometry --eval EST.txt --gt GT.txt [--delta S] [--max-dt S]\n\n"
            "Frame-to-keyframe RGB-D odometry (OpenCV rgbd) over any sequence sooc3d reads; writes the\n"
            "tracked frames' camera-to-world poses in TUM format (untracked frames are left out). When\n"
            "the sequence has poses, prints ATE and RPE (TUM definitions) against them.\n"
            "  --format F           tum|7scenes|slambook|replica (default auto)\n"
            "  --calib C            calibration YAML overriding the sequence's\n"
            "  --depth-scale S      metres per depth unit override; --depth-shift N (label-fusion: 3)\n"
            "  --variant V          rgbd|icp|rgbd_icp (default rgbd_icp)\n"
            "  --size WxH           working resolution (default 320x240; 0x0 = the frames')\n"
            "  --kf-trans M         new keyframe after M metres (default 0.10)\n"
            "  --kf-rot D           ... or D degrees (default 10)\n"
            "  --kf-frames N        ... or N frames (default 0 = off)\n"
            "  --min-agree A        failure when under this fraction of the depth agrees with the keyframe's (default 0.3)\n"
            "  --points P           fraction of the pixels OpenCV uses (default 0.07)\n"
            "  --depth-diff M       correspondence depth gate in metres (default 0.07)\n"
            "  --max-failures N     re-anchor after N failed frames in a row (default 10)\n"
            "  --depth-range A:B    depths used, metres (default 0.3:4)\n"
            "  --color-K K          colour camera when colour is not registered to depth: fx,fy,cx,cy\n"
            "                       (frames' resolution), '7scenes' (f 525) or 'registered'; default auto:\n"
            "                       7scenes for a 7-Scenes sequence with its depth intrinsics (f 585)\n"
            "  --color-t X,Y,Z      colour camera translation, p_color = p_depth + t (metres, default 0)\n"
            "  --max-frames N       stop after N frames; --first-frame N starts at frame N\n"
            "  --loop-closure       keyframe graph with place recognition, loop closure and pose-graph\n"
            "                       optimisation (docs/slam.md); the trajectory written is the optimised one\n"
            "  --map DB             keep the keyframes in this map database (created if missing); with\n"
            "                       stored keyframes the run starts lost and relocalises into them\n"
            "  --kf-depth WxH       keyframe depth kept for verification ICP (default 160x120)\n"
            "  --loop-window N      newest keyframes left out of the loop search (default 6)\n"
            "  --loop-per-frame N   a new keyframe's loop candidates verified per frame after it\n"
            "                       (default 1; 0: all on the keyframe's own frame)\n"
            "  --local-edges 0|1    verify each keyframe against the recent ones too (default 0)\n"
            "  --loop-sigma M,R     loop/relocalisation edge sigma: metres, radians (default 0.01,0.01)\n"
            "  --no-relocalise      with --map or --loop-closure: never relocalise (a new run starts its own\n"
            "                       frame; a lost tracker re-anchors at its last pose)\n"
            "  --start-gt           start at the sequence's first pose instead of the identity\n"
            "  --gt-out FILE        also write the sequence's poses (TUM)\n"
            "  --write-seq DIR      also write the tracked frames with the odometry poses as a sooc3d\n"
            "                       sequence (TUM layout), e.g. for `sooc3d eval` without recorded poses\n"
            "  --delta S            RPE delta in seconds (default 1.0); --delta-frames N uses frames\n"
            "  --max-dt S           timestamp association tolerance (default 0.02)\n"
            "The last line printed is a JSON object with the figures.\n");
}

static int print_metrics(const sooc_traj_metrics *m, const char *prefix) {
    printf("%sATE RMSE %.4f m (mean %.4f, median %.4f, max %.4f) over %lld poses\n", prefix, m->ate_rmse, m->ate_mean,
           m->ate_median, m->ate_max, (long long)m->pairs);
    printf("%sRPE per %g%s: translation RMSE %.4f m, rotation RMSE %.3f deg over %lld pairs\n", prefix, m->rpe_delta,
           "", m->rpe_trans_rmse, m->rpe_rot_rmse_deg, (long long)m->rpe_pairs);
    return 0;
}

int sooc_cmd_odometry(int argc, char **argv) {
    const char *cmd = "odometry";
    if (sooc_cli_wants_help(argc, argv)) {
        usage(stdout);
        return 0;
    }
    const char *seq_dir = NULL, *out = NULL, *gt_out = NULL, *eval_est = NULL, *eval_gt = NULL, *write_seq = NULL;
    sooc_seq_open_params sp;
    sooc_seq_open_params_default(&sp);
    sooc_odom_params op;
    sooc_odom_params_default(&op);
    double delta = 1.0, max_dt = 0.02;
    int delta_frames = 0, start_gt = 0;
    const char *color_K = "auto";
    long long max_frames = 0, first_frame = 0;
    int loop_closure = 0, relocalise = 1, kf_dw = 160, kf_dh = 120, local_edges = 0, loop_window = 6, loop_per_frame = 1;
    double loop_sig[2] = {0.01, 0.01};
    const char *map_path = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
#define NEEDV()                                                                   \
    do {                                                                          \
        if (!v) {                                                                 \
            fprintf(stderr, "sooc3d odometry: %s needs a value\n", a);            \
            return 2;                                                             \
        }                                                                         \
        i++;                                                                      \
    } while (0)
        if (!strcmp(a, "--seq")) { NEEDV(); seq_dir = v; }
        else if (!strcmp(a, "--out")) { NEEDV(); out = v; if (sooc_cli_need_parent(cmd, a, v)) return 2; }
        else if (!strcmp(a, "--gt-out")) { NEEDV(); gt_out = v; if (sooc_cli_need_parent(cmd, a, v)) return 2; }
        else if (!strcmp(a, "--write-seq")) { NEEDV(); write_seq = v; }
        else if (!strcmp(a, "--eval")) { NEEDV(); eval_est = v; }
        else if (!strcmp(a, "--gt")) { NEEDV(); eval_gt = v; }
        else if (!strcmp(a, "--format")) {
            NEEDV();
            sooc_status s = sooc_seq_format_parse(v, &sp.format);
            if (s) return sooc_cli_fail(cmd, s);
        } else if (!strcmp(a, "--calib")) { NEEDV(); sp.calib_path = v; }
        else if (!strcmp(a, "--depth-scale")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 1e-9, 1, &sp.depth_scale)) return 2; }
        else if (!strcmp(a, "--depth-shift")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 0, 15, &sp.depth_shift)) return 2; }
        else if (!strcmp(a, "--variant")) {
            NEEDV();
            sooc_status s = sooc_odom_variant_parse(v, &op.variant);
            if (s) return sooc_cli_fail(cmd, s);
        } else if (!strcmp(a, "--size")) {
            NEEDV();
            int w = -1, h = -1, n = 0;
            if (sscanf(v, "%dx%d%n", &w, &h, &n) != 2 || v[n] || w < 0 || h < 0 || w > 8192 || h > 8192 ||
                (!w) != (!h)) {
                fprintf(stderr, "sooc3d odometry: --size: expected WxH (e.g. 320x240, 0x0 = as read), got '%s'\n", v);
                return 2;
            }
            op.width = w;
            op.height = h;
        } else if (!strcmp(a, "--kf-trans")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 0, 10, &op.kf_translation_m)) return 2; }
        else if (!strcmp(a, "--kf-rot")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 0, 180, &op.kf_rotation_deg)) return 2; }
        else if (!strcmp(a, "--kf-frames")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 0, 1000000, &op.kf_max_frames)) return 2; }
        else if (!strcmp(a, "--min-agree")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 0, 1, &op.min_agreement)) return 2; }
        else if (!strcmp(a, "--points")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 1e-3, 1, &op.max_points_part)) return 2; }
        else if (!strcmp(a, "--depth-diff")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 1e-3, 1, &op.max_depth_diff_m)) return 2; }
        else if (!strcmp(a, "--max-failures")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 0, 1000000, &op.max_failures)) return 2; }
        else if (!strcmp(a, "--depth-range")) {
            NEEDV();
            double lo, hi;
            int n = 0;
            if (sscanf(v, "%lf:%lf%n", &lo, &hi, &n) != 2 || v[n] || !(lo >= 0 && hi > lo && hi < 100)) {
                fprintf(stderr, "sooc3d odometry: --depth-range: expected MIN:MAX metres, got '%s'\n", v);
                return 2;
            }
            op.min_depth_m = lo;
            op.max_depth_m = hi;
        } else if (!strcmp(a, "--color-K")) {
            NEEDV();
            double k[4];
            int n = 0;
            if (!strcmp(v, "auto") || !strcmp(v, "7scenes") || !strcmp(v, "registered")) color_K = v;
            else if (sscanf(v, "%lf,%lf,%lf,%lf%n", &k[0], &k[1], &k[2], &k[3], &n) == 4 && !v[n] && k[0] > 0 &&
                     k[1] > 0 && k[0] < 1e5 && k[1] < 1e5 && fabs(k[2]) < 1e5 && fabs(k[3]) < 1e5) {
                memcpy(op.color_K, k, sizeof k);
                color_K = "given";
            } else {
                fprintf(stderr, "sooc3d odometry: --color-K: expected fx,fy,cx,cy (pixels), 7scenes, registered "
                                "or auto, got '%s'\n", v);
                return 2;
            }
        } else if (!strcmp(a, "--color-t")) {
            NEEDV();
            double t[3];
            int n = 0;
            if (sscanf(v, "%lf,%lf,%lf%n", &t[0], &t[1], &t[2], &n) != 3 || v[n] || !(fabs(t[0]) < 1 && fabs(t[1]) < 1 &&
                                                                                    fabs(t[2]) < 1)) {
                fprintf(stderr, "sooc3d odometry: --color-t: expected X,Y,Z metres (each under 1 m), got '%s'\n", v);
                return 2;
            }
            op.T_color_depth[3] = t[0];
            op.T_color_depth[7] = t[1];
            op.T_color_depth[11] = t[2];
        } else if (!strcmp(a, "--max-frames")) { NEEDV(); if (!sooc_cli_count_opt(cmd, a, v, &max_frames)) return 2; }
        else if (!strcmp(a, "--first-frame")) { NEEDV(); if (!sooc_cli_count_opt(cmd, a, v, &first_frame)) return 2; }
        else if (!strcmp(a, "--loop-closure")) loop_closure = 1;
        else if (!strcmp(a, "--no-relocalise")) relocalise = 0;
        else if (!strcmp(a, "--loop-window")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 0, 100000, &loop_window)) return 2; }
        else if (!strcmp(a, "--loop-per-frame")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 0, 1000, &loop_per_frame)) return 2; }
        else if (!strcmp(a, "--local-edges")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 0, 1, &local_edges)) return 2; }
        else if (!strcmp(a, "--kf-depth")) {
            NEEDV();
            int n2 = 0;
            if (sscanf(v, "%dx%d%n", &kf_dw, &kf_dh, &n2) != 2 || v[n2] || kf_dw < 16 || kf_dh < 12 || kf_dw > 4096 ||
                kf_dh > 4096) {
                fprintf(stderr, "sooc3d odometry: --kf-depth: expected WxH (at least 16x12), got '%s'\n", v);
                return 2;
            }
        } else if (!strcmp(a, "--loop-sigma")) {
            NEEDV();
            int n2 = 0;
            if (sscanf(v, "%lf,%lf%n", &loop_sig[0], &loop_sig[1], &n2) != 2 || v[n2] || !(loop_sig[0] > 0) ||
                !(loop_sig[1] > 0) || loop_sig[0] > 10 || loop_sig[1] > 10) {
                fprintf(stderr, "sooc3d odometry: --loop-sigma: expected METRES,RADIANS (> 0), got '%s'\n", v);
                return 2;
            }
        }
        else if (!strcmp(a, "--map")) { NEEDV(); map_path = v; }
        else if (!strcmp(a, "--start-gt")) start_gt = 1;
        else if (!strcmp(a, "--delta")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 1e-6, 1e6, &delta)) return 2; }
        else if (!strcmp(a, "--delta-frames")) { NEEDV(); if (!sooc_cli_int_opt(cmd, a, v, 1, 1000000, &delta_frames)) return 2; }
        else if (!strcmp(a, "--max-dt")) { NEEDV(); if (!sooc_cli_double_opt(cmd, a, v, 0, 10, &max_dt)) return 2; }
        else {
            fprintf(stderr, "sooc3d odometry: unknown option '%s'\n", a);
            usage(stderr);
            return 2;
        }
#undef NEEDV
    }
    if (delta_frames) delta = 0;
    sooc_status st;
    if (eval_est || eval_gt) {
        if (!eval_est || !eval_gt) {
            fprintf(stderr, "sooc3d odometry: --eval needs --gt (and the other way round)\n");
            return 2;
        }
        sooc_traj e = {0}, g = {0};
        sooc_traj_metrics m;
        if ((st = sooc_traj_load_tum(eval_est, &e)) || (st = sooc_traj_load_tum(eval_gt, &g)) ||
            (st = sooc_traj_evaluate(&e, &g, max_dt, delta, delta_frames, &m))) {
            sooc_traj_free(&e);
            sooc_traj_free(&g);
            return sooc_cli_fail(cmd, st);
        }
        print_metrics(&m, "");
        printf("{\"ate_rmse\": %.6f, \"ate_mean\": %.6f, \"ate_median\": %.6f, \"ate_max\": %.6f, \"pairs\": %lld, "
               "\"rpe_trans_rmse\": %.6f, \"rpe_rot_rmse_deg\": %.6f, \"rpe_delta\": %g, \"rpe_pairs\": %lld}\n",
               m.ate_rmse, m.ate_mean, m.ate_median, m.ate_max, (long long)m.pairs, m.rpe_trans_rmse,
               m.rpe_rot_rmse_deg, m.rpe_delta, (long long)m.rpe_pairs);
        sooc_traj_free(&e);
        sooc_traj_free(&g);
        return 0;
    }
    if (!seq_dir || !out) {
        fprintf(stderr, "sooc3d odometry: --seq and --out are required\n");
        usage(stderr);
        return 2;
    }
    sooc_seq *seq = NULL;
    sooc_odom *odo = NULL;
    sooc_slam *slam = NULL;
    sooc_mapstore *store = NULL;
    sooc_frame f;
    memset(&f, 0, sizeof f);
    sooc_traj est = {0}, gt = {0};
    int64_t *kept = NULL;
    int rc = 1;
    if ((st = sooc_log_seq_open(&seq, seq_dir, &sp, NULL))) goto fail;   /* a folder, a ROS bag or an MCAP file */
    {
        const sooc_calib *cal = sooc_seq_calib(seq);
        int cw = cal->K.width, ch = cal->K.height;
        if (!strcmp(color_K, "7scenes") ||
            (!strcmp(color_K, "auto") && sooc_seq_get_format(seq) == SOOC_SEQ_7SCENES &&
             sooc_odom_is_7scenes_depth_K(&cal->K, cw, ch))) {
            double t[3] = {op.T_color_depth[3], op.T_color_depth[7], op.T_color_depth[11]};
            sooc_odom_params_7scenes_color(&op, cw, ch);
            op.T_color_depth[3] = t[0];
            op.T_color_depth[7] = t[1];
            op.T_color_depth[11] = t[2];
            sooc_log(SOOC_LOG_INFO, "odometry: %s: 7-Scenes colour is not registered to depth: colour camera "
                     "f %.1f, depth camera f %.1f (--color-K registered to turn off)", seq_dir, op.color_K[0], cal->K.fx);
        }
    }
    int use_slam = loop_closure || map_path;
    if (use_slam) {
        sooc_slam_params sp2;
        sooc_slam_params_default(&sp2);
        sp2.odom = op;
        sp2.loop_closure = loop_closure;
        sp2.relocalise = relocalise;
        sp2.depth_w = kf_dw;
        sp2.depth_h = kf_dh;
        sp2.local_edges = local_edges;
        sp2.recent_window = loop_window;
        sp2.loop_verify_per_frame = loop_per_frame;
        sp2.sigma_loop_m = loop_sig[0];
        sp2.sigma_loop_rad = loop_sig[1];
        if (map_path) {
            sooc_mapstore_params mp;
            sooc_mapstore_params_default(&mp);
            mp.create = 1;
            FILE *ex = fopen(map_path, "rb");
            if (ex) fclose(ex);
            else mp.dim = 1;   /* a new map made by odometry: keyframes only, latent dim 1 */
            if ((st = sooc_mapstore_open(&store, map_path, &mp))) goto fail;
        }
        if ((st = sooc_slam_create(&slam, &sp2, store))) goto fail;
        sooc_slam_stats ss0;
        sooc_slam_get_stats(slam, &ss0);
        if (ss0.stored_keyframes)
            printf("%s: %lld stored keyframes%s\n", map_path, (long long)ss0.stored_keyframes,
                   relocalise ? ": relocalising into them" : "");
    } else if ((st = sooc_odom_create(&odo, &op))) goto fail;
    int64_t n = sooc_seq_count(seq);
    if (first_frame >= n) {
        st = sooc_seterr(SOOC_EINVAL, "odometry: --first-frame %lld: the sequence has %lld frames", first_frame,
                         (long long)n);
        goto fail;
    }
    if (max_frames && first_frame + max_frames < n) n = first_frame + max_frames;
    int64_t failed = 0, reanchor = 0, n_slam = 0;
    kept = sooc_malloc((size_t)(n > 0 ? n : 1) * sizeof(int64_t));
    if (!kept) { st = sooc_seterr(SOOC_ENOMEM, "odometry: out of memory"); goto fail; }
    double t0 = sooc_seconds();
    for (int64_t i = first_frame; i < n; i++) {
        if ((st = sooc_seq_read(seq, i, &f))) goto fail;
        double t = (double)f.t_ns * 1e-9;
        if (f.has_pose && (st = sooc_traj_push(&gt, t, f.T_wc))) goto fail;
        if (slam) {
            if (i == first_frame && start_gt && f.has_pose) sooc_slam_set_initial_pose(slam, f.T_wc);
            sooc_slam_result sr;
            if ((st = sooc_slam_track(slam, &f, &sr))) goto fail;
            if (sr.state > SOOC_SLAM_RELOCALISED) failed++;
            else kept[n_slam++] = i;   /* the order of sooc_slam_trajectory */
            if (sr.state == SOOC_SLAM_RELOCALISED)
                sooc_log(SOOC_LOG_INFO, "odometry: frame %lld relocalised into the stored keyframes", (long long)f.index);
            if (sr.loop_closed)
                sooc_log(SOOC_LOG_INFO, "odometry: frame %lld closed a loop", (long long)f.index);
            continue;
        }
        if (i == first_frame && start_gt && f.has_pose) sooc_odom_set_initial_pose(odo, f.T_wc);
        sooc_odom_result r;
        if ((st = sooc_odom_track(odo, &f, &r))) goto fail;
        if (r.state == SOOC_ODOM_FIRST || r.state == SOOC_ODOM_TRACKED) {
            kept[est.n] = i;
            if ((st = sooc_traj_push(&est, t, r.T_wc))) goto fail;
        } else {
            failed++;
            if (r.state == SOOC_ODOM_REANCHORED) {
                reanchor++;
                sooc_log(SOOC_LOG_WARN, "odometry: lost at frame %lld, re-anchored", (long long)f.index);
            }
        }
    }
    double secs = sooc_seconds() - t0;
    sooc_odom_stats os;
    memset(&os, 0, sizeof os);
    sooc_slam_stats ss;
    memset(&ss, 0, sizeof ss);
    if (slam) {
        int closed = 0;
        if ((st = sooc_slam_flush(slam, &closed))) goto fail;   /* the last keyframe's loop candidates */
        if (closed) sooc_log(SOOC_LOG_INFO, "odometry: the last keyframe closed a loop");
        sooc_slam_get_stats(slam, &ss);
        if ((st = sooc_slam_trajectory(slam, &est))) goto fail;
        os.frames = ss.frames;
        os.tracked = ss.tracked;
        os.keyframes = ss.keyframes - ss.stored_keyframes;
        os.ms_total = ss.ms_track + ss.ms_features + ss.ms_loop + ss.ms_reloc + ss.ms_pgo;
    } else {
        sooc_odom_get_stats(odo, &os);
    }
    if ((st = sooc_traj_save_tum(out, &est))) goto fail;
    if (gt_out && gt.n && (st = sooc_traj_save_tum(gt_out, &gt))) goto fail;
    if (write_seq) {
        /* second pass: the tracked frames again, with their odometry poses */
        sooc_calib wc = *sooc_seq_calib(seq);
        if (!(wc.depth_scale > 0)) wc.depth_scale = 0.001;
        sooc_seq_writer *w = NULL;
        if ((st = sooc_seq_writer_create(&w, write_seq, &wc, est.n))) goto fail;
        for (int64_t k = 0; k < est.n && !st; k++) {
            if ((st = sooc_seq_read(seq, kept[k], &f))) break;
            memcpy(f.T_wc, est.T + 16 * k, sizeof f.T_wc);
            f.has_pose = 1;
            st = sooc_seq_writer_put(w, k, &f);
        }
        if (!st) st = sooc_seq_writer_finish(w);
        sooc_seq_writer_destroy(w);
        if (st) goto fail;
        printf("wrote the %lld tracked frames with odometry poses to %s\n", (long long)est.n, write_seq);
    }
    printf("odometry (%s, %dx%d): %lld frames, %lld tracked, %lld failed, %lld keyframes, %lld re-anchors; "
           "%.1f ms/frame in odometry (%.1f frames/s end to end)\n",
           sooc_odom_variant_name(op.variant), op.width, op.height, (long long)os.frames, (long long)os.tracked,
           (long long)failed, (long long)os.keyframes, (long long)reanchor, os.frames ? os.ms_total / os.frames : 0,
           secs > 0 ? n / secs : 0);
    printf("wrote %s (%lld poses)\n", out, (long long)est.n);
    sooc_traj_metrics m;
    memset(&m, 0, sizeof m);
    int have_m = 0;
    if (gt.n >= 3 && est.n >= 3) {
        if ((st = sooc_traj_evaluate(&est, &gt, max_dt, delta, delta_frames, &m))) goto fail;
        have_m = 1;
        print_metrics(&m, "");
    } else {
        printf("(the sequence has no poses: no ATE/RPE)\n");
    }
    printf("{\"frames\": %lld, \"tracked\": %lld, \"failed\": %lld, \"keyframes\": %lld, \"reanchors\": %lld, "
           "\"odometry_ms_per_frame\": %.3f",
           (long long)os.frames, (long long)os.tracked, (long long)failed, (long long)os.keyframes, (long long)reanchor,
           os.frames ? os.ms_total / os.frames : 0);
    if (slam)
        printf(", \"slam\": {\"stored_keyframes\": %lld, \"relocalised\": %lld, \"lost_frames\": %lld, \"loops\": %lld, "
               "\"loop_candidates\": %lld, \"loop_rejected\": %lld, \"optimisations\": %lld, \"ms_track\": %.1f, "
               "\"ms_features\": %.1f, \"ms_loop\": %.1f, \"ms_reloc\": %.1f, \"ms_pgo\": %.1f}",
               (long long)ss.stored_keyframes, (long long)ss.relocalised, (long long)ss.lost, (long long)ss.loops,
               (long long)ss.loop_candidates, (long long)ss.loop_rejected, (long long)ss.optimisations, ss.ms_track,
               ss.ms_features, ss.ms_loop, ss.ms_reloc, ss.ms_pgo);
    if (have_m)
        printf(", \"ate_rmse\": %.6f, \"ate_mean\": %.6f, \"ate_max\": %.6f, \"rpe_trans_rmse\": %.6f, "
               "\"rpe_rot_rmse_deg\": %.6f, \"rpe_delta\": %g",
               m.ate_rmse, m.ate_mean, m.ate_max, m.rpe_trans_rmse, m.rpe_rot_rmse_deg, m.rpe_delta);
    printf("}\n");
    rc = 0;
    goto done;
fail:
    rc = sooc_cli_fail(cmd, st);
done:
    sooc_free(kept);
    sooc_frame_free(&f);
    sooc_traj_free(&est);
    sooc_traj_free(&gt);
    sooc_odom_destroy(odo);
    sooc_slam_destroy(slam);
    sooc_mapstore_close(store);
    sooc_seq_close(seq);
    return rc;
}
