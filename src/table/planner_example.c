/*
 * sooc3d-planner-example: a minimal planner that follows the object table live.
 *
 *   sooc3d-planner-example <name> [--once] [--wait S] [--interval MS] [--rep103 | --source]
 *
 * It opens /dev/shm/sooc3d.v1.<name> read-only, takes a consistent snapshot
 * every --interval ms (default 100) and prints the table whenever the epoch
 * changes: id, x, z, yaw (deg), presence, age. Exit status: 0 when the writer
 * closed cleanly, on SIGINT/SIGTERM, or after --once printed a snapshot; 1 if
 * the table cannot be opened; 3 when the writer died or hung (message on
 * stderr), or when the table stays busy: left mid-batch by a writer killed
 * inside a keyframe, or in one batch for more than 2 s (BUSY_MAX_MS). This
 * file uses only <sooc3d/table.h>, so it is also
 * a template for planners outside the sooc3d tree:
 *   cc planner.c $(pkg-config --cflags --libs sooc3d_table)
 */
#include <sooc3d/table.h>

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define BUSY_MAX_MS 2000 /* a live writer inside one batch for longer: report "busy" */

static volatile sig_atomic_t g_stop = 0;
static void on_signal(int sig) {
    (void)sig;
    g_stop = 1;
}

static int64_t now_real_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

static int64_t now_mono_ms(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static void sleep_ms(long ms) {
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL); /* EINTR is fine: the loop re-checks g_stop */
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d-planner-example <name> [--once] [--wait S] [--interval MS] [--rep103 | --source]\n"
            "  Follow the sooc3d object table /dev/shm/sooc3d.v1.<name> and print it when it\n"
            "  changes. Exits when the writer is gone or on Ctrl-C: status 0 after a clean\n"
            "  close (or --once), 1 if the table cannot be opened, 3 if the writer died or\n"
            "  hung or the table stays busy (e.g. left mid-batch by a killed writer).\n"
            "  --once         print one snapshot and exit\n"
            "  --wait S       wait up to S seconds for the table to appear (default 0)\n"
            "  --interval MS  polling period (default 100)\n"
            "  --rep103       print poses in a ROS REP-103 frame (x fwd, y left, z up) of the map\n"
            "  --source       print poses in the pose source's frame (the robot base, the recording's\n"
            "                 world): the header's T_src_map applied (sooc_table_pose_source)\n");
}

static void print_table(const sooc_table_info *info, const sooc_table_record *recs, uint32_t n,
                        uint64_t epoch, int rep103, int source) {
    int64_t ref = info->stamp_ns ? info->stamp_ns : now_real_ns();
    printf("epoch %llu  objects %llu  frame %s  writer pid %lld\n", (unsigned long long)epoch,
           (unsigned long long)info->n_objects, source ? "pose source (T_src_map)" : info->frame_id,
           (long long)info->writer_pid);
    printf("  %10s %4s %9s %9s %9s %8s %8s %5s %8s %8s %17s\n", "id", "flag", rep103 ? "x_ros" : "x",
           rep103 ? "y_ros" : "y", rep103 ? "z_ros" : "z", "yaw_deg", "presence", "obs", "age_s", "sigma_m",
           "box x*y*z (m)");
    for (uint32_t i = 0; i < n; i++) {
        const sooc_table_record *r = &recs[i];
        char fl[5] = "----";
        if (r->flags & SOOC_TABLE_FLAG_VALID) fl[0] = 'V';
        if (r->flags & SOOC_TABLE_FLAG_TENTATIVE) fl[1] = 'T';
        if (r->flags & SOOC_TABLE_FLAG_REMOVED) fl[2] = 'R';
        if (r->flags & SOOC_TABLE_FLAG_STATIC) fl[3] = 'S';
        double p[3] = {r->x, r->y, r->z}, yaw = r->yaw;
        if (source) {   /* the box centre in the pose source's frame; yaw: the box x axis about the source's
                           axis nearest to the map's up (+z for a z-up robot base, +y for a y-up world) */
            double R[9];
            const double *T = info->T_src_map;
            sooc_table_pose_source(T, r, p, R, NULL);
            if (fabs(T[9]) >= fabs(T[5])) yaw = (T[9] > 0 ? 1 : -1) * atan2(R[3], R[0]);
            else yaw = (T[5] > 0 ? 1 : -1) * atan2(-R[6], R[0]);
        } else if (rep103) {
            float xr, yr, zr, yr_;
            sooc_table_pose_rep103(r, &xr, &yr, &zr, &yr_, NULL);
            p[0] = xr, p[1] = yr, p[2] = zr, yaw = yr_;
        }
        double age = r->last_seen_ns ? (double)(ref - r->last_seen_ns) * 1e-9 : 0.0;
        double sig = sqrt(0.5 * ((double)r->cov_xzyaw[0] + r->cov_xzyaw[3]));
        printf("  %10llu %4s %9.3f %9.3f %9.3f %8.1f %8.3f %5u %8.2f %8.4f %5.3fx%5.3fx%5.3f\n",
               (unsigned long long)r->object_id, fl, p[0], p[1], p[2], yaw * 57.29577951308232, r->presence,
               r->obs_count, age, sig, r->extent[0], r->extent[1], r->extent[2]);
    }
    fflush(stdout);
}

