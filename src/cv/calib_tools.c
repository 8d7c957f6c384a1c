/* Calibration boards and calibration (include/sooc3d/slam.h): board specs,
 * a ray-traced board renderer for tests with known truth, detection,
 * intrinsics (calibrateCamera) and hand-eye (calibrateHandEye) through
 * cvshim.h. */
#include "sooc3d/slam.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sooc3d/core.h"

#if SOOC_HAVE_OPENCV
#include "cvshim.h"
#endif

#define NO_OPENCV_MSG "sooc3d was built without OpenCV (install libopencv-contrib-dev, rebuild with -DSOOC_WITH_OPENCV=ON)"

static const struct {
    const char *name;
    int id;   /* cv::aruco::PREDEFINED_DICTIONARY_NAME */
} g_dicts[] = {{"4x4_50", 0}, {"4x4_100", 1}, {"4x4_250", 2}, {"5x5_50", 4}, {"5x5_100", 5},
               {"5x5_250", 6}, {"6x6_50", 8}, {"6x6_100", 9}, {"6x6_250", 10}};
#define NDICTS (sizeof g_dicts / sizeof g_dicts[0])

sooc_status sooc_board_parse(const char *spec, sooc_board *b) {
    memset(b, 0, sizeof *b);
    char kind[16] = "", dict[16] = "";
    int sx = 0, sy = 0, used = 0;
    double sq = 0, mk = 0;
    if (!spec) spec = "";
    if (!strncmp(spec, "charuco:", 8)) {
        int k = sscanf(spec + 8, "%dx%d:%lf:%lf%n", &sx, &sy, &sq, &mk, &used);
        if (k != 4) goto bad;
        const char *rest = spec + 8 + used;
        if (*rest == ':') {
            snprintf(dict, sizeof dict, "%s", rest + 1);
        } else if (*rest) {
            goto bad;
        }
        b->kind = SOOC_BOARD_CHARUCO;
        b->dict = 0;
        if (dict[0]) {
            int found = 0;
            for (size_t i = 0; i < NDICTS; i++)
                if (!strcmp(dict, g_dicts[i].name)) {
                    b->dict = g_dicts[i].id;
                    found = 1;
                }
            if (!found)
                return sooc_seterr(SOOC_EINVAL, "board '%s': unknown dictionary '%s' (4x4_50, 4x4_100, 4x4_250, "
                                   "5x5_50, 5x5_100, 5x5_250, 6x6_50, 6x6_100, 6x6_250)", spec, dict);
        }
        if (!(mk > 0 && mk < sq))
            return sooc_seterr(SOOC_EINVAL, "board '%s': marker side %g must be in (0, square %g)", spec, mk, sq);
    } else if (!strncmp(spec, "checker:", 8)) {
        int k = sscanf(spec + 8, "%dx%d:%lf%n", &sx, &sy, &sq, &used);
        if (k != 3 || spec[8 + used]) goto bad;
        b->kind = SOOC_BOARD_CHECKER;
    } else {
        goto bad;
    }
    (void)kind;
    if (sx < 3 || sy < 3 || sx > 64 || sy > 64 || !(sq > 0 && sq < 10))
        return sooc_seterr(SOOC_EINVAL, "board '%s': need 3..64 squares each way and a square side in (0, 10) m",
                           spec);
    b->squares_x = sx;
    b->squares_y = sy;
    b->square_m = sq;
    b->marker_m = mk;
    return SOOC_OK;
bad:
    return sooc_seterr(SOOC_EINVAL,
                       "board '%s': expected charuco:<sx>x<sy>:<square_m>:<marker_m>[:<dict>] or "
                       "checker:<sx>x<sy>:<square_m>",
                       spec);
}

size_t sooc_board_format(const sooc_board *b, char *buf, size_t cap) {
    if (b->kind == SOOC_BOARD_CHECKER)
        return (size_t)snprintf(buf, cap, "checker:%dx%d:%g", b->squares_x, b->squares_y, b->square_m);
    const char *d = "4x4_50";
    for (size_t i = 0; i < NDICTS; i++)
        if (g_dicts[i].id == b->dict) d = g_dicts[i].name;
    return (size_t)snprintf(buf, cap, "charuco:%dx%d:%g:%g:%s", b->squares_x, b->squares_y, b->square_m, b->marker_m,
                            d);
}

