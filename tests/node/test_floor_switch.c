/* The support plane after start-up (docs/node.md "Support plane", rule 4;
 * src/node/floor_watch.c): the node with the geometric map over ray-cast frames of
 * a table on a floor. The first 12 keyframes look down at the table top from
 * 0.5 m (no floor in view: the map's plane is the table top, a cup on it is an
 * entry); the next 24 step back and see the floor in front of the table and a
 * box standing on it.
 *  1. world.floor_switch on (default): one switch; the world frame's plane is
 *     the floor (within 2 cm), in the stats, the table header and the store;
 *     the cup's entry is removed, in the table and the store; the floor box
 *     is an entry with its height from the floor.
 *  2. floor_switch: false: the table top stays and the cup keeps its entry
 *     (negative control).
 *  3. camera heights 0.3-0.9 m given: the floor lies 1.5 m below the camera,
 *     outside them: the table top stays. */
#include "check.h"
#include "raycast_scene.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"
#include "sooc3d/table.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define DEG (3.14159265358979323846 / 180.0)
#define N1 12
#define N2 24

/* the node's log lines about the support plane: printed, and counted */
static int g_said_switch, g_said_stays;
static void log_cb(void *user, sooc_log_level level, const char *msg) {
    (void)user;
    (void)level;
    if (strstr(msg, "support plane") || strstr(msg, "level plane")) fprintf(stderr, "    log: %s\n", msg);
    g_said_switch += strstr(msg, "the map restarts in the new frame") != NULL;
    g_said_stays += strstr(msg, "the support plane stays") != NULL;
}

typedef struct src {
    const scene *s;
    int i;
} src;

static sooc_status src_read(void *ctx, sooc_frame *f, int timeout_ms) {
    src *c = ctx;
    (void)timeout_ms;
    if (c->i >= N1 + N2) return SOOC_EEOF;
    int i = c->i++;
    if (i < N1) {   /* over the table top, 0.5 m above it, looking down 75 deg */
        double pos[3] = {-0.1 + 0.2 * i / (N1 - 1), 1.25, -0.2};
        render(c->s, f, pos, 0, 75 * DEG, 100 + (uint64_t)i);
    } else {        /* stepped back: 1.5 m above the floor, 1.2 m in front of the table, looking down 50 deg */
        int k = i - N1;
        double pos[3] = {-0.3 + 0.6 * k / (N2 - 1), 1.5, -1.2};
        render(c->s, f, pos, 0, 50 * DEG, 100 + (uint64_t)i);
    }
    memset(f->rgb, 128, (size_t)f->width * f->height * 3);
    f->t_ns = 1000000000LL + (int64_t)i * 100000000LL;
    f->index = i;
    return SOOC_OK;
}

typedef struct result {
    uint64_t switches, removed, kf;
    double plane_y;            /* world y of the source's image of the world origin (the floor's point) */
    double store_plane_y;      /* the same with the stored frame */
    double header_plane_y;     /* the same with the table header's T_src_map */
    int floor_box;             /* an entry at the floor box with its height */
    int cup;                   /* an entry at the cup with its height above the table top */
    size_t n_entries;
} result;

/* world y of the floor point (world origin) under T_world_src */
static double floor_y(const double T_world_src[16]) {
    double Tsw[16], T[16];
    src_from_world(Tsw);
    sooc_se3_mul(T, T_world_src, Tsw);
    return T[7];
}

