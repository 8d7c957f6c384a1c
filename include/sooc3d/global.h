/*
 * The MulMON-style global-frame baseline (src/global, docs/baseline.md): its
 * training step and its online mapper. A module of its own above the model:
 * it runs the model's step layer (per-view update, reverse sweep) on world-
 * frame slots; the model never calls it (docs/model.md "Layers").
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_GLOBAL_H
#define SOOC3D_GLOBAL_H

#include "sooc3d/model.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== MulMON-style global-frame baseline (src/global/global.c, docs/baseline.md) ====
 *
 * A model created with config.global_frame = 1 has the same networks, but no
 * object coordinate systems relative to the view and no cognitive map: a
 * scene is explained by n fixed slots whose z^where = (X, Z, Θ) is in the
 * WORLD frame (floor y = 0), persisting over all views of the scene (the
 * posterior after view t is the prior of view t+1), plus one global layout
 * latent decoded in world coordinates. n = sooc_model_global_slots(m,
 * n_objects) = min(K, n_objects + 1): "strictly more slots than objects"
 * (the paper's MulMON protocol), slots n..K-1 unused; n_objects <= 0 -> K.
 * Slot priors: learnable, means spread over a disc of radius global_radius
 * around the world origin. Query views decode every slot of the final
 * posterior. For evaluation the "map" is the fixed slot set: the global
 * mapper keeps a cogmap holding its present slots (presence p >= 0.5, id =
 * slot + 1, world pose) and the layout at block (0, 0); sooc_model_field_*
 * on a global model renders such a map (world axes, layout in world
 * coordinates). */
/* The training step of the baseline (same contract as sooc_model_train_step;
 * losses->map_entries = present slots after the last input view). */
sooc_status sooc_model_global_train_step(sooc_model_ws *w, const sooc_frame *views, int T,
                                         const sooc_frame *queries, int Q, int n_objects,
                                         const sooc_step_opts *o, sooc_rng *rng,
                                         sooc_step_losses *losses);

/* Online inference of the baseline (what sooc_mapper is for the model). */
typedef struct sooc_global_mapper sooc_global_mapper;
/* Takes ownership of m (a global_frame model). */
sooc_status sooc_global_mapper_create(sooc_global_mapper **out, sooc_model *m, int n_objects,
                                      int iterations, uint64_t seed, int threads);
void sooc_global_mapper_destroy(sooc_global_mapper *g);   /* NULL-safe */
/* One input view: refine every slot L times from the current posterior
 * (n_retrieved = slots carried over, n_registered = present slots, n_new /
 * n_removed = slots whose presence crossed 0.5). */
sooc_status sooc_global_mapper_update(sooc_global_mapper *g, const sooc_frame *f, sooc_update_stats *st);
/* SOOC_LATENTS_MEAN (default) / _SAMPLE, as sooc_mapper_set_latents. */
void sooc_global_mapper_set_latents(sooc_global_mapper *g, int latents);
sooc_model *sooc_global_mapper_model(sooc_global_mapper *g);
const sooc_cogmap *sooc_global_mapper_cogmap(const sooc_global_mapper *g);
/* Current posterior of slot k (world frame in model units, config.unit_m; cogmap.h λ
 * layout). */
const float *sooc_global_mapper_slot(const sooc_global_mapper *g, int k);
/* Present slots as map entries (like sooc_mapper_entries). */
sooc_status sooc_global_mapper_entries(const sooc_global_mapper *g, sooc_map_entry *out, size_t cap, size_t *n);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_GLOBAL_H */
