/*
 * sooc3d model: the network (its parameters, weight files, inference and
 * training steps) and the data-parallel support for training it over MPI.
 *
 * Sections: the network (model); data-parallel training over MPI (dist).
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
#ifndef SOOC3D_MODEL_H
#define SOOC3D_MODEL_H

#include <stddef.h>

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/mapper.h"
#include "sooc3d/render.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== the network (model) ================================================ */

/*
 * sooc3d model (docs/model.md; the SOOC3D paper): latents and posteriors, the object-aware NeRF
 * decoder, the two-sample depth likelihood, KL terms, the refinement networks
 * and the differentiable retrieve -> refine -> register loop.
 *
 * Who calls what:
 *   - the trainer (src/train): sooc_model_create / _load, sooc_model_params /
 *     _grads / _tensors (a flat float slab; Adam and clipping are the trainer's),
 *     sooc_model_zero_grad, sooc_model_ws_create once, sooc_model_train_step
 *     once per scene, sooc_model_save.
 *   - the online mapper (include/sooc3d/mapper.h, implemented in src/mapper):
 *     loads a checkpoint and runs the same per-view update without gradients.
 *   - eval/render: sooc_model_field_* (a render.h field built from a map).
 *
 * Frames: every λ handed to the model is in the gravity-aligned camera frame
 * G_t of its view (core.h sooc_gframe); the flat λ layout is cogmap.h's:
 *   [0] mu_x [1] mu_z [2] mu_theta [3] rho_t [4] rho_theta
 *   [5, 5+d) what mean  [5+d, 5+2d) what log-variance  [5+2d] presence logit a
 * Layout latent: [0, d_l) mean, [d_l, 2 d_l) log-variance.
 *
 * Loss sign: every loss below is a quantity to MINIMISE (negative ELBO).
 * Gradients are ACCUMULATED (+=) into the gradient slab; call
 * sooc_model_zero_grad before a step (or between accumulation steps).
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

#define SOOC_MODEL_K_MAX 32   /* 32: the global-frame baseline needs K > 26 objects (docs/baseline.md) */
#define SOOC_MODEL_D_MAX 32

/* All sizes and constants. Stored in the checkpoint; sooc_model_config_default
 * gives the values of docs/model.md (with its slot priors). */
typedef struct sooc_model_config {
    /* latents */
    int K;                 /* object slots                                   (7)  */
    int d_what;            /* z^what dimension d                             (32) */
    int d_layout;          /* layout latent dimension d_l                    (16) */
    int L;                 /* refinement updates per view                    (3)  */
    /* images and rays */
    int img_w, img_h;      /* model input resolution                      (64x64) */
    int ray_w, ray_h;      /* ray grid per view (stratified sub-grid)     (32x32) */
    /* decoder (both NeRFs) */
    int dec_width;         /* hidden width                                   (64) */
    int dec_color_width;   /* colour head hidden                             (32) */
    int n_freq;            /* object PE frequencies 2^0..2^(n-1)             (5)  */
    int n_freq_layout;     /* layout PE frequencies                          (6)  */
    float dens_bias_init;  /* density head bias at init                     (-2)  */
    /* refinement network */
    int ref_ch[4];         /* conv widths                          (32,32,64,64)  */
    int ref_fc;            /* FC after the conv stack                       (128) */
    int ref_hidden;        /* LSTM hidden                                   (128) */
    /* likelihood */
    float sigma_max;       /* density scale per metre                        (30) */
    float sigma_c;         /* colour std                                    (0.2) */
    float air_cut;         /* c, air-sample near/far cut-off               (0.98) */
    float delta_s;         /* surface jitter behind the surface, m         (0.03) */
    float eps_sigma_rel;   /* eps_sigma = eps_sigma_rel * sigma_max        (1e-4) */
    float d_clip, t_near;  /* clip depth and near plane, m              (8, 0.1) */
    /* geometry */
    float box_rh, box_hb;  /* locality box half-width, height, m        (0.6, 1.2) */
    float gauss_s;         /* Gaussian-trick width s, m                     (0.3) */
    float block_size;      /* layout block side B_s, m                      (4.0) */
    int use_box;           /* 1 = locality box (always 1 except in tests)    (1)  */
    /* posteriors */
    float rho_min, rho_max;  /* log-variance clamp                      (-10, 4) */
    float prior_sigma_t;     /* slot prior position std, m                  (0.5) */
    float prior_near, prior_far; /* slot prior means spread ahead, m    (1.3, 6.2) */
    float prior_pres_logit;  /* initial learnable prior presence logit       (0) */
    /* MulMON-style global-frame baseline (src/global/global.c, docs/baseline.md);
     * appended fields (checkpoint version 2; version-1 files load with these = 0) */
    int global_frame;        /* 1 = the baseline: K world-frame slots, no cogmap   (0) */
    float global_radius;     /* slot prior means spread over a disc of this radius
                                around the world origin, m                    (4.2) */
    /* appended in checkpoint version 3 (older files load with 0) */
    int slots;               /* object slots per view at inference (mapper, eval), when
                                the caller does not choose: 0 = K; more = K plus
                                mirrored priors (sooc_model_copy_slots). Training
                                uses K                                          (0) */
    /* appended in checkpoint version 4 (older files load with 0 = free) */
    int invalid_depth;       /* what a pixel without valid depth says (SOOC_INVALID_DEPTH_*):
                                FREE = no surface up to d_clip (synthetic sky / beyond
                                range); UNKNOWN = a sensor hole, masked out of the
                                likelihood and the refinement inputs    (0 = FREE) */
    /* appended in checkpoint version 5 (older files load with 1) */
    float unit_m;            /* metres per model unit (docs/model.md "Model unit"): every
                                length above (d_clip, t_near, box, gauss_s, block_size,
                                delta_s, priors, global_radius; sigma_max is per unit) is
                                in model units; frames, poses and the cognitive map are
                                in metres and the model divides what comes in by unit_m
                                and multiplies what goes out                      (1) */
    /* appended in checkpoint version 6 (older files load with SOOC_MODEL_CAM_H_MIN / _MAX) */
    float cam_h_min, cam_h_max; /* camera heights above the support plane the model was
                                trained at, model units: `sooc3d train` stores the range
                                of its training views; the frame path and the node warn
                                outside it                                  (1.2, 2.0) */
} sooc_model_config;
/* The camera heights of the unity and blender generators (src/gen/gen.c), model
 * units: the default of cam_h_min / cam_h_max and of checkpoints older than
 * version 6. */
