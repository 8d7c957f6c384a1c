/* RGB-D frames from a robot log: the colour and depth topics (named, or the
 * one of each kind), their CameraInfos and depth units, colour-depth pairs
 * by log time, depth registered into the colour camera when the two cameras
 * differ, and the camera pose from the log's TF. */
#include "logseq_impl.h"
#include "logs_impl.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct ls_stream {
    int ch0;                   /* a channel of the topic (type, encoding)    */
    int compressed;            /* sensor_msgs/CompressedImage                */
    int kind;                  /* 1 colour, 2 depth, 0 neither               */
    int64_t *pos, n;           /* message positions of the topic, in order   */
    sooc_logseq_stream pub;
} ls_stream;

typedef struct ls_pair {
    int64_t kc, kd, t;
} ls_pair;

struct sooc_logseq {
    sooc_logfile *lf;
    sooc_logseq_params p;
    ls_stream col, dep;
    sooc_logseq_desc d;
    sooc_logs_tf *tf;
    ls_pair *pr;
    int64_t n;
    sooc_image img;
    float *zd;
    size_t zcap;
    char sbuf[4][160];         /* strings the description points at          */
};

void sooc_logseq_params_default(sooc_logseq_params *p) {
    memset(p, 0, sizeof *p);
    p->pair_tol_s = 0.02;
    p->pose_tol_s = 0.05;
    p->registration = -1;
}

static int type_is(const char *type, const char *base) {
    char b[160];
    return !strcmp(sooc_ros_type_base(type, b, sizeof b), base);
}

/* Leading '/'-separated components two topics share. */
static int common_prefix(const char *a, const char *b) {
    int n = 0;
    size_t i = 0;
    for (;; i++) {
        if (a[i] != b[i]) break;
        if (a[i] == '/' && i > 0) n++;
        if (!a[i]) break;
    }
    return n;
}

static int64_t cmp64(int64_t a, int64_t b) { return a < b ? -1 : a > b; }
static int cmp_pos(const void *a, const void *b) { return (int)cmp64(*(const int64_t *)a, *(const int64_t *)b); }

/* Every message of every channel with this topic (a bag may hold several connections on one topic). */
static sooc_status topic_positions(const sooc_logfile *lf, const char *topic, int64_t **out, int64_t *n) {
    int64_t total = 0;
    for (int c = 0; c < sooc_logfile_channel_count(lf); c++)
        if (!strcmp(sooc_logfile_channel_get(lf, c)->topic, topic)) total += sooc_logfile_channel_get(lf, c)->count;
    *out = sooc_malloc(sizeof(int64_t) * (size_t)(total ? total : 1));
    if (!*out) return SOOC_ENOMEM;
    *n = 0;
    for (int c = 0; c < sooc_logfile_channel_count(lf); c++) {
        if (strcmp(sooc_logfile_channel_get(lf, c)->topic, topic)) continue;
        int64_t k;
        const int64_t *p = sooc_logfile_channel_msgs(lf, c, &k);
        if (k) memcpy(*out + *n, p, sizeof(int64_t) * (size_t)k);
        *n += k;
    }
    if (*n > 1) qsort(*out, (size_t)*n, sizeof(int64_t), cmp_pos);
    return SOOC_OK;
}

static const char *ctx(sooc_logseq *s, const char *topic, int64_t k) {
    int64_t t = 0;
    sooc_logfile_entry(s->lf, k, NULL, &t);
    snprintf(s->sbuf[3], sizeof s->sbuf[3], "%.60s: %.60s at %.6f s", sooc_logfile_path(s->lf), topic, t * 1e-9);
    return s->sbuf[3];
}

