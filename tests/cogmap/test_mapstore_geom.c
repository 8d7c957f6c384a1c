/* Object geometry in the map database (schema 3, cogmap.h "object
 * geometry"): round trip (NaN yaw variance kept as "undefined"), the delete
 * trigger, refused non-finite values; migrations applied in order: a
 * version-2 map (finetuned decoders, no geometry) and a version-1 map
 * (tests/finetune/map_v1_unity_m.sqlite) open
 * read-write as version 3 with their entries intact; opened read-only they
 * read no geometry. */
#include <math.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/cogmap.h"

static char g_dir[64];

static void sql(const char *path, const char *q) {
    sqlite3 *db = NULL;
    CHECK(sqlite3_open(path, &db) == SQLITE_OK);
    char *err = NULL;
    int rc = sqlite3_exec(db, q, NULL, NULL, &err);
    CHECK_MSG(rc == SQLITE_OK, "%s: %s", q, err ? err : "");
    sqlite3_free(err);
    sqlite3_close(db);
}

static int has_table(const char *path, const char *name) {
    sqlite3 *db = NULL;
    sqlite3_stmt *q = NULL;
    int r = 0;
    if (sqlite3_open(path, &db) == SQLITE_OK &&
        sqlite3_prepare_v2(db, "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?1", -1, &q, NULL) ==
            SQLITE_OK) {
        sqlite3_bind_text(q, 1, name, -1, SQLITE_STATIC);
        r = sqlite3_step(q) == SQLITE_ROW;
    }
    sqlite3_finalize(q);
    sqlite3_close(db);
    return r;
}

static void entry(sooc_cogmap_entry *e, uint64_t id, int d) {
    memset(e, 0, sizeof *e);
    e->id = id;
    e->X = 0.5 * (double)id, e->Z = -1.0, e->Theta = 0.2;
    e->rho_t = -6, e->rho_theta = -2, e->pres_logit = 3;
    e->dim = d;
    for (int i = 0; i < d; i++) e->what_mu[i] = 0.1f * (float)i, e->what_logvar[i] = -1;
    e->obs_count = 2;
}

static void geom(sooc_map_geometry *g, float ext[3], int sym) {
    memset(g, 0, sizeof *g);
    g->flags = SOOC_GEOM_TIGHT | (sym ? SOOC_GEOM_SYMMETRIC : 0u);
    ext[0] = 0.41f, ext[1] = 0.52f, ext[2] = 0.33f;
    g->centre[0] = 0.01f, g->centre[1] = 0.26f, g->centre[2] = -0.02f;
    g->sym_iou = sym ? 0.95f : 0.6f;
    g->cov_xz[0] = 0.0021, g->cov_xz[1] = -0.0003, g->cov_xz[2] = 0.0017;
    g->var_yaw = sym ? NAN : 0.12;
    g->reg_n = 5;
    g->reg_mean[0] = 1.25, g->reg_mean[1] = -0.75;
    g->reg_m2[0] = 0.004, g->reg_m2[1] = 0.0005, g->reg_m2[2] = 0.003;
    g->reg_cs[0] = 4.9, g->reg_cs[1] = 0.8;
}

static void test_round_trip(const char *path) {
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.dim = 4;
    sooc_mapstore *s = NULL;
    CHECK_OK(sooc_mapstore_open(&s, path, &mp));
    if (!s) return;
    sooc_mapstore_info info;
    CHECK_OK(sooc_mapstore_info_get(s, &info));
    CHECK(info.schema_version == 3 && SOOC_MAPSTORE_SCHEMA_VERSION == 3);
    sooc_cogmap_entry e[3];
    for (int i = 0; i < 3; i++) entry(&e[i], (uint64_t)i + 1, 4);
    CHECK_OK(sooc_mapstore_begin(s));
    CHECK_OK(sooc_mapstore_put_entries(s, e, 3));
    sooc_map_geometry g1, g2, r;
    float x1[3], x2[3], rx[3] = {-1, -1, -1};
    geom(&g1, x1, 0);
    geom(&g2, x2, 1);
    CHECK_OK(sooc_mapstore_geom_put(s, 1, x1, &g1));
    CHECK_OK(sooc_mapstore_geom_put(s, 2, x2, &g2));
    CHECK_OK(sooc_mapstore_commit(s));
    int found = -1;
    CHECK_OK(sooc_mapstore_geom_get(s, 1, rx, &r, &found));
    CHECK(found == 1);
    CHECK(rx[0] == x1[0] && rx[1] == x1[1] && rx[2] == x1[2]);
    CHECK(r.flags == g1.flags && r.centre[1] == g1.centre[1] && r.sym_iou == g1.sym_iou);
    CHECK(r.cov_xz[1] == g1.cov_xz[1] && r.var_yaw == g1.var_yaw && r.reg_n == 5);
    CHECK(r.reg_mean[0] == g1.reg_mean[0] && r.reg_m2[2] == g1.reg_m2[2] && r.reg_cs[1] == g1.reg_cs[1]);
    CHECK_OK(sooc_mapstore_geom_get(s, 2, rx, &r, &found));
    CHECK(found == 1 && isnan(r.var_yaw) && (r.flags & SOOC_GEOM_SYMMETRIC));
    CHECK_OK(sooc_mapstore_geom_get(s, 3, rx, &r, &found));
    CHECK(found == 0);
    /* an entry upsert keeps its geometry (other table); deleting the entry deletes it */
    CHECK_OK(sooc_mapstore_put_entries(s, &e[0], 1));
    CHECK_OK(sooc_mapstore_geom_get(s, 1, rx, &r, &found));
    CHECK(found == 1);
    uint64_t id1 = 1;
    CHECK_OK(sooc_mapstore_remove_entries(s, &id1, 1));
    CHECK_OK(sooc_mapstore_geom_get(s, 1, rx, &r, &found));
    CHECK(found == 0);
    /* non-finite values are refused, naming the database */
    g1.cov_xz[0] = INFINITY;
    sooc_status st = sooc_mapstore_geom_put(s, 2, x1, &g1);
    CHECK(st == SOOC_ENUMERIC);
    CHECK(strstr(sooc_errmsg(), path) != NULL);
    sooc_clearerr();
    sooc_mapstore_close(s);
}

