/*
 * sooc3d frame path: the one way every command reads a recorded or synthetic
 * sequence (node replay, infer, render, eval, train; docs/formats.md
 * "One frame path").
 *
 *   sooc_framepath_open(dir, params)      the sequence reader (sooc_seq) with the
 *                                         same options everywhere: --calib,
 *                                         --format, --depth-scale, --depth-shift,
 *                                         depth range, --up, --world
 *   sooc_framepath_read(fp, i, frame)     frame i, already
 *                                           - cropped to the model's aspect and
 *                                             resized to its resolution (RGB by
 *                                             area, depth by min-of-valid, ids by
 *                                             nearest), intrinsics adjusted;
 *                                           - depth in metres (scale and invalid
 *                                             value from the calibration or the
 *                                             format's documented default), samples
 *                                             outside [min_depth_m, max_depth_m]
 *                                             invalid;
 *                                           - the pose in the map's world frame:
 *                                             T_wc = T_world_src * T_src_c.
 *
 * The world frame (+y up, the support plane at y = 0) is chosen at open:
 *   - a synthetic sequence (scene.yaml present): the identity;
 *   - a recorded one: the frame stored in the map database (p->map_db,
 *     sooc_mapstore_frame_get), else a fresh support-plane estimate
 *     (sooc_support_estimate over up to p->support_frames frames spread over
 *     the sequence; up from --up, else the sequence's gravity file, else the
 *     cameras' mean down direction);
 *   - or as forced by p->world.
 * The choice is logged (sooc_log INFO) and available from
 * sooc_framepath_world; the caller stores a fresh estimate in its own map
 * with sooc_mapstore_frame_put (sooc_framepath_map_frame fills the record).
 *
 * The preprocessing is sooc_node_preprocess (include/sooc3d/support.h), the
 * step the live node runs on every keyframe, with the same defaults as a
 * launch file (depth 0.1 .. 10 m, min-of-valid depth resampling).
 *
 * This header does not include support.h (so that it can be used next to
 * headers with a `sooc_support` tag of their own); the estimate's figures
 * come back as sooc_framepath_support_info.
 *
 * Thread safety: one thread at a time per sooc_framepath.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_FRAMEPATH_H
#define SOOC3D_FRAMEPATH_H

#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/support.h"
#include "sooc3d/seq.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sooc_framepath_world {
    SOOC_WORLD_AUTO = 0,      /* scene.yaml: identity; else stored map frame; else estimate */
    SOOC_WORLD_IDENTITY = 1,  /* poses are already gravity-aligned (+y up, floor at 0)      */
    SOOC_WORLD_STORED = 2,    /* the map database's frame; fails if it has none            */
    SOOC_WORLD_ESTIMATE = 3,  /* a fresh support-plane estimate (ignores a stored frame)   */
    SOOC_WORLD_GIVEN = 4      /* p->T_world_src as given                                   */
} sooc_framepath_world;

/* "auto", "identity", "stored", "estimate", "given" */
const char *sooc_framepath_world_name(sooc_framepath_world w);
sooc_status sooc_framepath_world_parse(const char *s, sooc_framepath_world *out);

typedef struct sooc_framepath_params {
    /* reading (sooc_seq_open_params) */
    const char *calib_path;   /* --calib: calib YAML overriding <dir>/calib.yaml (NULL: none)       */
    sooc_seq_format format;   /* --format (default AUTO)                                          */
    double depth_scale;       /* --depth-scale: > 0 overrides the calibration / format (m per unit) */
    int depth_shift;          /* --depth-shift: >= 0 overrides; -1 (default) = calibration/format   */
    /* preprocessing */
    int width, height;        /* target resolution (the model's); 0 = keep each frame's own       */
    double min_depth_m;       /* valid depth range; defaults 0.1 and 10 (as a launch file).       */
    double max_depth_m;       /* max <= min is an error at open, never an all-invalid frame        */
    sooc_node_depth_resample resample;  /* default SOOC_NODE_DEPTH_MIN                            */
    /* world frame */
    sooc_framepath_world world;
    int has_up;               /* --up: 1 = up (source frame) is the support estimate's hint        */
    double up[3];
    double T_world_src[16];   /* with world = GIVEN                                                */
    const char *map_db;       /* map database to read a stored frame from (NULL: none)            */
    int support_frames;       /* frames handed to sooc_support_estimate (default 30)              */
    double max_tilt_deg;      /* support plane within this angle of up (0 = the estimate's default) */
    double cam_height_min_m;  /* trained camera-height range for the warning (0 = the estimate's   */
    double cam_height_max_m;  /*   defaults, sooc_support_params_default)                          */
} sooc_framepath_params;

