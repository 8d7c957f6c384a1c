/*
 * sooc3d training: training the model, finetuning a map's objects after
 * online inference, and the MulMON-style global-frame baseline.
 *
 * Sections: training (train); per-object finetuning (finetune); the global-
 * frame baseline (global).
 *
 * Contract (CONTRIBUTING.md "Coding rules"), for every section below where
 * the section does not say otherwise. Ownership: the caller owns what it
 * creates and releases it with the matching _destroy / _free / _close
 * (NULL-safe); pointers a getter returns are borrowed and live as long as
 * their object. Threads: an object is used by one thread at a time;
 * functions without an object are reentrant. Errors: a status other than
 * SOOC_OK comes with a message naming the file, key or line (sooc_errmsg);
 * nothing here prints or exits.
 */
#ifndef SOOC3D_TRAIN_H
#define SOOC3D_TRAIN_H

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/model.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== training (train) =================================================== */

/*
 * sooc3d training: scene datasets, the training
 * configuration, and the training loop around sooc_model_train_step.
 *
 * The loop: for each step s, an RNG seeded with (seed, s) picks the scene, the
 * number of input views T (curriculum), the input segment and the query views,
 * and drives the model's sampling. So the data order depends only on (seed, s)
 * and a resumed run repeats exactly what an uninterrupted run would have done.
 * Adam with clipping, warm-up then linear or cosine decay; the relaxed-
 * Bernoulli temperature is annealed from tau_start to tau_end over the first
 * tau_frac of the steps and then held (docs/training.md "Schedule").
 *
 * Output directory:
 *   last.bin      checkpoint every ckpt_every steps (model + Adam + trainer state)
 *   best.bin      the checkpoint with the best validation mIoU so far
 *   log.csv       one row per log_every steps (every loss term, lr, tau, slots)
 *   val.csv       one row per validation
 *   curves.png    the loss curves, redrawn at each checkpoint
 *   config.yaml   a copy of the training configuration
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

/* --------------------------------------------------------------- dataset */

/* A set of synthetic scenes held in memory: every view of every scene, with
 * its input/query flag and the scene's ground-truth objects. */
typedef struct sooc_dataset sooc_dataset;

/* Load scenes from each directory in dirs: a directory holding scene.yaml is
 * one scene; otherwise every scene_* subdirectory is loaded; a directory with
 * neither that opens as a recorded sequence (7-Scenes, label-fusion, TUM, ...)
 * is one scene without objects whose posed frames are query views when their
 * position p (0-based) has p % SOOC_DATASET_QUERY_EVERY == SOOC_DATASET_QUERY_EVERY / 2
 * (the rule `sooc3d eval` holds real frames out by). Frames go through the
 * frame path (include/sooc3d/frame.h): any resolution is cropped/resized
 * to (width, height). Fails naming the offending file. */
#define SOOC_DATASET_QUERY_EVERY 5
sooc_status sooc_dataset_open(sooc_dataset **out, const char *const *dirs, int n_dirs, int width,
                              int height);
/* The same with the frame-path options (--calib, --depth-scale, --up, ...);
 * fpp->width/height are the model's resolution (required). */
struct sooc_framepath_params;
sooc_status sooc_dataset_open_fp(sooc_dataset **out, const char *const *dirs, int n_dirs,
                                 const struct sooc_framepath_params *fpp);
/* Training from recordings (docs/training.md "Training from recordings").
 * A recorded sequence's frames at sequence positions p with
 * p % held_out_every == held_out_every / 2 are the frames `sooc3d eval` holds
 * out (sooc_eval_real_is_query): they are loaded with is_query = 1 and never
 * returned by sooc_dataset_sample. Of the other frames, the input views are a
 * keyframe chain (each at least view_min_cm from the previous one or turned
 * by at least view_min_deg between optical axes), and each query view is,
 * among the frames outside the segment, the nearest one that is at least
 * view_min_cm from every input view of the segment or turned by at least
 * view_min_deg from it. Synthetic scenes keep their own input/query views.
 * world_dir (may be NULL): each recorded sequence's support-plane world
 * frame is stored there (world_<name>_<hash>.sqlite, a map database with the
 * frame only) when first estimated and reused by later runs (--resume), as
 * the node keeps it in its map. */
#define SOOC_DATASET_VIEW_MIN_CM 5.0
#define SOOC_DATASET_VIEW_MIN_DEG 5.0
typedef struct sooc_dataset_rec_params {
    double view_min_cm;      /* (SOOC_DATASET_VIEW_MIN_CM)                         */
    double view_min_deg;     /* (SOOC_DATASET_VIEW_MIN_DEG)                        */
    int held_out_every;      /* 0 = no held-out frames, else >= 2 (SOOC_DATASET_QUERY_EVERY) */
    const char *world_dir;   /* (NULL)                                             */
} sooc_dataset_rec_params;
void sooc_dataset_rec_params_default(sooc_dataset_rec_params *p);
/* sooc_dataset_open_fp with the recording rule's parameters (NULL = defaults). */
sooc_status sooc_dataset_open_rec(sooc_dataset **out, const char *const *dirs, int n_dirs,
                                  const struct sooc_framepath_params *fpp, const sooc_dataset_rec_params *rp);
