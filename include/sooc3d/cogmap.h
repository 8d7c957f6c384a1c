/*
 * sooc3d cognitive map (docs/cogmap.md; the SOOC3D paper): the posterior λ of every
 * registered object in the WORLD frame, a spatial hash grid on the floor plane,
 * the per-view query (in-view test, top-K by presence, world -> G_t) and the
 * registration after a view (G_t -> world, overwrite by id / append / remove).
 * Layout latents live per floor block (side B_s).
 *
 * Frames (geom.h): world +y up, floor y = 0. A λ handed to / returned by the
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
#ifndef SOOC3D_COGMAP_H
#define SOOC3D_COGMAP_H

#include "sooc3d/core.h"
#include "sooc3d/geom.h"

#ifdef __cplusplus
extern "C" {
#endif

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
 * decoder of the object / block (include/sooc3d/finetune.h; the model's field
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
#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_COGMAP_H */
