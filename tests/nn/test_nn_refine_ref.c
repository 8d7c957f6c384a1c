/*
 * The refinement-network kernel pairs (nn/nn_refine.h) against PyTorch.
 * Runs tests/ref/refine_ref.py with /usr/bin/python3 (Debian python3-torch),
 * which writes a small refinement net in float64 (MulMON LN of image channels
 * and vector entries, two conv 3x3 s2 + ELU, pool 4x4 -> 2x2 + flatten, FC +
 * ELU, LSTM cell, linear head) with its outputs and every gradient; the test
 * wires the float32 pairs the same way (as src/model/refine.c does) and
 * compares. Skips (77) only when python3 or torch is missing.
 *
 * Tolerance per array: |c - t| <= 2e-6 (max|t| + |t|) (outputs),
 * 1e-5 (max|t| + |t|) (gradients); the worst err/tol is printed (about 0.1).
 */
#include "check.h"
#include "nn/nn_refine.h"
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct rec {
    char name[64];
    int ndim;
    int64_t shape[4];
    int64_t n;
    float *data;
} rec;

static rec g_rec[64];
static int g_nrec;

static sooc_status load_ref(const char *path) {
    size_t n;
    void *file;
    sooc_status s = sooc_file_read_all(path, (size_t)16 << 20, &file, &n);
    if (s) return s;
    unsigned char *b = file, *e = b + n;
    uint32_t ver, nr;
    s = SOOC_OK;
    if (n < 16 || memcmp(b, "SOOCNNRF", 8) != 0) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: bad magic", path);
        goto done;
    }
    memcpy(&ver, b + 8, 4);
    memcpy(&nr, b + 12, 4);
    if (ver != 1 || nr > 64) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: version %u / %u records (expected 1 / <= 64)", path, ver, nr);
        goto done;
    }
    b += 16;
    for (uint32_t i = 0; i < nr; i++) {
        rec *r = &g_rec[i];
        uint32_t len, nd;
        if (e - b < 4) goto trunc;
        memcpy(&len, b, 4), b += 4;
        if (len >= sizeof r->name || e - b < (ptrdiff_t)len + 4) goto trunc;
        memcpy(r->name, b, len), r->name[len] = 0, b += len;
        memcpy(&nd, b, 4), b += 4;
        if (nd > 4 || e - b < (ptrdiff_t)(8 * nd)) goto trunc;
        r->ndim = (int)nd, r->n = 1;
        for (uint32_t d = 0; d < nd; d++) {
            memcpy(&r->shape[d], b, 8), b += 8;
            if (r->shape[d] < 0 || r->shape[d] > (1 << 20)) goto trunc;
            r->n *= r->shape[d];
        }
        if (e - b < (ptrdiff_t)(4 * r->n)) goto trunc;
        r->data = malloc((size_t)(r->n ? r->n : 1) * 4);
        memcpy(r->data, b, (size_t)r->n * 4);
        b += 4 * r->n;
        g_nrec = (int)i + 1;
    }
    goto done;
trunc:
    s = sooc_seterr(SOOC_EFORMAT, "%s: truncated record", path);
done:
    sooc_free(file);
    return s;
}

static rec *get(const char *name) {
    for (int i = 0; i < g_nrec; i++)
        if (!strcmp(g_rec[i].name, name)) return &g_rec[i];
    fprintf(stderr, "reference record '%s' missing\n", name);
    exit(1);
}
static float *D(const char *name) { return get(name)->data; }

static double g_worst;
static void cmp(const char *what, const float *c, const char *ref, double tol) {
    rec *r = get(ref);
    double mx = 0, worst = 0;
    int64_t wi = 0;
    for (int64_t i = 0; i < r->n; i++) mx = fmax(mx, fabs(r->data[i]));
    for (int64_t i = 0; i < r->n; i++) {
        double e = fabs((double)c[i] - r->data[i]) / (tol * mx + tol * fabs(r->data[i]) + 1e-30);
        if (!(e <= worst)) worst = e, wi = i;
    }
    g_worst = fmax(g_worst, worst);
    printf("  %-8s %-14s n=%-5lld max|torch| %.3e  worst err/tol %.3f\n", what, ref, (long long)r->n, mx, worst);
    CHECK_MSG(worst <= 1.0, "%s %s: worst err/tol %.3g at %lld: %.8g vs torch %.8g", what, ref, worst, (long long)wi,
              c[wi], r->data[wi]);
}

enum { B = 3, CIN = 4, HW = 16, C1 = 5, C2 = 6, FC = 10, NVEC = 7, G = 8, NOUT = 7, NFLAT = C2 * 4, NIN = FC + NVEC };

