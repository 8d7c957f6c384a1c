/* `sooc3d eval` on recorded sequences, end to end through the binary
 * ($SOOC_BIN) with a tiny model:
 *  - a hand-made 7-Scenes-layout walk over a floor (64x48 frames, the model
 *    takes 32x32) with 16-bit labels in instance/ on its query frames: the
 *    JSON cell has the contract keys, "scale": "real", "view": "Q", the
 *    labelled ids, 2 query frames of 10; --panels writes a panel per query
 *    frame; a missing label file is an error naming it; mixing a recorded
 *    sequence with a gen dataset is a usage error;
 *  - label-fusion from ../shared/real (skipped when absent): segm.png labels
 *    give obj_ids [48, 132] over 3 query frames; the masks set's mask.png
 *    labels give one object, id 255. */
#include "../data/util.h"
#include "../cli_util.h"
#include "sooc3d/core.h"
#include "sooc3d/model.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <sys/wait.h>

/* Frame i of a walk along +z, camera 1.3 m up and pitched 25 deg down over a
 * checkered floor (y = 0; depth in mm, 0 beyond 6 m), 7-Scenes layout. */
static void write_frame(const char *dir, int i, int with_label) {
    enum { W = 64, H = 48 };
    const double f = 50, cx = W / 2.0, cy = H / 2.0, pitch = 25 * M_PI / 180;
    const double c[3] = {0.04 * i, 1.3, 0.12 * i};
    double s = sin(pitch), co = cos(pitch);
    double R[9] = {-1, 0, 0, 0, -co, -s, 0, -s, co}, T[16];
    sooc_se3_from_rt(T, R, c);
    sooc_image rgb, dep, lab;
    memset(&rgb, 0, sizeof rgb);
    memset(&dep, 0, sizeof dep);
    memset(&lab, 0, sizeof lab);
    CHECK_OK(sooc_image_alloc(&rgb, W, H, SOOC_PIX_RGB8));
    CHECK_OK(sooc_image_alloc(&dep, W, H, SOOC_PIX_GRAY16));
    CHECK_OK(sooc_image_alloc(&lab, W, H, SOOC_PIX_GRAY16));
    uint8_t *px = rgb.data;
    uint16_t *dz = dep.data, *id = lab.data;
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            size_t k = (size_t)v * W + u;
            double d[3] = {(u + 0.5 - cx) / f, (v + 0.5 - cy) / f, 1}, dw[3];
            sooc_se3_rotate(dw, T, d);
            double t = dw[1] < -1e-6 ? -c[1] / dw[1] : -1;
            double X = c[0] + t * dw[0], Z = c[2] + t * dw[2];
            int chk = t > 0 && (((int)floor(2 * X) + (int)floor(2 * Z)) & 1);
            dz[k] = (uint16_t)(t > 0 && t < 6 ? lround(t * 1000) + 1 : 0);   /* +1: not all multiples of 8 */
            px[3 * k] = (uint8_t)(chk ? 210 : 50), px[3 * k + 1] = 120, px[3 * k + 2] = (uint8_t)(chk ? 40 : 160);
            id[k] = (uint16_t)(t > 0 && X > 0.2 && X < 0.8 && Z > 2.0 && Z < 2.6 ? 300 : 0);   /* a floor patch */
        }
    char p[1024];
    snprintf(p, sizeof p, "%s/frame-%06d.color.png", dir, i);
    CHECK_OK(sooc_png_write(p, &rgb, 1));
    snprintf(p, sizeof p, "%s/frame-%06d.depth.png", dir, i);
    CHECK_OK(sooc_png_write(p, &dep, 1));
    if (with_label) {
        snprintf(p, sizeof p, "%s/instance/frame-%06d.png", dir, i);
        CHECK_OK(sooc_png_write(p, &lab, 1));
    }
    char name[64];
    snprintf(name, sizeof name, "frame-%06d.pose.txt", i);
    tu_write(dir, name, "%.9f %.9f %.9f %.9f\n%.9f %.9f %.9f %.9f\n%.9f %.9f %.9f %.9f\n0 0 0 1\n", T[0], T[1], T[2],
             T[3], T[4], T[5], T[6], T[7], T[8], T[9], T[10], T[11]);
    sooc_image_free(&rgb);
    sooc_image_free(&dep);
    sooc_image_free(&lab);
}

