/* Geometric proposals for the mapper's new slots (docs/geometric.md
 * "Proposals"; mapper.h sooc_mapper_set_proposals): the keyframe's own
 * support-plane clusters (mapper.h) place the slots that the view pads
 * with priors. A cluster that a retrieved slot already covers (its centre
 * within the cluster's half-diagonal plus cover_m) proposes nothing; each
 * other cluster, largest first, moves the nearest unused prior slot to its
 * centre on the floor, with the position variance of its box and the
 * presence logit pres_logit; the prior slots no cluster placed start with
 * rest_logit (so that only proposals make new entries). Appearance, heading and the rest stay the
 * prior's: the refinement iterations fit them to the keyframe. */
#include "model/propose.h"

#include <math.h>
#include <string.h>

int sooc_mdl_propose(sooc_cluster_map *cm, const sooc_model_config *c, int NL, const sooc_frame *f, sooc_view_rec *V,
                       const sooc_mdl_prop_params *pp, sooc_status *st) {
    *st = SOOC_OK;
    sooc_cluster_map_clear(cm);
    int n = 0;
    if ((*st = sooc_cluster_map_add_frame(cm, f)) || (*st = sooc_cluster_map_segment(cm, &n))) return 0;
    sooc_cluster_object obj[SOOC_MODEL_K_MAX];
    if ((*st = sooc_cluster_map_objects(cm, obj, SOOC_MODEL_K_MAX, &n))) return 0;
    if (n > SOOC_MODEL_K_MAX) n = SOOC_MODEL_K_MAX;
    const double u = c->unit_m;
    int used[SOOC_MODEL_K_MAX] = {0}, placed = 0;
    for (int i = 0; i < n; i++) {
        const sooc_cluster_object *o = &obj[i];
        double w[3] = {o->x, o->z, o->yaw}, l[3];
        sooc_floor_to_local(&V->gf, w, l);
        double lx = l[0] / u, lz = l[1] / u;   /* model units, as λ0 */
        double half = 0.5 * hypot(o->extent[0], o->extent[2]);
        double cover = (half + pp->cover_m) / u;
        int covered = 0;
        for (int k = 0; k < V->n_ret && !covered; k++) {
            const float *r = V->lam0 + (size_t)k * NL;
            covered = hypot(r[SOOC_LAM_X] - lx, r[SOOC_LAM_Z] - lz) < cover;
        }
        if (covered) continue;
        int best = -1;
        double bd = INFINITY;
        for (int k = V->n_ret; k < V->nslot; k++) {
            if (used[k]) continue;
            const float *r = V->lam0 + (size_t)k * NL;
            double d = hypot(r[SOOC_LAM_X] - lx, r[SOOC_LAM_Z] - lz);
            if (d < bd) bd = d, best = k;
        }
        if (best < 0) break;
        used[best] = 1;
        float *r = V->lam0 + (size_t)best * NL;
        r[SOOC_LAM_X] = (float)lx;
        r[SOOC_LAM_Z] = (float)lz;
        if (pp->sigma_frac > 0) {
            double s = fmax(pp->sigma_frac * half, 0.005) / u;
            r[SOOC_LAM_RHO_T] = (float)log(s * s);
        }
        if (isfinite(pp->pres_logit)) r[SOOC_LAM_PRES(c->d_what)] = (float)pp->pres_logit;
        placed++;
    }
    if (isfinite(pp->rest_logit))
        for (int k = V->n_ret; k < V->nslot; k++)
            if (!used[k]) V->lam0[(size_t)k * NL + SOOC_LAM_PRES(c->d_what)] = (float)pp->rest_logit;
    return placed;
}

void sooc_mdl_prop_from_opts(const sooc_step_opts *o, sooc_mdl_prop_params *pp, sooc_cluster_params *cp) {
    sooc_cluster_params_default(cp);
    if (o->prop_join_m > 0) cp->dist_m = o->prop_join_m;
    cp->rest_m = 0;   /* as sooc_proposal_params_default */
    pp->cover_m = 0.02;
    pp->sigma_frac = 0;
    pp->pres_logit = o->prop_logit;
    pp->rest_logit = o->prop_rest_logit;
}
