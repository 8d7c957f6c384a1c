/* The toy scene of the finetuning tests (test_finetune_em, test_birth): two
 * spheres on a checkered floor, four 32x32 views. Header-only. */
#ifndef SOOC3D_TEST_FT_TOY_SCENE_H
#define SOOC3D_TEST_FT_TOY_SCENE_H

#include "model/synth.h"

#define NV 4

static const synth_sphere k_sp[2] = {{{-0.5, 0.35, 3.0}, 0.35, {0.85f, 0.15f, 0.1f}},
                                     {{0.6, 0.3, 3.6}, 0.3, {0.1f, 0.3f, 0.9f}}};

static inline sooc_status make_views(sooc_frame *fr) {
    static const double cam[NV][4] = {{0, 1.2, 0.6, 0}, {-1.0, 1.1, 0.9, 0.25}, {1.0, 1.3, 0.8, -0.25},
                                      {0.2, 1.0, 1.2, 0.05}};
    for (int v = 0; v < NV; v++) {
        double T[16];
        synth_pose(T, cam[v][0], cam[v][1], cam[v][2], cam[v][3], -0.3);
        sooc_status st = synth_frame(&fr[v], 32, 32, 60, T, k_sp, 2);
        if (st) return st;
        fr[v].index = v;
    }
    return SOOC_OK;
}

#endif