void sooc_board_view_free(sooc_board_view *v) {
    sooc_free(v->obj);
    sooc_free(v->img);
    memset(v, 0, sizeof *v);
}

void sooc_calib_report_free(sooc_calib_report *r) {
    sooc_free(r->T_cam_board);
    sooc_free(r->view_index);
    r->T_cam_board = NULL;
    r->view_index = NULL;
}

#if SOOC_HAVE_OPENCV

static sooc_status board_open(const sooc_board *b, sooc_cvboard **cb) {
    char err[512] = "";
    if (sooc_cvboard_create(cb, (int)b->kind, b->squares_x, b->squares_y, b->square_m, b->marker_m, b->dict, err,
                            sizeof err))
        return sooc_seterr(SOOC_ERR, "board: %s", err);
    return SOOC_OK;
}

/* to gray (caller frees *g when *own) */
static sooc_status to_gray(const sooc_image *img, const uint8_t **g, uint8_t **own) {
    *own = NULL;
    size_t n = (size_t)img->width * (size_t)img->height;
    if (img->fmt == SOOC_PIX_GRAY8) {
        *g = img->data;
        return SOOC_OK;
    }
    if (img->fmt != SOOC_PIX_RGB8)
        return sooc_seterr(SOOC_EINVAL, "board detection: image format %s (need 8-bit gray or RGB)",
                           sooc_pixfmt_name(img->fmt));
    uint8_t *o = sooc_malloc(n ? n : 1);
    if (!o) return sooc_seterr(SOOC_ENOMEM, "board detection: out of memory");
    const uint8_t *s = img->data;
    for (size_t i = 0; i < n; i++)
        o[i] = (uint8_t)((299 * s[3 * i] + 587 * s[3 * i + 1] + 114 * s[3 * i + 2] + 500) / 1000);
    *g = o;
    *own = o;
    return SOOC_OK;
}

/* The board texture: the flat board with a one-square white margin, pps
 * pixels per square, and the affine map board metres -> texture pixels
 * (u = A0 X + A1 Y + A2, v = A3 X + A4 Y + A5; OpenCV pixel centres). */
typedef struct texture {
    int w, h;
    uint8_t *px;
    double A[6];
} texture;

