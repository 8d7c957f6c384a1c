/* The online mapper (include/sooc3d/mapper.h): one amortised variational
 * update per keyframe on top of the cognitive map: query in-view entries,
 * pad to K with the slot priors, refine L times, register the present slots. */
#include "sooc3d/mapper.h"

#include <math.h>
#include <string.h>
#include <stdio.h>

#include "mapper/mapper_geo.h"
#include "model/propose.h"
#include "model/step.h"
#include "sooc3d/model.h"

#define MAPPER_TAU 0.7f
#define MAPPER_FREE_SLOTS 1024   /* free-space evidence cache (ids are sequential: no collision below 1024 apart) */   /* the trainer's final relaxed-Bernoulli temperature (docs/training.md "Schedule") */

/* The change set holds every slot of an update: arrays of SOOC_MAPPER_CHANGED_MAX
 * must fit the largest K a model (or a widened slot setting) can have. */
_Static_assert(SOOC_MAPPER_CHANGED_MAX >= SOOC_MODEL_K_MAX, "SOOC_MAPPER_CHANGED_MAX below SOOC_MODEL_K_MAX");
_Static_assert(SOOC_MODEL_D_MAX <= SOOC_COGMAP_DIM_MAX, "λ rows of the same-pose copy");

struct sooc_mapper {
    sooc_model *m;
    sooc_model_ws *ws;   /* the mapper runs the model: its workspace (decoder, refinement, step state, pool) */
    sooc_cogmap *map;
    sooc_view_rec V;
    int L, view_idx;
    double merge_r;   /* sooc_mapper_params.merge_radius, resolved (0 = off) */
    int merge_nb;     /* sooc_mapper_params.merge_neighbours */
    double same_r;    /* same-pose radius in m, resolved (0 = off) */
    int sample;       /* 1 = SOOC_LATENTS_SAMPLE */
    sooc_rng rng;
    /* what the last update changed (sooc_mapper_changed / _last_layout) */
    uint64_t chg_ids[SOOC_MODEL_K_MAX], rem_ids[SOOC_MODEL_K_MAX];
    /* the final λ and source ids after the same-pose rule (registered from here) */
    float lam_reg[SOOC_MODEL_K_MAX * SOOC_LAM_MAX];
    uint64_t src_reg[SOOC_MODEL_K_MAX];
    int n_chg, n_rem, has_block;
    int32_t bi, bj;
    /* free-space evidence of the revisit rules (retire_free): consecutive
     * keyframes whose depth showed an entry's place as free, a direct-mapped
     * cache by id (a collision forgets evidence: conservative) */
    uint64_t free_id[MAPPER_FREE_SLOTS];
    uint16_t free_run[MAPPER_FREE_SLOTS];
    uint16_t unsup_run[MAPPER_FREE_SLOTS];   /* registrations since the depth last showed a surface there */
    sooc_objgeom_cache *geo;   /* object geometry for planners (mapper.h) */
    int geo_budget;            /* tight boxes recomputed per update */
    /* the creation gate (revisit rule 5, mapper_gate.c): resolved parameters
     * (< 0 = that test off), the final decode's λ and zero noise */
    double gate_min, gate_ratio, gate_part;
    float lam_gate[SOOC_MODEL_K_MAX * SOOC_LAM_MAX];
    sooc_dec_noise gate_noise;
    float gate_boxes[SOOC_GATE_MAX_BOXES * 3];   /* nearby map entries' floor boxes (G frame) */
    uint64_t gate_box_ids[SOOC_GATE_MAX_BOXES];  /* their entry ids (the debug log) */
    sooc_mdl_geo *gm;               /* kind geometric (mapper_geo.c): the cluster map instead of the model */
    sooc_cluster_map *prop;    /* geometric proposals (propose.c): the keyframe's clusters; NULL = off */
    sooc_mdl_prop_params prop_p;
    /* geometric support (sooc_mapper_set_support): the clusters of every
     * mapped keyframe; NULL = off */
    sooc_cluster_map *supp;
    double supp_margin;
    sooc_cluster_object *supp_obj;
    int supp_cap;
    int surf_boxes;   /* observed-surface boxes (sooc_mapper_set_surface_boxes) */
};

void sooc_mapper_params_default(sooc_mapper_params *p) {
    memset(p, 0, sizeof *p);
    p->model_path = "models/default/model.bin";
    p->seed = 1;
    sooc_cluster_params_default(&p->cluster);
    p->input_width = 160, p->input_height = 120;
}

static sooc_status sooc_mdl_mapper_create_from(sooc_mapper **out, sooc_model *m, int iterations, uint64_t seed, int threads);

static sooc_status sooc_mdl_mapper_create_from(sooc_mapper **out, sooc_model *m, int iterations, uint64_t seed, int threads) {
    *out = NULL;
    sooc_mapper *mp = sooc_calloc(1, sizeof *mp);
    if (!mp) return SOOC_ENOMEM;
    mp->m = m;   /* calloc: merge off, latents mean (the defaults) */
    sooc_mapper_set_gate(mp, 0, 0, 0);
    const sooc_model_config *c = sooc_model_get_config(m);
    mp->L = iterations > 0 ? iterations : c->L;
    mp->same_r = SOOC_MAPPER_SAME_POSE_FRAC * 2.0 * c->box_rh * c->unit_m;   /* metres */
    if (mp->L > 16) mp->L = 16;
    sooc_model_set_threads(m, threads);
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = c->d_what;
    cp.layout_dim = c->d_layout;
    cp.block_size = (double)c->block_size * c->unit_m;   /* the map is in metres */
    sooc_status st = sooc_cogmap_create(&mp->map, &cp);
    if (!st) st = sooc_objgeom_cache_create(&mp->geo);
    mp->geo_budget = SOOC_OBJGEOM_BUDGET;
    if (!st) st = sooc_mdl_view_alloc(m, &mp->V, mp->L);
    if (!st) st = sooc_model_ws_create(&mp->ws, m);
    if (!st && !sooc_mdl_step_state(mp->ws, 1, mp->L)) st = sooc_seterr(SOOC_ENOMEM, "mapper: out of memory");
    if (st) {
        mp->m = NULL;
        sooc_mapper_destroy(mp);
        return st;
    }
    sooc_rng_seed(&mp->rng, seed, 0x6d6170ULL);
    *out = mp;
    return SOOC_OK;
}

