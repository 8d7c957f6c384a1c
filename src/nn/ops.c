/*
 * Elementwise, broadcasting, shape and reduction kernels (forward/backward
 * pairs). Backward functions accumulate (+=) and skip NULL gradients.
 * OpenMP: every parallel loop writes only the elements its iteration owns,
 * so results are bitwise identical with and without OpenMP.
 */
#include "nn_impl.h"
#include <math.h>
#include <string.h>

/* ----------------------------------------------------------- unary */

static inline float act_f(sooc_nn_act f, float x) {
    switch (f) {
    case SOOC_NN_ACT_SOFTPLUS:
        /* torch: threshold 20 -> identity; log1p(exp(x)) otherwise */
        return x > 20.f ? x : log1pf(expf(x));
    case SOOC_NN_ACT_EXP: return expf(x);
    case SOOC_NN_ACT_LOG: return logf(x);
    case SOOC_NN_ACT_SQUARE: return x * x;
    default: return sooc_nn_act_apply(f, x);   /* NONE, RELU, ELU, SIGMOID, TANH */
    }
}

/* derivative dy/dx from x and y */
static inline float act_df(sooc_nn_act f, float x, float y) {
    switch (f) {
    case SOOC_NN_ACT_NONE: return 1.f;
    case SOOC_NN_ACT_RELU: return y > 0.f ? 1.f : 0.f;
    case SOOC_NN_ACT_ELU: return y > 0.f ? 1.f : y + 1.f;
    case SOOC_NN_ACT_SIGMOID: return y * (1.f - y);
    case SOOC_NN_ACT_SOFTPLUS:
        if (x > 20.f) return 1.f;
        return act_f(SOOC_NN_ACT_SIGMOID, x);
    case SOOC_NN_ACT_EXP: return y;
    case SOOC_NN_ACT_LOG: return 1.f / x;
    case SOOC_NN_ACT_SQUARE: return 2.f * x;
    case SOOC_NN_ACT_TANH: return 1.f - y * y;
    }
    return 1.f;
}

void sooc_nn_unary_forward(sooc_nn_act f, float *y, const float *x, int64_t n) {
#pragma omp parallel for schedule(static) if (n > SOOC_NN_PAR_MIN)
    for (int64_t i = 0; i < n; i++) y[i] = act_f(f, x[i]);
}

void sooc_nn_unary_backward(sooc_nn_act f, float *dx, const float *dy, const float *x,
                            const float *y, int64_t n) {
    if (!dx) return;
#pragma omp parallel for schedule(static) if (n > SOOC_NN_PAR_MIN)
    for (int64_t i = 0; i < n; i++) dx[i] += dy[i] * act_df(f, x ? x[i] : 0.f, y ? y[i] : 0.f);
}

void sooc_nn_act_backward_inplace(sooc_nn_act act, float *dy, const float *y, int64_t n) {
    switch (act) {
    case SOOC_NN_ACT_NONE: return;
    case SOOC_NN_ACT_RELU:
#pragma omp parallel for schedule(static) if (n > SOOC_NN_PAR_MIN)
        for (int64_t i = 0; i < n; i++) dy[i] = y[i] > 0.f ? dy[i] : 0.f;
        return;
    case SOOC_NN_ACT_ELU:
    case SOOC_NN_ACT_SIGMOID:
    case SOOC_NN_ACT_TANH:
#pragma omp parallel for schedule(static) if (n > SOOC_NN_PAR_MIN)
        for (int64_t i = 0; i < n; i++) dy[i] *= act_df(act, 0.f, y[i]);
        return;
    default:
        SOOC_ASSERT(!"fused activation must be NONE/RELU/ELU/SIGMOID/TANH");
    }
}

/* -------------------------------------------------------- binary */

static inline float binop(sooc_nn_binop op, float a, float b) {
    switch (op) {
    case SOOC_NN_ADD: return a + b;
    case SOOC_NN_SUB: return a - b;
    case SOOC_NN_MUL: return a * b;
    case SOOC_NN_DIV: return a / b;
    }
    return 0.f;
}