static sooc_status texture_make(const sooc_board *b, sooc_cvboard *cb, texture *t) {
    const int pps = 64;
    int bw = b->squares_x * pps, bh = b->squares_y * pps;
    t->w = bw + 2 * pps;
    t->h = bh + 2 * pps;
    t->px = sooc_malloc((size_t)t->w * t->h);
    uint8_t *flat = sooc_malloc((size_t)bw * bh);
    if (!t->px || !flat) {
        sooc_free(flat);
        return sooc_seterr(SOOC_ENOMEM, "board texture: out of memory");
    }
    char err[512] = "";
    if (sooc_cvboard_draw(cb, flat, bw, bh, err, sizeof err)) {
        sooc_free(flat);
        return sooc_seterr(SOOC_ERR, "board texture: %s", err);
    }
    memset(t->px, 255, (size_t)t->w * t->h);
    for (int y = 0; y < bh; y++) memcpy(t->px + (size_t)(y + pps) * t->w + pps, flat + (size_t)y * bw, (size_t)bw);
    sooc_free(flat);
    double s = pps / b->square_m;
    if (b->kind == SOOC_BOARD_CHECKER) {
        /* inner corner (0, 0) is the corner between the first two squares */
        double A[6] = {s, 0, 2.0 * pps - 0.5, 0, s, 2.0 * pps - 0.5};
        memcpy(t->A, A, sizeof A);
        return SOOC_OK;
    }
    /* ChArUco: OpenCV decides where its board frame lies on the drawing;
     * recover it by detecting the flat board and fitting the affine map,
     * then snap the linear part to the exact scale (0 or +-s). */
    int cap = sooc_cvboard_npoints(cb), n = 0;
    double *obj = sooc_malloc((size_t)cap * 3 * sizeof(double)), *img = sooc_malloc((size_t)cap * 2 * sizeof(double));
    if (!obj || !img) {
        sooc_free(obj);
        sooc_free(img);
        return sooc_seterr(SOOC_ENOMEM, "board texture: out of memory");
    }
    if (sooc_cvboard_detect(cb, t->px, t->w, t->h, obj, img, cap, &n, err, sizeof err) || n < 4) {
        sooc_free(obj);
        sooc_free(img);
        return sooc_seterr(SOOC_ERR, "board texture: OpenCV does not find its own drawn board (%d corners) %s", n,
                           err);
    }
    /* normal equations for [X Y 1] -> u and v */
    double M[9] = {0}, bu[3] = {0}, bv[3] = {0};
    for (int i = 0; i < n; i++) {
        double r[3] = {obj[3 * i], obj[3 * i + 1], 1};
        for (int a = 0; a < 3; a++) {
            for (int c = 0; c < 3; c++) M[3 * a + c] += r[a] * r[c];
            bu[a] += r[a] * img[2 * i];
            bv[a] += r[a] * img[2 * i + 1];
        }
    }
    double Mi[9], det = sooc_m3_det(M);
    if (fabs(det) < 1e-12) {
        sooc_free(obj);
        sooc_free(img);
        return sooc_seterr(SOOC_ERR, "board texture: degenerate corner fit");
    }
    /* inverse by cofactors */
    Mi[0] = (M[4] * M[8] - M[5] * M[7]) / det;
    Mi[1] = (M[2] * M[7] - M[1] * M[8]) / det;
    Mi[2] = (M[1] * M[5] - M[2] * M[4]) / det;
    Mi[3] = (M[5] * M[6] - M[3] * M[8]) / det;
    Mi[4] = (M[0] * M[8] - M[2] * M[6]) / det;
    Mi[5] = (M[2] * M[3] - M[0] * M[5]) / det;
    Mi[6] = (M[3] * M[7] - M[4] * M[6]) / det;
    Mi[7] = (M[1] * M[6] - M[0] * M[7]) / det;
    Mi[8] = (M[0] * M[4] - M[1] * M[3]) / det;
    double cu[3], cv[3];
    sooc_m3_mulv(cu, Mi, bu);
    sooc_m3_mulv(cv, Mi, bv);
    double lin[4] = {cu[0], cu[1], cv[0], cv[1]};
    for (int k = 0; k < 4; k++) lin[k] = fabs(lin[k]) < 0.5 * s ? 0 : (lin[k] > 0 ? s : -s);
    /* offsets: mean residual with the snapped linear part */
    double ou = 0, ov = 0;
    for (int i = 0; i < n; i++) {
        ou += img[2 * i] - lin[0] * obj[3 * i] - lin[1] * obj[3 * i + 1];
        ov += img[2 * i + 1] - lin[2] * obj[3 * i] - lin[3] * obj[3 * i + 1];
    }
    ou /= n;
    ov /= n;
    /* board edges fall on pixel edges: offsets are k * pps - 0.5 */
    ou = floor((ou + 0.5) / pps + 0.5) * pps - 0.5;
    ov = floor((ov + 0.5) / pps + 0.5) * pps - 0.5;
    double A[6] = {lin[0], lin[1], ou, lin[2], lin[3], ov};
    memcpy(t->A, A, sizeof A);
    sooc_free(obj);
    sooc_free(img);
    return SOOC_OK;
}

static double tex_sample(const texture *t, double u, double v) {
    if (u < 0 || v < 0 || u > t->w - 1 || v > t->h - 1) return 128.0;   /* the wall */
    int x0 = (int)u, y0 = (int)v;
    int x1 = x0 + 1 < t->w ? x0 + 1 : x0, y1 = y0 + 1 < t->h ? y0 + 1 : y0;
    double fx = u - x0, fy = v - y0;
    const uint8_t *p = t->px;
    double a = p[(size_t)y0 * t->w + x0] * (1 - fx) + p[(size_t)y0 * t->w + x1] * fx;
    double c = p[(size_t)y1 * t->w + x0] * (1 - fx) + p[(size_t)y1 * t->w + x1] * fx;
    return a * (1 - fy) + c * fy;
}

/* normalised undistorted coordinates of an OpenCV pixel (fixed-point
 * inversion of the plumb-bob model) */
