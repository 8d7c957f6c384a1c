/* Tabletop preset and the Kinect sensor-noise model (gen_tabletop.c,
 * sensor_noise.c): exact geometry of the new shapes, generated statistics
 * in range (object sizes, counts, camera distance and pitch, objects per view
 * across s/m/l), measured axial noise against the formula, invalid pixels
 * at depth edges and beyond range, disparity quantisation, determinism. */
#include "util.h"
#include "sooc3d/gen.h"
#include "gen/sensor_noise.h"
#include "sooc3d/frame.h"

#include <math.h>

#define DEG (M_PI / 180.0)

/* Tabletop generator parameters at a scale with V input and Q query views
 * (0 and -1: the preset's defaults). */
static void tt_params(sooc_gen_params *p, sooc_gen_scale scale, int V, int Q) {
    sooc_gen_params_default(p);
    p->preset = SOOC_GEN_TABLETOP;
    p->scale = scale;
    p->n_views = V;
    p->n_query = Q;
}

/* Every valid instance pixel back-projects onto its object's surface;
 * background pixels lie on the support (y = 0 inside the top), a support
 * side, the ground or a room wall. */
static void check_view_geometry(const sooc_scene *sc, const sooc_frame *f, double tol, int64_t *npix,
                                int64_t *nlayout, double *worst) {
    for (int v = 0; v < f->height; v++)
        for (int u = 0; u < f->width; u++) {
            size_t i = (size_t)v * (size_t)f->width + (size_t)u;
            if (!f->valid[i]) continue;
            double dir[3];
            double dz = sooc_cam_ray(&f->K, u, v, dir);
            double t = f->depth[i] / dz, pc[3] = {dir[0] * t, dir[1] * t, dir[2] * t}, pw[3];
            sooc_se3_apply(pw, f->T_wc, pc);
            int id = f->instance[i];
            if (!id) {
                /* on the layout plane inside the top: count it */
                if (fabs(pw[1]) < 1e-6 && fabs(pw[0]) < sc->support_size[0] / 2 + 1e-6 &&
                    fabs(pw[2]) < sc->support_size[1] / 2 + 1e-6)
                    (*nlayout)++;
                CHECK_MSG(pw[1] >= -sc->support_height - 1e-6, "pixel (%d,%d) below the ground: y = %g", u, v, pw[1]);
                continue;
            }
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
    sooc_gen_params p;
    tt_params(&p, SOOC_GEN_M, 10, 2);
    p.width = 128;
    p.height = 96;
    int shapes_seen[SOOC_SHAPE_COUNT] = {0}, supports[3] = {0}, textures[4] = {0};
    int64_t npix = 0, nlayout = 0;
    double worst = 0;
    sooc_frame f = {0};
    sooc_intrinsics K;
    sooc_gen_intrinsics(&K, p.width, p.height, p.fov_deg);
    for (int k = 0; k < 8; k++) {
        sooc_scene sc;
        sooc_scene_init(&sc);
        CHECK_OK(sooc_gen_scene(&sc, &p, k));
        supports[sc.support]++;
        for (int v = 0; v < sc.n_views; v++) {
            CHECK_OK(sooc_gen_render_view(&sc, sc.view_T_wc + 16 * v, &K, &f));
            check_view_geometry(&sc, &f, 1e-3, &npix, &nlayout, &worst);
            for (int i = 0; i < f.width * f.height; i++)
                if (f.instance[i]) {
                    shapes_seen[sc.objects[f.instance[i] - 1].shape] = 1;
                    textures[sc.objects[f.instance[i] - 1].tex] = 1;
                }
        }
        sooc_scene_free(&sc);
    }
    printf("geometry tabletop: %lld object pixels (worst %.3g m), %lld layout pixels, supports table %d bin %d\n",
           (long long)npix, worst, (long long)nlayout, supports[SOOC_SUPPORT_TABLE], supports[SOOC_SUPPORT_BIN]);
    CHECK(npix > 5000 && nlayout > 20000);
    CHECK(shapes_seen[SOOC_SHAPE_CUP] && shapes_seen[SOOC_SHAPE_BOWL] && shapes_seen[SOOC_SHAPE_BOX] &&
          shapes_seen[SOOC_SHAPE_BOTTLE] && shapes_seen[SOOC_SHAPE_CAN]);
    CHECK(textures[SOOC_TEX_PLAIN] && textures[SOOC_TEX_STRIPES] && textures[SOOC_TEX_CHECKS] && textures[SOOC_TEX_LABEL]);
    CHECK(supports[SOOC_SUPPORT_TABLE] > 0 && supports[SOOC_SUPPORT_BIN] > 0 && supports[SOOC_SUPPORT_FLOOR] == 0);
    sooc_frame_free(&f);
}

/* A textured object is not one colour: its pixels take more than 2 values
 * per channel even without noise. */
static void test_textures(void) {
    sooc_scene sc;
    sooc_scene_init(&sc);
    snprintf(sc.preset, sizeof sc.preset, "tabletop");
    sc.support = SOOC_SUPPORT_TABLE;
    sc.support_size[0] = sc.support_size[1] = 1;
    sc.support_height = 0.75;
    sc.support_thick = 0.03;
    sc.ambient = 1; /* flat shading: only the texture changes the colour */
    sc.objects = sooc_calloc(1, sizeof *sc.objects);
    sc.n_objects = 1;
    sooc_scene_object *o = &sc.objects[0];
    o->id = 1;
    o->shape = SOOC_SHAPE_CAN;
    o->params[0] = 0.04; o->params[1] = 0.12;
    o->size[0] = o->size[2] = 0.08; o->size[1] = 0.12;
    o->color[0] = 0.8f; o->color[1] = 0.1f; o->color[2] = 0.1f;
    o->color2[0] = 0.9f; o->color2[1] = 0.9f; o->color2[2] = 0.9f;
    o->tex_scale = 0.015;
    sooc_intrinsics K;
    sooc_gen_intrinsics(&K, 96, 96, 40);
    /* camera 0.4 m in front (-z), level, looking at +z; OpenCV axes in world
     * coordinates: x right = -X, y down = -Y, z forward = +Z */
    double T[16], R[9] = {-1, 0, 0, 0, -1, 0, 0, 0, 1}, c[3] = {0, 0.06, -0.4};
    sooc_se3_from_rt(T, R, c);
    sooc_frame f = {0};
    for (int tex = 0; tex < 4; tex++) {
        o->tex = (sooc_obj_tex)tex;
        CHECK_OK(sooc_gen_render_view(&sc, T, &K, &f));
        int seen[2] = {0, 0}, n = 0;
        for (int i = 0; i < 96 * 96; i++)
            if (f.instance[i] == 1) {
                n++;
                if (f.rgb[3 * i + 1] < 60) seen[0] = 1;       /* red-ish: the base colour */
                if (f.rgb[3 * i + 1] > 150) seen[1] = 1;      /* light: the second colour */
            }
        CHECK_MSG(n > 500, "texture %d: the can covers %d pixels", tex, n);
        if (tex == SOOC_TEX_PLAIN) CHECK_MSG(seen[0] && !seen[1], "plain texture shows a second colour");
        else CHECK_MSG(seen[0] && seen[1], "texture %d does not show both colours", tex);
    }
    sooc_frame_free(&f);
    sooc_scene_free(&sc);
}

/* Statistics over generated scenes: the brief's ranges, and objects per view
 * similar across scales. */
static void test_statistics(void) {
    double per_view[3];
    for (int s = 0; s < 3; s++) {
        sooc_gen_params p;
        tt_params(&p, (sooc_gen_scale)s, 0, -1);
        double wd[2];
        CHECK_OK(sooc_gen_tabletop_size(p.scale, wd));
        sooc_intrinsics K;
        sooc_gen_intrinsics(&K, p.width, p.height, p.fov_deg);
        sooc_gen_stats st;
        memset(&st, 0, sizeof st);
        sooc_frame f = {0};
        int nmin = 99, nmax = 0;
        double dmin = 9, dmax = 0, pmin = 9, pmax = 0, smin = 9, smax = 0;
        for (int k = 0; k < 20; k++) {
            sooc_scene sc;
            sooc_scene_init(&sc);
            CHECK_OK(sooc_gen_scene(&sc, &p, k));
            CHECK(sc.n_views == sooc_gen_views(&p) + (sooc_gen_views(&p) / 5 > 2 ? sooc_gen_views(&p) / 5 : 2));
            nmin = sc.n_objects < nmin ? sc.n_objects : nmin;
            nmax = sc.n_objects > nmax ? sc.n_objects : nmax;
            CHECK(sc.support_size[0] == wd[0] && sc.support_size[1] == wd[1]);
            for (int a = 0; a < sc.n_objects; a++) {
                const sooc_scene_object *A = &sc.objects[a];
                double mx = fmax(A->size[0], fmax(A->size[1], A->size[2]));
                smin = fmin(smin, mx);
                smax = fmax(smax, mx);
                double fp = sooc_scene_object_footprint(A);
                CHECK(fabs(A->x) + fp <= wd[0] / 2 + 1e-9 && fabs(A->z) + fp <= wd[1] / 2 + 1e-9);
                for (int b = a + 1; b < sc.n_objects; b++) {
                    const sooc_scene_object *B = &sc.objects[b];
                    CHECK(hypot(A->x - B->x, A->z - B->z) >= fp + sooc_scene_object_footprint(B));
                }
            }
            for (int v = 0; v < sc.n_views; v++) {
                const double *T = sc.view_T_wc + 16 * v;
                double Tg[16], h, pitch, roll;
                CHECK_OK(sooc_gframe(T, Tg, &h, &pitch, &roll));
                CHECK(fabs(roll) < 1e-6);
                /* distance to where the optical axis meets the support plane */
                double d = h / sin(-pitch);
                dmin = fmin(dmin, d); dmax = fmax(dmax, d);
                pmin = fmin(pmin, -pitch); pmax = fmax(pmax, -pitch);
                CHECK_OK(sooc_gen_render_view(&sc, T, &K, &f));
                sooc_gen_stats_add(&st, &sc, &f);
            }
            sooc_scene_free(&sc);
        }
        sooc_frame_free(&f);
        per_view[s] = (double)st.n_objects_in_view / (double)st.n_views;
        printf("tabletop %s (%.1f x %.1f m): objects %d-%d, sizes %.3f-%.3f m, camera %.3f-%.3f m, pitch %.1f-%.1f deg, "
               "%.2f objects per view (%lld views)\n", sooc_gen_scale_name(p.scale), wd[0], wd[1], nmin, nmax, smin,
               smax, dmin, dmax, pmin / DEG, pmax / DEG, per_view[s], (long long)st.n_views);
        CHECK(nmin >= 2 && nmax <= 12);
        CHECK(smin >= 0.04 - 1e-9 && smax <= 0.30 + 1e-9);
        CHECK(dmin >= 0.35 - 1e-9 && dmax <= 1.0 + 1e-9);
        CHECK(pmin >= 25 * DEG - 1e-9 && pmax <= 70 * DEG + 1e-9);
        CHECK(st.views_by_count[0] < st.n_views / 10); /* <10% of the views show no object */
    }
    /* docs/formats.md 5.1: l within 25% of m; s (whose whole table is in view) at least half of m */
    CHECK_MSG(fabs(per_view[2] / per_view[1] - 1) <= 0.25, "objects per view l %.2f vs m %.2f", per_view[2], per_view[1]);
    CHECK_MSG(per_view[0] >= 0.5 * per_view[1], "objects per view s %.2f vs m %.2f", per_view[0], per_view[1]);
    /* xl is not a tabletop scale */
    double wd[2];
    CHECK(sooc_gen_tabletop_size(SOOC_GEN_XL, wd) == SOOC_EINVAL);
}

/* A plane over a W x W frame at depth z, its depth rising by `tilt` x z from
 * left to right (tilt 0: fronto-parallel; a tilt spreads the depths over
 * several disparity steps, as real surfaces are, so the quantisation error
 * is not that of one grid phase). */
static double plane_z(int W, int i, double z, double tilt) { return z * (1 + tilt * ((double)(i % W) / W - 0.5)); }

static void plane_frame(sooc_frame *f, int W, double z, double tilt) {
    if (f->width != W) {
        sooc_frame_free(f);
        CHECK_OK(sooc_frame_alloc(f, W, W, 1));
    }
    sooc_gen_intrinsics(&f->K, W, W, 60);
    for (int i = 0; i < W * W; i++) {
        f->depth[i] = (float)plane_z(W, i, z, tilt);
        f->valid[i] = 1;
        f->rgb[3 * i] = f->rgb[3 * i + 1] = f->rgb[3 * i + 2] = 128;
    }
}

/* Measured axial std at several depths against sigma_z(z), with and without
 * disparity quantisation, over 262,144 pixels per depth. */
static void test_noise_sigma(void) {
    sooc_frame f = {0};
    const double zs[] = {0.4, 0.6, 0.9, 1.3, 2.0, 3.0};
    for (int quant = 0; quant < 2; quant++) {
        sooc_noise_params np;
        sooc_noise_params_kinect(&np);
        np.quantise = quant;
        for (int k = 0; k < 6; k++) {
            /* errors normalised by sigma_z at each pixel's exact depth (the
             * tilt changes sigma_z by about +-1.5% over the plane) */
            double z = zs[k], s1 = 0, s2 = 0;
            int64_t n = 0;
            plane_frame(&f, 512, z, 0.02);
            CHECK_OK(sooc_noise_apply(&f, &np, 5, 1, k));
            for (int i = 0; i < 512 * 512; i++)
                if (f.valid[i]) {
                    double zi = plane_z(512, i, z, 0.02), e = (f.depth[i] - zi) / sooc_noise_sigma_z(&np, zi);
                    s1 += e;
                    s2 += e * e;
                    n++;
                }
            double want = sooc_noise_sigma_z(&np, z);
            double mean = s1 / (double)n * want, sd = sqrt(s2 / (double)n - (s1 / (double)n) * (s1 / (double)n)) * want;
            printf("noise quantise=%d z %.1f m: sigma %.5f m (formula %.5f, ratio %.4f), bias %+.6f m, %lld valid\n",
                   quant, z, sd, want, sd / want, mean, (long long)n);
            CHECK_MSG(fabs(sd / want - 1) < 0.03, "z %.1f: measured sigma %.5f vs %.5f", z, sd, want);
            CHECK_MSG(fabs(mean) < 0.1 * want, "z %.1f: bias %.6f", z, mean);
            CHECK(n > 512 * 512 * 0.99); /* only speckle dropout on a plane */
        }
    }
    CHECK_CLOSE(sooc_noise_sigma_z(&(sooc_noise_params){.sigma0 = 0.0012, .sigma_k = 0.0019, .z0 = 0.4}, 1.4),
                0.0012 + 0.0019, 1e-12, 0);
    /* a plane turned 70 degrees about the camera's y axis: sigma grows with
     * the angle term, 0.0001 / sqrt(z) x 12.2 at 70 degrees */
    {
        sooc_noise_params np;
        sooc_noise_params_kinect(&np);
        int W = 512;
        plane_frame(&f, W, 1, 0);
        double th = 70 * DEG, nx = sin(th), nz = cos(th);
        for (int i = 0; i < W * W; i++) {
            double rx = ((i % W) + 0.5 - f.K.cx) / f.K.fx, den = nx * rx + nz;
            f.depth[i] = den > 0.1 ? (float)(nz / den) : 0; /* n . P = n . (0, 0, 1) */
            f.valid[i] = f.depth[i] > 0;
        }
        sooc_frame ex = {0};
        CHECK_OK(sooc_frame_copy(&ex, &f));
        CHECK_OK(sooc_noise_apply(&f, &np, 9, 2, 0));
        double s1 = 0, s2 = 0, ratio = 0;
        int64_t n = 0;
        int W2 = W / 2;
        for (int i = 0; i < W * W; i++) {
            double z = ex.depth[i];
            if (!f.valid[i] || !(z > 0.5 && z < 2.5)) continue;
            double e = (f.depth[i] - z) / sooc_noise_sigma_zt(&np, z, th);
            s1 += e;
            s2 += e * e;
            n++;
            if (i == W2 * W + W2) ratio = sooc_noise_sigma_zt(&np, z, th) / sooc_noise_sigma_z(&np, z);
        }
        double sd = sqrt(s2 / (double)n - (s1 / (double)n) * (s1 / (double)n));
        printf("noise at 70 degrees: normalised sigma %.4f over %lld pixels (angle term x%.2f at the centre)\n", sd,
               (long long)n, ratio);
        CHECK_MSG(fabs(sd - 1) < 0.03 && n > 50000, "70 degrees: normalised sigma %.4f", sd);
        CHECK(ratio > 1.5);
        sooc_frame_free(&ex);
    }
    /* quantisation alone: every depth lies on the disparity grid F * 8 / k */
    sooc_noise_params np;
    sooc_noise_params_kinect(&np);
    np.sigma0 = np.sigma_k = 0;
    np.speckle_drop = 0;
    plane_frame(&f, 64, 1.2345, 0);
    CHECK_OK(sooc_noise_apply(&f, &np, 5, 1, 0));
    double F8 = np.f_ref * np.baseline * np.subpixel_inv, k = F8 / f.depth[0];
    CHECK_MSG(fabs(k - floor(k + 0.5)) < 1e-3, "depth %.6f is not on the disparity grid (k = %.5f)", f.depth[0], k);
    CHECK(fabs(f.depth[0] - 1.2345) <= 1.2345 * 1.2345 / F8 / 2 * 1.001);
    /* beyond range and too near */
    plane_frame(&f, 64, 3.6, 0);
    CHECK_OK(sooc_noise_apply(&f, &np, 5, 1, 0));
    int nv = 0;
    for (int i = 0; i < 64 * 64; i++) nv += f.valid[i];
    CHECK(nv == 0);
    plane_frame(&f, 64, 0.15, 0);
    CHECK_OK(sooc_noise_apply(&f, &np, 5, 1, 0));
    nv = 0;
    for (int i = 0; i < 64 * 64; i++) nv += f.valid[i];
    CHECK(nv == 0);
    sooc_frame_free(&f);
}

/* On rendered tabletop views: edge pixels are dropped far more often than
 * interior ones, projector shadows fall left of foreground edges, instance
 * ids stay exact, and the noise is a function of (seed, scene, view). */
static void test_noise_invalid(void) {
    sooc_gen_params p;
    tt_params(&p, SOOC_GEN_M, 0, -1);
    p.width = 128;
    p.height = 96;
    sooc_noise_params np;
    sooc_noise_params_kinect(&np);
    sooc_intrinsics K;
    sooc_gen_intrinsics(&K, p.width, p.height, p.fov_deg);
    sooc_frame f = {0}, g = {0}, h = {0};
    int64_t n_all = 0, inv_exact = 0, inv_noisy = 0;
    int64_t edge = 0, edge_drop = 0, flat = 0, flat_drop = 0, shadow_left = 0, shadow_right = 0;
    for (int k = 0; k < 4; k++) {
        sooc_scene sc;
        sooc_scene_init(&sc);
        CHECK_OK(sooc_gen_scene(&sc, &p, k));
        for (int v = 0; v < 6; v++) {
            CHECK_OK(sooc_gen_render_view(&sc, sc.view_T_wc + 16 * v, &K, &f));
            CHECK_OK(sooc_frame_copy(&g, &f));
            CHECK_OK(sooc_noise_apply(&g, &np, p.seed, (uint64_t)k, v));
            CHECK(memcmp(f.instance, g.instance, sizeof(uint16_t) * (size_t)(f.width * f.height)) == 0);
            int W = f.width;
            for (int i = 0; i < W * f.height; i++) {
                n_all++;
                inv_exact += !f.valid[i];
                inv_noisy += !g.valid[i];
            }
            for (int y = 1; y < f.height - 1; y++)
                for (int x = 1; x < W - 1; x++) {
                    size_t i = (size_t)y * (size_t)W + (size_t)x;
                    float z = f.depth[i];
                    if (!(z > np.z_min && z < np.z_max)) continue;
                    float zl = f.depth[i - 1], zr = f.depth[i + 1], zu = f.depth[i - (size_t)W], zd = f.depth[i + (size_t)W];
                    double jump = fmax(fmax(fabs(zl - z), fabs(zr - z)), fmax(fabs(zu - z), fabs(zd - z)));
                    if (jump > 0.1 * z && zl > 0 && zr > 0 && zu > 0 && zd > 0) {
                        edge++;
                        edge_drop += !g.valid[i];
                        /* a background pixel next to a nearer one: shadowed on the left of the foreground */
                        if (zr < z - 0.05) shadow_left += !g.valid[i];
                        if (zl < z - 0.05) shadow_right += !g.valid[i];
                    } else if (jump < 0.01 * z) {
                        flat++;
                        flat_drop += !g.valid[i];
                    }
                }
            /* deterministic: the same stream again gives the same bytes, another view does not */
            CHECK_OK(sooc_frame_copy(&h, &f));
            CHECK_OK(sooc_noise_apply(&h, &np, p.seed, (uint64_t)k, v));
            CHECK(memcmp(h.depth, g.depth, sizeof(float) * (size_t)(W * f.height)) == 0);
            CHECK(memcmp(h.rgb, g.rgb, (size_t)(3 * W * f.height)) == 0);
            CHECK_OK(sooc_frame_copy(&h, &f));
            CHECK_OK(sooc_noise_apply(&h, &np, p.seed, (uint64_t)k, v + 1));
            CHECK(memcmp(h.depth, g.depth, sizeof(float) * (size_t)(W * f.height)) != 0);
        }
        sooc_scene_free(&sc);
    }
    double fe = (double)edge_drop / (double)(edge ? edge : 1), ff = (double)flat_drop / (double)(flat ? flat : 1);
    printf("invalid pixels: %.1f%% of %lld edge pixels, %.2f%% of %lld flat pixels; background pixels left of a "
           "nearer one dropped %lld, right of one %lld\n", 100 * fe, (long long)edge, 100 * ff, (long long)flat,
           (long long)shadow_left, (long long)shadow_right);
    printf("invalid pixels over %lld: %.1f%% exact (beyond the clip), %.1f%% with sensor noise\n", (long long)n_all,
           100.0 * (double)inv_exact / (double)n_all, 100.0 * (double)inv_noisy / (double)n_all);
    CHECK(inv_noisy > inv_exact);
    CHECK(edge > 500 && flat > 10000);
    CHECK(fe > 0.4 && ff < 0.03 && fe > 10 * ff);
    CHECK(shadow_left > shadow_right);
    sooc_frame_free(&f);
    sooc_frame_free(&g);
    sooc_frame_free(&h);
    CHECK(sooc_noise_apply(&f, &np, 1, 0, 0) == SOOC_EINVAL);
}

static uint32_t file_crc(const char *path) {
    void *b;
    size_t n;
    if (sooc_file_read_all(path, 1 << 26, &b, &n)) return 0;
    uint32_t c = sooc_crc32(0, b, n);
    sooc_free(b);
    return c;
}

/* gen_run: bytes independent of the thread count; depth_gt/ is the exact
 * depth, depth/ the noisy one; scene.yaml round trip with the new keys. */
static void test_run(void) {
    sooc_gen_params p;
    tt_params(&p, SOOC_GEN_S, 5, 2);
    p.n_scenes = 2;
    p.seed = 21;
    char *dirs[2];
    uint32_t crc[2] = {0, 0};
    for (int run = 0; run < 2; run++) {
        dirs[run] = tu_tmpdir("tt");
        p.threads = run + 1;
        CHECK_OK(sooc_gen_run(&p, dirs[run], NULL, NULL, NULL));
        const char *sub[] = {"rgb", "depth", "depth_gt", "instance"};
        for (int v = 0; v < 7; v++)
            for (int k = 0; k < 4; k++) {
                char path[800];
                snprintf(path, sizeof path, "%s/scene_0001/%s/%06d.png", dirs[run], sub[k], v);
                uint32_t c = file_crc(path);
                CHECK_MSG(c != 0, "missing %s", path);
                crc[run] = crc[run] * 31u + c;
            }
    }
    CHECK_MSG(crc[0] == crc[1], "threads 1 vs 2 differ");
    /* depth/ differs from depth_gt/ (noise) */
    char a[800], b[800];
    snprintf(a, sizeof a, "%s/scene_0000/depth/000000.png", dirs[0]);
    snprintf(b, sizeof b, "%s/scene_0000/depth_gt/000000.png", dirs[0]);
    CHECK(file_crc(a) != file_crc(b));
    /* the sequence reader sees the noisy depth, exact ids and the query flags */
    char sd[800];
    snprintf(sd, sizeof sd, "%s/scene_0000", dirs[0]);
    sooc_seq *seq = NULL;
    CHECK_OK(sooc_seq_open(&seq, sd, NULL));
    if (seq) {
        sooc_frame f = {0};
        CHECK(sooc_seq_count(seq) == 7);
        CHECK_OK(sooc_seq_read(seq, 6, &f));
        CHECK(f.is_query == 1 && f.instance != NULL);
        int nvalid = 0;
        for (int i = 0; i < f.width * f.height; i++) nvalid += f.valid[i];
        CHECK(nvalid > f.width * f.height / 2 && nvalid < f.width * f.height);
        sooc_frame_free(&f);
        sooc_seq_close(seq);
    }
    /* scene.yaml: load, save, load again: identical text */
    sooc_scene sc, sc2;
    sooc_scene_init(&sc);
    sooc_scene_init(&sc2);
    snprintf(a, sizeof a, "%s/scene_0000/scene.yaml", dirs[0]);
    CHECK_OK(sooc_scene_load(a, &sc));
    CHECK(!strcmp(sc.preset, "tabletop") && !strcmp(sc.sensor_noise, "kinect") && sc.support != SOOC_SUPPORT_FLOOR);
    snprintf(b, sizeof b, "%s/again.yaml", dirs[0]);
    CHECK_OK(sooc_scene_save(b, &sc));
    CHECK(file_crc(a) == file_crc(b));
    CHECK_OK(sooc_scene_load(b, &sc2));
    CHECK(sc2.n_objects == sc.n_objects && sc2.support == sc.support && sc2.rim_height == sc.rim_height);
    for (int i = 0; i < sc.n_objects; i++) {
        CHECK(sc2.objects[i].tex == sc.objects[i].tex && sc2.objects[i].shape == sc.objects[i].shape);
        CHECK_CLOSE(sc2.objects[i].tex_scale, sc.objects[i].tex_scale, 1e-12, 0);
    }
    /* bad values name the file, the line and the key */
    tu_write(dirs[0], "bad1.yaml", "format: sooc3d-scene\nversion: 1\ninput_views: [0]\nquery_views: []\nobjects:\n"
             "  - {id: 1, shape: can, x: 0, z: 0, yaw: 0, size: [1, 1, 1], params: [0.03, 0.1], color: [1, 1, 1], texture: label}\n");
    snprintf(a, sizeof a, "%s/bad1.yaml", dirs[0]);
    CHECK_ERR_HAS(sooc_scene_load(a, &sc2), "bad1.yaml:6", "texture_scale: missing");
    tu_write(dirs[0], "bad2.yaml", "format: sooc3d-scene\nversion: 1\nsupport: shelf\ninput_views: [0]\nquery_views: []\n");
    snprintf(a, sizeof a, "%s/bad2.yaml", dirs[0]);
    CHECK_ERR_HAS(sooc_scene_load(a, &sc2), "bad2.yaml:3", "support: expected floor, table or bin");
    tu_write(dirs[0], "bad3.yaml", "format: sooc3d-scene\nversion: 1\nsupport: table\ninput_views: [0]\nquery_views: []\n");
    snprintf(a, sizeof a, "%s/bad3.yaml", dirs[0]);
    CHECK_ERR_HAS(sooc_scene_load(a, &sc2), "bad3.yaml", "support_size: missing");
    tu_write(dirs[0], "bad4.yaml", "format: sooc3d-scene\nversion: 1\nsensor_noise: lidar\ninput_views: [0]\nquery_views: []\n");
    snprintf(a, sizeof a, "%s/bad4.yaml", dirs[0]);
    CHECK_ERR_HAS(sooc_scene_load(a, &sc2), "bad4.yaml:3", "sensor_noise: expected none or kinect");
    sooc_scene_free(&sc);
    sooc_scene_free(&sc2);
    for (int run = 0; run < 2; run++) tu_rm_rf(dirs[run]);
}

/* The PLY meshes of the tabletop shapes lie on the analytic surfaces. */
static void test_meshes(void) {
    sooc_gen_params p;
    tt_params(&p, SOOC_GEN_L, 0, -1);
    char *dir = tu_tmpdir("ttmesh");
    int seen[SOOC_SHAPE_COUNT] = {0};
    double worst = 0;
    for (int k = 0; k < 3; k++) {
        sooc_scene sc;
        sooc_scene_init(&sc);
        CHECK_OK(sooc_gen_scene(&sc, &p, k));
        CHECK_OK(sooc_scene_write_meshes(dir, &sc));
        for (int i = 0; i < sc.n_objects; i++) {
            char path[800];
            snprintf(path, sizeof path, "%s/object_%04d.ply", dir, sc.objects[i].id);
            void *buf = NULL;
            size_t n = 0;
            CHECK_OK(sooc_file_read_all(path, 1 << 24, &buf, &n));
            if (!buf) continue;
            const char *b = buf, *end = strstr(b, "end_header\n"), *ev = strstr(b, "element vertex ");
            int nv = ev ? atoi(ev + 15) : 0;
            CHECK(end && nv > 0 && (size_t)(end - b) + 11 + (size_t)nv * 15 <= n);
            for (int v = 0; end && v < nv && (size_t)(end - b) + 11 + (size_t)(v + 1) * 15 <= n; v++) {
                float xyz[3];
                memcpy(xyz, end + 11 + (size_t)v * 15, sizeof xyz);
                double pw[3] = {xyz[0], xyz[1], xyz[2]};
                double d = sooc_scene_object_distance(&sc.objects[i], pw);
                if (d > worst) worst = d;
            }
            seen[sc.objects[i].shape] = 1;
            sooc_free(buf);
        }
        sooc_scene_free(&sc);
    }
    printf("meshes: worst vertex distance to the surface %.3g m\n", worst);
    CHECK(worst < 1e-5);
    CHECK(seen[SOOC_SHAPE_CUP] && seen[SOOC_SHAPE_BOWL] && seen[SOOC_SHAPE_BOTTLE] && seen[SOOC_SHAPE_CAN]);
    tu_rm_rf(dir);
}

/* --touch and --flat: objects placed against one another (footprint
 * circles within 3 mm or overlapping by at most 10% of the smaller radius)
 * and flat boxes; the views still render exact surfaces. Other presets and
 * values outside [0, 1] are refused. */
static void test_touch_flat(void) {
    sooc_gen_params p;
    tt_params(&p, SOOC_GEN_M, 4, 2);
    p.touch = 1;
    int placed = 0, touching = 0, flat = 0, objects = 0;
    double worst_gap = 1, worst = 0;
    int64_t npix = 0, nlayout = 0;
    sooc_frame f = {0};
    sooc_intrinsics K;
    sooc_gen_intrinsics(&K, p.width, p.height, p.fov_deg);
    for (int k = 0; k < 12; k++) {
        sooc_scene sc;
        sooc_scene_init(&sc);
        CHECK_OK(sooc_gen_scene(&sc, &p, k));
        for (int i = 1; i < sc.n_objects; i++) {
            const sooc_scene_object *A = &sc.objects[i];
            double fa = sooc_scene_object_footprint(A), best = 1e9;
            for (int j = 0; j < i; j++) {
                const sooc_scene_object *B = &sc.objects[j];
                double fb = sooc_scene_object_footprint(B);
                double gap = hypot(A->x - B->x, A->z - B->z) - fa - fb;
                CHECK_MSG(gap >= -0.1 * fmin(fa, fb) - 1e-9, "scene %d: objects %d and %d overlap by %.3f m", k, i, j, -gap);
                if (gap < best) best = gap;
            }
            placed++;
            touching += best <= 0.003 + 1e-9;
            if (best < worst_gap) worst_gap = best;
        }
        for (int v = 0; v < 2; v++) {
            CHECK_OK(sooc_gen_render_view(&sc, sc.view_T_wc + 16 * v, &K, &f));
            check_view_geometry(&sc, &f, 1e-3, &npix, &nlayout, &worst);
        }
        sooc_scene_free(&sc);
    }
    printf("touch 1: %d of %d objects after the first within 3 mm of one (closest gap %.4f m); views exact to %.3g m\n",
           touching, placed, worst_gap, worst);
    CHECK(placed > 20 && touching >= placed / 2);
    CHECK(worst_gap < 0);
    p.touch = 0;
    p.flat = 1;
    for (int k = 0; k < 12; k++) {
        sooc_scene sc;
        sooc_scene_init(&sc);
        CHECK_OK(sooc_gen_scene(&sc, &p, k));
        for (int i = 0; i < sc.n_objects; i++) {
            const sooc_scene_object *A = &sc.objects[i];
            objects++;
            flat += A->shape == SOOC_SHAPE_BOX && A->size[1] <= 0.04 + 1e-9 && fmax(A->size[0], A->size[2]) >= 0.08 - 1e-9;
        }
        sooc_scene_free(&sc);
    }
    printf("flat 1: %d of %d objects flat\n", flat, objects);
    CHECK(objects > 20 && flat == objects);
    sooc_scene sc;
    sooc_scene_init(&sc);
    p.flat = 1.5;
    CHECK(sooc_gen_scene(&sc, &p, 0) == SOOC_EINVAL);
    p.flat = 0.5;
    p.preset = SOOC_GEN_UNITY;
    CHECK(sooc_gen_scene(&sc, &p, 0) == SOOC_EINVAL);
    sooc_frame_free(&f);
}

int main(void) {
    test_geometry();
    test_touch_flat();
    test_textures();
    test_statistics();
    test_noise_sigma();
    test_noise_invalid();
    test_run();
    test_meshes();
    return check_report("test_data_tabletop");
}
