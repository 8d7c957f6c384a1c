/* sooc3d map: list, query, export or describe a stored map (SQLite, see
 * include/sooc3d/cogmap.h). Read-only: never modifies the database. */
#include "cli.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"
#include "sooc3d/table.h"
#include "sooc3d/render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void map_usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d map list   --db MAP.sqlite [--limit N]\n"
            "       sooc3d map query  --db MAP.sqlite --box X0 Z0 X1 Z1\n"
            "       sooc3d map export --db MAP.sqlite (--csv|--json|--ply) FILE [--box X0 Z0 X1 Z1]\n"
            "       sooc3d map export --db MAP.sqlite --ply DIR --model M [--res N] [--level L] [--box ...]\n"
            "       sooc3d map export --db MAP.sqlite --mcap FILE\n"
            "       sooc3d map info   --db MAP.sqlite\n"
            "       sooc3d map at     --db MAP.sqlite --pose T --K fx,fy,cx,cy --pixel U V [--model M] [--png F]\n"
            "\n"
            "Reads a persistent cognitive map (written by `sooc3d node`; `sooc3d infer` writes JSON/CSV,\n"
            "not a database). Needs only read permission on the database file.\n"
            "World frame: +y up, floor y = 0; an object is (x, z, yaw) on the floor.\n"
            "\n"
            "  list     one line per object, ordered by id: id x z (m) yaw (rad) sigma_t (m)\n"
            "           sigma_yaw (rad) presence obs_count first_seen_ns last_seen_ns, its box (x*y*z m),\n"
            "           height above the floor (m) and box quality (tight, clipped, empty, faint, symmetric,\n"
            "           surface: of the observed surface, not computed). The numbers of the shm table's record (docs/shm.md): sigma_t is\n"
            "           sqrt(cov_xx) in metres, sigma_yaw sqrt(cov_yawyaw) in radians\n"
            "  query    the same for objects whose (x, z) lies in the closed box [X0,X1] x [Z0,Z1]\n"
            "           (R*Tree lookup)\n"
            "  export   --csv FILE   header + one row per object (incl. what_mu / what_logvar, the\n"
            "                        covariance, box, height, box quality, the box centre's y and\n"
            "                        the record's flags)\n"
            "           --json FILE  {\"info\": {...}, \"objects\": [...]}\n"
            "           --ply FILE   ASCII PLY point cloud, one vertex per object at (x, 0, z),\n"
            "                        coloured by a hash of its id, with properties id, yaw,\n"
            "                        presence (open it in MeshLab / CloudCompare / Open3D)\n"
            "           FILE may be '-' for standard output.\n"
            "           --mcap FILE  for Foxglove: foxglove.SceneUpdate (JSON) on /sooc3d/objects, one cube,\n"
            "                        label and metadata per object, the last message holding every\n"
            "                        object; foxglove.FrameTransform map -> world -> source on\n"
            "                        /sooc3d/frames (docs/logs.md)\n"
            "           --ply DIR --model M: the objects' MESHES instead (what `sooc3d mesh` writes:\n"
            "                        DIR/object_<id>.ply and DIR/scene.ply, binary PLY with vertex\n"
            "                        colours, world frame; --res N samples per box axis, default 64;\n"
            "                        --level L on sigma_hat, default 0.5; --layout-cell C metres,\n"
            "                        default 0.05; docs/mesh.md)\n"
            "  info     schema version, model id, dims, counts, journal mode\n"
            "  at       which object a camera sees at a pixel (`sooc3d map at --help`)\n"
            "\n"
            "  --db FILE     the map database (required; it is never created or modified)\n"
            "  --box X0 Z0 X1 Z1   floor box in metres (query; optional filter for export)\n"
            "  --limit N     list at most N objects\n"
            "  -h, --help    this text\n");
}