/* Read and classify the first message of an image topic. */
static sooc_status probe(sooc_logseq *s, const char *topic, ls_stream *o) {
    memset(o, 0, sizeof *o);
    sooc_status st = topic_positions(s->lf, topic, &o->pos, &o->n);
    if (st) return st;
    o->ch0 = sooc_logfile_find(s->lf, topic);
    const sooc_logfile_channel *c = sooc_logfile_channel_get(s->lf, o->ch0);
    o->pub.topic = c->topic;
    o->pub.type = c->type;
    o->pub.count = o->n;
    o->compressed = type_is(c->type, "sensor_msgs/CompressedImage");
    if (!o->compressed && !type_is(c->type, "sensor_msgs/Image"))
        return sooc_seterr(SOOC_EINVAL, "%s: %s is a %s, not an image topic", sooc_logfile_path(s->lf), topic, c->type);
    if (!o->n) return sooc_seterr(SOOC_EFORMAT, "%s: %s has no messages", sooc_logfile_path(s->lf), topic);
    sooc_logfile_msg m;
    if ((st = sooc_logfile_read(s->lf, o->pos[0], &m))) return st;
    const char *name = ctx(s, topic, o->pos[0]);
    if (o->compressed) {
        sooc_ros_cimage ci;
        if ((st = sooc_ros_decode_cimage(m.data, m.size, c->enc, &ci))) return sooc_adderr(st, "%s", name);
        snprintf(o->pub.encoding, sizeof o->pub.encoding, "%s", ci.format);
        snprintf(o->pub.frame_id, sizeof o->pub.frame_id, "%s", ci.header.frame_id);
        if (strstr(ci.format, "compressedDepth")) {
            o->kind = 2;
            st = sooc_logs_depth_compressed(&ci, 0.001, &s->img, &s->zd, &s->zcap, &o->pub.width, &o->pub.height, name);
        } else {
            o->kind = 1;
            st = sooc_logs_color_compressed(&ci, &s->img, name);
            o->pub.width = s->img.width;
            o->pub.height = s->img.height;
        }
        if (st) o->kind = 0;
        return st;
    }
    sooc_ros_image im;
    if ((st = sooc_ros_decode_image(m.data, m.size, c->enc, &im))) return sooc_adderr(st, "%s", name);
    snprintf(o->pub.encoding, sizeof o->pub.encoding, "%s", im.encoding);
    snprintf(o->pub.frame_id, sizeof o->pub.frame_id, "%s", im.header.frame_id);
    o->pub.width = im.width;
    o->pub.height = im.height;
    sooc_logs_pix px = sooc_logs_pix_parse(im.encoding);
    o->kind = px == LOGS_PIX_NONE ? 0 : sooc_logs_pix_is_depth(px) ? 2 : 1;
    if (!o->kind)
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: unknown image encoding '%s' (rgb8, bgr8, rgba8, bgra8, mono8, mono16, "
                           "16UC1, 32FC1)", name, im.encoding);
    return SOOC_OK;
}

static void stream_free(ls_stream *t) {
    sooc_free(t->pos);
    memset(t, 0, sizeof *t);
}

