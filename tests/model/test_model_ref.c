/* Compare the C decoder with the PyTorch reference (tests/ref/model_ref.py):
 * decoding, composition, likelihood and KL of one view, outputs and all
 * gradients. The test runs the script itself; exit 77 (skip) only if
 * /usr/bin/python3 cannot import torch. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "model/step.h"

static const uint8_t *rp;
static size_t rleft;
static int rd(void *dst, size_t n) {
    if (n > rleft) return -1;
    memcpy(dst, rp, n);
    rp += n, rleft -= n;
    return 0;
}

static void cmp_arr(const char *name, const float *c, const float *ref, size_t n, double tol) {
    double mref = 0, merr = 0;
    size_t wi = 0;
    for (size_t i = 0; i < n; i++) {
        if (fabs(ref[i]) > mref) mref = fabs(ref[i]);
        double e = fabs((double)c[i] - ref[i]);
        if (e > merr) merr = e, wi = i;
    }
    double rel = merr / (mref > 1e-12 ? mref : 1e-12);
    printf("  %-14s n=%-6zu max|ref| %.4e  max|C-ref| %.3e  (rel %.2e, worst [%zu] C %.6e ref %.6e)\n", name, n, mref,
           merr, rel, wi, n ? c[wi] : 0.0, n ? ref[wi] : 0.0);
    CHECK_MSG(rel <= tol || merr <= 1e-6, "%s: relative max error %.3e > %.1e", name, rel, tol);
}

static int run_ref(int unknown);

int main(void) {
    if (system("/usr/bin/python3 -c 'import torch' >/dev/null 2>&1") != 0) {
        printf("test_model_ref: SKIP (/usr/bin/python3 cannot import torch)\n");
        return SOOC_TEST_SKIP;
    }
    /* pass 0: the plain decode; pass 1: config.invalid_depth unknown, a quarter of the rays holes */
    for (int unknown = 0; unknown < 2; unknown++)
        if (run_ref(unknown)) return 1;
    return check_report("test_model_ref");
}

