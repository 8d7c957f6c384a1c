/*
 * sooc3d synthetic world generator: random scenes of analytic primitives,
 * camera walks through them, and an exact CPU ray tracer (RGB, planar depth,
 * instance ids). Used by `sooc3d gen`, the model tests and the demo.
 *
 * Determinism: scene k of seed S is sampled from sooc_rng stream (S, k); a
 * rendered view depends only on the scene and the camera, so output bytes do
 * not depend on the thread count.
 *
 * Scales (side of the square room): s = 4 m, m = 8 m, l = 24 m, xl = 48 m.
 * Object density is constant (objects per m^2), so the object count grows
 * with the area; cameras walk THROUGH the room at every scale, so objects in
 * view lie at the same distances and only the number of views grows.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_GEN_H
#define SOOC3D_GEN_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/scene.h"
#include "sooc3d/image.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sooc_gen_preset { SOOC_GEN_UNITY = 0, SOOC_GEN_BLENDER = 1, SOOC_GEN_TABLETOP = 2 } sooc_gen_preset;
/* Sensor noise on the written depth and colour (sensor_noise.h): AUTO =
 * KINECT for the tabletop preset, NONE for unity and blender. */
typedef enum sooc_gen_noise { SOOC_GEN_NOISE_AUTO = 0, SOOC_GEN_NOISE_NONE, SOOC_GEN_NOISE_KINECT } sooc_gen_noise;
typedef enum sooc_gen_scale { SOOC_GEN_S = 0, SOOC_GEN_M, SOOC_GEN_L, SOOC_GEN_XL } sooc_gen_scale;

typedef struct sooc_gen_params {
    sooc_gen_preset preset;
    sooc_gen_scale scale;
    uint64_t seed;
    int n_scenes;         /* scenes to write (sooc_gen_run)                           */
    int first_scene;      /* index of the first scene (scene_%04d numbering)          */
    int width, height;    /* image size (default 64 x 64)                              */
    int n_views;          /* input views per scene; 0 = default for the scale          */
    int n_query;          /* query views per scene; -1 = default (max(2, views/5))     */
    double fov_deg;       /* horizontal FOV (default 60)                               */
    double clip_depth;    /* d_clip (default 8 m)                                      */
    double density;       /* objects per m^2 (default 0.2)                            */
    double wall_h[2];     /* unity/blender: walls in every scene, heights uniform in
                             [wall_h[0], wall_h[1]] m; 0 = the default (walls in half
                             the scenes, 0.3-0.8 m high)                              */
    double depth_scale;   /* metres per depth PNG unit (default 2e-4: 13.1 m range)   */
    int threads;          /* OpenMP threads for sooc_gen_run (0 = runtime default)     */
    int write_meshes;     /* write meshes/ (default 1)                                 */
    int contact_sheet;    /* write <out>/contact_sheet.png (default 1)                 */
    sooc_gen_noise noise; /* sensor noise (default AUTO); with noise, depth_gt/ keeps
                             the exact depth                                            */
} sooc_gen_params;

void sooc_gen_params_default(sooc_gen_params *p);
sooc_status sooc_gen_preset_parse(const char *s, sooc_gen_preset *out);
sooc_status sooc_gen_scale_parse(const char *s, sooc_gen_scale *out);
const char *sooc_gen_preset_name(sooc_gen_preset p);
const char *sooc_gen_scale_name(sooc_gen_scale s);
double sooc_gen_scale_side(sooc_gen_scale s);       /* 4, 8, 24, 48 m   */
int sooc_gen_default_views(sooc_gen_scale s);       /* 10, 20, 60, 120  */
/* Input views per scene for p (p->n_views, else the preset's default:
 * unity/blender as above, tabletop 10, 20, 30 for s, m, l). */
int sooc_gen_views(const sooc_gen_params *p);
/* 1 when p's scenes carry sensor noise (p->noise, AUTO by preset). */
int sooc_gen_noisy(const sooc_gen_params *p);

