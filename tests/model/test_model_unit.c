/* config.unit_m, metres per model unit (docs/model.md "Model unit"): the
 * model divides what comes in (frame depth, camera positions) by unit_m and
 * multiplies what goes out (map entries) back.
 *   - API: default 1, set / range / config check; sooc_model_set_clip takes
 *     metres, sooc_model_box_extent gives metres.
 *   - the training step on frames shown at U times their size (depth and
 *     camera translations times U) with unit_m = U equals the step on the
 *     original frames with unit_m = 1: the same total loss, loss terms, map
 *     entries and parameter gradients up to float round-off (the map inside
 *     the step is in metres, so the slot <-> entry conversions and the
 *     gradient routes through the map are exercised); likewise the
 *     global-frame baseline's step (world-frame slots, layout at the world
 *     origin);
 *   - a finite-difference check of d(total)/d(params) with unit_m = 0.3
 *     (steptest.h harness, as test_model_step). */
#include <stdio.h>
#include <string.h>
#include <stddef.h>
#include <unistd.h>

#include "check.h"
#include "model/step.h"
#include "sooc3d/train.h"
#include "steptest.h"
#include "oldver.h"
#include "synth.h"

#define U 0.3

static sooc_frame F1[3], FU[3];   /* original frames; the same at U times their size */

static void make_frames(void) {
    synth_sphere sp[2] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}}};
    double T[3][16];
    synth_pose(T[0], 0, 1.5, 0, 0.1, -0.45);
    synth_pose(T[1], 0.4, 1.4, 0.3, -0.1, -0.4);
    synth_pose(T[2], -0.3, 1.5, 0.2, 0.2, -0.45);
    for (int i = 0; i < 3; i++) {
        CHECK_OK(synth_frame(&F1[i], 32, 32, 60, T[i], sp, 2));
        CHECK_OK(sooc_frame_copy(&FU[i], &F1[i]));   /* scripts/scale_scenes.py in memory */
        for (size_t p = 0; p < (size_t)32 * 32; p++) FU[i].depth[p] = (float)(F1[i].depth[p] * U);
        FU[i].T_wc[3] *= U, FU[i].T_wc[7] *= U, FU[i].T_wc[11] *= U;
    }
}

static double total_of(sooc_model_ws *m, const sooc_frame *f, int global, sooc_step_losses *ls) {
    sooc_rng r;
    sooc_rng_seed(&r, 77, 0);
    sooc_step_opts o;
    sooc_step_opts_default(&o);
    o.tau = 0.8f;
    sooc_step_losses l;
    if (global) CHECK_OK(sooc_model_global_train_step(m, f, 2, f + 2, 1, 2, &o, &r, &l));
    else CHECK_OK(sooc_model_train_step(m, f, 2, f + 2, 1, &o, &r, &l));
    if (ls) *ls = l;
    return l.total;
}
static double fd_total(sooc_model *m, void *ctx) {   /* ctx: m's workspace */
    (void)m;
    return total_of(ctx, FU, 0, NULL);
}

static void test_api(void) {
    sooc_model_config c;
    sooc_model_config_default(&c);
    CHECK(c.unit_m == 1.0f);
    CHECK_OK(sooc_model_config_check(&c));
    c.unit_m = 0.0f;
    CHECK(sooc_model_config_check(&c) == SOOC_EINVAL);
    c.unit_m = NAN;
    CHECK(sooc_model_config_check(&c) == SOOC_EINVAL);
    synth_tiny_cfg(&c, 2, 1);
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 1));
    CHECK(sooc_model_set_unit(m, -1.0f) == SOOC_EINVAL);
    CHECK(sooc_model_set_unit(m, 1e4f) == SOOC_EINVAL);
    CHECK_OK(sooc_model_set_unit(m, 0.25f));
    const sooc_model_config *mc = sooc_model_get_config(m);
    CHECK(mc->unit_m == 0.25f);
    float e[3];
    sooc_model_box_extent(mc, e);
    CHECK(e[0] == 2 * mc->box_rh * 0.25f && e[1] == mc->box_hb * 0.25f);
    CHECK_OK(sooc_model_set_clip(m, 1.0f));   /* metres: 4 model units */
    CHECK(mc->d_clip == 4.0f);
    CHECK(sooc_model_set_clip(m, 0.02f) == SOOC_EINVAL);   /* 0.08 units: inside t_near 0.1 */
    sooc_model_destroy(m);
}