#define SOOC_MODEL_CAM_H_MIN 1.2f
#define SOOC_MODEL_CAM_H_MAX 2.0f

/* config.invalid_depth (docs/model.md "Invalid depth"). Under UNKNOWN a ray
 * whose depth is invalid (valid = 0, z <= 0 or non-finite) or nearer than
 * t_near has no surface sample, no air sample and no colour term; a valid
 * depth beyond d_clip is still "free up to d_clip". */
enum { SOOC_INVALID_DEPTH_FREE = 0, SOOC_INVALID_DEPTH_UNKNOWN = 1 };
/* "free" / "unknown" -> the enum value; SOOC_EINVAL naming the word otherwise. */
sooc_status sooc_model_invalid_depth_parse(const char *s, int *mode);
const char *sooc_model_invalid_depth_name(int mode);

void sooc_model_config_default(sooc_model_config *c);
/* Validate sizes (K <= SOOC_MODEL_K_MAX, d <= SOOC_MODEL_D_MAX, img divisible
 * by ray grid, ray grid divisible by 16, ...). */
sooc_status sooc_model_config_check(const sooc_model_config *c);

typedef struct sooc_model sooc_model;

/* Create with freshly initialised weights (deterministic for init_seed). */
sooc_status sooc_model_create(sooc_model **out, const sooc_model_config *c, uint64_t init_seed);
void sooc_model_destroy(sooc_model *m);   /* NULL-safe */
const sooc_model_config *sooc_model_get_config(const sooc_model *m);
/* The object locality box as a map-entry extent (x, y, z) in metres:
 * (2 R_h, H_b, 2 R_h) times unit_m. */
void sooc_model_box_extent(const sooc_model_config *c, float ext[3]);
/* Threads for the decoder / refinement loops (0 = OpenMP default). */
void sooc_model_set_threads(sooc_model *m, int n);
/* Use another clip depth d_clip (metres) than the one trained with, e.g. the
 * usable range of the depth sensor: pixels beyond it count as "no surface
 * up to d_clip", and map entries beyond it are out of view. The weights are
 * unchanged; config.d_clip becomes d_clip / unit_m (model units). SOOC_EINVAL
 * unless t_near < d_clip / unit_m < 1e4. */
sooc_status sooc_model_set_clip(sooc_model *m, float d_clip);
/* Set the model's inference slot count (config.slots, saved with it): 0 = K.
 * SOOC_EINVAL unless 0 or K <= slots <= SOOC_MODEL_K_MAX (0 for the
 * global-frame baseline). The weights are unchanged. */
