/* sooc3d map at: which object of a stored map a camera sees at a pixel
 * (sooc_map_pick_boxes / sooc_map_pick_model, include/sooc3d/eval.h).
 * Read-only: never modifies the database. */
#include "cli.h"
#include "sooc3d/eval.h"
#include "sooc3d/cogmap.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void at_usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d map at --db MAP.sqlite --pose T --K fx,fy,cx,cy --pixel U V\n"
            "                     [--frame source|world] [--model M] [--png FILE --size W,H]\n"
            "\n"
            "Which object a camera at pose T sees at pixel (U, V) of a stored map. Prints one JSON line:\n"
            "  {\"id\": N or null, \"depth_m\": planar depth of the hit, \"point_world\": [x, y, z],\n"
            "   \"point_source\": [x, y, z], \"method\": \"boxes\" | \"model\", ...}\n"
            "\n"
            "  --pose T      camera (OpenCV optical: x right, y down, z forward) to frame, as 7 numbers\n"
            "                tx,ty,tz,qx,qy,qz,qw (TUM order) or 12 / 16 numbers of the row-major matrix\n"
            "  --frame F     the frame of --pose: source (default: the pose source's frame, the one the\n"
            "                recording or the robot gives; the map's stored world frame maps it) or world\n"
            "                (the map's gravity-aligned frame, +y up, floor y = 0)\n"
            "  --K ...       pinhole intrinsics in pixels (undistorted image)\n"
            "  --pixel U V   column and row; the ray goes through the pixel's centre (U + 0.5, V + 0.5)\n"
            "  --model M     render the map with the model it was built with (refused for another\n"
            "                model's map) and answer with the object the rendering shows there; without\n"
            "                it, the nearest object box the ray enters (the boxes the shm table publishes)\n"
            "  --size W,H    the image size (default 2 cx x 2 cy): with --model, the objects in view are\n"
            "                those of the whole image\n"
            "  --png FILE    also write the id image of the whole view (--size W,H), one colour per id,\n"
            "                black where no object is seen\n");
}

/* "a,b,c" -> up to cap numbers; returns the count, -1 on a bad number */
static int parse_list(const char *s, double *v, int cap) {
    int n = 0;
    const char *p = s;
    while (*p) {
        char *end;
        double x = strtod(p, &end);
        if (end == p || !isfinite(x) || n == cap) return -1;
        v[n++] = x;
        p = end;
        if (*p == ',') p++;
        else if (*p) return -1;
    }
    return n;
}

static int parse_pose(const char *s, double T[16]) {
    double v[16];
    int n = parse_list(s, v, 16);
    if (n == 7) {
        double R[9];
        sooc_quat_to_m3(R, v + 3);
        sooc_se3_from_rt(T, R, v);
        return 1;
    }
    if (n != 12 && n != 16) return 0;
    memcpy(T, v, 12 * sizeof *T);
    T[12] = T[13] = T[14] = 0, T[15] = 1;
    if (n == 16 && (v[12] != 0 || v[13] != 0 || v[14] != 0 || v[15] != 1)) return 0;
    double R[9], t[3];   /* rigid: R^T R = I */
    sooc_se3_to_rt(R, t, T);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = R[i] * R[j] + R[3 + i] * R[3 + j] + R[6 + i] * R[6 + j] - (i == j);
            if (fabs(d) > 1e-4) return 0;
        }
    return 1;
}

static sooc_status write_ids_png(const char *path, const uint64_t *ids, int w, int h) {
    sooc_image img;
    memset(&img, 0, sizeof img);
    sooc_status st = sooc_image_alloc(&img, w, h, SOOC_PIX_RGB8);
    if (st) return st;
    uint8_t *px = img.data;
    for (size_t p = 0; p < (size_t)w * (size_t)h; p++) {
        int rgb[3] = {0, 0, 0};
        if (ids[p]) sooc_cli_id_colour(ids[p], rgb);
        for (int c = 0; c < 3; c++) px[3 * p + c] = (uint8_t)rgb[c];
    }
    st = sooc_png_write(path, &img, 6);
    sooc_image_free(&img);
    return st;
}

