/* Trajectories in TUM format and the TUM RGB-D benchmark metrics: ATE
 * (absolute trajectory error after a closed-form rigid alignment) and RPE
 * (relative pose error over a fixed time or frame delta). Plain C + LAPACKE. */
#include "sooc3d/slam.h"

#include <errno.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sooc3d/core.h"

sooc_status sooc_traj_push(sooc_traj *tr, double t, const double T[16]) {
    if (tr->n == tr->cap) {
        int64_t nc = tr->cap ? 2 * tr->cap : 256;
        double *nt = sooc_realloc(tr->t, (size_t)nc * sizeof(double));
        if (!nt) return sooc_seterr(SOOC_ENOMEM, "trajectory: out of memory");
        tr->t = nt;
        double *nT = sooc_realloc(tr->T, (size_t)nc * 16 * sizeof(double));
        if (!nT) return sooc_seterr(SOOC_ENOMEM, "trajectory: out of memory");
        tr->T = nT;
        tr->cap = nc;
    }
    tr->t[tr->n] = t;
    memcpy(tr->T + 16 * tr->n, T, 16 * sizeof(double));
    tr->n++;
    return SOOC_OK;
}

void sooc_traj_free(sooc_traj *tr) {
    sooc_free(tr->t);
    sooc_free(tr->T);
    memset(tr, 0, sizeof *tr);
}

sooc_status sooc_traj_load_tum(const char *path, sooc_traj *out) {
    memset(out, 0, sizeof *out);
    void *buf = NULL;
    size_t n = 0;
    sooc_status st = sooc_file_read_all(path, (size_t)1 << 30, &buf, &n);
    if (st) return sooc_adderr(st, "trajectory %s", path);
    char *s = buf;
    int line = 0;
    while (*s) {
        char *e = strchr(s, '\n');
        if (e) *e = 0;
        line++;
        char *p = s;
        while (*p == ' ' || *p == '\t' || *p == '\r') p++;
        if (*p && *p != '#') {
            double v[8];
            char *q = p;
            for (int k = 0; k < 8; k++) {
                char *end;
                errno = 0;
                v[k] = strtod(q, &end);
                if (end == q || errno || !isfinite(v[k])) {
                    /* the message quotes the line: set it before freeing buf */
                    st = sooc_seterr(SOOC_EFORMAT, "%s:%d: expected 8 numbers `t tx ty tz qx qy qz qw`, got '%.60s'",
                                     path, line, p);
                    sooc_free(buf);
                    sooc_traj_free(out);
                    return st;
                }
                q = end;
            }
            double qn = sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]);
            if (fabs(qn - 1) > 1e-2) {
                sooc_free(buf);
                sooc_traj_free(out);
                return sooc_seterr(SOOC_EFORMAT, "%s:%d: quaternion norm %.4f is not 1", path, line, qn);
            }
            if (out->n && v[0] <= out->t[out->n - 1]) {
                sooc_free(buf);
                sooc_traj_free(out);
                return sooc_seterr(SOOC_EFORMAT, "%s:%d: timestamp %.6f is not after the previous one", path, line,
                                   v[0]);
            }
            double R[9], T[16];
            sooc_quat_to_m3(R, v + 4);
            sooc_se3_from_rt(T, R, v + 1);
            if ((st = sooc_traj_push(out, v[0], T))) {
                sooc_free(buf);
                sooc_traj_free(out);
                return st;
            }
        }
        if (!e) break;
        s = e + 1;
    }
    sooc_free(buf);
    if (!out->n) return sooc_seterr(SOOC_EFORMAT, "%s: no poses", path);
    return SOOC_OK;
}

sooc_status sooc_traj_save_tum(const char *path, const sooc_traj *tr) {
    sooc_afile f;
    sooc_status st = sooc_afile_open(&f, path);
    if (st) return st;
    const char *hdr = "# timestamp tx ty tz qx qy qz qw (camera-to-world, sooc3d)\n";
    st = sooc_afile_write(&f, hdr, strlen(hdr));
    for (int64_t i = 0; !st && i < tr->n; i++) {
        const double *T = tr->T + 16 * i;
        double R[9], t[3], q[4];
        sooc_se3_to_rt(R, t, T);
        sooc_m3_to_quat(q, R);   /* (x, y, z, w), the TUM order */
        char line[256];
        int len = snprintf(line, sizeof line, "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", tr->t[i], t[0], t[1],
                           t[2], q[0], q[1], q[2], q[3]);
        st = sooc_afile_write(&f, line, (size_t)len);
    }
    if (st) {
        sooc_afile_abort(&f);
        return sooc_adderr(st, "trajectory %s", path);
    }
    return sooc_afile_commit(&f);
}

