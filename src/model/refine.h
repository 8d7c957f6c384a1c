/* Layer 2 of src/model (docs/model.md "Layers"): the refinement networks
 * (refine.c: auxiliary inputs, conv encoder + LSTM forward and backward).
 * Includes only the decoder layer (and, through it, layer 0). Internal
 * interface of src/model (docs/architecture.md "Layers"), seen through step.h. */
#ifndef SOOC3D_MODEL_REFINE_H
#define SOOC3D_MODEL_REFINE_H

#include "model/decoder.h"

/* Refinement activations for one (view, iteration), B items. */
typedef struct sooc_ref_act {
    int B;
    int nsh;                      /* leading input channels shared by every item, stored for
                                     item 0 only (the backward fills the other copies); 0 = none */
    float *x0;                    /* B x cin x gh x gw  (stored as [c][b][hw]) */
    float *y[4];                  /* conv outputs [c][b][hw] (post-ELU)        */
    float *flat, *f;              /* B x nflat, B x fc (post-ELU)              */
    float *xin;                   /* B x (fc + nvec)                           */
    float *gates;                 /* B x 4H post-nonlinearity (i, f, g, o)     */
    float *c_prev, *h_prev, *c, *h; /* B x H                                   */
} sooc_ref_act;

struct sooc_ref_ws {           /* scratch for conv forward/backward */
    float *cols, *gcols, *gy[4], *gflat, *gf, *gx, *gg, *gh;
    size_t ncols;                 /* floats in cols (and gcols): per-thread slices in the forward */
    float *ysh;                   /* 2 x ysh_ch x (gw gh / 4): first-conv share of the shared channels */
    int ysh_ch;
    float *gconv;                 /* ngconv: the second item block's conv weight gradients (backward) */
    size_t ngconv;
};
typedef struct sooc_ref_ws sooc_ref_ws;

/* The refinement's part of a workspace. */
sooc_status sooc_mdl_ref_ws_create(const sooc_model *m, sooc_ref_ws **out);
void sooc_mdl_ref_ws_destroy(sooc_ref_ws *r);   /* NULL-safe */

/* Build the refinement inputs of every object slot (and the layout) after a
 * decode with backward: images img[c][b][hw] for B = nslot (objects) and 1
 * (layout), vector inputs vec [B x nvec]. */
void sooc_mdl_aux_inputs(sooc_model_ws *x, const sooc_dec_call *c, const float *g_lam, const float *g_lay,
                    float *img_o, float *vec_o, float *img_l, float *vec_l);
sooc_status sooc_mdl_ref_act_alloc(const sooc_ref_net *n, int B, int gw, int gh, sooc_ref_act *a);
void sooc_mdl_ref_act_free(sooc_ref_act *a);
/* forward: a->x0 (and a->nsh) and the vector part of a->xin must be filled; h_prev/c_prev too. out: B x nout */
void sooc_mdl_ref_forward(sooc_model_ws *x, const sooc_ref_net *n, sooc_ref_act *a, int gw, int gh, float *out);
/* The conv stack's last map flattened (average-pooled to 2 x 2 above a 32 x 32
 * ray grid) for the FC layer, and its backward (writes gy3). */
void sooc_mdl_ref_flatten(const sooc_ref_net *n, const float *y3, int B, int gw, int gh, float *flat);
/* Two nets' forwards in one parallel pass (the object and the layout refinement: their
 * items split across the threads together). n1 / a1 / out1 NULL: one net. */
void sooc_mdl_ref_forward2(sooc_model_ws *x, const sooc_ref_net *n0, sooc_ref_act *a0, float *out0, const sooc_ref_net *n1, sooc_ref_act *a1,
                      float *out1, int gw, int gh);
/* Leading object-image aux channels that are the same for every slot (colour, depth,
 * beyond-clip flag, ray direction): sooc_mdl_aux_inputs writes them for slot 0 only. */
#define MDL_AUX_NSH 8
/* backward: gout B x nout; dh/dc: in = from the next iteration, out = to the previous.
 * gvec (B x nvec) receives d/d(vector inputs) (+=). Weight grads accumulated. */
void sooc_mdl_ref_backward(sooc_model_ws *x, const sooc_ref_net *n, sooc_ref_act *a, int gw, int gh,
                      const float *gout, float *dh, float *dc, float *gvec);

#endif
