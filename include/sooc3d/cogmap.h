/*
 * sooc3d cognitive map: the map and how it persists. The map of object
 * entries (registration, in-view queries), the map entry with its geometry,
 * the SQLite map store (keyframes, frames, entries) and the store's SLAM
 * records.
 *
 * Sections: the cognitive map (cogmap); map entries (map_entry); the map
 * store (SQLite) (mapstore); the map store's SLAM records (mapstore_slam).
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
#ifndef SOOC3D_COGMAP_H
#define SOOC3D_COGMAP_H

#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== the cognitive map (cogmap) ========================================= */

/*
 * sooc3d cognitive map (docs/cogmap.md; the SOOC3D paper): the posterior λ of every
 * registered object in the WORLD frame, a spatial hash grid on the floor plane,
 * the per-view query (in-view test, top-K by presence, world -> G_t) and the
 * registration after a view (G_t -> world, overwrite by id / append / remove).
 * Layout latents live per floor block (side B_s).
 *
 * Frames (core.h): world +y up, floor y = 0. A λ handed to / returned by the
 * model is expressed in the gravity-aligned camera frame G_t of its view; the
 * map stores (X, Z, Θ) in the world. Means transform rigidly,
 * log-variances are unchanged (σ_t is shared by x and z, so this is exact),
 * angles are wrapped to (-pi, pi].
 *
 * Flat λ layout (float, docs/cogmap.md; d = latent dim of the map, <= 32):
 *   [0] mu_x  [1] mu_z  [2] mu_theta  [3] rho_t  [4] rho_theta
 *   [5, 5+d)      what mean      [5+d, 5+2d)  what log-variance
 *   [5+2d]        presence logit a           size SOOC_LAM_SIZE(d) = 6 + 2d
 * The same layout is used for a λ in the world frame (then [0..2] = X, Z, Θ)
 * and for gradients with respect to either.
 *
 * Cost: a query visits only the hash-grid cells overlapping the camera
 * frustum's floor footprint up to d_clip, so it does not grow with the number
 * of registered entries (it grows with the local density). Query does not
 * allocate. Registration / insertion may grow internal arrays (amortised).
 *
 * Thread-safety: a sooc_cogmap is not internally locked. Any number of threads
 * may call the const functions concurrently if no thread modifies the map.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

#define SOOC_COGMAP_DIM_MAX 32          /* max latent dim d (and layout d_l)     */
#define SOOC_COGMAP_K_MAX 64            /* max slots per query / registration    */

/* flat λ offsets */
#define SOOC_LAM_X 0
#define SOOC_LAM_Z 1
#define SOOC_LAM_TH 2
#define SOOC_LAM_RHO_T 3
#define SOOC_LAM_RHO_TH 4
#define SOOC_LAM_WHAT_MU 5
#define SOOC_LAM_WHAT_LV(d) (5 + (d))
#define SOOC_LAM_PRES(d) (5 + 2 * (d))
#define SOOC_LAM_SIZE(d) (6 + 2 * (d))
#define SOOC_LAM_MAX SOOC_LAM_SIZE(SOOC_COGMAP_DIM_MAX)   /* 70 */

/* One entry, world frame. Plain value type: copied in and out; unused latent
 * elements (index >= dim) are zero so entries compare with memcmp. */
typedef struct sooc_cogmap_entry {
    uint64_t id;                         /* stable, never reused, from 1            */
    double X, Z, Theta;                  /* where mean in the world (m, m, rad)     */
    float rho_t, rho_theta;              /* where log-variances (rho_t: x and z)    */
    float pres_logit;                    /* presence logit a; p = sigmoid(a)        */
    int32_t dim;                         /* latent dim d of the map                 */
    float what_mu[SOOC_COGMAP_DIM_MAX];
    float what_logvar[SOOC_COGMAP_DIM_MAX];
    int64_t first_seen_ns, last_seen_ns;
    uint32_t obs_count;                  /* registrations so far (>= 1)             */
    int32_t last_view;                   /* view index that last registered it      */
} sooc_cogmap_entry;

typedef struct sooc_cogmap sooc_cogmap;

typedef struct sooc_cogmap_params {
    int dim;              /* object latent dim d, 1..32                      (32)  */
    int layout_dim;       /* layout latent dim d_l, 0..32 (0 = no layout)    (16)  */
    double cell_size;     /* hash-grid cell side on the floor, metres        (4.0) */
    double block_size;    /* layout block side B_s, metres                   (4.0) */
    size_t capacity;      /* initial entry capacity (grows as needed)      (1024) */
} sooc_cogmap_params;

void sooc_cogmap_params_default(sooc_cogmap_params *p);

/* Create an empty map (next id = 1). On failure *out = NULL, nothing leaked. */
sooc_status sooc_cogmap_create(sooc_cogmap **out, const sooc_cogmap_params *p);
void sooc_cogmap_destroy(sooc_cogmap *m);          /* NULL-safe */
/* Remove every entry and layout block. reset_ids = 0 keeps the id counter (ids
 * stay unique across the map's life); 1 restarts at 1 (a new scene in training). */
void sooc_cogmap_clear(sooc_cogmap *m, int reset_ids);

int sooc_cogmap_dim(const sooc_cogmap *m);
int sooc_cogmap_layout_dim(const sooc_cogmap *m);
size_t sooc_cogmap_count(const sooc_cogmap *m);
uint64_t sooc_cogmap_next_id(const sooc_cogmap *m);
/* Raise the id counter to at least `next` (resume; never lowers it). */
void sooc_cogmap_reserve_ids(sooc_cogmap *m, uint64_t next);

