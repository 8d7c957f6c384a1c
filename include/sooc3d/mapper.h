/*
 * sooc3d mapper: the online mapper and its geometry. Geometric clusters
 * of the voxelised frames, the mapper itself (keyframes, the gate, map
 * updates, proposals) and the geometry of map objects.
 *
 * Sections: geometric clusters (cluster); the online mapper (mapper); object
 * geometry (objgeom).
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
#ifndef SOOC3D_MAPPER_H
#define SOOC3D_MAPPER_H

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/render.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== geometric clusters (cluster) ======================================= */

/*
 * sooc3d support-plane clustering: the geometric object map (docs/geometric.md).
 *
 * The floor every learnt map must beat, and a mode users can pick
 * (`model: {kind: geometric}`, `sooc3d eval --baseline geometric`): in the
 * map's world frame (+y up, the support plane at y = 0; frame.h), the depth
 * points of every keyframe are merged into a voxel grid; the voxels between
 * min_height_m and max_height_m above the plane are joined when their
 * centroids lie within dist_m of each other (single linkage: connected
 * components in 3D), and each component of at least min_voxels voxels and
 * at most max_extent_m across is an object with its box. The other voxels
 * (the plane, the surround, what is too small or too large) stay in the grid
 * as background, so a rendered view is occluded by them as the camera saw it.
 *
 * The same code gives the learnt mapper its proposals: the objects of a map
 * made of one keyframe.
 *
 * Ownership: a sooc_cluster_map owns its grid; create / destroy. Results are
 * written to caller buffers. Threading: one map per thread; no globals.
 * Errors: sooc_status codes with a message (core.h); nothing prints.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

typedef struct sooc_cluster_params {
    double voxel_m;        /* grid cell: points of all keyframes merged per cell (0.004)    */
    double dist_m;         /* two voxels join when their centroids are closer (0.02)         */
    double min_height_m;   /* above the plane by at least this to be an object point (0.012) */
    double max_height_m;   /* higher points are the surround (0.6)                           */
    double max_depth_m;    /* depth beyond this is not used (3.0)                            */
    int min_voxels;        /* smaller components are noise (12)                              */
    double max_extent_m;   /* a component wider than this in x or z is the surround (0.5)    */
    int pixel_step;        /* back-projection stride in pixels (1)                           */
    double wall_m;         /* vertical planes running on this far are walls, not objects (0.3;
                              0 = keep them)                                                  */
    double free_ratio;     /* free space: a voxel that later frames saw through (their depth
                              lies behind it) at least this many times per frame that put a
                              point in it is not an object voxel: mixed pixels at depth
                              edges, reflections (1; 0 = keep every voxel)                  */
    double rest_m;         /* a component whose lowest voxel is higher above the plane than
                              this stands on nothing: not an object (0.06; 0 = keep them)   */
} sooc_cluster_params;
void sooc_cluster_params_default(sooc_cluster_params *p);

/* One object: a box on the floor (world frame, metres). */
typedef struct sooc_cluster_object {
    int label;             /* 0..n-1, the value sooc_cluster_render writes             */
    double x, z, yaw;      /* box centre on the floor; heading of the smallest floor rectangle */
    double extent[3];      /* box size along its own x, y (height), z                   */
    double centre_y;       /* box centre height above the plane                         */
    double rgb[3];         /* mean colour, 0..1                                          */
    int n_voxels;
} sooc_cluster_object;

typedef struct sooc_cluster_map sooc_cluster_map;

sooc_status sooc_cluster_map_create(sooc_cluster_map **out, const sooc_cluster_params *p);
void sooc_cluster_map_destroy(sooc_cluster_map *m);   /* NULL-safe */
void sooc_cluster_map_clear(sooc_cluster_map *m);

/* Add a posed depth frame (world frame; frames without a pose are refused).
 * Invalidates the last segmentation. */
sooc_status sooc_cluster_map_add_frame(sooc_cluster_map *m, const sooc_frame *f);