typedef struct out_ctx {
    FILE *f;
    int fmt;      /* 0 text, 1 csv, 2 json, 3 ply */
    size_t n, limit;
    int first;
    sooc_mapstore *s;   /* for each entry's stored box and spreads */
    sooc_status st;     /* a failed geometry read stops the walk */
} out_ctx;

/* A JSON number, or null where there is none (NaN, infinite) */
static void json_num(FILE *f, double v) {
    if (isfinite(v)) fprintf(f, "%.9g", v);
    else fprintf(f, "null");
}

static int print_cb(void *u, const sooc_cogmap_entry *e) {
    out_ctx *c = u;
    if (c->limit && c->n >= c->limit) return 1;
    c->n++;
    /* the entry as a planner gets it: the stored box and spreads (one uncertainty, cogmap.h) */
    float ext[3] = {0, 0, 0};
    sooc_map_geometry g;
    memset(&g, 0, sizeof g);
    int found = 0;
    if (c->s && (c->st = sooc_mapstore_geom_get(c->s, e->id, ext, &g, &found))) return 1;
    sooc_map_entry me;
    sooc_map_entry_from_cogmap(e, found ? ext : NULL, &me);
    if (found) me.geom = g;
    /* the numbers of the shm table's record: sigma_t = sqrt(cov_xx), the yaw's sqrt(cov_yawyaw) (NaN:
     * symmetric), the covariance, box, y, presence and flags */
    sooc_table_record r;
    sooc_node_table_record(&me, &r);
    double cov[4] = {r.cov_xzyaw[0], r.cov_xzyaw[1], r.cov_xzyaw[3], r.cov_xzyaw[5]};
    double st = sqrt(cov[0]), sy = sqrt(cov[3]);
    double h = sooc_map_entry_height(&me);   /* top above the floor */
    char q[64];
    sooc_map_entry_box_quality(&g, q, sizeof q);
    float p = r.presence;
    switch (c->fmt) {
    case 0:
        fprintf(c->f, "%8llu %10.4f %10.4f %8.4f %8.4f %8.4f %7.4f %6u %20lld %20lld", (unsigned long long)e->id, e->X,
                e->Z, e->Theta, st, sy, p, e->obs_count, (long long)e->first_seen_ns, (long long)e->last_seen_ns);
        if (found) fprintf(c->f, "  %5.3fx%5.3fx%5.3f %6.3f %s\n", me.extent[0], me.extent[1], me.extent[2], h, q);
        else fprintf(c->f, "  %17s %6s %s\n", "-", "-", q);
        break;
    case 1:
        fprintf(c->f, "%llu,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%u,%d,%lld,%lld,%d,", (unsigned long long)e->id,
                e->X, e->Z, e->Theta, st, sy, e->rho_t, e->rho_theta, p, e->obs_count, e->last_view,
                (long long)e->first_seen_ns, (long long)e->last_seen_ns, e->dim);
        for (int i = 0; i < e->dim; i++) fprintf(c->f, "%s%.9g", i ? " " : "\"", e->what_mu[i]);
        fprintf(c->f, "\",");
        for (int i = 0; i < e->dim; i++) fprintf(c->f, "%s%.9g", i ? " " : "\"", e->what_logvar[i]);
        fprintf(c->f, "\",%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%s,%.9g,%u\n", cov[0], cov[1], cov[2], cov[3],
                r.extent[0], r.extent[1], r.extent[2], h, q, r.y, r.flags);
        break;
    case 2:
        fprintf(c->f,
                "%s\n    {\"id\": %llu, \"x\": %.9g, \"y\": %.9g, \"z\": %.9g, \"yaw\": %.9g, \"sigma_t\": %.9g, "
                "\"sigma_yaw\": ",
                c->first ? "" : ",", (unsigned long long)e->id, e->X, r.y, e->Z, e->Theta, st);
        json_num(c->f, sy);   /* a symmetric object's yaw has no spread: null */
        fprintf(c->f,
                ", \"presence\": %.9g, \"presence_logit\": %.9g, \"flags\": %u, \"obs_count\": %u, "
                "\"last_view\": %d, \"first_seen_ns\": %lld, \"last_seen_ns\": %lld, \"what_mu\": [",
                p, e->pres_logit, r.flags, e->obs_count, e->last_view, (long long)e->first_seen_ns, (long long)e->last_seen_ns);
        for (int i = 0; i < e->dim; i++) fprintf(c->f, "%s%.9g", i ? ", " : "", e->what_mu[i]);
        fprintf(c->f, "], \"what_logvar\": [");
        for (int i = 0; i < e->dim; i++) fprintf(c->f, "%s%.9g", i ? ", " : "", e->what_logvar[i]);
        fprintf(c->f, "], \"cov_xz\": [%.9g, %.9g, %.9g], \"var_yaw\": ", cov[0], cov[1], cov[2]);
        json_num(c->f, cov[3]);
        if (found)
            fprintf(c->f, ", \"extent\": [%.9g, %.9g, %.9g], \"height\": %.9g", r.extent[0], r.extent[1],
                    r.extent[2], h);
        else fprintf(c->f, ", \"extent\": null, \"height\": null");
        fprintf(c->f, ", \"box\": \"%s\"}", q);
        c->first = 0;
        break;
    case 3: {
        int rgb[3];
        sooc_cli_id_colour(e->id, rgb);
        fprintf(c->f, "%.6f 0 %.6f %d %d %d %llu %.6f %.6f\n", e->X, e->Z, rgb[0], rgb[1], rgb[2],
                (unsigned long long)e->id, e->Theta, p);
        break;
    }
    }
    return 0;
}

