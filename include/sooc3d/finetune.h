/*
 * sooc3d per-object NeRF finetuning by EM (docs/finetune.md; the paper's
 * "SOOC3D+").
 *
 * After online inference every map entry gets its own copy of the object
 * decoder and a free z^what (initialised at its posterior mean); z^where
 * stays at the posterior mean. Every layout block gets its own copy of the
 * layout decoder and latent in the same way. The data are the input views
 * that saw the scene: every pixel, with one surface and one air sample per
 * ray drawn afresh every iteration, as in the model's likelihood.
 *
 *   E-step (no gradient): per ray, the responsibilities of the components
 *     at the surface sample, γ_k = σ̄_k N(C; c̃_k, σ_C²) / Σ_j σ̄_j N(C; c̃_j, σ_C²).
 *   M-step: Adam on one component's weights and z^what against the ray
 *     log-likelihood  ℓ = log(σ_max Σ̄(x_s) + ε_σ) + log Σ_k ω_k N(C; c̃_k, σ_C²)
 *     − W σ_max Σ̄(x_a)  (ω_k = σ̄_k / Σ̄; beyond-clip rays: only the air term),
 *     whose gradient with γ held fixed is the one of the marginal (Fisher).
 *
 * Components are finetuned one at a time ("units": the objects in id order,
 * then the layout blocks), each against the rays of the views that crossed
 * its locality box, evaluated with only the components whose boxes the ray
 * crosses (and the view's layout block). The cost of a unit therefore depends
 * on its iterations and its neighbours, not on the map's size. A finished
 * unit's decoder goes into the map as a payload (cogmap.h "payloads"), so the
 * model's field (render, eval, map export, the node) draws it from then on,
 * and the caller can store it (sooc_mapstore_ft_put, one transaction each).
 *
 * Units: model units inside (config.unit_m), the map and frames in metres.
 * The global-frame baseline is not supported (SOOC_EUNSUPPORTED).
 * Thread-safety: one thread per sooc_finetune; it reads the model and
 * writes payloads into the map.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_FINETUNE_H
#define SOOC3D_FINETUNE_H

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/model.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_finetune_params {
    int iterations;       /* Adam steps per unit                                   (300) */
    int rays;             /* rays per step (0 = every ray of the unit, full batch) (512) */
    float lr;             /* Adam learning rate of the decoder weights           (1e-3) */
    float lr_z;           /* Adam learning rate of z^what / the layout latent    (1e-3) */
    float lr_final;       /* the rates fall by a half cosine over a unit's steps to
                             lr_final x their start; 1 = constant                    (1) */
    float sigma_c;        /* colour std; 0 = the model's config                     (0) */
    int layout;           /* 1 = finetune the layout blocks too                     (1) */
    int max_obj;          /* components per view (top by presence), as the renderer (63) */
    int fixed_samples;    /* 1 = the same surface / air samples every step (tests)  (0) */
    uint64_t seed;        /* ray batches and samples                                 (1) */
} sooc_finetune_params;
void sooc_finetune_params_default(sooc_finetune_params *p);
/* The learning-rate factor of step it (0-based) of a unit's `iterations`
 * steps: lr_final + (1 - lr_final) (1 + cos(pi it / iterations)) / 2. */
float sooc_finetune_lr_scale(const sooc_finetune_params *p, int it);

typedef struct sooc_finetune sooc_finetune;

/* Create for model m (borrowed, read only) and map (borrowed; payloads are
 * written into it). The map's current payloads are the starting decoders of
 * the units that have one (so a resumed run continues from them). */
sooc_status sooc_finetune_create(sooc_finetune **out, sooc_model *m, sooc_cogmap *map,
                                 const sooc_finetune_params *p);
void sooc_finetune_destroy(sooc_finetune *ft);   /* NULL-safe */

/* Add an input view (the model's resolution, posed, planar depth in metres,
 * 0 = invalid). Its rays are copied; the frame can be reused afterwards.
 * Views are added before the first unit runs (SOOC_EINVAL after). */
sooc_status sooc_finetune_add_view(sooc_finetune *ft, const sooc_frame *f);

typedef enum { SOOC_FT_OBJECT = 0, SOOC_FT_LAYOUT = 1 } sooc_finetune_kind;
typedef struct sooc_finetune_unit {
    sooc_finetune_kind kind;
    uint64_t id;          /* map entry id (objects)          */
    int32_t bi, bj;       /* layout block (layout)           */
    int n_views;          /* views whose rays cross it       */
    size_t n_rays;        /* rays crossing its box / block   */
} sooc_finetune_unit;
/* Units with at least one ray, objects (id order) then blocks. */
int sooc_finetune_n_units(const sooc_finetune *ft);
sooc_status sooc_finetune_unit_get(const sooc_finetune *ft, int u, sooc_finetune_unit *out);