/* ------------------------------------------------------------ entries */

/* Copy the entry with this id into *out. SOOC_ENOTFOUND if absent. */
sooc_status sooc_cogmap_get(const sooc_cogmap *m, uint64_t id, sooc_cogmap_entry *out);
/* Insert or overwrite. e->id == 0: a fresh id is assigned (written to *id_out
 * if non-NULL); otherwise that id is used (overwrites if present, and the id
 * counter is raised past it). e->dim must equal the map's d. Non-finite
 * values -> SOOC_ENUMERIC, map unchanged. */
sooc_status sooc_cogmap_insert(sooc_cogmap *m, const sooc_cogmap_entry *e, uint64_t *id_out);
/* Remove by id, O(1) amortised. SOOC_ENOTFOUND if absent. */
sooc_status sooc_cogmap_remove(sooc_cogmap *m, uint64_t id);
/* Copy out up to `cap` entries ordered by id; *n = number copied, or the total
 * count when out == NULL. */
sooc_status sooc_cogmap_entries(const sooc_cogmap *m, sooc_cogmap_entry *out, size_t cap, size_t *n);
/* Replace all entries with e[0..n) (ids kept; ids must be non-zero and
 * distinct); the id counter becomes max(counter, max id + 1). */
sooc_status sooc_cogmap_load(sooc_cogmap *m, const sooc_cogmap_entry *e, size_t n);
/* Visit every entry in storage order (unspecified, not id order). The entry
 * pointer is only valid during the call; fn must not modify the map. A
 * non-zero return from fn stops the walk and is returned. */
typedef int (*sooc_cogmap_visit_fn)(void *user, const sooc_cogmap_entry *e);
int sooc_cogmap_foreach(const sooc_cogmap *m, sooc_cogmap_visit_fn fn, void *user);

/* ----------------------------------------------------- frame transforms */

/* World entry -> flat λ (size SOOC_LAM_SIZE(d)) in the G frame `f`. */
void sooc_cogmap_lam_to_local(const sooc_floor_frame *f, const sooc_cogmap_entry *e, float *lam);
/* Flat λ in G frame `f` -> world fields of *e (where, what, presence, dim = d);
 * id, times, counts and last_view are left untouched. */
void sooc_cogmap_lam_to_world(const sooc_floor_frame *f, int d, const float *lam, sooc_cogmap_entry *e);
/* Gradient transposes, ACCUMULATING (+=), flat layout for both sides:
 *  grad_local_to_world: g_world += J^T g_local for the query map world -> G
 *    (x,z): g_W += R2(psi) g_l; θ and every other element: identity.
 *  grad_world_to_local: g_local += J^T g_world for the registration map G -> world
 *    (x,z): g_l += R2(psi)^T g_W; identity otherwise.
 *  grad_route: the loop register(view t', frame f_reg) -> query(view t, frame
 *    f_query): g_reg += J^T g_query (= R2(psi_reg)^T R2(psi_query) on (x,z)). */
void sooc_cogmap_grad_local_to_world(const sooc_floor_frame *f, int d, const float *g_local, float *g_world);
void sooc_cogmap_grad_world_to_local(const sooc_floor_frame *f, int d, const float *g_world, float *g_local);
void sooc_cogmap_grad_route(const sooc_floor_frame *f_reg, const sooc_floor_frame *f_query, int d,
                            const float *g_query, float *g_reg);

/* ---------------------------------------------------------------- query */

typedef enum sooc_cogmap_inview {
    SOOC_INVIEW_CENTRE = 0,   /* box centre (X, H_b/2, Z) projects inside, depth in (t_near, d_clip) */
    SOOC_INVIEW_CORNERS = 1   /* conservative: any of the 8 box corners does (box yawed by Θ)        */
} sooc_cogmap_inview;

typedef struct sooc_cogmap_camera {
    double T_wc[16];          /* camera-to-world, OpenCV axes                   */
    sooc_intrinsics K;        /* width/height/fx/fy/cx/cy (distortion ignored)  */
    double t_near, d_clip;    /* camera-frame depth range (m), e.g. 0.1, 8      */
    double R_h, H_b;          /* object box half-width and height (m), 0.6, 1.2 */
    sooc_cogmap_inview mode;
} sooc_cogmap_camera;

/* One retrieved slot: the entry id, its λ in G_t, and the view that last
 * registered it (gradient routing in training). */
typedef struct sooc_cogmap_slot {
    uint64_t id;
    int32_t last_view;
    float lam[SOOC_LAM_MAX];  /* first SOOC_LAM_SIZE(d) used, rest zero */
} sooc_cogmap_slot;

/* In-view test of one world entry (exposed for tests and the renderer). */
int sooc_cogmap_in_view(const sooc_cogmap_camera *cam, const sooc_cogmap_entry *e);

/* Query for a camera: in-view entries, the top `k` (<= SOOC_COGMAP_K_MAX) by
 * presence logit (ties: smaller id first), in that order, transformed to G_t.
 * Writes *n_out <= k slots; the caller pads with priors. Optional outputs:
 * `gf` receives the G_t floor frame (for registration / gradient routing) and
 * `n_inview` the number of in-view entries before the top-K cut (may be NULL).
 * Does not modify the map and does not allocate. EINVAL if the camera looks
 * straight up/down or arguments are bad. */
sooc_status sooc_cogmap_query(const sooc_cogmap *m, const sooc_cogmap_camera *cam, int k,
                              sooc_cogmap_slot *out, int *n_out, sooc_floor_frame *gf, int *n_inview);

