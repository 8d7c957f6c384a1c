/*
 * sooc3d evaluation: the metrics, the evaluation of maps on synthetic
 * scenes (tables, figures, timing) and on real recordings (seen / churn /
 * object IoU).
 *
 * Sections: metrics (metrics); evaluation on synthetic scenes (eval);
 * evaluation on real recordings (eval_real).
 *
 * Contract (CONTRIBUTING.md "Coding rules"), for every section below where
 * the section does not say otherwise. Ownership: the caller owns what it
 * creates and releases it with the matching _destroy / _free / _close
 * (NULL-safe); pointers a getter returns are borrowed and live as long as
 * their object. Threads: an object is used by one thread at a time;
 * functions without an object are reentrant. Errors: a status other than
 * SOOC_OK comes with a message naming the file, key or line (sooc_errmsg);
 * nothing here prints or exits.
 */
#ifndef SOOC3D_EVAL_H
#define SOOC3D_EVAL_H

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "sooc3d/render.h"
#include "sooc3d/train.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== metrics (metrics) ================================================== */

/*
 * sooc3d metrics (docs/metrics.md): mIoU (MulMON best-match and
 * one-to-one Hungarian), RGB / depth RMSE, L2 floor-position error with the
 * matched fraction, recall by distance, and a place for mesh metrics. All are
 * computed per view and accumulated per scale x {input, query}.
 *
 * Pixel set: M = {p : GT depth valid and GT depth <= d_clip} (planar depth,
 * sooc_frame conventions); every per-view metric is restricted to M.
 * Label maps: predictions are int16 component indices (0 = layout /
 * background, 1.. = objects, SOOC_RENDER_LABEL_NONE = -1 = "none"); GT maps
 * are uint16 instance ids with 0 = floor/background (one instance, counted in
 * mIoU like MulMON --use_bg).
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

#define SOOC_METRIC_MAX_GT 256        /* visible GT instances per view            */
#define SOOC_METRIC_MAX_PRED 1024     /* predicted labels per view (0..n_pred-1)  */
#define SOOC_METRIC_IOU_MIN 0.05      /* IoU below this scores 0 (MulMON)         */
#define SOOC_METRIC_N_DBINS 3         /* recall bins: < 3 m, 3-5 m, >= 5 m        */
#define SOOC_METRIC_N_OBINS 8         /* views by visible GT objects: 0..6, >= 7  */

/* ---------------------------------------------------------------- Hungarian */

/* Minimum-cost assignment for a rectangular n x m cost matrix (row-major,
 * finite values). Every row is assigned to a distinct column when n <= m;
 * when n > m every column gets a distinct row and the other rows get -1.
 * O(min(n,m)^2 max(n,m)). assign[n] receives the column of each row or -1;
 * *total (may be NULL) the summed cost of the assigned pairs. */
sooc_status sooc_hungarian(const double *cost, int n, int m, int *assign, double *total);

/* -------------------------------------------------------------------- mIoU */

typedef struct sooc_iou_match {
    int n_gt;                                  /* GT instances with >= 1 pixel in M     */
    uint16_t gt_id[SOOC_METRIC_MAX_GT];        /* their ids, ascending                  */
    int best_pred[SOOC_METRIC_MAX_GT];         /* best-match label, -1 if IoU < 0.05    */
    double best_iou[SOOC_METRIC_MAX_GT];       /* 0 if below 0.05                       */
    int hung_pred[SOOC_METRIC_MAX_GT];         /* one-to-one label, -1 if unmatched     */
    double hung_iou[SOOC_METRIC_MAX_GT];       /* 0 if unmatched or below 0.05          */
    double miou_best, miou_hung;               /* means over the n_gt instances (NaN if 0) */
} sooc_iou_match;

/* mIoU of one view over the n pixels where mask != 0 (mask NULL = all).
 * Best-match (MulMON): IoU_g = max_k |P=k & G=g| / |P=k | G=g| over the
 * predicted labels k >= 0; "none" pixels count in the union, never as a
 * candidate. Hungarian: maximise the summed IoU one-to-one; unmatched GT
 * instances score 0. Both zero IoUs below SOOC_METRIC_IOU_MIN.
 * Fails with SOOC_EINVAL if more than SOOC_METRIC_MAX_GT instances are
 * visible or a label is >= n_pred. */
sooc_status sooc_metric_miou(const int16_t *pred, int n_pred, const uint16_t *gt, const uint8_t *mask,
                             size_t n, sooc_iou_match *out);

/* --------------------------------------------------------------------- RMSE */

/* mask[p] = valid[p] && depth[p] > 0 && depth[p] <= d_clip; returns |M|. */
size_t sooc_metric_valid_mask(const float *gt_depth, const uint8_t *valid, size_t n, double d_clip,
                              uint8_t *mask);
/* RGB RMSE, MulMON's channel-SUM convention: sqrt(mean_{p in M} sum_ch
 * (pred - gt/255)^2), pred in [0, 1]. Divide by sqrt(3) for the per-channel
 * mean convention. NaN if |M| = 0. */
double sooc_metric_rgb_rmse(const float *pred_rgb, const uint8_t *gt_rgb, const uint8_t *mask, size_t n);
/* Depth RMSE in metres: sqrt(mean_{p in M} (pred - gt)^2). NaN if |M| = 0. */
double sooc_metric_depth_rmse(const float *pred, const float *gt, const uint8_t *mask, size_t n);

/* ------------------------------------------------------------ per-view bundle */

/* A GT object of the scene: instance id and floor position (world X, Z) of
 * its bounding-box centre. */
typedef struct sooc_gt_object { uint16_t id; double x, z; } sooc_gt_object;

typedef struct sooc_view_metrics {
    int is_query;
    double miou_best, miou_hung;   /* NaN if no GT instance visible            */
    double rgb_rmse, depth_rmse;   /* NaN if |M| = 0                           */
    double rgb_rmse_obj;           /* RGB RMSE over M & GT id != 0 (objects); NaN
                                      without an instance map or such pixels   */
    int n_gt_visible;              /* GT instances incl. background            */
    int n_obj_visible;             /* GT objects (id != 0) visible             */
    int n_obj_matched;             /* of which matched (best-match IoU >= 0.05) with a position */
    double l2_sum;                 /* sum of floor-plane errors of the matched (m) */
    int recall_hit[SOOC_METRIC_N_DBINS], recall_tot[SOOC_METRIC_N_DBINS];
    size_t n_valid_pixels;
} sooc_view_metrics;

