/* An output file in a folder that does not exist, through the `sooc3d`
 * binary ($SOOC_BIN): each command that writes a file (odometry --out and
 * --gt-out, eval --json and --md, model --out, calib intrinsics and handeye
 * --out, map at --png, map export) exits 2 before it reads anything, with a
 * message naming the option, the path and the missing folder, and creates
 * nothing; a "folder" that is a regular file is named as not a folder; an
 * output in the working folder (no slash) is not refused. */
#include "check.h"
#include "cli_util.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char g_tmp[256];

/* Runs `bin args` with stderr captured; its exit status, the message in msg. */
static int run_cli(const char *bin, const char *args, char *msg, size_t cap) {
    char cmd[2048], err[400];
    snprintf(err, sizeof err, "%s/stderr.txt", g_tmp);
    snprintf(cmd, sizeof cmd, "'%s' %s > /dev/null 2> '%s'", bin, args, err);
    int rc = tc_run(cmd);
    char *t = tc_slurp(err);
    snprintf(msg, cap, "%s", t ? t : "");
    sooc_free(t);
    return rc;
}

int main(void) {
    const char *bin = getenv("SOOC_BIN");
    if (!bin || access(bin, X_OK)) {
        printf("test_cli_out_folder: SKIP: SOOC_BIN is not set\n");
        return 77;
    }
    snprintf(g_tmp, sizeof g_tmp, "/tmp/sooc_outdir_XXXXXX");
    if (!mkdtemp(g_tmp)) return 1;
    char miss[400], file[400], args[1400], msg[4096], want[1200];
    snprintf(miss, sizeof miss, "%s/no_such_dir", g_tmp);
    snprintf(file, sizeof file, "%s/plain_file", g_tmp);
    FILE *f = fopen(file, "w");
    if (f) fclose(f);
    static const struct { const char *fmt, *opt; } cases[] = {
        {"odometry --seq /nonexistent --out %s/t.txt", "--out"},
        {"odometry --seq /nonexistent --out t.txt --gt-out %s/gt.txt", "--gt-out"},
        {"eval --model /nonexistent --json %s/e.json", "--json"},
        {"eval --model /nonexistent --md %s/e.md", "--md"},
        {"model /nonexistent --out %s/m.bin", "--out"},
        {"calib intrinsics --board charuco:5x7:0.04:0.03 --out %s/c.yaml --images /nonexistent", "--out"},
        {"calib handeye --board charuco:5x7:0.04:0.03 --out %s/h.yaml --images /nonexistent", "--out"},
        {"map at --db /nonexistent --png %s/a.png", "--png"},
        {"map export --db /nonexistent --csv %s/m.csv", "--csv"},
    };
    int n = (int)(sizeof cases / sizeof *cases);
    for (int i = 0; i < n; i++) {
        snprintf(args, sizeof args, cases[i].fmt, miss);
        int rc = run_cli(bin, args, msg, sizeof msg);
        snprintf(want, sizeof want, "%s %s/", cases[i].opt, miss);
        CHECK_MSG(rc == 2 && strstr(msg, want) && strstr(msg, "does not exist") && strstr(msg, miss),
                  "`%s`: exit %d, '%s'", args, rc, msg);
        /* a regular file where the folder should be */
        snprintf(args, sizeof args, cases[i].fmt, file);
        rc = run_cli(bin, args, msg, sizeof msg);
        CHECK_MSG(rc == 2 && strstr(msg, "is not a folder") && strstr(msg, file), "`%s`: exit %d, '%s'", args, rc, msg);
    }
    CHECK_MSG(access(miss, F_OK) != 0, "%s was created", miss);
    /* no slash: the working folder, which exists; the command fails later, on its missing input */
    int rc = run_cli(bin, "map export --db /nonexistent/m.sqlite --csv out_here.csv", msg, sizeof msg);
    CHECK_MSG(rc != 0 && !strstr(msg, "the folder") && strstr(msg, "/nonexistent/m.sqlite"),
              "an output in the working folder: exit %d, '%s'", rc, msg);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmp);
    if (system(cmd)) {}
    return check_report("test_cli_out_folder");
}
