/* Floor plane estimate: RANSAC on 3-point hypotheses, then a total least
 * squares refit on the inliers (LAPACKE SVD of the centred inlier matrix; the
 * normal is the right singular vector of the smallest singular value). */
#include "sooc3d/frame.h"

#include <lapacke.h>
#include <math.h>
#include <string.h>

void sooc_floor_fit_params_default(sooc_floor_fit_params *p) {
    p->threshold_m = 0.02;
    p->iterations = 200;
    p->min_inlier_frac = 0.15;
    p->seed = 1;
    p->max_tilt_deg = 30.0;
}

static int orient_ok(double nrm[3], double *d, const double *hint, const double *view, double max_tilt_deg) {
    if (hint) {
        double h[3] = {hint[0], hint[1], hint[2]};
        sooc_v3_normalize(h);
        double c = sooc_v3_dot(nrm, h);
        if (c < 0) { sooc_v3_scale(nrm, nrm, -1); *d = -*d; c = -c; }
        return c >= cos(max_tilt_deg * 3.14159265358979323846 / 180.0);
    }
    if (view) {
        if (sooc_v3_dot(nrm, view) + *d < 0) { sooc_v3_scale(nrm, nrm, -1); *d = -*d; }
    }
    return 1;
}

static size_t count_inliers(const double *pts, size_t n, const double nrm[3], double d, double thr,
                            double *sse) {
    size_t c = 0;
    double s = 0;
    for (size_t i = 0; i < n; i++) {
        double r = fabs(sooc_v3_dot(nrm, pts + 3 * i) + d);
        if (r <= thr) { c++; s += r * r; }
    }
    if (sse) *sse = s;
    return c;
}

/* Total least squares plane through the inliers of (nrm, d). */
static sooc_status refit(const double *pts, size_t n, double thr, double nrm[3], double *d) {
    double mean[3] = {0, 0, 0};
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        const double *p = pts + 3 * i;
        if (fabs(sooc_v3_dot(nrm, p) + *d) <= thr) { sooc_v3_add(mean, mean, p); m++; }
    }
    if (m < 3) return sooc_seterr(SOOC_ENOTFOUND, "floor fit: fewer than 3 inliers");
    sooc_v3_scale(mean, mean, 1.0 / (double)m);
    /* scatter matrix (3x3) -> its SVD equals the SVD of the centred data, cheaper than m x 3 */
    double S[9] = {0};
    for (size_t i = 0; i < n; i++) {
        const double *p = pts + 3 * i;
        if (fabs(sooc_v3_dot(nrm, p) + *d) > thr) continue;
        double q[3];
        sooc_v3_sub(q, p, mean);
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) S[3 * a + b] += q[a] * q[b];
    }
    double sv[3], U[9], VT[9], superb[2];
    lapack_int info = LAPACKE_dgesvd(LAPACK_ROW_MAJOR, 'N', 'A', 3, 3, S, 3, sv, U, 3, VT, 3, superb);
    if (info != 0) return sooc_seterr(SOOC_ENUMERIC, "floor fit: LAPACKE_dgesvd failed (info %d)", (int)info);
    double nn[3] = {VT[6], VT[7], VT[8]};   /* smallest singular value: last row of V^T */
    sooc_v3_normalize(nn);
    if (sooc_v3_dot(nn, nrm) < 0) sooc_v3_scale(nn, nn, -1);
    memcpy(nrm, nn, sizeof nn);
    *d = -sooc_v3_dot(nrm, mean);
    return SOOC_OK;
}

sooc_status sooc_floor_fit(const double *pts, size_t n, const sooc_floor_fit_params *pp, const double *hint_up,
                           const double *viewpoint, double plane[4], size_t *n_inliers, double *rms) {
    sooc_floor_fit_params p;
    if (pp) p = *pp;
    else sooc_floor_fit_params_default(&p);
    if (n < 3) return sooc_seterr(SOOC_ENOTFOUND, "floor fit: only %zu points", n);
    sooc_rng rng;
    sooc_rng_seed(&rng, p.seed, 0x71007);
    size_t best = 0;
    double bn[3] = {0, 1, 0}, bd = 0, best_sse = 0;
    for (int it = 0; it < p.iterations; it++) {
        uint32_t n32 = n > 0xffffffffu ? 0xffffffffu : (uint32_t)n;
        const double *a = pts + 3 * (size_t)sooc_rng_below(&rng, n32);
        const double *b = pts + 3 * (size_t)sooc_rng_below(&rng, n32);
        const double *c = pts + 3 * (size_t)sooc_rng_below(&rng, n32);
        double ab[3], ac[3], nrm[3];
        sooc_v3_sub(ab, b, a);
        sooc_v3_sub(ac, c, a);
        sooc_v3_cross(nrm, ab, ac);
        if (sooc_v3_normalize(nrm) < 1e-9) continue;
        double d = -sooc_v3_dot(nrm, a);
        if (!orient_ok(nrm, &d, hint_up, viewpoint, p.max_tilt_deg)) continue;
        double sse;
        size_t cnt = count_inliers(pts, n, nrm, d, p.threshold_m, &sse);
        /* prefer more inliers; on ties, the tighter fit (MSAC-like) */
        if (cnt > best || (cnt == best && sse < best_sse)) {
            best = cnt;
            best_sse = sse;
            memcpy(bn, nrm, sizeof nrm);
            bd = d;
        }
    }
    if (best < 3 || (double)best < p.min_inlier_frac * (double)n)
        return sooc_seterr(SOOC_ENOTFOUND, "floor fit: best plane has %zu of %zu points as inliers (need %.0f%%)",
                           best, n, 100.0 * p.min_inlier_frac);
    /* two refinement rounds: refit on inliers, recount */
    for (int r = 0; r < 2; r++) {
        sooc_status st = refit(pts, n, p.threshold_m, bn, &bd);
        if (st) return st;
    }
    if (!orient_ok(bn, &bd, hint_up, viewpoint, p.max_tilt_deg))
        return sooc_seterr(SOOC_ENOTFOUND, "floor fit: refined plane is more than %g deg from the up hint",
                           p.max_tilt_deg);
    double sse;
    size_t cnt = count_inliers(pts, n, bn, bd, p.threshold_m, &sse);
    plane[0] = bn[0];
    plane[1] = bn[1];
    plane[2] = bn[2];
    plane[3] = bd;
    if (n_inliers) *n_inliers = cnt;
    if (rms) *rms = cnt ? sqrt(sse / (double)cnt) : 0;
    return SOOC_OK;
}
