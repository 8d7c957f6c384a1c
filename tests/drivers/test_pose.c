/* Pose sources: wire format, socket stream (UNIX + UDP loopback) with gaps,
 * out-of-order and duplicate packets, SLERP interpolation against analytic
 * poses, skip counting, hand-eye for end-effector poses, text form, TUM file. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#define T0 1700000000000000000LL   /* ns, CLOCK_REALTIME-like */
#define DT 10000000LL              /* 100 Hz */

/* Analytic trajectory: rotation about a fixed axis at 0.5 rad/s, linear motion. */
static void analytic(int64_t t_ns, double tr[3], double q[4]) {
    double s = (double)(t_ns - T0) * 1e-9;
    double axis[3] = {0.3, 0.8, -0.2};
    sooc_v3_normalize(axis);
    double a = 0.2 + 0.5 * s;
    q[0] = axis[0] * sin(a / 2);
    q[1] = axis[1] * sin(a / 2);
    q[2] = axis[2] * sin(a / 2);
    q[3] = cos(a / 2);
    tr[0] = 1.0 + 0.3 * s;
    tr[1] = 1.5 - 0.1 * s;
    tr[2] = -2.0 + 0.2 * s;
}

static void analytic_T(int64_t t_ns, double T[16]) {
    double tr[3], q[4], R[9];
    analytic(t_ns, tr, q);
    sooc_quat_to_m3(R, q);
    sooc_se3_from_rt(T, R, tr);
}

static double max_abs_diff(const double *a, const double *b, int n) {
    double m = 0;
    for (int i = 0; i < n; i++) m = fmax(m, fabs(a[i] - b[i]));
    return m;
}

