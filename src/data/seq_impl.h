/* Internals of the sequence readers (seq.c and the per-layout files
 * seq_list.c, seq_ycb.c, seq_apc.c, seq_write.c); not public API. */
#ifndef SOOC3D_SEQ_IMPL_H
#define SOOC3D_SEQ_IMPL_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#include <stdint.h>

typedef struct sooc_seqi_entry {
    char *rgb, *depth, *inst;     /* full paths (inst may be NULL) */
    int64_t t_ns;
    int has_pose;
    double T[16];
    int line;                     /* line in `src` that listed this frame (0 = none) */
    int64_t number;               /* the frame's number in its file names (TUM: list order) */
    const char *src;              /* file that listed it (points into seq->srcname) */
    int is_query;
    char *pose_err;               /* keep_bad_frames: why its pose file was refused (NULL = fine) */
} sooc_seqi_entry;

/* Format-specific per-frame labels (APC: built from the predicted masks):
 * fills ids (w x h) for frame i; the message names the file on error. */
/* The array sizes a MAT-file's headers declare against the file's size
 * (mat_sizes.c), before libmatio allocates them. f: the whole file. */
sooc_status sooc_seqi_mat_check_sizes(const char *path, const uint8_t *f, size_t size);

typedef sooc_status (*sooc_seqi_labels_fn)(sooc_seq *s, int64_t i, uint16_t *ids, int w, int h);
/* Name of label id, or NULL. */
typedef const char *(*sooc_seqi_label_name_fn)(const sooc_seq *s, int id);

struct sooc_seq {
    sooc_seq_format fmt;
    char dir[2048];
    char srcname[2][4096];        /* list files named in messages */
    sooc_calib calib;
    double depth_scale, max_depth;
    int depth_shift, depth_invalid;
    int depth_circular;           /* the shift rotates the 16 bits (APC) */
    int flip_y;
    int has_gravity;
    double gravity[3];            /* unit vector in the world frame */
    sooc_seqi_entry *e;
    int64_t n, cap, dropped;
    sooc_image img_rgb, img_depth, img_inst;
    /* labels: an instance image per frame (entry inst) or labels_fn (APC) */
    int labels_predicted;         /* those ids are a network's predictions, not ground truth */
    sooc_seqi_labels_fn labels_fn;
    sooc_seqi_label_name_fn label_name_fn;
    void *priv;                   /* the layout's own state, freed by priv_free at close */
    void (*priv_free)(void *priv);
    /* frames made by another reader (sooc_seq_open_source): read from priv */
    sooc_status (*source_read)(void *priv, int64_t i, sooc_frame *f);
};

/* Every call below that fails sets the message (naming the file). */
char *sooc_seqi_join_dup(const char *a, const char *b);
/* Appends a zeroed entry (identity pose) and returns it in *out. */
sooc_status sooc_seqi_push(sooc_seq *s, sooc_seqi_entry **out);
/* Split `line` in place into at most `max` tokens (space, tab, CR, comma);
 * returns max + 1 when there are more. */
int sooc_seqi_tokenize(char *line, char **tok, int max);
/* 1 when t is exactly one finite number. */
int sooc_seqi_parse_double(const char *t, double *v);
/* fn(user, lineno, line) for each line that is not empty and not a # comment. */
typedef sooc_status (*sooc_seqi_line_fn)(void *user, int lineno, char *line);
sooc_status sooc_seqi_for_lines(const char *path, sooc_seqi_line_fn fn, void *user);
/* A 4x4 row-major pose: rotation block orthonormal within tol (reported at
 * line_r), last row 0 0 0 1 (reported at line_last). */
sooc_status sooc_seqi_check_pose4(const char *file, int line_r, int line_last, const double T[16], double tol);
/* tok[0..7) = tx ty tz qx qy qz qw -> T (camera-to-world). */
sooc_status sooc_seqi_quat_pose(const char *file, int line, char **tok, double T[16], double tol);
/* ENOTFOUND "<list>:<line>: <path>: missing file" (or "<path>: missing file"). */
sooc_status sooc_seqi_need_file(const char *list, int line, const char *path);
/* <dir>/<prefix><i, zero-padded to width><ext>, or alt_ext when only that one
 * exists; NULL when out of memory. */
char *sooc_seqi_frame_path(const char *dir, const char *prefix, int width, int64_t i, const char *ext,
                           const char *alt_ext);
/* Layouts without timestamps number their frames; the time stamp of frame
 * i is i / 30 s. Frame numbers have at most SOOC_SEQI_FRAME_DIGITS digits
 * in file names (at most SOOC_SEQI_FRAME_MAX), so that the time stamp fits
 * int64 nanoseconds. */
#define SOOC_SEQI_FRAME_DIGITS 11
#define SOOC_SEQI_FRAME_MAX 99999999999LL
#define SOOC_SEQI_FRAME_NS 33333333LL
/* Calibration from p->calib_path, else <dir>/calib.yaml; ENOTFOUND without a
 * message when neither exists and !required. */
sooc_status sooc_seqi_load_calib(sooc_seq *s, const sooc_seq_open_params *p, int required);

/* The layouts outside seq.c. Each fills s->e (and s->calib, labels) or
 * fails with a message naming the file. */
sooc_status sooc_seqi_open_slambook(sooc_seq *s, const sooc_seq_open_params *p);
sooc_status sooc_seqi_open_replica(sooc_seq *s, const sooc_seq_open_params *p);
sooc_status sooc_seqi_open_ycb(sooc_seq *s, const sooc_seq_open_params *p);
sooc_status sooc_seqi_open_apc(sooc_seq *s, const sooc_seq_open_params *p);
/* sooc_seq_read of a sequence from sooc_seq_open_source (seq_source.c). */
sooc_status sooc_seqi_source_read(sooc_seq *s, int64_t i, sooc_frame *f);
/* Directory entry names of the layouts (for detection): the frame number,
 * or -1 when the name is not a YCB-Video colour image. */
int64_t sooc_seqi_ycb_color_number(const char *name);

#endif
