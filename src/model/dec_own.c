/* A decoder MLP on its own weights (dec_own.h): the finetuned copies of
 * model.md §4. Same network as decoder.c (pe -> 3 ReLU layers -> density
 * sigmoid, colour head -> sigmoid), written on a plain weight pointer with
 * CBLAS so that it does not depend on the model's slab or its kernels. */
#include "model/dec_own.h"

#include <cblas.h>
#include <math.h>
#include <string.h>

static inline float sigm(float x) { return 1.0f / (1.0f + expf(-x)); }

size_t mdl_dec_count(const dec_net *n) { return n->bc2 + 3 - n->W1x; }

void mdl_dec_rel(const dec_net *n, dec_net *r) {
    *r = *n;
    size_t o = n->W1x;
    r->W1x -= o, r->W1z -= o, r->b1 -= o, r->W2 -= o, r->b2 -= o, r->W3 -= o, r->b3 -= o;
    r->Wd -= o, r->bd -= o, r->Wc1 -= o, r->bc1 -= o, r->Wc2 -= o, r->bc2 -= o;
}

size_t mdl_ft_payload_size(const dec_net *n) { return MDL_FT_HDR + (size_t)n->dz + mdl_dec_count(n); }

void mdl_ft_payload_pack(const dec_net *n, int kind, const float *z, const float *w, float *out) {
    size_t nw = mdl_dec_count(n);
    out[0] = MDL_FT_MAGIC, out[1] = MDL_FT_VERSION, out[2] = (float)kind, out[3] = (float)n->dz;
    out[4] = (float)n->din, out[5] = (float)n->H, out[6] = (float)n->Hc, out[7] = (float)nw;
    memcpy(out + MDL_FT_HDR, z, (size_t)n->dz * sizeof(float));
    memcpy(out + MDL_FT_HDR + n->dz, w, nw * sizeof(float));
}

int mdl_ft_payload_ok(const dec_net *n, int kind, const float *v, size_t nv) {
    return v && nv == mdl_ft_payload_size(n) && v[0] == MDL_FT_MAGIC && v[1] == MDL_FT_VERSION &&
           v[2] == (float)kind && v[3] == (float)n->dz && v[4] == (float)n->din && v[5] == (float)n->H &&
           v[6] == (float)n->Hc && v[7] == (float)mdl_dec_count(n);
}

void mdl_own_bias(const float *w, const dec_net *r, const float *z, float *bias) {
    int H = r->H;
    memcpy(bias, w + r->b1, (size_t)H * sizeof(float));
    for (int i = 0; i < r->dz; i++) {
        const float *row = w + r->W1z + (size_t)i * H;
        float zi = z[i];
        for (int j = 0; j < H; j++) bias[j] += zi * row[j];
    }
}

static void relu(float *x, size_t n) {
    for (size_t i = 0; i < n; i++) x[i] = x[i] > 0 ? x[i] : 0;
}

void mdl_own_forward(const float *w, const dec_net *r, int R, const float *pe, const float *bias, float *a1,
                     float *a2, float *a3, float *ac, float *sig, float *col) {
    if (R <= 0) return;
    int H = r->H, Hc = r->Hc, din = r->din;
    for (int i = 0; i < R; i++) memcpy(a1 + (size_t)i * H, bias, (size_t)H * sizeof(float));
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, R, H, din, 1.0f, pe, din, w + r->W1x, H, 1.0f, a1, H);
    relu(a1, (size_t)R * H);
    for (int i = 0; i < R; i++) memcpy(a2 + (size_t)i * H, w + r->b2, (size_t)H * sizeof(float));
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, R, H, H, 1.0f, a1, H, w + r->W2, H, 1.0f, a2, H);
    relu(a2, (size_t)R * H);
    for (int i = 0; i < R; i++) memcpy(a3 + (size_t)i * H, w + r->b3, (size_t)H * sizeof(float));
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, R, H, H, 1.0f, a2, H, w + r->W3, H, 1.0f, a3, H);
    relu(a3, (size_t)R * H);
    for (int i = 0; i < R; i++) memcpy(ac + (size_t)i * Hc, w + r->bc1, (size_t)Hc * sizeof(float));
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, R, Hc, H, 1.0f, a3, H, w + r->Wc1, Hc, 1.0f, ac, Hc);
    relu(ac, (size_t)R * Hc);
    const float *Wd = w + r->Wd, *Wc2 = w + r->Wc2;
    float bd = w[r->bd];
    for (int i = 0; i < R; i++) {
        const float *h3 = a3 + (size_t)i * H, *hc = ac + (size_t)i * Hc;
        float s = bd;
        for (int j = 0; j < H; j++) s += h3[j] * Wd[j];
        sig[i] = sigm(s);
        float c0 = w[r->bc2], c1 = w[r->bc2 + 1], c2 = w[r->bc2 + 2];
        for (int j = 0; j < Hc; j++) {
            c0 += hc[j] * Wc2[j * 3], c1 += hc[j] * Wc2[j * 3 + 1], c2 += hc[j] * Wc2[j * 3 + 2];
        }
        col[(size_t)i * 3] = sigm(c0), col[(size_t)i * 3 + 1] = sigm(c1), col[(size_t)i * 3 + 2] = sigm(c2);
    }
}

