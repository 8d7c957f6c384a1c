/*
 * sooc3d rendering: the rasteriser, meshes (marching cubes, PLY), and the
 * node's live view in a browser.
 *
 * Sections: the rasteriser (render); meshes (mesh); the live view in a
 * browser (view).
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
#ifndef SOOC3D_RENDER_H
#define SOOC3D_RENDER_H

#include <stddef.h>
#include <stdint.h>

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/gen.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== the rasteriser (render) ============================================ */

/*
 * sooc3d dense volume renderer (docs/metrics.md "Rendering"; the composition of the SOOC3D paper).
 *
 * The renderer knows nothing about the model. It sees a "field": N
 * components (0 = layout/background, 1..K = objects), each answering batched
 * point queries with a raw density times presence sigma_hat in [0, 1] and a
 * colour in [0, 1]^3, plus an optional box per component outside of which the
 * component is known to be zero (the model's locality box).
 *
 * Composition at a point x (eps = 1e-8):
 *   S = sum_k sigma_hat_k + eps,   sbar_k = sigma_hat_k^2 / S,   Sbar = sum_k sbar_k
 *   sigma = sigma_max * Sbar,      c = sum_k (sigma_hat_k / S) * rgb_k
 *
 * Rays and depth. A pixel (u, v) casts the ray x(z) = o + z * r with r the
 * camera-frame direction through the pixel centre scaled so that r_z = 1:
 * the ray parameter z IS the planar depth (the same convention as
 * sooc_frame.depth). Samples lie on [t_near, d_clip] in planar depth; the
 * step used in alpha = 1 - exp(-sigma * delta) is the Euclidean length
 * delta = dz * |r|. Outputs (expected depth, d_clip fallback) are planar.
 *
 * Sampling: n_coarse stratified samples (midpoints of n_coarse equal bins, or
 * jittered within each bin when opts.jitter = 1), then, if n_fine > 0, an
 * importance pass: the coarse weights define a piecewise-constant pdf over the
 * gaps between coarse samples (and t_near, d_clip); each weight w_i goes 75 %
 * to the gap preceding sample i and 25 % to the gap following it (ObSuRF's
 * allocation: a surface first seen at z_i lies before z_i); n_fine samples are drawn by inverse CDF at stratified
 * quantiles (midpoints, or jittered) and merged with the coarse ones. The
 * field is evaluated at all n_coarse + n_fine samples and the final image is
 * composited from the merged, sorted set.
 *
 * Volume rendering on the merged samples z_1 < ... < z_N:
 *   delta_i = (z_{i+1} - z_i) |r|, delta_N = (d_clip - z_N) |r|
 *   alpha_i = 1 - exp(-sigma_i delta_i), T_i = prod_{j<i} (1 - alpha_j), w_i = T_i alpha_i
 *   A = sum w_i, RGB = sum w_i c_i + (1 - A) bg, D = sum w_i z_i + (1 - A) d_clip
 *   seg_k = sum_i w_i sbar_k(x_i) / Sbar(x_i);  label = argmax_k seg_k, or -1 if A < 0.5
 * Per-component image k: the same samples rendered with sigma_max * sbar_k and
 * rgb_k alone (premultiplied colour + opacity, no background).
 *
 * Culling: component k is evaluated only at samples inside its box (ray-box
 * slab test, padded by 1e-5 m so borderline samples are evaluated); elsewhere
 * sigma_hat_k = 0. Sample positions do not depend on culling, so when the
 * field is zero outside its boxes, culled and unculled images are identical.
 *
 * Threads and determinism: rays are processed in fixed chunks of
 * opts.chunk_rays consecutive pixels (row-major), so every eval batch holds
 * the same points whatever the thread count; jitter uses one RNG stream per
 * pixel (seed, pixel index). Results are bit-identical with OpenMP on or off
 * and for any thread count, provided the field's eval is deterministic per
 * batch. Scratch memory is allocated once per render call (per worker); there
 * is no allocation per ray.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

#define SOOC_RENDER_MAX_COMP 64   /* 1 layout + up to 63 objects per view */
#define SOOC_RENDER_LABEL_NONE (-1)

/* A box in the field's frame: points p (field frame) with
 * lo <= T_bf * p <= hi component-wise, where T_bf = inverse(T_fb). */
typedef struct sooc_render_box {
    int enabled;           /* 0: component is evaluated everywhere (no culling) */
    double T_fb[16];       /* box-local -> field frame, rigid, row-major        */
    double lo[3], hi[3];   /* extents in box-local coordinates                  */
} sooc_render_box;

