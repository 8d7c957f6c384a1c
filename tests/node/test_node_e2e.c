/* End to end with the fake mapper: source -> node -> shm table -> a reader
 * process (fork + the table reader API) sees exactly the objects the map
 * holds (removed ones flagged); SQLite holds them too; a restart from the
 * database loses nothing and new ids continue; the replay driver on a TUM
 * sequence written here gives the same; a bad calibration file names the key. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include "check.h"
#include "node_fixture.h"
#include "sooc3d/mapper.h"
#include "sooc3d/node.h"
#include "sooc3d/table.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/driver.h"

static char g_tmp[256], g_shm[64];

static sooc_status make_cfg(sooc_node_config *c, const char *extra_sensor, const char *db) {
    char text[4096];
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: %s/tum%s}\n"
             "pose: {source: sensor}\n"
             "model: {path: fake.bin}\n"
             "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
             "shm: {name: %s, capacity: 64, unlink_on_exit: false}\n"
             "map: {db: '%s', resume: true}\n"
             "world: {up: +y, floor: 0.0}\n"
             "pipeline: {ring_capacity: 4, block_when_full: true, stats_period_s: 0}\n"
             "log: {level: warn}\n",
             g_tmp, extra_sensor ? extra_sensor : "", g_shm, db);
    return sooc_node_config_parse(c, text, strlen(text), "e2e.yaml");
}

/* Child: wait for the table, follow it until the writer has exited, then
 * print "id flags" lines of the final snapshot and the max object count seen
 * while the writer was alive. */
static int reader_child(int fd) {
    sooc_table_reader *r = NULL;
    double t0 = sooc_seconds();
    while (sooc_table_open_reader(g_shm, &r) != SOOC_TABLE_OK) {
        if (sooc_seconds() - t0 > 20) return 3;
        usleep(2000);
    }
    static sooc_table_record recs[64];
    uint32_t n = 0, max_live = 0;
    uint64_t epoch = 0;
    for (;;) {
        sooc_table_liveness lv;
        int alive = sooc_table_writer_alive(r, &lv);
        if (sooc_table_snapshot(r, recs, 64, &n, &epoch) == SOOC_TABLE_OK) {
            uint32_t live = 0;
            for (uint32_t i = 0; i < n; i++) live += !(recs[i].flags & SOOC_TABLE_FLAG_REMOVED);
            if (live > max_live) max_live = live;
        }
        if (alive == 0 && lv.exited) break;
        if (sooc_seconds() - t0 > 30) return 4;
        usleep(1000);
    }
    if (sooc_table_snapshot(r, recs, 64, &n, &epoch) != SOOC_TABLE_OK) return 5;
    FILE *f = fdopen(fd, "w");
    fprintf(f, "max %u epoch %llu\n", max_live, (unsigned long long)epoch);
    for (uint32_t i = 0; i < n; i++)
        fprintf(f, "%llu %u %.4f %.4f %u\n", (unsigned long long)recs[i].object_id, recs[i].flags, recs[i].x,
                recs[i].z, recs[i].obs_count);
    fclose(f);
    sooc_table_close_reader(r);
    return 0;
}

typedef struct rrow {
    uint64_t id;
    unsigned flags, obs;
    float x, z;
} rrow;

static void check_reader(FILE *in, sooc_mapper *m, uint32_t *max_live) {
    size_t ne = 0;
    sooc_mapper_entries(m, NULL, 0, &ne);
    sooc_map_entry *e = calloc(ne + 1, sizeof *e);
    sooc_mapper_entries(m, e, ne, &ne);
    unsigned long long ep;
    CHECK(fscanf(in, "max %u epoch %llu\n", max_live, &ep) == 2);
    rrow rows[64];
    int nr = 0;
    unsigned long long id;
    while (nr < 64 && fscanf(in, "%llu %u %f %f %u\n", &id, &rows[nr].flags, &rows[nr].x, &rows[nr].z,
                             &rows[nr].obs) == 5)
        rows[nr++].id = id;
    /* every map entry is in the table, valid, same pose; every other row is REMOVED */
    size_t found = 0;
    for (int i = 0; i < nr; i++) {
        int in_map = 0;
        for (size_t k = 0; k < ne; k++)
            if (e[k].id == rows[i].id) {
                in_map = 1;
                found++;
                CHECK(rows[i].flags & 1u);
                CHECK(!(rows[i].flags & 4u));
                CHECK_CLOSE(rows[i].x, e[k].x, 1e-4, 0);
                CHECK_CLOSE(rows[i].z, e[k].z, 1e-4, 0);
                CHECK(rows[i].obs == e[k].obs_count);
            }
        if (!in_map) CHECK_MSG(rows[i].flags & 4u, "id %llu not in the map but not REMOVED",
                               (unsigned long long)rows[i].id);
    }
    CHECK_MSG(found == ne, "reader saw %zu of %zu map entries", found, ne);
    free(e);
}

