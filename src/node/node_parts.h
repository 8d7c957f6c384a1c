/* The node's parts (private to src/node; its tests include it): the frame
 * ring between the capture and mapping threads, the keyframe policy and the
 * latency recorder (docs/node.md). */
#ifndef SOOC3D_NODE_PARTS_H
#define SOOC3D_NODE_PARTS_H

#include "sooc3d/frame.h"

#include <stdint.h>

/* ------------------------------------------------------------- frame ring */

/* Bounded single-producer/single-consumer frame ring. push never blocks: when
 * full the oldest frame is dropped (counted). Frames are swapped in and out,
 * not copied: push takes over *f's buffers and gives back a spare frame's. */
typedef struct sooc_frame_ring sooc_frame_ring;

sooc_status sooc_frame_ring_create(sooc_frame_ring **out, int capacity);
void sooc_frame_ring_destroy(sooc_frame_ring *r);
/* Push a frame (stamped with t_mono_ns, the monotonic arrival time). */
void sooc_frame_ring_push(sooc_frame_ring *r, sooc_frame *f, int64_t t_mono_ns);
/* Pop the oldest frame into *f (swapping buffers). Waits up to timeout_ms
 * (-1 = forever). Returns SOOC_OK, SOOC_ETIMEOUT, or SOOC_EEOF once the ring is
 * closed and empty. */
sooc_status sooc_frame_ring_pop(sooc_frame_ring *r, sooc_frame *f, int64_t *t_mono_ns, int timeout_ms);
/* Blocking mode (replay only): push waits for space instead of dropping. */
void sooc_frame_ring_set_blocking(sooc_frame_ring *r, int on);
void sooc_frame_ring_close(sooc_frame_ring *r);   /* wakes the consumer; pop drains then EEOF */
void sooc_frame_ring_counts(sooc_frame_ring *r, uint64_t *pushed, uint64_t *dropped, int *fill);

/* --------------------------------------------------------- keyframe policy */

typedef struct sooc_kf_policy {
    double translation_m, rotation_deg, time_s;   /* 0 disables a rule */
    int have_last;
    double T_last[16];
    int64_t t_last_ns;
} sooc_kf_policy;

void sooc_kf_policy_init(sooc_kf_policy *p, double translation_m, double rotation_deg, double time_s);
/* 1 if (T_wc, t_ns) should be a keyframe: the first frame, or translation or
 * rotation angle since the last keyframe at/over a threshold, or time since it
 * at/over time_s. Does not change state. */
int sooc_kf_policy_check(const sooc_kf_policy *p, const double T_wc[16], int64_t t_ns);
void sooc_kf_policy_accept(sooc_kf_policy *p, const double T_wc[16], int64_t t_ns);
/* Rotation angle (deg) between two poses. */
double sooc_pose_angle_deg(const double A[16], const double B[16]);

/* ------------------------------------------------------- latency recorder */

#define SOOC_LAT_WINDOW 4096
typedef struct sooc_latency {
    double v[SOOC_LAT_WINDOW];       /* last SOOC_LAT_WINDOW samples (ms) */
    uint64_t n;                      /* total samples recorded */
} sooc_latency;
void sooc_latency_add(sooc_latency *l, double ms);
/* Percentile q in [0, 1] over the window (nearest rank); 0 if empty. */
double sooc_latency_pct(const sooc_latency *l, double q);

#endif
