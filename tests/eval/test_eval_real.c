/* Metrics for real sequences (eval.h) on hand-made frames: the query
 * rule, the free-space / surface / never-seen test, yaw and position spread,
 * churn, per-object IoU, label images (8- and 16-bit, nearest resample), and
 * the runner on a tiny model (query frames never mapped, counts consistent,
 * the JSON contract keys). */
#include "../data/util.h"
#include "sooc3d/eval.h"
#include "sooc3d/core.h"
#include "sooc3d/render.h"

#include <math.h>
#include <string.h>

/* ----------------------------------------------------------- query rule */
static void test_query_rule(void) {
    int q[15], nq = 0;
    for (int i = 0; i < 15; i++)
        if (sooc_eval_real_is_query(i, 5)) q[nq++] = i;
    CHECK(nq == 3 && q[0] == 2 && q[1] == 7 && q[2] == 12);
    nq = 0;
    for (int i = 0; i < 300; i++) nq += sooc_eval_real_is_query(i, SOOC_REAL_QUERY_EVERY);
    CHECK(nq == 60);
    CHECK(!sooc_eval_real_is_query(0, 5));                   /* the first frame is always mapped */
    CHECK(sooc_eval_real_is_query(1, 2) && !sooc_eval_real_is_query(0, 2));
    for (int i = 0; i < 10; i++) CHECK(!sooc_eval_real_is_query(i, 1) && !sooc_eval_real_is_query(i, 0));
}

/* ------------------------------------------------------ hand-made frames */

/* A w x h camera at world position c looking along +z (pitch down by
 * `pitch` rad), OpenCV axes, f = w, centre (w/2, h/2), depth d everywhere. */
static void make_frame_ids(sooc_frame *f, int w, int h, const double c[3], double pitch, float d, int ids) {
    CHECK_OK(sooc_frame_alloc(f, w, h, ids));
    double s = sin(pitch), co = cos(pitch);
    double R[9] = {-1, 0, 0, 0, -co, -s, 0, -s, co};   /* columns x_c, y_c, z_c in world */
    sooc_se3_from_rt(f->T_wc, R, c);
    f->has_pose = 1;
    f->K.width = w, f->K.height = h;
    f->K.fx = f->K.fy = w;
    f->K.cx = w / 2.0, f->K.cy = h / 2.0;
    for (int i = 0; i < w * h; i++) {
        f->depth[i] = d;
        f->valid[i] = d > 0;
    }
}

/* sooc_eval_box_fit: a camera 1 m above the plane looking straight down, an
 * 8 x 8 pixel block labelled 5 at 0.9 m (0.1 m above the plane, about 0.2 m
 * wide); the box that holds most of its points is the object's entry. */
static void test_box_fit(void) {
    sooc_frame f;
    const double c[3] = {0, 1, 0};
    make_frame_ids(&f, 32, 32, c, M_PI / 2, 1.0f, 1);
    if (!f.instance) return;
    memset(f.instance, 0, 32 * 32 * sizeof *f.instance);
    for (int v = 12; v < 20; v++)
        for (int u = 12; u < 20; u++) f.instance[v * 32 + u] = 5, f.depth[v * 32 + u] = 0.9f;
    sooc_map_entry e[3];
    memset(e, 0, sizeof e);
    for (int k = 0; k < 3; k++) e[k].id = (uint64_t)k + 1, e[k].geom.flags = SOOC_GEOM_TIGHT;
    e[0].extent[0] = e[0].extent[2] = 0.3f, e[0].extent[1] = 0.15f, e[0].geom.centre[1] = 0.075f;   /* over it */
    e[1].x = e[1].z = 1.0, e[1].extent[0] = e[1].extent[1] = e[1].extent[2] = 0.5f;                  /* elsewhere */
    e[1].geom.centre[1] = 0.25f;
    e[2].x = 0.1, e[2].extent[0] = e[2].extent[2] = 0.2f, e[2].extent[1] = 0.12f;                    /* half of it */
    e[2].geom.centre[1] = 0.06f;
    const uint8_t use = 1;
    sooc_box_fit b;
    CHECK_OK(sooc_eval_box_fit(e, 3, &f, 1, &use, 5, &b));
    double w = 0.9 * 8 / 32 * 0.9;   /* the central 90% of the points' width: 8 pixels of 0.9/32 m, 5th-95th */
    printf("box fit: entry %llu, %d points, cover %.3f, height error %.3f m, area ratio %.2f (want %.2f)\n",
           (unsigned long long)b.entry, b.n_points, b.cover, b.height_err_m, b.area_ratio, 0.09 / (w * w));
    CHECK(b.entry == 1 && b.n_points == 64 && b.cover == 1.0);
    CHECK_MSG(fabs(b.height_err_m - 0.05) < 1e-3, "height error %.4f (box 0.15, object 0.10)", b.height_err_m);
    CHECK_MSG(fabs(b.area_ratio - 0.09 / (w * w)) < 0.25 * 0.09 / (w * w), "area ratio %.2f", b.area_ratio);
    CHECK_OK(sooc_eval_box_fit(e + 1, 2, &f, 1, &use, 5, &b));   /* without the box over it */
    printf("box fit without it: entry %llu, cover %.3f, height error %.3f m\n", (unsigned long long)b.entry, b.cover,
           b.height_err_m);
    fflush(stdout);
    CHECK(b.entry == 3 && b.cover > 0.35 && b.cover < 0.65 && fabs(b.height_err_m - 0.02) < 1e-3);
    CHECK_OK(sooc_eval_box_fit(e + 1, 1, &f, 1, &use, 5, &b));   /* only the one elsewhere */
    CHECK(b.entry == 0 && b.cover == 0);
    CHECK_OK(sooc_eval_box_fit(e, 3, &f, 1, &use, 7, &b));       /* an id with no points */
    CHECK(b.entry == 0 && b.n_points == 0 && isnan(b.cover));
    const uint8_t skip = 0;
    CHECK_OK(sooc_eval_box_fit(e, 3, &f, 1, &skip, 5, &b));      /* the frame not used */
    CHECK(b.n_points == 0 && isnan(b.cover));
    CHECK(sooc_eval_box_fit(e, 3, NULL, 1, &use, 5, &b) == SOOC_EINVAL);
    sooc_frame_free(&f);
}

