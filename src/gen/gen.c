/* Synthetic world generator: scene sampling (objects, lighting, camera walk,
 * query views), statistics, contact sheets, and the dataset writer loop. */
#include "sooc3d/gen.h"
#include "sooc3d/frame.h"
#include "gen/gen_impl.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

#define DEG (M_PI / 180.0)

static void hsv2rgb(double h, double s, double v, float out[3]) {
    h = fmod(h, 1.0) * 6;
    int i = (int)h;
    double f = h - i, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    double r, g, b;
    switch (i) {
    case 0: r = v; g = t; b = p; break;
    case 1: r = q; g = v; b = p; break;
    case 2: r = p; g = v; b = t; break;
    case 3: r = p; g = q; b = v; break;
    case 4: r = t; g = p; b = v; break;
    default: r = v; g = p; b = q; break;
    }
    out[0] = (float)r; out[1] = (float)g; out[2] = (float)b;
}

static double U(sooc_rng *r, double a, double b) { return sooc_rng_range(r, a, b); }

static void sample_object(sooc_rng *r, sooc_gen_preset preset, sooc_scene_object *o) {
    memset(o, 0, sizeof *o);
    double u = sooc_rng_uniform(r);
    if (preset == SOOC_GEN_UNITY) {
        o->shape = (sooc_shape)(int)(u * 4);
    } else {
        static const double w[] = {0.09, 0.09, 0.09, 0.08, 0.14, 0.16, 0.12, 0.11, 0.12};
        double acc = 0;
        o->shape = SOOC_SHAPE_SHELF;
        for (int i = 0; i < 9; i++) {
            acc += w[i];
            if (u < acc) { o->shape = (sooc_shape)i; break; }
        }
    }
    double *q = o->params;
    switch (o->shape) {
    case SOOC_SHAPE_SPHERE: q[0] = U(r, 0.1, 0.45); o->size[0] = o->size[1] = o->size[2] = 2 * q[0]; break;
    case SOOC_SHAPE_BOX:
        q[0] = U(r, 0.1, 0.45); q[1] = U(r, 0.1, 0.45); q[2] = U(r, 0.1, 0.45);
        o->size[0] = 2 * q[0]; o->size[1] = 2 * q[1]; o->size[2] = 2 * q[2];
        break;
    case SOOC_SHAPE_CYLINDER:
        q[0] = U(r, 0.1, 0.4); q[1] = U(r, 0.1, 0.5);
        o->size[0] = o->size[2] = 2 * q[0]; o->size[1] = 2 * q[1];
        break;
    case SOOC_SHAPE_CONE:
        q[0] = U(r, 0.12, 0.45); q[1] = U(r, 0.25, 1.0);
        o->size[0] = o->size[2] = 2 * q[0]; o->size[1] = q[1];
        break;
    case SOOC_SHAPE_TORUS:
        q[0] = U(r, 0.15, 0.35); q[1] = q[0] * U(r, 0.3, 0.5);
        o->size[0] = o->size[2] = 2 * (q[0] + q[1]); o->size[1] = 2 * q[1];
        break;
    case SOOC_SHAPE_SUPERQUADRIC:
        q[0] = U(r, 0.12, 0.45); q[1] = U(r, 0.12, 0.45); q[2] = U(r, 0.12, 0.45);
        q[3] = U(r, 0.3, 1.3); q[4] = U(r, 0.3, 1.3);
        o->size[0] = 2 * q[0]; o->size[1] = 2 * q[1]; o->size[2] = 2 * q[2];
        break;
    case SOOC_SHAPE_TABLE:
        q[0] = U(r, 0.6, 1.0); q[1] = U(r, 0.5, q[0] < 0.9 ? q[0] : 0.9); q[2] = U(r, 0.45, 0.8);
        q[3] = U(r, 0.03, 0.06); q[4] = U(r, 0.04, 0.08);
        o->size[0] = q[0]; o->size[1] = q[2]; o->size[2] = q[1];
        break;
    case SOOC_SHAPE_CHAIR:
        q[0] = U(r, 0.4, 0.55); q[1] = U(r, 0.4, 0.55); q[2] = U(r, 0.4, 0.5); q[3] = U(r, 0.75, 1.0);
        q[4] = U(r, 0.03, 0.05); q[5] = U(r, 0.035, 0.06);
        o->size[0] = q[0]; o->size[1] = q[3]; o->size[2] = q[1];
        break;
    default: /* shelf */
        q[0] = U(r, 0.5, 1.0); q[1] = U(r, 0.25, 0.4); q[2] = U(r, 0.6, 1.0);
        q[3] = 2 + sooc_rng_below(r, 3); q[4] = U(r, 0.02, 0.04);
        o->size[0] = q[0]; o->size[1] = q[2]; o->size[2] = q[1];
        break;
    }
    o->yaw = U(r, -M_PI, M_PI);
    hsv2rgb(sooc_rng_uniform(r), U(r, 0.45, 0.9), U(r, 0.55, 0.95), o->color);
}