sooc_status sooc_mapper_create(sooc_mapper **out, const sooc_mapper_params *p) {
    *out = NULL;
    if (p->kind == SOOC_MAPPER_GEOMETRIC) {
        sooc_mapper *mp = sooc_calloc(1, sizeof *mp);
        if (!mp) return sooc_seterr(SOOC_ENOMEM, "mapper: out of memory");
        sooc_status st = sooc_mdl_geo_create(&mp->gm, p);
        if (st) sooc_free(mp);
        else *out = mp;
        return st;
    }
    if (p->kind != SOOC_MAPPER_LEARNT) return sooc_seterr(SOOC_EINVAL, "mapper: unknown kind %d", p->kind);
    sooc_model *m;
    sooc_status st = sooc_model_load(&m, p->model_path, NULL, NULL);
    if (st) return sooc_adderr(st, "mapper");
    if ((p->d_clip > 0 && (st = sooc_model_set_clip(m, (float)p->d_clip))) ||
        (p->invalid_depth > 0 && (st = sooc_model_set_invalid_depth(m, p->invalid_depth - 1)))) {
        sooc_model_destroy(m);
        return sooc_adderr(st, "mapper");
    }
    const sooc_model_config *mc = sooc_model_get_config(m);
    int slots = p->slots > 0 ? p->slots : mc->slots;   /* the caller's, else the model's inference setting */
    if (slots > 0 && slots != mc->K) {
        sooc_model *w;
        st = sooc_model_copy_slots(m, slots, &w);
        sooc_model_destroy(m);
        if (st) return sooc_adderr(st, "mapper: %s", p->model_path);
        m = w;
    }
    st = sooc_mdl_mapper_create_from(out, m, p->iterations, p->seed, p->threads);
    if (st) sooc_model_destroy(m);
    else {
        sooc_mapper_set_merge_radius(*out, p->merge_radius);
        sooc_mapper_set_merge_neighbours(*out, p->merge_neighbours);
        sooc_mapper_set_latents(*out, p->latents);
        sooc_mapper_set_gate(*out, p->gate_min_rays, p->gate_ratio, p->gate_part);
        if (p->same_pose != 0)
            (*out)->same_r = p->same_pose > 0 ? p->same_pose * 2.0 * sooc_model_get_config(m)->box_rh * sooc_model_get_config(m)->unit_m : 0.0;
    }
    return st;
}

void sooc_mapper_destroy(sooc_mapper *mp) {
    if (!mp) return;
    sooc_mdl_geo_destroy(mp->gm);
    sooc_cluster_map_destroy(mp->prop);
    sooc_cluster_map_destroy(mp->supp);
    sooc_free(mp->supp_obj);
    if (mp->V.buf) sooc_mdl_view_free(&mp->V);
    sooc_model_ws_destroy(mp->ws);
    sooc_cogmap_destroy(mp->map);
    sooc_objgeom_cache_destroy(mp->geo);
    sooc_model_destroy(mp->m);
    sooc_free(mp);
}

void sooc_mapper_input_size(const sooc_mapper *mp, int *w, int *h) {
    if (mp->gm) {
        sooc_mdl_geo_input_size(mp->gm, w, h);
        return;
    }
    const sooc_model_config *c = sooc_model_get_config(mp->m);
    *w = c->img_w;
    *h = c->img_h;
}

void sooc_mapper_cam_heights(const sooc_mapper *mp, double *lo_m, double *hi_m) {
    if (mp->gm) {   /* no trained range */
        *lo_m = *hi_m = 0;
        return;
    }
    sooc_model_cam_heights_m(sooc_model_get_config(mp->m), lo_m, hi_m);
}

/* The node's revisit rule (merge_neighbours; docs/cogmap.md "Revisits"): a
 * present slot whose refined centre left the keyframe's view is not evidence
 * of this view. A retrieved entry keeps its stored values (the slot is not
 * registered, the entry not removed: it stays bit-identical); a new slot is
 * dropped when its centre lies behind the camera or beyond the clip depth
 * (at the image edge it is kept: a partly seen object). Returns the count. */
static int hold_unseen(sooc_mapper *mp, const sooc_frame *f, const sooc_view_rec *V, int K, int d) {
    sooc_cogmap_camera cam;
    sooc_mdl_camera_of(mp->m, f, &cam);
    const int NL = SOOC_LAM_SIZE(d), PA = SOOC_LAM_PRES(d);
    int held = 0;
    for (int i = 0; i < K; i++) {
        float *lam = mp->lam_reg + (size_t)i * NL;
        if (!(lam[PA] >= 0.0f)) continue;
        sooc_cogmap_entry e;
        sooc_cogmap_lam_to_world(&V->gf, d, lam, &e);
        if (mp->src_reg[i]) {
            if (sooc_cogmap_in_view(&cam, &e)) continue;
        } else {
            const double *T = cam.T_wc;   /* camera depth of the box centre */
            double q[3] = {e.X - T[3], 0.5 * cam.H_b - T[7], e.Z - T[11]};
            double z = T[2] * q[0] + T[6] * q[1] + T[10] * q[2];
            if (z > cam.t_near && z < cam.d_clip) continue;
        }
        lam[PA] = -1.0f;
        mp->src_reg[i] = 0;
        held++;
    }
    return held;
}

/* An entry registered this many times has settled: revisit rule 2
 * (blend_revisits) damps its moves, so the map keeps it where it is stored. */
#define REVISIT_SETTLED 8

/* Map entries within reach of a new slot whose floor boxes join the gate's
 * part test, box test only: entries that are not among the keyframe's slots
 * (the keyframe did not retrieve them, e.g. their centre is just outside the
 * view, but the surface a new slot claims lies in their box), and settled
 * retrieved entries at their stored pose. A settled entry's slot may wander
 * in one keyframe's refinement (the object half in view), and its box with
 * it, while registration leaves the entry where it is: a prior slot that
 * claims the object there is its duplicate (a looped replay created such
 * copies 0.3-0.4 m from a large sphere's entry; docs/cogmap.md "Drift").
 * Nearest first is not needed: the cap is far above the entries one box can
 * touch. */
typedef struct gate_near {
    const sooc_view_rec *V;
    const uint64_t *src;
    int K, d, n, n_new;
    double unit, reach, nx[SOOC_MODEL_K_MAX], nz[SOOC_MODEL_K_MAX];
    float *out;
    uint64_t *ids;
} gate_near;

static int gate_near_visit(void *user, const sooc_cogmap_entry *e) {
    gate_near *g = user;
    if (g->n >= SOOC_GATE_MAX_BOXES) return 1;
    for (int i = 0; i < g->K; i++)   /* a retrieved entry: its slot's box, unless it has settled */
        if (g->src[i] == e->id && e->obs_count < REVISIT_SETTLED) return 0;
    int close = 0;
    for (int i = 0; i < g->n_new && !close; i++) close = hypot(e->X - g->nx[i], e->Z - g->nz[i]) < g->reach;
    if (!close) return 0;
    float lam[SOOC_LAM_MAX];
    sooc_cogmap_lam_to_local(&g->V->gf, e, lam);   /* metres in G -> model units, as the slots' poses */
    g->ids[g->n] = e->id;
    float *b = g->out + 3 * g->n++;
    b[0] = (float)(lam[SOOC_LAM_X] / g->unit), b[1] = (float)(lam[SOOC_LAM_Z] / g->unit), b[2] = lam[SOOC_LAM_TH];
    return 0;
}

/* The node's revisit rules, part 5: the creation gate (sooc_mapper_gate,
 * docs/cogmap.md "Revisits"). When the keyframe has a new present slot, the
 * final λ^L (model units; slots that will not register forced off) is decoded
 * once more, forward only, and each new slot creates an entry only if it owns
 * enough rays that no registered retrieved slot explains nearly as well and
 * is not the part of one (its owned surface points inside that slot's floor
 * box). A refused slot is turned off (it has no entry: nothing is removed).
 * Every new slot's verdict is logged at debug level. Returns the count. */
