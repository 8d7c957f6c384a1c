/* Map access a planner's developer needs:
 * 1. model_id: a map created with a model id stores it; opening it for another
 *    model is SOOC_EVERSION naming both ids; a map stored with an empty id
 *    takes the id of the first read-write open that gives one.
 * 2. Read-only maps: a database with no -wal/-shm left, in a folder the reader
 *    cannot write, opens read-only (sooc_mapstore_open readonly = 1) and
 *    `sooc3d map list` lists it, as an unprivileged user (uid 65534 when the
 *    test runs as root; else the folder is made read-only). A control shows
 *    SQLite's plain read-only open failing there ("attempt to write a
 *    readonly database"), the case the issue reported.
 * 3. A non-empty -wal (a writer that has not checkpointed) gives an error
 *    naming the database and the cause, not a wrong map. */
#include "check.h"
#include "sooc3d/cogmap.h"

#include <grp.h>
#include <sqlite3.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define D 4

static char g_dir[256];

static sooc_status open_rw(sooc_mapstore **s, const char *path, const char *model_id) {
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.dim = D;
    p.layout_dim = 0;
    p.model_id = model_id;
    return sooc_mapstore_open(s, path, &p);
}

static void make_map(const char *path, const char *model_id) {
    sooc_mapstore *s = NULL;
    CHECK_OK(open_rw(&s, path, model_id));
    if (!s) return;
    sooc_cogmap_entry e[3];
    memset(e, 0, sizeof e);
    for (int i = 0; i < 3; i++) {
        e[i].id = (uint64_t)i + 1;
        e[i].X = i;
        e[i].Z = -i;
        e[i].dim = D;
        e[i].pres_logit = 2;
        e[i].obs_count = 1;
    }
    CHECK_OK(sooc_mapstore_begin(s));
    CHECK_OK(sooc_mapstore_put_entries(s, e, 3));
    CHECK_OK(sooc_mapstore_set_next_id(s, 4));
    CHECK_OK(sooc_mapstore_commit(s));
    sooc_mapstore_close(s);
}

static int count_cb(void *u, const sooc_cogmap_entry *e) {
    (void)e;
    (*(int *)u)++;
    return 0;
}

static void test_model_id(void) {
    char db[512];
    snprintf(db, sizeof db, "%s/model.sqlite", g_dir);
    make_map(db, "crc32:0badf00d bytes:100");
    sooc_mapstore *s = NULL;
    sooc_mapstore_info info;
    CHECK_OK(open_rw(&s, db, NULL));
    if (s) {
        CHECK_OK(sooc_mapstore_info_get(s, &info));
        CHECK_MSG(!strcmp(info.model_id, "crc32:0badf00d bytes:100"), "stored model_id '%s'", info.model_id);
        sooc_mapstore_close(s);
    }
    sooc_status st = open_rw(&s, db, "crc32:12345678 bytes:100");
    CHECK(st == SOOC_EVERSION && s == NULL);
    CHECK_MSG(strstr(sooc_errmsg(), db) && strstr(sooc_errmsg(), "crc32:0badf00d") &&
                  strstr(sooc_errmsg(), "crc32:12345678"),
              "message: %s", sooc_errmsg());
    CHECK_OK(open_rw(&s, db, "crc32:0badf00d bytes:100"));
    sooc_mapstore_close(s);

    /* a map written without an id takes the first one given */
    snprintf(db, sizeof db, "%s/noid.sqlite", g_dir);
    make_map(db, NULL);
    CHECK_OK(open_rw(&s, db, "crc32:aaaaaaaa bytes:1"));
    sooc_mapstore_close(s);
    CHECK_OK(open_rw(&s, db, NULL));
    if (s) {
        CHECK_OK(sooc_mapstore_info_get(s, &info));
        CHECK_MSG(!strcmp(info.model_id, "crc32:aaaaaaaa bytes:1"), "model_id '%s'", info.model_id);
        sooc_mapstore_close(s);
    }
    CHECK(open_rw(&s, db, "crc32:bbbbbbbb bytes:1") == SOOC_EVERSION);
}