typedef struct sooc_view_eval_in {
    const sooc_frame *gt;          /* rgb, depth, valid, instance (instance may be NULL: no mIoU/L2) */
    const sooc_render_out *pred;   /* rgb, depth, label (same size as gt)                             */
    double d_clip;
    int n_pred;                    /* labels 0..n_pred-1 (= pred->n_comp)                            */
    const double *pred_xz;         /* n_pred x 2 world floor positions per label (NaN = no position,
                                      e.g. the layout); NULL = no L2                                  */
    const sooc_gt_object *gt_obj;  /* GT objects of the scene (may include invisible ones)           */
    int n_gt_obj;
    uint8_t *mask_scratch;         /* optional W*H scratch (else allocated per call); overwritten     */
} sooc_view_eval_in;

/* All per-view metrics. Recall bins use the floor distance from the camera
 * centre (gt->T_wc) to the GT object centre. If match_out is non-NULL it
 * receives the mIoU match (e.g. for pictures). */
sooc_status sooc_metric_view(const sooc_view_eval_in *in, sooc_view_metrics *out,
                             sooc_iou_match *match_out);

/* ------------------------------------------------------------- accumulation */

typedef enum sooc_scale { SOOC_SCALE_S = 0, SOOC_SCALE_M, SOOC_SCALE_L, SOOC_SCALE_XL, SOOC_N_SCALES } sooc_scale;
/* "s"/"small", "m"/"medium", "l"/"large", "xl"/"xlarge"; -1 if unknown. */
int sooc_scale_parse(const char *s);
const char *sooc_scale_name(int scale);   /* "s", "m", "l", "xl" */

/* Mesh metrics (docs/mesh.md). */
typedef struct sooc_mesh_sums {
    long n_obj;                    /* matched objects with a mesh              */
    double acc_cm, comp_cm;        /* sums of accuracy / completeness (cm)     */
    double fscore;                 /* sum of F-score at 5 cm                   */
} sooc_mesh_sums;

/* Object geometry (src/eval/eval_geom.h), per scene of the final map:
 * extent errors of the matched objects in a histogram of SOOC_METRIC_EXT_BIN_CM
 * bins (the last one holds everything above; the median is read from it to
 * within a bin), and the per-axis position errors within one published sigma. */
#define SOOC_METRIC_EXT_BINS 400
#define SOOC_METRIC_EXT_BIN_CM 0.25
typedef struct sooc_geom_sums {
    long ext_hist[SOOC_METRIC_EXT_BINS];
    long n_ext;                    /* matched objects with a tight box         */
    long n_axis, n_axis_within;    /* position error axes, within one sigma     */
    long n_sym, n_sym_agree;       /* symmetry flag agrees with the GT shape    */
} sooc_geom_sums;
/* Add one extent error (cm) to the histogram. */
void sooc_geom_sums_add_extent(sooc_geom_sums *g, double err_cm);

/* Sums over views of one (scale, I/Q) cell. Means: value / count. */
typedef struct sooc_metric_sums {
    long n_views;
    double miou_best, miou_hung; long n_miou;
    double rgb_rmse; long n_rgb;
    double rgb_rmse_obj; long n_rgb_obj;
    double depth_rmse; long n_depth;
    double l2_sum; long n_obj_matched, n_obj_visible;
    long recall_hit[SOOC_METRIC_N_DBINS], recall_tot[SOOC_METRIC_N_DBINS];
    /* best-match mIoU of the views with b visible GT objects (b >= 7 in the last bin) */
    double miou_by_nobj[SOOC_METRIC_N_OBINS]; long n_by_nobj[SOOC_METRIC_N_OBINS];
    sooc_mesh_sums mesh;
    sooc_geom_sums geom;
} sooc_metric_sums;

void sooc_metric_sums_add_view(sooc_metric_sums *s, const sooc_view_metrics *v);
void sooc_metric_sums_merge(sooc_metric_sums *dst, const sooc_metric_sums *src);

/* Means of a cell (NaN where the count is 0). */
typedef struct sooc_metric_means {
    double miou_best, miou_hung, rgb_rmse, depth_rmse;
    double rgb_rmse_obj;           /* mean over views with object pixels        */
    double l2;                     /* mean over matched (object, view) pairs    */
    double matched_frac;           /* n_obj_matched / n_obj_visible             */
    double recall[SOOC_METRIC_N_DBINS];
    double miou_by_nobj[SOOC_METRIC_N_OBINS];   /* NaN where no view has that count */
    long n_by_nobj[SOOC_METRIC_N_OBINS];
    double mesh_acc_cm, mesh_comp_cm, mesh_fscore;
    double extent_err_cm;          /* median extent error of matched objects (cm) */
    double sigma1_frac;            /* position error axes within one sigma       */
    double symmetric_agree;        /* symmetry flag agreeing with the GT shape   */
    long n_views;
} sooc_metric_means;
void sooc_metric_sums_means(const sooc_metric_sums *s, sooc_metric_means *m);

/* Accumulator per scale x {I = 0, Q = 1}. Zero-initialise it. */
typedef struct sooc_metric_acc {
    sooc_metric_sums cell[SOOC_N_SCALES][2];
} sooc_metric_acc;
void sooc_metric_acc_add_view(sooc_metric_acc *a, int scale, const sooc_view_metrics *v);

/* ==== evaluation on synthetic scenes (eval) ============================== */

/*
 * sooc3d evaluation: the paper's tables and the pictures.
 *
 * Tables. Per-view metrics (the metrics section) are accumulated per
 * model x scale x {I, Q} x run. A cell's value for one run is the mean over
 * that run's views (objects for L2); the table reports mean +- std over the
 * runs (sample std, n - 1; 0 for one run). Layout = the paper's Table 1: rows
 * model x {I, Q}, column groups mIoU (best-match), RGB RMSE, depth RMSE, L2,
 * each with the scales present (s, m, l, xl). L2 is shown for query views
 * only, as in the paper (opts). A second table gives the Hungarian mIoU, the
 * matched fraction, recall by distance and the RGB RMSE over object pixels. Outputs: plain text, Markdown,
 * JSON (all cells, all statistics).
 *
 * Pictures (PNG via core.h):
 *  - a panel per view: GT | reconstruction | segmentation | GT segmentation |
 *    depth | GT depth | uncertainty | components;
 *  - the cognitive map from above (paper Figure 3): camera frustums along the
 *    path, map entries coloured by id, out-of-view entries grey, ground-truth
 *    objects overlaid; a PNG per step plus a contact sheet;
 *  - training curves from a CSV log, one line plot per column.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

/* ------------------------------------------------------------------ tables */

