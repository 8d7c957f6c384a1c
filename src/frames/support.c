/* Support plane: the map's world frame from posed depth frames
 * (include/sooc3d/frame.h, docs/node.md "Support plane").
 *
 *  1. Up prior: the caller's hint, else minus the gravity file's direction,
 *     else the cameras (camera_up below).
 *  2. Candidates: up to SUPPORT_MAX_CANDIDATES level planes, fitted in turn by
 *     sooc_floor_fit (RANSAC with the tilt limit around the up prior, then a
 *     total least squares refit); the inliers of each are taken out before the
 *     next fit. A candidate needs min_support_frac of the points.
 *  3. Choice: among the candidates below every camera (each camera centre at
 *     least min_clearance_m above the plane) that hold at least
 *     lower_support_ratio of the largest such candidate's inliers, the lowest
 *     one along up. So a floor in view wins over a larger table top, and a bin
 *     bottom or table top is taken when no floor is in view.
 *  4. T_world_src: the smallest rotation taking the plane normal to +y, the
 *     plane to y = 0 (sooc_frames_world_from_up).
 *
 * All buffers are allocated once per call (no allocation per pixel).
 */
#include "sooc3d/frame.h"

#include "sooc3d/model.h"

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SUPPORT_MAX_CANDIDATES 6
#define DEG (3.14159265358979323846 / 180.0)

const char *sooc_up_source_name(sooc_up_source s) {
    switch (s) {
    case SOOC_UP_GIVEN: return "given";
    case SOOC_UP_GRAVITY_FILE: return "gravity file";
    case SOOC_UP_CAMERA_MEAN: return "camera mean";
    }
    return "unknown";
}

void sooc_support_params_default(sooc_support_params *p) {
    memset(p, 0, sizeof *p);
    p->max_tilt_deg = 30.0;
    p->threshold_m = 0.02;
    p->iterations = 300;
    p->max_frames = 8;
    p->pixel_step = 4;
    /* a default model's trained range at unit 1 (the unity/blender generators'
     * cameras); callers with a model pass its own (sooc_model_cam_heights_m) */
    p->cam_height_min_m = SOOC_MODEL_CAM_H_MIN;
    p->cam_height_max_m = SOOC_MODEL_CAM_H_MAX;
    p->seed = 1;
    p->max_tilt_camera_deg = 45.0;
    p->min_support_frac = 0.03;
    p->lower_support_ratio = 0.15;
    p->min_clearance_m = 0.05;
    p->max_points = 60000;
    p->max_depth_m = 8.0;
    p->parallel_deg = 5.0;
}

/* ------------------------------------------------------------- up prior */

/* Up from the cameras: OpenCV axes, so the image's down direction is the
 * camera's +y and its right direction +x. Cameras are rarely rolled, so up is
 * close to perpendicular to every camera's x axis: when the x axes span a
 * plane (the cameras turned), up is that plane's normal (smallest eigenvector
 * of sum x x^T), signed by the mean of -y. When they do not (one heading),
 * up is the mean of -y with its component along the common x axis removed;
 * that leaves the mean pitch as an error, which the wider tilt limit of this
 * source (max_tilt_camera_deg) covers. */
static sooc_status camera_up(const double *T, int n, double up[3], int *turned, double *roll_rms) {
    double m[3] = {0, 0, 0}, M[9] = {0};
    for (int i = 0; i < n; i++) {
        const double *R = T + 16 * i;
        double x[3] = {R[0], R[4], R[8]}, y[3] = {R[1], R[5], R[9]};
        for (int a = 0; a < 3; a++) {
            m[a] -= y[a] / n;
            for (int b = 0; b < 3; b++) M[3 * a + b] += x[a] * x[b] / n;
        }
    }
    if (sooc_v3_norm(m) < 0.3)
        return sooc_seterr(SOOC_ENOTFOUND,
                           "support plane: the cameras' image-down directions disagree (mean length %.2f); "
                           "give the up axis (world.up / --up)",
                           sooc_v3_norm(m));
    double w[3];
    lapack_int info = LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', 3, M, 3, w);   /* ascending */
    if (info != 0) return sooc_seterr(SOOC_ENUMERIC, "support plane: LAPACKE_dsyev failed (info %d)", (int)info);
    *turned = w[1] > 0.01 && w[1] > 10.0 * (w[0] > 0 ? w[0] : 0);
    *roll_rms = sqrt(w[0] > 0 ? w[0] : 0);   /* rms of x . up: the cameras' roll */
    if (*turned) {
        double e[3] = {M[0], M[3], M[6]};   /* eigenvectors are columns */
        if (sooc_v3_dot(e, m) < 0) sooc_v3_scale(e, e, -1);
        memcpy(up, e, sizeof e);
    } else {
        double e3[3] = {M[2], M[5], M[8]}, t[3];
        sooc_v3_scale(t, e3, sooc_v3_dot(m, e3));
        sooc_v3_sub(up, m, t);
    }
    if (sooc_v3_normalize(up) < 1e-6)
        return sooc_seterr(SOOC_ENOTFOUND, "support plane: no up direction from the cameras");
    return SOOC_OK;
}