/* The object locality box for a floor pose (p_x, p_z, yaw)
 * in a gravity-aligned frame G (y up, floor at y = -h):
 *   local origin b = (p_x, -h, p_z), rotation R_y(yaw),
 *   lo = (-R_h, 0, -R_h), hi = (R_h, H_b, R_h).
 * The box is in G, so the field's frame must be G (T_fc = T_gc). */
void sooc_render_box_object(sooc_render_box *b, double px, double pz, double yaw, double h,
                            double R_h, double H_b);
/* Axis-aligned box [lo, hi] in the field frame. */
void sooc_render_box_aabb(sooc_render_box *b, const double lo[3], const double hi[3]);

/* Batched evaluation of component `comp` at n points (n x 3 floats in the
 * field's frame, n <= the max_batch given to prepare). Writes sigma_hat[n]
 * (raw density times presence, in [0, 1]) and rgb[n x 3] (in [0, 1]).
 * Called concurrently from several workers; `worker` in [0, n_workers) is
 * stable within one render call, so per-worker scratch can be indexed by it.
 * Must not allocate per call if it wants to be fast; must be deterministic. */
typedef void (*sooc_field_eval_fn)(void *user, int worker, int comp, const float *pts, int n,
                                   float *sigma_hat, float *rgb);
/* Optional: called once per render call before any eval, on the calling
 * thread, so the field can size per-worker scratch. */
typedef sooc_status (*sooc_field_prepare_fn)(void *user, int n_workers, int max_batch);

typedef struct sooc_field {
    int n_comp;                       /* 1 + K, <= SOOC_RENDER_MAX_COMP        */
    const sooc_render_box *boxes;     /* n_comp boxes, or NULL = no culling     */
    float sigma_max;                  /* density scale (30 /m)                    */
    sooc_field_eval_fn eval;
    sooc_field_prepare_fn prepare;    /* may be NULL                           */
    void *user;
} sooc_field;

typedef struct sooc_render_opts {
    int n_coarse;          /* stratified samples per ray (default 96)             */
    int n_fine;            /* importance samples per ray (default 32; 0 = none)   */
    double t_near, d_clip; /* planar depth range in metres (default 0.1, 8)       */
    float bg_rgb[3];       /* colour behind the last sample (default 0, 0, 0)     */
    int jitter;            /* 0 = deterministic midpoints (default), 1 = jittered */
    uint64_t seed;         /* jitter seed                                         */
    int threads;           /* 0 = OpenMP default; 1 = serial                      */
    int cull;              /* 1 = ray-box culling (default), 0 = evaluate all     */
    int chunk_rays;        /* rays per work item / eval batch (default 16)        */
    int components;        /* 1 = also render per-component images (default 0)   */
    int soft_seg;          /* 1 = also keep seg_k per pixel (default 0)           */
} sooc_render_opts;

void sooc_render_opts_default(sooc_render_opts *o);

/* Render outputs, H x W row-major. Optional buffers are NULL when not asked. */
typedef struct sooc_render_out {
    int width, height, n_comp;
    float *rgb;            /* H*W*3                                                */
    float *depth;          /* H*W planar metres (expected depth, d_clip fallback)  */
    float *alpha;          /* H*W accumulated opacity A                            */
    int16_t *label;        /* H*W argmax component, SOOC_RENDER_LABEL_NONE if A<0.5 */
    float *seg;            /* optional H*W*n_comp seg_k (soft_seg)                 */
    float *comp_rgb;       /* optional n_comp*H*W*3 premultiplied (components)     */
    float *comp_alpha;     /* optional n_comp*H*W (components)                     */
    float *uncert;         /* optional H*W: sum over channels of RGB variance      */
    float *rgb_mean;       /* optional H*W*3: mean RGB over the posterior samples  */
} sooc_render_out;

void sooc_render_out_free(sooc_render_out *o);   /* NULL-safe, leaves *o zeroed */

/* Render one view. K gives the image size; T_fc maps camera (OpenCV optical)
 * coordinates to the field's frame (e.g. T_gc = inverse(T_wg) * T_wc for a
 * field in G_t). `out` is (re)allocated to K->width x K->height as needed.
 * Fails with SOOC_EINVAL on bad options, SOOC_ENOMEM, or the prepare status. */
sooc_status sooc_render_view(const sooc_field *f, const sooc_intrinsics *K, const double T_fc[16],
                             const sooc_render_opts *o, sooc_render_out *out);

/* Posterior sampling hook for the uncertainty map: fill *f with the field of
 * posterior sample m (0 <= m < M); `release` (may be NULL) is called after
 * sample m was rendered. */