static void undistort(const sooc_intrinsics *K, double u, double v, double *xn, double *yn) {
    double x = (u - K->cx) / K->fx, y = (v - K->cy) / K->fy;
    if (K->dist_model != SOOC_DIST_PLUMB_BOB && K->dist_model != SOOC_DIST_RATIONAL) {
        *xn = x;
        *yn = y;
        return;
    }
    const double *d = K->dist;
    double x0 = x, y0 = y;
    for (int it = 0; it < 20; it++) {
        double r2 = x * x + y * y;
        double rad = 1 + d[0] * r2 + d[1] * r2 * r2 + d[4] * r2 * r2 * r2;
        double dx = 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
        double dy = d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;
        x = (x0 - dx) / rad;
        y = (y0 - dy) / rad;
    }
    *xn = x;
    *yn = y;
}

sooc_status sooc_board_render(const sooc_board *b, const sooc_intrinsics *K, const double T_cam_board[16], int ss,
                              double noise, uint64_t seed, sooc_image *out) {
    if (K->width <= 0 || K->height <= 0 || !(K->fx > 0 && K->fy > 0))
        return sooc_seterr(SOOC_EINVAL, "board render: bad intrinsics %dx%d f %g %g", K->width, K->height, K->fx,
                           K->fy);
    if (ss < 1 || ss > 8) return sooc_seterr(SOOC_EINVAL, "board render: supersampling %d not in 1..8", ss);
    sooc_cvboard *cb = NULL;
    sooc_status st = board_open(b, &cb);
    if (st) return st;
    texture t;
    memset(&t, 0, sizeof t);
    if ((st = texture_make(b, cb, &t))) goto out;
    if ((st = sooc_image_alloc(out, K->width, K->height, SOOC_PIX_RGB8))) goto out;
    double T_bc[16];
    sooc_se3_inverse(T_bc, T_cam_board);
    const double o[3] = {T_bc[3], T_bc[7], T_bc[11]};
    sooc_rng rng;
    sooc_rng_seed(&rng, seed, 77);
    for (int y = 0; y < K->height; y++)
        for (int x = 0; x < K->width; x++) {
            double acc = 0;
            for (int sy = 0; sy < ss; sy++)
                for (int sx = 0; sx < ss; sx++) {
                    double u = x - 0.5 + (sx + 0.5) / ss, v = y - 0.5 + (sy + 0.5) / ss;
                    double xn, yn, d[3], dc[3];
                    undistort(K, u, v, &xn, &yn);
                    dc[0] = xn;
                    dc[1] = yn;
                    dc[2] = 1;
                    sooc_se3_rotate(d, T_bc, dc);
                    double val = 128.0;
                    if (fabs(d[2]) > 1e-12) {
                        double s = -o[2] / d[2];
                        if (s > 0) {
                            double X = o[0] + s * d[0], Y = o[1] + s * d[1];
                            val = tex_sample(&t, t.A[0] * X + t.A[1] * Y + t.A[2], t.A[3] * X + t.A[4] * Y + t.A[5]);
                        }
                    }
                    acc += val;
                }
            double g = acc / (ss * ss) + (noise > 0 ? noise * sooc_rng_normal(&rng) : 0);
            uint8_t q = (uint8_t)(g < 0 ? 0 : (g > 255 ? 255 : g + 0.5));
            uint8_t *p = (uint8_t *)out->data + 3 * ((size_t)y * K->width + x);
            p[0] = p[1] = p[2] = q;
        }
out:
    sooc_free(t.px);
    sooc_cvboard_destroy(cb);
    return st;
}

sooc_status sooc_board_layout(const sooc_board *b, double center[3], double *front_z, double *y_down) {
    sooc_cvboard *cb = NULL;
    sooc_status st = board_open(b, &cb);
    if (st) return st;
    texture t;
    memset(&t, 0, sizeof t);
    st = texture_make(b, cb, &t);
    if (!st) {
        /* invert the affine map at the texture centre */
        double det = t.A[0] * t.A[4] - t.A[1] * t.A[3];
        double u = 0.5 * (t.w - 1) - t.A[2], v = 0.5 * (t.h - 1) - t.A[5];
        center[0] = (t.A[4] * u - t.A[1] * v) / det;
        center[1] = (-t.A[3] * u + t.A[0] * v) / det;
        center[2] = 0;
        *front_z = det > 0 ? -1 : 1;
        *y_down = t.A[4] >= 0 ? 1 : -1;
    }
    sooc_free(t.px);
    sooc_cvboard_destroy(cb);
    return st;
}

