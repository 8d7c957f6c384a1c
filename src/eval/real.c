/* Metrics for real recorded sequences (eval.h, docs/metrics.md "Real
 * sequences"): the query rule, the free-space test, yaw/position spread,
 * churn, per-object IoU, label images, and the runner that puts them
 * together around the SOOC3D mapper. */
#include "sooc3d/eval.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/train.h"
#include "sooc3d/mapper.h"
#include "sooc3d/render.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- query rule */

int sooc_eval_real_is_query(int pos, int every) {
    if (every < 2 || pos < 0) return 0;
    return pos % every == every / 2;
}

/* ------------------------------------------------------ free / surface / never */

const char *sooc_seen_class_name(sooc_seen_class c) {
    switch (c) {
    case SOOC_SEEN_NEVER: return "never";
    case SOOC_SEEN_FREE: return "free";
    case SOOC_SEEN_SURFACE: return "surface";
    }
    return "?";
}

sooc_status sooc_eval_point_seen(const double p_w[3], const sooc_frame *frames, int n, double tol,
                                 sooc_seen_votes *out) {
    if (!p_w || !out || n < 0 || (n && !frames) || !(tol > 0))
        return sooc_seterr(SOOC_EINVAL, "point_seen: bad arguments (n %d, tol %g)", n, tol);
    memset(out, 0, sizeof *out);
    out->min_behind = NAN;
    for (int i = 0; i < n; i++) {
        const sooc_frame *f = &frames[i];
        if (!f->has_pose || !f->depth || !f->valid) continue;
        double T_cw[16], pc[3], u, v;
        sooc_se3_inverse(T_cw, f->T_wc);
        sooc_se3_apply(pc, T_cw, p_w);
        if (pc[2] < 0.1) continue;
        sooc_intrinsics K = f->K;
        K.width = f->width, K.height = f->height;
        if (!sooc_cam_project(&K, pc, &u, &v)) continue;
        if (!(u >= 0 && v >= 0 && u < f->width && v < f->height)) continue;
        out->n_in_view++;
        size_t k = (size_t)(int)v * (size_t)f->width + (size_t)(int)u;
        if (!f->valid[k]) continue;
        double d = f->depth[k];
        if (!(d > 0) || !isfinite(d)) continue;
        if (!(pc[2] - d >= out->min_behind)) out->min_behind = pc[2] - d;   /* also replaces NaN */
        if (pc[2] < d - tol) out->n_free++;
        else if (pc[2] > d + tol) out->n_behind++;
        else out->n_surface++;
    }
    if (out->n_free + out->n_surface == 0) out->cls = SOOC_SEEN_NEVER;
    else out->cls = out->n_free > out->n_surface ? SOOC_SEEN_FREE : SOOC_SEEN_SURFACE;
    return SOOC_OK;
}

int sooc_eval_entry_probes(const sooc_map_entry *e, double seen_height, double p_w[][3]) {
    const sooc_map_geometry *g = &e->geom;
    if (!(g->flags & SOOC_GEOM_TIGHT) || (g->flags & SOOC_GEOM_EMPTY)) {
        p_w[0][0] = e->x, p_w[0][1] = seen_height, p_w[0][2] = e->z;
        return 1;
    }
    double R[9];
    sooc_m3_rot_y(R, e->yaw);
    for (int i = 0; i < SOOC_ENTRY_PROBES_MAX; i++) {
        double c[3] = {g->centre[0], g->centre[1], g->centre[2]}, w[3];
        if (i > 0) c[(i - 1) / 2] += ((i - 1) % 2 ? 0.5 : -0.5) * e->extent[(i - 1) / 2];
        sooc_m3_mulv(w, R, c);
        p_w[i][0] = e->x + w[0], p_w[i][1] = w[1], p_w[i][2] = e->z + w[2];
    }
    return SOOC_ENTRY_PROBES_MAX;
}

sooc_status sooc_eval_entry_seen(const sooc_map_entry *e, double seen_height, const sooc_frame *frames, int n,
                                 double tol, sooc_seen_votes *out) {
    if (!e || !out) return sooc_seterr(SOOC_EINVAL, "entry_seen: NULL argument");
    double p[SOOC_ENTRY_PROBES_MAX][3];
    int np = sooc_eval_entry_probes(e, seen_height, p), any[3] = {0, 0, 0};
    memset(out, 0, sizeof *out);
    out->min_behind = NAN;
    for (int i = 0; i < np; i++) {
        sooc_seen_votes v;
        sooc_status st = sooc_eval_point_seen(p[i], frames, n, tol, &v);
        if (st) return st;
        out->n_in_view += v.n_in_view, out->n_free += v.n_free;
        out->n_surface += v.n_surface, out->n_behind += v.n_behind;
        if (!isnan(v.min_behind) && !(v.min_behind >= out->min_behind)) out->min_behind = v.min_behind;
        any[v.cls] = 1;
    }
    out->cls = any[SOOC_SEEN_SURFACE] ? SOOC_SEEN_SURFACE : any[SOOC_SEEN_FREE] ? SOOC_SEEN_FREE : SOOC_SEEN_NEVER;
    return SOOC_OK;
}