void sooc_framepath_params_default(sooc_framepath_params *p);

typedef struct sooc_framepath sooc_framepath;

/* Open dir with p (NULL = defaults) and settle the world frame (which may
 * read up to support_frames frames). On failure *out = NULL and the message
 * names the directory/file and the problem (e.g. "seq: no plane within 30 deg
 * of up (gravity file)"). */
sooc_status sooc_framepath_open(sooc_framepath **out, const char *dir, const sooc_framepath_params *p);
void sooc_framepath_close(sooc_framepath *fp);   /* NULL-safe */

int64_t sooc_framepath_count(const sooc_framepath *fp);
/* Read frame i (0 <= i < count) preprocessed into f (zero-initialised or from
 * an earlier call; buffers are reused). Fills rgb, depth, valid, instance
 * (when the sequence has ids; nearest-resized), K at f's resolution, t_ns,
 * index, is_query, has_pose and T_wc in the map's world frame. */
sooc_status sooc_framepath_read(sooc_framepath *fp, int64_t i, sooc_frame *f);
/* The same frame at the sequence's own resolution, pose in the world frame
 * (depth range applied, no crop/resize). */
sooc_status sooc_framepath_read_raw(sooc_framepath *fp, int64_t i, sooc_frame *f);

/* Resize an id image (w x h, 0 = none) of this sequence's frames with the
 * crop and nearest sampling sooc_framepath_read applies to depth, into dst
 * (width x height of the target). For labels kept outside the reader
 * (label-fusion segm.png). Fails if w x h is not the sequence's frame size
 * as last read. */
sooc_status sooc_framepath_resize_ids(const sooc_framepath *fp, const uint16_t *src, int w, int h, uint16_t *dst);

/* The world frame in use: T_world_src (p_world = T * p_src) and where it came
 * from (returned). */
sooc_framepath_world sooc_framepath_world_get(const sooc_framepath *fp, double T_world_src[16]);
/* The support estimate's figures (a copy of sooc_support's, support.h). */
typedef struct sooc_framepath_support_info {
    double T_world_src[16];
    double up_src[3];         /* unit up in the source frame                    */
    double plane_src[4];      /* n . p + d = 0 in the source frame              */
    int up_source;            /* sooc_up_source: 0 given, 1 gravity file, 2 camera mean */
    double tilt_deg, cam_height_m, rms_m;
    int height_warning, frames_used;
    size_t n_inliers, n_points;
} sooc_framepath_support_info;
/* 1 and *out filled when the world came from a support estimate, else 0. */
int sooc_framepath_support(const sooc_framepath *fp, sooc_framepath_support_info *out);
/* Fill a sooc_map_frame-compatible record (mapstore.h) for storing. Fields:
 * T_world_src, up_src, plane_src, cam_height_m, up_source (-1 when the
 * frame was given / identity). Declared with plain arrays so this header
 * does not need mapstore.h. */
void sooc_framepath_frame_record(const sooc_framepath *fp, double T_world_src[16], double up_src[3],
                                 double plane_src[4], double *cam_height_m, int *up_source);

int sooc_framepath_synthetic(const sooc_framepath *fp);   /* 1: the sequence has scene.yaml */
sooc_seq *sooc_framepath_seq(sooc_framepath *fp);         /* the underlying reader (borrowed) */
const char *sooc_framepath_dir(const sooc_framepath *fp);
/* Number of frames whose depth had no valid pixel after preprocessing so
 * far (a wrong depth scale or range shows up here; the commands warn). */
int64_t sooc_framepath_empty_depth(const sooc_framepath *fp);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_FRAMEPATH_H */