/* ------------------------------------------------------------ the estimate */

typedef struct cand {
    double plane[4];
    size_t n_inliers;
    double rms, min_clear, mean_clear, tilt_deg;
} cand;

/* Fit up to SUPPORT_MAX_CANDIDATES planes within `tilt` deg of `up`, each on
 * the points the earlier ones left (a slab of twice the inlier distance is
 * taken out). rem: scratch of 3 * n_pts doubles. Returns the count; *best_fail
 * is the inlier count of the first fit that fell short of `need`. */
static int extract(const double *pts, size_t n_pts, double *rem, const double up[3], double tilt, size_t need,
                   const sooc_support_params *p, const double *T_src_c, int n_cams, cand *c, size_t *best_fail) {
    memcpy(rem, pts, 3 * sizeof(double) * n_pts);
    size_t m = n_pts;
    int nc = 0;
    sooc_floor_fit_params fp;
    sooc_floor_fit_params_default(&fp);
    fp.threshold_m = p->threshold_m;
    fp.iterations = p->iterations;
    fp.min_inlier_frac = 0;
    fp.max_tilt_deg = tilt;
    *best_fail = 0;
    for (int k = 0; k < SUPPORT_MAX_CANDIDATES && m >= need; k++) {
        fp.seed = p->seed + 7919u * (uint64_t)k;
        double pl[4], rms;
        size_t ni = 0;
        if (sooc_floor_fit(rem, m, &fp, up, NULL, pl, &ni, &rms)) break;
        if (ni < need) {
            *best_fail = ni;
            break;
        }
        cand *q = &c[nc++];
        memcpy(q->plane, pl, sizeof pl);
        q->n_inliers = ni;
        q->rms = rms;
        q->tilt_deg = acos(fmin(1.0, sooc_v3_dot(pl, up))) / DEG;
        q->min_clear = INFINITY;
        q->mean_clear = 0;
        for (int i = 0; i < n_cams; i++) {
            const double *T = T_src_c + 16 * i;
            double cam[3] = {T[3], T[7], T[11]};
            double s = sooc_v3_dot(pl, cam) + pl[3];
            if (s < q->min_clear) q->min_clear = s;
            q->mean_clear += s / n_cams;
        }
        size_t w = 0;
        for (size_t i = 0; i < m; i++) {
            const double *r = rem + 3 * i;
            if (fabs(sooc_v3_dot(pl, r) + pl[3]) <= 2 * p->threshold_m) continue;
            if (w != i) memmove(rem + 3 * w, r, 3 * sizeof(double));
            w++;
        }
        m = w;
    }
    return nc;
}


/* Total least squares plane through the points within `w` of height h0 along
 * `lvl`; the normal is kept within max_dev_deg of lvl (else lvl itself).
 * Returns the number of points used. */