sooc_status sooc_align_rigid(const double *a, const double *b, int64_t n, double T[16]) {
    if (n < 3) return sooc_seterr(SOOC_EINVAL, "alignment: %lld point pairs, need at least 3", (long long)n);
    double ca[3] = {0, 0, 0}, cb[3] = {0, 0, 0};
    for (int64_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            ca[k] += a[3 * i + k];
            cb[k] += b[3 * i + k];
        }
    for (int k = 0; k < 3; k++) {
        ca[k] /= (double)n;
        cb[k] /= (double)n;
    }
    /* H = sum (b - cb)(a - ca)^T; R = U diag(1, 1, det(U V^T)) V^T */
    double H[9] = {0};
    for (int64_t i = 0; i < n; i++)
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) H[3 * r + c] += (b[3 * i + r] - cb[r]) * (a[3 * i + c] - ca[c]);
    double S[3], U[9], VT[9], sup[2];
    lapack_int info = LAPACKE_dgesvd(LAPACK_ROW_MAJOR, 'A', 'A', 3, 3, H, 3, S, U, 3, VT, 3, sup);
    if (info) return sooc_seterr(SOOC_ENUMERIC, "alignment: SVD failed (info %d)", (int)info);
    if (!(S[1] > 1e-12 * (S[0] > 1 ? S[0] : 1)))
        return sooc_seterr(SOOC_EINVAL, "alignment: the positions are collinear or coincide");
    double UV[9];
    sooc_m3_mul(UV, U, VT);
    double d = sooc_m3_det(UV) < 0 ? -1 : 1;
    double Ud[9];
    memcpy(Ud, U, sizeof Ud);
    for (int r = 0; r < 3; r++) Ud[3 * r + 2] *= d;
    double R[9], Rca[3], t[3];
    sooc_m3_mul(R, Ud, VT);
    sooc_m3_mulv(Rca, R, ca);
    for (int k = 0; k < 3; k++) t[k] = cb[k] - Rca[k];
    sooc_se3_from_rt(T, R, t);
    return SOOC_OK;
}

/* index in gt (sorted) of the timestamp nearest t, or -1 if farther than max_dt */
static int64_t nearest(const sooc_traj *gt, double t, double max_dt) {
    int64_t lo = 0, hi = gt->n;
    while (lo < hi) {
        int64_t m = (lo + hi) / 2;
        if (gt->t[m] < t) lo = m + 1;
        else hi = m;
    }
    int64_t best = -1;
    double bd = max_dt;
    for (int64_t k = lo - 1; k <= lo; k++)
        if (k >= 0 && k < gt->n && fabs(gt->t[k] - t) <= bd) {
            bd = fabs(gt->t[k] - t);
            best = k;
        }
    return best;
}

