/* Table machinery, end-to-end view evaluation (reproducible for a fixed
 * seed) and the pictures (written to a temp dir, or to $SOOC_EVAL_PICS). */
#include "check.h"
#include "sooc3d/eval.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- a tiny analytic field: floor (layout) + two spheres, field frame = camera frame ---- */
typedef struct sph { double c[3], r; float col[3]; } sph;
static sph g_sph[2] = {{{-0.6, 0.3, 3.0}, 0.5, {0.9f, 0.2f, 0.1f}}, {{0.7, 0.2, 4.0}, 0.6, {0.1f, 0.8f, 0.2f}}};
static double g_jit = 0.0;   /* posterior-sample offset */

static void field_eval(void *user, int worker, int comp, const float *p, int n, float *s, float *rgb) {
    (void)user; (void)worker;
    for (int i = 0; i < n; i++) {
        double x = p[3 * i], y = p[3 * i + 1], z = p[3 * i + 2];
        float v = 0.f, c[3] = {0.5f, 0.5f, 0.5f};
        if (comp == 0) {
            if (y >= 0.8) { v = 1.f; c[0] = c[1] = c[2] = (((int)floor(x * 2) + (int)floor(z * 2)) & 1) ? 0.7f : 0.4f; }
        } else {
            const sph *q = &g_sph[comp - 1];
            double dx = x - q->c[0] - g_jit, dy = y - q->c[1], dz = z - q->c[2];
            if (dx * dx + dy * dy + dz * dz <= q->r * q->r) { v = 1.f; memcpy(c, q->col, sizeof c); }
        }
        s[i] = v;
        memcpy(rgb + 3 * i, c, sizeof c);
    }
}

static sooc_status shift_get(void *user, int m, sooc_field *f) {
    *f = *(const sooc_field *)user;
    g_jit = 0.04 * m;
    return SOOC_OK;
}

static void make_gt(sooc_frame *f, const sooc_field *fld, const sooc_intrinsics *K, const double T[16]) {
    sooc_render_opts o;
    sooc_render_opts_default(&o);
    o.n_coarse = 128; o.n_fine = 64; o.d_clip = 8.0;
    sooc_render_out r;
    memset(&r, 0, sizeof r);
    CHECK_OK(sooc_render_view(fld, K, T, &o, &r));
    CHECK_OK(sooc_frame_alloc(f, K->width, K->height, 1));
    f->K = *K;
    sooc_se3_identity(f->T_wc);
    f->has_pose = 1;
    f->is_query = 1;
    for (int p = 0; p < K->width * K->height; p++) {
        for (int ch = 0; ch < 3; ch++) f->rgb[3 * p + ch] = (uint8_t)lrintf(fminf(1.f, r.rgb[3 * p + ch]) * 255.f);
        int sky = r.label[p] < 0;
        f->depth[p] = sky ? 0.f : r.depth[p];
        f->valid[p] = !sky;
        f->instance[p] = sky ? 0 : (uint16_t)(r.label[p] == 0 ? 0 : 10 + r.label[p]);
    }
    sooc_render_out_free(&r);
}