int sooc_dataset_scene_recorded(const sooc_dataset *d, int scene);   /* 1: a recorded sequence */
int sooc_dataset_n_recorded(const sooc_dataset *d);
/* The scene of one training draw: uniform over all scenes (one
 * sooc_rng_below) unless recorded_frac > 0 and the set holds both
 * kinds, then a recorded sequence with probability recorded_frac. */
int sooc_dataset_pick(const sooc_dataset *d, double recorded_frac, sooc_rng *rng);
void sooc_dataset_destroy(sooc_dataset *d);   /* NULL-safe */
/* The model's metres per unit (config.unit_m; default 1): query views of
 * sooc_dataset_sample mode 0 weigh camera distance in model units against
 * heading in radians, as on a copy of the scenes scaled by 1 / unit_m. */
void sooc_dataset_set_unit(sooc_dataset *d, double unit_m);
int sooc_dataset_n_scenes(const sooc_dataset *d);
const char *sooc_dataset_scene_path(const sooc_dataset *d, int scene);
/* Views of a scene in trajectory order (input and query views interleaved as
 * stored); is_query marks query views. */
int sooc_dataset_n_views(const sooc_dataset *d, int scene);
const sooc_frame *sooc_dataset_view(const sooc_dataset *d, int scene, int view);
/* The lowest and highest camera height above the support plane (y of the
 * camera centre in the views' gravity-aligned frame, metres) over every posed
 * view; returns the number of views counted (0: *lo = *hi = 0). `sooc3d train`
 * stores this range in the model (config cam_h_min / cam_h_max). */
int sooc_dataset_cam_heights(const sooc_dataset *d, double *lo, double *hi);
int sooc_dataset_n_inputs(const sooc_dataset *d, int scene);
/* Ground-truth objects of a scene (world floor position, for L2 and recall). */
int sooc_dataset_n_objects(const sooc_dataset *d, int scene);
void sooc_dataset_object(const sooc_dataset *d, int scene, int i, uint16_t *id, double *x, double *z);

/* Pick T consecutive input views (starting at a random input index) and Q
 * query views. mode 0: the query-flagged views nearest to the segment's
 * cameras. mode 1 (held-out views): Q views drawn at random among all views
 * outside the segment (query-flagged or not) that show an object and whose
 * object pixels are at least SOOC_HELD_OUT_COVER objects the segment saw;
 * falls back to mode 0 when none qualifies. Frames are shallow copies (they
 * share pixel buffers with the dataset). Returns the counts actually chosen
 * (a scene may have fewer views). */
#define SOOC_HELD_OUT_COVER 0.9
void sooc_dataset_sample(const sooc_dataset *d, int scene, int T, int Q, int mode, sooc_rng *rng,
                         sooc_frame *views, int *n_views, sooc_frame *queries, int *n_queries);

/* ---------------------------------------------------------------- config */

typedef struct sooc_train_config {
    int64_t steps;          /* total optimisation steps                        (20000) */
    uint64_t seed;          /* data order and sampling                            (1) */
    uint64_t init_seed;     /* weight initialisation                              (1) */
    float lr;               /* peak learning rate                              (2e-4) */
    int64_t warmup;         /* linear warm-up steps                            (1000) */
    float lr_final_frac;    /* lr at the end = lr * frac                        (0.1) */
    int cosine;             /* 1 = cosine decay, 0 = linear                       (1) */
    float clip;             /* gradient-norm clip                               (5.0) */
    float tau_start, tau_end, tau_frac;   /* temperature anneal        (1, 0.7, 0.2) */
    int64_t kl_warmup;      /* beta_kl linear 0 -> 1 over this many steps      (1000) */
    int64_t burnin;         /* presence burn-in steps (straight-through z=1)      (0) */
    int st_retrieved;       /* hard straight-through presence for retrieved slots (0) */
    /* curriculum (docs/training.md "Schedule"): phase A [0, a), B [a, b), C [b, 1) */
    float phase_a, phase_b; /* fractions of the steps                      (0.15, 0.5) */
    int t_min_b, t_max_b, t_min_c, t_max_c;  /* input views per phase   (2,3 / 2,5) */
    int q_a, q_bc;          /* query views in phase A and in B/C              (1, 2) */
    int query_held_out;     /* 1 = query views drawn from held-out views that see
                               the segment's objects (sooc_dataset_sample mode 1) (0) */
    int accum;              /* scenes per optimisation step (gradient accumulation) (1) */
    int threads;            /* model threads (0 = OpenMP default)                (0) */
    /* bookkeeping */
    int64_t log_every;      /* CSV + progress extra                              (10) */
    int64_t ckpt_every;     /* checkpoint                                       (250) */
    int64_t val_every;      /* validation (0 = off)                             (500) */
    int val_scenes;         /* validation scenes (from --val dirs)                (8) */
    float val_max_seconds;  /* stop the run cleanly after this many seconds (0 = no) */
    /* training from recordings (sooc_dataset_rec_params) */
    float view_min_cm;      /* input/query baseline, centimetres                   (5) */
    float view_min_deg;     /* ... or degrees between optical axes                 (5) */
    float recorded_frac;    /* share of draws from recorded sequences (0 = uniform) (0) */
    /* geometric proposals for the input views' padded slots (sooc_step_opts.proposals;
     * docs/geometric.md "Proposals") */
    int proposals;          /* 1 = on                                             (0) */
    float prop_join_m;      /* the clusters' join distance, 0 = default (0.02 m)  (0) */
    float prop_logit;       /* presence logit of a proposed slot, 0 = the prior's (0) */
} sooc_train_config;

