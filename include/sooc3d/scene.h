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
 * size[] = the object's axis-aligned extent (x, y, z) in its own frame.
 * Composite shapes are unions of parts (sooc_scene_object_parts).
 *
 * Instance ids: object k has id k+1 (1..n_objects); 0 = floor/walls/sky.
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
    SOOC_SHAPE_COUNT
} sooc_shape;

const char *sooc_shape_name(sooc_shape s);
/* Parse a shape name; returns SOOC_EINVAL for unknown names. */
sooc_status sooc_shape_parse(const char *name, sooc_shape *out);

typedef struct sooc_scene_object {
    int id;                 /* instance id, >= 1                               */
    sooc_shape shape;
    double x, z, yaw;       /* floor pose in world                              */
    double size[3];         /* extent (x, y, z) in the object frame             */
    double params[6];       /* shape parameters, see above                      */
    float color[3];         /* albedo, sRGB in [0, 1]                            */
} sooc_scene_object;

/* Primitive parts of an object (object frame, yaw already excluded):
 * prim uses the first six shapes (SPHERE..SUPERQUADRIC), c is the
 * primitive's reference point (centre; base centre for cones), d its
 * dimensions as in the params table. */
typedef struct sooc_scene_part {
    sooc_shape prim;
    double c[3];
    double d[5];
} sooc_scene_part;
#define SOOC_SCENE_MAX_PARTS 16

typedef enum sooc_floor_tex {
    SOOC_FLOOR_UNIFORM = 0, SOOC_FLOOR_CHECKER, SOOC_FLOOR_WOOD, SOOC_FLOOR_NOISE
} sooc_floor_tex;

typedef struct sooc_scene {
    char preset[16];        /* "unity" | "blender"                              */
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
    float sky_color[3];
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
sooc_status sooc_scene_copy(sooc_scene *dst, const sooc_scene *src);

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

/* Write one binary little-endian PLY per object (world coordinates, vertex
 * colours) to <dir>/object_%04d.ply (id), creating dir. */
sooc_status sooc_scene_write_meshes(const char *dir, const sooc_scene *sc);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_SCENE_H */
