/* bench_node: keyframes/s on replay and capture-to-table latency p50/p99
 * through the whole node pipeline (replay driver, ring, pose, keyframe
 * policy, preprocessing, mapper, shm table batch, SQLite transaction).
 *
 *   bench_node [frames=200]
 *       the fake mapper on a synthetic 64x48 TUM sequence (pipeline overhead)
 *   bench_node_model [frames=60] [--model M] [--threads T]
 *       the real model on a generated unity scene at 64x64 (models/sooc3d_unity/
 *       model.bin if present, else an untrained default-config model)
 *   bench_node_model --publish-scaling [--max-exp 5] [frames]
 *       publish time (table batch + SQLite transaction) with 10^2..10^max
 *       entries preloaded into the mapper (sooc_mapper_load_entries), away
 *       from the camera; also the cost of one full sooc_mapper_entries copy
 *       (the floor of what a diff-every-entry publisher paid per keyframe)
 * The model variant re-executes itself with OMP_WAIT_POLICY=passive when unset
 * (as `sooc3d node` does). Last line: JSON. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "../tests/node/node_fixture.h"
#include "sooc3d/mapper.h"
#include "sooc3d/node.h"
#if BENCH_MODEL
#include "sooc3d/gen.h"
#include "sooc3d/model.h"
#endif

#ifndef BENCH_MAPPER
#define BENCH_MAPPER "fake"
#endif

static char g_tmp[256];

static void cleanup(void) {
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (system(cmd)) fprintf(stderr, "cleanup of %s failed\n", g_tmp);
}

static sooc_status run_node(const char *text, sooc_mapper *m, sooc_node_stats *s, double *dt) {
    sooc_node_config c;
    sooc_status st = sooc_node_config_parse(&c, text, strlen(text), "bench.yaml");
    sooc_node *n = NULL;
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.mapper = m;
    if (!st) st = sooc_node_create(&n, &c, &o);
    if (st) return st;
    double t0 = sooc_seconds();
    st = sooc_node_run(n);
    *dt = sooc_seconds() - t0;
    sooc_node_get_stats(n, s);
    sooc_node_destroy(n);
    return st;
}

#if BENCH_MODEL
static int g_threads = 2;

/* entries on a grid (0.25 objects/m^2) starting 100 m from the scene */
static sooc_map_entry *far_entries(size_t n, int dim) {
    sooc_map_entry *e = calloc(n ? n : 1, sizeof *e);
    if (!e) return NULL;
    size_t side = 1;
    while (side * side < n) side++;
    for (size_t i = 0; i < n; i++) {
        sooc_map_entry *x = &e[i];
        x->id = i + 1;
        x->x = 100.0 + 2.0 * (double)(i % side);
        x->z = 100.0 + 2.0 * (double)(i / side);
        x->yaw = 0.01 * (double)(i % 628);
        x->sigma_t = 0.2;
        x->sigma_yaw = 0.3;
        x->presence_logit = 2.0f;
        x->presence = 0.88f;
        x->latent_dim = dim;
        for (int k = 0; k < dim; k++) x->what_mu[k] = 0.01f * (float)k, x->what_logvar[k] = -1.0f;
        x->first_seen_ns = x->last_seen_ns = 1;
        x->obs_count = 2;
    }
    return e;
}
#endif

int main(int argc, char **argv) {
#if BENCH_MODEL
    if (!getenv("OMP_WAIT_POLICY")) {
        setenv("OMP_WAIT_POLICY", "passive", 1);
        execv("/proc/self/exe", argv);
    }
#endif
    int nframes = 0, scaling = 0, max_exp = 5;
    const char *model = NULL;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--publish-scaling")) scaling = 1;
        else if (!strcmp(argv[i], "--max-exp") && i + 1 < argc) max_exp = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--model") && i + 1 < argc) model = argv[++i];
#if BENCH_MODEL
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc) g_threads = atoi(argv[++i]);
#endif
        else nframes = atoi(argv[i]);
    }
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_bench_node.%d", (int)getpid());
    char seq[512], db[512], text[4096], shm[64];
    snprintf(db, sizeof db, "%s/map.sqlite", g_tmp);
    snprintf(shm, sizeof shm, "bench_node_%d", (int)getpid());
