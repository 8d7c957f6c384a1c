/* The one frame path (include/sooc3d/frame.h) on a generated scene:
 *  - frames of another size and aspect are cropped/resized to the target:
 *    depth stays valid (the old [0, 0] range emptied every resized frame),
 *    intrinsics follow the crop, ids follow by nearest sampling, poses are
 *    untouched (scene.yaml: identity world);
 *  - the same scene written as a recorded sequence in another frame (up = +z,
 *    shifted, no scene.yaml): the support-plane estimate puts the cameras
 *    back at their heights over the floor, and a world frame stored in a map
 *    database is taken over the estimate;
 *  - the same preprocessing as the node's mapping thread (launch defaults);
 *  - bad options fail with a message naming the problem. */
#include "check.h"
#include "sooc3d/frame.h"
#include "sooc3d/node.h"
#include "sooc3d/gen.h"
#include "sooc3d/cogmap.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char g_tmp[256];

static double valid_frac(const sooc_frame *f) {
    size_t n = (size_t)f->width * f->height, v = 0;
    for (size_t i = 0; i < n; i++) v += f->valid[i] != 0;
    return n ? (double)v / (double)n : 0;
}

/* Synthetic scene at 80x60 read at 32x32: crop 60x60 at x0 = 10. */
static void test_resize(const char *scene) {
    sooc_framepath_params p;
    sooc_framepath_params_default(&p);
    p.width = p.height = 32;
    sooc_framepath *fp = NULL;
    CHECK_OK(sooc_framepath_open(&fp, scene, &p));
    if (!fp) return;
    double T[16];
    CHECK(sooc_framepath_world_get(fp, T) == SOOC_WORLD_IDENTITY);
    CHECK(sooc_framepath_synthetic(fp) == 1);
    CHECK(T[0] == 1 && T[5] == 1 && T[10] == 1 && T[3] == 0 && T[7] == 0);
    sooc_seq *sq = NULL;
    CHECK_OK(sooc_seq_open(&sq, scene, NULL));
    sooc_frame raw, f, old;
    memset(&raw, 0, sizeof raw);
    memset(&f, 0, sizeof f);
    memset(&old, 0, sizeof old);
    uint16_t ids[32 * 32];
    int64_t n = sooc_framepath_count(fp);
    CHECK(n == sooc_seq_count(sq) && n >= 4);
    for (int64_t i = 0; i < n && sq; i++) {
        CHECK_OK(sooc_seq_read(sq, i, &raw));
        CHECK_OK(sooc_framepath_read(fp, i, &f));
        CHECK(f.width == 32 && f.height == 32 && raw.width == 80 && raw.height == 60);
        double vr = valid_frac(&raw), vf = valid_frac(&f);
        CHECK_MSG(vr > 0.5 && vf > 0.9 * vr, "frame %lld: valid fraction %.3f resized, %.3f raw", (long long)i, vf, vr);
        /* the render bug: a [0, 0] depth range must not empty the frame */
        CHECK_OK(sooc_frames_preprocess(&raw, &old, 32, 32, SOOC_FRAMES_DEPTH_NEAREST, 0.0, 0.0));
        CHECK_MSG(valid_frac(&old) > 0.9 * vr, "frame %lld: [0,0] range leaves %.3f valid", (long long)i,
                  valid_frac(&old));
        double s = 32.0 / 60.0;
        CHECK_CLOSE(f.K.fx, raw.K.fx * s, 1e-9, 1e-9);
        CHECK_CLOSE(f.K.fy, raw.K.fy * s, 1e-9, 1e-9);
        CHECK_CLOSE(f.K.cx, (raw.K.cx - 10) * s, 1e-9, 1e-9);
        CHECK_CLOSE(f.K.cy, raw.K.cy * s, 1e-9, 1e-9);
        CHECK(f.K.width == 32 && f.K.height == 32);
        CHECK(f.has_pose == raw.has_pose && f.is_query == raw.is_query && f.index == raw.index);
        for (int k = 0; k < 16; k++) CHECK(f.T_wc[k] == raw.T_wc[k]);
        /* ids: nearest sampling of the same crop, also through resize_ids */
        CHECK(f.instance != NULL && raw.instance != NULL);
        if (f.instance && raw.instance) {
            CHECK_OK(sooc_framepath_resize_ids(fp, raw.instance, raw.width, raw.height, ids));
            CHECK(memcmp(ids, f.instance, sizeof ids) == 0);
            int x = 16, y = 16;   /* centre: source pixel (10 + floor(16.5 * 60 / 32), floor(16.5 * 60 / 32)) */
            int sx = 10 + (int)floor(16.5 * 60 / 32), sy = (int)floor(16.5 * 60 / 32);
            CHECK(f.instance[y * 32 + x] == raw.instance[sy * 80 + sx]);
        }
    }
    CHECK(sooc_framepath_empty_depth(fp) == 0);
    CHECK(sooc_framepath_resize_ids(fp, ids, 10, 10, ids) == SOOC_EINVAL);
    sooc_frame_free(&raw);
    sooc_frame_free(&f);
    sooc_frame_free(&old);
    sooc_seq_close(sq);
    sooc_framepath_close(fp);
}

