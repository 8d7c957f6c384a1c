/* bench_slam: the SLAM tracker's times against the plain odometry measured
 * in the same run on the same frames: per frame (median, mean, max) with
 * loop closure; per keyframe the features, the loop search + verification
 * and the pose-graph optimisation; per relocalisation attempt (a second run
 * on the second half of the frames relocalising into the first half's
 * keyframes, stored in a temporary map database). Frames come from
 * ../shared/real/7scenes_redkitchen or, when absent, from the ray-cast room
 * loop of the tests. The result is validated first (ATE of the loop-closure
 * run under 5 cm, the second run relocalised). The last line is a JSON
 * object; speeds are given as ratios to the odometry's median frame.
 *   bench_slam [max_frames=300] [dir] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sooc3d/cogmap.h"
#include "sooc3d/frame.h"
#include "sooc3d/slam.h"

#include "slam/loop_room.h"

#define NSYN 120

static sooc_seq *g_seq;
static int g_n;
static sooc_frame g_f;

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int read_frame(int i) {
    if (g_seq) return sooc_seq_read(g_seq, i, &g_f) ? -1 : 0;
    loop_frame(i, NSYN, &g_f);
    return 0;
}

static void params(sooc_slam_params *p) {
    sooc_slam_params_default(p);
    if (g_seq) {
        const sooc_calib *cal = sooc_seq_calib(g_seq);
        sooc_odom_params_7scenes_color(&p->odom, cal->K.width, cal->K.height);
    } else {
        p->odom.width = p->odom.height = 0;
    }
}

typedef struct times {
    double median, mean, max;
} times;

static times summarise(double *ms, int n) {
    times t = {0, 0, 0};
    if (n <= 0) return t;
    for (int i = 0; i < n; i++) {
        t.mean += ms[i] / n;
        if (ms[i] > t.max) t.max = ms[i];
    }
    qsort(ms, (size_t)n, sizeof *ms, cmp_d);
    t.median = ms[n / 2];
    return t;
}

/* SLAM over the frames: per-frame times summarised, the poor man's ground
 * truth of the tracked frames pushed to gt (NULL: not kept) */
static int run_slam(const sooc_slam_params *p, double *ms, times *t, sooc_slam **out, sooc_traj *gt) {
    if (sooc_slam_create(out, p, NULL)) return 1;
    for (int i = 0; i < g_n; i++) {
        sooc_slam_result r;
        if (read_frame(i) || sooc_slam_track(*out, &g_f, &r)) return 1;
        ms[i] = r.ms;
        double T[16];
        if (g_seq) memcpy(T, g_f.T_wc, sizeof T);
        else loop_pose(i, NSYN, T);
        if (gt && r.state <= SOOC_SLAM_RELOCALISED) sooc_traj_push(gt, g_f.t_ns * 1e-9, T);
    }
    *t = summarise(ms, g_n);
    return 0;
}

