/* Tiny overfit: one analytic scene (floor + 2 spheres), 2 input views + 1
 * query view, a small config, plain Adam written here (the trainer owns the
 * real optimiser). The mean step loss over the last 10 steps must fall below
 * OVERFIT_FACTOR times the mean of the first 10 steps within OVERFIT_STEPS
 * steps (measured: see the printed line). Runs in well under 2 minutes. */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "sooc3d/model.h"
#include "synth.h"

#define OVERFIT_STEPS 150
#define OVERFIT_FACTOR 1.0

int main(void) {
    double t0 = sooc_seconds();
    sooc_model_config c;
    sooc_model_config_default(&c);
    c.K = 3, c.d_what = 8, c.d_layout = 4, c.L = 2;
    c.img_w = c.img_h = 32, c.ray_w = c.ray_h = 16;
    c.dec_width = 32, c.dec_color_width = 16;
    c.ref_ch[0] = 8, c.ref_ch[1] = 8, c.ref_ch[2] = 16, c.ref_ch[3] = 16;
    c.ref_fc = 32, c.ref_hidden = 32;
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 2));
    synth_sphere sp[2] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}}};
    double T[3][16];
    synth_pose(T[0], 0, 1.5, 0, 0.1, -0.45);
    synth_pose(T[1], 0.4, 1.4, 0.3, -0.1, -0.4);
    synth_pose(T[2], -0.3, 1.5, 0.2, 0.2, -0.45);
    sooc_frame F[3];
    for (int i = 0; i < 3; i++) CHECK_OK(synth_frame(&F[i], 32, 32, 60, T[i], sp, 2));
    size_t n = sooc_model_param_count(m);
    float *p = sooc_model_params(m), *g = sooc_model_grads(m);
    float *mo = calloc(n, sizeof(float)), *vo = calloc(n, sizeof(float));
    sooc_rng r;
    sooc_rng_seed(&r, 5, 0);
    sooc_step_opts o;
    sooc_step_opts_default(&o);
    double first = 0, last = 0, lr = 3e-3;
    for (int s = 1; s <= OVERFIT_STEPS; s++) {
        sooc_model_zero_grad(m);
        sooc_step_losses ls;
        CHECK_OK(sooc_model_train_step(m, F, 2, F + 2, 1, &o, &r, &ls));
        if (ls.nonfinite) continue;
        if (s <= 10) first += ls.total / 10;
        if (s > OVERFIT_STEPS - 10) last += ls.total / 10;
        /* global-norm clip 5 * (loss scale) -> clip at 1e4, then Adam */
        double gn = 0;
        for (size_t i = 0; i < n; i++) gn += (double)g[i] * g[i];
        gn = sqrt(gn);
        float cs = gn > 1e4 ? (float)(1e4 / gn) : 1.0f;
        double b1 = 1 - pow(0.9, s), b2 = 1 - pow(0.999, s);
        for (size_t i = 0; i < n; i++) {
            float gi = g[i] * cs;
            mo[i] = 0.9f * mo[i] + 0.1f * gi;
            vo[i] = 0.999f * vo[i] + 0.001f * gi * gi;
            p[i] -= (float)(lr * (mo[i] / b1) / (sqrt(vo[i] / b2) + 1e-8));
        }
        if (s % 25 == 0 || s == 1)
            printf("step %3d total %10.1f nll_in %9.1f kl %7.2f nll_q %9.1f present %.2f entries %.0f\n", s, ls.total,
                   ls.nll_input, ls.kl, ls.nll_query, ls.present_slots, ls.map_entries);
    }
    double dt = sooc_seconds() - t0;
    printf("overfit: mean loss first 10 steps %.1f, last 10 steps %.1f: drop %.2fx |first| (need >= %.2f) in %d steps, %.1f s\n",
           first, last, (first - last) / fabs(first), OVERFIT_FACTOR, OVERFIT_STEPS, dt);
    CHECK(first - last >= OVERFIT_FACTOR * fabs(first));
    CHECK(dt < 120);
    free(mo), free(vo);
    for (int i = 0; i < 3; i++) sooc_frame_free(&F[i]);
    sooc_model_destroy(m);
    return check_report("test_model_overfit");
}