void sooc_train_config_default(sooc_train_config *c);
/* Load a YAML training config: top-level training keys (the field names
 * above) and an optional `model:` mapping with sooc_model_config field names
 * (K, d_what, L, sigma_max, ...). Unknown keys and bad values are errors that
 * name the file, line and key. */
sooc_status sooc_train_config_load(const char *path, sooc_train_config *c, sooc_model_config *mc);

/* --------------------------------------------------------------- running */

/* Validation hook: score the model on the validation scenes; *miou is the
 * query-view best-match mIoU (higher is better). */
typedef sooc_status (*sooc_train_val_fn)(void *user, sooc_model *m, const sooc_dataset *val,
                                         double *miou, double *miou_input, double *l2);

typedef struct sooc_train_run_params {
    const char *config_path;      /* copied into out_dir/config.yaml               */
    const char *out_dir;
    int resume;                   /* 1 = continue from out_dir/last.bin             */
    const sooc_dataset *train;
    const sooc_dataset *val;      /* may be NULL                                   */
    sooc_train_val_fn val_fn;     /* may be NULL (no validation)                   */
    void *val_user;
    int progress;                 /* 1 = draw a progress line on stderr (CLI)      */
    volatile int *stop_flag;      /* set non-zero (e.g. by SIGINT) to checkpoint and stop */
    const char *init_path;        /* new run (not a resume): start from this checkpoint's
                                     weights (fine-tuning) instead of init_seed's random
                                     ones; its network shapes must match the config's,
                                     other settings (clip, likelihood) come from the
                                     config. Fresh optimiser state. NULL = random init */
    void (*step_hook)(void *user, int64_t step);   /* called after each step (may be NULL) */
    void *hook_user;
} sooc_train_run_params;

/* Train until cfg->steps (or the stop flag, or the time budget). Always
 * leaves a consistent last.bin behind.
 * Under MPI (include/sooc3d/model.h; the caller ran sooc_dist_init) every
 * rank calls this with the same arguments: each takes accum scenes of the
 * step's ranks x accum, the gradients are summed over the ranks, and rank 0
 * alone writes out_dir (docs/cluster.md). log.csv's t_* columns give the
 * seconds of each stage of a step (docs/training.md). */
sooc_status sooc_train_run(const sooc_train_config *cfg, const sooc_model_config *mc,
                           const sooc_train_run_params *rp);

/* ==== per-object finetuning (finetune) =================================== */

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
    float support_m;      /* rays whose surface lies within this height (metres) of the
                             support plane are the layout's: their surface term has the
                             layout alone, and every object is penalised for density
                             there as for an air sample over the surface band;
                             0 = off (docs/finetune.md "The support plane")      (0) */
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
 * whose own density reaches the surface level nowhere (mapper.h EMPTY: they
 * explain nothing). The kept ids move to the front, *n = their number,
 * *n_pruned = entries removed. */
sooc_status sooc_birth_prune(sooc_model *m, sooc_cogmap *map, uint64_t *ids, int *n, int *n_pruned);
/* The same over every entry of the map. removed (may be NULL): *removed =
 * the removed ids in id order, sooc_malloc'd (caller frees; NULL if none). */
sooc_status sooc_birth_prune_all(sooc_model *m, sooc_cogmap *map, uint64_t **removed, int *n_pruned);

/* ==== the global-frame baseline (global) ================================= */

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
#endif /* SOOC3D_TRAIN_H */