/* Connected components over the grid; *n_objects gets the object count.
 * Objects are numbered by decreasing size. */
sooc_status sooc_cluster_map_segment(sooc_cluster_map *m, int *n_objects);

/* Objects of the last segmentation: up to cap into out, the count in *n. */
sooc_status sooc_cluster_map_objects(const sooc_cluster_map *m, sooc_cluster_object *out, int cap, int *n);

/* The object voxels of the last segmentation (those with a label), in one
 * fixed order: *n gets their count; up to cap of their centroids (world
 * frame, metres) go to xyz (cap x 3) and their segmentation labels to label
 * (cap; either may be NULL). */
sooc_status sooc_cluster_map_object_points(const sooc_cluster_map *m, float *xyz, int32_t *label, size_t cap,
                                           size_t *n);

/* Label the object voxels anew, in the order of
 * sooc_cluster_map_object_points (n must be their count): label[i] >= 0 is
 * what sooc_cluster_map_render writes for voxel i, -1 makes it background.
 * The objects (sooc_cluster_map_objects) stay those of the segmentation; the
 * next add_frame or segment drops the new labels. */
sooc_status sooc_cluster_map_relabel(sooc_cluster_map *m, const int32_t *label, size_t n);

/* Render the grid into a view (camera-to-world T_wc, intrinsics K at w x h):
 * each voxel centroid goes to its pixel with a depth test; pixels that no
 * centroid reached take the nearest in depth of their 8 neighbours. label
 * (w*h) gets the object label or -1 (background or nothing); depth (w*h)
 * planar metres or 0, and rgb (w*h*3) the voxels' mean colour 0..1 or 0 may
 * be NULL. */
sooc_status sooc_cluster_map_render(const sooc_cluster_map *m, const double T_wc[16], const sooc_intrinsics *K,
                                    int w, int h, int16_t *label, float *depth, float *rgb);

/* ---- the entries' observed surfaces (docs/geometric.md) ----
 *
 * Every object voxel of a segmented cluster map is claimed by the component
 * (1.., a map entry) of a field whose density (times presence, inside its
 * box) is highest at the voxel's centroid; none above min_sigma: unclaimed.
 * Then per cluster of the segmentation, claimants with less than min_share
 * of its claimed voxels give them to its largest claimant, and with fill its
 * unclaimed voxels go to that claimant too. */
typedef struct sooc_surface_params {
    double min_sigma;   /* the least density that claims a voxel               (0.01) */
    double min_share;   /* a claimant's least share of a cluster's claimed voxels (0) */
    int fill;           /* 1: a claimed cluster's unclaimed voxels to its largest  (0) */
} sooc_surface_params;
void sooc_surface_params_default(sooc_surface_params *p);

typedef struct sooc_surface_claims {
    size_t n;           /* the object voxels (sooc_cluster_map_object_points order) */
    float *xyz;         /* n x 3 centroids, world frame                            */
    int32_t *label;     /* n: the claiming component, or -1                       */
} sooc_surface_claims;
void sooc_surface_claims_free(sooc_surface_claims *c);   /* NULL-safe */

struct sooc_field;
/* Claim cm's object voxels for the components of f (T_fw: world -> the
 * field's frame); cm is relabelled with the claims (sooc_cluster_map_relabel)
 * and out gets them (free with sooc_surface_claims_free). sp NULL: defaults. */
sooc_status sooc_surface_claim(const struct sooc_field *f, const double T_fw[16], sooc_cluster_map *cm,
                               const sooc_surface_params *sp, sooc_surface_claims *out);
/* The same for the field that draws map from f's camera
 * (sooc_model_field_create: the in-view entries, up to max_obj, <= 0 = all
 * it can): *fld gets the field (its components name the claimants,
 * sooc_model_field_comp_id; the caller destroys it), out the claims. */
