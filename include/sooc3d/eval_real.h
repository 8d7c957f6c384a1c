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
#ifndef SOOC3D_EVAL_REAL_H
#define SOOC3D_EVAL_REAL_H

#include "sooc3d/core.h"
#include "sooc3d/eval.h"
#include "sooc3d/finetune.h"
#include "sooc3d/frame.h"
#include "sooc3d/map_entry.h"
#include "sooc3d/metrics.h"
#include "sooc3d/model.h"

#ifdef __cplusplus
extern "C" {
#endif

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
 * EMPTY; objgeom.h) is probed at 7 points: the box's centre and the centres
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
 * finetune.h), then finetuning by EM on the frames with use[i] != 0, then
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
                                  frames (finetune.h), then the query frames, spreads and the
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

/* The geometric baseline on the same sequence (cluster.h, docs/geometric.md):
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
#endif /* SOOC3D_EVAL_REAL_H */
