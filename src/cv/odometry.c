/* Frame-to-keyframe RGB-D odometry (include/sooc3d/slam.h) on top of
 * OpenCV's rgbd module (cvshim.h). The C side holds the keyframe rule and
 * the failure policy; OpenCV does the registration. */
#include "sooc3d/slam.h"

#include <math.h>
#include <string.h>

#include "sooc3d/core.h"

#if SOOC_HAVE_OPENCV
#include "cvshim.h"
#endif

int sooc_cv_available(void) {
#if SOOC_HAVE_OPENCV
    return 1;
#else
    return 0;
#endif
}

static const char *const g_variants[] = {"rgbd", "icp", "rgbd_icp"};

const char *sooc_odom_variant_name(sooc_odom_variant v) {
    return (unsigned)v < 3 ? g_variants[v] : "?";
}

sooc_status sooc_odom_variant_parse(const char *s, sooc_odom_variant *out) {
    for (int i = 0; i < 3; i++)
        if (s && !strcmp(s, g_variants[i])) {
            *out = (sooc_odom_variant)i;
            return SOOC_OK;
        }
    return sooc_seterr(SOOC_EINVAL, "odometry variant: expected rgbd|icp|rgbd_icp, got '%s'", s ? s : "");
}

void sooc_odom_params_default(sooc_odom_params *p) {
    memset(p, 0, sizeof *p);
    p->variant = SOOC_ODOM_RGBD_ICP;
    p->width = 320;
    p->height = 240;
    p->min_depth_m = 0.3;
    p->max_depth_m = 4.0;
    p->max_depth_diff_m = 0.07;
    p->max_points_part = 0.07;
    p->max_translation_m = 0.3;
    p->max_rotation_deg = 30;
    p->kf_translation_m = 0.10;
    p->kf_rotation_deg = 10;
    p->kf_max_frames = 0;
    p->max_failures = 10;
    p->min_agreement = 0.3;
    sooc_se3_identity(p->T_color_depth);
}

int sooc_odom_is_7scenes_depth_K(const sooc_intrinsics *K, int width, int height) {
    double sx = width / 640.0, sy = height / 480.0;
    return width > 0 && height > 0 && fabs(K->fx - 585.0 * sx) < 1e-6 * sx * 585 &&
           fabs(K->fy - 585.0 * sy) < 1e-6 * sy * 585 && fabs(K->cx - width / 2.0) < 1e-6 * width &&
           fabs(K->cy - height / 2.0) < 1e-6 * height;
}

void sooc_odom_params_7scenes_color(sooc_odom_params *p, int width, int height) {
    p->color_K[0] = SOOC_ODOM_7SCENES_COLOR_F * width / 640.0;
    p->color_K[1] = SOOC_ODOM_7SCENES_COLOR_F * height / 480.0;
    p->color_K[2] = width / 2.0;
    p->color_K[3] = height / 2.0;
    sooc_se3_identity(p->T_color_depth);
}

struct sooc_odom {
    sooc_odom_params p;
#if SOOC_HAVE_OPENCV
    sooc_cvodo *cv;
#endif
    int started, src_w, src_h;
    double T_init[16];
    double T_w_kf[16];      /* keyframe pose                          */
    double T_kf_last[16];   /* last tracked frame relative to the kf  */
    double T_w_last[16];    /* last tracked pose                      */
    int failures, since_kf;
    sooc_odom_stats st;
};

static sooc_status check_params(const sooc_odom_params *p) {
    if ((unsigned)p->variant > 2) return sooc_seterr(SOOC_EINVAL, "odometry: bad variant %d", (int)p->variant);
    if (p->width < 0 || p->height < 0 || p->width > 8192 || p->height > 8192 || (!p->width) != (!p->height))
        return sooc_seterr(SOOC_EINVAL, "odometry: working size %dx%d is invalid", p->width, p->height);
    if (!(p->min_depth_m >= 0 && p->max_depth_m > p->min_depth_m && p->max_depth_diff_m > 0))
        return sooc_seterr(SOOC_EINVAL, "odometry: depth range %g..%g (diff %g) is invalid", p->min_depth_m,
                           p->max_depth_m, p->max_depth_diff_m);
    if (!(p->max_points_part > 0 && p->max_points_part <= 1))
        return sooc_seterr(SOOC_EINVAL, "odometry: max_points_part %g not in (0, 1]", p->max_points_part);
    if (!(p->max_translation_m > 0 && p->max_rotation_deg > 0))
        return sooc_seterr(SOOC_EINVAL, "odometry: failure bounds must be > 0");
    if (!(p->min_agreement >= 0 && p->min_agreement <= 1))
        return sooc_seterr(SOOC_EINVAL, "odometry: min_agreement %g not in [0, 1]", p->min_agreement);
    if (p->kf_translation_m < 0 || p->kf_rotation_deg < 0 || p->kf_max_frames < 0 || p->max_failures < 0)
        return sooc_seterr(SOOC_EINVAL, "odometry: keyframe rule values must be >= 0");
    const double *c = p->color_K, *T = p->T_color_depth;
    if (c[0] || c[1] || c[2] || c[3]) {
        if (!(c[0] > 0 && c[1] > 0 && isfinite(c[0]) && isfinite(c[1]) && isfinite(c[2]) && isfinite(c[3])))
            return sooc_seterr(SOOC_EINVAL, "odometry: colour intrinsics fx %g fy %g cx %g cy %g are invalid", c[0],
                               c[1], c[2], c[3]);
        double err = 0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double d = T[i * 4 + 0] * T[j * 4 + 0] + T[i * 4 + 1] * T[j * 4 + 1] + T[i * 4 + 2] * T[j * 4 + 2];
                err = fmax(err, fabs(d - (i == j)));
            }
        for (int i = 0; i < 12; i++)
            if (!isfinite(T[i])) err = INFINITY;
        if (!(err < 1e-3) || T[12] != 0 || T[13] != 0 || T[14] != 0 || T[15] != 1)
            return sooc_seterr(SOOC_EINVAL, "odometry: T_color_depth is not rigid (rotation error %g)", err);
    }
    return SOOC_OK;
}