static int gate_new(sooc_mapper *mp, const sooc_view_rec *V, int K, int d, sooc_status *err) {
    sooc_model *m = mp->m;
    const sooc_model_config *c = sooc_model_get_config(m);
    const int NL = SOOC_LAM_SIZE(d), PA = SOOC_LAM_PRES(d);
    int role[SOOC_MODEL_K_MAX], n_new = 0;
    for (int i = 0; i < K; i++) {
        const float *lam = mp->lam_reg + (size_t)i * NL;
        role[i] = !(lam[PA] >= 0.0f) ? SOOC_GATE_OFF : mp->src_reg[i] ? SOOC_GATE_KNOWN : SOOC_GATE_NEW;
        n_new += role[i] == SOOC_GATE_NEW;
    }
    if (!n_new || (mp->gate_min < 0 && mp->gate_part < 0)) return 0;
    memcpy(mp->lam_gate, V->lam + (size_t)mp->L * K * NL, sizeof(float) * (size_t)K * NL);
    for (int i = 0; i < K; i++)
        if (role[i] == SOOC_GATE_OFF) mp->lam_gate[(size_t)i * NL + PA] = -30.0f;
    sooc_dec_call dc;
    memset(&dc, 0, sizeof dc);
    dc.rays = &V->vr;
    dc.nslot = K;
    dc.lam = mp->lam_gate;
    dc.lay = V->lay + (size_t)mp->L * 2 * c->d_layout;
    dc.noise = &mp->gate_noise;
    dc.tau = MAPPER_TAU;
    if ((*err = sooc_mdl_decode(mp->ws, &dc))) return 0;
    const int C = K + 1;
    gate_near near = {.V = V, .src = mp->src_reg, .K = K, .d = d, .unit = c->unit_m, .out = mp->gate_boxes,
                      .ids = mp->gate_box_ids};
    near.reach = 2.0 * M_SQRT2 * c->box_rh * c->unit_m;   /* a box corner can reach the new slot's points */
    for (int i = 0; i < K; i++)
        if (role[i] == SOOC_GATE_NEW) {
            sooc_cogmap_entry e;
            sooc_cogmap_lam_to_world(&V->gf, d, mp->lam_reg + (size_t)i * NL, &e);
            near.nx[near.n_new] = e.X, near.nz[near.n_new++] = e.Z;
        }
    sooc_cogmap_foreach(mp->map, gate_near_visit, &near);
    sooc_gate_input in = {V->vr.N, K, mp->ws->dec->sh, 2 * C, V->vr.pts, 6, V->vr.surf, mp->lam_gate, NL, role, c->box_rh,
                            near.n, mp->gate_boxes, 3};
    sooc_gate_verdict v[SOOC_MODEL_K_MAX];
    int refused = sooc_mapper_gate(&in, mp->gate_min, mp->gate_ratio, mp->gate_part, v);
    static const char *why[] = {"not new", "created", "refused: too few rays of its own",
                                "refused: part of a mapped entry"};
    for (int i = 0; i < K; i++) {
        if (role[i] != SOOC_GATE_NEW) continue;
        float *lam = mp->lam_reg + (size_t)i * NL;
        if (sooc_log_get_level() <= SOOC_LOG_DEBUG) {
            sooc_cogmap_entry e, ej;
            sooc_cogmap_lam_to_world(&V->gf, d, lam, &e);
            double dj = -1;
            uint64_t idj = 0;
            if (v[i].part >= 0 && v[i].part < K) {   /* a registered retrieved slot */
                sooc_cogmap_lam_to_world(&V->gf, d, mp->lam_reg + (size_t)v[i].part * NL, &ej);
                dj = hypot(e.X - ej.X, e.Z - ej.Z);
                idj = mp->src_reg[v[i].part];
            } else if (v[i].part >= K) {   /* a map entry's box: unretrieved, or settled as stored */
                const float *b = mp->gate_boxes + 3 * (v[i].part - K), *l = mp->lam_gate + (size_t)i * NL;
                dj = c->unit_m * hypot(l[SOOC_LAM_X] - b[0], l[SOOC_LAM_Z] - b[1]);
                idj = mp->gate_box_ids[v[i].part - K];
            }
            sooc_log(SOOC_LOG_DEBUG,
                     "mapper gate: view %d slot %d new at (%.2f, %.2f): owns %d rays, %d alone (of %d, need %.2f); "
                     "part share %.2f ratio %.3f of entry %llu (%s) %.2f m away -> %s",
                     mp->view_idx, i, e.X, e.Z, v[i].owned, v[i].alone, V->vr.N,
                     mp->gate_min >= 0 ? mp->gate_min * V->vr.N : -1.0, (double)v[i].part_share, (double)v[i].part_ratio,
                     (unsigned long long)idj, v[i].part < 0 ? "none" : v[i].part < K ? "its slot" : "its map box", dj,
                     why[v[i].reason]);
        }
        if (!v[i].create) lam[PA] = -1.0f;
    }
    return refused;
}

/* The node's revisit rule, part 2: once an entry has been registered
 * REVISIT_SETTLED times, the refined slot moves its stored where and what by
 * w = 1 / k^2 of the way (k = obs_count - REVISIT_SETTLED + 2 = 2, 3, ...), so
 * a settled entry moves at most sum w < 0.65 of one refinement's step in all.
 * Every refinement starts from the stored entry, so the refined values are
 * not independent estimates: with w = 1 / k (a running mean) a small
 * consistent bias of the refinement accumulates like the harmonic series,
 * ln(n), and a looped replay carried entries 0.2-0.4 m off their objects in
 * 10,000 keyframes, where new slots then mapped the objects
 * again (docs/cogmap.md "Revisits"). An object that moves is retired by the
 * depth evidence (part 4) and mapped anew. Younger entries take the
 * refinement as it is (a single pass over a scene barely changes). Variances
 * and presence are the refined ones. */
static void blend_revisits(sooc_mapper *mp, const sooc_view_rec *V, int K, int d) {
    const int NL = SOOC_LAM_SIZE(d), PA = SOOC_LAM_PRES(d);
    for (int i = 0; i < K; i++) {
        float *lam = mp->lam_reg + (size_t)i * NL;
        if (!mp->src_reg[i] || !(lam[PA] >= 0.0f)) continue;
        sooc_cogmap_entry old;
        if (sooc_cogmap_get(mp->map, mp->src_reg[i], &old)) continue;
        float o[SOOC_LAM_MAX];
        sooc_cogmap_lam_to_local(&V->gf, &old, o);
        if (old.obs_count < REVISIT_SETTLED) continue;   /* young entries: the refinement as is */
        float k = (float)(old.obs_count - REVISIT_SETTLED + 2), w = 1.0f / (k * k);
        lam[SOOC_LAM_X] = o[SOOC_LAM_X] + w * (lam[SOOC_LAM_X] - o[SOOC_LAM_X]);
        lam[SOOC_LAM_Z] = o[SOOC_LAM_Z] + w * (lam[SOOC_LAM_Z] - o[SOOC_LAM_Z]);
        float dth = lam[SOOC_LAM_TH] - o[SOOC_LAM_TH];
        dth = (float)atan2(sin(dth), cos(dth));
        lam[SOOC_LAM_TH] = o[SOOC_LAM_TH] + w * dth;
        for (int j = 0; j < d; j++)
            lam[SOOC_LAM_WHAT_MU + j] = o[SOOC_LAM_WHAT_MU + j] + w * (lam[SOOC_LAM_WHAT_MU + j] - o[SOOC_LAM_WHAT_MU + j]);
    }
}

