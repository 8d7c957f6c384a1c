/* `sooc3d mesh` and `sooc3d map export --ply DIR --model M` on a tiny model
 * whose decoders are set to known fields: every object's density is ~1 in
 * its whole locality box and its colour a constant, the layout's density ~1
 * everywhere. So each object_<id>.ply must be exactly its box, placed at the
 * entry's world pose (frames), closed, with the set colour; scene.ply holds
 * the objects plus one box per layout block; map export writes the same
 * bytes. Also: the metric of a map against a scene whose GT objects are
 * boxes the size of the locality box at the entries' poses is ~0 cm, and
 * the CLI's errors. Runs $SOOC_BIN (skipped without it). */
#include "check.h"
#include "cli_util.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/render.h"
#include "sooc3d/model.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void set_tensor(sooc_model *m, const char *name, const float *v, int fill_all, float fill) {
    sooc_model_tensor t[256];
    int n = sooc_model_tensors(m, t, 256);
    float *p = sooc_model_params(m);
    for (int i = 0; i < n; i++)
        if (!strcmp(t[i].name, name)) {
            for (size_t k = 0; k < t[i].count; k++) p[t[i].offset + k] = fill_all ? fill : v[k];
            return;
        }
    CHECK_MSG(0, "no tensor %s", name);
}

static const double g_pose[2][3] = {{1.0, -2.0, 0.7}, {-1.5, 0.5, -2.0}};

static void check_object(const char *path, const double pose[3], double Rh, double Hb) {
    sooc_mesh m = {0};
    CHECK_OK(sooc_mesh_read_ply(path, &m));
    CHECK_MSG(m.n_tri > 0, "%s is empty", path);
    CHECK(sooc_mesh_is_closed(&m, NULL));
    CHECK_CLOSE(sooc_mesh_volume(&m), 4 * Rh * Rh * Hb, 1e-4, 1e-4);
    double c = cos(pose[2]), s = sin(pose[2]), worst = 0, ext[3] = {0, 0, 0};
    for (size_t i = 0; i < m.n_vert; i++) {
        /* world -> box frame: R_y(yaw)^T (p - (X, 0, Z)) */
        double dx = m.xyz[3 * i] - pose[0], y = m.xyz[3 * i + 1], dz = m.xyz[3 * i + 2] - pose[1];
        double lx = c * dx - s * dz, lz = s * dx + c * dz;
        double e = fmax(fmax(fabs(lx) - Rh, fabs(lz) - Rh), fmax(-y, y - Hb));
        if (e > worst) worst = e;
        ext[0] = fmax(ext[0], fabs(lx)), ext[1] = fmax(ext[1], y), ext[2] = fmax(ext[2], fabs(lz));
    }
    CHECK_MSG(worst < 1e-4, "%s: a vertex lies %g m outside the entry's box in the world", path, worst);
    CHECK_CLOSE(ext[0], Rh, 1e-4, 0);
    CHECK_CLOSE(ext[1], Hb, 1e-4, 0);
    CHECK_CLOSE(ext[2], Rh, 1e-4, 0);
    /* the colour head's output for bias (2, -2, 0) and zero weights: red high, green low, blue mid,
     * the same at every vertex */
    CHECK_MSG(m.rgb[0] > 180 && m.rgb[1] < 75 && m.rgb[2] > 100 && m.rgb[2] < 156, "rgb %d %d %d", m.rgb[0], m.rgb[1],
              m.rgb[2]);
    size_t same = 0;
    for (size_t i = 0; i < m.n_vert; i++) same += !memcmp(m.rgb + 3 * i, m.rgb, 3);
    CHECK(same == m.n_vert);
    sooc_mesh_free(&m);
}