/* --------------------------------------------------------- registration */

typedef struct sooc_cogmap_reg_stats {
    int n_registered;         /* slots written (present: a >= 0)               */
    int n_new;                /* of which new entries (fresh ids)              */
    int n_updated;            /* of which overwrote a retrieved entry          */
    int n_removed;            /* retrieved entries removed (presence < 0.5)    */
} sooc_cogmap_reg_stats;

/* Register K slots after a view. lam: k rows of stride SOOC_LAM_SIZE(d), in
 * the G frame `gf` (from sooc_cogmap_query). src_ids[i]: entry the slot came
 * from, 0 for a padded prior slot. A slot with a >= 0 (sigmoid >= 0.5) is
 * written to the world: it overwrites its source entry (first_seen kept,
 * obs_count + 1) or becomes a new entry with a fresh id; a slot with a < 0 is
 * dropped and, if it had a source entry, that entry is removed.
 * ids_out[i] (may be NULL): the id written for slot i, 0 if dropped.
 * removed_out (may be NULL, room for k): ids removed, count in st->n_removed.
 * Everything is validated first (unknown or repeated src id -> ENOTFOUND /
 * EINVAL, non-finite λ -> ENUMERIC); on those errors the map is unchanged.
 * An allocation failure (ENOMEM) may leave part of the view registered, with
 * the map consistent. */
sooc_status sooc_cogmap_register(sooc_cogmap *m, const sooc_floor_frame *gf, int k, const float *lam,
                                 const uint64_t *src_ids, int64_t t_ns, int32_t view,
                                 uint64_t *ids_out, uint64_t *removed_out, sooc_cogmap_reg_stats *st);

/* Merge duplicates among the entries one view registered (ids[0..k), 0 =
 * none): two of them whose floor positions are closer than `radius` metres
 * describe one object split over two slots; the one observed more often is
 * kept (on a tie, the older: smaller id) and the other removed. Then a new
 * entry (obs_count 1) closer than `radius` to an entry the view did not
 * register duplicates an object the map already holds (the in-view test
 * missed it, e.g. at the image edge): the new entry is removed. Entries
 * outside ids[] are never modified. Removed ids are zeroed in ids[] and
 * written to removed_out (may be NULL, room for k), count in *n_removed.
 * radius <= 0 does nothing. Unknown ids are skipped. */
void sooc_cogmap_merge(sooc_cogmap *m, uint64_t *ids, int k, double radius, uint64_t *removed_out,
                       int *n_removed);

/* Revisits (the node; docs/cogmap.md "Revisits"), after sooc_cogmap_merge:
 * an entry the view registered (ids[i]) closer than `radius` to an entry the
 * view did not register (the nearest such) is that object seen again, which
 * the view did not retrieve (more entries in view than slots, or an entry
 * that drifted). The two become one: the better-observed id stays (tie: the
 * older), with where (X, Z, Theta) and what means averaged over the two
 * weighted by their observation counts, the view's variances and presence
 * (ids[i]'s), the sum of both observation counts and the earlier first_seen; the other id is removed
 * (written to removed_out, room for cap; at most cap merges) and ids[i] holds
 * the kept id. Unlike sooc_cogmap_merge this removes or overwrites entries
 * outside ids[] (only ones within radius of a registered entry). Fails only
 * when moving the kept entry to another grid cell runs out of memory (the map
 * stays consistent). */
sooc_status sooc_cogmap_merge_neighbours(sooc_cogmap *m, uint64_t *ids, int k, double radius,
                                         uint64_t *removed_out, int cap, int *n_removed);

/* --------------------------------------------------------- layout blocks */

/* Block (bi, bj) covers [bi*B_s, (bi+1)*B_s) x [bj*B_s, (bj+1)*B_s) on (X, Z);
 * its origin is the block centre on the floor. */
void sooc_cogmap_block_of(const sooc_cogmap *m, double X, double Z, int32_t *bi, int32_t *bj);
void sooc_cogmap_block_origin(const sooc_cogmap *m, int32_t bi, int32_t bj, double *X, double *Z);
/* The single active block of a view (docs/cogmap.md): the block holding the
 * ground point at d_clip/2 along the camera's horizontal forward direction.
 * origin_local (may be NULL) = the block origin (x, z) in G_t. */
sooc_status sooc_cogmap_active_block(const sooc_cogmap *m, const double T_wc[16], double d_clip,
                                     int32_t *bi, int32_t *bj, double origin_local[2]);
/* Layout latent of a block (d_l floats each). ENOTFOUND for a new block (use
 * the layout prior). */
sooc_status sooc_cogmap_layout_get(const sooc_cogmap *m, int32_t bi, int32_t bj, float *mu, float *logvar);
sooc_status sooc_cogmap_layout_set(sooc_cogmap *m, int32_t bi, int32_t bj, const float *mu, const float *logvar);
size_t sooc_cogmap_layout_count(const sooc_cogmap *m);
/* Visit every layout block (unspecified order). Non-zero return stops. */
typedef int (*sooc_cogmap_block_fn)(void *user, int32_t bi, int32_t bj, const float *mu, const float *logvar);
int sooc_cogmap_layout_foreach(const sooc_cogmap *m, sooc_cogmap_block_fn fn, void *user);