typedef struct sooc_eval_table sooc_eval_table;

sooc_status sooc_eval_table_create(sooc_eval_table **out);
void sooc_eval_table_destroy(sooc_eval_table *t);   /* NULL-safe */
/* Free text stored with the table and printed under it, e.g. "input views
 * rendered from the final map". */
sooc_status sooc_eval_table_set_note(sooc_eval_table *t, const char *note);

/* Add one view (v->is_query selects I/Q) to cell (model, scale, run). */
sooc_status sooc_eval_table_add_view(sooc_eval_table *t, const char *model, int scale, int run,
                                     const sooc_view_metrics *v);
/* Merge pre-accumulated sums. */
sooc_status sooc_eval_table_add_sums(sooc_eval_table *t, const char *model, int scale, int run,
                                     int is_query, const sooc_metric_sums *s);

typedef struct sooc_eval_stat { double mean, std; int n_runs; } sooc_eval_stat;
typedef struct sooc_eval_cell {
    sooc_eval_stat miou_best, miou_hung, rgb_rmse, depth_rmse, l2, matched_frac;
    sooc_eval_stat rgb_rmse_obj;       /* RGB RMSE over object pixels (GT id != 0) */
    sooc_eval_stat recall[SOOC_METRIC_N_DBINS];
    sooc_eval_stat mesh_acc_cm, mesh_comp_cm;
    sooc_eval_stat extent_err_cm, sigma1_frac, symmetric_agree;   /* object geometry (eval_geom.h) */
    long n_views;                      /* summed over runs */
    /* mIoU of the views with b visible GT objects (b >= 7 in the last bin),
     * pooled over runs (NaN where no view has that count), and their number */
    double miou_by_nobj[SOOC_METRIC_N_OBINS];
    long n_by_nobj[SOOC_METRIC_N_OBINS];
} sooc_eval_cell;
/* Statistics over runs of one cell; SOOC_ENOTFOUND if it has no data. */
sooc_status sooc_eval_table_cell(const sooc_eval_table *t, const char *model, int scale, int is_query,
                                 sooc_eval_cell *out);
/* Composition-matched mIoU (direct standardisation): the cell's mIoU per
 * visible-object count, weighted by how many views of the reference scale
 * (same model and view type) have that count. It answers "what would this
 * scale score on views that hold as many objects as the reference scale's",
 * since best-match mIoU falls with the objects a view holds (docs/metrics.md).
 * Counts the reference has but the cell lacks are left out and the weights
 * renormalised; *coverage (may be NULL) receives the reference weight used.
 * SOOC_ENOTFOUND if either cell has no data. */
sooc_status sooc_eval_table_miou_matched(const sooc_eval_table *t, const char *model, int scale, int is_query,
                                         int ref_scale, double *miou, double *coverage);

/* Formatted table in a sooc_malloc'd, NUL-terminated string (caller frees). */
sooc_status sooc_eval_table_text(const sooc_eval_table *t, char **out);
sooc_status sooc_eval_table_markdown(const sooc_eval_table *t, char **out);
sooc_status sooc_eval_table_json(const sooc_eval_table *t, char **out);
/* Write JSON and/or Markdown atomically (either path may be NULL). */
sooc_status sooc_eval_table_write(const sooc_eval_table *t, const char *json_path, const char *md_path);

/* One evaluation view end to end: render `f` for gt's intrinsics with T_fc
 * (camera -> field frame), then score against gt with d_clip = ro->d_clip
 * (sooc_metric_view; n_pred = f->n_comp). pred_xz: world floor position per
 * component (NaN for the layout), may be NULL. `out` keeps the render (for
 * panels). This is the call `sooc3d eval` makes per view. */
sooc_status sooc_eval_view(const sooc_field *f, const double T_fc[16], const sooc_frame *gt,
                           const sooc_render_opts *ro, const double *pred_xz,
                           const sooc_gt_object *gt_obj, int n_gt_obj, sooc_render_out *out,
                           sooc_view_metrics *vm, sooc_iou_match *match);

/* ---------------------------------------------------------------- pictures */

typedef struct sooc_panel_opts {
    int scale;                 /* magnification of every tile (default 2)            */
    double d_clip;             /* depth colour range [0, d_clip] (default 8)         */
    int max_components;        /* component tiles shown (default 8)                  */
    const uint32_t *comp_ids;  /* colour id per component (map entry id), or NULL:
                                  component k gets colour id k                        */
    const char *title;         /* may be NULL                                        */
} sooc_panel_opts;
void sooc_panel_opts_default(sooc_panel_opts *o);

/* Panel of one view. gt may be NULL (no GT tiles); r must hold rgb, depth and
 * label, optionally uncert and comp_rgb/comp_alpha. */
sooc_status sooc_eval_panel(sooc_image *out, const sooc_frame *gt, const sooc_render_out *r,
                            const sooc_panel_opts *o);

/* Ground-truth object for the top-down figure: floor centre, yaw and size. */
typedef struct sooc_fig_gt {
    uint16_t id;
    double x, z, yaw, size_x, size_z;
} sooc_fig_gt;

/* One step of an online run: the camera and the map after its update. */
typedef struct sooc_topdown_step {
    double T_wc[16];
    const sooc_map_entry *entries;
    size_t n_entries;
} sooc_topdown_step;

typedef struct sooc_topdown_opts {
    double px_per_m;           /* default 40                                          */
    double xmin, xmax, zmin, zmax;  /* world window; all 0 = fit cameras, entries, GT */
    double d_clip;             /* frustum length and in-view range (default 8)        */
    const sooc_intrinsics *K;  /* camera field of view (required)                      */
    float min_presence;        /* entries below are not drawn (default 0.5)           */
    const char *title;
} sooc_topdown_opts;
void sooc_topdown_opts_default(sooc_topdown_opts *o);

/* The map at step `cur` of steps[0..n_steps): frustums of steps <= cur (the
 * current one highlighted), entries of steps[cur] coloured by id
 * (sooc_cmap_id) or grey when outside the current frustum, GT as outlines. */