/* Camera centre on the floor (x, z) free: inside the room and clear of objects. */
static int cam_free(const sooc_scene *sc, double x, double z) {
    double half = sc->room_size / 2 - 0.25;
    if (fabs(x) > half || fabs(z) > half) return 0;
    for (int i = 0; i < sc->n_objects; i++) {
        const sooc_scene_object *o = &sc->objects[i];
        double dx = x - o->x, dz = z - o->z, m = sooc_scene_object_footprint(o) + 0.3;
        if (dx * dx + dz * dz < m * m) return 0;
    }
    return 1;
}

static void cam_pose(double T[16], double x, double z, double h, double yaw, double pitch) {
    /* forward f = (sin yaw cos p, -sin p, cos yaw cos p); OpenCV axes x right, y down, z fwd. */
    double f[3] = {sin(yaw) * cos(pitch), -sin(pitch), cos(yaw) * cos(pitch)};
    double up[3] = {0, 1, 0}, xr[3], yd[3];
    sooc_v3_cross(xr, f, up);
    sooc_v3_normalize(xr);
    sooc_v3_cross(yd, f, xr);
    double R[9] = {xr[0], yd[0], f[0], xr[1], yd[1], f[1], xr[2], yd[2], f[2]};
    double t[3] = {x, h, z};
    sooc_se3_from_rt(T, R, t);
}

/* A free point at least `min_dist` from (fx, fz) when possible (the
 * farthest of the candidates otherwise). Returns 0 if nothing is free. */
static int sample_free_point(sooc_rng *r, const sooc_scene *sc, double *x, double *z, double fx,
                             double fz, double min_dist) {
    double half = sc->room_size / 2 - 0.25, best = -1;
    for (int a = 0; a < 500; a++) {
        double px = U(r, -half, half), pz = U(r, -half, half);
        if (!cam_free(sc, px, pz)) continue;
        double d = hypot(px - fx, pz - fz);
        if (d > best) { best = d; *x = px; *z = pz; }
        if (d >= min_dist) return 1;
    }
    return best >= 0;
}

