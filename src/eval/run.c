/* The scene runner: the one evaluation path (eval.h "the scene runner").
 * Online inference over a scene's input views with a fresh mapper, then
 * render + score every view from the map (query views from the final map,
 * input views from the final map and/or right after their own update). */
#include "sooc3d/cogmap.h"
#include "sooc3d/train.h"
#include "sooc3d/eval.h"
#include "sooc3d/render.h"
#include "eval/eval_geom.h"

#include <math.h>
#include <string.h>

int sooc_eval_timing_parse(const char *s) {
    if (!s) return -1;
    if (!strcmp(s, "final")) return SOOC_EVAL_FINAL;
    if (!strcmp(s, "online")) return SOOC_EVAL_ONLINE;
    if (!strcmp(s, "both")) return SOOC_EVAL_BOTH;
    return -1;
}

const char *sooc_eval_timing_note(sooc_eval_timing t) {
    switch (t) {
    case SOOC_EVAL_FINAL:
        return "Input views (I) are rendered from the final map, after all input views were mapped; "
               "query views (Q) always from the final map.";
    case SOOC_EVAL_ONLINE:
        return "Input views (I) are rendered right after their own update (MulMON protocol); "
               "query views (Q) always from the final map.";
    case SOOC_EVAL_BOTH:
        return "Input views (I) are rendered from the final map (rows without a suffix) and right after "
               "their own update (rows marked 'online', MulMON protocol); query views (Q) always from the "
               "final map.";
    }
    return "";
}

void sooc_eval_run_opts_default(sooc_eval_run_opts *o) {
    memset(o, 0, sizeof *o);
    o->seed = 1;
    o->timing = SOOC_EVAL_FINAL;
    o->n_coarse = 96;
    o->n_fine = 32;
    sooc_surface_params_default(&o->surface_p);
}

sooc_status sooc_eval_model_copy(sooc_model *m, sooc_model **out) {
    sooc_status st = sooc_model_copy_slots(m, 0, out);
    return st ? sooc_adderr(st, "eval: model copy") : SOOC_OK;
}

/* ---------------------------------------------------- one view from a map */

typedef struct unc_sampler {
    sooc_model *m;
    const sooc_cogmap *map;
    const sooc_frame *gt;
    const sooc_intrinsics *K;
    int max_obj;
    uint64_t seed;
    sooc_model_field *cur;
} unc_sampler;

static sooc_status unc_get(void *user, int s, sooc_field *f) {
    unc_sampler *u = user;
    sooc_rng rng;
    sooc_rng_seed(&rng, u->seed + 0x9e3779b97f4a7c15ULL * (uint64_t)(s + 1), 0x756e63ULL ^ (uint64_t)u->gt->index);
    sooc_model_field_destroy(u->cur);
    u->cur = NULL;
    sooc_status st = sooc_model_field_create(&u->cur, u->m, u->map, u->gt->T_wc, u->K, u->max_obj, &rng);
    if (st) return st;
    *f = *sooc_model_field_get(u->cur);
    return SOOC_OK;
}

static void unc_release(void *user, int s, sooc_field *f) {
    (void)s;
    (void)f;
    unc_sampler *u = user;
    sooc_model_field_destroy(u->cur);
    u->cur = NULL;
}

