/*
 * sgemm-based kernels: linear, conv2d 3x3 (im2col), LSTM cell.
 * Layouts follow torch: Linear w[O,I], Conv w[Co,Ci,3,3], LSTMCell w_ih[4G,I]
 * with gate order (i, f, g, o). Backward accumulates (beta = 1).
 */
#include "nn_impl.h"
#include <math.h>
#include <string.h>

/* --------------------------------------------------------------- linear */

void sooc_nn_linear_forward(float *y, const float *x, const float *w, const float *b,
                            int64_t N, int I, int O, sooc_nn_act act) {
    if (N == 0) return;
    /* y[N,O] = x[N,I] w[O,I]^T */
    sooc_nn_sgemm(0, 1, (int)N, O, I, 1.f, x, I, w, I, 0.f, y,
                O);
    if (!b && act == SOOC_NN_ACT_NONE) return;
#pragma omp parallel for schedule(static) if (N * O > SOOC_NN_PAR_MIN)
    for (int64_t n = 0; n < N; n++) {
        float *r = y + n * O;
        for (int o = 0; o < O; o++) r[o] = sooc_nn_act_apply(act, b ? r[o] + b[o] : r[o]);
    }
}

void sooc_nn_linear_backward(float *dx, float *dw, float *db, float *dy, const float *x,
                             const float *y, const float *w, int64_t N, int I, int O,
                             sooc_nn_act act) {
    if (N == 0) return;
    sooc_nn_act_backward_inplace(act, dy, y, N * O);
    if (dx) /* dx[N,I] += dz[N,O] w[O,I] */
        sooc_nn_sgemm(0, 0, (int)N, I, O, 1.f, dy, O, w, I,
                    1.f, dx, I);
    if (dw) /* dw[O,I] += dz^T[O,N] x[N,I] */
        sooc_nn_sgemm(1, 0, O, I, (int)N, 1.f, dy, O, x, I, 1.f,
                    dw, I);
    if (db) {
        for (int o = 0; o < O; o++) {
            double s = 0.0;
            for (int64_t n = 0; n < N; n++) s += dy[n * O + o];
            db[o] += (float)s;
        }
    }
}

/* --------------------------------------------------------------- conv2d */

static void conv_pads(int in, int stride, int *out, int *pad_before) {
    int o = sooc_nn_conv2d_out(in, stride);
    int total = (o - 1) * stride + 3 - in;
    if (total < 0) total = 0;
    *out = o;
    *pad_before = total / 2;
}

size_t sooc_nn_conv2d_col_floats(int B, int Ci, int H, int W, int stride) {
    int Ho, Wo, p;
    conv_pads(H, stride, &Ho, &p);
    conv_pads(W, stride, &Wo, &p);
    return (size_t)Ci * 9 * (size_t)B * Ho * Wo;
}

size_t sooc_nn_conv2d_scratch_floats(int B, int Ci, int H, int W, int Co, int stride) {
    int Ho, Wo, p;
    conv_pads(H, stride, &Ho, &p);
    conv_pads(W, stride, &Wo, &p);
    return (size_t)(Co + Ci * 9) * (size_t)B * Ho * Wo;
}

