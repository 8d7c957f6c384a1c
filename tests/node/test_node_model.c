/* End to end with the REAL model (no fake mapper).
 *
 * A small unity scene is generated here (sooc_gen_run) and two untrained
 * models are saved here: "cold" (as initialised; it may register few or no
 * objects) and "hot" (the same with the slot priors' presence logits set to
 * +5 in the parameter slab, so every slot is registered and the map fills
 * regardless of training).
 *
 *  1. `sooc3d node` (SOOC_BIN) replays the scene with the hot model while
 *     `sooc3d-planner-example` follows the table in parallel; afterwards the
 *     table's live ids == the SQLite rows == `sooc3d map list --db` ids ==
 *     `sooc3d-planner-example --once`, the planner saw objects while the node
 *     ran, and the last keyframe row's stamp is the table's stamp.
 *  2. The same pipeline in-process (sooc_node_* with a mapper we own):
 *     table == mapper entries == SQLite rows (ids, x, z, presence), keyframe
 *     rows == keyframes; a restart resumes every entry and layout block.
 *  3. The cold model through `sooc3d node`: exit 0, table == SQLite == list.
 *  4. SIGINT mid-run (hot model, replay at recorded speed): exit 0, the table
 *     and the database agree and hold the last keyframe.
 * Skips (77) if SOOC_BIN is not set. */
#include <signal.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/gen.h"
#include "sooc3d/mapper.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/model.h"
#include "sooc3d/node.h"
#include "sooc3d/table.h"

#define MAXN 4096

static char g_tmp[256], g_scene[1024], g_bin[1024], g_planner[1024];

typedef struct idset {
    uint64_t id[MAXN];
    size_t n;
} idset;

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}
static void ids_sort(idset *s) { qsort(s->id, s->n, sizeof s->id[0], cmp_u64); }
static void ids_add(idset *s, uint64_t id) {
    if (s->n < MAXN) s->id[s->n++] = id;
}
static int ids_has(const idset *s, uint64_t id) {
    for (size_t i = 0; i < s->n; i++)
        if (s->id[i] == id) return 1;
    return 0;
}
static int ids_equal(const idset *a, const idset *b) {
    if (a->n != b->n) return 0;
    for (size_t i = 0; i < a->n; i++)
        if (a->id[i] != b->id[i]) return 0;
    return 1;
}

static int make_models(void) {
    sooc_model_config c;
    sooc_model_config_default(&c);
    c.K = 3;
    c.d_what = 8;
    c.d_layout = 8;
    c.ref_ch[0] = c.ref_ch[1] = 8;
    c.ref_ch[2] = c.ref_ch[3] = 16;
    c.ref_fc = 16;
    c.ref_hidden = 16;
    sooc_model *m = NULL;
    char p[512];
    if (sooc_model_create(&m, &c, 11)) return -1;
    snprintf(p, sizeof p, "%s/cold.bin", g_tmp);
    if (sooc_model_save(m, p, NULL, 0)) return -1;
    /* hot: prior presence logits +5 (λ layout: [5 + 2d] = presence logit a) */
    sooc_model_tensor t[128];
    int nt = sooc_model_tensors(m, t, 128), found = 0;
    for (int i = 0; i < nt && i < 128; i++) {
        if (strcmp(t[i].name, "prior.slots")) continue;
        float *w = sooc_model_params(m) + t[i].offset;
        for (int k = 0; k < t[i].rows; k++) w[(size_t)k * t[i].cols + 5 + 2 * c.d_what] = 5.0f;
        found = 1;
    }
    snprintf(p, sizeof p, "%s/hot.bin", g_tmp);
    int rc = found && !sooc_model_save(m, p, NULL, 0) ? 0 : -1;
    sooc_model_destroy(m);
    return rc;
}

static void write_launch(const char *path, const char *model, const char *shm, const char *db, const char *speed) {
    FILE *f = fopen(path, "w");
    if (!f) return;
    fprintf(f,
            "sensor: {driver: replay, path: %s, format: auto, speed: %s}\n"
            "pose: {source: sensor, tolerance_ms: 20}\n"
            "model: {path: %s/%s.bin, threads: 1, seed: 3}\n"
            "keyframe: {translation_m: 0.10, rotation_deg: 10, time_s: 0}\n"
            "shm: {name: %s, capacity: 1024, unlink_on_exit: false}\n"
            "map: {db: '%s', resume: true}\n"
            "world: {up: +y, floor: 0.0}\n"
            "pipeline: {ring_capacity: 8, block_when_full: true, stats_period_s: 0}\n"
            "log: {level: warn}\n",
            g_scene, speed, g_tmp, model, shm, db);
    fclose(f);
}

