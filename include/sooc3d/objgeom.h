/*
 * sooc3d object geometry for planners (docs/shm.md "How
 * each field is computed"): the tight box of an object's own density, its
 * height, whether it is rotationally symmetric, and position / yaw spreads
 * that mean something.
 *
 * Tight box. An object's density lives in its locality box,
 * in its own frame: origin on the floor under the object, +y up, rotated by
 * its yaw. The box is sampled on a res^3 grid of cell centres; a sample is
 * inside when sigma_hat >= level (mesh.h's SOOC_MESH_LEVEL, the one surface
 * level of the project). The coarse box of the inside samples is then
 * refined face by face: on each face, the grid columns whose first inside
 * sample is the extreme one are bisected between their last outside and
 * first inside sample (`refine` halvings), and the face is the extreme
 * crossing. A face whose first inside sample is the grid's edge is tested at
 * the box wall itself: inside there means the density is cut by the
 * locality box (SOOC_GEOM_CLIPPED; the face is the wall). Cost: res^3 +
 * about 6 x 12 x refine field evaluations plus the symmetry test (4 x 3 x
 * 144), all in batches: with the defaults about 6,000 decoder rows, no
 * allocation per point. A density that reaches the level nowhere in the box
 * but peaks at >= SOOC_OBJGEOM_FAINT_MIN gets the box of the points at or
 * above half its peak instead (SOOC_GEOM_TIGHT | SOOC_GEOM_FAINT: a faint
 * object still gets a box for planners; the mesh at the level is empty);
 * below that it is SOOC_GEOM_EMPTY (extent 0).
 *
 * Symmetry. The density is rotationally symmetric about the vertical axis
 * through the tight box's centre when the inside set of three horizontal
 * slices (at 25/50/75% of the box height, 12 x 12 samples over the disc
 * circumscribing the box's footprint) overlaps itself rotated by 25, 45 and
 * 70 degrees with IoU >= SOOC_OBJGEOM_SYM_IOU each (a square footprint
 * rotated by 45 degrees overlaps itself with IoU 0.71, a disc with 1).
 *
 * Spreads (world, per axis). Position: the posterior variance of the
 * refined latents, exp(rho_t) (shared by x and z), combined with the sample
 * covariance S of the entry's registered positions across keyframes:
 *   cov = K_POST exp(rho_t) I + K_REG S + SIGMA0^2 I       (n >= 2 registrations)
 *   cov = K_POST exp(rho_t) I + SIGMA_NEW^2 I              (one registration)
 * with the constants below fitted on generated scenes of a calibration set
 * (unity m, seed 8001) so that about 68% of the per-axis position errors of
 * held-out scenes (seed 9001) fall within one sigma (docs/shm.md gives the
 * figures; test_objgeom_calib checks it). Yaw: exp(rho_theta) plus the
 * circular variance -2 ln R of the registered yaws (R = mean resultant
 * length); NaN ("undefined") for a symmetric object.
 *
 * Cache. A mapper keeps one sooc_objgeom_cache: registration statistics are
 * updated for every entry a keyframe registers (O(1) each), and the tight
 * box of an entry is recomputed when it is new or its appearance latent has
 * moved by more than SOOC_OBJGEOM_DRIFT (RMS per element) since the box was
 * computed, at most `budget` entries per keyframe (new ones first, then by
 * drift), so a keyframe's cost stays bounded whatever the map size.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_OBJGEOM_H
#define SOOC3D_OBJGEOM_H

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/mapper.h"
#include "sooc3d/render.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SOOC_OBJGEOM_SYM_IOU 0.9     /* symmetric at or above this rotational self-IoU */
#define SOOC_OBJGEOM_DRIFT 0.05      /* RMS z^what change that makes a cached box stale */
#define SOOC_OBJGEOM_FAINT_MIN 0.05  /* a density peak below this (sigma_hat) is EMPTY, not FAINT */
#define SOOC_OBJGEOM_BUDGET 1        /* boxes recomputed per keyframe by the mapper (default) */

/* Position spread calibration (see above; fitted on unity m seed 8001). */
#define SOOC_OBJGEOM_K_POST 1.0
#define SOOC_OBJGEOM_K_REG 0.1
#define SOOC_OBJGEOM_SIGMA0 0.039    /* m */
#define SOOC_OBJGEOM_SIGMA_NEW 0.08  /* m */

