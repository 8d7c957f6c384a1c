/* The creation gate of the node's revisit rules (sooc_mapper_gate,
 * docs/cogmap.md "Revisits", rule 5), on crafted decodes: rays whose surface
 * points lie on objects seen from a camera at the floor-frame origin, with
 * per-slot densities written by hand.
 * - a large sphere (radius 0.37 m) that a retrieved slot represents, whose far
 *   half a spare prior slot claims 0.5 m away: no new entry (part of it);
 * - a genuinely new object 1.1 m beside a known one: a new entry;
 * - a present new slot that owns no ray: no new entry (too few rays);
 * - the box test follows the decoder's frame (mdl_pi_cs) at any yaw;
 * - map-entry boxes: an unretrieved entry's, and a settled entry's stored box
 *   when its slot wandered off in the refinement. */
#include "check.h"
#include "model/step.h"
#include "sooc3d/mapper.h"

#include <math.h>
#include <string.h>

#define NR 1024
#define K 4
#define C (K + 1)
#define RH 0.6

static float dens[NR * C], pts[NR * 3], pose[K * 3], boxes[4 * 3];
static int n_boxes;   /* map-entry boxes (not slots) of the part test */
static uint8_t surf[NR];
static int role[K];

static void reset(void) {
    memset(dens, 0, sizeof dens);
    memset(pts, 0, sizeof pts);
    memset(surf, 0, sizeof surf);
    memset(pose, 0, sizeof pose);
    for (int k = 0; k < K; k++) role[k] = SOOC_GATE_OFF;
    n_boxes = 0;
    for (int r = 0; r < NR; r++) {   /* every ray sees the floor first (the layout's) */
        surf[r] = 1;
        pts[r * 3 + 0] = (float)((r % 32) * 0.1 - 1.6);
        pts[r * 3 + 1] = -1.5f;
        pts[r * 3 + 2] = (float)(1.0 + (r / 32) * 0.1);
        dens[r * C] = 1.0f;
    }
}

static void set_pose(int k, double x, double z, double yaw) {
    pose[k * 3 + 0] = (float)x;
    pose[k * 3 + 1] = (float)z;
    pose[k * 3 + 2] = (float)yaw;
}

/* n rays starting at ray r0 hit a point of the circle of radius rad around
 * (cx, cz) at angles a0..a1; comp c gets density dc there, comp c2 gets d2 */
static void hit(int r0, int n, double cx, double cz, double rad, double a0, double a1, int c, float dc, int c2,
                float d2) {
    for (int i = 0; i < n; i++) {
        int r = r0 + i;
        double a = a0 + (a1 - a0) * (i + 0.5) / n;
        pts[r * 3 + 0] = (float)(cx + rad * cos(a));
        pts[r * 3 + 1] = -1.2f;
        pts[r * 3 + 2] = (float)(cz + rad * sin(a));
        dens[r * C] = 0.01f;
        dens[r * C + c] = dc;
        if (c2 >= 0) dens[r * C + c2] = d2;
    }
}

static int run(sooc_gate_verdict *v, double min_rays, double ratio, double part) {
    sooc_gate_input in = {NR, K, dens, C, pts, 3, surf, pose, 3, role, RH, n_boxes, boxes, 3};
    return sooc_mapper_gate(&in, min_rays, ratio, part, v);
}

