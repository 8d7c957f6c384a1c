/* sooc3d node <launch.yaml> [--max-keyframes N] [--print-table] [--log-level L] [--strict] [--set S.K=V]
 *
 * Signals: SIGINT/SIGTERM/SIGHUP/SIGQUIT/SIGUSR1 are blocked before any of
 * our threads exists (so every thread inherits the mask) and collected by a
 * dedicated signal thread (see on_signal for why it is not sigwait). The first SIGINT/SIGTERM asks the node to stop: the keyframe in
 * progress is finished and committed, the table is closed, exit status 0.
 * A second one exits at once (status 128 + signo). SIGUSR1 cycles the log
 * level. SIGPIPE is ignored.
 *
 * OpenMP: on a loaded machine libgomp's default busy-wait after each parallel
 * region costs the mapper 5-70x (docs/model.md). libgomp reads
 * OMP_WAIT_POLICY once, when it is loaded (before main), so a setenv here
 * would come too late: if the variable is unset, the node sets it to
 * "passive" and re-executes itself (/proc/self/exe with the same argv, same
 * pid) before doing anything else. An explicit OMP_WAIT_POLICY is kept. */
#include "cli.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"

#include <errno.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d node <launch.yaml> [options]\n"
            "\n"
            "Run the live mapping node: sensor -> frame ring -> pose association -> keyframe\n"
            "policy -> mapper update -> shared-memory object table + SQLite map.\n"
            "\n"
            "options:\n"
            "  --max-keyframes N   stop (cleanly) after N keyframes\n"
            "  --print-table       print the object table as it fills (also at log level info)\n"
            "  --quiet             do not print the table even at log level info\n"
            "  --log-level L       debug|info|warn|error (overrides log.level)\n"
            "  --set S.K=V         override key K of section S of the launch file (repeatable), e.g.\n"
            "                      --set shm.name=table --set map.resume=true --set model.path=M\n"
            "  --print-config      print the effective configuration and exit\n"
            "  --strict            stop at the first broken input frame (pipeline.strict;\n"
            "                      otherwise it is skipped, counted and named)\n"
            "  -h, --help          this help\n"
            "\n"
            "Signals: SIGINT/SIGTERM finish the current keyframe, commit and exit 0;\n"
            "a second one exits at once. SIGUSR1 cycles the log level.\n"
            "Launch file keys: docs/node.md. Examples: launch/*.yaml.\n");
}

/* Why not a plain sigwait thread: libraries start threads before main()
 * (OpenBLAS's pthread pool, lttng-ust under libcamera) with the signals
 * unblocked, so a process-directed SIGTERM can land there and kill the
 * process with the default action. So: the signals are blocked in main
 * before any of OUR threads exist; a handler is installed (it runs only in
 * the signal thread, which unblocks them, or in such foreign threads); the
 * handler is async-signal-safe: it counts, forwards the signal number through
 * a pipe to the signal thread, and _exit()s on the second one. */
static atomic_int g_sig_count;
static int g_sig_pipe[2] = {-1, -1};

static void on_signal(int sig) {
    if ((sig == SIGINT || sig == SIGTERM || sig == SIGQUIT) && atomic_fetch_add(&g_sig_count, 1) > 0) {
        static const char msg[] = "sooc3d node: second signal, exiting now\n";
        ssize_t w = write(2, msg, sizeof msg - 1);
        (void)w;
        _exit(128 + sig);
    }
    unsigned char b = (unsigned char)sig;
    ssize_t w = write(g_sig_pipe[1], &b, 1);
    (void)w;
}

typedef struct sigctx {
    sooc_node *node;
    sigset_t set;
    atomic_int done;
} sigctx;

static void *sig_main(void *arg) {
    sigctx *c = arg;
    pthread_sigmask(SIG_UNBLOCK, &c->set, NULL);   /* this thread receives them */
    while (!atomic_load(&c->done)) {
        struct pollfd pf = {g_sig_pipe[0], POLLIN, 0};
        int r = poll(&pf, 1, 200);
        if (r <= 0) continue;   /* timeout or EINTR */
        unsigned char b;
        if (read(g_sig_pipe[0], &b, 1) != 1) continue;
        int sig = b;
        if (sig == SIGUSR1) {
            sooc_log_level l = sooc_log_get_level();
            sooc_log_set_level(l >= SOOC_LOG_ERROR ? SOOC_LOG_DEBUG : (sooc_log_level)(l + 1));
            continue;
        }
        if (sig == SIGHUP) {
            sooc_log(SOOC_LOG_INFO, "node: SIGHUP ignored (restart to reload the launch file)");
            continue;
        }
        sooc_log(SOOC_LOG_INFO, "node: %s received: finishing the current keyframe (again to exit now)",
                 sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "SIGQUIT");
        sooc_node_request_stop(c->node);
    }
    pthread_sigmask(SIG_BLOCK, &c->set, NULL);
    return NULL;
}

