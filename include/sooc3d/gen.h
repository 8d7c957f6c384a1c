/*
 * sooc3d synthetic worlds: scene descriptions (objects, shapes, layout,
 * their files) and the generator that renders RGB-D sequences of them with
 * ground truth.
 *
 * Sections: scene descriptions (scene); the synthetic world generator (gen).
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
#ifndef SOOC3D_GEN_H
#define SOOC3D_GEN_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== scene descriptions (scene) ========================================= */

/*
 * sooc3d synthetic scene description (scene.yaml) and object geometry.
 *
 * World: gravity-aligned, +y up, floor at y = 0; the room is the square
 * [-room_size/2, room_size/2] in x and z. Every object stands on the floor.
 * An object's frame has its origin on the floor under the object's centre,
 * +y up, rotated by yaw about +y (R_y(yaw) as in core.h):
 *   p_world = R_y(yaw) p_obj + (x, 0, z).
 *
 * Shapes and their params[] (all lengths in metres, object frame):
 *   sphere        r                              centre at y = r
 *   box           hx hy hz (half extents)        centre at y = hy
 *   cylinder      r hy (half height)             axis +y, centre at y = hy
 *   cone          r h                            base disc at y = 0, apex at y = h
 *   torus         R r (ring and tube radius)     lying flat, axis +y, centre at y = r
 *   superquadric  a b c e1 e2 (x, y, z semi-axes; e1 vertical, e2 horizontal
 *                 shape exponent)                centre at y = b
 *   table         w d h t l (top width x, depth z, height, top thickness,
 *                 leg side)                      four legs + top
 *   chair         w d hs hb t l (seat width, depth, seat height, total
 *                 height, board thickness, leg side)  legs + seat + back at -z
 *   shelf         w d h n t (width, depth, height, number of boards,
 *                 board thickness)               two sides + n boards + back
 * Tabletop shapes (gen_tabletop.c; docs/formats.md 4.1):
 *   frustum       rb rt h (bottom, top radius, height)  solid truncated cone,
 *                 base disc at y = 0
 *   cup           rt rb h t (top, bottom radius, height, wall thickness)
 *                 open vessel + half-torus handle on +x
 *   bowl          rt rb h t                      open vessel
 *   bottle        r h rn hn (body radius, total height, neck radius, neck
 *                 length)                        body + shoulder + neck + cap
 *   can           r h                            cylinder + tapered top rim
 * size[] = the object's axis-aligned extent (x, y, z) in its own frame.
 * Composite shapes are unions of parts (sooc_scene_object_parts).
 *
 * Instance ids: object k has id k+1 (1..n_objects); 0 = floor/walls/sky.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

typedef enum sooc_shape {
    SOOC_SHAPE_SPHERE = 0,
    SOOC_SHAPE_BOX,
    SOOC_SHAPE_CYLINDER,
    SOOC_SHAPE_CONE,
    SOOC_SHAPE_TORUS,
    SOOC_SHAPE_SUPERQUADRIC,
    SOOC_SHAPE_TABLE,
    SOOC_SHAPE_CHAIR,
    SOOC_SHAPE_SHELF,
    SOOC_SHAPE_FRUSTUM,
    SOOC_SHAPE_CUP,
    SOOC_SHAPE_BOWL,
    SOOC_SHAPE_BOTTLE,
    SOOC_SHAPE_CAN,
    SOOC_SHAPE_COUNT
} sooc_shape;

const char *sooc_shape_name(sooc_shape s);
/* Parse a shape name; returns SOOC_EINVAL for unknown names. */
sooc_status sooc_shape_parse(const char *name, sooc_shape *out);

/* Object textures, evaluated in the object frame (y up from the base):
 * STRIPES: color2 where floor(y / tex_scale) is odd; CHECKS: a 3-D checker
 * of period tex_scale; LABEL: a color2 band over 30-75% of the height with
 * text-like dashes of `color` in it. */
typedef enum sooc_obj_tex {
    SOOC_TEX_PLAIN = 0, SOOC_TEX_STRIPES, SOOC_TEX_CHECKS, SOOC_TEX_LABEL
} sooc_obj_tex;

typedef struct sooc_scene_object {
    int id;                 /* instance id, >= 1                               */
    sooc_shape shape;
    double x, z, yaw;       /* floor pose in world                              */
    double size[3];         /* extent (x, y, z) in the object frame             */
    double params[6];       /* shape parameters, see above                      */
    float color[3];         /* albedo, sRGB in [0, 1]                            */
    sooc_obj_tex tex;       /* procedural texture (PLAIN = uniform `color`)      */
    float color2[3];        /* second texture colour                             */
    double tex_scale;       /* stripe / check period (m)                         */
} sooc_scene_object;

/* Primitive parts of an object (object frame, yaw already excluded):
 * prim uses the first six shapes (SPHERE..SUPERQUADRIC) or FRUSTUM, c is the
 * primitive's reference point (centre; base centre for cones and frusta), d
 * its dimensions as in the params table, with two part-only extensions:
 *   FRUSTUM d = rb rt h t b: t > 0 makes it an open vessel (wall thickness
 *     t measured horizontally, bottom thickness b); t = 0 is solid.
 *   TORUS d = R r axis half: axis 1 stands the ring in the x-y plane (axis
 *     +z; 0 = lying flat), half 1 keeps only the x >= 0 half (a handle). */