typedef struct sooc_field_sampler {
    sooc_status (*get)(void *user, int m, sooc_field *f);
    void (*release)(void *user, int m, sooc_field *f);
    void *user;
} sooc_field_sampler;

/* Render M posterior samples and fill out->uncert (per-pixel variance of RGB,
 * population variance over the M samples, summed over channels; MulMON) and
 * out->rgb_mean. Other buffers of `out` are left as they are. Each sample uses
 * the same opts (jitter seeds are offset by m). M >= 2. */
sooc_status sooc_render_uncertainty(const sooc_field_sampler *s, int M, const sooc_intrinsics *K,
                                    const double T_fc[16], const sooc_render_opts *o,
                                    sooc_render_out *out);
/* Convenience: the same with M explicit fields. */
sooc_status sooc_render_uncertainty_fields(const sooc_field *fields, int M, const sooc_intrinsics *K,
                                           const double T_fc[16], const sooc_render_opts *o,
                                           sooc_render_out *out);

/* Ray-box slab test in planar-depth parameter: for the ray x(z) = o + z r,
 * returns 1 and [*z0, *z1] (clipped to [zmin, zmax]) if it meets the box. */
int sooc_render_ray_box(const sooc_render_box *b, const double o[3], const double r[3],
                        double zmin, double zmax, double *z0, double *z1);

/* ==== meshes (mesh) ====================================================== */

/*
 * sooc3d meshes (docs/mesh.md): marching cubes on the density of a
 * map's objects and layout, binary PLY, and the Atlas mesh metric
 * (docs/mesh.md).
 *
 * THE SURFACE LEVEL (one definition for the whole project; the object extents
 * of the shared-memory table use the same level):
 *
 *   a point x is inside component k  <=>  sigma_hat_k(x) >= SOOC_MESH_LEVEL
 *
 * where sigma_hat_k in [0, 1] is what render.h's field returns for component
 * k: the decoder's raw density times presence (z^pres = 1 for registered map
 * entries). In density units this is sigma = SOOC_MESH_LEVEL * sigma_max
 * (sooc_mesh_level_sigma): with the shipped models' sigma_max = 30 / m,
 * 15 / m, i.e. a slab of ln 2 / 15 = 4.6 cm has opacity 0.5. Why not
 * a level of "sigma_iso = ln 2 / voxel": that depends on the grid, and
 * with sigma_max = 30 / m no voxel finer than 2.3 cm could ever reach it;
 * 0.5 on the sigmoid output is the decoder's own midpoint, independent of
 * grid resolution and of unit_m. Callers may pass another level.
 *
 * Frames: a grid is laid out in its own frame ("grid-local": an object's box
 * frame, origin on the floor under the object, y up, rotated by its yaw);
 * the field is evaluated at T_eg * p and vertices are written at T_og * p
 * (both rigid). Map meshes are in the WORLD frame (metres, +y up, floor
 * y = 0).
 *
 * Marching cubes: cells of a regular grid of res[0] x res[1] x res[2]
 * samples; one vertex per grid edge crossing the level (shared by every
 * triangle using that edge); values outside the grid count as below the
 * level, so the surface of a density that is inside at the grid's border is
 * closed there (capped). The cube table is generated from one rule per cube
 * face (each maximal run of inside corners around a face gets one segment:
 * diagonal inside corners are kept apart), so two cells sharing a face cut it
 * identically: the mesh is watertight (every edge in exactly two triangles,
 * once in each direction) and wound counter-clockwise seen from outside
 * (normals point from high density to low).
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

/* The surface level on sigma_hat (see above). */
#define SOOC_MESH_LEVEL 0.5f
/* The same level as a density per metre for a field with this sigma_max. */
static inline float sooc_mesh_level_sigma(float sigma_max) { return SOOC_MESH_LEVEL * sigma_max; }

#define SOOC_MESH_RES_DEFAULT 64   /* samples per axis over an object's box (docs/mesh.md) */

/* A triangle mesh: vertices xyz (n_vert x 3), colours rgb (n_vert x 3, 0-255),
 * triangles tri (n_tri x 3 vertex indices, counter-clockwise from outside). */
typedef struct sooc_mesh {
    float *xyz;
    uint8_t *rgb;
    uint32_t *tri;
    size_t n_vert, n_tri;
    size_t cap_vert, cap_tri;
} sooc_mesh;

void sooc_mesh_free(sooc_mesh *m);   /* NULL-safe; leaves *m zeroed */
/* Append src's vertices and triangles to dst (indices offset). */
sooc_status sooc_mesh_append(sooc_mesh *dst, const sooc_mesh *src);
/* Signed enclosed volume (divergence theorem; positive for outward winding)
 * and total area. */