/* Tabletop preset (gen_tabletop.c, docs/formats.md 5.1). Table top size
 * (x, z) in m for a scale: s 1.1 x 0.8, m 1.8 x 1.1, l 2.4 x 1.6; xl is not
 * a tabletop scale (SOOC_EINVAL). */
sooc_status sooc_gen_tabletop_size(sooc_gen_scale s, double wd[2]);
/* Sample tabletop scene `index` (called by sooc_gen_scene). */
sooc_status sooc_gen_tabletop_scene(sooc_scene *sc, const sooc_gen_params *p, int index);

/* Sample scene `index` (objects, lighting, camera walk + query views, with
 * poses in sc->view_T_wc). `sc` must be initialised (sooc_scene_init) or
 * hold a previous scene, which is freed. */
sooc_status sooc_gen_scene(sooc_scene *sc, const sooc_gen_params *p, int index);

/* Intrinsics of the generator's pinhole camera for a scene (w x h, the
 * scene's horizontal FOV, square pixels, principal point at the centre, in
 * the continuous pixel convention of geom.h: cx = w/2). */
void sooc_gen_intrinsics(sooc_intrinsics *K, int w, int h, double fov_deg);

/* Render one view of `sc` from camera pose T_wc (camera-to-world, OpenCV
 * axes) with intrinsics K into `f` (allocated with an instance buffer if it
 * is empty or of another size; reused otherwise). Fills rgb, planar depth
 * (0 = sky / beyond clip_depth), valid, instance, T_wc, K. Thread-safe; uses
 * OpenMP over rows when called outside a parallel region. */
sooc_status sooc_gen_render_view(const sooc_scene *sc, const double T_wc[16], const sooc_intrinsics *K,
                                 sooc_frame *f);

/* Per-scale statistics over rendered views (`--stats`). An object counts as
 * in view when it covers >= 4 pixels with valid depth. */
#define SOOC_GEN_DIST_BINS 9      /* [0,1), [1,2) ... [7,8), >= 8 m */
#define SOOC_GEN_PIX_BINS 6       /* <16, <64, <256, <1024, <4096, >= 4096 pixels */
typedef struct sooc_gen_stats {
    int64_t n_views, n_objects_in_view, n_scenes, n_objects_total;
    int64_t views_by_count[16];   /* views holding 0..14, >=15 objects */
    int64_t dist_hist[SOOC_GEN_DIST_BINS];
    int64_t pix_hist[SOOC_GEN_PIX_BINS];
    double sum_dist, sum_pix;
} sooc_gen_stats;

/* Add one rendered view of `sc` to the statistics. */
void sooc_gen_stats_add(sooc_gen_stats *st, const sooc_scene *sc, const sooc_frame *f);

/* Progress callback for sooc_gen_run: called from the calling thread after
 * each scene with (views done, views total). */
typedef void (*sooc_gen_progress_fn)(void *user, int64_t done, int64_t total);

/* Generate p->n_scenes scenes under out_dir/scene_%04d/ (TUM layout +
 * calib.yaml + scene.yaml + instance/ + meshes/) and, if asked,
 * out_dir/contact_sheet.png. `stats` (may be NULL) is filled. */
sooc_status sooc_gen_run(const sooc_gen_params *p, const char *out_dir, sooc_gen_progress_fn cb,
                         void *user, sooc_gen_stats *stats);

/* Contact sheet of frames: for each frame three tiles (RGB | depth with
 * turbo over [0, dmax] | instance ids), `per_row` frames per row, each tile
 * magnified by `scale`; labels[i] (may be NULL) go under frame i's RGB tile. */
sooc_status sooc_gen_contact_sheet(sooc_image *out, const sooc_frame *const *frames,
                                   const char *const *labels, int n, int per_row, int scale,
                                   double dmax, const char *title);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_GEN_H */
