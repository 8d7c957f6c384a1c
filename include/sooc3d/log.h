/*
 * sooc3d logs: robot log files. Reading and writing ROS 1 bags and MCAP
 * files, the ROS message codecs, log files as frame sequences, and the
 * Foxglove JSON messages of the map.
 *
 * Sections: ROS bags and MCAP: reading, writing, ROS messages (log);
 * Foxglove messages of the map (foxglove).
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
#ifndef SOOC3D_LOG_H
#define SOOC3D_LOG_H

#include <stddef.h>
#include <stdint.h>

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ==== ROS bags and MCAP: reading, writing, ROS messages (log) ============ */

/*
 * sooc3d robot logs: ROS 1 bags (format 2.0) and MCAP files read without ROS,
 * the messages a camera rig records decoded from ROS 1 serialisation and ROS 2
 * CDR, a minimal MCAP writer, and RGB-D frames assembled from a log
 * (docs/logs.md).
 *
 * Ownership: sooc_logfile_open returns a reader that the caller closes with
 * sooc_logfile_close. Channel descriptions and their strings belong to the
 * reader and live until it is closed. The bytes of a message read with
 * sooc_logfile_read belong to the reader and stay valid until the next
 * sooc_logfile_read on the same reader (or its close). Decoded messages
 * (sooc_ros_image, ...) point into the bytes they were decoded from; their
 * fixed-size strings are copies. Encoders append to a sooc_ros_buf the
 * caller frees with sooc_ros_buf_free. sooc_logseq owns its reader and its
 * buffers; frames are filled as sooc_seq_read fills them (frame.h).
 *
 * Threading: one thread at a time per sooc_logfile, sooc_logseq or
 * sooc_mcap_writer; distinct objects are independent. The decoders and
 * encoders keep no state.
 *
 * Errors: every fallible function returns a sooc_status and leaves a message
 * (sooc_errmsg) that names the file and the byte offset of the bad record
 * ("run.bag: offset 4523: chunk of 9000 bytes runs past the end of the file
 * (5280 bytes): the file is truncated") or the topic ("run.mcap: /camera/depth:
 * unknown image encoding 'yuv422'"). SOOC_EFORMAT: malformed, truncated or
 * corrupt data (bad CRC); SOOC_EUNSUPPORTED: a compression, encoding or
 * message type this code does not read; SOOC_ENOTFOUND: a missing file or
 * topic; SOOC_EVERSION: a ROS bag older than 2.0. Nothing is printed; the
 * library never exits.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */

/* ------------------------------------------------------------ containers */

typedef enum sooc_logfile_kind {
    SOOC_LOGFILE_NONE = 0,
    SOOC_LOGFILE_ROSBAG = 1,   /* "#ROSBAG V2.0\n"                      */
    SOOC_LOGFILE_MCAP = 2      /* 0x89 "MCAP0\r\n"                       */
} sooc_logfile_kind;

/* How the bytes of a channel's messages are serialised. */
typedef enum sooc_msg_encoding {
    SOOC_MSGENC_OTHER = 0,     /* json, protobuf, ...: not decoded here  */
    SOOC_MSGENC_ROS1 = 1,      /* ROS 1 serialisation (bags, MCAP "ros1") */
    SOOC_MSGENC_CDR = 2        /* ROS 2 CDR with its 4-byte encapsulation header (MCAP "cdr") */
} sooc_msg_encoding;

/* The kind of log at path by its first bytes; NONE when it is neither (or
 * cannot be read, or is a directory). Sets no error. */
sooc_logfile_kind sooc_logfile_detect(const char *path);
const char *sooc_logfile_kind_name(sooc_logfile_kind k);   /* "rosbag", "mcap", "none" */

typedef struct sooc_logfile sooc_logfile;

typedef struct sooc_logfile_channel {
    const char *topic;
    const char *type;          /* as recorded: "sensor_msgs/Image" or "sensor_msgs/msg/Image" */
    const char *encoding;      /* "ros1", "cdr", "json", ...                                   */
    sooc_msg_encoding enc;
    const char *definition;    /* message definition / schema text ("" when absent)           */
    int64_t count;             /* messages on the channel                                      */
    int64_t t_first_ns, t_last_ns; /* log times of its first and last message (0 when none)    */
} sooc_logfile_channel;

typedef struct sooc_logfile_info {
    sooc_logfile_kind kind;
    int64_t file_size, n_messages, n_chunks;
    int n_channels;
    int64_t t_first_ns, t_last_ns; /* log times (0 when there are no messages)                */
    char compression[32];      /* "none", "lz4", "bz2", "zstd", or a '+'-joined mix           */
    int indexed;               /* 1: messages located from the file's index (bag index records,
                                  MCAP summary and message indexes); 0: found by a scan        */
} sooc_logfile_info;

