/* Renderer against an analytic scene: a floor half-space (layout, component
 * 0), a hard-edged sphere (component 1, axis-aligned box) and a vertical
 * cylinder placed by a floor pose (component 2, sooc_render_box_object), all
 * in the gravity-aligned frame G of a camera pitched down by 15 degrees. */
#include "check.h"
#include "sooc3d/render.h"

#include <string.h>

#define W 48
#define H 40
#define HCAM 1.2
static const double SPH_C[3] = {0.4, -0.5, 3.0}, SPH_R = 0.5;
static const double CYL_X = -0.8, CYL_Z = 4.5, CYL_YAW = 0.7, CYL_R = 0.3, CYL_H = 0.9;
#define BOX_RH 0.6
#define BOX_HB 1.2

typedef struct scene {
    int n_eval_calls[8];
    long n_points[3];
    double shift;   /* extra sphere x-offset (posterior sample) */
} scene;

static int in_sphere(const scene *sc, double x, double y, double z) {
    double dx = x - SPH_C[0] - sc->shift, dy = y - SPH_C[1], dz = z - SPH_C[2];
    return dx * dx + dy * dy + dz * dz <= SPH_R * SPH_R;
}
/* object-local coordinates: x_k = R_y(yaw)^T (x - b) */
static void to_local(double x, double y, double z, double l[3]) {
    double R[9], d[3] = {x - CYL_X, y + HCAM, z - CYL_Z};
    sooc_m3_rot_y(R, CYL_YAW);
    sooc_m3_tmulv(l, R, d);
}
static int in_box_local(const double l[3]) {
    return fabs(l[0]) <= BOX_RH && fabs(l[2]) <= BOX_RH && l[1] >= 0 && l[1] <= BOX_HB;
}
static int in_cyl(double x, double y, double z) {
    double l[3];
    to_local(x, y, z, l);
    /* an elliptic cylinder so that yaw matters */
    double ex = l[0] / CYL_R, ez = l[2] / (0.5 * CYL_R);
    return in_box_local(l) && ex * ex + ez * ez <= 1.0 && l[1] <= CYL_H;
}

static void scene_eval(void *user, int worker, int comp, const float *p, int n, float *sig, float *rgb) {
    scene *sc = user;
    (void)worker;
    for (int i = 0; i < n; i++) {
        double x = p[3 * i], y = p[3 * i + 1], z = p[3 * i + 2];
        float s = 0.f, c[3] = {0, 0, 0};
        if (comp == 0) {
            if (y <= -HCAM) {
                s = 1.f;
                int chk = ((int)floor(x * 2) + (int)floor(z * 2)) & 1;
                c[0] = c[1] = c[2] = chk ? 0.8f : 0.4f;
            }
        } else if (comp == 1) {
            if (in_sphere(sc, x, y, z)) { s = 1.f; c[0] = 0.9f; c[1] = 0.1f; c[2] = 0.1f; }
        } else {
            double l[3];
            to_local(x, y, z, l);
            if (in_box_local(l)) {
                if (in_cyl(x, y, z)) s = 1.f;
                c[0] = 0.1f; c[1] = 0.2f; c[2] = 0.9f;
            }
        }
        sig[i] = s;
        rgb[3 * i] = c[0]; rgb[3 * i + 1] = c[1]; rgb[3 * i + 2] = c[2];
    }
#ifdef SOOC_HAVE_OPENMP
#pragma omp atomic
#endif
    sc->n_points[comp] += n;
}

/* analytic first hit by marching at 0.25 mm: returns component or -1, hit
 * depth (planar) and whether the medium persists >= 0.12 m after entry. */
static int cast(const scene *sc, const double r[3], double t0, double t1, double *zhit, int *thick) {
    const double dz = 0.00025;
    for (double z = t0; z <= t1; z += dz) {
        double x = z * r[0], y = z * r[1], zz = z * r[2];
        int k = y <= -HCAM ? 0 : in_sphere(sc, x, y, zz) ? 1 : in_cyl(x, y, zz) ? 2 : -1;
        if (k < 0) continue;
        *zhit = z;
        *thick = 1;
        for (double e = z; e <= z + 0.12; e += 0.005) {
            double a = e * r[0], b = e * r[1], c = e * r[2];
            int in = k == 0 ? b <= -HCAM : k == 1 ? in_sphere(sc, a, b, c) : in_cyl(a, b, c);
            if (!in || e > t1) { *thick = 0; break; }
        }
        return k;
    }
    return -1;
}