/* A: the recorded sequence's frame from the scene's world (up +y -> +z, shifted). */
static void make_A(double A[16]) {
    double R[9] = {1, 0, 0, 0, 0, -1, 0, 1, 0};   /* y -> z, z -> -y */
    double t[3] = {1.5, -0.7, 2.0};
    sooc_se3_from_rt(A, R, t);
}

static void write_recorded(const char *scene, const char *dir) {
    sooc_seq *sq = NULL;
    CHECK_OK(sooc_seq_open(&sq, scene, NULL));
    if (!sq) return;
    int64_t n = sooc_seq_count(sq);
    sooc_seq_writer *w = NULL;
    CHECK_OK(sooc_seq_writer_create(&w, dir, sooc_seq_calib(sq), n));
    double A[16];
    make_A(A);
    sooc_frame f;
    memset(&f, 0, sizeof f);
    for (int64_t i = 0; i < n && w; i++) {
        CHECK_OK(sooc_seq_read(sq, i, &f));
        double T[16];
        sooc_se3_mul(T, A, f.T_wc);
        memcpy(f.T_wc, T, sizeof T);
        f.is_query = 0;
        CHECK_OK(sooc_seq_writer_put(w, i, &f));
    }
    if (w) CHECK_OK(sooc_seq_writer_finish(w));
    sooc_seq_writer_destroy(w);
    sooc_frame_free(&f);
    sooc_seq_close(sq);
}

/* Camera heights over the floor in the world the frame path gives, against
 * the scene's own (floor at y = 0). */
static double max_height_err(sooc_framepath *fp, const char *scene) {
    sooc_seq *sq = NULL;
    CHECK_OK(sooc_seq_open(&sq, scene, NULL));
    if (!sq) return INFINITY;
    sooc_frame a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    double err = 0;
    for (int64_t i = 0; i < sooc_seq_count(sq); i++) {
        CHECK_OK(sooc_seq_read(sq, i, &a));
        CHECK_OK(sooc_framepath_read(fp, i, &b));
        err = fmax(err, fabs(a.T_wc[7] - b.T_wc[7]));
        /* the camera's own up (its -y axis) keeps its angle with the world's +y */
        err = fmax(err, fabs(a.T_wc[5] - b.T_wc[5]));
    }
    sooc_frame_free(&a);
    sooc_frame_free(&b);
    sooc_seq_close(sq);
    return err;
}

