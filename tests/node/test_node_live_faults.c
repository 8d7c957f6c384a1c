/* Live sources under faults (docs/node.md "Faults"), with the fake mapper and
 * the synthetic stream of node_fixture.h (each frame 0.15 m on: every posed
 * frame is a keyframe unless said otherwise):
 *
 *  sensor  a source whose device goes away at frame 10 (a stream error) and
 *          reopens at the 4th attempt: the node says so once each way, the
 *          frames after it go into the same map (ids go on, the database holds
 *          the map); reconnect_s 0 (negative control) ends the run at frame 10;
 *          a stop request while the device stays away ends the run cleanly.
 *  pose    a pose source silent for 40 frames (1.3 s): those frames are
 *          counted no_pose and not mapped, one line when it went silent and
 *          one when poses returned; a 5-frame gap (0.17 s) is counted, not
 *          logged.
 *  clock   stamps that jump back 100 s at frame 10 and forward 1000 s at frame
 *          20, with a time-only keyframe rule (0.2 s): both named, and a
 *          keyframe comes 7 frames after each jump, as without jumps
 *          (negative control: a forward jump not taken as one, time_jump_s =
 *          1e6, fires the rule on the jump itself).
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "check.h"
#include "node_fixture.h"
#include "sooc3d/mapper.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"
#include "sooc3d/table.h"

static char g_tmp[256], g_shm[64];
static atomic_int g_lost, g_back, g_still, g_silent, g_posesback, g_jump_back, g_jump_fwd;

static void log_cb(void *user, sooc_log_level lv, const char *msg) {
    (void)user;
    if (strstr(msg, "node: sensor lost: ")) atomic_fetch_add(&g_lost, 1);
    if (strstr(msg, "node: sensor back after")) atomic_fetch_add(&g_back, 1);
    if (strstr(msg, "node: sensor still lost")) atomic_fetch_add(&g_still, 1);
    if (strstr(msg, "node: no pose from")) atomic_fetch_add(&g_silent, 1);
    if (strstr(msg, "node: poses back at frame")) atomic_fetch_add(&g_posesback, 1);
    if (strstr(msg, "clock jumped back")) atomic_fetch_add(&g_jump_back, 1);
    if (strstr(msg, "clock jumped forward")) atomic_fetch_add(&g_jump_fwd, 1);
    if (lv >= SOOC_LOG_WARN && getenv("SOOC_TEST_VERBOSE")) fprintf(stderr, "[log] %s\n", msg);
}

static void logs_reset(void) {
    atomic_store(&g_lost, 0), atomic_store(&g_back, 0), atomic_store(&g_still, 0);
    atomic_store(&g_silent, 0), atomic_store(&g_posesback, 0);
    atomic_store(&g_jump_back, 0), atomic_store(&g_jump_fwd, 0);
}

/* A scripted source: frames 0..n-1; at frame `lose_at` the device goes away
 * (one read fails with a stream error); reopen fails `reopen_fails` times.
 * Stamps: +shift[k] ns from frame jump_at[k] on. */
typedef struct live_src {
    int i, n;
    int lose_at, lost, reopen_fails, reopens;
    int jump_at[2];
    int64_t shift[2];
    int never_back;
    sooc_node *node;         /* to request a stop while the device stays away */
} live_src;

static sooc_status live_read(void *ctx, sooc_frame *f, int timeout_ms) {
    live_src *s = ctx;
    (void)timeout_ms;
    if (s->i >= s->n) return SOOC_EEOF;
    if (s->i == s->lose_at && !s->lost) {
        s->lost = 1;
        return sooc_seterr(SOOC_EIO, "fake: /dev/fake0: device error or unplugged");
    }
    fx_fill(f, s->i, 0.15);
    for (int k = 0; k < 2; k++)
        if (s->jump_at[k] && s->i >= s->jump_at[k]) f->t_ns += s->shift[k];
    s->i++;
    return SOOC_OK;
}

static sooc_status live_reopen(void *ctx) {
    live_src *s = ctx;
    s->reopens++;
    if (s->never_back && s->reopens == 3 && s->node) sooc_node_request_stop(s->node);
    if (s->never_back || s->reopens <= s->reopen_fails)
        return sooc_seterr(SOOC_ENOTFOUND, "fake: /dev/fake0: no such device");
    return SOOC_OK;
}

static sooc_frame_fault live_fault(void *ctx) {
    (void)ctx;
    return SOOC_FRAME_FAULT_NONE;
}

