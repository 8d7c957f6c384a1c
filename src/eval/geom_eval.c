/* Object geometry against ground truth (src/eval/eval_geom.h). */
#include "eval/eval_geom.h"

#include <math.h>
#include <string.h>

/* 1 if the shape's footprint is a disc (see above). */
static int sooc_geom_shape_round(sooc_shape s) {
    switch (s) {
    case SOOC_SHAPE_SPHERE:
    case SOOC_SHAPE_CYLINDER:
    case SOOC_SHAPE_CONE:
    case SOOC_SHAPE_TORUS:
    case SOOC_SHAPE_FRUSTUM:
    case SOOC_SHAPE_CAN:
    case SOOC_SHAPE_BOTTLE:
    case SOOC_SHAPE_BOWL: return 1;
    default: return 0;
    }
}

/* GT tight box of object o in a frame with yaw `yaw` (extent x, y, z). */
static void sooc_geom_gt_extent(const sooc_scene_object *o, double yaw, double ext[3]) {
    ext[1] = o->size[1];
    if (sooc_geom_shape_round(o->shape)) {
        ext[0] = ext[2] = o->size[0] > o->size[2] ? o->size[0] : o->size[2];
        return;
    }
    double d = yaw - o->yaw, c = fabs(cos(d)), s = fabs(sin(d));
    ext[0] = c * o->size[0] + s * o->size[2];
    ext[2] = s * o->size[0] + c * o->size[2];
}

sooc_status sooc_geom_eval_scene(const sooc_map_entry *e, size_t n, const sooc_scene *sc, double gate_m,
                                 sooc_geom_match *out, int *n_out) {
    *n_out = 0;
    int no = sc->n_objects;
    if (no <= 0 || n == 0) return SOOC_OK;
    uint8_t *used_e = sooc_calloc(n, 1), *used_g = sooc_calloc((size_t)no, 1);
    if (!used_e || !used_g) {
        sooc_free(used_e);
        sooc_free(used_g);
        return sooc_seterr(SOOC_ENOMEM, "geometry eval: out of memory");
    }
    /* greedy one-to-one by floor distance: repeatedly take the closest free pair */
    for (;;) {
        double best = gate_m;
        int bg = -1;
        size_t be = 0;
        for (int g = 0; g < no; g++) {
            if (used_g[g]) continue;
            for (size_t i = 0; i < n; i++) {
                if (used_e[i]) continue;
                double d = hypot(e[i].x - sc->objects[g].x, e[i].z - sc->objects[g].z);
                if (d <= best) best = d, bg = g, be = i;
            }
        }
        if (bg < 0) break;
        used_g[bg] = used_e[be] = 1;
        const sooc_scene_object *o = &sc->objects[bg];
        const sooc_map_entry *m = &e[be];
        sooc_geom_match *r = &out[(*n_out)++];
        memset(r, 0, sizeof *r);
        r->gt_index = bg;
        r->entry = be;
        r->dist_m = best;
        r->tight = (m->geom.flags & SOOC_GEOM_TIGHT) != 0;
        sooc_geom_gt_extent(o, m->yaw, r->ext_gt);
        r->ext_err_cm = r->height_err_cm = NAN;
        if (r->tight) {
            double s = 0;
            for (int a = 0; a < 3; a++) {
                r->ext_pred[a] = m->extent[a];
                s += fabs(r->ext_pred[a] - r->ext_gt[a]);
            }
            r->ext_err_cm = 100.0 * s / 3.0;
            r->height_err_cm = 100.0 * fabs(m->geom.centre[1] - 0.5 * o->size[1]);
        }
        r->err_x = m->x - o->x;
        r->err_z = m->z - o->z;
        r->sig_x = sqrt(m->geom.cov_xz[0]);
        r->sig_z = sqrt(m->geom.cov_xz[2]);
        r->sym_pred = (m->geom.flags & SOOC_GEOM_SYMMETRIC) != 0;
        r->sym_gt = sooc_geom_shape_round(o->shape);
    }
    sooc_free(used_e);
    sooc_free(used_g);
    return SOOC_OK;
}
