/* Support-plane clustering (mapper.h): boxes on a plane, ray-cast from known
 * cameras. Two boxes with a gap wider than the join distance are two objects
 * with their boxes; closer than it, one. A slab wider than max_extent_m is
 * the surround; so is a wall (a vertical plane running on for wall_m), and
 * a box against it is an object of its own. A held-out view rendered from the map reproduces the
 * ray-cast labels. The mapper's proposals (propose.c) put prior slots on
 * the clusters and leave covered ones alone. Bad input is refused. */
#include "check.h"
#include "model/propose.h"
#include "sooc3d/mapper.h"
#include "sooc3d/core.h"

#include <math.h>
#include <string.h>

typedef struct box { double lo[3], hi[3]; } box;

#define W 128
#define H 96

/* camera at c looking at t: T_wc with OpenCV axes (x right, y down, z forward) */
static void look_at(double T[16], const double c[3], const double t[3]) {
    double z[3] = {t[0] - c[0], t[1] - c[1], t[2] - c[2]}, up[3] = {0, 1, 0}, x[3], y[3];
    double n = sqrt(z[0] * z[0] + z[1] * z[1] + z[2] * z[2]);
    for (int i = 0; i < 3; i++) z[i] /= n;
    x[0] = z[1] * up[2] - z[2] * up[1], x[1] = z[2] * up[0] - z[0] * up[2], x[2] = z[0] * up[1] - z[1] * up[0];
    n = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    for (int i = 0; i < 3; i++) x[i] /= n;
    y[0] = z[1] * x[2] - z[2] * x[1], y[1] = z[2] * x[0] - z[0] * x[2], y[2] = z[0] * x[1] - z[1] * x[0];
    memset(T, 0, 16 * sizeof *T);
    for (int r = 0; r < 3; r++) T[4 * r] = x[r], T[4 * r + 1] = y[r], T[4 * r + 2] = z[r], T[4 * r + 3] = c[r];
    T[15] = 1;
}

/* ray-box slab test: entry distance or INFINITY */
static double hit_box(const box *b, const double o[3], const double d[3]) {
    double t0 = 0, t1 = INFINITY;
    for (int a = 0; a < 3; a++) {
        if (fabs(d[a]) < 1e-12) {
            if (o[a] < b->lo[a] || o[a] > b->hi[a]) return INFINITY;
            continue;
        }
        double ta = (b->lo[a] - o[a]) / d[a], tb = (b->hi[a] - o[a]) / d[a];
        if (ta > tb) { double s = ta; ta = tb; tb = s; }
        if (ta > t0) t0 = ta;
        if (tb < t1) t1 = tb;
    }
    return t0 <= t1 ? t0 : INFINITY;
}

/* Ray-cast the plane y = 0 and the boxes into f (labels: 0 plane, i + 1 box i). */
static void cast(sooc_frame *f, const double c[3], const double t[3], const box *bx, int nb) {
    look_at(f->T_wc, c, t);
    f->has_pose = 1;
    f->K.width = W, f->K.height = H;
    f->K.fx = f->K.fy = 100, f->K.cx = W / 2.0, f->K.cy = H / 2.0;
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            double dc[3] = {(u + 0.5 - f->K.cx) / f->K.fx, (v + 0.5 - f->K.cy) / f->K.fy, 1}, d[3];
            sooc_se3_rotate(d, f->T_wc, dc);   /* t along d = planar depth */
            double best = d[1] < 0 ? -c[1] / d[1] : INFINITY;
            int lab = 0;
            for (int i = 0; i < nb; i++) {
                double th = hit_box(&bx[i], c, d);
                if (th < best) best = th, lab = i + 1;
            }
            size_t k = (size_t)v * W + u;
            int ok = isfinite(best) && best < 5;
            f->depth[k] = ok ? (float)best : 0;
            f->valid[k] = (uint8_t)ok;
            f->instance[k] = (uint16_t)(ok ? lab : 0);
            f->rgb[3 * k] = (uint8_t)(lab * 60), f->rgb[3 * k + 1] = 100, f->rgb[3 * k + 2] = 50;
        }
}

static const double g_cams[4][3] = {{0.0, 0.55, -0.55}, {0.45, 0.5, -0.35}, {-0.45, 0.5, -0.35}, {0.1, 0.6, -0.45}};

