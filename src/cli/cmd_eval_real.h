/* `sooc3d eval` on recorded sequences (cmd_eval_real.c): the part of the
 * eval command that runs when --data points at recorded sequences (no
 * scene.yaml, no scene_* folders). cmd_eval.c parses the options and calls
 * sooc_cmd_eval_real; docs/metrics.md "Real sequences". */
#ifndef SOOC3D_CMD_EVAL_REAL_H
#define SOOC3D_CMD_EVAL_REAL_H

#include "sooc3d/eval.h"
#include "sooc3d/frame.h"

typedef struct sooc_eval_real_cli {
    const char *const *models;    /* n_models checkpoints                    */
    const char *const *names;     /* row names (the same count)              */
    int n_models;
    const char *const *dirs;      /* recorded sequences                      */
    int n_dirs;
    const char *json, *md;        /* md may be NULL                          */
    sooc_eval_real_opts opts;     /* runner options (run.seed set)           */
    sooc_framepath_params fp;     /* how to read the sequences               */
    const char *panels;           /* NULL, or DIR: DIR/<sequence>/<model>/ gets a panel PNG
                                     and views.csv row per query frame      */
    int quiet;
    const sooc_finetune_params *ft;   /* non-NULL (--finetune): also a '<name>+ft' row per SOOC3D
                                     model and sequence (opts.finetune)     */
    int geometric;                /* 1 (--baseline geometric): a 'geometric' row per sequence,
                                     on the frames of the first model       */
} sooc_eval_real_cli;

/* The usage text of the recorded-sequence options. */
extern const char *const sooc_eval_real_cli_help;

/* 1 if dir is a recorded sequence for eval: neither DIR/scene.yaml nor a
 * DIR/scene_* entry (a `sooc3d gen` dataset or scene). */
int sooc_eval_dir_is_recorded(const char *dir);

/* Run every model on every sequence and write the JSON (and Markdown).
 * Returns the process exit code. */
int sooc_cmd_eval_real(const sooc_eval_real_cli *a);

#endif
