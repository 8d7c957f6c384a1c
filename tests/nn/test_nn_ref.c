/*
 * PyTorch reference test (llm.c style). Runs tests/ref/nn_ref.py with
 * /usr/bin/python3 (Debian python3-torch) to write nn_ref.bin into the build
 * directory, then rebuilds the same composite network on the sooc3d tape and
 * compares outputs, every gradient, the losses of 5 Adam steps and the final
 * parameters. (The decoder MLP as the model runs it: test_nn_nerf_ref.c.)
 * Skips (77) only when python3 or torch is missing.
 *
 * Tolerances (float32, different summation orders): |c - t| <= atol + rtol*|t|
 * with outputs (1e-6, 1e-5), gradients (1e-6, 1e-4) (output grads 1e-7),
 * Adam losses (0, 1e-4), final parameters (1e-5, 1e-4). Measured worst
 * err/tol is printed (about 0.1 at these tolerances).
 */
#include "check.h"
#include "nn/nn.h"
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

static rec g_rec[256];
static int g_nrec;
static void *g_file;

static sooc_status load_ref(const char *path) {
    size_t n;
    sooc_status s = sooc_file_read_all(path, (size_t)64 << 20, &g_file, &n);
    if (s) return s;
    unsigned char *b = g_file, *e = b + n;
    uint32_t ver, nr;
    if (n < 16 || memcmp(b, "SOOCNNRF", 8) != 0)
        return sooc_seterr(SOOC_EFORMAT, "%s: bad magic", path);
    memcpy(&ver, b + 8, 4);
    memcpy(&nr, b + 12, 4);
    if (ver != 1) return sooc_seterr(SOOC_EVERSION, "%s: version %u, expected 1", path, ver);
    if (nr > 256) return sooc_seterr(SOOC_EFORMAT, "%s: too many records", path);
    b += 16;
    for (uint32_t i = 0; i < nr; i++) {
        rec *r = &g_rec[i];
        uint32_t len, nd;
        if (e - b < 4) goto trunc;
        memcpy(&len, b, 4); b += 4;
        if (len >= sizeof r->name || e - b < (ptrdiff_t)len + 4) goto trunc;
        memcpy(r->name, b, len); r->name[len] = 0; b += len;
        memcpy(&nd, b, 4); b += 4;
        if (nd > 4 || e - b < (ptrdiff_t)(8 * nd)) goto trunc;
        r->ndim = (int)nd;
        r->n = 1;
        for (uint32_t d = 0; d < nd; d++) {
            memcpy(&r->shape[d], b, 8); b += 8;
            if (r->shape[d] < 0 || r->shape[d] > (1 << 24)) goto trunc;
            r->n *= r->shape[d];
        }
        if (e - b < (ptrdiff_t)(4 * r->n)) goto trunc;
        r->data = (float *)(void *)b; /* file buffer is 64-byte aligned; records may not be */
        float *cp = sooc_malloc((size_t)(r->n ? r->n : 1) * 4);
        memcpy(cp, b, (size_t)r->n * 4);
        r->data = cp;
        b += 4 * r->n;
    }
    g_nrec = (int)nr;
    return SOOC_OK;
trunc:
    return sooc_seterr(SOOC_EFORMAT, "%s: truncated record", path);
}

static rec *get(const char *name) {
    for (int i = 0; i < g_nrec; i++)
        if (!strcmp(g_rec[i].name, name)) return &g_rec[i];
    fprintf(stderr, "reference record '%s' missing\n", name);
    exit(1);
}

static double g_worst_all = 0;
static void cmp(const char *what, const float *c, const char *refname, double atol, double rtol) {
    rec *r = get(refname);
    double worst = 0;
    int64_t wi = 0;
    for (int64_t i = 0; i < r->n; i++) {
        double d = fabs((double)c[i] - r->data[i]) / (atol + rtol * fabs((double)r->data[i]));
        if (!(d <= worst)) { worst = d; wi = i; }
    }
    if (worst > g_worst_all) g_worst_all = worst;
    int ok = worst <= 1.0;
    if (!ok || getenv("SOOC_VERBOSE"))
        printf("  %-22s %-20s n=%-5lld worst err/tol %.3f at %lld (c %.7g, torch %.7g)\n", what,
               refname, (long long)r->n, worst, (long long)wi, c[wi], r->data[wi]);
    CHECK_MSG(ok, "%s %s: worst err/tol %.3g at %lld: %.7g vs torch %.7g", what, refname, worst,
              (long long)wi, c[wi], r->data[wi]);
}

