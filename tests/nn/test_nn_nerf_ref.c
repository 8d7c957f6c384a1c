/*
 * PyTorch reference of the decoder MLP as the model runs it (llm.c style).
 * Runs tests/ref/nerf_ref.py with /usr/bin/python3 (Debian python3-torch) to
 * write the reference into the build directory, then runs the same decoder on
 * the engine's pairs (nn/nn_kern.h) the way src/model/decoder.c does:
 * the slot bias b1 + z W1z as the layer-1 init, sooc_nn_dense_forward (ReLU),
 * sooc_nn_nerf_tail_forward; backward through sooc_nn_nerf_tail_backward (with
 * the transposed weights of the AVX2 path and without), sooc_nn_dense_backward
 * for W1x and d/dpe, and the slot-bias sums for b1, W1z and d/dz. Compares
 * outputs (|c - t| <= 1e-6 + 1e-5 |t|) and every gradient (1e-5 + 1e-4 |t|,
 * float32 with different summation orders). Skips (77) only when python3 or
 * torch is missing.
 */
#include "check.h"
#include "nn/nn_kern.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAXREC 64
typedef struct rec {
    char name[32];
    int n;
    float *v;
} rec;
static rec g_rec[MAXREC];
static int g_nrec;

static sooc_status load_ref(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) return sooc_seterr(SOOC_EIO, "%s: cannot open", path);
    char name[32];
    int n;
    while (g_nrec < MAXREC && fscanf(f, "%31s %d", name, &n) == 2) {
        if (n < 0 || n > (1 << 20)) break;
        rec *r = &g_rec[g_nrec++];
        snprintf(r->name, sizeof r->name, "%s", name);
        r->n = n;
        r->v = sooc_malloc((size_t)(n ? n : 1) * sizeof(float));
        for (int i = 0; i < n; i++)
            if (fscanf(f, "%f", &r->v[i]) != 1) {
                fclose(f);
                return sooc_seterr(SOOC_EFORMAT, "%s: record %s truncated", path, name);
            }
    }
    fclose(f);
    return g_nrec ? SOOC_OK : sooc_seterr(SOOC_EFORMAT, "%s: no records", path);
}

static rec *get(const char *name) {
    for (int i = 0; i < g_nrec; i++)
        if (!strcmp(g_rec[i].name, name)) return &g_rec[i];
    fprintf(stderr, "reference record '%s' missing\n", name);
    exit(1);
}

static void cmp(const char *what, const float *c, const char *name, double atol, double rtol) {
    rec *r = get(name);
    double worst = 0;
    int wi = 0;
    for (int i = 0; i < r->n; i++) {
        double d = fabs((double)c[i] - r->v[i]) / (atol + rtol * fabs((double)r->v[i]));
        if (!(d <= worst)) worst = d, wi = i;
    }
    printf("  %-8s %-10s n=%-5d worst err/tol %.3f (#%d: %.7g, torch %.7g)\n", what, name, r->n, worst, wi, c[wi],
           r->v[wi]);
    CHECK_MSG(worst <= 1.0, "%s %s: #%d %.7g vs torch %.7g", what, name, wi, c[wi], r->v[wi]);
}

static const char *WN[] = {"W1x", "W1z", "b1", "W2", "b2", "W3", "b3", "Wd", "bd", "Wc1", "bc1", "Wc2", "bc2"};
enum { NW = 13 };