static void setup_camera(sooc_intrinsics *K, double T_gc[16]) {
    memset(K, 0, sizeof *K);
    K->width = W; K->height = H;
    K->fx = K->fy = 40.0; K->cx = W / 2.0; K->cy = H / 2.0;
    double p = 15.0 * M_PI / 180.0;
    double R[9] = {-1, 0, 0,
                   0, -cos(p), -sin(p),
                   0, -sin(p), cos(p)};   /* columns: right, down, forward in the world */
    double t[3] = {2.0, HCAM, -1.0}, T_wc[16], T_wg[16], T_gw[16], h, pitch, roll;
    sooc_se3_from_rt(T_wc, R, t);
    CHECK_OK(sooc_gframe(T_wc, T_wg, &h, &pitch, &roll));
    CHECK_CLOSE(h, HCAM, 1e-12, 0);
    sooc_se3_inverse(T_gw, T_wg);
    sooc_se3_mul(T_gc, T_gw, T_wc);
}

static void make_field(sooc_field *f, sooc_render_box boxes[3], scene *sc) {
    memset(f, 0, sizeof *f);
    boxes[0].enabled = 0;
    double lo[3] = {SPH_C[0] + sc->shift - 0.6, SPH_C[1] - 0.6, SPH_C[2] - 0.6};
    double hi[3] = {SPH_C[0] + sc->shift + 0.6, SPH_C[1] + 0.6, SPH_C[2] + 0.6};
    sooc_render_box_aabb(&boxes[1], lo, hi);
    sooc_render_box_object(&boxes[2], CYL_X, CYL_Z, CYL_YAW, HCAM, BOX_RH, BOX_HB);
    f->n_comp = 3;
    f->boxes = boxes;
    f->sigma_max = 1000.f;
    f->eval = scene_eval;
    f->user = sc;
}

static int same_out(const sooc_render_out *a, const sooc_render_out *b) {
    size_t P = (size_t)W * H;
    return !memcmp(a->rgb, b->rgb, P * 3 * sizeof(float)) &&
           !memcmp(a->depth, b->depth, P * sizeof(float)) &&
           !memcmp(a->alpha, b->alpha, P * sizeof(float)) &&
           !memcmp(a->label, b->label, P * sizeof(int16_t));
}

