/*
 * sooc3d evaluation of object geometry for planners (docs/metrics.md
 * "Object geometry"): the map's tight boxes and position
 * spreads against a generated scene's ground truth.
 *
 * Matching: every GT object is matched to the nearest map entry on the
 * floor, one-to-one, greedily by distance, within `gate_m` (0.5 m in
 * `sooc3d eval`), the rule of render.h's scene metric.
 *
 * Extent error of a matched pair (cm): the mean over the three axes of
 * |extent_pred - extent_gt|, where extent_gt is the GT object's tight box in
 * the ENTRY's frame (its yaw): a shape with a round footprint (sphere,
 * cylinder, cone, torus, frustum, can, bottle, bowl) keeps its diameter; any
 * other footprint is the box of its x-z rectangle rotated by the yaw
 * difference (|c| sx + |s| sz, |s| sx + |c| sz). So a wrong yaw is not
 * counted twice, and a round density that should be a box is. Only entries
 * with a tight box (SOOC_GEOM_TIGHT) are scored. `sooc3d eval` reports the
 * median over matched objects as extent_err_cm.
 *
 * Calibration: for a matched entry, the per-axis position errors
 * (X - x_gt, Z - z_gt) are within one sigma when |e_x| <= sqrt(cov_xx) and
 * |e_z| <= sqrt(cov_zz); a calibrated spread has about 68% of axes within
 * (sigma1_frac). The symmetry flag agrees with GT when it is set exactly for
 * round-footprint shapes whose side view is symmetric too (sphere,
 * cylinder, cone, torus, frustum, can, bottle, bowl).
 */
#ifndef SOOC3D_EVAL_GEOM_H
#define SOOC3D_EVAL_GEOM_H

#include "sooc3d/core.h"
#include "sooc3d/mapper.h"
#include "sooc3d/gen.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_geom_match {
    int gt_index;              /* index into sc->objects                          */
    size_t entry;              /* index into the entries                          */
    double dist_m;             /* floor distance                                  */
    int tight;                 /* the entry has a tight box                       */
    double ext_pred[3], ext_gt[3];
    double ext_err_cm;         /* mean abs over the axes (NaN without a tight box) */
    double height_err_cm;      /* |centre height - GT centre height| (NaN likewise) */
    double err_x, err_z;       /* position error, world (m)                       */
    double sig_x, sig_z;       /* published position sigmas (m)                   */
    int sym_pred, sym_gt;
} sooc_geom_match;


/* Match and score the entries e[0..n) against sc's objects (see above).
 * out: room for sc->n_objects; *n_out = matched pairs. */
sooc_status sooc_geom_eval_scene(const sooc_map_entry *e, size_t n, const sooc_scene *sc, double gate_m,
                                 sooc_geom_match *out, int *n_out);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_EVAL_GEOM_H */