typedef struct print_ctx {
    int on;
} print_ctx;

static void on_kf(void *user, uint64_t kf, const sooc_map_entry *chg, size_t nc, const uint64_t *rem,
                  size_t nr, const sooc_node_stats *st) {
    print_ctx *p = user;
    if (!p->on) return;
    if (!nc && !nr) return;
    printf("keyframe %llu: %zu changed, %zu removed, %llu objects\n", (unsigned long long)kf, nc, nr,
           (unsigned long long)st->n_objects);
    if (nc)
        printf("  %8s %8s %8s %7s %6s %5s %7s %9s %17s %8s\n", "id", "x_m", "z_m", "yaw_deg", "pres", "obs", "sigma_m",
               "sig_yaw_d", "box_m", "height_m");
    for (size_t i = 0; i < nc; i++) {
        double st, sy;   /* the table's uncertainty (cogmap.h): sqrt(cov_xx), sqrt(cov_yawyaw) */
        sooc_map_entry_planner_sigmas(&chg[i], &st, &sy);
        double c[3], yaw;   /* the table's box */
        float ext[3];
        sooc_map_entry_box(&chg[i], c, &yaw, ext);
        printf("  %8llu %8.3f %8.3f %7.1f %6.3f %5u %7.4f %9.2f %5.3fx%5.3fx%5.3f %8.3f\n", (unsigned long long)chg[i].id,
               chg[i].x, chg[i].z, chg[i].yaw * 180.0 / 3.14159265358979323846, chg[i].presence, chg[i].obs_count, st,
               sy * 180.0 / 3.14159265358979323846, ext[0], ext[1], ext[2], sooc_map_entry_height(&chg[i]));
    }
    for (size_t i = 0; i < nr; i++) printf("  %8llu removed\n", (unsigned long long)rem[i]);
    fflush(stdout);
}

/* Re-exec with OMP_WAIT_POLICY=passive (see the top of the file). Returns
 * only if the variable was already set or the exec failed. */
static void reexec_omp_passive(void) {
    if (getenv("OMP_WAIT_POLICY")) return;
    if (setenv("OMP_WAIT_POLICY", "passive", 1)) return;
    static char buf[65536];
    FILE *f = fopen("/proc/self/cmdline", "rb");
    if (!f) return;
    size_t len = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    if (len == 0 || len >= sizeof buf - 1) return;
    buf[len] = 0;
    static char *args[1024];
    int na = 0;
    for (size_t i = 0; i < len && na < 1023; i += strlen(buf + i) + 1) args[na++] = buf + i;
    args[na] = NULL;
    fflush(NULL);
    execv("/proc/self/exe", args);
    /* exec failed: go on with the policy libgomp already read */
}

