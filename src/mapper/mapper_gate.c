/* The creation gate of the node's revisit rules (docs/cogmap.md "Revisits",
 * rule 5; include/sooc3d/mapper.h sooc_mapper_gate): on a keyframe's final
 * decode, a new slot creates an entry only where it explains observed rays
 * that the registered retrieved entries leave unexplained, and not when the
 * rays it claims lie inside the floor box of one of them (the far part of a
 * large object that the retrieved entry represents). */
#include "sooc3d/mapper.h"

#include <math.h>

int sooc_mapper_gate(const sooc_gate_input *in, double min_rays, double ratio, double part_frac,
                       sooc_gate_verdict *out) {
    const int K = in->n_slots;
    if (K <= 0) return 0;
    SOOC_ASSERT(K <= SOOC_MAPPER_CHANGED_MAX);
    const int NB = in->n_boxes > 0 ? in->n_boxes : 0, NC = K + NB;   /* part candidates: slots, then boxes */
    SOOC_ASSERT(NB <= SOOC_GATE_MAX_BOXES);
    enum { MAXC = SOOC_MAPPER_CHANGED_MAX + SOOC_GATE_MAX_BOXES };
    int known[MAXC], nk = 0, any_new = 0;
    double cs[MAXC], sn[MAXC], px[MAXC], pz[MAXC];
    int inbox[SOOC_MAPPER_CHANGED_MAX][MAXC];   /* [new slot][candidate] owned points in its box */
    float rsum[SOOC_MAPPER_CHANGED_MAX][MAXC];  /* sum of min(1, known / new density) there (slots) */
    for (int k = 0; k < K; k++) {
        sooc_gate_verdict *v = &out[k];
        v->owned = v->alone = 0;
        v->part = -1;
        v->part_share = v->part_ratio = 0.0f;
        v->create = 1;
        v->reason = SOOC_GATE_NOT_NEW;
        const float *ps = in->pose + (size_t)k * in->pose_stride;
        cs[k] = cos(ps[2]);
        sn[k] = sin(ps[2]);
        px[k] = ps[0];
        pz[k] = ps[1];
        if (in->role[k] == SOOC_GATE_KNOWN) known[nk++] = k;
        if (in->role[k] == SOOC_GATE_NEW) any_new = 1;
        for (int j = 0; j < NC; j++) inbox[k][j] = 0, rsum[k][j] = 0.0f;
    }
    for (int b = 0; b < NB; b++) {   /* map entries that are not slots: box test only */
        const float *pb = in->boxes + (size_t)b * in->box_stride;
        cs[K + b] = cos(pb[2]);
        sn[K + b] = sin(pb[2]);
        px[K + b] = pb[0];
        pz[K + b] = pb[1];
        known[nk++] = K + b;
    }
    if (!any_new) return 0;
    const double rh = in->box_rh;
    for (int r = 0; r < in->n_rays; r++) {
        if (!in->surf[r]) continue;
        const float *d = in->dens + (size_t)r * in->dens_stride;
        int best = 0;
        for (int c = 1; c <= K; c++)
            if (d[c] > d[best]) best = c;
        int k = best - 1;
        if (k < 0 || in->role[k] != SOOC_GATE_NEW || !(d[best] > 0)) continue;
        out[k].owned++;
        int alone = 1;
        const float *p = in->pts + (size_t)r * in->pts_stride;
        for (int a = 0; a < nk; a++) {
            int j = known[a];
            if (j < K && d[1 + j] >= ratio * d[best]) alone = 0;
            double vx = p[0] - px[j], vz = p[2] - pz[j];
            double xl = cs[j] * vx - sn[j] * vz, zl = sn[j] * vx + cs[j] * vz;
            if (fabs(xl) <= rh && fabs(zl) <= rh) {
                inbox[k][j]++;
                if (j < K) rsum[k][j] += d[1 + j] < d[best] ? d[1 + j] / d[best] : 1.0f;
            }
        }
        out[k].alone += alone;
    }
    int refused = 0;
    for (int k = 0; k < K; k++) {
        if (in->role[k] != SOOC_GATE_NEW) continue;
        sooc_gate_verdict *v = &out[k];
        for (int a = 0; a < nk; a++) {
            int j = known[a];
            if (inbox[k][j] > 0 && (v->part < 0 || inbox[k][j] > inbox[k][v->part])) v->part = j;
        }
        if (v->part >= 0 && v->owned > 0) {
            v->part_share = (float)inbox[k][v->part] / (float)v->owned;
            v->part_ratio = rsum[k][v->part] / (float)inbox[k][v->part];
        }
        if (min_rays >= 0 && v->alone < min_rays * in->n_rays) v->reason = SOOC_GATE_FEW_RAYS;
        else if (part_frac >= 0 && v->part >= 0 && v->part_share >= part_frac) v->reason = SOOC_GATE_PART_OF;
        else v->reason = SOOC_GATE_CREATED;
        v->create = v->reason == SOOC_GATE_CREATED;
        refused += !v->create;
    }
    return refused;
}