sooc_status sooc_eval_topdown(sooc_image *out, const sooc_topdown_step *steps, int n_steps, int cur,
                              const sooc_fig_gt *gt, int n_gt, const sooc_topdown_opts *o);
/* Write <dir>/cogmap_0000.png ... and <dir>/cogmap_sheet.png (at most 24
 * evenly spaced steps on the sheet). */
sooc_status sooc_eval_topdown_sequence(const char *dir, const sooc_topdown_step *steps, int n_steps,
                                       const sooc_fig_gt *gt, int n_gt, const sooc_topdown_opts *o);

/* Training curves: a CSV with a header row; the column named "step" (else the
 * row number) is x; every other numeric column becomes one line plot (log
 * scale when all values are positive and span > 100x). Writes one PNG grid. */
sooc_status sooc_eval_plot_csv(const char *csv_path, const char *png_path, const char *title);


/* ------------------------------------------------- the scene runner (run.c)
 *
 * The ONE evaluation path of sooc3d: `sooc3d eval`,
 * `sooc3d render` and the trainer's validation all go through it.
 *
 * sooc_eval_run_scene(m, frames, ...): online inference over the scene's
 * input views in trajectory order with a fresh mapper (an empty cognitive
 * map), then every view is rendered with the dense renderer and scored
 * (sooc_eval_view):
 *   - query views always from the FINAL map;
 *   - input views from the final map (SOOC_EVAL_FINAL), right after their own
 *     update (SOOC_EVAL_ONLINE, MulMON's protocol), or both (docs/metrics.md).
 * L2: the components matched to GT objects by that view's best-match mIoU
 * (IoU >= 0.05) take the world floor position (X, Z) of their map entry
 * (sooc_model_field_comp_id -> sooc_cogmap_get), compared with the GT
 * object's floor position (sooc_metric_view).
 *
 * Model ownership: the runner never modifies `m`. It makes a private copy
 * (same config, parameters memcpy'd) that its mapper owns and frees, so `m`
 * can be shared by successive calls (and, read-only, by other threads).
 *
 * Determinism: the result depends only on (m, frames, gt, opts) and the
 * thread count of the model (opts->threads; the renderer itself is
 * thread-count independent): the mapper's posterior sampling is seeded with
 * opts->seed, rendering uses deterministic midpoints, and the uncertainty
 * samples use RNG streams derived from (seed, frame index, sample).
 */
typedef enum sooc_eval_timing {
    SOOC_EVAL_FINAL = 1,       /* input views rendered from the final map              */
    SOOC_EVAL_ONLINE = 2,      /* input views rendered right after their own update    */
    SOOC_EVAL_BOTH = 3         /* both (input views are scored twice)                  */
} sooc_eval_timing;
/* "final", "online", "both" -> timing; -1 if unknown. */
int sooc_eval_timing_parse(const char *s);
/* One sentence for a table note, e.g. "input views rendered from the final
 * map (after all input views); query views always from the final map". */
const char *sooc_eval_timing_note(sooc_eval_timing t);

typedef struct sooc_eval_run_opts {
    uint64_t seed;             /* mapper seed (ray offsets, posterior samples)          (1) */
    int iterations;            /* L refinement updates per input view; 0 = model's L    (0) */
    sooc_eval_timing timing;   /* input-view timing                                 (FINAL) */
    int n_coarse, n_fine;      /* render samples per ray                           (96, 32) */
    int max_views;             /* > 0: map only the first max_views input views and score
                                  them plus the query views whose nearest input camera is
                                  one of them; 0 = all views                             (0) */
    int max_obj;               /* > 0: render at most this many in-view map entries (top by
                                  presence); 0 = every in-view entry, up to 63 (docs/metrics.md:
                                  "layout plus in-view objects"; the K-slot limit is for the
                                  refinement, not the rendering)                         (0) */
    int threads;               /* model and renderer threads; 0 = OpenMP default        (0) */
    double d_clip;             /* > 0: clip depth for inference and scoring instead of the
                                  model's (sooc_model_set_clip); 0 = the model's         (0) */
    double merge_radius;       /* SOOC3D mapper's duplicate merge radius (m); <= 0 = off (0) */
    int revisit;               /* SOOC3D mapper: the node's revisit rules with merge_radius
                                  (sooc_mapper_set_merge_neighbours; docs/cogmap.md) (0) */
    double gate[3];            /* SOOC3D mapper, with revisit: the creation gate's min_rays,
                                  ratio, part (sooc_mapper_set_gate: 0 = default, < 0 =
                                  that test off; docs/cogmap.md "Revisits" rule 5) (0, 0, 0) */
    int latents;               /* SOOC3D mapper: SOOC_LATENTS_MEAN / _SAMPLE          (MEAN) */
    int slots;                 /* SOOC3D models: object slots per keyframe (sooc_model_copy_slots);
                                  0 = the model's setting (config.slots, else K); ignored
                                  for the global-frame baseline                        (0) */
    int invalid_depth;         /* 0 = the model's config.invalid_depth; 1 + SOOC_INVALID_DEPTH_*
                                  overrides it (2 = holes unknown; docs/model.md)       (0) */
    const struct sooc_scene *scene;  /* the scene's description (scene.yaml) or NULL: with it, the
                                  final map's mesh accuracy / completeness (render.h
                                  sooc_mesh_eval_scene) go into the mesh sums of every cell
                                  of the scene (input and query rows)                   (NULL) */
    int mesh_res;              /* samples per box axis for those meshes; 0 = 64         (0) */
    /* extras, only for the views flagged in detail_views (NULL = every view): */
    int components;            /* 1 = per-component images in the render (panels)       (0) */
    int uncertainty;           /* M >= 2: uncertainty map from M posterior samples      (0) */
    const uint8_t *detail_views;  /* n_frames flags, or NULL                          (NULL) */
    const uint8_t *render_views;  /* n_frames flags: only these views are rendered and scored
                                  (the rest are mapped, not rendered); NULL = every view (NULL) */
    /* SOOC3D+: after online inference, finetune every object and
     * layout block of the map by EM on the input views (train.h), then score
     * the views from the finetuned map; NULL = no finetuning              (NULL) */
    const struct sooc_finetune_params *finetune;
    /* with finetune: births first (train.h "births"): entries for what the
     * map does not draw in the input views; NULL = none                  (NULL) */
    const struct sooc_birth_params *birth;
    /* SOOC3D mapper: geometric proposals for the new slots (mapper.h
     * sooc_mapper_set_proposals; docs/geometric.md); NULL = off       (NULL) */
    const struct sooc_proposal_params *proposals;
    /* SOOC3D mapper: geometric support of the entries (mapper.h
     * sooc_mapper_set_support): on with this margin in m; 0 = off     (0) */
    double geo_support_m;
    /* SOOC3D: the views scored from the final map are segmented by the
     * entries' observed surfaces (sooc_eval_surface_view): the mapped frames
     * clustered with these parameters, each object voxel claimed by the
     * densest entry; NULL = the model's own labels                    (NULL) */
    const struct sooc_cluster_params *surface;
    sooc_surface_params surface_p;   /* with surface: the claims       (the defaults) */
    int surface_boxes;         /* SOOC3D mapper with geo_support_m: observed-surface planner
                                  boxes (sooc_mapper_set_surface_boxes)                  (0) */
} sooc_eval_run_opts;
void sooc_eval_run_opts_default(sooc_eval_run_opts *o);

