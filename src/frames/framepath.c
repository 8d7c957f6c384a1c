/* The one frame path (include/sooc3d/frame.h): sequence reader +
 * sooc_frames_preprocess + the map's world frame, for every command. */
#include "sooc3d/frame.h"
#include "sooc3d/log.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sooc3d/cogmap.h"

struct sooc_framepath {
    char dir[1024];
    sooc_seq *seq;
    sooc_framepath_params p;
    int synthetic;
    sooc_framepath_world world;       /* where the frame came from (never AUTO) */
    double T_world_src[16];
    int has_support;
    sooc_support sup;
    double hmin, hmax;                /* the estimate's trained camera-height range */
    int has_record;                   /* a stored frame's extra fields */
    double up_src[3], plane_src[4], cam_h;
    int up_source;
    sooc_frame raw;                   /* scratch at the source resolution */
    int last_w, last_h;               /* source size of the last frame read */
    int64_t n_empty;
};

static const char *const world_names[] = {"auto", "identity", "stored", "estimate", "given"};

const char *sooc_framepath_world_name(sooc_framepath_world w) {
    return (unsigned)w < sizeof world_names / sizeof *world_names ? world_names[w] : "?";
}

sooc_status sooc_framepath_world_parse(const char *s, sooc_framepath_world *out) {
    for (unsigned i = 0; s && i < sizeof world_names / sizeof *world_names; i++)
        if (!strcmp(s, world_names[i])) {
            *out = (sooc_framepath_world)i;
            return SOOC_OK;
        }
    return sooc_seterr(SOOC_EINVAL, "unknown world frame '%s' (auto, identity, stored, estimate, given)", s ? s : "");
}

void sooc_framepath_params_default(sooc_framepath_params *p) {
    memset(p, 0, sizeof *p);
    p->format = SOOC_SEQ_AUTO;
    p->depth_shift = -1;
    p->min_depth_m = 0.1;
    p->max_depth_m = 10.0;
    p->resample = SOOC_FRAMES_DEPTH_MIN;
    p->world = SOOC_WORLD_AUTO;
    sooc_se3_identity(p->T_world_src);
    p->support_frames = 30;
}

void sooc_framepath_close(sooc_framepath *fp) {
    if (!fp) return;
    sooc_seq_close(fp->seq);
    sooc_frame_free(&fp->raw);
    sooc_free(fp);
}

int64_t sooc_framepath_count(const sooc_framepath *fp) { return sooc_seq_count(fp->seq); }
int sooc_framepath_synthetic(const sooc_framepath *fp) { return fp->synthetic; }
sooc_seq *sooc_framepath_seq(sooc_framepath *fp) { return fp->seq; }
const char *sooc_framepath_dir(const sooc_framepath *fp) { return fp->dir; }
int64_t sooc_framepath_empty_depth(const sooc_framepath *fp) { return fp->n_empty; }
int sooc_framepath_support(const sooc_framepath *fp, sooc_framepath_support_info *o) {
    if (!fp->has_support) return 0;
    const sooc_support *s = &fp->sup;
    memcpy(o->T_world_src, s->T_world_src, sizeof o->T_world_src);
    memcpy(o->up_src, s->up_src, sizeof o->up_src);
    memcpy(o->plane_src, s->plane_src, sizeof o->plane_src);
    o->up_source = (int)s->up_source;
    o->tilt_deg = s->tilt_deg, o->cam_height_m = s->cam_height_m, o->rms_m = s->rms_m;
    o->height_warning = s->height_warning, o->frames_used = s->frames_used;
    o->n_inliers = s->n_inliers, o->n_points = s->n_points;
    return 1;
}

sooc_framepath_world sooc_framepath_world_get(const sooc_framepath *fp, double T_world_src[16]) {
    if (T_world_src) memcpy(T_world_src, fp->T_world_src, sizeof fp->T_world_src);
    return fp->world;
}