int sooc_cli_map_at(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) {
        at_usage(stdout);
        return 0;
    }
    const char *db = NULL, *model = NULL, *png = NULL, *frame = "source";
    double T[16], Kv[4], uv[2] = {NAN, NAN}, sz[2] = {0, 0};
    int have_pose = 0, have_K = 0, have_px = 0;
    for (int i = 2; i < argc; i++) {
        const char *a = argv[i];
        int more = i + 1 < argc;
        if (!strcmp(a, "--db") && more) db = argv[++i];
        else if (!strcmp(a, "--model") && more) model = argv[++i];
        else if (!strcmp(a, "--png") && more) {
            png = argv[++i];
            if (sooc_cli_need_parent("map at", a, png)) return 2;
        }
        else if (!strcmp(a, "--frame") && more) {
            frame = argv[++i];
            if (strcmp(frame, "source") && strcmp(frame, "world")) {
                fprintf(stderr, "sooc3d map at: --frame: '%s' is neither source nor world\n", frame);
                return 2;
            }
        } else if (!strcmp(a, "--pose") && more) {
            if (!parse_pose(argv[++i], T)) {
                fprintf(stderr, "sooc3d map at: --pose: '%s' is not 7 numbers (t, q) or a rigid 3x4 / 4x4 matrix\n",
                        argv[i]);
                return 2;
            }
            have_pose = 1;
        } else if (!strcmp(a, "--K") && more) {
            if (parse_list(argv[++i], Kv, 4) != 4 || !(Kv[0] > 0) || !(Kv[1] > 0)) {
                fprintf(stderr, "sooc3d map at: --K: '%s' is not fx,fy,cx,cy with fx, fy > 0\n", argv[i]);
                return 2;
            }
            have_K = 1;
        } else if (!strcmp(a, "--size") && more) {
            if (parse_list(argv[++i], sz, 2) != 2 || !(sz[0] >= 1 && sz[0] <= 8192) || !(sz[1] >= 1 && sz[1] <= 8192)) {
                fprintf(stderr, "sooc3d map at: --size: '%s' is not W,H in [1, 8192]\n", argv[i]);
                return 2;
            }
        } else if (!strcmp(a, "--pixel") && i + 2 < argc) {
            for (int k = 0; k < 2; k++)
                if (!sooc_cli_parse_double(argv[i + 1 + k], -1e6, 1e6, &uv[k])) {
                    fprintf(stderr, "sooc3d map at: --pixel: '%s' is not a number\n", argv[i + 1 + k]);
                    return 2;
                }
            i += 2;
            have_px = 1;
        } else {
            fprintf(stderr, "sooc3d map at: unknown or incomplete option '%s' (see --help)\n", a);
            return 2;
        }
    }
    if (!db || !have_pose || !have_K || !have_px) {
        fprintf(stderr, "sooc3d map at: --db, --pose, --K and --pixel are required\n");
        return 2;
    }
    if (!(sz[0] >= 1)) {   /* the whole view: the principal point in its middle unless --size says */
        sz[0] = fmax(1.0, floor(2 * Kv[2] + 0.5)), sz[1] = fmax(1.0, floor(2 * Kv[3] + 0.5));
        if (png) {
            fprintf(stderr, "sooc3d map at: --png needs --size W,H\n");
            return 2;
        }
    }
    if (!sooc_file_exists(db)) {
        fprintf(stderr, "sooc3d map at: %s: no such map database\n", db);
        return 2;
    }
    sooc_model *m = NULL;
    sooc_cogmap *map = NULL;
    sooc_mapstore *s = NULL;
    sooc_map_entry *ents = NULL;
    size_t n_ents = 0;
    uint64_t *ids = NULL;
    sooc_status st = SOOC_OK;
    if (model) {   /* the map must have been built with this model (as the node checks on resume) */
        if ((st = sooc_model_load(&m, model, NULL, NULL)) ||
            (st = sooc_cli_open_stored_map(model, sooc_model_get_config(m), db, model, &s, &map)))
            goto fail;
    } else {
        sooc_mapstore_params mp;
        sooc_mapstore_params_default(&mp);
        mp.create = 0;
        mp.readonly = 1;
        if ((st = sooc_mapstore_open(&s, db, &mp))) goto fail;
    }
    /* the camera in the map's world frame */
    double T_wc[16], src_w[16];
    sooc_map_frame mf;
    int has_frame = 0;
    if ((st = sooc_mapstore_frame_get(s, &mf, &has_frame))) goto fail;
    if (!has_frame) sooc_se3_identity(mf.T_world_src);
    if (!strcmp(frame, "source")) sooc_se3_mul(T_wc, mf.T_world_src, T);
    else memcpy(T_wc, T, sizeof T_wc);
    sooc_se3_inverse(src_w, mf.T_world_src);
    /* one pixel: a 1 x 1 camera whose principal point is shifted onto it */
    sooc_intrinsics K1;
    memset(&K1, 0, sizeof K1);
    K1.width = K1.height = 1;
    K1.fx = Kv[0], K1.fy = Kv[1], K1.cx = Kv[2] - floor(uv[0]), K1.cy = Kv[3] - floor(uv[1]);
    sooc_intrinsics KI = K1;
    KI.width = (int)sz[0], KI.height = (int)sz[1], KI.cx = Kv[2], KI.cy = Kv[3];
    uint64_t id = 0;
    float depth = NAN;
    if (model) {
        if ((st = sooc_map_pick_model(m, map, T_wc, &K1, &KI, 0, &id, &depth))) goto fail;
        if (png && (ids = malloc((size_t)KI.width * (size_t)KI.height * sizeof *ids)))
            st = sooc_map_pick_model(m, map, T_wc, &KI, NULL, 0, ids, NULL);
    } else {
        if ((st = sooc_mapstore_planner_entries(s, &ents, &n_ents))) goto fail;
        if ((st = sooc_map_pick_boxes(ents, n_ents, T_wc, &K1, &id, &depth))) goto fail;
        if (png && (ids = malloc((size_t)KI.width * (size_t)KI.height * sizeof *ids)))
            st = sooc_map_pick_boxes(ents, n_ents, T_wc, &KI, ids, NULL);
    }
    if (png && !ids) st = SOOC_ENOMEM;
    if (!st && png) st = write_ids_png(png, ids, KI.width, KI.height);
    if (st) goto fail;
    printf("{\"pixel\": [%g, %g], \"method\": \"%s\", \"frame\": \"%s\", \"id\": ", uv[0], uv[1],
           model ? "model" : "boxes", frame);
    if (id) {
        /* the hit: planar depth along the pixel centre's ray */
        const double dc[3] = {(floor(uv[0]) + 0.5 - Kv[2]) / Kv[0] * depth, (floor(uv[1]) + 0.5 - Kv[3]) / Kv[1] * depth,
                              depth};
        double pw[3], ps[3];
        sooc_se3_apply(pw, T_wc, dc);
        sooc_se3_apply(ps, src_w, pw);
        printf("%llu, \"depth_m\": %.4f, \"point_world\": [%.4f, %.4f, %.4f], \"point_source\": [%.4f, %.4f, %.4f]}\n",
               (unsigned long long)id, depth, pw[0], pw[1], pw[2], ps[0], ps[1], ps[2]);
    } else
        printf("null}\n");
    if (png) fprintf(stderr, "wrote %s (%dx%d)\n", png, KI.width, KI.height);
fail:
    free(ids);
    sooc_free(ents);
    sooc_cogmap_destroy(map);
    sooc_mapstore_close(s);
    sooc_model_destroy(m);
    return st ? sooc_cli_fail_map("map at", st) : 0;
}