sooc_status sooc_gen_scene(sooc_scene *sc, const sooc_gen_params *p, int index) {
    sooc_scene_free(sc);
    if (p->width <= 0 || p->height <= 0 || p->width > 16384 || p->height > 16384)
        return sooc_seterr(SOOC_EINVAL, "gen: image size %dx%d out of range", p->width, p->height);
    if (!(p->fov_deg > 1 && p->fov_deg < 170))
        return sooc_seterr(SOOC_EINVAL, "gen: fov %g out of range", p->fov_deg);
    if (!(p->density > 0 && p->density < 5))
        return sooc_seterr(SOOC_EINVAL, "gen: density %g out of range (0, 5)", p->density);
    if (p->wall_h[1] != 0 && !(p->wall_h[0] > 0 && p->wall_h[0] <= p->wall_h[1] && p->wall_h[1] <= 20))
        return sooc_seterr(SOOC_EINVAL, "gen: wall heights %g,%g: need 0 < min <= max <= 20 m", p->wall_h[0],
                           p->wall_h[1]);
    if (!(p->touch >= 0 && p->touch <= 1) || !(p->flat >= 0 && p->flat <= 1))
        return sooc_seterr(SOOC_EINVAL, "gen: touch %g and flat %g must lie in [0, 1]", p->touch, p->flat);
    if (p->preset == SOOC_GEN_TABLETOP) return sooc_gen_tabletop_scene(sc, p, index);
    if (p->touch > 0 || p->flat > 0)
        return sooc_seterr(SOOC_EINVAL, "gen: touching and flat objects are the tabletop preset's (--preset tabletop)");
    sooc_rng rng;
    sooc_rng_seed(&rng, p->seed, (uint64_t)index);
    sooc_rng *r = &rng;
    int blender = p->preset == SOOC_GEN_BLENDER;
    snprintf(sc->preset, sizeof sc->preset, "%s", sooc_gen_preset_name(p->preset));
    snprintf(sc->scale, sizeof sc->scale, "%s", sooc_gen_scale_name(p->scale));
    sc->seed = p->seed;
    sc->index = index;
    double S = sooc_gen_scale_side(p->scale);
    sc->room_size = S;
    sc->clip_depth = p->clip_depth;
    sc->width = p->width;
    sc->height = p->height;
    sc->fov_deg = p->fov_deg;
    /* appearance */
    int tall = p->wall_h[1] > 0;   /* --walls (rooms like recorded ones): the same draws, its range */
    sc->walls = sooc_rng_uniform(r) < 0.5 || tall;
    sc->wall_height = tall ? U(r, p->wall_h[0], p->wall_h[1]) : U(r, 0.3, 0.8);
    hsv2rgb(sooc_rng_uniform(r), U(r, 0.1, 0.3), U(r, 0.55, 0.8), sc->wall_color);
    float sky[3];
    hsv2rgb(U(r, 0.55, 0.62), U(r, 0.3, 0.5), U(r, 0.85, 1.0), sky);
    memcpy(sc->sky_color, sky, sizeof sky);
    double el = U(r, 35, 70) * DEG, az = U(r, -M_PI, M_PI);
    sc->light_dir[0] = cos(el) * sin(az);
    sc->light_dir[1] = sin(el);
    sc->light_dir[2] = cos(el) * cos(az);
    double fh = sooc_rng_uniform(r);
    if (!blender) {
        sc->floor_tex = SOOC_FLOOR_UNIFORM;
        hsv2rgb(fh, U(r, 0.1, 0.35), U(r, 0.5, 0.75), sc->floor_color);
        memcpy(sc->floor_color2, sc->floor_color, sizeof sc->floor_color);
        sc->ambient = U(r, 0.3, 0.45);
        sc->shadows = 0;
        sc->specular = 0;
    } else {
        sc->floor_tex = (sooc_floor_tex)(1 + sooc_rng_below(r, 3));
        if (sc->floor_tex == SOOC_FLOOR_WOOD) {
            double k = U(r, 0.8, 1.1);
            sc->floor_color[0] = (float)(0.62 * k); sc->floor_color[1] = (float)(0.43 * k); sc->floor_color[2] = (float)(0.25 * k);
            sc->floor_color2[0] = (float)(0.36 * k); sc->floor_color2[1] = (float)(0.22 * k); sc->floor_color2[2] = (float)(0.12 * k);
            sc->tex_scale = U(r, 0.15, 0.25);
        } else {
            hsv2rgb(fh, U(r, 0.1, 0.35), U(r, 0.7, 0.85), sc->floor_color);
            hsv2rgb(fh, U(r, 0.1, 0.35), U(r, 0.35, 0.5), sc->floor_color2);
            sc->tex_scale = sc->floor_tex == SOOC_FLOOR_CHECKER ? U(r, 0.3, 0.6) : U(r, 0.4, 1.0);
        }
        sc->ambient = 0.25;
        sc->shadows = 1;
        sc->specular = 0.35;
        sc->shininess = 40;
    }
    /* objects: constant density, rejection sampling without overlaps */
    int target = (int)lround(p->density * S * S * U(r, 0.85, 1.15));
    if (target < 2) target = 2;
    if (target > 60000) target = 60000;
    sc->objects = sooc_calloc((size_t)target, sizeof *sc->objects);
    if (!sc->objects) return SOOC_ENOMEM;
    for (int attempt = 0; sc->n_objects < target && attempt < target * 40; attempt++) {
        sooc_scene_object o;
        sample_object(r, p->preset, &o);
        double fp = sooc_scene_object_footprint(&o), half = S / 2 - fp - 0.05;
        if (half <= 0) continue;
        o.x = U(r, -half, half);
        o.z = U(r, -half, half);
        int ok = 1;
        for (int j = 0; j < sc->n_objects && ok; j++) {
            const sooc_scene_object *q = &sc->objects[j];
            double dx = o.x - q->x, dz = o.z - q->z, m = fp + sooc_scene_object_footprint(q) + 0.05;
            if (dx * dx + dz * dz < m * m) ok = 0;
        }
        if (!ok) continue;
        o.id = sc->n_objects + 1;
        sc->objects[sc->n_objects++] = o;
    }
    /* cameras: a walk through the room towards random way points */
    int V = p->n_views > 0 ? p->n_views : sooc_gen_default_views(p->scale);
    int Q = p->n_query >= 0 ? p->n_query : (V / 5 > 2 ? V / 5 : 2);
    sc->n_views = V + Q;
    sc->view_is_query = sooc_calloc((size_t)sc->n_views, 1);
    sc->view_T_wc = sooc_calloc((size_t)sc->n_views * 16, sizeof(double));
    double *vx = sooc_calloc((size_t)V * 2, sizeof(double));
    if (!sc->view_is_query || !sc->view_T_wc || !vx) {
        sooc_free(vx);
        sooc_scene_free(sc);
        return SOOC_ENOMEM;
    }
    double x = 0, z = 0, tx = 0, tz = 0;
    /* way points lie across the room, so the camera looks over the objects */
    double far = fmin(0.6 * S, 6.0);
    if (!sample_free_point(r, sc, &x, &z, 0, 0, 0) || !sample_free_point(r, sc, &tx, &tz, x, z, far)) {
        sooc_free(vx);
        sooc_scene_free(sc);
        return sooc_seterr(SOOC_ERR, "gen: scene %d: no free space for the camera", index);
    }
    double heading = atan2(tx - x, tz - z) + U(r, -0.5, 0.5);
    double h = U(r, 1.2, 2.0), pitch = U(r, 20, 40) * DEG;
    double *yaws = vx + V;
    for (int v = 0; v < V; v++) {
        /* look at a point ~3 m ahead, kept inside the room (so that small
         * rooms are looked into, not out of) */
        double inner = S / 2 - 0.8 > 0.2 ? S / 2 - 0.8 : 0.2;
        double lx = x + 3.0 * sin(heading), lz = z + 3.0 * cos(heading);
        lx = lx < -inner ? -inner : lx > inner ? inner : lx;
        lz = lz < -inner ? -inner : lz > inner ? inner : lz;
        double look = hypot(lx - x, lz - z) > 0.5 ? atan2(lx - x, lz - z) : heading;
        double yaw = look + sooc_rng_normal(r) * 5 * DEG;
        cam_pose(sc->view_T_wc + 16 * v, x, z, h, yaw, pitch);
        vx[v] = 0;
        yaws[v] = yaw;
        /* next position */
        h += sooc_rng_normal(r) * 0.05;
        h = h < 1.2 ? 1.2 : h > 2.0 ? 2.0 : h;
        pitch += sooc_rng_normal(r) * 3 * DEG;
        pitch = pitch < 20 * DEG ? 20 * DEG : pitch > 40 * DEG ? 40 * DEG : pitch;
        if (hypot(tx - x, tz - z) < fmax(1.0, 0.25 * S < 3 ? 0.25 * S : 3)) sample_free_point(r, sc, &tx, &tz, x, z, far);
        double want = atan2(tx - x, tz - z), dh = sooc_wrap_angle(want - heading);
        double lim = 25 * DEG;
        heading += (dh > lim ? lim : dh < -lim ? -lim : dh) + sooc_rng_normal(r) * 5 * DEG;
        double step = U(r, 0.35, 0.6);
        for (int k = 0; k < 12; k++) {
            double hk = heading + (k == 0 ? 0 : ((k & 1) ? 1 : -1) * ((k + 1) / 2) * 30 * DEG);
            double nx = x + step * sin(hk), nz = z + step * cos(hk);
            if (cam_free(sc, nx, nz)) { x = nx; z = nz; heading = hk; break; }
        }
    }
    /* query views: near a random input view, <= 0.5 m and <= 30 degrees away */
    for (int q = 0; q < Q; q++) {
        int b = (int)sooc_rng_below(r, (uint32_t)V);
        double bx = sc->view_T_wc[16 * b + 3], bz = sc->view_T_wc[16 * b + 11];
        double qx = bx, qz = bz;
        for (int a = 0; a < 50; a++) {
            double rad = 0.5 * sqrt(sooc_rng_uniform(r)), ang = U(r, -M_PI, M_PI);
            double cx = bx + rad * cos(ang), cz = bz + rad * sin(ang);
            if (cam_free(sc, cx, cz)) { qx = cx; qz = cz; break; }
        }
        double yaw = yaws[b] + U(r, -30, 30) * DEG;
        cam_pose(sc->view_T_wc + 16 * (V + q), qx, qz, U(r, 1.2, 2.0), yaw, U(r, 20, 40) * DEG);
        sc->view_is_query[V + q] = 1;
    }
    sooc_free(vx);
    return SOOC_OK;
}