typedef struct sooc_finetune_progress {
    int unit, n_units, iter, iterations;
    double loss;          /* mean -ℓ per ray over the last steps        */
    double steps_per_s, eta_s;   /* this unit's speed and time left    */
} sooc_finetune_progress;
/* Return non-zero to stop (the unit is then not finished: SOOC_EINTERRUPTED). */
typedef int (*sooc_finetune_progress_fn)(void *user, const sooc_finetune_progress *p);

typedef struct sooc_finetune_result {
    int steps;
    double loss_first, loss_last;   /* mean -ℓ per ray of the first / last 10% of steps */
    double seconds;
} sooc_finetune_result;
/* Finetune unit u (p.iterations Adam steps; the progress callback, if any,
 * every `every` steps) and write its payload into the map. A stop from the
 * callback leaves the map's payload of u unchanged. */
sooc_status sooc_finetune_unit_run(sooc_finetune *ft, int u, sooc_finetune_progress_fn cb, void *user, int every,
                                   sooc_finetune_result *res);
/* Every unit in order (no per-unit storage: for eval). */
sooc_status sooc_finetune_run_all(sooc_finetune *ft, sooc_finetune_progress_fn cb, void *user, int every);

/* The unit's payload as it is in the map now (after sooc_finetune_unit_run),
 * for storing: *v points into the map (valid until the map's payloads change). */
sooc_status sooc_finetune_unit_payload(const sooc_finetune *ft, int u, const float **v, size_t *n);

/* Total log-likelihood Σ ℓ over every ray of every view with the current
 * decoders, samples drawn from `seed` (the same seed gives the same samples).
 * *n_rays = rays summed (may be NULL). */
sooc_status sooc_finetune_loglik(sooc_finetune *ft, uint64_t seed, double *ll, size_t *n_rays);

/* ------------------------------------------------------------ births
 *
 * Online inference can miss an object: nothing in the map draws it, so EM
 * has no component to fit to it (the "birth" move of EM mixture fitting).
 * Before finetuning, sooc_birth renders every view from the map and keeps
 * the pixels whose sensor surface lies more than depth_margin in front of
 * the rendered one, between min_height and the object box's height above
 * the floor. Their world points are clustered on the floor (cell, min_cell,
 * 8-connected; clusters wider than an object box are cut into box-sized
 * tiles), and each cluster seen in min_views views with min_pixels points,
 * not within dup_radius of an entry, becomes a new map entry at its points'
 * mean (yaw 0, z^what the mean of the slot priors). Lengths are in model
 * units (config.unit_m). The finetuning made afterwards on the same map fits
 * the new entries with the others; sooc_birth_prune then removes every entry
 * whose finetuned density is empty. docs/finetune.md "Births and deaths". */
typedef struct sooc_birth_params {
    float depth_margin;   /* rendered surface this far behind the sensor's (0.15) */
    float min_height;     /* points this high above the floor at least      (0.05) */
    float cell;           /* floor grid cell                                (0.1)  */
    int min_cell;         /* points per grid cell to join a cluster           (3)  */
    int min_pixels;       /* points per new entry                            (40)  */
    int min_views;        /* views that see a new entry                       (2)  */
    float dup_radius;     /* no birth this close to an entry                (0.15) */
    int max_births;       /* at most this many new entries                   (32)  */
    int n_coarse, n_fine; /* render samples per ray                       (64, 16) */
} sooc_birth_params;
void sooc_birth_params_default(sooc_birth_params *p);

typedef struct sooc_birth sooc_birth;
/* For model m and map (borrowed; new entries are inserted into it). */
sooc_status sooc_birth_create(sooc_birth **out, sooc_model *m, sooc_cogmap *map, const sooc_birth_params *p,
                              int threads);
void sooc_birth_destroy(sooc_birth *b);   /* NULL-safe */
/* Render view f from the map and keep its unexplained points (the frame at
 * any resolution, posed, planar depth in metres, 0 = invalid). */
sooc_status sooc_birth_add_view(sooc_birth *b, const sooc_frame *f);
size_t sooc_birth_n_points(const sooc_birth *b);   /* unexplained points so far */
/* Cluster the points and insert the new entries; their ids go to ids[0..cap)
 * (may be NULL), their number to *n_born. */
sooc_status sooc_birth_run(sooc_birth *b, uint64_t *ids, int cap, int *n_born);
/* Deaths, after finetuning: remove the entries ids[0..*n) (born or not)
 * whose own density reaches the surface level nowhere (objgeom.h EMPTY: they
 * explain nothing). The kept ids move to the front, *n = their number,
 * *n_pruned = entries removed. */
sooc_status sooc_birth_prune(sooc_model *m, sooc_cogmap *map, uint64_t *ids, int *n, int *n_pruned);
/* The same over every entry of the map. removed (may be NULL): *removed =
 * the removed ids in id order, sooc_malloc'd (caller frees; NULL if none). */
sooc_status sooc_birth_prune_all(sooc_model *m, sooc_cogmap *map, uint64_t **removed, int *n_pruned);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_FINETUNE_H */