/* The colour (kind 1) or depth (kind 2) stream: the named topic, or the one of that kind. */
static sooc_status pick(sooc_logseq *s, int kind, const char *named, ls_stream *out) {
    const char *what = kind == 1 ? "colour" : "depth", *key = kind == 1 ? "color_topic" : "depth_topic";
    const char *path = sooc_logfile_path(s->lf);
    if (named && *named) {
        if (sooc_logfile_find(s->lf, named) < 0) {
            char list[1024] = "";
            size_t m = 0;
            for (int c = 0; c < sooc_logfile_channel_count(s->lf); c++) {
                const sooc_logfile_channel *ch = sooc_logfile_channel_get(s->lf, c);
                if (!type_is(ch->type, "sensor_msgs/Image") && !type_is(ch->type, "sensor_msgs/CompressedImage")) continue;
                int k = snprintf(list + m, sizeof list - m, "%s%s", m ? ", " : "", ch->topic);
                if (k > 0 && (size_t)k < sizeof list - m) m += (size_t)k;
            }
            return sooc_seterr(SOOC_ENOTFOUND, "%s: %s '%s' is not in the log (image topics: %s)", path, key, named,
                               m ? list : "none");
        }
        sooc_status st = probe(s, named, out);
        if (!st && out->kind != kind)
            st = sooc_seterr(SOOC_EINVAL, "%s: %s '%s' holds %s images ('%s'), not %s", path, key, named,
                             out->kind == 1 ? "colour" : "depth", out->pub.encoding, what);
        return st;
    }
    char list[1024] = "";
    size_t m = 0;
    int found = 0;
    for (int c = 0; c < sooc_logfile_channel_count(s->lf); c++) {
        const sooc_logfile_channel *ch = sooc_logfile_channel_get(s->lf, c);
        if (!ch->count || sooc_logfile_find(s->lf, ch->topic) != c) continue;   /* each topic once */
        if (!type_is(ch->type, "sensor_msgs/Image") && !type_is(ch->type, "sensor_msgs/CompressedImage")) continue;
        ls_stream t;
        if (probe(s, ch->topic, &t) || t.kind != kind) {
            stream_free(&t);
            continue;
        }
        int k = snprintf(list + m, sizeof list - m, "%s%s (%s %dx%d)", m ? ", " : "", ch->topic, t.pub.encoding,
                         t.pub.width, t.pub.height);
        if (k > 0 && (size_t)k < sizeof list - m) m += (size_t)k;
        if (!found++) *out = t;
        else stream_free(&t);
    }
    sooc_clearerr();
    if (found == 1) return SOOC_OK;
    if (found) stream_free(out);
    if (!found)
        return sooc_seterr(SOOC_EFORMAT, "%s: no %s image topic (sensor_msgs/Image or CompressedImage)", path, what);
    return sooc_seterr(SOOC_EINVAL, "%s: %d %s image topics, name one with %s: %s", path, found, what, key, list);
}

/* The CameraInfo of the stream's size in the image's frame whose topic shares the most with the image topic. */
static void find_info(sooc_logseq *s, ls_stream *t) {
    int best = -1;
    for (int c = 0; c < sooc_logfile_channel_count(s->lf); c++) {
        const sooc_logfile_channel *ch = sooc_logfile_channel_get(s->lf, c);
        if (!ch->count || !type_is(ch->type, "sensor_msgs/CameraInfo")) continue;
        int64_t n;
        const int64_t *pos = sooc_logfile_channel_msgs(s->lf, c, &n);
        sooc_logfile_msg m;
        sooc_ros_caminfo ci;
        if (sooc_logfile_read(s->lf, pos[0], &m) || sooc_ros_decode_caminfo(m.data, m.size, ch->enc, &ci)) continue;
        if (ci.width != t->pub.width || ci.height != t->pub.height || !(ci.K[0] > 0 && ci.K[4] > 0) ||
            !isfinite(ci.K[0] + ci.K[2] + ci.K[4] + ci.K[5]))
            continue;
        /* the image's frame_id first, then the topic's path, then its characters */
        size_t nc = 0;
        while (ch->topic[nc] && ch->topic[nc] == t->pub.topic[nc]) nc++;
        int score = 100000 * !strcmp(ci.header.frame_id, t->pub.frame_id) + 1000 * common_prefix(ch->topic, t->pub.topic) +
                    (int)(nc < 999 ? nc : 999);
        if (score <= best) continue;
        best = score;
        sooc_intrinsics *K = &t->pub.K;
        memset(K, 0, sizeof *K);
        K->width = ci.width;
        K->height = ci.height;
        K->fx = ci.K[0];
        K->fy = ci.K[4];
        K->cx = ci.K[2];
        K->cy = ci.K[5];
        int nz = 0;
        for (int k = 0; k < 8 && k < ci.nD; k++) nz |= ci.D[k] != 0;
        if (nz) {
            K->dist_model = ci.nD > 5 ? SOOC_DIST_RATIONAL : SOOC_DIST_PLUMB_BOB;
            for (int k = 0; k < 8 && k < ci.nD; k++) K->dist[k] = ci.D[k];
        }
        t->pub.has_info = 1;
        t->pub.info_topic = ch->topic;
    }
    sooc_clearerr();
}