static size_t tls_slab(const double *pts, size_t n, const double lvl[3], double h0, double w, double max_dev_deg,
                       double plane[4]) {
    double mean[3] = {0, 0, 0};
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        const double *q = pts + 3 * i;
        if (fabs(sooc_v3_dot(lvl, q) - h0) <= w) { sooc_v3_add(mean, mean, q); m++; }
    }
    memcpy(plane, lvl, 3 * sizeof(double));
    plane[3] = -h0;
    if (m < 3) return m;
    sooc_v3_scale(mean, mean, 1.0 / (double)m);
    double S[9] = {0}, ev[3];
    for (size_t i = 0; i < n; i++) {
        const double *q = pts + 3 * i;
        if (fabs(sooc_v3_dot(lvl, q) - h0) > w) continue;
        double d[3];
        sooc_v3_sub(d, q, mean);
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) S[3 * a + b] += d[a] * d[b];
    }
    double nrm[3];
    if (LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', 3, S, 3, ev) == 0) {
        nrm[0] = S[0]; nrm[1] = S[3]; nrm[2] = S[6];   /* smallest eigenvalue's eigenvector */
        if (sooc_v3_dot(nrm, lvl) < 0) sooc_v3_scale(nrm, nrm, -1);
        if (sooc_v3_dot(nrm, lvl) < cos(max_dev_deg * DEG)) memcpy(nrm, lvl, sizeof nrm);
    } else {
        memcpy(nrm, lvl, sizeof nrm);
    }
    memcpy(plane, nrm, sizeof nrm);
    plane[3] = -sooc_v3_dot(nrm, mean);
    return m;
}

static void clearance(cand *q, const double *T_src_c, int n_cams) {
    q->min_clear = INFINITY;
    q->mean_clear = 0;
    for (int i = 0; i < n_cams; i++) {
        const double *T = T_src_c + 16 * i;
        double cam[3] = {T[3], T[7], T[11]};
        double s = sooc_v3_dot(q->plane, cam) + q->plane[3];
        if (s < q->min_clear) q->min_clear = s;
        q->mean_clear += s / n_cams;
    }
}

/* Stage 2: the planes perpendicular to `lvl` (within max_dev_deg): peaks of
 * the histogram of heights lvl . p (bins of half the threshold, a peak counts
 * the points within one threshold), strongest first, each refitted three
 * times by total least squares on its inliers and recounted. */
static int level_planes(const double *pts, size_t n, const double lvl[3], double max_dev_deg, size_t need,
                        const sooc_support_params *p, const double *T_src_c, int n_cams, cand *c) {
    double hmin = INFINITY, hmax = -INFINITY;
    for (size_t i = 0; i < n; i++) {
        double h = sooc_v3_dot(lvl, pts + 3 * i);
        if (h < hmin) hmin = h;
        if (h > hmax) hmax = h;
    }
    double bw = 0.5 * p->threshold_m;
    if ((hmax - hmin) / bw > 8192) bw = (hmax - hmin) / 8192;
    int nb = (int)((hmax - hmin) / bw) + 1;
    size_t *hist = sooc_calloc((size_t)nb + 1, sizeof *hist);
    if (!hist) return -1;
    for (size_t i = 0; i < n; i++) hist[(int)((sooc_v3_dot(lvl, pts + 3 * i) - hmin) / bw)]++;
    int half = (int)ceil(p->threshold_m / bw);   /* a peak counts the points within one threshold */
    int nc = 0;
    while (nc < SUPPORT_MAX_CANDIDATES) {
        size_t best = 0;
        int bb = -1;
        for (int b = 0; b < nb; b++) {
            size_t cnt = 0;
            for (int j = b - half; j <= b + half; j++)
                if (j >= 0 && j < nb) cnt += hist[j];
            if (cnt > best) { best = cnt; bb = b; }
        }
        if (bb < 0 || best < need) break;
        double h0 = hmin + (bb + 0.5) * bw;
        cand *q = &c[nc];
        tls_slab(pts, n, lvl, h0, p->threshold_m, max_dev_deg, q->plane);
        for (int r = 0; r < 2; r++) {   /* refit on the inliers of the refitted plane */
            double nn[3] = {q->plane[0], q->plane[1], q->plane[2]};
            tls_slab(pts, n, nn, -q->plane[3], p->threshold_m, max_dev_deg, q->plane);
            if (sooc_v3_dot(q->plane, lvl) < cos(max_dev_deg * DEG)) {
                memcpy(q->plane, lvl, 3 * sizeof(double));
                q->plane[3] = -h0;
            }
        }
        size_t cnt = 0;
        double sse = 0;
        for (size_t i = 0; i < n; i++) {
            double r = fabs(sooc_v3_dot(q->plane, pts + 3 * i) + q->plane[3]);
            if (r <= p->threshold_m) { cnt++; sse += r * r; }
        }
        for (int j = bb - 3 * half; j <= bb + 3 * half; j++)   /* suppress this peak (3 thresholds) */
            if (j >= 0 && j < nb) hist[j] = 0;
        if (cnt < need) continue;
        q->n_inliers = cnt;
        q->rms = cnt ? sqrt(sse / (double)cnt) : 0;
        q->tilt_deg = 0;
        clearance(q, T_src_c, n_cams);
        nc++;
    }
    sooc_free(hist);
    return nc;
}

