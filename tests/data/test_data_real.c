/* Reading the real recordings in ../shared/real (SOOC_SHARED_REAL); skipped
 * (exit 77) when the folder is absent. */
#include "util.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

static void read_all(const char *dir, const sooc_seq_open_params *p, int expect_n, double zmin, double zmax,
                     double max_reproj, int step) {
    sooc_seq *s = NULL;
    sooc_frame f = {0}, f0 = {0};
    CHECK_OK(sooc_seq_open(&s, dir, p));
    if (!s) return;
    CHECK_MSG(sooc_seq_count(s) == expect_n, "%s: %lld frames, expected %d", dir, (long long)sooc_seq_count(s), expect_n);
    double sum = 0, worst = 0;
    int64_t nv = 0, ntot = 0;
    for (int64_t i = 0; i < sooc_seq_count(s); i += step) {
        CHECK_OK(sooc_seq_read(s, i, &f));
        CHECK(f.width == 640 && f.height == 480 && f.has_pose);
        for (int k = 0; k < f.width * f.height; k++) {
            ntot++;
            if (f.valid[k]) { sum += f.depth[k]; nv++; }
        }
        if (i == 0) CHECK_OK(sooc_frame_copy(&f0, &f));
        else {
            double e = tu_reproj_err(&f0, &f);
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

/* label-fusion depth in metres: the range, the valid fraction, and the bin
 * bottom seen as a plane of plausible size (auto-detected format). */
static void test_label_fusion_depth(const char *real) {
    char dir[1200];
    snprintf(dir, sizeof dir, "%s/label_fusion/data/labels", real);
    sooc_seq *s = NULL;
    sooc_frame f = {0};
    CHECK_OK(sooc_seq_open(&s, dir, NULL));
    if (!s) return;
    CHECK(sooc_seq_get_format(s) == SOOC_SEQ_LABELFUSION);
    double sc;
    int sh, inv;
    sooc_seq_depth_decoding(s, &sc, &sh, &inv);
    CHECK(sc == 1e-4 && sh == 3 && inv == 0);
    CHECK_OK(sooc_seq_read(s, 0, &f));
    float zmax = 0;
    int nv = 0, near = 0;
    double sum = 0;
    for (int k = 0; k < f.width * f.height; k++)
        if (f.valid[k]) {
            nv++;
            sum += f.depth[k];
            near += f.depth[k] < 0.15f;
            if (f.depth[k] > zmax) zmax = f.depth[k];
        }
    double frac = (double)nv / (f.width * f.height), mean = nv ? sum / nv : 0;
    printf("label-fusion frame 0: %.0f%% valid, mean %.3f m, max %.3f m, %d valid pixels nearer than 0.15 m "
           "(fx %.1f)\n", 100 * frac, mean, zmax, near, f.K.fx);
    /* an arm camera looking into a shelf bin: mean about half a metre, at most
     * 0.82 m (8191 x 1e-4 is the largest value the encoding holds). About 1 in
     * 7 valid pixels decode to 0.09-0.15 m, below the sensor's range and
     * inconsistent with the other views (docs/formats.md): bounded here so a
     * change of decoding shows */
    CHECK_MSG(mean > 0.3 && mean < 0.7 && zmax < 0.82 && frac > 0.15 && frac < 0.6 && near < nv / 5,
              "mean %.3f max %.3f, %.2f valid, %d near", mean, zmax, frac, near);
    sooc_seq_close(s);
    sooc_frame_free(&f);
}

/* 7-Scenes: frame 0's JPEG, depth in metres, the gravity file, and a
 * trimmed copy (symlinks) that starts at 10 and has a gap. */
static void test_7scenes(const char *real, const char *tmp) {
    char dir[1200];
    snprintf(dir, sizeof dir, "%s/7scenes_redkitchen", real);
    sooc_seq *s = NULL;
    sooc_frame f = {0}, g = {0};
    CHECK_OK(sooc_seq_open(&s, dir, NULL));
    if (!s) return;
    CHECK(sooc_seq_get_format(s) == SOOC_SEQ_7SCENES && sooc_seq_count(s) == 300);
    CHECK(sooc_seq_frame_number(s, 0) == 0 && sooc_seq_frame_number(s, 299) == 598);
    CHECK(sooc_seq_calib(s)->K.fx == 585 && sooc_seq_calib(s)->K.cx == 320);
    double gr[3];
    CHECK(sooc_seq_gravity(s, gr) == 1);
    CHECK_CLOSE(gr[0] * gr[0] + gr[1] * gr[1] + gr[2] * gr[2], 1, 1e-9, 0);
    CHECK_CLOSE(gr[1], 0.904, 2e-3, 0);
    CHECK_OK(sooc_seq_read(s, 0, &f));
    CHECK(f.width == 640 && f.height == 480 && f.index == 0 && f.has_pose);
    int nv = 0, n65535 = 0;
    double sum = 0, rgbsum = 0;
    for (int k = 0; k < 640 * 480; k++) {
        if (f.valid[k]) { nv++; sum += f.depth[k]; }
        rgbsum += f.rgb[3 * k] + f.rgb[3 * k + 1] + f.rgb[3 * k + 2];
    }
    (void)n65535;
    double frac = nv / (640.0 * 480.0), mean = nv ? sum / nv : 0;
    printf("7-Scenes frame 0 (JPEG): %dx%d, mean colour %.1f, %.0f%% valid depth, mean %.3f m\n", f.width, f.height,
           rgbsum / (640.0 * 480 * 3), 100 * frac, mean);
    CHECK_MSG(frac > 0.5 && mean > 0.5 && mean < 4.0, "7-Scenes depth: %.2f valid, mean %.3f m", frac, mean);
    CHECK(rgbsum / (640.0 * 480 * 3) > 20 && rgbsum / (640.0 * 480 * 3) < 235);
    /* frames 0, 2, 4 (every 2nd stored) agree through the poses */
    CHECK_OK(sooc_seq_read(s, 2, &g));
    double e = tu_reproj_err(&f, &g);
    printf("7-Scenes frames 0 -> 4: median reprojection depth error %.1f%%\n", 100 * e);
    CHECK_MSG(e >= 0 && e < 0.05, "reprojection %.3f", e);
    sooc_seq_close(s);
    s = NULL;
    read_all(dir, NULL, 300, 0.5, 4.0, 0.10, 25);

    /* a trimmed, subsampled copy: frames 10, 12, 14, then 40, 42 (symlinks) */
    char cp[1200], src[5600], dst[1400], abs_dir[4096];
    if (!realpath(dir, abs_dir)) snprintf(abs_dir, sizeof abs_dir, "%s", dir);
    snprintf(cp, sizeof cp, "%s/7s_trim", tmp);
    mkdir(cp, 0755);
    static const int keep[] = {10, 12, 14, 40, 42};
    static const char *ext[] = {"color.jpg", "depth.png", "pose.txt"};
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 3; k++) {
            snprintf(src, sizeof src, "%s/frame-%06d.%s", abs_dir, keep[i], ext[k]);
            snprintf(dst, sizeof dst, "%s/frame-%06d.%s", cp, keep[i], ext[k]);
            CHECK(symlink(src, dst) == 0);
        }
    snprintf(src, sizeof src, "%s/camera-intrinsics.txt", abs_dir);
    snprintf(dst, sizeof dst, "%s/camera-intrinsics.txt", cp);
    CHECK(symlink(src, dst) == 0);
    CHECK_OK(sooc_seq_open(&s, cp, NULL));
    sooc_seq *full = NULL;
    CHECK_OK(sooc_seq_open(&full, dir, NULL));
    if (s && full) {
        CHECK(sooc_seq_count(s) == 5 && sooc_seq_gravity(s, gr) == 0);
        for (int i = 0; i < 5; i++) {
            CHECK_OK(sooc_seq_read(s, i, &f));
            CHECK_MSG(f.index == keep[i] && f.t_ns == keep[i] * 33333333LL, "trimmed frame %d: index %lld", i,
                      (long long)f.index);
            CHECK_OK(sooc_seq_read(full, keep[i] / 2, &g));
            CHECK(g.index == keep[i]);
            CHECK(!memcmp(f.depth, g.depth, sizeof(float) * 640 * 480) && !memcmp(f.rgb, g.rgb, 640 * 480 * 3));
            CHECK(!memcmp(f.T_wc, g.T_wc, sizeof f.T_wc));
        }
    }
    sooc_seq_close(s);
    sooc_seq_close(full);
    sooc_frame_free(&f);
    sooc_frame_free(&g);
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
     * by multi-view consistency (docs/formats.md); the format's default, and
     * what auto picks (depth samples are multiples of 8) */
    snprintf(dir, sizeof dir, "%s/label_fusion/data/labels", real);
    sooc_seq_open_params_default(&p);
    p.depth_scale = 1e-4;
    p.depth_shift = 3;
    read_all(dir, &p, 15, 0.2, 2.0, 0.05, 1);
    sooc_seq_open_params_default(&p);
    read_all(dir, &p, 15, 0.3, 0.7, 0.03, 1);              /* auto */
    CHECK_OK(sooc_seq_format_parse("label-fusion", &p.format));
    read_all(dir, &p, 15, 0.3, 0.7, 0.03, 1);
    /* the masks set has worse poses (mean over all pairs 3.6% at 1e-4, still
     * the minimum of a 0.5e-4..2e-4 scan; worst pair from frame 0: 15.6%) */
    snprintf(dir, sizeof dir, "%s/label_fusion/data/masks", real);
    sooc_seq_open_params_default(&p);
    read_all(dir, &p, 15, 0.3, 0.8, 0.2, 1);
    test_label_fusion_depth(real);

    /* 7-Scenes redkitchen as shipped: JPEG colour, camera-intrinsics.txt,
     * millimetres with 65535 invalid, every 2nd frame (numbers 0..598) */
    test_7scenes(real, tmp);

    /* slambook2 ch5: millimetres in big-endian 16-bit PGM; intrinsics from a calib file */
    snprintf(dir, sizeof dir, "%s/slambook2/ch5/rgbd", real);
    tu_write(tmp, "ch5.yaml", "%%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\n"
             "camera_matrix: {rows: 3, cols: 3, data: [518.0, 0, 325.5, 0, 519.0, 253.5, 0, 0, 1]}\ndepth_scale: 0.001\n");
    snprintf(cal, sizeof cal, "%s/ch5.yaml", tmp);
    sooc_seq_open_params_default(&p);
    p.calib_path = cal;
    read_all(dir, &p, 5, 0.5, 6.0, 0.08, 1);

    /* slambook2 ch12 (ICL-NUIM): depth / 5000, fy = -480 */
    snprintf(dir, sizeof dir, "%s/slambook2/ch12/dense_RGBD/data", real);
    tu_write(tmp, "ch12.yaml", "%%YAML 1.2\n---\nimage_width: 640\nimage_height: 480\n"
             "camera_matrix: {rows: 3, cols: 3, data: [481.2, 0, 319.5, 0, -480.0, 239.5, 0, 0, 1]}\ndepth_scale: 0.0002\n");
    snprintf(cal, sizeof cal, "%s/ch12.yaml", tmp);
    p.calib_path = cal;
    read_all(dir, &p, 5, 0.5, 6.0, 0.08, 1);

    /* slambook2 ch7: two TUM fr2 frames as plain PNGs */
    sooc_image img = {0};
    snprintf(dir, sizeof dir, "%s/slambook2/ch7/1_depth.png", real);
    CHECK_OK(sooc_png_read(dir, &img));
    CHECK(img.fmt == SOOC_PIX_GRAY16 && img.width == 640);
    sooc_image_free(&img);
    tu_rm_rf(tmp);
    return check_report("test_data_real");
}