static void test_recorded(const char *scene, const char *rec) {
    double A[16];
    make_A(A);
    sooc_framepath_params p;
    sooc_framepath_params_default(&p);
    p.width = p.height = 32;
    p.has_up = 1;
    p.up[0] = 0, p.up[1] = 0, p.up[2] = 1;   /* the hint a user gives with --up 0,0,1 */
    sooc_framepath *fp = NULL;
    CHECK_OK(sooc_framepath_open(&fp, rec, &p));
    if (fp) {
        CHECK(sooc_framepath_synthetic(fp) == 0);
        CHECK(sooc_framepath_world_get(fp, NULL) == SOOC_WORLD_ESTIMATE);
        sooc_framepath_support_info si;
        CHECK(sooc_framepath_support(fp, &si) == 1);
        CHECK_MSG(si.up_src[2] > 0.999, "up (%.4f %.4f %.4f)", si.up_src[0], si.up_src[1], si.up_src[2]);
        double e = max_height_err(fp, scene);
        CHECK_MSG(e < 0.03, "camera heights / tilts differ by up to %.4f from the scene's", e);
        /* the record for the map database */
        double T[16], up[3], pl[4], h;
        int src;
        sooc_framepath_frame_record(fp, T, up, pl, &h, &src);
        CHECK(src == 0 /* SOOC_UP_GIVEN */ && up[2] > 0.999 && h > 0.5);
        sooc_framepath_close(fp);
    }
    /* identity world: the poses as recorded */
    p.world = SOOC_WORLD_IDENTITY;
    CHECK_OK(sooc_framepath_open(&fp, rec, &p));
    if (fp) {
        sooc_frame f;
        memset(&f, 0, sizeof f);
        CHECK_OK(sooc_framepath_read(fp, 0, &f));
        sooc_seq *sq = NULL;
        CHECK_OK(sooc_seq_open(&sq, rec, NULL));
        sooc_frame r;
        memset(&r, 0, sizeof r);
        if (sq) CHECK_OK(sooc_seq_read(sq, 0, &r));
        for (int k = 0; k < 16; k++) CHECK(f.T_wc[k] == r.T_wc[k]);
        sooc_frame_free(&f);
        sooc_frame_free(&r);
        sooc_seq_close(sq);
        sooc_framepath_close(fp);
    }
    /* a stored world frame (inverse of A) wins over an estimate */
    char db[512];
    snprintf(db, sizeof db, "%s/map.sqlite", g_tmp);
    sooc_mapstore *ms = NULL;
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.dim = 8;
    CHECK_OK(sooc_mapstore_open(&ms, db, &mp));
    sooc_map_frame mf;
    memset(&mf, 0, sizeof mf);
    sooc_se3_inverse(mf.T_world_src, A);
    mf.up_src[2] = 1;
    mf.plane_src[2] = 1, mf.plane_src[3] = 0.7;
    mf.cam_height_m = 1.5;
    mf.up_source = 0;   /* SOOC_UP_GIVEN */
    if (ms) CHECK_OK(sooc_mapstore_frame_put(ms, &mf));
    sooc_mapstore_close(ms);
    p.world = SOOC_WORLD_AUTO;
    p.has_up = 0;
    p.map_db = db;
    CHECK_OK(sooc_framepath_open(&fp, rec, &p));
    if (fp) {
        CHECK(sooc_framepath_world_get(fp, NULL) == SOOC_WORLD_STORED);
        sooc_framepath_support_info si;
        CHECK(sooc_framepath_support(fp, &si) == 0);
        double e = max_height_err(fp, scene);
        CHECK_MSG(e < 1e-4, "stored frame: poses differ by %.6f", e);
        sooc_framepath_close(fp);
    }
    /* STORED without a stored frame fails and says so */
    p.map_db = NULL;
    p.world = SOOC_WORLD_STORED;
    CHECK(sooc_framepath_open(&fp, rec, &p) == SOOC_ENOTFOUND && fp == NULL);
    CHECK_MSG(strstr(sooc_errmsg(), "no world frame stored") != NULL, "%s", sooc_errmsg());
}

/* The node's mapping thread and the commands preprocess alike: the frame
 * path's defaults are a launch file's (pipeline.min/max_depth_m,
 * model.depth_resample), and a frame read through the frame path equals
 * sooc_frames_preprocess of the reader's frame with those settings. */