static void test_table(const char *dir) {
    sooc_eval_table *t;
    CHECK_OK(sooc_eval_table_create(&t));
    /* model A: runs 0 and 1 at scale m; per-run query mIoU 0.6 and 0.8 -> mean 0.7, std 0.1414 */
    for (int run = 0; run < 2; run++)
        for (int v = 0; v < 3; v++) {
            sooc_view_metrics vm;
            memset(&vm, 0, sizeof vm);
            vm.is_query = 1;
            vm.miou_best = run ? 0.8 : 0.6;
            vm.miou_hung = vm.miou_best - 0.1;
            vm.rgb_rmse = 0.1 + 0.01 * v;   /* mean 0.11 per run */
            vm.rgb_rmse_obj = v == 2 ? NAN : 0.3 + 0.1 * run;   /* runs: 0.3, 0.4 (NaN view left out) */
            vm.depth_rmse = 0.5;
            vm.n_obj_visible = 2; vm.n_obj_matched = 1; vm.l2_sum = 0.2 * (run + 1);
            vm.recall_tot[0] = 2; vm.recall_hit[0] = 1;
            CHECK_OK(sooc_eval_table_add_view(t, "ours", SOOC_SCALE_M, run, &vm));
            vm.is_query = 0;
            CHECK_OK(sooc_eval_table_add_view(t, "ours", SOOC_SCALE_M, run, &vm));
            vm.is_query = 1;
            vm.miou_best = 0.3;
            CHECK_OK(sooc_eval_table_add_view(t, "baseline", SOOC_SCALE_L, run, &vm));
        }
    sooc_eval_cell c;
    CHECK_OK(sooc_eval_table_cell(t, "ours", SOOC_SCALE_M, 1, &c));
    CHECK(c.n_views == 6 && c.miou_best.n_runs == 2);
    CHECK_CLOSE(c.miou_best.mean, 0.7, 1e-12, 0);
    CHECK_CLOSE(c.miou_best.std, sqrt(0.02), 1e-12, 0);
    CHECK_CLOSE(c.rgb_rmse.mean, 0.11, 1e-12, 0);
    CHECK_CLOSE(c.rgb_rmse.std, 0.0, 1e-12, 0);
    CHECK(c.rgb_rmse_obj.n_runs == 2);
    CHECK_CLOSE(c.rgb_rmse_obj.mean, 0.35, 1e-12, 0);
    CHECK_CLOSE(c.rgb_rmse_obj.std, sqrt(0.005), 1e-12, 0);
    CHECK_CLOSE(c.l2.mean, 0.3, 1e-12, 0);   /* runs: 0.2, 0.4 */
    CHECK_CLOSE(c.matched_frac.mean, 0.5, 1e-12, 0);
    CHECK(sooc_eval_table_cell(t, "ours", SOOC_SCALE_S, 1, &c) == SOOC_ENOTFOUND);
    CHECK(sooc_eval_table_add_view(t, "", 0, 0, &(sooc_view_metrics){0}) == SOOC_EINVAL);
    CHECK_OK(sooc_eval_table_set_note(t, "input views rendered from the final map"));
    char *txt = NULL, *md = NULL, *js = NULL;
    CHECK_OK(sooc_eval_table_text(t, &txt));
    CHECK_OK(sooc_eval_table_markdown(t, &md));
    CHECK_OK(sooc_eval_table_json(t, &js));
    if (txt) {
        printf("%s", txt);
        CHECK(strstr(txt, "0.700±0.141") != NULL);
        CHECK(strstr(txt, "n/a") != NULL);   /* L2 of input views */
    }
    if (md) CHECK(strstr(md, "| ours | I |") != NULL && strstr(md, "Hungarian") != NULL);
    /* object-pixel RGB RMSE: a supplementary column, not in the main table */
    if (md) CHECK(strstr(md, "| recall >5 m | RGB RMSE objects |") != NULL);
    if (md) CHECK(strstr(md, " 0.350±0.071 |\n") != NULL);
    if (txt) CHECK(strstr(txt, "objects") == NULL);
    if (js) CHECK(strstr(js, "\"model\": \"baseline\", \"scale\": \"l\", \"view\": \"Q\"") != NULL);
    if (js) CHECK(strstr(js, "\"rgb_rmse_obj\": {\"mean\": 0.35, ") != NULL &&
                  strstr(js, "\"rgb_rmse_obj\": \"channel sum") != NULL);
    sooc_free(txt); sooc_free(md); sooc_free(js);
    char jp[1024], mp[1024];
    snprintf(jp, sizeof jp, "%s/table.json", dir);
    snprintf(mp, sizeof mp, "%s/table.md", dir);
    CHECK_OK(sooc_eval_table_write(t, jp, mp));
    CHECK(sooc_file_exists(jp) && sooc_file_exists(mp));
    sooc_eval_table_destroy(t);

    /* composition-matched mIoU: medium views hold 1 object (0.8) or 3 (0.6), 3:1;
     * large views hold 1 (0.7), 3 (0.5) or 8 (0.2), 1:1:2. Large's plain mean is
     * 0.4; weighted as medium's views: 0.75 * 0.7 + 0.25 * 0.5 = 0.65. */
    CHECK_OK(sooc_eval_table_create(&t));
    struct { int scale, nobj, n; double miou; } vs[] = {
        {SOOC_SCALE_M, 1, 3, 0.8}, {SOOC_SCALE_M, 3, 1, 0.6},
        {SOOC_SCALE_L, 1, 1, 0.7}, {SOOC_SCALE_L, 3, 1, 0.5}, {SOOC_SCALE_L, 8, 2, 0.2}};
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < vs[i].n; k++) {
            sooc_view_metrics vm;
            memset(&vm, 0, sizeof vm);
            vm.is_query = 1;
            vm.miou_best = vm.miou_hung = vs[i].miou;
            vm.rgb_rmse = vm.depth_rmse = 0.1;
            vm.n_obj_visible = vs[i].nobj;
            CHECK_OK(sooc_eval_table_add_view(t, "ours", vs[i].scale, 0, &vm));
        }
    CHECK_OK(sooc_eval_table_cell(t, "ours", SOOC_SCALE_L, 1, &c));
    CHECK_CLOSE(c.miou_best.mean, 0.4, 1e-12, 0);
    CHECK(c.n_by_nobj[1] == 1 && c.n_by_nobj[3] == 1 && c.n_by_nobj[SOOC_METRIC_N_OBINS - 1] == 2 && c.n_by_nobj[0] == 0);
    CHECK(isnan(c.miou_by_nobj[0]));
    CHECK_CLOSE(c.miou_by_nobj[SOOC_METRIC_N_OBINS - 1], 0.2, 1e-12, 0);
    double mm = 0, cov = 0;
    CHECK_OK(sooc_eval_table_miou_matched(t, "ours", SOOC_SCALE_L, 1, SOOC_SCALE_M, &mm, &cov));
    CHECK_CLOSE(mm, 0.65, 1e-12, 0);
    CHECK_CLOSE(cov, 1.0, 1e-12, 0);
    CHECK_OK(sooc_eval_table_miou_matched(t, "ours", SOOC_SCALE_M, 1, SOOC_SCALE_M, &mm, &cov));
    CHECK_CLOSE(mm, 0.75, 1e-12, 0);   /* a scale matched to itself is its plain mean */
    /* no small-scene views, and no input views at all: nothing to match */
    CHECK(sooc_eval_table_miou_matched(t, "ours", SOOC_SCALE_S, 1, SOOC_SCALE_M, &mm, &cov) == SOOC_ENOTFOUND);
    CHECK(sooc_eval_table_miou_matched(t, "ours", SOOC_SCALE_L, 0, SOOC_SCALE_M, &mm, &cov) == SOOC_ENOTFOUND);
    CHECK_OK(sooc_eval_table_markdown(t, &md));
    if (md) CHECK(strstr(md, "| ours | Q | l | - | 0.700 (1) | - | 0.500 (1) |") && strstr(md, " 0.650 |"));
    CHECK_OK(sooc_eval_table_json(t, &js));
    if (js) CHECK(strstr(js, "\"miou_composition_matched_m\": 0.65") != NULL);
    sooc_free(md); sooc_free(js);
    sooc_eval_table_destroy(t);
}