/* The node's revisit rules, part 4: depth evidence (docs/cogmap.md
 * "Revisits"). Each keyframe, every entry it registered that is not new is
 * probed against the keyframe's depth (sooc_mapper_free_space).
 * - Free space: an entry whose place the depth showed free in
 *   REVISIT_FREE_VIEWS consecutive verdicts (verdicts of "no evidence"
 *   neither count nor break the run; a surface at a probe resets it) is
 *   retired: removed, published as a removal.
 * - Never seen: an entry at whose place the depth has shown no surface for
 *   REVISIT_UNSUPPORTED registrations (hidden behind another object, or free)
 *   that this keyframe registered together with an entry the depth does show,
 *   their floor boxes (side 2 R_h) overlapping by at least a quarter, is that
 *   object's duplicate: the two become one (merge_into).
 * The evidence lives in a direct-mapped cache by id (MAPPER_FREE_SLOTS; a
 * collision forgets evidence, which only delays a retirement); it is not
 * stored with the map, so a restart starts counting again. */
#define REVISIT_FREE_VIEWS 5
#define REVISIT_FREE_RING 6
#define REVISIT_UNSUPPORTED 48
int sooc_mapper_free_space(const sooc_cogmap_camera *cam, const sooc_frame *f, double X, double Z) {
    static const double hf[3] = {0.1, 0.2, 0.3};   /* centre probe heights / H_b */
    const double *T = cam->T_wc;
    const double rr = cam->R_h / 3.0;
    int vis = 0, hidden = 0;
    for (int p = 0; p < 3 + REVISIT_FREE_RING; p++) {
        double px = X, pz = Z, py;
        if (p < 3) py = hf[p] * cam->H_b;
        else {
            double a = 2.0 * M_PI * (p - 3) / REVISIT_FREE_RING;
            px += rr * cos(a);
            pz += rr * sin(a);
            py = 0.15 * cam->H_b;
        }
        double q[3] = {px - T[3], py - T[7], pz - T[11]};
        double xc = T[0] * q[0] + T[4] * q[1] + T[8] * q[2];
        double yc = T[1] * q[0] + T[5] * q[1] + T[9] * q[2];
        double zc = T[2] * q[0] + T[6] * q[1] + T[10] * q[2];
        if (!(zc > cam->t_near && zc < cam->d_clip)) continue;
        double u = cam->K.fx * xc / zc + cam->K.cx, v = cam->K.fy * yc / zc + cam->K.cy;
        if (!(u >= 0 && u < f->width && v >= 0 && v < f->height)) continue;
        size_t k = (size_t)(int)v * (size_t)f->width + (size_t)(int)u;
        if (f->valid && !f->valid[k]) continue;
        double D = f->depth[k];
        if (!(D > 0) || !isfinite(D)) continue;
        double tol = 0.1 + 0.02 * zc;
        /* the ray meets the floor (y = 0) at planar depth tf: a probe so close
         * above the floor that tf lies within the tolerance cannot tell the
         * floor behind it from an object at it */
        double tf = T[7] > py ? zc * T[7] / (T[7] - py) : INFINITY;
        if (!(tf > zc + 2.0 * tol)) continue;
        if (D < zc - tol) hidden++;           /* something in front of the probe */
        else if (!(D > zc + tol)) return 0;   /* a surface at the probe: occupied */
        else vis++;
    }
    return !hidden && vis >= 4 ? 1 : -1;
}

/* Remove entry id, publish it as a removal and forget its evidence (its
 * cache slot: a collision forgets another's, which only delays a retirement).
 * 1 on success; 0 when the update's removals are full or id is not mapped. */
static int retire_id(sooc_mapper *mp, uint64_t id) {
    if (mp->n_rem >= SOOC_MODEL_K_MAX || sooc_cogmap_remove(mp->map, id)) return 0;
    size_t c = (size_t)(id % MAPPER_FREE_SLOTS);
    mp->rem_ids[mp->n_rem++] = id;
    mp->free_id[c] = 0;
    mp->free_run[c] = mp->unsup_run[c] = 0;
    return 1;
}

static int retire_at(sooc_mapper *mp, uint64_t *ids, int i) {
    if (!retire_id(mp, ids[i])) return 0;
    ids[i] = 0;
    return 1;
}

/* Entry ids[i] joins ids[j]: one entry remains with ids[j]'s values, the
 * better-observed id (tie: the older) and both observation counts, as
 * sooc_cogmap_merge_neighbours does; the other id is removed. */
static int merge_into(sooc_mapper *mp, uint64_t *ids, int i, int j) {
    sooc_cogmap_entry ei, ej;
    if (mp->n_rem >= SOOC_MODEL_K_MAX || sooc_cogmap_get(mp->map, ids[i], &ei) ||
        sooc_cogmap_get(mp->map, ids[j], &ej))
        return 0;
    int keep_i = ei.obs_count > ej.obs_count || (ei.obs_count == ej.obs_count && ei.id < ej.id);
    uint64_t lose = keep_i ? ej.id : ei.id;
    uint64_t obs = (uint64_t)ei.obs_count + ej.obs_count;
    ej.obs_count = obs > UINT32_MAX ? UINT32_MAX : (uint32_t)obs;
    if (ei.first_seen_ns < ej.first_seen_ns) ej.first_seen_ns = ei.first_seen_ns;
    ej.id = keep_i ? ei.id : ej.id;
    if (sooc_cogmap_remove(mp->map, lose)) return 0;
    mp->rem_ids[mp->n_rem++] = lose;
    /* overwrites the kept id (never appends); should it run out of memory
     * moving grid cells, the kept entry keeps its stored values */
    (void)sooc_cogmap_insert(mp->map, &ej, NULL);
    size_t c = (size_t)(lose % MAPPER_FREE_SLOTS), ck = (size_t)(ej.id % MAPPER_FREE_SLOTS);
    mp->free_id[c] = 0;
    mp->free_run[c] = mp->unsup_run[c] = 0;
    mp->free_id[ck] = ej.id;   /* the kept entry is the one the depth shows */
    mp->free_run[ck] = mp->unsup_run[ck] = 0;
    ids[j] = ej.id;
    ids[i] = 0;
    return 1;
}

