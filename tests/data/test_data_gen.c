/* Generator: determinism (seed, thread count), geometric consistency of depth
 * and instance ids with the analytic surfaces, scene.yaml round trip, and a
 * generate -> read back round trip through the sequence reader. */
#include "util.h"
#include "sooc3d/gen.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <sys/stat.h>

static uint32_t file_crc(const char *path, int *ok) {
    void *b;
    size_t n;
    *ok = sooc_file_read_all(path, 1 << 26, &b, &n) == SOOC_OK;
    if (!*ok) return 0;
    uint32_t c = sooc_crc32(0, b, n);
    sooc_free(b);
    return c;
}

/* CRC over the files of a generated scene directory (lists, yaml, frames). */
static uint32_t scene_crc(const char *dir, int nviews) {
    uint32_t c = 0;
    const char *fixed[] = {"rgb.txt", "depth.txt", "groundtruth.txt", "calib.yaml", "scene.yaml", "meshes/object_0001.ply"};
    char p[1200];
    int ok;
    for (int i = 0; i < 6; i++) {
        snprintf(p, sizeof p, "%s/%s", dir, fixed[i]);
        c ^= file_crc(p, &ok) * (uint32_t)(i + 1);
        CHECK_MSG(ok, "missing %s", p);
    }
    const char *sub[] = {"rgb", "depth", "instance"};
    for (int v = 0; v < nviews; v++)
        for (int k = 0; k < 3; k++) {
            snprintf(p, sizeof p, "%s/%s/%06d.png", dir, sub[k], v);
            c = c * 31u + file_crc(p, &ok);
            CHECK_MSG(ok, "missing %s", p);
        }
    return c;
}

static void test_determinism(void) {
    sooc_gen_params p;
    sooc_gen_params_default(&p);
    p.preset = SOOC_GEN_BLENDER;
    p.scale = SOOC_GEN_M;
    p.n_scenes = 2;
    p.n_views = 6;
    p.n_query = 2;
    p.seed = 7;
    uint32_t crc[3];
    char *dirs[3];
    for (int run = 0; run < 3; run++) {
        dirs[run] = tu_tmpdir("det");
        p.threads = run == 1 ? 2 : 1;
        p.seed = run == 2 ? 8 : 7;
        CHECK_OK(sooc_gen_run(&p, dirs[run], NULL, NULL, NULL));
        char sd[700];
        snprintf(sd, sizeof sd, "%s/scene_0001", dirs[run]);
        crc[run] = scene_crc(sd, 8);
    }
    CHECK_MSG(crc[0] == crc[1], "threads 1 vs 2 differ: %08x %08x", crc[0], crc[1]);
    CHECK_MSG(crc[0] != crc[2], "different seeds gave identical output");
    for (int run = 0; run < 3; run++) tu_rm_rf(dirs[run]);
}

/* Every valid instance pixel back-projects onto its object's surface. */
static void check_view_geometry(const sooc_scene *sc, const sooc_frame *f, double tol, int64_t *npix,
                                double *worst) {
    for (int v = 0; v < f->height; v++)
        for (int u = 0; u < f->width; u++) {
            size_t i = (size_t)v * (size_t)f->width + (size_t)u;
            if (!f->valid[i] || !f->instance[i]) continue;
            double dir[3];
            double dz = sooc_cam_ray(&f->K, u, v, dir);
            double t = f->depth[i] / dz, pc[3] = {dir[0] * t, dir[1] * t, dir[2] * t}, pw[3];
            sooc_se3_apply(pw, f->T_wc, pc);
            int id = f->instance[i];
            CHECK(id >= 1 && id <= sc->n_objects);
            if (id < 1 || id > sc->n_objects) continue;
            double d = sooc_scene_object_distance(&sc->objects[id - 1], pw);
            if (d > *worst) *worst = d;
            (*npix)++;
            if (d > tol) {
                CHECK_MSG(d <= tol, "view pixel (%d,%d) id %d (%s): %.3g m from surface", u, v, id,
                          sooc_shape_name(sc->objects[id - 1].shape), d);
                return;
            }
        }
}