/* Two 8 x 10 x 6 cm boxes side by side along x with a gap, 3 mapped views. */
static void two_boxes(double gap, box b[2]) {
    double w = 0.08;
    b[0] = (box){{-gap / 2 - w, 0, -0.03}, {-gap / 2, 0.10, 0.03}};
    b[1] = (box){{gap / 2, 0, -0.03}, {gap / 2 + w, 0.10, 0.03}};
}

static int map_scene(sooc_cluster_map *m, sooc_frame *f, const box *b, int nb) {
    const double t[3] = {0, 0.04, 0};
    sooc_cluster_map_clear(m);
    for (int i = 0; i < 3; i++) {
        cast(f, g_cams[i], t, b, nb);
        if (sooc_cluster_map_add_frame(m, f)) return -1;
    }
    int n = -1;
    if (sooc_cluster_map_segment(m, &n)) return -1;
    return n;
}

/* Two boxes 3.5 cm apart; the first view also sees a bridge between them (the
 * mixed pixels of a depth edge, a reflection: in one frame only), the views
 * after it see the plane through where it was. */
static int map_bridged(sooc_cluster_map *m, sooc_frame *f) {
    box b[3];
    two_boxes(0.035, b);
    b[2] = (box){{-0.02, 0.03, -0.01}, {0.02, 0.05, 0.01}};
    const double t[3] = {0, 0.04, 0};
    sooc_cluster_map_clear(m);
    for (int i = 0; i < 4; i++) {
        cast(f, g_cams[i ? i - 1 : 0], t, b, i ? 2 : 3);
        if (sooc_cluster_map_add_frame(m, f)) return -1;
    }
    int n = -1;
    if (sooc_cluster_map_segment(m, &n)) return -1;
    return n;
}

/* As map_scene, with only every `row`-th image row's depth kept: the depth of a far or steep face comes
 * in bands a few cm apart, each its own component. */
static int map_rows(sooc_cluster_map *m, sooc_frame *f, const box *b, int nb, int row) {
    const double t[3] = {0, 0.04, 0};
    sooc_cluster_map_clear(m);
    for (int i = 0; i < 3; i++) {
        cast(f, g_cams[i], t, b, nb);
        for (int v = 0; v < H; v++)
            if (v % row)
                for (int u = 0; u < W; u++) f->valid[(size_t)v * W + u] = 0, f->depth[(size_t)v * W + u] = 0;
        if (sooc_cluster_map_add_frame(m, f)) return -1;
    }
    int n = -1;
    if (sooc_cluster_map_segment(m, &n)) return -1;
    return n;
}

/* map_scene (row 1) or map_rows on a map of its own with parameters np: the object count, -1 on failure */
static int map_with(const sooc_cluster_params *np, sooc_frame *f, const box *b, int nb, int row) {
    sooc_cluster_map *m = NULL;
    if (sooc_cluster_map_create(&m, np) != SOOC_OK) return -1;
    int n = row > 1 ? map_rows(m, f, b, nb, row) : map_scene(m, f, b, nb);
    sooc_cluster_map_destroy(m);
    return n;
}