static int retire_free(sooc_mapper *mp, const sooc_frame *f, uint64_t *ids, int K) {
    sooc_cogmap_camera cam;
    sooc_mdl_camera_of(mp->m, f, &cam);
    int n = 0, vd[SOOC_MODEL_K_MAX];
    double X[SOOC_MODEL_K_MAX], Z[SOOC_MODEL_K_MAX];
    for (int i = 0; i < K; i++) {
        sooc_cogmap_entry e;
        vd[i] = -1;
        if (!ids[i] || sooc_cogmap_get(mp->map, ids[i], &e) || e.obs_count < 2) continue;
        X[i] = e.X;
        Z[i] = e.Z;
        size_t c = (size_t)(ids[i] % MAPPER_FREE_SLOTS);
        if (mp->free_id[c] != ids[i]) {
            mp->free_id[c] = ids[i];
            mp->free_run[c] = mp->unsup_run[c] = 0;
        }
        vd[i] = sooc_mapper_free_space(&cam, f, e.X, e.Z);
        if (vd[i] == 0) mp->free_run[c] = mp->unsup_run[c] = 0;
        else {
            if (vd[i] == 1 && mp->free_run[c] < UINT16_MAX) mp->free_run[c]++;
            if (mp->unsup_run[c] < UINT16_MAX) mp->unsup_run[c]++;
        }
        if (mp->free_run[c] >= REVISIT_FREE_VIEWS) n += retire_at(mp, ids, i);
    }
    /* never seen, always next to one that is: an entry the depth has not shown
     * a surface at for REVISIT_UNSUPPORTED registrations, registered together
     * with an entry the depth shows at its place now, whose floor box overlaps
     * its own by at least a quarter, adds nothing the other does not explain */
    const double B = 2.0 * cam.R_h;
    for (int i = 0; i < K; i++) {
        if (!ids[i] || vd[i] == 0) continue;
        size_t c = (size_t)(ids[i] % MAPPER_FREE_SLOTS);
        if (mp->free_id[c] != ids[i] || mp->unsup_run[c] < REVISIT_UNSUPPORTED) continue;
        for (int j = 0; j < K; j++) {
            if (j == i || !ids[j] || vd[j] != 0) continue;
            double ox = B - fabs(X[i] - X[j]), oz = B - fabs(Z[i] - Z[j]);
            if (ox > 0 && oz > 0 && ox * oz >= 0.25 * B * B) {
                n += merge_into(mp, ids, i, j);
                break;
            }
        }
    }
    return n;
}

/* Object geometry (mapper.h): registration statistics of what this update
 * wrote, then at most geo_budget tight boxes recomputed. */
static sooc_status mapper_geometry(sooc_mapper *mp) {
    for (int i = 0; i < mp->n_rem; i++) sooc_objgeom_cache_remove(mp->geo, mp->rem_ids[i]);
    for (int i = 0; i < mp->n_chg; i++) {
        sooc_cogmap_entry e;
        if (sooc_cogmap_get(mp->map, mp->chg_ids[i], &e)) {
            sooc_clearerr();
            continue;
        }
        sooc_status s = sooc_objgeom_cache_observe(mp->geo, &e);
        if (s) return s;
    }
    if (mp->geo_budget == 0) return SOOC_OK;
    sooc_objgeom_opts o;
    sooc_objgeom_opts_default(&o);
    if (mp->geo_budget < 0) return sooc_objgeom_cache_refresh(mp->geo, mp->m, mp->map, &o, -1, NULL, NULL);
    /* a box computed for an entry this update did not register is republished
     * with the update's changes (sooc_mapper_changed), while there is room */
    int room = SOOC_MODEL_K_MAX - mp->n_chg, nd = 0, max = mp->geo_budget < room ? mp->geo_budget : room;
    uint64_t done[SOOC_MODEL_K_MAX];
    if (max <= 0) return SOOC_OK;
    sooc_status s = sooc_objgeom_cache_refresh(mp->geo, mp->m, mp->map, &o, max, &nd, done);
    for (int k = 0; k < nd; k++) {
        int j = 0;
        while (j < mp->n_chg && mp->chg_ids[j] < done[k]) j++;
        if (j < mp->n_chg && mp->chg_ids[j] == done[k]) continue;
        memmove(mp->chg_ids + j + 1, mp->chg_ids + j, sizeof mp->chg_ids[0] * (size_t)(mp->n_chg - j));
        mp->chg_ids[j] = done[k];
        mp->n_chg++;
    }
    return s;
}

sooc_status sooc_mapper_refresh_geometry(sooc_mapper *mp, int max_objects, int *n_done) {
    if (mp->gm) {   /* its boxes are always up to date */
        if (n_done) *n_done = 0;
        return SOOC_OK;
    }
    sooc_objgeom_opts o;
    sooc_objgeom_opts_default(&o);
    return sooc_objgeom_cache_refresh(mp->geo, mp->m, mp->map, &o, max_objects, n_done, NULL);
}

static int adopt_entry(void *user, const sooc_cogmap_entry *e) {
    sooc_objgeom_cache *c = user;
    return !sooc_objgeom_cache_has(c, e->id) && sooc_objgeom_cache_observe(c, e) != SOOC_OK;
}

void sooc_mapper_geometry_invalidate(sooc_mapper *mp) {
    if (mp->gm) return;
    if (sooc_cogmap_foreach(mp->map, adopt_entry, mp->geo)) sooc_clearerr();   /* out of memory: no box for it */
    sooc_objgeom_cache_invalidate(mp->geo);
}

sooc_status sooc_mapper_set_proposals(sooc_mapper *mp, const sooc_proposal_params *p) {
    if (mp->gm) return sooc_seterr(SOOC_EINVAL, "mapper: proposals need a learnt model, not the geometric map");
    if (!p || !p->on) {
        sooc_cluster_map_destroy(mp->prop);
        mp->prop = NULL;
        return SOOC_OK;
    }
    sooc_cluster_map *cm = NULL;
    sooc_status st = sooc_cluster_map_create(&cm, &p->cluster);
    if (st) return sooc_adderr(st, "mapper: proposals");
    sooc_cluster_map_destroy(mp->prop);
    mp->prop = cm;
    mp->prop_p.cover_m = p->cover_m;
    mp->prop_p.sigma_frac = p->sigma_frac;
    mp->prop_p.pres_logit = p->pres_logit;
    mp->prop_p.rest_logit = p->rest_logit;
    return SOOC_OK;
}

/* the support's grid: 1 cm voxels (a model's input frames are coarse; at the
 * clusters' default 4 mm the check costs twice as much for entries within the
 * seeds' spread, docs/geometric.md "Geometric support") */
#define SUPPORT_VOXEL_M 0.01
sooc_status sooc_mapper_set_support(sooc_mapper *mp, double margin_m) {
    if (mp->gm) return sooc_seterr(SOOC_EINVAL, "mapper: geometric support needs a learnt model, not the geometric map");
    if (!(margin_m >= 0 && margin_m < 10))
        return sooc_seterr(SOOC_EINVAL, "mapper: geometric support margin %g m out of range", margin_m);
    sooc_cluster_map *cm = NULL;
    sooc_status st = SOOC_OK;
    if (margin_m > 0) {
        const sooc_model_config *c = sooc_model_get_config(mp->m);
        sooc_cluster_params cp;
        sooc_cluster_params_default(&cp);
        cp.voxel_m = SUPPORT_VOXEL_M;
        /* floating clusters support entries too: without them the online label-fusion masks and APC rows
         * fall (0.067 -> 0.055, 0.138 -> 0.115 over 3 seeds; docs/geometric.md "Geometric support") */
        cp.rest_m = 0;
        double clip = c->d_clip * c->unit_m;
        if (clip > 0 && clip < cp.max_depth_m) cp.max_depth_m = clip;
        st = sooc_cluster_map_create(&cm, &cp);
    }
    if (st) return sooc_adderr(st, "mapper: geometric support");
    sooc_cluster_map_destroy(mp->supp);
    mp->supp = cm;
    mp->supp_margin = margin_m;
    return SOOC_OK;
}

