/* `sooc3d finetune` end to end (runs $SOOC_BIN; skipped without the shipped
 * model): the version-1 map of unity m scene 0 of seed 9001
 * (tests/finetune/map_v1_unity_m.sqlite, written by the node) and that scene
 * generated again (sooc3d gen is deterministic).
 *  1. Ctrl-C mid-run: SIGINT once some objects are stored -> exit 130, the
 *     database passes integrity_check, holds whole decoders for a prefix of
 *     the units (each its own transaction) and all its entries.
 *  2. The same command again resumes: the stored units are skipped (their rows
 *     untouched) and the rest finetuned -> every object and block stored.
 *  3. sooc3d map list and map export --ply (meshes through the field, which
 *     draws the stored decoders) read the map; bad arguments exit 2.
 *  4. births (the default; steps 1-3 run with --no-birth) on a fresh copy:
 *     the new entries are stored with the others and finetuned like them,
 *     and the entries left with no density are removed (born or not); a
 *     second run adds none. */
#include "check.h"
#include "cli_util.h"
#include "sooc3d/core.h"

#include <signal.h>
#include <sqlite3.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#define SHIPPED "models/sooc3d_unity/model.bin"

static long long q1(const char *db, const char *sql) {
    sqlite3 *h = NULL;
    long long v = -1;
    if (sqlite3_open_v2(db, &h, SQLITE_OPEN_READONLY, NULL) == SQLITE_OK) {
        sqlite3_busy_timeout(h, 2000);
        sqlite3_stmt *q = NULL;
        if (sqlite3_prepare_v2(h, sql, -1, &q, NULL) == SQLITE_OK && sqlite3_step(q) == SQLITE_ROW)
            v = sqlite3_column_int64(q, 0);
        sqlite3_finalize(q);
    }
    sqlite3_close(h);
    return v;
}

static int is_ok(const char *db) {
    sqlite3 *h = NULL;
    int ok = 0;
    if (sqlite3_open_v2(db, &h, SQLITE_OPEN_READONLY, NULL) == SQLITE_OK) {
        sqlite3_stmt *q = NULL;
        if (sqlite3_prepare_v2(h, "PRAGMA integrity_check", -1, &q, NULL) == SQLITE_OK && sqlite3_step(q) == SQLITE_ROW)
            ok = !strcmp((const char *)sqlite3_column_text(q, 0), "ok");
        sqlite3_finalize(q);
    }
    sqlite3_close(h);
    return ok;
}