static void test_geometry(void) {
    for (int preset = 0; preset < 2; preset++) {
        sooc_gen_params p;
        sooc_gen_params_default(&p);
        p.preset = (sooc_gen_preset)preset;
        p.scale = SOOC_GEN_L;
        p.n_views = 8;
        p.n_query = 2;
        p.width = 96;
        p.height = 72;
        p.seed = 3;
        sooc_scene sc;
        sooc_scene_init(&sc);
        CHECK_OK(sooc_gen_scene(&sc, &p, 0));
        sooc_intrinsics K;
        sooc_gen_intrinsics(&K, p.width, p.height, p.fov_deg);
        sooc_frame f = {0};
        int64_t npix = 0;
        double worst = 0;
        int shapes_seen[SOOC_SHAPE_COUNT] = {0};
        for (int v = 0; v < sc.n_views; v++) {
            CHECK_OK(sooc_gen_render_view(&sc, sc.view_T_wc + 16 * v, &K, &f));
            check_view_geometry(&sc, &f, 1e-3, &npix, &worst);
            for (int i = 0; i < f.width * f.height; i++)
                if (f.instance[i]) shapes_seen[sc.objects[f.instance[i] - 1].shape] = 1;
            /* depth is 0 exactly where invalid, and within the clip */
            for (int i = 0; i < f.width * f.height; i++) {
                CHECK(f.valid[i] == (f.depth[i] > 0));
                if (f.depth[i] > sc.clip_depth) { CHECK(f.depth[i] <= sc.clip_depth); break; }
            }
        }
        int nshapes = 0;
        for (int k = 0; k < SOOC_SHAPE_COUNT; k++) nshapes += shapes_seen[k];
        printf("geometry %s: %lld object pixels, worst %.3g m, %d shapes seen\n", preset ? "blender" : "unity",
               (long long)npix, worst, nshapes);
        CHECK(npix > 1000);
        CHECK(nshapes >= (preset ? 6 : 3));
        /* objects never intersect and stand inside the room */
        for (int a = 0; a < sc.n_objects; a++) {
            const sooc_scene_object *A = &sc.objects[a];
            CHECK(fabs(A->x) + sooc_scene_object_footprint(A) <= sc.room_size / 2 + 1e-9);
            double mx = fmax(A->size[0], fmax(A->size[1], A->size[2]));
            CHECK(mx >= 0.2 - 1e-9 && mx <= 1.0 + 1e-9);
            for (int b = a + 1; b < sc.n_objects; b++) {
                const sooc_scene_object *B = &sc.objects[b];
                CHECK(hypot(A->x - B->x, A->z - B->z) >= sooc_scene_object_footprint(A) + sooc_scene_object_footprint(B));
            }
        }
        /* cameras 1.2-2 m high, pitched 20-40 degrees down */
        for (int v = 0; v < sc.n_views; v++) {
            double Tg[16], h, pitch, roll;
            CHECK_OK(sooc_gframe(sc.view_T_wc + 16 * v, Tg, &h, &pitch, &roll));
            CHECK(h >= 1.2 - 1e-9 && h <= 2.0 + 1e-9);
            CHECK(-pitch >= 20 * M_PI / 180 - 1e-6 && -pitch <= 40 * M_PI / 180 + 1e-6);
            CHECK(fabs(roll) < 1e-6);
        }
        /* scene.yaml round trip */
        char *dir = tu_tmpdir("scene");
        char path[700];
        snprintf(path, sizeof path, "%s/scene.yaml", dir);
        CHECK_OK(sooc_scene_save(path, &sc));
        sooc_scene back;
        sooc_scene_init(&back);
        CHECK_OK(sooc_scene_load(path, &back));
        CHECK(back.n_objects == sc.n_objects && back.n_views == sc.n_views);
        CHECK(back.floor_tex == sc.floor_tex && back.walls == sc.walls && back.shadows == sc.shadows);
        for (int i = 0; i < sc.n_objects && i < back.n_objects; i++) {
            CHECK(back.objects[i].shape == sc.objects[i].shape && back.objects[i].id == sc.objects[i].id);
            CHECK_CLOSE(back.objects[i].x, sc.objects[i].x, 1e-8, 0);
            CHECK_CLOSE(back.objects[i].yaw, sc.objects[i].yaw, 1e-8, 0);
            CHECK_CLOSE(back.objects[i].params[0], sc.objects[i].params[0], 1e-8, 0);
        }
        for (int v = 0; v < sc.n_views && v < back.n_views; v++) CHECK(back.view_is_query[v] == sc.view_is_query[v]);
        snprintf(path, sizeof path, "%s/meshes", dir);
        CHECK_OK(sooc_scene_write_meshes(path, &sc));
        /* bad scene.yaml */
        tu_write(dir, "bad.yaml", "%%YAML 1.2\n---\nformat: sooc3d-scene\nversion: 1\ninput_views: [0]\nquery_views: []\n"
                 "objects:\n  - {id: 1, shape: blob, x: 0, z: 0, yaw: 0, size: [1, 1, 1], params: [1], color: [1, 1, 1]}\n");
        snprintf(path, sizeof path, "%s/bad.yaml", dir);
        CHECK_ERR_HAS(sooc_scene_load(path, &back), "bad.yaml:8", "blob");
        /* duplicate keys are errors (a repeated input_views leaked the first list) */
        tu_write(dir, "dup.yaml", "format: sooc3d-scene\ninput_views: [0]\ninput_views: [1]\n");
        snprintf(path, sizeof path, "%s/dup.yaml", dir);
        CHECK_ERR_HAS(sooc_scene_load(path, &back), "dup.yaml:3", "input_views: duplicate key (first given at line 2)");
        tu_write(dir, "dupobj.yaml", "format: sooc3d-scene\nversion: 1\ninput_views: [0]\nquery_views: []\nobjects:\n"
                 "  - {id: 1, shape: box, x: 0, x: 1, z: 0, yaw: 0, size: [1, 1, 1], params: [1], color: [1, 1, 1]}\n");
        snprintf(path, sizeof path, "%s/dupobj.yaml", dir);
        CHECK_ERR_HAS(sooc_scene_load(path, &back), "dupobj.yaml:6", "objects.x: duplicate key");
        sooc_scene_free(&back);
        tu_rm_rf(dir);
        sooc_frame_free(&f);
        sooc_scene_free(&sc);
    }
}