/* ------------------------------------------------------------- payloads */
/* A float vector kept with an entry id or a layout block: the finetuned
 * decoder of the object / block (include/sooc3d/train.h; the model's field
 * renders with it, sooc_mapstore_load_map / _save_map carry it). The map
 * only stores the values: their meaning is the finetuning module's. Keyed by
 * id (ids are never reused, so a payload of a removed entry is never looked
 * up again); sooc_cogmap_clear and _destroy drop every payload.
 * set: copies v[0..n); n = 0 removes; non-finite values -> SOOC_ENUMERIC.
 * get: the stored values (valid until the next set/clear of that key) and *n,
 * or NULL (*n = 0) if none. */
sooc_status sooc_cogmap_payload_set(sooc_cogmap *m, uint64_t id, const float *v, size_t n);
const float *sooc_cogmap_payload_get(const sooc_cogmap *m, uint64_t id, size_t *n);
sooc_status sooc_cogmap_block_payload_set(sooc_cogmap *m, int32_t bi, int32_t bj, const float *v, size_t n);
const float *sooc_cogmap_block_payload_get(const sooc_cogmap *m, int32_t bi, int32_t bj, size_t *n);
size_t sooc_cogmap_payload_count(const sooc_cogmap *m);
/* Visit every payload (is_block: 0 entry `id`, 1 block (bi, bj)); non-zero stops. */
typedef int (*sooc_cogmap_payload_fn)(void *user, int is_block, uint64_t id, int32_t bi, int32_t bj, const float *v,
                                      size_t n);
int sooc_cogmap_payload_foreach(const sooc_cogmap *m, sooc_cogmap_payload_fn fn, void *user);

/* ==== map entries (map_entry) ============================================ */

/*
 * A cognitive-map entry as the mapper hands it out (world frame, metres,
 * standard deviations), and its conversions to and from the cognitive map's
 * own entry (sooc3d/cogmap.h: log-variances, the rows of the SQLite map
 * store). Implemented in src/cogmap/map_entry.c, so anything that links the
 * cogmap module (the node with a real or a fake mapper, the CLI, the model's
 * mapper) shares one definition.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

#define SOOC_MAP_LATENT_MAX 32

/* Object geometry for planners (docs/shm.md "How each field is
 * computed"; src/mapper/objgeom.c). flags 0 = not computed: extent is then
 * the model's locality box and the spreads are the posterior's. */