static pid_t spawn(char *const argv[], const char *out_path) {
    fflush(NULL);   /* or the child's freopen writes our buffered output again */
    pid_t pid = fork();
    if (pid == 0) {
        if (out_path && !freopen(out_path, "w", stdout)) _exit(126);
        execv(argv[0], argv);
        _exit(127);
    }
    return pid;
}

static int wait_exit(pid_t pid, double timeout_s) {
    double t0 = sooc_seconds();
    for (;;) {
        int status = 0;
        pid_t r = waitpid(pid, &status, WNOHANG);
        if (r == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        if (sooc_seconds() - t0 > timeout_s) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            return -1;
        }
        usleep(5000);
    }
}

/* live (not REMOVED) ids in the table, and the header stamp */
static int table_ids(const char *shm, idset *out, int64_t *stamp) {
    sooc_table_reader *r = NULL;
    out->n = 0;
    if (sooc_table_open_reader(shm, &r)) return -1;
    static sooc_table_record recs[1024];
    uint32_t n = 0;
    uint64_t epoch = 0;
    int rc = sooc_table_snapshot(r, recs, 1024, &n, &epoch);
    sooc_table_info info;
    if (!rc) rc = sooc_table_get_info(r, &info);
    if (!rc && stamp) *stamp = info.stamp_ns;
    for (uint32_t i = 0; !rc && i < n; i++)
        if (!(recs[i].flags & SOOC_TABLE_FLAG_REMOVED)) ids_add(out, recs[i].object_id);
    sooc_table_close_reader(r);
    ids_sort(out);
    return rc;
}

static int visit_id(void *u, const sooc_cogmap_entry *e) {
    ids_add(u, e->id);
    return 0;
}

static int db_ids(const char *db, idset *out) {
    sooc_mapstore *s;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    out->n = 0;
    if (sooc_mapstore_open(&s, db, &p)) return -1;
    sooc_status st = sooc_mapstore_foreach(s, visit_id, out);
    sooc_mapstore_close(s);
    ids_sort(out);
    return st ? -1 : 0;
}

/* the map's id counter (ids below it were handed out; never reused) */
static uint64_t db_next_id(const char *db) {
    sooc_mapstore *s;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    sooc_mapstore_info in;
    memset(&in, 0, sizeof in);
    if (sooc_mapstore_open(&s, db, &p)) return 0;
    if (sooc_mapstore_info_get(s, &in)) in.next_id = 0;
    sooc_mapstore_close(s);
    return in.next_id;
}

/* keyframe rows and the latest keyframe stamp, straight from SQLite */
static int db_keyframes(const char *db, int64_t *n, int64_t *max_t) {
    sqlite3 *d;
    if (sqlite3_open_v2(db, &d, SQLITE_OPEN_READONLY, NULL) != SQLITE_OK) return -1;
    sqlite3_stmt *q;
    int rc = -1;
    if (sqlite3_prepare_v2(d, "SELECT count(*), coalesce(max(t_ns), 0) FROM keyframes", -1, &q, NULL) == SQLITE_OK) {
        if (sqlite3_step(q) == SQLITE_ROW) {
            *n = sqlite3_column_int64(q, 0);
            *max_t = sqlite3_column_int64(q, 1);
            rc = 0;
        }
        sqlite3_finalize(q);
    }
    sqlite3_close(d);
    return rc;
}

/* ids in `sooc3d map list --db` output (lines not starting with '#') */
static int list_ids(const char *db, idset *out) {
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "'%s' map list --db '%s'", g_bin, db);
    FILE *p = popen(cmd, "r");
    if (!p) return -1;
    out->n = 0;
    char line[1024];
    while (fgets(line, sizeof line, p)) {
        unsigned long long id;
        if (line[0] != '#' && sscanf(line, "%llu", &id) == 1) ids_add(out, id);
    }
    int st = pclose(p);
    ids_sort(out);
    return st == 0 ? 0 : -1;
}