struct sooc_model;
struct sooc_model_field;
sooc_status sooc_surface_claim_frame(struct sooc_model *m, const sooc_cogmap *map, const sooc_frame *f, int max_obj,
                                     sooc_cluster_map *cm, const sooc_surface_params *sp,
                                     struct sooc_model_field **fld, sooc_surface_claims *out);
/* The box of the voxels component comp claims, in the frame of an entry at
 * (X, Z) with heading yaw, centred on (X, Z) as every planner box: extent
 * along its x, height, z (twice the farthest voxel centroid on each floor
 * axis, plus a voxel; the highest centroid plus half a voxel) and the centre
 * (0, half the height, 0: objects stand on the plane). Returns their count
 * (0: none, the box is not written). */
int sooc_surface_box(const sooc_surface_claims *c, int comp, double X, double Z, double yaw, double voxel_m,
                     float extent[3], float centre[3]);

/* ==== the online mapper (mapper) ========================================= */

/*
 * sooc3d online mapper: the amortised variational update, once per keyframe
 * (docs/model.md). This is the API the node calls.
 *
 *   sooc_mapper *m;
 *   sooc_mapper_create(&m, &params);          // loads the model checkpoint
 *   for each keyframe: sooc_mapper_update(m, &frame, &stats);
 *   sooc_mapper_entries(m, ...)               // read the map
 *   sooc_mapper_destroy(m);
 *
 * Thread-safety: one thread may call update/entries at a time (the mapping
 * thread owns the mapper). The cost of an update depends on K, L and the ray
 * count, never on the map size.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

/* sooc_map_entry, sooc_map_geometry and their conversions to and from the
 * cognitive map's entries: sooc3d/cogmap.h (src/cogmap/map_entry.c). */

typedef struct sooc_mapper sooc_mapper;

