/*
 * sooc3d shared-memory object table: the ABI for planners.
 *
 * This header stands alone: a planner includes only this file and links
 * libsooc3d_table (pkg-config sooc3d_table, or CMake find_package(sooc3d_table)).
 * It depends on nothing else from sooc3d. Full specification: docs/shm.md.
 *
 * Layout: one POSIX shm object per map, named "/sooc3d.v1.<name>" (visible as
 * /dev/shm/sooc3d.v1.<name>). It holds a 4096-byte header followed by
 * `capacity` records of 256 bytes. Everything is little-endian, fixed-width,
 * and its offsets are frozen by the _Static_asserts below.
 *
 * Concurrency: one writer process, any number of readers; readers never write
 * (they map the object PROT_READ). Consistency comes from seqlocks:
 *   - each record has `seq` (odd while being written);
 *   - the header has `table_seq` (odd while a batch, e.g. a keyframe, is being
 *     applied); epoch = table_seq / 2 counts published batches.
 * Readers copy with relaxed 64-bit atomic loads, then check the counter did not
 * move (see docs/shm.md "Reader protocol"). All reader functions below do this
 * with bounded retries and report SOOC_TABLE_EBUSY rather than spin forever:
 * a writer killed mid-batch leaves table_seq odd until a new writer starts.
 *
 * Liveness: the writer holds flock(LOCK_EX) on the shm object for its whole
 * life (the kernel drops it when the process dies, even on SIGKILL) and
 * refreshes heartbeat_mono_ns (CLOCK_MONOTONIC) at >= 10 Hz.
 *
 * Frame: gravity-aligned right-handed map frame, +y up, the floor at y = 0.
 * (x, z) span the floor; yaw is the rotation about +y (counter-clockwise seen
 * from above), yaw = 0 when the object's +x axis is along map +x. ROS REP-103
 * (x forward, y left, z up): x_ros = -z_map, y_ros = -x_map, z_ros = y_map,
 * yaw_ros = yaw_map; see sooc_table_pose_rep103().
 *
 * Return codes: 0 = OK, negative = error (SOOC_TABLE_E*); sooc_table_strerror()
 * names them. Functions never print, never exit, and keep errno from the
 * failing system call when the code is SOOC_TABLE_ESYS.
 */
#ifndef SOOC3D_TABLE_H
#define SOOC3D_TABLE_H

#include <stddef.h> /* offsetof, for the asserts only */
#include <stdint.h>
#ifdef __cplusplus
#include <atomic> /* ATOMIC_LLONG_LOCK_FREE, for the asserts only */
#else
#include <stdatomic.h>
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* C (C11 and later): the seqlock and header words are _Atomic(T). C++ (C++11
 * to C++23): the same words are plain T, so records and headers stay
 * trivially copyable (a std::atomic member would delete the copy) and the
 * header compiles without C++23's <stdatomic.h>. The layout is identical (the
 * asserts below check it in both languages). A C++ planner reads through the
 * library functions, which do the atomic loads; one that reads the mapping
 * directly must use std::atomic_ref (C++20) or __atomic_load_n on those words. */
#ifdef __cplusplus
#define SOOC_TABLE_ATOMIC(T) T
#define SOOC_TABLE_STATIC_ASSERT_(c, m) static_assert(c, m)
#define SOOC_TABLE_ALIGNOF_(T) alignof(T)
#else
#define SOOC_TABLE_ATOMIC(T) _Atomic(T)
#define SOOC_TABLE_STATIC_ASSERT_(c, m) _Static_assert(c, m)
#define SOOC_TABLE_ALIGNOF_(T) _Alignof(T)
#endif
#if defined(__GNUC__)
#define SOOC_TABLE_API __attribute__((visibility("default")))
#else
#define SOOC_TABLE_API
#endif

/* ------------------------------------------------------------ constants */

#define SOOC_TABLE_MAGIC 0x42544433434F4F53ull /* "SOOC3DTB" as little-endian bytes */
#define SOOC_TABLE_ABI_MAJOR 1u  /* any incompatible change: bump, and the name prefix */
#define SOOC_TABLE_ABI_MINOR 2u  /* fields appended into reserved bytes and new flag bits only (1: the store
                                    block; 2: the BOX_* record flags) */
