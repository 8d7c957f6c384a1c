/* Core and geometry: errors, allocator fault injection, RNG determinism and
 * moments, CRC, atomic saves, rotations, SE(3), the G frame and floor poses. */
#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#include <string.h>
#include <unistd.h>

static void test_errors(void) {
    sooc_status s = sooc_seterr(SOOC_EINVAL, "file %s line %d", "a.yaml", 3);
    CHECK(s == SOOC_EINVAL);
    CHECK(strcmp(sooc_errmsg(), "file a.yaml line 3") == 0);
    sooc_adderr(s, "loading %s", "x");
    CHECK(strcmp(sooc_errmsg(), "loading x: file a.yaml line 3") == 0);
    CHECK(strcmp(sooc_status_str(SOOC_EFORMAT), "EFORMAT") == 0);
}

static void test_alloc(void) {
    sooc_alloc_stats a, b;
    sooc_alloc_get_stats(&a);
    void *p = sooc_malloc(1000);
    CHECK(p && ((uintptr_t)p % 64) == 0);
    sooc_free(p);
    sooc_alloc_get_stats(&b);
    CHECK(b.live_bytes == a.live_bytes);
    sooc_alloc_fault_inject(1, 1);
    void *p1 = sooc_malloc(8), *p2 = sooc_malloc(8), *p3 = sooc_malloc(8);
    CHECK(p1 && !p2 && p3);
    sooc_free(p1);
    sooc_free(p3);
    CHECK(sooc_calloc(SIZE_MAX / 2, 4) == NULL);
}

static void test_rng(void) {
    sooc_rng a, b, c;
    sooc_rng_seed(&a, 42, 0);
    sooc_rng_seed(&b, 42, 0);
    sooc_rng_seed(&c, 42, 1);
    int same = 1, diff = 0;
    for (int i = 0; i < 100; i++) {
        uint64_t x = sooc_rng_u64(&a), y = sooc_rng_u64(&b), z = sooc_rng_u64(&c);
        same &= x == y;
        diff += x != z;
    }
    CHECK(same);
    CHECK(diff == 100);
    /* moments */
    double m = 0, v = 0, lm = 0, lv = 0, um = 0;
    int n = 200000, below = 0;
    for (int i = 0; i < n; i++) {
        double g = sooc_rng_normal(&a), l = sooc_rng_logistic(&a), u = sooc_rng_uniform(&a);
        m += g; v += g * g; lm += l; lv += l * l; um += u;
        below += sooc_rng_below(&a, 10) < 3;
    }
    m /= n; v = v / n - m * m; lm /= n; lv = lv / n - lm * lm; um /= n;
    CHECK_CLOSE(m, 0, 0.01, 0);
    CHECK_CLOSE(v, 1, 0.02, 0);
    CHECK_CLOSE(lm, 0, 0.02, 0);
    CHECK_CLOSE(lv, M_PI * M_PI / 3, 0.06, 0);   /* logistic variance pi^2/3 */
    CHECK_CLOSE(um, 0.5, 0.005, 0);
    CHECK_CLOSE((double)below / n, 0.3, 0.005, 0);
}

static void test_files(void) {
    CHECK(sooc_crc32(0, "123456789", 9) == 0xCBF43926u); /* the standard check value */
    char dir[] = "/tmp/sooc_test_XXXXXX";
    CHECK(mkdtemp(dir) != NULL);
    char path[256];
    CHECK_OK(sooc_path_join(path, sizeof path, dir, "a/b/c"));
    CHECK_OK(sooc_mkdirs(path));
    CHECK_OK(sooc_path_join(path, sizeof path, dir, "f.bin"));
    CHECK_OK(sooc_file_write_atomic(path, "hello", 5));
    void *buf;
    size_t n;
    CHECK_OK(sooc_file_read_all(path, 100, &buf, &n));
    CHECK(n == 5 && memcmp(buf, "hello", 5) == 0);
    sooc_free(buf);
    CHECK(sooc_file_read_all(path, 2, &buf, &n) == SOOC_EFORMAT);
    /* an aborted save leaves the old file intact */
    sooc_afile f;
    CHECK_OK(sooc_afile_open(&f, path));
    CHECK_OK(sooc_afile_write(&f, "xx", 2));
    sooc_afile_abort(&f);
    CHECK_OK(sooc_file_read_all(path, 100, &buf, &n));
    CHECK(n == 5);
    sooc_free(buf);
    CHECK(sooc_file_read_all("/nonexistent/x", 10, &buf, &n) == SOOC_ENOTFOUND);
    CHECK(strstr(sooc_errmsg(), "/nonexistent/x") != NULL);
    /* the folder of a path */
    char pdir[64];
    sooc_path_parent("a/b/c.txt", pdir, sizeof pdir);
    CHECK(!strcmp(pdir, "a/b"));
    sooc_path_parent("c.txt", pdir, sizeof pdir);
    CHECK(!strcmp(pdir, "."));
    sooc_path_parent("/c.txt", pdir, sizeof pdir);
    CHECK(!strcmp(pdir, "/"));
    sooc_path_parent("a/b/", pdir, sizeof pdir);
    CHECK(!strcmp(pdir, "a"));
    /* a save into a folder that does not exist names the folder */
    CHECK(sooc_afile_open(&f, "/nonexistent/dir/x.bin") == SOOC_ENOTFOUND);
    CHECK(strstr(sooc_errmsg(), "/nonexistent/dir/x.bin: the folder /nonexistent/dir does not exist") != NULL);
}