int main(void) {
    const char *bin = getenv("SOOC_BIN");
    if (!bin || !sooc_file_exists(bin) || !sooc_file_exists(SHIPPED)) {
        printf("test_finetune_cli: SKIP: needs $SOOC_BIN and %s (run from the repository root)\n", SHIPPED);
        return SOOC_TEST_SKIP;
    }
    int asan = getenv("SOOC_ASAN") != NULL;
    char tmp[128], cmd[2048], db[256], out[256];
    snprintf(tmp, sizeof tmp, "/tmp/sooc_test_ft_cli_%d", (int)getpid());
    snprintf(db, sizeof db, "%s/map.sqlite", tmp);
    snprintf(out, sizeof out, "%s/run.txt", tmp);
    snprintf(cmd, sizeof cmd,
             "mkdir -p %s && cp tests/finetune/map_v1_unity_m.sqlite %s && %s gen --preset unity --scale m --scenes 1 "
             "--seed 9001 --out %s/seq --threads 1 --no-meshes --no-sheet > /dev/null",
             tmp, db, bin, tmp);
    CHECK(tc_run(cmd) == 0);
    char args[1024];
    /* small runs under ASan (about 10x slower) */
    snprintf(args, sizeof args,
             "finetune --map %s --model %s --seq %s/seq/scene_0000 --iterations %d --rays %d --every 1 --no-birth", db,
             SHIPPED, tmp, asan ? 12 : 40, asan ? 64 : 128);

    /* 1. SIGINT once two units are stored */
    pid_t pid = fork();
    if (pid == 0) {
        snprintf(cmd, sizeof cmd, "exec %s %s --quiet > %s 2>&1", bin, args, out);
        execl("/bin/sh", "sh", "-c", cmd, (char *)NULL);
        _exit(127);
    }
    CHECK(pid > 0);
    long long stored = 0;
    int status = 0, exited = 0;
    for (int t = 0; t < 60000 && !exited; t++) {   /* up to 10 minutes */
        long long n = q1(db, "SELECT (SELECT count(*) FROM ft_objects) + (SELECT count(*) FROM ft_layout)");
        if (n >= 2) {
            kill(pid, SIGINT);
            break;
        }
        if (waitpid(pid, &status, WNOHANG) == pid) exited = 1;
        usleep(10000);
    }
    if (!exited) waitpid(pid, &status, 0);
    char *txt = tc_slurp(out);
    printf("first run: %s", txt ? txt : "(no output)\n");
    CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 130, "status %d", status);
    CHECK(txt && strstr(txt, "interrupted"));
    sooc_free(txt);
    stored = q1(db, "SELECT (SELECT count(*) FROM ft_objects) + (SELECT count(*) FROM ft_layout)");
    long long n_units = 17;   /* 10 objects + 7 layout blocks in this map and scene */
    printf("after SIGINT: %lld of %lld units stored\n", stored, n_units);
    CHECK(stored >= 2 && stored < n_units);
    CHECK(is_ok(db));
    CHECK(q1(db, "SELECT count(*) FROM entries") == 10);
    CHECK(q1(db, "SELECT count(*) FROM keyframes") == 24);
    CHECK(q1(db, "SELECT CAST(value AS INTEGER) FROM meta WHERE key = 'schema_version'") >= 2);
    /* every stored blob is whole */
    CHECK(q1(db, "SELECT count(*) FROM ft_objects WHERE length(data) != 4 * n") == 0);
    long long crc_first = q1(db, "SELECT crc FROM ft_objects ORDER BY id LIMIT 1");

    /* 2. resume */
    snprintf(cmd, sizeof cmd, "%s %s --quiet > %s 2>&1", bin, args, out);
    int rc = tc_run(cmd);
    txt = tc_slurp(out);
    printf("second run: %s", txt ? txt : "(no output)\n");
    CHECK(rc == 0);
    char want[64];
    snprintf(want, sizeof want, "%lld already stored", stored);
    CHECK_MSG(txt && strstr(txt, want), "wanted '%s'", want);
    sooc_free(txt);
    CHECK(q1(db, "SELECT count(*) FROM ft_objects") == 10);
    CHECK(q1(db, "SELECT count(*) FROM ft_layout") == 7);
    CHECK(q1(db, "SELECT crc FROM ft_objects ORDER BY id LIMIT 1") == crc_first);
    CHECK(is_ok(db));

    /* 3. the map still lists; bad arguments */
    snprintf(cmd, sizeof cmd, "%s map list --db %s > /dev/null", bin, db);
    CHECK(tc_run(cmd) == 0);
    /* meshes of the finetuned map (the field draws the stored decoders) */
    snprintf(cmd, sizeof cmd, "%s map export --db %s --ply %s/ply --model %s --res 16 > /dev/null", bin, db, tmp, SHIPPED);
    CHECK(tc_run(cmd) == 0);
    snprintf(cmd, sizeof cmd, "%s finetune --map %s --model %s > /dev/null 2>&1", bin, db, SHIPPED);
    CHECK(tc_run(cmd) == 2);
    /* a births margin outside (0, 100] model units is refused by name */
    snprintf(cmd, sizeof cmd, "%s finetune --map %s --model %s --seq %s/seq/scene_0000 --birth-margin 0 > %s 2>&1", bin,
             db, SHIPPED, tmp, out);
    CHECK(tc_run(cmd) == 2);
    txt = tc_slurp(out);
    CHECK_MSG(txt && strstr(txt, "--birth-margin"), "%s", txt ? txt : "");
    sooc_free(txt);
    snprintf(cmd, sizeof cmd, "%s finetune --map %s/none.sqlite --model %s --seq %s/seq/scene_0000 > %s 2>&1", bin, tmp,
             SHIPPED, tmp, out);
    CHECK(tc_run(cmd) != 0);
    txt = tc_slurp(out);
    CHECK_MSG(txt && strstr(txt, "none.sqlite"), "%s", txt ? txt : "");
    sooc_free(txt);

    /* 4. births */
    char db2[256];
    snprintf(db2, sizeof db2, "%s/map_birth.sqlite", tmp);
    snprintf(cmd, sizeof cmd, "cp tests/finetune/map_v1_unity_m.sqlite %s", db2);
    CHECK(tc_run(cmd) == 0);
    long long max0 = q1(db2, "SELECT max(id) FROM entries");   /* of the copy: the repository's file stays untouched */
    snprintf(cmd, sizeof cmd,
             "%s finetune --map %s --model %s --seq %s/seq/scene_0000 --iterations %d --rays 128 > %s 2>&1",
             bin, db2, SHIPPED, tmp, asan ? 30 : 150, out);
    CHECK(tc_run(cmd) == 0);
    txt = tc_slurp(out);
    int born = -1;
    const char *bl = txt ? strstr(txt, "new entries") : NULL;
    if (bl) {
        while (bl > txt && bl[-1] == ' ') bl--;
        while (bl > txt && bl[-1] >= '0' && bl[-1] <= '9') bl--;
        born = atoi(bl);
    }
    int pruned = -1;
    const char *pl = txt ? strstr(txt, "entries born, ") : NULL;   /* "N entries born, M entries removed" */
    if (pl) pruned = atoi(pl + strlen("entries born, "));
    printf("births run: %d new entries, %d entries removed after finetuning\n", born, pruned);
    CHECK_MSG(born >= 1 && born <= 32 && pruned >= 0 && pruned <= born, "%s", txt ? txt : "(no output)");
    sooc_free(txt);
    CHECK(is_ok(db2));
    CHECK(q1(db2, "SELECT count(*) FROM entries") == 10 + born - pruned);
    CHECK(q1(db2, "SELECT count(*) FROM ft_objects") == 10 + born - pruned);
    char sql[128];
    snprintf(sql, sizeof sql, "SELECT count(*) FROM entries WHERE id > %lld", max0);
    long long kept = q1(db2, sql);   /* born entries (fresh ids above the old ones) still there */
    printf("births run: %lld born entries kept\n", kept);
    CHECK(max0 > 0 && kept >= 0 && kept <= born);
    if (!asan) CHECK(kept >= 1);   /* 150 steps: some births take shape */
    snprintf(cmd, sizeof cmd, "%s finetune --map %s --model %s --seq %s/seq/scene_0000 --iterations 4 --rays 64 "
             "> %s 2>&1", bin, db2, SHIPPED, tmp, out);
    CHECK(tc_run(cmd) == 0);
    CHECK(q1(db2, "SELECT count(*) FROM entries") == 10 + born - pruned);

    if (!getenv("SOOC_KEEP_TMP")) {
        snprintf(cmd, sizeof cmd, "rm -rf %s", tmp);
        if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmp);
    }
    return check_report("test_finetune_cli");
}
