/* The frame-path options every command that reads a sequence takes
 * (include/sooc3d/frame.h): one parser, one help text. */
#include "cli.h"

#include <stdio.h>
#include <string.h>

const char *const sooc_cli_framepath_help =
    "Reading the sequence (the same options for infer, render, eval, train):\n"
    "  --calib F         calibration YAML for sequences without DIR/calib.yaml (intrinsics,\n"
    "                    depth_scale, ...); docs/formats.md\n"
    "  --format NAME     sequence format (auto, tum, 7scenes, label-fusion, slambook, replica,\n"
    "                    ycb-video, apc; docs/formats.md 2.0; default auto)\n"
    "  --depth-scale S   metres per depth unit, overriding the calibration / format default\n"
    "  --depth-shift N   right-shift raw depth before scaling (label-fusion: 3)\n"
    "  --min-depth M     valid depth range in metres (default 0.1 .. 10, as a launch file);\n"
    "  --max-depth M     samples outside it are invalid\n"
    "  --up X,Y,Z        the up direction in the poses' frame (hint for the support plane)\n"
    "  --world W         the map's world frame: auto (default: identity for a synthetic\n"
    "                    sequence with scene.yaml, else the frame stored in the map, else a\n"
    "                    support-plane estimate), identity (poses already +y up, floor at 0),\n"
    "                    stored, estimate\n"
    "Frames of any resolution are cropped to the model's aspect and resized to its resolution\n"
    "(the node's preprocessing); poses are moved into the map's world frame.\n";

static int parse_vec3(const char *s, double v[3]) {
    char tail;
    if (sscanf(s, "%lf,%lf,%lf%c", &v[0], &v[1], &v[2], &tail) != 3) return 0;
    for (int k = 0; k < 3; k++)
        if (!(v[k] == v[k]) || v[k] > 1e9 || v[k] < -1e9) return 0;
    return v[0] != 0 || v[1] != 0 || v[2] != 0;
}

int sooc_cli_framepath_opt(const char *cmd, int argc, char **argv, int *i, sooc_framepath_params *p) {
    const char *a = argv[*i];
    static const char *const names[] = {"--calib",     "--format",    "--depth-scale", "--depth-shift",
                                        "--min-depth", "--max-depth", "--up",          "--world"};
    int which = -1;
    for (int k = 0; k < (int)(sizeof names / sizeof *names); k++)
        if (!strcmp(a, names[k])) which = k;
    if (which < 0) return 0;
    if (*i + 1 >= argc) {
        fprintf(stderr, "sooc3d %s: %s needs a value\n", cmd, a);
        return -1;
    }
    const char *v = argv[++*i];
    switch (which) {
    case 0: p->calib_path = v; return 1;
    case 1:
        if (sooc_seq_format_parse(v, &p->format)) {
            fprintf(stderr, "sooc3d %s: --format: %s\n", cmd, sooc_errmsg());
            return -1;
        }
        return 1;
    case 2: return sooc_cli_double_opt(cmd, a, v, 1e-9, 1e3, &p->depth_scale) ? 1 : -1;
    case 3: return sooc_cli_int_opt(cmd, a, v, 0, 15, &p->depth_shift) ? 1 : -1;
    case 4: return sooc_cli_double_opt(cmd, a, v, 0, 1000, &p->min_depth_m) ? 1 : -1;
    case 5: return sooc_cli_double_opt(cmd, a, v, 0.01, 1000, &p->max_depth_m) ? 1 : -1;
    case 6:
        if (!parse_vec3(v, p->up)) {
            fprintf(stderr, "sooc3d %s: --up: expected a non-zero direction X,Y,Z, got '%s'\n", cmd, v);
            return -1;
        }
        p->has_up = 1;
        return 1;
    default:
        if (sooc_framepath_world_parse(v, &p->world) || p->world == SOOC_WORLD_GIVEN) {
            fprintf(stderr, "sooc3d %s: --world: expected auto, identity, stored or estimate, got '%s'\n", cmd, v);
            return -1;
        }
        return 1;
    }
}

int sooc_cli_framepath_check(const char *cmd, const sooc_framepath_params *p) {
    if (!(p->max_depth_m > p->min_depth_m)) {
        fprintf(stderr, "sooc3d %s: --min-depth %g must be below --max-depth %g\n", cmd, p->min_depth_m,
                p->max_depth_m);
        return 0;
    }
    return 1;
}

void sooc_cli_framepath_model(sooc_framepath_params *p, const sooc_model_config *c) {
    p->width = c->img_w, p->height = c->img_h;
    sooc_model_cam_heights_m(c, &p->cam_height_min_m, &p->cam_height_max_m);
}