typedef struct sooc_mapper_params {
    const char *model_path;    /* checkpoint file (models/<name>/model.bin)           */
    int iterations;            /* L refinement updates per keyframe; 0 = model default */
    uint64_t seed;             /* seed of ray offsets and posterior samples (results
                                  are deterministic for a seed)                        */
    int threads;               /* 0 = OpenMP default                                   */
    double d_clip;             /* > 0: clip depth in m instead of the model's trained one,
                                  e.g. the depth sensor's usable range (deeper pixels are
                                  "no surface up to d_clip", deeper objects out of view);
                                  0 = the model's                                      */
    double merge_radius;       /* duplicate radius on the floor (m): entries one keyframe
                                  registers closer than this are merged (the better-
                                  observed one is kept), and a new entry this close to an
                                  entry the keyframe did not register is dropped
                                  (sooc_cogmap_merge). <= 0 = never merge (the default:
                                  the paper registers without object matching);
                                  SOOC_MAPPER_MERGE_SUGGESTED opts in                  */
    int latents;               /* what the refinement loop decodes: SOOC_LATENTS_MEAN
                                  (posterior means, no sampling noise: the default) or
                                  SOOC_LATENTS_SAMPLE (one posterior sample per
                                  iteration, as in training; docs/model.md)            */
    int slots;                 /* object slots per keyframe (retrieved + padded): 0 = the
                                  model's inference setting (its config.slots, else its
                                  trained K); more than K pads the extra slots with mirror
                                  images of the learnt priors (sooc_model_copy_slots,
                                  docs/model.md "Slots at inference")                   */
    double same_pose;          /* same-pose radius as a fraction of the object box's
                                  floor side (2 R_h, sooc_model_box_extent): two present
                                  slots of one keyframe closer than this never both
                                  register (sooc_mapper_same_pose). 0 = the default
                                  SOOC_MAPPER_SAME_POSE_FRAC; < 0 = off              */
    int invalid_depth;         /* pixels without valid depth: 0 = the model's setting
                                  (config.invalid_depth), 1 + SOOC_INVALID_DEPTH_* overrides
                                  it (2 = sensor holes unknown, masked out of the
                                  likelihood; docs/model.md "Invalid depth")            */
    int merge_neighbours;      /* 1: with merge_radius > 0, the node's revisit rules
                                  (docs/cogmap.md "Revisits"): also merge a registered
                                  entry with an unregistered one within the radius
                                  (sooc_cogmap_merge_neighbours), hold entries that left
                                  the view, average settled entries, and retire entries
                                  the depth keeps showing as free or never shows
                                  (sooc_mapper_free_space). 0 = off (the default)      */
    /* The creation gate, part of the revisit rules (merge_neighbours; docs/cogmap.md
     * "Revisits", rule 5, sooc_mapper_gate): a NEW slot creates an entry only if it
     * explains enough rays on its own and is not the part of a registered retrieved
     * entry. 0 = the default (SOOC_GATE_*), < 0 = that test off.                    */
    double gate_min_rays;      /* fraction of the keyframe's rays a new slot must own
                                  (largest density) with no registered retrieved slot's
                                  density reaching gate_ratio x its own               */
    double gate_ratio;         /* "explains nearly as well": a retrieved slot's density at
                                  the ray's surface point >= this x the new slot's     */
    double gate_part;          /* fold-in: the fraction of the new slot's owned surface
                                  points inside one registered retrieved slot's floor
                                  box (side 2 R_h) at or above which it is that
                                  object's part (no new entry)                        */
    /* The geometric object map instead of the model (docs/geometric.md "In the node";
     * launch `model: {kind: geometric}`): each keyframe goes into a support-plane
     * cluster map, its clusters are the entries (matched to the entries they
     * continue by floor position; entries in view that no cluster continues are
     * removed). model_path, the model and refinement settings are not used.   */
    int kind;                  /* SOOC_MAPPER_LEARNT (0) or SOOC_MAPPER_GEOMETRIC      */
    sooc_cluster_params cluster;   /* geometric: the clustering (defaults: sooc_mapper_params_default) */
    int input_width, input_height; /* geometric: the frame size it maps at (160 x 120)      */
    double min_presence;       /* geometric: an entry is shown (entries, changes, so the
                                  table and the store) once its presence reaches this,
                                  and withdrawn (reported removed) when it falls below
                                  this - SOOC_MAPPER_PRESENCE_HYST; 0 = every entry (0) */
} sooc_mapper_params;
#define SOOC_MAPPER_PRESENCE_HYST 0.05

enum { SOOC_MAPPER_LEARNT = 0, SOOC_MAPPER_GEOMETRIC = 1 };
/* A geometric entry's appearance latent is its mean colour (RGB, 0..1). */
#define SOOC_GEOMETRIC_LATENT_DIM 3

/* Creation-gate defaults (docs/cogmap.md "Revisits", rule 5; measured on the
 * looped replay and the 10-scene eval, see there) */
#define SOOC_GATE_MIN_RAYS 0.003
#define SOOC_GATE_RATIO 0.5
#define SOOC_GATE_PART 0.5

enum { SOOC_LATENTS_MEAN = 0, SOOC_LATENTS_SAMPLE = 1 };

/* docs/model.md "merging split objects": 0.35 m measured best of 0.25/0.35/0.5 */
#define SOOC_MAPPER_MERGE_SUGGESTED 0.35
/* docs/cogmap.md "Same-pose slots": the default same-pose radius, a fraction of
 * the box's floor side (shipped model: 2 R_h = 1.2 m -> 1.2 mm). Measured:
 * same-keyframe pairs of registered entries are either < 1e-5 m apart
 * (converged to one pose) or >= 2 mm, and >= 4.5 mm at 10 and 16 slots */
#define SOOC_MAPPER_SAME_POSE_FRAC 1e-3