static void sleep_ms(int ms) {
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* Wait until the source holds `want` received poses (or 3 s). */
static void wait_received(sooc_pose_src *src, int64_t want) {
    sooc_pose_stats st;
    for (int i = 0; i < 300; i++) {
        sooc_pose_get_stats(src, &st);
        if (st.received + st.duplicates >= want) return;
        sleep_ms(10);
    }
}

static void test_packet(void) {
    sooc_pose_packet pk = {.seq = 7, .kind = SOOC_POSE_EFFECTOR, .t_ns = T0 + 123,
                           .t = {1, 2, 3}, .q = {0, 0, 0.6, 0.8}}, out;
    uint8_t buf[SOOC_POSE_PACKET_SIZE];
    sooc_pose_packet_encode(buf, &pk);
    CHECK(buf[0] == 'S' && buf[1] == 'S' && buf[2] == 'P' && buf[3] == 'O');
    CHECK_OK(sooc_pose_packet_decode(buf, sizeof buf, &out));
    CHECK(out.seq == 7 && out.kind == SOOC_POSE_EFFECTOR && out.t_ns == T0 + 123);
    CHECK(out.t[2] == 3 && out.q[3] == 0.8);
    buf[30] ^= 1;
    CHECK(sooc_pose_packet_decode(buf, sizeof buf, &out) == SOOC_EFORMAT);
    CHECK(strstr(sooc_errmsg(), "CRC") != NULL);
    CHECK(sooc_pose_packet_decode(buf, 40, &out) == SOOC_EFORMAT);
}

/* Stream 100 Hz poses for 1 s with a 100 ms gap, swapped pairs and
 * duplicates; check interpolation at 30 Hz frame times. */
static void run_stream(const char *addr) {
    sooc_pose_params pp;
    sooc_pose_params_default(&pp);
    pp.capacity = 512;
    sooc_pose_src *src = NULL;
    CHECK_OK(sooc_pose_open_socket(&src, addr, &pp));
    if (!src) return;
    sooc_pose_sender *tx = NULL;
    CHECK_OK(sooc_pose_sender_open(&tx, addr));
    if (!tx) { sooc_pose_close(src); return; }
    int order[100], n = 0;
    for (int k = 0; k < 100; k++) {
        if (k >= 40 && k < 50) continue;            /* gap: 100 ms lost */
        order[n++] = k;
    }
    for (int i = 0; i + 1 < n; i += 7) {           /* out of order: swap pairs */
        int t = order[i]; order[i] = order[i + 1]; order[i + 1] = t;
    }
    int sent = 0, dups = 0;
    for (int i = 0; i < n; i++) {
        int k = order[i];
        sooc_pose_packet pk = {.seq = (uint32_t)k, .kind = SOOC_POSE_CAMERA, .t_ns = T0 + k * DT};
        analytic(pk.t_ns, pk.t, pk.q);
        CHECK_OK(sooc_pose_sender_send(tx, &pk));
        sent++;
        if (k % 25 == 3) { CHECK_OK(sooc_pose_sender_send(tx, &pk)); dups++; }
        if (i % 16 == 0) sleep_ms(1);               /* keep the socket buffer from overflowing */
    }
    /* a corrupt packet */
    uint8_t bad[SOOC_POSE_PACKET_SIZE];
    sooc_pose_packet pk0 = {.seq = 1000, .t_ns = T0};
    analytic(T0, pk0.t, pk0.q);
    sooc_pose_packet_encode(bad, &pk0);
    bad[50] ^= 0x10;
    CHECK_OK(sooc_pose_sender_send_raw(tx, bad, sizeof bad));
    wait_received(src, sent + dups);
    sleep_ms(20);
    sooc_pose_stats st;
    sooc_pose_get_stats(src, &st);
    CHECK_MSG(st.received == sent, "received %lld of %d", (long long)st.received, sent);
    CHECK_MSG(st.duplicates == dups, "duplicates %lld, sent %d", (long long)st.duplicates, dups);
    CHECK(st.out_of_order > 0);
    CHECK(st.bad_packets == 1);
    CHECK_MSG(st.seq_gaps == 10, "seq_gaps %lld", (long long)st.seq_gaps);
    CHECK(st.count == sent);
    /* 30 Hz frames over the second; tolerance 20 ms */
    int hits = 0, skips = 0;
    double worst_t = 0, worst_R = 0;
    for (int j = 0; j < 30; j++) {
        int64_t t = T0 + 5000000 + j * 33333333LL;
        double T[16], Ta[16];
        sooc_status s = sooc_pose_lookup(src, t, 20000000, T);
        int in_gap = t > T0 + 39 * DT && t < T0 + 50 * DT && (t - (T0 + 39 * DT) > 20000000 || (T0 + 50 * DT) - t > 20000000);
        int beyond = t > T0 + 99 * DT;
        if (in_gap || beyond) {
            CHECK_MSG(s == SOOC_ENOTFOUND, "frame %d t=+%.1f ms should be skipped", j, (double)(t - T0) * 1e-6);
            skips++;
            continue;
        }
        CHECK_MSG(s == SOOC_OK, "frame %d t=+%.1f ms: %s", j, (double)(t - T0) * 1e-6, sooc_errmsg());
        if (s) continue;
        hits++;
        analytic_T(t, Ta);
        double dtr = fmax(fabs(T[3] - Ta[3]), fmax(fabs(T[7] - Ta[7]), fabs(T[11] - Ta[11])));
        double dR = 0;
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) dR = fmax(dR, fabs(T[4 * r + c] - Ta[4 * r + c]));
        worst_t = fmax(worst_t, dtr);
        worst_R = fmax(worst_R, dR);
    }
    CHECK_MSG(worst_t < 1e-9 && worst_R < 1e-9, "SLERP vs analytic: translation %.3g, rotation %.3g", worst_t, worst_R);
    sooc_pose_get_stats(src, &st);
    CHECK(st.skipped == skips && st.hits == hits && st.lookups == 30);
    printf("  %s: %lld poses (%d dup, %lld out of order, %lld seq gaps), %d frames posed, %d skipped, "
           "max err %.2g m / %.2g\n",
           addr, (long long)st.received, dups, (long long)st.out_of_order, (long long)st.seq_gaps, hits, skips, worst_t,
           worst_R);
    /* text form */
    char line[256];
    int64_t tt = T0 + 200 * DT;
    double tr[3], q[4];
    analytic(tt, tr, q);
    snprintf(line, sizeof line, "# comment\n%lld.%09lld %.12f %.12f %.12f %.12f %.12f %.12f %.12f\n",
             (long long)(tt / 1000000000), (long long)(tt % 1000000000), tr[0], tr[1], tr[2], q[0], q[1], q[2], q[3]);
    CHECK_OK(sooc_pose_sender_send_raw(tx, line, strlen(line)));
    CHECK_OK(sooc_pose_sender_send_raw(tx, "garbage 1 2\n", 12));
    double T[16], Ta[16];
    CHECK_OK(sooc_pose_wait_lookup(src, tt, 0, 2000, T));
    analytic_T(tt, Ta);
    CHECK(max_abs_diff(T, Ta, 16) < 1e-9);
    for (int i = 0; i < 200; i++) {   /* the garbage datagram may still be in flight */
        sooc_pose_get_stats(src, &st);
        if (st.bad_packets >= 2) break;
        sleep_ms(5);
    }
    CHECK(st.bad_packets == 2);
    /* wait_lookup for a future pose times out with ENOTFOUND */
    int64_t w0 = sooc_now_ns();
    CHECK(sooc_pose_wait_lookup(src, tt + DT, DT, 60, T) == SOOC_ENOTFOUND);
    double waited = (double)(sooc_now_ns() - w0) * 1e-6;
    /* it waited for its timeout (a lower bound, which load cannot break), no upper bound on a wall clock */
    CHECK_MSG(waited >= 50, "waited %.1f ms of the 60 ms timeout", waited);
    sooc_pose_sender_close(tx);
    sooc_pose_close(src);
}