/* ------------------------------------------------------------------ stats */

void sooc_gen_stats_add(sooc_gen_stats *st, const sooc_scene *sc, const sooc_frame *f) {
    int n = sc->n_objects;
    int32_t *cnt = sooc_calloc((size_t)n + 1, sizeof(int32_t));
    if (!cnt) return;
    size_t np = (size_t)f->width * (size_t)f->height;
    for (size_t i = 0; i < np; i++)
        if (f->instance[i] && f->instance[i] <= n && f->valid[i]) cnt[f->instance[i]]++;
    int inview = 0;
    double c[3] = {f->T_wc[3], f->T_wc[7], f->T_wc[11]};
    for (int id = 1; id <= n; id++) {
        if (cnt[id] < 4) continue;
        inview++;
        double oc[3], d[3];
        sooc_scene_object_center(&sc->objects[id - 1], oc);
        sooc_v3_sub(d, oc, c);
        double dist = sooc_v3_norm(d);
        int db = (int)dist;
        st->dist_hist[db < SOOC_GEN_DIST_BINS - 1 ? db : SOOC_GEN_DIST_BINS - 1]++;
        int pb = cnt[id] < 16 ? 0 : cnt[id] < 64 ? 1 : cnt[id] < 256 ? 2 : cnt[id] < 1024 ? 3 : cnt[id] < 4096 ? 4 : 5;
        st->pix_hist[pb]++;
        st->sum_dist += dist;
        st->sum_pix += cnt[id];
    }
    st->n_views++;
    st->n_objects_in_view += inview;
    st->views_by_count[inview < 15 ? inview : 15]++;
    sooc_free(cnt);
}

