/* Keyframe features (ORB + depth points), their stored blobs, descriptor
 * matching and the geometric verification of a candidate keyframe
 * (include/sooc3d/slam.h). */
#include <math.h>
#include <string.h>

#include "sooc3d/core.h"
#include "slam/slam_impl.h"

void sooc__slam_node_free(sooc_slam_node *n) {
    sooc_free(n->uv);
    sooc_free(n->xyz);
    sooc_free(n->desc);
    sooc_free(n->depth);
    n->uv = n->xyz = n->depth = NULL;
    n->desc = NULL;
    n->nf = 0;
}

static sooc_status node_alloc(sooc_slam_node *n, int nf, int dw, int dh) {
    sooc__slam_node_free(n);
    n->uv = sooc_malloc(sizeof(float) * 2 * (size_t)(nf > 0 ? nf : 1));
    n->xyz = sooc_malloc(sizeof(float) * 3 * (size_t)(nf > 0 ? nf : 1));
    n->desc = sooc_malloc(32 * (size_t)(nf > 0 ? nf : 1));
    n->depth = sooc_malloc(sizeof(float) * (size_t)dw * (size_t)dh);
    if (!n->uv || !n->xyz || !n->desc || !n->depth) {
        sooc__slam_node_free(n);
        return sooc_seterr(SOOC_ENOMEM, "slam: out of memory (keyframe)");
    }
    n->nf = nf;
    n->dw = dw;
    n->dh = dh;
    return SOOC_OK;
}

sooc_status sooc__slam_extract(sooc_slam *s, sooc_slam_node *n) {
#if !SOOC_HAVE_OPENCV
    (void)s;
    (void)n;
    return sooc_seterr(SOOC_EUNSUPPORTED, "slam: built without OpenCV");
#else
    int w, h;
    double K[4];
    sooc_status st = sooc_odom_current_frame(s->odo, NULL, NULL, &w, &h, K);
    if (st) return st;
    if (w != s->w || h != s->h || !s->gray) {
        sooc_free(s->gray);
        sooc_free(s->depth);
        s->gray = sooc_malloc((size_t)w * h);
        s->depth = sooc_malloc(sizeof(float) * (size_t)w * h);
        if (!s->gray || !s->depth) return sooc_seterr(SOOC_ENOMEM, "slam: out of memory (frame buffers)");
        s->w = w;
        s->h = h;
    }
    memcpy(s->K, K, sizeof s->K);
    if ((st = sooc_odom_current_frame(s->odo, s->gray, s->depth, &w, &h, K))) return st;
    int dw = s->p.depth_w, dh = s->p.depth_h;
    if ((st = node_alloc(n, s->p.n_features, dw, dh))) return st;
    char err[256] = "";
    int nf = 0;
    if (sooc_slsh_orb(s->gray, w, h, s->p.n_features, n->uv, n->desc, &nf, err, sizeof err))
        return sooc_seterr(SOOC_ERR, "slam: %s", err);
    n->nf = nf;
    memcpy(n->Kf, K, sizeof n->Kf);
    const double lo = s->p.odom.min_depth_m, hi = s->p.odom.max_depth_m;
    for (int i = 0; i < nf; i++) {
        int u = (int)lrintf(n->uv[2 * i]), v = (int)lrintf(n->uv[2 * i + 1]);
        float *X = n->xyz + 3 * i;
        X[0] = X[1] = X[2] = NAN;
        if (u < 1 || v < 1 || u >= w - 1 || v >= h - 1) continue;
        float z = s->depth[(size_t)v * w + u];
        if (!(z > lo && z < hi)) continue;
        /* no point on a depth edge: the 3x3 neighbourhood must agree */
        float zmin = z, zmax = z;
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                float zz = s->depth[(size_t)(v + dy) * w + u + dx];
                if (!(zz > 0)) zz = 0;
                zmin = fminf(zmin, zz);
                zmax = fmaxf(zmax, zz);
            }
        if (zmax - zmin > 0.03f * z) continue;
        X[0] = (float)((n->uv[2 * i] - K[2]) / K[0] * z);
        X[1] = (float)((n->uv[2 * i + 1] - K[3]) / K[1] * z);
        X[2] = z;
    }
    /* the depth at the stored size (nearest sample) */
    double sx = (double)dw / w, sy = (double)dh / h;
    n->Kd[0] = K[0] * sx;
    n->Kd[1] = K[1] * sy;
    n->Kd[2] = (K[2] + 0.5) * sx - 0.5;
    n->Kd[3] = (K[3] + 0.5) * sy - 0.5;
    for (int y = 0; y < dh; y++) {
        int ys = (int)((y + 0.5) / sy);
        if (ys >= h) ys = h - 1;
        for (int x = 0; x < dw; x++) {
            int xs = (int)((x + 0.5) / sx);
            if (xs >= w) xs = w - 1;
            float z = s->depth[(size_t)ys * w + xs];
            n->depth[(size_t)y * dw + x] = (z > lo && z < hi) ? z : 0.0f;
        }
    }
    return SOOC_OK;