/* A value from the Float32/64 topic ending in `suffix` nearest the topic `near`. */
static int find_option(sooc_logseq *s, const char *suffix, const char *near, double *v, const char **topic) {
    int best = -1;
    size_t ns = strlen(suffix);
    for (int c = 0; c < sooc_logfile_channel_count(s->lf); c++) {
        const sooc_logfile_channel *ch = sooc_logfile_channel_get(s->lf, c);
        size_t nt = strlen(ch->topic);
        if (!ch->count || nt < ns || strcmp(ch->topic + nt - ns, suffix)) continue;
        int64_t n;
        const int64_t *pos = sooc_logfile_channel_msgs(s->lf, c, &n);
        sooc_logfile_msg m;
        double x;
        if (sooc_logfile_read(s->lf, pos[0], &m) || sooc_ros_decode_float(ch->type, m.data, m.size, ch->enc, &x)) continue;
        int score = common_prefix(ch->topic, near);
        if (score > best && x > 0 && isfinite(x)) {
            best = score;
            *v = x;
            *topic = ch->topic;
        }
    }
    sooc_clearerr();
    return best >= 0;
}

/* librealsense records each stream's extrinsics from the reference stream as
 * geometry_msgs/Transform on <stream>/tf/<ref>: p_stream = R p_ref + t. */
static int find_stream_extrinsics(sooc_logseq *s, const char *image_topic, double E[16], const char **topic) {
    for (int c = 0; c < sooc_logfile_channel_count(s->lf); c++) {
        const sooc_logfile_channel *ch = sooc_logfile_channel_get(s->lf, c);
        if (!ch->count || !type_is(ch->type, "geometry_msgs/Transform")) continue;
        const char *tfp = strstr(ch->topic, "/tf/");
        if (!tfp || strncmp(ch->topic, image_topic, (size_t)(tfp - ch->topic) + 1)) continue;
        int64_t n;
        const int64_t *pos = sooc_logfile_channel_msgs(s->lf, c, &n);
        sooc_logfile_msg m;
        sooc_ros_transform t;
        if (sooc_logfile_read(s->lf, pos[0], &m) || sooc_ros_decode_pose(ch->type, m.data, m.size, ch->enc, &t)) continue;
        double R[9];
        sooc_quat_to_m3(R, t.q);
        sooc_se3_from_rt(E, R, t.t);
        *topic = ch->topic;
        return 1;
    }
    sooc_clearerr();
    return 0;
}

static sooc_status load_tf(sooc_logseq *s) {
    sooc_status st = sooc_logs_tf_create(&s->tf);
    int cap = 64;
    sooc_ros_transform *buf = sooc_malloc(sizeof *buf * (size_t)cap);
    if (!buf) st = SOOC_ENOMEM;
    for (int c = 0; !st && c < sooc_logfile_channel_count(s->lf); c++) {
        const sooc_logfile_channel *ch = sooc_logfile_channel_get(s->lf, c);
        const char *t = ch->topic[0] == '/' ? ch->topic + 1 : ch->topic;
        int is_static = !strcmp(t, "tf_static");
        if ((strcmp(t, "tf") && !is_static) || (!type_is(ch->type, "tf2_msgs/TFMessage") && !type_is(ch->type, "tf/tfMessage")))
            continue;
        int64_t n;
        const int64_t *pos = sooc_logfile_channel_msgs(s->lf, c, &n);
        for (int64_t k = 0; k < n && !st; k++) {
            sooc_logfile_msg m;
            int nt = 0;
            if ((st = sooc_logfile_read(s->lf, pos[k], &m))) break;
            st = sooc_ros_decode_tf(m.data, m.size, ch->enc, buf, cap, &nt);
            if (!st && nt > cap) {
                sooc_ros_transform *b2 = sooc_realloc(buf, sizeof *buf * (size_t)nt);
                if (!b2) { st = SOOC_ENOMEM; break; }
                buf = b2;
                cap = nt;
                st = sooc_ros_decode_tf(m.data, m.size, ch->enc, buf, cap, &nt);
            }
            if (st) st = sooc_adderr(st, "%s", ctx(s, ch->topic, pos[k]));
            for (int i = 0; i < nt && !st; i++) st = sooc_logs_tf_add(s->tf, &buf[i], is_static);
        }
    }
    sooc_free(buf);
    if (!st) sooc_logs_tf_finish(s->tf);
    return st;
}

