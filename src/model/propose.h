/* Geometric proposals for a view's padded slots (propose.c): the online
 * mapper's keyframes and, with sooc_step_opts.proposals, the training
 * step's input views. Internal interface of src/model (the step layer;
 * docs/architecture.md "Layers"): src/mapper includes it. */
#ifndef SOOC3D_MODEL_PROPOSE_H
#define SOOC3D_MODEL_PROPOSE_H

#include "model/step.h"
#include "sooc3d/mapper.h"

typedef struct sooc_mdl_prop_params {
    double cover_m;      /* a retrieved slot within the cluster's half-diagonal + this covers it (m) */
    double sigma_frac;   /* position std of a proposed slot = this x the half-diagonal (<= 0: the prior's) */
    double pres_logit;   /* presence logit of a proposed slot (NaN: the prior's)                     */
    double rest_logit;   /* presence logit of the prior slots no cluster placed (NaN: the prior's)   */
} sooc_mdl_prop_params;

/* Place the prior slots of view V (set up by sooc_mdl_view_setup with padding)
 * on the support-plane clusters of keyframe f (world frame). cm is the
 * caller's scratch map (cleared here). Returns the slots placed; *st the
 * status (0 placed on failure). */
/* The step options' proposal settings as parameters (cover 2 cm, no sigma change). */
void sooc_mdl_prop_from_opts(const sooc_step_opts *o, sooc_mdl_prop_params *pp, sooc_cluster_params *cp);

int sooc_mdl_propose(sooc_cluster_map *cm, const sooc_model_config *c, int NL, const sooc_frame *f, sooc_view_rec *V,
                       const sooc_mdl_prop_params *pp, sooc_status *st);

#endif
