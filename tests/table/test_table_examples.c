/* The example planners against a live writer: the C one
 * (<build>/bin/sooc3d-planner-example, env SOOC_PLANNER_EXAMPLE) and the Python
 * one (scripts/planner_example.py with Debian's python3, no extension).
 * 1. --once prints the current objects.
 * 2. Follow mode prints each new epoch (an added and a removed object) and
 *    exits by itself when the writer closes.
 * 3. A table left mid-batch by a writer SIGKILLed inside a batch: --once and
 *    follow mode say it is stuck mid-batch and exit 3 (not silence and exit 0).
 * 4. A live writer that stays inside one batch: --once says "busy", exits 3.
 * Skips (77) the Python part if python3 is missing. */
#include "check.h"
#include "table_test_util.h"

#include <signal.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <sys/wait.h>

static char g_name[64];

/* Writer child: objects 101..103, then on "go" adds 104, removes 102, closes. */
static pid_t spawn_writer(int *go_fd) {
    int ready[2], go[2];
    if (pipe(ready) != 0 || pipe(go) != 0) return -1;
    pid_t pid = fork();
    if (pid != 0) {
        close(ready[1]);
        close(go[0]);
        char c = 0;
        if (read(ready[0], &c, 1) != 1) return -1;
        close(ready[0]);
        *go_fd = go[1];
        return pid;
    }
    close(ready[0]);
    close(go[1]);
    sooc_table_writer *w = NULL;
    if (sooc_table_create_writer(g_name, 32, 0, "map", &w) != 0) _exit(3);
    sooc_table_start_heartbeat(w, 20);
    sooc_table_record rec;
    sooc_table_begin_batch(w);
    /* the pose source is z-up and shifted: p_src = (x_map + 1, -z_map, y_map + 0.5) */
    const double T[16] = {1, 0, 0, 1, 0, 0, -1, 0, 0, 1, 0, 0.5, 0, 0, 0, 1};
    sooc_table_set_meta(w, 0, 0, 0, T);
    for (uint64_t id = 101; id <= 103; id++) {
        tt_make(&rec, id, (uint32_t)id);
        rec.x = 1.5f * (float)(id - 100);
        rec.y = 0.125f;
        rec.z = -2.25f;
        rec.yaw = 0.5f;
        rec.presence = 0.875f;
        sooc_table_upsert(w, &rec);
    }
    sooc_table_end_batch(w);
    char c = 'R';
    if (write(ready[1], &c, 1) != 1) _exit(4);
    if (read(go[0], &c, 1) != 1) _exit(5);
    tt_sleep_ms(400);
    sooc_table_begin_batch(w);
    tt_make(&rec, 104, 104);
    rec.x = 7.0f;
    sooc_table_upsert(w, &rec);
    sooc_table_end_batch(w);
    tt_sleep_ms(400);
    sooc_table_begin_batch(w);
    sooc_table_remove(w, 102);
    sooc_table_end_batch(w);
    tt_sleep_ms(400);
    sooc_table_close_writer(w, 0);
    _exit(0);
}

/* Read a whole popen'ed output. */
static int slurp(FILE *f, char *buf, size_t cap) {
    size_t n = 0, k;
    while (n + 1 < cap && (k = fread(buf + n, 1, cap - 1 - n, f)) > 0) n += k;
    buf[n] = 0;
    return pclose(f);
}

/* source = 1: with --source, the rows in the pose source's frame (the writer's T_src_map) */
static void check_once(const char *what, const char *cmd, int source) {
    static char out[16384];
    FILE *f = popen(cmd, "r");
    CHECK(f != NULL);
    if (!f) return;
    int st = slurp(f, out, sizeof out);
    CHECK_MSG(st == 0, "%s --once exit status %d", what, st);
    printf("---- %s --once%s:\n%s", what, source ? " --source" : "", out);
    CHECK_MSG(strstr(out, source ? "epoch 1  objects 3  frame pose source" : "epoch 1  objects 3  frame map") != NULL,
              "%s: header line", what);
    for (int id = 101; id <= 103; id++) {
        char line[160];
        double x = 1.5 * (id - 100), y = 0.125, z = -2.25;
        if (source) /* the box x axis (cos .5, 0, -sin .5) goes to (cos .5, sin .5, 0): 0.5 rad about source +z */
            snprintf(line, sizeof line, "%10d V--- %9.3f %9.3f %9.3f %8.1f %8.3f", id, x + 1, -z, y + 0.5,
                     0.5 * 57.29577951308232, 0.875);
        else
            snprintf(line, sizeof line, "%10d V--- %9.3f %9.3f %9.3f %8.1f %8.3f", id, x, y, z,
                     0.5 * 57.29577951308232, 0.875);
        CHECK_MSG(strstr(out, line) != NULL, "%s: missing row '%s'", what, line);
    }
}

