/*
 * The refinement network's non-convolutional layers (nn_refine.h): MulMON
 * layer norm, linear (w[I][O]), LSTM cell (wx[I][4G], wh[G][4G], one bias),
 * average pool + flatten; float32 kernels and their float64 twins.
 */
#include "rnet_impl.h"

#include <string.h>

static inline float sigm(float x) { return 1.0f / (1.0f + expf(-x)); }
static inline double sigm_d(double x) { return 1.0 / (1.0 + exp(-x)); }

/* ------------------------------------------------------- MulMON layer norm */

/* Sums in double with 8 independent partial sums (a fixed order). */
void sooc_nn_mln_forward(float *y, float *stats, const float *x, int nblk, int64_t len, int64_t ld) {
    double s8[8] = {0}, q8[8] = {0};
    double n = (double)nblk * (double)len;
    for (int c = 0; c < nblk; c++) {
        const float *restrict v = x + (size_t)c * ld;
        int64_t i = 0;
        for (; i + 8 <= len; i += 8)
            for (int u = 0; u < 8; u++) s8[u] += v[i + u];
        for (; i < len; i++) s8[0] += v[i];
    }
    double s = ((s8[0] + s8[4]) + (s8[1] + s8[5])) + ((s8[2] + s8[6]) + (s8[3] + s8[7]));
    float mean = (float)(s / n);
    for (int c = 0; c < nblk; c++) {
        const float *restrict v = x + (size_t)c * ld;
        int64_t i = 0;
        for (; i + 8 <= len; i += 8)
            for (int u = 0; u < 8; u++) {
                double d = v[i + u] - mean;
                q8[u] += d * d;
            }
        for (; i < len; i++) {
            double d = v[i] - mean;
            q8[0] += d * d;
        }
    }
    double s2 = ((q8[0] + q8[4]) + (q8[1] + q8[5])) + ((q8[2] + q8[6]) + (q8[3] + q8[7]));
    float sd = (float)sqrt(s2 / n), inv = 1.0f / (sd + SOOC_NN_MLN_EPS);
    for (int c = 0; c < nblk; c++) {
        const float *v = x + (size_t)c * ld;
        float *o = y + (size_t)c * ld;
        for (int64_t i = 0; i < len; i++) o[i] = (v[i] - mean) * inv;
    }
    if (stats) stats[0] = mean, stats[1] = sd, stats[2] = inv;
}

/* y = xc inv, inv = 1 / (sd + eps), sd = sqrt(mean xc^2):
 * dx = inv (dy - mean(dy)) - inv (sum dy y) / n * xc / sd, xc / sd = y (sd + eps) / sd. */
void sooc_nn_mln_backward(float *dx, const float *dy, const float *y, const float *stats, int nblk, int64_t len,
                          int64_t ld) {
    double sg = 0, sgy = 0, n = (double)nblk * (double)len;
    for (int c = 0; c < nblk; c++)
        for (int64_t i = 0; i < len; i++) {
            size_t k = (size_t)c * ld + i;
            sg += dy[k];
            sgy += (double)dy[k] * y[k];
        }
    double inv = stats[2], sd = stats[1], r = sd > 0 ? (sd + SOOC_NN_MLN_EPS) / sd : 0.0;
    double mg = sg / n, a = sgy / n * r;
    for (int c = 0; c < nblk; c++)
        for (int64_t i = 0; i < len; i++) {
            size_t k = (size_t)c * ld + i;
            dx[k] += (float)(inv * (dy[k] - mg - a * y[k]));
        }
}

void sooc_nn_mln_forward_f64(double *y, double *stats, const double *x, int nblk, int64_t len, int64_t ld) {
    double s = 0, s2 = 0, n = (double)nblk * (double)len;
    for (int c = 0; c < nblk; c++)
        for (int64_t i = 0; i < len; i++) s += x[(size_t)c * ld + i];
    double mean = s / n;
    for (int c = 0; c < nblk; c++)
        for (int64_t i = 0; i < len; i++) {
            double d = x[(size_t)c * ld + i] - mean;
            s2 += d * d;
        }
    double sd = sqrt(s2 / n), inv = 1.0 / (sd + SOOC_NN_MLN_EPS);
    for (int c = 0; c < nblk; c++)
        for (int64_t i = 0; i < len; i++) y[(size_t)c * ld + i] = (x[(size_t)c * ld + i] - mean) * inv;
    if (stats) stats[0] = mean, stats[1] = sd, stats[2] = inv;
}

