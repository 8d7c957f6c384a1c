/* Real frames through an MCAP file written outside the project (docs/logs.md
 * "Round trips"): the 10 YCB-Video frames of ../shared/real/ycb_video/data/0000
 * written as a ROS 2 MCAP file by the reference MCAP library, @mcap/core
 * (tests/logs/npm/write_mcap.mjs decodes the PNGs and meta.mat and serialises
 * CDR itself: rgb8 and 32FC1 sensor_msgs/Image, CameraInfo, /tf and
 * /tf_static as tf2_msgs/TFMessage), read through the frame path and mapped
 * by `sooc3d infer` next to the same frames read from their folder: the same
 * pixels and depth, poses within 1e-12, and the maps hold the same objects
 * (count, positions within 1 cm). The folder is the one write_mcap.mjs writes
 * beside the log (links to the PNGs, calib.yaml, the rotation the log's
 * quaternion stands for: YCB-Video's recorded rotations are orthonormal only
 * to about 1e-6); the map of the original YCB-Video folder is printed beside
 * them. Skips (77) with the reason when node, @mcap/core (npm ci in
 * tests/logs/npm, scripts/install-deps.sh), the real recordings or the sooc3d
 * binary are missing. */
#include "logs_util.h"
#include "sooc3d/frame.h"

#include <math.h>
#include <sys/wait.h>

static const char *g_model = "models/sooc3d_tabletop/model.bin";

static void same_frames(const char *a, const char *b, int64_t n) {
    sooc_framepath_params p;
    sooc_framepath_params_default(&p);
    p.world = SOOC_WORLD_IDENTITY;
    sooc_framepath *fa = NULL, *fb = NULL;
    CHECK_OK(sooc_framepath_open(&fa, a, &p));
    CHECK_OK(sooc_framepath_open(&fb, b, &p));
    if (!fa || !fb) goto done;
    CHECK_MSG(sooc_framepath_count(fa) == n && sooc_framepath_count(fb) == n, "%lld / %lld frames, expected %lld",
              (long long)sooc_framepath_count(fa), (long long)sooc_framepath_count(fb), (long long)n);
    sooc_frame x = {0}, y = {0};
    int64_t bad_px = 0, bad_valid = 0;
    double dT = 0, dz = 0, dK = 0;
    for (int64_t i = 0; i < n && i < sooc_framepath_count(fb); i++) {
        CHECK_OK(sooc_framepath_read_raw(fa, i, &x));
        CHECK_OK(sooc_framepath_read_raw(fb, i, &y));
        CHECK(x.width == y.width && x.height == y.height && x.has_pose && y.has_pose);
        if (x.width != y.width || x.height != y.height) break;
        CHECK_MSG(x.t_ns == y.t_ns, "frame %lld: stamps %lld and %lld", (long long)i, (long long)x.t_ns,
                  (long long)y.t_ns);
        dK = fmax(dK, fmax(fmax(fabs(x.K.fx - y.K.fx), fabs(x.K.fy - y.K.fy)), fmax(fabs(x.K.cx - y.K.cx),
                                                                                  fabs(x.K.cy - y.K.cy))));
        size_t np = (size_t)x.width * (size_t)x.height;
        bad_px += memcmp(x.rgb, y.rgb, np * 3) != 0;
        for (size_t k = 0; k < np; k++) {
            bad_valid += x.valid[k] != y.valid[k];
            if (x.valid[k] && y.valid[k]) dz = fmax(dz, fabs((double)x.depth[k] - (double)y.depth[k]));
        }
        for (int k = 0; k < 16; k++) dT = fmax(dT, fabs(x.T_wc[k] - y.T_wc[k]));
    }
    CHECK_MSG(bad_px == 0 && bad_valid == 0 && dz == 0 && dT < 1e-12 && dK == 0,
              "%s vs %s: %lld colour images differ, %lld validity flags, depth by %.3g m, poses by %.3g, K by %.3g",
              a, b, (long long)bad_px, (long long)bad_valid, dz, dT, dK);
    printf("  %s = %s: %lld frames, colour identical, depth within %.2g m, poses within %.2g\n", b, a, (long long)n,
           dz, dT);
    sooc_frame_free(&x);
    sooc_frame_free(&y);
done:
    sooc_framepath_close(fa);
    sooc_framepath_close(fb);
}

