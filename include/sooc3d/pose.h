/*
 * sooc3d pose sources: timestamped camera poses T_wc for frames.
 *
 *   file     a trajectory in TUM format (groundtruth.txt: `t tx ty tz qx qy qz qw`,
 *            t in seconds, '#' comments), camera-to-world.
 *   socket   a live stream on a UDP ("udp://127.0.0.1:5005", "udp://:5005") or UNIX
 *            datagram socket ("unix:/run/sooc3d/pose.sock"); a receiver thread
 *            inserts poses into the buffer. Datagrams hold one binary packet
 *            (below) or text lines `t tx ty tz qx qy qz qw` (t in seconds).
 *   buffer   no input; the caller pushes poses with sooc_pose_push.
 *
 * Poses of the camera are stored as given. Poses of the end effector
 * (T_base_effector from arm kinematics) are turned into camera poses with the
 * hand-eye extrinsic:  T_wc = T_world_base * T_base_effector * T_effector_camera.
 *
 * All sources keep a bounded ring sorted by time: out-of-order poses are
 * inserted in place, duplicates (same t_ns) are dropped, and when full the
 * oldest pose is dropped (a pose older than everything in a full ring is
 * rejected). sooc_pose_lookup interpolates between the two poses bracketing
 * t (SLERP on rotation, linear on translation, sooc_se3_interp).
 *
 * Thread-safety: every function may be called concurrently with the receiver
 * thread; lookups from several threads are fine.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_POSE_H
#define SOOC3D_POSE_H

#include <stddef.h>
#include <stdint.h>

#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sooc_pose_src sooc_pose_src;

typedef enum sooc_pose_kind {
    SOOC_POSE_CAMERA = 0,      /* pose is T_world_camera (OpenCV optical axes)  */
    SOOC_POSE_EFFECTOR = 1     /* pose is T_base_effector (needs hand-eye)      */
} sooc_pose_kind;

typedef struct sooc_pose_params {
    int capacity;                  /* ring size in poses (default 4096)                    */
    int has_hand_eye;              /* 1: T_effector_camera below is valid (required for
                                      effector poses; they are rejected and counted
                                      otherwise)                                           */
    double T_effector_camera[16];  /* hand-eye extrinsic (calib `T_effector_camera`)       */
    double T_world_base[16];       /* robot base in the world (default identity)           */
    sooc_pose_kind text_kind;      /* kind of text-form poses (default camera)             */
    int64_t max_gap_ns;            /* never interpolate across a gap longer than this
                                      (default 0 = no limit beyond the lookup tolerance)   */
    int rcvbuf_bytes;              /* socket SO_RCVBUF (0 = system default)                */
} sooc_pose_params;

void sooc_pose_params_default(sooc_pose_params *p);

sooc_status sooc_pose_open_file(sooc_pose_src **out, const char *path, const sooc_pose_params *p);
sooc_status sooc_pose_open_socket(sooc_pose_src **out, const char *address, const sooc_pose_params *p);
sooc_status sooc_pose_open_buffer(sooc_pose_src **out, const sooc_pose_params *p);
void sooc_pose_close(sooc_pose_src *src);  /* NULL-safe; joins the receiver thread */

/* Insert a pose (kind camera or effector, T row-major 4x4). Returns SOOC_OK,
 * or SOOC_EINVAL for a non-rigid T / an effector pose without hand-eye; a
 * duplicate or too-old pose returns SOOC_OK and is counted. */
sooc_status sooc_pose_push(sooc_pose_src *src, int64_t t_ns, sooc_pose_kind kind, const double T[16]);
/* Same with translation + unit quaternion (x, y, z, w). */
sooc_status sooc_pose_push_tq(sooc_pose_src *src, int64_t t_ns, sooc_pose_kind kind,
                              const double t[3], const double q[4]);

/* Camera pose at t_ns. Uses the poses p0 <= t <= p1 around t (an exact match
 * needs only one) and requires t - t0 <= tol_ns and t1 - t <= tol_ns (and
 * t1 - t0 <= max_gap_ns when set). Otherwise SOOC_ENOTFOUND, counted as a
 * skipped frame. Every call counts as one lookup. */