int main(void) {
    sooc_intrinsics K;
    double T_gc[16];
    setup_camera(&K, T_gc);
    scene sc;
    memset(&sc, 0, sizeof sc);
    sooc_render_box boxes[3];
    sooc_field f;
    make_field(&f, boxes, &sc);
    sooc_render_opts o;
    sooc_render_opts_default(&o);
    o.n_coarse = 96; o.n_fine = 32; o.t_near = 0.1; o.d_clip = 8.0;
    o.components = 1; o.soft_seg = 1;
    sooc_render_out out;
    memset(&out, 0, sizeof out);
    double t0 = sooc_seconds();
    CHECK_OK(sooc_render_view(&f, &K, T_gc, &o, &out));
    double t_render = sooc_seconds() - t0;
    {   /* printed so builds with and without OpenMP can be compared */
        uint32_t crc = sooc_crc32(0, out.rgb, (size_t)W * H * 3 * sizeof(float));
        crc = sooc_crc32(crc, out.depth, (size_t)W * H * sizeof(float));
        crc = sooc_crc32(crc, out.label, (size_t)W * H * sizeof(int16_t));
        printf("render crc32 %08x\n", crc);
    }

    /* ---- depth and labels against ray casting ---- */
    double R[9], tt[3];
    sooc_se3_to_rt(R, tt, T_gc);
    int n_hit[3] = {0, 0, 0}, n_sky = 0, bad_lab = 0, bad_sky = 0;
    double max_err[3] = {0, 0, 0}, sum_err = 0;
    int n_err = 0;
    for (int v = 0; v < H; v++) {
        for (int u = 0; u < W; u++) {
            double rc[3] = {(u + 0.5 - K.cx) / K.fx, (v + 0.5 - K.cy) / K.fy, 1.0}, r[3];
            sooc_m3_mulv(r, R, rc);
            double zh = 0;
            int thick = 0, k = cast(&sc, r, o.t_near, o.d_clip, &zh, &thick);
            size_t p = (size_t)v * W + u;
            if (k < 0) {
                n_sky++;
                if (out.label[p] != SOOC_RENDER_LABEL_NONE || out.alpha[p] > 0.01f) bad_sky++;
                CHECK_CLOSE(out.depth[p], o.d_clip, 1e-3, 0);
                continue;
            }
            if (!thick || zh > o.d_clip - 0.2) continue;   /* silhouettes and the clip edge */
            n_hit[k]++;
            double e = fabs(out.depth[p] - zh);
            if (e > max_err[k]) max_err[k] = e;
            sum_err += e;
            n_err++;
            if (out.label[p] != k) bad_lab++;
        }
    }
    printf("render %dx%d, 96+32 samples, sigma_max 1000: %.3f s; clean pixels floor %d sphere %d "
           "cylinder %d sky %d\n", W, H, t_render, n_hit[0], n_hit[1], n_hit[2], n_sky);
    printf("depth |err| max: floor %.4f m, sphere %.4f m, cylinder %.4f m; mean %.4f m\n",
           max_err[0], max_err[1], max_err[2], sum_err / (n_err ? n_err : 1));
    CHECK(n_hit[0] > 100 && n_hit[1] > 50 && n_hit[2] > 15 && n_sky > 50);
    CHECK_MSG(max_err[0] <= 0.02 && max_err[1] <= 0.02 && max_err[2] <= 0.02,
              "depth tolerance 2 cm exceeded");
    CHECK_MSG(bad_lab == 0, "%d clean pixels mislabelled", bad_lab);
    CHECK_MSG(bad_sky == 0, "%d sky pixels not 'none'", bad_sky);
    /* the sphere's colour: red where labelled 1 */
    {
        size_t P = (size_t)W * H;
        int okc = 1;
        for (size_t p = 0; p < P; p++)
            if (out.label[p] == 1 && out.alpha[p] > 0.999f)
                okc &= fabsf(out.rgb[3 * p] - 0.9f) < 1e-3f && fabsf(out.rgb[3 * p + 1] - 0.1f) < 1e-3f;
        CHECK(okc);
        /* per-component images: the sphere alone is opaque where labelled 1 */
        int okk = 1;
        for (size_t p = 0; p < P; p++)
            if (out.label[p] == 1 && out.alpha[p] > 0.999f) okk &= out.comp_alpha[1 * P + p] > 0.99f;
        CHECK(okk);
        /* soft segmentation sums to A */
        double md = 0;
        for (size_t p = 0; p < P; p++) {
            double s = out.seg[p * 3] + out.seg[p * 3 + 1] + out.seg[p * 3 + 2];
            if (fabs(s - out.alpha[p]) > md) md = fabs(s - out.alpha[p]);
        }
        CHECK_MSG(md < 1e-4, "sum_k seg_k - A = %g", md);
    }

    /* ---- sigma_max = 30: expected depth = hit + planar mean free path ---- */
    {
        sooc_render_out o30;
        memset(&o30, 0, sizeof o30);
        sooc_field f30 = f;
        f30.sigma_max = 30.f;
        CHECK_OK(sooc_render_view(&f30, &K, T_gc, &o, &o30));
        double me = 0;
        for (int v = 0; v < H; v++)
            for (int u = 0; u < W; u++) {
                double rc[3] = {(u + 0.5 - K.cx) / K.fx, (v + 0.5 - K.cy) / K.fy, 1.0}, r[3];
                sooc_m3_mulv(r, R, rc);
                double zh = 0;
                int thick = 0, k = cast(&sc, r, o.t_near, o.d_clip, &zh, &thick);
                if (k != 1 || !thick) continue;   /* the sphere is >= 12 cm thick: exp(-3.6) */
                /* thick enough for the sphere centre region only: require 0.4 m of medium */
                double zz = zh + 0.4;
                if (!in_sphere(&sc, zz * r[0], zz * r[1], zz * r[2])) continue;
                double expect = zh + 1.0 / (30.0 * sooc_v3_norm(r));
                double e = fabs(o30.depth[(size_t)v * W + u] - expect);
                if (e > me) me = e;
            }
        printf("sigma_max 30: sphere depth vs hit + 1/(sigma |r|): max |err| %.4f m\n", me);
        CHECK(me <= 0.02);
        sooc_render_out_free(&o30);
    }

    /* ---- culling changes nothing but the work ---- */
    {
        sooc_render_out b;
        memset(&b, 0, sizeof b);
        long n_cull = sc.n_points[1] + sc.n_points[2];
        sc.n_points[1] = sc.n_points[2] = 0;
        sooc_render_opts o2 = o;
        o2.cull = 0;
        CHECK_OK(sooc_render_view(&f, &K, T_gc, &o2, &b));
        long n_all = sc.n_points[1] + sc.n_points[2];
        CHECK(same_out(&out, &b));
        CHECK(!memcmp(out.comp_rgb, b.comp_rgb, (size_t)W * H * 9 * sizeof(float)));
        printf("culling: object evaluations %ld -> %ld (%.1f%%), image identical: %s\n", n_all,
               n_cull, 100.0 * n_cull / n_all, same_out(&out, &b) ? "yes" : "NO");
        CHECK(n_cull < n_all / 4);
        sooc_render_out_free(&b);
    }

    /* ---- threads: 1 vs 2 vs 3 workers, other chunk count; deterministic ---- */
    {
        sooc_render_out b;
        memset(&b, 0, sizeof b);
        for (int nt = 1; nt <= 3; nt++) {
            sooc_render_opts o2 = o;
            o2.threads = nt;
            CHECK_OK(sooc_render_view(&f, &K, T_gc, &o2, &b));
            CHECK_MSG(same_out(&out, &b), "threads=%d differs", nt);
        }
        /* jittered sampling: same seed, same image; different seed, different image */
        sooc_render_opts oj = o;
        oj.jitter = 1; oj.seed = 42; oj.threads = 1;
        sooc_render_out j1, j2;
        memset(&j1, 0, sizeof j1);
        memset(&j2, 0, sizeof j2);
        CHECK_OK(sooc_render_view(&f, &K, T_gc, &oj, &j1));
        oj.threads = 2;
        CHECK_OK(sooc_render_view(&f, &K, T_gc, &oj, &j2));
        CHECK(same_out(&j1, &j2));
        oj.seed = 43;
        CHECK_OK(sooc_render_view(&f, &K, T_gc, &oj, &j2));
        CHECK(!same_out(&j1, &j2));
        sooc_render_out_free(&b);
        sooc_render_out_free(&j1);
        sooc_render_out_free(&j2);
    }

    /* ---- no importance pass: still within a coarse bin ---- */
    {
        sooc_render_out b;
        memset(&b, 0, sizeof b);
        sooc_render_opts o2 = o;
        o2.n_fine = 0;
        CHECK_OK(sooc_render_view(&f, &K, T_gc, &o2, &b));
        double me = 0, dzc = (o.d_clip - o.t_near) / o.n_coarse;
        for (size_t p = 0; p < (size_t)W * H; p++)
            if (out.label[p] == 1 && b.label[p] == 1) {
                double e = fabs(b.depth[p] - out.depth[p]);
                if (e > me) me = e;
            }
        printf("96 coarse only: max |depth - depth(96+32)| on the sphere %.4f m (bin %.4f m)\n", me, dzc);
        CHECK(me <= dzc);
        sooc_render_out_free(&b);
    }

    /* ---- uncertainty: M samples that move the sphere ---- */
    {
        scene s2[4];
        sooc_render_box bx[4][3];
        sooc_field fs[4];
        for (int m = 0; m < 4; m++) {
            memset(&s2[m], 0, sizeof s2[m]);
            s2[m].shift = 0.05 * m;
            make_field(&fs[m], bx[m], &s2[m]);
        }
        sooc_render_out u;
        memset(&u, 0, sizeof u);
        CHECK_OK(sooc_render_uncertainty_fields(fs, 4, &K, T_gc, &o, &u));
        CHECK(u.uncert && u.rgb_mean);
        /* pixels far from the sphere have zero variance; some sphere-edge pixels do not */
        int nz = 0, zero_far = 1;
        for (size_t p = 0; p < (size_t)W * H; p++) {
            if (u.uncert[p] > 1e-3f) nz++;
            if (out.label[p] == 2) zero_far &= u.uncert[p] == 0.f;
        }
        printf("uncertainty (M=4, sphere shifted 5 cm per sample): %d pixels with variance > 1e-3\n", nz);
        CHECK(nz > 5);
        CHECK(zero_far);
        /* identical samples give zero variance everywhere */
        sooc_field same[3] = {f, f, f};
        CHECK_OK(sooc_render_uncertainty_fields(same, 3, &K, T_gc, &o, &u));
        double mx = 0;
        for (size_t p = 0; p < (size_t)W * H; p++) if (u.uncert[p] > mx) mx = u.uncert[p];
        CHECK(mx < 1e-10);
        CHECK(sooc_render_uncertainty_fields(same, 1, &K, T_gc, &o, &u) == SOOC_EINVAL);
        sooc_render_out_free(&u);
    }

    /* ---- ray-box helper and argument checks ---- */
    {
        sooc_render_box b;
        double lo[3] = {-1, -1, 2}, hi[3] = {1, 1, 4}, oo[3] = {0, 0, 0}, r[3] = {0, 0, 1}, z0, z1;
        sooc_render_box_aabb(&b, lo, hi);
        CHECK(sooc_render_ray_box(&b, oo, r, 0, 10, &z0, &z1));
        CHECK_CLOSE(z0, 2, 1e-4, 0);
        CHECK_CLOSE(z1, 4, 1e-4, 0);
        double r2[3] = {1, 0, 1};
        CHECK(!sooc_render_ray_box(&b, oo, r2, 0, 10, &z0, &z1));
        sooc_field bad = f;
        bad.n_comp = 0;
        CHECK(sooc_render_view(&bad, &K, T_gc, &o, &out) == SOOC_EINVAL);
        sooc_render_opts ob = o;
        ob.d_clip = 0.05;
        CHECK(sooc_render_view(&f, &K, T_gc, &ob, &out) == SOOC_EINVAL);
    }
    sooc_render_out_free(&out);
    sooc_alloc_stats st;
    sooc_alloc_get_stats(&st);
    CHECK_MSG(st.live_bytes == 0, "leak: %llu bytes", (unsigned long long)st.live_bytes);
    return check_report("test_render");
}