#endif
}

/* Hamming distances with the POPCNT instruction when the CPU has it (the
 * build does not assume it: no -march) */
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define SLAM_POPCNT_TARGET __attribute__((target("popcnt")))
#define SLAM_HAVE_TARGET 1
#else
#define SLAM_POPCNT_TARGET
#define SLAM_HAVE_TARGET 0
#endif

#define SLAM_MATCH_BODY                                                                       \
    int m = 0;                                                                                \
    for (int i = 0; i < q->nf && m < cap; i++) {                                              \
        uint64_t x[4];                                                                        \
        memcpy(x, q->desc + 32 * (size_t)i, 32);                                              \
        int best = 257, second = 257, bj = -1;                                                \
        for (int j = 0; j < b->nf; j++) {                                                     \
            uint64_t y[4];                                                                    \
            memcpy(y, b->desc + 32 * (size_t)j, 32);                                          \
            int h = __builtin_popcountll(x[0] ^ y[0]) + __builtin_popcountll(x[1] ^ y[1]) +   \
                    __builtin_popcountll(x[2] ^ y[2]) + __builtin_popcountll(x[3] ^ y[3]);    \
            if (h < best) {                                                                   \
                second = best;                                                                \
                best = h;                                                                     \
                bj = j;                                                                       \
            } else if (h < second) {                                                          \
                second = h;                                                                   \
            }                                                                                 \
        }                                                                                     \
        if (bj >= 0 && best <= 64 && best < 0.8 * second) {                                   \
            if (pairs) {                                                                      \
                pairs[2 * m] = i;                                                             \
                pairs[2 * m + 1] = bj;                                                        \
            }                                                                                 \
            m++;                                                                              \
        }                                                                                     \
    }                                                                                         \
    return m;

static int match_generic(const sooc_slam_node *q, const sooc_slam_node *b, int *pairs, int cap) { SLAM_MATCH_BODY }

#if SLAM_HAVE_TARGET
SLAM_POPCNT_TARGET static int match_popcnt(const sooc_slam_node *q, const sooc_slam_node *b, int *pairs, int cap) {
    SLAM_MATCH_BODY
}
#endif

int sooc__slam_match(const sooc_slam_node *q, const sooc_slam_node *b, int *pairs, int cap) {
#if SLAM_HAVE_TARGET
    static int have = -1;
    if (have < 0) have = __builtin_cpu_supports("popcnt") ? 1 : 0;
    if (have) return match_popcnt(q, b, pairs, cap);
#endif
    return match_generic(q, b, pairs, cap);
}

static double rot_deg(const double T[16]) {
    double c = (T[0] + T[5] + T[10] - 1) * 0.5;
    c = c > 1 ? 1 : (c < -1 ? -1 : c);
    return acos(c) * 180.0 / M_PI;
}

