/*
 * Fused chunked MLP (the NeRF decoder hot path).
 *
 * Points are processed in chunks of SOOC_NN_MLP_CHUNK rows that never straddle
 * a slot, so each chunk's working set (~230 KB for the decoder) stays in L2.
 * Forward: chunks in parallel; each chunk owns its output rows.
 * Backward: chunks are grouped into SOOC_NN_MLP_LANES fixed lanes (contiguous
 * runs of chunks); a lane owns private dW/db/dslot accumulators and runs its
 * chunks in order; lanes run in parallel; the lanes are then reduced in lane
 * order. The lane count does not depend on the thread count, so the result
 * is bitwise identical for any number of threads and with OpenMP off.
 * Every sgemm runs on one OpenBLAS thread (sooc_nn_blas_single).
 */
#include "nn_impl.h"
#include <math.h>
#include <string.h>

#define CH SOOC_NN_MLP_CHUNK
#define SMALL_OUT 4 /* layers with <= 4 outputs use plain loops instead of sgemm */

static inline size_t up16(size_t n) { return (n + 15) & ~(size_t)15; }

static int64_t sum_out(const sooc_nn_mlp *m) {
    int64_t s = 0;
    for (int l = 0; l < m->n_layers; l++) s += m->layer[l].c_out;
    return s;
}

size_t sooc_nn_mlp_act_floats(const sooc_nn_mlp *m, int64_t N) { return (size_t)(N * sum_out(m)); }

float *sooc_nn_mlp_output(const sooc_nn_mlp *m, float *acts, int64_t N, int l) {
    int64_t off = 0;
    for (int i = 0; i < l; i++) off += N * m->layer[i].c_out;
    return acts + off;
}

static size_t lane_floats(const sooc_nn_mlp *m, int K) {
    size_t s = up16((size_t)CH * (size_t)sum_out(m));
    for (int l = 0; l < m->n_layers; l++)
        s += up16((size_t)m->layer[l].c_out * m->layer[l].c_in) + up16((size_t)m->layer[l].c_out);
    s += up16((size_t)K * m->layer[0].c_out);
    return s;
}

size_t sooc_nn_mlp_scratch_floats(const sooc_nn_mlp *m, int K) {
    return (size_t)SOOC_NN_MLP_LANES * lane_floats(m, K < 1 ? 1 : K);
}

static sooc_status check_mlp(const sooc_nn_mlp *m) {
    if (m->n_layers < 1 || m->n_layers > SOOC_NN_MLP_MAX_LAYERS)
        return sooc_seterr(SOOC_EINVAL, "nn mlp: n_layers %d out of range", m->n_layers);
    for (int l = 0; l < m->n_layers; l++) {
        const sooc_nn_mlp_layer *L = &m->layer[l];
        int cin = L->src < 0 ? m->c_in : m->layer[L->src].c_out;
        if (L->src >= l || L->c_in != cin || L->c_out < 1 || !L->w)
            return sooc_seterr(SOOC_EINVAL, "nn mlp: layer %d: bad src/c_in/c_out/w", l);
        if (L->act != SOOC_NN_ACT_NONE && L->act != SOOC_NN_ACT_RELU && L->act != SOOC_NN_ACT_ELU &&
            L->act != SOOC_NN_ACT_SIGMOID && L->act != SOOC_NN_ACT_TANH)
            return sooc_seterr(SOOC_EINVAL, "nn mlp: layer %d: unsupported activation", l);
    }
    return SOOC_OK;
}

/* chunk c -> [r0, r1) rows; chunks never straddle slots */
typedef struct chunking { int64_t N, pps, per_slot, n_chunks; } chunking;

static chunking make_chunks(int64_t N, int64_t pps) {
    chunking c;
    c.N = N;
    c.pps = pps > 0 ? pps : (N > 0 ? N : 1);
    c.per_slot = (c.pps + CH - 1) / CH;
    int64_t K = (N + c.pps - 1) / c.pps;
    c.n_chunks = K * c.per_slot;
    return c;
}

static void chunk_rows(const chunking *c, int64_t ci, int64_t *r0, int64_t *r1, int64_t *slot) {
    int64_t k = ci / c->per_slot, j = ci % c->per_slot;
    *slot = k;
    *r0 = k * c->pps + j * CH;
    int64_t e = k * c->pps + (j + 1) * CH, se = (k + 1) * c->pps;
    if (e > se) e = se;
    if (e > c->N) e = c->N;
    *r1 = e;
}

