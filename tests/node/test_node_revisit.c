/* Revisits update instead of duplicating, with the shipped model
 * (models/sooc3d_unity/model.bin; skipped, 77, when absent):
 *  1. a generated unity m scene replayed twice into one map.db with
 *     map.resume: true: the second pass grows the map by at most 5%;
 *  2. label-fusion (../shared/real, that part skipped when absent) with
 *     world.floor: estimate and no up hint: the support plane is estimated
 *     once and stored in map.db; later passes use the stored frame, also
 *     when given a wrong up hint that would fail the estimate (no frame waits);
 *  3. 7-Scenes redkitchen with its gravity file: the floor, and a second pass
 *     grows the map by at most 5%. */
#include "check.h"
#include "sooc3d/gen.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *g_model = "models/sooc3d_unity/model.bin";

static int run_pass(const char *text, sooc_node_stats *out) {
    sooc_node_config c;
    sooc_status st = sooc_node_config_parse(&c, text, strlen(text), "revisit.yaml");
    CHECK_MSG(st == SOOC_OK, "config: %s", sooc_errmsg());
    if (st) return 0;
    sooc_node *n = NULL;
    st = sooc_node_create(&n, &c, NULL);
    CHECK_MSG(st == SOOC_OK, "create: %s", sooc_errmsg());
    if (st) return 0;
    st = sooc_node_run(n);
    CHECK_MSG(st == SOOC_OK, "run: %s", sooc_errmsg());
    sooc_node_get_stats(n, out);
    sooc_node_destroy(n);
    return st == SOOC_OK;
}

static int stored_frame(const char *db, sooc_map_frame *f) {
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    sooc_mapstore *s = NULL;
    int found = 0;
    CHECK_OK(sooc_mapstore_open(&s, db, &p));
    if (!s) return 0;
    CHECK_OK(sooc_mapstore_frame_get(s, f, &found));
    sooc_mapstore_close(s);
    return found;
}

static void synthetic(const char *tmp) {
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.preset = SOOC_GEN_UNITY;
    gp.scale = SOOC_GEN_M;
    gp.seed = 7;
    gp.n_scenes = 1;
    gp.threads = 1;
    gp.write_meshes = 0;
    gp.contact_sheet = 0;
    char gen[600], db[600], text[2048];
    snprintf(gen, sizeof gen, "%s/gen", tmp);
    CHECK_OK(sooc_gen_run(&gp, gen, NULL, NULL, NULL));
    snprintf(db, sizeof db, "%s/syn.sqlite", tmp);
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: '%s/scene_0000', speed: fast}\n"
             "pose: {source: sensor}\n"
             "model: {path: '%s'}\n"
             "keyframe: {translation_m: 0.25, rotation_deg: 15, time_s: 0}\n"
             "map: {db: '%s', resume: true}\n"
             "world: {up: +y, floor: 0.0}\n"
             "pipeline: {block_when_full: true, stats_period_s: 0}\n"
             "log: {level: warn}\n",
             gen, g_model, db);
    sooc_node_stats s1, s2, s3;
    if (!run_pass(text, &s1) || !run_pass(text, &s2) || !run_pass(text, &s3)) return;
    printf("synthetic m scene: %llu keyframes per pass, entries %llu -> %llu -> %llu\n",
           (unsigned long long)s1.keyframes, (unsigned long long)s1.n_objects, (unsigned long long)s2.n_objects,
           (unsigned long long)s3.n_objects);
    CHECK(s1.keyframes == s2.keyframes && s1.keyframes > 10);
    CHECK(s1.n_objects >= 3);
    CHECK(s2.resumed == s1.n_objects);
    CHECK_MSG((double)s2.n_objects <= 1.05 * (double)s1.n_objects, "second pass %llu > 1.05 x %llu",
              (unsigned long long)s2.n_objects, (unsigned long long)s1.n_objects);
    CHECK_MSG((double)s3.n_objects <= 1.05 * (double)s1.n_objects, "third pass %llu > 1.05 x %llu",
              (unsigned long long)s3.n_objects, (unsigned long long)s1.n_objects);
    sooc_map_frame f;
    CHECK(stored_frame(db, &f) && f.up_source == -1);   /* world.floor given: stored as given */
}

