/* The pose-list layouts: slambook2 (pose.txt, color/, depth/) and Replica as
 * used by NICE-SLAM (traj.txt, results/); docs/formats.md sections 2.3, 2.4. */
#include "seq_impl.h"

#include <stdio.h>
#include <string.h>

/* slambook2 and Replica list one pose a line in one file and name each
 * frame's images by its number; neither has timestamps (30 Hz by index). */
typedef struct list_ctx {
    sooc_seq *s;
    const char *file;
    double tol;
    int64_t lines;    /* pose lines read so far (frame number of the next = lines + first) */
    int64_t skipped;  /* lines whose colour and depth files are both absent */
} list_ctx;

/* Fills the fields every listed frame shares (its pose has been read) and
 * checks that both images exist; rgb and depth are set by the caller. A line
 * whose colour and depth files are both missing is dropped (a trimmed or
 * subsampled copy); only one of them missing is an error. */
static sooc_status list_entry_done(list_ctx *c, int lineno, sooc_seqi_entry *e, int64_t number) {
    e->has_pose = 1;
    e->line = lineno;
    e->src = c->s->srcname[0];
    e->number = number;
    e->t_ns = number * SOOC_SEQI_FRAME_NS;
    if (!e->rgb || !e->depth) return SOOC_ENOMEM;
    if (!sooc_file_exists(e->rgb) && !sooc_file_exists(e->depth)) {
        sooc_free(e->rgb);
        sooc_free(e->depth);
        c->s->n--;
        c->skipped++;
        return SOOC_OK;
    }
    sooc_status st = sooc_seqi_need_file(c->file, lineno, e->rgb);
    if (!st) st = sooc_seqi_need_file(c->file, lineno, e->depth);
    return st;
}

/* Reads the pose list <dir>/<name> with fn (one frame a line; at least
 * one). The list's path goes to s->srcname[0] for per-frame messages. */
static sooc_status read_pose_list(sooc_seq *s, const sooc_seq_open_params *p, const char *name, int need,
                                  sooc_seqi_line_fn fn) {
    char path[4096];
    sooc_status st = sooc_path_join(path, sizeof path, s->dir, name);
    if (st) return st;
    if (need) {
        st = sooc_seqi_need_file(NULL, 0, path);
        if (st) return st;
    }
    snprintf(s->srcname[0], sizeof s->srcname[0], "%s", path);
    list_ctx c = {s, s->srcname[0], p->rot_tol, 0, 0};
    st = sooc_seqi_for_lines(path, fn, &c);
    if (!st && s->n == 0)
        st = sooc_seterr(SOOC_EFORMAT, c.lines ? "%s: none of its %lld frames has its images" : "%s: no poses", path,
                         (long long)c.lines);
    if (!st && c.skipped)
        sooc_log(SOOC_LOG_INFO, "%s: %lld of %lld listed frames have no images (trimmed copy): skipped", path,
                 (long long)c.skipped, (long long)c.lines);
    return st;
}

/* slambook2: pose.txt "tx ty tz qx qy qz qw"; color/<n>.png and
 * depth/<n>.pgm (or .png), n from 1. */
static sooc_status sb_line(void *user, int lineno, char *line) {
    list_ctx *c = user;
    char *tok[10];
    int nt = sooc_seqi_tokenize(line, tok, 8);
    if (nt != 7)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected 7 numbers (tx ty tz qx qy qz qw), got %d", c->file,
                           lineno, nt);
    sooc_seqi_entry *e;
    sooc_status st = sooc_seqi_push(c->s, &e);
    if (st) return st;
    st = sooc_seqi_quat_pose(c->file, lineno, tok, e->T, c->tol);
    if (st) return st;
    int64_t k = ++c->lines; /* numbered from 1 */
    e->rgb = sooc_seqi_frame_path(c->s->dir, "color/", 0, k, ".png", ".jpg");
    e->depth = sooc_seqi_frame_path(c->s->dir, "depth/", 0, k, ".pgm", ".png");
    return list_entry_done(c, lineno, e, k);
}

sooc_status sooc_seqi_open_slambook(sooc_seq *s, const sooc_seq_open_params *p) {
    sooc_status st = read_pose_list(s, p, "pose.txt", 1, sb_line);
    if (!st) st = sooc_seqi_load_calib(s, p, 1);
    return st;
}

/* Replica (NICE-SLAM): traj.txt, a row-major 4x4 a line;
 * results/frame<i>.png (or .jpg) and results/depth<i>.png, i from 0. */
static sooc_status rp_line(void *user, int lineno, char *line) {
    list_ctx *c = user;
    char *tok[20];
    int nt = sooc_seqi_tokenize(line, tok, 16);
    if (nt != 16)
        return sooc_seterr(SOOC_EFORMAT, "%s:%d: expected 16 numbers (row-major 4x4), got %d", c->file, lineno, nt);
    sooc_seqi_entry *e;
    sooc_status st = sooc_seqi_push(c->s, &e);
    if (st) return st;
    for (int k = 0; k < 16; k++)
        if (!sooc_seqi_parse_double(tok[k], &e->T[k]))
            return sooc_seterr(SOOC_EINVAL, "%s:%d: '%s' is not a finite number", c->file, lineno, tok[k]);
    st = sooc_seqi_check_pose4(c->file, lineno, lineno, e->T, c->tol);
    if (st) return st;
    int64_t i = c->lines++; /* numbered from 0 */
    e->rgb = sooc_seqi_frame_path(c->s->dir, "results/frame", 6, i, ".jpg", ".png");
    e->depth = sooc_seqi_frame_path(c->s->dir, "results/depth", 6, i, ".png", NULL);
    return list_entry_done(c, lineno, e, i);
}

sooc_status sooc_seqi_open_replica(sooc_seq *s, const sooc_seq_open_params *p) {
    sooc_status st = read_pose_list(s, p, "traj.txt", 0, rp_line);
    if (st) return st;
    st = sooc_seqi_load_calib(s, p, 0);
    if (st == SOOC_ENOTFOUND) {
        /* NICE-SLAM Replica camera (configs/Replica/replica.yaml) */
        sooc_calib_pinhole(&s->calib, 1200, 680, 600, 600, 599.5, 339.5);
        st = SOOC_OK; /* depth: the format default, 1 / 6553.5 m */
    }
    return st;
}
