/* Layer 3 of src/model (docs/model.md "Layers"): the per-view update and the
 * training step (step.c: per-view records, retrieve -> refine -> register,
 * the reverse sweep; workspace.c: the runner's workspace, sooc_model_ws).
 * Includes only the refinement layer (and, through it, the lower ones).
 * Internal interface of src/model (docs/architecture.md "Layers"): src/mapper,
 * src/global and tests include it; not a public API. */
#ifndef SOOC3D_MODEL_STEP_H
#define SOOC3D_MODEL_STEP_H

#include "model/refine.h"
#include "sooc3d/mapper.h"
#include "sooc3d/cogmap.h"

#define STEP_MAX_LAY 256

typedef struct sooc_view_rec {
    sooc_view_rays vr;
    sooc_floor_frame gf;          /* G_t floor frame                                   */
    int nslot, n_ret;             /* slots in use; of which retrieved (first n_ret)    */
    uint64_t src_id[SOOC_MODEL_K_MAX];
    int src_view[SOOC_MODEL_K_MAX], src_slot[SOOC_MODEL_K_MAX], prior_idx[SOOC_MODEL_K_MAX];
    int32_t bi, bj;               /* active layout block                               */
    int lay_src;                  /* view that last set the block's layout, -1 = prior */
    int64_t t_ns;
    int Lcap;
    float *lam, *glam;            /* (L+1) x K x NL: λ^l and local dL^l/dλ^l (unweighted) */
    float *lay, *glay;            /* (L+1) x 2 d_l                                     */
    float *lam0, *glam0, *G;      /* K x NL: start/prior, sum_l w_l dKL^l/dλ^0, sweep grad */
    float *lay0, *glay0, *Glay;
    sooc_ref_act *ao, *al;             /* L refinement activations (objects, layout)       */
    sooc_dec_noise *noise;             /* L + 1                                             */
    float *buf;
    float zwb[17][SOOC_MODEL_K_MAX * 3];   /* sampled z^where per decode (test replay) */
} sooc_view_rec;

struct sooc_step_state {
    sooc_cogmap *map;
    sooc_view_rec *views;
    int ncap, L;
    float *vec_o, *vec_l, *gvec, *dh, *dc, *delta, *tmp0, *tmpl0, *gbak;
    int *id_view, *id_slot;       /* id -> (view, slot) that last registered it */
    size_t id_cap;
    int n_lay;
    int32_t lay_bi[STEP_MAX_LAY], lay_bj[STEP_MAX_LAY];
    int lay_view[STEP_MAX_LAY];
    float zq[64][SOOC_MODEL_K_MAX * 3];   /* query-view z^where samples (test replay) */
    sooc_cluster_map *prop;       /* proposals' scratch map (sooc_step_opts.proposals), made on first use */
    int aux_replay;               /* TEST ONLY: 1 = keep the stored auxiliary inputs (stop-gradient
                                     as a forward, for finite-difference checks); only the λ part
                                     of the refinement vector input is refreshed; the Gaussian
                                     trick is applied as a forward around the stored z^where
                                     samples (sooc_dec_call.zw_sg) */
};
typedef struct sooc_step_state sooc_step_state;

/* The workspace's step scratch (created on first use, x->step) with room for T view records of L iterations. */
sooc_step_state *sooc_mdl_step_state(sooc_model_ws *x, int T, int L);
void sooc_mdl_step_free(sooc_step_state *S);   /* NULL-safe */
sooc_status sooc_mdl_view_alloc(sooc_model *m, sooc_view_rec *V, int L);
void sooc_mdl_view_free(sooc_view_rec *V);
void sooc_mdl_camera_of(const sooc_model *m, const sooc_frame *f, sooc_cogmap_camera *cam);
sooc_status sooc_mdl_view_setup(sooc_model *m, sooc_cogmap *map, sooc_view_rec *V, const sooc_frame *f, int pad,
                           sooc_rng *rng, int *n_inview);
sooc_status sooc_mdl_view_forward(sooc_model_ws *x, sooc_step_state *S, sooc_view_rec *V, int L, const sooc_step_opts *o, int train,
                             sooc_rng *rng, double *loss_w, sooc_dec_call *last);
void sooc_mdl_view_backward(sooc_model_ws *x, sooc_step_state *S, sooc_view_rec *V, int L);
sooc_status sooc_mdl_view_forward_train(sooc_model_ws *x, sooc_step_state *S, sooc_view_rec *V, int L, const sooc_step_opts *opt,
                                   sooc_rng *rng, double *total, sooc_step_losses *out, int *nonfinite);
sooc_status sooc_mdl_query_decode(sooc_model_ws *x, sooc_step_state *S, sooc_view_rec *V, int q, int nslot, const float *lam,
                             const float *lay, const sooc_step_opts *opt, sooc_rng *rng, double *total,
                             sooc_step_losses *out, int *nonfinite);
sooc_status sooc_mdl_step_finish(sooc_model *m, sooc_step_state *S, double total, int nonfinite, sooc_step_losses *out);

#endif