/* g[i] = y[i] > 0 ? g[i] : 0 (ReLU backward on the post-activation) */
static void mask(float *g, const float *y, size_t n) {
    for (size_t i = 0; i < n; i++) g[i] = y[i] > 0 ? g[i] : 0;
}
/* bias gradient: gb[j] += sum_i G[i][j] */
static void colsum(const float *G, int R, int N, float *gb) {
    for (int i = 0; i < R; i++)
        for (int j = 0; j < N; j++) gb[j] += G[(size_t)i * N + j];
}

void mdl_own_backward(const float *w, const dec_net *r, int R, const float *pe, const float *a1, const float *a2,
                      const float *a3, const float *ac, const float *sig, const float *col, float *gsig, float *gcol,
                      float *gA, float *gB, float *gC, float *gw, float *gbias) {
    if (R <= 0) return;
    int H = r->H, Hc = r->Hc, din = r->din;
    const float *Wd = w + r->Wd, *Wc2 = w + r->Wc2;
    /* heads: sig = sigmoid(a3 Wd + bd), col = sigmoid(ac Wc2 + bc2) */
    for (int i = 0; i < R; i++) {
        float gs = gsig[i] * sig[i] * (1 - sig[i]);
        gsig[i] = gs;
        float *gc = gcol + (size_t)i * 3;
        const float *c = col + (size_t)i * 3;
        for (int a = 0; a < 3; a++) gc[a] *= c[a] * (1 - c[a]);
        float *ga = gA + (size_t)i * H;   /* d/d a3 from the density head */
        for (int j = 0; j < H; j++) ga[j] = gs * Wd[j];
        float *gh = gC + (size_t)i * Hc;  /* d/d ac */
        for (int j = 0; j < Hc; j++) gh[j] = gc[0] * Wc2[j * 3] + gc[1] * Wc2[j * 3 + 1] + gc[2] * Wc2[j * 3 + 2];
    }
    mask(gC, ac, (size_t)R * Hc);
    /* weight grads of the heads */
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, H, 1, R, 1.0f, a3, H, gsig, 1, 1.0f, gw + r->Wd, 1);
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, Hc, 3, R, 1.0f, ac, Hc, gcol, 3, 1.0f, gw + r->Wc2, 3);
    for (int i = 0; i < R; i++) {
        gw[r->bd] += gsig[i];
        for (int a = 0; a < 3; a++) gw[r->bc2 + a] += gcol[(size_t)i * 3 + a];
    }
    /* ac = relu(a3 Wc1 + bc1) */
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, H, Hc, R, 1.0f, a3, H, gC, Hc, 1.0f, gw + r->Wc1, Hc);
    colsum(gC, R, Hc, gw + r->bc1);
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, R, H, Hc, 1.0f, gC, Hc, w + r->Wc1, Hc, 1.0f, gA, H);
    mask(gA, a3, (size_t)R * H);   /* gA = d/d(a3 pre-activation) */
    /* a3 = relu(a2 W3 + b3) */
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, H, H, R, 1.0f, a2, H, gA, H, 1.0f, gw + r->W3, H);
    colsum(gA, R, H, gw + r->b3);
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, R, H, H, 1.0f, gA, H, w + r->W3, H, 0.0f, gB, H);
    mask(gB, a2, (size_t)R * H);
    /* a2 = relu(a1 W2 + b2) */
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, H, H, R, 1.0f, a1, H, gB, H, 1.0f, gw + r->W2, H);
    colsum(gB, R, H, gw + r->b2);
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, R, H, H, 1.0f, gB, H, w + r->W2, H, 0.0f, gA, H);
    mask(gA, a1, (size_t)R * H);
    /* a1 = relu(pe W1x + bias) */
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, din, H, R, 1.0f, pe, din, gA, H, 1.0f, gw + r->W1x, H);
    colsum(gA, R, H, gbias);
}

void mdl_own_bias_backward(const float *w, const dec_net *r, const float *z, const float *gbias, float *gw,
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
