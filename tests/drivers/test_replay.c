/* Replay driver on a TUM sequence written by the test: as fast as possible,
 * recorded speed (and 2x), loop with increasing stamps, start/stop, timeout,
 * interrupt, pose from groundtruth, error paths, parameter parsing. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "drv_testutil.h"
#include "sooc3d/driver.h"

#define N 10
#define W 64
#define H 48
#define T0 1305031102.0
#define PER 0.04

static sooc_sensor *open_replay(const char *dir, double speed, int loop, double start, double stop) {
    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    p.uri = dir;
    p.speed = speed;
    p.loop = loop;
    p.start_s = start;
    p.stop_s = stop;
    sooc_sensor *s = NULL;
    CHECK_OK(sooc_sensor_open(&s, "replay", &p));
    return s;
}

static void test_fast(const char *dir) {
    sooc_sensor *s = open_replay(dir, 0.0, 0, 0, -1);
    if (!s) return;
    sooc_sensor_info info;
    sooc_sensor_get_info(s, &info);
    CHECK(info.width == W && info.height == H && info.n_frames == N && info.has_pose);
    CHECK_MSG(info.fps == 25, "fps %d", info.fps);
    CHECK_OK(sooc_sensor_start(s));
    sooc_frame f = {0};
    int n = 0;
    int64_t prev = 0;
    double t0 = sooc_seconds();
    sooc_status st;
    while ((st = sooc_sensor_read(s, &f, 1000)) == SOOC_OK) {
        CHECK(f.width == W && f.height == H);
        CHECK_CLOSE(f.depth[W + 1], 1.0 + 0.1 * n, 1e-3, 0);
        CHECK(f.valid[0] == 0 && f.depth[0] == 0 && f.valid[1] == 1);
        CHECK(f.rgb[0] == 10 * n && f.rgb[3 * 5 + 1] == 5);
        CHECK(f.index == n);
        CHECK(f.has_pose);
        CHECK_CLOSE(f.T_wc[3], n * PER, 1e-5, 0);
        CHECK(f.K.fx > 0 || !info.has_intrinsics);
        int64_t want = (int64_t)llround((T0 + n * PER) * 1e9);
        CHECK_MSG(llabs(f.t_ns - want) < 1000, "t_ns %lld want %lld", (long long)f.t_ns, (long long)want);
        if (n) CHECK(f.t_ns > prev);
        prev = f.t_ns;
        n++;
    }
    double dt = sooc_seconds() - t0;
    CHECK_MSG(st == SOOC_EEOF, "end status %s: %s", sooc_status_str(st), sooc_errmsg());
    CHECK(n == N);
    sooc_sensor_stats ss;
    sooc_sensor_get_stats(s, &ss);
    CHECK(ss.frames == N);
    printf("  replay speed 0: %d frames %dx%d in %.1f ms (%.0f fps)\n", n, W, H, dt * 1e3, n / dt);
    sooc_sensor_close(s);
    sooc_frame_free(&f);
}

static void test_speed(const char *dir, double speed) {
    sooc_sensor *s = open_replay(dir, speed, 0, 0, -1);
    if (!s) return;
    sooc_frame f = {0};
    double t0 = sooc_seconds();
    int n = 0;
    while (sooc_sensor_read(s, &f, 500) == SOOC_OK) n++;
    double dt = sooc_seconds() - t0;
    double want = (N - 1) * PER / speed;
    CHECK(n == N);
    /* paced replay never runs ahead of the recording's clock (a lower bound: a loaded machine only makes
     * it later, so this cannot fail for want of CPU); how late it may run is not a test's business */
    CHECK_MSG(dt > want * 0.95, "speed %.1f: %.3f s for %d frames, the recording's span at that speed is %.3f s",
              speed, dt, n, want);
    printf("  replay speed %.1f: %d frames in %.3f s (recorded span %.3f s)\n", speed, n, dt, (N - 1) * PER);
    sooc_sensor_close(s);
    sooc_frame_free(&f);
}