static int count_visit(void *u, const sooc_cogmap_entry *e) {
    (void)e;
    (*(size_t *)u)++;
    return 0;
}
static size_t db_count(const char *db) {
    sooc_mapstore *s;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    if (sooc_mapstore_open(&s, db, &p)) return (size_t)-1;
    size_t n = 0;
    sooc_mapstore_foreach(s, count_visit, &n);
    sooc_mapstore_close(s);
    return n;
}

/* keyframe rows, layout blocks and the stored box extent */
static void db_info(const char *db, sooc_mapstore_info *info, float ext[3]) {
    sooc_mapstore *s;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    memset(info, 0, sizeof *info);
    ext[0] = ext[1] = ext[2] = -1;
    CHECK_OK(sooc_mapstore_open(&s, db, &p));
    if (!s) return;
    CHECK_OK(sooc_mapstore_info_get(s, info));
    char b[128];
    CHECK_OK(sooc_mapstore_meta_get(s, "extent", b, sizeof b));
    CHECK(sscanf(b, "%f %f %f", &ext[0], &ext[1], &ext[2]) == 3);
    sooc_mapstore_close(s);
}

int fake_mapper_get_block(const sooc_mapper *m, int32_t bi, int32_t bj, float *mu);

/* Run the node over `nframes` synthetic frames with a reader process. */
static void run_once(const char *db, sooc_mapper *m, int nframes, int first_frame, uint64_t *kf_out,
                     uint64_t *resumed_out) {
    sooc_node_config c;
    CHECK_OK(make_cfg(&c, NULL, db));
    char shm_path[128];
    sooc_table_shm_name(g_shm, shm_path, sizeof shm_path);
    shm_unlink(shm_path);   /* the reader must see this run's table, not the last one */
    int pfd[2];
    CHECK(pipe(pfd) == 0);
    pid_t pid = fork();
    if (pid == 0) {
        close(pfd[0]);
        _exit(reader_child(pfd[1]));
    }
    close(pfd[1]);
    fx_src s = {first_frame, first_frame + nframes, 0.15, 0};
    sooc_node_source src = fx_source(&s);
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.source = &src;
    o.mapper = m;
    sooc_node *n = NULL;
    sooc_status st = sooc_node_create(&n, &c, &o);
    CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
    if (st) return;
    sooc_node_stats s0;
    sooc_node_get_stats(n, &s0);
    if (resumed_out) *resumed_out = s0.resumed;
    CHECK_OK(sooc_node_run(n));
    sooc_node_stats sn;
    sooc_node_get_stats(n, &sn);
    *kf_out = sn.keyframes;
    char line[512];
    sooc_node_stats_format(&sn, line, sizeof line);
    printf("e2e run: %s\n", line);
    sooc_node_destroy(n);
    FILE *in = fdopen(pfd[0], "r");
    uint32_t max_live = 0;
    check_reader(in, m, &max_live);
    fclose(in);
    int status = 0;
    waitpid(pid, &status, 0);
    CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "reader exit %d", WEXITSTATUS(status));
    CHECK(max_live > 0);
}