#define SOOC_GEOM_TIGHT 0x1u      /* extent and centre: the tight box of the object's own density */
#define SOOC_GEOM_SYMMETRIC 0x2u  /* rotationally symmetric about its vertical axis: yaw undefined */
#define SOOC_GEOM_EMPTY 0x4u      /* no density at the surface level in its box (extent 0) */
#define SOOC_GEOM_CLIPPED 0x8u    /* the density reaches the locality box's side: extent cut there */
#define SOOC_GEOM_FAINT 0x10u     /* below the surface level everywhere: the box at half its peak density */
#define SOOC_GEOM_SURFACE 0x20u   /* with TIGHT: the tight box is the box of the observed surface it claims
                                     (geometric support on; docs/geometric.md "The entries' observed
                                     surfaces"), not of its density */
typedef struct sooc_map_geometry {
    uint32_t flags;            /* SOOC_GEOM_* */
    float centre[3];           /* tight box centre in the object frame (m); centre[1] = height above the floor */
    float sym_iou;             /* rotational self-overlap of the density (symmetric when >= SOOC_OBJGEOM_SYM_IOU) */
    double cov_xz[3];          /* position covariance xx xz zz (m^2, world), calibrated (mapper.h) */
    double var_yaw;            /* yaw variance (rad^2); NaN = undefined (SYMMETRIC) */
    uint32_t reg_n;            /* registrations in the spread statistics */
    double reg_mean[2];        /* their mean floor position (X, Z) */
    double reg_m2[3];          /* Welford sums of squares xx xz zz about it */
    double reg_cs[2];          /* sums of cos / sin of their yaw */
} sooc_map_geometry;

/* One cognitive-map entry in the world frame (+y up, floor y = 0). */
typedef struct sooc_map_entry {
    uint64_t id;               /* stable, never reused; starts at 1 */
    double x, z, yaw;          /* posterior mean of z^where in the world frame (m, m, rad) */
    double sigma_t, sigma_yaw; /* posterior std of position (shared by x and z) and yaw */
    float presence;            /* sigmoid of the presence logit */
    float presence_logit;
    int latent_dim;            /* <= SOOC_MAP_LATENT_MAX */
    float what_mu[SOOC_MAP_LATENT_MAX];
    float what_logvar[SOOC_MAP_LATENT_MAX];
    float extent[3];           /* box size (x, y, z) in m: the tight box (geom.flags TIGHT) or the model's locality box */
    int64_t first_seen_ns, last_seen_ns;
    uint32_t obs_count;
    sooc_map_geometry geom;    /* tight box, height, spreads (zero: not computed) */
} sooc_map_entry;

/* Conversions between a map entry and the cognitive map's entry (the rows of
 * the SQLite map store): the one definition the mapper, the node (also when
 * it links a fake mapper) and the CLI share; src/cogmap/map_entry.c.
 *
 * from_cogmap: sigma = exp(rho / 2), presence = sigmoid(logit), latent_dim
 *   clamped to [0, SOOC_MAP_LATENT_MAX]. The cogmap does not store the box
 *   extent: it is copied from `extent` (the model's box, or the one stored
 *   with a map; NULL = zeros).
 * to_cogmap: rho = 2 log(max(sigma, 1e-12)), latent_dim clamped to
 *   [0, SOOC_COGMAP_DIM_MAX], obs_count >= 1 (an entry in a map has been
 *   registered at least once: the cogmap invariant), last_view = -1 (a map
 *   entry does not carry it; -1 = not registered by a view of this session,
 *   where 0 would claim view 0). The extent is dropped. */
void sooc_map_entry_from_cogmap(const sooc_cogmap_entry *c, const float extent[3], sooc_map_entry *e);

/* The uncertainty a planner gets, the same in the shm table, `sooc3d map
 * list` and the CSV / JSON export (docs/shm.md "How each field is computed"):
 * the calibrated spreads of e->geom when computed (cov_xz, var_yaw; var_yaw
 * NaN for a symmetric shape), else the posterior's sigma_t^2 (x and z, no
 * correlation) and sigma_yaw^2. cov = {xx, xz, zz, yaw yaw}; returns 1 when
 * the calibrated spreads were used. */
int sooc_map_entry_planner_cov(const sooc_map_entry *e, double cov[4]);
/* The sigmas printed beside it (map list, exports, the live view, MCAP):
 * sigma_t = sqrt(cov xx) in metres (the table's sqrt(cov_xzyaw[0]); cov zz
 * and xz are in the covariance), sigma_yaw = sqrt(cov yaw yaw) (NaN:
 * symmetric). */
void sooc_map_entry_planner_sigmas(const sooc_map_entry *e, double *sigma_t, double *sigma_yaw);
/* The height of the entry's top above the floor (m), as `map list` and the
 * exports print it: twice the tight box's centre height, else the extent's y. */
double sooc_map_entry_height(const sooc_map_entry *e);
/* The largest yaw variance published: that of an angle uniform on the
 * circle, (2 pi)^2 / 12 = pi^2 / 3 rad^2 (a yaw known not at all). */
#define SOOC_MAP_YAW_VAR_MAX 3.289868133696453

/* The planner's box of an entry, as the shm table publishes it: centre
 * (x, y, z) in the world frame (y above the floor: the tight box's centre
 * height when computed, else half the extent), rotation yaw about +y, full
 * extent ext (m) along the box's own axes. */
void sooc_map_entry_box(const sooc_map_entry *e, double centre[3], double *yaw, float ext[3]);

/* The box-quality words of geom.flags for people and exports: "tight",
 * "tight,clipped", "empty", "faint", "not computed", ... (buf >= 48). */
const char *sooc_map_entry_box_quality(const sooc_map_geometry *g, char *buf, size_t cap);
void sooc_map_entry_to_cogmap(const sooc_map_entry *e, sooc_cogmap_entry *c);

/* ==== the map store (SQLite) (mapstore) ================================== */

/*
 * sooc3d persistent map: the cognitive map in an SQLite database
 * (docs/cogmap.md "Persistent store (SQLite)").
 *
 *  - WAL journal (readers never block the mapping thread), synchronous=NORMAL.
 *  - One transaction per keyframe: sooc_mapstore_commit_keyframe() writes the
 *    entries registered by the view, deletes the removed ones, stores the
 *    layout block, the id counter and a keyframe row, atomically. Lower-level
 *    begin/put/remove/commit calls exist for other uses.
 *  - An R*Tree virtual table `entries_rtree(id, min_x, max_x, min_z, max_z)`
 *    indexes the floor position; triggers on `entries` keep it in sync.
 *  - Restart: sooc_mapstore_load_map() puts every entry, layout block and the
 *    id counter back into a sooc_cogmap; new ids continue after the stored
 *    counter (ids of removed entries are never handed out again).
 *
 * Schema (version 1):
 *   meta(key TEXT PRIMARY KEY, value TEXT)  app='sooc3d-map', schema_version,
 *        model_id, dim, layout_dim, block_size, next_id
 *   entries(id INTEGER PRIMARY KEY, x, z, yaw, rho_t, rho_yaw, pres_logit REAL,
 *        dim, latent_version INTEGER, what_mu, what_logvar BLOB,
 *        first_seen_ns, last_seen_ns, obs_count, last_view INTEGER)
 *   entries_rtree  (R*Tree, see above)
 *   layout(bi, bj, dim, latent_version, mu BLOB, logvar BLOB, PRIMARY KEY(bi, bj))
 *   keyframes(seq INTEGER PRIMARY KEY, t_ns, view, tx, ty, tz, qx, qy, qz, qw,
 *        n_changed, n_removed, n_entries)
 * Latent blobs, latent_version 1: dim little-endian IEEE float32 values.
 *
 * Schema version 2 adds the finetuned decoders (train.h):
 *   ft_objects(id INTEGER PRIMARY KEY, version, n, crc, data BLOB, steps, loss)
 *   ft_layout(bi, bj, version, n, crc, data BLOB, steps, loss, PRIMARY KEY(bi, bj))
 *   trigger entries_ad_ft: deleting an entry deletes its decoder.
 * data: n little-endian float32 (a cogmap payload), crc = CRC-32 of its bytes,
 * version 1. A version-1 map is migrated on its first read-write open (one
 * transaction: the tables, then schema_version 2); opened read-only it reads
 * as a version-1 map, without finetuned decoders. load_map puts the stored decoders
 * into the map's payloads (cogmap.h); save_map stores the map's payloads.
 *
 * Schema version 3 adds the object geometry for planners
 * (include/sooc3d/mapper.h, docs/shm.md):
 *   entry_geometry(id INTEGER PRIMARY KEY, flags, ext_x, ext_y, ext_z,
 *        centre_x, centre_y, centre_z, sym_score, cov_xx, cov_xz, cov_zz,
 *        var_yaw (NULL = undefined), reg_n, reg_mean_x, reg_mean_z, reg_m2_xx,
 *        reg_m2_xz, reg_m2_zz, reg_cos, reg_sin)
 *   trigger entries_ad_geom: deleting an entry deletes its geometry.
 * Migrations apply in order on a read-write open, one transaction each
 * (1 -> 2, then 2 -> 3); a read-only open of an older map reads no geometry.
 *
 * Errors: every failure message starts with the database path; a file that is
 * not an SQLite database, not a sooc3d map, or corrupt gives SOOC_EFORMAT, a
 * schema/dimension/model mismatch SOOC_EVERSION, a missing file (create = 0)
 * SOOC_ENOTFOUND.
 *
 * Thread-safety: one sooc_mapstore per thread. Other processes may read the
 * same file concurrently (WAL).
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

#define SOOC_MAPSTORE_SCHEMA_VERSION 3
#define SOOC_MAPSTORE_LATENT_VERSION 1

typedef struct sooc_mapstore sooc_mapstore;

typedef struct sooc_mapstore_params {
    int create;            /* create the file if missing, and its folder          (1) */
    int readonly;          /* open read-only (the file must exist); needs only read
                              permission on the file: with no un-checkpointed -wal
                              left it opens immutable, so a folder the reader
                              cannot write is fine                              (0) */
    const char *model_id;  /* stored on creation; on open a non-empty stored id must
                              match (SOOC_EVERSION), an empty stored id is set to it
                              (read-write opens); NULL = no check              (NULL) */
    int dim, layout_dim;   /* 0 = take from the file; else stored / must match   (0) */
    double block_size;     /* layout block side stored on creation; 0 = not set  (0) */
} sooc_mapstore_params;

