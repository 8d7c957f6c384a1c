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
#ifndef SOOC3D_TRAIN_H
#define SOOC3D_TRAIN_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/model.h"

#ifdef __cplusplus
extern "C" {
#endif

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
 * frame path (include/sooc3d/framepath.h): any resolution is cropped/resized
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
 * Under MPI (include/sooc3d/dist.h; the caller ran sooc_dist_init) every
 * rank calls this with the same arguments: each takes accum scenes of the
 * step's ranks x accum, the gradients are summed over the ranks, and rank 0
 * alone writes out_dir (docs/cluster.md). log.csv's t_* columns give the
 * seconds of each stage of a step (docs/training.md). */
sooc_status sooc_train_run(const sooc_train_config *cfg, const sooc_model_config *mc,
                           const sooc_train_run_params *rp);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_TRAIN_H */
