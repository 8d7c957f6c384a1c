/* The tabletop preset of `sooc3d gen` (docs/formats.md 5.1): household
 * objects (cups, bowls, boxes, bottles, cans, procedurally textured; flat
 * ones and objects against one another on request) on a table top or in a
 * bin, seen by an arm-mounted camera at arm's reach (0.35-1.0 m from the
 * point it looks at, pitched 25-70 degrees down) that circles the table.
 * The support plane is the layout at y = 0, +y up, as the floor of the
 * unity preset. Scales s/m/l set the table size; the camera distance range
 * is the same at every scale. */
#include "sooc3d/gen.h"
#include "gen/sensor_noise.h"
#include "gen/gen_impl.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define DEG (M_PI / 180.0)

/* table top (x, z) per scale and objects per m^2 of table */
static const double g_tt_size[3][2] = {{1.1, 0.8}, {1.8, 1.1}, {2.4, 1.6}};
#define TT_DENSITY 3.0
#define TT_MIN_OBJECTS 2
#define TT_MAX_OBJECTS 12
/* camera: distance to the look-at point on the support plane, pitch */
#define TT_DMIN 0.35
#define TT_DMAX 1.0
#define TT_PMIN (25 * DEG)
#define TT_PMAX (70 * DEG)

sooc_status sooc_gen_tabletop_size(sooc_gen_scale s, double wd[2]) {
    if ((unsigned)s > (unsigned)SOOC_GEN_L)
        return sooc_seterr(SOOC_EINVAL, "gen: the tabletop preset has scales s, m and l (got %s)", sooc_gen_scale_name(s));
    wd[0] = g_tt_size[s][0];
    wd[1] = g_tt_size[s][1];
    return SOOC_OK;
}

static double U(sooc_rng *r, double a, double b) { return sooc_rng_range(r, a, b); }

/* Same conventions as gen.c's helpers (HSV in [0, 1]; OpenCV camera axes). */
static void tt_hsv(double h, double s, double v, float out[3]) {
    h = fmod(h, 1.0);
    if (h < 0) h += 1;
    h *= 6;
    int i = (int)h;
    double f = h - i, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    double c[6][3] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
    for (int k = 0; k < 3; k++) out[k] = (float)c[i < 6 ? i : 5][k];
}

static void tt_cam_pose(double T[16], const double c[3], double yaw, double pitch) {
    double f[3] = {sin(yaw) * cos(pitch), -sin(pitch), cos(yaw) * cos(pitch)};
    double up[3] = {0, 1, 0}, xr[3], yd[3];
    sooc_v3_cross(xr, f, up);
    sooc_v3_normalize(xr);
    sooc_v3_cross(yd, f, xr);
    double R[9] = {xr[0], yd[0], f[0], xr[1], yd[1], f[1], xr[2], yd[2], f[2]};
    sooc_se3_from_rt(T, R, c);
}

/* A household object with its texture: with odds `flat` a flat one (a
 * packet or book, or a marker lying down: boxes), else a cup, bowl, box,
 * bottle or can. With flat = 0 no draw is made for it, so the scenes of a
 * seed stay those of the preset without flat objects. */