static void check_keys(const char *js, const char *what) {
    const char *keys[] = {"\"scale\": \"real\"", "\"view\": \"Q\"", "\"depth_rmse\": ", "\"rgb_rmse\": ",
                          "\"entries_final\": ", "\"entries_created\": ", "\"miou\": ", "\"obj_iou\": [",
                          "\"growth\": ", "\"pos_spread_m\": ", "\"yaw_spread_deg\": ", "\"free_frac\": ",
                          "\"never_seen_frac\": ", "\"entries_pass2\": "};
    for (size_t k = 0; k < sizeof keys / sizeof *keys; k++)
        CHECK_MSG(js && strstr(js, keys[k]), "%s: JSON lacks %s", what, keys[k]);
    CHECK_MSG(js && !strstr(js, "\"depth_rmse\": null") && !strstr(js, "\"rgb_rmse\": null"),
              "%s: RMSE not finite", what);
}

/* `sooc3d eval` on ../shared/real/label_fusion/data/<set> (skipped when absent):
 * its <kind>.png labels on the 3 query frames give the expected ids / views. */
static void eval_labelfusion(const char *bin, const char *model, const char *tmp, const char *real, const char *set,
                             const char *kind, const char *ids, const char *views) {
    char dir[1200], p[1400], cmd[4096];
    snprintf(dir, sizeof dir, "%s/label_fusion/data/%s", real ? real : "", set);
    snprintf(p, sizeof p, "%s/frame-000000.%s.png", dir, kind);
    if (!real || !sooc_file_exists(p)) {
        printf("test_eval_real_cli: label-fusion %s part SKIPPED: %s not found\n", set, p);
        return;
    }
    snprintf(cmd, sizeof cmd, "%s eval --model %s --name tiny --data %s --json %s/lf_%s.json --samples 16,0 --quiet",
             bin, model, dir, tmp, set);
    int rc = tc_run(cmd);
    CHECK_MSG(rc == 0, "eval on label-fusion %s: exit %d", set, rc);
    snprintf(p, sizeof p, "%s/lf_%s.json", tmp, set);
    char *js = tc_slurp(p);
    check_keys(js, set);
    CHECK_MSG(js && strstr(js, ids) && strstr(js, views) && strstr(js, "\"frames_query\": 3") &&
                  strstr(js, "\"frames_mapped\": 12"),
              "%s: %s", p, js ? js : "(missing)");
    sooc_free(js);
}