/* strides (in elements) of a padded shape, 0 where the dim is broadcast */
static void bcast_strides(const int64_t *shape, const int64_t *oshape, int ndim, int64_t *st) {
    int64_t s = 1;
    for (int d = ndim - 1; d >= 0; d--) {
        st[d] = (shape[d] == 1 && oshape[d] != 1) ? 0 : s;
        s *= shape[d];
    }
}

static int64_t bcast_setup(const int64_t *ashape, const int64_t *bshape, int ndim, int64_t *o,
                           int64_t *sa, int64_t *sb) {
    SOOC_ASSERT(ndim >= 1 && ndim <= SOOC_NN_MAX_DIMS);
    int64_t n = 1;
    for (int d = 0; d < ndim; d++) {
        SOOC_ASSERT(ashape[d] == bshape[d] || ashape[d] == 1 || bshape[d] == 1);
        o[d] = ashape[d] > bshape[d] ? ashape[d] : bshape[d];
        n *= o[d];
    }
    bcast_strides(ashape, o, ndim, sa);
    bcast_strides(bshape, o, ndim, sb);
    return n;
}

/* flat output index -> (ia, ib) */
static inline void bcast_index(int64_t i, const int64_t *o, const int64_t *sa, const int64_t *sb,
                               int ndim, int64_t *ia, int64_t *ib) {
    int64_t a = 0, b = 0;
    for (int d = ndim - 1; d >= 0; d--) {
        int64_t c = i % o[d];
        i /= o[d];
        a += c * sa[d];
        b += c * sb[d];
    }
    *ia = a;
    *ib = b;
}

void sooc_nn_binary_forward(sooc_nn_binop op, float *out, const float *a, const int64_t *ashape,
                            const float *b, const int64_t *bshape, int ndim) {
    int64_t o[SOOC_NN_MAX_DIMS], sa[SOOC_NN_MAX_DIMS], sb[SOOC_NN_MAX_DIMS];
    int64_t n = bcast_setup(ashape, bshape, ndim, o, sa, sb);
#pragma omp parallel for schedule(static) if (n > SOOC_NN_PAR_MIN)
    for (int64_t i = 0; i < n; i++) {
        int64_t ia, ib;
        bcast_index(i, o, sa, sb, ndim, &ia, &ib);
        out[i] = binop(op, a[ia], b[ib]);
    }
}

/* d/da and d/db of a (op) b */
static inline void binop_grad(sooc_nn_binop op, float a, float b, float g, float *ga, float *gb) {
    switch (op) {
    case SOOC_NN_ADD: *ga = g; *gb = g; break;
    case SOOC_NN_SUB: *ga = g; *gb = -g; break;
    case SOOC_NN_MUL: *ga = g * b; *gb = g * a; break;
    case SOOC_NN_DIV: *ga = g / b; *gb = -g * a / (b * b); break;
    }
}

/* Accumulate the gradient of operand a (side 0, into g = da) or b (side 1,
 * into g = db) in output order. A broadcast operand (ng < n) receives sums in
 * that fixed order, so the loop is serial; when the operand is not broadcast
 * (ng == n) each i owns its element and the loop may run in parallel. Either
 * way the result is bitwise the same. */
static void binary_grad_acc(sooc_nn_binop op, int side, float *g, int64_t ng, const float *dout,
                            const float *a, const float *b, int64_t n, const int64_t *o,
                            const int64_t *sa, const int64_t *sb, int ndim) {
#pragma omp parallel for schedule(static) if (ng == n && n > SOOC_NN_PAR_MIN)
    for (int64_t i = 0; i < n; i++) {
        int64_t ia, ib;
        float ga = 0.f, gb = 0.f;
        bcast_index(i, o, sa, sb, ndim, &ia, &ib);
        binop_grad(op, a[ia], b[ib], dout[i], &ga, &gb);
        if (side) g[ib] += gb;
        else g[ia] += ga;
    }
}