typedef struct sooc_objgeom_opts {
    int res;          /* coarse samples per axis over the locality box (8), >= 4 */
    int refine;       /* bisection halvings per face (5)                        */
    float level;      /* surface level on sigma_hat (SOOC_MESH_LEVEL)           */
    int symmetry;     /* 1 = run the symmetry test (1)                          */
} sooc_objgeom_opts;
void sooc_objgeom_opts_default(sooc_objgeom_opts *o);

typedef struct sooc_objgeom_box {
    uint32_t flags;        /* SOOC_GEOM_TIGHT, _EMPTY, _CLIPPED, _SYMMETRIC (mapper.h) */
    double lo[3], hi[3];   /* the tight box in box-local coordinates (m); 0 when EMPTY */
    double sym_iou;        /* min rotational self-IoU (1 when not tested or EMPTY)   */
    long n_eval;           /* field evaluations used                                */
} sooc_objgeom_box;

/* The tight box of component `comp` of a render.h field inside `box` (its
 * T_fb maps box-local points into the field's frame; lo/hi bound the
 * search). f->prepare, if any, is called first. Scratch is allocated once
 * per call. */
sooc_status sooc_objgeom_field_box(const sooc_field *f, int comp, const sooc_render_box *box,
                                   const sooc_objgeom_opts *o, sooc_objgeom_box *out);

struct sooc_model;
/* The tight box of map entry `id`: its component of the model's field
 * (sooc_model_field_*, so an entry's own finetuned decoder is used when the
 * field has one), seen by a virtual camera in front of it, over its
 * locality box. SOOC_ENOTFOUND if the map has no such entry. */
sooc_status sooc_objgeom_entry_box(struct sooc_model *m, const sooc_cogmap *map, uint64_t id,
                                   const sooc_objgeom_opts *o, sooc_objgeom_box *out);

/* Geometry fields of a map entry from a tight box: extent, centre, flags. */
void sooc_objgeom_apply_box(const sooc_objgeom_box *b, float extent[3], sooc_map_geometry *g);
/* Add one registration (world floor position and yaw) to g's statistics. */
void sooc_objgeom_observe(sooc_map_geometry *g, double X, double Z, double yaw);
/* g->cov_xz and g->var_yaw from the posterior log-variances and g's
 * registration statistics (formulas above). */
void sooc_objgeom_spread(double rho_t, double rho_theta, sooc_map_geometry *g);

/* ---------------------------------------------------------------- cache */

typedef struct sooc_objgeom_cache sooc_objgeom_cache;
sooc_status sooc_objgeom_cache_create(sooc_objgeom_cache **out);
void sooc_objgeom_cache_destroy(sooc_objgeom_cache *c);   /* NULL-safe */
void sooc_objgeom_cache_clear(sooc_objgeom_cache *c);
size_t sooc_objgeom_cache_count(const sooc_objgeom_cache *c);
/* Entry e was registered (new or overwritten): update its statistics and
 * mark its box stale if new or drifted. May grow the cache (amortised). */
sooc_status sooc_objgeom_cache_observe(sooc_objgeom_cache *c, const sooc_cogmap_entry *e);
void sooc_objgeom_cache_remove(sooc_objgeom_cache *c, uint64_t id);
/* 1 if the cache holds entry id. */
int sooc_objgeom_cache_has(const sooc_objgeom_cache *c, uint64_t id);
/* Mark every box stale (recomputed by the next refresh). */
void sooc_objgeom_cache_invalidate(sooc_objgeom_cache *c);
/* Resume: take a stored entry's geometry (e->geom, e->extent) as cached for
 * its current latent. */
sooc_status sooc_objgeom_cache_seed(sooc_objgeom_cache *c, const sooc_map_entry *e);
/* Recompute the stale boxes, at most `max` (< 0: all), new entries first,
 * then by drift. *n_done (may be NULL) = boxes computed; their ids go to
 * done_ids (may be NULL; room for max when max >= 0). Entries the map no
 * longer holds are dropped. */
sooc_status sooc_objgeom_cache_refresh(sooc_objgeom_cache *c, struct sooc_model *m, const sooc_cogmap *map,
                                       const sooc_objgeom_opts *o, int max, int *n_done, uint64_t *done_ids);
/* Fill out->extent and out->geom for cogmap entry e from the cache
 * (spreads from e's posterior and the statistics; box fields only once a
 * box was computed, else extent stays as it is). */
void sooc_objgeom_cache_fill(const sooc_objgeom_cache *c, const sooc_cogmap_entry *e, sooc_map_entry *out);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_OBJGEOM_H */
