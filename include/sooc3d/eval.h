/*
 * sooc3d evaluation: the paper's tables and the pictures.
 *
 * Tables. Per-view metrics (metrics.h) are accumulated per
 * model x scale x {I, Q} x run. A cell's value for one run is the mean over
 * that run's views (objects for L2); the table reports mean +- std over the
 * runs (sample std, n - 1; 0 for one run). Layout = the paper's Table 1: rows
 * model x {I, Q}, column groups mIoU (best-match), RGB RMSE, depth RMSE, L2,
 * each with the scales present (s, m, l, xl). L2 is shown for query views
 * only, as in the paper (opts). A second table gives the Hungarian mIoU, the
 * matched fraction, recall by distance and the RGB RMSE over object pixels. Outputs: plain text, Markdown,
 * JSON (all cells, all statistics).
 *
 * Pictures (PNG via image.h):
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
#ifndef SOOC3D_EVAL_H
#define SOOC3D_EVAL_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/image.h"
#include "sooc3d/mapper.h"
#include "sooc3d/metrics.h"
#include "sooc3d/model.h"
#include "sooc3d/render.h"

#ifdef __cplusplus
extern "C" {
#endif

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
                                  final map's mesh accuracy / completeness (mesh.h
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
     * layout block of the map by EM on the input views (finetune.h), then score
     * the views from the finetuned map; NULL = no finetuning              (NULL) */
    const struct sooc_finetune_params *finetune;
    /* with finetune: births first (finetune.h "births"): entries for what the
     * map does not draw in the input views; NULL = none                  (NULL) */
    const struct sooc_birth_params *birth;
    /* SOOC3D mapper: geometric proposals for the new slots (mapper.h
     * sooc_mapper_set_proposals; docs/geometric.md); NULL = off       (NULL) */
    const struct sooc_proposal_params *proposals;
    /* SOOC3D mapper: geometric support of the entries (mapper.h
     * sooc_mapper_set_support): on with this margin in m; 0 = off     (0) */
    double geo_support_m;
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

/* The geometric baseline on one scene (cluster.h, docs/geometric.md): the
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

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_EVAL_H */
