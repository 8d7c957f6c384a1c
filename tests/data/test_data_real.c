/* Reading the real recordings in ../shared/real (SOOC_SHARED_REAL); skipped
 * (exit 77) when the folder is absent. */
#include "util.h"
#include "sooc3d/image.h"
#include "sooc3d/seq.h"

#include <math.h>

/* Median |z_pred - z_meas| / z_meas when frame a's points are moved into
 * frame b: a multi-view check that the depth scale and poses agree. */
static double reproj_err(const sooc_frame *a, const sooc_frame *b) {
    static float errs[640 * 480];
    int n = 0;
    double Tba[16], Tbw[16];
    sooc_se3_inverse(Tbw, b->T_wc);
    sooc_se3_mul(Tba, Tbw, a->T_wc);
    for (int v = 0; v < a->height; v += 4)
        for (int u = 0; u < a->width; u += 4) {
            size_t i = (size_t)v * a->width + u;
            if (!a->valid[i]) continue;
            double pa[3] = {(u - a->K.cx) / a->K.fx * a->depth[i], (v - a->K.cy) / a->K.fy * a->depth[i], a->depth[i]}, pb[3];
            sooc_se3_apply(pb, Tba, pa);
            if (pb[2] <= 0.1) continue;
            int ub = (int)lround(b->K.fx * pb[0] / pb[2] + b->K.cx), vb = (int)lround(b->K.fy * pb[1] / pb[2] + b->K.cy);
            if (ub < 0 || vb < 0 || ub >= b->width || vb >= b->height) continue;
            size_t j = (size_t)vb * b->width + ub;
            if (!b->valid[j]) continue;
            errs[n++] = (float)(fabs(pb[2] - b->depth[j]) / b->depth[j]);
        }
    if (n < 50) return -1;
    /* median by partial selection */
    for (int k = 0; k <= n / 2; k++) {
        int m = k;
        for (int j = k + 1; j < n; j++) if (errs[j] < errs[m]) m = j;
        float t = errs[k]; errs[k] = errs[m]; errs[m] = t;
        if (k == n / 2) break;
    }
    return errs[n / 2];
}

static void read_all(const char *dir, const sooc_seq_open_params *p, int expect_n, double zmin, double zmax,
                     double max_reproj) {
    sooc_seq *s = NULL;
    sooc_frame f = {0}, f0 = {0};
    CHECK_OK(sooc_seq_open(&s, dir, p));
    if (!s) return;
    CHECK_MSG(sooc_seq_count(s) == expect_n, "%s: %lld frames, expected %d", dir, (long long)sooc_seq_count(s), expect_n);
    double sum = 0, worst = 0;
    int64_t nv = 0, ntot = 0;
    for (int64_t i = 0; i < sooc_seq_count(s); i++) {
        CHECK_OK(sooc_seq_read(s, i, &f));
        CHECK(f.width == 640 && f.height == 480 && f.has_pose);
        for (int k = 0; k < f.width * f.height; k++) {
            ntot++;
            if (f.valid[k]) { sum += f.depth[k]; nv++; }
        }
        if (i == 0) CHECK_OK(sooc_frame_copy(&f0, &f));
        else {
            double e = reproj_err(&f0, &f);
            if (e > worst) worst = e;
        }
    }
    double mean = nv ? sum / nv : 0;
    printf("%s: %lld frames, %.0f%% valid depth, mean depth %.3f m, worst median reprojection depth error %.1f%%\n",
           dir, (long long)sooc_seq_count(s), 100.0 * nv / (ntot ? ntot : 1), mean, 100 * worst);
    CHECK_MSG(mean > zmin && mean < zmax, "%s: mean depth %.3f m outside [%g, %g]", dir, mean, zmin, zmax);
    CHECK_MSG(worst < max_reproj, "%s: reprojection error %.3f", dir, worst);
    sooc_seq_close(s);
    sooc_frame_free(&f);
    sooc_frame_free(&f0);
}

int main(void) {
    const char *real = tu_real_dir();
    if (!real) {
        printf("test_data_real: SKIP: real data folder not found (set SOOC_SHARED_REAL or place ../shared/real)\n");
        return SOOC_TEST_SKIP;
    }
    char dir[1200], *tmp = tu_tmpdir("real"), cal[700];
    sooc_seq_open_params p;

    /* label-fusion (7-Scenes layout): depth is (raw >> 3) * 1e-4 m, measured
     * by multi-view consistency (docs/formats.md) */
    snprintf(dir, sizeof dir, "%s/label_fusion/data/labels", real);
    sooc_seq_open_params_default(&p);
    p.depth_scale = 1e-4;
    p.depth_shift = 3;
    read_all(dir, &p, 15, 0.2, 2.0, 0.05);

    /* slambook2 ch5: millimetres in big-endian 16-bit PGM; intrinsics from a calib file */
    snprintf(dir, sizeof dir, "%s/slambook2/ch5/rgbd", real);
    tu_write(tmp, "ch5.yaml", "%%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\n"
             "camera_matrix: {rows: 3, cols: 3, data: [518.0, 0, 325.5, 0, 519.0, 253.5, 0, 0, 1]}\ndepth_scale: 0.001\n");
    snprintf(cal, sizeof cal, "%s/ch5.yaml", tmp);
    sooc_seq_open_params_default(&p);
    p.calib_path = cal;
    read_all(dir, &p, 5, 0.5, 6.0, 0.08);

    /* slambook2 ch12 (ICL-NUIM): depth / 5000, fy = -480 */
    snprintf(dir, sizeof dir, "%s/slambook2/ch12/dense_RGBD/data", real);
    tu_write(tmp, "ch12.yaml", "%%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\n"
             "camera_matrix: {rows: 3, cols: 3, data: [481.2, 0, 319.5, 0, -480.0, 239.5, 0, 0, 1]}\ndepth_scale: 0.0002\n");
    snprintf(cal, sizeof cal, "%s/ch12.yaml", tmp);
    p.calib_path = cal;
    read_all(dir, &p, 5, 0.5, 6.0, 0.08);

    /* slambook2 ch7: two TUM fr2 frames as plain PNGs */
    sooc_image img = {0};
    snprintf(dir, sizeof dir, "%s/slambook2/ch7/1_depth.png", real);
    CHECK_OK(sooc_png_read(dir, &img));
    CHECK(img.fmt == SOOC_PIX_GRAY16 && img.width == 640);
    sooc_image_free(&img);
    tu_rm_rf(tmp);
    return check_report("test_data_real");
}