/* A pose lookup that is silent for frame stamps in [t0, t1). */
typedef struct gap_pose {
    int64_t t0, t1;
} gap_pose;

static sooc_status gap_lookup(void *ctx, int64_t t_ns, int64_t tol, double T[16]) {
    gap_pose *g = ctx;
    (void)tol;
    if (t_ns >= g->t0 && t_ns < g->t1) return sooc_seterr(SOOC_ENOTFOUND, "no pose within tolerance");
    int i = (int)((t_ns - 1000000000000LL + 16666666) / 33333333LL);
    fx_pose(T, i, 0.15);
    return SOOC_OK;
}

static void make_cfg(sooc_node_config *c, const char *db, const char *extra_pipeline, const char *kf) {
    char text[2048];
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: /nonexistent}\n"
             "pose: {source: sensor}\n"
             "model: {path: fake.bin}\n"
             "keyframe: {%s}\n"
             "shm: {name: %s, capacity: 256}\n"
             "map: {db: '%s', resume: false}\n"
             "world: {up: +y, floor: 0.0}\n"
             "pipeline: {ring_capacity: 4, block_when_full: true, stats_period_s: 0%s}\n"
             "log: {level: warn}\n",
             kf ? kf : "translation_m: 0.10, rotation_deg: 10, time_s: 0", g_shm, db, extra_pipeline ? extra_pipeline : "");
    sooc_status st = sooc_node_config_parse(c, text, strlen(text), "live.yaml");
    CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
}

typedef struct run_out {
    sooc_status st;
    sooc_node_stats s;
} run_out;

static sooc_node_kf_fn g_on_kf;
static void *g_on_kf_user;

static void run(sooc_node_config *c, sooc_mapper *m, live_src *ls, const sooc_node_pose_source *pose, run_out *o) {
    logs_reset();
    sooc_node_source src;
    memset(&src, 0, sizeof src);
    src.ctx = ls;
    src.read = live_read;
    src.reopen = live_reopen;
    src.frame_fault = live_fault;
    sooc_node_options opt;
    memset(&opt, 0, sizeof opt);
    opt.source = &src;
    opt.mapper = m;
    opt.pose = pose;
    opt.on_keyframe = g_on_kf;
    opt.user = g_on_kf_user;
    if (pose) c->pose_kind = SOOC_NODE_POSE_FILE;
    sooc_node *n = NULL;
    memset(o, 0, sizeof *o);
    o->st = sooc_node_create(&n, c, &opt);
    CHECK_MSG(o->st == SOOC_OK, "create: %s", sooc_errmsg());
    if (o->st) return;
    ls->node = n;
    o->st = sooc_node_run(n);
    sooc_node_get_stats(n, &o->s);
    sooc_node_destroy(n);
}

/* A fresh database and fake mapper, then run(); returns the mapper (the caller destroys it). */
static sooc_mapper *fresh_run(const char *db, const char *extra_pipeline, const char *kf, live_src *ls,
                                const sooc_node_pose_source *pose, run_out *o) {
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    sooc_mapper *m = NULL;
    CHECK_OK(sooc_mapper_create(&m, &mp));
    unlink(db);
    sooc_node_config c;
    make_cfg(&c, db, extra_pipeline, kf);
    run(&c, m, ls, pose, o);
    return m;
}

static size_t db_count(const char *db) {
    sooc_mapstore *s = NULL;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    if (sooc_mapstore_open(&s, db, &p)) return (size_t)-1;
    sooc_mapstore_info info;
    size_t n = sooc_mapstore_info_get(s, &info) ? (size_t)-1 : (size_t)info.n_entries;
    sooc_mapstore_close(s);
    return n;
}

