/* The KL terms of the variational model (model/decoder.h; docs/model.md):
 * between diagonal Gaussians, and of one slot (where, what, presence) against
 * its prior, with their gradients. */
#include "model/decoder.h"

#include <math.h>

static inline float sigm(float x) { return 1.0f / (1.0f + expf(-x)); }
static inline float clampf(float x, float a, float b) { return x < a ? a : x > b ? b : x; }

/* ---------------------------------------------------------------- KL */

double sooc_mdl_kl_gauss(int n, const float *mu, const float *rho, const float *mu0, const float *rho0, float rmin,
                    float rmax, float beta, float *gmu, float *grho, float *gmu0, float *grho0) {
    double kl = 0;
    for (int i = 0; i < n; i++) {
        float r = clampf(rho[i], rmin, rmax), r0 = clampf(rho0[i], rmin, rmax);
        float dm = mu[i] - mu0[i];
        float e = expf(r), ie0 = expf(-r0);
        kl += 0.5 * (r0 - r) + 0.5 * (e + dm * dm) * ie0 - 0.5;
        if (gmu) gmu[i] += beta * dm * ie0;
        if (gmu0) gmu0[i] -= beta * dm * ie0;
        if (grho && rho[i] >= rmin && rho[i] <= rmax) grho[i] += beta * (-0.5f + 0.5f * e * ie0);
        if (grho0 && rho0[i] >= rmin && rho0[i] <= rmax) grho0[i] += beta * (0.5f - 0.5f * (e + dm * dm) * ie0);
    }
    return beta * kl;
}

static float log_sigm(float a) { return a >= 0 ? -log1pf(expf(-a)) : a - log1pf(expf(a)); }

double sooc_mdl_kl_slot(const sooc_model_config *cfg, const float *lam, const float *lam0, float beta, float *g,
                   float *g0) {
    int d = cfg->d_what;
    float rmin = cfg->rho_min, rmax = cfg->rho_max;
    double kl = 0;
    /* x and z share rho_t; θ wrapped */
    float mu[3] = {lam[0], lam[1], lam[2]}, mu0[3] = {lam0[0], lam0[1], lam0[2]};
    float dth = (float)sooc_wrap_angle((double)lam[2] - lam0[2]);
    mu[2] = mu0[2] + dth;
    float rho[3] = {lam[3], lam[3], lam[4]}, rho0[3] = {lam0[3], lam0[3], lam0[4]};
    float gm[3] = {0}, gr[3] = {0}, gm0[3] = {0}, gr0[3] = {0};
    kl += sooc_mdl_kl_gauss(3, mu, rho, mu0, rho0, rmin, rmax, beta, gm, gr, gm0, gr0);
    if (g) {
        g[0] += gm[0], g[1] += gm[1], g[2] += gm[2];
        g[3] += gr[0] + gr[1], g[4] += gr[2];
    }
    if (g0) {
        g0[0] += gm0[0], g0[1] += gm0[1], g0[2] += gm0[2];
        g0[3] += gr0[0] + gr0[1], g0[4] += gr0[2];
    }
    kl += sooc_mdl_kl_gauss(d, lam + 5, lam + 5 + d, lam0 + 5, lam0 + 5 + d, rmin, rmax, beta, g ? g + 5 : NULL,
                       g ? g + 5 + d : NULL, g0 ? g0 + 5 : NULL, g0 ? g0 + 5 + d : NULL);
    float a = lam[5 + 2 * d], a0 = lam0[5 + 2 * d];
    float p = sigm(a), p0 = sigm(a0);
    float lp = log_sigm(a), lq = log_sigm(-a), lp0 = log_sigm(a0), lq0 = log_sigm(-a0);
    kl += beta * (p * (lp - lp0) + (1 - p) * (lq - lq0));
    if (g) g[5 + 2 * d] += beta * p * (1 - p) * (a - a0);
    if (g0) g0[5 + 2 * d] += beta * (p0 - p);
    return kl;
}