void sooc_mapstore_params_default(sooc_mapstore_params *p);

/* Open or create the database at `path`. On failure *out = NULL. */
sooc_status sooc_mapstore_open(sooc_mapstore **out, const char *path, const sooc_mapstore_params *p);
/* Close (rolls back an open transaction). NULL-safe. */
void sooc_mapstore_close(sooc_mapstore *s);
const char *sooc_mapstore_path(const sooc_mapstore *s);

typedef struct sooc_mapstore_info {
    int schema_version;
    char model_id[128];
    int dim, layout_dim;
    double block_size;
    uint64_t next_id;
    uint64_t n_entries, n_layout, n_keyframes;
    char journal_mode[16];  /* "wal" */
} sooc_mapstore_info;
sooc_status sooc_mapstore_info_get(sooc_mapstore *s, sooc_mapstore_info *out);

/* ---------------------------------------------------- keyframe commit */

typedef struct sooc_mapstore_keyframe {
    int64_t t_ns;
    int32_t view;
    double T_wc[16];
    const uint64_t *changed;   /* ids written by this view (0s are skipped), read from the map */
    size_t n_changed;
    const uint64_t *removed;   /* ids removed by this view */
    size_t n_removed;
    int has_block;             /* 1: also store layout block (bi, bj) from the map */
    int32_t bi, bj;
} sooc_mapstore_keyframe;

/* One transaction: upsert the changed entries (taken from `map`), delete the
 * removed ids, store the layout block and map->next_id, append a keyframe
 * row. On failure the database is unchanged. The dims of `map` must match. */
sooc_status sooc_mapstore_commit_keyframe(sooc_mapstore *s, const sooc_cogmap *map,
                                          const sooc_mapstore_keyframe *kf);

/* Replace the stored map by a full snapshot of `map` (one transaction). */
sooc_status sooc_mapstore_save_map(sooc_mapstore *s, const sooc_cogmap *map);
/* Load every entry, layout block and the id counter into `map` (its entries
 * are replaced; dims must match). */
sooc_status sooc_mapstore_load_map(sooc_mapstore *s, sooc_cogmap *map);

/* ----------------------------------------------------- low-level API */

sooc_status sooc_mapstore_begin(sooc_mapstore *s);
sooc_status sooc_mapstore_commit(sooc_mapstore *s);
void sooc_mapstore_rollback(sooc_mapstore *s);
/* Upsert entries (e[i].dim must equal the store's dim). */
sooc_status sooc_mapstore_put_entries(sooc_mapstore *s, const sooc_cogmap_entry *e, size_t n);
/* Delete ids (absent ids are ignored). */
sooc_status sooc_mapstore_remove_entries(sooc_mapstore *s, const uint64_t *ids, size_t n);
sooc_status sooc_mapstore_put_layout(sooc_mapstore *s, int32_t bi, int32_t bj, const float *mu,
                                     const float *logvar);
/* Append a keyframe row (t_ns, view, pose, counts from kf; changed ids are
 * only counted, not written). n_entries: map size after the keyframe, or -1
 * if unknown. Use inside begin/commit to keep one transaction per keyframe. */
sooc_status sooc_mapstore_add_keyframe(sooc_mapstore *s, const sooc_mapstore_keyframe *kf, int64_t n_entries);
/* Raise the stored id counter to at least `next_id`. */
sooc_status sooc_mapstore_set_next_id(sooc_mapstore *s, uint64_t next_id);

/* ---------------------------------------------------------- reading */

/* Visit entries in id order: all of them, or those whose (x, z) lies in the
 * closed box [x0, x1] x [z0, z1] (R*Tree lookup, exact filter). A non-zero
 * return from fn stops the walk (the function then returns SOOC_OK).
 * fn must not use the store. */
