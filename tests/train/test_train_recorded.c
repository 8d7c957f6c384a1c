/* Training from recordings (docs/training.md "Training from
 * recordings"). A generated scene is rewritten as a recorded sequence (TUM
 * layout, no scene.yaml, poses in a tilted source frame, a hole punched in
 * every depth image) and loaded through sooc_dataset_open_rec:
 *   - the frames `sooc3d eval` holds out (sooc_eval_real_is_query) are
 *     flagged and never returned by sooc_dataset_sample, in either mode, for
 *     any segment length or query count;
 *   - consecutive input views and each query against every input view of its
 *     segment keep the minimum baseline (view_min_cm or view_min_deg);
 *   - the support-plane world frame is stored in world_dir and reused by the
 *     next open (identical poses);
 *   - sensor holes stay invalid (valid = 0) through the frame path;
 *   - synthetic and recorded scenes mix in one training run (recorded_frac);
 *   - `sooc3d train --init M --max-seconds S` stops on the budget with a
 *     loadable last.bin (runs $SOOC_BIN; skipped without it).
 */
#include "check.h"
#include "cli_util.h"
#include "sooc3d/eval.h"
#include "sooc3d/frame.h"
#include "sooc3d/gen.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/train.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char g_dir[256];
#define N_VIEWS 30
#define HOLE 6   /* a HOLE x HOLE block of invalid depth (raw 0) in every frame */

/* The recorded copy of a synthetic scene: poses in a source frame rotated
 * and shifted away from the world (so the support plane must be estimated),
 * depth zeroed in a block (a sensor hole). */
static void write_recorded(const char *scene, const char *dir) {
    sooc_seq *sq = NULL;
    CHECK_OK(sooc_seq_open(&sq, scene, NULL));
    if (!sq) return;
    int64_t n = sooc_seq_count(sq);
    sooc_seq_writer *w = NULL;
    CHECK_OK(sooc_seq_writer_create(&w, dir, sooc_seq_calib(sq), n));
    double A[16], R[9] = {1, 0, 0, 0, 0, -1, 0, 1, 0}, t[3] = {1.5, -0.7, 2.0};
    sooc_se3_from_rt(A, R, t);
    sooc_frame f;
    memset(&f, 0, sizeof f);
    for (int64_t i = 0; i < n && w; i++) {
        CHECK_OK(sooc_seq_read(sq, i, &f));
        double T[16];
        sooc_se3_mul(T, A, f.T_wc);
        memcpy(f.T_wc, T, sizeof T);
        f.is_query = 0;
        for (int y = 10; y < 10 + HOLE; y++)
            for (int x = 20; x < 20 + HOLE; x++) {
                f.depth[(size_t)y * (size_t)f.width + (size_t)x] = 0;
                f.valid[(size_t)y * (size_t)f.width + (size_t)x] = 0;
            }
        CHECK_OK(sooc_seq_writer_put(w, i, &f));
    }
    if (w) CHECK_OK(sooc_seq_writer_finish(w));
    sooc_seq_writer_destroy(w);
    sooc_frame_free(&f);
    sooc_seq_close(sq);
}

/* The dataset view a sampled (shallow) frame is, by its pixel buffer; -1 if none. */
static int view_of(const sooc_dataset *d, int s, const sooc_frame *f) {
    for (int v = 0; v < sooc_dataset_n_views(d, s); v++)
        if (sooc_dataset_view(d, s, v)->rgb == f->rgb) return v;
    return -1;
}

static int distinct(const sooc_frame *a, const sooc_frame *b, double cm, double deg) {
    const double *A = a->T_wc, *B = b->T_wc;
    double dx = A[3] - B[3], dy = A[7] - B[7], dz = A[11] - B[11];
    double c = A[2] * B[2] + A[6] * B[6] + A[10] * B[10];
    c = c > 1 ? 1 : c < -1 ? -1 : c;
    return 100 * sqrt(dx * dx + dy * dy + dz * dz) >= cm - 1e-9 || acos(c) * 180 / M_PI >= deg - 1e-9;
}