sooc_status sooc_odom_create(sooc_odom **out, const sooc_odom_params *p) {
    *out = NULL;
    sooc_odom_params d;
    if (!p) {
        sooc_odom_params_default(&d);
        p = &d;
    }
    sooc_status st = check_params(p);
    if (st) return st;
#if !SOOC_HAVE_OPENCV
    return sooc_seterr(SOOC_EUNSUPPORTED,
                       "odometry: sooc3d was built without OpenCV (install libopencv-contrib-dev and rebuild with "
                       "-DSOOC_WITH_OPENCV=ON)");
#else
    sooc_odom *o = sooc_calloc(1, sizeof *o);
    if (!o) return sooc_seterr(SOOC_ENOMEM, "odometry: out of memory");
    o->p = *p;
    sooc_se3_identity(o->T_init);
    *out = o;
    return SOOC_OK;
#endif
}

void sooc_odom_set_initial_pose(sooc_odom *o, const double T_wc[16]) { memcpy(o->T_init, T_wc, sizeof o->T_init); }

void sooc_odom_get_stats(const sooc_odom *o, sooc_odom_stats *s) { *s = o->st; }

void sooc_odom_destroy(sooc_odom *o) {
    if (!o) return;
#if SOOC_HAVE_OPENCV
    sooc_cvodo_destroy(o->cv);
#endif
    sooc_free(o);
}

#if SOOC_HAVE_OPENCV
static double rot_angle_deg(const double T[16]) {
    double tr = T[0] + T[5] + T[10];
    double c = (tr - 1) * 0.5;
    c = c > 1 ? 1 : (c < -1 ? -1 : c);
    return acos(c) * 180.0 / M_PI;
}

static double trans_norm(const double T[16]) { return sqrt(T[3] * T[3] + T[7] * T[7] + T[11] * T[11]); }

static sooc_status start(sooc_odom *o, const sooc_frame *f) {
    int w = o->p.width ? o->p.width : f->width, h = o->p.height ? o->p.height : f->height;
    double sx = (double)w / f->width, sy = (double)h / f->height;
    /* OpenCV pixel centres: u' + 0.5 = (u + 0.5) * s */
    double K[4] = {f->K.fx * sx, f->K.fy * sy, (f->K.cx + 0.5) * sx - 0.5, (f->K.cy + 0.5) * sy - 0.5};
    const double *c = o->p.color_K;
    int unreg = c[0] || c[1] || c[2] || c[3];
    double Kc[4] = {c[0] * sx, c[1] * sy, (c[2] + 0.5) * sx - 0.5, (c[3] + 0.5) * sy - 0.5};
    char err[512] = "";
    if (sooc_cvodo_create(&o->cv, (int)o->p.variant, K, w, h, o->p.min_depth_m, o->p.max_depth_m,
                          o->p.max_depth_diff_m, o->p.max_points_part, o->p.max_translation_m,
                          o->p.max_rotation_deg, unreg ? Kc : NULL, o->p.T_color_depth, err, sizeof err))
        return sooc_seterr(SOOC_ERR, "odometry: %s", err);
    o->src_w = f->width;
    o->src_h = f->height;
    o->started = 1;
    return SOOC_OK;
}

static sooc_status make_keyframe(sooc_odom *o, const double T_w[16]) {
    char err[512] = "";
    if (sooc_cvodo_set_keyframe(o->cv, err, sizeof err)) return sooc_seterr(SOOC_ERR, "odometry: %s", err);
    memcpy(o->T_w_kf, T_w, sizeof o->T_w_kf);
    sooc_se3_identity(o->T_kf_last);
    o->since_kf = 0;
    o->st.keyframes++;
    return SOOC_OK;
}
#endif