static void test_geom(void) {
    double q[4] = {0.1, -0.3, 0.2, 0.9}, R[9], q2[4], R2[9];
    sooc_quat_to_m3(R, q);
    CHECK(sooc_m3_is_rotation(R, 1e-12, NULL));
    sooc_m3_to_quat(q2, R);
    sooc_quat_to_m3(R2, q2);
    for (int i = 0; i < 9; i++) CHECK_CLOSE(R[i], R2[i], 1e-12, 0);
    double bad[9] = {1, 0, 0, 0, 1.01, 0, 0, 0, 1}, err;
    CHECK(!sooc_m3_is_rotation(bad, 1e-4, &err) && err > 0.005);
    double T[16], Ti[16], I[16], t[3] = {1, 2, 3};
    sooc_se3_from_rt(T, R, t);
    sooc_se3_inverse(Ti, T);
    sooc_se3_mul(I, T, Ti);
    for (int i = 0; i < 16; i++) CHECK_CLOSE(I[i], (i % 5 == 0) ? 1 : 0, 1e-12, 0);
    /* G frame of a camera 1.5 m high, yawed 0.7 rad, pitched 30 deg down. */
    double Ry[9], Rx[9], Rc[9], Tc[16];
    sooc_m3_rot_y(Ry, 0.7);
    double p = -30 * M_PI / 180; /* camera looks down: optical z gets a -y world component */
    /* optical frame (x right, y down, z fwd) -> level body frame with y up: flip y and x */
    double flip[9] = {-1, 0, 0, 0, -1, 0, 0, 0, 1};
    double c = cos(-p), s = sin(-p); /* R_x(-p) makes forward (0, sin p, cos p) */
    double pitch[9] = {1, 0, 0, 0, c, -s, 0, s, c}; /* rotate about x */
    sooc_m3_mul(Rx, pitch, flip);
    sooc_m3_mul(Rc, Ry, Rx);
    double tc[3] = {2, 1.5, -1};
    sooc_se3_from_rt(Tc, Rc, tc);
    double Twg[16], h, pt, rl;
    CHECK_OK(sooc_gframe(Tc, Twg, &h, &pt, &rl));
    CHECK_CLOSE(h, 1.5, 1e-12, 0);
    CHECK_CLOSE(pt, p, 1e-9, 0);
    CHECK_CLOSE(rl, 0, 1e-9, 0);
    sooc_floor_frame ff;
    sooc_floor_frame_of(&ff, Twg);
    CHECK_CLOSE(ff.psi, 0.7, 1e-9, 0);
    /* floor poses round-trip, and agree with the 3-D transform */
    double w[3] = {4, 5, 2.5}, l[3], w2[3];
    sooc_floor_to_local(&ff, w, l);
    sooc_floor_to_world(&ff, l, w2);
    for (int i = 0; i < 3; i++) CHECK_CLOSE(w[i], w2[i], 1e-12, 0);
    double Tgw[16], pw[3] = {4, 0, 5}, pg[3];
    sooc_se3_inverse(Tgw, Twg);
    sooc_se3_apply(pg, Tgw, pw);
    CHECK_CLOSE(pg[0], l[0], 1e-12, 0);
    CHECK_CLOSE(pg[2], l[1], 1e-12, 0);
    CHECK_CLOSE(pg[1], -1.5, 1e-12, 0);
    CHECK_CLOSE(sooc_wrap_angle(3 * M_PI), M_PI, 1e-12, 0);
    /* camera ray and projection are inverse */
    sooc_intrinsics K = {64, 48, 50, 50, 32, 24, SOOC_DIST_NONE, {0}};
    double d[3], u, v;
    sooc_cam_ray(&K, 10, 20, d);
    CHECK(sooc_cam_project(&K, d, &u, &v));
    CHECK_CLOSE(u, 10.5, 1e-9, 0);
    CHECK_CLOSE(v, 20.5, 1e-9, 0);
    sooc_frame f = {0}, g = {0};
    CHECK_OK(sooc_frame_alloc(&f, 4, 3, 1));
    f.depth[5] = 2.5f;
    CHECK_OK(sooc_frame_copy(&g, &f));
    CHECK(g.depth[5] == 2.5f && g.instance != NULL);
    sooc_frame_free(&f);
    sooc_frame_free(&g);
}

int main(void) {
    test_errors();
    test_alloc();
    test_rng();
    test_files();
    test_geom();
    return check_report("test_core");
}