/* parameter names in the file order */
static const char *PN[] = {"mlp.wz", "mlp.w0", "mlp.b0", "mlp.w1", "mlp.b1", "mlp.wd", "mlp.bd",
                           "mlp.wc", "mlp.bc", "enc.fc.w", "enc.fc.b", "enc.ln.g", "enc.ln.b",
                           "head.w", "head.b"};
enum { NP = sizeof PN / sizeof PN[0] };

static sooc_nn_params g_p;
static sooc_nn_tensor *P(const char *n) { return sooc_nn_params_tensor(&g_p, sooc_nn_params_find(&g_p, n)); }

typedef struct fwd {
    sooc_nn_tensor *loss, *dens, *col, *enc, *dz, *pts, *z, *sb, *pe;
} fwd;

static sooc_nn_tensor *in_tensor(sooc_nn_tape *t, const char *name, int req) {
    rec *r = get(name);
    return sooc_nn_tensor_new(t, r->data, r->ndim, r->shape, req);
}

static sooc_nn_tensor *mse(sooc_nn_tape *t, sooc_nn_tensor *a, sooc_nn_tensor *b) {
    return sooc_nn_mean(t, sooc_nn_unary(t, SOOC_NN_ACT_SQUARE, sooc_nn_binary(t, SOOC_NN_SUB, a, b)),
                        SOOC_NN_ALL);
}

static void forward(sooc_nn_tape *t, fwd *f) {
    const int K = 2, NPTS = 16, W = 16;
    f->pts = in_tensor(t, "in.pts", 1);
    f->z = in_tensor(t, "in.z", 1);
    f->pe = sooc_nn_posenc(t, f->pts, 5);
    f->sb = sooc_nn_linear(t, f->z, P("mlp.wz"), NULL, SOOC_NN_ACT_NONE);
    sooc_nn_tensor *h = sooc_nn_linear(t, f->pe, P("mlp.w0"), P("mlp.b0"), SOOC_NN_ACT_NONE);
    int64_t s3[3] = {K, NPTS, W}, s2[2] = {K * NPTS, W};
    h = sooc_nn_unary(t, SOOC_NN_ACT_RELU, sooc_nn_slot_bias(t, sooc_nn_reshape(t, h, 3, s3), f->sb));
    h = sooc_nn_reshape(t, h, 2, s2);
    h = sooc_nn_linear(t, h, P("mlp.w1"), P("mlp.b1"), SOOC_NN_ACT_RELU);
    f->dens = sooc_nn_linear(t, h, P("mlp.wd"), P("mlp.bd"), SOOC_NN_ACT_SIGMOID);
    f->col = sooc_nn_linear(t, h, P("mlp.wc"), P("mlp.bc"), SOOC_NN_ACT_SIGMOID);
    sooc_nn_tensor *img = in_tensor(t, "in.img", 0);
    int64_t sf[2] = {K, img->n / K};
    sooc_nn_tensor *e = sooc_nn_layernorm(t, sooc_nn_reshape(t, img, 2, sf), NULL, NULL, 1e-5f);
    e = sooc_nn_linear(t, e, P("enc.fc.w"), P("enc.fc.b"), SOOC_NN_ACT_ELU);
    f->enc = sooc_nn_layernorm(t, e, P("enc.ln.g"), P("enc.ln.b"), 1e-5f);
    sooc_nn_tensor *cat[2] = {f->enc, f->z};
    f->dz = sooc_nn_linear(t, sooc_nn_concat(t, cat, 2, 1), P("head.w"), P("head.b"), SOOC_NN_ACT_NONE);
    sooc_nn_tensor *l = sooc_nn_binary(t, SOOC_NN_ADD, mse(t, f->dens, in_tensor(t, "in.t_dens", 0)),
                                       mse(t, f->col, in_tensor(t, "in.t_col", 0)));
    f->loss = sooc_nn_binary(t, SOOC_NN_ADD, l, mse(t, f->dz, in_tensor(t, "in.t_dz", 0)));
}