static sooc_status detect_with(const sooc_board *b, sooc_cvboard *cb, const sooc_image *img, sooc_board_view *view) {
    sooc_board_view_free(view);
    int cap = (b->squares_x - 1) * (b->squares_y - 1);
    view->obj = sooc_malloc((size_t)cap * 3 * sizeof(double));
    view->img = sooc_malloc((size_t)cap * 2 * sizeof(double));
    if (!view->obj || !view->img) return sooc_seterr(SOOC_ENOMEM, "board detection: out of memory");
    const uint8_t *g = NULL;
    uint8_t *own = NULL;
    sooc_status st = to_gray(img, &g, &own);
    if (st) return st;
    char err[512] = "";
    int r = sooc_cvboard_detect(cb, g, img->width, img->height, view->obj, view->img, cap, &view->n, err, sizeof err);
    sooc_free(own);
    if (r) return sooc_seterr(SOOC_ERR, "board detection: %s", err);
    return SOOC_OK;
}

sooc_status sooc_board_detect(const sooc_board *b, const sooc_image *img, sooc_board_view *view) {
    sooc_cvboard *cb = NULL;
    sooc_status st = board_open(b, &cb);
    if (!st) st = detect_with(b, cb, img, view);
    sooc_cvboard_destroy(cb);
    return st;
}

/* Detect the board in every image; views[i].n = 0 where it is missing. */
static sooc_status detect_all(const sooc_board *b, const char *const *paths, int n, sooc_board_view *views, int *w,
                              int *h) {
    sooc_cvboard *cb = NULL;
    sooc_status st = board_open(b, &cb);
    if (st) return st;
    sooc_image img;
    memset(&img, 0, sizeof img);
    for (int i = 0; i < n && !st; i++) {
        st = sooc_image_read(paths[i], &img);
        if (st) {
            st = sooc_adderr(st, "calibration image %s", paths[i]);
            break;
        }
        if (i == 0) {
            *w = img.width;
            *h = img.height;
        } else if (img.width != *w || img.height != *h) {
            st = sooc_seterr(SOOC_EINVAL, "%s: image is %dx%d, %s is %dx%d", paths[i], img.width, img.height,
                             paths[0], *w, *h);
            break;
        }
        st = detect_with(b, cb, &img, &views[i]);
        if (st) st = sooc_adderr(st, "%s", paths[i]);
        sooc_image_free(&img);
    }
    sooc_image_free(&img);
    sooc_cvboard_destroy(cb);
    return st;
}

/* "a.png, b.png (+3 more)" into buf */
static void list_failed(const char *const *paths, const sooc_board_view *views, int n, int min_points, char *buf,
                        size_t cap) {
    size_t len = 0;
    int shown = 0, more = 0;
    buf[0] = 0;
    for (int i = 0; i < n; i++) {
        if (views[i].n >= min_points) continue;
        if (shown < 4) {
            const char *base = strrchr(paths[i], '/');
            base = base ? base + 1 : paths[i];
            int k = snprintf(buf + len, cap - len, "%s%s (%d corners)", shown ? ", " : "", base, views[i].n);
            if (k > 0 && (size_t)k < cap - len) len += (size_t)k;
            shown++;
        } else {
            more++;
        }
    }
    if (more && len < cap) snprintf(buf + len, cap - len, " and %d more", more);
}