/* planner output: rows "  id flag x z ..." ; live ids of the LAST table printed
 * go to last, ids with V and without R in any table to seen; returns tables */
static int parse_planner(const char *path, idset *last, idset *seen, size_t *max_objects) {
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    char line[1024];
    int tables = 0;
    last->n = 0;
    if (seen) seen->n = 0;
    if (max_objects) *max_objects = 0;
    while (fgets(line, sizeof line, f)) {
        unsigned long long ep, nobj;
        if (sscanf(line, "epoch %llu objects %llu", &ep, &nobj) == 2) {
            tables++;
            last->n = 0;
            if (max_objects && nobj > *max_objects) *max_objects = nobj;
            continue;
        }
        unsigned long long id;
        char fl[8];
        if (sscanf(line, " %llu %7s", &id, fl) == 2 && fl[0] == 'V' && fl[2] != 'R') {
            ids_add(last, id);
            if (seen && !ids_has(seen, id)) ids_add(seen, id);
        }
    }
    fclose(f);
    ids_sort(last);
    return tables;
}

static void print_ids(const char *what, const idset *s) {
    fprintf(stderr, "  %s (%zu):", what, s->n);
    for (size_t i = 0; i < s->n && i < 40; i++) fprintf(stderr, " %llu", (unsigned long long)s->id[i]);
    fprintf(stderr, "\n");
}

/* 1 and 3: the binary, a parallel planner, then table == db == map list */
static void run_binary(const char *model, int expect_objects) {
    char launch[512], db[512], shm[64], pout[512], pout2[512], shm_path[128];
    snprintf(shm, sizeof shm, "t_node_model_%s_%d", model, (int)getpid());
    snprintf(launch, sizeof launch, "%s/%s.yaml", g_tmp, model);
    snprintf(db, sizeof db, "%s/%s.sqlite", g_tmp, model);
    snprintf(pout, sizeof pout, "%s/planner_%s.txt", g_tmp, model);
    snprintf(pout2, sizeof pout2, "%s/planner_once_%s.txt", g_tmp, model);
    write_launch(launch, model, shm, db, "fast");
    sooc_table_shm_name(shm, shm_path, sizeof shm_path);
    shm_unlink(shm_path);

    char *pargv[] = {g_planner, shm, "--wait", "30", "--interval", "2", NULL};
    pid_t planner = spawn(pargv, pout);
    char *nargv[] = {g_bin, "node", launch, "--quiet", NULL};
    double t0 = sooc_seconds();
    pid_t node = spawn(nargv, NULL);
    int rc = wait_exit(node, 60);
    double dt = sooc_seconds() - t0;
    CHECK_MSG(rc == 0, "sooc3d node (%s model) exit %d", model, rc);
    int prc = wait_exit(planner, 20);
    CHECK_MSG(prc == 0, "planner exit %d", prc);

    idset T, D, M, P, Plast, seen;
    int64_t stamp = 0, nkf = 0, tmax = 0;
    CHECK(table_ids(shm, &T, &stamp) == 0);
    CHECK(db_ids(db, &D) == 0);
    CHECK(list_ids(db, &M) == 0);
    CHECK(db_keyframes(db, &nkf, &tmax) == 0);
    size_t max_obj = 0;
    int tables = parse_planner(pout, &Plast, &seen, &max_obj);
    char *oargv[] = {g_planner, shm, "--once", NULL};
    CHECK(wait_exit(spawn(oargv, pout2), 10) == 0);
    CHECK(parse_planner(pout2, &P, NULL, NULL) == 1);
    printf("binary, %s model: %.2f s, %lld keyframe rows, table %zu, db %zu, map list %zu, planner: %d tables "
           "while running (max %zu objects, %zu ids seen), --once %zu\n",
           model, dt, (long long)nkf, T.n, D.n, M.n, tables, max_obj, seen.n, P.n);
    CHECK_MSG(ids_equal(&T, &D), "table ids != SQLite ids");
    CHECK_MSG(ids_equal(&T, &M), "table ids != `sooc3d map list` ids");
    CHECK_MSG(ids_equal(&T, &P), "table ids != planner --once ids");
    if (!ids_equal(&T, &D) || !ids_equal(&T, &M) || !ids_equal(&T, &P)) {
        print_ids("table", &T);
        print_ids("db", &D);
        print_ids("list", &M);
        print_ids("planner", &P);
    }
    CHECK(nkf > 0);
    CHECK_MSG(tmax == stamp, "last keyframe row t_ns %lld, table stamp %lld", (long long)tmax, (long long)stamp);
    CHECK(tables >= 1);
    /* what the planner saw while the node ran is (or was) in the map: in the
     * final map, or an id the map handed out and later removed (the revisit
     * rules retire the untrained model's entries that the depth shows as free
     * space; ids are never reused) */
    uint64_t next_id = db_next_id(db);
    for (size_t i = 0; i < seen.n; i++)
        CHECK_MSG(ids_has(&D, seen.id[i]) || (seen.id[i] >= 1 && seen.id[i] < next_id),
                  "planner saw id %llu, not in the final map nor below its id counter %llu",
                  (unsigned long long)seen.id[i], (unsigned long long)next_id);
    if (expect_objects) {
        CHECK_MSG(T.n > 0, "hot model registered no objects");
        CHECK_MSG(seen.n > 0 && tables >= 2, "the planner saw no objects while the node ran");
    }
    shm_unlink(shm_path);
}