sooc_status sooc_odom_track(sooc_odom *o, const sooc_frame *f, sooc_odom_result *r) {
    memset(r, 0, sizeof *r);
    r->state = SOOC_ODOM_FAILED;
    sooc_se3_identity(r->T_wc);
    if (!f->rgb || !f->depth || f->width <= 0 || f->height <= 0)
        return sooc_seterr(SOOC_EINVAL, "odometry: frame %lld has no colour or depth", (long long)f->index);
    if (!(f->K.fx > 0 && f->K.fy > 0))
        return sooc_seterr(SOOC_EINVAL, "odometry: frame %lld has no intrinsics (fx %g, fy %g)",
                           (long long)f->index, f->K.fx, f->K.fy);
#if !SOOC_HAVE_OPENCV
    (void)o;
    return sooc_seterr(SOOC_EUNSUPPORTED, "odometry: sooc3d was built without OpenCV");
#else
    double t0 = sooc_seconds();
    sooc_status st;
    if (!o->started && (st = start(o, f))) return st;
    if (f->width != o->src_w || f->height != o->src_h)
        return sooc_seterr(SOOC_EINVAL, "odometry: frame %lld is %dx%d, earlier frames were %dx%d",
                           (long long)f->index, f->width, f->height, o->src_w, o->src_h);
    char err[512] = "";
    if (sooc_cvodo_load(o->cv, f->rgb, f->depth, f->width, f->height, err, sizeof err))
        return sooc_seterr(SOOC_ERR, "odometry: frame %lld: %s", (long long)f->index, err);
    o->st.frames++;
    if (o->st.frames == 1) {
        if ((st = make_keyframe(o, o->T_init))) return st;
        memcpy(o->T_w_last, o->T_init, sizeof o->T_w_last);
        memcpy(r->T_wc, o->T_init, sizeof r->T_wc);
        r->state = SOOC_ODOM_FIRST;
        r->new_keyframe = 1;
        o->st.tracked++;
        goto done;
    }
    double T_kf_cur[16];
    int ok = sooc_cvodo_track(o->cv, o->T_kf_last, T_kf_cur, err, sizeof err);
    if (ok < 0) return sooc_seterr(SOOC_ERR, "odometry: frame %lld: %s", (long long)f->index, err);
    if (ok && (trans_norm(T_kf_cur) > o->p.max_translation_m || rot_angle_deg(T_kf_cur) > o->p.max_rotation_deg))
        ok = 0;
    if (ok && o->p.min_agreement > 0) {
        /* OpenCV accepts some wrong solutions: the frame's depth moved into
         * the keyframe must agree with the keyframe's depth */
        double agree = 0;
        if (sooc_cvodo_check(o->cv, T_kf_cur, o->p.max_depth_diff_m, 2, &agree, err, sizeof err))
            return sooc_seterr(SOOC_ERR, "odometry: frame %lld: %s", (long long)f->index, err);
        r->agreement = agree;
        if (agree < o->p.min_agreement) ok = 0;
    }
    if (!ok) {
        o->st.failed++;
        o->failures++;
        if (o->p.max_failures && o->failures >= o->p.max_failures) {
            /* lost: restart from this frame at the last tracked pose */
            if ((st = make_keyframe(o, o->T_w_last))) return st;
            o->failures = 0;
            o->st.reanchors++;
            r->state = SOOC_ODOM_REANCHORED;
            r->new_keyframe = 1;
        }
        goto done;
    }
    o->failures = 0;
    o->since_kf++;
    o->st.tracked++;
    sooc_se3_mul(r->T_wc, o->T_w_kf, T_kf_cur);
    memcpy(o->T_w_last, r->T_wc, sizeof o->T_w_last);
    memcpy(o->T_kf_last, T_kf_cur, sizeof o->T_kf_last);
    r->state = SOOC_ODOM_TRACKED;
    int far = (o->p.kf_translation_m > 0 && trans_norm(T_kf_cur) >= o->p.kf_translation_m) ||
              (o->p.kf_rotation_deg > 0 && rot_angle_deg(T_kf_cur) >= o->p.kf_rotation_deg) ||
              (o->p.kf_max_frames > 0 && o->since_kf >= o->p.kf_max_frames);
    if (far) {
        if ((st = make_keyframe(o, r->T_wc))) return st;
        r->new_keyframe = 1;
    }
done:
    r->ms = (sooc_seconds() - t0) * 1e3;
    o->st.ms_total += r->ms;
    return SOOC_OK;
#endif
}

sooc_status sooc_odom_current_frame(const sooc_odom *o, uint8_t *gray, float *depth, int *w, int *h, double K[4]) {
#if !SOOC_HAVE_OPENCV
    (void)o; (void)gray; (void)depth; (void)w; (void)h; (void)K;
    return sooc_seterr(SOOC_EUNSUPPORTED, "odometry: sooc3d was built without OpenCV");
#else
    char err[256] = "";
    if (!o->started) return sooc_seterr(SOOC_EINVAL, "odometry: no frame tracked yet");
    int rc = sooc_cvodo_current(o->cv, gray, depth, w, h, K, err, sizeof err);
    if (rc < 0) return sooc_seterr(SOOC_ERR, "odometry: %s", err);
    if (rc > 0 && gray) return sooc_seterr(SOOC_EUNSUPPORTED, "odometry: the icp variant keeps no grey image");
    return SOOC_OK;
#endif
}