/* Writer child for parts 3 and 4: objects 201..202 published, then a batch is
 * opened (an upsert half done). kill_in_batch: SIGKILL itself there; else
 * keep the batch open with the heartbeat running until the pipe closes. */
static pid_t spawn_batch_writer(int kill_in_batch, int *hold_fd) {
    int ready[2], hold[2];
    if (pipe(ready) != 0 || pipe(hold) != 0) return -1;
    pid_t pid = fork();
    if (pid != 0) {
        close(ready[1]);
        close(hold[0]);
        char c = 0;
        if (read(ready[0], &c, 1) != 1) pid = -1;
        close(ready[0]);
        *hold_fd = hold[1];
        return pid;
    }
    close(ready[0]);
    close(hold[1]);
    sooc_table_writer *w = NULL;
    if (sooc_table_create_writer(g_name, 32, 0, "map", &w) != 0) _exit(3);
    sooc_table_start_heartbeat(w, 20);
    sooc_table_record rec;
    sooc_table_begin_batch(w);
    for (uint64_t id = 201; id <= 202; id++) {
        tt_make(&rec, id, (uint32_t)id);
        sooc_table_upsert(w, &rec);
    }
    sooc_table_end_batch(w);
    sooc_table_begin_batch(w);
    tt_make(&rec, 203, 203);
    sooc_table_upsert(w, &rec);
    char c = 'R';
    if (write(ready[1], &c, 1) != 1) _exit(4);
    if (kill_in_batch) raise(SIGKILL);
    if (read(hold[0], &c, 1) < 0) _exit(5);
    sooc_table_close_writer(w, 1);
    _exit(0);
}

/* Run `cmd` (stderr folded into stdout); expect exit status `want` and `needle`. */
static void check_exit(const char *what, const char *cmd, int want, const char *needle) {
    static char out[16384];
    char full[1200];
    snprintf(full, sizeof full, "%s 2>&1", cmd);
    FILE *f = popen(full, "r");
    CHECK(f != NULL);
    if (!f) return;
    int st = slurp(f, out, sizeof out);
    printf("---- %s:\n%s", what, out);
    CHECK_MSG(WIFEXITED(st) && WEXITSTATUS(st) == want, "%s: exit status %d, want %d", what,
              WIFEXITED(st) ? WEXITSTATUS(st) : -1, want);
    CHECK_MSG(strstr(out, needle) != NULL, "%s: no '%s' in the output", what, needle);
}