/* a version-2 map: the schema before object geometry (drop what 3 added) */
static void test_migrate_v2(const char *path) {
    sql(path, "DROP TRIGGER entries_ad_geom; DROP TABLE entry_geometry;"
              "UPDATE meta SET value = '2' WHERE key = 'schema_version';");
    CHECK(!has_table(path, "entry_geometry"));
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.readonly = 1;
    sooc_mapstore *s = NULL;
    CHECK_OK(sooc_mapstore_open(&s, path, &mp));   /* read-only: opens as version 2, no geometry */
    if (s) {
        sooc_mapstore_info info;
        CHECK_OK(sooc_mapstore_info_get(s, &info));
        CHECK(info.schema_version == 2 && info.n_entries == 2);
        sooc_map_geometry g;
        float x[3];
        int found = -1;
        CHECK_OK(sooc_mapstore_geom_get(s, 2, x, &g, &found));
        CHECK(found == 0);
        geom(&g, x, 0);
        CHECK(sooc_mapstore_geom_put(s, 2, x, &g) != SOOC_OK);
        sooc_clearerr();
        sooc_mapstore_close(s);
    }
    CHECK(!has_table(path, "entry_geometry"));   /* a read-only open changes nothing */
    mp.readonly = 0;
    s = NULL;
    CHECK_OK(sooc_mapstore_open(&s, path, &mp));   /* read-write: migrated 2 -> 3 */
    if (s) {
        sooc_mapstore_info info;
        CHECK_OK(sooc_mapstore_info_get(s, &info));
        CHECK(info.schema_version == 3 && info.n_entries == 2);
        sooc_map_geometry g, r;
        float x[3], rx[3];
        geom(&g, x, 1);
        CHECK_OK(sooc_mapstore_geom_put(s, 3, x, &g));
        int found = 0;
        CHECK_OK(sooc_mapstore_geom_get(s, 3, rx, &r, &found));
        CHECK(found == 1 && rx[1] == x[1]);
        sooc_mapstore_close(s);
    }
    CHECK(has_table(path, "entry_geometry"));
}

/* a version-1 map (no payloads, no geometry): both migrations, in order */
static void test_migrate_v1(void) {
    const char *fix = "tests/finetune/map_v1_unity_m.sqlite";
    FILE *fi = fopen(fix, "rb");
    if (!fi) {
        printf("test_mapstore_geom: %s not found (run from the repository root): v1 part skipped\n", fix);
        return;
    }
    char path[128];
    snprintf(path, sizeof path, "%s/v1.sqlite", g_dir);
    FILE *fo = fopen(path, "wb");
    CHECK(fo != NULL);
    if (!fo) {
        fclose(fi);
        return;
    }
    char buf[4096];
    size_t k;
    while ((k = fread(buf, 1, sizeof buf, fi)) > 0) CHECK(fwrite(buf, 1, k, fo) == k);
    fclose(fi);
    fclose(fo);
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.readonly = 1;
    sooc_mapstore *s = NULL;
    uint64_t n1 = 0;
    CHECK_OK(sooc_mapstore_open(&s, path, &mp));
    if (s) {
        sooc_mapstore_info info;
        CHECK_OK(sooc_mapstore_info_get(s, &info));
        CHECK(info.schema_version == 1);
        n1 = info.n_entries;
        sooc_mapstore_close(s);
    }
    mp.readonly = 0;
    s = NULL;
    CHECK_OK(sooc_mapstore_open(&s, path, &mp));
    if (s) {
        sooc_mapstore_info info;
        CHECK_OK(sooc_mapstore_info_get(s, &info));
        CHECK(info.schema_version == 3 && info.n_entries == n1 && n1 > 0);
        sooc_mapstore_close(s);
    }
    CHECK(has_table(path, "ft_objects") && has_table(path, "entry_geometry"));
}

int main(void) {
    snprintf(g_dir, sizeof g_dir, "/tmp/sooc_mapgeom_XXXXXX");
    if (!mkdtemp(g_dir)) {
        perror("mkdtemp");
        return 1;
    }
    char path[128];
    snprintf(path, sizeof path, "%s/map.sqlite", g_dir);
    test_round_trip(path);
    test_migrate_v2(path);
    test_migrate_v1();
    char cmd[160];
    snprintf(cmd, sizeof cmd, "rm -rf %s", g_dir);
    if (system(cmd) != 0) fprintf(stderr, "test_mapstore_geom: could not remove %s\n", g_dir);
    return check_report("test_mapstore_geom");
}