static void run(const scene *sc, const char *dir, const char *tag, const char *world_extra, result *r) {
    memset(r, 0, sizeof *r);
    char db[600], shm[64], text[2048];
    snprintf(db, sizeof db, "%s/%s.sqlite", dir, tag);
    snprintf(shm, sizeof shm, "sooc_fsw_%s_%d", tag, (int)getpid());
    snprintf(text, sizeof text,
             "sensor: {driver: replay, path: unused}\n"
             "pose: {source: sensor}\n"
             "model: {kind: geometric, join_m: 0.02, width: 160, height: 120}\n"
             "keyframe: {translation_m: 0.01, rotation_deg: 5, time_s: 0}\n"
             "shm: {name: %s, capacity: 64, unlink_on_exit: false}\n"
             "map: {db: '%s', resume: false}\n"
             "world: {up: +z, floor: estimate, gravity: none%s}\n"
             "pipeline: {ring_capacity: 4, block_when_full: true, stats_period_s: 0}\n"
             "log: {level: info}\n",
             shm, db, world_extra);
    sooc_node_config c;
    CHECK_OK(sooc_node_config_parse(&c, text, strlen(text), "floor_switch.yaml"));
    src s = {sc, 0};
    sooc_node_source ns;
    memset(&ns, 0, sizeof ns);
    ns.ctx = &s;
    ns.read = src_read;
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.source = &ns;
    sooc_node *n = NULL;
    sooc_status st = sooc_node_create(&n, &c, &o);
    CHECK_MSG(st == SOOC_OK, "%s", sooc_errmsg());
    if (st) return;
    CHECK_OK(sooc_node_run(n));
    sooc_node_stats ss;
    sooc_node_get_stats(n, &ss);
    r->switches = ss.floor_switches, r->removed = ss.removed, r->kf = ss.keyframes;
    r->plane_y = floor_y(ss.T_world_src);
    /* the table header, before the node goes */
    sooc_table_reader *tr = NULL;
    CHECK(sooc_table_open_reader(shm, &tr) == SOOC_TABLE_OK);
    if (tr) {
        sooc_table_info hi;
        CHECK(sooc_table_get_info(tr, &hi) == SOOC_TABLE_OK);
        double T_ws[16];
        sooc_se3_inverse(T_ws, hi.T_src_map);
        r->header_plane_y = floor_y(T_ws);
        sooc_table_close_reader(tr);
    }
    sooc_node_destroy(n);
    /* the store: its world frame and its entries */
    sooc_mapstore *ms = NULL;
    sooc_mapstore_params mpar;
    sooc_mapstore_params_default(&mpar);
    CHECK_OK(sooc_mapstore_open(&ms, db, &mpar));
    if (!ms) return;
    sooc_map_frame mf;
    int found = 0;
    CHECK_OK(sooc_mapstore_frame_get(ms, &mf, &found));
    CHECK(found);
    r->store_plane_y = floor_y(mf.T_world_src);
    sooc_map_entry *e = NULL;
    size_t ne = 0;
    CHECK_OK(sooc_mapstore_planner_entries(ms, &e, &ne));
    r->n_entries = ne;
    /* the floor box (world x 0..0.2, z -0.8..-0.65, 0.2 m high) in the map */
    double Tsw[16], T[16];
    src_from_world(Tsw);
    sooc_se3_mul(T, mf.T_world_src, Tsw);   /* world (test) -> map */
    double bw[3] = {0.1, 0.0, -0.725}, bm[3], cw[3] = {0.0, 0.0, 0.025}, cm[3];
    sooc_se3_apply(bm, T, bw);
    sooc_se3_apply(cm, T, cw);
    for (size_t i = 0; i < ne; i++) {
        double d = hypot(e[i].x - bm[0], e[i].z - bm[2]);
        printf("  %s: entry %llu at (%.3f, %.3f), extent %.3f x %.3f x %.3f; floor box at (%.3f, %.3f): %.3f m\n", tag,
               (unsigned long long)e[i].id, e[i].x, e[i].z, e[i].extent[0], e[i].extent[1], e[i].extent[2], bm[0],
               bm[2], d);
        if (d < 0.05 && fabs(e[i].extent[1] - 0.2) < 0.03) r->floor_box = 1;
        if (hypot(e[i].x - cm[0], e[i].z - cm[2]) < 0.05 && fabs(e[i].extent[1] - 0.15) < 0.03) r->cup = 1;
    }
    sooc_free(e);
    sooc_mapstore_close(ms);
    char p[700];
    snprintf(p, sizeof p, "/dev/shm/%s", shm);
    unlink(p);
    printf("%s: %llu keyframes, %llu floor switches, %llu removed, %zu entries; the floor at map y = %.3f (table "
           "header %.3f, store %.3f)\n",
           tag, (unsigned long long)r->kf, (unsigned long long)r->switches, (unsigned long long)r->removed,
           r->n_entries, r->plane_y, r->header_plane_y, r->store_plane_y);
}

int main(void) {
    scene sc = {0};
    add(&sc, 1, 0.0, -4, 4, -4, 4);                          /* the floor */
    add_box(&sc, -0.6, 0, -0.4, 0.6, 0.75, 0.4);             /* the table */
    add_box(&sc, -0.1, 0.75, -0.05, 0.1, 0.9, 0.1);          /* a cup on it */
    add_box(&sc, 0.0, 0.0, -0.8, 0.2, 0.2, -0.65);           /* a box on the floor */
    char dir[] = "/tmp/sooc_fsw_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    result a, b, c;
    sooc_log_set_callback(log_cb, NULL);

    run(&sc, dir, "switch", "", &a);
    CHECK_MSG(a.kf == N1 + N2, "keyframes %llu", (unsigned long long)a.kf);
    CHECK_MSG(a.switches == 1, "switches %llu", (unsigned long long)a.switches);
    CHECK_MSG(fabs(a.plane_y) < 0.02, "the floor at map y = %.3f", a.plane_y);
    CHECK_MSG(fabs(a.header_plane_y - a.plane_y) < 1e-6 && fabs(a.store_plane_y - a.plane_y) < 1e-6,
              "header %.4f, store %.4f, node %.4f", a.header_plane_y, a.store_plane_y, a.plane_y);
    CHECK_MSG(!a.cup && a.removed >= 1, "the cup's entry (made on the table top) is still stored (%llu removed)",
              (unsigned long long)a.removed);
    CHECK_MSG(a.floor_box, "no entry for the box on the floor with its 0.2 m height");
    CHECK(g_said_switch == 1 && g_said_stays == 0);

    run(&sc, dir, "no_switch", ", floor_switch: false", &b);
    CHECK(b.switches == 0);
    CHECK_MSG(b.cup, "no entry for the cup on the table top");
    CHECK_MSG(fabs(b.plane_y + 0.75) < 0.02, "the table top at map y = %.3f, want -0.75 for the floor", b.plane_y);

    run(&sc, dir, "out_of_range", ", camera_height_min_m: 0.3, camera_height_max_m: 0.9", &c);
    CHECK(c.switches == 0);
    CHECK_MSG(fabs(c.plane_y + 0.75) < 0.02, "the table top at map y = %.3f", c.plane_y);
    CHECK(g_said_switch == 1 && g_said_stays == 1);   /* said once, not at every check */

    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    CHECK(system(cmd) == 0);
    return check_report("test_floor_switch");
}