sooc_status sooc_eval_map_view(sooc_model *m, const sooc_cogmap *map, const sooc_frame *gt,
                               const sooc_gt_object *gt_obj, int n_gt, const sooc_eval_run_opts *o,
                               int detail, sooc_render_out *out, sooc_view_metrics *vm,
                               sooc_iou_match *match, uint64_t *comp_ids, double *comp_xz, int *n_comp) {
    sooc_eval_run_opts od;
    if (!o) {
        sooc_eval_run_opts_default(&od);
        o = &od;
    }
    if (!m || !map || !gt || !out || !vm) return sooc_seterr(SOOC_EINVAL, "eval_map_view: missing argument");
    if (!gt->has_pose)
        return sooc_seterr(SOOC_EINVAL, "eval: frame %lld has no pose", (long long)gt->index);
    const sooc_model_config *c = sooc_model_get_config(m);
    int max_obj = o->max_obj > 0 ? o->max_obj : SOOC_RENDER_MAX_COMP - 1;   /* docs/metrics.md: every in-view object */
    if (max_obj > SOOC_RENDER_MAX_COMP - 1) max_obj = SOOC_RENDER_MAX_COMP - 1;
    sooc_intrinsics K = gt->K;
    K.width = gt->width;
    K.height = gt->height;
    sooc_render_opts ro;
    sooc_render_opts_default(&ro);
    ro.n_coarse = o->n_coarse > 0 ? o->n_coarse : 96;
    ro.n_fine = o->n_fine >= 0 ? o->n_fine : 0;
    ro.t_near = c->t_near * c->unit_m;   /* metres (config.unit_m) */
    ro.d_clip = c->d_clip * c->unit_m;
    ro.threads = o->threads;
    ro.components = detail && o->components;
    sooc_model_field *fld = NULL;
    sooc_status st = sooc_model_field_create(&fld, m, map, gt->T_wc, &K, max_obj, NULL);
    if (st) return sooc_adderr(st, "eval: frame %lld", (long long)gt->index);
    const sooc_field *field = sooc_model_field_get(fld);
    double T_fc[16], xz[2 * SOOC_RENDER_MAX_COMP];
    sooc_model_field_T_fc(fld, T_fc);
    int nc = field->n_comp;
    for (int k = 0; k < nc; k++) {
        sooc_cogmap_entry e;
        uint64_t id = sooc_model_field_comp_id(fld, k);
        if (comp_ids) comp_ids[k] = id;
        if (id && sooc_cogmap_get(map, id, &e) == SOOC_OK) {
            xz[2 * k] = e.X;
            xz[2 * k + 1] = e.Z;
        } else {
            sooc_clearerr();
            xz[2 * k] = xz[2 * k + 1] = NAN;
        }
    }
    if (comp_xz) memcpy(comp_xz, xz, sizeof(double) * 2 * (size_t)nc);
    if (n_comp) *n_comp = nc;
    st = sooc_eval_view(field, T_fc, gt, &ro, xz, gt_obj, n_gt, out, vm, match);
    sooc_model_field_destroy(fld);
    if (!st && detail && o->uncertainty >= 2) {
        unc_sampler u = {m, map, gt, &K, max_obj, o->seed, NULL};
        sooc_field_sampler smp = {unc_get, unc_release, &u};
        ro.components = 0;
        st = sooc_render_uncertainty(&smp, o->uncertainty, &K, T_fc, &ro, out);
        sooc_model_field_destroy(u.cur);
        if (st) sooc_adderr(st, "eval: uncertainty of frame %lld", (long long)gt->index);
    }
    return st;
}

sooc_status sooc_eval_finetune_map(sooc_model *m, sooc_cogmap *map, const sooc_frame *frames, int n_frames,
                                   const uint8_t *use, const sooc_finetune_params *fp, const sooc_birth_params *bp,
                                   int threads, sooc_finetune_progress_fn cb, void *user, int *n_born, int *n_pruned) {
    *n_born = *n_pruned = 0;
    sooc_status st = SOOC_OK;
    if (bp) {
        sooc_birth *b = NULL;
        st = sooc_birth_create(&b, m, map, bp, threads);
        for (int i = 0; i < n_frames && !st; i++)
            if (use[i]) st = sooc_birth_add_view(b, &frames[i]);
        if (!st) st = sooc_birth_run(b, NULL, 0, n_born);
        sooc_birth_destroy(b);
    }
    sooc_finetune *ft = NULL;
    if (!st) st = sooc_finetune_create(&ft, m, map, fp);
    for (int i = 0; i < n_frames && !st; i++)
        if (use[i]) st = sooc_finetune_add_view(ft, &frames[i]);
    if (!st) st = sooc_finetune_run_all(ft, cb, user, cb ? 50 : 0);
    sooc_finetune_destroy(ft);
    if (!st && bp) st = sooc_birth_prune_all(m, map, NULL, n_pruned);
    return st;
}

/* ------------------------------------------------------------- the runner */

static double dist2_cam(const sooc_frame *a, const sooc_frame *b) {
    double dx = a->T_wc[3] - b->T_wc[3], dy = a->T_wc[7] - b->T_wc[7], dz = a->T_wc[11] - b->T_wc[11];
    return dx * dx + dy * dy + dz * dz;
}

typedef struct run_ctx {
    sooc_model *model;
    const sooc_cogmap *map;
    const sooc_frame *frames;
    const sooc_gt_object *gt;
    int n_gt;
    const sooc_eval_run_opts *o;
    sooc_eval_view_fn view_cb;
    void *user;
    sooc_render_out rout;
    sooc_eval_scene_result *res;
    sooc_cluster_map *surf;   /* the entries' observed surfaces (o->surface), for the final map's views */
} run_ctx;

