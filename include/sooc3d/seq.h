/*
 * sooc3d RGB-D sequence readers and the synthetic-layout writer
 * (docs/formats.md §Sequences).
 *
 * Formats (forced, or detected: rgb.txt -> TUM, traj.txt -> Replica,
 * pose.txt -> slambook2, cam.info.txt -> APC, then the first of
 * frame-NNNNNN.color.* -> 7-Scenes / label-fusion and NNNNNN-color.png ->
 * YCB-Video in the directory):
 *  - TUM / sooc3d synthetic: rgb.txt, depth.txt, groundtruth.txt
 *    (`t tx ty tz qx qy qz qw`, camera-to-world), rgb/, depth/ (16-bit PNG),
 *    calib.yaml (depth_scale); optional instance/ (16-bit ids) and
 *    scene.yaml (query views). Streams are associated by nearest timestamp
 *    within max_dt; rgb frames without a depth match are dropped, frames
 *    without a pose match get has_pose = 0.
 *  - 7-Scenes / label-fusion: frame-NNNNNN.{color.jpg | color.png, depth.png,
 *    pose.txt}, camera-intrinsics.color.txt or camera-intrinsics.txt (3x3),
 *    or calib.yaml. The directory is scanned for frame-NNNNNN.color.*: the
 *    numbers may start anywhere and have gaps (trimmed or subsampled
 *    recordings); frames are read in numeric order and sooc_frame.index is
 *    the file's number. Optional gravity-direction.txt (sooc_seq_gravity).
 *  - slambook2: pose.txt (`tx ty tz qx qy qz qw` per line, line i = frame
 *    i+1), color/N.png, depth/N.{pgm,png}; intrinsics and depth_scale must
 *    come from p->calib_path or <dir>/calib.yaml.
 *  - Replica (NICE-SLAM): traj.txt (16 floats per line, row-major c2w),
 *    results/frame%06d.jpg (or .png), results/depth%06d.png.
 *  slambook2 and Replica name frame i after line i of their pose list; a
 *  line whose colour and depth files are both absent is skipped (a trimmed
 *  copy), one with only one of them is an error.
 *  - YCB-Video as shipped (PoseCNN, DenseFusion, BOP YCB-V): NNNNNN-color.png,
 *    NNNNNN-depth.png (metres = value / factor_depth), NNNNNN-label.png
 *    (8-bit class index = instance id, ground truth; optional) and
 *    NNNNNN-meta.mat (MATLAB v5, read with libmatio: intrinsic_matrix,
 *    factor_depth, rotation_translation_matrix = world-to-camera 3x4; T_wc is
 *    its inverse); a calibration YAML, when given, overrides its intrinsics
 *    and depth scale.
 *  - APC (apc-vision-toolbox): cam.info.txt (colour and depth intrinsics,
 *    depth-to-colour, bin-to-world, then one camera-to-world 4x4 per frame,
 *    which lists the frames), frame-NNNNNN.color.png, frame-NNNNNN.depth.png
 *    (aligned to colour; the 16 bits rotated right by 3, then 1e-4 m), and
 *    optional masks/frame-NNNNNN.<object>.mask.png (16-bit confidence) with
 *    masks/<object>.thresh.txt: the instance label of a pixel is the object
 *    whose confidence passes its threshold, the highest when several do;
 *    object k of the "# Objects:" line has id k + 1 (sooc_seq_label_name).
 *    These labels are predictions (sooc_seq_labels_predicted).
 *
 * Colour may be PNG or JPEG whatever the extension (read by content).
 * Depth: metres = (raw >> depth_shift) * depth_scale (APC: a right rotation
 * of the 16 bits instead of the shift); raw 0 and raw ==
 * depth_invalid (before the shift) are invalid. Each of the three comes from
 * the open parameters, else the calibration YAML, else the format's default
 * (sooc_seq_formats(): 7-Scenes mm with 65535 invalid, label-fusion
 * (raw >> 3) * 1e-4 m, Replica 1/6553.5 m), else it is an error (scale) or
 * 0 / 65535 (shift / invalid).
 *
 * Every reader validates at open: missing files, unparsable numbers,
 * non-monotonic timestamps, non-orthonormal rotations; and at read: image
 * sizes against the calibration and each other, depth bit depth (must be
 * 16-bit). Messages name the file and the line, e.g.
 * "seq/groundtruth.txt:7: rotation is not orthonormal (error 0.02)".
 *
 * A camera with fy < 0 (ICL-NUIM) is converted to fy > 0 by mirroring the
 * world y axis: T_wc' = S T_wc S with S = diag(1, -1, 1, 1), cy unchanged
 * (the image is not flipped).
 *
 * Thread safety: a sooc_seq may be used by one thread at a time; distinct
 * sequences are independent.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_SEQ_H
#define SOOC3D_SEQ_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/calib.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sooc_seq_format {
    SOOC_SEQ_AUTO = 0,
    SOOC_SEQ_TUM,        /* TUM RGB-D and the sooc3d synthetic layout */
    SOOC_SEQ_7SCENES,    /* frame-%06d.* (7-Scenes)                  */
    SOOC_SEQ_SLAMBOOK,   /* pose.txt + color/ + depth/               */
    SOOC_SEQ_REPLICA,    /* NICE-SLAM Replica traj.txt + results/    */
    SOOC_SEQ_LABELFUSION,/* the 7-Scenes layout, label-fusion depth  */
    SOOC_SEQ_YCB,        /* YCB-Video: %06d-{color,depth,label}.png, -meta.mat */
    SOOC_SEQ_APC,        /* APC: cam.info.txt, frame-%06d.*, masks/  */
    /* Not a directory layout and not in the format table: frames from
     * another reader through sooc_seq_open_source (a robot log, log.h). */
    SOOC_SEQ_SOURCE = 64
} sooc_seq_format;
#define SOOC_SEQ_FORMAT_COUNT 8

