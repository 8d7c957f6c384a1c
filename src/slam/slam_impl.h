/* Internal: what the files of the SLAM module share (include/sooc3d/slam.h). */
#ifndef SOOC3D_SLAM_IMPL_H
#define SOOC3D_SLAM_IMPL_H

#include "sooc3d/slam.h"
#include "sooc3d/cogmap.h"

#if SOOC_HAVE_OPENCV
#include "slam/slamshim.h"
#endif

/* a graph node: one keyframe */
typedef struct sooc_slam_node {
    int64_t id, frame, t_ns;
    int32_t run;
    int segment;          /* odometry segment of this run; -1 for stored keyframes */
    double T[16];         /* world pose (optimised)                                */
    double T_odo[16];     /* pose in its odometry segment's frame                  */
    int nf;               /* features                                              */
    float *uv, *xyz;      /* 2 and 3 per feature; xyz NaN = no depth               */
    uint8_t *desc;        /* 32 bytes per feature                                  */
    float *depth;         /* dw x dh metres (0 = invalid)                          */
    int dw, dh;
    double Kf[4], Kd[4];  /* K of the feature image and of the stored depth        */
} sooc_slam_node;

typedef struct sooc_slam_edge {
    int a, b, kind;       /* node indices; 0 odometry, 1 loop, 2 relocalisation, 3 re-anchor, 4 local */
    double T_ab[16], w_t, w_r;
} sooc_slam_edge;

/* a loop candidate waiting for verification: query node q against node b */
typedef struct sooc_slam_pair {
    int q, b;
    int local;            /* a local edge (the recent window), not a loop */
} sooc_slam_pair;

typedef struct sooc_slam_frame {
    int64_t index, t_ns;
    int node;
    double T_rel[16];     /* pose relative to its node: T_node^-1 T_frame */
} sooc_slam_frame;

struct sooc_slam {
    sooc_slam_params p;
    sooc_mapstore *store;
    sooc_odom *odo;
    int32_t run;
    int64_t next_id;
    int segment;          /* current odometry segment                         */
    int cur_node;         /* node of the odometry's keyframe (-1: none)        */
    int last_node;        /* newest node of this run                            */
    int lost;             /* 1: relocalise before tracking                      */
    int reanchor;         /* 1: next frame starts a segment at the last pose    */
    int started;
    double T_init[16], T_last[16];
    sooc_slam_node *nodes;
    int n_nodes, cap_nodes;
    sooc_slam_edge *edges;
    int n_edges, cap_edges;
    sooc_slam_frame *frames;
    int64_t n_frames, cap_frames;
    /* working buffers at the tracker's resolution */
    int w, h;
    double K[4];
    uint8_t *gray;
    float *depth;
    int *pairs;            /* 2 per match                    */
    double *obj, *img;     /* PnP input                      */
    sooc_slam_kf_change *changes;   /* the last optimisation's, this run's keyframes */
    size_t n_changes, cap_changes;
    uint64_t graph_version;
    sooc_slam_pair *pend;           /* loop candidates to verify, oldest first */
    int n_pend, cap_pend;
    int pend_loops, pend_local;     /* edges added since the last optimisation */
#if SOOC_HAVE_OPENCV
    sooc_slsh_icp *icp;
#endif
    sooc_slam_stats st;
};

/* slam_kf.c: features, blobs, matching, verification */
sooc_status sooc__slam_extract(sooc_slam *s, sooc_slam_node *n);
void sooc__slam_node_free(sooc_slam_node *n);
int sooc__slam_match(const sooc_slam_node *q, const sooc_slam_node *b, int *pairs, int cap);
sooc_status sooc__slam_verify(sooc_slam *s, const sooc_slam_node *q, const sooc_slam_node *b, int *ok, double T_b_q[16],
                              int *inliers);
/* encode into sooc_malloc'd blobs / decode into the node */
sooc_status sooc__slam_encode(const sooc_slam_node *n, void **feat, size_t *feat_bytes, void **depth, size_t *depth_bytes);
sooc_status sooc__slam_decode(sooc_slam_node *n, const void *feat, size_t feat_bytes, const void *depth,
                              size_t depth_bytes);

#endif