/* The same-pose rule (docs/cogmap.md "Same-pose slots"), applied by every
 * update between refinement and registration: present slots (presence logit
 * a >= 0) of one keyframe whose floor positions lie closer than `radius`
 * metres are one object reached by several slots (e.g. mirrored slot priors
 * converging to it) and must not all register. Slots are visited by presence
 * logit, highest first (tie: lower index); a slot still on turns off the later
 * ones within `radius`: their presence logit is set to -1, so registration
 * drops them. When a turned-off slot came from a map entry (src_ids[j] != 0)
 * and the slot that turned it off did not, the kept slot takes that entry's id
 * (src_ids[i] = src_ids[j], src_ids[j] = 0), so the object keeps its id and
 * history; otherwise the turned-off slot's entry is removed by registration as
 * for any slot that is off. lam: k rows of stride SOOC_LAM_SIZE(d) in one
 * floor frame; src_ids may be NULL. Returns the number of slots turned off.
 * radius <= 0 or k > SOOC_MAPPER_CHANGED_MAX does nothing. */
int sooc_mapper_same_pose(float *lam, uint64_t *src_ids, int k, int d, double radius);

/* Free-space evidence of the revisit rules (docs/cogmap.md "Revisits"): does
 * the frame's depth show the floor place (X, Z) of a map entry as free? Nine
 * probe points inside the entry's footprint, above the floor: three on the
 * vertical through (X, Z) at 0.1, 0.2 and 0.3 H_b and six on a ring of radius
 * R_h / 3 at 0.15 H_b (cam's box). A probe that projects into the frame with
 * valid depth D is informative when the floor behind it along its ray lies
 * more than twice the tolerance t = 0.1 m + 2% of the probe's depth z beyond
 * it; then D > z + t means the ray passed through the probe (free), |D - z| <= t
 * a surface at the probe (occupied), D < z - t something in front (hidden).
 * Returns 0 if any probe is occupied, 1 (free) if at least four probes are
 * free and none hidden, else -1 (no evidence). f: depth in planar metres at
 * cam's intrinsics (0 = invalid; f->valid may be NULL); cam->T_wc world with
 * +y up and the floor at y = 0. */
int sooc_mapper_free_space(const sooc_cogmap_camera *cam, const sooc_frame *f, double X, double Z);

/* The creation gate (revisit rule 5, docs/cogmap.md "Revisits"), on one
 * keyframe's final decode. Components are c = 0 (layout) and 1..n_slots (the
 * object slots). For each slot with role SOOC_GATE_NEW:
 * - owned: rays with a surface point where the slot's density is the largest
 *   of all components (ties: the lower component);
 * - alone: owned rays where no SOOC_GATE_KNOWN slot's density reaches
 *   ratio x the slot's own;
 * - part: the KNOWN slot or map-entry box whose floor box (|x'|, |z'| <=
 *   box_rh in its frame, the decoder's box test) holds the most owned surface
 *   points (slot k < n_slots, or box b as n_slots + b), and that share of the
 *   owned points (part = -1, share 0 if none), and the mean of min(1, part's
 *   density / the slot's) over those points (part_ratio; 0 for a box).
 * create = 0 (reason SOOC_GATE_FEW_RAYS) if alone < min_rays x n_rays
 * (min_rays < 0: test off), else 0 (SOOC_GATE_PART_OF) if the share >=
 * part_frac (part_frac < 0: off), else 1 (SOOC_GATE_CREATED). Slots of
 * other roles get create = 1, reason SOOC_GATE_NOT_NEW and no counts.
 * Pure: no allocation, the inputs are read only. Returns the number of NEW
 * slots refused. */
