/* The MulMON-style global-frame baseline (issue 5 part 4, docs/baseline.md):
 * the same networks as the shipped model, but every object lives in one
 * fixed set of slots in the WORLD frame, persisting across all views of a
 * scene (the posterior after view t is the prior of view t+1), no cognitive
 * map, no query/registration, one global layout latent. */
#include "model/step_internal.h"

#include <math.h>
#include <string.h>

/* Slot prior means: a Vogel (golden-angle) spiral over a disc of radius
 * global_radius around the world origin, so that every prefix of n slots is
 * spread evenly over a disc of radius R·sqrt(n/K) (a scene with fewer
 * objects uses fewer slots, see sooc_model_global_slots). */
void mdl_global_init_priors(sooc_model *m) {
    const sooc_model_config *c = &m->cfg;
    int NL = m->NL;
    const double ga = M_PI * (3.0 - sqrt(5.0));
    for (int k = 0; k < c->K; k++) {
        float *l = m->p + m->prior + (size_t)k * NL;
        double r = c->global_radius * sqrt((k + 0.5) / c->K), a = ga * k;
        l[0] = (float)(r * cos(a));
        l[1] = (float)(r * sin(a));
    }
}
