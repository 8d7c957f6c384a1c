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
#ifndef SOOC3D_MESH_H
#define SOOC3D_MESH_H

#include <stddef.h>
#include <stdint.h>

#include "sooc3d/core.h"
#include "sooc3d/render.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

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

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_MESH_H */