/* Reported once per rendered and scored view. Pointers are valid during the
 * callback only. */
typedef struct sooc_eval_view_info {
    int frame;                 /* index into frames[]                                   */
    const sooc_frame *gt;
    int online;                /* 1 = an input view rendered right after its own update */
    int n_mapped;              /* input views mapped when it was rendered               */
    const sooc_render_out *render;   /* rgb, depth, alpha, label (+ comp_*, uncert)      */
    const sooc_view_metrics *metrics;
    const sooc_iou_match *match;     /* NULL when the frame has no instance ids          */
    int n_comp;                /* components rendered (0 = layout)                      */
    const uint64_t *comp_ids;  /* map entry id per component (0 for the layout)          */
    const double *comp_xz;     /* world (X, Z) per component (NaN for the layout)        */
} sooc_eval_view_info;
typedef sooc_status (*sooc_eval_view_fn)(void *user, const sooc_eval_view_info *v);

/* Reported after each input view's update: the map at that moment (for the
 * top-down figure). */
typedef struct sooc_eval_step_info {
    int step;                  /* 0.. input views mapped so far - 1                     */
    int frame;                 /* index into frames[]                                   */
    const sooc_frame *gt;
    const sooc_update_stats *stats;
    const sooc_map_entry *entries;   /* the whole map after the update, by id             */
    size_t n_entries;
} sooc_eval_step_info;
typedef sooc_status (*sooc_eval_step_fn)(void *user, const sooc_eval_step_info *s);

/* Summed per-view metrics of one scene (sooc_metric_sums: means = sum/count). */
typedef struct sooc_eval_scene_result {
    sooc_metric_sums input_final;    /* input views from the final map (FINAL, BOTH)     */
    sooc_metric_sums input_online;   /* input views right after their update (ONLINE, BOTH) */
    sooc_metric_sums query;          /* query views, from the final map                   */
    int n_mapped, n_query;           /* input views mapped, query views scored            */
    size_t n_entries;                /* map entries at the end                            */
    double update_s, render_s;       /* time in mapper updates and in render + scoring    */
    double mesh_s;                   /* time in the mesh metric (opts.scene)               */
    int mesh_objects, mesh_empty;    /* objects it averaged / matched with an empty mesh   */
    double finetune_s;               /* time in finetuning (opts.finetune)                */
    int n_born;                      /* entries born before finetuning (opts.birth)       */
    int n_pruned;                    /* entries removed after it (no density; with births) */
} sooc_eval_scene_result;

/* Run one scene (see above). frames[0..n_frames): trajectory order, input
 * and query views (is_query) in any interleaving, all with poses, of the
 * model's resolution (img_w x img_h); frames without instance ids get no
 * mIoU/L2. gt: the scene's GT objects (may be NULL / 0). view_cb / step_cb /
 * res may be NULL. A callback's non-OK status stops the run and is returned. */
sooc_status sooc_eval_run_scene(sooc_model *m, const sooc_frame *frames, int n_frames,
                                const sooc_gt_object *gt, int n_gt, const sooc_eval_run_opts *o,
                                sooc_eval_view_fn view_cb, sooc_eval_step_fn step_cb, void *user,
                                sooc_eval_scene_result *res);

/* The geometric baseline on one scene (mapper.h, docs/geometric.md): the
 * input views (is_query 0) go into one support-plane cluster map; every view
 * is rendered from it (label 0 the plane and the surround, 1.. its objects)
 * and scored by sooc_metric_view with clip d_clip (m), into res->input_final
 * and res->query; n_entries = its objects. cp NULL = defaults. */
struct sooc_cluster_params;
sooc_status sooc_eval_geometric_scene(const sooc_frame *frames, int n_frames, const sooc_gt_object *gt, int n_gt,
                                      const struct sooc_cluster_params *cp, double d_clip,
                                      sooc_eval_scene_result *res);

/* Render and score one view from a given map (what the runner does per view;
 * `sooc3d render --map` uses it with a map loaded from SQLite). `detail` asks
 * for the extras of o (components, uncertainty); uncertainty sample s uses an
 * RNG seeded from (o->seed, s, gt->index). Fills out (reallocated as
 * needed), vm, match (may be NULL), and if non-NULL comp_ids / comp_xz
 * (room for SOOC_RENDER_MAX_COMP / 2 x that) and *n_comp. */
sooc_status sooc_eval_map_view(sooc_model *m, const sooc_cogmap *map, const sooc_frame *gt,
                               const sooc_gt_object *gt_obj, int n_gt, const sooc_eval_run_opts *o,
                               int detail, sooc_render_out *out, sooc_view_metrics *vm,
                               sooc_iou_match *match, uint64_t *comp_ids, double *comp_xz, int *n_comp);

/* How well the planner's boxes (sooc_map_entry_box, sooc_map_entry_height)
 * fit labelled object id: its points are its labelled pixels with valid depth
 * in frames[i] with use[i] (use NULL: every frame), in the world frame, 5 mm or more above the
 * support plane; its entry is the one of e[0..ne) whose box holds most of
 * them. cover: the fraction its box holds (0: no box holds any); height_err_m:
 * the box's height minus the points' (their 98th percentile); area_ratio: the
 * box's floor area over the points' floor rectangle on the entry's axes
 * (from their 5th to their 95th percentile on each axis).
 * NaN (entry 0) with fewer than 20 points. */