/* Geometric support, after registration: the keyframe joins the clusters of
 * the keyframes before it, and every entry in the keyframe's view whose floor
 * position lies in no cluster's floor box (grown by supp_margin) is removed:
 * no object points stand under it, so it explains only the support surface or
 * a wall. Entries out of view stay (the clusters hold only what the mapped
 * keyframes saw: a resumed map's far entries). At most the room left in
 * rem_ids per update; the rest go with the next keyframes. ids[] of removed
 * entries become 0. */
typedef struct supp_visit {
    const sooc_cluster_object *o;
    int n;
    double margin;
    const sooc_cogmap_camera *cam;
    uint64_t *out;
    int cap, k;
} supp_visit;

static int supp_on_geometry(const supp_visit *v, double X, double Z) {
    for (int i = 0; i < v->n; i++) {
        const sooc_cluster_object *o = &v->o[i];
        double dx = X - o->x, dz = Z - o->z, c = cos(o->yaw), s = sin(o->yaw);
        double a = fabs(c * dx - s * dz), b = fabs(s * dx + c * dz);   /* along the box's axes (R_y) */
        if (a <= 0.5 * o->extent[0] + v->margin && b <= 0.5 * o->extent[2] + v->margin) return 1;
    }
    return 0;
}

/* 1 when the entry's place on the floor (X, 0, Z) projects into the view at
 * a depth in (t_near, d_clip): the keyframe could show what stands there (or
 * its box centre does: sooc_cogmap_in_view) */
static int supp_floor_in_view(const sooc_cogmap_camera *cam, double X, double Z) {
    const double *T = cam->T_wc;
    double q[3] = {X - T[3], -T[7], Z - T[11]};
    double z = T[2] * q[0] + T[6] * q[1] + T[10] * q[2];
    if (!(z > cam->t_near && z < cam->d_clip)) return 0;
    double x = T[0] * q[0] + T[4] * q[1] + T[8] * q[2], y = T[1] * q[0] + T[5] * q[1] + T[9] * q[2];
    double u = cam->K.fx * x / z + cam->K.cx, w = cam->K.fy * y / z + cam->K.cy;
    return u >= 0 && w >= 0 && u < cam->K.width && w < cam->K.height;
}

static int supp_collect(void *user, const sooc_cogmap_entry *e) {
    supp_visit *v = user;
    if (v->k >= v->cap) return 1;
    if ((supp_floor_in_view(v->cam, e->X, e->Z) || sooc_cogmap_in_view(v->cam, e)) && !supp_on_geometry(v, e->X, e->Z))
        v->out[v->k++] = e->id;
    return 0;
}

static sooc_status support_prune(sooc_mapper *mp, const sooc_frame *f, uint64_t *ids, int K, int *n_pruned) {
    *n_pruned = 0;
    int n = 0;
    sooc_status s = sooc_cluster_map_add_frame(mp->supp, f);
    if (!s) s = sooc_cluster_map_segment(mp->supp, &n);
    if (!s && n > mp->supp_cap) {
        sooc_cluster_object *o = sooc_realloc(mp->supp_obj, (size_t)n * sizeof *o);
        if (!o) return sooc_seterr(SOOC_ENOMEM, "mapper: out of memory for %d clusters", n);
        mp->supp_obj = o, mp->supp_cap = n;
    }
    if (!s) s = sooc_cluster_map_objects(mp->supp, mp->supp_obj, mp->supp_cap, &n);
    if (s) return sooc_adderr(s, "mapper: geometric support of frame %lld", (long long)f->index);
    uint64_t out[SOOC_MODEL_K_MAX];
    sooc_cogmap_camera cam;
    sooc_mdl_camera_of(mp->m, f, &cam);
    supp_visit v = {mp->supp_obj, n, mp->supp_margin, &cam, out, SOOC_MODEL_K_MAX - mp->n_rem, 0};
    sooc_cogmap_foreach(mp->map, supp_collect, &v);
    for (int i = 0; i < v.k; i++) {
        if (!retire_id(mp, out[i])) continue;
        for (int j = 0; j < K; j++)
            if (ids[j] == out[i]) ids[j] = 0;
        (*n_pruned)++;
    }
    return SOOC_OK;
}

/* Geometric support, after the removals: the written entries' observed
 * surfaces. The support's object voxels are claimed by the entries in the
 * keyframe's view (sooc_surface_claim), and each written entry that claims
 * at least SURF_MIN_VOXELS gets the box of its claim as its planner box. */
#define SURF_MIN_VOXELS 8
static sooc_status support_surfaces(sooc_mapper *mp, const sooc_frame *f, const uint64_t *ids, int K) {
    sooc_model_field *fld = NULL;
    sooc_surface_claims cl;
    sooc_status s = sooc_surface_claim_frame(mp->m, mp->map, f, 0, mp->supp, NULL, &fld, &cl);
    if (s) return sooc_adderr(s, "mapper");
    int nc = sooc_model_field_get(fld)->n_comp;
    for (int k = 1; !s && k < nc; k++) {
        uint64_t id = sooc_model_field_comp_id(fld, k);
        int written = 0;
        for (int j = 0; j < K; j++) written |= id && ids[j] == id;
        if (!written) continue;
        sooc_cogmap_entry e;
        if (sooc_cogmap_get(mp->map, id, &e) != SOOC_OK) {
            sooc_clearerr();
            continue;
        }
        float ext[3], cen[3];
        if (sooc_surface_box(&cl, k, e.X, e.Z, e.Theta, SUPPORT_VOXEL_M, ext, cen) >= SURF_MIN_VOXELS)
            s = sooc_objgeom_cache_set_surface(mp->geo, id, ext, cen);
    }
    sooc_surface_claims_free(&cl);
    sooc_model_field_destroy(fld);
    return s ? sooc_adderr(s, "mapper: surfaces of frame %lld", (long long)f->index) : SOOC_OK;
}

void sooc_mapper_set_surface_boxes(sooc_mapper *mp, int on) { mp->surf_boxes = on != 0; }

void sooc_proposal_params_default(sooc_proposal_params *p) {
    memset(p, 0, sizeof *p);
    sooc_cluster_params_default(&p->cluster);
    p->cluster.rest_m = 0;   /* a keyframe's own clusters: floating ones too (the foot of one often unseen) */
    p->cover_m = 0.02;
    p->sigma_frac = 0;
    p->pres_logit = NAN;
    p->rest_logit = NAN;
}

void sooc_mapper_set_geometry_budget(sooc_mapper *mp, int per_update) {
    mp->geo_budget = per_update < 0 ? -1 : per_update;
}

