/* sooc3d gen: render synthetic RGB-D datasets (docs/formats.md). */
#include "cli.h"
#include "sooc3d/gen.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d gen --preset unity|blender|tabletop --scale s|m|l|xl --scenes N --seed S --out DIR\n"
            "                  [--width 64 --height 64 --views V --query Q --threads T --first K\n"
            "                   --density D --clip D --noise none|kinect --touch P --flat P --no-meshes\n"
            "                   --no-sheet --stats]\n\n"
            "Renders N scenes with an exact CPU ray tracer into DIR/scene_%%04d/ (TUM layout +\n"
            "calib.yaml + scene.yaml + instance/ + meshes/) and DIR/contact_sheet.png.\n\n"
            "  --preset     unity: spheres/boxes/cylinders/cones, uniform colours, Lambertian + ambient\n"
            "               blender: + tori, superquadrics, tables/chairs/shelves, textured floors,\n"
            "               cast shadows, specular highlights                      (default unity)\n"
            "               tabletop: cups, bowls, boxes, bottles, cans (textured) on a table or in\n"
            "               a bin, arm-mounted camera 0.35-1 m away pitched 25-70 deg down, circling\n"
            "               the table; kinect sensor noise by default; scales s/m/l = table\n"
            "               1.1x0.8 / 1.8x1.1 / 2.4x1.6 m (docs/formats.md 5.1)\n"
            "  --scale      room side s = 4 m, m = 8 m, l = 24 m, xl = 48 m; constant object density;\n"
            "               the camera walks through the room at every scale        (default s)\n"
            "  --scenes     number of scenes (default 1);  --first: index of the first (default 0)\n"
            "  --seed       seed; scene k uses RNG stream (seed, k)                 (default 1)\n"
            "  --views      input views per scene (default 10/20/60/120 for s/m/l/xl; tabletop 10/20/30)\n"
            "  --query      held-out query views per scene (default max(2, views/5))\n"
            "  --width/--height  image size (default 64x64), 60 degree horizontal FOV\n"
            "  --density    objects per square metre (default 0.2; unity and blender only)\n"
            "  --touch      tabletop: fraction of objects placed against another one (0-3 mm apart\n"
            "               or slightly overlapping; the others stand 2 cm apart; default 0)\n"
            "  --flat       tabletop: fraction of flat objects: packets and books 0.8-4 cm tall,\n"
            "               markers lying down (default 0)\n"
            "  --walls MIN,MAX  walls in every room, MIN-MAX m high (default: half the rooms,\n"
            "               0.3-0.8 m; unity and blender only; e.g. 2.2,3.0 for rooms like recordings)\n"
            "  --noise      sensor noise on depth and colour: none | kinect (axial sigma\n"
            "               0.0012 + 0.0019 (z - 0.4)^2 m, disparity quantisation, shadows, edge\n"
            "               dropout, exposure, colour noise); exact depth kept in depth_gt/\n"
            "               (default kinect for tabletop, none otherwise)\n"
            "  --clip       camera clipping depth in m: depth beyond it is stored as 0 (default 8)\n"
            "  --threads    OpenMP threads (default: all); output does not depend on it\n"
            "  --stats      print objects per view, distance and pixel-size histograms\n\n"
            "Calibration boards: sooc3d gen --board SPEC --out DIR [--views 15 --focal 525 --width 640\n"
            "  --height 480 --noise 2 --seed S --pure-translation]: views of a ChArUco or checkerboard\n"
            "  (charuco:7x5:0.04:0.03, checker:9x6:0.025) with known intrinsics and hand-eye, for\n"
            "  `sooc3d calib` (docs/node.md \"Your own camera\").\n");
}

typedef struct prog_ctx {
    sooc_progress pr;
} prog_ctx;

static void on_progress(void *user, int64_t done, int64_t total) {
    (void)total;
    prog_ctx *c = user;
    sooc_progress_update(&c->pr, (uint64_t)done, NULL);
}

static void print_stats(const sooc_gen_params *p, const sooc_gen_stats *st) {
    double wd[2];
    char where[48];
    if (p->preset == SOOC_GEN_TABLETOP && !sooc_gen_tabletop_size(p->scale, wd))
        snprintf(where, sizeof where, "%.1f x %.1f m table", wd[0], wd[1]);
    else
        snprintf(where, sizeof where, "%.0f m room", sooc_gen_scale_side(p->scale));
    printf("stats: preset %s, scale %s (%s), %lld scenes, %.1f objects per scene\n",
           sooc_gen_preset_name(p->preset), sooc_gen_scale_name(p->scale), where,
           (long long)st->n_scenes, st->n_scenes ? (double)st->n_objects_total / st->n_scenes : 0);
    double nv = st->n_views ? (double)st->n_views : 1, no = st->n_objects_in_view ? (double)st->n_objects_in_view : 1;
    printf("  objects per view (>= 4 valid pixels): mean %.2f over %lld views\n",
           (double)st->n_objects_in_view / nv, (long long)st->n_views);
    printf("  views holding k objects:");
    for (int k = 0; k < 16; k++)
        if (st->views_by_count[k]) printf(" %d%s:%.0f%%", k, k == 15 ? "+" : "", 100.0 * st->views_by_count[k] / nv);
    printf("\n  distance camera -> object centre (m): mean %.2f\n", st->sum_dist / no);
    for (int b = 0; b < SOOC_GEN_DIST_BINS; b++) {
        double fr = st->dist_hist[b] / no;
        printf("    %s%d-%d m %6.1f%% ", b == SOOC_GEN_DIST_BINS - 1 ? ">=" : "  ", b,
               b == SOOC_GEN_DIST_BINS - 1 ? 99 : b + 1, 100 * fr);
        for (int k = 0; k < (int)(fr * 60 + 0.5); k++) putchar('#');
        putchar('\n');
    }
    static const char *pb[SOOC_GEN_PIX_BINS] = {"<16", "16-63", "64-255", "256-1023", "1024-4095", ">=4096"};
    printf("  object size in pixels: mean %.1f\n", st->sum_pix / no);
    for (int b = 0; b < SOOC_GEN_PIX_BINS; b++) {
        double fr = st->pix_hist[b] / no;
        printf("    %9s px %6.1f%% ", pb[b], 100 * fr);
        for (int k = 0; k < (int)(fr * 60 + 0.5); k++) putchar('#');
        putchar('\n');
    }
}