sooc_status sooc_mapstore_foreach(sooc_mapstore *s, sooc_cogmap_visit_fn fn, void *user);
sooc_status sooc_mapstore_query_box(sooc_mapstore *s, double x0, double z0, double x1, double z1,
                                    sooc_cogmap_visit_fn fn, void *user);
/* Visit every stored layout block, ordered by (bi, bj) (nothing if the map
 * has no layout latents). A non-zero return from fn stops the walk. */
sooc_status sooc_mapstore_foreach_layout(sooc_mapstore *s, sooc_cogmap_block_fn fn, void *user);

/* Application meta values (e.g. the node's box extent "0.6 1.2 0.6"). The
 * schema's own keys (app, schema_version, model_id, dim, layout_dim,
 * block_size, next_id) are refused. get: SOOC_ENOTFOUND if absent. */
sooc_status sooc_mapstore_meta_set(sooc_mapstore *s, const char *key, const char *value);
sooc_status sooc_mapstore_meta_get(sooc_mapstore *s, const char *key, char *buf, size_t cap);

/* ------------------------------------------- finetuned decoders (schema 2) */

/* Store (replace) the finetuned decoder of entry `id` (is_block 0; the entry
 * must be stored: SOOC_ENOTFOUND) or of layout block (bi, bj) (is_block 1):
 * v[0..n) as sooc_finetune_unit_payload gives it, the Adam steps it took and
 * its last loss (NAN: none). Its own transaction unless one is open, so a
 * finetuning run commits object by object. Non-finite values: SOOC_ENUMERIC.
 * A version-1 map opened read-only: SOOC_EUNSUPPORTED. */
sooc_status sooc_mapstore_ft_put(sooc_mapstore *s, int is_block, uint64_t id, int32_t bi, int32_t bj, const float *v,
                                 size_t n, int steps, double loss);
/* Is a decoder stored for this entry / block? *found = 0 or 1 (steps, loss
 * may be NULL). */
sooc_status sooc_mapstore_ft_get(sooc_mapstore *s, int is_block, uint64_t id, int32_t bi, int32_t bj, int *found,
                                 int *steps, double *loss);
sooc_status sooc_mapstore_ft_count(sooc_mapstore *s, uint64_t *n_objects, uint64_t *n_blocks);
/* Delete every stored decoder (sooc3d finetune --restart). */
sooc_status sooc_mapstore_ft_clear(sooc_mapstore *s);

/* The distinct view indices of the stored keyframes, ascending: *n = their
 * number; the first min(n, cap) go to views (may be NULL). */
sooc_status sooc_mapstore_keyframe_views(sooc_mapstore *s, int64_t *views, size_t cap, size_t *n);

/* ------------------------------------------- object geometry (schema 3) */

/* Store (replace) entry id's geometry: its extent (tight box, or the
 * locality box when g->flags has no SOOC_GEOM_TIGHT) and g (mapper.h).
 * Use inside the keyframe's transaction. Non-finite values other than an
 * undefined (NaN) yaw variance: SOOC_ENUMERIC. */
sooc_status sooc_mapstore_geom_put(sooc_mapstore *s, uint64_t id, const float extent[3], const sooc_map_geometry *g);
/* Read it back: *found = 0 (extent, g untouched) when none is stored or the
 * map predates schema 3. */
sooc_status sooc_mapstore_geom_get(sooc_mapstore *s, uint64_t id, float extent[3], sooc_map_geometry *g, int *found);

/* Planner entries: every entry of the map as a planner receives it (the
 * shm table, `sooc3d map list`, `map at`): sooc_map_entry_from_cogmap plus
 * its stored box and spreads where the map has them. *out (sooc_free) gets
 * *n entries in id order; on failure *out = NULL, *n = 0. */
sooc_status sooc_mapstore_planner_entries(sooc_mapstore *s, sooc_map_entry **out, size_t *n);

/* Fetch one entry by id (SOOC_ENOTFOUND if absent). */
sooc_status sooc_mapstore_get(sooc_mapstore *s, uint64_t id, sooc_cogmap_entry *out);

/* ------------------------------------------------------- world frame */

/* The map's world frame (support plane, include/sooc3d/frame.h): how the
 * pose source's frame maps into the gravity-aligned world the map lives in.
 * Stored as meta key "world_frame" (text: "v1" then the values with %.17g,
 * so a round trip is exact). The node writes it when it first estimates (or
 * is given) the frame; resume, render, eval and map export read it back. */
typedef struct sooc_map_frame {
    double T_world_src[16];  /* p_world = T_world_src * p_src, row-major, rigid      */
    double up_src[3];        /* unit up direction in the source frame                */
    double plane_src[4];     /* support plane n . p + d = 0 in the source frame      */
    double cam_height_m;     /* mean camera height over the plane when estimated     */
    int up_source;           /* sooc_up_source (frame.h): 0 given, 1 gravity file,
                                2 camera mean; -1 = world.floor: given (no estimate) */
} sooc_map_frame;

/* Store (replace) the world frame. Fails on a non-finite value or a
 * T_world_src that is not rigid (rotation part off orthonormal by > 1e-6). */
sooc_status sooc_mapstore_frame_put(sooc_mapstore *s, const sooc_map_frame *f);
/* Read the world frame: *found = 1 and *f filled, or *found = 0 (f untouched)
 * when the map has none. A malformed stored value is SOOC_EFORMAT naming the
 * database. */
sooc_status sooc_mapstore_frame_get(sooc_mapstore *s, sooc_map_frame *f, int *found);

/* ---------------------------------------------------- storage faults */

/* What a failed call met in SQLite, for callers that go on when the storage
 * fails (the node: docs/node.md "Faults"). */