static void test_e2e_and_restart(void) {
    char db[512];
    snprintf(db, sizeof db, "%s/map.sqlite", g_tmp);
    sooc_mapper *m;
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    CHECK_OK(sooc_mapper_create(&m, &mp));
    uint64_t kf = 0, resumed = 0;
    run_once(db, m, 12, 0, &kf, &resumed);
    CHECK(resumed == 0);
    CHECK_MSG(kf == 12, "keyframes %llu (every frame moves 0.15 m > 0.10 m)", (unsigned long long)kf);
    size_t n1 = 0;
    sooc_mapper_entries(m, NULL, 0, &n1);
    sooc_map_entry *e1 = calloc(n1 + 1, sizeof *e1);
    sooc_mapper_entries(m, e1, n1, &n1);
    CHECK(n1 == 12 - 2);   /* 12 registered, 2 removed by the fake mapper */
    CHECK_MSG(db_count(db) == n1, "db holds %zu, map %zu", db_count(db), n1);
    /* one keyframe row per keyframe, the layout block(s), the box extent */
    sooc_mapstore_info info;
    float ext[3];
    db_info(db, &info, ext);
    CHECK_MSG(info.n_keyframes == 12, "keyframe rows %llu", (unsigned long long)info.n_keyframes);
    CHECK_MSG(info.layout_dim == 4 && info.n_layout == 1, "layout dim %d, %llu blocks", info.layout_dim,
              (unsigned long long)info.n_layout);
    CHECK(ext[0] == 0.4f && ext[1] == 0.8f && ext[2] == 0.5f);
    CHECK(info.next_id == 13);
    float mu1[4] = {0}, mu2[4] = {0};
    CHECK(fake_mapper_get_block(m, 0, 0, mu1) == 0);
    sooc_mapper_destroy(m);

    /* restart with a fresh mapper and the same db: nothing lost */
    CHECK_OK(sooc_mapper_create(&m, &mp));
    run_once(db, m, 0, 100, &kf, &resumed);
    CHECK_MSG(resumed == n1, "resumed %llu of %zu", (unsigned long long)resumed, n1);
    CHECK_MSG(fake_mapper_get_block(m, 0, 0, mu2) == 0 && !memcmp(mu1, mu2, sizeof mu1),
              "layout block (0,0) restored: %g vs %g", mu2[0], mu1[0]);
    size_t n2 = 0;
    sooc_mapper_entries(m, NULL, 0, &n2);
    sooc_map_entry *e2 = calloc(n2 + 1, sizeof *e2);
    sooc_mapper_entries(m, e2, n2, &n2);
    CHECK(n2 == n1);
    for (size_t i = 0; i < n1 && i < n2; i++) {
        CHECK(e2[i].id == e1[i].id);
        CHECK_CLOSE(e2[i].x, e1[i].x, 1e-9, 0);
        CHECK_CLOSE(e2[i].z, e1[i].z, 1e-9, 0);
        CHECK_CLOSE(e2[i].yaw, e1[i].yaw, 1e-9, 0);
        CHECK_CLOSE(e2[i].sigma_t, e1[i].sigma_t, 1e-6, 1e-6);
        CHECK(e2[i].obs_count == e1[i].obs_count);
        CHECK(e2[i].latent_dim == e1[i].latent_dim && e2[i].what_mu[3] == e1[i].what_mu[3]);
        CHECK(e2[i].first_seen_ns == e1[i].first_seen_ns && e2[i].last_seen_ns == e1[i].last_seen_ns);
        CHECK(e2[i].extent[0] == 0.4f && e2[i].extent[1] == 0.8f && e2[i].extent[2] == 0.5f);
    }
    /* continue mapping: new ids follow the stored ones, nothing duplicated */
    uint64_t maxid = n1 ? e1[n1 - 1].id : 0;
    run_once(db, m, 3, 200, &kf, &resumed);
    CHECK(kf == 3);
    size_t n3 = 0;
    sooc_mapper_entries(m, NULL, 0, &n3);
    sooc_map_entry *e3 = calloc(n3 + 1, sizeof *e3);
    sooc_mapper_entries(m, e3, n3, &n3);
    CHECK(n3 == n1 + 3);
    CHECK(e3[n3 - 1].id == maxid + 3);
    CHECK_MSG(db_count(db) == n3, "db holds %zu, map %zu", db_count(db), n3);
    db_info(db, &info, ext);
    CHECK_MSG(info.n_keyframes == 15, "keyframe rows %llu", (unsigned long long)info.n_keyframes);
    free(e2);
    free(e3);
    sooc_mapper_destroy(m);
    free(e1);
}

