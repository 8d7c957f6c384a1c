/*
 * sooc3d nn: the layers of the refinement network (docs/model.md "Layers") as the model
 * runs them, as forward/backward kernel pairs (the internal interface of src/nn
 * for src/model; docs/architecture.md "Layers"). src/model/refine.c
 * is built from these; tests/nn/test_nn_refine_grad.c checks every pair by
 * finite differences in float64, tests/nn/test_nn_refine_ref.c against
 * PyTorch (tests/ref/refine_ref.py).
 *
 * Conventions (as nn.h): backward ACCUMULATES (+=) into every gradient
 * pointer, any of which may be NULL; no allocation (callers pass scratch).
 * Layouts are the model's, not torch's:
 *   images  [C][B][H][W] ("CBHW": channel-major, then item, then pixel);
 *   conv    w[Co][Ci*9] (torch's [Co,Ci,3,3] flattened), b[Co];
 *   linear  w[I][O] (y = x w, torch's weight transposed), b[O];
 *   LSTM    wx[I][4G], wh[G][4G], one bias b[4G], gate order i, f, g, o.
 *
 * Every float32 kernel, forward and backward, computes each output as ONE
 * multiply-add chain over the reduction index in order (sooc_nn_gemm,
 * _gemm_tn and _gemm_nt of nn/nn_kern.h: AVX2/FMA, or the portable C
 * kernel), then adds the bias and applies the activation; results do not
 * depend on how items are split across threads nor on the BLAS library. ELU is exp(x) - 1 with a Cephes polynomial
 * (relative error < 1e-7, like expf).
 *
 * Each pair also has a plain float64 version (suffix _f64, same arguments in
 * double, no scratch, serial) used by the finite-difference checks and as the
 * reference of the float32 kernels.
 */
#ifndef SOOC3D_NN_REFINE_H
#define SOOC3D_NN_REFINE_H

#include <stddef.h>
#include <stdint.h>
#include "nn/nn.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------- conv
 * 3x3, stride 2, TF "SAME" on even sizes: no padding before, one zero row and
 * column after. x[Ci][B][H][W] -> y[Co][B][H/2][W/2] = act(conv + b), act NONE
 * or ELU. H and W must be even. */
static inline size_t sooc_nn_rconv_cols_floats(int Ci, int nb, int H, int W) {
    return (size_t)Ci * 9 * (size_t)nb * (size_t)(H / 2) * (size_t)(W / 2);
}
/* The share of input channels [0, nsh) of item 0 in the convolution (no bias):
 * ysh[Co][Ho*Wo]. For inputs whose first nsh channels are the same for every
 * item (and stored for item 0 only). cols: sooc_nn_rconv_cols_floats(nsh, 1, H, W). */
void sooc_nn_rconv_shared(float *ysh, float *cols, const float *x, const float *w, int B, int Ci, int H, int W,
                          int Co, int nsh);
/* Forward of items [b0, b1) (y keeps its full [Co][B][Ho*Wo] layout). ysh NULL:
 * the plain convolution; else channels [0, nsh) are taken from ysh (continuing
 * each output's FMA chain from it, so the result equals the full product).
 * cols: sooc_nn_rconv_cols_floats(Ci - nsh, b1 - b0, H, W) floats. */
void sooc_nn_rconv_forward(float *y, float *cols, const float *x, const float *w, const float *b,
                           const float *ysh, int nsh, int B, int b0, int b1, int Ci, int H, int W, int Co,
                           sooc_nn_act act);
/* Backward of items [b0, b1) (whole batch: 0, B; serial). dy [Co][B][Ho*Wo]
 * (dL/dy) is OVERWRITTEN with the pre-activation gradient on those items; y is
 * the forward output. dx [Ci][B][H][W] (those items), dw, db accumulate.
 * cols, dcols: sooc_nn_rconv_cols_floats(Ci, b1 - b0, H, W) floats each
 * (dcols only if dx). Callers split items into a FIXED set of blocks (private
 * dw/db per block, summed in block order) to get thread-count independent
 * results; dx needs no reduction (items are independent). */
void sooc_nn_rconv_backward(float *dx, float *dw, float *db, float *dy, const float *y, const float *x,
                            const float *w, float *cols, float *dcols, int B, int b0, int b1, int Ci, int H, int W,
                            int Co, sooc_nn_act act);
void sooc_nn_rconv_forward_f64(double *y, const double *x, const double *w, const double *b, int B, int Ci, int H,
                               int W, int Co, sooc_nn_act act);
void sooc_nn_rconv_backward_f64(double *dx, double *dw, double *db, const double *dy, const double *y,
                                const double *x, const double *w, int B, int Ci, int H, int W, int Co,
                                sooc_nn_act act);

/* -------------------------------------------------------------------- ELU
 * y = x > 0 ? x : exp(x) - 1;  dx += dy * (y > 0 ? 1 : y + 1). y may alias x. */