typedef struct sooc_box_fit {
    uint64_t entry;
    int n_points;
    double cover, height_err_m, area_ratio;
} sooc_box_fit;
sooc_status sooc_eval_box_fit(const sooc_map_entry *e, size_t ne, const sooc_frame *frames, int n,
                              const uint8_t *use, uint16_t id, sooc_box_fit *out);

/* The support-plane clusters of frames[i] with use[i] (use NULL: every
 * frame) with parameters cp (NULL: the defaults), segmented: the geometric
 * row's map and the one the entries' observed surfaces are drawn from. */
sooc_status sooc_eval_cluster_map(const struct sooc_cluster_params *cp, const sooc_frame *frames, int n,
                                  const uint8_t *use, sooc_cluster_map **out);
/* The entries' observed surfaces (docs/geometric.md "The entries' observed
 * surfaces") of view gt: cm (sooc_eval_cluster_map of the mapped frames) is
 * claimed by the entries of the field that draws gt's camera from map
 * (sooc_surface_claim_frame, max_obj as sooc_eval_map_view, sp NULL: the
 * defaults), rendered into gt's camera, and becomes out->label: a pixel that
 * shows a claimed voxel takes its entry's component, any other the
 * background (out: a render of the same view from the same map,
 * sooc_eval_map_view, whose components and comp_xz are the same). The view
 * is then scored again (gt_obj as sooc_eval_map_view) into vm and match (may
 * be NULL). */
sooc_status sooc_eval_surface_view(sooc_model *m, const sooc_cogmap *map, sooc_cluster_map *cm,
                                   const sooc_frame *gt, const sooc_gt_object *gt_obj, int n_gt, int max_obj,
                                   const sooc_surface_params *sp, double d_clip, const double *comp_xz,
                                   sooc_render_out *out, sooc_view_metrics *vm, sooc_iou_match *match);

/* Which object a camera sees at each pixel of a stored map (`sooc3d map at`).
 * ids (K->height x K->width, row-major) gets the map entry id whose surface
 * the ray through the pixel's centre meets first, 0 where it meets none;
 * depth (optional, may be NULL) the planar depth of that hit in metres, NaN
 * where none. T_wc: camera (OpenCV optical) to the map's world frame.
 *  - boxes: the planner's boxes of n entries (sooc_map_entry_box), the
 *    nearest box the ray enters; any map, no model needed.
 *  - model: the map rendered by the model it was built with (the argmax
 *    component where the accumulated opacity reaches 0.5, as the panels of
 *    `sooc3d render` show it); threads as sooc_render_opts.threads. The
 *    objects in view are those of the camera K_view (NULL = K): to ask
 *    for part of a view (one pixel), K is that part (its principal point
 *    shifted) and K_view the whole view.
 * Both fail with SOOC_EINVAL on a missing argument or an empty image. */
sooc_status sooc_map_pick_boxes(const sooc_map_entry *e, size_t n, const double T_wc[16], const sooc_intrinsics *K,
                                uint64_t *ids, float *depth);
sooc_status sooc_map_pick_model(sooc_model *m, const sooc_cogmap *map, const double T_wc[16],
                                const sooc_intrinsics *K, const sooc_intrinsics *K_view, int threads, uint64_t *ids,
                                float *depth);

/* A private copy of a model (same config and parameters; the caller owns it). */
sooc_status sooc_eval_model_copy(sooc_model *m, sooc_model **out);

/* ==== evaluation on real recordings (eval_real) ========================== */

/*
 * sooc3d metrics for real recorded sequences (docs/metrics.md "Real
 * sequences").
 *
 * A recorded sequence has no scene.yaml: no GT objects, no designated query
 * views, often no labels. The runner (sooc_eval_real_run) holds out query
 * frames by a fixed rule (sooc_eval_real_is_query: every N-th frame, never
 * mapped), maps the others in order with a fresh SOOC3D mapper, renders the
 * query frames from the final map and scores them (depth and RGB RMSE, and
 * mIoU plus the IoU of each labelled object when the frames carry labels),
 * then measures what needs no labels:
 *   - churn: entries at the end and entries ever created;
 *   - growth: the same input frames mapped a second time into the same map;
 *   - spread: the RMS position and circular yaw spread of persistent entries
 *     over the keyframes that registered them;
 *   - seen: whether each final entry lies where the sensor saw free space, a
 *     surface, or never looked (sooc_eval_entry_seen: sooc_eval_point_seen
 *     at the entry's probe points, sooc_eval_entry_probes).
 *
 * Every building block is a plain function testable on hand-made frames.
 * No function prints or exits; errors are sooc_status codes with messages.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

/* ---------------------------------------------------------------- query rule */

/* Default N of the query rule: label-fusion (15 frames) gets 3 query frames,
 * the 7-Scenes excerpt (300 frames) 60. */
#define SOOC_REAL_QUERY_EVERY 5

/* The query rule: the frame at position `pos` (0-based, sequence order) is a
 * held-out query frame iff every >= 2 and pos % every == every / 2 (the
 * middle of each block of N frames, so the first frame is always mapped and
 * every query frame has mapped neighbours on both sides). every <= 1: no
 * query frames. */
int sooc_eval_real_is_query(int pos, int every);

/* ------------------------------------------------------ free / surface / never */

typedef enum sooc_seen_class {
    SOOC_SEEN_NEVER = 0,     /* no frame saw the point (outside every view, behind every
                                surface the frames measured, or invalid depth there)     */
    SOOC_SEEN_FREE = 1,      /* more frames saw through it (free space) than on a surface */
    SOOC_SEEN_SURFACE = 2    /* at least as many frames saw a surface at it as saw free   */
} sooc_seen_class;
const char *sooc_seen_class_name(sooc_seen_class c);   /* "never", "free", "surface" */

typedef struct sooc_seen_votes {
    int n_in_view;           /* frames whose image holds the point (in front, >= 0.1 m)   */
    int n_free;              /* ... with valid depth d there and z < d - tol              */
    int n_surface;           /* ... with |z - d| <= tol                                   */
    int n_behind;            /* ... with z > d + tol (occluded: no evidence)              */
    double min_behind;       /* smallest z - d over the frames with valid depth there (m;
                                > tol when every such frame saw it occluded); NaN if none */
    sooc_seen_class cls;
} sooc_seen_votes;