static double angle_deg(const double T[16]) {
    double c = (T[0] + T[5] + T[10] - 1) * 0.5;
    c = c > 1 ? 1 : (c < -1 ? -1 : c);
    return acos(c) * 180.0 / M_PI;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

sooc_status sooc_traj_evaluate(const sooc_traj *est, const sooc_traj *gt, double max_dt, double delta_s,
                               int delta_frames, sooc_traj_metrics *out) {
    memset(out, 0, sizeof *out);
    if (!(delta_s > 0) && delta_frames <= 0)
        return sooc_seterr(SOOC_EINVAL, "RPE: delta must be > 0 seconds or >= 1 frame");
    for (int64_t i = 1; i < gt->n; i++)
        if (gt->t[i] <= gt->t[i - 1])
            return sooc_seterr(SOOC_EINVAL, "ground truth: timestamps not increasing at pose %lld", (long long)i);
    int64_t *ie = sooc_malloc((size_t)(est->n + 1) * sizeof(int64_t));
    int64_t *ig = sooc_malloc((size_t)(est->n + 1) * sizeof(int64_t));
    double *pa = sooc_malloc((size_t)(est->n + 1) * 3 * sizeof(double));
    double *pb = sooc_malloc((size_t)(est->n + 1) * 3 * sizeof(double));
    double *err = sooc_malloc((size_t)(est->n + 1) * sizeof(double));
    sooc_status st = SOOC_OK;
    if (!ie || !ig || !pa || !pb || !err) {
        st = sooc_seterr(SOOC_ENOMEM, "trajectory metrics: out of memory");
        goto out;
    }
    int64_t m = 0;
    for (int64_t i = 0; i < est->n; i++) {
        int64_t g = nearest(gt, est->t[i], max_dt);
        if (g < 0) continue;
        ie[m] = i;
        ig[m] = g;
        for (int k = 0; k < 3; k++) {
            pa[3 * m + k] = est->T[16 * i + 4 * k + 3];
            pb[3 * m + k] = gt->T[16 * g + 4 * k + 3];
        }
        m++;
    }
    if (m < 3) {
        st = sooc_seterr(SOOC_EINVAL, "trajectory metrics: only %lld poses associate within %.3f s (need 3)",
                         (long long)m, max_dt);
        goto out;
    }
    out->pairs = m;
    if ((st = sooc_align_rigid(pa, pb, m, out->T_align))) goto out;
    double s2 = 0, s1 = 0, mx = 0;
    for (int64_t k = 0; k < m; k++) {
        double q[3];
        sooc_se3_apply(q, out->T_align, pa + 3 * k);
        double dx = q[0] - pb[3 * k], dy = q[1] - pb[3 * k + 1], dz = q[2] - pb[3 * k + 2];
        double e = sqrt(dx * dx + dy * dy + dz * dz);
        err[k] = e;
        s2 += e * e;
        s1 += e;
        if (e > mx) mx = e;
    }
    out->ate_rmse = sqrt(s2 / (double)m);
    out->ate_mean = s1 / (double)m;
    out->ate_max = mx;
    qsort(err, (size_t)m, sizeof(double), cmp_double);
    out->ate_median = (m & 1) ? err[m / 2] : 0.5 * (err[m / 2 - 1] + err[m / 2]);

    /* RPE over the associated pairs */
    double t2 = 0, t1 = 0, r2 = 0, r1 = 0;
    int64_t np = 0;
    for (int64_t k = 0; k < m; k++) {
        int64_t k2;
        if (delta_s > 0) {
            k2 = k + 1;
            while (k2 < m && est->t[ie[k2]] - est->t[ie[k]] < delta_s) k2++;
            if (k2 >= m) break;
            /* the nearer of k2 - 1 and k2 to the delta */
            if (k2 - 1 > k && fabs(est->t[ie[k2 - 1]] - est->t[ie[k]] - delta_s) <
                                  fabs(est->t[ie[k2]] - est->t[ie[k]] - delta_s))
                k2--;
        } else {
            k2 = k + delta_frames;
            if (k2 >= m) break;
        }
        double Pi[16], Qi[16], dP[16], dQ[16], dQi[16], E[16];
        sooc_se3_inverse(Pi, est->T + 16 * ie[k]);
        sooc_se3_mul(dP, Pi, est->T + 16 * ie[k2]);
        sooc_se3_inverse(Qi, gt->T + 16 * ig[k]);
        sooc_se3_mul(dQ, Qi, gt->T + 16 * ig[k2]);
        sooc_se3_inverse(dQi, dQ);
        sooc_se3_mul(E, dQi, dP);
        double te = sqrt(E[3] * E[3] + E[7] * E[7] + E[11] * E[11]), re = angle_deg(E);
        t2 += te * te;
        t1 += te;
        r2 += re * re;
        r1 += re;
        np++;
    }
    out->rpe_delta = delta_s > 0 ? delta_s : (double)delta_frames;
    out->rpe_pairs = np;
    if (np) {
        out->rpe_trans_rmse = sqrt(t2 / (double)np);
        out->rpe_trans_mean = t1 / (double)np;
        out->rpe_rot_rmse_deg = sqrt(r2 / (double)np);
        out->rpe_rot_mean_deg = r1 / (double)np;
    }
out:
    sooc_free(ie);
    sooc_free(ig);
    sooc_free(pa);
    sooc_free(pb);
    sooc_free(err);
    return st;
}