void sooc_nn_mln_backward_f64(double *dx, const double *dy, const double *y, const double *stats, int nblk,
                              int64_t len, int64_t ld) {
    double sg = 0, sgy = 0, n = (double)nblk * (double)len;
    for (int c = 0; c < nblk; c++)
        for (int64_t i = 0; i < len; i++) {
            size_t k = (size_t)c * ld + i;
            sg += dy[k];
            sgy += dy[k] * y[k];
        }
    double inv = stats[2], sd = stats[1], r = sd > 0 ? (sd + SOOC_NN_MLN_EPS) / sd : 0.0;
    double mg = sg / n, a = sgy / n * r;
    for (int c = 0; c < nblk; c++)
        for (int64_t i = 0; i < len; i++) {
            size_t k = (size_t)c * ld + i;
            dx[k] += inv * (dy[k] - mg - a * y[k]);
        }
}

/* ----------------------------------------------------------------- linear */

static void act_bias_rows(float *y, const float *b, int M, int N, sooc_nn_act act) {
    SOOC_ASSERT(act == SOOC_NN_ACT_NONE || act == SOOC_NN_ACT_ELU);
    for (int i = 0; i < M; i++) {
        float *r = y + (size_t)i * N;
        if (act == SOOC_NN_ACT_ELU)
            for (int j = 0; j < N; j++) r[j] = sooc_nn_r_elu1(b ? r[j] + b[j] : r[j]);
        else if (b)
            for (int j = 0; j < N; j++) r[j] += b[j];
    }
}

void sooc_nn_rlinear_forward(float *y, const float *x, int ldx, const float *w, const float *b, int M, int K, int N,
                             sooc_nn_act act) {
    sooc_nn_gemm(M, N, K, x, ldx, w, N, y, N, NULL, 0, SOOC_NN_EP_NONE, NULL, 0);
    act_bias_rows(y, b, M, N, act);
}

void sooc_nn_rlinear_backward(float *dx, float *dw, float *db, float *dy, const float *x, int ldx, const float *y,
                              const float *w, int M, int K, int N, sooc_nn_act act) {
    if (act == SOOC_NN_ACT_ELU)
        for (size_t i = 0; i < (size_t)M * N; i++) dy[i] *= y[i] > 0 ? 1.0f : y[i] + 1.0f;
    if (dw) sooc_nn_gemm_tn(K, N, M, 1.0f, x, ldx, dy, N, dw, N);
    if (db)
        for (int i = 0; i < M; i++)
            for (int j = 0; j < N; j++) db[j] += dy[(size_t)i * N + j];
    if (dx) sooc_nn_gemm_nt(M, K, N, dy, N, w, N, dx, ldx, 1, SOOC_NN_EP_NONE, NULL, 0);
}

void sooc_nn_rlinear_forward_f64(double *y, const double *x, int ldx, const double *w, const double *b, int M, int K,
                                 int N, sooc_nn_act act) {
    for (int i = 0; i < M; i++)
        for (int j = 0; j < N; j++) {
            double s = b ? b[j] : 0.0;
            for (int k = 0; k < K; k++) s += x[(size_t)i * ldx + k] * w[(size_t)k * N + j];
            y[(size_t)i * N + j] = act == SOOC_NN_ACT_ELU && s <= 0 ? expm1(s) : s;
        }
}

void sooc_nn_rlinear_backward_f64(double *dx, double *dw, double *db, double *dy, const double *x, int ldx,
                                  const double *y, const double *w, int M, int K, int N, sooc_nn_act act) {
    for (int i = 0; i < M; i++)
        for (int j = 0; j < N; j++) {
            size_t o = (size_t)i * N + j;
            if (act == SOOC_NN_ACT_ELU && y[o] <= 0) dy[o] *= y[o] + 1.0;
            if (db) db[j] += dy[o];
            for (int k = 0; k < K; k++) {
                if (dw) dw[(size_t)k * N + j] += x[(size_t)i * ldx + k] * dy[o];
                if (dx) dx[(size_t)i * ldx + k] += dy[o] * w[(size_t)k * N + j];
            }
        }
}

/* ------------------------------------------------------------- LSTM cell */

void sooc_nn_rlstm_forward(float *h1, float *c1, float *gates, const float *x, const float *h0, const float *c0,
                           const float *wx, const float *wh, const float *b, int B, int I, int G) {
    int G4 = 4 * G;
    sooc_nn_gemm(B, G4, I, x, I, wx, G4, gates, G4, NULL, 0, SOOC_NN_EP_NONE, NULL, 0);
    if (h0) sooc_nn_gemm(B, G4, G, h0, G, wh, G4, gates, G4, NULL, 1, SOOC_NN_EP_NONE, NULL, 0);
    for (int bb = 0; bb < B; bb++) {
        float *g = gates + (size_t)bb * G4;
        for (int j = 0; j < G; j++) {
            float bi = b ? b[j] : 0, bf = b ? b[G + j] : 0, bg = b ? b[2 * G + j] : 0, bo = b ? b[3 * G + j] : 0;
            float gi = sigm(g[j] + bi), gf = sigm(g[G + j] + bf);
            float gg = tanhf(g[2 * G + j] + bg), go = sigm(g[3 * G + j] + bo);
            g[j] = gi, g[G + j] = gf, g[2 * G + j] = gg, g[3 * G + j] = go;
            size_t i = (size_t)bb * G + j;
            float cc = gf * (c0 ? c0[i] : 0.0f) + gi * gg;
            c1[i] = cc;
            h1[i] = go * tanhf(cc);
        }
    }
}