sooc_status sooc_calib_intrinsics(const sooc_board *b, const char *const *paths, int n, int min_views, int min_points,
                                  int dist_n, sooc_calib *calib, sooc_calib_report *rep) {
    memset(rep, 0, sizeof *rep);
    rep->views_given = n;
    if (dist_n != 0 && dist_n != 4 && dist_n != 5)
        return sooc_seterr(SOOC_EINVAL, "calibration: distortion coefficients %d (0, 4 or 5)", dist_n);
    if (min_points < 4) min_points = 4;
    if (min_views < 3) min_views = 3;
    if (n < min_views)
        return sooc_seterr(SOOC_EINVAL, "calibration: %d images given, need at least %d views of the board", n,
                           min_views);
    sooc_board_view *views = sooc_calloc((size_t)n, sizeof *views);
    if (!views) return sooc_seterr(SOOC_ENOMEM, "calibration: out of memory");
    int w = 0, h = 0, used = 0;
    size_t total = 0;
    int *counts = NULL;
    double *obj = NULL, *img = NULL, K[4], dist[5], rms = 0, *Tcb = NULL;
    sooc_status st = detect_all(b, paths, n, views, &w, &h);
    if (st) goto out;
    for (int i = 0; i < n; i++)
        if (views[i].n >= min_points) {
            used++;
            total += (size_t)views[i].n;
        }
    if (used < min_views) {
        char failed[1024];
        list_failed(paths, views, n, min_points, failed, sizeof failed);
        char bs[96];
        sooc_board_format(b, bs, sizeof bs);
        st = sooc_seterr(SOOC_EINVAL,
                         "calibration: the board (%s) was found in %d of %d images, need %d views with >= %d corners; "
                         "no board in: %s",
                         bs, used, n, min_views, min_points, failed);
        goto out;
    }
    counts = sooc_malloc((size_t)used * sizeof(int));
    obj = sooc_malloc(total * 3 * sizeof(double));
    img = sooc_malloc(total * 2 * sizeof(double));
    Tcb = sooc_malloc((size_t)used * 16 * sizeof(double));
    rep->view_index = sooc_malloc((size_t)used * sizeof(int));
    if (!counts || !obj || !img || !Tcb || !rep->view_index) {
        st = sooc_seterr(SOOC_ENOMEM, "calibration: out of memory");
        goto out;
    }
    size_t k = 0;
    int v = 0;
    for (int i = 0; i < n; i++) {
        if (views[i].n < min_points) continue;
        counts[v] = views[i].n;
        rep->view_index[v++] = i;
        memcpy(obj + 3 * k, views[i].obj, (size_t)views[i].n * 3 * sizeof(double));
        memcpy(img + 2 * k, views[i].img, (size_t)views[i].n * 2 * sizeof(double));
        k += (size_t)views[i].n;
    }
    char err[512] = "";
    if (sooc_cv_calibrate(used, counts, obj, img, w, h, dist_n, K, dist, &rms, Tcb, err, sizeof err)) {
        st = sooc_seterr(SOOC_ERR, "calibration: %s", err);
        goto out;
    }
    if (!(K[0] > 0 && K[1] > 0 && isfinite(rms)) || K[0] > 100.0 * w) {
        st = sooc_seterr(SOOC_EINVAL, "calibration: degenerate views (focal %g %g, RMS %g px): tilt the board more", K[0],
                         K[1], rms);
        goto out;
    }
    sooc_calib_pinhole(calib, w, h, K[0], K[1], K[2], K[3]);
    if (dist_n) {
        calib->K.dist_model = SOOC_DIST_PLUMB_BOB;
        calib->n_dist = 5;
        for (int i = 0; i < 5; i++) calib->K.dist[i] = dist[i];
    }
    rep->views_used = used;
    rep->rms_px = rms;
    rep->T_cam_board = (double(*)[16])Tcb;
    Tcb = NULL;
out:
    for (int i = 0; i < n; i++) sooc_board_view_free(&views[i]);
    sooc_free(views);
    sooc_free(counts);
    sooc_free(obj);
    sooc_free(img);
    sooc_free(Tcb);
    if (st) sooc_calib_report_free(rep);
    return st;
}

static double rot_angle(const double R[9]) {
    double c = (R[0] + R[4] + R[8] - 1) * 0.5;
    c = c > 1 ? 1 : (c < -1 ? -1 : c);
    return acos(c);
}

/* relative rotation between two poses: angle (rad) and unit axis */
static double rel_rot(const double *A, const double *B, double axis[3]) {
    double Ra[9], Rb[9], ta[3], tb[3], RaT[9], R[9];
    sooc_se3_to_rt(Ra, ta, A);
    sooc_se3_to_rt(Rb, tb, B);
    sooc_m3_transpose(RaT, Ra);
    sooc_m3_mul(R, RaT, Rb);
    axis[0] = R[7] - R[5];
    axis[1] = R[2] - R[6];
    axis[2] = R[3] - R[1];
    double nn = sooc_v3_norm(axis);
    if (nn > 0)
        for (int k = 0; k < 3; k++) axis[k] /= nn;
    return rot_angle(R);
}