void sooc_framepath_frame_record(const sooc_framepath *fp, double T_world_src[16], double up_src[3],
                                 double plane_src[4], double *cam_height_m, int *up_source) {
    memcpy(T_world_src, fp->T_world_src, sizeof fp->T_world_src);
    if (fp->has_support) {
        memcpy(up_src, fp->sup.up_src, 3 * sizeof(double));
        memcpy(plane_src, fp->sup.plane_src, 4 * sizeof(double));
        *cam_height_m = fp->sup.cam_height_m;
        *up_source = (int)fp->sup.up_source;
    } else if (fp->has_record) {
        memcpy(up_src, fp->up_src, sizeof fp->up_src);
        memcpy(plane_src, fp->plane_src, sizeof fp->plane_src);
        *cam_height_m = fp->cam_h;
        *up_source = fp->up_source;
    } else {
        /* identity / given: up is the world's +y seen from the source frame */
        double R_t[3] = {T_world_src[4], T_world_src[5], T_world_src[6]};   /* row 1 of R = up in src */
        memcpy(up_src, R_t, sizeof R_t);
        plane_src[0] = up_src[0], plane_src[1] = up_src[1], plane_src[2] = up_src[2];
        plane_src[3] = T_world_src[7];   /* y_world = up . p + t_y = 0 on the plane */
        *cam_height_m = 0;
        *up_source = -1;
    }
}

/* The frame as the sequence stores it (source pose), K completed. */
static sooc_status read_source(sooc_framepath *fp, int64_t i, sooc_frame *f) {
    sooc_status st = sooc_seq_read(fp->seq, i, f);
    if (st) return st;
    if (f->K.width <= 0 || f->K.height <= 0) {
        f->K.width = f->width;
        f->K.height = f->height;
    }
    return SOOC_OK;
}

/* Target size for the frames handed to the support estimate: at most 160
 * columns, the source aspect kept (plane fitting needs no more). */
static void estimate_size(int w, int h, int *tw, int *th) {
    *tw = w > 160 ? 160 : w;
    *th = (int)lround((double)h * *tw / w);
    if (*th < 1) *th = 1;
}

static sooc_status world_estimate(sooc_framepath *fp) {
    int64_t n = sooc_seq_count(fp->seq);
    int m = fp->p.support_frames > 0 ? fp->p.support_frames : 30;
    if (n <= 0) return sooc_seterr(SOOC_EINVAL, "%s: the sequence has no frames", fp->dir);
    if (m > n) m = (int)n;
    sooc_frame *fr = sooc_calloc((size_t)m, sizeof *fr);
    const sooc_frame **pf = sooc_calloc((size_t)m, sizeof *pf);
    sooc_status st = (fr && pf) ? SOOC_OK : SOOC_ENOMEM;
    int k = 0;
    for (int j = 0; j < m && !st; j++) {
        int64_t i = (int64_t)((j + 0.5) * (double)n / m);
        if ((st = read_source(fp, i, &fp->raw))) break;
        if (!fp->raw.has_pose) continue;
        int tw, th;
        estimate_size(fp->raw.width, fp->raw.height, &tw, &th);
        if ((st = sooc_frames_preprocess(&fp->raw, &fr[k], tw, th, SOOC_FRAMES_DEPTH_MIN, fp->p.min_depth_m,
                                         fp->p.max_depth_m)))
            break;
        pf[k] = &fr[k];
        k++;
    }
    if (!st && k == 0) st = sooc_seterr(SOOC_EINVAL, "%s: no frame with a pose for the support-plane estimate", fp->dir);
    if (!st) {
        sooc_support_params sp;
        sooc_support_params_default(&sp);
        if (fp->p.max_tilt_deg > 0) sp.max_tilt_deg = fp->p.max_tilt_deg;
        if (fp->p.cam_height_min_m > 0) sp.cam_height_min_m = fp->p.cam_height_min_m;
        if (fp->p.cam_height_max_m > 0) sp.cam_height_max_m = fp->p.cam_height_max_m;
        /* the frames are already at <= 160 columns: every pixel is a sample (the
         * default stride of 4 is meant for 640-column frames and leaves a
         * 80x60 frame 300 points, too few for the height-histogram refit) */
        sp.pixel_step = 1;
        sp.max_frames = k;   /* all the frames read, spread over the sequence */
        if (fp->p.has_up) {
            sp.has_up_hint = 1;
            memcpy(sp.up_hint, fp->p.up, sizeof sp.up_hint);
        }
        double g[3];
        if (sooc_seq_gravity(fp->seq, g)) {
            sp.has_gravity = 1;
            memcpy(sp.gravity, g, sizeof g);
        }
        fp->hmin = sp.cam_height_min_m, fp->hmax = sp.cam_height_max_m;
        st = sooc_support_estimate(pf, k, &sp, &fp->sup);
        if (st)
            sooc_adderr(st, "%s: support-plane estimate for the map's world frame (give --up x,y,z, or "
                            "--world identity for poses that are already gravity-aligned)", fp->dir);
    }
    for (int j = 0; j < k; j++) sooc_frame_free(&fr[j]);
    sooc_free(fr);
    sooc_free(pf);
    if (st) return st;
    fp->has_support = 1;
    fp->world = SOOC_WORLD_ESTIMATE;
    memcpy(fp->T_world_src, fp->sup.T_world_src, sizeof fp->T_world_src);
    sooc_log(SOOC_LOG_INFO,
             "%s: world frame from the support plane: up (%.3f %.3f %.3f) from %s, tilt %.1f deg, camera %.2f m "
             "above it, %zu/%zu inliers over %d frames",
             fp->dir, fp->sup.up_src[0], fp->sup.up_src[1], fp->sup.up_src[2], sooc_up_source_name(fp->sup.up_source),
             fp->sup.tilt_deg, fp->sup.cam_height_m, fp->sup.n_inliers, fp->sup.n_points, fp->sup.frames_used);
    if (fp->sup.height_warning)
        sooc_log(SOOC_LOG_WARN, "%s: the camera is %.2f m above the support plane, outside the range the model "
                                "was trained for (%.2f .. %.2f m)",
                 fp->dir, fp->sup.cam_height_m, fp->hmin, fp->hmax);
    return SOOC_OK;
}