int main(void) {
    const char *bin = getenv("SOOC_BIN");
    if (!bin || access(bin, X_OK) != 0) {
        printf("test_mesh_cli: SOOC_BIN not set or not executable (%s); skipping\n", bin ? bin : "unset");
        return SOOC_TEST_SKIP;
    }
    char dir[] = "/tmp/sooc_meshcli_XXXXXX", model[512], db[512], cmd[4096], path[600];
    if (!mkdtemp(dir)) return 1;
    snprintf(model, sizeof model, "%s/tiny.bin", dir);
    snprintf(db, sizeof db, "%s/map.sqlite", dir);

    /* the tiny model with known decoders */
    tc_tiny_model(model);
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_load(&m, model, NULL, NULL));
    if (!m) return check_report("test_mesh_cli");
    const sooc_model_config *c = sooc_model_get_config(m);
    double Rh = c->box_rh * c->unit_m, Hb = c->box_hb * c->unit_m, bs = c->block_size * c->unit_m;
    const float one = 8.0f, bc2[3] = {2.0f, -2.0f, 0.0f};
    set_tensor(m, "dec.obj.Wd", NULL, 1, 0.0f);
    set_tensor(m, "dec.obj.bd", &one, 0, 0);
    set_tensor(m, "dec.obj.Wc2", NULL, 1, 0.0f);
    set_tensor(m, "dec.obj.bc2", bc2, 0, 0);
    set_tensor(m, "dec.lay.Wd", NULL, 1, 0.0f);
    set_tensor(m, "dec.lay.bd", &one, 0, 0);
    CHECK_OK(sooc_model_save(m, model, NULL, 0));

    /* a map: two entries, one layout block */
    sooc_cogmap_params mp;
    sooc_cogmap_params_default(&mp);
    mp.dim = c->d_what, mp.layout_dim = c->d_layout, mp.block_size = bs;
    sooc_cogmap *map = NULL;
    CHECK_OK(sooc_cogmap_create(&map, &mp));
    for (int i = 0; i < 2; i++) {
        sooc_cogmap_entry e;
        memset(&e, 0, sizeof e);
        e.X = g_pose[i][0], e.Z = g_pose[i][1], e.Theta = g_pose[i][2];
        e.rho_t = -4, e.rho_theta = -2, e.pres_logit = 3, e.dim = c->d_what, e.obs_count = 1;
        CHECK_OK(sooc_cogmap_insert(map, &e, NULL));
    }
    float mu[8] = {0}, lv[8] = {0};
    CHECK_OK(sooc_cogmap_layout_set(map, 0, -1, mu, lv));
    sooc_mapstore_params sp;
    sooc_mapstore_params_default(&sp);
    sp.dim = c->d_what, sp.layout_dim = c->d_layout, sp.block_size = bs;
    sooc_mapstore *s = NULL;
    CHECK_OK(sooc_mapstore_open(&s, db, &sp));
    if (s) CHECK_OK(sooc_mapstore_save_map(s, map));
    sooc_mapstore_close(s);

    /* sooc3d mesh */
    snprintf(cmd, sizeof cmd, "'%s' mesh --map '%s' --model '%s' --out '%s/m' --res 12 --layout-cell 0.25", bin, db,
             model, dir);
    CHECK(tc_run(cmd) == 0);
    for (int i = 0; i < 2; i++) {
        snprintf(path, sizeof path, "%s/m/object_%d.ply", dir, i + 1);
        check_object(path, g_pose[i], Rh, Hb);
    }
    {
        sooc_mesh sc = {0};
        snprintf(path, sizeof path, "%s/m/scene.ply", dir);
        CHECK_OK(sooc_mesh_read_ply(path, &sc));
        CHECK(sooc_mesh_is_closed(&sc, NULL));
        /* two object boxes + the layout block (block (0, -1): x in [0, 4), z in [-4, 0)) over y -0.25..3 */
        double want = 2 * 4 * Rh * Rh * Hb + bs * bs * 3.25 * c->unit_m;
        CHECK_CLOSE(sooc_mesh_volume(&sc), want, 1e-3, 1e-4);
        double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
        for (size_t i = 0; i < sc.n_vert; i++)
            for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], sc.xyz[3 * i + d]), hi[d] = fmax(hi[d], sc.xyz[3 * i + d]);
        CHECK_CLOSE(lo[1], -0.25, 1e-4, 0);
        CHECK_CLOSE(hi[1], 3.0, 1e-4, 0);
        printf("scene.ply: %zu vertices, %zu triangles, volume %.4f (want %.4f)\n", sc.n_vert, sc.n_tri,
               sooc_mesh_volume(&sc), want);
        sooc_mesh_free(&sc);
    }

    /* map export --ply DIR --model M writes the same files */
    snprintf(cmd, sizeof cmd, "'%s' map export --db '%s' --ply '%s/x' --model '%s' --res 12 --layout-cell 0.25", bin,
             db, dir, model);
    CHECK(tc_run(cmd) == 0);
    const char *names[3] = {"object_1.ply", "object_2.ply", "scene.ply"};
    for (int i = 0; i < 3; i++) {
        char a[700], b[700];
        snprintf(a, sizeof a, "%s/m/%s", dir, names[i]);
        snprintf(b, sizeof b, "%s/x/%s", dir, names[i]);
        snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s'", a, b);
        CHECK_MSG(tc_run(cmd) == 0, "%s differs between mesh and map export", names[i]);
    }
    /* --box keeps the objects whose floor point is inside */
    snprintf(cmd, sizeof cmd,
             "'%s' map export --db '%s' --ply '%s/b' --model '%s' --res 8 --layout-cell 0.5 --box 0 -3 2 -1", bin, db,
             dir, model);
    CHECK(tc_run(cmd) == 0);
    snprintf(path, sizeof path, "%s/b/object_1.ply", dir);
    CHECK(access(path, F_OK) == 0);
    snprintf(path, sizeof path, "%s/b/object_2.ply", dir);
    CHECK(access(path, F_OK) != 0);

    /* errors: missing options, a bad level, a missing map (named) */
    snprintf(cmd, sizeof cmd, "'%s' mesh --map '%s' --out '%s/e' 2>/dev/null", bin, db, dir);
    CHECK(tc_run(cmd) == 2);
    snprintf(cmd, sizeof cmd, "'%s' mesh --map '%s' --model '%s' --out '%s/e' --level 1.5 2>/dev/null", bin, db, model, dir);
    CHECK(tc_run(cmd) == 2);
    snprintf(cmd, sizeof cmd, "'%s' mesh --map '%s/none.sqlite' --model '%s' --out '%s/e' 2>'%s/err.txt'", bin, dir,
             model, dir, dir);
    CHECK(tc_run(cmd) == 1);
    snprintf(path, sizeof path, "%s/err.txt", dir);
    char *err = tc_slurp(path);
    CHECK(err && strstr(err, "none.sqlite"));
    sooc_free(err);
    snprintf(cmd, sizeof cmd, "'%s' map list --db '%s' --model '%s' 2>/dev/null", bin, db, model);
    CHECK(tc_run(cmd) == 2);

    /* a map built with another model: mesh and map export --ply refuse it, naming both ids */
    {
        char other[1200], mid[128];
        snprintf(other, sizeof other, "%s/other.sqlite", dir);
        sooc_mapstore_params op = sp;
        op.model_id = "fnv1a64:0123456789abcdef bytes:1";
        sooc_mapstore *so = NULL;
        CHECK_OK(sooc_mapstore_open(&so, other, &op));
        if (so) CHECK_OK(sooc_mapstore_save_map(so, map));
        sooc_mapstore_close(so);
        CHECK_OK(sooc_file_id(model, mid, sizeof mid, NULL));
        snprintf(cmd, sizeof cmd, "'%s' mesh --map '%s' --model '%s' --out '%s/o' 2>'%s/err.txt'", bin, other, model,
                 dir, dir);
        CHECK(tc_run(cmd) == 2);
        err = tc_slurp(path);
        CHECK_MSG(err && strstr(err, "0123456789abcdef") && strstr(err, mid), "mesh with another model: %s",
                  err ? err : "");
        sooc_free(err);
        snprintf(cmd, sizeof cmd, "'%s' map export --db '%s' --ply '%s/o2' --model '%s' 2>/dev/null", bin, other, dir,
                 model);
        CHECK(tc_run(cmd) == 2);
        /* the same map with this model's id is accepted */
        op.model_id = mid;
        snprintf(other, sizeof other, "%s/same.sqlite", dir);
        CHECK_OK(sooc_mapstore_open(&so, other, &op));
        if (so) CHECK_OK(sooc_mapstore_save_map(so, map));
        sooc_mapstore_close(so);
        snprintf(cmd, sizeof cmd, "'%s' mesh --map '%s' --model '%s' --out '%s/o3' --res 12 > /dev/null", bin, other,
                 model, dir);
        CHECK(tc_run(cmd) == 0);
    }

    /* the metric: GT boxes the size of the locality box at the entries' poses */
    {
        sooc_scene sc;
        sooc_scene_init(&sc);
        sc.n_objects = 2;
        sc.objects = sooc_calloc(2, sizeof *sc.objects);
        for (int i = 0; i < 2 && sc.objects; i++) {
            sooc_scene_object *o = &sc.objects[i];
            o->id = i + 1, o->shape = SOOC_SHAPE_BOX;
            o->x = g_pose[i][0] + 0.05, o->z = g_pose[i][1], o->yaw = g_pose[i][2];
            o->size[0] = o->size[2] = 2 * Rh, o->size[1] = Hb;
            o->params[0] = o->params[2] = Rh, o->params[1] = 0.5 * Hb;
        }
        sooc_mesh_opts o;
        sooc_mesh_opts_default(&o);
        o.res = 32;
        sooc_mesh_metric r;
        CHECK_OK(sooc_mesh_eval_scene(m, map, &sc, &o, &r));
        printf("metric vs boxes shifted 5 cm in x: acc %.2f cm, comp %.2f cm, F %.3f over %d objects\n", r.acc_cm,
               r.comp_cm, r.fscore, r.n_objects);
        CHECK(r.n_objects == 2 && r.n_empty == 0 && r.n_gt == 2);
        /* a 5 cm shift: every distance is below 5 cm, and well above 0 */
        CHECK(r.acc_cm > 0.3 && r.acc_cm < 5.0);
        CHECK(r.comp_cm > 0.3 && r.comp_cm < 5.0);
        /* unshifted: about 0 (2 cm voxel centroids) */
        for (int i = 0; i < 2; i++) sc.objects[i].x = g_pose[i][0];
        CHECK_OK(sooc_mesh_eval_scene(m, map, &sc, &o, &r));
        printf("metric vs the boxes themselves: acc %.2f cm, comp %.2f cm, F %.3f\n", r.acc_cm, r.comp_cm, r.fscore);
        CHECK(r.acc_cm < 0.8 && r.comp_cm < 0.8 && r.fscore > 0.99);
        /* an object far from every entry is not matched */
        sc.objects[1].x = 50;
        CHECK_OK(sooc_mesh_eval_scene(m, map, &sc, &o, &r));
        CHECK(r.n_objects == 1 && r.n_gt == 2);
        sooc_scene_free(&sc);
    }

    sooc_cogmap_destroy(map);
    sooc_model_destroy(m);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    CHECK(system(cmd) == 0);
    return check_report("test_mesh_cli");
}
