/* Foxglove messages of the map (docs/logs.md "Foxglove"): the JSON schemas
 * of foxglove.SceneUpdate and foxglove.FrameTransform, and the JSON of one
 * map object as a SceneEntity (a cube of its box, its id as a text label, its
 * presence and covariance as metadata) and of one transform. Shared by
 * `sooc3d map export --mcap` and the node's `record: {mcap: FILE}`.
 * Appends to a sooc_ros_buf (log.h); on allocation failure b->oom is set. */
#ifndef SOOC3D_FOXGLOVE_H
#define SOOC3D_FOXGLOVE_H

#include <stdint.h>

#include "sooc3d/log.h"
#include "sooc3d/map_entry.h"

#ifdef __cplusplus
extern "C" {
#endif

extern const char sooc_foxglove_scene_schema[];   /* "foxglove.SceneUpdate", encoding "jsonschema" */
extern const char sooc_foxglove_frame_schema[];   /* "foxglove.FrameTransform"                    */

/* printf-style append to b (JSON text, not NUL-terminated in b->size). */
void sooc_foxglove_printf(sooc_ros_buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* One SceneEntity in the map's +y-up "world" frame: the box centred at half
 * its height h (m), turned by yaw about +y; cov is the planner covariance of
 * (x, z, yaw) (sooc_map_entry_planner_cov: xx, xz, zz, yaw). */
void sooc_foxglove_entity(sooc_ros_buf *b, const sooc_map_entry *e, const double cov[4], double h, int64_t t_ns);
/* One FrameTransform parent -> child of the 4x4 row-major T. */
void sooc_foxglove_frame(sooc_ros_buf *b, int64_t t_ns, const char *parent, const char *child, const double T[16]);
/* map (REP 103: x forward, y left, z up) <- world (+y up): x = -z_w, y = -x_w, z = y_w (table.h) */
extern const double sooc_foxglove_T_map_world[16];

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_FOXGLOVE_H */