typedef enum sooc_mapstore_fault {
    SOOC_MAPSTORE_FAULT_NONE = 0,   /* no SQLite failure since the last begin           */
    SOOC_MAPSTORE_FAULT_FULL,       /* SQLITE_FULL: the disk or file system is full     */
    SOOC_MAPSTORE_FAULT_IO,         /* SQLITE_IOERR, CANTOPEN, READONLY, PROTOCOL       */
    SOOC_MAPSTORE_FAULT_BUSY,       /* SQLITE_BUSY / LOCKED: another connection holds
                                       the lock longer than the busy timeout            */
    SOOC_MAPSTORE_FAULT_CORRUPT,    /* SQLITE_CORRUPT / NOTADB                          */
    SOOC_MAPSTORE_FAULT_NOMEM,      /* SQLITE_NOMEM                                     */
    SOOC_MAPSTORE_FAULT_OTHER
} sooc_mapstore_fault;

/* The fault of the last SQLite call that failed since the last
 * sooc_mapstore_begin (NONE if none did: a failure then came from the data,
 * e.g. a dimension mismatch or a non-finite value). */
sooc_mapstore_fault sooc_mapstore_last_fault(const sooc_mapstore *s);
/* The fault of this thread's last sooc_mapstore_open that failed in SQLite
 * (NONE when it failed for another reason: not a map, a version, a model). */
sooc_mapstore_fault sooc_mapstore_open_fault(void);
/* "disk full", "I/O error", "locked by another connection", ... */
const char *sooc_mapstore_fault_name(sooc_mapstore_fault f);
/* *empty = 1 when `path` is an SQLite file without any table (what a
 * creation that failed, e.g. on a full disk, leaves behind). */
sooc_status sooc_mapstore_file_empty(const char *path, int *empty);
/* How long a write waits for a lock another connection holds before it fails
 * with SOOC_EBUSY (opened with 5000 ms). */
sooc_status sooc_mapstore_set_busy_timeout(sooc_mapstore *s, int ms);
/* Copy the WAL into the database file (truncate = 1: and cut the WAL file to
 * zero bytes, which frees its space on a full disk). Not inside a transaction. */
sooc_status sooc_mapstore_checkpoint(sooc_mapstore *s, int truncate);

/* ==== the map store's SLAM records (mapstore_slam) ======================= */

/*
 * The tracking keyframes of a camera without a pose source in the map
 * database (src/cogmap/mapstore_slam.c, docs/slam.md). Two tables, made on
 * the first write (a map without them reads as having no keyframes):
 *
 *   slam_keyframes(id INTEGER PRIMARY KEY, run INTEGER, frame INTEGER,
 *        t_ns INTEGER, pose BLOB, feat BLOB, depth BLOB)
 *   slam_edges(a INTEGER, b INTEGER, kind INTEGER, rel BLOB, w_t REAL,
 *        w_r REAL, PRIMARY KEY(a, b, kind))
 *
 * pose and rel: 16 little-endian float64 (row-major 4x4; pose camera-to-
 * world, rel = T_a^-1 T_b). feat and depth are the SLAM module's own
 * records (magic, version, CRC-32; include/sooc3d/slam.h); the store keeps
 * them as given. Writes go into the caller's transaction when one is open
 * (sooc_mapstore_begin), else into their own.
 */

typedef struct sooc_slamdb_kf {
    int64_t id;               /* unique in the map                    */
    int32_t run;              /* the tracking run that made it        */
    int64_t frame, t_ns;      /* its frame in that run                */
    double T_wc[16];          /* camera-to-world (after optimisation) */
    const void *feat;         /* blobs: valid during a visit only      */
    size_t feat_bytes;
    const void *depth;
    size_t depth_bytes;
} sooc_slamdb_kf;

typedef struct sooc_slamdb_edge {
    int64_t a, b;
    int32_t kind;             /* 0 odometry, 1 loop closure, 2 relocalisation, 3 re-anchor
                                 (weak), 4 local (recent keyframes)             */
    double T_ab[16];          /* T_a^-1 T_b as measured                        */
    double w_t, w_r;          /* 1 / sigma: metres, radians                    */
} sooc_slamdb_edge;

/* Insert or replace a keyframe / an edge. Non-finite poses: SOOC_ENUMERIC. */
sooc_status sooc_mapstore_slam_put_keyframe(sooc_mapstore *s, const sooc_slamdb_kf *kf);
sooc_status sooc_mapstore_slam_put_edge(sooc_mapstore *s, const sooc_slamdb_edge *e);
/* Set the poses of n stored keyframes (one transaction unless one is open). */
sooc_status sooc_mapstore_slam_set_poses(sooc_mapstore *s, const int64_t *ids, const double *T_wc, size_t n);
/* Visit the keyframes in id order / the edges; a non-zero return stops. */
typedef int (*sooc_slamdb_kf_fn)(const sooc_slamdb_kf *kf, void *user);
typedef int (*sooc_slamdb_edge_fn)(const sooc_slamdb_edge *e, void *user);
sooc_status sooc_mapstore_slam_foreach_keyframe(sooc_mapstore *s, sooc_slamdb_kf_fn fn, void *user);
sooc_status sooc_mapstore_slam_foreach_edge(sooc_mapstore *s, sooc_slamdb_edge_fn fn, void *user);
/* Counts, and the largest run number stored (-1 when none). */
sooc_status sooc_mapstore_slam_count(sooc_mapstore *s, int64_t *n_keyframes, int64_t *n_edges, int32_t *max_run);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_COGMAP_H */