static void make_frame(sooc_frame *f, int w, int h, const double c[3], double pitch, float d) {
    make_frame_ids(f, w, h, c, pitch, d, 0);
}

static void test_point_seen(void) {
    sooc_frame f[3];
    memset(f, 0, sizeof f);
    const double c0[3] = {0, 0, 0};
    make_frame(&f[0], 16, 16, c0, 0, 2.0f);
    sooc_seen_votes v;
    double p_free[3] = {0, 0, 1}, p_surf[3] = {0, 0, 2.1}, p_behind[3] = {0, 0, 3}, p_back[3] = {0, 0, -1};
    double p_side[3] = {5, 0, 1};
    CHECK_OK(sooc_eval_point_seen(p_free, f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_FREE && v.n_free == 1 && v.n_surface == 0 && v.n_in_view == 1);
    CHECK_OK(sooc_eval_point_seen(p_surf, f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_SURFACE && v.n_surface == 1);
    CHECK_OK(sooc_eval_point_seen(p_behind, f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_NEVER && v.n_behind == 1 && v.n_in_view == 1);   /* occluded: never looked */
    CHECK_CLOSE(v.min_behind, 1.0, 1e-6, 0);                                  /* 1 m behind the wall */
    CHECK_OK(sooc_eval_point_seen(p_back, f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_NEVER && v.n_in_view == 0 && isnan(v.min_behind));
    CHECK_OK(sooc_eval_point_seen(p_side, f, 1, 0.25, &v));                   /* outside the image */
    CHECK(v.cls == SOOC_SEEN_NEVER && v.n_in_view == 0);
    /* invalid depth where the point projects: no evidence */
    int u = 8, vv = 8;   /* (0, 0, 1) projects to the centre pixel */
    f[0].valid[vv * 16 + u] = 0;
    CHECK_OK(sooc_eval_point_seen(p_free, f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_NEVER && v.n_in_view == 1 && v.n_free == 0);
    f[0].valid[vv * 16 + u] = 1;
    /* a second camera 1 m behind, wall at 3.1 m: (0, 0, 2.1) is on its surface too;
     * a third one 1 m to the left looking along +z with a wall at 1.5 m: the
     * point lies behind it (x = 0 projects inside its image) */
    const double c1[3] = {0, 0, -1}, c2[3] = {0.2, 0, 0};
    make_frame(&f[1], 16, 16, c1, 0, 3.1f);
    make_frame(&f[2], 16, 16, c2, 0, 1.5f);
    CHECK_OK(sooc_eval_point_seen(p_surf, f, 3, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_SURFACE && v.n_surface == 2 && v.n_behind == 1 && v.n_in_view == 3);
    /* majority: free in two frames, surface in one -> free; a tie -> surface */
    double p1[3] = {0, 0, 1.8};   /* f0: 1.8 vs 2.0 surface; f1: 2.8 vs 3.1 -> free (tol 0.25); f2: behind 1.5 */
    CHECK_OK(sooc_eval_point_seen(p1, f, 3, 0.25, &v));
    CHECK(v.n_free == 1 && v.n_surface == 1 && v.n_behind == 1 && v.cls == SOOC_SEEN_SURFACE);
    CHECK_CLOSE(v.min_behind, -0.3, 1e-6, 0);   /* f1: 2.8 - 3.1 (float depth) */
    CHECK_OK(sooc_eval_point_seen(p1, f, 3, 0.1, &v));   /* tighter band: free in f0 and f1 */
    CHECK(v.n_free == 2 && v.n_surface == 0 && v.cls == SOOC_SEEN_FREE);
    /* a frame without a pose is skipped */
    f[1].has_pose = 0;
    CHECK_OK(sooc_eval_point_seen(p_surf, f, 2, 0.25, &v));
    CHECK(v.n_in_view == 1);
    /* pitch: a camera 1 m up looking 45 deg down sees the floor point 1 m ahead
     * at planar depth sqrt(2) */
    sooc_frame g;
    memset(&g, 0, sizeof g);
    const double cg[3] = {0, 1, 0};
    make_frame(&g, 16, 16, cg, M_PI / 4, (float)sqrt(2.0));
    double pf[3] = {0, 0, 1}, pa[3] = {0, 0.5, 0.5};
    CHECK_OK(sooc_eval_point_seen(pf, &g, 1, 0.05, &v));
    CHECK(v.cls == SOOC_SEEN_SURFACE);
    CHECK_OK(sooc_eval_point_seen(pa, &g, 1, 0.05, &v));   /* halfway along the same ray: free */
    CHECK(v.cls == SOOC_SEEN_FREE);
    CHECK(sooc_eval_point_seen(pf, &g, 1, 0, &v) == SOOC_EINVAL);
    sooc_clearerr();
    CHECK(!strcmp(sooc_seen_class_name(SOOC_SEEN_NEVER), "never"));
    for (int i = 0; i < 3; i++) sooc_frame_free(&f[i]);
    sooc_frame_free(&g);
}

/* ------------------------------------------------------------- spread */
/* The probe points of an entry: its tight box's centre and face centres
 * carried to the world by the renderer's own object-box transform; one point
 * at the fixed height without a box (or with an empty one). Then the class
 * rule on a wall seen by one camera. */
static void test_entry_probe(void) {
    sooc_map_entry e;
    memset(&e, 0, sizeof e);
    e.x = 1.0, e.z = 2.0, e.yaw = 0.7;
    double p[SOOC_ENTRY_PROBES_MAX][3];
    CHECK(sooc_eval_entry_probes(&e, 0.1, p) == 1);
    CHECK(p[0][0] == 1.0 && p[0][1] == 0.1 && p[0][2] == 2.0);
    e.geom.flags = SOOC_GEOM_TIGHT;
    const float c[3] = {0.25f, 0.9f, -0.1f}, ext[3] = {0.4f, 0.2f, 0.6f};
    memcpy(e.geom.centre, c, sizeof c);
    memcpy(e.extent, ext, sizeof ext);
    CHECK(sooc_eval_entry_probes(&e, 0.1, p) == 7);
    sooc_render_box b;
    sooc_render_box_object(&b, e.x, e.z, e.yaw, 0.0, 0.6, 1.2);
    for (int i = 0; i < 7; i++) {
        double o[3] = {c[0], c[1], c[2]}, q[3];
        if (i) o[(i - 1) / 2] += ((i - 1) % 2 ? 0.5 : -0.5) * ext[(i - 1) / 2];
        for (int r = 0; r < 3; r++)
            q[r] = b.T_fb[4 * r] * o[0] + b.T_fb[4 * r + 1] * o[1] + b.T_fb[4 * r + 2] * o[2] + b.T_fb[4 * r + 3];
        for (int r = 0; r < 3; r++) CHECK_CLOSE(p[i][r], q[r], 1e-6, 0);
    }
    CHECK_CLOSE(p[0][1], 0.9, 1e-6, 0);
    CHECK_CLOSE(p[3][1], 0.8, 1e-6, 0);   /* the bottom face */
    CHECK(fabs(p[0][0] - 1.0) > 0.05);    /* the box's offset is used, rotated */
    e.geom.flags = SOOC_GEOM_TIGHT | SOOC_GEOM_EMPTY;
    CHECK(sooc_eval_entry_probes(&e, 0.3, p) == 1);
    CHECK(p[0][0] == 1.0 && p[0][1] == 0.3 && p[0][2] == 2.0);

    /* one camera at the origin looking down +z at a wall 4 m away (the
     * frame of test_point_seen) */
    sooc_frame f;
    memset(&f, 0, sizeof f);
    const double c0[3] = {0, 0, 0};
    make_frame(&f, 16, 16, c0, 0, 4.0f);
    sooc_seen_votes v;
    memset(&e, 0, sizeof e);
    e.geom.flags = SOOC_GEOM_TIGHT;
    e.extent[0] = e.extent[1] = e.extent[2] = 1.0f;
    e.z = 4.45;   /* centre 0.45 m behind the wall, front face 0.05 m behind it: surface */
    CHECK_OK(sooc_eval_entry_seen(&e, 0.1, &f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_SURFACE && v.n_surface >= 1);
    sooc_seen_votes vc;
    double pc[3] = {0, 0, 4.45};
    CHECK_OK(sooc_eval_point_seen(pc, &f, 1, 0.25, &vc));
    CHECK(vc.cls == SOOC_SEEN_NEVER);   /* the centre alone is occluded */
    e.z = 5.5;    /* wholly behind the wall: never, 1.0 m behind at the front face */
    CHECK_OK(sooc_eval_entry_seen(&e, 0.1, &f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_NEVER);
    CHECK_CLOSE(v.min_behind, 1.0, 1e-6, 0);
    e.z = 2.0;    /* in the air in front of the wall: free */
    CHECK_OK(sooc_eval_entry_seen(&e, 0.1, &f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_FREE && v.n_surface == 0 && v.n_free >= 1);
    e.geom.flags |= SOOC_GEOM_EMPTY;   /* no box: the floor point (0, 0.1, 2) only, free as well */
    CHECK_OK(sooc_eval_entry_seen(&e, 0.1, &f, 1, 0.25, &v));
    CHECK(v.cls == SOOC_SEEN_FREE && v.n_free == 1);
    sooc_frame_free(&f);
}

static void test_spread(void) {
    sooc_track t;
    memset(&t, 0, sizeof t);
    double pr, yr;
    sooc_track_spread(&t, &pr, &yr);
    CHECK(isnan(pr) && isnan(yr));
    sooc_track_add(&t, 3.0, -1.0, 0.2);
    sooc_track_spread(&t, &pr, &yr);
    CHECK_CLOSE(pr, 0, 1e-12, 0);
    CHECK_CLOSE(yr, 0, 1e-6, 0);
    /* (3, -1) and (5, -1): mean (4, -1), RMS distance 1; yaw 0.2 and -0.2:
     * R = cos 0.2, circular std sqrt(-2 ln cos 0.2) ~ 0.2 */
    sooc_track_add(&t, 5.0, -1.0, -0.2);
    sooc_track_spread(&t, &pr, &yr);
    CHECK_CLOSE(pr, 1.0, 1e-12, 0);
    CHECK_CLOSE(yr, sqrt(-2.0 * log(cos(0.2))), 1e-12, 0);
    CHECK(yr > 0.19 && yr < 0.21);
    /* yaw wraps: 3.1 and -3.1 are 0.083 rad apart, not 6.2 */
    sooc_track w;
    memset(&w, 0, sizeof w);
    sooc_track_add(&w, 0, 0, 3.1);
    sooc_track_add(&w, 0, 0, -3.1);
    sooc_track_spread(&w, &pr, &yr);
    CHECK(yr < 0.05);
    /* four points on a circle of radius 0.3 around (1, 2) */
    sooc_track c;
    memset(&c, 0, sizeof c);
    for (int k = 0; k < 4; k++) sooc_track_add(&c, 1 + 0.3 * cos(k * M_PI / 2), 2 + 0.3 * sin(k * M_PI / 2), 0);
    sooc_track_spread(&c, &pr, &yr);
    CHECK_CLOSE(pr, 0.3, 1e-12, 0);
}

/* --------------------------------------------------------------- churn */
static void test_churn(void) {
    sooc_churn c;
    memset(&c, 0, sizeof c);
    uint64_t r1[] = {1, 2, 3};
    sooc_churn_update(&c, 1, r1, 3, NULL, 0);   /* first update creates 1, 2, 3 */
    CHECK(c.created == 3 && c.removed == 0 && c.updates == 1);
    uint64_t r2[] = {2, 4, 5}, m2[] = {1, 5};   /* re-registers 2, creates 4 and 5, removes 1, merges 5 away */
    sooc_churn_update(&c, 4, r2, 3, m2, 2);
    CHECK(c.created == 4 && c.removed == 1 && c.updates == 2);
    /* entries now: 2, 3, 4 = created - removed */
    CHECK(c.created - c.removed == 3);
}

/* ------------------------------------------------------- per-object IoU */
static void test_obj_iou(void) {
    /* 4x4 view: GT ids 0 (top half), 9 (bottom-left 2x2), 4 (bottom-right 2x2).
     * prediction: label 0 top half, label 1 the whole bottom row pair (8 px). */
    uint16_t gt[16];
    int16_t pr[16];
    for (int i = 0; i < 16; i++) {
        int y = i / 4, x = i % 4;
        gt[i] = y < 2 ? 0 : x < 2 ? 9 : 4;
        pr[i] = y < 2 ? 0 : 1;
    }
    sooc_iou_match m;
    CHECK_OK(sooc_metric_miou(pr, 2, gt, NULL, 16, &m));
    sooc_obj_iou_acc a;
    memset(&a, 0, sizeof a);
    CHECK_OK(sooc_obj_iou_add(&a, &m));
    CHECK(a.n == 2 && a.id[0] == 4 && a.id[1] == 9);   /* background left out, ids ascending */
    CHECK_CLOSE(sooc_obj_iou_mean(&a, 0), 0.5, 1e-12, 0);   /* 4 px of an 8-px union */
    CHECK_CLOSE(sooc_obj_iou_mean(&a, 1), 0.5, 1e-12, 0);
    /* second view: object 9 fills the bottom half and is predicted exactly, 4 is absent */
    for (int i = 0; i < 16; i++) gt[i] = i / 4 < 2 ? 0 : 9;
    CHECK_OK(sooc_metric_miou(pr, 2, gt, NULL, 16, &m));
    CHECK_OK(sooc_obj_iou_add(&a, &m));
    CHECK(a.n == 2 && a.views[0] == 1 && a.views[1] == 2);
    CHECK_CLOSE(sooc_obj_iou_mean(&a, 0), 0.5, 1e-12, 0);
    CHECK_CLOSE(sooc_obj_iou_mean(&a, 1), 0.75, 1e-12, 0);   /* (0.5 + 1) / 2 */
    /* third view: object 4 covers one pixel that the prediction gives to a big label: IoU 1/8 */
    for (int i = 0; i < 16; i++) gt[i] = i == 15 ? 4 : 0;
    CHECK_OK(sooc_metric_miou(pr, 2, gt, NULL, 16, &m));
    CHECK_OK(sooc_obj_iou_add(&a, &m));
    CHECK_CLOSE(sooc_obj_iou_mean(&a, 0), (0.5 + 0.125) / 2, 1e-12, 0);
    CHECK(isnan(sooc_obj_iou_mean(&a, 5)));
}

/* ------------------------------------------------------------- labels */
static void test_labels(void) {
    char *dir = tu_tmpdir("evreal");
    char p8[600], p16[600], prgb[600];
    snprintf(p8, sizeof p8, "%s/frame-000000.segm.png", dir);
    snprintf(p16, sizeof p16, "%s/000000.png", dir);
    snprintf(prgb, sizeof prgb, "%s/rgb.png", dir);
    sooc_image im;
    memset(&im, 0, sizeof im);
    CHECK_OK(sooc_image_alloc(&im, 8, 6, SOOC_PIX_GRAY8));
    uint8_t *b8 = im.data;
    for (int i = 0; i < 48; i++) b8[i] = (i % 8) < 4 ? 48 : 132;
    b8[0] = 0;
    CHECK_OK(sooc_png_write(p8, &im, -1));
    CHECK_OK(sooc_image_alloc(&im, 8, 6, SOOC_PIX_GRAY16));
    uint16_t *b16 = im.data;
    for (int i = 0; i < 48; i++) b16[i] = (uint16_t)(1000 + i);
    CHECK_OK(sooc_png_write(p16, &im, -1));
    CHECK_OK(sooc_image_alloc(&im, 8, 6, SOOC_PIX_RGB8));
    CHECK_OK(sooc_png_write(prgb, &im, -1));
    sooc_image_free(&im);

    uint16_t *ids = NULL;
    int w = 0, h = 0;
    CHECK_OK(sooc_eval_labels_read(p8, &ids, &w, &h));
    CHECK(w == 8 && h == 6 && ids && ids[0] == 0 && ids[1] == 48 && ids[4] == 132 && ids[47] == 132);
    CHECK_OK(sooc_eval_labels_read(p16, &ids, &w, &h));
    CHECK(w == 8 && h == 6 && ids[0] == 1000 && ids[47] == 1047);
    /* the crop (2, 1, 4 x 4) halved to 2 x 2: source pixels (3, 2), (5, 2), (3, 4), (5, 4) */
    uint16_t out[4];
    CHECK_OK(sooc_eval_labels_resample(ids, 8, 6, 2, 1, 4, 4, out, 2, 2));
    CHECK(out[0] == 1000 + 2 * 8 + 3 && out[1] == 1000 + 2 * 8 + 5 && out[2] == 1000 + 4 * 8 + 3 &&
          out[3] == 1000 + 4 * 8 + 5);
    /* upsampling keeps ids (no blending): 8 x 6 -> 16 x 12 */
    uint16_t up[16 * 12];
    CHECK_OK(sooc_eval_labels_resample(ids, 8, 6, 0, 0, 8, 6, up, 16, 12));
    CHECK(up[0] == 1000 && up[1] == 1000 && up[2] == 1001 && up[16 * 12 - 1] == 1047);
    CHECK_ERR_HAS(sooc_eval_labels_resample(ids, 8, 6, 6, 0, 4, 4, out, 2, 2), "not inside");
    CHECK_ERR_HAS(sooc_eval_labels_read(prgb, &ids, &w, &h), "rgb.png", "expected an 8- or 16-bit");
    char miss[640];
    snprintf(miss, sizeof miss, "%s/nope.png", dir);
    CHECK_ERR_HAS(sooc_eval_labels_read(miss, &ids, &w, &h), "nope.png");
    sooc_free(ids);
    tu_rm_rf(dir);
}

/* ------------------------------------------------------------- runner */

static void small_cfg(sooc_model_config *c) {
    sooc_model_config_default(c);
    c->K = 3;
    c->d_what = 8;
    c->d_layout = 4;
    c->L = 2;
    c->img_w = c->img_h = 32;
    c->ray_w = c->ray_h = 16;
    c->dec_width = 32;
    c->dec_color_width = 16;
    c->ref_ch[0] = c->ref_ch[1] = 8;
    c->ref_ch[2] = c->ref_ch[3] = 16;
    c->ref_fc = 32;
    c->ref_hidden = 32;
}

/* A camera 1.2 m up, 20 deg down, walking along +z over a checkered floor
 * (planar depth of the floor plane y = 0, sky beyond 6 m invalid); frame
 * `alt` != 0 changes colours and depth (used on query frames only). */
static void floor_frame(sooc_frame *f, int W, int i, int alt, int labels) {
    const double c[3] = {0.05 * i, 1.2, 0.15 * i};
    double pitch = 20 * M_PI / 180;
    sooc_frame_free(f);
    make_frame(f, W, W, c, pitch, 0);
    if (labels) {
        f->instance = sooc_calloc((size_t)W * W, sizeof *f->instance);
        CHECK(f->instance != NULL);
    }
    f->index = i;
    f->K.fx = f->K.fy = 0.8 * W;
    for (int v = 0; v < W; v++)
        for (int u = 0; u < W; u++) {
            size_t k = (size_t)v * W + u;
            double dir[3] = {(u + 0.5 - f->K.cx) / f->K.fx, (v + 0.5 - f->K.cy) / f->K.fy, 1}, dw[3];
            sooc_se3_rotate(dw, f->T_wc, dir);
            double t = dw[1] < -1e-6 ? -c[1] / dw[1] : -1;   /* planar depth: dir has z = 1 */
            float z = t > 0 && t < 6 ? (float)t : 0.0f;
            if (alt && z > 0) z *= 0.6f;
            f->depth[k] = z;
            f->valid[k] = z > 0;
            double X = c[0] + t * dw[0], Z = c[2] + t * dw[2];
            int chk = t > 0 && (((int)floor(X * 2) + (int)floor(Z * 2)) & 1);
            uint8_t col = (uint8_t)(chk ? 200 : 60);
            if (alt) col = (uint8_t)(255 - col);
            f->rgb[3 * k] = col, f->rgb[3 * k + 1] = (uint8_t)(col / 2), f->rgb[3 * k + 2] = 90;
            if (f->instance) f->instance[k] = (uint16_t)(u < W / 3 && v > W / 2 ? 7 : 0);
        }
}

typedef struct cb_ctx { int n, bad; int mapped; double d_sum, c_sum; } cb_ctx;
/* Recomputes each query frame's depth and RGB RMSE from the render and the
 * frame (valid pixels; all are within the 8 m clip) to check the runner's means. */
static sooc_status on_view(void *user, const sooc_eval_view_info *v) {
    cb_ctx *c = user;
    c->n++;
    if (!sooc_eval_real_is_query(v->frame, 4) || v->n_mapped != c->mapped) c->bad++;
    double sd = 0, sc = 0;
    long n = 0;
    for (int k = 0; k < v->gt->width * v->gt->height; k++) {
        if (!v->gt->valid[k]) continue;
        double e = v->render->depth[k] - v->gt->depth[k];
        sd += e * e;
        for (int ch = 0; ch < 3; ch++) {
            double ec = v->render->rgb[3 * k + ch] - v->gt->rgb[3 * k + ch] / 255.0;
            sc += ec * ec;
        }
        n++;
    }
    c->d_sum += sqrt(sd / (double)n);
    c->c_sum += sqrt(sc / (double)n);
    return SOOC_OK;
}

static void test_runner(void) {
    sooc_model_config mc;
    small_cfg(&mc);
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_create(&m, &mc, 5));
    if (!m) return;
    enum { N = 12, W = 32 };
    sooc_frame fa[N], fb[N];
    memset(fa, 0, sizeof fa);
    memset(fb, 0, sizeof fb);
    for (int i = 0; i < N; i++) {
        int q = sooc_eval_real_is_query(i, 4);
        floor_frame(&fa[i], W, i, 0, q);
        floor_frame(&fb[i], W, i, q, q);   /* the query frames differ, the input frames do not */
    }
    sooc_eval_real_opts o;
    sooc_eval_real_opts_default(&o);
    o.query_every = 4;
    o.run.n_coarse = 16, o.run.n_fine = 0, o.run.threads = 1;
    sooc_eval_real_result ra, rb;
    cb_ctx cb = {0, 0, 9, 0, 0};
    CHECK_OK(sooc_eval_real_run(m, fa, N, &o, on_view, &cb, &ra));
    CHECK_OK(sooc_eval_real_run(m, fb, N, &o, NULL, NULL, &rb));
    CHECK(ra.n_frames == N && ra.n_mapped == 9 && ra.n_query == 3);
    CHECK(cb.n == 3 && cb.bad == 0);
    CHECK(ra.has_labels && ra.obj.n == 1 && ra.obj.id[0] == 7 && ra.obj.views[0] == 3);
    CHECK(ra.query.n_depth == 3 && ra.query.n_rgb == 3 && ra.query.n_miou == 3);
    sooc_metric_means mm;
    sooc_metric_sums_means(&ra.query, &mm);
    CHECK(isfinite(mm.depth_rmse) && mm.depth_rmse >= 0 && isfinite(mm.rgb_rmse) && isfinite(mm.miou_best));
    CHECK_CLOSE(mm.depth_rmse, cb.d_sum / 3, 1e-9, 1e-6);   /* mean over the query frames of per-frame RMSE */
    CHECK_CLOSE(mm.rgb_rmse, cb.c_sum / 3, 1e-9, 1e-6);
    /* counts: the map holds what was created minus what was removed, in both passes */
    CHECK((long)ra.entries_final == ra.churn.created - ra.churn.removed);
    CHECK((long)ra.entries_pass2 == (long)ra.entries_final + ra.churn2.created - ra.churn2.removed);
    CHECK(ra.churn.updates == 9 && ra.churn2.updates == 9);
    CHECK((size_t)(ra.n_seen[0] + ra.n_seen[1] + ra.n_seen[2]) == ra.entries_final);
    CHECK(ra.n_never_behind <= ra.n_seen[SOOC_SEEN_NEVER]);
    /* the own-surface rule classes every final entry too (by its box without a mesh) */
    CHECK((size_t)(ra.n_seen_own[0] + ra.n_seen_own[1] + ra.n_seen_own[2]) == ra.entries_final);
    CHECK(ra.n_own_mesh >= 0 && (size_t)ra.n_own_mesh <= ra.entries_final);
    CHECK(ra.n_never_behind == 0 ? isnan(ra.never_behind_med_m) : ra.never_behind_med_m > o.seen_tol);
    CHECK(ra.n_persistent >= 0 && (size_t)ra.n_persistent <= ra.entries_final);
    if (ra.n_persistent) CHECK(isfinite(ra.pos_spread_m) && isfinite(ra.yaw_spread_deg));
    printf("runner: %zu entries (%ld created, %ld removed), pass 2: %zu, persistent %d, seen never/free/surface "
           "%d/%d/%d, depth RMSE %.3f\n",
           ra.entries_final, ra.churn.created, ra.churn.removed, ra.entries_pass2, ra.n_persistent, ra.n_seen[0],
           ra.n_seen[1], ra.n_seen[2], mm.depth_rmse);
    /* query frames are never mapped: changing them leaves the map unchanged */
    CHECK(ra.entries_final == rb.entries_final && ra.churn.created == rb.churn.created &&
          ra.churn.removed == rb.churn.removed && ra.entries_pass2 == rb.entries_pass2 &&
          ra.n_persistent == rb.n_persistent);
    CHECK(ra.n_persistent == 0 || ra.pos_spread_m == rb.pos_spread_m);
    sooc_metric_means mb;
    sooc_metric_sums_means(&rb.query, &mb);
    CHECK(mb.depth_rmse != mm.depth_rmse);   /* ... while their scores change */
    /* no second pass: entries_pass2 = entries_final */
    o.second_pass = 0;
    CHECK_OK(sooc_eval_real_run(m, fa, N, &o, NULL, NULL, &rb));
    CHECK(rb.entries_pass2 == rb.entries_final && rb.churn2.updates == 0 && rb.entries_final == ra.entries_final);

    /* JSON contract */
    char *js = NULL;
    o.second_pass = 1;
    CHECK_OK(sooc_eval_real_json("tiny", "floor", "/x/floor", &o, &ra, &js));
    if (js) {
        const char *keys[] = {"\"scale\": \"real\"", "\"view\": \"Q\"", "\"depth_rmse\": ", "\"rgb_rmse\": ",
                              "\"entries_final\": ", "\"entries_created\": ", "\"miou\": ", "\"obj_iou\": [",
                              "\"obj_ids\": [7]", "\"growth\": ", "\"free_frac\": ", "\"never_seen_frac\": ",
                              "\"pos_spread_m\": ", "\"yaw_spread_deg\": ", "\"frames_query\": 3", "\"query_every\": 4"};
        for (size_t k = 0; k < sizeof keys / sizeof keys[0]; k++)
            CHECK_MSG(strstr(js, keys[k]) != NULL, "JSON lacks %s: %s", keys[k], js);
        char want[64];
        snprintf(want, sizeof want, "\"entries_final\": %zu,", ra.entries_final);
        CHECK(strstr(js, want) != NULL);
        sooc_free(js);
    }
    /* unlabelled: no miou / obj_iou keys */
    ra.has_labels = 0;
    CHECK_OK(sooc_eval_real_json("tiny", "floor", NULL, &o, &ra, &js));
    if (js) {
        CHECK(!strstr(js, "\"miou\"") && !strstr(js, "obj_iou"));
        sooc_free(js);
    }

    /* merging (--merge 0.35 --revisit): the counts still add up */
    o.second_pass = 1;
    o.run.merge_radius = 0.35;
    o.run.revisit = 1;
    CHECK_OK(sooc_eval_real_run(m, fa, N, &o, NULL, NULL, &rb));
    CHECK((long)rb.entries_final == rb.churn.created - rb.churn.removed);
    CHECK((long)rb.entries_pass2 == (long)rb.entries_final + rb.churn2.created - rb.churn2.removed);
    o.run.merge_radius = 0;
    o.run.revisit = 0;

    /* the global-frame baseline: its present slots are the entries */
    {
        sooc_model_config gc;
        small_cfg(&gc);
        gc.global_frame = 1;
        gc.global_radius = 2.5f;
        sooc_model *g = NULL;
        CHECK_OK(sooc_model_create(&g, &gc, 7));
        sooc_eval_real_result rg;
        o.second_pass = 1;
        if (g) CHECK_OK(sooc_eval_real_run(g, fa, N, &o, NULL, NULL, &rg));
        if (g) {
            CHECK(rg.n_mapped == 9 && rg.n_query == 3 && rg.churn.updates == 9 && rg.churn2.updates == 9);
            CHECK(rg.entries_final <= (size_t)gc.K && rg.entries_pass2 <= (size_t)gc.K);
            CHECK((long)rg.entries_final == rg.churn.created - rg.churn.removed);
            CHECK((long)rg.entries_pass2 == (long)rg.entries_final + rg.churn2.created - rg.churn2.removed);
            CHECK((size_t)(rg.n_seen[0] + rg.n_seen[1] + rg.n_seen[2]) == rg.entries_final);
            CHECK(rg.n_seen_own[0] + rg.n_seen_own[1] + rg.n_seen_own[2] == 0);   /* no own meshes: SOOC3D only */
            CHECK(rg.query.n_depth == 3 && rg.obj.n == 1);
            printf("baseline: %zu slots present (%ld created, %ld removed), pass 2: %zu, persistent %d\n",
                   rg.entries_final, rg.churn.created, rg.churn.removed, rg.entries_pass2, rg.n_persistent);
        }
        sooc_model_destroy(g);
    }

    /* errors name the problem */
    o.query_every = 1;
    CHECK_ERR_HAS(sooc_eval_real_run(m, fa, N, &o, NULL, NULL, &rb), "query rule", ">= 2");
    o.query_every = 4;
    CHECK_ERR_HAS(sooc_eval_real_run(m, fa, 2, &o, NULL, NULL, &rb), "2 frames", "0 query");
    fa[5].has_pose = 0;
    CHECK_ERR_HAS(sooc_eval_real_run(m, fa, N, &o, NULL, NULL, &rb), "frame 5", "no pose");
    fa[5].has_pose = 1;
    sooc_frame big;
    memset(&big, 0, sizeof big);
    floor_frame(&big, 48, 3, 0, 0);
    sooc_frame keep = fa[3];
    fa[3] = big;
    CHECK_ERR_HAS(sooc_eval_real_run(m, fa, N, &o, NULL, NULL, &rb), "48x48", "32x32");
    fa[3] = keep;
    sooc_frame_free(&big);
    for (int i = 0; i < N; i++) {
        sooc_frame_free(&fa[i]);
        sooc_frame_free(&fb[i]);
    }
    sooc_model_destroy(m);
}

/* sooc_eval_points_seen: the class of a surface given as points, by the
 * majority of its probed points. A camera at the origin looks along +z at a
 * wall 2 m away. */
static void test_points_seen(void) {
    sooc_frame f;
    memset(&f, 0, sizeof f);
    const double c0[3] = {0, 0, 0};
    make_frame(&f, 16, 16, c0, 0, 2.0f);
    /* 10 points: 6 on the wall, 4 in the air in front of it */
    float xyz[30];
    for (int i = 0; i < 10; i++) {
        xyz[3 * i] = 0.05f * (float)(i - 5), xyz[3 * i + 1] = 0.0f;
        xyz[3 * i + 2] = i < 6 ? 2.05f : 1.0f;
    }
    int pts[3];
    sooc_seen_class cls;
    CHECK_OK(sooc_eval_points_seen(xyz, 10, 64, &f, 1, 0.1, pts, &cls));
    CHECK(pts[SOOC_SEEN_SURFACE] == 6 && pts[SOOC_SEEN_FREE] == 4 && pts[SOOC_SEEN_NEVER] == 0);
    CHECK(cls == SOOC_SEEN_SURFACE);
    /* only the air points: free */
    CHECK_OK(sooc_eval_points_seen(xyz + 18, 4, 64, &f, 1, 0.1, pts, &cls));
    CHECK(cls == SOOC_SEEN_FREE && pts[SOOC_SEEN_FREE] == 4);
    /* a tie is a surface */
    CHECK_OK(sooc_eval_points_seen(xyz + 12, 4, 64, &f, 1, 0.1, pts, &cls));
    CHECK(pts[SOOC_SEEN_SURFACE] == 2 && pts[SOOC_SEEN_FREE] == 2 && cls == SOOC_SEEN_SURFACE);
    /* max_probes 2 of 10: points 0 and 6 (index step 6): one surface, one free */
    CHECK_OK(sooc_eval_points_seen(xyz, 10, 2, &f, 1, 0.1, pts, &cls));
    CHECK(pts[SOOC_SEEN_SURFACE] + pts[SOOC_SEEN_FREE] + pts[SOOC_SEEN_NEVER] == 2);
    CHECK(pts[SOOC_SEEN_SURFACE] == 1 && pts[SOOC_SEEN_FREE] == 1);
    /* behind the wall, or no points at all: never */
    float behind[3] = {0, 0, 3.0f};
    CHECK_OK(sooc_eval_points_seen(behind, 1, 64, &f, 1, 0.1, pts, &cls));
    CHECK(cls == SOOC_SEEN_NEVER && pts[SOOC_SEEN_NEVER] == 1);
    CHECK_OK(sooc_eval_points_seen(NULL, 0, 64, &f, 1, 0.1, pts, &cls));
    CHECK(cls == SOOC_SEEN_NEVER && pts[0] + pts[1] + pts[2] == 0);
    CHECK(sooc_eval_points_seen(xyz, 10, 0, &f, 1, 0.1, pts, &cls) == SOOC_EINVAL);
    sooc_frame_free(&f);
}

int main(void) {
    test_query_rule();
    test_point_seen();
    test_points_seen();
    test_box_fit();
    test_entry_probe();
    test_spread();
    test_churn();
    test_obj_iou();
    test_labels();
    test_runner();
    return check_report("test_eval_real");
}