typedef struct sooc_scene_part {
    sooc_shape prim;
    double c[3];
    double d[5];
} sooc_scene_part;
#define SOOC_SCENE_MAX_PARTS 16

typedef enum sooc_floor_tex {
    SOOC_FLOOR_UNIFORM = 0, SOOC_FLOOR_CHECKER, SOOC_FLOOR_WOOD, SOOC_FLOOR_NOISE
} sooc_floor_tex;

/* What the objects stand on (the layout plane y = 0):
 * FLOOR: an unbounded floor (unity, blender).
 * TABLE: a table top support_size[0] (x) x support_size[1] (z) centred at
 *   the origin, support_thick thick, over a room floor ("ground") at
 *   y = -support_height.
 * BIN:   a bin floor of support_size at y = 0 inside four walls of
 *   thickness support_thick rising rim_height above it, standing on a
 *   ground plane at y = -support_height.
 * Only the upward faces at y = 0 are the layout (floor colour/texture);
 * table edges and bin walls take support_color, the ground ground_color.
 * With TABLE/BIN, room walls (walls = 1) stand on the ground and are
 * wall_height tall. */
typedef enum sooc_support_kind {
    SOOC_SUPPORT_FLOOR = 0, SOOC_SUPPORT_TABLE, SOOC_SUPPORT_BIN
} sooc_support_kind;

typedef struct sooc_scene {
    char preset[16];        /* "unity" | "blender" | "tabletop"                 */
    char scale[4];          /* "s" | "m" | "l" | "xl"                           */
    uint64_t seed;          /* generator seed                                   */
    int index;              /* scene number under that seed                    */
    double room_size;       /* side of the square room (m)                      */
    double clip_depth;      /* d_clip (m): farther (planar z) pixels are invalid */
    int walls;              /* 1: low walls on the room border; 0: open floor + sky */
    double wall_height;
    float wall_color[3];
    sooc_floor_tex floor_tex;
    float floor_color[3], floor_color2[3];
    double tex_scale;       /* texture period (m)                               */
    sooc_support_kind support; /* FLOOR (default), TABLE or BIN                    */
    double support_size[2]; /* table top / bin floor: x and z extent (m)         */
    double support_height;  /* ground at y = -support_height                     */
    double support_thick;   /* table top thickness / bin wall thickness          */
    double rim_height;      /* bin walls above y = 0                             */
    float support_color[3]; /* table edges, bin walls                            */
    float ground_color[3];
    float sky_color[3];
    char sensor_noise[16];  /* "" (exact depth) | "kinect": depth/ and rgb/ carry
                               sensor noise, depth_gt/ the exact depth        */
    double light_dir[3];    /* unit vector towards the light                    */
    double ambient;         /* ambient fraction in [0, 1]                        */
    int shadows;            /* cast shadows (blender)                           */
    double specular;        /* specular strength (0 = Lambertian only)          */
    double shininess;
    int width, height;      /* image size the views were rendered at            */
    double fov_deg;         /* horizontal field of view                          */
    int n_objects;
    sooc_scene_object *objects;  /* sooc_malloc'd                               */
    int n_views;            /* views in the sequence (input + query)            */
    uint8_t *view_is_query; /* n_views flags: 1 = held-out query view           */
    double *view_T_wc;      /* n_views x 16 camera-to-world poses, or NULL (not in scene.yaml) */
} sooc_scene;

void sooc_scene_init(sooc_scene *sc);          /* zero + sensible defaults */
void sooc_scene_free(sooc_scene *sc);          /* NULL-safe; leaves it initialised */

/* Save scene.yaml atomically (`%YAML 1.2` + `---`). */
sooc_status sooc_scene_save(const char *path, const sooc_scene *sc);
/* Load and validate scene.yaml. Errors name the file, line and key; unknown
 * keys, unknown shapes, missing fields and bad numbers are errors. */
sooc_status sooc_scene_load(const char *path, sooc_scene *out);

/* Fill up to `cap` parts; returns the part count (<= SOOC_SCENE_MAX_PARTS). */
int sooc_scene_object_parts(const sooc_scene_object *o, sooc_scene_part *parts, int cap);
/* Distance (m) from a world point to the object's analytic surface (exact for
 * sphere/box/cylinder/cone/torus, radial bound for superquadrics). */
double sooc_scene_object_distance(const sooc_scene_object *o, const double p_world[3]);
/* Radius of the object's footprint circle on the floor (for spacing). */
double sooc_scene_object_footprint(const sooc_scene_object *o);
/* World centre of the object's bounding box. */
void sooc_scene_object_center(const sooc_scene_object *o, double c[3]);
/* The cup's half-torus handle: centre c (object frame), ring radius R and
 * tube radius r for cup params q = rt rb h t. */
void sooc_scene_cup_handle(const double *q, double c[3], double *R, double *r);

/* Write one binary little-endian PLY per object (world coordinates, vertex
 * colours) to <dir>/object_%04d.ply (id), creating dir. */
sooc_status sooc_scene_write_meshes(const char *dir, const sooc_scene *sc);

/* ==== the synthetic world generator (gen) ================================ */

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
    double touch;         /* tabletop: fraction of objects placed against another one
                             (footprints 0-3 mm apart or slightly overlapping; the
                             others stand 2 cm apart; default 0)                       */
    double flat;          /* tabletop: fraction of objects that are flat: packets and
                             books 0.8-4 cm tall, markers lying down (default 0)       */
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
 * the continuous pixel convention of core.h: cx = w/2). */
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