#if BENCH_MODEL
    if (nframes <= 0) nframes = 60;
    char mpath[512];
    if (!model && access("models/sooc3d_unity/model.bin", R_OK) == 0) model = "models/sooc3d_unity/model.bin";
    const char *model_kind = model ? "given" : "untrained-default";
    if (!model) {   /* untrained default config (64x64, K = 7, d = 32): same cost as a trained one */
        sooc_model_config c;
        sooc_model_config_default(&c);
        sooc_model *m = NULL;
        snprintf(mpath, sizeof mpath, "%s/model.bin", g_tmp);
        if (sooc_mkdirs(g_tmp) || sooc_model_create(&m, &c, 1) || sooc_model_save(m, mpath, NULL, 0)) {
            fprintf(stderr, "bench_node: cannot create a model: %s\n", sooc_errmsg());
            return 1;
        }
        sooc_model_destroy(m);
        model = mpath;
    }
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.preset = SOOC_GEN_UNITY;
    gp.scale = SOOC_GEN_M;
    gp.seed = 7;
    gp.n_scenes = 1;
    gp.n_views = nframes;
    gp.n_query = 0;
    gp.write_meshes = 0;
    gp.contact_sheet = 0;
    char gen[384];
    snprintf(gen, sizeof gen, "%s/gen", g_tmp);
    if (sooc_gen_run(&gp, gen, NULL, NULL, NULL)) {
        fprintf(stderr, "bench_node: gen: %s\n", sooc_errmsg());
        return 1;
    }
    snprintf(seq, sizeof seq, "%s/scene_0000", gen);
    const char *sensor_fmt = "auto", *depth_scale = "";
    const char *frame_size = "64x64";
#else
    if (nframes <= 0) nframes = 200;
    snprintf(seq, sizeof seq, "%s/tum", g_tmp);
    if (fx_write_tum(seq, nframes, 0.15)) {
        fprintf(stderr, "bench_node: cannot write %s\n", seq);
        return 1;
    }
    if (!model) model = "fake.bin";
    const char *sensor_fmt = "tum", *depth_scale = ", depth_scale: 0.0002";
    const char *frame_size = "64x48";
    (void)max_exp;
    if (scaling) {
        fprintf(stderr, "bench_node: --publish-scaling needs the model build (bench_node_model)\n");
        return 2;
    }
#endif

    if (!scaling) {
        snprintf(text, sizeof text,
                 "sensor: {driver: replay, path: %s, format: %s, speed: fast%s}\n"
                 "pose: {source: sensor}\nmodel: {path: '%s', threads: %d}\n"
                 "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
                 "shm: {name: %s, capacity: 4096, unlink_on_exit: true}\nmap: {db: '%s'}\n"
                 "world: {up: +y, floor: 0.0}\n"
                 "pipeline: {ring_capacity: 8, block_when_full: true, stats_period_s: 0}\nlog: {level: warn}\n",
                 seq, sensor_fmt, depth_scale, model,
#if BENCH_MODEL
                 g_threads,
#else
                 0,
#endif
                 shm, db);
        sooc_node_stats s, sr;
        memset(&sr, 0, sizeof sr);
        double dt = 0, dtr = 0;
        sooc_status st = run_node(text, NULL, &s, &dt);
#if BENCH_MODEL
        /* the same at the recorded rate (10 Hz): latency without ring queueing */
        char *sp = strstr(text, "speed: fast");
        if (!st && sp) {
            memcpy(sp, "speed: 1.0 ", 11);
            remove(db);
            st = run_node(text, NULL, &sr, &dtr);
        }
#endif
        cleanup();
        if (st) {
            fprintf(stderr, "bench_node: %s\n", sooc_errmsg());
            return 1;
        }
        (void)dtr;
        printf("{\"bench\": \"node\", \"mapper\": \"%s\", "
#if BENCH_MODEL
               "\"model\": \"%s\", \"threads\": %d, \"omp_wait_policy\": \"%s\", "
               "\"realtime_10hz_capture_to_table_p50_ms\": %.3f, \"realtime_10hz_capture_to_table_p99_ms\": %.3f, "
#endif
               "\"frames\": %llu, \"keyframes\": %llu, \"seconds\": %.3f, "
               "\"keyframes_per_s\": %.2f, \"update_p50_ms\": %.3f, \"update_p99_ms\": %.3f, "
               "\"publish_p50_ms\": %.3f, \"publish_p99_ms\": %.3f, "
               "\"capture_to_table_p50_ms\": %.3f, \"capture_to_table_p99_ms\": %.3f, \"frame_size\": \"%s\", "
               "\"objects\": %llu, \"dropped\": %llu}\n",
               BENCH_MAPPER,
#if BENCH_MODEL
               model_kind, g_threads, getenv("OMP_WAIT_POLICY") ? getenv("OMP_WAIT_POLICY") : "", sr.c2t_p50_ms,
               sr.c2t_p99_ms,
#endif
               (unsigned long long)s.frames_in, (unsigned long long)s.keyframes, dt, (double)s.keyframes / dt,
               s.update_p50_ms, s.update_p99_ms, s.publish_p50_ms, s.publish_p99_ms, s.c2t_p50_ms, s.c2t_p99_ms,
               frame_size, (unsigned long long)s.n_objects, (unsigned long long)s.frames_dropped);
        return 0;
    }