/* ----------------------------------------------------------- contact sheet */

static sooc_status tile_of(sooc_image *t, const sooc_frame *f, int which, double dmax, int sub) {
    int w = (f->width + sub - 1) / sub, h = (f->height + sub - 1) / sub;
    sooc_status s = sooc_image_alloc(t, w, h, SOOC_PIX_RGB8);
    if (s) return s;
    uint8_t *o = t->data;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)(y * sub) * (size_t)f->width + (size_t)(x * sub);
            uint32_t c;
            if (which == 0) c = SOOC_RGB(f->rgb[3 * i], f->rgb[3 * i + 1], f->rgb[3 * i + 2]);
            else if (which == 1) c = f->depth[i] > 0 ? sooc_cmap_turbo(f->depth[i] / dmax) : 0;
            else c = f->instance ? sooc_cmap_id(f->instance[i]) : 0;
            uint8_t *p = o + 3 * ((size_t)y * (size_t)w + (size_t)x);
            p[0] = (uint8_t)(c >> 16); p[1] = (uint8_t)(c >> 8); p[2] = (uint8_t)c;
        }
    return SOOC_OK;
}

sooc_status sooc_gen_contact_sheet(sooc_image *out, const sooc_frame *const *frames,
                                   const char *const *labels, int n, int per_row, int scale,
                                   double dmax, const char *title) {
    if (n <= 0) return sooc_seterr(SOOC_EINVAL, "contact sheet: no frames");
    sooc_image *tiles = sooc_calloc((size_t)n * 3, sizeof(sooc_image));
    const sooc_image **tp = sooc_calloc((size_t)n * 3, sizeof(*tp));
    const char **lb = sooc_calloc((size_t)n * 3, sizeof(*lb));
    sooc_status s = (tiles && tp && lb) ? SOOC_OK : SOOC_ENOMEM;
    for (int i = 0; i < n && !s; i++) {
        int sub = frames[i]->width > 160 ? (frames[i]->width + 159) / 160 : 1;
        for (int k = 0; k < 3 && !s; k++) {
            s = tile_of(&tiles[3 * i + k], frames[i], k, dmax > 0 ? dmax : 8, sub);
            tp[3 * i + k] = &tiles[3 * i + k];
        }
        lb[3 * i] = labels ? labels[i] : NULL;
        lb[3 * i + 1] = "depth";
        lb[3 * i + 2] = "instance";
    }
    if (!s) s = sooc_image_contact_sheet(out, tp, lb, 3 * n, 3 * (per_row > 0 ? per_row : 4), scale, title);
    for (int i = 0; tiles && i < 3 * n; i++) sooc_image_free(&tiles[i]);
    sooc_free(tiles);
    sooc_free(tp);
    sooc_free(lb);
    return s;
}

