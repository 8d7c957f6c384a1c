/* The MulMON-style global-frame baseline (src/model/global.c, docs/baseline.md):
 *  1. finite-difference check of d(total)/d(params) of the global training step
 *     (T = 3 input views carrying one slot set, L = 2, one query view) w.r.t.
 *     the slot and layout priors and samples of every other tensor; box off,
 *     Gaussian-trick width 100 m and stop-gradient inputs replayed, as in
 *     test_model_step;
 *  2. slots persist: view t starts from view t-1's final posterior (bitwise),
 *     and in online inference a slot present after view 1 keeps its id and its
 *     world position in view 3 (zero refinement heads: no view-relative
 *     transform is ever applied), and the rendered field's component of that
 *     id sits at the same world position;
 *  3. overfit: the loss falls on one scene;
 *  4. the one eval path (sooc_eval_run_scene) runs the baseline and returns
 *     finite metrics. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "model/step.h"
#include "sooc3d/train.h"
#include "sooc3d/eval.h"
#include "steptest.h"
#include "synth.h"

static void tiny_cfg(sooc_model_config *c) {
    synth_tiny_cfg(c, 3, 0);
    c->prior_pres_logit = 1.5f;
    c->gauss_s = 100.0f;
    c->global_frame = 1;
    c->global_radius = 2.5f;
}

static sooc_frame F[4];
static sooc_model_ws *W;   /* the workspace of the model a test runs */

static double total_of(sooc_model *m, uint64_t seed, sooc_step_losses *ls) {
    sooc_rng r;
    sooc_rng_seed(&r, seed, 0);
    sooc_step_opts o;
    sooc_step_opts_default(&o);
    o.tau = 0.8f;
    sooc_step_losses l;
    (void)m;
    CHECK_OK(sooc_model_global_train_step(W, F, 3, F + 3, 1, 0, &o, &r, &l));
    if (ls) *ls = l;
    return l.total;
}

static double fd_total(sooc_model *m, void *ctx) {
    (void)ctx;
    return total_of(m, 77, NULL);
}

static sooc_status overfit_step(sooc_model *m, const sooc_step_opts *o, sooc_rng *r, sooc_step_losses *ls,
                                void *ctx) {
    const sooc_frame *F = ctx;
    (void)m;
    return sooc_model_global_train_step(W, F, 2, F + 3, 1, 2, o, r, ls);
}

static void test_grad(void) {
    sooc_model_config c;
    tiny_cfg(&c);
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 5));
    CHECK_OK(sooc_model_ws_create(&W, m));
    CHECK(sooc_model_is_global(m));
    CHECK(sooc_model_global_slots(m, 0) == 3 && sooc_model_global_slots(m, 1) == 2 &&
          sooc_model_global_slots(m, 7) == 3);
    sooc_rng r;
    sooc_rng_seed(&r, 9, 0);
    steptest_random_heads(m, &r, 0.02f);
    sooc_model_zero_grad(m);
    sooc_step_losses ls;
    double L0 = total_of(m, 77, &ls);
    printf("global step: total %.3f nll_in %.3f kl %.3f nll_q %.3f present %.2f slots on %.0f\n", ls.total,
           ls.nll_input, ls.kl, ls.nll_query, ls.present_slots, ls.map_entries);
    CHECK(isfinite(L0) && !ls.nonfinite && ls.n_queries == 1 && ls.n_views == 3);
    float *g = sooc_malloc(m->np * sizeof(float));
    memcpy(g, m->g, m->np * sizeof(float));
    sooc_model_zero_grad(m);
    CHECK(total_of(m, 77, NULL) == L0);
    CHECK(memcmp(g, m->g, m->np * sizeof(float)) == 0);
    /* persistence in the training step: λ^0 of view t = λ^L of view t-1 */
    sooc_step_state *S = W->step;
    int NL = m->NL, n = 3, L = c.L;
    for (int t = 1; t < 3; t++) {
        CHECK(S->views[t].nslot == n);
        CHECK(memcmp(S->views[t].lam0, S->views[t - 1].lam + (size_t)L * n * NL, (size_t)n * NL * sizeof(float)) == 0);
        CHECK(memcmp(S->views[t].lay0, S->views[t - 1].lay + (size_t)L * 2 * c.d_layout,
                     (size_t)2 * c.d_layout * sizeof(float)) == 0);
    }
    CHECK(memcmp(S->views[0].lam0, m->p + m->prior, (size_t)n * NL * sizeof(float)) == 0);
    /* FD with the stop-gradient inputs replayed */
    S->aux_replay = 1;
    CHECK(total_of(m, 77, NULL) == L0);
    steptest_fd_result fd;
    steptest_fd_check(m, g, &r, 1, 8, fd_total, NULL, "global step", &fd);
    CHECK_MSG(fd.worst <= 1.0, "global-step gradient check failed at %s", fd.wname);
    sooc_free(g);
    sooc_model_ws_destroy(W);
    sooc_model_destroy(m);
}