/* `sooc3d infer` on both, the maps compared; with strict 0 only printed. */
static void same_maps(const char *bin, const char *a, const char *b, const char *tmp, const char *tag,
                      const char *label, int strict) {
    char oa[700], ob[700];
    snprintf(oa, sizeof oa, "%s/map_%s_folder", tmp, tag);
    snprintf(ob, sizeof ob, "%s/map_mcap", tmp);
    int na, nb;
    double worst;
    lu_infer_maps(bin, g_model, a, oa, b, ob, 1, &na, &nb, &worst);
    if (strict) {
        CHECK_MSG(na > 0 && na == nb, "%s: %d objects from the folder, %d from the log", label, na, nb);
        CHECK_MSG(worst <= 0.01, "%s: an object moved %.4f m", label, worst);
    }
    printf("  %s: infer maps %d objects from the folder and %d from the log, largest offset %.2g m\n", label, na, nb,
           worst);
}

int main(void) {
    const char *real = getenv("SOOC_SHARED_REAL"), *bin = getenv("SOOC_BIN"), *node = getenv("SOOC_NODE");
    const char *srcdir = getenv("SOOC_SRC") ? getenv("SOOC_SRC") : ".";
    char ycb[1024];
    snprintf(ycb, sizeof ycb, "%s/ycb_video/data/0000", real ? real : "../shared/real");
    if (!sooc_dir_exists(ycb)) {
        printf("test_logs_npm: SKIP: the real recordings are not at %s (SOOC_SHARED_REAL)\n", ycb);
        return SOOC_TEST_SKIP;
    }
    if (!node || !*node || !sooc_file_exists(node)) {
        printf("test_logs_npm: SKIP: no node (Node.js) to run tests/logs/npm/write_mcap.mjs\n");
        return SOOC_TEST_SKIP;
    }
    if (!bin || !sooc_file_exists(bin) || !sooc_file_exists(g_model)) {
        printf("test_logs_npm: SKIP: no sooc3d binary (SOOC_BIN) or no %s\n", g_model);
        return SOOC_TEST_SKIP;
    }
    char *tmp = lu_tmpdir("logs_npm");
    char cmd[4096], mcap[700], folder[700];
    snprintf(mcap, sizeof mcap, "%s/ycb0000.mcap", tmp);
    snprintf(folder, sizeof folder, "%s/ycb0000", tmp);
    snprintf(cmd, sizeof cmd, "'%s' '%s/tests/logs/npm/write_mcap.mjs' '%s' '%s' --folder '%s'", node, srcdir, ycb,
             mcap, folder);
    int rc = system(cmd);
    if (WIFEXITED(rc) && WEXITSTATUS(rc) == 77) {
        printf("test_logs_npm: SKIP: @mcap/core is not installed (bash scripts/install-deps.sh runs npm ci in "
               "tests/logs/npm)\n");
        return SOOC_TEST_SKIP;
    }
    CHECK_MSG(rc == 0, "%s failed (%d)", cmd, rc);
    if (rc == 0) {
        same_frames(folder, mcap, 10);
        same_maps(bin, folder, mcap, tmp, "links", "YCB-Video 0000 MCAP (@mcap/core, CDR, /tf)", 1);
        same_maps(bin, ycb, mcap, tmp, "ycb", "the same MCAP against the original YCB-Video folder (not asserted)", 0);
    }
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (!g_check_fail && system(cmd) != 0) printf("could not remove %s\n", tmp);
    return check_report("test_logs_npm");
}