sooc_status sooc_model_set_slots(sooc_model *m, int slots);
/* Set config.invalid_depth (saved with the model; the weights are unchanged),
 * e.g. SOOC_INVALID_DEPTH_UNKNOWN to run a model trained on synthetic data on
 * a real sensor's frames. SOOC_EINVAL for another value. */
sooc_status sooc_model_set_invalid_depth(sooc_model *m, int mode);
/* Set config.unit_m (metres per model unit, saved with the model; the weights
 * and the config's lengths in model units are unchanged), e.g. 1 / 3.5 to run
 * a model trained on scenes shown 3.5 times larger on metric tabletop frames.
 * The clip depth in metres becomes d_clip * unit_m. SOOC_EINVAL unless
 * 1e-3 <= unit_m <= 1e3. */
sooc_status sooc_model_set_unit(sooc_model *m, float unit_m);
/* The trained camera-height range (config cam_h_min / cam_h_max) in metres,
 * and setting it from metres (0 < lo < hi; SOOC_EINVAL otherwise). */
void sooc_model_cam_heights_m(const sooc_model_config *c, double *lo_m, double *hi_m);
sooc_status sooc_model_set_cam_heights(sooc_model *m, double lo_m, double hi_m);
/* A copy of m that samples its rays on a ray_w x ray_h grid of each view
 * instead of its config's (e.g. every pixel of a 64x64 frame: 64x64 instead
 * of the stratified 32x32 sub-grid). No weight depends on the grid (above
 * 32 x 32 the refinement nets average-pool their last conv map to the 2 x 2
 * of a 32 x 32 grid), so the copy's weights are m's bit for bit; the cost of
 * an update grows with the ray count. SOOC_EINVAL for a grid the config
 * check rejects (multiples of 16 dividing the image, above 32 multiples of
 * 32), and between a 16-wide grid and a wider one (their FC sizes differ). */
sooc_status sooc_model_copy_rays(const sooc_model *m, int ray_w, int ray_h, sooc_model **out);

/* A copy of m that runs with K object slots per view (K = 0: m's inference
 * setting, config.slots, or its K when that is 0; the copy's config.slots is
 * 0, so it runs with exactly its K). The weights and the K_trained learnt slot
 * priors are m's; the added slots' priors are mirror images (x -> -x) of the
 * learnt ones nearest the median prior depth, in slot order (docs/model.md
 * "slots at inference"). SOOC_EINVAL unless m's K <= K <= SOOC_MODEL_K_MAX
 * (the global-frame baseline: only its own K). */
sooc_status sooc_model_copy_slots(const sooc_model *m, int K, sooc_model **out);

/* ---- the runner's workspace ----
 *
 * A sooc_model holds configuration and weights only. Whoever runs it (the
 * mapper, the trainer, eval, finetuning) creates a workspace for it: the
 * decoder's and the refinement's scratch (sized for the model's ray grid and
 * K at creation), the task pool (m's thread count, sooc_model_set_threads)
 * and the training step's state (made on the first step). One workspace per
 * thread of control; several may share one model (read-only weights) when
 * no step writes its gradients. The model must outlive its workspaces
 * (docs/model.md "Layers"). */
typedef struct sooc_model_ws sooc_model_ws;
sooc_status sooc_model_ws_create(sooc_model_ws **out, sooc_model *m);
void sooc_model_ws_destroy(sooc_model_ws *w);   /* NULL-safe */

/* ---- parameters: one flat float slab, with named tensors ---- */
size_t sooc_model_param_count(const sooc_model *m);
float *sooc_model_params(sooc_model *m);
float *sooc_model_grads(sooc_model *m);
void sooc_model_zero_grad(sooc_model *m);

typedef struct sooc_model_tensor {
    const char *name;      /* e.g. "dec.obj.W1x", "ref.obj.lstm.Wx", "prior.slots" */
    size_t offset, count;  /* into the slab                                        */
    int rows, cols;        /* 2-D shape (rows x cols, row-major), cols = 1 for 1-D */
    int no_decay;          /* 1 for biases, priors (no weight decay)               */
} sooc_model_tensor;
/* Number of tensors; fills up to cap entries of out (out may be NULL). */
int sooc_model_tensors(const sooc_model *m, sooc_model_tensor *out, int cap);

/* ---- checkpoint (magic "SOOCMDL1", version, config, params, optional
 * opaque trainer blob, CRC32; atomic save) ---- */
sooc_status sooc_model_save(const sooc_model *m, const char *path, const void *trainer_blob,
                            size_t blob_size);
/* Load: creates the model. If blob != NULL, *blob receives a sooc_malloc'd copy
 * of the trainer blob (NULL if none) and *blob_size its size. */