/* Open a ROS 1 bag (format 2.0) or an MCAP file and index its messages (log
 * time order; ties keep file order). Chunks are located from the file's
 * index when it has one and are only decompressed at open when no index
 * lists their messages. Fails (no reader) on an empty file, a wrong magic, a
 * truncated file, an unknown chunk compression, a bad MCAP summary CRC. */
sooc_status sooc_logfile_open(sooc_logfile **out, const char *path);
void sooc_logfile_close(sooc_logfile *lf);   /* NULL-safe */

const char *sooc_logfile_path(const sooc_logfile *lf);
void sooc_logfile_get_info(const sooc_logfile *lf, sooc_logfile_info *out);
int sooc_logfile_channel_count(const sooc_logfile *lf);
/* Channel i (0 <= i < count), NULL when out of range. */
const sooc_logfile_channel *sooc_logfile_channel_get(const sooc_logfile *lf, int i);
/* The channel with this topic, -1 when there is none. */
int sooc_logfile_find(const sooc_logfile *lf, const char *topic);
/* Positions (in sooc_logfile_read's numbering) of channel ch's messages, in
 * time order; *n gets their count. NULL (n = 0) when out of range. */
const int64_t *sooc_logfile_channel_msgs(const sooc_logfile *lf, int ch, int64_t *n);

int64_t sooc_logfile_count(const sooc_logfile *lf);   /* messages */
/* Message k's channel and log time, without reading it. */
sooc_status sooc_logfile_entry(const sooc_logfile *lf, int64_t k, int *channel, int64_t *t_ns);

typedef struct sooc_logfile_msg {
    int channel;
    int64_t t_ns;              /* log time (bag: record time; MCAP: log_time)     */
    const uint8_t *data;       /* serialised message, valid until the next read   */
    size_t size;
    uint64_t offset;           /* file offset of the record or of its chunk       */
} sooc_logfile_msg;

/* Read message k (0 <= k < count). Decompresses its chunk (the last two are
 * kept) and checks the chunk's CRC when the file stores one. */
sooc_status sooc_logfile_read(sooc_logfile *lf, int64_t k, sooc_logfile_msg *m);
/* Decompress every chunk and check every CRC the file stores (MCAP chunk,
 * data-section and summary CRCs); the first failure is returned. */
sooc_status sooc_logfile_verify(sooc_logfile *lf);

/* -------------------------------------------------------------- messages */

/* "sensor_msgs/msg/Image" -> "sensor_msgs/Image" (ROS 2 names to ROS 1 ones),
 * written to buf; returns buf. */
const char *sooc_ros_type_base(const char *type, char *buf, size_t cap);
/* Channel encoding from the MCAP/bag name: "ros1" -> ROS1, "cdr" -> CDR. */
sooc_msg_encoding sooc_msg_encoding_parse(const char *name);

typedef struct sooc_ros_header {
    int64_t stamp_ns;          /* header.stamp                                    */
    char frame_id[128];        /* truncated copies are an error, not a cut name   */
} sooc_ros_header;

/* sensor_msgs/Image */
typedef struct sooc_ros_image {
    sooc_ros_header header;
    int width, height;
    size_t step;               /* bytes per row                                   */
    char encoding[32];         /* "rgb8", "16UC1", ...                            */
    int bigendian;
    const uint8_t *data;
    size_t size;
} sooc_ros_image;

/* sensor_msgs/CompressedImage */
typedef struct sooc_ros_cimage {
    sooc_ros_header header;
    char format[96];           /* "jpeg", "png", "rgb8; jpeg compressed bgr8", "16UC1; compressedDepth" */
    const uint8_t *data;
    size_t size;
} sooc_ros_cimage;

/* sensor_msgs/CameraInfo */
typedef struct sooc_ros_caminfo {
    sooc_ros_header header;
    int width, height;
    char distortion_model[32];
    double D[8];
    int nD;                    /* coefficients in the message (D holds the first 8) */
    double K[9], R[9], P[12];
} sooc_ros_caminfo;

/* A transform or pose: tf2_msgs/TFMessage entries, geometry_msgs/
 * TransformStamped, Transform, PoseStamped, nav_msgs/Odometry. p_parent =
 * R(q) p_child + t, i.e. the pose of child in header.frame_id. */
typedef struct sooc_ros_transform {
    sooc_ros_header header;    /* parent frame and stamp                          */
    char child[128];           /* child frame ("" for PoseStamped and Transform)  */
    double t[3], q[4];         /* metres; quaternion x y z w                      */
} sooc_ros_transform;

/* Decoders. enc is the channel's encoding; d/n the message bytes. They
 * check every length against n (SOOC_EFORMAT "truncated <type>: ..." naming
 * the byte) and fail with SOOC_EUNSUPPORTED for SOOC_MSGENC_OTHER. */