/* 1: a stored frame was found and taken. */
static sooc_status world_stored(sooc_framepath *fp, int *found) {
    *found = 0;
    if (!fp->p.map_db || !fp->p.map_db[0] || !sooc_file_exists(fp->p.map_db)) return SOOC_OK;
    sooc_mapstore *ms = NULL;
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    mp.readonly = 1;
    sooc_status st = sooc_mapstore_open(&ms, fp->p.map_db, &mp);
    if (st) return st;
    sooc_map_frame mf;
    st = sooc_mapstore_frame_get(ms, &mf, found);
    sooc_mapstore_close(ms);
    if (st || !*found) return st;
    memcpy(fp->T_world_src, mf.T_world_src, sizeof fp->T_world_src);
    memcpy(fp->up_src, mf.up_src, sizeof fp->up_src);
    memcpy(fp->plane_src, mf.plane_src, sizeof fp->plane_src);
    fp->cam_h = mf.cam_height_m;
    fp->up_source = mf.up_source;
    fp->has_record = 1;
    fp->world = SOOC_WORLD_STORED;
    sooc_log(SOOC_LOG_INFO, "%s: world frame stored in %s (up (%.3f %.3f %.3f), camera %.2f m above the plane)",
             fp->dir, fp->p.map_db, mf.up_src[0], mf.up_src[1], mf.up_src[2], mf.cam_height_m);
    return SOOC_OK;
}

sooc_status sooc_framepath_open(sooc_framepath **out, const char *dir, const sooc_framepath_params *p) {
    *out = NULL;
    sooc_framepath *fp = sooc_calloc(1, sizeof *fp);
    if (!fp) return SOOC_ENOMEM;
    if (p) fp->p = *p;
    else sooc_framepath_params_default(&fp->p);
    sooc_status st = SOOC_OK;
    if (snprintf(fp->dir, sizeof fp->dir, "%s", dir) >= (int)sizeof fp->dir) {
        st = sooc_seterr(SOOC_EINVAL, "%s: path too long", dir);
        goto fail;
    }
    const sooc_framepath_params *q = &fp->p;
    if (!(q->min_depth_m >= 0) || !(q->max_depth_m > q->min_depth_m) || !isfinite(q->max_depth_m)) {
        st = sooc_seterr(SOOC_EINVAL, "%s: depth range [%g, %g] m is empty (need 0 <= min < max)", dir,
                         q->min_depth_m, q->max_depth_m);
        goto fail;
    }
    if (q->width < 0 || q->height < 0 || (q->width > 0) != (q->height > 0)) {
        st = sooc_seterr(SOOC_EINVAL, "%s: target size %dx%d is invalid", dir, q->width, q->height);
        goto fail;
    }
    if (q->has_up && !(sooc_v3_norm(q->up) > 1e-9)) {
        st = sooc_seterr(SOOC_EINVAL, "%s: --up must be a non-zero direction", dir);
        goto fail;
    }
    sooc_seq_open_params sp;
    sooc_seq_open_params_default(&sp);
    sp.format = q->format;
    sp.calib_path = q->calib_path;
    if (q->depth_scale > 0) sp.depth_scale = q->depth_scale;
    if (q->depth_shift >= 0) sp.depth_shift = q->depth_shift;
    if ((st = sooc_log_seq_open(&fp->seq, dir, &sp, NULL))) goto fail;   /* a folder, a ROS bag or an MCAP file */
    char path[1100];
    if ((st = sooc_path_join(path, sizeof path, dir, "scene.yaml"))) goto fail;
    fp->synthetic = sooc_file_exists(path);

    sooc_se3_identity(fp->T_world_src);
    switch (q->world) {
    case SOOC_WORLD_IDENTITY:
        fp->world = SOOC_WORLD_IDENTITY;
        break;
    case SOOC_WORLD_GIVEN:
        fp->world = SOOC_WORLD_GIVEN;
        memcpy(fp->T_world_src, q->T_world_src, sizeof fp->T_world_src);
        break;
    case SOOC_WORLD_ESTIMATE:
        st = world_estimate(fp);
        break;
    case SOOC_WORLD_STORED: {
        int found = 0;
        if (!(st = world_stored(fp, &found)) && !found)
            st = sooc_seterr(SOOC_ENOTFOUND, "%s: no world frame stored in the map database%s%s", dir,
                             q->map_db ? " " : "", q->map_db ? q->map_db : " (none given)");
        break;
    }
    case SOOC_WORLD_AUTO:
    default:
        if (fp->synthetic) {
            fp->world = SOOC_WORLD_IDENTITY;
        } else {
            int found = 0;
            if (!(st = world_stored(fp, &found)) && !found) {
                if (q->map_db && q->map_db[0])
                    sooc_log(SOOC_LOG_WARN, "%s: %s stores no world frame (written before the support plane was "
                                            "stored): estimating one, which may differ from the node's",
                             dir, q->map_db);
                st = world_estimate(fp);
            }
        }
        break;
    }
    if (st) goto fail;
    *out = fp;
    return SOOC_OK;
fail:
    sooc_framepath_close(fp);
    return st;
}