void sooc_nn_rlstm_backward(float *dx, float *dh0, float *dc0, float *dwx, float *dwh, float *db, const float *dh1,
                            const float *dc1, float *scratch, const float *gates, const float *c1, const float *x,
                            const float *h0, const float *c0, const float *wx, const float *wh, int B, int I, int G) {
    int G4 = 4 * G;
    float *dz = scratch;
    for (int bb = 0; bb < B; bb++) {
        const float *gt = gates + (size_t)bb * G4;
        float *q = dz + (size_t)bb * G4;
        for (int j = 0; j < G; j++) {
            size_t i = (size_t)bb * G + j;
            float gh = dh1 ? dh1[i] : 0.0f;
            float gi = gt[j], gf = gt[G + j], ggt = gt[2 * G + j], go = gt[3 * G + j];
            float tc = tanhf(c1[i]);
            float gc = gh * go * (1 - tc * tc) + (dc1 ? dc1[i] : 0.0f);
            q[j] = gc * ggt * gi * (1 - gi);
            q[G + j] = gc * (c0 ? c0[i] : 0.0f) * gf * (1 - gf);
            q[2 * G + j] = gc * gi * (1 - ggt * ggt);
            q[3 * G + j] = gh * tc * go * (1 - go);
            if (dc0) dc0[i] += gc * gf;
        }
    }
    if (dwx) sooc_nn_gemm_tn(I, G4, B, 1.0f, x, I, dz, G4, dwx, G4);
    if (dwh && h0) sooc_nn_gemm_tn(G, G4, B, 1.0f, h0, G, dz, G4, dwh, G4);
    if (db)
        for (int bb = 0; bb < B; bb++)
            for (int j = 0; j < G4; j++) db[j] += dz[(size_t)bb * G4 + j];
    if (dh0) sooc_nn_gemm_nt(B, G, G4, dz, G4, wh, G4, dh0, G, 1, SOOC_NN_EP_NONE, NULL, 0);
    if (dx) sooc_nn_gemm_nt(B, I, G4, dz, G4, wx, G4, dx, I, 1, SOOC_NN_EP_NONE, NULL, 0);
}

void sooc_nn_rlstm_forward_f64(double *h1, double *c1, double *gates, const double *x, const double *h0,
                               const double *c0, const double *wx, const double *wh, const double *b, int B, int I,
                               int G) {
    int G4 = 4 * G;
    for (int bb = 0; bb < B; bb++) {
        double *g = gates + (size_t)bb * G4;
        for (int j = 0; j < G4; j++) {
            double s = b ? b[j] : 0.0;
            for (int k = 0; k < I; k++) s += x[(size_t)bb * I + k] * wx[(size_t)k * G4 + j];
            if (h0)
                for (int k = 0; k < G; k++) s += h0[(size_t)bb * G + k] * wh[(size_t)k * G4 + j];
            g[j] = j >= 2 * G && j < 3 * G ? tanh(s) : sigm_d(s);
        }
        for (int j = 0; j < G; j++) {
            size_t i = (size_t)bb * G + j;
            c1[i] = g[G + j] * (c0 ? c0[i] : 0.0) + g[j] * g[2 * G + j];
            h1[i] = g[3 * G + j] * tanh(c1[i]);
        }
    }
}