static float *z(size_t n) { return calloc(n ? n : 1, sizeof(float)); }

int main(void) {
    if (system("/usr/bin/python3 -c 'import torch' > /dev/null 2>&1") != 0) {
        printf("SKIP: /usr/bin/python3 with torch not available (apt install python3-torch)\n");
        return SOOC_TEST_SKIP;
    }
    const char *src = getenv("SOOC_SRC") ? getenv("SOOC_SRC") : ".";
    const char *out = getenv("SOOC_NN_REFINE_REF_OUT") ? getenv("SOOC_NN_REFINE_REF_OUT") : "refine_ref.bin";
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "/usr/bin/python3 %s/tests/ref/refine_ref.py %s", src, out);
    if (system(cmd) != 0) {
        fprintf(stderr, "FAIL: reference script failed: %s\n", cmd);
        return 1;
    }
    if (load_ref(out)) {
        fprintf(stderr, "FAIL: %s\n", sooc_errmsg());
        return 1;
    }
    const int H1 = HW / 2, H2 = HW / 4, NP = HW * HW;
    /* forward, wired like refine.c: LN of image channels 1..2 per item, of vector entries 0..4 */
    float *x0 = z((size_t)CIN * B * NP), st_img[B][3], st_vec[B][3];
    memcpy(x0, D("in.img"), sizeof(float) * CIN * B * NP);
    for (int b = 0; b < B; b++) {
        float *g0 = x0 + ((size_t)1 * B + b) * NP;
        sooc_nn_mln_forward(g0, st_img[b], g0, 2, NP, (int64_t)B * NP);
    }
    float *y1 = z((size_t)C1 * B * H1 * H1), *y2 = z((size_t)C2 * B * H2 * H2);
    float *cols = z(sooc_nn_rconv_cols_floats(CIN, B, HW, HW)), *dcols = z(sooc_nn_rconv_cols_floats(CIN, B, HW, HW));
    for (int b = 0; b < B; b++) {   /* item by item, as the model's pool tasks */
        sooc_nn_rconv_forward(y1, cols, x0, D("c1.w"), D("c1.b"), NULL, 0, B, b, b + 1, CIN, HW, HW, C1, SOOC_NN_ACT_ELU);
        sooc_nn_rconv_forward(y2, cols, y1, D("c2.w"), D("c2.b"), NULL, 0, B, b, b + 1, C1, H1, H1, C2, SOOC_NN_ACT_ELU);
    }
    float *flat = z((size_t)B * NFLAT), *f = z((size_t)B * FC), *xin = z((size_t)B * NIN);
    sooc_nn_pool2_forward(flat, y2, C2, B, H2, H2);
    sooc_nn_rlinear_forward(f, flat, NFLAT, D("fc.w"), D("fc.b"), B, NFLAT, FC, SOOC_NN_ACT_ELU);
    for (int b = 0; b < B; b++) {
        memcpy(xin + (size_t)b * NIN, f + (size_t)b * FC, FC * sizeof(float));
        memcpy(xin + (size_t)b * NIN + FC, D("in.vec") + (size_t)b * NVEC, NVEC * sizeof(float));
        float *v = xin + (size_t)b * NIN + FC;
        sooc_nn_mln_forward(v, st_vec[b], v, 1, 5, 5);
    }
    float *h1 = z((size_t)B * G), *c1 = z((size_t)B * G), *gates = z((size_t)B * 4 * G), *o = z((size_t)B * NOUT);
    sooc_nn_rlstm_forward(h1, c1, gates, xin, D("in.h0"), D("in.c0"), D("lstm.wx"), D("lstm.wh"), D("lstm.b"), B, NIN, G);
    sooc_nn_rlinear_forward(o, h1, G, D("head.w"), D("head.b"), B, G, NOUT, SOOC_NN_ACT_NONE);
    double L = 0;
    for (int i = 0; i < B * NOUT; i++) L += (double)o[i] * D("in.r_out")[i];
    for (int i = 0; i < B * G; i++) L += (double)h1[i] * D("in.r_h")[i] + (double)c1[i] * D("in.r_c")[i];
    float Lf = (float)L;
    printf("test_nn_refine_ref: loss %.9f, torch %.9f\n", L, D("out.loss")[0]);
    cmp("output", &Lf, "out.loss", 2e-6);
    cmp("output", y1, "out.y1", 2e-6);
    cmp("output", y2, "out.y2", 2e-6);
    cmp("output", f, "out.f", 2e-6);
    cmp("output", h1, "out.h1", 2e-6);
    cmp("output", c1, "out.c1", 2e-6);
    cmp("output", o, "out.out", 2e-6);

    /* backward */
    const char *pn[] = {"c1.w", "c1.b", "c2.w", "c2.b", "fc.w", "fc.b", "lstm.wx", "lstm.wh", "lstm.b", "head.w", "head.b"};
    enum { NPRM = sizeof pn / sizeof pn[0] };
    float *gp[NPRM];
    for (int i = 0; i < NPRM; i++) gp[i] = z((size_t)get(pn[i])->n);
    float *dout = z((size_t)B * NOUT), *dh1 = z((size_t)B * G), *dxin = z((size_t)B * NIN), *dh0 = z((size_t)B * G),
          *dc0 = z((size_t)B * G), *scr = z((size_t)B * 4 * G);
    memcpy(dout, D("in.r_out"), sizeof(float) * B * NOUT);
    sooc_nn_rlinear_backward(dh1, gp[9], gp[10], dout, h1, G, o, D("head.w"), B, G, NOUT, SOOC_NN_ACT_NONE);
    for (int i = 0; i < B * G; i++) dh1[i] += D("in.r_h")[i];
    sooc_nn_rlstm_backward(dxin, dh0, dc0, gp[6], gp[7], gp[8], dh1, D("in.r_c"), scr, gates, c1, xin, D("in.h0"),
                           D("in.c0"), D("lstm.wx"), D("lstm.wh"), B, NIN, G);
    float *dvec = z((size_t)B * NVEC), *df = z((size_t)B * FC), *dflat = z((size_t)B * NFLAT);
    for (int b = 0; b < B; b++) {
        memcpy(df + (size_t)b * FC, dxin + (size_t)b * NIN, FC * sizeof(float));
        const float *g = dxin + (size_t)b * NIN + FC;
        sooc_nn_mln_backward(dvec + (size_t)b * NVEC, g, xin + (size_t)b * NIN + FC, st_vec[b], 1, 5, 5);
        for (int j = 5; j < NVEC; j++) dvec[(size_t)b * NVEC + j] += g[j];
    }
    sooc_nn_rlinear_backward(dflat, gp[4], gp[5], df, flat, NFLAT, f, D("fc.w"), B, NFLAT, FC, SOOC_NN_ACT_ELU);
    float *dy2 = z((size_t)C2 * B * H2 * H2), *dy1 = z((size_t)C1 * B * H1 * H1), *dx0 = z((size_t)CIN * B * NP);
    sooc_nn_pool2_backward(dy2, dflat, C2, B, H2, H2);
    sooc_nn_rconv_backward(dy1, gp[2], gp[3], dy2, y2, y1, D("c2.w"), cols, dcols, B, 0, B, C1, H1, H1, C2, SOOC_NN_ACT_ELU);
    sooc_nn_rconv_backward(dx0, gp[0], gp[1], dy1, y1, x0, D("c1.w"), cols, dcols, B, 0, B, CIN, HW, HW, C1, SOOC_NN_ACT_ELU);
    /* through the image LN (channels 1..2 of each item); channels 0 and 3 pass through */
    float *dimg = z((size_t)CIN * B * NP);
    for (int c = 0; c < CIN; c += 3) memcpy(dimg + (size_t)c * B * NP, dx0 + (size_t)c * B * NP, sizeof(float) * B * NP);
    for (int b = 0; b < B; b++) {
        size_t off = ((size_t)1 * B + b) * NP;
        sooc_nn_mln_backward(dimg + off, dx0 + off, x0 + off, st_img[b], 2, NP, (int64_t)B * NP);
    }
    char gname[64];
    for (int i = 0; i < NPRM; i++) {
        snprintf(gname, sizeof gname, "grad.%s", pn[i]);
        cmp("grad", gp[i], gname, 1e-5);
    }
    cmp("grad", dimg, "grad.in.img", 1e-5);
    cmp("grad", dvec, "grad.in.vec", 1e-5);
    cmp("grad", dh0, "grad.in.h0", 1e-5);
    cmp("grad", dc0, "grad.in.c0", 1e-5);
    printf("test_nn_refine_ref: worst err/tol %.3f over all arrays (1.0 = tolerance)\n", g_worst);
    for (int i = 0; i < NPRM; i++) free(gp[i]);
    free(x0), free(y1), free(y2), free(cols), free(dcols), free(flat), free(f), free(xin), free(h1), free(c1), free(gates),
        free(o), free(dout), free(dh1), free(dxin), free(dh0), free(dc0), free(scr), free(dvec), free(df), free(dflat),
        free(dy2), free(dy1), free(dx0), free(dimg);
    for (int i = 0; i < g_nrec; i++) free(g_rec[i].data);
    return check_report("test_nn_refine_ref");
}