static void layer_forward_rows(const sooc_nn_mlp_layer *L, float *y, const float *x, int64_t R,
                               const float *sbias) {
    int I = L->c_in, O = L->c_out;
    if (O <= SMALL_OUT) {
        for (int64_t r = 0; r < R; r++) {
            const float *xr = x + r * I;
            for (int o = 0; o < O; o++) {
                const float *wr = L->w + (int64_t)o * I;
                float s = 0.f;
                for (int i = 0; i < I; i++) s += xr[i] * wr[i];
                float v = s + (L->b ? L->b[o] : 0.f) + (sbias ? sbias[o] : 0.f);
                y[r * O + o] = sooc_nn_act_apply(L->act, v);
            }
        }
        return;
    }
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, (int)R, O, I, 1.f, x, I, L->w, I, 0.f, y,
                O);
    float bias[1024];
    const float *bp = NULL;
    if (L->b || sbias) {
        SOOC_ASSERT(O <= 1024);
        for (int o = 0; o < O; o++) bias[o] = (L->b ? L->b[o] : 0.f) + (sbias ? sbias[o] : 0.f);
        bp = bias;
    }
    switch (L->act) {
    case SOOC_NN_ACT_RELU:
        for (int64_t r = 0; r < R; r++) {
            float *yr = y + r * O;
            if (bp)
                for (int o = 0; o < O; o++) { float v = yr[o] + bp[o]; yr[o] = v > 0.f ? v : 0.f; }
            else
                for (int o = 0; o < O; o++) yr[o] = yr[o] > 0.f ? yr[o] : 0.f;
        }
        break;
    default:
        for (int64_t r = 0; r < R; r++) {
            float *yr = y + r * O;
            for (int o = 0; o < O; o++) yr[o] = sooc_nn_act_apply(L->act, bp ? yr[o] + bp[o] : yr[o]);
        }
    }
}

sooc_status sooc_nn_mlp_forward(const sooc_nn_mlp *m, float *acts, const float *x, int64_t N,
                                const float *slot_bias, int64_t pts_per_slot) {
    sooc_status s = check_mlp(m);
    if (s) return s;
    if (slot_bias && (pts_per_slot < 1 || N % pts_per_slot))
        return sooc_seterr(SOOC_EINVAL, "nn mlp: N=%lld not a multiple of pts_per_slot=%lld",
                           (long long)N, (long long)pts_per_slot);
    chunking c = make_chunks(N, slot_bias ? pts_per_slot : 0);
    float *out[SOOC_NN_MLP_MAX_LAYERS];
    for (int l = 0; l < m->n_layers; l++) out[l] = sooc_nn_mlp_output(m, acts, N, l);
    sooc_nn_blas_single();
#pragma omp parallel for schedule(dynamic, 1)
    for (int64_t ci = 0; ci < c.n_chunks; ci++) {
        int64_t r0, r1, k;
        chunk_rows(&c, ci, &r0, &r1, &k);
        if (r1 <= r0) continue;
        for (int l = 0; l < m->n_layers; l++) {
            const sooc_nn_mlp_layer *L = &m->layer[l];
            const float *xin = L->src < 0 ? x + r0 * m->c_in : out[L->src] + r0 * L->c_in;
            const float *sb = (l == 0 && slot_bias) ? slot_bias + k * L->c_out : NULL;
            layer_forward_rows(L, out[l] + r0 * L->c_out, xin, r1 - r0, sb);
        }
    }
    return SOOC_OK;
}

/* dz = dact * act'(y) in place */
static void act_grad_rows(sooc_nn_act a, float *d, const float *y, int64_t n) {
    switch (a) {
    case SOOC_NN_ACT_NONE: return;
    case SOOC_NN_ACT_RELU:
        for (int64_t i = 0; i < n; i++) d[i] = y[i] > 0.f ? d[i] : 0.f;
        return;
    case SOOC_NN_ACT_ELU:
        for (int64_t i = 0; i < n; i++) d[i] *= y[i] > 0.f ? 1.f : y[i] + 1.f;
        return;
    case SOOC_NN_ACT_SIGMOID:
        for (int64_t i = 0; i < n; i++) d[i] *= y[i] * (1.f - y[i]);
        return;
    case SOOC_NN_ACT_TANH:
        for (int64_t i = 0; i < n; i++) d[i] *= 1.f - y[i] * y[i];
        return;
    default: return;
    }
}