sooc_status sooc_eval_points_seen(const float *xyz, size_t n, int max_probes, const sooc_frame *frames, int n_frames,
                                  double tol, int pts[3], sooc_seen_class *cls) {
    if ((n && !xyz) || !pts || !cls || max_probes < 1)
        return sooc_seterr(SOOC_EINVAL, "points_seen: bad arguments (n %zu, max probes %d)", n, max_probes);
    pts[0] = pts[1] = pts[2] = 0;
    size_t step = n / (size_t)max_probes + 1;
    for (size_t i = 0; i < n; i += step) {
        double p[3] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
        sooc_seen_votes v;
        sooc_status st = sooc_eval_point_seen(p, frames, n_frames, tol, &v);
        if (st) return st;
        pts[v.cls]++;
    }
    int s = pts[SOOC_SEEN_SURFACE], f = pts[SOOC_SEEN_FREE];
    *cls = s && s >= f ? SOOC_SEEN_SURFACE : f > s ? SOOC_SEEN_FREE : SOOC_SEEN_NEVER;
    return SOOC_OK;
}

/* The own-surface class of entry id (opts.own_surface): its mesh's vertices,
 * or `fallback` (its box class) when its density makes no mesh. */
static sooc_status own_surface_seen(sooc_model *m, const sooc_cogmap *map, uint64_t id, const sooc_frame *frames,
                                    int n_frames, double tol, sooc_seen_class fallback, sooc_mesh *me,
                                    sooc_seen_class *cls, int *meshed) {
    sooc_mesh_opts mo;
    sooc_mesh_opts_default(&mo);
    mo.res = 32;
    *cls = fallback, *meshed = 0;
    sooc_status st = sooc_mesh_object(m, map, id, &mo, me);
    if (st) return sooc_adderr(st, "eval real: mesh of entry %llu", (unsigned long long)id);
    if (!me->n_vert) return SOOC_OK;
    int pts[3];
    *meshed = 1;
    return sooc_eval_points_seen(me->xyz, me->n_vert, 64, frames, n_frames, tol, pts, cls);
}

/* ------------------------------------------------------------- spread */

void sooc_track_add(sooc_track *t, double x, double z, double yaw) {
    t->n++;
    double dx = x - t->mx, dz = z - t->mz;
    t->mx += dx / (double)t->n;
    t->mz += dz / (double)t->n;
    t->m2 += dx * (x - t->mx) + dz * (z - t->mz);
    t->sc += cos(yaw);
    t->ss += sin(yaw);
}

void sooc_track_spread(const sooc_track *t, double *pos_rms, double *yaw_std) {
    if (t->n <= 0) {
        if (pos_rms) *pos_rms = NAN;
        if (yaw_std) *yaw_std = NAN;
        return;
    }
    if (pos_rms) *pos_rms = sqrt(t->m2 > 0 ? t->m2 / (double)t->n : 0.0);
    if (yaw_std) {
        double R = hypot(t->sc, t->ss) / (double)t->n;
        if (R > 1) R = 1;
        *yaw_std = R > 0 ? sqrt(-2.0 * log(R)) : INFINITY;
    }
}

/* --------------------------------------------------------------- churn */

static int has_id(const uint64_t *ids, size_t n, uint64_t id) {
    for (size_t i = 0; i < n; i++)
        if (ids[i] == id) return 1;
    return 0;
}

void sooc_churn_update(sooc_churn *c, uint64_t born, const uint64_t *reg_ids, size_t n_reg,
                       const uint64_t *rem_ids, size_t n_rem) {
    c->updates++;
    for (size_t i = 0; i < n_reg; i++)
        if (reg_ids[i] >= born && !has_id(rem_ids, n_rem, reg_ids[i])) c->created++;
    for (size_t i = 0; i < n_rem; i++)
        if (rem_ids[i] < born) c->removed++;
}

/* ------------------------------------------------------- per-object IoU */

sooc_status sooc_obj_iou_add(sooc_obj_iou_acc *a, const sooc_iou_match *m) {
    if (!a || !m) return sooc_seterr(SOOC_EINVAL, "obj_iou_add: missing argument");
    for (int g = 0; g < m->n_gt; g++) {
        uint16_t id = m->gt_id[g];
        if (!id) continue;
        int k = 0;
        while (k < a->n && a->id[k] < id) k++;
        if (k == a->n || a->id[k] != id) {
            if (a->n == SOOC_METRIC_MAX_GT)
                return sooc_seterr(SOOC_EINVAL, "obj_iou: more than %d labelled objects", SOOC_METRIC_MAX_GT);
            memmove(&a->id[k + 1], &a->id[k], (size_t)(a->n - k) * sizeof a->id[0]);
            memmove(&a->sum[k + 1], &a->sum[k], (size_t)(a->n - k) * sizeof a->sum[0]);
            memmove(&a->views[k + 1], &a->views[k], (size_t)(a->n - k) * sizeof a->views[0]);
            a->id[k] = id, a->sum[k] = 0, a->views[k] = 0;
            a->n++;
        }
        a->sum[k] += m->best_iou[g];
        a->views[k]++;
    }
    return SOOC_OK;
}