sooc_status sooc_model_load(sooc_model **out, const char *path, void **blob, size_t *blob_size);

/* ---- training step ---- */

typedef enum sooc_pres_mode {
    SOOC_PRES_RELAXED = 0,      /* relaxed Bernoulli everywhere (default)                  */
    SOOC_PRES_ST_RETRIEVED = 1, /* hard straight-through z^pres for map-retrieved slots   */
    SOOC_PRES_ST_ONE = 2        /* burn-in: forward z^pres = 1 for every slot, gradient of
                                   the relaxed sample (straight-through)                  */
} sooc_pres_mode;

typedef struct sooc_step_opts {
    float tau;             /* relaxed-Bernoulli temperature (trainer anneals 1 -> 0.7) (1)  */
    float beta_kl;         /* KL weight (curriculum warm-up)                          (1)  */
    sooc_pres_mode pres_mode;                                                    /* RELAXED */
    int L;                 /* 0 = config L                                            (0)  */
    int truncate_views;    /* 1 = detach λ between views (fallback)                  (0)  */
    float sigma_c;         /* 0 = config sigma_c (for likelihood annealing)           (0)  */
    int mean_latents;      /* 1 = decode the posterior means in the refinement loop
                              (no reparameterisation noise; inference only)        (0)  */
    int proposals;         /* 1 = each input view's padded slots start on its support-plane
                              clusters (docs/geometric.md "Proposals"); those slots take no
                              gradient to the learnt priors                         (0)  */
    double prop_join_m;    /* the clusters' join distance; 0 = mapper.h's default  (0)  */
    double prop_logit;     /* presence logit of a proposed slot; NaN = the prior's (NaN) */
    double prop_rest_logit;/* presence logit of the other padded slots; NaN = the prior's (NaN) */
} sooc_step_opts;
void sooc_step_opts_default(sooc_step_opts *o);

typedef struct sooc_step_losses {
    double total;          /* the minimised loss: sum_t sum_l (l/L) L_t^l + query NLL       */
    double nll_input;      /* sum_t of -ell_t(λ_t^L) (final iterate)                         */
    double kl;             /* sum_t KL(λ_t^L || λ_t^0) (final iterate, unweighted by beta)   */
    double nll_query;      /* sum_q -ell_q                                                   */
    double nll_depth, nll_color;  /* final-iterate input NLL split                           */
    double present_slots;  /* mean over input views of #slots with p >= 0.5 after refinement */
    double mean_pres_logit;/* mean final presence logit over slots and views                 */
    double map_entries;    /* entries in the map after the last input view                   */
    int n_views, n_queries;
    int nonfinite;         /* 1 if the loss or a gradient was non-finite (grads zeroed)      */
    double sec_backward;   /* wall seconds of the reverse sweep (refinement backward); the
                              rest of the step is the forward sweep, which includes the
                              decoder's backward (the trainer's t_forward / t_backward)  */
} sooc_step_losses;

/* One scene: T input views (in order) then Q query views, all of the model's
 * resolution, with poses (world +y up, floor y = 0) and planar depth
 * (0 = invalid). Runs retrieve -> refine -> register over the input views with
 * a cognitive map, decodes the query views from the final map, and
 * ACCUMULATES d(total)/d(params) into the gradient slab of w's model. `rng` drives every
 * random choice (ray offsets, samples, noise), so a step is deterministic for
 * a given rng state and thread count. If the loss is non-finite, nothing is
 * accumulated and losses->nonfinite = 1 (status OK). */
sooc_status sooc_model_train_step(sooc_model_ws *w, const sooc_frame *views, int T,
                                  const sooc_frame *queries, int Q, const sooc_step_opts *o,
                                  sooc_rng *rng, sooc_step_losses *losses);

/* ---- render.h field adapter: draw from a map ----
 *
 * A field for one camera: component 0 = the layout of the camera's active
 * block (its latent from the map, or the layout prior), components 1..n =
 * the map entries in view (cogmap query, top max_obj by presence), each with
 * its locality box for culling. Latents at their posterior means, or one
 * posterior sample when sample_rng != NULL (for the uncertainty map);
 * z^pres = 1 for registered entries. The field's frame is G of the camera:
 * pass sooc_model_field_T_fc() to sooc_render_view. Evaluation is
 * allocation-free (per-worker scratch sized by the prepare callback) and
 * deterministic per batch. The model and map must outlive the field; the
 * map is only read during create, except the finetuned decoders: an entry
 * or the active layout block with a finetuning payload (cogmap.h payloads,
 * include/sooc3d/train.h) is drawn with its own decoder copy and z^what,
 * read from the map while the field lives (do not change payloads meanwhile). */