double sooc_mesh_volume(const sooc_mesh *m);
double sooc_mesh_area(const sooc_mesh *m);
/* Watertight and consistently wound: every undirected edge is used by exactly
 * two triangles, once in each direction, and no triangle is degenerate in
 * its indices. Returns 1 if so; *n_bad (may be NULL) = offending edges. */
int sooc_mesh_is_closed(const sooc_mesh *m, size_t *n_bad);

/* A sampling grid: res[i] >= 2 samples from lo[i] to hi[i] (grid-local). */
typedef struct sooc_mesh_grid {
    double T_eg[16];      /* grid-local -> the frame the field is evaluated in */
    double T_og[16];      /* grid-local -> the frame the vertices are written in */
    double lo[3], hi[3];
    int res[3];
} sooc_mesh_grid;

/* Marching cubes on component `comp` of a render.h field: sigma_hat is
 * evaluated on the grid in batches (f->prepare is called first; OpenMP over
 * batches, `threads` 0 = default, 1 = serial), the level set
 * sigma_hat = level is extracted, and every vertex gets the field's colour
 * there. Replaces *out's contents (its buffers are reused). The result does
 * not depend on the thread count. */
sooc_status sooc_mesh_extract(const sooc_field *f, int comp, const sooc_mesh_grid *g, float level, int threads,
                              sooc_mesh *out);

/* ---- PLY (binary little-endian: float x y z, uchar red green blue; faces
 * as "list uchar int vertex_indices"), written atomically. ---- */
sooc_status sooc_mesh_write_ply(const sooc_mesh *m, const char *path, const char *comment);
/* Reads what sooc_mesh_write_ply writes (and other binary little-endian
 * triangle PLYs with float xyz and optional uchar rgb). Errors name the file. */
sooc_status sooc_mesh_read_ply(const char *path, sooc_mesh *out);

/* ---- meshes of a map (model.h's sooc_model_field_*: an entry's own
 * decoder once finetuned) ---- */
struct sooc_model;
typedef struct sooc_mesh_opts {
    int res;              /* samples per axis over an object's box     (64) */
    float level;          /* on sigma_hat                    (SOOC_MESH_LEVEL) */
    int threads;          /* 0 = OpenMP default                          (0) */
    double layout_cell;   /* layout grid spacing                      (0.05) */
    double layout_y[2];   /* layout grid height range           (-0.25, 3.0)
                             (layout lengths in metres for a model with
                             unit_m 1; they are multiplied by unit_m)        */
} sooc_mesh_opts;
void sooc_mesh_opts_default(sooc_mesh_opts *o);

/* The mesh of map entry `id`: its component alone, sampled over its
 * locality box in its own frame, in the WORLD frame. SOOC_ENOTFOUND if the
 * map has no such entry. */
sooc_status sooc_mesh_object(struct sooc_model *m, const sooc_cogmap *map, uint64_t id, const sooc_mesh_opts *o,
                             sooc_mesh *out);
/* The layout (floor / walls) of every layout block the map holds, each over
 * its block's square and layout_y, in the WORLD frame; a map without layout
 * blocks gives the layout prior's mesh over the block at the origin. */
sooc_status sooc_mesh_layout(struct sooc_model *m, const sooc_cogmap *map, const sooc_mesh_opts *o,
                             sooc_mesh *out);

/* Write <dir>/object_<id>.ply for map entries ids[0..n_ids) (ids NULL: every
 * entry) and <dir>/scene.ply (those objects plus the layout), creating dir;
 * each file is written atomically. An entry with nothing above the level
 * gets a PLY without vertices. */
typedef struct sooc_mesh_write_stats {
    int n_objects, n_empty;     /* object files written, of which empty        */
    size_t n_vert, n_tri;       /* of scene.ply                                */
    size_t n_layout_tri;        /* layout triangles in scene.ply               */
} sooc_mesh_write_stats;
sooc_status sooc_mesh_write_map(struct sooc_model *m, const sooc_cogmap *map, const char *dir, const sooc_mesh_opts *o,
                                const uint64_t *ids, size_t n_ids, sooc_mesh_write_stats *stats);

/* ---- the Atlas mesh metric (docs/mesh.md) ---- */
typedef struct sooc_mesh_metric {
    double acc_cm;        /* mean over predicted points of the distance to GT, cm */
    double comp_cm;       /* mean over GT points of the distance to prediction, cm */
    double precision, recall, fscore;   /* at 5 cm                          */
    int n_objects;        /* objects averaged over (matched GT objects whose
                             map entry has a non-empty mesh)                 */
    int n_empty;          /* matched objects whose mesh is empty (nothing above
                             the level): not averaged, counted here          */
    int n_gt;             /* GT objects in the scene                         */
} sooc_mesh_metric;