void sooc_nn_conv2d_forward(float *y, float *col, float *scratch, const float *x, const float *w,
                            const float *b, int B, int Ci, int H, int W, int Co, int stride,
                            sooc_nn_act act) {
    int Ho, Wo, pt, pl;
    conv_pads(H, stride, &Ho, &pt);
    conv_pads(W, stride, &Wo, &pl);
    int64_t P = (int64_t)Ho * Wo, BP = (int64_t)B * P;
    /* im2col: col[(ci*9 + ky*3 + kx), b*P + oy*Wo + ox] */
#pragma omp parallel for schedule(static) if (9 * (int64_t)Ci * BP > SOOC_NN_PAR_BIG)
    for (int r = 0; r < Ci * 9; r++) {
        int ci = r / 9, ky = (r % 9) / 3, kx = r % 3;
        float *cr = col + (int64_t)r * BP;
        for (int bb = 0; bb < B; bb++) {
            const float *xp = x + ((int64_t)bb * Ci + ci) * H * W;
            for (int oy = 0; oy < Ho; oy++) {
                int iy = oy * stride + ky - pt;
                float *dst = cr + bb * P + (int64_t)oy * Wo;
                if (iy < 0 || iy >= H) {
                    for (int ox = 0; ox < Wo; ox++) dst[ox] = 0.f;
                    continue;
                }
                for (int ox = 0; ox < Wo; ox++) {
                    int ix = ox * stride + kx - pl;
                    dst[ox] = (ix >= 0 && ix < W) ? xp[(int64_t)iy * W + ix] : 0.f;
                }
            }
        }
    }
    float *tmp = scratch; /* [Co, B*P] */
    sooc_nn_sgemm(0, 0, Co, (int)BP, Ci * 9, 1.f, w, Ci * 9,
                col, (int)BP, 0.f, tmp, (int)BP);
#pragma omp parallel for schedule(static) if ((int64_t)Co * BP > SOOC_NN_PAR_BIG)
    for (int bc = 0; bc < B * Co; bc++) {
        int bb = bc / Co, co = bc % Co;
        const float *s = tmp + (int64_t)co * BP + bb * P;
        float *d = y + (int64_t)bc * P;
        float bias = b ? b[co] : 0.f;
        for (int64_t p = 0; p < P; p++) d[p] = sooc_nn_act_apply(act, s[p] + bias);
    }
}

void sooc_nn_conv2d_backward(float *dx, float *dw, float *db, float *dy, const float *col,
                             float *scratch, const float *y, const float *w, int B, int Ci, int H,
                             int W, int Co, int stride, sooc_nn_act act) {
    int Ho, Wo, pt, pl;
    conv_pads(H, stride, &Ho, &pt);
    conv_pads(W, stride, &Wo, &pl);
    int64_t P = (int64_t)Ho * Wo, BP = (int64_t)B * P;
    sooc_nn_act_backward_inplace(act, dy, y, (int64_t)B * Co * P);
    float *tmp = scratch;                  /* dz as [Co, B*P] */
    float *dcol = scratch + (int64_t)Co * BP; /* [Ci*9, B*P] */
#pragma omp parallel for schedule(static) if ((int64_t)Co * BP > SOOC_NN_PAR_BIG)
    for (int co = 0; co < Co; co++) {
        double s = 0.0;
        for (int bb = 0; bb < B; bb++) {
            const float *src = dy + ((int64_t)bb * Co + co) * P;
            float *d = tmp + (int64_t)co * BP + bb * P;
            for (int64_t p = 0; p < P; p++) { d[p] = src[p]; s += src[p]; }
        }
        if (db) db[co] += (float)s;
    }
    if (dw) /* dw[Co, Ci*9] += tmp[Co,BP] col^T[BP, Ci*9] */
        sooc_nn_sgemm(0, 1, Co, Ci * 9, (int)BP, 1.f, tmp,
                    (int)BP, col, (int)BP, 1.f, dw, Ci * 9);
    if (!dx) return;
    /* dcol[Ci*9, BP] = w^T[Ci*9, Co] tmp[Co, BP] */
    sooc_nn_sgemm(1, 0, Ci * 9, (int)BP, Co, 1.f, w, Ci * 9, tmp,
                (int)BP, 0.f, dcol, (int)BP);
    /* col2im: each (b, ci) owns dx[b, ci, :, :]; taps summed in fixed order */
#pragma omp parallel for schedule(static) if (9 * (int64_t)Ci * BP > SOOC_NN_PAR_BIG)
    for (int bc = 0; bc < B * Ci; bc++) {
        int bb = bc / Ci, ci = bc % Ci;
        float *dxp = dx + (int64_t)bc * H * W;
        for (int k = 0; k < 9; k++) {
            int ky = k / 3, kx = k % 3;
            const float *cr = dcol + (int64_t)(ci * 9 + k) * BP + bb * P;
            for (int oy = 0; oy < Ho; oy++) {
                int iy = oy * stride + ky - pt;
                if (iy < 0 || iy >= H) continue;
                for (int ox = 0; ox < Wo; ox++) {
                    int ix = ox * stride + kx - pl;
                    if (ix >= 0 && ix < W) dxp[(int64_t)iy * W + ix] += cr[(int64_t)oy * Wo + ox];
                }
            }
        }
    }
}

