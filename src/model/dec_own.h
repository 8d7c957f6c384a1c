/* A decoder MLP on its own weight vector (the finetuned per-object
 * and per-block copies of docs/finetune.md), forward and backward, and the payload
 * format a finetuned decoder is kept in (cogmap payloads, the map database).
 * Internal interface of src/model (docs/architecture.md "Layers"): src/finetune
 * and tests include it.
 *
 * Weights: the model slab's tensors of one sooc_dec_net (W1x, W1z, b1, W2, b2, W3,
 * b3, Wd, bd, Wc1, bc1, Wc2, bc2) copied contiguously, in that order; `rel`
 * (sooc_mdl_dec_rel) holds their offsets relative to W1x. W is [in x out]
 * row-major, Y = X W + b, as in decoder.c.
 *
 * Payload (floats): [0] MDL_FT_MAGIC, [1] MDL_FT_VERSION, [2] kind (0 object,
 * 1 layout), [3] dz, [4] din, [5] H, [6] Hc, [7] weight count; then z (dz),
 * then the weights. Small integers are exact in float. */
#ifndef SOOC3D_MODEL_DEC_OWN_H
#define SOOC3D_MODEL_DEC_OWN_H

#include "model/decoder.h"

#define MDL_FT_HDR 8
#define MDL_FT_MAGIC 19019.0f
#define MDL_FT_VERSION 1.0f
enum { MDL_FT_OBJ = 0, MDL_FT_LAY = 1 };

/* Weights of one decoder (floats from W1x through bc2). */
size_t sooc_mdl_dec_count(const sooc_dec_net *n);
/* n with offsets relative to its W1x. */
void sooc_mdl_dec_rel(const sooc_dec_net *n, sooc_dec_net *rel);
size_t sooc_mdl_ft_payload_size(const sooc_dec_net *n);
/* out[sooc_mdl_ft_payload_size(n)] = header, z[n->dz], w[sooc_mdl_dec_count(n)]. */
void sooc_mdl_ft_payload_pack(const sooc_dec_net *n, int kind, const float *z, const float *w, float *out);
/* 1 if v[0..nv) is a payload of this kind for a decoder shaped like n. */
int sooc_mdl_ft_payload_ok(const sooc_dec_net *n, int kind, const float *v, size_t nv);
static inline const float *mdl_ft_payload_z(const float *v) { return v + MDL_FT_HDR; }
static inline const float *mdl_ft_payload_w(const sooc_dec_net *n, const float *v) { return v + MDL_FT_HDR + n->dz; }

/* bias[H] = b1 + z W1z (layer 1's per-component bias). */
void sooc_mdl_own_bias(const float *w, const sooc_dec_net *rel, const float *z, float *bias);
/* Forward on R rows: a1 = pe W1x + bias (pre-activation, ReLU'd in place),
 * a2, a3 (R x H), ac (R x Hc) post-ReLU; sig (R), col (R x 3) sigmoids. */
void sooc_mdl_own_forward(const float *w, const sooc_dec_net *rel, int R, const float *pe, const float *bias, float *a1,
                     float *a2, float *a3, float *ac, float *sig, float *col);
/* Backward of sooc_mdl_own_forward: gsig (R), gcol (R x 3) = dL/d(sig), dL/d(col)
 * on entry (overwritten). ACCUMULATES weight gradients into gw (rel layout;
 * W1z and b1 excluded: they only enter through the bias) and dL/d(bias) into
 * gbias (H). Scratch gA, gB (R x H), gC (R x Hc). */
void sooc_mdl_own_backward(const float *w, const sooc_dec_net *rel, int R, const float *pe, const float *a1, const float *a2,
                      const float *a3, const float *ac, const float *sig, const float *col, float *gsig, float *gcol,
                      float *gA, float *gB, float *gC, float *gw, float *gbias);
/* From dL/d(bias): gw's W1z and b1 parts and gz (dz) (all +=). */
void sooc_mdl_own_bias_backward(const float *w, const sooc_dec_net *rel, const float *z, const float *gbias, float *gw,
                           float *gz);

#endif