sooc_status sooc_pose_lookup(sooc_pose_src *src, int64_t t_ns, int64_t tol_ns, double T_wc_out[16]);
/* Like lookup, but for a live stream whose pose after t has not arrived yet:
 * waits up to timeout_ms for a pose newer than t before giving up. */
sooc_status sooc_pose_wait_lookup(sooc_pose_src *src, int64_t t_ns, int64_t tol_ns, int timeout_ms,
                                  double T_wc_out[16]);

typedef struct sooc_pose_stats {
    int64_t received;      /* poses accepted into the ring                        */
    int64_t packets;       /* datagrams received (socket)                         */
    int64_t bad_packets;   /* bad magic/version/CRC/size, unparsable text         */
    int64_t duplicates;    /* same t_ns as a stored pose: dropped                 */
    int64_t out_of_order;  /* inserted before the newest stored pose              */
    int64_t overflow;      /* dropped because the ring was full                   */
    int64_t rejected;      /* effector pose without hand-eye, non-rigid matrix    */
    int64_t seq_gaps;      /* packets missing according to the sender's seq       */
    int64_t lookups, hits, exact, skipped;  /* skipped = lookups returning ENOTFOUND */
    int count;             /* poses in the ring now                               */
    int64_t t_first_ns, t_last_ns;          /* range held (0 when empty)          */
} sooc_pose_stats;
void sooc_pose_get_stats(sooc_pose_src *src, sooc_pose_stats *out);

/* ---- wire format ---------------------------------------------------------
 * One binary packet per datagram, 88 bytes, little-endian:
 *   0  u32  magic 0x4F505353 ("SSPO" in memory order: 'S','S','P','O')
 *   4  u16  version (1)
 *   6  u16  flags: bit 0 = 1 for an end-effector pose, 0 for a camera pose
 *   8  u32  seq (sender's counter, for gap counting)
 *  12  u32  reserved (0)
 *  16  i64  t_ns (same clock as the frames, normally CLOCK_REALTIME)
 *  24  f64 x7  tx ty tz qx qy qz qw (metres; Hamilton quaternion, scalar last)
 *  80  u32  CRC-32 (zlib) of bytes 0..79
 *  84  u32  reserved (0)
 * Text form (one or more lines per datagram): `t tx ty tz qx qy qz qw`,
 * t in seconds (as in TUM files); '#' lines ignored; kind = params.text_kind. */
#define SOOC_POSE_PACKET_SIZE 88
#define SOOC_POSE_PACKET_MAGIC 0x4F505353u
#define SOOC_POSE_PACKET_VERSION 1

typedef struct sooc_pose_packet {
    uint32_t seq;
    sooc_pose_kind kind;
    int64_t t_ns;
    double t[3];
    double q[4];   /* x y z w */
} sooc_pose_packet;

void sooc_pose_packet_encode(uint8_t buf[SOOC_POSE_PACKET_SIZE], const sooc_pose_packet *pk);
/* SOOC_EFORMAT with a message on a bad size/magic/CRC, SOOC_EVERSION on a
 * newer version. */
sooc_status sooc_pose_packet_decode(const uint8_t *buf, size_t n, sooc_pose_packet *pk);

/* Send one packet (binary) or a text line to `address` (same syntax as
 * sooc_pose_open_socket). For tools and tests; opens and closes a socket per
 * call unless a sender is kept. */
typedef struct sooc_pose_sender sooc_pose_sender;
sooc_status sooc_pose_sender_open(sooc_pose_sender **out, const char *address);
sooc_status sooc_pose_sender_send(sooc_pose_sender *s, const sooc_pose_packet *pk);
sooc_status sooc_pose_sender_send_raw(sooc_pose_sender *s, const void *data, size_t n);
void sooc_pose_sender_close(sooc_pose_sender *s);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_POSE_H */