void sooc_nn_binary_backward(sooc_nn_binop op, float *da, float *db, const float *dout,
                             const float *a, const int64_t *ashape, const float *b,
                             const int64_t *bshape, int ndim) {
    int64_t o[SOOC_NN_MAX_DIMS], sa[SOOC_NN_MAX_DIMS], sb[SOOC_NN_MAX_DIMS];
    int64_t n = bcast_setup(ashape, bshape, ndim, o, sa, sb);
    int64_t na = 1, nb = 1;
    for (int d = 0; d < ndim; d++) { na *= ashape[d]; nb *= bshape[d]; }
    if (da) binary_grad_acc(op, 0, da, na, dout, a, b, n, o, sa, sb, ndim);
    if (db) binary_grad_acc(op, 1, db, nb, dout, a, b, n, o, sa, sb, ndim);
}

/* ------------------------------------------------------ slot bias */

void sooc_nn_slot_bias_forward(float *y, const float *x, const float *b, int K, int64_t N,
                               int C) {
#pragma omp parallel for schedule(static) if ((int64_t)K * N * C > SOOC_NN_PAR_MIN)
    for (int64_t r = 0; r < (int64_t)K * N; r++) {
        const float *bk = b + (r / N) * C;
        for (int c = 0; c < C; c++) y[r * C + c] = x[r * C + c] + bk[c];
    }
}

void sooc_nn_slot_bias_backward(float *dx, float *db, const float *dy, int K, int64_t N, int C) {
    if (dx) {
        int64_t n = (int64_t)K * N * C;
#pragma omp parallel for schedule(static) if (n > SOOC_NN_PAR_MIN)
        for (int64_t i = 0; i < n; i++) dx[i] += dy[i];
    }
    if (db) {
        /* each (k) owns db[k,:] */
#pragma omp parallel for schedule(static) if ((int64_t)K * N * C > SOOC_NN_PAR_MIN)
        for (int k = 0; k < K; k++) {
            float *dbk = db + (int64_t)k * C;
            for (int64_t n = 0; n < N; n++) {
                const float *r = dy + ((int64_t)k * N + n) * C;
                for (int c = 0; c < C; c++) dbk[c] += r[c];
            }
        }
    }
}

/* ---------------------------------------------- concat and slice */

void sooc_nn_concat_forward(float *out, const float *const *in, const int64_t *c, int n_in,
                            int64_t outer, int64_t inner) {
    int64_t ctot = 0;
    for (int i = 0; i < n_in; i++) ctot += c[i];
    for (int64_t o = 0; o < outer; o++) {
        int64_t off = 0;
        for (int i = 0; i < n_in; i++) {
            int64_t blk = c[i] * inner;
            memcpy(out + (o * ctot) * inner + off, in[i] + o * blk, (size_t)blk * sizeof(float));
            off += blk;
        }
    }
}

void sooc_nn_concat_backward(float *const *din, const float *dout, const int64_t *c, int n_in,
                             int64_t outer, int64_t inner) {
    int64_t ctot = 0;
    for (int i = 0; i < n_in; i++) ctot += c[i];
    for (int64_t o = 0; o < outer; o++) {
        int64_t off = 0;
        for (int i = 0; i < n_in; i++) {
            int64_t blk = c[i] * inner;
            if (din[i]) {
                const float *s = dout + (o * ctot) * inner + off;
                float *d = din[i] + o * blk;
                for (int64_t j = 0; j < blk; j++) d[j] += s[j];
            }
            off += blk;
        }
    }
}

void sooc_nn_slice_forward(float *out, const float *in, int64_t outer, int64_t C, int64_t inner,
                           int64_t start, int64_t len) {
    SOOC_ASSERT(start >= 0 && len >= 0 && start + len <= C);
    for (int64_t o = 0; o < outer; o++)
        memcpy(out + o * len * inner, in + (o * C + start) * inner,
               (size_t)(len * inner) * sizeof(float));
}

