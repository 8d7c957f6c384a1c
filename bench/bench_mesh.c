/* Mesh benchmark (docs/mesh.md): the shipped unity model maps the
 * input views of generated scenes (online inference, posterior means), then
 * every map entry is meshed (include/sooc3d/render.h) and the Atlas metric is
 * taken against the generator's true surfaces at several surface levels.
 * Prints per-level mean accuracy / completeness / empty meshes and the
 * meshing time per object; the last line is a JSON object.
 *   bench_mesh [DATA_DIR [N_SCENES [RES]]]   (default: out/data/test_m, 4, 64) */
#include "sooc3d/mapper.h"
#include "sooc3d/render.h"
#include "sooc3d/model.h"
#include "sooc3d/gen.h"
#include "sooc3d/train.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NL 5
static const float g_levels[NL] = {0.2f, 0.3f, 0.4f, 0.5f, 0.6f};

static int fail(const char *what, sooc_status s) {
    fprintf(stderr, "bench_mesh: %s: %s: %s\n", what, sooc_status_str(s), sooc_errmsg());
    return 1;
}

int main(int argc, char **argv) {
    const char *data = argc > 1 ? argv[1] : "out/data/test_m", *mpath = "models/sooc3d_unity/model.bin";
    int nsc = argc > 2 ? atoi(argv[2]) : 4, res = argc > 3 ? atoi(argv[3]) : 64;
    sooc_model *m = NULL;
    sooc_status st = sooc_model_load(&m, mpath, NULL, NULL);
    if (st) return fail(mpath, st);
    const sooc_model_config *c = sooc_model_get_config(m);
    sooc_dataset *ds = NULL;
    if ((st = sooc_dataset_open(&ds, &data, 1, c->img_w, c->img_h))) return fail(data, st);
    if (nsc > sooc_dataset_n_scenes(ds)) nsc = sooc_dataset_n_scenes(ds);
    double acc[NL] = {0}, comp[NL] = {0}, fs[NL] = {0};
    long nobj[NL] = {0}, nemp[NL] = {0}, n_mesh = 0;
    double t_mesh = 0;
    size_t tri = 0;
    for (int s = 0; s < nsc; s++) {
        char path[1024];
        sooc_scene sc;
        sooc_scene_init(&sc);
        snprintf(path, sizeof path, "%s/scene.yaml", sooc_dataset_scene_path(ds, s));
        if ((st = sooc_scene_load(path, &sc))) return fail(path, st);
        sooc_model *cp = NULL;
        if ((st = sooc_model_copy_slots(m, 0, &cp))) return fail("copy", st);
        if ((st = sooc_model_set_clip(cp, 5.0f))) return fail("clip", st);   /* as scripts/eval_unity.sh */
        sooc_mapper *mp = NULL;
        if ((st = sooc_mapper_create_with_model(&mp, cp, 0, 1, 0))) return fail("mapper", st);
        for (int v = 0; v < sooc_dataset_n_views(ds, s); v++) {
            const sooc_frame *f = sooc_dataset_view(ds, s, v);
            sooc_update_stats us;
            if (!f->is_query && (st = sooc_mapper_update(mp, f, &us))) return fail("update", st);
        }
        sooc_model *mm = sooc_mapper_model(mp);
        const sooc_cogmap *map = sooc_mapper_cogmap(mp);
        /* meshing time: every entry at the default level */
        size_t ne = 0;
        sooc_cogmap_entries(map, NULL, 0, &ne);
        sooc_cogmap_entry *E = calloc(ne ? ne : 1, sizeof *E);
        sooc_cogmap_entries(map, E, ne, &ne);
        sooc_mesh_opts o;
        sooc_mesh_opts_default(&o);
        o.res = res;
        sooc_mesh mesh = {0};
        double t0 = sooc_seconds();
        for (size_t i = 0; i < ne; i++) {
            if ((st = sooc_mesh_object(mm, map, E[i].id, &o, &mesh))) return fail("mesh", st);
            tri += mesh.n_tri;
            n_mesh++;
        }
        t_mesh += sooc_seconds() - t0;
        sooc_mesh_free(&mesh);
        free(E);
        for (int l = 0; l < NL; l++) {
            o.level = g_levels[l];
            sooc_mesh_metric r;
            if ((st = sooc_mesh_eval_scene(mm, map, &sc, &o, &r))) return fail("metric", st);
            if (r.n_objects) acc[l] += r.acc_cm * r.n_objects, comp[l] += r.comp_cm * r.n_objects, fs[l] += r.fscore * r.n_objects;
            nobj[l] += r.n_objects, nemp[l] += r.n_empty;
        }
        fprintf(stderr, "scene %d: %zu entries, %d GT objects\n", s, ne, sc.n_objects);
        sooc_mapper_destroy(mp);
        sooc_scene_free(&sc);
    }
    printf("%-6s %8s %8s %7s %6s %6s\n", "level", "acc_cm", "comp_cm", "F@5cm", "objs", "empty");
    for (int l = 0; l < NL; l++)
        printf("%-6.2f %8.2f %8.2f %7.3f %6ld %6ld\n", (double)g_levels[l], acc[l] / (double)nobj[l],
               comp[l] / (double)nobj[l], fs[l] / (double)nobj[l], nobj[l], nemp[l]);
    int d = 3;   /* SOOC_MESH_LEVEL = 0.5 */
    printf("{\"bench\": \"mesh\", \"data\": \"%s\", \"scenes\": %d, \"res\": %d, \"level\": %.2f, \"mesh_acc_cm\": %.3f, "
           "\"mesh_comp_cm\": %.3f, \"fscore\": %.3f, \"objects\": %ld, \"empty\": %ld, \"mesh_s_per_object\": %.3f, "
           "\"triangles_per_object\": %.0f}\n",
           data, nsc, res, (double)g_levels[d], acc[d] / (double)nobj[d], comp[d] / (double)nobj[d],
           fs[d] / (double)nobj[d], nobj[d], nemp[d], n_mesh ? t_mesh / (double)n_mesh : 0.0,
           n_mesh ? (double)tri / (double)n_mesh : 0.0);
    sooc_dataset_destroy(ds);
    sooc_model_destroy(m);
    return 0;
}