static void test_replay_driver(void) {
    if (!sooc_sensor_has_driver("replay")) {
        fprintf(stderr, "test_node_e2e: replay driver absent: part skipped\n");
        return;
    }
    char dir[512], db[512];
    snprintf(dir, sizeof dir, "%s/tum", g_tmp);
    snprintf(db, sizeof db, "%s/replay.sqlite", g_tmp);
    CHECK(fx_write_tum(dir, 10, 0.15) == 0);
    sooc_node_config c;
    CHECK_OK(make_cfg(&c, ", format: tum, speed: fast, depth_scale: 0.0002", db));
    sooc_mapper *m;
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    CHECK_OK(sooc_mapper_create(&m, &mp));
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.mapper = m;
    sooc_node *n = NULL;
    sooc_status st = sooc_node_create(&n, &c, &o);
    CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
    if (!st) {
        CHECK_OK(sooc_node_run(n));
        sooc_node_stats s;
        sooc_node_get_stats(n, &s);
        char line[512];
        sooc_node_stats_format(&s, line, sizeof line);
        printf("replay driver run: %s\n", line);
        CHECK(s.frames_in == 10);
        CHECK(s.frames_dropped == 0);
        CHECK_MSG(s.keyframes == 10, "keyframes %llu", (unsigned long long)s.keyframes);
        sooc_node_destroy(n);
        size_t ne = 0;
        sooc_mapper_entries(m, NULL, 0, &ne);
        CHECK(db_count(db) == ne);
    }
    sooc_mapper_destroy(m);
}

static void test_bad_calib(void) {
    char cal[512], launch[1024];
    const char *cases[][2] = {
        {"%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [1, 0, 0]}\n",
         "camera_matrix"},
        {"%YAML 1.2\n---\nimage_width: -640\nimage_height: 480\n"
         "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\n",
         "image_width"},
        {"%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\n"
         "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\ndepth_scale: zero\n",
         "depth_scale"},
        {"%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\n"
         "camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 500, 240, 0, 0, 1]}\nfocal: 3\n",
         "focal"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        snprintf(cal, sizeof cal, "%s/bad_calib_%zu.yaml", g_tmp, i);
        FILE *f = fopen(cal, "w");
        fputs(cases[i][0], f);
        fclose(f);
        snprintf(launch, sizeof launch,
                 "sensor: {driver: replay, path: %s/none}\ncalib: %s\nmodel: {path: fake.bin}\n", g_tmp, cal);
        sooc_node_config c;
        CHECK_OK(sooc_node_config_parse(&c, launch, strlen(launch), "cal.yaml"));
        sooc_mapper *m;
        sooc_mapper_params mp;
        sooc_mapper_params_default(&mp);
        sooc_mapper_create(&m, &mp);
        fx_src s = {0, 0, 0.1, 0};
        sooc_node_source src = fx_source(&s);
        sooc_node_options o;
        memset(&o, 0, sizeof o);
        o.mapper = m;
        o.source = &src;
        sooc_node *n = NULL;
        sooc_status st = sooc_node_create(&n, &c, &o);
        CHECK_MSG(st != SOOC_OK, "bad calib %zu accepted", i);
        CHECK_MSG(strstr(sooc_errmsg(), cases[i][1]) && strstr(sooc_errmsg(), "bad_calib_"),
                  "calib case %zu: '%s' lacks '%s'", i, sooc_errmsg(), cases[i][1]);
        sooc_node_destroy(n);
        sooc_mapper_destroy(m);
    }
}

int main(void) {
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_node_e2e.%d", (int)getpid());
    snprintf(g_shm, sizeof g_shm, "node_e2e_%d", (int)getpid());
    sooc_mkdirs(g_tmp);
    test_e2e_and_restart();
    test_replay_driver();
    test_bad_calib();
    char name[128];
    sooc_table_shm_name(g_shm, name, sizeof name);
    shm_unlink(name);
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (system(cmd)) fprintf(stderr, "cleanup of %s failed\n", g_tmp);
    return check_report("test_node_e2e");
}