static void json_str(FILE *f, const char *s) {
    fputc('"', f);
    for (; *s; s++) {
        unsigned char ch = (unsigned char)*s;
        if (ch == '"' || ch == '\\') fprintf(f, "\\%c", ch);
        else if (ch < 0x20) fprintf(f, "\\u%04x", ch);
        else fputc(ch, f);
    }
    fputc('"', f);
}

static int count_cb(void *u, const sooc_cogmap_entry *e) {
    (void)e;
    (*(size_t *)u)++;
    return 0;
}

static int parse_d(const char *s, double *v) {
    char *end;
    *v = strtod(s, &end);
    return end != s && !*end && isfinite(*v);
}

int sooc_cmd_map(int argc, char **argv) {
    if (argc >= 2 && !strcmp(argv[1], "at")) return sooc_cli_map_at(argc, argv);
    if (sooc_cli_wants_help(argc, argv)) {
        map_usage(stdout);
        return 0;
    }
    if (argc < 2) {
        map_usage(stderr);
        return 2;
    }
    const char *sub = argv[1], *db = NULL, *out = NULL, *out_opt = NULL, *model = NULL;
    int fmt = -1, has_box = 0, mesh_opt = 0;
    sooc_mesh_opts mo;
    sooc_mesh_opts_default(&mo);
    double box[4] = {0};
    size_t limit = 0;
    for (int i = 2; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--db") && i + 1 < argc) db = argv[++i];
        else if (!strcmp(a, "--model") && i + 1 < argc) model = argv[++i];
        else if (!strcmp(a, "--res") && i + 1 < argc) {
            if (!sooc_cli_int_opt("map", "--res", argv[++i], 2, 1024, &mo.res)) return 2;
            mesh_opt = 1;
        } else if (!strcmp(a, "--level") && i + 1 < argc) {
            double l;
            if (!sooc_cli_double_opt("map", "--level", argv[++i], 1e-6, 1 - 1e-6, &l)) return 2;
            mo.level = (float)l, mesh_opt = 1;
        } else if (!strcmp(a, "--layout-cell") && i + 1 < argc) {
            if (!sooc_cli_double_opt("map", "--layout-cell", argv[++i], 0.005, 1.0, &mo.layout_cell)) return 2;
            mesh_opt = 1;
        }
        else if ((!strcmp(a, "--csv") || !strcmp(a, "--json") || !strcmp(a, "--ply") || !strcmp(a, "--mcap")) &&
                 i + 1 < argc) {
            if (fmt >= 0) { fprintf(stderr, "sooc3d map: give one of --csv, --json, --ply, --mcap\n"); return 2; }
            fmt = a[2] == 'c' ? 1 : a[2] == 'j' ? 2 : a[2] == 'p' ? 3 : 4;
            out_opt = a;
            out = argv[++i];
        } else if (!strcmp(a, "--box") && i + 4 < argc) {
            for (int k = 0; k < 4; k++)
                if (!parse_d(argv[i + 1 + k], &box[k])) {
                    fprintf(stderr, "sooc3d map: --box: '%s' is not a number\n", argv[i + 1 + k]);
                    return 2;
                }
            i += 4;
            has_box = 1;
            if (box[0] > box[2] || box[1] > box[3]) {
                fprintf(stderr, "sooc3d map: --box needs X0 <= X1 and Z0 <= Z1\n");
                return 2;
            }
        } else if (!strcmp(a, "--limit") && i + 1 < argc) {
            char *end;
            long long v = strtoll(argv[++i], &end, 10);
            if (*end || v < 0) { fprintf(stderr, "sooc3d map: --limit: bad value '%s'\n", argv[i]); return 2; }
            limit = (size_t)v;
        } else {
            fprintf(stderr, "sooc3d map: unknown or incomplete option '%s' (see --help)\n", a);
            return 2;
        }
    }
    int is_list = !strcmp(sub, "list"), is_query = !strcmp(sub, "query"), is_export = !strcmp(sub, "export"),
        is_info = !strcmp(sub, "info");
    if (!is_list && !is_query && !is_export && !is_info) {
        fprintf(stderr, "sooc3d map: unknown subcommand '%s' (list, query, export, info)\n", sub);
        return 2;
    }
    if (!db) { fprintf(stderr, "sooc3d map %s: --db FILE is required\n", sub); return 2; }
    if (is_query && !has_box) { fprintf(stderr, "sooc3d map query: --box X0 Z0 X1 Z1 is required\n"); return 2; }
    if (is_export && fmt < 0) { fprintf(stderr, "sooc3d map export: give --csv, --json, --ply or --mcap FILE\n"); return 2; }
    if (!is_export && fmt >= 0) { fprintf(stderr, "sooc3d map %s: --csv/--json/--ply/--mcap belong to export\n", sub); return 2; }
    if (fmt == 4 && (has_box || model || mesh_opt)) {
        fprintf(stderr, "sooc3d map export --mcap: writes every object (no --box, --model)\n");
        return 2;
    }
    if (is_export && sooc_cli_need_parent("map export", out_opt, out)) return 2;
    if (fmt == 4) return sooc_cli_map_export_mcap(db, out);
    if ((model || mesh_opt) && !(is_export && fmt == 3)) {
        fprintf(stderr, "sooc3d map: --model/--res/--level/--layout-cell belong to export --ply DIR (meshes)\n");
        return 2;
    }
    if (model) return sooc_cli_mesh_map("map export", db, model, out, &mo, has_box ? box : NULL);

    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0;
    p.readonly = 1;
    sooc_mapstore *s = NULL;
    sooc_status st = sooc_mapstore_open(&s, db, &p);
    if (st) return sooc_cli_fail("map", st);
    sooc_mapstore_info info;
    if ((st = sooc_mapstore_info_get(s, &info))) {
        sooc_mapstore_close(s);
        return sooc_cli_fail("map", st);
    }
    int rc = 0;
    if (is_info) {
        printf("database       %s\nschema_version %d\nmodel_id       %s\nlatent_dim     %d\nlayout_dim     %d\n"
               "block_size     %g\nobjects        %llu\nlayout_blocks  %llu\nkeyframes      %llu\nnext_id        %llu\n"
               "journal_mode   %s\n",
               db, info.schema_version, info.model_id, info.dim, info.layout_dim, info.block_size,
               (unsigned long long)info.n_entries, (unsigned long long)info.n_layout,
               (unsigned long long)info.n_keyframes, (unsigned long long)info.next_id, info.journal_mode);
        sooc_mapstore_close(s);
        return 0;
    }
    out_ctx c = {stdout, 0, 0, limit, 1, s, SOOC_OK};
    if (is_list || is_query) {
        printf("# %8s %10s %10s %8s %8s %8s %7s %6s %20s %20s  %17s %6s %s\n", "id", "x", "z", "yaw", "sigma_t",
               "sigma_yaw", "pres", "obs", "first_seen_ns", "last_seen_ns", "box x*y*z (m)", "height", "box");
        st = is_query ? sooc_mapstore_query_box(s, box[0], box[1], box[2], box[3], print_cb, &c)
                      : sooc_mapstore_foreach(s, print_cb, &c);
        if (!st && c.st) st = c.st;
        if (st) rc = sooc_cli_fail("map", st);
        else fprintf(stderr, "%zu object(s)%s\n", c.n, is_query ? " in the box" : "");
        sooc_mapstore_close(s);
        return rc;
    }
    /* export */
    int to_stdout = !strcmp(out, "-");
    FILE *f = to_stdout ? stdout : fopen(out, "w");
    if (!f) {
        fprintf(stderr, "sooc3d map export: cannot write %s\n", out);
        sooc_mapstore_close(s);
        return 1;
    }
    c.f = f;
    c.fmt = fmt;
    if (fmt == 3) {
        size_t n = 0;
        st = has_box ? sooc_mapstore_query_box(s, box[0], box[1], box[2], box[3], count_cb, &n)
                     : sooc_mapstore_foreach(s, count_cb, &n);
        if (!st)
            fprintf(f,
                    "ply\nformat ascii 1.0\ncomment sooc3d map export: one vertex per object at (x, 0, z), "
                    "world frame +y up\nelement vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
                    "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uint id\n"
                    "property float yaw\nproperty float presence\nend_header\n",
                    n);
    } else if (fmt == 1) {
        fprintf(f, "id,x,z,yaw,sigma_t,sigma_yaw,rho_t,rho_yaw,presence,obs_count,last_view,first_seen_ns,"
                   "last_seen_ns,dim,what_mu,what_logvar,cov_xx,cov_xz,cov_zz,var_yaw,extent_x,extent_y,extent_z,"
                   "height,box,y,flags\n");
    } else {
        fprintf(f, "{\n  \"info\": {\"database\": ");
        json_str(f, db);
        fprintf(f, ", \"schema_version\": %d, \"model_id\": ", info.schema_version);
        json_str(f, info.model_id);
        fprintf(f,
                ", \"latent_dim\": %d, "
                "\"layout_dim\": %d, \"objects\": %llu, \"keyframes\": %llu, \"next_id\": %llu},\n  \"objects\": [",
                info.dim, info.layout_dim, (unsigned long long)info.n_entries,
                (unsigned long long)info.n_keyframes, (unsigned long long)info.next_id);
    }
    if (!st)
        st = has_box ? sooc_mapstore_query_box(s, box[0], box[1], box[2], box[3], print_cb, &c)
                     : sooc_mapstore_foreach(s, print_cb, &c);
    if (!st && c.st) st = c.st;
    if (fmt == 2) fprintf(f, "\n  ]\n}\n");
    int werr = ferror(f);
    if (!to_stdout && fclose(f)) werr = 1;
    if (st) rc = sooc_cli_fail("map", st);
    else if (werr) {
        fprintf(stderr, "sooc3d map export: write error on %s\n", out);
        rc = 1;
    } else if (!to_stdout)
        fprintf(stderr, "wrote %zu object(s) to %s\n", c.n, out);
    sooc_mapstore_close(s);
    return rc;
}