#if BENCH_MODEL
    /* publish time vs map size */
    printf("%9s %10s %10s %10s %12s %12s\n", "entries", "kf", "pub p50", "pub p99", "update p50", "full copy");
    char json[2048];
    size_t jl = (size_t)snprintf(json, sizeof json, "{\"bench\": \"node_publish_scaling\", \"mapper\": \"model\", "
                                                   "\"model\": \"%s\", \"points\": [", model_kind);
    int first = 1;
    for (int ex = 2; ex <= max_exp; ex++) {
        size_t N = 1;
        for (int k = 0; k < ex; k++) N *= 10;
        sooc_mapper_params mp;
        sooc_mapper_params_default(&mp);
        mp.model_path = model;
        mp.threads = g_threads;
        sooc_mapper *m = NULL;
        if (sooc_mapper_create(&m, &mp)) {
            fprintf(stderr, "bench_node: %s\n", sooc_errmsg());
            return 1;
        }
        sooc_map_entry *e = far_entries(N, sooc_mapper_latent_dim(m));
        if (!e || sooc_mapper_load_entries(m, e, N)) {
            fprintf(stderr, "bench_node: load_entries: %s\n", sooc_errmsg());
            return 1;
        }
        /* what a diff-every-entry publisher copied per keyframe (at least) */
        double tc = sooc_seconds();
        size_t got = 0;
        sooc_mapper_entries(m, e, N, &got);
        double copy_ms = (sooc_seconds() - tc) * 1e3;
        free(e);
        char dbn[600];
        snprintf(dbn, sizeof dbn, "%s/map_%d.sqlite", g_tmp, ex);
        snprintf(text, sizeof text,
                 "sensor: {driver: replay, path: %s, format: auto, speed: fast}\n"
                 "pose: {source: sensor}\nmodel: {path: '%s'}\n"
                 "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
                 "shm: {name: %s, capacity: %zu, unlink_on_exit: true}\nmap: {db: '%s'}\n"
                 "world: {up: +y, floor: 0.0}\n"
                 "pipeline: {ring_capacity: 8, block_when_full: true, stats_period_s: 0}\nlog: {level: warn}\n",
                 seq, model, shm, N + 4096, dbn);
        sooc_node_stats s;
        double dt = 0;
        sooc_status st = run_node(text, m, &s, &dt);
        sooc_mapper_destroy(m);
        if (st) {
            fprintf(stderr, "bench_node: %s\n", sooc_errmsg());
            cleanup();
            return 1;
        }
        printf("%9zu %10llu %8.3f ms %8.3f ms %9.2f ms %9.2f ms\n", N, (unsigned long long)s.keyframes,
               s.publish_p50_ms, s.publish_p99_ms, s.update_p50_ms, copy_ms);
        fflush(stdout);
        jl += (size_t)snprintf(json + jl, sizeof json - jl,
                               "%s{\"entries\": %zu, \"keyframes\": %llu, \"publish_p50_ms\": %.4f, "
                               "\"publish_p99_ms\": %.4f, \"update_p50_ms\": %.3f, \"full_copy_ms\": %.3f}",
                               first ? "" : ", ", N, (unsigned long long)s.keyframes, s.publish_p50_ms,
                               s.publish_p99_ms, s.update_p50_ms, copy_ms);
        first = 0;
        if (jl >= sizeof json - 256) break;
    }
    cleanup();
    printf("%s]}\n", json);
#endif
    return 0;
}