#define SOOC_TABLE_HEADER_SIZE 4096u
#define SOOC_TABLE_RECORD_SIZE 256u
#define SOOC_TABLE_LATENT_MAX 32u
#define SOOC_TABLE_NAME_MAX 64u            /* max length of <name> */
#define SOOC_TABLE_SHM_PREFIX "/sooc3d.v1." /* shm_open name = prefix + <name> */
#define SOOC_TABLE_CAPACITY_MAX (1u << 20)
#define SOOC_TABLE_DEFAULT_MODE 0640u
#define SOOC_TABLE_READ_RETRIES 100        /* bounded seqlock retries per copy */
#define SOOC_TABLE_HEARTBEAT_STALE_NS 1000000000ll /* older heartbeat = hung writer */

/* Canonical field list of ABI major 1; schema_hash is its 64-bit FNV-1a.
 * It is frozen for major 1: minor versions add fields into reserved bytes
 * without changing it. tests/table checks the constant against the string. */
#define SOOC_TABLE_SCHEMA_STRING                                                          \
    "sooc3d.table.v1;"                                                                    \
    "header 4096:magic u64 0,abi_major u16 8,abi_minor u16 10,header_size u32 12,"        \
    "record_size u32 16,capacity u32 20,records_offset u64 24,schema_hash u64 32,"        \
    "frame_id char[32] 40,latent_max u32 72,reserved_a u32 76,instance_id u64 80,"        \
    "writer_pid i64 88,hflags u64 96,table_seq u64 104,heartbeat_mono_ns i64 112,"        \
    "high_water u64 120,n_objects u64 128,created_real_ns i64 136,latent_dim u32 256,"    \
    "reserved_b u32 260,latent_model_id u64 264,stamp_ns i64 272,T_src_map f64[16] 280;"  \
    "record 256:seq u64 0,object_id u64 8,flags u32 16,obs_count u32 20,presence f32 24," \
    "x f32 28,z f32 32,yaw f32 36,cov_xzyaw f32[6] 40,y f32 64,extent f32[3] 68,"         \
    "first_seen_ns i64 80,last_seen_ns i64 88,latent_dim u32 96,reserved0 u32 100,"       \
    "reserved u8[24] 104,latent f32[32] 128"
#define SOOC_TABLE_SCHEMA_HASH 0x784f569ffda8b30aull

/* Record flags (sooc_table_record.flags). */
#define SOOC_TABLE_FLAG_VALID 0x1u     /* the record describes a mapped object */
#define SOOC_TABLE_FLAG_TENTATIVE 0x2u /* seen too few times to trust yet */
#define SOOC_TABLE_FLAG_REMOVED 0x4u   /* object deleted from the map; the slot is
                                          kept for >= 1 epoch, then may be reused */
#define SOOC_TABLE_FLAG_STATIC 0x8u    /* believed not to move */
#define SOOC_TABLE_FLAG_SYMMETRIC 0x10u /* rotationally symmetric about its vertical axis:
                                           yaw is undefined, cov_xzyaw[5] (yaw variance)
                                           is NaN and the yaw cross terms 0 (docs/shm.md) */
/* The box's quality (abi_minor >= 2; a writer of an older minor leaves them 0):
 * BOX_TIGHT: extent is the tight box of the object's own geometry; without it
 * extent is the model's locality box (not computed yet). BOX_CLIPPED: the
 * geometry reaches the locality box's side, the extent is cut there.
 * BOX_EMPTY: no surface at all (extent 0). BOX_FAINT: below the surface
 * level everywhere, the box at half its peak. */
#define SOOC_TABLE_FLAG_BOX_TIGHT 0x20u
#define SOOC_TABLE_FLAG_BOX_CLIPPED 0x40u
#define SOOC_TABLE_FLAG_BOX_EMPTY 0x80u
#define SOOC_TABLE_FLAG_BOX_FAINT 0x100u

/* The map database's state (the header's store block, abi_minor >= 1;
 * sooc_table_get_store). */
#define SOOC_TABLE_STORE_NONE 0u    /* no database, or a writer of abi_minor 0 that does not say */
#define SOOC_TABLE_STORE_OK 1u      /* the database holds every published change */
#define SOOC_TABLE_STORE_FAILING 2u /* commits fail: the table is live, the database lags behind
                                       (store_pending objects wait; retried with backoff) */