/* config cam_h_min / cam_h_max (version 6): defaults, checks, metres at the
 * model's unit, a save / load round trip, and a version-5 file (the config
 * cut before cam_h_min) loading with the unity generator's 1.2-2.0. */
static void test_cam_heights(void) {
    sooc_model_config c;
    sooc_model_config_default(&c);
    CHECK(c.cam_h_min == 1.2f && c.cam_h_max == 2.0f);
    c.cam_h_min = 2.5f;
    CHECK(sooc_model_config_check(&c) == SOOC_EINVAL);
    c.cam_h_min = 0.0f;
    CHECK(sooc_model_config_check(&c) == SOOC_EINVAL);
    synth_tiny_cfg(&c, 2, 1);
    sooc_model *m = NULL, *l = NULL;
    CHECK_OK(sooc_model_create(&m, &c, 1));
    CHECK_OK(sooc_model_set_unit(m, 0.25f));
    double lo, hi;
    sooc_model_cam_heights_m(sooc_model_get_config(m), &lo, &hi);
    CHECK_CLOSE(lo, 0.3, 1e-6, 0);   /* 1.2 units of 0.25 m */
    CHECK_CLOSE(hi, 0.5, 1e-6, 0);
    CHECK(sooc_model_set_cam_heights(m, 0.5, 0.4) == SOOC_EINVAL);
    CHECK(sooc_model_set_cam_heights(m, 0.0, 0.4) == SOOC_EINVAL);
    CHECK_OK(sooc_model_set_cam_heights(m, 0.15, 0.95));
    CHECK_CLOSE(sooc_model_get_config(m)->cam_h_min, 0.6, 1e-6, 0);
    char p[256], p5[256];
    snprintf(p, sizeof p, "/tmp/test_model_unit_h_%ld.bin", (long)getpid());
    snprintf(p5, sizeof p5, "/tmp/test_model_unit_h5_%ld.bin", (long)getpid());
    CHECK_OK(sooc_model_save(m, p, NULL, 0));
    CHECK_OK(sooc_model_load(&l, p, NULL, NULL));
    if (l) {
        sooc_model_cam_heights_m(sooc_model_get_config(l), &lo, &hi);
        CHECK_CLOSE(lo, 0.15, 1e-6, 0);
        CHECK_CLOSE(hi, 0.95, 1e-6, 0);
    }
    sooc_model_destroy(l);
    l = NULL;
    uint32_t csz5 = (uint32_t)offsetof(sooc_model_config, cam_h_min);
    CHECK(csz5 < sizeof(sooc_model_config));
    CHECK(tm_write_old_version(p, p5, 5, csz5) == 0);
    CHECK_OK(sooc_model_load(&l, p5, NULL, NULL));
    if (l) {
        const sooc_model_config *lc = sooc_model_get_config(l);
        CHECK(lc->cam_h_min == 1.2f && lc->cam_h_max == 2.0f && lc->unit_m == 0.25f);
        CHECK(!memcmp(sooc_model_params(l), sooc_model_params(m), sooc_model_param_count(m) * sizeof(float)));
    }
    /* the same bytes claiming version 6: a clear version error, not a misread */
    CHECK(tm_write_old_version(p, p5, 6, csz5) == 0);
    sooc_model *bad = NULL;
    CHECK(sooc_model_load(&bad, p5, NULL, NULL) == SOOC_EVERSION);
    sooc_model_destroy(l);
    sooc_model_destroy(m);
    remove(p);
    remove(p5);
}