static void test_sensor(void) {
    char db[400];
    snprintf(db, sizeof db, "%s/live.db", g_tmp);
    run_out o;

    /* lost at frame 10, back at the 4th attempt */
    live_src ls = {0, 30, 10, 0, 3, 0, {0, 0}, {0, 0}, 0, NULL};
    sooc_mapper *m = fresh_run(db, ", reconnect_s: 0.001, reconnect_max_s: 0.004", NULL, &ls, NULL, &o);
    CHECK_MSG(o.st == SOOC_OK, "reconnect: %s", sooc_errmsg());
    CHECK_MSG(o.s.keyframes == 30 && o.s.frames_in == 30 && o.s.sensor_lost == 1 && o.s.sensor_reconnects == 1 &&
                  !o.s.sensor_down && ls.reopens == 4,
              "reconnect: %llu keyframes, lost %llu back %llu, %d reopens", (unsigned long long)o.s.keyframes,
              (unsigned long long)o.s.sensor_lost, (unsigned long long)o.s.sensor_reconnects, ls.reopens);
    CHECK_MSG(atomic_load(&g_lost) == 1 && atomic_load(&g_back) == 1 && atomic_load(&g_still) == 1,
              "reconnect: %d lost, %d back, %d still-lost lines", atomic_load(&g_lost), atomic_load(&g_back),
              atomic_load(&g_still));
    size_t ne = 0;
    sooc_mapper_entries(m, NULL, 0, &ne);
    CHECK_MSG(sooc_mapper_next_id(m) == 31 && db_count(db) == ne,
              "reconnect: next id %llu (want 31: one map), %zu objects in the database for %zu in the map",
              (unsigned long long)sooc_mapper_next_id(m), db_count(db), ne);
    printf("sensor: lost at frame 10, back at the 4th reopen: 30 keyframes into one map (%zu objects), "
           "1 'lost' and 1 'back' line\n", ne);
    sooc_mapper_destroy(m);

    /* negative control: no reconnection, the run ends at the loss */
    live_src l2 = {0, 30, 10, 0, 3, 0, {0, 0}, {0, 0}, 0, NULL};
    m = fresh_run(db, ", reconnect_s: 0", NULL, &l2, NULL, &o);
    CHECK_MSG(o.st == SOOC_EIO && o.s.keyframes == 10 && l2.reopens == 0 && atomic_load(&g_lost) == 0,
              "no reconnect: status %d, %llu keyframes", o.st, (unsigned long long)o.s.keyframes);
    sooc_mapper_destroy(m);

    /* a stop request while the device stays away: a clean end */
    live_src l3 = {0, 30, 10, 0, 0, 0, {0, 0}, {0, 0}, 1, NULL};
    m = fresh_run(db, ", reconnect_s: 0.001, reconnect_max_s: 0.002", NULL, &l3, NULL, &o);
    CHECK_MSG(o.st == SOOC_OK && o.s.keyframes == 10 && o.s.sensor_down == 1 && o.s.sensor_reconnects == 0 &&
                  l3.reopens == 3 && db_count(db) > 0,
              "stopped while lost: status %d, %llu keyframes, down %d, %d reopens", o.st,
              (unsigned long long)o.s.keyframes, o.s.sensor_down, l3.reopens);
    sooc_mapper_destroy(m);
}

static void test_pose(void) {
    char db[400];
    snprintf(db, sizeof db, "%s/pose.db", g_tmp);
    run_out o;
    const int64_t T0 = 1000000000000LL, DT = 33333333LL;
    struct { int a, b, warn; } cases[3] = {{10, 50, 1}, {10, 15, 0}, {0, 0, 0}};
    for (int k = 0; k < 3; k++) {
        gap_pose g = {T0 + cases[k].a * DT - DT / 2, T0 + cases[k].b * DT - DT / 2};
        sooc_node_pose_source ps = {&g, gap_lookup, NULL};
        live_src ls = {0, 60, -1, 0, 0, 0, {0, 0}, {0, 0}, 0, NULL};
        sooc_mapper *m = fresh_run(db, NULL, NULL, &ls, &ps, &o);
        int gap = cases[k].b - cases[k].a;
        CHECK_MSG(o.st == SOOC_OK && o.s.frames_no_pose == (uint64_t)gap && o.s.keyframes == (uint64_t)(60 - gap) &&
                      o.s.pose_gaps == (uint64_t)cases[k].warn && atomic_load(&g_silent) == cases[k].warn &&
                      atomic_load(&g_posesback) == cases[k].warn,
                  "pose gap of %d frames: no_pose %llu, keyframes %llu, gaps %llu, %d silent / %d back lines", gap,
                  (unsigned long long)o.s.frames_no_pose, (unsigned long long)o.s.keyframes,
                  (unsigned long long)o.s.pose_gaps, atomic_load(&g_silent), atomic_load(&g_posesback));
        if (k == 0)
            printf("pose: silent for 40 frames (1.3 s): 40 counted no_pose, 20 keyframes, 1 'no pose' and 1 'back' "
                   "line\n");
        sooc_mapper_destroy(m);
    }
}

/* The frame each keyframe came from: the fake mapper's new object carries the frame's stamp. */
typedef struct kf_rec {
    const live_src *ls;
    int idx[64], n;
} kf_rec;