double sooc_obj_iou_mean(const sooc_obj_iou_acc *a, int k) {
    if (!a || k < 0 || k >= a->n || a->views[k] <= 0) return NAN;
    return a->sum[k] / (double)a->views[k];
}

/* ------------------------------------------------------------- labels */

sooc_status sooc_eval_labels_read(const char *path, uint16_t **ids, int *w, int *h) {
    if (!path || !ids || !w || !h) return sooc_seterr(SOOC_EINVAL, "labels_read: missing argument");
    sooc_image img;
    memset(&img, 0, sizeof img);
    sooc_status st = sooc_png_read(path, &img);
    if (st) return sooc_adderr(st, "labels");
    if (img.fmt != SOOC_PIX_GRAY8 && img.fmt != SOOC_PIX_GRAY16) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: label image is %s, expected an 8- or 16-bit single-channel PNG of ids",
                         path, sooc_pixfmt_name(img.fmt));
        sooc_image_free(&img);
        return st;
    }
    size_t np = (size_t)img.width * (size_t)img.height;
    uint16_t *b = sooc_realloc(*ids, (np ? np : 1) * sizeof *b);
    if (!b) {
        sooc_image_free(&img);
        return sooc_seterr(SOOC_ENOMEM, "%s: out of memory for %dx%d labels", path, img.width, img.height);
    }
    *ids = b;
    if (img.fmt == SOOC_PIX_GRAY8) {
        const uint8_t *s = img.data;
        for (size_t i = 0; i < np; i++) b[i] = s[i];
    } else {
        memcpy(b, img.data, np * sizeof *b);
    }
    *w = img.width, *h = img.height;
    sooc_image_free(&img);
    return SOOC_OK;
}

sooc_status sooc_eval_labels_resample(const uint16_t *src, int sw, int sh, int x0, int y0, int cw, int ch,
                                      uint16_t *dst, int dw, int dh) {
    if (!src || !dst || sw <= 0 || sh <= 0 || dw <= 0 || dh <= 0 || cw <= 0 || ch <= 0 || x0 < 0 || y0 < 0 ||
        x0 + cw > sw || y0 + ch > sh)
        return sooc_seterr(SOOC_EINVAL, "labels_resample: crop (%d, %d, %d x %d) not inside %dx%d, or bad size %dx%d",
                           x0, y0, cw, ch, sw, sh, dw, dh);
    for (int v = 0; v < dh; v++) {
        int sy = y0 + (int)floor((v + 0.5) * ch / (double)dh);
        if (sy >= y0 + ch) sy = y0 + ch - 1;
        for (int u = 0; u < dw; u++) {
            int sx = x0 + (int)floor((u + 0.5) * cw / (double)dw);
            if (sx >= x0 + cw) sx = x0 + cw - 1;
            dst[(size_t)v * dw + u] = src[(size_t)sy * sw + sx];
        }
    }
    return SOOC_OK;
}

/* -------------------------------------------------------------- the runner */

void sooc_eval_real_opts_default(sooc_eval_real_opts *o) {
    memset(o, 0, sizeof *o);
    sooc_eval_run_opts_default(&o->run);
    o->query_every = SOOC_REAL_QUERY_EVERY;
    o->second_pass = 1;
    o->seen_tol = 0.25;
    o->seen_height = 0.1;
    o->persist_min = 3;
    o->own_surface = 1;
}

typedef struct real_ctx {
    sooc_mapper *mp;         /* SOOC3D, or                                        */
    sooc_global_mapper *gm;    /* the global-frame baseline (its present slots)     */
    sooc_map_entry gent[2][SOOC_MODEL_K_MAX];   /* baseline: slots before / after an update */
    size_t n_gent;
    sooc_track *tr;            /* indexed by entry id */
    size_t tr_cap;
    sooc_map_entry chg[SOOC_MAPPER_CHANGED_MAX];
} real_ctx;

/* Grow the per-id track table to hold id `need` (amortised, once per update). */
static sooc_status tracks_reserve(real_ctx *C, uint64_t need) {
    if (need < C->tr_cap) return SOOC_OK;
    size_t cap = C->tr_cap ? C->tr_cap : 64;
    while (cap <= need) cap *= 2;
    sooc_track *t = sooc_realloc(C->tr, cap * sizeof *t);
    if (!t) return sooc_seterr(SOOC_ENOMEM, "eval real: out of memory for %zu tracks", cap);
    memset(t + C->tr_cap, 0, (cap - C->tr_cap) * sizeof *t);
    C->tr = t, C->tr_cap = cap;
    return SOOC_OK;
}