/* the map stores the id of the model that built it (its
 * checkpoint's content) and a node with another model (same shape, other
 * seed) refuses to resume it */
static void run_model_check(void) {
    char db[512], launch[512], out[512], shm[64], cmd[2200];
    snprintf(db, sizeof db, "%s/hot.sqlite", g_tmp);
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.readonly = 1;
    p.create = 0;
    sooc_mapstore *s = NULL;
    sooc_mapstore_info info;
    memset(&info, 0, sizeof info);
    CHECK_OK(sooc_mapstore_open(&s, db, &p));
    if (s) CHECK_OK(sooc_mapstore_info_get(s, &info));
    sooc_mapstore_close(s);
    CHECK_MSG(!strncmp(info.model_id, "fnv1a64:", 8), "stored model_id '%s'", info.model_id);
    snprintf(shm, sizeof shm, "t_node_model_mc_%d", (int)getpid());
    snprintf(launch, sizeof launch, "%s/model_check.yaml", g_tmp);
    snprintf(out, sizeof out, "%s/model_check.txt", g_tmp);
    /* another model of the same shape (other seed): only the model id differs */
    sooc_model_config c;
    sooc_model_config_default(&c);
    c.K = 3;
    c.d_what = 8;
    c.d_layout = 8;
    c.ref_ch[0] = c.ref_ch[1] = 8;
    c.ref_ch[2] = c.ref_ch[3] = 16;
    c.ref_fc = 16;
    c.ref_hidden = 16;
    sooc_model *m = NULL;
    char mp[512];
    snprintf(mp, sizeof mp, "%s/other.bin", g_tmp);
    CHECK_OK(sooc_model_create(&m, &c, 12));
    if (m) CHECK_OK(sooc_model_save(m, mp, NULL, 0));
    sooc_model_destroy(m);
    write_launch(launch, "other", shm, db, "fast");
    snprintf(cmd, sizeof cmd, "'%s' node '%s' --quiet > '%s' 2>&1", g_bin, launch, out);
    int rc = system(cmd);
    char text[4096] = "";
    FILE *f = fopen(out, "r");
    if (f) {
        size_t n = fread(text, 1, sizeof text - 1, f);
        text[n] = 0;
        fclose(f);
    }
    printf("model check: stored '%s'; node with another model on that map: exit %d: %s", info.model_id,
           WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, text);
    CHECK_MSG(WIFEXITED(rc) && WEXITSTATUS(rc) == 1, "node with another model resumed the map");
    CHECK_MSG(strstr(text, "map was built by model") && strstr(text, info.model_id), "message: %s", text);
    char shm_path[128];
    sooc_table_shm_name(shm, shm_path, sizeof shm_path);
    shm_unlink(shm_path);
}

/* 2: in-process with a mapper we own: table == mapper == SQLite; resume */
static sooc_status empty_read(void *ctx, sooc_frame *f, int t) {
    (void)ctx;
    (void)f;
    (void)t;
    return SOOC_EEOF;
}