void sooc_nn_rlstm_backward_f64(double *dx, double *dh0, double *dc0, double *dwx, double *dwh, double *db,
                                const double *dh1, const double *dc1, const double *gates, const double *c1,
                                const double *x, const double *h0, const double *c0, const double *wx,
                                const double *wh, int B, int I, int G) {
    int G4 = 4 * G;
    double q[4];
    for (int bb = 0; bb < B; bb++) {
        const double *gt = gates + (size_t)bb * G4;
        for (int j = 0; j < G; j++) {
            size_t i = (size_t)bb * G + j;
            double gh = dh1 ? dh1[i] : 0.0, gi = gt[j], gf = gt[G + j], gg = gt[2 * G + j], go = gt[3 * G + j];
            double tc = tanh(c1[i]), gc = gh * go * (1 - tc * tc) + (dc1 ? dc1[i] : 0.0);
            q[0] = gc * gg * gi * (1 - gi);
            q[1] = gc * (c0 ? c0[i] : 0.0) * gf * (1 - gf);
            q[2] = gc * gi * (1 - gg * gg);
            q[3] = gh * tc * go * (1 - go);
            if (dc0) dc0[i] += gc * gf;
            for (int a = 0; a < 4; a++) {
                int col = a * G + j;
                if (db) db[col] += q[a];
                for (int k = 0; k < I; k++) {
                    if (dwx) dwx[(size_t)k * G4 + col] += x[(size_t)bb * I + k] * q[a];
                    if (dx) dx[(size_t)bb * I + k] += q[a] * wx[(size_t)k * G4 + col];
                }
                for (int k = 0; h0 && k < G; k++) {
                    if (dwh) dwh[(size_t)k * G4 + col] += h0[(size_t)bb * G + k] * q[a];
                    if (dh0) dh0[(size_t)bb * G + k] += q[a] * wh[(size_t)k * G4 + col];
                }
            }
        }
    }
}

/* -------------------------------------------------------- pool + flatten */

typedef struct pool_geom {
    int ph, pw, sh, sw;
} pool_geom;

static pool_geom pool_of(int fh, int fw) {
    pool_geom g;
    g.ph = fh > 2 ? 2 : fh, g.pw = fw > 2 ? 2 : fw;
    g.sh = fh / g.ph, g.sw = fw / g.pw;
    return g;
}

void sooc_nn_pool2_forward(float *flat, const float *x, int C, int B, int fh, int fw) {
    pool_geom g = pool_of(fh, fw);
    float inv = 1.0f / (float)(g.sh * g.sw);
    int nflat = C * g.ph * g.pw;
    for (int b = 0; b < B; b++)
        for (int c = 0; c < C; c++) {
            const float *src = x + ((size_t)c * B + b) * fh * fw;
            float *dst = flat + (size_t)b * nflat + (size_t)c * g.ph * g.pw;
            for (int i = 0; i < g.ph; i++)
                for (int j = 0; j < g.pw; j++) {
                    float acc = 0;
                    for (int u = 0; u < g.sh; u++)
                        for (int v = 0; v < g.sw; v++) acc += src[(i * g.sh + u) * fw + j * g.sw + v];
                    dst[i * g.pw + j] = acc * inv;
                }
        }
}

void sooc_nn_pool2_backward(float *dx, const float *dflat, int C, int B, int fh, int fw) {
    pool_geom g = pool_of(fh, fw);
    float inv = 1.0f / (float)(g.sh * g.sw);
    int nflat = C * g.ph * g.pw;
    for (int b = 0; b < B; b++)
        for (int c = 0; c < C; c++) {
            float *dst = dx + ((size_t)c * B + b) * fh * fw;
            const float *src = dflat + (size_t)b * nflat + (size_t)c * g.ph * g.pw;
            for (int y = 0; y < fh; y++)
                for (int x = 0; x < fw; x++) dst[y * fw + x] += src[(y / g.sh) * g.pw + x / g.sw] * inv;
        }
}

void sooc_nn_pool2_forward_f64(double *flat, const double *x, int C, int B, int fh, int fw) {
    pool_geom g = pool_of(fh, fw);
    int nflat = C * g.ph * g.pw;
    for (int b = 0; b < B; b++)
        for (int c = 0; c < C; c++)
            for (int i = 0; i < g.ph; i++)
                for (int j = 0; j < g.pw; j++) {
                    double acc = 0;
                    for (int u = 0; u < g.sh; u++)
                        for (int v = 0; v < g.sw; v++)
                            acc += x[((size_t)c * B + b) * fh * fw + (size_t)(i * g.sh + u) * fw + j * g.sw + v];
                    flat[(size_t)b * nflat + (size_t)c * g.ph * g.pw + i * g.pw + j] = acc / (g.sh * g.sw);
                }
}

void sooc_nn_pool2_backward_f64(double *dx, const double *dflat, int C, int B, int fh, int fw) {
    pool_geom g = pool_of(fh, fw);
    int nflat = C * g.ph * g.pw;
    for (int b = 0; b < B; b++)
        for (int c = 0; c < C; c++)
            for (int y = 0; y < fh; y++)
                for (int x = 0; x < fw; x++)
                    dx[((size_t)c * B + b) * fh * fw + (size_t)y * fw + x] +=
                        dflat[(size_t)b * nflat + (size_t)c * g.ph * g.pw + (y / g.sh) * g.pw + x / g.sw] /
                        (g.sh * g.sw);
}
