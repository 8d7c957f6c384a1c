/* Map entries follow the keyframes that made them when the pose graph moves
 * them (include/sooc3d/slam.h "moving what was mapped"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sooc3d/core.h"
#include "slam/slam_impl.h"

size_t sooc_slam_move_entries(const sooc_slam_kf_change *chg, size_t n_chg, const double T_world_src[16],
                              int64_t max_gap_ns, sooc_map_entry *e, size_t n) {
    if (!n_chg) return 0;
    double Winv[16];
    sooc_se3_inverse(Winv, T_world_src);
    size_t moved = 0, cached = (size_t)-1;
    double C[16];
    for (size_t i = 0; i < n; i++) {
        int64_t t = e[i].last_seen_ns;
        if (t < chg[0].t_ns - max_gap_ns || t > chg[n_chg - 1].t_ns + max_gap_ns) continue;
        /* the keyframe nearest in time (binary search) */
        size_t lo = 0, hi = n_chg;
        while (hi - lo > 1) {
            size_t mid = (lo + hi) / 2;
            if (chg[mid].t_ns <= t) lo = mid;
            else hi = mid;
        }
        size_t k = lo;
        if (lo + 1 < n_chg && llabs(chg[lo + 1].t_ns - t) < llabs(t - chg[lo].t_ns)) k = lo + 1;
        if (k != cached) {   /* C = W T_after T_before^-1 W^-1 */
            double inv[16], A[16], B[16];
            sooc_se3_inverse(inv, chg[k].T_before);
            sooc_se3_mul(A, chg[k].T_after, inv);
            sooc_se3_mul(B, T_world_src, A);
            sooc_se3_mul(C, B, Winv);
            cached = k;
        }
        sooc_map_entry *m = &e[i];
        double p[3] = {m->x, m->geom.centre[1], m->z}, q[3];
        sooc_se3_apply(q, C, p);
        m->x = q[0];
        m->z = q[2];
        double dyaw = atan2(C[2], C[0]);   /* rotation about +y: R = rot_y(dyaw) */
        m->yaw += dyaw;
        double c = cos(dyaw), s = sin(dyaw);
        if (m->geom.reg_n) {
            double r[3] = {m->geom.reg_mean[0], m->geom.centre[1], m->geom.reg_mean[1]}, rq[3];
            sooc_se3_apply(rq, C, r);
            m->geom.reg_mean[0] = rq[0];
            m->geom.reg_mean[1] = rq[2];
        }
        /* cov' = R cov R^T with R the 2x2 rotation of (x, z) by rot_y: x' = c x + s z, z' = -s x + c z */
        double xx = m->geom.cov_xz[0], xz = m->geom.cov_xz[1], zz = m->geom.cov_xz[2];
        m->geom.cov_xz[0] = c * c * xx + 2 * c * s * xz + s * s * zz;
        m->geom.cov_xz[1] = -c * s * xx + (c * c - s * s) * xz + c * s * zz;
        m->geom.cov_xz[2] = s * s * xx - 2 * c * s * xz + c * c * zz;
        moved++;
    }
    return moved;
}