enum { SOOC_GATE_OFF = 0, SOOC_GATE_NEW = 1, SOOC_GATE_KNOWN = 2 };
#define SOOC_GATE_MAX_BOXES 64
enum { SOOC_GATE_NOT_NEW = 0, SOOC_GATE_CREATED = 1, SOOC_GATE_FEW_RAYS = 2, SOOC_GATE_PART_OF = 3 };
typedef struct sooc_gate_input {
    int n_rays, n_slots;       /* n_slots <= SOOC_MAPPER_CHANGED_MAX                 */
    const float *dens;         /* dens[r * dens_stride + c]: density of component c at
                                  ray r's surface point                               */
    int dens_stride;
    const float *pts;          /* pts[r * pts_stride + 0..2]: ray r's surface point
                                  (x, y, z) in the slots' floor frame                 */
    int pts_stride;
    const uint8_t *surf;       /* 1 = ray r has a surface point                       */
    const float *pose;         /* pose[k * pose_stride + 0..2]: slot k's (x, z, yaw);
                                  a point p is at x' = cos(yaw)(p.x - x) - sin(yaw)(p.z - z),
                                  z' = sin(yaw)(p.x - x) + cos(yaw)(p.z - z)          */
    int pose_stride;
    const int *role;           /* n_slots SOOC_GATE_OFF / _NEW / _KNOWN             */
    double box_rh;             /* half side of a slot's floor box (units of pts)      */
    int n_boxes;               /* floor boxes of map entries that are not among the
                                  slots (<= SOOC_GATE_MAX_BOXES; may be 0): candidates
                                  of the part test like KNOWN slots, without density */
    const float *boxes;        /* boxes[b * box_stride + 0..2]: (x, z, yaw) as pose   */
    int box_stride;
} sooc_gate_input;
typedef struct sooc_gate_verdict {
    int owned, alone, part;
    float part_share;          /* share of the owned points inside part's box          */
    float part_ratio;          /* mean of min(1, part's density / the slot's) there   */
    int create, reason;
} sooc_gate_verdict;
int sooc_mapper_gate(const sooc_gate_input *in, double min_rays, double ratio, double part_frac,
                       sooc_gate_verdict *out);

void sooc_mapper_params_default(sooc_mapper_params *p);

/* Load the model and create an empty map. */
sooc_status sooc_mapper_create(sooc_mapper **out, const sooc_mapper_params *p);
void sooc_mapper_destroy(sooc_mapper *m);   /* NULL-safe */

/* Model input resolution (frames passed to update must have this size). */
void sooc_mapper_input_size(const sooc_mapper *m, int *width, int *height);
/* The camera heights above the support plane the model was trained at, metres
 * (its config cam_h_min / cam_h_max times unit_m): the node's support-plane
 * warning range unless the launch file sets one. */
void sooc_mapper_cam_heights(const sooc_mapper *m, double *lo_m, double *hi_m);

typedef struct sooc_update_stats {
    int n_retrieved;           /* in-view entries retrieved from the map  */
    int n_registered;          /* slots written back (present)            */
    int n_new;                 /* of which new entries                    */
    int n_removed;             /* retrieved entries whose presence fell   */
    int n_merged;              /* registered entries removed as duplicates */
    int n_same_pose;           /* present slots not registered: another slot of
                                  this keyframe with a higher presence landed at
                                  the same pose (sooc_mapper_same_pose)     */
    int n_retired;             /* entries retired on free-space evidence (the
                                  revisit rules, sooc_mapper_free_space) or
                                  for want of geometric support
                                  (sooc_mapper_set_support)                 */
    int n_gated;               /* new slots the creation gate refused (revisit
                                  rule 5, sooc_mapper_gate)                 */
    int n_proposed;            /* prior slots placed on the keyframe's support-plane
                                  clusters (sooc_mapper_set_proposals)       */
    double elapsed_ms;
} sooc_update_stats;

/* One keyframe: query in-view entries, pad to K with the slot priors, refine
 * L times, register the present slots, then remove the duplicates among them
 * within the merge radius (sooc_cogmap_merge; removals are reported
 * by sooc_mapper_changed like presence removals). `f` must have a pose and the model's
 * resolution; depth is planar metres with 0 = invalid. */
sooc_status sooc_mapper_update(sooc_mapper *m, const sooc_frame *f, sooc_update_stats *st);

/* Copy out up to `cap` entries (all entries if out == NULL: returns the count
 * in *n). Entries are ordered by id. */