static void tt_object(sooc_rng *r, sooc_scene_object *o, double flat) {
    memset(o, 0, sizeof *o);
    static const double w[5] = {0.22, 0.16, 0.22, 0.20, 0.20}; /* cup bowl box bottle can */
    int kind = 4;
    if (flat > 0 && sooc_rng_uniform(r) < flat) {
        kind = 5;
    } else {
        double u = sooc_rng_uniform(r), acc = 0;
        for (int i = 0; i < 5; i++) {
            acc += w[i];
            if (u < acc) { kind = i; break; }
        }
    }
    double *q = o->params;
    /* texture odds by kind: plain, stripes, checks, label */
    double tex_w[4] = {0.25, 0.25, 0.15, 0.35};
    switch (kind) {
    case 0: { /* cup: rt rb h t, handle on +x */
        o->shape = SOOC_SHAPE_CUP;
        q[0] = U(r, 0.035, 0.05); q[1] = q[0] * U(r, 0.88, 1.0); q[2] = U(r, 0.07, 0.12); q[3] = q[0] * U(r, 0.08, 0.12);
        double c[3], R, rr;
        sooc_scene_cup_handle(q, c, &R, &rr);
        o->size[0] = 2 * fmax(q[0], c[0] + R + rr); o->size[1] = q[2]; o->size[2] = 2 * q[0];
        tex_w[0] = 0.4; tex_w[1] = 0.35; tex_w[2] = 0.1; tex_w[3] = 0.15;
        break;
    }
    case 1: /* bowl: rt rb h t */
        o->shape = SOOC_SHAPE_BOWL;
        q[0] = U(r, 0.06, 0.13); q[1] = q[0] * U(r, 0.45, 0.65); q[2] = q[0] * U(r, 0.5, 0.8); q[3] = U(r, 0.006, 0.01);
        o->size[0] = o->size[2] = 2 * q[0]; o->size[1] = q[2];
        tex_w[0] = 0.5; tex_w[1] = 0.35; tex_w[2] = 0.15; tex_w[3] = 0;
        break;
    case 2: /* box: half extents */
        o->shape = SOOC_SHAPE_BOX;
        q[0] = U(r, 0.02, 0.12); q[1] = U(r, 0.015, 0.14); q[2] = U(r, 0.02, 0.08);
        o->size[0] = 2 * q[0]; o->size[1] = 2 * q[1]; o->size[2] = 2 * q[2];
        tex_w[0] = 0.2; tex_w[1] = 0.15; tex_w[2] = 0.25; tex_w[3] = 0.4;
        break;
    case 3: /* bottle: r h rn hn */
        o->shape = SOOC_SHAPE_BOTTLE;
        q[0] = U(r, 0.025, 0.045); q[1] = U(r, 0.15, 0.30); q[2] = q[0] * U(r, 0.3, 0.45); q[3] = q[1] * U(r, 0.12, 0.25);
        o->size[0] = o->size[2] = 2 * q[0]; o->size[1] = q[1];
        tex_w[0] = 0.3; tex_w[1] = 0.1; tex_w[2] = 0.05; tex_w[3] = 0.55;
        break;
    case 5: /* flat: half extents */
        o->shape = SOOC_SHAPE_BOX;
        if (sooc_rng_uniform(r) < 0.25) {   /* a marker or pen lying down */
            q[0] = U(r, 0.05, 0.075); q[1] = q[2] = U(r, 0.006, 0.01);
        } else {                            /* a packet, book or envelope */
            q[0] = U(r, 0.04, 0.12); q[1] = U(r, 0.004, 0.02); q[2] = U(r, 0.03, 0.09);
        }
        o->size[0] = 2 * q[0]; o->size[1] = 2 * q[1]; o->size[2] = 2 * q[2];
        tex_w[0] = 0.3; tex_w[1] = 0.1; tex_w[2] = 0.2; tex_w[3] = 0.4;
        break;
    default: /* can: r h */
        o->shape = SOOC_SHAPE_CAN;
        q[0] = U(r, 0.026, 0.042); q[1] = U(r, 0.07, 0.16);
        o->size[0] = o->size[2] = 2 * q[0]; o->size[1] = q[1];
        tex_w[0] = 0.15; tex_w[1] = 0.2; tex_w[2] = 0.05; tex_w[3] = 0.6;
        break;
    }
    o->yaw = U(r, -M_PI, M_PI);
    double hue = sooc_rng_uniform(r);
    if (sooc_rng_uniform(r) < 0.15) tt_hsv(hue, U(r, 0, 0.08), U(r, 0.75, 0.95), o->color);   /* white-ish */
    else tt_hsv(hue, U(r, 0.35, 0.9), U(r, 0.45, 0.95), o->color);
    double u = sooc_rng_uniform(r), acc = 0;
    o->tex = SOOC_TEX_LABEL;
    for (int i = 0; i < 4; i++) {
        acc += tex_w[i];
        if (u < acc) { o->tex = (sooc_obj_tex)i; break; }
    }
    if (o->tex != SOOC_TEX_PLAIN) {
        if (sooc_rng_uniform(r) < 0.3) tt_hsv(0, 0, sooc_rng_uniform(r) < 0.5 ? U(r, 0.85, 0.98) : U(r, 0.08, 0.2), o->color2);
        else tt_hsv(hue + U(r, 0.25, 0.75), U(r, 0.4, 0.9), U(r, 0.4, 0.95), o->color2);
        o->tex_scale = o->tex == SOOC_TEX_STRIPES ? U(r, 0.008, 0.03) : o->tex == SOOC_TEX_CHECKS ? U(r, 0.01, 0.04) : 0.02;
    }
}