static void check_stuck(const char *cbin, const char *py, const char *src) {
    char cmd[1024], what[128];
    /* 3. writer killed inside a batch */
    int hold = -1;
    pid_t wpid = spawn_batch_writer(1, &hold);
    CHECK(wpid > 0);
    if (wpid <= 0) return;
    int status = 0;
    waitpid(wpid, &status, 0);
    CHECK(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
    close(hold);
    for (int follow = 0; follow < 2; follow++) {
        snprintf(cmd, sizeof cmd, "%s %s %s", cbin, g_name, follow ? "--interval 20" : "--once");
        snprintf(what, sizeof what, "C example, dead mid-batch, %s", follow ? "follow" : "--once");
        check_exit(what, cmd, 3, "stuck mid-batch: its writer");
        if (!py) continue;
        snprintf(cmd, sizeof cmd, "%s %s/scripts/planner_example.py %s %s", py, src, g_name,
                 follow ? "--interval 20" : "--once");
        snprintf(what, sizeof what, "Python example, dead mid-batch, %s",
                 follow ? "follow" : "--once");
        check_exit(what, cmd, 3, "stuck mid-batch: its writer");
    }
    /* 4. live writer inside one batch */
    wpid = spawn_batch_writer(0, &hold);
    CHECK(wpid > 0);
    if (wpid <= 0) return;
    snprintf(cmd, sizeof cmd, "%s %s --once --interval 50", cbin, g_name);
    check_exit("C example, live writer inside a batch", cmd, 3, "busy: its writer");
    if (py) {
        snprintf(cmd, sizeof cmd, "%s %s/scripts/planner_example.py %s --once --interval 50", py,
                 src, g_name);
        check_exit("Python example, live writer inside a batch", cmd, 3, "busy: its writer");
    }
    close(hold);
    waitpid(wpid, &status, 0);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

int main(void) {
    tt_name(g_name, sizeof g_name, "examples");
    const char *cbin = getenv("SOOC_PLANNER_EXAMPLE");
    const char *src = getenv("SOOC_SRC") ? getenv("SOOC_SRC") : ".";
    const char *py = access("/usr/bin/python3", X_OK) == 0 ? "/usr/bin/python3"
                     : system("command -v python3 >/dev/null 2>&1") == 0 ? "python3"
                                                                         : NULL;
    if (!cbin) cbin = "build/bin/sooc3d-planner-example";
    int go_fd = -1;
    pid_t wpid = spawn_writer(&go_fd);
    CHECK(wpid > 0);
    if (wpid <= 0) return check_report("test_table_examples");

    char cmd_c[1024], cmd_py[1024];
    for (int source = 0; source <= 1; source++) {
        snprintf(cmd_c, sizeof cmd_c, "%s %s --once%s", cbin, g_name, source ? " --source" : "");
        check_once("C example", cmd_c, source);
        if (py) {
            snprintf(cmd_py, sizeof cmd_py, "%s %s/scripts/planner_example.py %s --once%s", py, src, g_name,
                     source ? " --source" : "");
            check_once("Python example", cmd_py, source);
        }
    }

    /* follow mode: both run while the writer adds, removes, then closes */
    snprintf(cmd_c, sizeof cmd_c, "%s %s --interval 20", cbin, g_name);
    FILE *fc = popen(cmd_c, "r");
    FILE *fp = NULL;
    if (py) {
        snprintf(cmd_py, sizeof cmd_py, "%s %s/scripts/planner_example.py %s --interval 20", py,
                 src, g_name);
        fp = popen(cmd_py, "r");
    }
    tt_sleep_ms(300); /* let both print epoch 1 */
    char c = 'G';
    CHECK(write(go_fd, &c, 1) == 1);
    FILE *fs[2] = {fc, fp};
    const char *names[2] = {"C example", "Python example"};
    static char out[65536];
    for (int i = 0; i < 2; i++) {
        if (!fs[i]) continue;
        int st = slurp(fs[i], out, sizeof out);
        CHECK_MSG(st == 0, "%s follow exit status %d", names[i], st);
        printf("---- %s follow:\n%s", names[i], out);
        CHECK_MSG(strstr(out, "epoch 1  objects 3") && strstr(out, "epoch 2  objects 4") &&
                      strstr(out, "epoch 3  objects 3"),
                  "%s: did not see every epoch", names[i]);
        CHECK_MSG(strstr(out, "       104 V---     7.000") != NULL, "%s: object 104", names[i]);
        CHECK_MSG(strstr(out, "       102 --R-") != NULL, "%s: removed 102", names[i]);
        CHECK_MSG(strstr(out, "writer gone (closed cleanly)") != NULL, "%s: exit", names[i]);
    }
    int status = 0;
    waitpid(wpid, &status, 0);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    check_stuck(cbin, py, src);
    char shm[128];
    sooc_table_shm_name(g_name, shm, sizeof shm);
    shm_unlink(shm);
    int rc = check_report("test_table_examples");
    if (rc == 0 && !py) {
        printf("python3 not found: Python example skipped\n");
        return SOOC_TEST_SKIP;
    }
    return rc;
}