static void test_rule(const char *rec, const char *synth) {
    char world[512];
    snprintf(world, sizeof world, "%s/world", g_dir);
    sooc_framepath_params fpp;
    sooc_framepath_params_default(&fpp);
    fpp.width = fpp.height = 32;
    sooc_dataset_rec_params rp;
    sooc_dataset_rec_params_default(&rp);
    CHECK(rp.view_min_cm == SOOC_DATASET_VIEW_MIN_CM && rp.view_min_deg == SOOC_DATASET_VIEW_MIN_DEG &&
          rp.held_out_every == SOOC_REAL_QUERY_EVERY);
    rp.world_dir = world;
    const char *dirs[2] = {rec, synth};
    sooc_dataset *d = NULL;
    CHECK_OK(sooc_dataset_open_rec(&d, dirs, 2, &fpp, &rp));
    if (!d) return;
    CHECK(sooc_dataset_n_scenes(d) == 2 && sooc_dataset_n_recorded(d) == 1);
    CHECK(sooc_dataset_scene_recorded(d, 0) && !sooc_dataset_scene_recorded(d, 1));
    int nv = sooc_dataset_n_views(d, 0), n_held = 0;
    CHECK(nv == N_VIEWS);
    /* the held-out flags are eval's rule on the sequence position */
    for (int v = 0; v < nv; v++) {
        const sooc_frame *f = sooc_dataset_view(d, 0, v);
        CHECK_MSG(f->is_query == sooc_eval_real_is_query(v, SOOC_REAL_QUERY_EVERY), "view %d is_query %d", v,
                  f->is_query);
        n_held += f->is_query;
        /* the hole stays invalid (32x32 is the 64x64 frame halved: rows 5-7, columns 10-12) */
        for (int y = 5; y < 8; y++)
            for (int x = 10; x < 13; x++) CHECK(!f->valid[y * 32 + x]);
    }
    CHECK(n_held == N_VIEWS / 5);
    /* inputs: a keyframe chain with the baseline; fewer than the non-held frames */
    int ni = sooc_dataset_n_inputs(d, 0);
    CHECK(ni >= 2 && ni <= N_VIEWS - n_held);
    /* thousands of draws: never a held-out frame; baselines kept */
    int drawn[N_VIEWS] = {0}, n_q = 0, n_far = 0;
    sooc_frame views[8], q[4];
    for (int it = 0; it < 400; it++) {
        sooc_rng rng;
        sooc_rng_seed(&rng, 11, (uint64_t)it);
        int T = 1 + it % 5, Q = 1 + it % 3, mode = (it / 5) % 2, n_v = 0, n_qq = 0;
        sooc_dataset_sample(d, 0, T, Q, mode, &rng, views, &n_v, q, &n_qq);
        CHECK(n_v == (T < ni ? T : ni) && n_qq <= Q);
        for (int t = 0; t < n_v; t++) {
            int v = view_of(d, 0, &views[t]);
            CHECK_MSG(v >= 0 && !sooc_eval_real_is_query(v, SOOC_REAL_QUERY_EVERY), "input view %d is held out", v);
            if (v >= 0) drawn[v]++;
            if (t) CHECK(distinct(&views[t], &views[t - 1], rp.view_min_cm, rp.view_min_deg));
        }
        for (int k = 0; k < n_qq; k++) {
            int v = view_of(d, 0, &q[k]);
            CHECK_MSG(v >= 0 && !sooc_eval_real_is_query(v, SOOC_REAL_QUERY_EVERY), "query view %d is held out", v);
            if (v >= 0) drawn[v]++;
            for (int t = 0; t < n_v; t++) {
                CHECK(distinct(&q[k], &views[t], rp.view_min_cm, rp.view_min_deg));
                CHECK(q[k].rgb != views[t].rgb);
            }
            n_q++;
        }
    }
    for (int v = 0; v < N_VIEWS; v++)
        if (sooc_eval_real_is_query(v, SOOC_REAL_QUERY_EVERY)) CHECK_MSG(!drawn[v], "held-out view %d drawn", v);
    CHECK_MSG(n_q > 300, "%d query views over 400 draws", n_q);
    /* a larger baseline leaves fewer inputs */
    sooc_dataset_rec_params rp2 = rp;
    rp2.view_min_cm = 200, rp2.view_min_deg = 90;
    sooc_dataset *d2 = NULL;
    CHECK_OK(sooc_dataset_open_rec(&d2, dirs, 1, &fpp, &rp2));
    if (d2) CHECK_MSG(sooc_dataset_n_inputs(d2, 0) < ni, "inputs %d at 200 cm / 90 deg, %d at 5 / 5",
                      sooc_dataset_n_inputs(d2, 0), ni);
    sooc_dataset_destroy(d2);
    (void)n_far;
    /* the world frame was stored and the next open reuses it */
    DIR *dp = opendir(world);
    char db[1024] = "";
    struct dirent *e;
    while (dp && (e = readdir(dp)))
        if (!strncmp(e->d_name, "world_", 6) && strlen(e->d_name) > 7 &&
            !strcmp(e->d_name + strlen(e->d_name) - 7, ".sqlite"))
            snprintf(db, sizeof db, "%s/%s", world, e->d_name);
    if (dp) closedir(dp);
    CHECK_MSG(db[0], "no world_*.sqlite in %s", world);
    if (db[0]) {
        sooc_mapstore *ms = NULL;
        sooc_mapstore_params mp;
        sooc_mapstore_params_default(&mp);
        mp.create = 0;
        CHECK_OK(sooc_mapstore_open(&ms, db, &mp));
        sooc_map_frame mf;
        int found = 0;
        if (ms) CHECK_OK(sooc_mapstore_frame_get(ms, &mf, &found));
        CHECK(found && fabs(mf.cam_height_m) > 0.3);
        /* tamper: a stored frame shifted 1 m along up moves every camera by 1 m in y */
        if (found) {
            mf.T_world_src[7] += 1.0;
            CHECK_OK(sooc_mapstore_frame_put(ms, &mf));
        }
        sooc_mapstore_close(ms);
        sooc_dataset *d3 = NULL;
        CHECK_OK(sooc_dataset_open_rec(&d3, dirs, 1, &fpp, &rp));
        if (d3) {
            double dy = sooc_dataset_view(d3, 0, 3)->T_wc[7] - sooc_dataset_view(d, 0, 3)->T_wc[7];
            CHECK_MSG(fabs(dy - 1.0) < 1e-9, "stored frame not reused: camera moved %g m", dy);
        }
        sooc_dataset_destroy(d3);
    }
    /* the scene pick: recorded_frac 0 is the plain uniform draw; 0.5 draws both */
    int n_rec = 0;
    for (int it = 0; it < 2000; it++) {
        sooc_rng a, b;
        sooc_rng_seed(&a, 2, (uint64_t)it);
        sooc_rng_seed(&b, 2, (uint64_t)it);
        CHECK(sooc_dataset_pick(d, 0, &a) == (int)sooc_rng_below(&b, 2));
        n_rec += sooc_dataset_scene_recorded(d, sooc_dataset_pick(d, 0.8, &a));
    }
    CHECK_MSG(n_rec > 1500 && n_rec < 1700, "recorded_frac 0.8: %d of 2000 draws recorded", n_rec);
    /* bad parameters are errors */
    sooc_dataset *bad = NULL;
    rp2 = rp;
    rp2.held_out_every = 1;
    CHECK(sooc_dataset_open_rec(&bad, dirs, 1, &fpp, &rp2) == SOOC_EINVAL && !bad);
    rp2 = rp;
    rp2.view_min_deg = -1;
    CHECK(sooc_dataset_open_rec(&bad, dirs, 1, &fpp, &rp2) == SOOC_EINVAL && !bad);
    sooc_clearerr();

    /* one training run over both kinds (recorded_frac 0.5) */
    sooc_train_config c;
    sooc_model_config mc;
    sooc_train_config_default(&c);
    sooc_model_config_default(&mc);
    mc.K = 3, mc.d_what = 8, mc.d_layout = 4, mc.L = 1;
    mc.img_w = mc.img_h = 32;
    mc.ray_w = mc.ray_h = 16;
    mc.dec_width = 16, mc.dec_color_width = 8;
    mc.ref_ch[0] = mc.ref_ch[1] = mc.ref_ch[2] = mc.ref_ch[3] = 8;
    mc.ref_fc = 16, mc.ref_hidden = 16;
    mc.invalid_depth = 1;
    c.steps = 8, c.warmup = 2, c.kl_warmup = 0, c.log_every = 1, c.ckpt_every = 100, c.val_every = 0;
    c.threads = 1, c.recorded_frac = 0.5f, c.t_max_b = 3, c.t_max_c = 3;
    char out[512];
    snprintf(out, sizeof out, "%s/mixed", g_dir);
    sooc_train_run_params p;
    memset(&p, 0, sizeof p);
    p.out_dir = out;
    p.train = d;
    CHECK_OK(sooc_train_run(&c, &mc, &p));
    char path[600];
    snprintf(path, sizeof path, "%s/last.bin", out);
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_load(&m, path, NULL, NULL));
    sooc_model_destroy(m);
    snprintf(path, sizeof path, "%s/log.csv", out);
    char *log = tc_slurp(path);
    int rows = 0;
    for (char *s = log; s && *s; s++) rows += *s == '\n';
    CHECK_MSG(rows == 9, "log rows %d, expected 9", rows);
    sooc_free(log);
    sooc_dataset_destroy(d);
}