/* In a child with only read permission: returns a bit mask of failures. */
static int ro_child(const char *db, const char *bin) {
    int fail = 0;
    if (geteuid() == 0) {
        if (setgroups(0, NULL) != 0 || setgid(65534) != 0 || setuid(65534) != 0) return 64;
    }
    if (access(g_dir, W_OK) == 0) return 128; /* the test would prove nothing */
    /* control: SQLite's plain read-only open of this WAL database */
    sqlite3 *raw = NULL;
    int rc = sqlite3_open_v2(db, &raw, SQLITE_OPEN_READONLY, NULL);
    if (rc == SQLITE_OK) rc = sqlite3_exec(raw, "SELECT count(*) FROM entries", NULL, NULL, NULL);
    printf("control: plain SQLITE_OPEN_READONLY (the issue's failure): %s\n",
           rc == SQLITE_OK ? "ok" : sqlite3_errmsg(raw));
    sqlite3_close(raw);
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.readonly = 1;
    p.create = 0;
    sooc_mapstore *s = NULL;
    sooc_status st = sooc_mapstore_open(&s, db, &p);
    if (st) {
        printf("read-only open: %s\n", sooc_errmsg());
        fail |= 1;
    } else {
        int n = 0;
        if (sooc_mapstore_foreach(s, count_cb, &n) || n != 3) fail |= 2;
        sooc_mapstore_info info;
        if (sooc_mapstore_info_get(s, &info) || info.next_id != 4 || info.n_entries != 3) fail |= 4;
        printf("read-only open: %d entries, next_id %llu\n", n, (unsigned long long)info.next_id);
        sooc_mapstore_close(s);
    }
    if (bin) {
        char cmd[1200];
        snprintf(cmd, sizeof cmd, "%s map list --db '%s' 2>&1", bin, db);
        FILE *f = popen(cmd, "r");
        char line[512];
        int rows = 0;
        while (f && fgets(line, sizeof line, f)) {
            printf("  map list: %s", line);
            unsigned long long id;
            if (line[0] == ' ' && sscanf(line, "%llu", &id) == 1) rows++;
        }
        int ps = f ? pclose(f) : -1;
        if (ps != 0 || rows != 3) fail |= 8;
    }
    fflush(stdout);
    return fail;
}

static void test_readonly(void) {
    char db[512];
    snprintf(db, sizeof db, "%s/ro/map.sqlite", g_dir);
    char sub[300];
    snprintf(sub, sizeof sub, "%s/ro", g_dir);
    CHECK(mkdir(sub, 0755) == 0);
    make_map(db, "m");
    char wal[600], shm[600];
    snprintf(wal, sizeof wal, "%s-wal", db);
    snprintf(shm, sizeof shm, "%s-shm", db);
    CHECK_MSG(access(wal, F_OK) != 0 && access(shm, F_OK) != 0, "the writer left -wal/-shm behind");
    CHECK(chmod(db, 0444) == 0 && chmod(sub, 0555) == 0);
    if (geteuid() == 0) CHECK(chmod(g_dir, 0755) == 0);
    const char *bin = getenv("SOOC_BIN");
    if (bin && access(bin, X_OK) != 0) bin = NULL;
    if (!bin) printf("SOOC_BIN not built: `sooc3d map list` part skipped\n");
    fflush(stdout);
    pid_t pid = fork();
    if (pid == 0) {
        /* keep g_dir traversable: the child walks into it */
        _exit(ro_child(db, bin));
    }
    int status = 0;
    waitpid(pid, &status, 0);
    int code = WIFEXITED(status) ? WEXITSTATUS(status) : 255;
    CHECK_MSG(code == 0, "read-only child failed: mask %d (1 open, 2 entries, 4 info, 8 map list, 64 "
              "setuid, 128 folder writable)", code);

    /* a -wal holding un-checkpointed transactions: a clear error, not a wrong map */
    CHECK(chmod(sub, 0755) == 0 && chmod(db, 0644) == 0);
    sqlite3 *w = NULL;
    CHECK(sqlite3_open(db, &w) == SQLITE_OK);
    CHECK(sqlite3_exec(w, "PRAGMA wal_autocheckpoint = 0; INSERT INTO meta(key, value) VALUES('x', 'y');",
                       NULL, NULL, NULL) == SQLITE_OK);
    struct stat sb;
    CHECK(stat(wal, &sb) == 0 && sb.st_size > 0);
    CHECK(chmod(sub, 0555) == 0);
    pid = fork();
    if (pid == 0) {
        if (geteuid() == 0 && (setgroups(0, NULL) || setgid(65534) || setuid(65534))) _exit(64);
        if (access(shm, W_OK) == 0) _exit(128);
        sooc_mapstore_params p;
        sooc_mapstore_params_default(&p);
        p.readonly = 1;
        p.create = 0;
        sooc_mapstore *s = NULL;
        sooc_status st = sooc_mapstore_open(&s, db, &p);
        printf("read-only open with a live -wal: %s\n", st ? sooc_errmsg() : "ok");
        fflush(stdout);
        int n = 0;
        if (!st) sooc_mapstore_foreach(s, count_cb, &n);
        sooc_mapstore_close(s);
        /* either it reads the -wal through the -shm the writer keeps, or it
         * says why it cannot; never a silently stale map */
        _exit(st == SOOC_OK ? (n == 3 ? 0 : 1)
                            : (strstr(sooc_errmsg(), db) && strstr(sooc_errmsg(), "-wal") ? 0 : 2));
    }
    waitpid(pid, &status, 0);
    CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "live -wal child: %d", WEXITSTATUS(status));
    sqlite3_close(w);
    CHECK(chmod(sub, 0755) == 0);
}

int main(void) {
    snprintf(g_dir, sizeof g_dir, "/tmp/sooc3d_test_mapstore_access.%d", (int)getpid());
    CHECK(mkdir(g_dir, 0755) == 0);
    test_model_id();
    test_readonly();
    char cmd[700];
    snprintf(cmd, sizeof cmd, "chmod -R u+w '%s'; rm -rf '%s'", g_dir, g_dir);
    if (system(cmd) != 0) fprintf(stderr, "cleanup of %s failed\n", g_dir);
    return check_report("test_mapstore_access");
}