int main(void) {
    const char *bin = getenv("SOOC_BIN");
    if (!bin || access(bin, X_OK)) {
        printf("test_eval_real_cli: SKIP: SOOC_BIN not set or not executable\n");
        return SOOC_TEST_SKIP;
    }
    char *tmp = tu_tmpdir("evrealcli");
    char seq[600], model[600], cmd[4096], p[2600];
    snprintf(seq, sizeof seq, "%s/walk", tmp);
    snprintf(model, sizeof model, "%s/tiny.bin", tmp);
    snprintf(p, sizeof p, "%s/instance", seq);
    CHECK_OK(sooc_mkdirs(p));
    tu_write(seq, "camera-intrinsics.txt", "50 0 32\n0 50 24\n0 0 1\n");
    for (int i = 0; i < 10; i++) write_frame(seq, i, i % 5 == 2);   /* labels on the query frames only */
    tc_tiny_model(model);

    snprintf(cmd, sizeof cmd,
             "%s eval --model %s --name tiny --data %s --json %s/walk.json --md %s/walk.md --panels %s/pan "
             "--world identity --samples 16,0 --threads 1 --quiet > %s/out.txt 2>&1",
             bin, model, seq, tmp, tmp, tmp, tmp);
    int rc = tc_run(cmd);
    CHECK_MSG(rc == 0, "eval on a recorded sequence: exit %d", rc);
    snprintf(p, sizeof p, "%s/walk.json", tmp);
    char *js = tc_slurp(p);
    check_keys(js, "walk");
    CHECK_MSG(js && strstr(js, "\"model\": \"tiny\"") && strstr(js, "\"sequence\": \"walk\"") &&
                  strstr(js, "\"obj_ids\": [300]") && strstr(js, "\"frames\": 10") &&
                  strstr(js, "\"frames_mapped\": 8") && strstr(js, "\"frames_query\": 2") &&
                  strstr(js, "\"obj_views\": [2]"),
              "walk.json: %s", js ? js : "(missing)");
    sooc_free(js);
    snprintf(p, sizeof p, "%s/walk.md", tmp);
    char *md = tc_slurp(p);
    CHECK_MSG(md && strstr(md, "| tiny | walk | 8/2 |"), "walk.md: %s", md ? md : "(missing)");
    sooc_free(md);
    for (int k = 2; k < 10; k += 5) {
        snprintf(p, sizeof p, "%s/pan/walk/tiny/query_%06d.png", tmp, k);
        CHECK_MSG(sooc_file_exists(p), "%s missing", p);
    }
    snprintf(p, sizeof p, "%s/pan/walk/tiny/views.csv", tmp);
    char *csv = tc_slurp(p);
    int rows = 0;
    for (const char *q = csv; q && *q; q++) rows += *q == '\n';
    CHECK_MSG(rows == 3, "views.csv: %d lines", rows);
    sooc_free(csv);

    /* --finetune: a 'tiny+ft' cell after the base one (finetuned on the 8
     * mapped frames, scored on the 2 held-out ones, no second pass); the base
     * cell is the run above's */
    snprintf(cmd, sizeof cmd,
             "%s eval --model %s --name tiny --data %s --json %s/ft.json --md %s/ft.md --finetune --ft-iterations 40 "
             "--ft-rays 256 --world identity --samples 16,0 --threads 1 --quiet > %s/out_ft.txt 2>&1",
             bin, model, seq, tmp, tmp, tmp);
    rc = tc_run(cmd);
    CHECK_MSG(rc == 0, "eval --finetune on a recorded sequence: exit %d", rc);
    snprintf(p, sizeof p, "%s/ft.json", tmp);
    js = tc_slurp(p);
    const char *ftc = js ? strstr(js, "\"model\": \"tiny+ft\"") : NULL;
    CHECK_MSG(ftc != NULL, "ft.json has no tiny+ft cell: %s", js ? js : "(missing)");
    if (ftc) {
        check_keys(ftc, "tiny+ft");
        CHECK(strstr(ftc, "\"finetuned\": true") && strstr(ftc, "\"ft_iterations\": 40") &&
              strstr(ftc, "\"second_pass\": 0") && strstr(ftc, "\"growth\": null"));
        const char *base = strstr(js, "\"model\": \"tiny\"");
        CHECK(base && base < ftc && strstr(base, "\"finetuned\": false"));
        double d0 = NAN, d1 = NAN;
        const char *q = base ? strstr(base, "\"depth_rmse\": ") : NULL;
        if (q) d0 = atof(q + 14);
        q = strstr(ftc, "\"depth_rmse\": ");
        if (q) d1 = atof(q + 14);
        printf("finetune on the walk: held-out depth RMSE %.4f -> %.4f m\n", d0, d1);
        /* the finetuned decoders are what renders the +ft cell (2.58 -> 2.06 m when written) */
        CHECK_MSG(isfinite(d0) && isfinite(d1) && d1 < 0.95 * d0, "depth RMSE %g -> %g", d0, d1);
    }
    sooc_free(js);
    snprintf(p, sizeof p, "%s/ft.md", tmp);
    md = tc_slurp(p);
    CHECK_MSG(md && strstr(md, "| tiny | walk | 8/2 |") && strstr(md, "| tiny+ft | walk | 8/2 |"), "ft.md: %s",
              md ? md : "(missing)");
    sooc_free(md);

    /* a query frame without its label file: an error naming the file */
    snprintf(p, sizeof p, "%s/instance/frame-000007.png", seq);
    CHECK(remove(p) == 0);
    snprintf(cmd, sizeof cmd, "%s eval --model %s --data %s --json %s/x.json --world identity --quiet > %s/err.txt 2>&1",
             bin, model, seq, tmp, tmp);
    CHECK(tc_run(cmd) == 1);
    snprintf(p, sizeof p, "%s/err.txt", tmp);
    char *err = tc_slurp(p);
    CHECK_MSG(err && strstr(err, "frame-000007.png"), "error: %s", err ? err : "");
    sooc_free(err);
    /* mixing a recorded sequence with a gen dataset, bad option values */
    snprintf(p, sizeof p, "%s/gen/scene_0000", tmp);
    CHECK_OK(sooc_mkdirs(p));
    snprintf(cmd, sizeof cmd, "%s eval --model %s --data %s %s/gen --json %s/x.json 2>/dev/null", bin, model, seq, tmp,
             tmp);
    CHECK(tc_run(cmd) == 2);
    snprintf(cmd, sizeof cmd, "%s eval --model %s --data %s --json %s/x.json --query-every 1 2>/dev/null", bin, model,
             seq, tmp);
    CHECK(tc_run(cmd) == 2);
    snprintf(cmd, sizeof cmd, "%s eval --model %s --data %s --json %s/x.json --runs 2 2>/dev/null", bin, model, seq, tmp);
    CHECK(tc_run(cmd) == 2);

    /* the TUM layout with instance/ on every frame (read by the sequence
     * reader): the walk rewritten by sooc_seq_writer, ids 5 on the left third */
    {
        char tum[700];
        snprintf(tum, sizeof tum, "%s/tumwalk", tmp);
        sooc_seq *sq = NULL;
        sooc_seq_writer *w = NULL;
        sooc_frame f;
        memset(&f, 0, sizeof f);
        CHECK_OK(sooc_seq_open(&sq, seq, NULL));
        sooc_calib cal;
        sooc_calib_pinhole(&cal, 64, 48, 50, 50, 32, 24);
        cal.depth_scale = 0.001;
        if (sq) CHECK_OK(sooc_seq_writer_create(&w, tum, &cal, sooc_seq_count(sq)));
        for (int64_t i = 0; sq && w && i < sooc_seq_count(sq); i++) {
            CHECK_OK(sooc_seq_read(sq, i, &f));
            if (!f.instance) f.instance = sooc_calloc((size_t)f.width * f.height, sizeof *f.instance);
            for (int k = 0; f.instance && k < f.width * f.height; k++) f.instance[k] = (uint16_t)(k % f.width < 21 ? 5 : 0);
            f.t_ns = i * 100000000LL;
            CHECK_OK(sooc_seq_writer_put(w, i, &f));
        }
        if (w) CHECK_OK(sooc_seq_writer_finish(w));
        sooc_seq_writer_destroy(w);
        sooc_seq_close(sq);
        sooc_frame_free(&f);
        snprintf(cmd, sizeof cmd, "%s eval --model %s --name tiny --data %s --json %s/tum.json --world identity "
                 "--samples 16,0 --quiet", bin, model, tum, tmp);
        rc = tc_run(cmd);
        CHECK_MSG(rc == 0, "eval on a TUM-layout sequence: exit %d", rc);
        snprintf(p, sizeof p, "%s/tum.json", tmp);
        js = tc_slurp(p);
        check_keys(js, "tum");
        CHECK_MSG(js && strstr(js, "\"obj_ids\": [5]") && strstr(js, "\"obj_views\": [2]") &&
                      strstr(js, "\"sequence\": \"tumwalk\""),
                  "tum.json: %s", js ? js : "(missing)");
        sooc_free(js);
    }

    /* label-fusion: the labels set (segm.png, two objects) and the masks set
     * (mask.png, one object, id 255) */
    const char *real = tu_real_dir();
    eval_labelfusion(bin, model, tmp, real, "labels", "segm",
                     "\"obj_ids\": [48, 132]", "\"obj_views\": [3, 3]");
    eval_labelfusion(bin, model, tmp, real, "masks", "mask", "\"obj_ids\": [255]", "\"obj_views\": [3]");
    tu_rm_rf(tmp);
    return check_report("test_eval_real_cli");
}