sooc_status sooc_calib_handeye(const sooc_board *b, const char *const *paths, const double *T_base_ee, int n,
                               int min_views, int method, sooc_calib *calib, double *rms_px, int *views_used) {
    *rms_px = 0;
    *views_used = 0;
    if (method < 0 || method > 4)
        return sooc_seterr(SOOC_EINVAL, "hand-eye: method %d (0 tsai, 1 park, 2 horaud, 3 andreff, 4 daniilidis)",
                           method);
    if (b->kind != SOOC_BOARD_CHARUCO)
        return sooc_seterr(SOOC_EINVAL, "hand-eye: needs a ChArUco board (a checkerboard's corner order is "
                                        "ambiguous, so its frame is not the same in every view)");
    if (min_views < 3) min_views = 3;
    if (!(calib->K.fx > 0 && calib->K.fy > 0 && calib->K.width > 0))
        return sooc_seterr(SOOC_EINVAL, "hand-eye: the camera's intrinsics are missing");
    if (n < min_views)
        return sooc_seterr(SOOC_EINVAL, "hand-eye: %d image/pose pairs given, need at least %d", n, min_views);
    for (int i = 0; i < n; i++) {
        double err;
        double R[9], t[3];
        sooc_se3_to_rt(R, t, T_base_ee + 16 * i);
        if (!sooc_m3_is_rotation(R, 1e-3, &err))
            return sooc_seterr(SOOC_EINVAL, "hand-eye: arm pose %d is not a rotation (error %g)", i + 1, err);
    }
    sooc_board_view *views = sooc_calloc((size_t)n, sizeof *views);
    double *Tee = sooc_malloc((size_t)n * 16 * sizeof(double)), *Tcb = sooc_malloc((size_t)n * 16 * sizeof(double));
    int w = 0, h = 0, used = 0;
    sooc_status st = SOOC_OK;
    if (!views || !Tee || !Tcb) {
        st = sooc_seterr(SOOC_ENOMEM, "hand-eye: out of memory");
        goto out;
    }
    if ((st = detect_all(b, paths, n, views, &w, &h))) goto out;
    if (w != calib->K.width || h != calib->K.height) {
        st = sooc_seterr(SOOC_EINVAL, "hand-eye: images are %dx%d, the intrinsics are for %dx%d", w, h,
                         calib->K.width, calib->K.height);
        goto out;
    }
    double K[4] = {calib->K.fx, calib->K.fy, calib->K.cx, calib->K.cy}, dist[5] = {0, 0, 0, 0, 0};
    if (calib->K.dist_model == SOOC_DIST_PLUMB_BOB || calib->K.dist_model == SOOC_DIST_RATIONAL)
        for (int i = 0; i < 5; i++) dist[i] = calib->K.dist[i];
    double rsum = 0;
    for (int i = 0; i < n; i++) {
        if (views[i].n < 6) continue;
        char err[512] = "";
        double r;
        if (sooc_cv_pnp(views[i].n, views[i].obj, views[i].img, K, dist, Tcb + 16 * used, &r, err, sizeof err))
            continue;
        memcpy(Tee + 16 * used, T_base_ee + 16 * i, 16 * sizeof(double));
        rsum += r;
        used++;
    }
    if (used < min_views) {
        char failed[1024];
        list_failed(paths, views, n, 6, failed, sizeof failed);
        st = sooc_seterr(SOOC_EINVAL, "hand-eye: the board was located in %d of %d images, need %d; no board in: %s",
                         used, n, min_views, failed);
        goto out;
    }
    /* degenerate motions: hand-eye needs rotations about two non-parallel axes */
    double max_ang = 0, a0[3] = {0, 0, 0}, max_axis_sep = 0;
    int have_a0 = 0;
    for (int i = 0; i < used; i++)
        for (int j = i + 1; j < used; j++) {
            double ax[3];
            double ang = rel_rot(Tee + 16 * i, Tee + 16 * j, ax);
            if (ang > max_ang) max_ang = ang;
            if (ang < 2.0 * M_PI / 180) continue;
            if (!have_a0) {
                memcpy(a0, ax, sizeof a0);
                have_a0 = 1;
                continue;
            }
            double c[3];
            sooc_v3_cross(c, a0, ax);
            double sep = asin(fmin(1.0, sooc_v3_norm(c)));
            if (sep > max_axis_sep) max_axis_sep = sep;
        }
    if (max_ang < 5.0 * M_PI / 180) {
        st = sooc_seterr(SOOC_EINVAL,
                         "hand-eye: degenerate motions: the arm poses differ by at most %.2f deg of rotation (pure "
                         "translations determine no rotation); rotate the wrist by 10+ deg about two different axes",
                         max_ang * 180 / M_PI);
        goto out;
    }
    if (max_axis_sep < 5.0 * M_PI / 180) {
        st = sooc_seterr(SOOC_EINVAL,
                         "hand-eye: degenerate motions: every rotation between arm poses is about the same axis "
                         "(within %.2f deg); rotate about two different axes",
                         max_axis_sep * 180 / M_PI);
        goto out;
    }
    char err[512] = "";
    double X[16];
    if (sooc_cv_handeye(used, Tee, Tcb, method, X, err, sizeof err)) {
        st = sooc_seterr(SOOC_ERR, "hand-eye: %s", err);
        goto out;
    }
    double R[9], t[3], e;
    sooc_se3_to_rt(R, t, X);
    if (!sooc_m3_is_rotation(R, 1e-6, &e)) {
        /* re-orthonormalise through the quaternion */
        double q[4];
        sooc_m3_to_quat(q, R);
        sooc_quat_to_m3(R, q);
        sooc_se3_from_rt(X, R, t);
    }
    memcpy(calib->T_effector_camera, X, sizeof X);
    calib->has_T_effector_camera = 1;
    if (!calib->effector_parent[0]) snprintf(calib->effector_parent, sizeof calib->effector_parent, "effector");
    if (!calib->effector_child[0]) snprintf(calib->effector_child, sizeof calib->effector_child, "camera");
    *rms_px = rsum / used;
    *views_used = used;
out:
    if (views)
        for (int i = 0; i < n; i++) sooc_board_view_free(&views[i]);
    sooc_free(views);
    sooc_free(Tee);
    sooc_free(Tcb);
    return st;
}

