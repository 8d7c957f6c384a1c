/* bench_node: keyframes/s on replay and capture-to-table latency p50/p99.
 * Replays a synthetic TUM sequence (written to /tmp) through the replay
 * driver and the whole node pipeline (ring, pose, keyframe policy,
 * preprocessing, mapper, shm table batch, SQLite transaction). Uses the real
 * model when built and models/sooc3d_unity/model.bin exists (bench_node_model),
 * otherwise the fake mapper (bench_node), and says which in the JSON.
 *   bench_node [frames=200]                      last line: JSON */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "../tests/node/node_fixture.h"
#include "sooc3d/mapper.h"
#include "sooc3d/node.h"
#if SOOC_NODE_HAVE_TABLE
#include "sooc3d/table.h"
#endif

#ifndef BENCH_MAPPER
#define BENCH_MAPPER "fake"
#endif

int main(int argc, char **argv) {
    int nframes = argc > 1 ? atoi(argv[1]) : 200;
    char tmp[256], seq[512], db[512], text[2048], shm[64];
    snprintf(tmp, sizeof tmp, "/tmp/sooc3d_bench_node.%d", (int)getpid());
    snprintf(seq, sizeof seq, "%s/tum", tmp);
    snprintf(db, sizeof db, "%s/map.sqlite", tmp);
    snprintf(shm, sizeof shm, "bench_node_%d", (int)getpid());
    if (fx_write_tum(seq, nframes, 0.15)) {
        fprintf(stderr, "bench_node: cannot write %s\n", seq);
        return 1;
    }
    const char *model = "models/sooc3d_unity/model.bin";
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: %s, format: tum, speed: fast, depth_scale: 0.0002}\n"
             "pose: {source: sensor}\nmodel: {path: %s}\n"
             "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
             "shm: {name: %s, capacity: %d, unlink_on_exit: true}\nmap: {db: '%s'}\n"
             "world: {up: +y, floor: 0.0}\npipeline: {ring_capacity: 8, block_when_full: true, stats_period_s: 0}\n",
             seq, model, shm, nframes + 16, db);
    sooc_node_config c;
    sooc_status st = sooc_node_config_parse(&c, text, strlen(text), "bench.yaml");
    sooc_node *n = NULL;
    if (!st) st = sooc_node_create(&n, &c, NULL);
    if (st) {
        fprintf(stderr, "bench_node: %s\n", sooc_errmsg());
        return 1;
    }
    double t0 = sooc_seconds();
    st = sooc_node_run(n);
    double dt = sooc_seconds() - t0;
    sooc_node_stats s;
    sooc_node_get_stats(n, &s);
    sooc_node_destroy(n);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd)) fprintf(stderr, "cleanup failed\n");
    if (st) {
        fprintf(stderr, "bench_node: %s\n", sooc_errmsg());
        return 1;
    }
    printf("{\"bench\": \"node\", \"mapper\": \"%s\", \"frames\": %llu, \"keyframes\": %llu, \"seconds\": %.3f, "
           "\"keyframes_per_s\": %.1f, \"update_p50_ms\": %.3f, \"update_p99_ms\": %.3f, "
           "\"capture_to_table_p50_ms\": %.3f, \"capture_to_table_p99_ms\": %.3f, \"frame_size\": \"%dx%d\", "
           "\"dropped\": %llu}\n",
           BENCH_MAPPER, (unsigned long long)s.frames_in, (unsigned long long)s.keyframes, dt,
           (double)s.keyframes / dt, s.update_p50_ms, s.update_p99_ms, s.c2t_p50_ms, s.c2t_p99_ms, FX_W, FX_H,
           (unsigned long long)s.frames_dropped);
    return 0;
}
