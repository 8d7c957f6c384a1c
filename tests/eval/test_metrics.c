/* Metrics on hand-computed cases (docs/metrics.md). */
#include "check.h"
#include "sooc3d/eval.h"

#include <string.h>

/* brute-force minimum assignment: every injective map of the smaller side */
static double bf_best;
static void bf_rec(const double *c, int n, int m, int i, int *used, double acc) {
    if (n <= m) {
        if (i == n) { if (acc < bf_best) bf_best = acc; return; }
        for (int j = 0; j < m; j++)
            if (!used[j]) { used[j] = 1; bf_rec(c, n, m, i + 1, used, acc + c[i * m + j]); used[j] = 0; }
    } else {
        if (i == m) { if (acc < bf_best) bf_best = acc; return; }
        for (int r = 0; r < n; r++)
            if (!used[r]) { used[r] = 1; bf_rec(c, n, m, i + 1, used, acc + c[r * m + i]); used[r] = 0; }
    }
}

static void test_hungarian(void) {
    /* classic 3x3 */
    double c[9] = {4, 1, 3, 2, 0, 5, 3, 2, 2};
    int a[3];
    double t;
    CHECK_OK(sooc_hungarian(c, 3, 3, a, &t));
    CHECK_CLOSE(t, 5.0, 1e-12, 0);   /* 1 + 2 + 2 */
    CHECK(a[0] == 1 && a[1] == 0 && a[2] == 2);
    /* random rectangular vs brute force */
    sooc_rng r;
    sooc_rng_seed(&r, 7, 0);
    int bad = 0, ntest = 0;
    for (int it = 0; it < 400; it++) {
        int n = 1 + (int)sooc_rng_below(&r, 6), m = 1 + (int)sooc_rng_below(&r, 6);
        double cc[36];
        for (int i = 0; i < n * m; i++)
            cc[i] = it % 3 == 0 ? (double)sooc_rng_below(&r, 4) : sooc_rng_range(&r, -2, 3);  /* ties too */
        int as[6], used[6] = {0};
        double tot;
        CHECK_OK(sooc_hungarian(cc, n, m, as, &tot));
        bf_best = INFINITY;
        bf_rec(cc, n, m, 0, used, 0.0);
        /* assignment is valid: distinct columns, min(n,m) assigned */
        int seen[6] = {0}, na = 0, dup = 0;
        double chk = 0;
        for (int i = 0; i < n; i++)
            if (as[i] >= 0) { dup |= seen[as[i]]++; na++; chk += cc[i * m + as[i]]; }
        ntest++;
        if (fabs(tot - bf_best) > 1e-9 || dup || na != (n < m ? n : m) || fabs(chk - tot) > 1e-9) bad++;
    }
    CHECK_MSG(bad == 0, "%d of %d random matrices disagree with brute force", bad, ntest);
    printf("hungarian: %d random matrices up to 6x6 (rectangular, with ties) match brute force\n", ntest);
    CHECK_OK(sooc_hungarian(NULL, 0, 3, NULL, &t));
    double nanc[1] = {NAN};
    CHECK(sooc_hungarian(nanc, 1, 1, a, &t) == SOOC_ENUMERIC);
}

