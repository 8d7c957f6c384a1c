/* Reduction lengths of the decoder for the float error bounds of the golden
 * tests (check_gamma_n, tests/check.h; docs/engine.md "Determinism contract"). */
#ifndef SOOC3D_TEST_MODEL_CHAIN_H
#define SOOC3D_TEST_MODEL_CHAIN_H

#include "model/weights.h"

/* One decoder's chain: layer 1 on the positional code and the slot latent, two
 * hidden layers, the colour layer and the heads; the backward the same way. */
static inline double dec_chain_n(const sooc_dec_net *d) {
    return 2.0 * ((double)d->din + d->dz + 3.0 * d->H + d->Hc + 3.0);
}

#endif