/* step on FU with unit_m = U vs step on F1 with unit_m = 1 */
static void test_equivalence(int global) {
    sooc_model_config c;
    synth_tiny_cfg(&c, 3, 0);
    c.prior_pres_logit = 1.5f;
    c.prior_far = 4.0f;
    c.gauss_s = 100.0f;
    c.global_frame = global;
    sooc_model *m1, *mu;
    CHECK_OK(sooc_model_create(&m1, &c, 5));
    CHECK_OK(sooc_model_create(&mu, &c, 5));
    sooc_model_ws *w1, *wu;
    CHECK_OK(sooc_model_ws_create(&w1, m1));
    CHECK_OK(sooc_model_ws_create(&wu, mu));
    sooc_rng r;
    sooc_rng_seed(&r, 9, 0);
    steptest_random_heads(m1, &r, 0.02f);
    memcpy(sooc_model_params(mu), sooc_model_params(m1), m1->np * sizeof(float));
    CHECK_OK(sooc_model_set_unit(mu, (float)U));
    sooc_model_zero_grad(m1);
    sooc_model_zero_grad(mu);
    sooc_step_losses a, b;
    double L1 = total_of(w1, F1, global, &a), LU = total_of(wu, FU, global, &b);
    double gmax = 0, gdiff = 0;
    for (size_t i = 0; i < m1->np; i++) {
        double g1 = m1->g[i], gu = mu->g[i];
        gmax = fmax(gmax, fabs(g1));
        gdiff = fmax(gdiff, fabs(g1 - gu));
    }
    printf("%s step: unit 1 on the frames %.9g, unit %.1f on the frames x%.1f %.9g (rel %.2g); nll_in %.6g / %.6g, "
           "kl %.6g / %.6g, nll_q %.6g / %.6g, entries %.0f / %.0f; gradients max |g| %.4g, max |dg| %.3g\n",
           global ? "global-frame" : "SOOC3D", L1, U, U, LU, fabs(L1 - LU) / fabs(L1), a.nll_input, b.nll_input, a.kl,
           b.kl, a.nll_query, b.nll_query, a.map_entries, b.map_entries, gmax, gdiff);
    CHECK(isfinite(L1) && !a.nonfinite && !b.nonfinite);
    CHECK_CLOSE(L1, LU, 0, 1e-4);
    CHECK_CLOSE(a.nll_input, b.nll_input, 1e-3, 1e-4);
    CHECK_CLOSE(a.kl, b.kl, 1e-3, 1e-4);
    CHECK_CLOSE(a.nll_query, b.nll_query, 1e-3, 1e-4);
    CHECK(a.map_entries == b.map_entries && a.map_entries >= 1);
    CHECK_MSG(gdiff <= 1e-3 * gmax, "gradients differ by %g (max |g| %g)", gdiff, gmax);
    /* a unit not matching the frames' scale is a different problem (the check can fail) */
    CHECK_OK(sooc_model_set_unit(mu, 1.0f));
    double LW = total_of(wu, FU, global, NULL);
    printf("  unit 1 on the frames x%.1f: %.9g\n", U, LW);
    CHECK(fabs(LW - L1) > 1e-2 * fabs(L1));
    sooc_model_ws_destroy(w1);
    sooc_model_ws_destroy(wu);
    sooc_model_destroy(m1);
    sooc_model_destroy(mu);
}

static void test_fd(void) {
    sooc_model_config c;
    synth_tiny_cfg(&c, 3, 0);
    c.prior_pres_logit = 1.5f;
    c.prior_far = 4.0f;
    c.gauss_s = 100.0f;   /* as test_model_step: box off, stiff trick term off */
    c.unit_m = (float)U;
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 5));
    sooc_model_ws *w;
    CHECK_OK(sooc_model_ws_create(&w, m));
    sooc_rng r;
    sooc_rng_seed(&r, 9, 0);
    steptest_random_heads(m, &r, 0.02f);
    sooc_model_zero_grad(m);
    double L0 = total_of(w, FU, 0, NULL);
    CHECK(isfinite(L0));
    float *g = sooc_malloc(m->np * sizeof(float));
    memcpy(g, m->g, m->np * sizeof(float));
    sooc_step_state *S = w->step;
    S->aux_replay = 1;
    CHECK(total_of(w, FU, 0, NULL) == L0);
    steptest_fd_result fd;
    steptest_fd_check(m, g, &r, 1, 4, fd_total, w, "train-step (unit_m 0.3)", &fd);
    CHECK_MSG(fd.worst <= 1.0, "train-step gradient check with unit_m %g failed at %s", U, fd.wname);
    sooc_free(g);
    sooc_model_ws_destroy(w);
    sooc_model_destroy(m);
}

int main(void) {
    make_frames();
    test_api();
    test_cam_heights();
    test_equivalence(0);
    test_equivalence(1);
    test_fd();
    for (int i = 0; i < 3; i++) sooc_frame_free(&F1[i]), sooc_frame_free(&FU[i]);
    return check_report("test_model_unit");
}