/* The baseline has no changed-list: diff its present slots (ids = slot + 1)
 * before and after the update; every present slot was refined, so every one
 * is tracked. A slot that turns present again counts as created again. */
static sooc_status global_update(real_ctx *C, const sooc_frame *f, int track, sooc_churn *ch) {
    sooc_update_stats us;
    sooc_status st = sooc_global_mapper_update(C->gm, f, &us);
    if (st) return st;
    size_t n = 0;
    if ((st = sooc_global_mapper_entries(C->gm, C->gent[1], SOOC_MODEL_K_MAX, &n))) return st;
    ch->updates++;
    for (size_t k = 0; k < n; k++) {
        int was = 0;
        for (size_t j = 0; j < C->n_gent; j++) was |= C->gent[0][j].id == C->gent[1][k].id;
        ch->created += !was;
        if (track) {
            if ((st = tracks_reserve(C, C->gent[1][k].id))) return st;
            sooc_track_add(&C->tr[C->gent[1][k].id], C->gent[1][k].x, C->gent[1][k].z, C->gent[1][k].yaw);
        }
    }
    for (size_t j = 0; j < C->n_gent; j++) {
        int is = 0;
        for (size_t k = 0; k < n; k++) is |= C->gent[0][j].id == C->gent[1][k].id;
        ch->removed += !is;
    }
    memcpy(C->gent[0], C->gent[1], n * sizeof C->gent[0][0]);
    C->n_gent = n;
    return SOOC_OK;
}

static sooc_model *ctx_model(real_ctx *C) {
    return C->gm ? sooc_global_mapper_model(C->gm) : sooc_mapper_model(C->mp);
}
static const sooc_cogmap *ctx_map(const real_ctx *C) {
    return C->gm ? sooc_global_mapper_cogmap(C->gm) : sooc_mapper_cogmap(C->mp);
}

/* Map every input frame once; track=1 records positions for the spread. */
static sooc_status map_pass(real_ctx *C, const sooc_frame *frames, int n, int every, int track, sooc_churn *ch,
                            sooc_eval_real_result *res) {
    for (int i = 0; i < n; i++) {
        if (sooc_eval_real_is_query(i, every)) continue;
        if (C->gm) {
            double t0 = sooc_seconds();
            sooc_status st = global_update(C, &frames[i], track, ch);
            res->update_s += sooc_seconds() - t0;
            if (st) return sooc_adderr(st, "eval real: frame %d (index %lld)", i, (long long)frames[i].index);
            continue;
        }
        uint64_t born = sooc_mapper_next_id(C->mp);
        sooc_update_stats us;
        double t0 = sooc_seconds();
        sooc_status st = sooc_mapper_update(C->mp, &frames[i], &us);
        res->update_s += sooc_seconds() - t0;
        if (st) return sooc_adderr(st, "eval real: frame %d (index %lld)", i, (long long)frames[i].index);
        uint64_t reg[SOOC_MAPPER_CHANGED_MAX], rem[SOOC_MAPPER_CHANGED_MAX];
        size_t nc = 0, nr = 0;
        if ((st = sooc_mapper_changed(C->mp, C->chg, SOOC_MAPPER_CHANGED_MAX, &nc, rem, SOOC_MAPPER_CHANGED_MAX, &nr)))
            return st;
        for (size_t k = 0; k < nc; k++) reg[k] = C->chg[k].id;
        sooc_churn_update(ch, born, reg, nc, rem, nr);
        if (!track) continue;
        for (size_t k = 0; k < nc; k++) {
            if (has_id(rem, nr, reg[k])) continue;
            if ((st = tracks_reserve(C, reg[k]))) return st;
            sooc_track_add(&C->tr[reg[k]], C->chg[k].x, C->chg[k].z, C->chg[k].yaw);
        }
    }
    return SOOC_OK;
}