int sooc_cmd_node(int argc, char **argv) {
    reexec_omp_passive();
    if (sooc_cli_wants_help(argc, argv)) {
        usage(stdout);
        return 0;
    }
    const char *launch = NULL, *level = NULL, *sets[64];
    int n_sets = 0;
    uint64_t max_kf = 0;
    int print_table = 0, quiet = 0, print_config = 0, strict = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--max-keyframes") && i + 1 < argc) {
            char *end;
            long long v = strtoll(argv[++i], &end, 10);
            if (*end || v < 0) {
                fprintf(stderr, "sooc3d node: --max-keyframes: expected a count, got '%s'\n", argv[i]);
                return 2;
            }
            max_kf = (uint64_t)v;
        } else if (!strcmp(argv[i], "--print-table")) {
            print_table = 1;
        } else if (!strcmp(argv[i], "--quiet")) {
            quiet = 1;
        } else if (!strcmp(argv[i], "--print-config")) {
            print_config = 1;
        } else if (!strcmp(argv[i], "--strict")) {
            strict = 1;
        } else if (!strcmp(argv[i], "--log-level") && i + 1 < argc) {
            level = argv[++i];
        } else if (!strcmp(argv[i], "--set") && i + 1 < argc) {
            if (n_sets == (int)(sizeof sets / sizeof *sets)) {
                fprintf(stderr, "sooc3d node: at most %d --set\n", n_sets);
                return 2;
            }
            sets[n_sets++] = argv[++i];
        } else if (argv[i][0] == '-') {
            fprintf(stderr, "sooc3d node: unknown option '%s'\n", argv[i]);
            usage(stderr);
            return 2;
        } else if (!launch) {
            launch = argv[i];
        } else {
            fprintf(stderr, "sooc3d node: one launch file only ('%s')\n", argv[i]);
            return 2;
        }
    }
    if (!launch) {
        usage(stderr);
        return 2;
    }
    sooc_node_config cfg;
    sooc_status st = sooc_node_config_load_sets(&cfg, launch, sets, n_sets);
    if (st) {   /* the launch file or a --set: what was asked cannot run (exit 2, as for a bad option) */
        sooc_cli_fail("node", st);
        return 2;
    }
    if (level && sooc_log_level_parse(level, &cfg.log_level)) {
        fprintf(stderr, "sooc3d node: --log-level: expected debug|info|warn|error, got '%s'\n", level);
        return 2;
    }
    if (strict) cfg.strict = 1;
    sooc_log_set_level(cfg.log_level);
    char text[4096];
    sooc_node_config_format(&cfg, text, sizeof text);
    if (print_config) {
        fputs(text, stdout);
        return 0;
    }
    sooc_log(SOOC_LOG_INFO, "node: %s, effective config:\n%s", launch, text);

    /* Block the signals before any thread exists: all threads inherit the mask. */
    sigctx sc;
    memset(&sc, 0, sizeof sc);
    sigemptyset(&sc.set);
    sigaddset(&sc.set, SIGINT);
    sigaddset(&sc.set, SIGTERM);
    sigaddset(&sc.set, SIGHUP);
    sigaddset(&sc.set, SIGQUIT);
    sigaddset(&sc.set, SIGUSR1);
    /* block before creating any thread of ours: they all inherit the mask */
    pthread_sigmask(SIG_BLOCK, &sc.set, NULL);
    signal(SIGPIPE, SIG_IGN);
    if (pipe(g_sig_pipe)) {
        fprintf(stderr, "sooc3d node: pipe: %s\n", strerror(errno));
        return 1;
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigfillset(&sa.sa_mask);
    for (int s = 1; s < 32; s++)
        if (sigismember(&sc.set, s)) sigaction(s, &sa, NULL);

    print_ctx pc = {print_table || (!quiet && cfg.log_level <= SOOC_LOG_INFO)};
    sooc_node_options opt;
    memset(&opt, 0, sizeof opt);
    opt.max_keyframes = max_kf;
    opt.on_keyframe = on_kf;
    opt.user = &pc;
    sooc_node *node = NULL;
    st = sooc_node_create(&node, &cfg, &opt);
    if (st) return sooc_cli_fail("node", st);
    sooc_node_stats s0;
    sooc_node_get_stats(node, &s0);
    if (s0.resumed) sooc_log(SOOC_LOG_INFO, "node: resumed %llu entries from %s", (unsigned long long)s0.resumed,
                             cfg.map_db);

    sc.node = node;
    pthread_t sig_thread;
    int sig_ok = pthread_create(&sig_thread, NULL, sig_main, &sc) == 0;
    if (!sig_ok) sooc_log(SOOC_LOG_WARN, "node: no signal thread; SIGINT/SIGTERM will not stop cleanly");
    st = sooc_node_run(node);
    sooc_node_stats s;
    sooc_node_get_stats(node, &s);
    sooc_node_destroy(node);   /* closes the table (unlink only if configured) and the database */
    atomic_store(&sc.done, 1);
    if (sig_ok) pthread_join(sig_thread, NULL);
    if (st) return sooc_cli_fail("node", st);
    char line[512];
    sooc_node_stats_format(&s, line, sizeof line);
    fprintf(stderr, "sooc3d node: done%s: %s\n", atomic_load(&g_sig_count) ? " (stopped by signal)" : "", line);
    return 0;
}
