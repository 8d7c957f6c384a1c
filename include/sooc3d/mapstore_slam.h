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
#ifndef SOOC3D_MAPSTORE_SLAM_H
#define SOOC3D_MAPSTORE_SLAM_H

#include "sooc3d/mapstore.h"

#ifdef __cplusplus
extern "C" {
#endif

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
#endif
