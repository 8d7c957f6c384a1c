/* sooc3d model: show a checkpoint's configuration, or write a copy with
 * another inference slot count or ray grid (the weights are copied bit for
 * bit). */
#include "cli.h"
#include "sooc3d/model.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d model M [--slots N] [--rays R] [--invalid-depth free|unknown] [--unit-m U]\n"
            "                    [--cam-heights MIN,MAX] [--out F]\n\n"
            "Print checkpoint M's configuration (resolution, slots, latent sizes, clip depth,\n"
            "parameter count). With --out, write a copy of M changed by:\n"
            "  --slots N  inference slot count: the mapper and `sooc3d eval`/`infer` then run it\n"
            "             with N object slots per view unless told otherwise (0 = its trained K;\n"
            "             more pads the extra slots with mirrored learnt priors, docs/model.md)\n"
            "  --rays R   ray grid R x R per view (16, 32, or a multiple of 32 dividing the image\n"
            "             side; R = the image side uses every pixel; a model of a 16 x 16 grid\n"
            "             stays at 16). Updates cost about R^2/1024 times a 32 x 32 grid's\n"
            "             (docs/model.md)\n"
            "  --invalid-depth free|unknown  what a pixel without valid depth means: no surface up\n"
            "             to the clip depth (free; synthetic sky) or a sensor hole, masked out of the\n"
            "             likelihood (unknown; docs/model.md \"Invalid depth\")\n"
            "  --unit-m U metres per model unit (0.001..1000): the model divides frame depth and\n"
            "             camera positions by U and multiplies the map's positions, sizes and the\n"
            "             rendered depth back; e.g. 0.2857 (= 1/3.5) runs a model trained on scenes\n"
            "             shown 3.5x larger on metric tabletop frames (docs/model.md \"Model unit\")\n"
            "  --cam-heights MIN,MAX  the camera heights above the support plane the model was\n"
            "             trained at, metres at the (new) unit; `sooc3d train` stores its training\n"
            "             views' range, the frame path and the node warn outside it\n"
            "The weights and any trainer state are copied unchanged; F is written atomically and\n"
            "may be M itself.\n");
}

int sooc_cmd_model(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) {
        usage(stdout);
        return 0;
    }
    const char *path = NULL, *out = NULL;
    int slots = -1, rays = -1, invalid = -1;
    double unit = -1, hts[2] = {0, 0};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--slots") && i + 1 < argc) {
            if (!sooc_cli_parse_slots(argv[++i], &slots)) {
                fprintf(stderr, "sooc3d model: --slots wants 0 (the trained K) up to %d\n", SOOC_MODEL_K_MAX);
                return 2;
            }
        } else if (!strcmp(a, "--rays") && i + 1 < argc) {
            if (!sooc_cli_parse_int(argv[++i], 16, 1024, &rays)) {
                fprintf(stderr, "sooc3d model: --rays wants a ray grid side, 16..1024 (got '%s')\n", argv[i]);
                return 2;
            }
        } else if (!strcmp(a, "--invalid-depth") && i + 1 < argc) {
            if (sooc_model_invalid_depth_parse(argv[++i], &invalid)) {
                fprintf(stderr, "sooc3d model: --invalid-depth wants free or unknown (got '%s')\n", argv[i]);
                return 2;
            }
        } else if (!strcmp(a, "--unit-m") && i + 1 < argc) {
            if (!sooc_cli_double_opt("model", a, argv[++i], 0.001, 1000, &unit)) return 2;
        } else if (!strcmp(a, "--cam-heights") && i + 1 < argc) {
            const char *v = argv[++i];
            char tail;
            if (sscanf(v, "%lf,%lf%c", &hts[0], &hts[1], &tail) != 2 || !(hts[0] > 0) || !(hts[1] > hts[0]) ||
                !(hts[1] < 1e3)) {
                fprintf(stderr, "sooc3d model: --cam-heights wants MIN,MAX in metres, 0 < MIN < MAX < 1000 (got '%s')\n",
                        v);
                return 2;
            }
        } else if (!strcmp(a, "--out") && i + 1 < argc) {
            out = argv[++i];
            if (sooc_cli_need_parent("model", a, out)) return 2;
        }
        else if (a[0] != '-' && !path) path = a;
        else {
            fprintf(stderr, "sooc3d model: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
    }
    if (!path || (slots >= 0 || rays >= 0 || invalid >= 0 || unit > 0 || hts[0] > 0) != (out != NULL)) {
        usage(stderr);
        return 2;
    }
    sooc_model *m = NULL;
    void *blob = NULL;
    size_t bs = 0;
    sooc_status st = sooc_model_load(&m, path, &blob, &bs);
    if (st) return sooc_cli_fail("model", st);
    if (out) {
        if (rays >= 0) {
            sooc_model *r = NULL;
            if (!(st = sooc_model_copy_rays(m, rays, rays, &r))) {
                sooc_model_destroy(m);
                m = r;
            }
        }
        if (!st && slots >= 0) st = sooc_model_set_slots(m, slots);
        if (!st && invalid >= 0) st = sooc_model_set_invalid_depth(m, invalid);
        if (!st && unit > 0) st = sooc_model_set_unit(m, (float)unit);
        if (!st && hts[0] > 0) st = sooc_model_set_cam_heights(m, hts[0], hts[1]);
        if (!st) st = sooc_model_save(m, out, blob, bs);
        if (st) sooc_adderr(st, "%s", out);
    }
    if (!st) {
        const sooc_model_config *c = sooc_model_get_config(m);
        printf("%s%s\n", out ? out : path, out ? " (written)" : "");
        printf("  kind        %s\n", c->global_frame ? "global-frame baseline" : "SOOC3D (view-relative slots + cognitive map)");
        printf("  input       %dx%d, rays %dx%d\n", c->img_w, c->img_h, c->ray_w, c->ray_h);
        printf("  slots       K = %d trained, %d at inference%s\n", c->K, c->slots ? c->slots : c->K,
               c->slots > c->K ? " (extra priors mirrored)" : "");
        printf("  latents     d_what %d, d_layout %d, L = %d refinement updates\n", c->d_what, c->d_layout, c->L);
        printf("  clip        %g m (near %g m)\n", (double)(c->d_clip * c->unit_m), (double)(c->t_near * c->unit_m));
        printf("  unit        %g m per model unit\n", (double)c->unit_m);
        double hl, hh;
        sooc_model_cam_heights_m(c, &hl, &hh);
        printf("  cameras     trained at %.2f-%.2f m above the support plane\n", hl, hh);
        printf("  no depth    %s\n", c->invalid_depth == SOOC_INVALID_DEPTH_UNKNOWN
                                         ? "unknown (sensor holes masked out of the likelihood)"
                                         : "free (no surface up to the clip depth)");
        printf("  parameters  %zu%s\n", sooc_model_param_count(m), bs ? ", with trainer state" : "");
    }
    sooc_free(blob);
    sooc_model_destroy(m);
    return st ? sooc_cli_fail("model", st) : 0;
}