int main(void) {
    sooc_gate_verdict v[K];

    /* 1. A large sphere centred at (0, 4) (radius 0.37 m): slot 0 (retrieved,
     * registered) sits at its centre and explains the near half; slot 1 (a
     * spare prior) sits 0.5 m away, behind and to the side, and has the largest
     * density on the other half of the visible surface, where slot 0's density
     * is a tenth of its own. */
    reset();
    role[0] = SOOC_GATE_KNOWN;
    role[1] = SOOC_GATE_NEW;
    set_pose(0, 0.0, 4.0, 0.3);
    set_pose(1, 0.35, 4.35, -0.4);
    hit(0, 60, 0.0, 4.0, 0.37, -M_PI, -M_PI / 2, 1, 1.0f, 2, 0.2f);        /* the near-left quarter: slot 0's */
    hit(60, 60, 0.0, 4.0, 0.37, -M_PI / 2, 0.0, 2, 1.0f, 1, 0.1f);         /* the near-right quarter: slot 1's */
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 1);
    CHECK(v[0].reason == SOOC_GATE_NOT_NEW && v[0].create == 1);
    CHECK_MSG(v[1].owned == 60 && v[1].alone == 60, "owned %d alone %d", v[1].owned, v[1].alone);
    CHECK_MSG(v[1].part == 0 && v[1].part_share == 1.0f, "part %d share %g", v[1].part, (double)v[1].part_share);
    CHECK_CLOSE(v[1].part_ratio, 0.1, 1e-6, 0);
    CHECK(v[1].create == 0 && v[1].reason == SOOC_GATE_PART_OF);
    /* without the fold-in it owns enough rays on its own: created */
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, -1) == 0);
    CHECK(v[1].create == 1 && v[1].reason == SOOC_GATE_CREATED);
    /* where slot 0 explains the rays nearly as well (0.6 of the new slot's
     * density), they are not the new slot's own: too few rays */
    for (int r = 60; r < 120; r++) dens[r * C + 1] = 0.6f;
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, -1) == 1);
    CHECK_MSG(v[1].alone == 0 && v[1].reason == SOOC_GATE_FEW_RAYS, "alone %d reason %d", v[1].alone, v[1].reason);

    /* 2. A genuinely new object beside a known one: slot 0 (known) at (0, 4),
     * a small box-like object (radius 0.2 m) at (1.1, 4.0) that slot 2 (new)
     * explains: its surface points lie 0.9-1.3 m from slot 0, outside its box
     * (half side 0.6 m), and slot 0's density there is nil. */
    reset();
    role[0] = SOOC_GATE_KNOWN;
    role[2] = SOOC_GATE_NEW;
    set_pose(0, 0.0, 4.0, 0.0);
    set_pose(2, 1.1, 4.0, 0.7);
    hit(0, 80, 0.0, 4.0, 0.3, -M_PI, 0.0, 1, 1.0f, -1, 0.0f);
    hit(80, 40, 1.1, 4.0, 0.2, -M_PI, 0.0, 3, 0.8f, -1, 0.0f);
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 0);
    CHECK_MSG(v[2].owned == 40 && v[2].alone == 40, "owned %d alone %d", v[2].owned, v[2].alone);
    CHECK_MSG(v[2].part == -1 && v[2].part_share == 0.0f, "part %d share %g", v[2].part, (double)v[2].part_share);
    CHECK(v[2].create == 1 && v[2].reason == SOOC_GATE_CREATED);
    /* the same object 0.75 m away: about a quarter of its visible points (x <= 0.6) lie in slot 0's box */
    reset();
    role[0] = SOOC_GATE_KNOWN;
    role[2] = SOOC_GATE_NEW;
    set_pose(0, 0.0, 4.0, 0.0);
    set_pose(2, 0.75, 4.0, 0.0);
    hit(0, 80, 0.0, 4.0, 0.3, -M_PI, 0.0, 1, 1.0f, -1, 0.0f);
    hit(80, 40, 0.75, 4.0, 0.2, -M_PI, 0.0, 3, 0.8f, -1, 0.0f);
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 0);
    CHECK_MSG(v[2].part == 0 && v[2].part_share > 0.2f && v[2].part_share < 0.5f, "part %d share %g", v[2].part,
              (double)v[2].part_share);
    CHECK(v[2].create == 1);

    /* 3. A present new slot that owns no ray (all of them are the floor's or
     * the known object's): no new entry; with the minimum off it is created. */
    reset();
    role[0] = SOOC_GATE_KNOWN;
    role[3] = SOOC_GATE_NEW;
    set_pose(0, 0.0, 4.0, 0.0);
    set_pose(3, -2.0, 6.0, 0.0);
    hit(0, 80, 0.0, 4.0, 0.3, -M_PI, 0.0, 1, 1.0f, 4, 0.5f);
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 1);
    CHECK(v[3].owned == 0 && v[3].reason == SOOC_GATE_FEW_RAYS);
    CHECK(run(v, -1, SOOC_GATE_RATIO, SOOC_GATE_PART) == 0 && v[3].create == 1);
    /* 10 own rays of 1024 is under 1% (10.24): refused; 11 pass */
    hit(100, 10, -2.0, 6.0, 0.2, -M_PI, 0.0, 4, 1.0f, -1, 0.0f);
    CHECK(run(v, 0.01, SOOC_GATE_RATIO, SOOC_GATE_PART) == 1 && v[3].alone == 10);
    hit(100, 11, -2.0, 6.0, 0.2, -M_PI, 0.0, 4, 1.0f, -1, 0.0f);
    CHECK(run(v, 0.01, SOOC_GATE_RATIO, SOOC_GATE_PART) == 0 && v[3].alone == 11);
    /* no new slot: nothing refused, every verdict "not new" */
    role[3] = SOOC_GATE_OFF;
    CHECK(run(v, 0.01, SOOC_GATE_RATIO, SOOC_GATE_PART) == 0);
    for (int k = 0; k < K; k++) CHECK(v[k].create == 1 && v[k].reason == SOOC_GATE_NOT_NEW);

    /* 4. The floor box follows the decoder's object frame (mdl_pi_cs and its
     * box test) at any yaw: points around a known slot at yaw 0.8 rad, each
     * owned by the new slot; a point is counted in the box exactly when the
     * decoder's frame puts it inside |x'|, |z'| <= R_h. */
    reset();
    role[0] = SOOC_GATE_KNOWN;
    role[1] = SOOC_GATE_NEW;
    set_pose(0, 0.3, 3.0, 0.8);
    set_pose(1, 0.3, 3.0, 0.0);
    int want = 0;
    for (int r = 0; r < 400; r++) {
        float x = (float)(0.3 + 1.6 * (((r * 37) % 400) / 400.0 - 0.5));
        float z = (float)(3.0 + 1.6 * (((r * 91 + 7) % 400) / 400.0 - 0.5));
        pts[r * 3 + 0] = x;
        pts[r * 3 + 1] = -1.2f;
        pts[r * 3 + 2] = z;
        dens[r * C] = 0.0f;
        dens[r * C + 2] = 1.0f;
        float xk[3];
        mdl_pi_cs(pts + r * 3, pose[0], pose[1], cosf(pose[2]), sinf(pose[2]), 1.5f, xk);
        want += fabsf(xk[0]) <= RH && fabsf(xk[2]) <= RH;
    }
    run(v, -1, SOOC_GATE_RATIO, 2.0);
    CHECK_MSG(v[1].part == 0 && v[1].owned == 400, "part %d owned %d", v[1].part, v[1].owned);
    CHECK_MSG(fabs(v[1].part_share * 400.0 - want) < 1.5, "in box %g, decoder frame %d", v[1].part_share * 400.0,
              want);
    CHECK(want > 150 && want < 350);

    /* 5. Map entries the keyframe did not retrieve (no slot) join the part
     * test as boxes: case 1's sphere with its entry not among the slots (its
     * centre just outside the view): the new slot's points lie in that
     * entry's box -> part of it (candidate K + 0, no density ratio); a box
     * 3 m away is not chosen; with no box the slot is created. */
    reset();
    role[1] = SOOC_GATE_NEW;
    set_pose(1, 0.35, 4.35, -0.4);
    hit(60, 60, 0.0, 4.0, 0.37, -M_PI / 2, 0.0, 2, 1.0f, -1, 0.0f);
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 0 && v[1].create == 1);
    boxes[0] = 3.0f, boxes[1] = 4.0f, boxes[2] = 0.0f;   /* far */
    boxes[3] = 0.0f, boxes[4] = 4.0f, boxes[5] = 0.3f;   /* the sphere's entry */
    n_boxes = 2;
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 1);
    CHECK_MSG(v[1].part == K + 1 && v[1].part_share == 1.0f && v[1].part_ratio == 0.0f, "part %d share %g ratio %g",
              v[1].part, (double)v[1].part_share, (double)v[1].part_ratio);
    CHECK_MSG(v[1].alone == 60, "a box has no density: alone %d", v[1].alone);
    CHECK(v[1].create == 0 && v[1].reason == SOOC_GATE_PART_OF);
    n_boxes = 1;   /* only the far one */
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 0 && v[1].part == -1);

    /* 6. A settled retrieved entry whose slot wandered in this keyframe's
     * refinement (the looped replay of docs/cogmap.md "Drift": the sphere's
     * slot 0.83 m off, its box no longer holding the sphere). Registration
     * damps a settled entry, so it stays at its stored pose; the mapper passes
     * that pose as a box. With the wandered slot alone the spare slot on the
     * sphere is created (a copy); with the stored box it is part of it. */
    reset();
    role[0] = SOOC_GATE_KNOWN;
    role[1] = SOOC_GATE_NEW;
    set_pose(0, -0.75, 4.35, 0.3);   /* the wandered slot */
    set_pose(1, 0.35, 4.35, -0.4);
    hit(0, 60, 0.0, 4.0, 0.37, -M_PI, -M_PI / 2, 1, 1.0f, 2, 0.2f);
    hit(60, 60, 0.0, 4.0, 0.37, -M_PI / 2, 0.0, 2, 1.0f, 1, 0.1f);
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 0);
    CHECK_MSG(v[1].create == 1 && v[1].part_share < SOOC_GATE_PART, "share %g", (double)v[1].part_share);
    boxes[0] = 0.0f, boxes[1] = 4.0f, boxes[2] = 0.3f;   /* the entry as stored */
    n_boxes = 1;
    CHECK(run(v, SOOC_GATE_MIN_RAYS, SOOC_GATE_RATIO, SOOC_GATE_PART) == 1);
    CHECK_MSG(v[1].part == K && v[1].part_share == 1.0f, "part %d share %g", v[1].part, (double)v[1].part_share);
    CHECK(v[1].create == 0 && v[1].reason == SOOC_GATE_PART_OF);
    return check_report("test_mapper_gate");
}
