/* OpenNI2 driver against Debian's DummyDevice (docs/drivers.md "openni2").
 * The parent sets up a private driver folder (libOpenNI2.so.0 plus
 * OpenNI2/Drivers/{libDummyDevice,libOniFile}.so.0) and re-runs this program
 * with LD_LIBRARY_PATH pointing at it; the child does the checks. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "drv_testutil.h"
#include "sooc3d/driver.h"

#ifndef SOOC_OPENNI2_LIBDIR
#define SOOC_OPENNI2_LIBDIR "/usr/lib/x86_64-linux-gnu"
#endif

static int copy_file(const char *src, const char *dst) {
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "cp '%s' '%s'", src, dst);
    return system(cmd);
}

static int child(void) {
    const char *priv = getenv("SOOC_ONI_PRIVDIR");
    /* the private copy must be the one loaded */
    FILE *m = fopen("/proc/self/maps", "r");
    int private_loaded = 0;
    char line[1024];
    while (m && fgets(line, sizeof line, m))
        if (strstr(line, "libOpenNI2.so") && priv && strstr(line, priv)) private_loaded = 1;
    if (m) fclose(m);
    CHECK_MSG(private_loaded, "libOpenNI2 not loaded from %s", priv ? priv : "?");

    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    sooc_sensor *s = NULL;
    /* any device: only Dummy/OniFile drivers, so none is found -> clear error */
    sooc_status st = sooc_sensor_open(&s, "openni2", &p);
    CHECK_MSG(st == SOOC_ENOTFOUND, "any-device open: %s %s", sooc_status_str(st), sooc_errmsg());
    CHECK(s == NULL);
    printf("  no device: %s\n", sooc_errmsg());
    p.uri = "/nonexistent/file.oni";
    CHECK(sooc_sensor_open(&s, "openni2", &p) != SOOC_OK);

    for (int round = 0; round < 2; round++) {
        p.uri = "Dummy";
        CHECK_OK(sooc_sensor_open(&s, "openni2", &p));
        if (!s) return check_report("test_openni2");
        sooc_sensor_info info;
        sooc_sensor_get_info(s, &info);
        CHECK_MSG(info.width == 320 && info.height == 240, "mode %dx%d", info.width, info.height);
        CHECK(info.has_intrinsics && info.K.fx > 0);
        CHECK(!info.depth_registered);   /* Dummy: registration NOT_IMPLEMENTED */
        CHECK_OK(sooc_sensor_start(s));
        sooc_frame f = {0};
        int n = 0, mono = 1, step33 = 1, row0_ok = 0;
        int64_t prev = 0, prev_idx = 0;
        double t0 = sooc_seconds();
        int want = round == 0 ? 20 : 5;
        while (n < want) {
            st = sooc_sensor_read(s, &f, 1000);
            CHECK_MSG(st == SOOC_OK, "read: %s %s", sooc_status_str(st), sooc_errmsg());
            if (st) break;
            CHECK(f.width == 320 && f.height == 240);
            if (n) {
                if (f.t_ns <= prev) mono = 0;
                /* timestamps = frameIndex x 33000 us */
                if (f.t_ns - prev != (f.index - prev_idx) * 33000000LL) step33 = 0;
            }
            if (f.valid[10] && f.depth[10] > 1.99f && f.depth[10] < 2.01f) row0_ok++;
            prev = f.t_ns;
            prev_idx = f.index;
            n++;
        }
        double dt = sooc_seconds() - t0;
        CHECK(mono);
        CHECK_MSG(step33, "timestamps are not frameIndex x 33 ms");
        CHECK_MSG(row0_ok == n, "row 0 depth 2.0 m in %d of %d frames", row0_ok, n);
        sooc_sensor_stats ss;
        sooc_sensor_get_stats(s, &ss);
        if (round == 0)
            printf("  Dummy: %d frames 320x240 in %.2f s (%.1f fps), depth_in %lld color_in %lld dropped %lld unpaired %lld, "
                   "f=%.1f\n",
                   n, dt, n / dt, (long long)ss.depth_in, (long long)ss.color_in, (long long)ss.dropped,
                   (long long)ss.unpaired, info.K.fx);
        double ts = sooc_seconds();
        CHECK_OK(sooc_sensor_stop(s));
        sooc_sensor_close(s);   /* must not crash (Dummy teardown delay) */
        if (round == 0) printf("  stop+close: %.0f ms\n", (sooc_seconds() - ts) * 1e3);
        sooc_frame_free(&f);
    }
    return check_report("test_openni2");
}

int main(int argc, char **argv) {
    (void)argc;
    if (getenv("SOOC_ONI_CHILD")) return child();
    char lib[1024], dummy[1024], onifile[1024];
    snprintf(lib, sizeof lib, "%s/libOpenNI2.so.0", SOOC_OPENNI2_LIBDIR);
    snprintf(dummy, sizeof dummy, "%s/OpenNI2/Drivers/libDummyDevice.so.0", SOOC_OPENNI2_LIBDIR);
    snprintf(onifile, sizeof onifile, "%s/OpenNI2/Drivers/libOniFile.so.0", SOOC_OPENNI2_LIBDIR);
    if (access(lib, R_OK) || access(dummy, R_OK)) {
        printf("SKIP: libOpenNI2.so.0 or its DummyDevice driver is not installed (%s)\n", SOOC_OPENNI2_LIBDIR);
        return SOOC_TEST_SKIP;
    }
    char dir[] = "/tmp/sooc_oni_XXXXXX";
    if (!mkdtemp(dir)) return 1;
    char drv[1100], dst[1200];
    snprintf(drv, sizeof drv, "%s/OpenNI2/Drivers", dir);
    snprintf(dst, sizeof dst, "mkdir -p '%s'", drv);
    int bad = system(dst) != 0;
    snprintf(dst, sizeof dst, "%s/libOpenNI2.so.0", dir);
    bad |= copy_file(lib, dst) != 0;
    snprintf(dst, sizeof dst, "%s/libDummyDevice.so.0", drv);
    bad |= copy_file(dummy, dst) != 0;
    snprintf(dst, sizeof dst, "%s/libOniFile.so.0", drv);
    if (access(onifile, R_OK) == 0) bad |= copy_file(onifile, dst) != 0;
    int rc = 1;
    if (!bad) {
        static char e1[1200], e2[1200];
        const char *old = getenv("LD_LIBRARY_PATH");
        snprintf(e1, sizeof e1, "LD_LIBRARY_PATH=%s%s%s", dir, old ? ":" : "", old ? old : "");
        snprintf(e2, sizeof e2, "SOOC_ONI_PRIVDIR=%s", dir);
        /* OpenNI2 and its drivers leak at shutdown (dlclose'd modules): not ours */
        const char *env[] = {e1, e2, "SOOC_ONI_CHILD=1", "LSAN_OPTIONS=detect_leaks=0", NULL};
        rc = tu_reexec(env, argv);
    } else {
        fprintf(stderr, "cannot set up the private OpenNI2 folder in %s\n", dir);
    }
    snprintf(dst, sizeof dst, "rm -rf '%s'", dir);
    if (system(dst)) { /* ignore */ }
    return rc;
}
