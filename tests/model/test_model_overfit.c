/* Tiny overfit: one analytic scene (floor + 2 spheres), 2 input views + 1
 * query view, a small config, the tests' own plain Adam (steptest.h; the
 * trainer owns the real optimiser). The mean step loss over the last 10 steps must fall below
 * OVERFIT_FACTOR times the mean of the first 10 steps within OVERFIT_STEPS
 * steps (measured: see the printed line). Runs in well under 2 minutes. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "sooc3d/model.h"
#include "steptest.h"
#include "synth.h"

#define OVERFIT_STEPS 150
#define OVERFIT_FACTOR 1.0

static sooc_model_ws *W;   /* the test runs the model: its workspace */

static sooc_status overfit_step(sooc_model *m, const sooc_step_opts *o, sooc_rng *r, sooc_step_losses *ls,
                                void *ctx) {
    const sooc_frame *F = ctx;
    (void)m;
    return sooc_model_train_step(W, F, 2, F + 2, 1, o, r, ls);
}

int main(void) {
    double t0 = sooc_seconds();
    sooc_model_config c;
    steptest_overfit_cfg(&c);
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 2));
    CHECK_OK(sooc_model_ws_create(&W, m));
    synth_sphere sp[2] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}}};
    double T[3][16];
    synth_pose(T[0], 0, 1.5, 0, 0.1, -0.45);
    synth_pose(T[1], 0.4, 1.4, 0.3, -0.1, -0.4);
    synth_pose(T[2], -0.3, 1.5, 0.2, 0.2, -0.45);
    sooc_frame F[3];
    for (int i = 0; i < 3; i++) CHECK_OK(synth_frame(&F[i], 32, 32, 60, T[i], sp, 2));
    double first, last;
    steptest_overfit(m, OVERFIT_STEPS, 25, overfit_step, F, &first, &last);
    double dt = sooc_seconds() - t0;
    printf("overfit: mean loss first 10 steps %.1f, last 10 steps %.1f: drop %.2fx |first| (need >= %.2f) in %d steps, %.1f s\n",
           first, last, (first - last) / fabs(first), OVERFIT_FACTOR, OVERFIT_STEPS, dt);
    CHECK(first - last >= OVERFIT_FACTOR * fabs(first));   /* the time budget is the test's TIMEOUT (120 s) */
    for (int i = 0; i < 3; i++) sooc_frame_free(&F[i]);
    sooc_model_ws_destroy(W);
    sooc_model_destroy(m);
    return check_report("test_model_overfit");
}