static sooc_status finish(sooc_framepath *fp, sooc_frame *f) {
    if (f->has_pose) {
        double T[16];
        sooc_se3_mul(T, fp->T_world_src, fp->raw.T_wc);
        memcpy(f->T_wc, T, sizeof T);
    }
    size_t np = (size_t)f->width * (size_t)f->height, nv = 0;
    for (size_t k = 0; k < np; k++) nv += f->valid[k] != 0;
    if (nv == 0) fp->n_empty++;
    return SOOC_OK;
}

sooc_status sooc_framepath_read(sooc_framepath *fp, int64_t i, sooc_frame *f) {
    sooc_status st = read_source(fp, i, &fp->raw);
    if (st) return st;
    int tw = fp->p.width > 0 ? fp->p.width : fp->raw.width, th = fp->p.height > 0 ? fp->p.height : fp->raw.height;
    st = sooc_frames_preprocess(&fp->raw, f, tw, th, fp->p.resample, fp->p.min_depth_m, fp->p.max_depth_m);
    if (st) return sooc_adderr(st, "%s: frame %lld", fp->dir, (long long)i);
    fp->last_w = fp->raw.width, fp->last_h = fp->raw.height;
    return finish(fp, f);
}

sooc_status sooc_framepath_read_raw(sooc_framepath *fp, int64_t i, sooc_frame *f) {
    sooc_status st = read_source(fp, i, &fp->raw);
    if (st) return st;
    /* the identity crop: a copy with the depth range applied */
    st = sooc_frames_preprocess(&fp->raw, f, fp->raw.width, fp->raw.height, fp->p.resample, fp->p.min_depth_m,
                                fp->p.max_depth_m);
    if (st) return sooc_adderr(st, "%s: frame %lld", fp->dir, (long long)i);
    fp->last_w = fp->raw.width, fp->last_h = fp->raw.height;
    return finish(fp, f);
}

sooc_status sooc_framepath_resize_ids(const sooc_framepath *fp, const uint16_t *src, int w, int h, uint16_t *dst) {
    if (!fp->last_w || w != fp->last_w || h != fp->last_h)
        return sooc_seterr(SOOC_EINVAL, "%s: id image is %dx%d, the frames are %dx%d", fp->dir, w, h, fp->last_w,
                           fp->last_h);
    int tw = fp->p.width > 0 ? fp->p.width : w, th = fp->p.height > 0 ? fp->p.height : h;
    int x0, y0, cw, ch;
    sooc_frames_crop_for_aspect(w, h, tw, th, &x0, &y0, &cw, &ch);
    sooc_frames_resize_ids(src, w, x0, y0, cw, ch, dst, tw, th);
    return SOOC_OK;
}
