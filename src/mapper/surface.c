/* The entries' observed surfaces (mapper.h: sooc_surface_claim;
 * docs/geometric.md "The entries' observed surfaces"): every object voxel of
 * a support-plane cluster map is claimed by the field component (a map
 * entry) whose density is highest there. The learnt map says which object a
 * point belongs to; the depth says where the object's surface is. */
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "sooc3d/render.h"

#include <math.h>
#include <string.h>

#define SURF_BATCH 1024

void sooc_surface_params_default(sooc_surface_params *p) {
    p->min_sigma = 0.01;
    p->min_share = 0;
    p->fill = 0;
}

void sooc_surface_claims_free(sooc_surface_claims *c) {
    if (!c) return;
    sooc_free(c->xyz);
    sooc_free(c->label);
    memset(c, 0, sizeof *c);
}

/* 1 when field point p lies in box b (or b does not cull) */
static int in_box(const sooc_render_box *b, const float p[3]) {
    if (!b || !b->enabled) return 1;
    const double *T = b->T_fb;   /* box-local = R^T (p - t) */
    double d[3] = {p[0] - T[3], p[1] - T[7], p[2] - T[11]};
    for (int r = 0; r < 3; r++) {
        double q = T[r] * d[0] + T[4 + r] * d[1] + T[8 + r] * d[2];
        if (q < b->lo[r] || q > b->hi[r]) return 0;
    }
    return 1;
}

/* Per segmentation cluster: claimants with less than min_share of the
 * cluster's claimed voxels give them to its largest claimant; with fill,
 * unclaimed voxels of a claimed cluster go to it too. */
static sooc_status consolidate(const int32_t *seg, int32_t *lab, size_t n, int nc, const sooc_surface_params *p) {
    int n_cl = 0;
    for (size_t i = 0; i < n; i++) n_cl = seg[i] + 1 > n_cl ? seg[i] + 1 : n_cl;
    if (!n_cl) return SOOC_OK;
    int *cnt = sooc_calloc((size_t)n_cl * (size_t)nc, sizeof *cnt), *top = sooc_malloc((size_t)n_cl * sizeof *top);
    if (!cnt || !top) {
        sooc_free(cnt), sooc_free(top);
        return sooc_seterr(SOOC_ENOMEM, "surface: out of memory for %d clusters", n_cl);
    }
    for (size_t i = 0; i < n; i++)
        if (seg[i] >= 0 && lab[i] > 0) cnt[(size_t)seg[i] * nc + lab[i]]++;
    for (int c = 0; c < n_cl; c++) {
        const int *q = cnt + (size_t)c * nc;
        int t = 0, tot = 0;
        for (int k = 1; k < nc; k++) {
            tot += q[k];
            if (q[k] > q[t]) t = k;
        }
        top[c] = t;
        cnt[(size_t)c * nc] = tot;   /* column 0 (unused by claimants): the claimed total */
    }
    for (size_t i = 0; i < n; i++) {
        int c = seg[i];
        if (c < 0 || !top[c]) continue;
        int tot = cnt[(size_t)c * nc];
        if (lab[i] > 0 ? cnt[(size_t)c * nc + lab[i]] < p->min_share * tot : p->fill) lab[i] = top[c];
    }
    sooc_free(cnt);
    sooc_free(top);
    return SOOC_OK;
}