/* ----------------------------------------------------------------- LSTM */

void sooc_nn_lstm_forward(float *h1, float *c1, float *gates, const float *x, const float *h0,
                          const float *c0, const float *w_ih, const float *w_hh,
                          const float *b_ih, const float *b_hh, int B, int I, int G) {
    int G4 = 4 * G;
    sooc_nn_sgemm(0, 1, B, G4, I, 1.f, x, I, w_ih, I, 0.f, gates,
                G4);
    if (h0)
        sooc_nn_sgemm(0, 1, B, G4, G, 1.f, h0, G, w_hh, G, 1.f,
                    gates, G4);
    for (int bb = 0; bb < B; bb++) {
        float *z = gates + (int64_t)bb * G4;
        for (int j = 0; j < G4; j++) {
            float v = z[j];
            if (b_ih) v += b_ih[j];
            if (b_hh) v += b_hh[j];
            z[j] = (j >= 2 * G && j < 3 * G) ? tanhf(v) : sooc_nn_sigm(v);
        }
        for (int j = 0; j < G; j++) {
            float ig = z[j], fg = z[G + j], gg = z[2 * G + j], og = z[3 * G + j];
            float cp = c0 ? c0[(int64_t)bb * G + j] : 0.f;
            float cn = fg * cp + ig * gg;
            c1[(int64_t)bb * G + j] = cn;
            h1[(int64_t)bb * G + j] = og * tanhf(cn);
        }
    }
}

void sooc_nn_lstm_backward(float *dx, float *dh0, float *dc0, float *dw_ih, float *dw_hh,
                           float *db_ih, float *db_hh, const float *dh1, const float *dc1,
                           float *scratch, const float *gates, const float *c1, const float *x,
                           const float *h0, const float *c0, const float *w_ih,
                           const float *w_hh, int B, int I, int G) {
    int G4 = 4 * G;
    float *dz = scratch; /* [B, 4G] */
    for (int bb = 0; bb < B; bb++) {
        const float *z = gates + (int64_t)bb * G4;
        float *d = dz + (int64_t)bb * G4;
        for (int j = 0; j < G; j++) {
            int64_t k = (int64_t)bb * G + j;
            float ig = z[j], fg = z[G + j], gg = z[2 * G + j], og = z[3 * G + j];
            float tc = tanhf(c1[k]);
            float gh = dh1 ? dh1[k] : 0.f;
            /* forward: h1 = o*tanh(c1); c1 = f*c0 + i*g */
            float dc = (dc1 ? dc1[k] : 0.f) + gh * og * (1.f - tc * tc);
            float cp = c0 ? c0[k] : 0.f;
            d[j] = dc * gg * ig * (1.f - ig);
            d[G + j] = dc * cp * fg * (1.f - fg);
            d[2 * G + j] = dc * ig * (1.f - gg * gg);
            d[3 * G + j] = gh * tc * og * (1.f - og);
            if (dc0) dc0[k] += dc * fg;
        }
    }
    if (dx)
        sooc_nn_sgemm(0, 0, B, I, G4, 1.f, dz, G4, w_ih, I, 1.f,
                    dx, I);
    if (dh0)
        sooc_nn_sgemm(0, 0, B, G, G4, 1.f, dz, G4, w_hh, G, 1.f,
                    dh0, G);
    if (dw_ih)
        sooc_nn_sgemm(1, 0, G4, I, B, 1.f, dz, G4, x, I, 1.f,
                    dw_ih, I);
    if (dw_hh && h0)
        sooc_nn_sgemm(1, 0, G4, G, B, 1.f, dz, G4, h0, G, 1.f,
                    dw_hh, G);
    for (int j = 0; j < G4; j++) {
        double s = 0.0;
        for (int bb = 0; bb < B; bb++) s += dz[(int64_t)bb * G4 + j];
        if (db_ih) db_ih[j] += (float)s;
        if (db_hh) db_hh[j] += (float)s;
    }
}