/* ------------------------------------------------------------------- run */

#define SHEET_SCENES 4
#define SHEET_VIEWS 4

sooc_status sooc_gen_run(const sooc_gen_params *p, const char *out_dir, sooc_gen_progress_fn cb,
                         void *user, sooc_gen_stats *stats) {
    if (p->n_scenes <= 0) return sooc_seterr(SOOC_EINVAL, "gen: --scenes must be >= 1");
    if (!(p->depth_scale > 0) || p->clip_depth / p->depth_scale > 65535)
        return sooc_seterr(SOOC_EINVAL, "gen: depth_scale %g cannot store clip depth %g m in 16 bits",
                           p->depth_scale, p->clip_depth);
    sooc_status s = sooc_mkdirs(out_dir);
    if (s) return s;
    if (stats) memset(stats, 0, sizeof *stats);
    int V = sooc_gen_views(p);
    int Q = p->n_query >= 0 ? p->n_query : (V / 5 > 2 ? V / 5 : 2);
    int noisy = sooc_gen_noisy(p);
    int64_t total = (int64_t)p->n_scenes * (V + Q), done = 0;
    sooc_frame sheet[SHEET_SCENES * SHEET_VIEWS];
    char sheet_lab[SHEET_SCENES * SHEET_VIEWS][48];
    int n_sheet = 0;
    memset(sheet, 0, sizeof sheet);
    sooc_scene sc;
    sooc_scene_init(&sc);
    sooc_intrinsics K;
    sooc_gen_intrinsics(&K, p->width, p->height, p->fov_deg);
    for (int si = 0; si < p->n_scenes && !s; si++) {
        int idx = p->first_scene + si;
        s = sooc_gen_scene(&sc, p, idx);
        if (s) break;
        char name[32], dir[4096], path[4096];
        snprintf(name, sizeof name, "scene_%04d", idx);
        s = sooc_path_join(dir, sizeof dir, out_dir, name);
        if (s) break;
        if (noisy) { /* sensor noise: depth_gt/ keeps the exact depth (gen_tabletop.c) */
            snprintf(sc.sensor_noise, sizeof sc.sensor_noise, "kinect");
            s = sooc_path_join(path, sizeof path, dir, "depth_gt");
            if (!s) s = sooc_mkdirs(path);
            if (s) break;
        }
        sooc_calib cal;
        sooc_calib_pinhole(&cal, K.width, K.height, K.fx, K.fy, K.cx, K.cy);
        snprintf(cal.camera_name, sizeof cal.camera_name, "sooc3d_synthetic");
        cal.depth_scale = p->depth_scale;
        cal.depth_registered = 1;
        sooc_seq_writer *w = NULL;
        s = sooc_seq_writer_create(&w, dir, &cal, sc.n_views);
        if (s) break;
        sooc_frame *fr = sooc_calloc((size_t)sc.n_views, sizeof(sooc_frame));
        sooc_status *vs = sooc_calloc((size_t)sc.n_views, sizeof(sooc_status));
        char errbuf[512] = "";
        if (!fr || !vs) s = SOOC_ENOMEM;
        int nv = s ? 0 : sc.n_views;
#ifdef SOOC_HAVE_OPENMP
        int nth = p->threads > 0 ? p->threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, 1) num_threads(nth)
#endif
        for (int v = 0; v < nv; v++) {
            sooc_status e = sooc_gen_render_view(&sc, sc.view_T_wc + 16 * v, &K, &fr[v]);
            if (!e && noisy) e = sooc_gen_noise_view(&fr[v], dir, v, p->depth_scale, p->seed, idx);
            if (!e) {
                fr[v].t_ns = (int64_t)v * 100000000;  /* 10 Hz */
                fr[v].index = v;
                fr[v].is_query = sc.view_is_query[v];
                e = sooc_seq_writer_put(w, v, &fr[v]);
            }
            vs[v] = e;
            if (e) {
#ifdef SOOC_HAVE_OPENMP
#pragma omp critical(sooc_gen_err)
#endif
                if (!errbuf[0]) snprintf(errbuf, sizeof errbuf, "%s", sooc_errmsg());
            }
        }
        for (int v = 0; v < nv && !s; v++)
            if (vs[v]) s = sooc_seterr(vs[v], "%s", errbuf);
        if (!s) s = sooc_seq_writer_finish(w);
        sooc_seq_writer_destroy(w);
        if (!s) {
            s = sooc_path_join(path, sizeof path, dir, "scene.yaml");
            if (!s) s = sooc_scene_save(path, &sc);
        }
        if (!s && p->write_meshes) {
            s = sooc_path_join(path, sizeof path, dir, "meshes");
            if (!s) s = sooc_scene_write_meshes(path, &sc);
        }
        for (int v = 0; v < nv && !s; v++)
            if (stats) sooc_gen_stats_add(stats, &sc, &fr[v]);
        if (stats && !s) {
            stats->n_scenes++;
            stats->n_objects_total += sc.n_objects;
        }
        if (!s && si < SHEET_SCENES && p->contact_sheet) {
            int nin = V;
            int pick[SHEET_VIEWS] = {0, nin / 3, (2 * nin) / 3, nin < sc.n_views ? nin : nin - 1};
            for (int k = 0; k < SHEET_VIEWS && !s; k++) {
                s = sooc_frame_copy(&sheet[n_sheet], &fr[pick[k]]);
                snprintf(sheet_lab[n_sheet], sizeof sheet_lab[0], "s%d v%d%s", idx, pick[k],
                         sc.view_is_query[pick[k]] ? " query" : "");
                if (!s) n_sheet++;
            }
        }
        for (int v = 0; fr && v < sc.n_views; v++) sooc_frame_free(&fr[v]);
        sooc_free(fr);
        sooc_free(vs);
        done += sc.n_views;
        if (cb) cb(user, done, total);
    }
    if (!s && n_sheet > 0) {
        const sooc_frame *fp[SHEET_SCENES * SHEET_VIEWS];
        const char *lp[SHEET_SCENES * SHEET_VIEWS];
        for (int i = 0; i < n_sheet; i++) { fp[i] = &sheet[i]; lp[i] = sheet_lab[i]; }
        char title[160], path[4096];
        char where[48];
        double wd[2], dmax = p->clip_depth;
        if (p->preset == SOOC_GEN_TABLETOP && !sooc_gen_tabletop_size(p->scale, wd)) {
            snprintf(where, sizeof where, "%.1f x %.1f m table", wd[0], wd[1]);
            dmax = 2.5; /* arm's reach: colour the depth over 0-2.5 m */
        } else {
            snprintf(where, sizeof where, "%.0f m room", sooc_gen_scale_side(p->scale));
        }
        snprintf(title, sizeof title, "sooc3d gen: preset %s, scale %s (%s), seed %llu, %dx%d%s",
                 sooc_gen_preset_name(p->preset), sooc_gen_scale_name(p->scale), where,
                 (unsigned long long)p->seed, p->width, p->height, noisy ? ", kinect noise" : "");
        sooc_image img = {0};
        int scale = p->width <= 96 ? 2 : 1;
        s = sooc_gen_contact_sheet(&img, fp, lp, n_sheet, SHEET_VIEWS, scale, dmax, title);
        if (!s) s = sooc_path_join(path, sizeof path, out_dir, "contact_sheet.png");
        if (!s) s = sooc_png_write(path, &img, 6);
        sooc_image_free(&img);
    }
    for (int i = 0; i < n_sheet; i++) sooc_frame_free(&sheet[i]);
    sooc_scene_free(&sc);
    return s;
}