/* `sooc3d train --init M --max-seconds S` on the recorded + synthetic pair. */
static void test_cli(const char *rec, const char *synth) {
    const char *bin = getenv("SOOC_BIN");
    if (!bin || access(bin, X_OK) != 0) {
        printf("SKIP test_cli: SOOC_BIN not set or not executable\n");
        return;
    }
    char cfg[512], init[512], out[512], cmd[4096], path[700];
    snprintf(cfg, sizeof cfg, "%s/tiny.yaml", g_dir);
    snprintf(init, sizeof init, "%s/tiny.bin", g_dir);
    snprintf(out, sizeof out, "%s/budget", g_dir);
    tc_tiny_model(init);
    FILE *f = fopen(cfg, "w");
    CHECK(f != NULL);
    if (!f) return;
    fprintf(f, "steps: 1000000\nwarmup: 10\nkl_warmup: 0\nlog_every: 1\nckpt_every: 1000000\nval_every: 0\n"
               "threads: 1\nrecorded_frac: 0.5\nview_min_cm: 5\nview_min_deg: 5\nlr: 1e-5\n"
               "model:\n  K: 3\n  d_what: 8\n  d_layout: 4\n  L: 1\n  img_w: 32\n  img_h: 32\n  ray_w: 16\n"
               "  ray_h: 16\n  dec_width: 16\n  dec_color_width: 8\n  ref_ch: [8, 8, 8, 8]\n  ref_fc: 16\n"
               "  ref_hidden: 16\n");
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s train --config %s --init %s --data %s %s --out %s --max-seconds 2 >%s/budget.txt 2>&1",
             bin, cfg, init, rec, synth, out, g_dir);
    CHECK(tc_run(cmd) == 0);
    snprintf(path, sizeof path, "%s/last.bin", out);
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_load(&m, path, NULL, NULL));
    /* the model keeps the camera heights of its training views (config
     * cam_h_min / cam_h_max), the range the run printed, not the default */
    snprintf(path, sizeof path, "%s/budget.txt", g_dir);
    char *txt = tc_slurp(path);
    const char *hl = txt ? strstr(txt, "training cameras ") : NULL;
    double lo = 0, hi = 0, mlo = 0, mhi = 0;
    CHECK_MSG(hl && sscanf(hl, "training cameras %lf-%lf", &lo, &hi) == 2, "no camera-height line: %s",
              txt ? txt : "");
    if (m) sooc_model_cam_heights_m(sooc_model_get_config(m), &mlo, &mhi);
    CHECK_MSG(fabs(mlo - lo) < 0.006 && fabs(mhi - hi) < 0.006 && lo > 0 && hi > lo && !(lo == 1.2 && hi == 2.0),
              "stored %g-%g m, printed %g-%g m", mlo, mhi, lo, hi);
    sooc_free(txt);
    sooc_model_destroy(m);
    /* it stopped on the budget: far fewer than the 1,000,000 steps, at least one */
    snprintf(path, sizeof path, "%s/log.csv", out);
    char *log = tc_slurp(path);
    int rows = 0;
    for (char *s = log; s && *s; s++) rows += *s == '\n';
    CHECK_MSG(rows >= 2 && rows < 1000000, "log rows %d", rows);
    sooc_free(log);
    /* the world frame of the recording was kept in OUT/world */
    snprintf(path, sizeof path, "%s/world", out);
    CHECK(sooc_dir_exists(path));
    /* a bad key value is refused naming the key */
    f = fopen(cfg, "a");
    if (f) {
        fprintf(f, "view_min_deg: 400\n");
        fclose(f);
    }
    snprintf(cmd, sizeof cmd, "%s train --config %s --data %s --out %s_bad 2>&1 | grep -q view_min_deg", bin, cfg,
             rec, out);
    CHECK(tc_run(cmd) == 0);
}

int main(void) {
    snprintf(g_dir, sizeof g_dir, "/tmp/sooc_train_rec_XXXXXX");
    if (!mkdtemp(g_dir)) return 1;
    char data[512], scene[600], rec[600];
    snprintf(data, sizeof data, "%s/data", g_dir);
    snprintf(scene, sizeof scene, "%s/scene_0000", data);
    snprintf(rec, sizeof rec, "%s/recorded", g_dir);
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.preset = SOOC_GEN_UNITY;
    gp.scale = SOOC_GEN_S;
    gp.seed = 7;
    gp.n_scenes = 1;
    gp.n_views = N_VIEWS - 4;
    gp.n_query = 4;
    gp.write_meshes = 0;
    gp.contact_sheet = 0;
    CHECK_OK(sooc_gen_run(&gp, data, NULL, NULL, NULL));
    write_recorded(scene, rec);
    test_rule(rec, scene);
    test_cli(rec, scene);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", g_dir);
    if (!g_check_fail && !getenv("SOOC_KEEP_TMP") && system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
    return check_report("test_train_recorded");
}
