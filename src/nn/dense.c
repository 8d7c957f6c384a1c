/*
 * sgemm-based kernel: linear (torch layout w[O,I]). Backward accumulates
 * (beta = 1). The refinement net's conv and LSTM are in rconv.c / rcell.c.
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