/* Camera centre at least TT_CLEAR from every object's bounding cylinder
 * (a sensor's minimum range) and, for bins, above the rim. */
#define TT_CLEAR 0.2
static int tt_cam_ok(const sooc_scene *sc, const double c[3]) {
    if (sc->support == SOOC_SUPPORT_BIN && c[1] < sc->rim_height + 0.05) return 0;
    for (int i = 0; i < sc->n_objects; i++) {
        const sooc_scene_object *o = &sc->objects[i];
        double dh = hypot(c[0] - o->x, c[2] - o->z) - sooc_scene_object_footprint(o);
        double dv = c[1] - o->size[1];
        double d = hypot(dh > 0 ? dh : 0, dv > 0 ? dv : 0);
        if (d < TT_CLEAR) return 0;
    }
    return 1;
}

/* Camera centre for look-at point g, yaw, pitch, distance. */
static void tt_cam_centre(double c[3], const double g[2], double yaw, double pitch, double dist) {
    c[0] = g[0] - dist * sin(yaw) * cos(pitch);
    c[1] = dist * sin(pitch);
    c[2] = g[1] - dist * cos(yaw) * cos(pitch);
}

static double clampd(double v, double lo, double hi) { return v < lo ? lo : v > hi ? hi : v; }

/* A point on the table to look at: an object (70%) or anywhere on the top,
 * kept 5 cm inside the edge. */
static void tt_waypoint(sooc_rng *r, const sooc_scene *sc, double g[2]) {
    double hx = sc->support_size[0] / 2 - 0.05, hz = sc->support_size[1] / 2 - 0.05;
    if (sc->n_objects > 0 && sooc_rng_uniform(r) < 0.7) {
        const sooc_scene_object *o = &sc->objects[sooc_rng_below(r, (uint32_t)sc->n_objects)];
        g[0] = o->x + U(r, -0.05, 0.05);
        g[1] = o->z + U(r, -0.05, 0.05);
    } else {
        g[0] = U(r, -hx, hx);
        g[1] = U(r, -hz, hz);
    }
    g[0] = clampd(g[0], -hx, hx);
    g[1] = clampd(g[1], -hz, hz);
}

/* Pose for (g, yaw, pitch, dist), nudged up and back until the camera is
 * clear: pitch and distance grow towards 70 degrees and 1 m (0.94 m above
 * the support, over every object and rim). */
static void tt_place(const sooc_scene *sc, double T[16], const double g[2], double yaw, double *pitch, double *dist) {
    double c[3];
    for (int k = 0; k < 40; k++) {
        tt_cam_centre(c, g, yaw, *pitch, *dist);
        if (tt_cam_ok(sc, c)) break;
        *pitch = fmin(*pitch + 2 * DEG, TT_PMAX);
        *dist = fmin(*dist + 0.02, TT_DMAX);
    }
    tt_cam_centre(c, g, yaw, *pitch, *dist);
    tt_cam_pose(T, c, yaw, *pitch);
}

