/* sooc3d mesh: marching cubes on every object of a stored map and on its
 * layout, one binary PLY per object plus scene.ply (include/sooc3d/render.h,
 * docs/mesh.md). `sooc3d map export --ply DIR --model M` calls the same code. */
#include "cli.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/render.h"
#include "sooc3d/model.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void mesh_usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d mesh --map MAP.sqlite --model M --out DIR [--res N] [--level L] [--layout-cell C]\n"
            "                   [--threads N]\n"
            "\n"
            "Extracts a triangle mesh of every object of a stored map (written by `sooc3d node`) by\n"
            "marching cubes on the object's own density (its component of the model's field; a\n"
            "finetuned object uses its own decoder), sampled on a grid over its locality box in its own\n"
            "frame, and of the layout (floor, walls) over every layout block. Writes binary\n"
            "little-endian PLY with vertex colours in the WORLD frame (metres, +y up, floor y = 0):\n"
            "  DIR/object_<id>.ply   one per map entry\n"
            "  DIR/scene.ply         every object plus the layout\n"
            "Meshes are watertight and wound counter-clockwise seen from outside (docs/mesh.md).\n"
            "\n"
            "  --map FILE     the map database (read only)\n"
            "  --model M      the checkpoint the map was built with\n"
            "  --out DIR      output folder (created)\n"
            "  --res N        samples per axis over an object's box (default %d; 2..1024)\n"
            "  --level L      surface level on the raw density sigma_hat in (0, 1) (default %g =\n"
            "                 sigma_max / 2 per metre)\n"
            "  --layout-cell C  layout grid spacing in metres (default %g; times the model's unit_m)\n"
            "  --threads N    0 = OpenMP default\n"
            "  -h, --help     this text\n",
            SOOC_MESH_RES_DEFAULT, (double)SOOC_MESH_LEVEL, 0.05);
}

int sooc_cli_mesh_map(const char *cmd, const char *db, const char *model, const char *dir, const sooc_mesh_opts *o,
                      const double *box) {
    sooc_model *m = NULL;
    sooc_mapstore *ms = NULL;
    sooc_cogmap *map = NULL;
    uint64_t *ids = NULL;
    sooc_status st = sooc_model_load(&m, model, NULL, NULL);
    if (st) goto fail;
    const sooc_model_config *mc = sooc_model_get_config(m);
    if ((st = sooc_cli_open_stored_map(model, mc, db, model, &ms, &map))) goto fail;
    size_t ne = 0, nsel = 0;
    if ((st = sooc_cogmap_entries(map, NULL, 0, &ne))) goto fail;
    sooc_cogmap_entry *E = calloc(ne ? ne : 1, sizeof *E);
    ids = calloc(ne ? ne : 1, sizeof *ids);
    if (!E || !ids) {
        free(E);
        st = SOOC_ENOMEM;
        goto fail;
    }
    if ((st = sooc_cogmap_entries(map, E, ne, &ne))) {
        free(E);
        goto fail;
    }
    for (size_t i = 0; i < ne; i++)
        if (!box || (E[i].X >= box[0] && E[i].X <= box[2] && E[i].Z >= box[1] && E[i].Z <= box[3])) ids[nsel++] = E[i].id;
    free(E);
    double t0 = sooc_seconds();
    sooc_mesh_write_stats ws;
    if ((st = sooc_mesh_write_map(m, map, dir, o, ids, nsel, &ws))) goto fail;
    printf("%s: %d object meshes (%d empty: nothing above level %g) and scene.ply (%zu vertices, %zu triangles, "
           "%zu of them layout) in %s, %.1f s\n",
           cmd, ws.n_objects, ws.n_empty, (double)o->level, ws.n_vert, ws.n_tri, ws.n_layout_tri, dir,
           sooc_seconds() - t0);
fail:
    free(ids);
    sooc_cogmap_destroy(map);
    sooc_mapstore_close(ms);
    sooc_model_destroy(m);
    return st ? sooc_cli_fail_map(cmd, st) : 0;
}

int sooc_cmd_mesh(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) {
        mesh_usage(stdout);
        return 0;
    }
    const char *db = NULL, *model = NULL, *out = NULL;
    sooc_mesh_opts o;
    sooc_mesh_opts_default(&o);
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int has = i + 1 < argc;
        if (!strcmp(a, "--map") && has) db = argv[++i];
        else if (!strcmp(a, "--model") && has) model = argv[++i];
        else if (!strcmp(a, "--out") && has) out = argv[++i];
        else if (!strcmp(a, "--res") && has) {
            if (!sooc_cli_int_opt("mesh", "--res", argv[++i], 2, 1024, &o.res)) return 2;
        } else if (!strcmp(a, "--level") && has) {
            double l;
            if (!sooc_cli_double_opt("mesh", "--level", argv[++i], 1e-6, 1 - 1e-6, &l)) return 2;
            o.level = (float)l;
        } else if (!strcmp(a, "--layout-cell") && has) {
            if (!sooc_cli_double_opt("mesh", "--layout-cell", argv[++i], 0.005, 1.0, &o.layout_cell)) return 2;
        } else if (!strcmp(a, "--threads") && has) {
            if (!sooc_cli_int_opt("mesh", "--threads", argv[++i], 0, 1024, &o.threads)) return 2;
        } else {
            fprintf(stderr, "sooc3d mesh: unknown or incomplete option '%s' (see --help)\n", a);
            return 2;
        }
    }
    if (!db || !model || !out) {
        fprintf(stderr, "sooc3d mesh: --map, --model and --out are required (see --help)\n");
        return 2;
    }
    return sooc_cli_mesh_map("mesh", db, model, out, &o, NULL);
}