static void test_same_as_node(const char *scene) {
    sooc_node_config c;
    sooc_node_config_default(&c);
    sooc_framepath_params p;
    sooc_framepath_params_default(&p);
    CHECK(p.min_depth_m == c.min_depth_m && p.max_depth_m == c.max_depth_m && p.resample == c.depth_resample);
    p.width = 40, p.height = 30;
    sooc_framepath *fp = NULL;
    sooc_seq *sq = NULL;
    CHECK_OK(sooc_framepath_open(&fp, scene, &p));
    CHECK_OK(sooc_seq_open(&sq, scene, NULL));
    sooc_frame raw, a, b;
    memset(&raw, 0, sizeof raw);
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    if (fp && sq) {
        CHECK_OK(sooc_framepath_read(fp, 1, &a));
        CHECK_OK(sooc_seq_read(sq, 1, &raw));
        CHECK_OK(sooc_frames_preprocess(&raw, &b, 40, 30, c.depth_resample, c.min_depth_m, c.max_depth_m));
        CHECK(a.width == b.width && a.height == b.height && a.width == 40);
        if (a.width == b.width && a.height == b.height) {
            size_t np = (size_t)a.width * a.height;
            CHECK(memcmp(a.rgb, b.rgb, 3 * np) == 0 && memcmp(a.depth, b.depth, np * sizeof(float)) == 0 &&
                  memcmp(a.valid, b.valid, np) == 0);
            CHECK(a.K.fx == b.K.fx && a.K.cx == b.K.cx && a.K.cy == b.K.cy);
        }
    }
    sooc_frame_free(&raw);
    sooc_frame_free(&a);
    sooc_frame_free(&b);
    sooc_seq_close(sq);
    sooc_framepath_close(fp);
}

static void test_bad(const char *scene) {
    sooc_framepath_params p;
    sooc_framepath *fp = (sooc_framepath *)1;
    sooc_framepath_params_default(&p);
    p.min_depth_m = 0, p.max_depth_m = 0;   /* an empty depth range */
    CHECK(sooc_framepath_open(&fp, scene, &p) == SOOC_EINVAL && fp == NULL);
    CHECK_MSG(strstr(sooc_errmsg(), "depth range") != NULL, "%s", sooc_errmsg());
    sooc_framepath_params_default(&p);
    p.width = 32;   /* height missing */
    CHECK(sooc_framepath_open(&fp, scene, &p) == SOOC_EINVAL);
    sooc_framepath_params_default(&p);
    CHECK(sooc_framepath_open(&fp, "/nonexistent/seq", &p) != SOOC_OK && fp == NULL);
    sooc_framepath_world w;
    CHECK_OK(sooc_framepath_world_parse("estimate", &w));
    CHECK(w == SOOC_WORLD_ESTIMATE && !strcmp(sooc_framepath_world_name(w), "estimate"));
    CHECK(sooc_framepath_world_parse("gravity", &w) == SOOC_EINVAL);
}

int main(void) {
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_test_framepath_%ld", (long)getpid());
    CHECK_OK(sooc_mkdirs(g_tmp));
    char data[512], scene[600], rec[600];
    snprintf(data, sizeof data, "%s/data", g_tmp);
    snprintf(scene, sizeof scene, "%s/scene_0000", data);
    snprintf(rec, sizeof rec, "%s/recorded", g_tmp);
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.preset = SOOC_GEN_UNITY;
    gp.scale = SOOC_GEN_S;
    gp.seed = 7;
    gp.n_scenes = 1;
    gp.width = 80;
    gp.height = 60;
    gp.n_views = 6;
    gp.n_query = 2;
    gp.write_meshes = 0;
    gp.contact_sheet = 0;
    CHECK_OK(sooc_gen_run(&gp, data, NULL, NULL, NULL));
    test_resize(scene);
    write_recorded(scene, rec);
    test_recorded(scene, rec);
    test_same_as_node(scene);
    test_bad(scene);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf %s", g_tmp);
    if (!getenv("SOOC_KEEP_TMP") && system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_tmp);
    return check_report("test_framepath");
}