int main(int argc, char **argv) {
    const char *name = NULL;
    int once = 0, rep103 = 0, source = 0;
    double wait_s = 0;
    long interval_ms = 100;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(argv[i], "--once")) {
            once = 1;
        } else if (!strcmp(argv[i], "--rep103")) {
            rep103 = 1;
        } else if (!strcmp(argv[i], "--source")) {
            source = 1;
        } else if (!strcmp(argv[i], "--wait") && i + 1 < argc) {
            wait_s = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--interval") && i + 1 < argc) {
            interval_ms = atol(argv[++i]);
            if (interval_ms < 1) interval_ms = 1;
        } else if (argv[i][0] != '-' && !name) {
            name = argv[i];
        } else {
            usage(stderr);
            return 2;
        }
    }
    if (!name) {
        usage(stderr);
        return 2;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);

    sooc_table_reader *r = NULL;
    int rc;
    for (long waited = 0;; waited += 100) {
        rc = sooc_table_open_reader(name, &r);
        if (rc == 0) break;
        int retry = rc == SOOC_TABLE_ENOENT || rc == SOOC_TABLE_ENOTREADY;
        if (!retry || waited >= (long)(wait_s * 1000) || g_stop) {
            fprintf(stderr, "sooc3d-planner-example: cannot open table '%s': %s\n", name,
                    sooc_table_strerror(rc));
            return 1;
        }
        sleep_ms(100);
    }
    uint32_t cap = sooc_table_capacity(r);
    sooc_table_record *recs = malloc((size_t)cap * sizeof *recs);
    if (!recs) {
        sooc_table_close_reader(r);
        return 1;
    }
    uint64_t last_epoch = UINT64_MAX;
    int status = 0;
    int64_t busy_since = -1; /* CLOCK_MONOTONIC ms of the first busy snapshot in a row */
    while (!g_stop) {
        uint32_t n = 0;
        uint64_t epoch = 0;
        sooc_table_info info;
        rc = sooc_table_snapshot(r, recs, cap, &n, &epoch);
        if (rc == 0) rc = sooc_table_get_info(r, &info);
        if (rc == 0 && (epoch != last_epoch || once)) {
            print_table(&info, recs, n, epoch, rep103, source);
            sooc_table_store ts;   /* the map database's state (abi_minor >= 1) */
            static const char *const fault[] = {"", " (disk full)", " (I/O error)", " (locked)", " (corrupt)",
                                                " (out of memory)", ""};
            if (sooc_table_get_store(r, &ts) == 0 && ts.state == SOOC_TABLE_STORE_FAILING)
                printf("  map database failing%s: %llu objects and %llu keyframes not stored yet\n",
                       fault[ts.fault < 7 ? ts.fault : 6], (unsigned long long)ts.pending,
                       (unsigned long long)ts.pending_kf);
            last_epoch = epoch;
        } else if (rc != 0 && rc != SOOC_TABLE_EBUSY) {
            fprintf(stderr, "sooc3d-planner-example: table '%s': %s\n", name,
                    sooc_table_strerror(rc));
            status = 1;
            break;
        }
        if (once && rc == 0) break;
        if (rc != SOOC_TABLE_EBUSY) busy_since = -1;
        else if (busy_since < 0) busy_since = now_mono_ms();
        sooc_table_liveness live;
        if (sooc_table_writer_alive(r, &live) != 1) {
            const char *why = live.exited      ? "closed cleanly"
                              : live.lock_held ? "heartbeat stale"
                                               : "process died";
            if (rc == SOOC_TABLE_EBUSY) {
                fprintf(stderr,
                        "sooc3d-planner-example: table '%s' is stuck mid-batch: its writer (pid "
                        "%lld) %s inside a batch; no consistent copy can be read until a new "
                        "writer takes the table over\n",
                        name, (long long)live.writer_pid,
                        live.exited ? "closed" : live.lock_held ? "hung" : "died");
                status = 3;
                break;
            }
            printf("writer gone (%s)\n", why);
            if (!live.exited) {
                fprintf(stderr, "sooc3d-planner-example: table '%s': writer (pid %lld) %s\n",
                        name, (long long)live.writer_pid,
                        live.lock_held ? "hung (heartbeat stale)" : "died");
                status = 3;
            }
            break;
        }
        if (busy_since >= 0 && now_mono_ms() - busy_since > BUSY_MAX_MS) {
            fprintf(stderr,
                    "sooc3d-planner-example: table '%s' busy: its writer (pid %lld) is alive "
                    "but has been inside one batch for more than %d ms\n",
                    name, (long long)live.writer_pid, BUSY_MAX_MS);
            status = 3;
            break;
        }
        sleep_ms(interval_ms);
    }
    free(recs);
    sooc_table_close_reader(r);
    return status;
}