static void check_png(const char *path, int min_w, int min_h) {
    int w = 0, h = 0;
    sooc_pixfmt fm;
    sooc_status s = sooc_png_info(path, &w, &h, &fm);
    CHECK_MSG(s == SOOC_OK && w >= min_w && h >= min_h, "%s: %s (%dx%d)", path, sooc_errmsg(), w, h);
}

int main(void) {
    char tmpl[] = "/tmp/sooc_eval_test_XXXXXX";
    const char *env = getenv("SOOC_EVAL_PICS");
    const char *dir = env && *env ? env : mkdtemp(tmpl);
    CHECK(dir != NULL);
    if (!dir) return check_report("test_eval");
    CHECK_OK(sooc_mkdirs(dir));
    test_table(dir);

    /* ---- end-to-end view evaluation ---- */
    sooc_intrinsics K;
    memset(&K, 0, sizeof K);
    K.width = 48; K.height = 36; K.fx = K.fy = 36; K.cx = 24; K.cy = 18;
    double T[16];
    sooc_se3_identity(T);
    sooc_render_box boxes[3] = {{0}};
    for (int k = 0; k < 2; k++) {
        double lo[3], hi[3];
        for (int a = 0; a < 3; a++) { lo[a] = g_sph[k].c[a] - g_sph[k].r - 0.3; hi[a] = g_sph[k].c[a] + g_sph[k].r + 0.3; }
        sooc_render_box_aabb(&boxes[k + 1], lo, hi);
    }
    sooc_field fld = {3, boxes, 1000.f, field_eval, NULL, NULL};
    sooc_frame gt;
    make_gt(&gt, &fld, &K, T);
    sooc_gt_object go[2] = {{11, -0.6, 3.0}, {12, 0.7, 4.0}};
    double pxz[6] = {NAN, NAN, -0.55, 3.1, 0.7, 4.0};
    sooc_render_opts o;
    sooc_render_opts_default(&o);
    o.jitter = 1; o.seed = 1234; o.components = 1;
    sooc_render_out r1, r2;
    memset(&r1, 0, sizeof r1);
    memset(&r2, 0, sizeof r2);
    sooc_view_metrics v1, v2;
    sooc_iou_match m1;
    g_jit = 0.0;
    CHECK_OK(sooc_eval_view(&fld, T, &gt, &o, pxz, go, 2, &r1, &v1, &m1));
    o.threads = 1;
    CHECK_OK(sooc_eval_view(&fld, T, &gt, &o, pxz, go, 2, &r2, &v2, NULL));
    CHECK(!memcmp(&v1, &v2, sizeof v1));   /* same seed: bit-identical metrics, any thread count */
    printf("self-eval: mIoU %.4f (Hungarian %.4f), RGB RMSE %.4f, depth RMSE %.4f m, L2 %.3f m, matched %d/%d\n",
           v1.miou_best, v1.miou_hung, v1.rgb_rmse, v1.depth_rmse, v1.n_obj_matched ? v1.l2_sum / v1.n_obj_matched : NAN,
           v1.n_obj_matched, v1.n_obj_visible);
    CHECK(v1.miou_best > 0.9 && v1.miou_hung > 0.9);
    CHECK(v1.rgb_rmse < 0.1 && v1.depth_rmse < 0.1);
    CHECK(v1.n_obj_visible == 2 && v1.n_obj_matched == 2);
    CHECK_CLOSE(v1.l2_sum, hypot(0.05, 0.1), 1e-9, 0);
    o.seed = 99;
    CHECK_OK(sooc_eval_view(&fld, T, &gt, &o, pxz, go, 2, &r2, &v2, NULL));
    CHECK(memcmp(r1.depth, r2.depth, sizeof(float) * 48 * 36) != 0);   /* a different seed moves samples */

    /* ---- uncertainty + panel ---- */
    {
        /* posterior samples through the sampler hook: sample m shifts the spheres by 4 cm * m */
        sooc_render_opts ou = o;
        ou.jitter = 0;
        sooc_field_sampler smp = {shift_get, NULL, &fld};
        CHECK_OK(sooc_render_uncertainty(&smp, 3, &K, T, &ou, &r1));
        g_jit = 0.0;
        int nz = 0;
        for (int p = 0; p < 48 * 36; p++) nz += r1.uncert[p] > 1e-3f;
        CHECK(nz > 5);
        CHECK_OK(sooc_render_view(&fld, &K, T, &ou, &r1));   /* keeps uncert, refreshes the rest */
        CHECK(r1.uncert != NULL);
        sooc_panel_opts po;
        sooc_panel_opts_default(&po);
        po.title = "test view";
        sooc_image pan = {0};
        CHECK_OK(sooc_eval_panel(&pan, &gt, &r1, &po));
        char path[1024];
        snprintf(path, sizeof path, "%s/panel.png", dir);
        CHECK_OK(sooc_png_write(path, &pan, -1));
        check_png(path, 7 * 48 * 2, 36 * 2);
        sooc_image_free(&pan);
    }

    /* ---- top-down cognitive map sequence ---- */
    {
        enum { NS = 6 };
        sooc_topdown_step steps[NS];
        sooc_map_entry ent[NS][4];
        memset(ent, 0, sizeof ent);
        for (int i = 0; i < NS; i++) {
            double yaw = 0.4 * i, R[9], c[9], t[3] = {0.5 * i, 1.2, 0.2 * i};
            /* camera looking along world direction (sin yaw, 0, cos yaw): columns right, down, fwd */
            double f[3] = {sin(yaw), 0, cos(yaw)}, d[3] = {0, -1, 0}, rt[3];
            sooc_v3_cross(rt, d, f);
            for (int a = 0; a < 3; a++) { c[3 * a] = rt[a]; c[3 * a + 1] = d[a]; c[3 * a + 2] = f[a]; }
            memcpy(R, c, sizeof R);
            sooc_se3_from_rt(steps[i].T_wc, R, t);
            int ne = i < 3 ? i + 1 : 4;
            for (int j = 0; j < ne; j++) {
                ent[i][j].id = (uint64_t)j + 1;
                ent[i][j].x = -1.0 + 1.5 * j; ent[i][j].z = 3.0 + 0.5 * j; ent[i][j].yaw = 0.3 * j;
                ent[i][j].presence = 0.9f;
                ent[i][j].extent[0] = 0.5f; ent[i][j].extent[1] = 0.6f; ent[i][j].extent[2] = 0.4f;
            }
            steps[i].entries = ent[i];
            steps[i].n_entries = (size_t)ne;
        }
        sooc_fig_gt fg[4] = {{1, -1.0, 3.1, 0, 0.5, 0.4}, {2, 0.5, 3.5, 0.3, 0.5, 0.4},
                             {3, 2.0, 4.0, 0.6, 0.5, 0.4}, {4, 3.5, 4.4, 0.9, 0.5, 0.4}};
        sooc_topdown_opts to;
        sooc_topdown_opts_default(&to);
        to.K = &K;
        to.title = "cogmap";
        char sub[1024], path[1100];
        snprintf(sub, sizeof sub, "%.900s/cogmap", dir);
        CHECK_OK(sooc_eval_topdown_sequence(sub, steps, NS, fg, 4, &to));
        snprintf(path, sizeof path, "%s/cogmap_%04d.png", sub, NS - 1);
        check_png(path, 100, 100);
        snprintf(path, sizeof path, "%s/cogmap_sheet.png", sub);
        check_png(path, 200, 100);
    }

    /* ---- training curves ---- */
    {
        char csv[1024], png[1024];
        snprintf(csv, sizeof csv, "%s/train.csv", dir);
        snprintf(png, sizeof png, "%s/curves.png", dir);
        FILE *fp = fopen(csv, "w");
        CHECK(fp != NULL);
        if (fp) {
            fprintf(fp, "step,loss,nll_rgb,kl,present_slots\n");
            for (int s = 0; s <= 200; s += 10)
                fprintf(fp, "%d,%g,%g,%g,%d\n", s, 1000.0 * exp(-s / 40.0) + 1, 0.5 - s * 0.001, 0.01 * s, s / 50);
            fclose(fp);
            CHECK_OK(sooc_eval_plot_csv(csv, png, "training"));
            check_png(png, 600, 300);
        }
        CHECK(sooc_eval_plot_csv("/nonexistent/x.csv", png, NULL) != SOOC_OK);
    }
    printf("pictures in %s\n", dir);
    sooc_render_out_free(&r1);
    sooc_render_out_free(&r2);
    sooc_frame_free(&gt);
    sooc_alloc_stats st;
    sooc_alloc_get_stats(&st);
    CHECK_MSG(st.live_bytes == 0, "leak: %llu bytes", (unsigned long long)st.live_bytes);
    return check_report("test_eval");
}