/* Why the latest commit failed (store_fault). */
#define SOOC_TABLE_STORE_FAULT_NONE 0u
#define SOOC_TABLE_STORE_FAULT_FULL 1u    /* disk or file system full */
#define SOOC_TABLE_STORE_FAULT_IO 2u      /* I/O error, read-only or unopenable file */
#define SOOC_TABLE_STORE_FAULT_BUSY 3u    /* locked by another process */
#define SOOC_TABLE_STORE_FAULT_CORRUPT 4u /* the database file is corrupt */
#define SOOC_TABLE_STORE_FAULT_NOMEM 5u
#define SOOC_TABLE_STORE_FAULT_OTHER 6u

/* Header flags (sooc_table_header.hflags). */
#define SOOC_TABLE_HFLAG_WRITER_EXITED 0x1u /* writer closed cleanly (table is final) */
#define SOOC_TABLE_HFLAG_FLOOR_SET 0x2u     /* T_src_map holds the floor alignment, configured
                                               (world.up/floor) or estimated, once known */

/* Return codes. */
#define SOOC_TABLE_OK 0
#define SOOC_TABLE_EINVAL (-1)    /* bad argument or bad table name */
#define SOOC_TABLE_ENOENT (-2)    /* no table with that name / no such object */
#define SOOC_TABLE_EVERSION (-3)  /* incompatible ABI, sizes or schema hash */
#define SOOC_TABLE_ENOTREADY (-4) /* the creator has not finished the header yet */
#define SOOC_TABLE_EBUSY (-5)     /* seqlock retries exhausted (writer busy or dead mid-batch) */
#define SOOC_TABLE_ELOCKED (-6)   /* another live writer owns the table */
#define SOOC_TABLE_EFULL (-7)     /* no free slot (capacity reached) */
#define SOOC_TABLE_ERANGE (-8)    /* output buffer too small (count still reported) */
#define SOOC_TABLE_ESTATE (-9)    /* call out of order (e.g. upsert outside a batch) */
#define SOOC_TABLE_ENOMEM (-10)   /* allocation failed */
#define SOOC_TABLE_ESYS (-11)     /* a system call failed; errno is kept */

/* ---------------------------------------------------------------- layout */

/* One object, 256 bytes. The writer fills everything except `seq`. */
typedef struct sooc_table_record {
    SOOC_TABLE_ATOMIC(uint64_t) seq;   /*   0 per-record seqlock: odd = being written      */
    uint64_t object_id;      /*   8 unique within one map; 0 = empty slot. A writer
                                    restart that does not resume its map starts
                                    ids at 1 again: key by (instance_id, object_id),
                                    reset when instance_id changes (docs/shm.md) */
    uint32_t flags;          /*  16 SOOC_TABLE_FLAG_*                             */
    uint32_t obs_count;      /*  20 keyframes that observed the object            */
    float presence;          /*  24 p(exists) in [0, 1]                           */
    float x, z, yaw;         /*  28 floor pose in the map frame: m, m, rad        */
    float cov_xzyaw[6];      /*  40 upper triangle: xx xz xyaw zz zyaw yawyaw     */
    float y;                 /*  64 box-centre height above the floor (m)         */
    float extent[3];         /*  68 full box size along object axes x, y, z (m)   */
    int64_t first_seen_ns;   /*  80 sensor clock (ns), first seen: the frame stamps,
                                    CLOCK_REALTIME only with timebase: realtime or
                                    host-stamped drivers; replays keep the recording's
                                    stamps (synthetic scenes start at 0). Compare with
                                    the header's stamp_ns, not with your clock. */
    int64_t last_seen_ns;    /*  88 sensor clock of the latest observation        */
    uint32_t latent_dim;     /*  96 <= SOOC_TABLE_LATENT_MAX                      */
    uint32_t reserved0;      /* 100 zero                                          */
    uint8_t reserved[24];    /* 104 future fields (abi_minor++)                   */
    float latent[32];        /* 128 appearance latent z^what, 64-byte aligned     */
} sooc_table_record;