static void run_inprocess(void) {
    char launch[512], db[512], shm[64], shm_path[128], text[4096];
    snprintf(shm, sizeof shm, "t_node_model_ip_%d", (int)getpid());
    snprintf(launch, sizeof launch, "%s/ip.yaml", g_tmp);
    snprintf(db, sizeof db, "%s/ip.sqlite", g_tmp);
    write_launch(launch, "hot", shm, db, "fast");
    sooc_table_shm_name(shm, shm_path, sizeof shm_path);
    shm_unlink(shm_path);
    FILE *f = fopen(launch, "r");
    size_t len = f ? fread(text, 1, sizeof text - 1, f) : 0;
    if (f) fclose(f);
    text[len] = 0;
    sooc_node_config c;
    CHECK_OK(sooc_node_config_parse(&c, text, len, launch));
    sooc_mapper_params mp;
    sooc_mapper_params_default(&mp);
    char model[512];
    snprintf(model, sizeof model, "%s/hot.bin", g_tmp);
    mp.model_path = model;
    mp.threads = 1;
    mp.seed = 3;
    sooc_mapper *m = NULL;
    CHECK_OK(sooc_mapper_create(&m, &mp));
    if (!m) return;
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.mapper = m;
    sooc_node *n = NULL;
    CHECK_OK(sooc_node_create(&n, &c, &o));
    if (!n) return;
    CHECK_OK(sooc_node_run(n));
    sooc_node_stats s;
    sooc_node_get_stats(n, &s);
    char line[512];
    sooc_node_stats_format(&s, line, sizeof line);
    printf("in-process, hot model: %s\n", line);
    sooc_node_destroy(n);

    size_t ne = 0;
    CHECK_OK(sooc_mapper_entries(m, NULL, 0, &ne));
    sooc_map_entry *e = calloc(ne + 1, sizeof *e);
    CHECK_OK(sooc_mapper_entries(m, e, ne, &ne));
    CHECK_MSG(ne > 0, "hot model: no entries");
    CHECK(s.n_objects == ne);
    idset T, D;
    CHECK(table_ids(shm, &T, NULL) == 0);
    CHECK(db_ids(db, &D) == 0);
    CHECK_MSG(T.n == ne && D.n == ne, "table %zu, db %zu, mapper %zu", T.n, D.n, ne);
    /* field by field: mapper entry vs table record vs SQLite row */
    sooc_table_reader *r = NULL;
    CHECK(sooc_table_open_reader(shm, &r) == 0);
    sooc_mapstore *st = NULL;
    sooc_mapstore_params pp;
    sooc_mapstore_params_default(&pp);
    pp.create = 0;
    CHECK_OK(sooc_mapstore_open(&st, db, &pp));
    sooc_mapstore_info info;
    memset(&info, 0, sizeof info);
    if (st) CHECK_OK(sooc_mapstore_info_get(st, &info));
    for (size_t i = 0; i < ne && r && st; i++) {
        sooc_table_record rec;
        sooc_cogmap_entry ce;
        CHECK_MSG(sooc_table_find(r, e[i].id, &rec) == 0, "id %llu not in the table", (unsigned long long)e[i].id);
        CHECK_MSG(sooc_mapstore_get(st, e[i].id, &ce) == SOOC_OK, "id %llu not in SQLite", (unsigned long long)e[i].id);
        CHECK_CLOSE(rec.x, e[i].x, 1e-5, 1e-6);
        CHECK_CLOSE(rec.z, e[i].z, 1e-5, 1e-6);
        CHECK_CLOSE(rec.presence, e[i].presence, 1e-6, 0);
        CHECK(rec.obs_count == e[i].obs_count);
        CHECK(rec.extent[1] == e[i].extent[1] && e[i].extent[1] > 0);
        /* object geometry (mapper.h, docs/shm.md): the record carries the mapper's latest */
        if (e[i].geom.flags & SOOC_GEOM_TIGHT) CHECK(rec.y == e[i].geom.centre[1]);
        CHECK(e[i].geom.cov_xz[0] > 0 && rec.cov_xzyaw[0] == (float)e[i].geom.cov_xz[0]);
        CHECK(!(rec.flags & SOOC_TABLE_FLAG_SYMMETRIC) == !(e[i].geom.flags & SOOC_GEOM_SYMMETRIC));
        CHECK(ce.X == e[i].x && ce.Z == e[i].z && ce.pres_logit == e[i].presence_logit);
        CHECK(ce.obs_count == e[i].obs_count && ce.what_mu[2] == e[i].what_mu[2]);
    }
    if (r) sooc_table_close_reader(r);
    CHECK_MSG(info.n_keyframes == s.keyframes, "keyframe rows %llu, keyframes %llu",
              (unsigned long long)info.n_keyframes, (unsigned long long)s.keyframes);
    CHECK_MSG(info.layout_dim == 8 && info.n_layout > 0, "layout dim %d, %llu blocks", info.layout_dim,
              (unsigned long long)info.n_layout);
    CHECK(info.next_id == sooc_mapper_next_id(m));
    char ext[128] = "";
    if (st) CHECK_OK(sooc_mapstore_meta_get(st, "extent", ext, sizeof ext));
    CHECK_MSG(!strcmp(ext, "1.20000005 1.20000005 1.20000005") || !strcmp(ext, "1.2 1.2 1.2"), "extent '%s'", ext);
    sooc_mapstore_close(st);

    /* restart: a fresh mapper resumes every entry and layout block */
    sooc_mapper *m2 = NULL;
    CHECK_OK(sooc_mapper_create(&m2, &mp));
    sooc_node_source src;
    memset(&src, 0, sizeof src);
    src.read = empty_read;
    o.mapper = m2;
    o.source = &src;
    CHECK_OK(sooc_node_create(&n, &c, &o));
    if (n) {
        sooc_node_stats s0;
        sooc_node_get_stats(n, &s0);
        CHECK_MSG(s0.resumed == ne && s0.resumed_blocks == info.n_layout, "resumed %llu entries, %llu blocks",
                  (unsigned long long)s0.resumed, (unsigned long long)s0.resumed_blocks);
        CHECK_OK(sooc_node_run(n));
        sooc_node_destroy(n);
    }
    size_t ne2 = 0;
    sooc_mapper_entries(m2, NULL, 0, &ne2);
    sooc_map_entry *e2 = calloc(ne2 + 1, sizeof *e2);
    sooc_mapper_entries(m2, e2, ne2, &ne2);
    CHECK(ne2 == ne);
    for (size_t i = 0; i < ne && i < ne2; i++) {
        CHECK(e2[i].id == e[i].id && e2[i].x == e[i].x && e2[i].z == e[i].z);
        CHECK(e2[i].extent[0] == e[i].extent[0] && e2[i].what_mu[0] == e[i].what_mu[0]);
        CHECK(e2[i].geom.flags == e[i].geom.flags && e2[i].geom.reg_n == e[i].geom.reg_n);   /* stored geometry */
    }
    CHECK(sooc_mapper_next_id(m2) == sooc_mapper_next_id(m));
    /* layout blocks equal */
    const sooc_cogmap *c1 = sooc_mapper_cogmap(m), *c2 = sooc_mapper_cogmap(m2);
    CHECK(sooc_cogmap_layout_count(c1) == sooc_cogmap_layout_count(c2));
    int32_t bi, bj;
    float mu1[32], lv1[32], mu2[32], lv2[32];
    if (!sooc_mapper_last_layout(m, &bi, &bj, mu1, lv1)) {
        CHECK_OK(sooc_cogmap_layout_get(c2, bi, bj, mu2, lv2));
        CHECK(!memcmp(mu1, mu2, 8 * sizeof(float)) && !memcmp(lv1, lv2, 8 * sizeof(float)));
    } else {
        CHECK_MSG(0, "mapper has no last layout block");
    }
    free(e);
    free(e2);
    sooc_mapper_destroy(m);
    sooc_mapper_destroy(m2);
    shm_unlink(shm_path);
}