typedef struct sooc_model_field sooc_model_field;
sooc_status sooc_model_field_create(sooc_model_field **out, sooc_model *m, const sooc_cogmap *map,
                                    const double T_wc[16], const sooc_intrinsics *K, int max_obj,
                                    sooc_rng *sample_rng);
void sooc_model_field_destroy(sooc_model_field *f);   /* NULL-safe */
const sooc_field *sooc_model_field_get(const sooc_model_field *f);
void sooc_model_field_T_fc(const sooc_model_field *f, double T_fc[16]);
/* Map entry id of component c (0 for the layout). */
uint64_t sooc_model_field_comp_id(const sooc_model_field *f, int c);

/* The online mapper's model and cognitive map (for rendering / evaluation
 * from a mapper; owned by the mapper). */
sooc_model *sooc_mapper_model(sooc_mapper *mp);
const sooc_cogmap *sooc_mapper_cogmap(const sooc_mapper *mp);
/* Create a mapper around an already loaded model (takes ownership of m). */
sooc_status sooc_mapper_create_with_model(sooc_mapper **out, sooc_model *m, int iterations, uint64_t seed,
                                            int threads);

/* The MulMON-style global-frame baseline (config.global_frame = 1): its
 * training step and mapper are in sooc3d/train.h (src/global). */
int sooc_model_is_global(const sooc_model *m);
/* n = min(K, n_objects + 1) slots for a scene of n_objects (<= 0: K). */
int sooc_model_global_slots(const sooc_model *m, int n_objects);

/* ==== data-parallel training over MPI (dist) ============================= */

/*
 * Data-parallel training over MPI (docs/cluster.md).
 *
 * `mpirun -np N sooc3d train ...` runs N ranks. Every rank holds the whole
 * model; each takes a disjoint share of a step's scenes, and the gradients
 * are summed with one in-place allreduce over the flat gradient slab, so
 * every rank applies the same Adam update. Rank 0 alone writes checkpoints,
 * logs, validation and curves (src/train/trainer.c).
 *
 * This is the whole interface; the MPI calls live in src/train/dist.c.
 * Without MPI (built with -DSOOC_WITH_MPI=OFF, or Open MPI absent) or when
 * the process was not started by an MPI launcher (no OMPI_COMM_WORLD_SIZE,
 * PMIX_RANK or PMI_RANK in the environment), it is one rank of one and every
 * collective is a no-op. A build without MPI that finds itself started as one
 * of several ranks refuses to run (sooc_dist_init fails) rather than let N
 * copies write the same files.
 *
 * Errors: MPI_COMM_WORLD gets MPI_ERRORS_RETURN, every call is checked, and a
 * failing collective returns SOOC_EIO with a message naming this rank, the
 * call and MPI's error string. The caller (the CLI) then calls
 * sooc_dist_abort so that no other rank waits forever. A rank that dies
 * (signal, exit without finalising) is caught by the runtime: mpirun aborts
 * the job and names the rank ("mpirun noticed that process rank R ...").
 * The library never prints or exits; sooc_dist_abort is for the CLI only.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

/* 1 if this build has MPI (SOOC_WITH_MPI and Open MPI found). */
int sooc_dist_compiled(void);
/* Start MPI if the process was started by an MPI launcher; otherwise (or
 * without MPI) become rank 0 of 1. argc/argv may be NULL. Call once, before
 * any other sooc_dist_* call. */
sooc_status sooc_dist_init(int *argc, char ***argv);
/* Finalise MPI if sooc_dist_init started it. */
void sooc_dist_finalize(void);
/* Abort every rank of the job (MPI_Abort) with exit code `code`; without MPI
 * it returns (the caller exits). For the CLI's failure path. */
void sooc_dist_abort(int code);

int sooc_dist_rank(void);   /* 0 .. size-1 (0 without MPI)           */
int sooc_dist_size(void);   /* number of ranks (1 without MPI)       */
/* Processor name (host) of this rank, for messages. */
const char *sooc_dist_host(void);

/* In-place sums over all ranks (MPI_Allreduce with MPI_IN_PLACE, MPI_SUM).
 * `what` names the collective in an error message. */
sooc_status sooc_dist_sum_f32(float *buf, size_t n, const char *what);
sooc_status sooc_dist_sum_f64(double *buf, size_t n, const char *what);
/* Rank 0's bytes to every rank (MPI_Bcast). */
sooc_status sooc_dist_bcast(void *buf, size_t bytes, const char *what);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_MODEL_H */