sooc_status sooc__slam_verify(sooc_slam *s, const sooc_slam_node *q, const sooc_slam_node *b, int *ok, double T_b_q[16],
                              int *inliers) {
    *ok = 0;
    *inliers = 0;
    sooc_se3_identity(T_b_q);
#if !SOOC_HAVE_OPENCV
    (void)s;
    (void)q;
    (void)b;
    return sooc_seterr(SOOC_EUNSUPPORTED, "slam: built without OpenCV");
#else
    int cap = s->p.n_features;
    int m = sooc__slam_match(q, b, s->pairs, cap);
    int n = 0;
    for (int k = 0; k < m; k++) {
        int i = s->pairs[2 * k], j = s->pairs[2 * k + 1];
        const float *X = b->xyz + 3 * j;
        if (!isfinite(X[2])) continue;
        for (int c = 0; c < 3; c++) s->obj[3 * n + c] = X[c];
        s->img[2 * n] = q->uv[2 * i];
        s->img[2 * n + 1] = q->uv[2 * i + 1];
        n++;
    }
    if (n < s->p.min_inliers) return SOOC_OK;
    char err[256] = "";
    double T_q_b[16];
    int ninl = 0;
    int r = sooc_slsh_pnp_ransac(n, s->obj, s->img, q->Kf, 300, s->p.reproj_px, T_q_b, NULL, &ninl, err, sizeof err);
    if (r < 0) return sooc_seterr(SOOC_ERR, "slam: %s", err);
    *inliers = ninl;
    if (!r || ninl < s->p.min_inliers) return SOOC_OK;
    double init[16], T[16], agree = 0, overlap = 0;
    sooc_se3_inverse(init, T_q_b);
    if (!s->icp) {
        if (sooc_slsh_icp_create(&s->icp, b->Kd, b->dw, b->dh, s->p.odom.min_depth_m, s->p.odom.max_depth_m, 0.04, err,
                                 sizeof err))
            return sooc_seterr(SOOC_ERR, "slam: %s", err);
    }
    if (q->dw != b->dw || q->dh != b->dh) return SOOC_OK;   /* stored at another size: not comparable */
    r = sooc_slsh_icp_run(s->icp, q->depth, b->depth, init, T, &agree, &overlap, err, sizeof err);
    if (r < 0) return sooc_seterr(SOOC_ERR, "slam: %s", err);
    if (!r || agree < s->p.min_icp_agree || overlap < s->p.min_overlap) return SOOC_OK;
    double inv[16], D[16];
    sooc_se3_inverse(inv, init);
    sooc_se3_mul(D, inv, T);
    double dt = sqrt(D[3] * D[3] + D[7] * D[7] + D[11] * D[11]);
    if (dt > s->p.max_jump_m || rot_deg(D) > s->p.max_jump_deg) return SOOC_OK;
    memcpy(T_b_q, T, sizeof T);
    *ok = 1;
    return SOOC_OK;
#endif
}

/* ------------------------------------------------------------- blobs */

static void put_u32(unsigned char *p, uint32_t v) {
    for (int b = 0; b < 4; b++) p[b] = (unsigned char)(v >> (8 * b));
}
static uint32_t get_u32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static void put_f32(unsigned char *p, float f) {
    uint32_t u;
    memcpy(&u, &f, 4);
    put_u32(p, u);
}
static float get_f32(const unsigned char *p) {
    uint32_t u = get_u32(p);
    float f;
    memcpy(&f, &u, 4);
    return f;
}
static void put_f64(unsigned char *p, double d) {
    uint64_t u;
    memcpy(&u, &d, 8);
    put_u32(p, (uint32_t)u);
    put_u32(p + 4, (uint32_t)(u >> 32));
}
static double get_f64(const unsigned char *p) {
    uint64_t u = (uint64_t)get_u32(p) | (uint64_t)get_u32(p + 4) << 32;
    double d;
    memcpy(&d, &u, 8);
    return d;
}

#define FEAT_REC 52   /* 5 float32 + 32 bytes */