static void test_hand_eye(void) {
    sooc_pose_params pp;
    sooc_pose_params_default(&pp);
    sooc_pose_src *src;
    CHECK_OK(sooc_pose_open_buffer(&src, &pp));
    double Tbe[16], t[3], q[4];
    analytic_T(T0, Tbe);
    CHECK(sooc_pose_push(src, T0, SOOC_POSE_EFFECTOR, Tbe) == SOOC_EINVAL);   /* no hand-eye */
    sooc_pose_close(src);

    pp.has_hand_eye = 1;
    double R[9], te[3] = {0.05, -0.02, 0.10};
    double axis[3] = {1, 0, 0};
    double qe[4] = {axis[0] * sin(0.35), 0, 0, cos(0.35)};
    sooc_quat_to_m3(R, qe);
    sooc_se3_from_rt(pp.T_effector_camera, R, te);
    pp.T_world_base[3] = 2.0;   /* base 2 m along world x */
    CHECK_OK(sooc_pose_open_buffer(&src, &pp));
    for (int k = 0; k < 5; k++) {
        analytic(T0 + k * DT, t, q);
        CHECK_OK(sooc_pose_push_tq(src, T0 + k * DT, SOOC_POSE_EFFECTOR, t, q));
    }
    double T[16], A[16], B[16];
    CHECK_OK(sooc_pose_lookup(src, T0 + 2 * DT, 0, T));
    analytic_T(T0 + 2 * DT, Tbe);
    sooc_se3_mul(A, pp.T_world_base, Tbe);
    sooc_se3_mul(B, A, pp.T_effector_camera);
    CHECK(max_abs_diff(T, B, 16) < 1e-12);
    /* interpolated effector pose: T_wc(t) = T_wb * interp(T_be) * T_ec; with a
     * fixed-axis rotation this equals the analytic one */
    CHECK_OK(sooc_pose_lookup(src, T0 + 25 * DT / 10, DT, T));
    analytic_T(T0 + 25 * DT / 10, Tbe);
    sooc_se3_mul(A, pp.T_world_base, Tbe);
    sooc_se3_mul(B, A, pp.T_effector_camera);
    CHECK_MSG(max_abs_diff(T, B, 16) < 1e-9, "hand-eye interp err %.3g", max_abs_diff(T, B, 16));
    /* ring overflow: capacity 4096 default, push older-than-all into a full small ring */
    sooc_pose_close(src);
    pp.capacity = 4;
    CHECK_OK(sooc_pose_open_buffer(&src, &pp));
    for (int k = 0; k < 6; k++) {
        analytic(T0 + k * DT, t, q);
        CHECK_OK(sooc_pose_push_tq(src, T0 + k * DT, SOOC_POSE_CAMERA, t, q));
    }
    sooc_pose_stats st;
    sooc_pose_get_stats(src, &st);
    CHECK(st.count == 4 && st.overflow == 2 && st.t_first_ns == T0 + 2 * DT);
    analytic(T0, t, q);
    CHECK_OK(sooc_pose_push_tq(src, T0, SOOC_POSE_CAMERA, t, q));   /* older than all: rejected */
    sooc_pose_get_stats(src, &st);
    CHECK(st.count == 4 && st.overflow == 3);
    double qbad[4] = {0, 0, 0, 3};
    CHECK(sooc_pose_push_tq(src, T0 + 99 * DT, SOOC_POSE_CAMERA, t, qbad) == SOOC_EINVAL);
    sooc_pose_close(src);
}