/* The 4096-byte header at offset 0. Fields above `instance_id` are written once
 * by the creator before `magic` (stored last, release). Atomics are updated
 * while readers run. The "batch block" (from latent_dim) is written only inside
 * a batch, so readers copy it under table_seq (sooc_table_get_info). */
typedef struct sooc_table_header {
    SOOC_TABLE_ATOMIC(uint64_t) magic;          /*   0 SOOC_TABLE_MAGIC, stored last            */
    uint16_t abi_major;               /*   8 SOOC_TABLE_ABI_MAJOR                     */
    uint16_t abi_minor;               /*  10 SOOC_TABLE_ABI_MINOR                     */
    uint32_t header_size;             /*  12 4096                                     */
    uint32_t record_size;             /*  16 256                                      */
    uint32_t capacity;                /*  20 number of record slots                   */
    uint64_t records_offset;          /*  24 4096 (page aligned)                      */
    uint64_t schema_hash;             /*  32 SOOC_TABLE_SCHEMA_HASH                   */
    char frame_id[32];                /*  40 NUL-terminated, e.g. "map"               */
    uint32_t latent_max;              /*  72 SOOC_TABLE_LATENT_MAX                    */
    uint32_t reserved_a;              /*  76 zero                                     */
    SOOC_TABLE_ATOMIC(uint64_t) instance_id;    /*  80 random per writer start (detects restarts) */
    SOOC_TABLE_ATOMIC(int64_t) writer_pid;      /*  88 pid of the current/last writer           */
    SOOC_TABLE_ATOMIC(uint64_t) hflags;         /*  96 SOOC_TABLE_HFLAG_*                       */
    SOOC_TABLE_ATOMIC(uint64_t) table_seq;      /* 104 table seqlock; epoch = table_seq / 2     */
    SOOC_TABLE_ATOMIC(int64_t) heartbeat_mono_ns; /* 112 CLOCK_MONOTONIC of the last heartbeat  */
    SOOC_TABLE_ATOMIC(uint64_t) high_water;     /* 120 slots [0, high_water) may be in use      */
    SOOC_TABLE_ATOMIC(uint64_t) n_objects;      /* 128 occupied, not-removed slots              */
    int64_t created_real_ns;          /* 136 CLOCK_REALTIME at creation               */
    /* store block (abi_minor >= 1): the map database's state, written outside
       batches under its own seqlock store_seq (odd while written) */
    SOOC_TABLE_ATOMIC(uint64_t) store_seq;      /* 144 seqlock of the store block               */
    uint32_t store_state;             /* 152 SOOC_TABLE_STORE_*                       */
    uint32_t store_fault;             /* 156 SOOC_TABLE_STORE_FAULT_* of the latest failure */
    uint64_t store_pending;           /* 160 objects to write or delete, not in the database yet */
    uint64_t store_pending_kf;        /* 168 keyframe rows not in the database yet     */
    int64_t store_committed_ns;       /* 176 sensor clock of the newest keyframe in the
                                             database (INT64_MIN: none yet)            */
    uint8_t reserved_c[72];           /* 184 zero                                     */
    /* batch block */
    uint32_t latent_dim;              /* 256 latent size the encoder produces         */
    uint32_t reserved_b;              /* 260 zero                                     */
    uint64_t latent_model_id;         /* 264 which encoder produced the latents       */
    int64_t stamp_ns;                 /* 272 sensor clock of the latest batch         */
    double T_src_map[16];             /* 280 pose of the map frame in the pose source's
                                             frame (row-major 4x4; identity if the
                                             source is already gravity-aligned)       */
    uint8_t reserved_d[3688];         /* 408 zero, up to 4096                         */
} sooc_table_header;

/* ABI stability: sizes, offsets, lock-free address-free 64-bit atomics, byte order. */
SOOC_TABLE_STATIC_ASSERT_(sizeof(sooc_table_record) == 256, "record must be 256 bytes");
SOOC_TABLE_STATIC_ASSERT_(sizeof(sooc_table_header) == 4096, "header must be 4096 bytes");
SOOC_TABLE_STATIC_ASSERT_(ATOMIC_LLONG_LOCK_FREE == 2, "64-bit atomics must be lock-free");
#ifdef __cplusplus
SOOC_TABLE_STATIC_ASSERT_(sizeof(std::atomic<uint64_t>) == 8 &&
                              SOOC_TABLE_ALIGNOF_(std::atomic<uint64_t>) == 8 &&
                              SOOC_TABLE_ALIGNOF_(uint64_t) == 8,
                          "atomic u64 must be a plain 8-byte word");