static int cmp_dbl(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of v[0..n) (sorted in place); NaN if n == 0. */
static double median_inplace(double *v, int n) {
    if (n <= 0) return NAN;
    qsort(v, (size_t)n, sizeof *v, cmp_dbl);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

sooc_status sooc_eval_real_run(sooc_model *m, const sooc_frame *frames, int n_frames,
                               const sooc_eval_real_opts *o, sooc_eval_view_fn view_cb, void *user,
                               sooc_eval_real_result *res) {
    sooc_eval_real_opts od;
    if (!o) {
        sooc_eval_real_opts_default(&od);
        o = &od;
    }
    if (!m || !res || n_frames < 0 || (n_frames && !frames))
        return sooc_seterr(SOOC_EINVAL, "eval real: bad arguments");
    memset(res, 0, sizeof *res);
    res->pos_spread_m = res->yaw_spread_deg = res->never_behind_med_m = NAN;
    if (o->query_every < 2)
        return sooc_seterr(SOOC_EINVAL, "eval real: query rule N = %d, must be >= 2", o->query_every);
    if (!(o->seen_tol > 0) || !isfinite(o->seen_height) || o->persist_min < 1)
        return sooc_seterr(SOOC_EINVAL, "eval real: bad options (seen_tol %g, seen_height %g, persist_min %d)",
                           o->seen_tol, o->seen_height, o->persist_min);
    const sooc_model_config *cfg = sooc_model_get_config(m);
    int n_lab = 0;
    for (int i = 0; i < n_frames; i++) {
        const sooc_frame *f = &frames[i];
        if (!f->has_pose)
            return sooc_seterr(SOOC_EINVAL, "eval real: frame %d (index %lld) has no pose", i, (long long)f->index);
        if (f->width != cfg->img_w || f->height != cfg->img_h)
            return sooc_seterr(SOOC_EINVAL, "eval real: frame %d (index %lld) is %dx%d, the model needs %dx%d", i,
                               (long long)f->index, f->width, f->height, cfg->img_w, cfg->img_h);
        if (sooc_eval_real_is_query(i, o->query_every)) {
            res->n_query++;
            n_lab += f->instance != NULL;
        } else {
            res->n_mapped++;
        }
    }
    res->n_frames = n_frames;
    if (!res->n_mapped || !res->n_query)
        return sooc_seterr(SOOC_EINVAL, "eval real: %d frames give %d mapped and %d query frames with N = %d (need "
                                        "at least one of each)", n_frames, res->n_mapped, res->n_query, o->query_every);
    res->has_labels = n_lab == res->n_query;

    real_ctx C;
    memset(&C, 0, sizeof C);
    sooc_model *copy = NULL;
    sooc_map_entry *ent = NULL;
    sooc_cluster_map *surf = NULL;
    uint8_t *mapped = NULL;   /* the frames pass 1 mapped (SOOC3D+ and the surfaces use them) */
    sooc_render_out rout;
    memset(&rout, 0, sizeof rout);
    int global = sooc_model_is_global(m);
    if (global && o->finetune)
        return sooc_seterr(SOOC_EINVAL, "eval real: finetuning needs a SOOC3D model, not the global-frame baseline");
    sooc_status st = sooc_model_copy_slots(m, global ? 0 : o->run.slots, &copy);
    if (st) return sooc_adderr(st, "eval real: model copy");
    if ((o->run.d_clip > 0 && (st = sooc_model_set_clip(copy, (float)o->run.d_clip))) ||
        (o->run.invalid_depth > 0 && (st = sooc_model_set_invalid_depth(copy, o->run.invalid_depth - 1)))) {
        sooc_model_destroy(copy);
        return st;
    }
    if (global) {   /* every slot of the fixed set (n_objects unknown: K) */
        if ((st = sooc_global_mapper_create(&C.gm, copy, 0, o->run.iterations, o->run.seed, o->run.threads))) {
            sooc_model_destroy(copy);
            return st;
        }
        sooc_global_mapper_set_latents(C.gm, o->run.latents);
    } else {
        if ((st = sooc_mapper_create_with_model(&C.mp, copy, o->run.iterations, o->run.seed, o->run.threads))) {
            sooc_model_destroy(copy);
            return st;
        }
        sooc_mapper_set_merge_radius(C.mp, o->run.merge_radius);
        sooc_mapper_set_merge_neighbours(C.mp, o->run.revisit);
        sooc_mapper_set_gate(C.mp, o->run.gate[0], o->run.gate[1], o->run.gate[2]);
        sooc_mapper_set_latents(C.mp, o->run.latents);
        if (o->run.proposals && (st = sooc_mapper_set_proposals(C.mp, o->run.proposals))) goto done;
        if (o->run.geo_support_m > 0 && (st = sooc_mapper_set_support(C.mp, o->run.geo_support_m))) goto done;
        sooc_mapper_set_surface_boxes(C.mp, o->run.surface_boxes);
    }

    /* pass 1 */
    if ((st = map_pass(&C, frames, n_frames, o->query_every, 1, &res->churn, res))) goto done;
    res->entries_final = sooc_cogmap_count(ctx_map(&C));

    if (o->finetune || (o->run.surface && C.mp)) {
        if (!(mapped = sooc_malloc((size_t)(n_frames ? n_frames : 1)))) {
            st = sooc_seterr(SOOC_ENOMEM, "eval real: out of memory");
            goto done;
        }
        for (int i = 0; i < n_frames; i++) mapped[i] = !sooc_eval_real_is_query(i, o->query_every);
    }

    /* SOOC3D+: finetune the pass-1 map on the mapped frames (the decoders go
     * into the mapper's map as payloads; its tight boxes are stale after) */
    if (o->finetune) {
        double t0 = sooc_seconds();
        st = sooc_eval_finetune_map(ctx_model(&C), (sooc_cogmap *)ctx_map(&C), frames, n_frames, mapped, o->finetune,
                                    o->run.birth, o->run.threads, o->ft_progress, o->ft_user, &res->n_born,
                                    &res->n_pruned);
        res->churn.created += res->n_born;
        res->churn.removed += res->n_pruned;
        res->entries_final = sooc_cogmap_count(ctx_map(&C));
        res->finetune_s = sooc_seconds() - t0;
        if (st) goto done;
        sooc_mapper_geometry_invalidate(C.mp);
    }

    /* the entries' observed surfaces: the mapped frames' clusters */
    if (o->run.surface && C.mp && (st = sooc_eval_cluster_map(o->run.surface, frames, n_frames, mapped, &surf)))
        goto done;

    /* query frames from the pass-1 map */
    for (int i = 0; i < n_frames && !st; i++) {
        if (!sooc_eval_real_is_query(i, o->query_every)) continue;
        sooc_view_metrics vm;
        sooc_iou_match match;
        uint64_t ids[SOOC_RENDER_MAX_COMP];
        double xz[2 * SOOC_RENDER_MAX_COMP];
        int nc = 0;
        double t0 = sooc_seconds();
        st = sooc_eval_map_view(ctx_model(&C), ctx_map(&C), &frames[i], NULL, 0, &o->run,
                                0, &rout, &vm, &match, ids, xz, &nc);
        if (!st && surf) {
            const sooc_model_config *mc = sooc_model_get_config(ctx_model(&C));   /* the clip as rendered */
            st = sooc_eval_surface_view(ctx_model(&C), ctx_map(&C), surf, &frames[i], NULL, 0, o->run.max_obj,
                                        &o->run.surface_p, mc->d_clip * mc->unit_m, xz, &rout, &vm, &match);
        }
        res->render_s += sooc_seconds() - t0;
        if (st) break;
        vm.is_query = 1;
        sooc_metric_sums_add_view(&res->query, &vm);
        if (frames[i].instance && (st = sooc_obj_iou_add(&res->obj, &match))) break;
        if (view_cb) {
            sooc_eval_view_info vi = {i, &frames[i], 0, res->n_mapped, &rout, &vm,
                                      frames[i].instance ? &match : NULL, nc, ids, xz};
            st = view_cb(user, &vi);
        }
    }
    if (st) goto done;

    /* persistent entries and the free-space test on the pass-1 map (every
     * entry's tight box brought up to date first: the mapper computes a
     * bounded number per keyframe) */
    {
        size_t ne = 0;
        if (C.mp && (st = sooc_mapper_refresh_geometry(C.mp, -1, NULL))) goto done;
        if ((st = C.gm ? sooc_global_mapper_entries(C.gm, NULL, 0, &ne) : sooc_mapper_entries(C.mp, NULL, 0, &ne)))
            goto done;
        if (!(ent = sooc_calloc(ne ? ne : 1, sizeof *ent))) {
            st = sooc_seterr(SOOC_ENOMEM, "eval real: out of memory for %zu entries", ne);
            goto done;
        }
        if ((st = C.gm ? sooc_global_mapper_entries(C.gm, ent, ne, &ne) : sooc_mapper_entries(C.mp, ent, ne, &ne)))
            goto done;
        double ps = 0, ys = 0, *beh = sooc_calloc(ne ? ne : 1, sizeof *beh);
        if (!beh) {
            st = sooc_seterr(SOOC_ENOMEM, "eval real: out of memory for %zu entries", ne);
            goto done;
        }
        int nb = 0;
        for (size_t k = 0; k < ne; k++) {
            uint64_t id = ent[k].id;
            if (id < C.tr_cap && C.tr[id].n >= o->persist_min) {
                double pr, yr;
                sooc_track_spread(&C.tr[id], &pr, &yr);
                ps += pr, ys += yr;
                res->n_persistent++;
            }
            const sooc_map_geometry *g = &ent[k].geom;
            res->n_seen_box += (g->flags & SOOC_GEOM_TIGHT) && !(g->flags & SOOC_GEOM_EMPTY);
            res->n_empty += (g->flags & SOOC_GEOM_EMPTY) != 0;
            sooc_seen_votes sv;
            if ((st = sooc_eval_entry_seen(&ent[k], o->seen_height, frames, n_frames, o->seen_tol, &sv))) {
                sooc_free(beh);
                goto done;
            }
            res->n_seen[sv.cls]++;
            if (o->own_surface && C.mp) {
                sooc_mesh me;
                memset(&me, 0, sizeof me);
                sooc_seen_class oc;
                int meshed;
                st = own_surface_seen(ctx_model(&C), ctx_map(&C), id, frames, n_frames, o->seen_tol, sv.cls, &me,
                                      &oc, &meshed);
                sooc_mesh_free(&me);
                if (st) {
                    sooc_free(beh);
                    goto done;
                }
                res->n_seen_own[oc]++;
                res->n_own_mesh += meshed;
            }
            if (sv.cls == SOOC_SEEN_NEVER && isfinite(sv.min_behind)) beh[nb++] = sv.min_behind;
        }
        res->n_never_behind = nb;
        res->never_behind_med_m = median_inplace(beh, nb);
        sooc_free(beh);
        /* the planner's boxes against the labelled objects, from every labelled frame */
        for (int k = 0; res->has_labels && k < res->obj.n && !st; k++)
            st = sooc_eval_box_fit(ent, ne, frames, n_frames, NULL, res->obj.id[k], &res->obj_box[k]);
        if (st) goto done;
        if (res->n_persistent) {
            res->pos_spread_m = ps / res->n_persistent;
            res->yaw_spread_deg = ys / res->n_persistent * 180.0 / M_PI;
        }
    }

    /* pass 2: the same input frames again, into the same map */
    if (sooc_eval_real_second_pass(o) && (st = map_pass(&C, frames, n_frames, o->query_every, 0, &res->churn2, res))) goto done;
    res->entries_pass2 = sooc_cogmap_count(ctx_map(&C));

done:
    sooc_render_out_free(&rout);
    sooc_cluster_map_destroy(surf);
    sooc_free(mapped);
    sooc_free(ent);
    sooc_free(C.tr);
    sooc_mapper_destroy(C.mp);
    sooc_global_mapper_destroy(C.gm);
    return st;
}

/* ---------------------------------------------------------------- JSON */

/* element k of a JSON array: a number, or null */
static void jb_arr_num(sooc_strbuf *b, int k, double v) {
    if (isfinite(v)) sooc_strbuf_printf(b, "%s%.6g", k ? ", " : "", v);
    else sooc_strbuf_printf(b, "%snull", k ? ", " : "");
}

static void jb_num(sooc_strbuf *b, const char *key, double v) {
    if (isfinite(v)) sooc_strbuf_printf(b, ", \"%s\": %.6g", key, v);
    else sooc_strbuf_printf(b, ", \"%s\": null", key);
}

static void jb_str(sooc_strbuf *b, const char *s) {
    sooc_strbuf_printf(b, "\"");
    for (; s && *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') sooc_strbuf_printf(b, "\\%c", c);
        else if (c < 0x20) sooc_strbuf_printf(b, "\\u%04x", c);
        else sooc_strbuf_printf(b, "%c", c);
    }
    sooc_strbuf_printf(b, "\"");
}

sooc_status sooc_eval_real_json(const char *model, const char *sequence, const char *path,
                                const sooc_eval_real_opts *o, const sooc_eval_real_result *r, char **out) {
    if (!model || !sequence || !o || !r || !out) return sooc_seterr(SOOC_EINVAL, "eval real json: missing argument");
    sooc_strbuf b = {0};
    sooc_metric_means mm;
    sooc_metric_sums_means(&r->query, &mm);
    sooc_strbuf_printf(&b, "{\"model\": ");
    jb_str(&b, model);
    sooc_strbuf_printf(&b, ", \"sequence\": ");
    jb_str(&b, sequence);
    sooc_strbuf_printf(&b, ", \"path\": ");
    jb_str(&b, path ? path : "");
    sooc_strbuf_printf(&b, ", \"scale\": \"real\", \"view\": \"Q\"");
    jb_num(&b, "depth_rmse", mm.depth_rmse);
    jb_num(&b, "rgb_rmse", mm.rgb_rmse);
    sooc_strbuf_printf(&b, ", \"entries_final\": %zu, \"entries_created\": %ld", r->entries_final, r->churn.created);
    if (r->has_labels) {
        sooc_strbuf_printf(&b, ", \"labels\": \"%s\"", o->labels_predicted ? "predicted" : "ground_truth");
        jb_num(&b, "miou", mm.miou_best);
        jb_num(&b, "miou_hungarian", mm.miou_hung);
        sooc_strbuf_printf(&b, ", \"obj_ids\": [");
        for (int k = 0; k < r->obj.n; k++) sooc_strbuf_printf(&b, "%s%u", k ? ", " : "", (unsigned)r->obj.id[k]);
        sooc_strbuf_printf(&b, "], \"obj_iou\": [");
        for (int k = 0; k < r->obj.n; k++) {
            double v = sooc_obj_iou_mean(&r->obj, k);
            if (isfinite(v)) sooc_strbuf_printf(&b, "%s%.6g", k ? ", " : "", v);
            else sooc_strbuf_printf(&b, "%snull", k ? ", " : "");
        }
        sooc_strbuf_printf(&b, "], \"obj_box_cover\": [");
        for (int k = 0; k < r->obj.n; k++) jb_arr_num(&b, k, r->obj_box[k].cover);
        sooc_strbuf_printf(&b, "], \"obj_box_height_err_m\": [");
        for (int k = 0; k < r->obj.n; k++) jb_arr_num(&b, k, r->obj_box[k].height_err_m);
        sooc_strbuf_printf(&b, "], \"obj_box_area_ratio\": [");
        for (int k = 0; k < r->obj.n; k++) jb_arr_num(&b, k, r->obj_box[k].area_ratio);
        sooc_strbuf_printf(&b, "], \"obj_views\": [");
        for (int k = 0; k < r->obj.n; k++) sooc_strbuf_printf(&b, "%s%ld", k ? ", " : "", r->obj.views[k]);
        sooc_strbuf_printf(&b, "]");
        jb_num(&b, "rgb_rmse_obj", mm.rgb_rmse_obj);
    }
    sooc_strbuf_printf(&b, ", \"entries_removed\": %ld", r->churn.removed);
    jb_num(&b, "churn", r->churn.created ? (double)r->churn.removed / (double)r->churn.created : NAN);
    int pass2 = sooc_eval_real_second_pass(o);
    sooc_strbuf_printf(&b, ", \"second_pass\": %d, \"entries_pass2\": %zu, \"entries_created_pass2\": %ld, "
                  "\"entries_removed_pass2\": %ld",
              pass2, r->entries_pass2, r->churn2.created, r->churn2.removed);
    jb_num(&b, "growth", pass2 && r->entries_final
                             ? ((double)r->entries_pass2 - (double)r->entries_final) / (double)r->entries_final
                             : NAN);
    sooc_strbuf_printf(&b, ", \"persistent\": %d, \"persist_min\": %d", r->n_persistent, o->persist_min);
    jb_num(&b, "pos_spread_m", r->pos_spread_m);
    jb_num(&b, "yaw_spread_deg", r->yaw_spread_deg);
    double ne = (double)(r->n_seen[0] + r->n_seen[1] + r->n_seen[2]);
    jb_num(&b, "free_frac", ne > 0 ? r->n_seen[SOOC_SEEN_FREE] / ne : NAN);
    sooc_strbuf_printf(&b, ", \"seen_box_n\": %d, \"empty_n\": %d", r->n_seen_box, r->n_empty);
    jb_num(&b, "never_seen_frac", ne > 0 ? r->n_seen[SOOC_SEEN_NEVER] / ne : NAN);
    jb_num(&b, "surface_frac", ne > 0 ? r->n_seen[SOOC_SEEN_SURFACE] / ne : NAN);
    double no = (double)(r->n_seen_own[0] + r->n_seen_own[1] + r->n_seen_own[2]);
    if (no > 0) {   /* the own-surface rule (opts.own_surface) */
        jb_num(&b, "free_frac_own", r->n_seen_own[SOOC_SEEN_FREE] / no);
        jb_num(&b, "never_seen_frac_own", r->n_seen_own[SOOC_SEEN_NEVER] / no);
        sooc_strbuf_printf(&b, ", \"own_mesh_n\": %d", r->n_own_mesh);
    }
    sooc_strbuf_printf(&b, ", \"never_seen_behind_n\": %d", r->n_never_behind);
    jb_num(&b, "never_seen_behind_median_m", r->never_behind_med_m);
    jb_num(&b, "seen_tol_m", o->seen_tol);
    jb_num(&b, "seen_height_m", o->seen_height);
    sooc_strbuf_printf(&b, ", \"frames\": %d, \"frames_mapped\": %d, \"frames_query\": %d, \"query_every\": %d", r->n_frames,
              r->n_mapped, r->n_query, o->query_every);
    sooc_strbuf_printf(&b, ", \"views_depth\": %ld, \"views_rgb\": %ld", r->query.n_depth, r->query.n_rgb);
    jb_num(&b, "update_ms", r->n_mapped ? 1e3 * r->update_s / (double)(r->n_mapped * (pass2 ? 2 : 1)) : NAN);
    sooc_strbuf_printf(&b, ", \"finetuned\": %s", o->finetune ? "true" : "false");
    if (o->finetune)
        sooc_strbuf_printf(&b,
                  ", \"ft_iterations\": %d, \"ft_rays\": %d, \"ft_lr\": %g, \"finetune_s\": %.3f, \"births\": %s, "
                  "\"born\": %d, \"ft_removed\": %d",
                  o->finetune->iterations, o->finetune->rays, (double)o->finetune->lr, r->finetune_s,
                  o->run.birth ? "true" : "false", r->n_born, r->n_pruned);
    sooc_strbuf_printf(&b, "}");
    if (b.oom) {
        sooc_free(b.p);
        return sooc_seterr(SOOC_ENOMEM, "eval real json: out of memory");
    }
    *out = b.p;
    return SOOC_OK;
}