static void test_persist(void) {
    sooc_model_config c;
    tiny_cfg(&c);
    c.use_box = 1, c.gauss_s = 0.3f;
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 3));   /* zero refinement heads: λ stays at the priors */
    int NL = m->NL, d = c.d_what;
    /* slot 0 on sphere 0 (world (0.3, 3.0)), present; slot 1 off */
    float *pr = m->p + m->prior;
    pr[0] = 0.3f, pr[1] = 3.0f, pr[5 + 2 * d] = 3.0f;
    pr[NL + 5 + 2 * d] = -3.0f;
    sooc_global_mapper *gm;
    CHECK_OK(sooc_global_mapper_create(&gm, m, 0, 0, 1, 1));
    double X1 = NAN, Z1 = NAN;
    for (int v = 0; v < 3; v++) {
        sooc_update_stats us;
        CHECK_OK(sooc_global_mapper_update(gm, &F[v], &us));
        sooc_cogmap_entry e;
        CHECK_OK(sooc_cogmap_get(sooc_global_mapper_cogmap(gm), 1, &e));   /* id = slot + 1 */
        CHECK(sooc_cogmap_get(sooc_global_mapper_cogmap(gm), 2, &e) == SOOC_ENOTFOUND);
        sooc_clearerr();
        CHECK_OK(sooc_cogmap_get(sooc_global_mapper_cogmap(gm), 1, &e));
        const float *l = sooc_global_mapper_slot(gm, 0);
        CHECK(e.X == l[0] && e.Z == l[1]);
        if (v == 0) X1 = e.X, Z1 = e.Z;
        printf("view %d: slot 0 world (%.3f, %.3f), retrieved %d registered %d new %d\n", v + 1, e.X, e.Z,
               us.n_retrieved, us.n_registered, us.n_new);
        CHECK(e.X == X1 && e.Z == Z1);
        CHECK(us.n_retrieved == (v ? 3 : 0));
        CHECK(us.n_new == (v == 0 ? us.n_registered : 0));
        /* the field of a global model: the component of id 1 at the slot's world position */
        sooc_model_field *fld;
        sooc_intrinsics K = F[v].K;
        CHECK_OK(sooc_model_field_create(&fld, sooc_global_mapper_model(gm), sooc_global_mapper_cogmap(gm), F[v].T_wc,
                                         &K, c.K, NULL));
        const sooc_field *fl = sooc_model_field_get(fld);
        int found = 0;
        for (int k = 1; k < fl->n_comp; k++)
            if (sooc_model_field_comp_id(fld, k) == 1) {
                double T_fc[16], T_cf[16], T_wf[16], o[3] = {0, 0, 0}, bw[3], bf[3];
                sooc_model_field_T_fc(fld, T_fc);
                sooc_se3_inverse(T_cf, T_fc);
                sooc_se3_mul(T_wf, F[v].T_wc, T_cf);
                sooc_se3_apply(bf, fl->boxes[k].T_fb, o);   /* box origin (floor under the object) in the field */
                sooc_se3_apply(bw, T_wf, bf);
                CHECK_CLOSE(bw[0], 0.3, 1e-4, 0);
                CHECK_CLOSE(bw[1], 0.0, 1e-4, 0);
                CHECK_CLOSE(bw[2], 3.0, 1e-4, 0);
                found = 1;
            }
        CHECK(found);
        sooc_model_field_destroy(fld);
    }
    sooc_global_mapper_destroy(gm);
}