static int run_ref(int unknown) {
    const char *src = getenv("SOOC_SRC") ? getenv("SOOC_SRC") : ".";
    char path[256], cmd[1024];
    snprintf(path, sizeof path, "/tmp/sooc_model_ref.%d.bin", (int)getpid());
    snprintf(cmd, sizeof cmd, "/usr/bin/python3 %s/tests/ref/model_ref.py %s%s", src, path,
             unknown ? " --unknown" : "");
    printf("test_model_ref: %s\n", unknown ? "unknown rays (a quarter of the rays are holes)" : "plain decode");
    if (system(cmd) != 0) {
        fprintf(stderr, "test_model_ref: reference script failed: %s\n", cmd);
        return 1;
    }
    void *buf;
    size_t n;
    CHECK_OK(sooc_file_read_all(path, 1 << 28, &buf, &n));
    remove(path);
    rp = buf, rleft = n;
    char magic[8];
    uint32_t ver;
    int32_t I[9];
    float Fl[16];
    CHECK(!rd(magic, 8) && !memcmp(magic, "SOOCREF1", 8));
    CHECK(!rd(&ver, 4) && ver == 1);
    CHECK(!rd(I, sizeof I) && !rd(Fl, sizeof Fl));
    int K = I[0], d = I[1], dl = I[2], N = I[7];
    sooc_model_config c;
    sooc_model_config_default(&c);
    c.K = K, c.d_what = d, c.d_layout = dl, c.dec_width = I[3], c.dec_color_width = I[4];
    c.n_freq = I[5], c.n_freq_layout = I[6], c.use_box = I[8];
    c.ray_w = c.ray_h = 16;
    CHECK(N == 256);
    c.sigma_max = Fl[0], c.sigma_c = Fl[1], c.eps_sigma_rel = Fl[2], c.box_rh = Fl[3], c.box_hb = Fl[4];
    c.gauss_s = Fl[5], c.block_size = Fl[6], c.rho_min = Fl[7], c.rho_max = Fl[8];
    float tau = Fl[9], beta = Fl[10];
    c.img_w = c.img_h = (int)lround(sqrt(Fl[12]));
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 1));
    sooc_model_ws *w;
    CHECK_OK(sooc_model_ws_create(&w, m));
    int NL = m->NL, P = 2 * N, C = K + 1;
    sooc_view_rays vr;
    CHECK_OK(sooc_mdl_rays_alloc(&vr, 16, 16));
    vr.h = Fl[11];
    vr.blk[0] = Fl[13], vr.blk[1] = Fl[14], vr.blk[2] = Fl[15];
    float *surf = malloc(N * sizeof(float));
    float *lam = malloc(K * NL * 4), *lam0 = malloc(K * NL * 4), *lay = malloc(2 * dl * 4), *lay0 = malloc(2 * dl * 4);
    sooc_dec_noise nz;
    memset(&nz, 0, sizeof nz);
    CHECK(!rd(vr.rgb, N * 12) && !rd(vr.depth, N * 4) && !rd(surf, N * 4) && !rd(vr.W, N * 4) && !rd(vr.pts, P * 12));
    int nunk = 0;
    for (int r = 0; r < N; r++) {
        vr.surf[r] = surf[r] > 0.5f && surf[r] < 1.5f;
        vr.unk[r] = surf[r] > 1.5f;
        nunk += vr.unk[r];
    }
    CHECK(unknown ? nunk == N / 4 : nunk == 0);
    CHECK(!rd(lam, K * NL * 4) && !rd(lam0, K * NL * 4) && !rd(lay, 2 * dl * 4) && !rd(lay0, 2 * dl * 4));
    for (int k = 0; k < K; k++) CHECK(!rd(nz.eps_where[k], 12));
    for (int k = 0; k < K; k++) CHECK(!rd(nz.eps_what[k], d * 4));
    CHECK(!rd(nz.logistic, K * 4) && !rd(nz.eps_lay, dl * 4));
    size_t nobj = m->dlay.W1x - m->dobj.W1x, nlay = m->robj.cw[0] - m->dlay.W1x;
    CHECK(!rd(m->p + m->dobj.W1x, nobj * 4) && !rd(m->p + m->dlay.W1x, nlay * 4));
    double ref3[3];
    CHECK(!rd(ref3, sizeof ref3));
    float *r_sh = malloc(P * C * 4), *r_col = malloc(P * 12), *r_gl = malloc(K * NL * 4), *r_gl0 = malloc(K * NL * 4);
    float *r_gy = malloc(2 * dl * 4), *r_gy0 = malloc(2 * dl * 4), *r_gw = malloc((nobj + nlay) * 4);
    CHECK(!rd(r_sh, P * C * 4) && !rd(r_col, P * 12) && !rd(r_gl, K * NL * 4) && !rd(r_gl0, K * NL * 4));
    CHECK(!rd(r_gy, 2 * dl * 4) && !rd(r_gy0, 2 * dl * 4) && !rd(r_gw, (nobj + nlay) * 4));
    CHECK(!rd(magic, 4) && !memcmp(magic, "END!", 4) && rleft == 0);
    if (g_check_fail) return 1;

    float g_lam[16 * 70] = {0}, g_lam0[16 * 70] = {0}, g_lay[64] = {0}, g_lay0[64] = {0};
    sooc_dec_call dc;
    memset(&dc, 0, sizeof dc);
    dc.rays = &vr, dc.nslot = K, dc.lam = lam, dc.lam0 = lam0, dc.lay = lay, dc.lay0 = lay0, dc.noise = &nz;
    dc.tau = tau, dc.beta_kl = beta, dc.wgrad = 1.0f, dc.backward = 1;
    dc.g_lam = g_lam, dc.g_lam0 = g_lam0, dc.g_lay = g_lay, dc.g_lay0 = g_lay0;
    sooc_model_zero_grad(m);
    CHECK_OK(sooc_mdl_decode(w, &dc));
    printf("test_model_ref: loss C %.6f ref %.6f | nll C %.6f ref %.6f | kl C %.6f ref %.6f | %d object rows\n",
           dc.loss, ref3[0], dc.nll, ref3[1], dc.kl, ref3[2], w->dec->nro);
    CHECK_CLOSE(dc.loss, ref3[0], 1e-3, 1e-5);
    CHECK_CLOSE(dc.nll, ref3[1], 1e-3, 1e-5);
    CHECK_CLOSE(dc.kl, ref3[2], 1e-4, 1e-5);
    CHECK(w->dec->nro > 0);
    /* outputs at used points */
    float *c_col = calloc(P * 3, 4);
    for (int p = 0; p < P; p++)
        if ((p & 1) ? !vr.unk[p >> 1] : vr.surf[p >> 1]) memcpy(c_col + p * 3, w->dec->cc + p * 3, 12);
    cmp_arr("sigma_hat", w->dec->sh, r_sh, (size_t)P * C, 1e-4);
    cmp_arr("colour", c_col, r_col, (size_t)P * 3, 1e-4);
    cmp_arr("dL/dlam", g_lam, r_gl, (size_t)K * NL, 2e-3);
    cmp_arr("dL/dlam0", g_lam0, r_gl0, (size_t)K * NL, 2e-3);
    cmp_arr("dL/dlayout", g_lay, r_gy, 2 * dl, 2e-3);
    cmp_arr("dL/dlayout0", g_lay0, r_gy0, 2 * dl, 2e-3);
    for (int t = 0; t < m->nt; t++) {
        if (strncmp(m->t[t].name, "dec.", 4)) continue;
        size_t o = m->t[t].offset - m->dobj.W1x;
        cmp_arr(m->t[t].name, m->g + m->t[t].offset, r_gw + o, m->t[t].count, 2e-3);
    }
    sooc_mdl_rays_free(&vr);
    sooc_model_ws_destroy(w);
    sooc_model_destroy(m);
    free(surf), free(lam), free(lam0), free(lay), free(lay0), free(r_sh), free(r_col), free(r_gl), free(r_gl0);
    free(r_gy), free(r_gy0), free(r_gw), free(c_col);
    sooc_free(buf);
    return 0;
}