static void test_roundtrip(void) {
    sooc_gen_params p;
    sooc_gen_params_default(&p);
    p.preset = SOOC_GEN_BLENDER;
    p.scale = SOOC_GEN_M;
    p.n_views = 5;
    p.n_query = 2;
    p.seed = 11;
    p.width = 48;
    p.height = 40;
    char *dir = tu_tmpdir("rt");
    CHECK_OK(sooc_gen_run(&p, dir, NULL, NULL, NULL));
    sooc_scene sc;
    sooc_scene_init(&sc);
    CHECK_OK(sooc_gen_scene(&sc, &p, 0));
    char sd[700];
    snprintf(sd, sizeof sd, "%s/scene_0000", dir);
    sooc_seq *seq = NULL;
    CHECK_OK(sooc_seq_open(&seq, sd, NULL));
    if (!seq) { tu_rm_rf(dir); return; }
    CHECK(sooc_seq_count(seq) == 7 && sooc_seq_get_format(seq) == SOOC_SEQ_TUM);
    sooc_intrinsics K;
    sooc_gen_intrinsics(&K, p.width, p.height, p.fov_deg);
    sooc_frame f = {0}, g = {0};
    int nq = 0;
    for (int v = 0; v < 7; v++) {
        CHECK_OK(sooc_seq_read(seq, v, &f));
        CHECK_OK(sooc_gen_render_view(&sc, sc.view_T_wc + 16 * v, &K, &g));
        CHECK(f.width == 48 && f.height == 40 && f.instance);
        CHECK(memcmp(f.rgb, g.rgb, 48 * 40 * 3) == 0);
        CHECK(f.instance && memcmp(f.instance, g.instance, 48 * 40 * 2) == 0);
        double maxdz = 0;
        for (int i = 0; i < 48 * 40; i++) {
            CHECK(f.valid[i] == g.valid[i]);
            double dz = fabs(f.depth[i] - g.depth[i]);
            if (dz > maxdz) maxdz = dz;
        }
        CHECK_MSG(maxdz <= 1.01e-4, "depth round trip error %g > half a unit", maxdz);
        for (int k = 0; k < 16; k++) CHECK_CLOSE(f.T_wc[k], g.T_wc[k], 2e-8, 0);
        CHECK_CLOSE(f.K.fx, K.fx, 1e-9, 0);
        CHECK(f.t_ns == (int64_t)v * 100000000);
        nq += f.is_query;
        CHECK(f.is_query == (v >= 5));
    }
    CHECK(nq == 2);
    struct stat stt;
    char cs[700];
    snprintf(cs, sizeof cs, "%s/contact_sheet.png", dir);
    CHECK(stat(cs, &stt) == 0 && stt.st_size > 1000);
    sooc_seq_close(seq);
    sooc_frame_free(&f);
    sooc_frame_free(&g);
    sooc_scene_free(&sc);
    tu_rm_rf(dir);
}