void sooc_nn_elu_forward(float *y, const float *x, int64_t n);
void sooc_nn_elu_backward(float *dx, const float *dy, const float *y, int64_t n);
void sooc_nn_elu_forward_f64(double *y, const double *x, int64_t n);
void sooc_nn_elu_backward_f64(double *dx, const double *dy, const double *y, int64_t n);

/* ------------------------------------------------------- MulMON layer norm
 * y = (x - mean) / (std + 1e-5) over one group of n = nblk * len values: nblk
 * blocks of len contiguous values, ld apart (one item's channels of a CBHW
 * image: len = H*W, ld = B*H*W; a vector: nblk = 1). Biased std, sums in
 * double. No learnable scale. y may alias x. stats[3] (mean, std, 1/(std+eps))
 * are saved for backward. */
#define SOOC_NN_MLN_EPS 1e-5f
void sooc_nn_mln_forward(float *y, float *stats, const float *x, int nblk, int64_t len, int64_t ld);
void sooc_nn_mln_backward(float *dx, const float *dy, const float *y, const float *stats, int nblk, int64_t len,
                          int64_t ld);
void sooc_nn_mln_forward_f64(double *y, double *stats, const double *x, int nblk, int64_t len, int64_t ld);
void sooc_nn_mln_backward_f64(double *dx, const double *dy, const double *y, const double *stats, int nblk,
                              int64_t len, int64_t ld);

/* ----------------------------------------------------------------- linear
 * y[M][N] = act(x[M][K] w[K][N] + b[N]) (ldx: row stride of x; b may be NULL;
 * act NONE or ELU). backward: dy[M][N] is OVERWRITTEN with the pre-activation
 * gradient; dx[M][K] (row stride ldx), dw[K][N], db[N] accumulate. */
void sooc_nn_rlinear_forward(float *y, const float *x, int ldx, const float *w, const float *b, int M, int K, int N,
                             sooc_nn_act act);
void sooc_nn_rlinear_backward(float *dx, float *dw, float *db, float *dy, const float *x, int ldx, const float *y,
                              const float *w, int M, int K, int N, sooc_nn_act act);
void sooc_nn_rlinear_forward_f64(double *y, const double *x, int ldx, const double *w, const double *b, int M, int K,
                                 int N, sooc_nn_act act);
void sooc_nn_rlinear_backward_f64(double *dx, double *dw, double *db, double *dy, const double *x, int ldx,
                                  const double *y, const double *w, int M, int K, int N, sooc_nn_act act);

/* ------------------------------------------------------------- LSTM cell
 * z[B][4G] = x[B][I] wx + h0[B][G] wh (one FMA chain over x then h0) + b;
 * i, f, o = sigmoid, g = tanh; c1 = f c0 + i g; h1 = o tanh(c1).
 * gates[B][4G] (post-activation) and c1 are saved. backward: dh1, dc1 (either
 * may be NULL) are the gradients w.r.t. h1 and c1; dx, dh0, dc0, dwx, dwh, db
 * accumulate; scratch: 4 B G floats. */
void sooc_nn_rlstm_forward(float *h1, float *c1, float *gates, const float *x, const float *h0, const float *c0,
                           const float *wx, const float *wh, const float *b, int B, int In, int G);
void sooc_nn_rlstm_backward(float *dx, float *dh0, float *dc0, float *dwx, float *dwh, float *db, const float *dh1,
                            const float *dc1, float *scratch, const float *gates, const float *c1, const float *x,
                            const float *h0, const float *c0, const float *wx, const float *wh, int B, int In, int G);
void sooc_nn_rlstm_forward_f64(double *h1, double *c1, double *gates, const double *x, const double *h0,
                               const double *c0, const double *wx, const double *wh, const double *b, int B, int In,
                               int G);
void sooc_nn_rlstm_backward_f64(double *dx, double *dh0, double *dc0, double *dwx, double *dwh, double *db,
                                const double *dh1, const double *dc1, const double *gates, const double *c1,
                                const double *x, const double *h0, const double *c0, const double *wx,
                                const double *wh, int B, int In, int G);

/* -------------------------------------------------------- pool + flatten
 * The conv stack's last map x[C][B][fh][fw] flattened per item for the FC:
 * flat[B][C * ph * pw], average-pooled to ph = min(fh, 2), pw = min(fw, 2)
 * (fh, fw multiples of ph, pw). backward: dx += (dflat spread over windows). */
void sooc_nn_pool2_forward(float *flat, const float *x, int C, int B, int fh, int fw);
void sooc_nn_pool2_backward(float *dx, const float *dflat, int C, int B, int fh, int fw);
void sooc_nn_pool2_forward_f64(double *flat, const double *x, int C, int B, int fh, int fw);
void sooc_nn_pool2_backward_f64(double *dx, const double *dflat, int C, int B, int fh, int fw);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_NN_REFINE_H */