int main(void) {
    sooc_frame f, q;
    CHECK(sooc_frame_alloc(&f, W, H, 1) == SOOC_OK);
    CHECK(sooc_frame_alloc(&q, W, H, 1) == SOOC_OK);
    sooc_cluster_params p;
    sooc_cluster_params_default(&p);
    sooc_cluster_map *m = NULL;
    CHECK(sooc_cluster_map_create(&m, &p) == SOOC_OK);
    box b[3];

    /* a gap wider than the join distance: two objects with their boxes */
    two_boxes(0.035, b);
    int n = map_scene(m, &f, b, 2);
    CHECK_MSG(n == 2, "gap 3.5 cm: %d objects (want 2)", n);
    sooc_cluster_object o[4];
    int no = 0;
    CHECK(sooc_cluster_map_objects(m, o, 4, &no) == SOOC_OK && no == n);
    for (int i = 0; i < no && n == 2; i++) {
        const box *t = &b[o[i].x < 0 ? 0 : 1];
        double cx = 0.5 * (t->lo[0] + t->hi[0]), cz = 0.5 * (t->lo[2] + t->hi[2]);
        /* the box's heading is axis-aligned up to its symmetry (pi / 2) */
        double yaw = fmod(fabs(o[i].yaw), M_PI / 2);
        int swap = fabs(fmod(fabs(o[i].yaw), M_PI) - M_PI / 2) < M_PI / 4;
        double ex = swap ? o[i].extent[2] : o[i].extent[0], ez = swap ? o[i].extent[0] : o[i].extent[2];
        printf("object %d: (%.3f, %.3f) yaw %.3f extent %.3f x %.3f x %.3f, %d voxels\n", i, o[i].x, o[i].z,
               o[i].yaw, ex, o[i].extent[1], ez, o[i].n_voxels);
        CHECK_MSG(fabs(o[i].x - cx) < 0.01 && fabs(o[i].z - cz) < 0.01, "centre (%.3f, %.3f) vs (%.3f, %.3f)",
                  o[i].x, o[i].z, cx, cz);
        CHECK_MSG(yaw < 0.05 || yaw > M_PI / 2 - 0.05, "yaw %.3f not axis-aligned", o[i].yaw);
        /* the boxes' back faces are hidden from every camera: the seen extent is at most the true one */
        CHECK_MSG(fabs(ex - 0.08) < 0.012 && ez > 0.03 && ez < 0.07 && fabs(o[i].extent[1] - 0.10) < 0.01,
                  "extent %.3f x %.3f x %.3f vs 0.08 x 0.10 x 0.06", ex, o[i].extent[1], ez);
    }

    /* a held-out view rendered from the map: per-object IoU with the ray-cast labels */
    {
        const double c[3] = {-0.2, 0.45, -0.5}, t[3] = {0, 0.04, 0};
        cast(&q, c, t, b, 2);
        int16_t lab[W * H];
        float dep[W * H];
        CHECK(sooc_cluster_map_render(m, q.T_wc, &q.K, W, H, lab, dep, NULL) == SOOC_OK);
        for (int i = 0; i < no && n == 2; i++) {
            int gt_id = o[i].x < 0 ? 1 : 2, inter = 0, uni = 0;
            double derr = 0;
            int nd = 0;
            for (int k = 0; k < W * H; k++) {
                int a = lab[k] == o[i].label, g = q.instance[k] == gt_id && q.valid[k];
                inter += a && g, uni += a || g;
                if (g && a) derr += fabs(dep[k] - q.depth[k]), nd++;
            }
            double iou = uni ? (double)inter / uni : 0;
            printf("held-out view: object %d IoU %.3f, mean depth error %.4f m\n", i, iou, nd ? derr / nd : NAN);
            CHECK_MSG(iou > 0.8, "held-out IoU %.3f", iou);
            CHECK(nd && derr / nd < 0.01);
        }
        /* negative control: the labels of the other object do not match */
        int inter = 0, uni = 0;
        for (int k = 0; k < W * H && n == 2; k++) {
            int a = lab[k] == o[0].label, g = q.instance[k] == (o[0].x < 0 ? 2 : 1);
            inter += a && g, uni += a || g;
        }
        CHECK(uni && (double)inter / uni < 0.05);
    }

    /* the mapper's proposals: prior slots move onto the clusters; a covered one stays */
    {
        sooc_model_config c;
        memset(&c, 0, sizeof c);
        c.K = 4, c.d_what = 2, c.unit_m = 0.5;
        int NL = SOOC_LAM_SIZE(c.d_what);
        sooc_view_rec V;
        memset(&V, 0, sizeof V);
        float lam[4 * SOOC_LAM_SIZE(2)];
        memset(lam, 0, sizeof lam);
        V.lam0 = lam;
        V.n_ret = 1, V.nslot = 4;
        V.gf.X = 0.1, V.gf.Z = -0.2, V.gf.psi = 0.3;   /* a G frame off the world's */
        for (int k = 0; k < 4; k++) lam[k * NL + SOOC_LAM_X] = (float)k, lam[k * NL + SOOC_LAM_Z] = 3;
        sooc_cluster_map *pm = NULL;
        CHECK(sooc_cluster_map_create(&pm, &p) == SOOC_OK);
        cast(&f, g_cams[0], (double[3]){0, 0.04, 0}, b, 2);
        sooc_mdl_prop_params pp = {0.02, 0.5, 1.5, NAN};
        sooc_status st;
        int placed = sooc_mdl_propose(pm, &c, NL, &f, &V, &pp, &st);
        CHECK_MSG(st == SOOC_OK && placed == 2, "placed %d (want 2)", placed);
        int found[2] = {0, 0};
        for (int k = 1; k < 4; k++) {
            double l[3] = {lam[k * NL + SOOC_LAM_X] * c.unit_m, lam[k * NL + SOOC_LAM_Z] * c.unit_m, 0}, w[3];
            sooc_floor_to_world(&V.gf, l, w);
            for (int j = 0; j < 2; j++) {
                double cx = 0.5 * (b[j].lo[0] + b[j].hi[0]);
                if (fabs(w[0] - cx) < 0.015 && fabs(w[1]) < 0.02) {
                    found[j]++;
                    CHECK(fabs(lam[k * NL + SOOC_LAM_PRES(c.d_what)] - 1.5f) < 1e-6);
                }
            }
        }
        CHECK_MSG(found[0] == 1 && found[1] == 1, "proposed slots at the boxes: %d, %d", found[0], found[1]);
        /* the retrieved slot (slot 0) now sits on box 0: that cluster is covered */
        double wb[3] = {0.5 * (b[0].lo[0] + b[0].hi[0]), 0, 0}, lb[3];
        sooc_floor_to_local(&V.gf, wb, lb);
        for (int k = 0; k < 4; k++) lam[k * NL + SOOC_LAM_X] = (float)k + 5, lam[k * NL + SOOC_LAM_Z] = 3;
        lam[SOOC_LAM_X] = (float)(lb[0] / c.unit_m), lam[SOOC_LAM_Z] = (float)(lb[1] / c.unit_m);
        placed = sooc_mdl_propose(pm, &c, NL, &f, &V, &pp, &st);
        CHECK_MSG(st == SOOC_OK && placed == 1, "with box 0 retrieved: placed %d (want 1)", placed);
        sooc_cluster_map_destroy(pm);
    }

    /* closer than the join distance: one object */
    two_boxes(0.01, b);
    n = map_scene(m, &f, b, 2);
    CHECK_MSG(n == 1, "gap 1 cm: %d objects (want 1)", n);

    /* the joined pair labelled anew by side (as the entries' densities split it, src/eval/surface.c):
     * a held-out view shows the two boxes apart, and a new segmentation drops the labels */
    if (n == 1) {
        size_t nv = 0, nv2 = 0;
        CHECK(sooc_cluster_map_object_points(m, NULL, NULL, 0, &nv) == SOOC_OK);
        CHECK(sooc_cluster_map_objects(m, o, 4, &no) == SOOC_OK && no == 1);
        CHECK_MSG(nv == (size_t)o[0].n_voxels, "%zu object points, the object has %d voxels", nv, o[0].n_voxels);
        float *xyz = malloc(nv * 3 * sizeof *xyz);
        int32_t *seg = malloc(nv * sizeof *seg), *rl = malloc(nv * sizeof *rl);
        CHECK(xyz && seg && rl);
        CHECK(sooc_cluster_map_object_points(m, xyz, seg, nv, &nv2) == SOOC_OK && nv2 == nv);
        int n_left = 0;
        for (size_t i = 0; i < nv; i++) {
            CHECK(seg[i] == 0);
            rl[i] = xyz[3 * i] < 0 ? 3 : 7;   /* box 0 lies at x < 0 */
            rl[i] = xyz[3 * i + 1] > 0.095 && xyz[3 * i] > 0.07 ? -1 : rl[i];   /* a corner of box 1's top: background */
            n_left += xyz[3 * i] < 0;
        }
        CHECK(n_left > 0 && (size_t)n_left < nv);
        CHECK(sooc_cluster_map_relabel(m, rl, nv - 1) == SOOC_EINVAL);   /* one label short */
        CHECK(sooc_cluster_map_relabel(m, rl, nv) == SOOC_OK);
        /* the same voxels, with their segmentation labels, after relabelling */
        CHECK(sooc_cluster_map_object_points(m, xyz, seg, nv, &nv2) == SOOC_OK && nv2 == nv);
        int seg_ok = 1;
        for (size_t i = 0; i < nv; i++) seg_ok &= seg[i] == 0;
        CHECK(seg_ok);
        const double c[3] = {-0.2, 0.45, -0.5}, t[3] = {0, 0.04, 0};
        cast(&q, c, t, b, 2);
        int16_t lab[W * H];
        CHECK(sooc_cluster_map_render(m, q.T_wc, &q.K, W, H, lab, NULL, NULL) == SOOC_OK);
        for (int side = 0; side < 2; side++) {
            int want = side ? 7 : 3, inter = 0, uni = 0;
            for (int k = 0; k < W * H; k++) {
                int a = lab[k] == want, g = q.instance[k] == side + 1 && q.valid[k];
                inter += a && g, uni += a || g;
            }
            double iou = uni ? (double)inter / uni : 0;
            printf("joined pair labelled by side: box %d IoU %.3f in a held-out view\n", side, iou);
            CHECK_MSG(iou > 0.75, "box %d IoU %.3f", side, iou);
        }
        sooc_cluster_map_segment(m, &n);
        CHECK(sooc_cluster_map_render(m, q.T_wc, &q.K, W, H, lab, NULL, NULL) == SOOC_OK);
        int n3 = 0;
        for (int k = 0; k < W * H; k++) n3 += lab[k] == 3 || lab[k] == 7;
        CHECK_MSG(n == 1 && n3 == 0, "after a new segmentation: %d objects, %d pixels keep the new labels", n, n3);
        free(xyz), free(seg), free(rl);
    }

    /* a slab wider than max_extent_m is the surround, the box on its own is kept */
    b[0] = (box){{-0.5, 0, 0.15}, {0.5, 0.3, 0.2}};
    b[1] = (box){{-0.04, 0, -0.1}, {0.04, 0.08, -0.04}};
    n = map_scene(m, &f, b, 2);
    CHECK_MSG(n == 1, "slab + box: %d objects (want 1)", n);
    if (n == 1 && sooc_cluster_map_objects(m, o, 4, &no) == SOOC_OK)
        CHECK_MSG(fabs(o[0].z + 0.07) < 0.01, "kept object at z %.3f (the box is at -0.07)", o[0].z);

    /* a box against a wall (a bin's side, 0.5 m long, 0.25 m tall): the wall is taken out and the box is
     * an object of its own; with the wall test off (wall_m 0) the box goes with the wall into the surround */
    box wb[3];
    wb[0] = (box){{-0.25, 0, 0.05}, {0.25, 0.25, 0.07}};
    wb[1] = (box){{-0.04, 0, -0.03}, {0.04, 0.10, 0.05}};
    n = map_scene(m, &f, wb, 2);
    CHECK_MSG(n == 1, "box against a wall: %d objects (want 1)", n);
    if (n == 1 && sooc_cluster_map_objects(m, o, 4, &no) == SOOC_OK) {
        printf("box against a wall: (%.3f, %.3f) extent %.3f x %.3f x %.3f\n", o[0].x, o[0].z, o[0].extent[0],
               o[0].extent[1], o[0].extent[2]);
        CHECK_MSG(fabs(o[0].x) < 0.01 && o[0].z > -0.04 && o[0].z < 0.03 && fabs(o[0].extent[1] - 0.10) < 0.01,
                  "box at (%.3f, %.3f), height %.3f", o[0].x, o[0].z, o[0].extent[1]);
    }
    {
        sooc_cluster_params np = p;
        np.wall_m = 0;
        int nn = map_with(&np, &f, wb, 2, 1);
        CHECK_MSG(nn == 0, "wall test off: %d objects (want 0: box and wall are one surround)", nn);
        /* a row of boxes whose fronts line up, with 6 cm between them: three objects, not a wall */
        for (int i = 0; i < 3; i++) wb[i] = (box){{-0.15 + 0.12 * i, 0, -0.03}, {-0.09 + 0.12 * i, 0.12, 0.03}};
        n = map_scene(m, &f, wb, 3);
        CHECK_MSG(n == 3, "a row of three boxes: %d objects (want 3)", n);
    }

    /* a sliver (a strip of a bin's side between gaps in the depth: 6 cm wide, 25 cm tall, 8 mm thick) is
     * not an object; a book on its edge (15 x 20 x 3 cm) beside it is */
    {
        box sb[2];
        sb[0] = (box){{-0.20, 0, 0.00}, {-0.14, 0.25, 0.008}};
        sb[1] = (box){{0.00, 0, -0.015}, {0.15, 0.20, 0.015}};
        n = map_scene(m, &f, sb, 2);
        int book = 0;
        if (n == 1 && sooc_cluster_map_objects(m, o, 4, &no) == SOOC_OK) book = o[0].x > 0.03 && o[0].x < 0.12;
        CHECK_MSG(n == 1 && book, "sliver and book: %d objects (want 1, the book)", n);
        printf("a sliver beside a book on its edge: %d object(s), the book\n", n);
    }

    /* floating: a shelf's lip (20 x 3 x 4 cm, 20 cm above the plane, behind) is not an object; a box on the
     * plane and a box stacked on it are one, the lip's lowest voxel is above rest_m; with rest_m 0 it is kept */
    {
        box fb[3];
        fb[0] = (box){{-0.04, 0, -0.03}, {0.04, 0.08, 0.03}};
        fb[1] = (box){{-0.02, 0.08, -0.02}, {0.02, 0.12, 0.02}};
        fb[2] = (box){{-0.10, 0.20, 0.10}, {0.10, 0.23, 0.14}};
        n = map_scene(m, &f, fb, 3);
        int stack = 0;
        if (n == 1 && sooc_cluster_map_objects(m, o, 4, &no) == SOOC_OK)
            stack = fabs(o[0].extent[1] - 0.12) < 0.01 && fabs(o[0].z) < 0.02;
        CHECK_MSG(n == 1 && stack, "a stack and a floating lip: %d objects (want 1, the stack 12 cm tall)", n);
        sooc_cluster_params np = p;
        np.rest_m = 0;
        int nn = map_with(&np, &f, fb, 3, 1);
        CHECK_MSG(nn == 2, "rest test off: %d objects (want 2: the stack and the lip)", nn);
        printf("a stack of two boxes and a floating lip: %d object(s), the stack; with rest_m 0: %d\n", n, nn);
    }

    /* a tall box whose depth comes in bands (every 8th row of three views): its upper bands rest on the lower ones down to
     * the plane and all stay, as with rest_m 0; a lip 10 cm above the box's top and behind it goes */
    {
        box tb[2];
        tb[0] = (box){{-0.04, 0, -0.03}, {0.04, 0.25, 0.03}};
        tb[1] = (box){{-0.10, 0.35, 0.10}, {0.10, 0.38, 0.14}};
        sooc_cluster_params np = p;
        np.rest_m = 0;
        int n0 = map_with(&np, &f, tb, 1, 8), n1 = map_rows(m, &f, tb, 1, 8);
        CHECK_MSG(n0 >= 2 && n1 == n0, "a box in bands: %d objects, %d with rest_m 0 (want the same, 2 or more)", n1,
                  n0);
        int l0 = map_with(&np, &f, tb, 2, 8), l1 = map_rows(m, &f, tb, 2, 8);
        CHECK_MSG(l0 == n0 + 1 && l1 == n1, "a box in bands and a lip: %d objects, %d with rest_m 0 (want %d, %d)", l1,
                  l0, n1, n0 + 1);
        printf("a box whose depth comes in bands: %d components, all kept; with a lip above: %d (%d with rest_m 0)\n",
               n1, l1, l0);
    }

    /* free space: a bridge that one view showed and the later ones see through does not join the boxes;
     * with the test off (free_ratio 0) it does */
    n = map_bridged(m, &f);
    CHECK_MSG(n == 2, "bridge seen in one view, seen through in three: %d objects (want 2)", n);
    {
        sooc_cluster_params np = p;
        np.free_ratio = 0;
        sooc_cluster_map *nf = NULL;
        CHECK(sooc_cluster_map_create(&nf, &np) == SOOC_OK);
        int nn = nf ? map_bridged(nf, &f) : -1;
        CHECK_MSG(nn == 1, "free-space test off: %d objects (want 1: the bridge joins the boxes)", nn);
        sooc_cluster_map_destroy(nf);
    }
    printf("a bridge seen in one view: %d objects; with the free-space test off: joined\n", n);

    /* bad input */
    sooc_cluster_map *bad = NULL;
    sooc_cluster_params bp = p;
    bp.dist_m = p.voxel_m / 2;
    CHECK(sooc_cluster_map_create(&bad, &bp) == SOOC_EINVAL && !bad);
    bp = p, bp.min_voxels = 0;
    CHECK(sooc_cluster_map_create(&bad, &bp) == SOOC_EINVAL);
    bp = p, bp.free_ratio = -1;
    CHECK(sooc_cluster_map_create(&bad, &bp) == SOOC_EINVAL);
    bp = p, bp.rest_m = -0.1;
    CHECK(sooc_cluster_map_create(&bad, &bp) == SOOC_EINVAL);
    f.has_pose = 0;
    CHECK(sooc_cluster_map_add_frame(m, &f) == SOOC_EINVAL);
    f.has_pose = 1;
    sooc_cluster_map *fresh = NULL;
    CHECK(sooc_cluster_map_create(&fresh, NULL) == SOOC_OK);
    int16_t l1[W * H];
    CHECK(sooc_cluster_map_render(fresh, f.T_wc, &f.K, W, H, l1, NULL, NULL) == SOOC_EINVAL);   /* before segment */
    CHECK(sooc_cluster_map_segment(fresh, &n) == SOOC_OK && n == 0);   /* empty map: no objects */
    sooc_cluster_map_destroy(fresh);

    sooc_cluster_map_destroy(m);
    sooc_frame_free(&f);
    sooc_frame_free(&q);
    printf("test_cluster: %d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail != 0;
}
