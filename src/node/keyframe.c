/* Keyframe policy (translation / rotation / time thresholds) and a latency
 * window with percentiles. */
#include "sooc3d/node.h"
#include "node/node_parts.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void sooc_kf_policy_init(sooc_kf_policy *p, double translation_m, double rotation_deg, double time_s) {
    memset(p, 0, sizeof *p);
    p->translation_m = translation_m;
    p->rotation_deg = rotation_deg;
    p->time_s = time_s;
}

double sooc_pose_angle_deg(const double A[16], const double B[16]) {
    /* angle of R_A^T R_B from its trace */
    double tr = 0;
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) tr += A[4 * k + i] * B[4 * k + i];
    double c = 0.5 * (tr - 1.0);
    if (c > 1) c = 1;
    if (c < -1) c = -1;
    return acos(c) * 180.0 / 3.14159265358979323846;
}

int sooc_kf_policy_check(const sooc_kf_policy *p, const double T_wc[16], int64_t t_ns) {
    if (!p->have_last) return 1;
    if (p->translation_m > 0) {
        double dx = T_wc[3] - p->T_last[3], dy = T_wc[7] - p->T_last[7], dz = T_wc[11] - p->T_last[11];
        if (sqrt(dx * dx + dy * dy + dz * dz) >= p->translation_m) return 1;
    }
    if (p->rotation_deg > 0 && sooc_pose_angle_deg(p->T_last, T_wc) >= p->rotation_deg) return 1;
    if (p->time_s > 0 && (double)(t_ns - p->t_last_ns) * 1e-9 >= p->time_s) return 1;
    return 0;
}

void sooc_kf_policy_accept(sooc_kf_policy *p, const double T_wc[16], int64_t t_ns) {
    p->have_last = 1;
    memcpy(p->T_last, T_wc, sizeof p->T_last);
    p->t_last_ns = t_ns;
}

void sooc_latency_add(sooc_latency *l, double ms) {
    l->v[l->n % SOOC_LAT_WINDOW] = ms;
    l->n++;
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

double sooc_latency_pct(const sooc_latency *l, double q) {
    size_t m = l->n < SOOC_LAT_WINDOW ? (size_t)l->n : SOOC_LAT_WINDOW;
    if (!m) return 0;
    double *tmp = sooc_malloc(m * sizeof *tmp);
    if (!tmp) return 0;
    memcpy(tmp, l->v, m * sizeof *tmp);
    qsort(tmp, m, sizeof *tmp, cmp_d);
    if (q < 0) q = 0;
    if (q > 1) q = 1;
    size_t k = (size_t)ceil(q * (double)m);
    if (k < 1) k = 1;
    double r = tmp[k - 1];
    sooc_free(tmp);
    return r;
}