sooc_status sooc_mapper_entries(const sooc_mapper *m, sooc_map_entry *out, size_t cap, size_t *n);

/* Replace the map's contents (resume from a stored map). Ids are kept and new
 * ids continue after the largest one. */
sooc_status sooc_mapper_load_entries(sooc_mapper *m, const sooc_map_entry *e, size_t n);

/* What the last sooc_mapper_update changed, so a publisher's cost does not
 * depend on the map size: the entries it registered (new or overwritten),
 * ordered by id, and the ids it removed. At most K of each (the slots the
 * mapper runs with), and K <= SOOC_MODEL_K_MAX whatever the slot setting, so
 * arrays of SOOC_MAPPER_CHANGED_MAX always fit. out / removed_ids may be NULL
 * (counts only). EINVAL if a non-NULL array is too small (*n / *n_removed
 * still give the counts). Empty after create, after load_entries and after an
 * update that failed early. */
#define SOOC_MAPPER_CHANGED_MAX 32   /* = SOOC_MODEL_K_MAX (model.h includes this header; mapper.c asserts it) */
sooc_status sooc_mapper_changed(const sooc_mapper *m, sooc_map_entry *out, size_t cap, size_t *n,
                                  uint64_t *removed_ids, size_t cap_r, size_t *n_removed);

/* Layout latents (one per floor block, d_l floats of mean and log-variance).
 * layout_dim is 0 for a mapper without layout latents. last_layout: the block
 * the last update wrote (SOOC_ENOTFOUND if none). load_layout: restore a
 * stored block (resume). */
int sooc_mapper_layout_dim(const sooc_mapper *m);
/* z^what dimension of the entries (sooc_map_entry.latent_dim). */
int sooc_mapper_latent_dim(const sooc_mapper *m);
sooc_status sooc_mapper_last_layout(const sooc_mapper *m, int32_t *bi, int32_t *bj, float *mu, float *logvar);
sooc_status sooc_mapper_load_layout(sooc_mapper *m, int32_t bi, int32_t bj, const float *mu,
                                      const float *logvar);

/* Object geometry (include/sooc3d/mapper.h): every update keeps the
 * registration statistics of the entries it wrote and recomputes at most
 * `per_update` stale tight boxes (default SOOC_OBJGEOM_BUDGET; 0 = none
 * during updates, < 0 = all); an entry whose box it recomputed without
 * registering it is added to the update's changed set (sooc_mapper_changed)
 * so that publishers republish it, room permitting (K_MAX). refresh_geometry computes up to max_objects
 * stale boxes now (< 0 = all; e.g. before reading a final map); *n_done
 * (may be NULL) = boxes computed. entries() / changed() fill extent and geom. */
void sooc_mapper_set_geometry_budget(sooc_mapper *m, int per_update);
/* Mark every cached tight box stale (the decoders changed, e.g. finetuning),
 * and take up the entries someone else put into the mapper's map (births
 * before finetuning, train.h): their statistics start from their current
 * pose, their boxes are computed by the next refresh. */
void sooc_mapper_geometry_invalidate(sooc_mapper *m);
sooc_status sooc_mapper_refresh_geometry(sooc_mapper *m, int max_objects, int *n_done);

/* Set the merge radius of a live mapper (same meaning as the parameter). */
/* The revisit rule of sooc_mapper_params.merge_neighbours (0 / 1). */
void sooc_mapper_set_merge_neighbours(sooc_mapper *mp, int on);
/* The creation gate's parameters of a live mapper (same meaning as the
 * gate_* parameters: 0 = default, < 0 = off). */
void sooc_mapper_set_gate(sooc_mapper *mp, double min_rays, double ratio, double part);

/* Geometric proposals (docs/geometric.md "Proposals"): each keyframe's
 * support-plane clusters (the cluster section) place the slots the view
 * pads with priors, before the refinement. A cluster that a retrieved slot covers (its
 * centre within the cluster's half-diagonal + cover_m) proposes nothing. */