static int same_camera(const sooc_intrinsics *a, const sooc_intrinsics *b) {
    return a->width == b->width && a->height == b->height && fabs(a->fx - b->fx) < 1e-6 && fabs(a->fy - b->fy) < 1e-6 &&
           fabs(a->cx - b->cx) < 1e-6 && fabs(a->cy - b->cy) < 1e-6;
}

/* Decide whether depth is reprojected, and with which extrinsics. */
static sooc_status settle_registration(sooc_logseq *s) {
    sooc_logseq_desc *d = &s->d;
    const char *path = sooc_logfile_path(s->lf);
    sooc_se3_identity(d->T_color_depth);
    d->extrinsics_source = "n/a";
    int same_size = s->col.pub.width == s->dep.pub.width && s->col.pub.height == s->dep.pub.height;
    int both = s->col.pub.has_info && s->dep.pub.has_info;
    int need = s->p.registration == 1 || (s->p.registration < 0 && (!same_size || (both && !same_camera(&s->col.pub.K, &s->dep.pub.K))));
    if (!need) {
        if (!same_size)
            return sooc_seterr(SOOC_EINVAL, "%s: depth %s is %dx%d but colour %s is %dx%d: registration is off", path,
                               s->dep.pub.topic, s->dep.pub.width, s->dep.pub.height, s->col.pub.topic,
                               s->col.pub.width, s->col.pub.height);
        return SOOC_OK;
    }
    if (!both)
        return sooc_seterr(SOOC_EFORMAT, "%s: cannot register depth %s to colour %s: %s has no CameraInfo of its size",
                           path, s->dep.pub.topic, s->col.pub.topic,
                           s->col.pub.has_info ? s->dep.pub.topic : s->col.pub.topic);
    d->registered = 1;
    const char *cf = s->col.pub.frame_id, *df = s->dep.pub.frame_id, *et = NULL;
    double Ec[16], Ed[16], Edi[16];
    if (strcmp(cf, df) && sooc_logs_tf_has_frame(s->tf, cf) && sooc_logs_tf_has_frame(s->tf, df) &&
        sooc_logs_tf_lookup(s->tf, cf, df, s->pr && s->n ? s->pr[0].t : 0, INT64_MAX / 4, d->T_color_depth) == SOOC_OK) {
        snprintf(s->sbuf[0], sizeof s->sbuf[0], "tf %.70s <- %.70s", cf, df);
        d->extrinsics_source = s->sbuf[0];
    } else if (find_stream_extrinsics(s, s->col.pub.topic, Ec, &et)) {
        snprintf(s->sbuf[0], sizeof s->sbuf[0], "%.150s", et);
        if (!find_stream_extrinsics(s, s->dep.pub.topic, Ed, &et)) sooc_se3_identity(Ed);
        sooc_se3_inverse(Edi, Ed);
        sooc_se3_mul(d->T_color_depth, Ec, Edi);
        d->extrinsics_source = s->sbuf[0];
    } else {
        d->extrinsics_source = "identity (none in the log)";
        sooc_log(SOOC_LOG_WARN, "%s: no transform between depth frame '%s' and colour frame '%s': depth is reprojected "
                 "with intrinsics only", path, df, cf);
    }
    sooc_clearerr();
    return SOOC_OK;
}