static void test_file(const char *dir) {
    char path[512];
    snprintf(path, sizeof path, "%s/groundtruth.txt", dir);
    FILE *fp = fopen(path, "w");
    CHECK(fp != NULL);
    if (!fp) return;
    fprintf(fp, "# ground truth trajectory\n# file: test\n# timestamp tx ty tz qx qy qz qw\n");
    for (int k = 0; k < 50; k++) {
        int64_t t = T0 + k * DT;
        double tr[3], q[4];
        analytic(t, tr, q);
        fprintf(fp, "%lld.%06lld %.9f %.9f %.9f %.12f %.12f %.12f %.12f\n", (long long)(t / 1000000000),
                (long long)((t % 1000000000) / 1000), tr[0], tr[1], tr[2], q[0], q[1], q[2], q[3]);
    }
    fclose(fp);
    sooc_pose_src *src;
    CHECK_OK(sooc_pose_open_file(&src, path, NULL));
    if (!src) return;
    double T[16], Ta[16];
    int64_t t = T0 + 123 * DT / 10;
    CHECK_OK(sooc_pose_lookup(src, t, DT, T));
    analytic_T(t, Ta);
    CHECK_MSG(max_abs_diff(T, Ta, 16) < 1e-8, "file interp err %.3g", max_abs_diff(T, Ta, 16));
    CHECK(sooc_pose_lookup(src, T0 - DT, DT, T) == SOOC_ENOTFOUND);
    sooc_pose_close(src);
    fp = fopen(path, "a");
    fprintf(fp, "1.0 2.0 oops\n");
    fclose(fp);
    CHECK(sooc_pose_open_file(&src, path, NULL) == SOOC_EFORMAT);
    CHECK_MSG(strstr(sooc_errmsg(), "groundtruth.txt:54") != NULL, "msg: %s", sooc_errmsg());
    CHECK(sooc_pose_open_file(&src, "/nonexistent/gt.txt", NULL) != SOOC_OK);
    /* fuzz regressions: timestamps whose nanoseconds overflow int64 are rejected
     * (were signed overflow / an out-of-range llround) */
    static const char *const huge[] = {"9223372039 0 0 0 0 0 0 1\n", "9223372036.9 0 0 0 0 0 0 1\n",
                                       "1e300 0 0 0 0 0 0 1\n", "-1e12 0 0 0 0 0 0 1\n"};
    for (int i = 0; i < 4; i++) {
        fp = fopen(path, "w");
        fputs(huge[i], fp);
        fclose(fp);
        CHECK_MSG(sooc_pose_open_file(&src, path, NULL) == SOOC_EFORMAT, "huge timestamp %d accepted", i);
    }
}

int main(void) {
    char dir[] = "/tmp/sooc_pose_XXXXXX";
    if (!mkdtemp(dir)) return 1;
    test_packet();
    test_hand_eye();
    test_file(dir);
    char addr[600];
    snprintf(addr, sizeof addr, "unix:%s/pose.sock", dir);
    run_stream(addr);
    /* UDP loopback on a pid-derived port; retry a few ports if busy */
    for (int tries = 0; tries < 5; tries++) {
        int port = 20000 + (int)((getpid() * 7 + tries * 131) % 30000);
        snprintf(addr, sizeof addr, "udp://127.0.0.1:%d", port);
        sooc_pose_src *probe;
        if (sooc_pose_open_socket(&probe, addr, NULL) == SOOC_OK) {
            sooc_pose_close(probe);
            run_stream(addr);
            break;
        }
    }
    CHECK(sooc_pose_open_socket(&(sooc_pose_src *){0}, "tcp://x:1", NULL) == SOOC_EINVAL);
    snprintf(addr, sizeof addr, "rm -rf %s", dir);
    if (system(addr)) { /* ignore */ }
    return check_report("test_pose");
}