sooc_status sooc_surface_claim(const sooc_field *f, const double T_fw[16], sooc_cluster_map *cm,
                               const sooc_surface_params *sp, sooc_surface_claims *out) {
    if (!f || !T_fw || !cm || !out) return sooc_seterr(SOOC_EINVAL, "surface: bad arguments");
    memset(out, 0, sizeof *out);
    sooc_surface_params spd;
    if (!sp) sooc_surface_params_default(&spd), sp = &spd;
    size_t n = 0;
    sooc_status st = sooc_cluster_map_object_points(cm, NULL, NULL, 0, &n);
    if (st) return sooc_adderr(st, "surface");
    size_t n1 = n ? n : 1;
    float *pf = sooc_malloc(n1 * 3 * sizeof *pf), *best = sooc_malloc(n1 * sizeof *best);
    int32_t *seg = sooc_malloc(n1 * sizeof *seg);
    size_t *idx = sooc_malloc(SURF_BATCH * sizeof *idx);
    out->xyz = sooc_malloc(n1 * 3 * sizeof *out->xyz);
    out->label = sooc_malloc(n1 * sizeof *out->label);
    float pts[3 * SURF_BATCH], sig[SURF_BATCH], rgb[3 * SURF_BATCH];
    if (!pf || !best || !seg || !idx || !out->xyz || !out->label)
        st = sooc_seterr(SOOC_ENOMEM, "surface: out of memory for %zu voxels", n);
    if (!st) st = sooc_cluster_map_object_points(cm, out->xyz, seg, n, &n);
    if (!st && f->prepare) st = f->prepare(f->user, 1, SURF_BATCH);
    if (!st) {
        out->n = n;
        for (size_t i = 0; i < n; i++) {
            double w[3] = {out->xyz[3 * i], out->xyz[3 * i + 1], out->xyz[3 * i + 2]}, q[3];
            sooc_se3_apply(q, T_fw, w);
            for (int r = 0; r < 3; r++) pf[3 * i + r] = (float)q[r];
            best[i] = (float)sp->min_sigma, out->label[i] = -1;
        }
        /* per component, the voxels inside its box, in batches */
        for (int k = 1; k < f->n_comp; k++) {
            const sooc_render_box *b = f->boxes ? &f->boxes[k] : NULL;
            size_t i = 0;
            while (i < n) {
                int nb = 0;
                for (; i < n && nb < SURF_BATCH; i++)
                    if (in_box(b, pf + 3 * i)) {
                        idx[nb] = i;
                        memcpy(pts + 3 * nb, pf + 3 * i, 3 * sizeof(float));
                        nb++;
                    }
                if (!nb) break;
                f->eval(f->user, 0, k, pts, nb, sig, rgb);
                for (int j = 0; j < nb; j++)
                    if (sig[j] > best[idx[j]]) best[idx[j]] = sig[j], out->label[idx[j]] = k;
            }
        }
        st = consolidate(seg, out->label, n, f->n_comp, sp);
        if (!st) st = sooc_cluster_map_relabel(cm, out->label, n);
    }
    sooc_free(pf);
    sooc_free(best);
    sooc_free(seg);
    sooc_free(idx);
    if (st) sooc_surface_claims_free(out);
    return st;
}

sooc_status sooc_surface_claim_frame(sooc_model *m, const sooc_cogmap *map, const sooc_frame *f, int max_obj,
                                     sooc_cluster_map *cm, const sooc_surface_params *sp, sooc_model_field **fld,
                                     sooc_surface_claims *out) {
    if (!m || !map || !f || !cm || !fld || !out) return sooc_seterr(SOOC_EINVAL, "surface: bad arguments");
    *fld = NULL;
    memset(out, 0, sizeof *out);
    if (max_obj <= 0 || max_obj > SOOC_RENDER_MAX_COMP - 1) max_obj = SOOC_RENDER_MAX_COMP - 1;
    sooc_intrinsics K = f->K;
    K.width = f->width, K.height = f->height;
    sooc_status st = sooc_model_field_create(fld, m, map, f->T_wc, &K, max_obj, NULL);
    if (st) return sooc_adderr(st, "surface: frame %lld", (long long)f->index);
    double T_fc[16], T_cw[16], T_fw[16];   /* world -> the field's frame: T_fc T_cw */
    sooc_model_field_T_fc(*fld, T_fc);
    sooc_se3_inverse(T_cw, f->T_wc);
    sooc_se3_mul(T_fw, T_fc, T_cw);
    st = sooc_surface_claim(sooc_model_field_get(*fld), T_fw, cm, sp, out);
    if (st) {
        sooc_model_field_destroy(*fld);
        *fld = NULL;
        return sooc_adderr(st, "surface: frame %lld", (long long)f->index);
    }
    return SOOC_OK;
}

int sooc_surface_box(const sooc_surface_claims *c, int comp, double X, double Z, double yaw, double voxel_m,
                     float extent[3], float centre[3]) {
    double cy = cos(yaw), sy = sin(yaw), lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY}, top = 0;
    int k = 0;
    for (size_t i = 0; i < c->n; i++) {
        if (c->label[i] != comp) continue;
        double dx = c->xyz[3 * i] - X, dz = c->xyz[3 * i + 2] - Z;
        double a = cy * dx - sy * dz, b = sy * dx + cy * dz;   /* along the entry's axes (R_y) */
        lo[0] = fmin(lo[0], a), hi[0] = fmax(hi[0], a);
        lo[1] = fmin(lo[1], b), hi[1] = fmax(hi[1], b);
        top = fmax(top, c->xyz[3 * i + 1]);
        k++;
    }
    if (!k) return 0;
    /* centred on the entry's place, as every planner box (cogmap.h sooc_map_entry_box) */
    extent[0] = (float)(2.0 * fmax(-lo[0], hi[0]) + voxel_m);
    extent[1] = (float)(top + 0.5 * voxel_m);   /* objects stand on the plane */
    extent[2] = (float)(2.0 * fmax(-lo[1], hi[1]) + voxel_m);
    centre[0] = centre[2] = 0.0f;
    centre[1] = 0.5f * extent[1];
    return k;
}
