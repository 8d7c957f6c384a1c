/*
 * test_fuzz_corpus: replay the committed seed corpus tests/fuzz/corpus/<target>/
 * (and any extra directories/files given) through the fuzz entry points, with
 * any compiler. Under -DSOOC_ASAN=ON this catches memory errors on the seeds
 * and on every past crasher that was fixed and moved into the corpus.
 *
 *   test_fuzz_corpus                       every target, corpus from $SOOC_SRC
 *   test_fuzz_corpus <target> <path>...    one target, given files/folders
 */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fuzz_targets.h"
#include "sooc3d/core.h"

static int n_accepted;
static int verbose;

static int run_file(const sooc_fuzz_target *t, const char *path) {
    void *buf = NULL;
    size_t n = 0;
    if (sooc_file_read_all(path, (size_t)64 << 20, &buf, &n)) {
        fprintf(stderr, "FAIL: cannot read %s: %s\n", path, sooc_errmsg());
        return -1;
    }
    int ok = t->fn(buf, n);
    n_accepted += ok;
    if (verbose) printf("  %s %s%s%s\n", ok ? "accepted" : "rejected", path, ok ? "" : ": ", ok ? "" : sooc_errmsg());
    sooc_free(buf);
    return 1;
}

/* Returns the number of inputs run, or -1 on error. */
static int run_path(const sooc_fuzz_target *t, const char *path) {
    struct stat st;
    if (stat(path, &st)) {
        fprintf(stderr, "FAIL: %s: no such file or directory\n", path);
        return -1;
    }
    if (!S_ISDIR(st.st_mode)) return run_file(t, path);
    DIR *dir = opendir(path);
    if (!dir) return -1;
    /* sorted, so a failure is reproducible in order */
    char **names = NULL;
    int n = 0, cap = 0;
    struct dirent *de;
    while ((de = readdir(dir))) {
        if (de->d_name[0] == '.') continue;
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            names = realloc(names, (size_t)cap * sizeof *names);
            if (!names) abort();
        }
        names[n++] = strdup(de->d_name);
    }
    closedir(dir);
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && strcmp(names[j - 1], names[j]) > 0; j--) {
            char *x = names[j]; names[j] = names[j - 1]; names[j - 1] = x;
        }
    int total = 0;
    for (int i = 0; i < n; i++) {
        char p[4096];
        snprintf(p, sizeof p, "%s/%s", path, names[i]);
        int r = run_file(t, p);
        if (r < 0) total = -1; else if (total >= 0) total += r;
        free(names[i]);
    }
    free(names);
    return total;
}

int main(int argc, char **argv) {
    const char *vb = getenv("SOOC_FUZZ_VERBOSE");
    verbose = vb && *vb && strcmp(vb, "0");
    if (argc >= 2) {
        const sooc_fuzz_target *t = sooc_fuzz_find(argv[1]);
        if (!t) { fprintf(stderr, "unknown target %s\n", argv[1]); return 2; }
        int total = 0;
        for (int i = 2; i < argc; i++) {
            int r = run_path(t, argv[i]);
            if (r < 0) return 1;
            total += r;
        }
        printf("%s: %d inputs OK (%d accepted)\n", t->name, total, n_accepted);
        return 0;
    }
    const char *src = getenv("SOOC_SRC");
    if (!src) src = ".";
    int fails = 0, all = 0;
    for (const sooc_fuzz_target *t = sooc_fuzz_targets; t->name; t++) {
        char dir[4096];
        snprintf(dir, sizeof dir, "%s/tests/fuzz/corpus/%s", src, t->name);
        n_accepted = 0;
        int r = run_path(t, dir);
        if (r <= 0) {
            fprintf(stderr, "FAIL: %s: no corpus in %s\n", t->name, dir);
            fails++;
            continue;
        }
        printf("%-14s %4d inputs OK (%d accepted)\n", t->name, r, n_accepted);
        all += r;
    }
    printf("%d inputs, %d failures\n", all, fails);
    return fails ? 1 : 0;
}
