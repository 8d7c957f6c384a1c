/* Geometry of table records for planners (table.h): a record's pose in the
 * pose source's frame (sooc_table_pose_source) and which record's box a
 * camera pixel sees (sooc_table_pick). Pure functions of their arguments. */
#include "sooc3d/table.h"

#include <math.h>

void sooc_table_pose_source(const double T_src_map[16], const sooc_table_record *r, double p_src[3], double R_src[9],
                            double cov_src[9]) {
    const double *T = T_src_map;
    const double m[3] = {r->x, r->y, r->z};
    for (int i = 0; i < 3; i++) p_src[i] = T[4 * i] * m[0] + T[4 * i + 1] * m[1] + T[4 * i + 2] * m[2] + T[4 * i + 3];
    const double c = cos((double)r->yaw), s = sin((double)r->yaw);
    const double Ry[9] = {c, 0, s, 0, 1, 0, -s, 0, c};   /* R_y(yaw) */
    if (R_src)
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                R_src[3 * i + j] = T[4 * i] * Ry[j] + T[4 * i + 1] * Ry[3 + j] + T[4 * i + 2] * Ry[6 + j];
    if (cov_src) {
        const float *k = r->cov_xzyaw;   /* xx xz xyaw zz zyaw yawyaw */
        const double C[9] = {k[0], 0, k[1], 0, 0, 0, k[1], 0, k[3]};
        double RC[9];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                RC[3 * i + j] = T[4 * i] * C[j] + T[4 * i + 1] * C[3 + j] + T[4 * i + 2] * C[6 + j];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                cov_src[3 * i + j] = RC[3 * i] * T[4 * j] + RC[3 * i + 1] * T[4 * j + 1] + RC[3 * i + 2] * T[4 * j + 2];
    }
}

int sooc_table_pick(const sooc_table_record *recs, uint32_t n, const double T_map_cam[16], double fx, double fy,
                    double cx, double cy, double u, double v, double *t_hit) {
    if (!recs || !T_map_cam || !(fx != 0) || !(fy != 0)) return -1;
    const double *T = T_map_cam;
    const double dc[3] = {(u - cx) / fx, (v - cy) / fy, 1.0};
    double o[3] = {T[3], T[7], T[11]}, d[3];
    for (int i = 0; i < 3; i++) d[i] = T[4 * i] * dc[0] + T[4 * i + 1] * dc[1] + T[4 * i + 2] * dc[2];
    int best = -1;
    double bt = INFINITY;
    for (uint32_t k = 0; k < n; k++) {
        const sooc_table_record *r = &recs[k];
        if (!r->object_id || !(r->flags & SOOC_TABLE_FLAG_VALID) || (r->flags & SOOC_TABLE_FLAG_REMOVED)) continue;
        /* the ray in the box's frame: R_y(yaw)^T (p - centre) */
        const double c = cos((double)r->yaw), s = sin((double)r->yaw);
        const double po[3] = {o[0] - r->x, o[1] - r->y, o[2] - r->z};
        const double ob[3] = {c * po[0] - s * po[2], po[1], s * po[0] + c * po[2]};
        const double db[3] = {c * d[0] - s * d[2], d[1], s * d[0] + c * d[2]};
        double t0 = 0, t1 = INFINITY;
        int miss = 0;
        for (int a = 0; a < 3 && !miss; a++) {
            double h = 0.5 * r->extent[a];
            if (fabs(db[a]) < 1e-15) {
                miss = fabs(ob[a]) > h;
                continue;
            }
            double ta = (-h - ob[a]) / db[a], tb = (h - ob[a]) / db[a];
            if (ta > tb) { double q = ta; ta = tb; tb = q; }
            if (ta > t0) t0 = ta;
            if (tb < t1) t1 = tb;
            miss = t0 > t1;
        }
        if (!miss && t0 < bt) bt = t0, best = (int)k;
    }
    if (best >= 0 && t_hit) *t_hit = bt;
    return best;
}