/* Test a world point p_w against n posed depth frames: project it with each
 * frame's T_wc and K (nearest pixel), compare its camera z with the frame's
 * planar depth d there (valid pixels only). tol in metres (> 0). Frames
 * without a pose are skipped. */
sooc_status sooc_eval_point_seen(const double p_w[3], const sooc_frame *frames, int n, double tol,
                                 sooc_seen_votes *out);

/* Where an entry lies, for the seen test (world, y up, support plane y = 0).
 * An entry with a tight box of its own density (geom.flags TIGHT and not
 * EMPTY; mapper.h) is probed at 7 points: the box's centre and the centres
 * of its 6 faces (the box is tight, so a face centre sits on or next to the
 * density's surface), carried by its floor pose, X + R_y(yaw) p. An entry
 * without one (not computed, or EMPTY: no density at the surface level) is
 * probed at one point, (X, seen_height, Z). sooc_eval_entry_probes writes
 * the points to p_w (room for SOOC_ENTRY_PROBES_MAX) and returns their count.
 * An object's density may sit anywhere up its locality box (a counter 0.9 m
 * high stands on the floor its frame stands on), and its centre lies up to
 * half its depth behind its visible face, so a fixed height, or the centre
 * alone, would probe where no camera can look. */
#define SOOC_ENTRY_PROBES_MAX 7
int sooc_eval_entry_probes(const sooc_map_entry *e, double seen_height, double p_w[][3]);

/* The seen class of an entry: SURFACE when any of its probe points is a
 * surface point (sooc_eval_point_seen), else FREE when any is free, else
 * NEVER. The counts of `out` are summed over the points, min_behind is the
 * smallest over them. */
sooc_status sooc_eval_entry_seen(const sooc_map_entry *e, double seen_height, const sooc_frame *frames, int n,
                                 double tol, sooc_seen_votes *out);

/* The seen class of a surface given as points (an entry's own mesh vertices,
 * xyz[3 i], world frame): up to max_probes of the n points, evenly spaced
 * in index, each tested by sooc_eval_point_seen. pts[class] counts the probed
 * points by class; *cls is SURFACE when at least as many points are surface
 * points as free ones and some are, FREE when more are free, NEVER when none
 * is either (n = 0 included). Open shapes (a chair, a table's edge) and boxes
 * larger than their contents have box probes in the air around a surface
 * the sensor saw; their own surface does not. */
sooc_status sooc_eval_points_seen(const float *xyz, size_t n, int max_probes, const sooc_frame *frames, int n_frames,
                                  double tol, int pts[3], sooc_seen_class *cls);

/* ------------------------------------------------------------- spread */

/* Position / yaw track of one entry over the keyframes that registered it
 * (Welford for position; unit vectors for yaw). Zero-initialise. */
typedef struct sooc_track {
    long n;
    double mx, mz, m2;        /* running mean of x, z; summed squared distance to it */
    double sc, ss;            /* sums of cos(yaw), sin(yaw)                          */
} sooc_track;
void sooc_track_add(sooc_track *t, double x, double z, double yaw);
/* pos_rms: sqrt(mean |p - mean p|^2) on the floor (m); yaw_std: circular
 * std sqrt(-2 ln R), R = |mean of exp(i yaw)| (rad). Both NaN if n == 0. */
void sooc_track_spread(const sooc_track *t, double *pos_rms, double *yaw_std);

/* --------------------------------------------------------------- churn */

typedef struct sooc_churn {
    long updates;
    long created;             /* entries created that were still in the map after their update */
    long removed;             /* entries removed that an earlier update had created            */
} sooc_churn;
/* Account one update: `born` = the mapper's next id before it, reg_ids the
 * entries it registered, rem_ids the ids it removed (sooc_mapper_changed).
 * An id >= born that is also removed was merged away within the update: it
 * never was in the map and counts as neither. */
void sooc_churn_update(sooc_churn *c, uint64_t born, const uint64_t *reg_ids, size_t n_reg,
                       const uint64_t *rem_ids, size_t n_rem);

/* ------------------------------------------------------- per-object IoU */

/* Per labelled object (GT id != 0): the best-match IoU (sooc_metric_miou,
 * IoU < 0.05 -> 0) summed over the views where the object is visible.
 * Zero-initialise. Ids kept ascending. */
typedef struct sooc_obj_iou_acc {
    int n;
    uint16_t id[SOOC_METRIC_MAX_GT];
    double sum[SOOC_METRIC_MAX_GT];
    long views[SOOC_METRIC_MAX_GT];
} sooc_obj_iou_acc;
sooc_status sooc_obj_iou_add(sooc_obj_iou_acc *a, const sooc_iou_match *m);
/* Mean IoU of object k (0 <= k < a->n); NaN if it was never visible. */
double sooc_obj_iou_mean(const sooc_obj_iou_acc *a, int k);

/* ------------------------------------------------------------- labels */

/* Read a label image: an 8-bit PNG (label-fusion segm.png, object ids 1..255)
 * or a 16-bit PNG (the generic instance/ layout); 0 = background. *ids is
 * (re)allocated with sooc_realloc (pass NULL or an earlier buffer). RGB
 * images are refused with a message naming the file. */
sooc_status sooc_eval_labels_read(const char *path, uint16_t **ids, int *w, int *h);
/* SOOC3D+ on a runner's map (both runners' +ft step): births (bp != NULL,
 * train.h), then finetuning by EM on the frames with use[i] != 0, then
 * (with births) every entry that explains nothing is removed
 * (sooc_birth_prune_all). cb (may be NULL) gets progress every 50 steps.
 * *n_born / *n_pruned: entries born / removed after finetuning. */
sooc_status sooc_eval_finetune_map(sooc_model *m, sooc_cogmap *map, const sooc_frame *frames, int n_frames,
                                   const uint8_t *use, const sooc_finetune_params *fp, const sooc_birth_params *bp,
                                   int threads, sooc_finetune_progress_fn cb, void *user, int *n_born, int *n_pruned);
/* Nearest-neighbour resample of a label map: destination pixel (u, v) of a
 * dw x dh image takes source pixel (x0 + floor((u + 0.5) cw / dw),
 * y0 + floor((v + 0.5) ch / dh)), i.e. the crop [x0, x0+cw) x [y0, y0+ch)
 * scaled to dw x dh like the frame. The crop must lie inside the source. */