static int real(const char *tmp) {
    const char *e = getenv("SOOC_SHARED_REAL");
    char dir[1200], probe[1300], db[600], text[4096];
    snprintf(dir, sizeof dir, "%s/label_fusion/data/labels", e && *e ? e : "../shared/real");
    snprintf(probe, sizeof probe, "%s/frame-000000.depth.png", dir);
    if (access(probe, R_OK)) {
        printf("test_node_revisit: %s absent: real-data part skipped\n", dir);
        return 0;
    }
    snprintf(db, sizeof db, "%s/lf.sqlite", tmp);
    const char *fmt = "sensor: {driver: replay, path: '%s', speed: fast}\n"
                      "pose: {source: sensor}\n"
                      "model: {path: '%s'}\n"
                      "keyframe: {translation_m: 0.05, rotation_deg: 5, time_s: 0}\n"
                      "map: {db: '%s', resume: true}\n"
                      "world: {floor: estimate%s}\n"
                      "pipeline: {block_when_full: true, stats_period_s: 0}\n"
                      "log: {level: warn}\n";
    snprintf(text, sizeof text, fmt, dir, g_model, db, "");
    sooc_node_stats s1, s2, s3;
    if (!run_pass(text, &s1)) return 1;
    sooc_map_frame f1;
    CHECK(stored_frame(db, &f1));
    CHECK(f1.up_source == 2);   /* camera mean: no hint, no gravity file */
    CHECK(f1.cam_height_m > 0.05 && f1.cam_height_m < 1.0);
    CHECK(s1.floor_estimated && s1.frames_floor_wait == 0);
    if (!run_pass(text, &s2)) return 1;
    /* a wrong up hint: the estimate would fail, but the stored frame is used */
    snprintf(text, sizeof text, fmt, dir, g_model, db, ", up: +y");
    if (!run_pass(text, &s3)) return 1;
    printf("label-fusion: %llu keyframes per pass, camera %.3f m above the support plane, entries %llu -> %llu -> "
           "%llu\n",
           (unsigned long long)s1.keyframes, f1.cam_height_m, (unsigned long long)s1.n_objects,
           (unsigned long long)s2.n_objects, (unsigned long long)s3.n_objects);
    CHECK(s1.keyframes == s2.keyframes && s2.keyframes == s3.keyframes && s1.keyframes >= 10);
    CHECK(s3.frames_floor_wait == 0);
    double d = 0;
    for (int i = 0; i < 16; i++) d = fmax(d, fabs(s2.T_world_src[i] - f1.T_world_src[i]) + fabs(s3.T_world_src[i] - f1.T_world_src[i]));
    CHECK_MSG(d == 0, "resumed world frame differs from the stored one by %g", d);
    CHECK(s1.n_objects >= 1);
    /* growth is reported, not bounded, here: the camera is 0.16 m above the bin bottom, far below the
     * trained 1.2-2.0 m, so the model's box centres (0.6 m up) are never in view and never retrieved
     * (docs/cogmap.md "Revisits") */
    return 1;
}

/* 7-Scenes redkitchen (JPEG colour, gravity file): the support plane from
 * the gravity file, then two passes: growth <= 5%. */
static int sevenscenes(const char *tmp) {
    const char *e = getenv("SOOC_SHARED_REAL");
    char dir[1200], probe[1300], db[600], text[4096];
    snprintf(dir, sizeof dir, "%s/7scenes_redkitchen", e && *e ? e : "../shared/real");
    snprintf(probe, sizeof probe, "%s/frame-000000.color.jpg", dir);
    if (access(probe, R_OK)) {
        printf("test_node_revisit: %s absent: 7-Scenes part skipped\n", dir);
        return 0;
    }
    snprintf(db, sizeof db, "%s/7s.sqlite", tmp);
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: '%s', speed: fast}\n"
             "pose: {source: sensor}\n"
             "model: {path: '%s'}\n"
             "keyframe: {translation_m: 0.25, rotation_deg: 15, time_s: 0}\n"
             "map: {db: '%s', resume: true}\n"
             "world: {floor: estimate}\n"
             "pipeline: {block_when_full: true, stats_period_s: 0}\n"
             "log: {level: warn}\n",
             dir, g_model, db);
    sooc_node_stats s1, s2;
    if (!run_pass(text, &s1)) return 1;
    sooc_map_frame f;
    CHECK(stored_frame(db, &f));
    CHECK(f.up_source == 1);   /* the gravity file */
    CHECK_MSG(f.cam_height_m > 1.0 && f.cam_height_m < 2.0, "camera %.2f m above the support plane (the floor)",
              f.cam_height_m);
    if (!run_pass(text, &s2)) return 1;
    printf("7-Scenes: %llu keyframes per pass, camera %.3f m above the floor, entries %llu -> %llu\n",
           (unsigned long long)s1.keyframes, f.cam_height_m, (unsigned long long)s1.n_objects,
           (unsigned long long)s2.n_objects);
    CHECK(s1.keyframes == s2.keyframes && s1.keyframes >= 10);
    CHECK(s1.n_objects >= 5);
    CHECK_MSG((double)s2.n_objects <= 1.05 * (double)s1.n_objects, "second pass %llu > 1.05 x %llu",
              (unsigned long long)s2.n_objects, (unsigned long long)s1.n_objects);
    return 1;
}

int main(void) {
    if (access(g_model, R_OK)) {
        printf("test_node_revisit: SKIP: no model at %s\n", g_model);
        return SOOC_TEST_SKIP;
    }
    sooc_log_set_level(SOOC_LOG_WARN);
    char tmp[] = "/tmp/sooc_revisit_XXXXXX";
    if (!mkdtemp(tmp)) return 1;
    synthetic(tmp);
    real(tmp);
    sevenscenes(tmp);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd)) fprintf(stderr, "could not remove %s\n", tmp);
    return check_report("test_node_revisit");
}
