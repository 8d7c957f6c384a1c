/* libfreenect driver: the test writes a fakenect dump (INDEX.txt + host-endian
 * PGM/PPM, docs/drivers.md) and re-runs itself under Debian's fakenect
 * (LD_LIBRARY_PATH=/usr/lib/x86_64-linux-gnu/fakenect FAKENECT_PATH=dir). The
 * child checks the 11-bit disparity -> metres conversion and the replay. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "drv_testutil.h"
#include "sooc3d/driver.h"

#define FAKENECT_DIR "/usr/lib/x86_64-linux-gnu/fakenect"
#define NF 5
#define FW 640
#define FH 480

/* raw disparity at a few probe pixels, frame i */
static uint16_t probe_raw(int k, int i) {
    static const uint16_t base[6] = {2047, 1083, 500, 800, 1084, 0};
    return k < 6 ? base[k] : (uint16_t)(600 + 40 * i);
}

static int write_dump(const char *dir) {
    char p[1200];
    snprintf(p, sizeof p, "%s/INDEX.txt", dir);
    FILE *idx = fopen(p, "w");
    if (!idx) return -1;
    uint16_t *d = malloc((size_t)FW * FH * 2);
    uint8_t *c = malloc((size_t)FW * FH * 3);
    for (int i = 0; i < NF; i++) {
        double now = 1700000000.0 + i * 0.033;
        for (int j = 0; j < FW * FH; j++) d[j] = probe_raw(6, i);
        for (int k = 0; k < 6; k++) d[k] = probe_raw(k, i);
        for (int j = 0; j < FW * FH; j++) { c[3 * j] = (uint8_t)(50 * i); c[3 * j + 1] = 7; c[3 * j + 2] = 9; }
        char name[128];
        snprintf(name, sizeof name, "d-%.6f-%u.pgm", now, 1000u * (unsigned)i);
        snprintf(p, sizeof p, "%s/%s", dir, name);
        FILE *f = fopen(p, "wb");
        if (!f) return -1;
        fprintf(f, "P5 %d %d 65535\n", FW, FH);
        fwrite(d, 2, (size_t)FW * FH, f);   /* host-endian, as fakenect-record writes */
        fclose(f);
        fprintf(idx, "%s\n", name);
        snprintf(name, sizeof name, "r-%.6f-%u.ppm", now + 0.001, 1000u * (unsigned)i + 10);
        snprintf(p, sizeof p, "%s/%s", dir, name);
        f = fopen(p, "wb");
        if (!f) return -1;
        fprintf(f, "P6 %d %d 255\n", FW, FH);
        fwrite(c, 3, (size_t)FW * FH, f);
        fclose(f);
        fprintf(idx, "%s\n", name);
    }
    free(d);
    free(c);
    fclose(idx);
    return 0;
}

static int child(void) {
    /* the conversion itself */
    CHECK(sooc_freenect_disparity_to_m(2047) == 0.0f);
    CHECK(sooc_freenect_disparity_to_m(1084) == 0.0f);
    CHECK_CLOSE(sooc_freenect_disparity_to_m(0), 1.0 / 3.3309495161, 1e-6, 0);
    CHECK_CLOSE(sooc_freenect_disparity_to_m(500), 1.0 / (3.3309495161 - 0.0030711016 * 500), 1e-6, 0);
    CHECK_CLOSE(sooc_freenect_disparity_to_m(800), 1.0 / (3.3309495161 - 0.0030711016 * 800), 1e-5, 1e-6);
    /* monotonic over the valid range */
    for (int r = 1; r < 1084; r++)
        if (!(sooc_freenect_disparity_to_m((uint16_t)r) > sooc_freenect_disparity_to_m((uint16_t)(r - 1)))) {
            CHECK_MSG(0, "not increasing at %d", r);
            break;
        }

    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    p.depth_max = 1000.0f;
    sooc_sensor *s = NULL;
    CHECK_OK(sooc_sensor_open(&s, "freenect", &p));
    if (!s) return check_report("test_freenect");
    sooc_sensor_info info;
    sooc_sensor_get_info(s, &info);
    CHECK(info.width == FW && info.height == FH && !info.depth_registered);
    printf("  opened: %s\n", info.device);
    sooc_frame f = {0};
    int n = 0;
    double t0 = sooc_seconds();
    sooc_status st;
    while ((st = sooc_sensor_read(s, &f, 2000)) == SOOC_OK) {
        CHECK(f.width == FW && f.height == FH);
        CHECK(f.valid[0] == 0 && f.depth[0] == 0);            /* 2047 = no data */
        CHECK(f.valid[4] == 0);                                /* 1084 invalid   */
        CHECK(f.valid[1] == 1); CHECK_CLOSE(f.depth[1], 202.164, 0.05, 0);  /* 1083: last valid raw */
        CHECK_CLOSE(f.depth[2], sooc_freenect_disparity_to_m(500), 1e-6, 0);
        CHECK_CLOSE(f.depth[2], 0.55698, 1e-4, 0);
        CHECK_CLOSE(f.depth[3], 1.14408, 1e-4, 0);
        CHECK_CLOSE(f.depth[5], 0.30021, 1e-4, 0);
        CHECK_CLOSE(f.depth[1000], sooc_freenect_disparity_to_m((uint16_t)(600 + 40 * n)), 1e-6, 0);
        CHECK(f.rgb[0] == 50 * n && f.rgb[1] == 7 && f.rgb[2] == 9);
        n++;
    }
    double dt = sooc_seconds() - t0;
    CHECK_MSG(st == SOOC_EEOF, "end: %s %s", sooc_status_str(st), sooc_errmsg());
    CHECK_MSG(n == NF, "%d of %d frames", n, NF);
    printf("  fakenect: %d frames 640x480 in %.3f s (%.1f fps); raw 500 -> %.4f m, 800 -> %.4f m\n", n, dt, n / dt,
           f.depth[2], f.depth[3]);
    sooc_sensor_close(s);
    sooc_frame_free(&f);
    return check_report("test_freenect");
}

int main(int argc, char **argv) {
    (void)argc;
    if (getenv("SOOC_FN_CHILD")) return child();
    char lib[300];
    snprintf(lib, sizeof lib, "%s/libfreenect.so.0.5", FAKENECT_DIR);
    if (access(lib, R_OK)) {
        printf("SKIP: Debian's fakenect (%s) is not installed (libfreenect-bin / libfreenect0.5)\n", lib);
        return SOOC_TEST_SKIP;
    }
    /* without a Kinect, the real library gives a clean error */
    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    sooc_sensor *s = NULL;
    sooc_status st = sooc_sensor_open(&s, "freenect", &p);
    CHECK_MSG(st == SOOC_ENOTFOUND || st == SOOC_EIO, "no-device open: %s %s", sooc_status_str(st), sooc_errmsg());
    CHECK(s == NULL);
    printf("  no Kinect: %s\n", sooc_errmsg());

    char dir[] = "/tmp/sooc_fakenect_XXXXXX";
    if (!mkdtemp(dir)) return 1;
    int rc = 1;
    if (write_dump(dir) == 0) {
        static char e1[600], e2[600];
        snprintf(e1, sizeof e1, "LD_LIBRARY_PATH=%s", FAKENECT_DIR);
        snprintf(e2, sizeof e2, "FAKENECT_PATH=%s", dir);
        const char *env[] = {e1, e2, "SOOC_FN_CHILD=1", NULL};
        rc = tu_reexec(env, argv);
    }
    char cmd[700];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd)) { /* ignore */ }
    if (check_report("test_freenect (parent)")) return 1;
    return rc;
}