int sooc_cmd_gen(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) { usage(stdout); return 0; }
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--board")) return sooc_cmd_gen_board(argc, argv);   /* calibration boards */
    sooc_gen_params p;
    sooc_gen_params_default(&p);
    const char *out = NULL;
    int stats = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
#define NEEDV() do { if (!v) { fprintf(stderr, "sooc3d gen: %s needs a value\n", a); return 2; } i++; } while (0)
#define INTV(lo, hi, x) do { NEEDV(); if (!sooc_cli_int_opt("gen", a, v, lo, hi, x)) return 2; } while (0)
#define DBLV(lo, hi, x) do { NEEDV(); if (!sooc_cli_double_opt("gen", a, v, lo, hi, x)) return 2; } while (0)
        sooc_status s = SOOC_OK;
        if (!strcmp(a, "--preset")) { NEEDV(); s = sooc_gen_preset_parse(v, &p.preset); }
        else if (!strcmp(a, "--scale")) { NEEDV(); s = sooc_gen_scale_parse(v, &p.scale); }
        else if (!strcmp(a, "--scenes")) INTV(1, 1000000, &p.n_scenes);
        else if (!strcmp(a, "--first")) INTV(0, 1000000, &p.first_scene);
        else if (!strcmp(a, "--seed")) { NEEDV(); if (!sooc_cli_u64_opt("gen", a, v, UINT64_MAX, &p.seed)) return 2; }
        else if (!strcmp(a, "--out")) { NEEDV(); out = v; }
        else if (!strcmp(a, "--width")) INTV(1, 16384, &p.width);
        else if (!strcmp(a, "--height")) INTV(1, 16384, &p.height);
        else if (!strcmp(a, "--views")) INTV(0, 10000, &p.n_views);
        else if (!strcmp(a, "--query")) INTV(0, 10000, &p.n_query);
        else if (!strcmp(a, "--threads")) INTV(0, 256, &p.threads);
        else if (!strcmp(a, "--density")) DBLV(0.001, 4.99, &p.density);
        else if (!strcmp(a, "--touch")) DBLV(0, 1, &p.touch);
        else if (!strcmp(a, "--flat")) DBLV(0, 1, &p.flat);
        else if (!strcmp(a, "--walls")) {
            NEEDV();
            char tail;
            if (sscanf(v, "%lf,%lf%c", &p.wall_h[0], &p.wall_h[1], &tail) != 2 || !(p.wall_h[0] > 0) ||
                !(p.wall_h[0] <= p.wall_h[1]) || !(p.wall_h[1] <= 20)) {
                fprintf(stderr, "sooc3d gen: --walls: expected MIN,MAX in metres, 0 < MIN <= MAX <= 20, got '%s'\n", v);
                return 2;
            }
        }
        else if (!strcmp(a, "--clip")) DBLV(0.01, 65535 * p.depth_scale, &p.clip_depth); /* 16-bit depth PNGs */
        else if (!strcmp(a, "--noise")) {
            NEEDV();
            if (!strcmp(v, "none")) p.noise = SOOC_GEN_NOISE_NONE;
            else if (!strcmp(v, "kinect")) p.noise = SOOC_GEN_NOISE_KINECT;
            else { fprintf(stderr, "sooc3d gen: --noise: expected none or kinect, got '%s'\n", v); return 2; }
        } else if (!strcmp(a, "--no-meshes")) p.write_meshes = 0;
        else if (!strcmp(a, "--no-sheet")) p.contact_sheet = 0;
        else if (!strcmp(a, "--stats")) stats = 1;
        else { fprintf(stderr, "sooc3d gen: unknown option '%s'\n", a); usage(stderr); return 2; }
        if (s) return sooc_cli_fail("gen", s);
#undef NEEDV
#undef INTV
#undef DBLV
    }
    if (!out) { fprintf(stderr, "sooc3d gen: --out DIR is required\n"); usage(stderr); return 2; }
    int V = sooc_gen_views(&p);
    int Q = p.n_query >= 0 ? p.n_query : (V / 5 > 2 ? V / 5 : 2);
    prog_ctx pc;
    sooc_progress_begin(&pc.pr, "gen views", (uint64_t)p.n_scenes * (uint64_t)(V + Q));
    sooc_gen_stats st;
    double t0 = sooc_seconds();
    sooc_status s = sooc_gen_run(&p, out, on_progress, &pc, &st);
    char extra[96];
    snprintf(extra, sizeof extra, "%.2f s", sooc_seconds() - t0);
    sooc_progress_end(&pc.pr, extra);
    if (s) return sooc_cli_fail("gen", s);
    fprintf(stderr, "sooc3d gen: wrote %d scenes (%d views each) to %s in %.2f s\n", p.n_scenes, V + Q, out,
            sooc_seconds() - t0);
    if (stats) print_stats(&p, &st);
    return 0;
}