sooc_status sooc_eval_labels_resample(const uint16_t *src, int sw, int sh, int x0, int y0, int cw, int ch,
                                      uint16_t *dst, int dw, int dh);

/* -------------------------------------------------------------- the runner */

typedef struct sooc_eval_real_opts {
    sooc_eval_run_opts run;    /* seed, iterations, samples, clip, merge, latents, slots, threads,
                                  max_obj (timing and max_views are not used)                 */
    int query_every;           /* the query rule's N (>= 2)                (SOOC_REAL_QUERY_EVERY) */
    int second_pass;           /* 1 = map the input frames again (growth)                  (1) */
    double seen_tol;           /* depth band of a surface (m)                            (0.25) */
    double seen_height;        /* height above the support plane at which an entry without a
                                  tight box is tested (sooc_eval_entry_probes; m)         (0.1) */
    int persist_min;           /* entries registered by at least this many keyframes (and in
                                  the final map) are persistent                            (3) */
    int own_surface;           /* 1 = the seen test also by each final entry's own surface:
                                  its mesh (sooc_mesh_object, 32 samples per axis) probed at
                                  up to 64 vertices (sooc_eval_points_seen; SOOC3D only)   (1) */
    const sooc_finetune_params *finetune;   /* non-NULL: SOOC3D+. After pass 1 every entry and
                                  layout block of the map is finetuned by EM on the mapped
                                  frames (train.h), then the query frames, spreads and the
                                  seen test are scored on the finetuned map; no second pass
                                  (SOOC3D models only)                                  (NULL) */
    sooc_finetune_progress_fn ft_progress;  /* with finetune: called every 50 steps (NULL) */
    void *ft_user;
    int labels_predicted;      /* 1: the labels are a network's predictions (APC masks,
                                  sooc_seq_labels_predicted): the JSON says "labels":
                                  "predicted" and its scores are agreement with them  (0) */
} sooc_eval_real_opts;
void sooc_eval_real_opts_default(sooc_eval_real_opts *o);
/* 1 when the runner maps the input frames a second time (growth): asked for,
 * and not a finetuned run. */
static inline int sooc_eval_real_second_pass(const sooc_eval_real_opts *o) { return o->second_pass && !o->finetune; }

typedef struct sooc_eval_real_result {
    int n_frames, n_mapped, n_query;
    int has_labels;                /* every query frame carried labels                   */
    sooc_metric_sums query;        /* query frames from the pass-1 map (means = sum/count) */
    sooc_obj_iou_acc obj;          /* labelled objects over the query frames             */
    sooc_box_fit obj_box[SOOC_METRIC_MAX_GT];   /* their planner boxes, final map (obj order) */
    size_t entries_final;          /* entries after pass 1                               */
    sooc_churn churn;              /* pass 1                                             */
    size_t entries_pass2;          /* entries after pass 2 (= entries_final without it)  */
    sooc_churn churn2;             /* pass 2                                             */
    int n_persistent;
    double pos_spread_m;           /* mean over persistent entries (NaN if none)         */
    double yaw_spread_deg;
    int n_seen[3];                 /* final entries by sooc_seen_class                   */
    int n_seen_box;                /* of them, probed over their tight box                 */
    int n_seen_own[3];             /* final entries by the class of their own surface
                                      (sooc_eval_points_seen over the vertices of their
                                      mesh; opts.own_surface)                              */
    int n_own_mesh;                /* of them, with a mesh (the others: their box class)  */
    int n_empty;                   /* final entries whose density reaches the surface level
                                      nowhere (objgeom EMPTY): they render nothing         */
    double never_behind_med_m;     /* median min_behind of the never-seen entries that some
                                      frame measured a surface in front of (NaN if none)  */
    int n_never_behind;            /* their number                                       */
    double update_s, render_s;
    double finetune_s;             /* with opts.finetune: the finetuning's wall time      */
    int n_born;                    /* with opts.run.birth: entries born before finetuning
                                      (counted in churn.created)                          */
    int n_pruned;                  /* entries removed after it, born or not: no density
                                      (counted in churn.removed)                          */
} sooc_eval_real_result;

/* Run one recorded sequence. frames[0..n_frames): sequence order, all posed,
 * at the model's resolution (img_w x img_h), in the map's world frame (y up,
 * support plane y = 0); instance = labels (0 = background) or NULL. The
 * frames' is_query flags are ignored: the query rule decides. A
 * global-frame baseline (sooc_model_is_global) is run with its global mapper
 * over all K slots; its "entries" are its present slots (id = slot + 1):
 * churn diffs the present set after each update (a slot that turns present
 * again counts as created again), and every present slot is tracked at every
 * update. view_cb (may be NULL) gets each scored query frame. `m` is not
 * modified. */
sooc_status sooc_eval_real_run(sooc_model *m, const sooc_frame *frames, int n_frames,
                               const sooc_eval_real_opts *o, sooc_eval_view_fn view_cb, void *user,
                               sooc_eval_real_result *res);

/* The geometric baseline on the same sequence (mapper.h, docs/geometric.md):
 * the mapped frames of the query rule go into one support-plane cluster map,
 * each query frame is rendered from it (label 0 the plane and the surround,
 * 1.. its objects) and scored by sooc_metric_view with clip d_clip (m), as a
 * learnt map is. The result's entries are its objects; spreads, growth and
 * the seen test are not computed (NaN / 0). cp NULL = defaults. */
struct sooc_cluster_params;
sooc_status sooc_eval_geometric_run(const sooc_frame *frames, int n_frames, const sooc_eval_real_opts *o,
                                    const struct sooc_cluster_params *cp, double d_clip, sooc_eval_view_fn view_cb,
                                    void *user, sooc_eval_real_result *res);

/* One JSON object (no trailing newline) for cell (model, sequence): the
 * contract keys "scale": "real", "view": "Q", depth_rmse, rgb_rmse,
 * entries_final, entries_created, plus "labels" ("ground_truth", or
 * "predicted" with o->labels_predicted: the scores are agreement with a
 * network's masks), miou and obj_iou (list, with obj_ids and obj_views) when
 * labelled, and the churn, growth, spread and seen
 * figures. *out is sooc_malloc'd (caller frees). */
sooc_status sooc_eval_real_json(const char *model, const char *sequence, const char *path,
                                const sooc_eval_real_opts *o, const sooc_eval_real_result *r, char **out);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_EVAL_H */
