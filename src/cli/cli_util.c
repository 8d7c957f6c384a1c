/* Helpers every sooc3d command uses (cli.h); linked into the sooc3d binary and
 * into tests/node's sooc3d_node_fake. */
#include "cli.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "sooc3d/cogmap.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int sooc_cli_need_parent(const char *cmd, const char *opt, const char *path) {
    if (!path || !strcmp(path, "-")) return 0;
    char dir[4096];
    sooc_path_parent(path, dir, sizeof dir);   /* "." (the working folder) exists */
    if (sooc_dir_exists(dir)) return 0;
    fprintf(stderr, "sooc3d %s: %s %s: the folder %s %s\n", cmd, opt, path, dir,
            sooc_file_exists(dir) ? "is not a folder" : "does not exist");
    return 2;
}

int sooc_cli_fail(const char *cmd, sooc_status s) {
    fprintf(stderr, "sooc3d %s: error (%s): %s\n", cmd, sooc_status_str(s), sooc_errmsg());
    return 1;
}

int sooc_cli_fail_map(const char *cmd, sooc_status s) {
    sooc_cli_fail(cmd, s);
    return s == SOOC_EVERSION ? 2 : 1;
}

int sooc_cli_wants_help(int argc, char **argv) {
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) return 1;
    return 0;
}

void sooc_cli_log(void *user, sooc_log_level level, const char *msg) {
    (void)user;
    static const char *tag[] = {"debug", "info", "warn", "error", "fatal"};
    fprintf(stderr, "[%s] %s\n", tag[level], msg);
}

int sooc_cli_parse_merge(const char *s, double *radius) {
    char *e;
    double r = strtod(s, &e);
    if (e == s || *e || !(r >= 0) || !(r < 100)) return 0;
    *radius = r;
    return 1;
}

int sooc_cli_parse_latents(const char *s, int *latents) {
    if (!strcmp(s, "mean")) *latents = SOOC_LATENTS_MEAN;
    else if (!strcmp(s, "sample")) *latents = SOOC_LATENTS_SAMPLE;
    else return 0;
    return 1;
}

int sooc_cli_parse_int(const char *s, int lo, int hi, int *out) {
    char *end;
    long v = strtol(s, &end, 10);
    if (end == s || *end || v < lo || v > hi) return 0;
    *out = (int)v;
    return 1;
}

int sooc_cli_parse_double(const char *s, double lo, double hi, double *out) {
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end || !(v >= lo && v <= hi)) return 0; /* NaN fails the range */
    *out = v;
    return 1;
}

/* The one usage message of a bad option value; range is "[lo, hi]". */
static int bad_value(const char *cmd, const char *opt, const char *s, const char *what, const char *range) {
    fprintf(stderr, "sooc3d %s: %s: expected %s in %s, got '%s'\n", cmd, opt, what, range, s);
    return 0;
}

static int bad_number(const char *cmd, const char *opt, const char *s, const char *what, double lo, double hi) {
    char range[80];
    snprintf(range, sizeof range, "[%.15g, %.15g]", lo, hi);
    return bad_value(cmd, opt, s, what, range);
}

int sooc_cli_int_opt(const char *cmd, const char *opt, const char *s, int lo, int hi, int *out) {
    return sooc_cli_parse_int(s, lo, hi, out) || bad_number(cmd, opt, s, "an integer", lo, hi);
}

int sooc_cli_double_opt(const char *cmd, const char *opt, const char *s, double lo, double hi, double *out) {
    return sooc_cli_parse_double(s, lo, hi, out) || bad_number(cmd, opt, s, "a number", lo, hi);
}

int sooc_cli_u64_opt(const char *cmd, const char *opt, const char *s, uint64_t hi, uint64_t *out) {
    char *end;
    errno = 0;
    unsigned long long v = s[0] >= '0' && s[0] <= '9' ? strtoull(s, &end, 10) : 0;
    if (s[0] < '0' || s[0] > '9' || *end || errno || v > hi) {
        char range[48];   /* exact: a double would round 2^64 - 1 */
        snprintf(range, sizeof range, "[0, %llu]", (unsigned long long)hi);
        return bad_value(cmd, opt, s, "an integer", range);
    }
    *out = v;
    return 1;
}

int sooc_cli_count_opt(const char *cmd, const char *opt, const char *s, long long *out) {
    uint64_t v;
    if (!sooc_cli_u64_opt(cmd, opt, s, INT64_MAX, &v)) return 0;
    *out = (long long)v;
    return 1;
}

int sooc_cli_parse_slots(const char *s, int *slots) { return sooc_cli_parse_int(s, 0, SOOC_MODEL_K_MAX, slots); }

/* "C" or "C,F": coarse and fine render samples per ray (C >= 2, F >= 0). */
int sooc_cli_parse_samples(const char *s, int *c, int *f) {
    char *e;
    long a = strtol(s, &e, 10), b = 0;
    if (e == s || a < 2) return 0;
    if (*e == ',') {
        const char *s2 = e + 1;
        b = strtol(s2, &e, 10);
        if (e == s2 || b < 0) return 0;
    }
    if (*e) return 0;
    *c = (int)a;
    *f = (int)b;
    return 1;
}
void sooc_cli_id_colour(uint64_t id, int rgb[3]) {
    uint64_t x = id * 0x9e3779b97f4a7c15ULL;
    x ^= x >> 29;
    x *= 0xbf58476d1ce4e5b9ULL;
    x ^= x >> 32;
    for (int i = 0; i < 3; i++) rgb[i] = 64 + (int)((x >> (8 * i)) & 0xff) * 191 / 255;
}


sooc_status sooc_cli_open_stored_map(const char *model, const sooc_model_config *mc, const char *db,
                                     const char *note_model, sooc_mapstore **ms, sooc_cogmap **map) {
    sooc_status st;
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    mp.readonly = 1;
    char mid[128];   /* the map must have been built with this model (as the node checks on resume) */
    if ((st = sooc_file_id(model, mid, sizeof mid, NULL))) return st;
    mp.model_id = mid;
    if ((st = sooc_mapstore_open(ms, db, &mp))) return st;
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = mc->d_what, cp.layout_dim = mc->d_layout, cp.block_size = (double)mc->block_size * mc->unit_m;
    if ((st = sooc_cogmap_create(map, &cp))) return st;
    if ((st = sooc_mapstore_load_map(*ms, *map))) {
        if (note_model) sooc_adderr(st, "%s (built with another model than %s?)", db, note_model);
        return st;
    }
    return SOOC_OK;
}