static void test_loop_and_window(const char *dir) {
    sooc_sensor *s = open_replay(dir, 0.0, 1, 0, -1);
    if (!s) return;
    sooc_frame f = {0};
    int64_t prev = 0;
    for (int i = 0; i < 25; i++) {
        CHECK_OK(sooc_sensor_read(s, &f, 100));
        CHECK(f.rgb[0] == 10 * (i % N));
        CHECK(f.index == i);
        if (i) CHECK_MSG(f.t_ns - prev > 0 && llabs(f.t_ns - prev - 40000000) < 1000, "loop step %lld ns",
                         (long long)(f.t_ns - prev));
        prev = f.t_ns;
    }
    sooc_sensor_close(s);

    /* start 0.1 s, stop 0.2 s: frames at 0.12, 0.16, 0.20 -> 3, 4, 5 */
    s = open_replay(dir, 0.0, 0, 0.1, 0.2);
    if (!s) return;
    sooc_sensor_info info;
    sooc_sensor_get_info(s, &info);
    CHECK(info.n_frames == 3);
    int got[8], n = 0;
    while (n < 8 && sooc_sensor_read(s, &f, 100) == SOOC_OK) got[n++] = f.rgb[0] / 10;
    CHECK_MSG(n == 3 && got[0] == 3 && got[2] == 5, "window frames: n=%d first=%d", n, n ? got[0] : -1);
    sooc_sensor_close(s);

    /* loop within the window */
    s = open_replay(dir, 0.0, 1, 0.1, 0.2);
    if (!s) return;
    for (int i = 0; i < 7; i++) {
        CHECK_OK(sooc_sensor_read(s, &f, 100));
        CHECK(f.rgb[0] / 10 == 3 + i % 3);
    }
    sooc_sensor_close(s);

    /* empty window */
    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    p.uri = dir;
    p.start_s = 5;
    CHECK(sooc_sensor_open(&s, "replay", &p) == SOOC_EINVAL);

    /* timeout at recorded speed, then interrupt */
    s = open_replay(dir, 1.0, 0, 0, -1);
    if (!s) return;
    CHECK_OK(sooc_sensor_read(s, &f, 100));            /* frame 0 is due at once */
    CHECK(sooc_sensor_read(s, &f, 5) == SOOC_ETIMEOUT);  /* frame 1 is due after 40 ms */
    CHECK_OK(sooc_sensor_read(s, &f, 200));
    sooc_sensor_interrupt(s);
    CHECK(sooc_sensor_read(s, &f, 200) == SOOC_EINTERRUPTED);
    sooc_sensor_close(s);
    sooc_frame_free(&f);
}

static void test_errors(void) {
    sooc_sensor *s = (sooc_sensor *)1;
    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    p.uri = "/nonexistent/sequence";
    CHECK(sooc_sensor_open(&s, "replay", &p) == SOOC_ENOTFOUND);
    CHECK(s == NULL);
    CHECK(strstr(sooc_errmsg(), "/nonexistent/sequence") != NULL);
    CHECK(sooc_sensor_open(&s, "kinect9000", &p) == SOOC_EINVAL);
    CHECK(sooc_sensor_params_set(&p, "speed", "fast") == SOOC_EINVAL);
    CHECK(strstr(sooc_errmsg(), "speed") != NULL);
    CHECK(sooc_sensor_params_set(&p, "colour", "x") == SOOC_EINVAL);
    CHECK(strstr(sooc_errmsg(), "colour") != NULL);
    CHECK_OK(sooc_sensor_params_set(&p, "speed", "0.5"));
    CHECK_OK(sooc_sensor_params_set(&p, "loop", "true"));
    CHECK_OK(sooc_sensor_params_set(&p, "stop", "12.5"));
    CHECK_OK(sooc_sensor_params_set(&p, "timebase", "realtime"));
    CHECK(p.speed == 0.5 && p.loop == 1 && p.stop_s == 12.5 && p.timebase == SOOC_TIMEBASE_REALTIME);
    const char *const *names = sooc_sensor_list_drivers();
    CHECK(names[0] && !strcmp(names[0], "replay"));
    printf("  compiled-in drivers:");
    for (; *names; names++) printf(" %s", *names);
    printf("\n");
}

int main(void) {
    char dir[] = "/tmp/sooc_replay_XXXXXX";
    if (!mkdtemp(dir)) return 1;
    char seq[600];
    snprintf(seq, sizeof seq, "%s/rgbd_dataset_test", dir);
    if (tu_write_tum(seq, N, W, H, T0, PER)) {
        fprintf(stderr, "cannot write the test sequence\n");
        return 1;
    }
    test_errors();
    test_fast(seq);
    test_speed(seq, 1.0);
    test_speed(seq, 2.0);
    test_loop_and_window(seq);
    char cmd[700];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd)) { /* ignore */ }
    return check_report("test_replay");
}