sooc_status sooc_mapper_update(sooc_mapper *mp, const sooc_frame *f, sooc_update_stats *stp) {
    double t0 = sooc_seconds();
    sooc_update_stats st0;
    sooc_update_stats *st = stp ? stp : &st0;
    if (mp->gm) {
        if (!f->has_pose) return sooc_seterr(SOOC_EINVAL, "mapper: frame %lld has no pose", (long long)f->index);
        return sooc_mdl_geo_update(mp->gm, f, st);
    }
    memset(st, 0, sizeof *st);
    mp->n_chg = mp->n_rem = mp->has_block = 0;
    sooc_model *m = mp->m;
    const sooc_model_config *c = sooc_model_get_config(m);
    if (!f->has_pose) return sooc_seterr(SOOC_EINVAL, "mapper: frame %lld has no pose", (long long)f->index);
    if (f->width != c->img_w || f->height != c->img_h)
        return sooc_seterr(SOOC_EINVAL, "mapper: frame %lld is %dx%d, the model needs %dx%d", (long long)f->index,
                           f->width, f->height, c->img_w, c->img_h);
    sooc_step_state *S = sooc_mdl_step_state(mp->ws, 1, mp->L);
    if (!S) return sooc_seterr(SOOC_ENOMEM, "mapper: out of memory");
    S->aux_replay = 0;
    sooc_view_rec *V = &mp->V;
    sooc_status s = sooc_mdl_view_setup(m, mp->map, V, f, 1, &mp->rng, NULL);
    if (s) return s;
    if (mp->prop) {
        st->n_proposed = sooc_mdl_propose(mp->prop, c, MDL_NL(c->d_what), f, V, &mp->prop_p, &s);
        if (s) return sooc_adderr(s, "mapper: proposals of frame %lld", (long long)f->index);
    }
    sooc_step_opts o;
    sooc_step_opts_default(&o);
    o.tau = MAPPER_TAU;
    o.L = mp->L;
    o.mean_latents = !mp->sample;
    double lw;
    if ((s = sooc_mdl_view_forward(mp->ws, S, V, mp->L, &o, 0, &mp->rng, &lw, NULL))) return s;
    int NL = MDL_NL(c->d_what), D2 = 2 * c->d_layout;
    const float *lamL = V->lam + (size_t)mp->L * c->K * NL;
    const float *layL = V->lay + (size_t)mp->L * D2;
    memcpy(mp->lam_reg, lamL, sizeof(float) * (size_t)c->K * NL);
    memcpy(mp->src_reg, V->src_id, sizeof(uint64_t) * (size_t)c->K);
    sooc_mdl_lam_to_m(c, mp->lam_reg, c->K, NL);   /* model units -> metres (config.unit_m) */
    int n_same = sooc_mapper_same_pose(mp->lam_reg, mp->src_reg, c->K, c->d_what, mp->same_r);
    int n_gated = 0;
    if (mp->merge_nb && mp->merge_r > 0) {
        hold_unseen(mp, f, V, c->K, c->d_what);
        n_gated = gate_new(mp, V, c->K, c->d_what, &s);
        if (s) return s;
        blend_revisits(mp, V, c->K, c->d_what);
    }
    sooc_cogmap_reg_stats rs;
    uint64_t ids[SOOC_MODEL_K_MAX];
    if ((s = sooc_cogmap_register(mp->map, &V->gf, c->K, mp->lam_reg, mp->src_reg, f->t_ns, mp->view_idx, ids,
                                  mp->rem_ids, &rs)))
        return s;
    mp->n_rem = rs.n_removed;
    int n_retired = 0;
    int n_merged = 0;   /* merged-away entries: removed, and no longer among the written ids */
    sooc_cogmap_merge(mp->map, ids, c->K, mp->merge_r, mp->rem_ids + mp->n_rem, &n_merged);
    mp->n_rem += n_merged;
    if (mp->merge_nb && mp->merge_r > 0) {   /* revisits: merge with unregistered neighbours */
        int n_nb = 0;
        s = sooc_cogmap_merge_neighbours(mp->map, ids, c->K, mp->merge_r, mp->rem_ids + mp->n_rem,
                                         mp->n_rem < SOOC_MODEL_K_MAX ? SOOC_MODEL_K_MAX - mp->n_rem : 0, &n_nb);
        mp->n_rem += n_nb;
        n_merged += n_nb;
        if (s) return s;
        n_retired = retire_free(mp, f, ids, c->K);
    }
    if (mp->supp) {
        int n_pr = 0;
        if ((s = support_prune(mp, f, ids, c->K, &n_pr))) return s;
        n_retired += n_pr;
        if (mp->surf_boxes && (s = support_surfaces(mp, f, ids, c->K))) return s;
    }
    for (int i = 0; i < c->K; i++)   /* ids of written slots, ascending (insertion sort, K <= 32) */
        if (ids[i]) {
            int j = mp->n_chg++;
            while (j > 0 && mp->chg_ids[j - 1] > ids[i]) {
                mp->chg_ids[j] = mp->chg_ids[j - 1];
                j--;
            }
            mp->chg_ids[j] = ids[i];
        }
    if ((s = sooc_cogmap_layout_set(mp->map, V->bi, V->bj, layL, layL + c->d_layout))) return s;
    if ((s = mapper_geometry(mp))) return s;
    mp->has_block = 1;
    mp->bi = V->bi;
    mp->bj = V->bj;
    mp->view_idx++;
    st->n_retrieved = V->n_ret;
    st->n_registered = rs.n_registered;
    st->n_new = rs.n_new;
    st->n_removed = rs.n_removed;
    st->n_merged = n_merged;
    st->n_same_pose = n_same;
    st->n_retired = n_retired;
    st->n_gated = n_gated;
    st->elapsed_ms = 1e3 * (sooc_seconds() - t0);
    return SOOC_OK;
}

int sooc_mapper_same_pose(float *lam, uint64_t *src_ids, int k, int d, double radius) {
    if (!(radius > 0) || k < 2 || k > SOOC_MAPPER_CHANGED_MAX) return 0;
    const int NL = SOOC_LAM_SIZE(d), PA = SOOC_LAM_PRES(d);
    int order[SOOC_MAPPER_CHANGED_MAX], n = 0;
    for (int i = 0; i < k; i++) {   /* present slots by presence logit, highest first (stable: ties by index) */
        if (!(lam[(size_t)i * NL + PA] >= 0.0f)) continue;
        int j = n++;
        while (j > 0 && lam[(size_t)order[j - 1] * NL + PA] < lam[(size_t)i * NL + PA]) {
            order[j] = order[j - 1];
            j--;
        }
        order[j] = i;
    }
    const double r2 = radius * radius;
    int off = 0;
    for (int a = 0; a < n; a++) {
        int i = order[a];
        float *li = lam + (size_t)i * NL;
        if (!(li[PA] >= 0.0f)) continue;   /* turned off by an earlier slot */
        for (int b = a + 1; b < n; b++) {
            int j = order[b];
            float *lj = lam + (size_t)j * NL;
            if (!(lj[PA] >= 0.0f)) continue;
            double dx = (double)li[SOOC_LAM_X] - lj[SOOC_LAM_X], dz = (double)li[SOOC_LAM_Z] - lj[SOOC_LAM_Z];
            if (dx * dx + dz * dz >= r2) continue;
            lj[PA] = -1.0f;
            off++;
            if (src_ids && src_ids[j] && !src_ids[i]) {   /* the kept posterior continues the entry */
                src_ids[i] = src_ids[j];
                src_ids[j] = 0;
            }
        }
    }
    return off;
}