static void log_cands(const char *stage, const cand *c, int nc, int pick) {
    for (int k = 0; k < nc; k++)
        sooc_log(SOOC_LOG_DEBUG,
                 "support plane: %s candidate %d: n = (%.3f %.3f %.3f) d = %.3f, %zu inliers, rms %.4f, tilt %.1f "
                 "deg, camera clearance min %.3f mean %.3f m%s",
                 stage, k, c[k].plane[0], c[k].plane[1], c[k].plane[2], c[k].plane[3], c[k].n_inliers, c[k].rms,
                 c[k].tilt_deg, c[k].min_clear, c[k].mean_clear, k == pick ? " (chosen)" : "");
}

sooc_status sooc_support_estimate_points(const double *pts, size_t n_pts, const double *T_src_c, int n_cams,
                                         const sooc_support_params *pp, sooc_support *out) {
    sooc_support_params p;
    if (pp) p = *pp;
    else sooc_support_params_default(&p);
    memset(out, 0, sizeof *out);
    if (n_cams < 1) return sooc_seterr(SOOC_EINVAL, "support plane: no camera pose");
    if (n_pts < 3) return sooc_seterr(SOOC_ENOTFOUND, "support plane: only %zu depth points", n_pts);
    double up[3];
    double tilt = p.max_tilt_deg;
    int turned = 1;         /* cameras that turned: up from them is closer */
    double roll_rms = 0;    /* rms sine of the cameras' roll about the estimated up */
    if (p.has_up_hint) {
        memcpy(up, p.up_hint, sizeof up);
        out->up_source = SOOC_UP_GIVEN;
    } else if (p.has_gravity) {
        sooc_v3_scale(up, p.gravity, -1);
        out->up_source = SOOC_UP_GRAVITY_FILE;
    } else {
        sooc_status st = camera_up(T_src_c, n_cams, up, &turned, &roll_rms);
        if (st) return st;
        out->up_source = SOOC_UP_CAMERA_MEAN;
        if (!turned && p.max_tilt_camera_deg > tilt) tilt = p.max_tilt_camera_deg;
    }
    if (!(sooc_v3_normalize(up) > 1e-9)) return sooc_seterr(SOOC_EINVAL, "support plane: up direction has zero length");

    double *rem = sooc_malloc(3 * sizeof(double) * n_pts);
    if (!rem) return sooc_seterr(SOOC_ENOMEM, "support plane: out of memory (%zu points)", n_pts);
    size_t need = (size_t)ceil(p.min_support_frac * (double)n_pts);
    if (need < 30) need = 30;
    cand a[SUPPORT_MAX_CANDIDATES], c[SUPPORT_MAX_CANDIDATES];
    size_t best_fail = 0;
    /* stage 1: is there a plane within the tilt limit at all? */
    int na = extract(pts, n_pts, rem, up, tilt, need, &p, T_src_c, n_cams, a, &best_fail);
    log_cands("tilt-limited", a, na, -1);
    sooc_free(rem);
    if (na == 0)
        return sooc_seterr(SOOC_ENOTFOUND,
                           "support plane: no plane within %.0f deg of the up direction (%.3f %.3f %.3f, %s): "
                           "the best has %zu of %zu points as inliers, %zu needed; check the up axis "
                           "(world.up) and the depth scale",
                           tilt, up[0], up[1], up[2], sooc_up_source_name(out->up_source), best_fail, n_pts, need);
    /* stage 2: the planes perpendicular to the level direction. Up from
     * cameras that turned and kept level (roll under 2 deg rms: an arm, a
     * robot) is used as it is; otherwise (hand-held, or one heading, where
     * the mean pitch biases it) the level direction is the normal of the
     * tilt-limited plane with the most support, each counting the inliers of
     * the planes parallel to it (within parallel_deg): the floor, tables and
     * shelves of a room agree on one normal. */
    double lvl[3];
    memcpy(lvl, up, sizeof lvl);
    if (out->up_source == SOOC_UP_CAMERA_MEAN && !(turned && roll_rms < sin(2 * DEG))) {
        int ia = 0;
        size_t best_sup = 0;
        for (int k = 0; k < na; k++) {
            size_t sup = 0;
            for (int j = 0; j < na; j++)
                if (sooc_v3_dot(a[k].plane, a[j].plane) >= cos(p.parallel_deg * DEG)) sup += a[j].n_inliers;
            if (sup > best_sup) { best_sup = sup; ia = k; }
        }
        memcpy(lvl, a[ia].plane, sizeof lvl);
        sooc_log(SOOC_LOG_DEBUG, "support plane: level direction from candidate %d (%.3f %.3f %.3f), roll %.1f deg rms%s",
                 ia, lvl[0], lvl[1], lvl[2], asin(fmin(1, roll_rms)) / DEG, turned ? "" : ", cameras did not turn");
    }
    int nc;
    nc = level_planes(pts, n_pts, lvl, p.parallel_deg, need, &p, T_src_c, n_cams, c);
    if (nc < 0) return sooc_seterr(SOOC_ENOMEM, "support plane: out of memory");
    for (int k = 0; k < nc; k++) c[k].tilt_deg = acos(fmin(1.0, sooc_v3_dot(c[k].plane, up))) / DEG;

    size_t largest = 0;
    for (int k = 0; k < nc; k++)
        if (c[k].min_clear >= p.min_clearance_m && c[k].n_inliers > largest) largest = c[k].n_inliers;
    int pick = -1;
    for (int k = 0; k < nc; k++) {
        if (c[k].min_clear < p.min_clearance_m) continue;
        if ((double)c[k].n_inliers < p.lower_support_ratio * (double)largest) continue;
        if (pick < 0 || c[k].mean_clear > c[pick].mean_clear) pick = k;   /* lowest: farthest below the cameras */
    }
    log_cands("parallel", c, nc, pick);
    if (pick < 0) {
        double cl = nc ? c[0].min_clear : a[0].min_clear;
        return sooc_seterr(SOOC_ENOTFOUND,
                           "support plane: %d level plane(s) within %.0f deg of the up direction (%.3f %.3f %.3f, "
                           "%s), none below every camera (the strongest lies %.3f m %s the lowest camera); check "
                           "the up axis (world.up; without it the cameras give one)",
                           nc, tilt, up[0], up[1], up[2], sooc_up_source_name(out->up_source), fabs(cl),
                           cl < 0 ? "above" : "below");
    }
    const cand *q = &c[pick];
    memcpy(out->plane_src, q->plane, sizeof out->plane_src);
    memcpy(out->up_src, q->plane, 3 * sizeof(double));
    sooc_frames_world_from_up(q->plane, -q->plane[3], out->T_world_src);
    out->tilt_deg = q->tilt_deg;
    out->cam_height_m = q->mean_clear;
    /* no range (min >= max: the geometric map has none): nothing to warn about */
    out->height_warning = p.cam_height_max_m > p.cam_height_min_m &&
                          (q->mean_clear < p.cam_height_min_m || q->mean_clear > p.cam_height_max_m);
    out->n_inliers = q->n_inliers;
    out->n_points = n_pts;
    out->rms_m = q->rms;
    out->frames_used = n_cams;
    out->n_candidates = nc;
    return SOOC_OK;
}

