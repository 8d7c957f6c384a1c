/* bench_table: shared-memory object table costs (part 10).
 *   - reader: sooc_table_snapshot of 10^4 objects (consistent whole-table copy),
 *             and sooc_table_read_record per record;
 *   - writer: publish = begin_batch + N upserts + end_batch, for N = 10^4 (a
 *             full map) and N = 10 (one keyframe's objects).
 * Single process, quiet table (no concurrent writer). Each figure is the
 * median of --reps repetitions (default 50). The snapshot is validated against
 * the written records before timing. Last line: a JSON object. */
#include "sooc3d/table.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#define NOBJ 10000

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    return v[n / 2];
}

static void make(sooc_table_record *r, uint64_t id, uint32_t c) {
    memset((void *)r, 0, sizeof *r);
    r->object_id = id;
    r->flags = SOOC_TABLE_FLAG_VALID;
    r->obs_count = c;
    r->presence = 0.9f;
    r->x = (float)(id % 100);
    r->z = (float)(id / 100);
    r->yaw = 0.01f * (float)c;
    r->latent_dim = 32;
    for (int i = 0; i < 32; i++) r->latent[i] = (float)(c + (uint32_t)i);
}

static int fail(const char *what, int rc) {
    fprintf(stderr, "bench_table: %s: %s\n", what, sooc_table_strerror(rc));
    return 1;
}

int main(int argc, char **argv) {
    int reps = 50;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--help")) {
            printf("usage: bench_table [--reps N]\n");
            return 0;
        }
    }
    if (reps < 3) reps = 3;
    char name[64];
    snprintf(name, sizeof name, "bench_table_%ld", (long)getpid());
    sooc_table_writer *w = NULL;
    sooc_table_reader *r = NULL;
    int rc = sooc_table_create_writer(name, NOBJ, 0, "map", &w);
    if (rc) return fail("create_writer", rc);
    rc = sooc_table_open_reader(name, &r);
    if (rc) return fail("open_reader", rc);

    sooc_table_record *in = malloc(NOBJ * sizeof *in);
    sooc_table_record *out = malloc(NOBJ * sizeof *out);
    double *t = malloc((size_t)reps * sizeof *t);
    if (!in || !out || !t) return 1;

    /* writer: full-map publish (the first run inserts, later runs overwrite) */
    for (int k = 0; k < reps; k++) {
        for (uint32_t i = 0; i < NOBJ; i++) make(&in[i], 1 + i, (uint32_t)k);
        double t0 = now_s();
        sooc_table_begin_batch(w);
        for (uint32_t i = 0; i < NOBJ; i++)
            if ((rc = sooc_table_upsert(w, &in[i])) != 0) return fail("upsert", rc);
        sooc_table_end_batch(w);
        t[k] = now_s() - t0;
    }
    double pub_full = median(t, reps);

    /* writer: one keyframe's 10 objects */
    for (int k = 0; k < reps; k++) {
        double t0 = now_s();
        sooc_table_begin_batch(w);
        for (uint32_t i = 0; i < 10; i++) {
            make(&in[i], 1 + (uint32_t)(k * 10 + i) % NOBJ, (uint32_t)k + 1000);
            sooc_table_upsert(w, &in[i]);
        }
        sooc_table_end_batch(w);
        t[k] = now_s() - t0;
    }
    double pub_kf = median(t, reps);

    /* validate a snapshot against what was written */
    uint32_t n = 0;
    uint64_t epoch = 0;
    rc = sooc_table_snapshot(r, out, NOBJ, &n, &epoch);
    if (rc) return fail("snapshot", rc);
    if (n != NOBJ || out[123].object_id != 124) {
        fprintf(stderr, "bench_table: snapshot mismatch (n = %u)\n", n);
        return 1;
    }
    for (uint32_t i = 0; i < NOBJ; i++)
        if (out[i].x != (float)((i + 1) % 100) || (out[i].seq & 1)) {
            fprintf(stderr, "bench_table: snapshot record %u wrong\n", i);
            return 1;
        }

    /* reader: whole-table snapshot, and per-record reads */
    for (int k = 0; k < reps; k++) {
        double t0 = now_s();
        rc = sooc_table_snapshot(r, out, NOBJ, &n, &epoch);
        t[k] = now_s() - t0;
        if (rc) return fail("snapshot", rc);
    }
    double snap = median(t, reps);
    for (int k = 0; k < reps; k++) {
        sooc_table_record rec;
        double t0 = now_s();
        for (uint32_t i = 0; i < NOBJ; i++) sooc_table_read_record(r, i, &rec);
        t[k] = (now_s() - t0) / NOBJ;
    }
    double per_rec = median(t, reps);
    for (int k = 0; k < reps; k++) {
        double t0 = now_s();
        sooc_table_liveness live;
        for (int i = 0; i < 1000; i++) sooc_table_writer_alive(r, &live);
        t[k] = (now_s() - t0) / 1000;
    }
    double alive = median(t, reps);

    printf("table with %d objects (%.2f MB), %d reps, medians:\n", NOBJ,
           (4096.0 + 256.0 * NOBJ) / 1e6, reps);
    printf("  reader snapshot (10^4 objects):   %9.1f us  (%.2f GB/s)\n", snap * 1e6,
           256.0 * NOBJ / snap / 1e9);
    printf("  reader per-record read:           %9.1f ns\n", per_rec * 1e9);
    printf("  reader liveness check:            %9.2f us\n", alive * 1e6);
    printf("  writer publish 10^4 upserts:      %9.1f us\n", pub_full * 1e6);
    printf("  writer publish 10 upserts (kf):   %9.2f us\n", pub_kf * 1e6);
    sooc_table_close_reader(r);
    sooc_table_close_writer(w, 1);
    free(in);
    free(out);
    free(t);
    printf("{\"bench\":\"table\",\"objects\":%d,\"snapshot_us\":%.2f,\"read_record_ns\":%.1f,"
           "\"alive_check_us\":%.3f,\"publish_10k_us\":%.2f,\"publish_10_us\":%.3f}\n",
           NOBJ, snap * 1e6, per_rec * 1e9, alive * 1e6, pub_full * 1e6, pub_kf * 1e6);
    return 0;
}