static void run(int transposed) {
    const float *dims = get("dims")->v;
    int R = (int)dims[0], S = (int)dims[1], DIN = (int)dims[2], DZ = (int)dims[3], H = (int)dims[4], HC = (int)dims[5];
    const float *w[NW];
    float *g[NW];
    for (int i = 0; i < NW; i++) {
        char nm[32];
        snprintf(nm, sizeof nm, "in.%s", WN[i]);
        rec *r = get(nm);
        w[i] = r->v;
        g[i] = sooc_calloc((size_t)r->n, sizeof(float));
    }
    const float *pe = get("in.pe")->v, *z = get("in.z")->v, *slotf = get("in.slot")->v;
    size_t RH = (size_t)R * H;
    float *sb = sooc_malloc(sizeof(float) * (size_t)S * H), *a1 = sooc_malloc(sizeof(float) * RH),
          *a2 = sooc_malloc(sizeof(float) * RH), *a3 = sooc_malloc(sizeof(float) * RH),
          *ac = sooc_malloc(sizeof(float) * (size_t)R * HC), *sig = sooc_malloc(sizeof(float) * R),
          *col = sooc_malloc(sizeof(float) * R * 3), *gs = sooc_malloc(sizeof(float) * R),
          *gc = sooc_malloc(sizeof(float) * R * 3), *gA = sooc_malloc(sizeof(float) * RH),
          *gB = sooc_malloc(sizeof(float) * RH), *gpe = sooc_malloc(sizeof(float) * (size_t)R * DIN),
          *gz = sooc_calloc((size_t)S * DZ, sizeof(float)), *gsb = sooc_calloc((size_t)S * H, sizeof(float)),
          *wt = sooc_malloc(sizeof(float) * (size_t)H * (2 * H + HC + DIN));
    /* slot bias b1 + z W1z (decoder.c step 1) and the layer-1 init */
    for (int k = 0; k < S; k++)
        for (int j = 0; j < H; j++) {
            float v = w[2][j];
            for (int i = 0; i < DZ; i++) v += z[k * DZ + i] * w[1][i * H + j];
            sb[k * H + j] = v;
        }
    for (int r = 0; r < R; r++) memcpy(a1 + (size_t)r * H, sb + (size_t)((int)slotf[r]) * H, sizeof(float) * H);
    sooc_nn_dense_forward(R, DIN, H, pe, DIN, w[0], NULL, a1, H, 1, SOOC_NN_EP_RELU);
    /* transposed weights (decoder.c wt_build) */
    float *W2t = wt, *W3t = W2t + H * H, *Wc1t = W3t + H * H, *W1xt = Wc1t + H * HC;
    for (int i = 0; i < H; i++)
        for (int j = 0; j < H; j++) W2t[j * H + i] = w[3][i * H + j], W3t[j * H + i] = w[5][i * H + j];
    for (int i = 0; i < H; i++)
        for (int j = 0; j < HC; j++) Wc1t[j * H + i] = w[9][i * HC + j];
    for (int i = 0; i < DIN; i++)
        for (int j = 0; j < H; j++) W1xt[j * DIN + i] = w[0][i * H + j];
    sooc_nn_nerf_tail t = {H, HC, w[3], w[4], w[5], w[6], w[7], w[8], w[9], w[10], w[11], w[12],
                           transposed ? W2t : NULL, transposed ? W3t : NULL, transposed ? Wc1t : NULL};
    sooc_nn_nerf_tail_forward(&t, R, a1, a2, a3, ac, sig, col, 0);
    const char *tag = transposed ? "Wt" : "W";
    cmp(tag, a3, "out.a3", 1e-6, 1e-5);
    cmp(tag, sig, "out.sig", 1e-6, 1e-5);
    cmp(tag, col, "out.col", 1e-6, 1e-5);
    double loss = 0;
    const float *ts = get("in.t_sig")->v, *tc = get("in.t_col")->v;
    for (int r = 0; r < R; r++) {
        loss += (double)sig[r] * ts[r];
        for (int a = 0; a < 3; a++) loss += (double)col[r * 3 + a] * tc[r * 3 + a];
    }
    float lf = (float)loss;
    cmp(tag, &lf, "out.loss", 1e-6, 1e-5);
    /* backward */
    memcpy(gs, ts, sizeof(float) * R);
    memcpy(gc, tc, sizeof(float) * R * 3);
    sooc_nn_nerf_tail_grad tg = {g[3], g[4], g[5], g[6], g[7], g[8], g[9], g[10], g[11], g[12]};
    sooc_nn_nerf_tail_backward(&t, &tg, 1.0f, R, a1, a2, a3, ac, sig, col, gs, gc, gA, gB, gB, gA);
    sooc_nn_dense_backward(R, DIN, H, gA, H, pe, DIN, w[0], transposed ? W1xt : NULL, gpe, DIN, 0, NULL, g[0], NULL,
                           1.0f);
    /* slot bias -> b1, W1z, z (decoder.c step 7) */
    for (int r = 0; r < R; r++)
        for (int j = 0; j < H; j++) gsb[(int)slotf[r] * H + j] += gA[(size_t)r * H + j];
    for (int k = 0; k < S; k++)
        for (int j = 0; j < H; j++) {
            g[2][j] += gsb[k * H + j];
            for (int i = 0; i < DZ; i++) {
                g[1][i * H + j] += z[k * DZ + i] * gsb[k * H + j];
                gz[k * DZ + i] += w[1][i * H + j] * gsb[k * H + j];
            }
        }
    for (int i = 0; i < NW; i++) {
        char nm[32];
        snprintf(nm, sizeof nm, "grad.%s", WN[i]);
        cmp(tag, g[i], nm, 1e-5, 1e-4);
        sooc_free(g[i]);
    }
    cmp(tag, gpe, "grad.pe", 1e-5, 1e-4);
    cmp(tag, gz, "grad.z", 1e-5, 1e-4);
    float *bufs[] = {sb, a1, a2, a3, ac, sig, col, gs, gc, gA, gB, gpe, gz, gsb, wt};
    for (size_t i = 0; i < sizeof bufs / sizeof *bufs; i++) sooc_free(bufs[i]);
}

int main(void) {
    if (system("/usr/bin/python3 -c 'import torch' > /dev/null 2>&1") != 0) {
        printf("SKIP: /usr/bin/python3 with torch not available (apt install python3-torch)\n");
        return SOOC_TEST_SKIP;
    }
    const char *out = getenv("SOOC_NERF_REF_OUT"), *src = getenv("SOOC_SRC");
    if (!out) out = "nerf_ref.txt";
    if (!src) src = ".";
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "/usr/bin/python3 %s/tests/ref/nerf_ref.py %s", src, out);
    CHECK_MSG(system(cmd) == 0, "%s failed", cmd);
    CHECK_OK(load_ref(out));
    if (g_check_fail) return check_report("test_nn_nerf_ref");
    printf("test_nn_nerf_ref: %s kernels\n", sooc_nn_gemm_avx2() ? "AVX2/FMA" : "portable (OpenBLAS)");
    run(1);
    run(0);
    for (int i = 0; i < g_nrec; i++) sooc_free(g_rec[i].v);
    return check_report("test_nn_nerf_ref");
}