/* Back-project frame f into pts (source frame): every `step`-th pixel with
 * depth in (0, max_depth], then every `keep`-th of those. */
static size_t frame_points(const sooc_frame *f, int step, size_t keep, double max_depth, double *pts, size_t cap) {
    size_t n = 0, seen = 0;
    for (int v = step / 2; v < f->height && n < cap; v += step)
        for (int u = step / 2; u < f->width && n < cap; u += step) {
            size_t i = (size_t)v * f->width + u;
            float z = f->depth[i];
            if (!(z > 0.0f) || !isfinite(z) || z > max_depth) continue;
            if (f->valid && !f->valid[i]) continue;
            if (seen++ % keep) continue;
            double pc[3] = {((u + 0.5) - f->K.cx) / f->K.fx * z, ((v + 0.5) - f->K.cy) / f->K.fy * z, z};
            sooc_se3_apply(pts + 3 * n, f->T_wc, pc);
            n++;
        }
    return n;
}

sooc_status sooc_support_estimate(const sooc_frame *const *frames, int n, const sooc_support_params *pp,
                                  sooc_support *out) {
    sooc_support_params p;
    if (pp) p = *pp;
    else sooc_support_params_default(&p);
    memset(out, 0, sizeof *out);
    int posed = 0;
    for (int i = 0; i < n; i++)
        if (frames[i] && frames[i]->has_pose && frames[i]->depth) posed++;
    if (posed == 0) return sooc_seterr(SOOC_EINVAL, "support plane: none of the %d frames has a pose and depth", n);
    int use = p.max_frames > 0 && posed > p.max_frames ? p.max_frames : posed;
    int step = p.pixel_step < 1 ? 1 : p.pixel_step;
    size_t cap = p.max_points > 0 ? (size_t)p.max_points : 60000;
    size_t per = cap / (size_t)use;
    double *pts = sooc_malloc(3 * sizeof(double) * cap);
    double *T = sooc_malloc(16 * sizeof(double) * (size_t)use);
    if (!pts || !T) {
        sooc_free(pts);
        sooc_free(T);
        return sooc_seterr(SOOC_ENOMEM, "support plane: out of memory");
    }
    size_t np = 0;
    int k = 0;
    for (int j = 0, seen = 0; j < n && k < use; j++) {
        const sooc_frame *f = frames[j];
        if (!(f && f->has_pose && f->depth)) continue;
        /* the use frames spread evenly over the posed ones */
        int want = (int)((long long)k * posed / use);
        if (seen++ != want) continue;
        if (f->K.fx == 0 || f->K.fy == 0) {
            sooc_free(pts);
            sooc_free(T);
            return sooc_seterr(SOOC_EINVAL, "support plane: frame %lld has no intrinsics", (long long)f->index);
        }
        /* thin the pixels so each frame contributes at most `per` points */
        size_t grid = (size_t)((f->width + step - 1) / step) * (size_t)((f->height + step - 1) / step);
        size_t keep = grid / per + 1;
        np += frame_points(f, step, keep, p.max_depth_m > 0 ? p.max_depth_m : INFINITY, pts + 3 * np, cap - np);
        memcpy(T + 16 * k, f->T_wc, 16 * sizeof(double));
        k++;
    }
    sooc_status st = sooc_support_estimate_points(pts, np, T, k, &p, out);
    sooc_free(pts);
    sooc_free(T);
    return st;
}