void sooc_nn_slice_backward(float *din, const float *dout, int64_t outer, int64_t C,
                            int64_t inner, int64_t start, int64_t len) {
    if (!din) return;
    for (int64_t o = 0; o < outer; o++) {
        float *d = din + (o * C + start) * inner;
        const float *s = dout + o * len * inner;
        for (int64_t j = 0; j < len * inner; j++) d[j] += s[j];
    }
}

/* ------------------------------------------ gather / scatter-add */

void sooc_nn_gather_forward(float *out, const float *in, const int32_t *idx, int64_t N,
                            int64_t M, int64_t C) {
    for (int64_t n = 0; n < N; n++) {
        SOOC_ASSERT(idx[n] >= 0 && idx[n] < M);
        memcpy(out + n * C, in + (int64_t)idx[n] * C, (size_t)C * sizeof(float));
    }
}

void sooc_nn_gather_backward(float *din, const float *dout, const int32_t *idx, int64_t N,
                             int64_t M, int64_t C) {
    if (!din) return;
    for (int64_t n = 0; n < N; n++) {
        SOOC_ASSERT(idx[n] >= 0 && idx[n] < M);
        float *d = din + (int64_t)idx[n] * C;
        const float *s = dout + n * C;
        for (int64_t c = 0; c < C; c++) d[c] += s[c];
    }
}

void sooc_nn_scatter_add_forward(float *out, const float *src, const int32_t *idx, int64_t N,
                                 int64_t M, int64_t C) {
    memset(out, 0, (size_t)(M * C) * sizeof(float));
    sooc_nn_gather_backward(out, src, idx, N, M, C);
}

void sooc_nn_scatter_add_backward(float *dsrc, const float *dout, const int32_t *idx, int64_t N,
                                  int64_t M, int64_t C) {
    if (!dsrc) return;
    for (int64_t n = 0; n < N; n++) {
        SOOC_ASSERT(idx[n] >= 0 && idx[n] < M);
        float *d = dsrc + n * C;
        const float *s = dout + (int64_t)idx[n] * C;
        for (int64_t c = 0; c < C; c++) d[c] += s[c];
    }
}

/* ------------------------------------------------------ reductions */

void sooc_nn_sum_forward(float *out, const float *in, int64_t outer, int64_t C, int64_t inner,
                         int mean) {
#pragma omp parallel for schedule(static) if (outer * C * inner > SOOC_NN_PAR_MIN)
    for (int64_t oi = 0; oi < outer * inner; oi++) {
        int64_t o = oi / inner, i = oi % inner;
        double s = 0.0;
        for (int64_t c = 0; c < C; c++) s += in[(o * C + c) * inner + i];
        out[oi] = (float)(mean ? s / (double)C : s);
    }
}

void sooc_nn_sum_backward(float *din, const float *dout, int64_t outer, int64_t C,
                          int64_t inner, int mean) {
    if (!din) return;
    float sc = mean ? 1.f / (float)C : 1.f;
#pragma omp parallel for schedule(static) if (outer * C * inner > SOOC_NN_PAR_MIN)
    for (int64_t oc = 0; oc < outer * C; oc++) {
        int64_t o = oc / C;
        for (int64_t i = 0; i < inner; i++) din[oc * inner + i] += dout[o * inner + i] * sc;
    }
}

/* ------------------------------------------------------ layer norm */

void sooc_nn_layernorm_forward(float *y, float *mean, float *rstd, const float *x,
                               const float *w, const float *b, int64_t N, int64_t C, float eps) {
#pragma omp parallel for schedule(static) if (N * C > SOOC_NN_PAR_MIN)
    for (int64_t n = 0; n < N; n++) {
        const float *xr = x + n * C;
        double s = 0.0, ss = 0.0;
        for (int64_t c = 0; c < C; c++) s += xr[c];
        double m = s / (double)C;
        for (int64_t c = 0; c < C; c++) { double d = xr[c] - m; ss += d * d; }
        float r = (float)(1.0 / sqrt(ss / (double)C + (double)eps));
        float mf = (float)m;
        mean[n] = mf;
        rstd[n] = r;
        float *yr = y + n * C;
        for (int64_t c = 0; c < C; c++) {
            float v = (xr[c] - mf) * r;
            if (w) v *= w[c];
            if (b) v += b[c];
            yr[c] = v;
        }
    }
}