static void test_overfit(void) {
    sooc_model_config c;
    steptest_overfit_cfg(&c);
    c.global_frame = 1, c.global_radius = 2.5f;
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 2));
    CHECK_OK(sooc_model_ws_create(&W, m));
    double first, last, t0 = sooc_seconds();
    steptest_overfit(m, 120, 30, overfit_step, F, &first, &last);
    printf("global overfit: mean loss first 10 steps %.1f, last 10 %.1f: drop %.2fx |first|, %.1f s\n", first, last,
           (first - last) / fabs(first), sooc_seconds() - t0);
    CHECK(first - last >= 0.5 * fabs(first));
    sooc_model_ws_destroy(W);
    sooc_model_destroy(m);
}

static void test_eval(void) {
    sooc_model_config c;
    tiny_cfg(&c);
    c.use_box = 1, c.gauss_s = 0.3f;
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 4));
    sooc_rng r;
    sooc_rng_seed(&r, 3, 0);
    steptest_random_heads(m, &r, 0.02f);
    sooc_frame fr[4];
    memcpy(fr, F, sizeof fr);
    fr[3].is_query = 1;
    for (int i = 0; i < 3; i++) fr[i].is_query = 0;
    sooc_gt_object gt[2] = {{1, 0.3, 3.0}, {2, -0.8, 2.2}};
    sooc_eval_run_opts o;
    sooc_eval_run_opts_default(&o);
    o.n_coarse = 32, o.n_fine = 0, o.threads = 1;
    o.timing = SOOC_EVAL_BOTH;
    sooc_eval_scene_result res;
    CHECK_OK(sooc_eval_run_scene(m, fr, 4, gt, 2, &o, NULL, NULL, NULL, &res));
    sooc_metric_means qm, im;
    sooc_metric_sums_means(&res.query, &qm);
    sooc_metric_sums_means(&res.input_final, &im);
    printf("eval (untrained baseline): mapped %d, query views %d, slots on %zu; Q mIoU %.3f rgb %.3f depth %.3f; "
           "I mIoU %.3f rgb %.3f depth %.3f\n",
           res.n_mapped, res.n_query, (size_t)res.n_entries, qm.miou_best, qm.rgb_rmse, qm.depth_rmse, im.miou_best,
           im.rgb_rmse, im.depth_rmse);
    CHECK(res.n_mapped == 3 && res.n_query == 1);
    CHECK(isfinite(qm.miou_best) && isfinite(qm.rgb_rmse) && isfinite(qm.depth_rmse));
    CHECK(isfinite(im.miou_best) && isfinite(im.rgb_rmse) && isfinite(im.depth_rmse));
    CHECK(res.input_online.n_views == 3);
    sooc_model_destroy(m);
}

int main(void) {
    synth_sphere sp[2] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}}};
    double T[4][16];
    synth_pose(T[0], 0, 1.5, 0, 0.1, -0.45);
    synth_pose(T[1], 0.4, 1.4, 0.3, -0.1, -0.4);
    synth_pose(T[2], -1.0, 1.5, 0.8, 0.5, -0.45);   /* view 3: moved and turned */
    synth_pose(T[3], -0.3, 1.5, 0.2, 0.2, -0.45);
    for (int i = 0; i < 4; i++) CHECK_OK(synth_frame(&F[i], 32, 32, 60, T[i], sp, 2));
    if (!getenv("GSKIP_GRAD")) test_grad();
    test_persist();
    test_overfit();
    test_eval();
    for (int i = 0; i < 4; i++) sooc_frame_free(&F[i]);
    return check_report("test_model_global");
}