sooc_status sooc_support_read_gravity(const char *path, double g[3]) {
    FILE *fp = fopen(path, "r");
    if (!fp) return sooc_seterr(SOOC_ENOTFOUND, "%s: cannot open the gravity file", path);
    double v[3];
    int k = 0;
    char tok[64];
    sooc_status st = SOOC_OK;
    while (fscanf(fp, "%63s", tok) == 1) {
        char *end;
        double x = strtod(tok, &end);
        if (end == tok || *end || !isfinite(x)) {
            st = sooc_seterr(SOOC_EFORMAT, "%s: '%s' is not a number (want gravity x y z)", path, tok);
            break;
        }
        if (k == 3) {
            st = sooc_seterr(SOOC_EFORMAT, "%s: more than 3 numbers (want gravity x y z)", path);
            break;
        }
        v[k++] = x;
    }
    fclose(fp);
    if (st) return st;
    if (k != 3) return sooc_seterr(SOOC_EFORMAT, "%s: %d numbers, want 3 (gravity x y z)", path, k);
    double nrm = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(nrm > 1e-9)) return sooc_seterr(SOOC_EINVAL, "%s: gravity direction has zero length", path);
    for (int i = 0; i < 3; i++) g[i] = v[i] / nrm;
    return SOOC_OK;
}
