/*
 * sooc3d synthetic scene description (scene.yaml) and object geometry.
 *
 * World: gravity-aligned, +y up, floor at y = 0; the room is the square
 * [-room_size/2, room_size/2] in x and z. Every object stands on the floor.
 * An object's frame has its origin on the floor under the object's centre,
 * +y up, rotated by yaw about +y (R_y(yaw) as in geom.h):
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
#ifndef SOOC3D_SCENE_H
#define SOOC3D_SCENE_H

#include "sooc3d/core.h"
#include "sooc3d/geom.h"

#ifdef __cplusplus
extern "C" {
#endif

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

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_SCENE_H */