static void test_scales(void) {
    /* constant density: object count grows with area; the walk keeps views busy */
    sooc_gen_params p;
    sooc_gen_params_default(&p);
    int counts[4];
    for (int s = 0; s < 4; s++) {
        p.scale = (sooc_gen_scale)s;
        sooc_scene sc;
        sooc_scene_init(&sc);
        CHECK_OK(sooc_gen_scene(&sc, &p, 0));
        counts[s] = sc.n_objects;
        CHECK(sc.n_views == sooc_gen_default_views(p.scale) + (sooc_gen_default_views(p.scale) / 5 > 2 ? sooc_gen_default_views(p.scale) / 5 : 2));
        sooc_scene_free(&sc);
    }
    printf("objects per scene s/m/l/xl: %d %d %d %d\n", counts[0], counts[1], counts[2], counts[3]);
    CHECK(counts[1] > 2 * counts[0] && counts[2] > 6 * counts[1] && counts[3] > 3 * counts[2]);
}

/* --walls MIN,MAX: walls in every room within the heights; everything else
 * (objects, cameras) as without it; out-of-range heights are refused */
static void test_walls(void) {
    sooc_gen_params p;
    sooc_gen_params_default(&p);
    p.scale = SOOC_GEN_M;
    int with_walls = 0;
    for (int i = 0; i < 8; i++) {
        sooc_scene a, b;
        sooc_scene_init(&a);
        sooc_scene_init(&b);
        p.wall_h[0] = p.wall_h[1] = 0;
        CHECK_OK(sooc_gen_scene(&a, &p, i));
        p.wall_h[0] = 2.2, p.wall_h[1] = 3.0;
        CHECK_OK(sooc_gen_scene(&b, &p, i));
        with_walls += a.walls;
        CHECK(a.wall_height >= 0.3 && a.wall_height <= 0.8);
        CHECK_MSG(b.walls && b.wall_height >= 2.2 && b.wall_height <= 3.0, "scene %d: walls %d height %g", i, b.walls,
                  b.wall_height);
        CHECK(a.n_objects == b.n_objects && a.n_views == b.n_views);
        for (int k = 0; k < a.n_objects && k < b.n_objects; k++)
            CHECK(a.objects[k].x == b.objects[k].x && a.objects[k].z == b.objects[k].z);
        for (int v = 0; v < a.n_views && v < b.n_views; v++) CHECK(!memcmp(a.view_T_wc + 16 * v, b.view_T_wc + 16 * v, 16 * sizeof(double)));
        sooc_scene_free(&a);
        sooc_scene_free(&b);
    }
    CHECK_MSG(with_walls > 0 && with_walls < 8, "default: walls in %d of 8 rooms", with_walls);
    sooc_scene sc;
    sooc_scene_init(&sc);
    p.wall_h[0] = 3.0, p.wall_h[1] = 2.0;
    CHECK(sooc_gen_scene(&sc, &p, 0) == SOOC_EINVAL);
    sooc_clearerr();
    sooc_scene_free(&sc);
}

int main(void) {
    test_walls();
    test_determinism();
    test_geometry();
    test_roundtrip();
    test_scales();
    return check_report("test_data_gen");
}