sooc_status sooc__slam_encode(const sooc_slam_node *n, void **feat, size_t *feat_bytes, void **depth, size_t *depth_bytes) {
    *feat = *depth = NULL;
    size_t fb = 12 + 32 + (size_t)n->nf * FEAT_REC + 4;
    size_t db = 16 + 32 + (size_t)n->dw * n->dh * 2 + 4;
    unsigned char *f = sooc_malloc(fb), *d = sooc_malloc(db);
    if (!f || !d) {
        sooc_free(f);
        sooc_free(d);
        return sooc_seterr(SOOC_ENOMEM, "slam: out of memory (keyframe record)");
    }
    memcpy(f, "SLF1", 4);
    put_u32(f + 4, SOOC_SLAM_BLOB_VERSION);
    put_u32(f + 8, (uint32_t)n->nf);
    for (int k = 0; k < 4; k++) put_f64(f + 12 + 8 * k, n->Kf[k]);
    unsigned char *p = f + 44;
    for (int i = 0; i < n->nf; i++, p += FEAT_REC) {
        put_f32(p, n->uv[2 * i]);
        put_f32(p + 4, n->uv[2 * i + 1]);
        for (int c = 0; c < 3; c++) put_f32(p + 8 + 4 * c, n->xyz[3 * i + c]);
        memcpy(p + 20, n->desc + 32 * (size_t)i, 32);
    }
    put_u32(p, sooc_crc32(0, f, fb - 4));
    memcpy(d, "SLD1", 4);
    put_u32(d + 4, SOOC_SLAM_BLOB_VERSION);
    put_u32(d + 8, (uint32_t)n->dw);
    put_u32(d + 12, (uint32_t)n->dh);
    for (int k = 0; k < 4; k++) put_f64(d + 16 + 8 * k, n->Kd[k]);
    p = d + 48;
    for (size_t i = 0; i < (size_t)n->dw * n->dh; i++, p += 2) {
        double mm = n->depth[i] * 1000.0 + 0.5;
        uint16_t v = mm > 0 && mm < 65535 ? (uint16_t)mm : 0;
        p[0] = (unsigned char)v;
        p[1] = (unsigned char)(v >> 8);
    }
    put_u32(p, sooc_crc32(0, d, db - 4));
    *feat = f;
    *feat_bytes = fb;
    *depth = d;
    *depth_bytes = db;
    return SOOC_OK;
}

sooc_status sooc__slam_decode(sooc_slam_node *n, const void *feat, size_t fb, const void *depth, size_t db) {
    const unsigned char *f = feat, *d = depth;
    if (!f || fb < 48 || memcmp(f, "SLF1", 4) || get_u32(f + 4) != SOOC_SLAM_BLOB_VERSION)
        return sooc_seterr(SOOC_EFORMAT, "slam keyframe %lld: feature record missing or of another version",
                           (long long)n->id);
    uint32_t nf = get_u32(f + 8);
    if (nf > 100000 || fb != 12 + 32 + (size_t)nf * FEAT_REC + 4 || get_u32(f + fb - 4) != sooc_crc32(0, f, fb - 4))
        return sooc_seterr(SOOC_EFORMAT, "slam keyframe %lld: feature record size or checksum wrong", (long long)n->id);
    if (!d || db < 52 || memcmp(d, "SLD1", 4) || get_u32(d + 4) != SOOC_SLAM_BLOB_VERSION)
        return sooc_seterr(SOOC_EFORMAT, "slam keyframe %lld: depth record missing or of another version",
                           (long long)n->id);
    uint32_t dw = get_u32(d + 8), dh = get_u32(d + 12);
    if (dw == 0 || dh == 0 || dw > 4096 || dh > 4096 || db != 16 + 32 + (size_t)dw * dh * 2 + 4 ||
        get_u32(d + db - 4) != sooc_crc32(0, d, db - 4))
        return sooc_seterr(SOOC_EFORMAT, "slam keyframe %lld: depth record size or checksum wrong", (long long)n->id);
    sooc_status st = node_alloc(n, (int)nf, (int)dw, (int)dh);
    if (st) return st;
    for (int k = 0; k < 4; k++) {
        n->Kf[k] = get_f64(f + 12 + 8 * k);
        n->Kd[k] = get_f64(d + 16 + 8 * k);
    }
    const unsigned char *p = f + 44;
    for (uint32_t i = 0; i < nf; i++, p += FEAT_REC) {
        n->uv[2 * i] = get_f32(p);
        n->uv[2 * i + 1] = get_f32(p + 4);
        for (int c = 0; c < 3; c++) n->xyz[3 * i + c] = get_f32(p + 8 + 4 * c);
        memcpy(n->desc + 32 * (size_t)i, p + 20, 32);
    }
    p = d + 48;
    for (size_t i = 0; i < (size_t)dw * dh; i++, p += 2) n->depth[i] = (float)((p[0] | p[1] << 8) * 1e-3);
    return SOOC_OK;
}
