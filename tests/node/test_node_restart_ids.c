/* Object ids across node restarts, as a planner sees them in the table
 * (the rule is docs/shm.md "Object ids and restarts"):
 *  A. a first run on a new map.db;
 *  B. a restart on ANOTHER new map.db (the map is not resumed): instance_id
 *     changes, the ids start at 1 again (some ids of run A come back: a
 *     planner that ignored instance_id would confuse the objects), and
 *     every record left by run A is flagged REMOVED or overwritten;
 *  C. a restart that resumes run B's map.db: instance_id changes again, the
 *     objects of run B keep their ids, and new ids continue above every id
 *     run B handed out (the persistent id counter).
 * The node runs in-process with the fake mapper (one new object per
 * keyframe, the oldest removed every few keyframes). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "check.h"
#include "node_fixture.h"
#include "sooc3d/mapper.h"
#include "sooc3d/node.h"
#include "sooc3d/table.h"

static char g_tmp[256], g_shm[64];

typedef struct view {
    uint64_t instance;
    uint32_t n;
    sooc_table_record rec[64];
    uint64_t live_min, live_max; /* ids of records not REMOVED */
    uint32_t n_live;
} view;

/* Run the node over frames [first, first + n) with a fresh fake mapper. */
static void run_node(const char *db, int first, int n) {
    char text[2048];
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: %s/unused}\n"
             "pose: {source: sensor}\n"
             "model: {path: fake.bin}\n"
             "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
             "shm: {name: %s, capacity: 64, unlink_on_exit: false}\n"
             "map: {db: '%s', resume: true}\n"
             "world: {up: +y, floor: 0.0}\n"
             "pipeline: {ring_capacity: 4, block_when_full: true, stats_period_s: 0}\n"
             "log: {level: warn}\n",
             g_tmp, g_shm, db);
    sooc_node_config c;
    CHECK_OK(sooc_node_config_parse(&c, text, strlen(text), "restart_ids.yaml"));
    sooc_mapper *m = NULL;
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    CHECK_OK(sooc_mapper_create(&m, &mp));
    fx_src s = {first, first + n, 0.15, 0};
    sooc_node_source src = fx_source(&s);
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.source = &src;
    o.mapper = m;
    sooc_node *node = NULL;
    sooc_status st = sooc_node_create(&node, &c, &o);
    CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
    if (!st) {
        CHECK_OK(sooc_node_run(node));
        sooc_node_destroy(node);
    }
    sooc_mapper_destroy(m);
}

/* The table as a planner reads it after the run (the writer closed it). */
static void read_table(view *v) {
    memset(v, 0, sizeof *v);
    sooc_table_reader *r = NULL;
    CHECK(sooc_table_open_reader(g_shm, &r) == SOOC_TABLE_OK);
    if (!r) return;
    sooc_table_info info;
    uint64_t epoch = 0;
    CHECK(sooc_table_get_info(r, &info) == SOOC_TABLE_OK);
    CHECK(sooc_table_snapshot(r, v->rec, 64, &v->n, &epoch) == SOOC_TABLE_OK);
    v->instance = info.instance_id;
    v->live_min = UINT64_MAX;
    for (uint32_t i = 0; i < v->n; i++) {
        if (v->rec[i].flags & SOOC_TABLE_FLAG_REMOVED) continue;
        v->n_live++;
        if (v->rec[i].object_id < v->live_min) v->live_min = v->rec[i].object_id;
        if (v->rec[i].object_id > v->live_max) v->live_max = v->rec[i].object_id;
    }
    sooc_table_close_reader(r);
}

static int has_live(const view *v, uint64_t id) {
    for (uint32_t i = 0; i < v->n; i++)
        if (v->rec[i].object_id == id && !(v->rec[i].flags & SOOC_TABLE_FLAG_REMOVED)) return 1;
    return 0;
}

int main(void) {
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_node_restart_ids.%d", (int)getpid());
    snprintf(g_shm, sizeof g_shm, "node_restart_ids_%d", (int)getpid());
    sooc_mkdirs(g_tmp);
    char dbA[512], dbB[512];
    snprintf(dbA, sizeof dbA, "%s/a.sqlite", g_tmp);
    snprintf(dbB, sizeof dbB, "%s/b.sqlite", g_tmp);
    static view A, B, C;

    run_node(dbA, 0, 8);
    read_table(&A);
    printf("run A (new map a.sqlite): instance %016llx, %u live ids %llu..%llu\n",
           (unsigned long long)A.instance, A.n_live, (unsigned long long)A.live_min,
           (unsigned long long)A.live_max);
    CHECK(A.n_live > 0);

    run_node(dbB, 100, 5);
    read_table(&B);
    printf("run B (another new map b.sqlite, not resumed): instance %016llx, %u live ids %llu..%llu\n",
           (unsigned long long)B.instance, B.n_live, (unsigned long long)B.live_min,
           (unsigned long long)B.live_max);
    CHECK_MSG(B.instance != A.instance, "instance_id did not change on a restart");
    /* 5 keyframes, one new object each, ids from 1: every id is <= 5 */
    CHECK_MSG(B.live_max <= 5, "a new map starts its ids at 1 (5 keyframes, max id %llu)",
              (unsigned long long)B.live_max);
    int reused = 0;
    for (uint64_t id = B.live_min; id <= B.live_max; id++) reused += has_live(&B, id) && id <= A.live_max;
    CHECK_MSG(reused > 0, "no id of run A came back: the case the instance_id rule is for");
    /* nothing of run A is still live unless run B wrote it */
    for (uint32_t i = 0; i < B.n; i++)
        if (!(B.rec[i].flags & SOOC_TABLE_FLAG_REMOVED))
            CHECK_MSG(B.rec[i].last_seen_ns >= 1000000000000LL + 100 * 33333333LL,
                      "id %llu is a leftover of run A", (unsigned long long)B.rec[i].object_id);

    run_node(dbB, 200, 3);
    read_table(&C);
    printf("run C (resumes b.sqlite): instance %016llx, %u live ids %llu..%llu\n",
           (unsigned long long)C.instance, C.n_live, (unsigned long long)C.live_min,
           (unsigned long long)C.live_max);
    CHECK_MSG(C.instance != B.instance, "instance_id did not change on a resumed restart");
    uint32_t kept = 0, added = 0;
    for (uint32_t i = 0; i < C.n; i++) {
        const sooc_table_record *r = &C.rec[i];
        if (r->flags & SOOC_TABLE_FLAG_REMOVED) continue;
        if (r->object_id <= B.live_max) {
            kept++;
            int same = 0; /* the same object under the same id */
            for (uint32_t k = 0; k < B.n; k++)
                if (B.rec[k].object_id == r->object_id && B.rec[k].x == r->x && B.rec[k].z == r->z &&
                    B.rec[k].first_seen_ns == r->first_seen_ns)
                    same = 1;
            CHECK_MSG(same || r->last_seen_ns >= 1000000000000LL + 200 * 33333333LL,
                      "resumed id %llu is not run B's object", (unsigned long long)r->object_id);
        } else {
            added++;
        }
    }
    CHECK_MSG(kept > 0 && added > 0, "resumed: %u ids kept, %u new", kept, added);
    CHECK_MSG(C.live_max > B.live_max, "new ids continue above run B's (%llu <= %llu)",
              (unsigned long long)C.live_max, (unsigned long long)B.live_max);

    char name[128], cmd[600];
    sooc_table_shm_name(g_shm, name, sizeof name);
    shm_unlink(name);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (system(cmd)) fprintf(stderr, "cleanup of %s failed\n", g_tmp);
    return check_report("test_node_restart_ids");
}