static sooc_status score_view(run_ctx *C, int i, int online, int n_mapped, sooc_metric_sums *sums) {
    const sooc_frame *f = &C->frames[i];
    if (C->o->render_views && !C->o->render_views[i]) return SOOC_OK;
    int detail = !C->o->detail_views || C->o->detail_views[i];
    sooc_view_metrics vm;
    sooc_iou_match match;
    uint64_t ids[SOOC_RENDER_MAX_COMP];
    double xz[2 * SOOC_RENDER_MAX_COMP];
    int nc = 0;
    double t0 = sooc_seconds();
    sooc_status st = sooc_eval_map_view(C->model, C->map, f, C->gt, C->n_gt, C->o, detail, &C->rout, &vm, &match,
                                        ids, xz, &nc);
    if (!st && C->surf && !online) {
        const sooc_model_config *c = sooc_model_get_config(C->model);
        st = sooc_eval_surface_view(C->model, C->map, C->surf, f, C->gt, C->n_gt, C->o->max_obj, &C->o->surface_p,
                                    c->d_clip * c->unit_m, xz, &C->rout, &vm, &match);
    }
    C->res->render_s += sooc_seconds() - t0;
    if (st) return st;
    sooc_metric_sums_add_view(sums, &vm);
    if (!C->view_cb) return SOOC_OK;
    sooc_eval_view_info vi = {i, f, online, n_mapped, &C->rout, &vm, f->instance ? &match : NULL, nc, ids, xz};
    return C->view_cb(C->user, &vi);
}

/* Object geometry of the final map against the scene (eval_geom.h): every
 * stale tight box is computed (all of them after finetuning), then the
 * matched objects' extent errors, position-sigma coverage and symmetry flags
 * go into the geometry sums of every cell of the scene. */
static sooc_status geometry_scene(sooc_mapper *mp, const struct sooc_scene *sc, int finetuned,
                                  sooc_eval_scene_result *res) {
    if (finetuned) sooc_mapper_geometry_invalidate(mp);
    sooc_status st = sooc_mapper_refresh_geometry(mp, -1, NULL);
    size_t n = 0;
    if (!st) st = sooc_mapper_entries(mp, NULL, 0, &n);
    if (st) return st;
    sooc_map_entry *e = sooc_calloc(n + 1, sizeof *e);
    sooc_geom_match *mt = sooc_calloc((size_t)sc->n_objects + 1, sizeof *mt);
    int nm = 0;
    if (!e || !mt) st = sooc_seterr(SOOC_ENOMEM, "eval: object geometry: out of memory");
    if (!st) st = sooc_mapper_entries(mp, e, n, &n);
    if (!st) st = sooc_geom_eval_scene(e, n, sc, 0.5, mt, &nm);
    sooc_geom_sums g;
    memset(&g, 0, sizeof g);
    for (int i = 0; !st && i < nm; i++) {
        const sooc_geom_match *r = &mt[i];
        g.n_axis += 2;
        g.n_axis_within += (fabs(r->err_x) <= r->sig_x) + (fabs(r->err_z) <= r->sig_z);
        if (!r->tight) continue;
        sooc_geom_sums_add_extent(&g, r->ext_err_cm);
        g.n_sym++;
        g.n_sym_agree += r->sym_pred == r->sym_gt;
    }
    sooc_metric_sums *cells[3] = {&res->input_final, &res->input_online, &res->query};
    for (int k = 0; k < 3 && !st; k++) {
        sooc_metric_sums add;
        memset(&add, 0, sizeof add);
        add.geom = g;
        sooc_metric_sums_merge(cells[k], &add);
    }
    sooc_free(e);
    sooc_free(mt);
    return st;
}