typedef struct sooc_proposal_params {
    int on;                      /* 0 = off (the default)                                  */
    sooc_cluster_params cluster; /* the clustering of one keyframe                         */
    double cover_m;              /* (0.02)                                                 */
    double sigma_frac;           /* position std of a placed slot = this x the cluster's
                                    half-diagonal; <= 0: the prior's (0)                   */
    double pres_logit;           /* presence logit of a placed slot; NaN: the prior's (NaN) */
    double rest_logit;           /* presence logit of the prior slots no cluster placed; NaN:
                                    the prior's (NaN)                                        */
} sooc_proposal_params;
void sooc_proposal_params_default(sooc_proposal_params *p);
sooc_status sooc_mapper_set_proposals(sooc_mapper *mp, const sooc_proposal_params *p);
/* Geometric support of the entries (docs/geometric.md "Geometric support"):
 * with margin_m > 0 the mapper also keeps the support-plane clusters of every
 * keyframe it maps (sooc_cluster_params_default with 1 cm voxels, depth up to
 * the model's clip or 3 m) and after each update removes every entry in the
 * keyframe's view whose floor position lies in no cluster's floor box grown by
 * margin_m: with no object points under it, an entry explains only the support
 * surface or a wall. Entries out of view stay. The removals are published as
 * removals (counted as retired in the update's stats). margin_m 0 turns it
 * off (the default). Learnt mappers only. */
sooc_status sooc_mapper_set_support(sooc_mapper *mp, double margin_m);
/* Observed-surface boxes (docs/geometric.md "The entries' observed
 * surfaces"), with the geometric support on: after each update the support's
 * object voxels are claimed by the entries in the keyframe's view
 * (sooc_surface_claim), and each entry the update wrote that claims at least
 * 8 voxels gets the box of its claim (sooc_surface_box) as its planner box
 * (geometry flags TIGHT | SURFACE) in place of its density's. Off by default;
 * on without the support it does nothing while the support is off. */
void sooc_mapper_set_surface_boxes(sooc_mapper *mp, int on);
void sooc_mapper_set_merge_radius(sooc_mapper *m, double radius);
/* Set the latents mode of a live mapper (SOOC_LATENTS_*). */
void sooc_mapper_set_latents(sooc_mapper *m, int latents);

/* Forget the map: every entry, layout block and payload, the evidence kept
 * about them, and the clusters of the keyframes mapped so far (the geometric
 * map, its support and proposals). The id counter goes on (ids are never
 * handed out twice). For a change of world frame: the node's switch to the
 * floor (docs/node.md "Support plane"). The caller publishes the removals. */
sooc_status sooc_mapper_clear(sooc_mapper *m);

/* Id counter: new entries get ids >= next_id. reserve_ids raises it (resume:
 * ids of entries removed before the restart are not handed out again). */
void sooc_mapper_reserve_ids(sooc_mapper *m, uint64_t next_id);
uint64_t sooc_mapper_next_id(const sooc_mapper *m);

/* ==== object geometry (objgeom) ========================================== */

/*
 * sooc3d object geometry for planners (docs/shm.md "How
 * each field is computed"): the tight box of an object's own density, its
 * height, whether it is rotationally symmetric, and position / yaw spreads
 * that mean something.
 *
 * Tight box. An object's density lives in its locality box,
 * in its own frame: origin on the floor under the object, +y up, rotated by
 * its yaw. The box is sampled on a res^3 grid of cell centres; a sample is
 * inside when sigma_hat >= level (render.h's SOOC_MESH_LEVEL, the one surface
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
/* The box of the observed surface entry id claims (sooc_surface_box): fill
 * gives it in place of the density's box, with SOOC_GEOM_SURFACE. */
sooc_status sooc_objgeom_cache_set_surface(sooc_objgeom_cache *c, uint64_t id, const float extent[3],
                                           const float centre[3]);
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
#endif /* SOOC3D_MAPPER_H */