/* One row of the format-name table: the only place format names live. The
 * launch parser, the CLI and the replay driver use the functions below. */
typedef struct sooc_seq_format_info {
    sooc_seq_format format;
    const char *name;         /* canonical name, e.g. "7scenes"                      */
    const char *aliases;      /* other accepted names, '|'-separated ("" = none)     */
    const char *layout;       /* one line for help texts                             */
    double depth_scale;       /* default metres per (shifted) unit; 0 = from calib   */
    int depth_shift;          /* default right shift of raw depth                    */
    int depth_invalid;        /* default raw "no depth" value besides 0 (0 = none)   */
    int depth_circular;       /* 1: the shift rotates the 16 bits right (APC)        */
    int labels_predicted;     /* 1: the layout's labels are a network's predictions
                                 (scores against them measure agreement)           */
} sooc_seq_format_info;

/* The table (SOOC_SEQ_FORMAT_COUNT rows, row i = enum value i). */
const sooc_seq_format_info *sooc_seq_formats(int *n);
/* The row of f, or NULL when f is out of range. */
const sooc_seq_format_info *sooc_seq_format_info_of(sooc_seq_format f);
/* Canonical name: "auto", "tum", "7scenes", "slambook", "replica",
 * "label-fusion", "ycb-video", "apc" ("?" when out of range). */
const char *sooc_seq_format_name(sooc_seq_format f);
/* Any name or alias, case-insensitive: auto; tum, sooc, tum-rgbd; 7scenes,
 * sevenscenes, 7-scenes; slambook, slambook2; replica, nice-slam;
 * label-fusion, labelfusion, label_fusion; ycb-video, ycb, ycbv, ycb_video;
 * apc, apc-shelf, apc_shelf. Unknown -> EINVAL listing them. */
sooc_status sooc_seq_format_parse(const char *s, sooc_seq_format *out);
/* Writes "auto, tum (sooc, tum-rgbd), 7scenes (...), ..." for messages and
 * help texts; returns the full length (like snprintf). */
size_t sooc_seq_format_list(char *buf, size_t cap);

typedef struct sooc_seq_open_params {
    sooc_seq_format format;   /* AUTO = detect                                         */
    const char *calib_path;   /* calib YAML overriding <dir>/calib.yaml (may be NULL)  */
    double depth_scale;       /* > 0 overrides the calibration's depth_scale (m/unit)  */
    int depth_shift;          /* >= 0: right-shift raw depth before scaling; -1 (the
                                 default) = calibration, else the format's default    */
    int depth_invalid;        /* >= 0: raw value that means "no depth" besides 0 (0 =
                                 none); -1 (the default) = calibration, else format   */
    double max_dt;            /* TUM association tolerance in seconds (default 0.02)   */
    double rot_tol;           /* orthonormality tolerance (default 1e-3)               */
    double max_depth;         /* depths beyond this are invalid (0 = no limit)         */
    int keep_bad_frames;      /* 7-Scenes layout: 1 = a frame whose depth or pose file is
                                 missing, or whose pose file does not parse, still opens
                                 and reading it fails with that message (the replay
                                 driver skips such frames); 0 = the open fails        */
} sooc_seq_open_params;

void sooc_seq_open_params_default(sooc_seq_open_params *p);

typedef struct sooc_seq sooc_seq;

/* Open and validate a sequence directory. p may be NULL (defaults). On
 * failure *out = NULL and the message names the file and line. */
sooc_status sooc_seq_open(sooc_seq **out, const char *dir, const sooc_seq_open_params *p);
int64_t sooc_seq_count(const sooc_seq *s);
/* Read frame i (0 <= i < count) into f. f must be zero-initialised or hold a
 * frame from an earlier call (its buffers are reused when the size matches).
 * Fills rgb, depth (planar metres, 0 = invalid), valid, instance (synthetic
 * layout, YCB-Video label.png, APC masks; else NULL), t_ns, has_pose/T_wc, K, index (the frame's number
 * in its file names, = i for TUM), is_query. On error (a missing, truncated
 * or corrupt image, named in the message) f may hold a partial frame: do not
 * use it; nothing else changes and later frames can still be read. */