sooc_status sooc_ros_decode_image(const uint8_t *d, size_t n, sooc_msg_encoding enc, sooc_ros_image *out);
sooc_status sooc_ros_decode_cimage(const uint8_t *d, size_t n, sooc_msg_encoding enc, sooc_ros_cimage *out);
sooc_status sooc_ros_decode_caminfo(const uint8_t *d, size_t n, sooc_msg_encoding enc, sooc_ros_caminfo *out);
/* tf2_msgs/TFMessage or tf/tfMessage: the first cap transforms into out;
 * *n_out = the number in the message (may exceed cap). */
sooc_status sooc_ros_decode_tf(const uint8_t *d, size_t n, sooc_msg_encoding enc, sooc_ros_transform *out,
                               int cap, int *n_out);
/* One pose by type name (ROS 1 or ROS 2 spelling): geometry_msgs/
 * TransformStamped, Transform, PoseStamped, Pose, nav_msgs/Odometry. */
sooc_status sooc_ros_decode_pose(const char *type, const uint8_t *d, size_t n, sooc_msg_encoding enc,
                                 sooc_ros_transform *out);
/* std_msgs/Float32, Float64 (the RealSense "Depth Units" option). */
sooc_status sooc_ros_decode_float(const char *type, const uint8_t *d, size_t n, sooc_msg_encoding enc,
                                  double *out);

/* Encoders (tests, writers): append one message to b. */
typedef struct sooc_ros_buf {
    uint8_t *data;
    size_t size, cap;
    int oom;                   /* an allocation failed: the buffer is incomplete */
} sooc_ros_buf;
void sooc_ros_buf_free(sooc_ros_buf *b);
sooc_status sooc_ros_encode_image(sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_image *m);
sooc_status sooc_ros_encode_cimage(sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_cimage *m);
sooc_status sooc_ros_encode_caminfo(sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_caminfo *m);
sooc_status sooc_ros_encode_tf(sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_transform *tf, int n);
/* The message definition of an encoded type (bag connection records, MCAP
 * "ros1msg" schemas for ROS1, "ros2msg" for CDR), "" for other types. */
const char *sooc_ros_definition(const char *type, sooc_msg_encoding enc);

/* ---------------------------------------------------------- MCAP writer */

typedef struct sooc_mcap_writer sooc_mcap_writer;

typedef struct sooc_mcap_writer_params {
    const char *profile;       /* header profile: "ros2", "ros1", "" (default "")         */
    const char *compression;   /* "" (none), "zstd", "lz4" (default "zstd")              */
    size_t chunk_size;         /* bytes of records per chunk before it is closed (1 MiB)  */
    int summary;               /* 1 (default): summary, message indexes and summary offsets;
                                  0: a streamed file (Data End and Footer only)           */
} sooc_mcap_writer_params;
void sooc_mcap_writer_params_default(sooc_mcap_writer_params *p);

/* Write to a temporary file next to path; sooc_mcap_writer_close renames it
 * over path (an interrupted writer leaves path untouched). */
sooc_status sooc_mcap_writer_open(sooc_mcap_writer **out, const char *path, const sooc_mcap_writer_params *p);
/* Register a schema / channel; ids are returned in *id (schemas from 1,
 * channels from 0). */
sooc_status sooc_mcap_writer_schema(sooc_mcap_writer *w, const char *name, const char *encoding,
                                    const void *data, size_t n, int *id);
sooc_status sooc_mcap_writer_channel(sooc_mcap_writer *w, int schema_id, const char *topic,
                                     const char *message_encoding, int *id);
sooc_status sooc_mcap_writer_message(sooc_mcap_writer *w, int channel, int64_t log_time_ns,
                                     int64_t publish_time_ns, const void *data, size_t n);
/* Flush, write the summary and footer, and commit. Frees w either way. */
sooc_status sooc_mcap_writer_close(sooc_mcap_writer *w);
void sooc_mcap_writer_abort(sooc_mcap_writer *w);   /* NULL-safe; leaves path untouched */

/* ------------------------------------------------------ frames from a log */

typedef struct sooc_logseq sooc_logseq;

typedef struct sooc_logseq_params {
    const char *color_topic;   /* NULL/"" = the one colour image topic (an error naming the
                                  candidates when there are several)                       */
    const char *depth_topic;   /* NULL/"" = the one depth image topic                      */
    const char *pose_parent;   /* pose from TF: the world frame; NULL/"" = no pose; "auto" =
                                  the root of the camera frame's TF tree (no pose when the
                                  camera frame is not in the TF)                          */
    const char *pose_child;    /* the camera frame; NULL/"" = the colour image's frame_id  */
    double pair_tol_s;         /* colour-depth pairing by log time (default 0.02 s)        */
    double pose_tol_s;         /* TF lookup: the nearest transform on each edge may be
                                  this far from the stamp when it cannot interpolate (0.05) */
    double depth_scale;        /* > 0: metres per unit of 16-bit depth; 0 = the log's
                                  "Depth Units" option, else 0.001 (REP 118 millimetres)   */
    double max_depth;          /* depths beyond this are invalid (0 = no limit)            */
    int registration;          /* -1 auto (register when the depth camera differs from the
                                  colour camera), 0 never, 1 always                         */
} sooc_logseq_params;
void sooc_logseq_params_default(sooc_logseq_params *p);