static void on_kf(void *user, uint64_t kf, const sooc_map_entry *chg, size_t nc, const uint64_t *rem, size_t nr,
                  const sooc_node_stats *st) {
    (void)kf, (void)rem, (void)nr, (void)st;
    kf_rec *r = user;
    for (size_t i = 0; i < nc && r->n < 64; i++) {
        if (chg[i].obs_count != 1) continue;
        int64_t t = chg[i].first_seen_ns - 1000000000000LL;
        for (int region = 2; region >= 0; region--) {   /* undo the shifts of the frame's region */
            int64_t u = t;
            for (int k = 0; k < region && k < 2; k++) u -= r->ls->shift[k];
            int fi = (int)((u + 16666666) / 33333333LL);
            int lo = region == 0 ? 0 : r->ls->jump_at[region - 1];
            int hi = region < 2 && r->ls->jump_at[region] ? r->ls->jump_at[region] : 1 << 30;
            if (region > 0 && !r->ls->jump_at[region - 1]) continue;
            if (fi >= lo && fi < hi) {
                r->idx[r->n++] = fi;
                break;
            }
        }
    }
}

static void kf_str(const kf_rec *r, char *buf, size_t cap) {
    size_t k = 0;
    buf[0] = 0;
    for (int i = 0; i < r->n && k + 8 < cap; i++) k += (size_t)snprintf(buf + k, cap - k, "%s%d", i ? " " : "", r->idx[i]);
}

static void test_clock(void) {
    char db[400];
    snprintf(db, sizeof db, "%s/clock.db", g_tmp);
    run_out o;
    const char *kf = "translation_m: 0, rotation_deg: 0, time_s: 0.2";
    /* 30 frames at 30 Hz, a keyframe once 0.2 s passed: frames 0 7 14 21 28 without jumps. With a
     * 100 s jump back at frame 10 and 1000 s forward at 20, each re-anchors the rule: 0 7 17 27 (a
     * keyframe 7 frames after each jump, as without). A forward jump not taken as one
     * (time_jump_s: 1e6) fires the rule on the jump itself: 0 7 14 20 27. */
    static const char *want[3] = {"0 7 14 21 28", "0 7 17 27", "0 7 14 20 27"};
    for (int k = 0; k < 3; k++) {
        live_src ls = {0, 30, -1, 0, 0, 0, {0, 0}, {0, 0}, 0, NULL};
        if (k == 1) ls = (live_src){0, 30, -1, 0, 0, 0, {10, 20}, {-100000000000LL, 1000000000000LL}, 0, NULL};
        if (k == 2) ls = (live_src){0, 30, -1, 0, 0, 0, {20, 0}, {1000000000000LL, 0}, 0, NULL};
        kf_rec rec = {&ls, {0}, 0};
        g_on_kf = on_kf;
        g_on_kf_user = &rec;
        sooc_mapper *m = fresh_run(db, k == 2 ? ", time_jump_s: 1e6" : NULL, kf, &ls, NULL, &o);
        g_on_kf = NULL;
        CHECK_OK(o.st);
        char got[256];
        kf_str(&rec, got, sizeof got);
        CHECK_MSG(!strcmp(got, want[k]), "clock case %d: keyframes at frames %s, want %s", k, got, want[k]);
        if (k == 1)
            CHECK_MSG(o.s.time_jumps == 2 && atomic_load(&g_jump_back) == 1 && atomic_load(&g_jump_fwd) == 1,
                      "jumps: %llu counted, %d back / %d forward lines", (unsigned long long)o.s.time_jumps,
                      atomic_load(&g_jump_back), atomic_load(&g_jump_fwd));
        else
            CHECK(o.s.time_jumps == 0 && atomic_load(&g_jump_back) == 0 && atomic_load(&g_jump_fwd) == 0);
        printf("clock case %d: keyframes at frames %s\n", k, got);
        sooc_mapper_destroy(m);
    }
}

int main(void) {
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_live_faults.%d", (int)getpid());
    snprintf(g_shm, sizeof g_shm, "live_faults_%d", (int)getpid());
    sooc_mkdirs(g_tmp);
    sooc_log_set_callback(log_cb, NULL);
    sooc_log_set_level(SOOC_LOG_INFO);
    test_sensor();
    test_pose();
    test_clock();
    char name[128];
    sooc_table_shm_name(g_shm, name, sizeof name);
    shm_unlink(name);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (system(cmd)) fprintf(stderr, "cleanup of %s failed\n", g_tmp);
    return check_report("test_node_live_faults");
}
