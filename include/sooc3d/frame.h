/*
 * sooc3d frames: the one RGB-D frame type that crosses every seam
 * (readers -> node -> mapper -> eval), see docs/formats.md §2.7.
 *
 * A frame owns its pixel buffers (allocated with sooc_malloc by
 * sooc_frame_alloc and released by sooc_frame_free).
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_FRAME_H
#define SOOC3D_FRAME_H

#include "sooc3d/core.h"
#include "sooc3d/geom.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_frame {
    int width, height;
    uint8_t *rgb;          /* H*W*3, RGB8, row-major                                   */
    float *depth;          /* H*W metres along the optical axis (planar z); 0 = invalid */
    uint8_t *valid;        /* H*W, 1 where depth is valid (depth > 0 and finite)        */
    uint16_t *instance;    /* H*W instance ids (0 = floor/background), or NULL          */
    int64_t t_ns;          /* sensor clock, nanoseconds                                 */
    int has_pose;          /* 1 when T_wc holds a pose                                  */
    double T_wc[16];       /* camera-to-world, row-major, OpenCV camera axes            */
    sooc_intrinsics K;     /* intrinsics at this frame's resolution                     */
    int64_t index;         /* frame number within its sequence                          */
    int is_query;          /* synthetic data: 1 for a held-out query view               */
} sooc_frame;

/* Why a frame could not be read, for sources that skip a broken frame and go
 * on (the replay driver; the node counts them, docs/node.md "Faults"). */
typedef enum sooc_frame_fault {
    SOOC_FRAME_FAULT_NONE = 0,
    SOOC_FRAME_FAULT_COLOR,   /* colour image missing, truncated or corrupt      */
    SOOC_FRAME_FAULT_DEPTH,   /* depth image missing, truncated or corrupt       */
    SOOC_FRAME_FAULT_POSE,    /* its pose (file) does not parse                  */
    SOOC_FRAME_FAULT_SIZE,    /* wrong size: depth vs colour, or vs the camera   */
    SOOC_FRAME_FAULT_OTHER,
    SOOC_FRAME_FAULT_COUNT
} sooc_frame_fault;

/* "colour", "depth", "pose", "size", "other" ("none" for 0). */
static inline const char *sooc_frame_fault_name(sooc_frame_fault f) {
    static const char *const k[SOOC_FRAME_FAULT_COUNT] = {"none", "colour", "depth", "pose", "size", "other"};
    return (int)f >= 0 && f < SOOC_FRAME_FAULT_COUNT ? k[f] : "other";
}

/* Allocate buffers for a w x h frame (instance buffer only if with_instance).
 * Zeroes everything. On failure, the frame is left empty. */
sooc_status sooc_frame_alloc(sooc_frame *f, int w, int h, int with_instance);
void sooc_frame_free(sooc_frame *f);     /* NULL-safe; leaves *f zeroed */
sooc_status sooc_frame_copy(sooc_frame *dst, const sooc_frame *src); /* dst is (re)allocated */

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_FRAME_H */