sooc_status sooc_cv_calib_yaml_read(const char *path, int *width, int *height, double K[9]) {
    char err[1024] = "";
    if (sooc_cv_yaml_read(path, width, height, K, err, sizeof err)) return sooc_seterr(SOOC_EFORMAT, "%s", err);
    return SOOC_OK;
}

#else /* !SOOC_HAVE_OPENCV */

sooc_status sooc_cv_calib_yaml_read(const char *path, int *width, int *height, double K[9]) {
    return sooc_seterr(SOOC_EUNSUPPORTED, "%s: %s", path, NO_OPENCV_MSG);
}

sooc_status sooc_board_render(const sooc_board *b, const sooc_intrinsics *K, const double T_cam_board[16], int ss,
                              double noise, uint64_t seed, sooc_image *out) {
    return sooc_seterr(SOOC_EUNSUPPORTED, "board render: %s", NO_OPENCV_MSG);
}
sooc_status sooc_board_layout(const sooc_board *b, double center[3], double *front_z, double *y_down) {
    return sooc_seterr(SOOC_EUNSUPPORTED, "board: %s", NO_OPENCV_MSG);
}
sooc_status sooc_board_detect(const sooc_board *b, const sooc_image *img, sooc_board_view *view) {
    return sooc_seterr(SOOC_EUNSUPPORTED, "board detection: %s", NO_OPENCV_MSG);
}
sooc_status sooc_calib_intrinsics(const sooc_board *b, const char *const *paths, int n, int min_views, int min_points,
                                  int dist_n, sooc_calib *calib, sooc_calib_report *rep) {
    memset(rep, 0, sizeof *rep);
    return sooc_seterr(SOOC_EUNSUPPORTED, "calibration: %s", NO_OPENCV_MSG);
}
sooc_status sooc_calib_handeye(const sooc_board *b, const char *const *paths, const double *T_base_ee, int n,
                               int min_views, int method, sooc_calib *calib, double *rms_px, int *views_used) {
    return sooc_seterr(SOOC_EUNSUPPORTED, "hand-eye: %s", NO_OPENCV_MSG);
}
#endif