sooc_status sooc_gen_tabletop_scene(sooc_scene *sc, const sooc_gen_params *p, int index) {
    sooc_scene_free(sc);
    double wd[2];
    sooc_status st = sooc_gen_tabletop_size(p->scale, wd);
    if (st) return st;
    sooc_rng rng;
    sooc_rng_seed(&rng, p->seed, (uint64_t)index);
    sooc_rng *r = &rng;
    snprintf(sc->preset, sizeof sc->preset, "tabletop");
    snprintf(sc->scale, sizeof sc->scale, "%s", sooc_gen_scale_name(p->scale));
    sc->seed = p->seed;
    sc->index = index;
    sc->clip_depth = p->clip_depth;
    sc->width = p->width;
    sc->height = p->height;
    sc->fov_deg = p->fov_deg;
    /* support: a table (75%) or a bin standing on a bench */
    int bin = sooc_rng_uniform(r) < 0.25;
    sc->support = bin ? SOOC_SUPPORT_BIN : SOOC_SUPPORT_TABLE;
    sc->support_size[0] = wd[0];
    sc->support_size[1] = wd[1];
    if (bin) {
        sc->support_height = U(r, 0.02, 0.05);
        sc->support_thick = U(r, 0.01, 0.02);
        sc->rim_height = U(r, 0.08, 0.2);
        double h = sooc_rng_uniform(r);
        sc->floor_tex = sooc_rng_uniform(r) < 0.5 ? SOOC_FLOOR_UNIFORM : SOOC_FLOOR_NOISE;
        tt_hsv(h, U(r, 0.2, 0.7), U(r, 0.45, 0.8), sc->floor_color);
        tt_hsv(h, U(r, 0.2, 0.7), U(r, 0.35, 0.6), sc->floor_color2);
        sc->tex_scale = U(r, 0.03, 0.08);
        for (int k = 0; k < 3; k++) sc->support_color[k] = sc->floor_color[k] * 0.85f;
        /* the bench the bin stands on */
        tt_hsv(U(r, 0.05, 0.12), U(r, 0.1, 0.4), U(r, 0.35, 0.7), sc->ground_color);
    } else {
        sc->support_height = U(r, 0.7, 0.9);
        sc->support_thick = U(r, 0.025, 0.05);
        sc->rim_height = 0;
        double t = sooc_rng_uniform(r);
        if (t < 0.4) {
            sc->floor_tex = SOOC_FLOOR_WOOD;
            double k = U(r, 0.75, 1.15);
            sc->floor_color[0] = (float)(0.66 * k); sc->floor_color[1] = (float)(0.48 * k); sc->floor_color[2] = (float)(0.30 * k);
            sc->floor_color2[0] = (float)(0.42 * k); sc->floor_color2[1] = (float)(0.27 * k); sc->floor_color2[2] = (float)(0.15 * k);
            sc->tex_scale = U(r, 0.08, 0.16);
        } else if (t < 0.65) {
            sc->floor_tex = SOOC_FLOOR_UNIFORM;
            tt_hsv(sooc_rng_uniform(r), U(r, 0.0, 0.3), U(r, 0.55, 0.92), sc->floor_color);
            memcpy(sc->floor_color2, sc->floor_color, sizeof sc->floor_color);
        } else if (t < 0.85) {
            sc->floor_tex = SOOC_FLOOR_NOISE; /* laminate / stone */
            double h = sooc_rng_uniform(r);
            double val = U(r, 0.6, 0.9);
            tt_hsv(h, U(r, 0.0, 0.2), val, sc->floor_color);
            tt_hsv(h, U(r, 0.0, 0.2), val * U(r, 0.7, 0.85), sc->floor_color2);
            sc->tex_scale = U(r, 0.02, 0.06);
        } else {
            sc->floor_tex = SOOC_FLOOR_CHECKER; /* table cloth */
            double h = sooc_rng_uniform(r);
            tt_hsv(h, U(r, 0.4, 0.8), U(r, 0.5, 0.85), sc->floor_color);
            tt_hsv(0, 0, U(r, 0.85, 0.97), sc->floor_color2);
            sc->tex_scale = U(r, 0.04, 0.1);
        }
        for (int k = 0; k < 3; k++) sc->support_color[k] = sc->floor_color2[k] * 0.8f;
        tt_hsv(U(r, 0.05, 0.15), U(r, 0.05, 0.3), U(r, 0.3, 0.6), sc->ground_color);
    }
    /* the room around it */
    sc->walls = 1;
    sc->room_size = fmax(wd[0], wd[1]) + U(r, 3, 5);
    sc->wall_height = 2.6;
    tt_hsv(sooc_rng_uniform(r), U(r, 0.03, 0.2), U(r, 0.7, 0.92), sc->wall_color);
    tt_hsv(0.6, 0.05, 0.95, sc->sky_color);
    double el = U(r, 45, 80) * DEG, az = U(r, -M_PI, M_PI);
    sc->light_dir[0] = cos(el) * sin(az);
    sc->light_dir[1] = sin(el);
    sc->light_dir[2] = cos(el) * cos(az);
    sc->ambient = U(r, 0.3, 0.45);
    sc->shadows = 1;
    sc->specular = U(r, 0.15, 0.4);
    sc->shininess = U(r, 25, 60);

    /* objects: TT_DENSITY per m^2 of support, 2-12, standing 2 cm apart
     * inside the edge (inside the walls for bins); with odds p->touch an
     * object (after the first) is put against a placed one instead: its
     * footprint circle 0-3 mm from that one's or overlapping it by up to 10%
     * of the smaller radius (boxes then touch or nearly, round shapes barely
     * meet), 2 cm from every other */
    double area = wd[0] * wd[1];
    int target = (int)lround(TT_DENSITY * area * U(r, 0.8, 1.2));
    target = target < TT_MIN_OBJECTS ? TT_MIN_OBJECTS : target > TT_MAX_OBJECTS ? TT_MAX_OBJECTS : target;
    sc->objects = sooc_calloc((size_t)target, sizeof *sc->objects);
    if (!sc->objects) return SOOC_ENOMEM;
    for (int attempt = 0; sc->n_objects < target && attempt < target * 200; attempt++) {
        sooc_scene_object o;
        tt_object(r, &o, p->flat);
        double fp = sooc_scene_object_footprint(&o);
        double hx = wd[0] / 2 - fp - 0.02, hz = wd[1] / 2 - fp - 0.02;
        if (hx <= 0 || hz <= 0) continue;
        int against = -1;
        if (p->touch > 0 && sc->n_objects > 0 && sooc_rng_uniform(r) < p->touch) {
            against = (int)sooc_rng_below(r, (uint32_t)sc->n_objects);
            const sooc_scene_object *q = &sc->objects[against];
            double fq = sooc_scene_object_footprint(q), ang = U(r, -M_PI, M_PI);
            double d = fp + fq + U(r, -0.1 * fmin(fp, fq), 0.003);
            o.x = q->x + d * cos(ang);
            o.z = q->z + d * sin(ang);
            if (fabs(o.x) > hx || fabs(o.z) > hz) continue;
        } else {
            o.x = U(r, -hx, hx);
            o.z = U(r, -hz, hz);
        }
        int ok = 1;
        for (int j = 0; j < sc->n_objects && ok; j++) {
            if (j == against) continue;
            const sooc_scene_object *q = &sc->objects[j];
            double m = fp + sooc_scene_object_footprint(q) + 0.02;
            if (hypot(o.x - q->x, o.z - q->z) < m) ok = 0;
        }
        if (!ok) continue;
        o.id = sc->n_objects + 1;
        sc->objects[sc->n_objects++] = o;
    }
    if (sc->n_objects < TT_MIN_OBJECTS) {
        sooc_scene_free(sc);
        return sooc_seterr(SOOC_ERR, "gen: tabletop scene %d: could not place %d objects", index, TT_MIN_OBJECTS);
    }

    /* cameras: the look-at point moves between way points on the table while
     * the camera circles it (8-16 degrees of yaw per view, one direction per
     * scene); distance and pitch random-walk inside their ranges */
    int V = sooc_gen_views(p);
    int Q = p->n_query >= 0 ? p->n_query : (V / 5 > 2 ? V / 5 : 2);
    sc->n_views = V + Q;
    sc->view_is_query = sooc_calloc((size_t)sc->n_views, 1);
    sc->view_T_wc = sooc_calloc((size_t)sc->n_views * 16, sizeof(double));
    double *vs = sooc_calloc((size_t)V * 5, sizeof(double)); /* g x, g z, yaw, pitch, dist */
    if (!sc->view_is_query || !sc->view_T_wc || !vs) {
        sooc_free(vs);
        sooc_scene_free(sc);
        return SOOC_ENOMEM;
    }
    double g[2], wp[2];
    tt_waypoint(r, sc, g);
    tt_waypoint(r, sc, wp);
    double yaw = U(r, -M_PI, M_PI), dir = sooc_rng_uniform(r) < 0.5 ? -1 : 1;
    double pitch = U(r, 30, 65) * DEG, dist = U(r, 0.45, 0.9);
    for (int v = 0; v < V; v++) {
        double pv = pitch, dv = dist;
        tt_place(sc, sc->view_T_wc + 16 * v, g, yaw, &pv, &dv);
        double *rec = vs + 5 * v;
        rec[0] = g[0]; rec[1] = g[1]; rec[2] = yaw; rec[3] = pv; rec[4] = dv;
        /* next view */
        yaw += dir * U(r, 8, 16) * DEG + sooc_rng_normal(r) * 3 * DEG;
        pitch = clampd(pitch + sooc_rng_normal(r) * 5 * DEG, TT_PMIN, TT_PMAX);
        dist = clampd(dist + sooc_rng_normal(r) * 0.07, TT_DMIN, TT_DMAX);
        double dx = wp[0] - g[0], dz = wp[1] - g[1], len = hypot(dx, dz), step = U(r, 0.05, 0.12);
        if (len <= step) {
            g[0] = wp[0]; g[1] = wp[1];
            tt_waypoint(r, sc, wp);
        } else {
            g[0] += dx / len * step;
            g[1] += dz / len * step;
        }
    }
    /* query views: near a random input view (look-at point within 10 cm,
     * yaw within 30 degrees, distance within 15 cm, pitch within 10 degrees) */
    for (int q = 0; q < Q; q++) {
        const double *b = vs + 5 * sooc_rng_below(r, (uint32_t)V);
        double hx = wd[0] / 2 - 0.05, hz = wd[1] / 2 - 0.05;
        double rad = 0.1 * sqrt(sooc_rng_uniform(r)), ang = U(r, -M_PI, M_PI);
        double gq[2] = {clampd(b[0] + rad * cos(ang), -hx, hx), clampd(b[1] + rad * sin(ang), -hz, hz)};
        double yq = b[2] + U(r, -30, 30) * DEG;
        double pq = clampd(b[3] + U(r, -10, 10) * DEG, TT_PMIN, TT_PMAX);
        double dq = clampd(b[4] + U(r, -0.15, 0.15), TT_DMIN, TT_DMAX);
        tt_place(sc, sc->view_T_wc + 16 * (V + q), gq, yq, &pq, &dq);
        sc->view_is_query[V + q] = 1;
    }
    sooc_free(vs);
    return SOOC_OK;
}