/* 4: SIGINT mid-run with the hot model */
static void run_sigint(void) {
    char launch[512], db[512], shm[64], shm_path[128];
    snprintf(shm, sizeof shm, "t_node_model_sig_%d", (int)getpid());
    snprintf(launch, sizeof launch, "%s/sig.yaml", g_tmp);
    snprintf(db, sizeof db, "%s/sig.sqlite", g_tmp);
    write_launch(launch, "hot", shm, db, "realtime");
    sooc_table_shm_name(shm, shm_path, sizeof shm_path);
    shm_unlink(shm_path);
    char *nargv[] = {g_bin, "node", launch, "--quiet", NULL};
    pid_t node = spawn(nargv, NULL);
    /* wait until at least two keyframes are in the table (epoch >= 3) */
    double t0 = sooc_seconds();
    uint64_t epoch = 0;
    sooc_table_reader *r = NULL;
    while (sooc_seconds() - t0 < 30) {
        if (!r && sooc_table_open_reader(shm, &r)) r = NULL;
        if (r) {
            sooc_table_info info;
            if (!sooc_table_get_info(r, &info)) epoch = info.epoch;
            if (epoch >= 3) break;
        }
        usleep(2000);
    }
    if (r) sooc_table_close_reader(r);
    CHECK_MSG(epoch >= 3, "table epoch %llu after 30 s", (unsigned long long)epoch);
    kill(node, SIGINT);
    double ts = sooc_seconds();
    int rc = wait_exit(node, 30);
    double stop_s = sooc_seconds() - ts;
    CHECK_MSG(rc == 0, "sooc3d node after SIGINT: exit %d", rc);
    idset T, D;
    int64_t stamp = 0, nkf = 0, tmax = 0;
    CHECK(table_ids(shm, &T, &stamp) == 0);
    CHECK(db_ids(db, &D) == 0);
    CHECK(db_keyframes(db, &nkf, &tmax) == 0);
    printf("SIGINT, hot model: stopped %.3f s after the signal, %lld keyframe rows, table %zu ids, db %zu\n", stop_s,
           (long long)nkf, T.n, D.n);
    CHECK_MSG(ids_equal(&T, &D), "table ids != SQLite ids after SIGINT");
    CHECK(T.n > 0);
    CHECK(nkf >= 2);
    CHECK_MSG(nkf < 40, "the node was not stopped mid-run (%lld keyframes)", (long long)nkf);
    CHECK_MSG(tmax == stamp && stamp > 0, "last keyframe row %lld, table stamp %lld", (long long)tmax,
              (long long)stamp);
    /* the writer closed cleanly */
    if (!sooc_table_open_reader(shm, &r)) {
        sooc_table_liveness lv;
        CHECK(sooc_table_writer_alive(r, &lv) == 0 && lv.exited);
        sooc_table_close_reader(r);
    }
    shm_unlink(shm_path);
}

