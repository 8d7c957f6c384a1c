/* The decoder MLP layers the model runs (docs/engine.md §9), as forward / backward
 * pairs (nn/nn_kern.h): dense + ReLU on sooc_nn_gemm with the bias and the
 * activation fused into the GEMM, the density / colour sigmoid heads, and
 * their composition, layers 2.. of a decoder. Weights are [in x out]
 * row-major (Y = X W + b), the layout of the model's checkpoints. */
#include "nn_impl.h"
#include "nn/nn_kern.h"

#include <string.h>

static inline float sigm(float x) { return 1.0f / (1.0f + expf(-x)); }

/* dot product with 8 independent partial sums (vectorisable without reassociation) */
static inline float dot8(const float *restrict a, const float *restrict b, int n) {
    float s[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    int j = 0;
    for (; j + 8 <= n; j += 8)
        for (int u = 0; u < 8; u++) s[u] += a[j + u] * b[j + u];
    float t = ((s[0] + s[4]) + (s[1] + s[5])) + ((s[2] + s[6]) + (s[3] + s[7]));
    for (; j < n; j++) t += a[j] * b[j];
    return t;
}

/* ---------------------------------------------------------------- dense */

void sooc_nn_dense_forward(int R, int I, int O, const float *x, int ldx, const float *W, const float *b, float *y,
                           int ldy, int acc, int act) {
    SOOC_ASSERT(act == SOOC_NN_EP_NONE || act == SOOC_NN_EP_RELU);
    sooc_nn_gemm(R, O, I, x, ldx, W, O, y, ldy, b, acc, act, NULL, 0);
}

void sooc_nn_dense_backward(int R, int I, int O, const float *dz, int ldz, const float *x, int ldx, const float *W,
                            const float *Wt, float *dx, int lddx, int acc_dx, const float *xmask, float *dW,
                            float *db, float alpha) {
    if (R <= 0) return;
    if (dW) sooc_nn_gemm_tn(I, O, R, alpha, x, ldx, dz, ldz, dW, O);
    if (db)
        for (int r = 0; r < R; r++) {
            const float *restrict g = dz + (size_t)r * ldz;
            for (int j = 0; j < O; j++) db[j] += alpha * g[j];
        }
    if (!dx) return;
    if (Wt) {
        sooc_nn_gemm(R, I, O, dz, ldz, Wt, I, dx, lddx, NULL, acc_dx, xmask ? SOOC_NN_EP_MASK : SOOC_NN_EP_NONE, xmask,
                     ldx);
        return;
    }
    sooc_nn_gemm_nt(R, I, O, dz, ldz, W, O, dx, lddx, acc_dx, xmask ? SOOC_NN_EP_MASK : SOOC_NN_EP_NONE, xmask, ldx);
}

/* ---------------------------------------------------------------- heads */

void sooc_nn_nerf_heads_forward(int R, int H, int Hc, const float *h, const float *hc, const float *Wd,
                                const float *bd, const float *Wc2, const float *bc2, float *sig, float *col) {
    SOOC_ASSERT(Hc <= SOOC_NN_HC_MAX);
    /* Wc2 [Hc x 3] transposed to 3 contiguous rows */
    float w2t[3][SOOC_NN_HC_MAX];
    for (int j = 0; j < Hc; j++)
        for (int a = 0; a < 3; a++) w2t[a][j] = Wc2[j * 3 + a];
    float b = bd[0], b0 = bc2[0], b1 = bc2[1], b2 = bc2[2];
    for (int r = 0; r < R; r++) {
        const float *h3 = h + (size_t)r * H, *hr = hc + (size_t)r * Hc;
        sig[r] = sigm(dot8(h3, Wd, H) + b);
        float *cr = col + (size_t)r * 3;
        cr[0] = sigm(dot8(hr, w2t[0], Hc) + b0);
        cr[1] = sigm(dot8(hr, w2t[1], Hc) + b1);
        cr[2] = sigm(dot8(hr, w2t[2], Hc) + b2);
    }
}

void sooc_nn_nerf_heads_backward(int R, int H, int Hc, const float *h, const float *hc, const float *sig,
                                 const float *col, const float *Wd, const float *Wc2, float *gsig, float *gcol,
                                 float *dh, float *dhc, float *dWd, float *dbd, float *dWc2, float *dbc2,
                                 float alpha) {
    SOOC_ASSERT(Hc <= SOOC_NN_HC_MAX);
    if (R <= 0) return;
    float w2t[3][SOOC_NN_HC_MAX];
    for (int j = 0; j < Hc; j++)
        for (int a = 0; a < 3; a++) w2t[a][j] = Wc2[j * 3 + a];
    for (int r = 0; r < R; r++) {
        gsig[r] *= sig[r] * (1 - sig[r]);
        float *gc = gcol + (size_t)r * 3;
        const float *cl = col + (size_t)r * 3;
        gc[0] *= cl[0] * (1 - cl[0]), gc[1] *= cl[1] * (1 - cl[1]), gc[2] *= cl[2] * (1 - cl[2]);
    }
    /* dhc = (gcol' Wc2^T) masked by hc > 0 and dh = gsig' Wd^T as GEMMs with K = 3 and 1
     * (the register kernels; per-row loops over Hc and H cost ~7% of a decode) */
    sooc_nn_gemm(R, Hc, 3, gcol, 3, &w2t[0][0], SOOC_NN_HC_MAX, dhc, Hc, NULL, 0, SOOC_NN_EP_MASK, hc, Hc);
    sooc_nn_gemm(R, H, 1, gsig, 1, Wd, H, dh, H, NULL, 0, SOOC_NN_EP_NONE, NULL, 0);
    if (!dWd) return;
    sooc_nn_gemm_tn(Hc, 3, R, alpha, hc, Hc, gcol, 3, dWc2, 3);
    sooc_nn_gemm_tn(H, 1, R, alpha, h, H, gsig, 1, dWd, 1);
    for (int r = 0; r < R; r++) {
        dbd[0] += alpha * gsig[r];
        for (int a = 0; a < 3; a++) dbc2[a] += alpha * gcol[(size_t)r * 3 + a];
    }
}

/* ---------------------------------------------------------------- tail */

/* Rows per block: a block's activations (~4 x 256 x 64 floats) stay in L2 between layers. */
#define TAIL_BLOCK 256

void sooc_nn_nerf_tail_forward(const sooc_nn_nerf_tail *t, int R, float *a1, float *a2, float *a3, float *ac,
                               float *sig, float *col, int relu_a1) {
    int H = t->H, Hc = t->Hc;
    for (int r0 = 0; r0 < R; r0 += TAIL_BLOCK) {
        int nb = R - r0 < TAIL_BLOCK ? R - r0 : TAIL_BLOCK;
        float *x1 = a1 + (size_t)r0 * H, *x2 = a2 + (size_t)r0 * H, *x3 = a3 + (size_t)r0 * H, *xc = ac + (size_t)r0 * Hc;
        if (relu_a1)
            for (size_t i = 0; i < (size_t)nb * H; i++) x1[i] = x1[i] > 0 ? x1[i] : 0;
        sooc_nn_dense_forward(nb, H, H, x1, H, t->W2, t->b2, x2, H, 0, SOOC_NN_EP_RELU);
        sooc_nn_dense_forward(nb, H, H, x2, H, t->W3, t->b3, x3, H, 0, SOOC_NN_EP_RELU);
        sooc_nn_dense_forward(nb, H, Hc, x3, H, t->Wc1, t->bc1, xc, Hc, 0, SOOC_NN_EP_RELU);
        sooc_nn_nerf_heads_forward(nb, H, Hc, x3, xc, t->Wd, t->bd, t->Wc2, t->bc2, sig + r0, col + (size_t)r0 * 3);
    }
}

void sooc_nn_nerf_tail_backward(const sooc_nn_nerf_tail *t, const sooc_nn_nerf_tail_grad *g, float alpha, int R,
                                const float *a1, const float *a2, const float *a3, const float *ac, const float *sig,
                                const float *col, float *gsig, float *gcol, float *gA, float *gB, float *gC,
                                float *g1) {
    int H = t->H, Hc = t->Hc;
    if (R <= 0) return;
    /* heads: density share of dL/da3 into gA, colour hidden pre-activation gradient into gC */
    sooc_nn_nerf_heads_backward(R, H, Hc, a3, ac, sig, col, t->Wd, t->Wc2, gsig, gcol, gA, gC, g ? g->Wd : NULL,
                                g ? g->bd : NULL, g ? g->Wc2 : NULL, g ? g->bc2 : NULL, alpha);
    /* Wc1: gA += gC Wc1^T, masked by a3 > 0 -> layer-3 pre-activation gradient */
    sooc_nn_dense_backward(R, H, Hc, gC, Hc, a3, H, t->Wc1, t->Wc1t, gA, H, 1, a3, g ? g->Wc1 : NULL, g ? g->bc1 : NULL,
                           alpha);
    /* W3: gB = gA W3^T masked by a2 (gC may alias gB: it is consumed) */
    sooc_nn_dense_backward(R, H, H, gA, H, a2, H, t->W3, t->W3t, gB, H, 0, a2, g ? g->W3 : NULL, g ? g->b3 : NULL,
                           alpha);
    /* W2: g1 = gB W2^T masked by a1 (g1 may alias gA: it is consumed) */
    sooc_nn_dense_backward(R, H, H, gB, H, a1, H, t->W2, t->W2t, g1, H, 0, a1, g ? g->W2 : NULL, g ? g->b2 : NULL,
                           alpha);
}