void sooc_nn_layernorm_backward(float *dx, float *dw, float *db, const float *dy,
                                const float *x, const float *mean, const float *rstd,
                                const float *w, int64_t N, int64_t C) {
    /* forward: xh = (x-mean)*rstd; y = xh*w + b.
     * dxh = dy*w; dx = rstd * (dxh - mean(dxh) - xh*mean(dxh*xh)). */
    if (dx) {
#pragma omp parallel for schedule(static) if (N * C > SOOC_NN_PAR_MIN)
        for (int64_t n = 0; n < N; n++) {
            const float *xr = x + n * C, *dyr = dy + n * C;
            float m = mean[n], r = rstd[n];
            double s1 = 0.0, s2 = 0.0;
            for (int64_t c = 0; c < C; c++) {
                float g = w ? dyr[c] * w[c] : dyr[c];
                float xh = (xr[c] - m) * r;
                s1 += g;
                s2 += (double)g * xh;
            }
            float a1 = (float)(s1 / (double)C), a2 = (float)(s2 / (double)C);
            float *dxr = dx + n * C;
            for (int64_t c = 0; c < C; c++) {
                float g = w ? dyr[c] * w[c] : dyr[c];
                float xh = (xr[c] - m) * r;
                dxr[c] += r * (g - a1 - xh * a2);
            }
        }
    }
    if (dw || db) {
        /* parallel over channels: each c owns dw[c], db[c] */
#pragma omp parallel for schedule(static) if (N * C > SOOC_NN_PAR_MIN)
        for (int64_t c = 0; c < C; c++) {
            double sw = 0.0, sb = 0.0;
            for (int64_t n = 0; n < N; n++) {
                float g = dy[n * C + c];
                sw += (double)g * ((x[n * C + c] - mean[n]) * rstd[n]);
                sb += g;
            }
            if (dw) dw[c] += (float)sw;
            if (db) db[c] += (float)sb;
        }
    }
}

/* ------------------------------------------------ positional encoding */

void sooc_nn_posenc_forward(float *y, const float *x, int64_t N, int D, int F) {
    int64_t E = sooc_nn_posenc_dim(D, F);
#pragma omp parallel for schedule(static) if (N * E > SOOC_NN_PAR_MIN)
    for (int64_t n = 0; n < N; n++) {
        const float *xr = x + n * D;
        float *yr = y + n * E;
        for (int d = 0; d < D; d++) yr[d] = xr[d];
        for (int f = 0; f < F; f++) {
            float s = (float)(1 << f);
            float *ys = yr + D * (1 + 2 * f), *yc = ys + D;
            for (int d = 0; d < D; d++) {
                float a = s * xr[d];
                ys[d] = sinf(a);
                yc[d] = cosf(a);
            }
        }
    }
}

void sooc_nn_posenc_backward(float *dx, const float *dy, const float *y, int64_t N, int D,
                             int F) {
    if (!dx) return;
    int64_t E = sooc_nn_posenc_dim(D, F);
    /* d sin(s x)/dx = s cos(s x); d cos(s x)/dx = -s sin(s x) */
#pragma omp parallel for schedule(static) if (N * E > SOOC_NN_PAR_MIN)
    for (int64_t n = 0; n < N; n++) {
        const float *yr = y + n * E, *g = dy + n * E;
        float *dxr = dx + n * D;
        for (int d = 0; d < D; d++) {
            float acc = g[d];
            for (int f = 0; f < F; f++) {
                float s = (float)(1 << f);
                int64_t is = D * (1 + 2 * f) + d, ic = is + D;
                acc += s * (g[is] * yr[ic] - g[ic] * yr[is]);
            }
            dxr[d] += acc;
        }
    }
}