/* Points sampled uniformly (by area) on a mesh: n points into pts (n x 3),
 * deterministic for seed. SOOC_EINVAL for a mesh without area. */
sooc_status sooc_mesh_sample(const sooc_mesh *m, size_t n, uint64_t seed, float *pts);
/* Points on a generator object's true surface (world frame), voxel-
 * downsampled at `voxel` m; *pts is sooc_malloc'd (n_out x 3). */
sooc_status sooc_mesh_gt_points(const sooc_scene_object *o, double voxel, uint64_t seed, float **pts, size_t *n_out);
/* Accuracy / completeness between two point sets (both voxel-downsampled
 * by the caller), nearest neighbours through a uniform grid. */
sooc_status sooc_mesh_acc_comp(const float *pred, size_t n_pred, const float *gt, size_t n_gt, sooc_mesh_metric *out);
/* The scene's metric: every GT object is matched to the nearest map entry
 * on the floor (one-to-one, greedy by distance, within 0.5 m); each matched
 * pair's object mesh is sampled (50k points, 2 cm voxels) and compared with
 * the object's true surface; acc/comp/precision/recall are means over
 * matched objects (n_objects = 0 and NaN figures when none matched). */
sooc_status sooc_mesh_eval_scene(struct sooc_model *m, const sooc_cogmap *map, const sooc_scene *sc,
                                 const sooc_mesh_opts *o, sooc_mesh_metric *out);

/* ==== the live view in a browser (view) ================================== */

/*
 * sooc3d live view: a small web server (Debian's libwebsockets) that shows a
 * running node in a browser: the latest colour frame, the map from above with
 * each object's box and id, the object list with presence and sigma, and the
 * node's stats, pushed over a WebSocket at the keyframe rate (docs/logs.md
 * "Live view").
 *
 *   GET /              the page (no external resources)
 *   GET /api/objects   {"epoch": N, "objects": [...]} (the last published table)
 *   GET /api/stats     the last published stats object
 *   GET /frame.jpg     the last published colour frame (JPEG)
 *   WS  /ws            protocol "sooc3d": one text message per publication:
 *                      {"epoch": N, "frame": F, "objects": [...], "stats": {...}}
 *
 * Ownership: sooc_view_start returns a server the caller stops with
 * sooc_view_stop. The publish calls copy what they are given.
 *
 * Threading: the server runs its own thread. sooc_view_publish may be called
 * from any one thread (the node's mapping thread); start and stop from the
 * thread that owns the view.
 *
 * Errors: a port outside 1..65535, a bind address that is not an IPv4
 * address, or a port another program holds is a clear error naming it
 * (SOOC_EINVAL, SOOC_EBUSY); without libwebsockets at build time,
 * SOOC_EUNSUPPORTED. Nothing is printed: libwebsockets' own log goes to the
 * sooc_log callback at debug level.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

typedef struct sooc_view sooc_view;

typedef struct sooc_view_params {
    int port;                  /* 1..65535; 0 = any free port (tests; sooc_view_port tells which) */
    const char *bind;          /* IPv4 address to listen on (default "127.0.0.1")               */
} sooc_view_params;

/* One object of the table as the page shows it. */
typedef struct sooc_view_object {
    uint64_t id;
    double x, z, yaw;          /* map frame: floor position (m), yaw about +y (rad)             */
    double size[3];            /* box: x, height, z (m)                                         */
    double presence, sigma_t, sigma_yaw;
    uint32_t obs_count;
} sooc_view_object;

sooc_status sooc_view_start(sooc_view **out, const sooc_view_params *p);
void sooc_view_stop(sooc_view *v);     /* NULL-safe: closes every connection and joins the thread */
int sooc_view_port(const sooc_view *v);
/* 1 when the server was built in (libwebsockets found at build time). */
int sooc_view_available(void);

/* Publish one keyframe's state: the objects (n), the colour frame (RGB8,
 * w x h; NULL keeps the previous one) and a stats JSON object (NULL keeps
 * the previous one). Every WebSocket client gets one message. */
sooc_status sooc_view_publish(sooc_view *v, const sooc_view_object *obj, size_t n, const uint8_t *rgb, int w, int h,
                              const char *stats_json);
/* Publications so far, and WebSocket messages sent (for tests and stats). */
void sooc_view_counts(const sooc_view *v, uint64_t *epoch, uint64_t *ws_sent, int *ws_clients);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_RENDER_H */