sooc_status sooc_seq_read(sooc_seq *s, int64_t i, sooc_frame *f);
/* The format actually read (never AUTO once open). */
sooc_seq_format sooc_seq_get_format(const sooc_seq *s);
/* Frame i's number in its file names (7-Scenes frame-000042.* -> 42; TUM:
 * i), and its colour and depth image paths; -1 / NULL when i is out of range. */
int64_t sooc_seq_frame_number(const sooc_seq *s, int64_t i);
/* Frame i's t_ns as sooc_seq_read would give it, without reading any image
 * (known at open); INT64_MIN when i is out of range. */
int64_t sooc_seq_frame_time(const sooc_seq *s, int64_t i);
const char *sooc_seq_color_path(const sooc_seq *s, int64_t i);
const char *sooc_seq_depth_path(const sooc_seq *s, int64_t i);
/* The depth decoding in use: metres = (raw >> shift) * scale, raw 0 and raw ==
 * invalid (when > 0) are invalid. With sooc_seq_depth_circular(s) == 1 the
 * shift is a right rotation of the 16 bits: (raw >> shift) | (raw << (16 -
 * shift)) on 16 bits (APC). */
void sooc_seq_depth_decoding(const sooc_seq *s, double *scale, int *shift, int *invalid);
/* 1 when frame i was kept with a pose file that is missing or does not parse
 * (keep_bad_frames): sooc_seq_read of it fails with that file's message. */
int sooc_seq_pose_bad(const sooc_seq *s, int64_t i);
int sooc_seq_depth_circular(const sooc_seq *s);
/* 1 when the frames carry instance ids (sooc_seq_read fills f->instance). */
int sooc_seq_has_labels(const sooc_seq *s);
/* 1 when those ids are predictions (APC: a segmentation network's masks), not
 * ground truth: scores against them measure agreement, not accuracy. 0 for
 * ground truth or no labels. */
int sooc_seq_labels_predicted(const sooc_seq *s);
/* The name of label id (APC: the object of the "# Objects:" line; YCB-Video:
 * the class, e.g. "025_mug"), or NULL when the layout names none. */
const char *sooc_seq_label_name(const sooc_seq *s, int id);
const sooc_calib *sooc_seq_calib(const sooc_seq *s);
/* Gravity direction in the world frame (the frame of T_wc), from
 * <dir>/gravity-direction.txt (7-Scenes: three numbers, one per line or on
 * one line). Returns 1 and g normalised to unit length when the sequence has
 * one, 0 (g untouched) otherwise. A malformed or zero-length file fails
 * sooc_seq_open (EFORMAT/EINVAL naming the file). */
int sooc_seq_gravity(const sooc_seq *s, double g[3]);
void sooc_seq_close(sooc_seq *s);   /* NULL-safe */

/* A sequence whose frames another reader makes (sooc_log_seq_open in log.h
 * reads ROS bags and MCAP files this way): n frames with stamps t_ns[i]
 * (ascending, copied), read(user, i, f) fills frame i as sooc_seq_read would
 * (the sequence applies max_depth after it), close(user) runs at
 * sooc_seq_close (also when this call fails). calib is copied: its K is what
 * sooc_seq_calib returns. name stands for the directory in messages. The
 * format is SOOC_SEQ_SOURCE ("source"). */
typedef struct sooc_seq_source {
    const char *name;
    int64_t n;
    const int64_t *t_ns;
    const sooc_calib *calib;
    double max_depth;          /* 0 = no limit */
    void *user;
    sooc_status (*read)(void *user, int64_t i, sooc_frame *f);
    void (*close)(void *user);
} sooc_seq_source;
sooc_status sooc_seq_open_source(sooc_seq **out, const sooc_seq_source *src);

/* ------------------------------------------------------------- writer */

/* Writes the sooc3d synthetic layout (TUM + calib.yaml [+ instance/]):
 * rgb/%06d.png, depth/%06d.png (16-bit, round(z / depth_scale)),
 * instance/%06d.png when frames carry ids, and on finish rgb.txt, depth.txt,
 * groundtruth.txt (timestamps from frame t_ns, 6 decimals) and calib.yaml
 * (calib->depth_scale must be > 0; depths beyond 65535 units are stored as 0). */
typedef struct sooc_seq_writer sooc_seq_writer;

sooc_status sooc_seq_writer_create(sooc_seq_writer **out, const char *dir, const sooc_calib *calib,
                                   int64_t n_frames);
/* Write frame slot i (0 <= i < n_frames). Thread-safe for distinct i. */
sooc_status sooc_seq_writer_put(sooc_seq_writer *w, int64_t i, const sooc_frame *f);
/* Write the index files; fails if a slot was never put. */
sooc_status sooc_seq_writer_finish(sooc_seq_writer *w);
void sooc_seq_writer_destroy(sooc_seq_writer *w);  /* NULL-safe */

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_SEQ_H */