sooc_status sooc_nn_mlp_backward(const sooc_nn_mlp *m, float *dx, float *dslot_bias,
                                 const float *const *dout, const float *acts, const float *x,
                                 int64_t N, const float *slot_bias, int64_t pts_per_slot,
                                 float *scratch) {
    sooc_status s = check_mlp(m);
    if (s) return s;
    int has_slots = slot_bias != NULL || dslot_bias != NULL;
    if (has_slots && (pts_per_slot < 1 || N % pts_per_slot))
        return sooc_seterr(SOOC_EINVAL, "nn mlp: N=%lld not a multiple of pts_per_slot=%lld",
                           (long long)N, (long long)pts_per_slot);
    int K = has_slots ? (int)(N / pts_per_slot) : 1;
    chunking c = make_chunks(N, has_slots ? pts_per_slot : 0);
    int nl = m->n_layers;
    const float *out[SOOC_NN_MLP_MAX_LAYERS];
    size_t dact_off[SOOC_NN_MLP_MAX_LAYERS], dw_off[SOOC_NN_MLP_MAX_LAYERS],
        db_off[SOOC_NN_MLP_MAX_LAYERS], ds_off;
    {
        size_t o = 0;
        for (int l = 0; l < nl; l++) {
            out[l] = sooc_nn_mlp_output(m, (float *)acts, N, l);
            dact_off[l] = o;
            o += (size_t)CH * m->layer[l].c_out;
        }
        o = up16(o);
        for (int l = 0; l < nl; l++) {
            dw_off[l] = o;
            o += up16((size_t)m->layer[l].c_out * m->layer[l].c_in);
            db_off[l] = o;
            o += up16((size_t)m->layer[l].c_out);
        }
        ds_off = o;
    }
    size_t lf = lane_floats(m, K);
    size_t acc0 = dw_off[0]; /* accumulators start here in each lane */
    sooc_nn_blas_single();
#pragma omp parallel for schedule(dynamic, 1) /* any thread may take any lane: same result */
    for (int lane = 0; lane < SOOC_NN_MLP_LANES; lane++) {
        float *S = scratch + (size_t)lane * lf;
        memset(S + acc0, 0, (lf - acc0) * sizeof(float));
        int64_t c0 = c.n_chunks * lane / SOOC_NN_MLP_LANES,
                c1 = c.n_chunks * (lane + 1) / SOOC_NN_MLP_LANES;
        for (int64_t ci = c0; ci < c1; ci++) {
            int64_t r0, r1, k;
            chunk_rows(&c, ci, &r0, &r1, &k);
            int64_t R = r1 - r0;
            if (R <= 0) continue;
            for (int l = 0; l < nl; l++) {
                float *d = S + dact_off[l];
                size_t n = (size_t)R * m->layer[l].c_out;
                if (dout && dout[l]) memcpy(d, dout[l] + r0 * m->layer[l].c_out, n * sizeof(float));
                else memset(d, 0, n * sizeof(float));
            }
            for (int l = nl - 1; l >= 0; l--) {
                const sooc_nn_mlp_layer *L = &m->layer[l];
                int I = L->c_in, O = L->c_out;
                float *dz = S + dact_off[l];
                act_grad_rows(L->act, dz, out[l] + r0 * O, R * O);
                const float *xin = L->src < 0 ? x + r0 * I : out[L->src] + r0 * I;
                float *dW = S + dw_off[l], *dB = S + db_off[l];
                float *dsrc = L->src >= 0 ? S + dact_off[L->src] : (dx ? dx + r0 * I : NULL);
                if (O <= SMALL_OUT) {
                    for (int64_t r = 0; r < R; r++) {
                        const float *xr = xin + r * I;
                        for (int o = 0; o < O; o++) {
                            float g = dz[r * O + o];
                            float *dwr = dW + (int64_t)o * I;
                            for (int i = 0; i < I; i++) dwr[i] += g * xr[i];
                            if (dsrc) {
                                const float *wr = L->w + (int64_t)o * I;
                                float *dr = dsrc + r * I;
                                for (int i = 0; i < I; i++) dr[i] += g * wr[i];
                            }
                        }
                    }
                } else {
                    if (L->dw)
                        cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, O, I, (int)R, 1.f, dz,
                                    O, xin, I, 1.f, dW, I);
                    if (dsrc)
                        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, (int)R, I, O, 1.f,
                                    dz, O, L->w, I, 1.f, dsrc, I);
                }
                for (int64_t r = 0; r < R; r++)
                    for (int o = 0; o < O; o++) dB[o] += dz[r * O + o];
                if (l == 0 && dslot_bias) {
                    float *ds = S + ds_off + k * O;
                    for (int64_t r = 0; r < R; r++)
                        for (int o = 0; o < O; o++) ds[o] += dz[r * O + o];
                }
            }
        }
    }
    /* reduce lanes in lane order; each output element owned by one iteration */
    for (int l = 0; l < nl; l++) {
        const sooc_nn_mlp_layer *L = &m->layer[l];
        int64_t nw = (int64_t)L->c_out * L->c_in;
        if (L->dw) {
#pragma omp parallel for schedule(static) if (nw > 4096)
            for (int64_t i = 0; i < nw; i++) {
                float a = 0.f;
                for (int lane = 0; lane < SOOC_NN_MLP_LANES; lane++)
                    a += scratch[(size_t)lane * lf + dw_off[l] + i];
                L->dw[i] += a;
            }
        }
        if (L->db)
            for (int o = 0; o < L->c_out; o++) {
                float a = 0.f;
                for (int lane = 0; lane < SOOC_NN_MLP_LANES; lane++)
                    a += scratch[(size_t)lane * lf + db_off[l] + o];
                L->db[o] += a;
            }
    }
    if (dslot_bias) {
        int64_t n = (int64_t)K * m->layer[0].c_out;
        for (int64_t i = 0; i < n; i++) {
            float a = 0.f;
            for (int lane = 0; lane < SOOC_NN_MLP_LANES; lane++)
                a += scratch[(size_t)lane * lf + ds_off + i];
            dslot_bias[i] += a;
        }
    }
    return SOOC_OK;
}