static void pair_streams(sooc_logseq *s, int64_t tol) {
    int64_t j = 0;
    s->d.nearest_unpaired_s = 0;
    for (int64_t i = 0; i < s->col.n; i++) {
        int64_t tc, td, best = INT64_MAX, bk = -1;
        sooc_logfile_entry(s->lf, s->col.pos[i], NULL, &tc);
        while (j + 1 < s->dep.n) {   /* advance while the next depth is at least as close */
            sooc_logfile_entry(s->lf, s->dep.pos[j + 1], NULL, &td);
            if (td > tc) {
                int64_t tj;
                sooc_logfile_entry(s->lf, s->dep.pos[j], NULL, &tj);
                if (logs_tgap(td, tc) > logs_tgap(tj, tc)) break;
            }
            j++;
        }
        for (int64_t k = j; k < s->dep.n && k <= j + 1; k++) {
            sooc_logfile_entry(s->lf, s->dep.pos[k], NULL, &td);
            if (logs_tgap(td, tc) < best) { best = logs_tgap(td, tc); bk = k; }
        }
        if (bk >= 0 && best <= tol) {
            s->pr[s->n++] = (ls_pair){s->col.pos[i], s->dep.pos[bk], tc};
        } else {
            s->d.n_unpaired++;
            double gap = bk >= 0 ? best * 1e-9 : 0;
            if (bk >= 0 && (s->d.nearest_unpaired_s == 0 || gap < s->d.nearest_unpaired_s)) s->d.nearest_unpaired_s = gap;
        }
    }
}

static double rate(const sooc_logseq *s, const ls_stream *t) {
    if (t->n < 2) return 0;
    int64_t a, b;
    sooc_logfile_entry(s->lf, t->pos[0], NULL, &a);
    sooc_logfile_entry(s->lf, t->pos[t->n - 1], NULL, &b);
    return b > a ? (double)(t->n - 1) / (((double)b - (double)a) * 1e-9) : 0;
}

sooc_status sooc_logseq_open(sooc_logseq **out, const char *path, const sooc_logseq_params *pp) {
    *out = NULL;
    sooc_logseq *s = sooc_calloc(1, sizeof *s);
    if (!s) return SOOC_ENOMEM;
    if (pp) s->p = *pp;
    else sooc_logseq_params_default(&s->p);
    if (s->p.pair_tol_s <= 0) s->p.pair_tol_s = 0.02;
    if (s->p.pose_tol_s <= 0) s->p.pose_tol_s = 0.05;
    sooc_logseq_desc *d = &s->d;
    sooc_status st = sooc_logfile_open(&s->lf, path);
    if (!st) st = pick(s, 1, s->p.color_topic, &s->col);
    if (!st) st = pick(s, 2, s->p.depth_topic, &s->dep);
    if (st) goto fail;
    find_info(s, &s->col);
    find_info(s, &s->dep);
    s->col.pub.rate_hz = rate(s, &s->col);
    s->dep.pub.rate_hz = rate(s, &s->dep);
    /* depth units */
    const char *dt = NULL;
    double units = 0;
    int is_f32 = !strcmp(s->dep.pub.encoding, "32FC1") || !strncmp(s->dep.pub.encoding, "32FC1", 5);
    if (is_f32) {
        d->depth_scale = 0;
        d->depth_scale_source = "32FC1 metres";
    } else if (s->p.depth_scale > 0) {
        d->depth_scale = s->p.depth_scale;
        d->depth_scale_source = "launch";
    } else if (find_option(s, "/Depth Units/value", s->dep.pub.topic, &units, &dt)) {
        d->depth_scale = units;
        snprintf(s->sbuf[1], sizeof s->sbuf[1], "Depth Units option %.120s", dt);
        d->depth_scale_source = s->sbuf[1];
    } else {
        d->depth_scale = 0.001;
        d->depth_scale_source = "REP 118 default (millimetres)";
    }
    if ((st = load_tf(s))) goto fail;
    d->tf_transforms = sooc_logs_tf_count(s->tf);
    /* pairs */
    s->pr = sooc_malloc(sizeof *s->pr * (size_t)(s->col.n ? s->col.n : 1));
    if (!s->pr) { st = SOOC_ENOMEM; goto fail; }
    pair_streams(s, (int64_t)llround(s->p.pair_tol_s * 1e9));
    d->n_frames = s->n;
    if ((st = settle_registration(s))) goto fail;
    /* pose */
    const char *parent = s->p.pose_parent;
    const char *child = s->p.pose_child && *s->p.pose_child ? s->p.pose_child : s->col.pub.frame_id;
    if (parent && !strcmp(parent, "auto")) {
        parent = sooc_logs_tf_root(s->tf, child);
        if (parent && !strcmp(parent, child[0] == '/' ? child + 1 : child)) parent = NULL;
    }
    if (parent && *parent) {
        snprintf(d->pose_parent, sizeof d->pose_parent, "%s", parent);
        snprintf(d->pose_child, sizeof d->pose_child, "%s", child);
        char list[512];
        sooc_logs_tf_frame_list(s->tf, list, sizeof list);
        if (!sooc_logs_tf_has_frame(s->tf, d->pose_parent) || !sooc_logs_tf_has_frame(s->tf, d->pose_child)) {
            st = sooc_seterr(SOOC_ENOTFOUND, "%s: pose: frame '%s' is not in /tf or /tf_static (frames: %s)", path,
                             sooc_logs_tf_has_frame(s->tf, d->pose_parent) ? d->pose_child : d->pose_parent, list);
            goto fail;
        }
        d->has_pose = 1;
        double T[16];
        int64_t tol = (int64_t)llround(s->p.pose_tol_s * 1e9);
        for (int64_t i = 0; i < s->n; i++)
            if (sooc_logs_tf_lookup(s->tf, d->pose_parent, d->pose_child, s->pr[i].t, tol, T)) d->n_unposed++;
        sooc_clearerr();
    }
    d->color = s->col.pub;
    d->depth = s->dep.pub;
    *out = s;
    return SOOC_OK;
fail:
    sooc_logseq_close(s);
    return st;
}

