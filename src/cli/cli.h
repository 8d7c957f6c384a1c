/* Shared helpers for the sooc3d subcommands (CLI only: these may print). */
#ifndef SOOC3D_CLI_H
#define SOOC3D_CLI_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"

/* Every subcommand: int sooc_cmd_<name>(int argc, char **argv), argv[0] is
 * the subcommand name. Returns the process exit code. */
typedef int (*sooc_cmd_fn)(int argc, char **argv);

int sooc_cmd_gen(int argc, char **argv);
int sooc_cmd_train(int argc, char **argv);
int sooc_cmd_infer(int argc, char **argv);
int sooc_cmd_eval(int argc, char **argv);
int sooc_cmd_render(int argc, char **argv);
int sooc_cmd_finetune(int argc, char **argv);
int sooc_cmd_mesh(int argc, char **argv);
int sooc_cmd_map(int argc, char **argv);
int sooc_cmd_model(int argc, char **argv);
int sooc_cmd_node(int argc, char **argv);
int sooc_cmd_odometry(int argc, char **argv);
int sooc_cmd_calib(int argc, char **argv);
int sooc_cmd_log(int argc, char **argv);
/* cmd_map_mcap.c: `sooc3d map export --db MAP --mcap FILE` (Foxglove SceneUpdate); exit code. */
int sooc_cli_map_export_mcap(const char *db, const char *out);
/* cmd_map_at.c: `sooc3d map at` (argv as given to `sooc3d map`); exit code. */
int sooc_cli_map_at(int argc, char **argv);
/* A colour for an object id (64..255 per channel), the same in every picture and export. */
void sooc_cli_id_colour(uint64_t id, int rgb[3]);
/* `sooc3d gen --board ...`: board views for calibration (cmd_calib.c). */
int sooc_cmd_gen_board(int argc, char **argv);

/* cmd_mesh.c: meshes of a stored map into dir (`sooc3d mesh`, `sooc3d map export --ply DIR
 * --model M`); box = X0 Z0 X1 Z1 (objects whose floor point lies in it) or NULL. Exit code. */
struct sooc_mesh_opts;
int sooc_cli_mesh_map(const char *cmd, const char *db, const char *model, const char *dir,
                      const struct sooc_mesh_opts *o, const double *box);

/* An output file's folder must exist: 0, or "sooc3d <cmd>: <opt> <path>: the folder <dir> does not exist"
 * (or is not a folder) on stderr and 2. "-" (stdout) passes. */
int sooc_cli_need_parent(const char *cmd, const char *opt, const char *path);
/* Print "sooc3d <cmd>: <status>: <errmsg>" to stderr and return 1. */
int sooc_cli_fail(const char *cmd, sooc_status s);
/* The same for a command that reads a stored map with a model: a map that does not fit (built by
 * another model, or a newer schema: SOOC_EVERSION) is bad input, exit 2; other failures exit 1. */
int sooc_cli_fail_map(const char *cmd, sooc_status s);
/* Open the stored map db read-only for the model file `model` (config mc; the
 * map must have been built with it, as the node checks on resume) and load it
 * into a new cognitive map of the model's sizes. On failure *ms and *map hold
 * what was made (the caller closes / destroys both); with note_model a load
 * failure's message adds "(built with another model than <note_model>?)". */
struct sooc_mapstore;
struct sooc_cogmap;
struct sooc_model_config;
sooc_status sooc_cli_open_stored_map(const char *model, const struct sooc_model_config *mc, const char *db,
                                     const char *note_model, struct sooc_mapstore **ms, struct sooc_cogmap **map);
/* render --map of a map made by a camera without a pose source: each frame's
 * pose from the tracking keyframes stored in db, matched by timestamp (a
 * keyframe's own, else interpolated between the keyframes around it in time;
 * the latest run's when runs overlap), into the world frame by T_world_src. *moved = 0
 * and *n_kf = 0 when the map holds no tracking keyframes (cli_slam.c). */
sooc_status sooc_cli_slam_poses(const char *db, const double T_world_src[16], sooc_frame *fr, int n, int *moved,
                                int64_t *n_kf);
/* True if argv has -h or --help. */
int sooc_cli_wants_help(int argc, char **argv);
/* Parse "C" or "C,F" render sample counts (C >= 2, F >= 0); 1 on success. */
int sooc_cli_parse_samples(const char *s, int *c, int *f);
/* "--merge R": R >= 0 metres, below 100; 0 = never merge (the mapper's default). */
int sooc_cli_parse_merge(const char *s, double *radius);
/* "mean" | "sample" -> SOOC_LATENTS_*; 0 if neither. */
int sooc_cli_parse_latents(const char *s, int *latents);
/* A whole decimal integer in lo..hi (nothing after it); 1 on success, *out untouched otherwise. */
int sooc_cli_parse_int(const char *s, int lo, int hi, int *out);
/* A whole number strtod reads (not NaN) in lo..hi; 1 on success, *out untouched otherwise. */
int sooc_cli_parse_double(const char *s, double lo, double hi, double *out);
/* Option opt of command cmd: as above, else "sooc3d <cmd>: <opt>: expected ... in [lo, hi], got 's'" on stderr, 0. */
int sooc_cli_int_opt(const char *cmd, const char *opt, const char *s, int lo, int hi, int *out);
int sooc_cli_double_opt(const char *cmd, const char *opt, const char *s, double lo, double hi, double *out);
/* A whole unsigned decimal integer in 0..hi (seeds, step and frame counts), with the same message. */
int sooc_cli_u64_opt(const char *cmd, const char *opt, const char *s, uint64_t hi, uint64_t *out);
/* A count in 0..INT64_MAX (train --steps, --max-frames), with the same message. */
int sooc_cli_count_opt(const char *cmd, const char *opt, const char *s, long long *out);
/* "--slots N": object slots per keyframe, 0 (the model's K) or 1..SOOC_MODEL_K_MAX. */
int sooc_cli_parse_slots(const char *s, int *slots);
/* sooc_log callback of the CLI: "[level] message" lines on stderr. */
void sooc_cli_log(void *user, sooc_log_level level, const char *msg);

/* The frame-path options (cli_frames.c, include/sooc3d/frame.h): --calib, --format,
 * --depth-scale, --depth-shift, --min-depth, --max-depth, --up, --world. At argv[*i]:
 * 1 = consumed (with its value, *i advanced), 0 = not one of them, -1 = bad value
 * (message printed). sooc_cli_framepath_check: the range is not empty (0 + message). */
#include "sooc3d/model.h"
extern const char *const sooc_cli_framepath_help;
int sooc_cli_framepath_opt(const char *cmd, int argc, char **argv, int *i, sooc_framepath_params *p);
int sooc_cli_framepath_check(const char *cmd, const sooc_framepath_params *p);
/* The frame path for model c: its input size (img_w x img_h) and its trained
 * camera-height range (config cam_h_min / cam_h_max) for the support-plane warning. */
void sooc_cli_framepath_model(sooc_framepath_params *p, const sooc_model_config *c);

#endif