int main(void) {
    if (system("/usr/bin/python3 -c 'import torch' > /dev/null 2>&1") != 0) {
        printf("SKIP: /usr/bin/python3 with torch not available (apt install python3-torch)\n");
        return SOOC_TEST_SKIP;
    }
    const char *src = getenv("SOOC_SRC") ? getenv("SOOC_SRC") : ".";
    const char *out = getenv("SOOC_NN_REF_OUT") ? getenv("SOOC_NN_REF_OUT") : "nn_ref.bin";
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "/usr/bin/python3 %s/tests/ref/nn_ref.py %s", src, out);
    if (system(cmd) != 0) {
        fprintf(stderr, "FAIL: reference script failed: %s\n", cmd);
        return 1;
    }
    if (load_ref(out)) {
        fprintf(stderr, "FAIL: %s\n", sooc_errmsg());
        return 1;
    }
    sooc_nn_params_init(&g_p);
    for (int i = 0; i < NP; i++) CHECK(sooc_nn_params_add(&g_p, PN[i], get(PN[i])->ndim, get(PN[i])->shape) == i);
    CHECK_OK(sooc_nn_params_alloc(&g_p));
    for (int i = 0; i < NP; i++) memcpy(P(PN[i])->data, get(PN[i])->data, (size_t)get(PN[i])->n * 4);
    sooc_nn_arena ar;
    CHECK_OK(sooc_nn_arena_init(&ar, 8 << 20));
    sooc_nn_tape *t;
    CHECK_OK(sooc_nn_tape_create(&t, &ar, 256));
    fwd f;
    forward(t, &f);
    CHECK_OK(sooc_nn_tape_status(t));
    if (sooc_nn_tape_status(t)) { fprintf(stderr, "%s\n", sooc_nn_tape_errmsg(t)); return 1; }
    CHECK_OK(sooc_nn_tape_seed(t, f.loss, NULL, 1.f));
    CHECK_OK(sooc_nn_tape_backward(t));
    cmp("output", f.loss->data, "out.loss", 1e-6, 1e-5);
    sooc_nn_tensor *outs[4] = {f.dens, f.col, f.enc, f.dz};
    const char *on[4] = {"out.dens", "out.col", "out.enc", "out.dz"};
    char gname[80];
    for (int i = 0; i < 4; i++) {
        cmp("output", outs[i]->data, on[i], 1e-6, 1e-5);
        snprintf(gname, sizeof gname, "grad.%s", on[i]);
        cmp("output grad", outs[i]->grad, gname, 1e-7, 1e-4);
    }
    for (int i = 0; i < NP; i++) {
        snprintf(gname, sizeof gname, "grad.%s", PN[i]);
        cmp("param grad", P(PN[i])->grad, gname, 1e-6, 1e-4);
    }
    cmp("input grad", f.pts->grad, "grad.in.pts", 1e-6, 1e-4);
    cmp("input grad", f.z->grad, "grad.in.z", 1e-6, 1e-4);
    printf("forward/backward vs torch: worst err/tol %.3f over all tensors\n", g_worst_all);
    /* digests for comparing builds (OpenMP on/off, thread counts): bitwise */
    uint32_t grad_crc = sooc_crc32(0, g_p.g, g_p.n_total * sizeof(float));

    /* 5 Adam steps, lr 1e-2 */
    float losses[5];
    sooc_nn_adam_cfg ac = sooc_nn_adam_default();
    for (int s = 0; s < 5; s++) {
        sooc_nn_params_zero_grad(&g_p);
        sooc_nn_tape_reset(t);
        sooc_nn_arena_reset(&ar);
        forward(t, &f);
        CHECK_OK(sooc_nn_tape_seed(t, f.loss, NULL, 1.f));
        CHECK_OK(sooc_nn_tape_backward(t));
        losses[s] = f.loss->data[0];
        CHECK_OK(sooc_nn_adam_step(&g_p, &ac, 1e-2f));
    }
    rec *rl = get("adam.losses");
    for (int s = 0; s < 5; s++)
        printf("adam step %d: loss %.7f torch %.7f\n", s, losses[s], rl->data[s]);
    cmp("adam losses", losses, "adam.losses", 0, 1e-4);
    for (int i = 0; i < NP; i++) {
        snprintf(gname, sizeof gname, "final.%s", PN[i]);
        cmp("final param", P(PN[i])->data, gname, 1e-5, 1e-4);
    }
    printf("overall worst err/tol %.3f (1.0 = tolerance)\n", g_worst_all);
    printf("bitwise digest: grads %08x final params %08x (compare across builds)\n", grad_crc,
           sooc_crc32(0, g_p.w, g_p.n_total * sizeof(float)));
    sooc_nn_tape_destroy(t);
    sooc_nn_arena_deinit(&ar);
    sooc_nn_params_deinit(&g_p);
    for (int i = 0; i < g_nrec; i++) sooc_free(g_rec[i].data);
    sooc_free(g_file);
    return check_report("test_nn_ref");
}
