/* How well the planner's boxes fit the labelled objects (eval.h:
 * sooc_eval_box_fit; docs/metrics.md "Real sequences"): an object's points
 * are its labelled pixels of the mapped frames in the world frame; its entry
 * is the one whose box holds most of them. */
#include "sooc3d/eval.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BOX_MIN_POINTS 20
#define BOX_ABOVE_M 0.005   /* points on the support plane are the plane's */

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

sooc_status sooc_eval_box_fit(const sooc_map_entry *e, size_t ne, const sooc_frame *frames, int n,
                              const uint8_t *use, uint16_t id, sooc_box_fit *out) {
    if ((ne && !e) || n < 0 || (n && !frames) || !out) return sooc_seterr(SOOC_EINVAL, "box fit: bad arguments");
    out->entry = 0;
    out->n_points = 0;
    out->cover = out->height_err_m = out->area_ratio = NAN;
    size_t np = 0, cap = 0;
    double *p = NULL;   /* x y z */
    sooc_status st = SOOC_OK;
    for (int i = 0; i < n && !st; i++) {
        const sooc_frame *f = &frames[i];
        if ((use && !use[i]) || !f->instance || !f->has_pose) continue;
        for (int v = 0; v < f->height && !st; v++)
            for (int u = 0; u < f->width; u++) {
                size_t k = (size_t)v * f->width + u;
                if (f->instance[k] != id || !f->valid[k]) continue;
                double z = f->depth[k], c[3] = {(u + 0.5 - f->K.cx) / f->K.fx * z, (v + 0.5 - f->K.cy) / f->K.fy * z, z}, w[3];
                sooc_se3_apply(w, f->T_wc, c);
                if (w[1] < BOX_ABOVE_M) continue;
                if (np == cap) {
                    size_t nc = cap ? 2 * cap : 1024;
                    double *q = sooc_realloc(p, nc * 3 * sizeof *q);
                    if (!q) {
                        st = sooc_seterr(SOOC_ENOMEM, "box fit: out of memory for %zu points", nc);
                        break;
                    }
                    p = q, cap = nc;
                }
                memcpy(p + 3 * np++, w, sizeof w);
            }
    }
    out->n_points = (int)np;
    if (st || np < BOX_MIN_POINTS) {
        sooc_free(p);
        return st;
    }
    /* the entry whose box holds most points */
    size_t best = 0, best_n = 0;
    for (size_t j = 0; j < ne; j++) {
        double c[3], yaw;
        float ext[3];
        sooc_map_entry_box(&e[j], c, &yaw, ext);
        double cy = cos(yaw), sy = sin(yaw), h = sooc_map_entry_height(&e[j]);
        size_t in = 0;
        for (size_t i = 0; i < np; i++) {
            double dx = p[3 * i] - c[0], dz = p[3 * i + 2] - c[2];
            double a = cy * dx - sy * dz, b = sy * dx + cy * dz;
            in += fabs(a) <= 0.5 * ext[0] && fabs(b) <= 0.5 * ext[2] && p[3 * i + 1] <= h;
        }
        if (in > best_n) best = j, best_n = in;
    }
    double *ys = sooc_malloc(np * sizeof *ys);
    if (!ys) {
        sooc_free(p);
        return sooc_seterr(SOOC_ENOMEM, "box fit: out of memory");
    }
    for (size_t i = 0; i < np; i++) ys[i] = p[3 * i + 1];
    qsort(ys, np, sizeof *ys, cmp_double);
    double top = ys[(size_t)(0.98 * (double)(np - 1))];   /* the object's height, robust to stray labels */
    sooc_free(ys);
    if (best_n) {
        const sooc_map_entry *q = &e[best];
        double c[3], yaw;
        float ext[3];
        sooc_map_entry_box(q, c, &yaw, ext);
        double cy = cos(yaw), sy = sin(yaw);
        double *ab = sooc_malloc(2 * np * sizeof *ab);
        if (!ab) {
            sooc_free(p);
            return sooc_seterr(SOOC_ENOMEM, "box fit: out of memory");
        }
        for (size_t i = 0; i < np; i++) {   /* the points' own floor rectangle, on the entry's axes */
            double dx = p[3 * i] - c[0], dz = p[3 * i + 2] - c[2];
            ab[i] = cy * dx - sy * dz, ab[np + i] = sy * dx + cy * dz;
        }
        /* from the 5th to the 95th percentile on each axis: labelled pixels at depth edges land behind the
         * object (label-fusion's box: 4% of its points up to 0.3 m away) */
        qsort(ab, np, sizeof *ab, cmp_double);
        qsort(ab + np, np, sizeof *ab, cmp_double);
        size_t i0 = (size_t)(0.05 * (double)(np - 1)), i1 = (size_t)(0.95 * (double)(np - 1));
        double area = (ab[i1] - ab[i0]) * (ab[np + i1] - ab[np + i0]);
        sooc_free(ab);
        out->entry = q->id;
        out->cover = (double)best_n / (double)np;
        out->height_err_m = sooc_map_entry_height(q) - top;
        out->area_ratio = area > 0 ? (double)ext[0] * ext[2] / area : NAN;
    } else {
        out->cover = 0;
    }
    sooc_free(p);
    return SOOC_OK;
}