/* One image stream of the log as the frames would use it. */
typedef struct sooc_logseq_stream {
    const char *topic, *type;  /* borrowed from the reader                                */
    char encoding[96];         /* image encoding, or the CompressedImage format           */
    int width, height;
    int64_t count;
    double rate_hz;            /* messages per second over the stream's span (0: one)    */
    int has_info;              /* a CameraInfo of the same size was found                 */
    const char *info_topic;
    sooc_intrinsics K;         /* from the CameraInfo (K; D when plumb_bob/rational)     */
    char frame_id[128];
} sooc_logseq_stream;

typedef struct sooc_logseq_desc {
    sooc_logseq_stream color, depth;
    double depth_scale;        /* metres per 16-bit unit in use (0 for 32FC1 depth)       */
    const char *depth_scale_source; /* "launch", "Depth Units option <topic>", "REP 118 default", "32FC1 metres" */
    int registered;            /* 1: depth is reprojected into the colour camera          */
    double T_color_depth[16];  /* p_color = T p_depth (identity when registered as given) */
    const char *extrinsics_source; /* "tf <parent> -> <child>", "<topic>", "identity", "n/a" */
    int has_pose;
    char pose_parent[128], pose_child[128];
    int64_t tf_transforms;     /* transforms read from /tf and /tf_static                 */
    int64_t n_frames, n_unpaired; /* colour images paired with depth / without a partner  */
    double nearest_unpaired_s; /* smallest colour-depth gap of an unpaired colour image   */
    int64_t n_unposed;         /* frames without a pose at their log time (pose source set) */
} sooc_logseq_desc;

/* Open a log and pair its colour and depth images (from the index: no image
 * is decoded to pair them). Fails with SOOC_ENOTFOUND naming a topic that
 * does not exist, SOOC_EINVAL listing the candidates when a kind has several
 * topics and none is named, SOOC_EFORMAT when no image can be read. A log
 * with no colour-depth pair opens with count 0. */
sooc_status sooc_logseq_open(sooc_logseq **out, const char *path, const sooc_logseq_params *p);
void sooc_logseq_close(sooc_logseq *s);   /* NULL-safe */
int64_t sooc_logseq_count(const sooc_logseq *s);
/* Frame i's stamp (the colour image's header stamp, else its log time),
 * known at open from the index: INT64_MIN when out of range. */
int64_t sooc_logseq_frame_time(const sooc_logseq *s, int64_t i);
/* Frame i: rgb at the colour image's size, depth (registered into the
 * colour camera when it is not), valid, K of the colour camera, t_ns, index
 * = i, has_pose/T_wc from TF. Buffers of f are reused when the size matches. */
sooc_status sooc_logseq_read(sooc_logseq *s, int64_t i, sooc_frame *f);
const sooc_logseq_desc *sooc_logseq_describe(const sooc_logseq *s);

/* Open path as a sequence (frame.h) whatever it is: a ROS bag or MCAP file
 * (detected by content) through sooc_logseq, anything else through
 * sooc_seq_open. For a log, sp gives calib_path (its K replaces the colour
 * CameraInfo's, and is needed when the log has none), depth_scale (over
 * lp's), max_depth, and max_dt (the pairing tolerance when lp is NULL);
 * sp->format must be AUTO. lp NULL: the defaults with pose_parent "auto".
 * A log in which no colour image pairs with a depth image fails with
 * SOOC_EFORMAT naming the nearest gap. */
sooc_status sooc_log_seq_open(sooc_seq **out, const char *path, const sooc_seq_open_params *sp,
                              const sooc_logseq_params *lp);

/* ==== Foxglove messages of the map (foxglove) ============================ */

/* Foxglove messages of the map (docs/logs.md "Foxglove"): the JSON schemas
 * of foxglove.SceneUpdate and foxglove.FrameTransform, and the JSON of one
 * map object as a SceneEntity (a cube of its box, its id as a text label, its
 * presence and covariance as metadata) and of one transform. Shared by
 * `sooc3d map export --mcap` and the node's `record: {mcap: FILE}`.
 * Appends to a sooc_ros_buf (log.h); on allocation failure b->oom is set. */

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
#endif /* SOOC3D_LOG_H */