static void test_miou(void) {
    sooc_iou_match m;
    /* 1. best-match is not injective; Hungarian differs */
    {
        uint16_t g[6] = {0, 0, 1, 1, 2, 2};
        int16_t p[6] = {0, 0, 1, 1, 1, 1};
        CHECK_OK(sooc_metric_miou(p, 2, g, NULL, 6, &m));
        CHECK(m.n_gt == 3);
        CHECK_CLOSE(m.best_iou[0], 1.0, 1e-12, 0);
        CHECK_CLOSE(m.best_iou[1], 0.5, 1e-12, 0);   /* 2 / (2 + 4 - 2) */
        CHECK_CLOSE(m.best_iou[2], 0.5, 1e-12, 0);
        CHECK(m.best_pred[1] == 1 && m.best_pred[2] == 1);   /* label 1 used twice */
        CHECK_CLOSE(m.miou_best, 2.0 / 3.0, 1e-12, 0);
        CHECK_CLOSE(m.miou_hung, 0.5, 1e-12, 0);           /* (1 + 0.5 + 0) / 3 */
        CHECK((m.hung_pred[1] == 1) != (m.hung_pred[2] == 1));
    }
    /* 2. IoU < 0.05 is zeroed (1/30 = 0.033); 0.0526 is kept */
    {
        uint16_t g[40];
        int16_t p[40];
        for (int i = 0; i < 40; i++) { g[i] = i == 0 ? 7 : 0; p[i] = i < 30 ? 0 : 1; }
        CHECK_OK(sooc_metric_miou(p, 2, g, NULL, 40, &m));
        CHECK(m.n_gt == 2 && m.gt_id[0] == 0 && m.gt_id[1] == 7);
        CHECK_CLOSE(m.best_iou[0], 29.0 / 40.0, 1e-12, 0);
        CHECK(m.best_iou[1] == 0.0 && m.best_pred[1] == -1);
        CHECK_CLOSE(m.miou_best, 29.0 / 80.0, 1e-12, 0);
        CHECK(m.hung_iou[1] == 0.0 && m.hung_pred[1] == -1);
        /* 2 of 38 GT pixels of id 7 predicted as 1, alone: IoU = 2/38 = 0.0526 >= 0.05 */
        uint16_t g2[40];
        int16_t p2[40];
        for (int i = 0; i < 40; i++) { g2[i] = i < 38 ? 7 : 0; p2[i] = i < 2 ? 1 : (i < 38 ? -1 : 0); }
        CHECK_OK(sooc_metric_miou(p2, 2, g2, NULL, 40, &m));
        CHECK_CLOSE(m.best_iou[1], 2.0 / 38.0, 1e-12, 0);
        CHECK(m.best_pred[1] == 1);
        CHECK_CLOSE(m.best_iou[0], 1.0, 1e-12, 0);
    }
    /* 3. invisible GT (only under the mask) is excluded; "none" counts in unions */
    {
        uint16_t g[8] = {0, 0, 1, 1, 1, 1, 3, 3};
        int16_t p[8] = {0, 0, 1, 1, -1, -1, 1, 1};
        uint8_t mk[8] = {1, 1, 1, 1, 1, 1, 0, 0};
        CHECK_OK(sooc_metric_miou(p, 2, g, mk, 8, &m));
        CHECK(m.n_gt == 2);                              /* id 3 not visible */
        CHECK_CLOSE(m.best_iou[1], 0.5, 1e-12, 0);        /* 2 / (4 + 2 - 2) */
        CHECK_CLOSE(m.miou_best, 0.75, 1e-12, 0);
        CHECK_CLOSE(m.miou_hung, 0.75, 1e-12, 0);
        /* nothing visible: NaN, n_gt = 0 */
        uint8_t none[8] = {0};
        CHECK_OK(sooc_metric_miou(p, 2, g, none, 8, &m));
        CHECK(m.n_gt == 0 && isnan(m.miou_best));
        /* label out of range */
        int16_t pb[8] = {0, 0, 5, 0, 0, 0, 0, 0};
        CHECK(sooc_metric_miou(pb, 2, g, NULL, 8, &m) == SOOC_EINVAL);
    }
    /* 4. Hungarian with more GT than predictions (2 labels, 3 GT) and vice versa */
    {
        uint16_t g[6] = {0, 0, 1, 1, 2, 2};
        int16_t p[6] = {0, 0, 2, 2, 3, 3};   /* label 1 unused */
        CHECK_OK(sooc_metric_miou(p, 4, g, NULL, 6, &m));
        CHECK_CLOSE(m.miou_best, 1.0, 1e-12, 0);
        CHECK_CLOSE(m.miou_hung, 1.0, 1e-12, 0);
        CHECK(m.hung_pred[1] == 2 && m.hung_pred[2] == 3);
    }
}