void sooc_logseq_close(sooc_logseq *s) {
    if (!s) return;
    sooc_logfile_close(s->lf);
    stream_free(&s->col);
    stream_free(&s->dep);
    sooc_logs_tf_free(s->tf);
    sooc_free(s->pr);
    sooc_image_free(&s->img);
    sooc_free(s->zd);
    sooc_free(s);
}

int64_t sooc_logseq_count(const sooc_logseq *s) { return s ? s->n : 0; }
int64_t sooc_logseq_frame_time(const sooc_logseq *s, int64_t i) { return i >= 0 && i < s->n ? s->pr[i].t : INT64_MIN; }
const sooc_logseq_desc *sooc_logseq_describe(const sooc_logseq *s) { return &s->d; }

static sooc_status read_color(sooc_logseq *s, int64_t k, sooc_frame *f, int64_t *stamp) {
    const ls_stream *c = &s->col;
    const sooc_logfile_channel *ch = NULL;
    sooc_logfile_msg m;
    sooc_status st = sooc_logfile_read(s->lf, k, &m);
    if (st) return st;
    ch = sooc_logfile_channel_get(s->lf, m.channel);
    const char *name = ctx(s, c->pub.topic, k);
    int w = c->pub.width, h = c->pub.height;
    if (!f->rgb || f->width != w || f->height != h || f->instance) {
        sooc_frame_free(f);
        if ((st = sooc_frame_alloc(f, w, h, 0))) return st;
    }
    if (c->compressed) {
        sooc_ros_cimage ci;
        if (!(st = sooc_ros_decode_cimage(m.data, m.size, ch->enc, &ci))) st = sooc_logs_color_compressed(&ci, &s->img, name);
        if (st) return sooc_adderr(st, "%s", name);
        if (s->img.width != w || s->img.height != h)
            return sooc_seterr(SOOC_EFORMAT, "%s: image is %dx%d, the stream's first was %dx%d", name, s->img.width,
                               s->img.height, w, h);
        size_t np = (size_t)w * (size_t)h;
        const uint8_t *src = s->img.data;
        if (s->img.fmt == SOOC_PIX_RGB8) memcpy(f->rgb, src, np * 3);
        else
            for (size_t i = 0; i < np; i++) f->rgb[3 * i] = f->rgb[3 * i + 1] = f->rgb[3 * i + 2] = src[i];
        *stamp = ci.header.stamp_ns;
        return SOOC_OK;
    }
    sooc_ros_image im;
    if (!(st = sooc_ros_decode_image(m.data, m.size, ch->enc, &im))) st = sooc_logs_color_image(&im, f->rgb, w, h);
    *stamp = im.header.stamp_ns;
    return st ? sooc_adderr(st, "%s", name) : SOOC_OK;
}