int main(int argc, char **argv) {
    int max_frames = argc > 1 ? atoi(argv[1]) : 300;
    char dir[1024];
    const char *real = getenv("SOOC_SHARED_REAL");
    if (argc > 2) snprintf(dir, sizeof dir, "%s", argv[2]);
    else snprintf(dir, sizeof dir, "%s/7scenes_redkitchen", real ? real : "../shared/real");
    if (!sooc_cv_available()) {
        printf("{\"bench\": \"slam\", \"error\": \"built without OpenCV\"}\n");
        return 1;
    }
    const char *source = "room loop (synthetic)";
    if (sooc_dir_exists(dir) && sooc_seq_open(&g_seq, dir, NULL) == SOOC_OK) {
        g_n = (int)sooc_seq_count(g_seq);
        source = "7scenes_redkitchen";
    } else {
        g_n = NSYN;
        if (sooc_frame_alloc(&g_f, W, H, 0)) return 1;
    }
    if (max_frames > 0 && max_frames < g_n) g_n = max_frames;
    double *ms = malloc(sizeof(double) * (size_t)g_n);
    if (!ms) return 1;
    sooc_slam_params p;
    params(&p);
    /* warm-up: OpenCV's first calls allocate */
    {
        sooc_odom *o = NULL;
        if (sooc_odom_create(&o, &p.odom)) return 1;
        for (int i = 0; i < 5 && i < g_n; i++) {
            sooc_odom_result r;
            if (read_frame(i) || sooc_odom_track(o, &g_f, &r)) return 1;
        }
        sooc_odom_destroy(o);
    }
    /* 1. the odometry alone */
    sooc_odom *o = NULL;
    if (sooc_odom_create(&o, &p.odom)) return 1;
    for (int i = 0; i < g_n; i++) {
        sooc_odom_result r;
        if (read_frame(i) || sooc_odom_track(o, &g_f, &r)) return 1;
        ms[i] = r.ms;
    }
    sooc_odom_destroy(o);
    times t_odo = summarise(ms, g_n);
    /* 2. SLAM with loop closure: a keyframe's loop candidates verified on its
     * own frame (all at once), then spread over the frames after it (default) */
    sooc_slam_params p_now = p;
    p_now.loop_verify_per_frame = 0;
    times t_now;
    sooc_slam *s = NULL;
    if (run_slam(&p_now, ms, &t_now, &s, NULL)) return 1;
    sooc_slam_destroy(s);
    sooc_traj gt = {0}, est = {0};
    times t_slam;
    if (run_slam(&p, ms, &t_slam, &s, &gt)) return 1;
    if (sooc_slam_flush(s, NULL)) return 1;
    sooc_slam_stats st;
    sooc_slam_get_stats(s, &st);
    sooc_traj_metrics m;
    if (sooc_slam_trajectory(s, &est) || sooc_traj_evaluate(&est, &gt, 0.02, 1.0, 0, &m) || m.ate_rmse > 0.05) {
        printf("{\"bench\": \"slam\", \"error\": \"validation failed: ATE %.4f m\"}\n", m.ate_rmse);
        return 1;
    }
    sooc_slam_destroy(s);
    /* 3. relocalisation: the second half into the first half's keyframes */
    char tmp[] = "/tmp/sooc_benchslam_XXXXXX", path[256];
    if (!mkdtemp(tmp)) return 1;
    snprintf(path, sizeof path, "%s/map.sqlite", tmp);
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 1;
    mp.dim = 1;
    sooc_mapstore *store = NULL;
    if (sooc_mapstore_open(&store, path, &mp) || sooc_slam_create(&s, &p, store)) return 1;
    int half = g_seq ? g_n / 2 : 3 * g_n / 4;
    for (int i = 0; i < half; i++) {
        sooc_slam_result r;
        if (read_frame(i) || sooc_slam_track(s, &g_f, &r)) return 1;
    }
    sooc_slam_destroy(s);
    if (sooc_slam_create(&s, &p, store)) return 1;
    int reloc_at = -1;
    for (int i = g_seq ? half : 0; i < g_n && reloc_at < 0; i++) {
        sooc_slam_result r;
        if (read_frame(i) || sooc_slam_track(s, &g_f, &r)) return 1;
        if (r.state == SOOC_SLAM_RELOCALISED) reloc_at = i;
    }
    sooc_slam_stats st2;
    sooc_slam_get_stats(s, &st2);
    sooc_slam_destroy(s);
    sooc_mapstore_close(store);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd)) return 1;
    if (reloc_at < 0) {
        printf("{\"bench\": \"slam\", \"error\": \"validation failed: the second run never relocalised\"}\n");
        return 1;
    }
    double kf = st.keyframes > 0 ? (double)st.keyframes : 1;
    double reloc_ms = st2.reloc_attempts ? st2.ms_reloc / st2.reloc_attempts : 0;
    double loop_ms = st.ms_loop / kf, feat_ms = st.ms_features / kf;
    double pgo_ms = st.optimisations ? st.ms_pgo / st.optimisations : 0;
    printf("%s, %d frames: odometry %.1f ms/frame (median), SLAM %.1f ms (median, mean %.1f, max %.1f); per keyframe "
           "(%lld): features %.1f ms, loop search %.1f ms; %lld optimisations %.1f ms each; relocalisation %.1f ms "
           "per attempt (%lld attempts, %lld stored keyframes); ATE %.4f m with %lld loops; max %.1f ms with every candidate verified on its keyframe's frame\n",
           source, g_n, t_odo.median, t_slam.median, t_slam.mean, t_slam.max, (long long)st.keyframes, feat_ms,
           loop_ms, (long long)st.optimisations, pgo_ms, reloc_ms, (long long)st2.reloc_attempts,
           (long long)st2.stored_keyframes, m.ate_rmse, (long long)st.loops, t_now.max);
    printf("{\"bench\": \"slam\", \"source\": \"%s\", \"frames\": %d, \"odometry_ms_median\": %.2f, "
           "\"slam_ms_median\": %.2f, \"slam_ms_mean\": %.2f, \"slam_ms_max\": %.2f, \"keyframes\": %lld, "
           "\"features_ms_per_keyframe\": %.2f, \"loop_ms_per_keyframe\": %.2f, \"optimisations\": %lld, "
           "\"pgo_ms\": %.2f, \"reloc_ms_per_attempt\": %.2f, \"reloc_stored_keyframes\": %lld, "
           "\"ratio_slam_mean_to_odometry\": %.3f, \"ratio_loop_to_odometry\": %.3f, "
           "\"ratio_reloc_to_odometry\": %.3f, \"ate_rmse\": %.5f, \"loops\": %lld, "
           "\"slam_ms_max_verify_on_keyframe\": %.2f, \"ratio_slam_max_to_odometry\": %.3f, "
           "\"ratio_slam_max_verify_on_keyframe_to_odometry\": %.3f}\n",
           source, g_n, t_odo.median, t_slam.median, t_slam.mean, t_slam.max, (long long)st.keyframes, feat_ms,
           loop_ms, (long long)st.optimisations, pgo_ms, reloc_ms, (long long)st2.stored_keyframes,
           t_slam.mean / t_odo.median, loop_ms / t_odo.median, reloc_ms / t_odo.median, m.ate_rmse,
           (long long)st.loops, t_now.max, t_slam.max / t_odo.median, t_now.max / t_odo.median);
    sooc_traj_free(&gt);
    sooc_traj_free(&est);
    sooc_frame_free(&g_f);
    sooc_seq_close(g_seq);
    free(ms);
    return 0;
}
