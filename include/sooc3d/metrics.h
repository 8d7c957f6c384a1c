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
#ifndef SOOC3D_METRICS_H
#define SOOC3D_METRICS_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/render.h"

#ifdef __cplusplus
extern "C" {
#endif

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

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_METRICS_H */