static void test_rmse(void) {
    float pr[9] = {0.5f, 0.5f, 0.5f, 0.2f, 0.2f, 0.2f, 1, 1, 1};
    uint8_t gt[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    /* pixel 0: diffs (0.1, 0.2, 0.2) -> sum sq 0.09; pixel 1: (0.2, 0.2, 0.2) -> 0.12; pixel 2 masked */
    gt[0] = 102; gt[1] = 76; gt[2] = 76;   /* /255: 0.4, 0.298, 0.298 */
    uint8_t mk[3] = {1, 1, 0};
    double e0 = 0.5 - 102 / 255.0, e1 = 0.5 - 76 / 255.0;
    double expect = sqrt((e0 * e0 + 2 * e1 * e1 + 3 * 0.04) / 2.0);
    double got = sooc_metric_rgb_rmse(pr, gt, mk, 3);
    CHECK_CLOSE(got, expect, 1e-6, 0);
    /* a uniform error e on every channel gives RMSE = e * sqrt(3) (channel sum) */
    float u[6] = {0.6f, 0.6f, 0.6f, 0.6f, 0.6f, 0.6f};
    uint8_t ug[6] = {102, 102, 102, 102, 102, 102};
    CHECK_CLOSE(sooc_metric_rgb_rmse(u, ug, NULL, 2), 0.2 * sqrt(3.0), 1e-6, 0);
    float dp[3] = {4, 6, 100}, dg[3] = {1, 10, 1};
    CHECK_CLOSE(sooc_metric_depth_rmse(dp, dg, mk, 3), sqrt(12.5), 1e-12, 0);
    uint8_t z[3] = {0, 0, 0};
    CHECK(isnan(sooc_metric_depth_rmse(dp, dg, z, 3)));
    /* valid mask: depth <= d_clip, > 0, valid */
    float d[5] = {1, 8, 8.01f, 0, 3};
    uint8_t v[5] = {1, 1, 1, 1, 0}, mo[5];
    CHECK(sooc_metric_valid_mask(d, v, 5, 8.0, mo) == 2);
    CHECK(mo[0] && mo[1] && !mo[2] && !mo[3] && !mo[4]);
}

static void test_view(void) {
    /* 4x2 frame, camera at world (0, 1, 0): GT ids [0 0 1 1 / 2 2 9 9],
     * object 1 at (1, 2) (d = 2.24, bin 0), object 2 at (0, 4) (bin 1), object 9 at (0, 9) (bin 2) */
    sooc_frame f;
    CHECK_OK(sooc_frame_alloc(&f, 4, 2, 1));
    sooc_se3_identity(f.T_wc);
    f.T_wc[7] = 1.0;
    f.is_query = 1;
    uint16_t ids[8] = {0, 0, 1, 1, 2, 2, 9, 9};
    for (int p = 0; p < 8; p++) {
        f.instance[p] = ids[p];
        f.depth[p] = p == 7 ? 9.0f : 2.0f;   /* pixel 7 beyond d_clip = 8 */
        f.valid[p] = 1;
        f.rgb[3 * p] = f.rgb[3 * p + 1] = f.rgb[3 * p + 2] = 0;
    }
    sooc_render_out pr;
    memset(&pr, 0, sizeof pr);
    pr.width = 4; pr.height = 2; pr.n_comp = 3;
    float rgb[24] = {0}, dep[8];
    int16_t lab[8] = {0, 0, 1, 1, 2, 1, 0, 0};
    for (int p = 0; p < 8; p++) dep[p] = 2.5f;
    pr.rgb = rgb; pr.depth = dep; pr.label = lab;
    double pxz[6] = {NAN, NAN, 1.3, 2.4, 0.0, 4.5};   /* layout has no position */
    sooc_gt_object go[3] = {{1, 1.0, 2.0}, {2, 0.0, 4.0}, {9, 0.0, 9.0}};
    sooc_view_eval_in in = {&f, &pr, 8.0, 3, pxz, go, 3, NULL};
    sooc_view_metrics vm;
    sooc_iou_match m;
    CHECK_OK(sooc_metric_view(&in, &vm, &m));
    /* M = 7 pixels; GT 0: {0,1}, 1: {2,3}, 2: {4,5}, 9: {6} */
    CHECK(vm.n_valid_pixels == 7 && vm.n_gt_visible == 4 && vm.is_query == 1);
    /* IoUs: g0 -> label 0: inter 2, union 2 + 3 - 2 = 3 -> 2/3; g1 -> label 1: 2 / (2+3-2) = 2/3;
     * g2 -> label 2: 1/2 (label 1: 1/4); g9 -> label 0: 1/3 */
    CHECK_CLOSE(m.best_iou[0], 2.0 / 3, 1e-12, 0);
    CHECK_CLOSE(m.best_iou[1], 2.0 / 3, 1e-12, 0);
    CHECK_CLOSE(m.best_iou[2], 0.5, 1e-12, 0);
    CHECK_CLOSE(m.best_iou[3], 1.0 / 3, 1e-12, 0);
    CHECK_CLOSE(vm.miou_best, (2.0 / 3 + 2.0 / 3 + 0.5 + 1.0 / 3) / 4, 1e-12, 0);
    /* Hungarian: 3 labels for 4 GT; best total 2/3 + 2/3 + 1/2, g9 unmatched */
    CHECK_CLOSE(vm.miou_hung, (2.0 / 3 + 2.0 / 3 + 0.5) / 4, 1e-12, 0);
    CHECK_CLOSE(vm.depth_rmse, 0.5, 1e-6, 0);
    CHECK_CLOSE(vm.rgb_rmse, 0.0, 1e-12, 0);
    /* objects: 1 matched (err hypot(0.3, 0.4) = 0.5), 2 matched (0.5), 9 matched to the layout -> no position */
    CHECK(vm.n_obj_visible == 3 && vm.n_obj_matched == 2);
    CHECK_CLOSE(vm.l2_sum, 1.0, 1e-12, 0);
    CHECK(vm.recall_tot[0] == 1 && vm.recall_tot[1] == 1 && vm.recall_tot[2] == 1);
    CHECK(vm.recall_hit[0] == 1 && vm.recall_hit[1] == 1 && vm.recall_hit[2] == 0);

    /* accumulate: two views at scale m, Q */
    sooc_metric_acc acc;
    memset(&acc, 0, sizeof acc);
    sooc_metric_acc_add_view(&acc, SOOC_SCALE_M, &vm);
    sooc_view_metrics v2 = vm;
    v2.miou_best = 0.2; v2.rgb_rmse = NAN;   /* a view without valid pixels does not count in RMSE */
    sooc_metric_acc_add_view(&acc, SOOC_SCALE_M, &v2);
    sooc_metric_means mm;
    sooc_metric_sums_means(&acc.cell[SOOC_SCALE_M][1], &mm);
    CHECK(mm.n_views == 2);
    CHECK_CLOSE(mm.miou_best, (vm.miou_best + 0.2) / 2, 1e-12, 0);
    CHECK_CLOSE(mm.rgb_rmse, 0.0, 1e-12, 0);
    CHECK_CLOSE(mm.l2, 0.5, 1e-12, 0);
    CHECK_CLOSE(mm.matched_frac, 4.0 / 6.0, 1e-12, 0);
    CHECK_CLOSE(mm.recall[2], 0.0, 1e-12, 0);
    CHECK(isnan(mm.mesh_acc_cm));
    CHECK(acc.cell[SOOC_SCALE_M][0].n_views == 0);
    CHECK(sooc_scale_parse("medium") == SOOC_SCALE_M && sooc_scale_parse("XL") == SOOC_SCALE_XL &&
          sooc_scale_parse("huge") == -1);
    sooc_frame_free(&f);
}

/* Object-pixel RGB RMSE: a 4x2 frame, GT ids [0 0 1 1 / 2 2 0 0], pixel 5
 * beyond d_clip. The prediction's floor is exact; object 1 is off by
 * (0.5, 0, 0) (sum sq 0.25 per pixel), object 2 by (0.1, 0.2, 0.2) (0.09). */
static void test_view_obj(void) {
    sooc_frame f;
    CHECK_OK(sooc_frame_alloc(&f, 4, 2, 1));
    sooc_se3_identity(f.T_wc);
    uint16_t ids[8] = {0, 0, 1, 1, 2, 2, 0, 0};
    float rgb[24], dep[8];
    int16_t lab[8] = {0};
    for (int p = 0; p < 8; p++) {
        f.instance[p] = ids[p];
        f.depth[p] = p == 5 ? 9.0f : 2.0f;
        f.valid[p] = 1;
        const uint8_t c[3] = {128, 64, 32};
        for (int ch = 0; ch < 3; ch++) {
            f.rgb[3 * p + ch] = c[ch];
            rgb[3 * p + ch] = (float)(c[ch] / 255.0);
        }
        dep[p] = 2.0f;
    }
    const float e1[3] = {0.5f, 0, 0}, e2[3] = {0.1f, 0.2f, 0.2f};
    for (int p = 2; p < 6; p++)
        for (int ch = 0; ch < 3; ch++) rgb[3 * p + ch] += p < 4 ? e1[ch] : p == 4 ? e2[ch] : 1.0f;
    sooc_render_out pr;
    memset(&pr, 0, sizeof pr);
    pr.width = 4; pr.height = 2; pr.n_comp = 1;
    pr.rgb = rgb; pr.depth = dep; pr.label = lab;
    uint8_t scratch[8];
    sooc_view_eval_in in = {&f, &pr, 8.0, 1, NULL, NULL, 0, scratch};
    sooc_view_metrics vm;
    CHECK_OK(sooc_metric_view(&in, &vm, NULL));
    /* M = 7 pixels (5 is beyond d_clip); object pixels in M: 2, 3 (0.25 each) and 4 (0.09) */
    CHECK(vm.n_valid_pixels == 7);
    CHECK_CLOSE(vm.rgb_rmse, sqrt(0.59 / 7), 1e-6, 0);
    CHECK_CLOSE(vm.rgb_rmse_obj, sqrt(0.59 / 3), 1e-6, 0);
    CHECK_CLOSE(vm.depth_rmse, 0.0, 1e-12, 0);
    /* the same without a caller scratch */
    in.mask_scratch = NULL;
    sooc_view_metrics v2;
    CHECK_OK(sooc_metric_view(&in, &v2, NULL));
    CHECK(v2.rgb_rmse == vm.rgb_rmse && v2.rgb_rmse_obj == vm.rgb_rmse_obj);
    /* no object pixel in M (the only object pixel is beyond d_clip): NaN */
    uint16_t *inst = f.instance;
    for (int p = 0; p < 8; p++) inst[p] = p == 5 ? 3 : 0;
    sooc_view_metrics vn;
    CHECK_OK(sooc_metric_view(&in, &vn, NULL));
    CHECK(isnan(vn.rgb_rmse_obj) && isfinite(vn.rgb_rmse));
    CHECK_CLOSE(vn.rgb_rmse, vm.rgb_rmse, 1e-12, 0);
    /* no instance map: NaN, the all-pixel RMSE unchanged */
    f.instance = NULL;
    CHECK_OK(sooc_metric_view(&in, &vn, NULL));
    CHECK(isnan(vn.rgb_rmse_obj) && isnan(vn.miou_best));
    CHECK_CLOSE(vn.rgb_rmse, vm.rgb_rmse, 1e-12, 0);
    f.instance = inst;
    /* accumulation: the view-mean over views where it is finite */
    sooc_metric_sums a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    sooc_metric_sums_add_view(&a, &vm);
    sooc_metric_sums_add_view(&a, &vn);   /* NaN: not counted */
    vm.rgb_rmse_obj = 0.5;
    sooc_metric_sums_add_view(&b, &vm);
    sooc_metric_sums_merge(&a, &b);
    sooc_metric_means mm;
    sooc_metric_sums_means(&a, &mm);
    CHECK(a.n_views == 3 && a.n_rgb_obj == 2 && a.n_rgb == 3);
    CHECK_CLOSE(mm.rgb_rmse_obj, (sqrt(0.59 / 3) + 0.5) / 2, 1e-6, 0);
    memset(&b, 0, sizeof b);
    sooc_metric_sums_means(&b, &mm);
    CHECK(isnan(mm.rgb_rmse_obj));
    sooc_frame_free(&f);
}

int main(void) {
    test_hungarian();
    test_miou();
    test_rmse();
    test_view();
    test_view_obj();
    sooc_alloc_stats st;
    sooc_alloc_get_stats(&st);
    CHECK_MSG(st.live_bytes == 0, "leak: %llu bytes", (unsigned long long)st.live_bytes);
    return check_report("test_metrics");
}