/* Depth at the depth image's size into s->zd (or straight into dst when it fits). */
static sooc_status read_depth(sooc_logseq *s, int64_t k, float *dst) {
    const ls_stream *c = &s->dep;
    sooc_logfile_msg m;
    sooc_status st = sooc_logfile_read(s->lf, k, &m);
    if (st) return st;
    const sooc_logfile_channel *ch = sooc_logfile_channel_get(s->lf, m.channel);
    const char *name = ctx(s, c->pub.topic, k);
    int w = c->pub.width, h = c->pub.height;
    if (c->compressed) {
        sooc_ros_cimage ci;
        int gw = 0, gh = 0;
        if (!(st = sooc_ros_decode_cimage(m.data, m.size, ch->enc, &ci)))
            st = sooc_logs_depth_compressed(&ci, s->d.depth_scale, &s->img, &s->zd, &s->zcap, &gw, &gh, name);
        if (!st && (gw != w || gh != h))
            st = sooc_seterr(SOOC_EFORMAT, "%s: depth is %dx%d, the stream's first was %dx%d", name, gw, gh, w, h);
        if (!st && dst) memcpy(dst, s->zd, sizeof(float) * (size_t)w * (size_t)h);
        return st ? sooc_adderr(st, "%s", name) : SOOC_OK;
    }
    float *z = dst;
    if (!z) {
        if ((st = sooc_logs_reserve((uint8_t **)&s->zd, &s->zcap, sizeof(float) * (size_t)w * (size_t)h))) return st;
        z = s->zd;
    }
    sooc_ros_image im;
    if (!(st = sooc_ros_decode_image(m.data, m.size, ch->enc, &im))) st = sooc_logs_depth_image(&im, s->d.depth_scale, z, w, h);
    return st ? sooc_adderr(st, "%s", name) : SOOC_OK;
}

sooc_status sooc_logseq_read(sooc_logseq *s, int64_t i, sooc_frame *f) {
    if (i < 0 || i >= s->n)
        return sooc_seterr(SOOC_EINVAL, "%s: frame %lld out of range (%lld frames)", sooc_logfile_path(s->lf),
                           (long long)i, (long long)s->n);
    const ls_pair *p = &s->pr[i];
    int64_t stamp = 0;
    sooc_status st = read_color(s, p->kc, f, &stamp);   /* colour first: the next read may reuse its bytes */
    if (st) return st;
    if (s->d.registered) {
        if (!(st = read_depth(s, p->kd, NULL))) sooc_logs_register_depth(s->zd, &s->dep.pub.K, s->d.T_color_depth, f->depth, &s->col.pub.K);
    } else {
        st = read_depth(s, p->kd, f->depth);
    }
    if (st) return st;
    size_t np = (size_t)f->width * (size_t)f->height;
    float zmax = s->p.max_depth > 0 ? (float)s->p.max_depth : INFINITY;
    for (size_t k = 0; k < np; k++) {
        if (!(f->depth[k] <= zmax)) f->depth[k] = 0;
        f->valid[k] = f->depth[k] > 0;
    }
    f->t_ns = p->t;
    f->index = i;
    f->is_query = 0;
    f->K = s->col.pub.K;
    f->has_pose = 0;
    if (s->d.has_pose) {
        int64_t t = stamp ? stamp : p->t;
        st = sooc_logs_tf_lookup(s->tf, s->d.pose_parent, s->d.pose_child, t, (int64_t)llround(s->p.pose_tol_s * 1e9), f->T_wc);
        if (!st) f->has_pose = 1;
        else if (st != SOOC_ENOTFOUND) return sooc_adderr(st, "%s", sooc_logfile_path(s->lf));
        else sooc_clearerr();
    }
    return SOOC_OK;
}