sooc_status sooc_mapper_entries(const sooc_mapper *mp, sooc_map_entry *out, size_t cap, size_t *n) {
    if (mp->gm) return sooc_mdl_geo_entries(mp->gm, out, cap, n);
    size_t cnt = sooc_cogmap_count(mp->map);
    if (!out) {
        *n = cnt;
        return SOOC_OK;
    }
    if (cnt > cap) cnt = cap;
    sooc_cogmap_entry *tmp = sooc_calloc(cnt ? cnt : 1, sizeof *tmp);
    if (!tmp) return SOOC_ENOMEM;
    size_t got = 0;
    sooc_status s = sooc_cogmap_entries(mp->map, tmp, cnt, &got);
    float ext[3];
    sooc_model_box_extent(sooc_model_get_config(mp->m), ext);
    for (size_t i = 0; !s && i < got; i++) {
        sooc_map_entry_from_cogmap(&tmp[i], ext, &out[i]);
        sooc_objgeom_cache_fill(mp->geo, &tmp[i], &out[i]);
    }
    *n = s ? 0 : got;
    sooc_free(tmp);
    return s;
}

sooc_status sooc_mapper_load_entries(sooc_mapper *mp, const sooc_map_entry *e, size_t n) {
    if (mp->gm) return sooc_mdl_geo_load_entries(mp->gm, e, n);
    const sooc_model_config *c = sooc_model_get_config(mp->m);
    sooc_cogmap_entry *tmp = sooc_calloc(n ? n : 1, sizeof *tmp);
    if (!tmp) return SOOC_ENOMEM;
    sooc_status s = SOOC_OK;
    for (size_t i = 0; i < n; i++) {
        if (e[i].latent_dim != c->d_what) {
            s = sooc_seterr(SOOC_EINVAL, "mapper: entry %llu has latent_dim %d, model d = %d",
                            (unsigned long long)e[i].id, e[i].latent_dim, c->d_what);
            break;
        }
        sooc_map_entry_to_cogmap(&e[i], &tmp[i]);
    }
    if (!s) s = sooc_cogmap_load(mp->map, tmp, n);
    sooc_free(tmp);
    sooc_objgeom_cache_clear(mp->geo);
    for (size_t i = 0; !s && i < n; i++) s = sooc_objgeom_cache_seed(mp->geo, &e[i]);
    mp->n_chg = mp->n_rem = mp->has_block = 0;
    return s;
}

sooc_status sooc_mapper_changed(const sooc_mapper *mp, sooc_map_entry *out, size_t cap, size_t *n,
                                  uint64_t *removed_ids, size_t cap_r, size_t *n_removed) {
    if (mp->gm) return sooc_mdl_geo_changed(mp->gm, out, cap, n, removed_ids, cap_r, n_removed);
    size_t nc = (size_t)mp->n_chg, nr = (size_t)mp->n_rem;
    if (n) *n = nc;
    if (n_removed) *n_removed = nr;
    if ((out && nc > cap) || (removed_ids && nr > cap_r))
        return sooc_seterr(SOOC_EINVAL, "mapper changed: %zu changed / %zu removed do not fit in %zu / %zu", nc, nr,
                           cap, cap_r);
    float ext[3];
    sooc_model_box_extent(sooc_model_get_config(mp->m), ext);
    for (size_t i = 0; out && i < nc; i++) {
        sooc_cogmap_entry e;
        sooc_status s = sooc_cogmap_get(mp->map, mp->chg_ids[i], &e);
        if (s) return sooc_adderr(s, "mapper changed: entry %llu", (unsigned long long)mp->chg_ids[i]);
        sooc_map_entry_from_cogmap(&e, ext, &out[i]);
        sooc_objgeom_cache_fill(mp->geo, &e, &out[i]);
    }
    if (removed_ids) memcpy(removed_ids, mp->rem_ids, nr * sizeof *removed_ids);
    return SOOC_OK;
}

int sooc_mapper_layout_dim(const sooc_mapper *mp) { return mp->gm ? 0 : sooc_model_get_config(mp->m)->d_layout; }
int sooc_mapper_latent_dim(const sooc_mapper *mp) {
    return mp->gm ? SOOC_GEOMETRIC_LATENT_DIM : sooc_model_get_config(mp->m)->d_what;
}

sooc_status sooc_mapper_last_layout(const sooc_mapper *mp, int32_t *bi, int32_t *bj, float *mu, float *logvar) {
    if (mp->gm || !mp->has_block) return SOOC_ENOTFOUND;
    *bi = mp->bi;
    *bj = mp->bj;
    return sooc_cogmap_layout_get(mp->map, mp->bi, mp->bj, mu, logvar);
}

sooc_status sooc_mapper_load_layout(sooc_mapper *mp, int32_t bi, int32_t bj, const float *mu,
                                      const float *logvar) {
    if (mp->gm) return SOOC_OK;   /* no layout */
    return sooc_cogmap_layout_set(mp->map, bi, bj, mu, logvar);
}

sooc_status sooc_mapper_clear(sooc_mapper *mp) {
    if (mp->gm) {
        sooc_mdl_geo_clear(mp->gm);
        return SOOC_OK;
    }
    sooc_cogmap_clear(mp->map, 0);
    sooc_objgeom_cache_clear(mp->geo);
    memset(mp->free_id, 0, sizeof mp->free_id);
    memset(mp->free_run, 0, sizeof mp->free_run);
    memset(mp->unsup_run, 0, sizeof mp->unsup_run);
    if (mp->supp) sooc_cluster_map_clear(mp->supp);
    if (mp->prop) sooc_cluster_map_clear(mp->prop);
    mp->n_chg = mp->n_rem = mp->has_block = 0;
    return SOOC_OK;
}

void sooc_mapper_reserve_ids(sooc_mapper *mp, uint64_t next_id) {
    if (mp->gm) sooc_mdl_geo_reserve_ids(mp->gm, next_id);
    else sooc_cogmap_reserve_ids(mp->map, next_id);
}
void sooc_mapper_set_merge_neighbours(sooc_mapper *mp, int on) { mp->merge_nb = on != 0; }
void sooc_mapper_set_gate(sooc_mapper *mp, double min_rays, double ratio, double part) {
    mp->gate_min = min_rays == 0 ? SOOC_GATE_MIN_RAYS : min_rays < 0 ? -1.0 : min_rays;
    mp->gate_ratio = ratio > 0 ? ratio : SOOC_GATE_RATIO;
    mp->gate_part = part == 0 ? SOOC_GATE_PART : part < 0 ? -1.0 : part;
}

void sooc_mapper_set_merge_radius(sooc_mapper *mp, double radius) {
    mp->merge_r = radius > 0 ? radius : 0;
}
void sooc_mapper_set_latents(sooc_mapper *mp, int latents) { mp->sample = latents == SOOC_LATENTS_SAMPLE; }
uint64_t sooc_mapper_next_id(const sooc_mapper *mp) {
    return mp->gm ? sooc_mdl_geo_next_id(mp->gm) : sooc_cogmap_next_id(mp->map);
}

sooc_model *sooc_mapper_model(sooc_mapper *mp) { return mp->m; }
const sooc_cogmap *sooc_mapper_cogmap(const sooc_mapper *mp) { return mp->map; }
sooc_status sooc_mapper_create_with_model(sooc_mapper **out, sooc_model *m, int iterations, uint64_t seed,
                                            int threads) {
    return sooc_mdl_mapper_create_from(out, m, iterations, seed, threads);
}