int main(void) {
    const char *bin = getenv("SOOC_BIN");
    if (!bin || access(bin, X_OK)) {
        fprintf(stderr, "test_node_model: SOOC_BIN (the sooc3d binary) is not set or not executable: skipped\n");
        return 77;
    }
    snprintf(g_bin, sizeof g_bin, "%s", bin);
    const char *pl = getenv("SOOC_PLANNER_BIN");
    if (pl) {
        snprintf(g_planner, sizeof g_planner, "%s", pl);
    } else {
        snprintf(g_planner, sizeof g_planner, "%s", bin);
        char *slash = strrchr(g_planner, '/');
        snprintf(slash ? slash + 1 : g_planner, sizeof g_planner - (size_t)(slash ? slash + 1 - g_planner : 0),
                 "sooc3d-planner-example");
    }
    if (access(g_planner, X_OK)) {
        fprintf(stderr, "test_node_model: %s missing: skipped\n", g_planner);
        return 77;
    }
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc3d_test_node_model.%d", (int)getpid());
    CHECK_OK(sooc_mkdirs(g_tmp));
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.preset = SOOC_GEN_UNITY;
    gp.scale = SOOC_GEN_S;
    gp.seed = 5;
    gp.n_scenes = 1;
    gp.n_views = 40;
    gp.n_query = 0;
    gp.threads = 1;
    gp.write_meshes = 0;
    gp.contact_sheet = 0;
    char gen_dir[512];
    snprintf(gen_dir, sizeof gen_dir, "%s/gen", g_tmp);
    CHECK_OK(sooc_gen_run(&gp, gen_dir, NULL, NULL, NULL));
    snprintf(g_scene, sizeof g_scene, "%s/scene_0000", gen_dir);
    CHECK(make_models() == 0);
    if (check_report("test_node_model setup")) return 1;

    run_binary("hot", 1);
    run_inprocess();
    run_binary("cold", 0);
    run_model_check();
    run_sigint();

    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (!check_report("test_node_model") && !getenv("SOOC_KEEP")) {
        if (system(cmd)) fprintf(stderr, "cleanup of %s failed\n", g_tmp);
        return 0;
    }
    fprintf(stderr, "test_node_model: outputs kept in %s\n", g_tmp);
    return 1;
}