sooc_status sooc_eval_run_scene(sooc_model *m, const sooc_frame *frames, int n_frames,
                                const sooc_gt_object *gt, int n_gt, const sooc_eval_run_opts *o,
                                sooc_eval_view_fn view_cb, sooc_eval_step_fn step_cb, void *user,
                                sooc_eval_scene_result *res) {
    sooc_eval_run_opts od;
    if (!o) {
        sooc_eval_run_opts_default(&od);
        o = &od;
    }
    sooc_eval_scene_result res_local;
    if (!res) res = &res_local;
    memset(res, 0, sizeof *res);
    if (!m || (!frames && n_frames) || n_frames < 0 || n_gt < 0 || (n_gt && !gt))
        return sooc_seterr(SOOC_EINVAL, "eval_run_scene: bad arguments");
    if (o->timing < SOOC_EVAL_FINAL || o->timing > SOOC_EVAL_BOTH)
        return sooc_seterr(SOOC_EINVAL, "eval_run_scene: bad input-view timing %d", (int)o->timing);
    if (o->uncertainty == 1) return sooc_seterr(SOOC_EINVAL, "eval_run_scene: uncertainty needs >= 2 samples");
    for (int i = 0; i < n_frames; i++)
        if (!frames[i].has_pose)
            return sooc_seterr(SOOC_EINVAL, "eval: frame %d (index %lld) has no pose", i, (long long)frames[i].index);

    /* which views take part */
    uint8_t *use = sooc_calloc(n_frames ? (size_t)n_frames : 1, 1);
    if (!use) return SOOC_ENOMEM;
    int n_in = 0;
    for (int i = 0; i < n_frames; i++)
        if (!frames[i].is_query) use[i] = (o->max_views <= 0 || n_in++ < o->max_views);
    for (int i = 0; i < n_frames; i++) {
        if (!frames[i].is_query) continue;
        if (o->max_views <= 0) {
            use[i] = 1;
            continue;
        }
        int best = -1;
        double bd = INFINITY;
        for (int j = 0; j < n_frames; j++)
            if (!frames[j].is_query && dist2_cam(&frames[i], &frames[j]) < bd) bd = dist2_cam(&frames[i], &frames[j]), best = j;
        use[i] = best >= 0 && use[best];
    }

    sooc_model *copy = NULL;
    sooc_mapper *mp = NULL;
    sooc_global_mapper *gm = NULL;   /* global-frame baseline: its fixed slot set is the "map" */
    sooc_map_entry *ent = NULL;
    size_t ent_cap = 0;
    run_ctx C;
    memset(&C, 0, sizeof C);
    sooc_status st = sooc_model_copy_slots(m, sooc_model_is_global(m) ? 0 : o->slots, &copy);
    if (st) goto done;
    if ((o->d_clip > 0 && (st = sooc_model_set_clip(copy, (float)o->d_clip))) ||
        (o->invalid_depth > 0 && (st = sooc_model_set_invalid_depth(copy, o->invalid_depth - 1)))) {
        sooc_model_destroy(copy);
        goto done;
    }
    if (sooc_model_is_global(copy)) {
        if ((st = sooc_global_mapper_create(&gm, copy, n_gt, o->iterations, o->seed, o->threads))) {
            sooc_model_destroy(copy);
            goto done;
        }
        sooc_global_mapper_set_latents(gm, o->latents);
        C.model = sooc_global_mapper_model(gm);
        C.map = sooc_global_mapper_cogmap(gm);
    } else {
        if ((st = sooc_mapper_create_with_model(&mp, copy, o->iterations, o->seed, o->threads))) {
            sooc_model_destroy(copy);
            goto done;
        }
        sooc_mapper_set_merge_radius(mp, o->merge_radius);
        sooc_mapper_set_merge_neighbours(mp, o->revisit);
        sooc_mapper_set_gate(mp, o->gate[0], o->gate[1], o->gate[2]);
        sooc_mapper_set_latents(mp, o->latents);
        if (o->proposals && (st = sooc_mapper_set_proposals(mp, o->proposals))) goto done;
        if (o->geo_support_m > 0 && (st = sooc_mapper_set_support(mp, o->geo_support_m))) goto done;
        C.model = sooc_mapper_model(mp);
        C.map = sooc_mapper_cogmap(mp);
    }
    C.frames = frames, C.gt = gt, C.n_gt = n_gt, C.o = o, C.view_cb = view_cb, C.user = user, C.res = res;

    /* online inference over the input views */
    for (int i = 0; i < n_frames && !st; i++) {
        if (!use[i] || frames[i].is_query) continue;
        sooc_update_stats us;
        double t0 = sooc_seconds();
        if ((st = gm ? sooc_global_mapper_update(gm, &frames[i], &us) : sooc_mapper_update(mp, &frames[i], &us)))
            break;
        res->update_s += sooc_seconds() - t0;
        res->n_mapped++;
        if (step_cb) {
            size_t n = 0;
            if (gm) sooc_global_mapper_entries(gm, NULL, 0, &n);
            else sooc_mapper_entries(mp, NULL, 0, &n);
            if (n > ent_cap) {
                sooc_free(ent);
                ent_cap = n + n / 2 + 16;
                ent = sooc_malloc(ent_cap * sizeof *ent);
                if (!ent) {
                    st = SOOC_ENOMEM;
                    break;
                }
            }
            if ((st = gm ? sooc_global_mapper_entries(gm, ent, ent_cap, &n) : sooc_mapper_entries(mp, ent, ent_cap, &n)))
                break;
            sooc_eval_step_info si = {res->n_mapped - 1, i, &frames[i], &us, ent, n};
            if ((st = step_cb(user, &si))) break;
        }
        if (o->timing & SOOC_EVAL_ONLINE) st = score_view(&C, i, 1, res->n_mapped, &res->input_online);
    }
    /* the mapped input views (SOOC3D+ finetunes on them, the surfaces are drawn from them) */
    uint8_t *inp = NULL;
    if (!st && mp && (o->finetune || o->surface)) {
        if (!(inp = sooc_malloc((size_t)(n_frames ? n_frames : 1)))) st = sooc_seterr(SOOC_ENOMEM, "eval: out of memory");
        for (int i = 0; i < n_frames && inp; i++) inp[i] = use[i] && !frames[i].is_query;
    }
    /* SOOC3D+: finetune the final map's objects and blocks on the mapped input views */
    if (!st && o->finetune && mp) {
        double t0 = sooc_seconds();
        /* the mapper owns its map; the finetuned decoders go into it as payloads */
        st = sooc_eval_finetune_map(C.model, (sooc_cogmap *)C.map, frames, n_frames, inp, o->finetune, o->birth,
                                    o->threads, NULL, NULL, &res->n_born, &res->n_pruned);
        res->finetune_s = sooc_seconds() - t0;
    }
    /* the entries' observed surfaces: the mapped input views' clusters */
    if (!st && o->surface && mp) st = sooc_eval_cluster_map(o->surface, frames, n_frames, inp, &C.surf);
    sooc_free(inp);
    /* everything else from the final map */
    for (int i = 0; i < n_frames && !st; i++) {
        if (!use[i]) continue;
        if (frames[i].is_query) {
            st = score_view(&C, i, 0, res->n_mapped, &res->query);
            res->n_query++;
        } else if (o->timing & SOOC_EVAL_FINAL) {
            st = score_view(&C, i, 0, res->n_mapped, &res->input_final);
        }
    }
    if (!st) res->n_entries = sooc_cogmap_count(C.map);
    if (!st && o->scene) {   /* mesh accuracy / completeness of the final map (docs/mesh.md) */
        sooc_mesh_opts mo;
        sooc_mesh_opts_default(&mo);
        if (o->mesh_res > 0) mo.res = o->mesh_res;
        mo.threads = o->threads;
        sooc_mesh_metric mm;
        double t0 = sooc_seconds();
        st = sooc_mesh_eval_scene(C.model, C.map, o->scene, &mo, &mm);
        res->mesh_s = sooc_seconds() - t0;
        if (!st) {
            res->mesh_objects = mm.n_objects, res->mesh_empty = mm.n_empty;
            sooc_mesh_sums ms = {mm.n_objects, mm.n_objects * mm.acc_cm, mm.n_objects * mm.comp_cm,
                                 mm.n_objects * mm.fscore};
            if (mm.n_objects) {
                sooc_metric_sums *cells[3] = {&res->input_final, &res->input_online, &res->query};
                for (int k = 0; k < 3; k++) {
                    cells[k]->mesh.n_obj += ms.n_obj, cells[k]->mesh.acc_cm += ms.acc_cm;
                    cells[k]->mesh.comp_cm += ms.comp_cm, cells[k]->mesh.fscore += ms.fscore;
                }
            }
        }
    }
    if (!st && o->scene && mp) st = geometry_scene(mp, o->scene, o->finetune != NULL, res);
done:
    sooc_render_out_free(&C.rout);
    sooc_cluster_map_destroy(C.surf);
    sooc_free(ent);
    sooc_mapper_destroy(mp);
    sooc_global_mapper_destroy(gm);
    sooc_free(use);
    return st;
}
