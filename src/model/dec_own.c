/* A decoder MLP on its own weights (dec_own.h): the finetuned copies of
 * docs/finetune.md (SOOC3D+). Same network as decoder.c (pe -> 3 ReLU layers -> density
 * sigmoid, colour head -> sigmoid), on the engine's layer pairs
 * (nn/nn_kern.h) over a plain weight pointer, not the model's slab. */
#include "model/dec_own.h"
#include "nn/nn_kern.h"

#include <string.h>

size_t sooc_mdl_dec_count(const sooc_dec_net *n) { return n->bc2 + 3 - n->W1x; }

void sooc_mdl_dec_rel(const sooc_dec_net *n, sooc_dec_net *r) {
    *r = *n;
    size_t o = n->W1x;
    r->W1x -= o, r->W1z -= o, r->b1 -= o, r->W2 -= o, r->b2 -= o, r->W3 -= o, r->b3 -= o;
    r->Wd -= o, r->bd -= o, r->Wc1 -= o, r->bc1 -= o, r->Wc2 -= o, r->bc2 -= o;
}

size_t sooc_mdl_ft_payload_size(const sooc_dec_net *n) { return MDL_FT_HDR + (size_t)n->dz + sooc_mdl_dec_count(n); }

void sooc_mdl_ft_payload_pack(const sooc_dec_net *n, int kind, const float *z, const float *w, float *out) {
    size_t nw = sooc_mdl_dec_count(n);
    out[0] = MDL_FT_MAGIC, out[1] = MDL_FT_VERSION, out[2] = (float)kind, out[3] = (float)n->dz;
    out[4] = (float)n->din, out[5] = (float)n->H, out[6] = (float)n->Hc, out[7] = (float)nw;
    memcpy(out + MDL_FT_HDR, z, (size_t)n->dz * sizeof(float));
    memcpy(out + MDL_FT_HDR + n->dz, w, nw * sizeof(float));
}

int sooc_mdl_ft_payload_ok(const sooc_dec_net *n, int kind, const float *v, size_t nv) {
    return v && nv == sooc_mdl_ft_payload_size(n) && v[0] == MDL_FT_MAGIC && v[1] == MDL_FT_VERSION &&
           v[2] == (float)kind && v[3] == (float)n->dz && v[4] == (float)n->din && v[5] == (float)n->H &&
           v[6] == (float)n->Hc && v[7] == (float)sooc_mdl_dec_count(n);
}

void sooc_mdl_own_bias(const float *w, const sooc_dec_net *r, const float *z, float *bias) {
    int H = r->H;
    memcpy(bias, w + r->b1, (size_t)H * sizeof(float));
    for (int i = 0; i < r->dz; i++) {
        const float *row = w + r->W1z + (size_t)i * H;
        float zi = z[i];
        for (int j = 0; j < H; j++) bias[j] += zi * row[j];
    }
}

/* The layers 2.. of the copy, on its own weight vector. */
static sooc_nn_nerf_tail own_tail(const float *w, const sooc_dec_net *r) {
    return (sooc_nn_nerf_tail){r->H,       r->Hc,      w + r->W2,  w + r->b2,  w + r->W3, w + r->b3, w + r->Wd,
                               w + r->bd,  w + r->Wc1, w + r->bc1, w + r->Wc2, w + r->bc2, NULL, NULL, NULL};
}

void sooc_mdl_own_forward(const float *w, const sooc_dec_net *r, int R, const float *pe, const float *bias, float *a1,
                     float *a2, float *a3, float *ac, float *sig, float *col) {
    if (R <= 0) return;
    sooc_nn_nerf_tail t = own_tail(w, r);
    sooc_nn_dense_forward(R, r->din, r->H, pe, r->din, w + r->W1x, bias, a1, r->H, 0, SOOC_NN_EP_RELU);
    sooc_nn_nerf_tail_forward(&t, R, a1, a2, a3, ac, sig, col, 0);
}

void sooc_mdl_own_backward(const float *w, const sooc_dec_net *r, int R, const float *pe, const float *a1, const float *a2,
                      const float *a3, const float *ac, const float *sig, const float *col, float *gsig, float *gcol,
                      float *gA, float *gB, float *gC, float *gw, float *gbias) {
    if (R <= 0) return;
    int H = r->H;
    sooc_nn_nerf_tail t = own_tail(w, r);
    sooc_nn_nerf_tail_grad g = {gw + r->W2, gw + r->b2,  gw + r->W3,  gw + r->b3,  gw + r->Wd,
                                gw + r->bd, gw + r->Wc1, gw + r->bc1, gw + r->Wc2, gw + r->bc2};
    /* gA ends as dL/d(layer-1 pre-activation) */
    sooc_nn_nerf_tail_backward(&t, &g, 1.0f, R, a1, a2, a3, ac, sig, col, gsig, gcol, gA, gB, gC, gA);
    sooc_nn_dense_backward(R, r->din, H, gA, H, pe, r->din, w + r->W1x, NULL, NULL, 0, 0, NULL, gw + r->W1x, gbias,
                           1.0f);
}

void sooc_mdl_own_bias_backward(const float *w, const sooc_dec_net *r, const float *z, const float *gbias, float *gw,
                           float *gz) {
    int H = r->H;
    for (int j = 0; j < H; j++) gw[r->b1 + j] += gbias[j];
    for (int i = 0; i < r->dz; i++) {
        const float *row = w + r->W1z + (size_t)i * H;
        float *grow = gw + r->W1z + (size_t)i * H, s = 0;
        for (int j = 0; j < H; j++) {
            grow[j] += z[i] * gbias[j];
            s += row[j] * gbias[j];
        }
        gz[i] += s;
    }
}