#else
SOOC_TABLE_STATIC_ASSERT_(sizeof(_Atomic(uint64_t)) == 8 && _Alignof(_Atomic(uint64_t)) == 8,
                          "atomic u64 must be a plain 8-byte word");
#endif
SOOC_TABLE_STATIC_ASSERT_(sizeof(float) == 4 && sizeof(double) == 8, "IEEE-754 float/double");
#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "sooc3d table ABI is little-endian"
#endif
#define SOOC_TABLE_REC_AT_(f, o) \
    SOOC_TABLE_STATIC_ASSERT_(offsetof(sooc_table_record, f) == (o), "record." #f)
#define SOOC_TABLE_HDR_AT_(f, o) \
    SOOC_TABLE_STATIC_ASSERT_(offsetof(sooc_table_header, f) == (o), "header." #f)
SOOC_TABLE_REC_AT_(seq, 0);
SOOC_TABLE_REC_AT_(object_id, 8);
SOOC_TABLE_REC_AT_(flags, 16);
SOOC_TABLE_REC_AT_(obs_count, 20);
SOOC_TABLE_REC_AT_(presence, 24);
SOOC_TABLE_REC_AT_(x, 28);
SOOC_TABLE_REC_AT_(z, 32);
SOOC_TABLE_REC_AT_(yaw, 36);
SOOC_TABLE_REC_AT_(cov_xzyaw, 40);
SOOC_TABLE_REC_AT_(y, 64);
SOOC_TABLE_REC_AT_(extent, 68);
SOOC_TABLE_REC_AT_(first_seen_ns, 80);
SOOC_TABLE_REC_AT_(last_seen_ns, 88);
SOOC_TABLE_REC_AT_(latent_dim, 96);
SOOC_TABLE_REC_AT_(reserved0, 100);
SOOC_TABLE_REC_AT_(reserved, 104);
SOOC_TABLE_REC_AT_(latent, 128);
SOOC_TABLE_HDR_AT_(magic, 0);
SOOC_TABLE_HDR_AT_(abi_major, 8);
SOOC_TABLE_HDR_AT_(abi_minor, 10);
SOOC_TABLE_HDR_AT_(header_size, 12);
SOOC_TABLE_HDR_AT_(record_size, 16);
SOOC_TABLE_HDR_AT_(capacity, 20);
SOOC_TABLE_HDR_AT_(records_offset, 24);
SOOC_TABLE_HDR_AT_(schema_hash, 32);
SOOC_TABLE_HDR_AT_(frame_id, 40);
SOOC_TABLE_HDR_AT_(latent_max, 72);
SOOC_TABLE_HDR_AT_(instance_id, 80);
SOOC_TABLE_HDR_AT_(writer_pid, 88);
SOOC_TABLE_HDR_AT_(hflags, 96);
SOOC_TABLE_HDR_AT_(table_seq, 104);
SOOC_TABLE_HDR_AT_(heartbeat_mono_ns, 112);
SOOC_TABLE_HDR_AT_(high_water, 120);
SOOC_TABLE_HDR_AT_(n_objects, 128);
SOOC_TABLE_HDR_AT_(created_real_ns, 136);
SOOC_TABLE_HDR_AT_(store_seq, 144);
SOOC_TABLE_HDR_AT_(store_state, 152);
SOOC_TABLE_HDR_AT_(store_fault, 156);
SOOC_TABLE_HDR_AT_(store_pending, 160);
SOOC_TABLE_HDR_AT_(store_pending_kf, 168);
SOOC_TABLE_HDR_AT_(store_committed_ns, 176);
SOOC_TABLE_HDR_AT_(reserved_c, 184);
SOOC_TABLE_HDR_AT_(latent_dim, 256);
SOOC_TABLE_HDR_AT_(latent_model_id, 264);
SOOC_TABLE_HDR_AT_(stamp_ns, 272);
SOOC_TABLE_HDR_AT_(T_src_map, 280);
#undef SOOC_TABLE_REC_AT_
#undef SOOC_TABLE_HDR_AT_

/* ------------------------------------------------------------ utilities */

/* Message for a return code, e.g. "table busy (seqlock retries exhausted)". */
SOOC_TABLE_API const char *sooc_table_strerror(int code);

/* FNV-1a 64 of SOOC_TABLE_SCHEMA_STRING (equals SOOC_TABLE_SCHEMA_HASH). */
SOOC_TABLE_API uint64_t sooc_table_schema_hash(void);

/* 0 if `name` is a valid table name: 1..SOOC_TABLE_NAME_MAX characters from
 * [A-Za-z0-9_.-], not starting with '.'; SOOC_TABLE_EINVAL otherwise. */
SOOC_TABLE_API int sooc_table_validate_name(const char *name);

/* Writes "/sooc3d.v1.<name>" into out[cap]; 0 or EINVAL / ERANGE. */
SOOC_TABLE_API int sooc_table_shm_name(const char *name, char *out, unsigned cap);

/* Convert a record's floor pose to a ROS REP-103 frame (x forward, y left,
 * z up; map -z is "forward"). The object's box axes convert the same way, so
 * yaw is unchanged and the ROS box size is (extent[2], extent[0], extent[1]).
 * cov_ros (optional) gets the upper triangle of cov(x_ros, y_ros, yaw). */
static inline void sooc_table_pose_rep103(const sooc_table_record *r, float *x_ros, float *y_ros,
                                          float *z_ros, float *yaw_ros, float cov_ros[6]) {
    *x_ros = -r->z;
    *y_ros = -r->x;
    *z_ros = r->y;
    *yaw_ros = r->yaw;
    if (cov_ros) {
        const float *c = r->cov_xzyaw; /* xx xz xyaw zz zyaw yawyaw */
        cov_ros[0] = c[3];             /* var(x_ros) = var(z)       */
        cov_ros[1] = c[1];             /* cov(x_ros, y_ros) = cov(z, x) */
        cov_ros[2] = -c[4];            /* cov(x_ros, yaw) = -cov(z, yaw) */
        cov_ros[3] = c[0];             /* var(y_ros) = var(x)       */
        cov_ros[4] = -c[2];            /* cov(y_ros, yaw) = -cov(x, yaw) */
        cov_ros[5] = c[5];
    }
}

/* A record's pose in the pose source's frame (the robot base, the
 * recording's world, the odometry's first camera: whatever gave the node its
 * camera poses), through the header's T_src_map (sooc_table_info): the box
 * centre p_src = T_src_map (x, y, z), the box axes R_src = R_src_map R_y(yaw)
 * (columns: the box's x, y, z axes in the source frame, row-major). cov_src
 * (optional, row-major 3x3) gets the covariance of the centre in the source
 * frame: R_src_map C R_src_map^T with C the map-frame covariance of (x, y, z)
 * from cov_xzyaw (the height's variance 0). */
SOOC_TABLE_API void sooc_table_pose_source(const double T_src_map[16], const sooc_table_record *r, double p_src[3],
                                          double R_src[9], double cov_src[9]);

/* Which object is at a pixel: the ray through pixel (u, v) (pixel centres at
 * integer + 0.5; pinhole fx fy cx cy, OpenCV camera axes) of a camera at
 * T_map_cam (camera to map frame, row-major 4x4) against the boxes of recs[0..n)
 * (valid, not removed: box centre (x, y, z), axes R_y(yaw), size extent).
 * Returns the index of the nearest box the ray enters (its distance along
 * the ray, metres, in *t if non-NULL), or -1 when it hits none. A camera in
 * the pose source's frame: T_map_cam = inverse(T_src_map) T_src_cam. */
SOOC_TABLE_API int sooc_table_pick(const sooc_table_record *recs, uint32_t n, const double T_map_cam[16], double fx,
                                   double fy, double cx, double cy, double u, double v, double *t);

/* --------------------------------------------------------------- reader */

typedef struct sooc_table_reader sooc_table_reader;

/* Header fields a planner may want, copied consistently under table_seq. */
typedef struct sooc_table_info {
    uint32_t capacity, latent_dim, abi_minor;
    uint64_t instance_id, high_water, n_objects, epoch, hflags, latent_model_id;
    int64_t writer_pid, heartbeat_mono_ns, created_real_ns, stamp_ns;
    double T_src_map[16];
    char frame_id[32];
} sooc_table_info;

/* The map database's state (the header's store block). */
typedef struct sooc_table_store {
    uint32_t state;           /* SOOC_TABLE_STORE_*                                   */
    uint32_t fault;           /* SOOC_TABLE_STORE_FAULT_* of the latest failure        */
    uint64_t pending;         /* objects to write or delete, not in the database yet   */
    uint64_t pending_kf;      /* keyframe rows not in the database yet                 */
    int64_t committed_ns;     /* sensor clock of the newest keyframe in the database   */
} sooc_table_store;

/* Writer liveness as seen by a reader. */
typedef struct sooc_table_liveness {
    int lock_held;            /* 1: a process holds the writer flock             */
    int exited;               /* 1: WRITER_EXITED set (clean close)              */
    int64_t heartbeat_age_ns; /* now - heartbeat_mono_ns (CLOCK_MONOTONIC)        */
    uint64_t instance_id;
    int64_t writer_pid;
} sooc_table_liveness;

/* Open table `name` read-only (PROT_READ mapping). Checks magic, ABI major,
 * sizes, capacity against the object size and the schema hash.
 * Errors: EINVAL (name), ENOENT (no such table), ENOTREADY (creator still
 * filling the header: retry), EVERSION, ESYS. On error *out is NULL. */
SOOC_TABLE_API int sooc_table_open_reader(const char *name, sooc_table_reader **out);
/* Unmap and close; NULL is fine. */
SOOC_TABLE_API void sooc_table_close_reader(sooc_table_reader *r);

/* Consistent copy of the whole table: every occupied slot (object_id != 0,
 * including REMOVED ones) in slot order, copied between two equal even reads
 * of table_seq. Up to `cap` records go to out; *n gets the count (if it
 * exceeds cap, ERANGE is returned and out holds the first cap). *epoch (may be
 * NULL) gets table_seq / 2. EBUSY after SOOC_TABLE_READ_RETRIES attempts.
 * Costs one pass over [0, high_water). */
SOOC_TABLE_API int sooc_table_snapshot(sooc_table_reader *r, sooc_table_record *out, uint32_t cap,
                                       uint32_t *n, uint64_t *epoch);
/* Consistent copy of slot `slot` under its own seqlock (no table-level
 * consistency). An empty slot gives object_id == 0. EINVAL if slot >= capacity. */
SOOC_TABLE_API int sooc_table_read_record(sooc_table_reader *r, uint32_t slot,
                                          sooc_table_record *rec);
/* Find `object_id` among [0, high_water) with per-record reads; ENOENT if absent. */
SOOC_TABLE_API int sooc_table_find(sooc_table_reader *r, uint64_t object_id,
                                   sooc_table_record *rec);
/* Header fields (consistent copy under table_seq; EBUSY if it stays odd). */
SOOC_TABLE_API int sooc_table_get_info(sooc_table_reader *r, sooc_table_info *info);
/* The store block, copied under store_seq (EBUSY if it stays odd). A table
 * of abi_minor 0 gives state SOOC_TABLE_STORE_NONE and zeros. */
SOOC_TABLE_API int sooc_table_get_store(sooc_table_reader *r, sooc_table_store *out);
/* Current epoch (table_seq / 2, even if a batch is in progress) and capacity. */
SOOC_TABLE_API uint64_t sooc_table_epoch(const sooc_table_reader *r);
SOOC_TABLE_API uint32_t sooc_table_capacity(const sooc_table_reader *r);

/* 1 if the writer is alive: it holds the flock (tested with
 * flock(LOCK_SH|LOCK_NB)), WRITER_EXITED is clear and the heartbeat is younger
 * than SOOC_TABLE_HEARTBEAT_STALE_NS. 0 if dead, exited or hung. <0 on error.
 * `live` (may be NULL) gets the details. Cost: two syscalls. */
SOOC_TABLE_API int sooc_table_writer_alive(sooc_table_reader *r, sooc_table_liveness *live);

/* --------------------------------------------------------------- writer */

typedef struct sooc_table_writer sooc_table_writer;

/* Create or take over table `name` with room for `capacity` records.
 * mode: permission bits (0 = SOOC_TABLE_DEFAULT_MODE 0640; set with fchmod, so
 * the umask does not matter). frame_id: e.g. "map" (NULL = "map").
 * - New table: O_CREAT, fchmod, ftruncate, header filled, magic stored last.
 * - Existing table with the same capacity and frame_id (a restart): records
 *   left odd by a dead writer are cleared, table_seq is made even, the other
 *   records are kept (their ids re-registered), instance_id is renewed.
 * - Existing but incompatible (other capacity/ABI/frame): unlinked and created
 *   anew (old readers then see the writer as dead and must reopen).
 * The writer holds flock(LOCK_EX) until close. ELOCKED if another writer is
 * alive. The caller should run sooc_table_heartbeat() at >= 10 Hz, or start
 * the helper thread with sooc_table_start_heartbeat(). */
SOOC_TABLE_API int sooc_table_create_writer(const char *name, uint32_t capacity, uint32_t mode,
                                            const char *frame_id, sooc_table_writer **out);
/* Stop the heartbeat thread, set WRITER_EXITED, release the lock, unmap.
 * unlink != 0 also removes the shm object. A batch left open is published
 * first. NULL is fine. Returns 0 or ESYS (unlink failed). */
SOOC_TABLE_API int sooc_table_close_writer(sooc_table_writer *w, int unlink);

/* A batch (e.g. one keyframe) makes table_seq odd; upserts/removes inside it;
 * end_batch makes it even again (epoch + 1). Only one thread may call these. */
SOOC_TABLE_API int sooc_table_begin_batch(sooc_table_writer *w);
/* Insert or overwrite the record of rec->object_id (!= 0). rec->seq is ignored;
 * latent_dim must be <= 32. Overwrites a REMOVED record's flags too. EFULL if
 * no slot is free; ESTATE outside a batch. */
SOOC_TABLE_API int sooc_table_upsert(sooc_table_writer *w, const sooc_table_record *rec);
/* Mark object_id REMOVED (clears VALID). Its slot is reused only after the
 * REMOVED record has been published for at least one whole epoch.
 * ENOENT if the id is not in the table. */
SOOC_TABLE_API int sooc_table_remove(sooc_table_writer *w, uint64_t object_id);
/* Remove every object (same rules as sooc_table_remove). */
SOOC_TABLE_API int sooc_table_clear(sooc_table_writer *w);
/* Batch-block header fields (inside a batch). NULL T keeps the old value. */
SOOC_TABLE_API int sooc_table_set_meta(sooc_table_writer *w, uint32_t latent_dim,
                                       uint64_t latent_model_id, int64_t stamp_ns,
                                       const double T_src_map[16]);
SOOC_TABLE_API int sooc_table_end_batch(sooc_table_writer *w);

/* Publish the map database's state (the store block; any time, inside a
 * batch or not; only the batch thread may call it). */
SOOC_TABLE_API int sooc_table_set_store(sooc_table_writer *w, const sooc_table_store *st);

/* Store CLOCK_MONOTONIC now into heartbeat_mono_ns. Thread-safe with respect
 * to the batch calls (touches only that atomic). */
SOOC_TABLE_API void sooc_table_heartbeat(sooc_table_writer *w);
/* Start a thread calling sooc_table_heartbeat() at `hz` (>= 1; 0 = 20 Hz).
 * Stopped by close_writer or sooc_table_stop_heartbeat. */
SOOC_TABLE_API int sooc_table_start_heartbeat(sooc_table_writer *w, double hz);
SOOC_TABLE_API void sooc_table_stop_heartbeat(sooc_table_writer *w);

/* Writer introspection. */
SOOC_TABLE_API uint64_t sooc_table_writer_epoch(const sooc_table_writer *w);
SOOC_TABLE_API uint64_t sooc_table_writer_instance(const sooc_table_writer *w);
SOOC_TABLE_API uint32_t sooc_table_writer_count(const sooc_table_writer *w); /* live objects */

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_TABLE_H */
