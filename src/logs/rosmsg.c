/* Decoding the camera-rig messages without ROS: ROS 1 serialisation (little
 * endian, packed, strings and arrays with a uint32 length) and ROS 2 CDR (a
 * 4-byte encapsulation header, then every primitive aligned to its size
 * relative to the end of that header, strings with their NUL counted). */
#include "logs_impl.h"

#include <math.h>
#include <stdio.h>

/* A bounds-checked reader over one message. */
typedef struct rc {
    const uint8_t *p;
    size_t n, i, origin;
    int cdr, swap, bad;
    size_t bad_at, bad_need;
    const char *type;
} rc;

static sooc_status rc_init(rc *c, const uint8_t *d, size_t n, sooc_msg_encoding enc, const char *type) {
    memset(c, 0, sizeof *c);
    c->p = d;
    c->n = n;
    c->type = type;
    if (enc == SOOC_MSGENC_ROS1) return SOOC_OK;
    if (enc != SOOC_MSGENC_CDR)
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: message encoding not decoded (ros1 and cdr are)", type);
    if (n < 4) return sooc_seterr(SOOC_EFORMAT, "truncated %s: %zu bytes, no CDR encapsulation header", type, n);
    if (d[0] != 0 || d[1] > 1)
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: CDR encapsulation 0x%02x%02x not read (plain CDR only)", type, d[0],
                           d[1]);
    c->cdr = 1;
    c->swap = d[1] == 0;   /* 0x0000 = big endian, 0x0001 = little endian */
    c->i = c->origin = 4;
    return SOOC_OK;
}

static const uint8_t *take(rc *c, size_t k, size_t align) {
    if (c->bad) return NULL;
    if (c->cdr && align > 1) {
        size_t rel = c->i - c->origin, pad = (align - rel % align) % align;
        if (pad > c->n - c->i) goto bad;
        c->i += pad;
    }
    if (k > c->n - c->i) goto bad;
    const uint8_t *q = c->p + c->i;
    c->i += k;
    return q;
bad:
    c->bad = 1;
    c->bad_at = c->i;
    c->bad_need = k;
    return NULL;
}

static uint32_t rd32(const rc *c, const uint8_t *q) {
    return c->swap ? ((uint32_t)q[0] << 24) | ((uint32_t)q[1] << 16) | ((uint32_t)q[2] << 8) | q[3] : logs_u32(q);
}
static uint32_t g_u32(rc *c) {
    const uint8_t *q = take(c, 4, 4);
    return q ? rd32(c, q) : 0;
}
static uint8_t g_u8(rc *c) {
    const uint8_t *q = take(c, 1, 1);
    return q ? q[0] : 0;
}
static double g_f64(rc *c) {
    const uint8_t *q = take(c, 8, 8);
    if (!q) return 0;
    uint64_t v = c->swap ? ((uint64_t)rd32(c, q) << 32) | rd32(c, q + 4) : logs_u64(q);
    double d;
    memcpy(&d, &v, 8);
    return d;
}
static float g_f32(rc *c) {
    const uint8_t *q = take(c, 4, 4);
    if (!q) return 0;
    uint32_t v = rd32(c, q);
    float f;
    memcpy(&f, &v, 4);
    return f;
}
/* A string into out (cap bytes); a longer one is an error, not a cut name. */
static void g_str(rc *c, char *out, size_t cap) {
    uint32_t n = g_u32(c);
    const uint8_t *q = take(c, n, 1);
    if (!q) { if (cap) out[0] = 0; return; }
    size_t m = n;
    if (c->cdr && m && q[m - 1] == 0) m--;   /* CDR counts the terminating NUL */
    if (m >= cap) {
        c->bad = 2;
        c->bad_at = c->i - n;
        c->bad_need = m;
        out[0] = 0;
        return;
    }
    memcpy(out, q, m);
    out[m] = 0;
}
static const uint8_t *g_bytes(rc *c, size_t *n) {
    uint32_t k = g_u32(c);
    const uint8_t *q = take(c, k, 1);
    *n = q ? k : 0;
    return q;
}

static sooc_status rc_done(const rc *c) {
    if (c->bad == 2)
        return sooc_seterr(SOOC_EFORMAT, "%s: a string of %zu bytes at byte %zu is longer than this reader keeps",
                           c->type, c->bad_need, c->bad_at);
    if (c->bad)
        return sooc_seterr(SOOC_EFORMAT, "truncated %s: needs %zu bytes at byte %zu of %zu", c->type, c->bad_need,
                           c->bad_at, c->n);
    return SOOC_OK;
}

static void g_header(rc *c, sooc_ros_header *h) {
    int64_t sec, nsec;
    if (c->cdr) {
        sec = (int32_t)g_u32(c);
        nsec = g_u32(c);
    } else {
        (void)g_u32(c);   /* seq */
        sec = g_u32(c);
        nsec = g_u32(c);
    }
    h->stamp_ns = sec * 1000000000 + nsec;
    g_str(c, h->frame_id, sizeof h->frame_id);
}

/* ------------------------------------------------------------------ names */

const char *sooc_ros_type_base(const char *type, char *buf, size_t cap) {
    if (!cap) return buf;
    const char *m = type ? strstr(type, "/msg/") : NULL;
    if (m) snprintf(buf, cap, "%.*s/%s", (int)(m - type), type, m + 5);
    else snprintf(buf, cap, "%s", type ? type : "");
    return buf;
}

sooc_msg_encoding sooc_msg_encoding_parse(const char *name) {
    if (!name) return SOOC_MSGENC_OTHER;
    if (!strcmp(name, "ros1")) return SOOC_MSGENC_ROS1;
    if (!strcmp(name, "cdr")) return SOOC_MSGENC_CDR;
    return SOOC_MSGENC_OTHER;
}

static int type_is(const char *type, const char *base) {
    char b[160];
    return !strcmp(sooc_ros_type_base(type, b, sizeof b), base);
}

/* --------------------------------------------------------------- decoders */

sooc_status sooc_ros_decode_image(const uint8_t *d, size_t n, sooc_msg_encoding enc, sooc_ros_image *o) {
    rc c;
    memset(o, 0, sizeof *o);
    sooc_status st = rc_init(&c, d, n, enc, "sensor_msgs/Image");
    if (st) return st;
    g_header(&c, &o->header);
    uint32_t h = g_u32(&c), w = g_u32(&c);
    g_str(&c, o->encoding, sizeof o->encoding);
    o->bigendian = g_u8(&c);
    o->step = g_u32(&c);
    o->data = g_bytes(&c, &o->size);
    if ((st = rc_done(&c))) return st;
    if (w > 32768 || h > 32768)
        return sooc_seterr(SOOC_EFORMAT, "sensor_msgs/Image: %ux%u is larger than 32768 a side", w, h);
    o->width = (int)w;
    o->height = (int)h;
    if ((uint64_t)o->step * h > o->size)
        return sooc_seterr(SOOC_EFORMAT, "sensor_msgs/Image: %u rows of %zu bytes need %llu bytes, the data holds %zu",
                           h, o->step, (unsigned long long)o->step * h, o->size);
    return SOOC_OK;
}

sooc_status sooc_ros_decode_cimage(const uint8_t *d, size_t n, sooc_msg_encoding enc, sooc_ros_cimage *o) {
    rc c;
    memset(o, 0, sizeof *o);
    sooc_status st = rc_init(&c, d, n, enc, "sensor_msgs/CompressedImage");
    if (st) return st;
    g_header(&c, &o->header);
    g_str(&c, o->format, sizeof o->format);
    o->data = g_bytes(&c, &o->size);
    return rc_done(&c);
}

sooc_status sooc_ros_decode_caminfo(const uint8_t *d, size_t n, sooc_msg_encoding enc, sooc_ros_caminfo *o) {
    rc c;
    memset(o, 0, sizeof *o);
    sooc_status st = rc_init(&c, d, n, enc, "sensor_msgs/CameraInfo");
    if (st) return st;
    g_header(&c, &o->header);
    uint32_t h = g_u32(&c), w = g_u32(&c);
    g_str(&c, o->distortion_model, sizeof o->distortion_model);
    uint32_t nd = g_u32(&c);
    if (!c.bad && nd > (c.n - c.i) / 8) {
        c.bad = 1;
        c.bad_at = c.i;
        c.bad_need = (size_t)nd * 8;
    }
    for (uint32_t k = 0; k < nd && !c.bad; k++) {
        double v = g_f64(&c);
        if (k < 8) o->D[k] = v;
    }
    o->nD = (int)nd;
    for (int k = 0; k < 9; k++) o->K[k] = g_f64(&c);
    for (int k = 0; k < 9; k++) o->R[k] = g_f64(&c);
    for (int k = 0; k < 12; k++) o->P[k] = g_f64(&c);
    /* binning and roi follow; nothing here needs them */
    if ((st = rc_done(&c))) return st;
    if (w > 32768 || h > 32768)
        return sooc_seterr(SOOC_EFORMAT, "sensor_msgs/CameraInfo: %ux%u is larger than 32768 a side", w, h);
    o->width = (int)w;
    o->height = (int)h;
    return SOOC_OK;
}

static void g_vec(rc *c, double *v, int k) {
    for (int i = 0; i < k; i++) v[i] = g_f64(c);
}

sooc_status sooc_ros_decode_tf(const uint8_t *d, size_t n, sooc_msg_encoding enc, sooc_ros_transform *out, int cap,
                               int *n_out) {
    rc c;
    *n_out = 0;
    sooc_status st = rc_init(&c, d, n, enc, "tf2_msgs/TFMessage");
    if (st) return st;
    uint32_t k = g_u32(&c);
    sooc_ros_transform tmp;
    for (uint32_t i = 0; i < k && !c.bad; i++) {
        sooc_ros_transform *t = (int)i < cap ? &out[i] : &tmp;
        memset(t, 0, sizeof *t);
        g_header(&c, &t->header);
        g_str(&c, t->child, sizeof t->child);
        g_vec(&c, t->t, 3);
        g_vec(&c, t->q, 4);
    }
    if ((st = rc_done(&c))) return st;
    *n_out = (int)k;
    return SOOC_OK;
}

sooc_status sooc_ros_decode_pose(const char *type, const uint8_t *d, size_t n, sooc_msg_encoding enc,
                                 sooc_ros_transform *o) {
    rc c;
    memset(o, 0, sizeof *o);
    int kind = type_is(type, "geometry_msgs/TransformStamped") ? 1
             : type_is(type, "geometry_msgs/Transform")        ? 2
             : type_is(type, "geometry_msgs/PoseStamped")      ? 3
             : type_is(type, "geometry_msgs/Pose")             ? 4
             : type_is(type, "nav_msgs/Odometry")              ? 5
                                                               : 0;
    if (!kind) return sooc_seterr(SOOC_EUNSUPPORTED, "'%s' is not a pose or transform type read here", type);
    sooc_status st = rc_init(&c, d, n, enc, type);
    if (st) return st;
    if (kind == 1 || kind == 3 || kind == 5) g_header(&c, &o->header);
    if (kind == 1 || kind == 5) g_str(&c, o->child, sizeof o->child);
    g_vec(&c, o->t, 3);
    g_vec(&c, o->q, 4);
    return rc_done(&c);
}

sooc_status sooc_ros_decode_float(const char *type, const uint8_t *d, size_t n, sooc_msg_encoding enc, double *out) {
    rc c;
    int f64 = type_is(type, "std_msgs/Float64");
    if (!f64 && !type_is(type, "std_msgs/Float32"))
        return sooc_seterr(SOOC_EUNSUPPORTED, "'%s' is not std_msgs/Float32 or Float64", type);
    sooc_status st = rc_init(&c, d, n, enc, type);
    if (st) return st;
    *out = f64 ? g_f64(&c) : (double)g_f32(&c);
    return rc_done(&c);
}

/* --------------------------------------------------------------- encoders */

typedef struct wc {
    sooc_ros_buf *b;
    size_t origin;
    int cdr;
} wc;

void sooc_ros_buf_free(sooc_ros_buf *b) {
    if (!b) return;
    sooc_free(b->data);
    memset(b, 0, sizeof *b);
}

static void put(wc *w, const void *src, size_t k, size_t align) {
    sooc_ros_buf *b = w->b;
    if (b->oom) return;
    size_t pad = 0;
    if (w->cdr && align > 1) pad = (align - (b->size - w->origin) % align) % align;
    if (b->size + pad + k > b->cap) {
        size_t cap = b->cap ? b->cap : 256;
        while (cap < b->size + pad + k) cap *= 2;
        uint8_t *p = sooc_realloc(b->data, cap);
        if (!p) { b->oom = 1; return; }
        b->data = p;
        b->cap = cap;
    }
    memset(b->data + b->size, 0, pad);
    b->size += pad;
    if (k) memcpy(b->data + b->size, src, k);
    b->size += k;
}
static void p_u32(wc *w, uint32_t v) {
    uint8_t q[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
    put(w, q, 4, 4);
}
static void p_u8(wc *w, uint8_t v) { put(w, &v, 1, 1); }
static void p_f64(wc *w, double d) {
    uint64_t v;
    memcpy(&v, &d, 8);
    uint8_t q[8];
    for (int i = 0; i < 8; i++) q[i] = (uint8_t)(v >> (8 * i));
    put(w, q, 8, 8);
}
static void p_str(wc *w, const char *s) {
    size_t n = strlen(s);
    p_u32(w, (uint32_t)(n + (w->cdr ? 1 : 0)));
    put(w, s, n + (w->cdr ? 1 : 0), 1);
}
static void p_bytes(wc *w, const uint8_t *d, size_t n) {
    p_u32(w, (uint32_t)n);
    put(w, d, n, 1);
}
static void p_header(wc *w, const sooc_ros_header *h) {
    int64_t s = h->stamp_ns >= 0 ? h->stamp_ns / 1000000000 : -((-h->stamp_ns + 999999999) / 1000000000);
    uint32_t ns = (uint32_t)(h->stamp_ns - s * 1000000000);
    if (!w->cdr) p_u32(w, 0);
    p_u32(w, (uint32_t)s);
    p_u32(w, ns);
    p_str(w, h->frame_id);
}

/* Start a message (its encapsulation header in CDR) and write its std_msgs/Header when h is given. */
static sooc_status w_begin(wc *w, sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_header *h) {
    w->b = b;
    w->cdr = enc == SOOC_MSGENC_CDR;
    if (enc != SOOC_MSGENC_CDR && enc != SOOC_MSGENC_ROS1)
        return sooc_seterr(SOOC_EUNSUPPORTED, "encode: only ros1 and cdr are written");
    if (w->cdr) {
        static const uint8_t hdr[4] = {0, 1, 0, 0};
        put(w, hdr, 4, 1);
    }
    w->origin = b->size;
    if (h) p_header(w, h);
    return SOOC_OK;
}
static sooc_status w_end(wc *w) {
    return w->b->oom ? sooc_seterr(SOOC_ENOMEM, "encode: out of memory") : SOOC_OK;
}

sooc_status sooc_ros_encode_image(sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_image *m) {
    wc w;
    sooc_status st = w_begin(&w, b, enc, &m->header);
    if (st) return st;
    p_u32(&w, (uint32_t)m->height);
    p_u32(&w, (uint32_t)m->width);
    p_str(&w, m->encoding);
    p_u8(&w, (uint8_t)m->bigendian);
    p_u32(&w, (uint32_t)m->step);
    p_bytes(&w, m->data, m->size);
    return w_end(&w);
}

sooc_status sooc_ros_encode_cimage(sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_cimage *m) {
    wc w;
    sooc_status st = w_begin(&w, b, enc, &m->header);
    if (st) return st;
    p_str(&w, m->format);
    p_bytes(&w, m->data, m->size);
    return w_end(&w);
}

sooc_status sooc_ros_encode_caminfo(sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_caminfo *m) {
    wc w;
    sooc_status st = w_begin(&w, b, enc, &m->header);
    if (st) return st;
    p_u32(&w, (uint32_t)m->height);
    p_u32(&w, (uint32_t)m->width);
    p_str(&w, m->distortion_model);
    int nd = m->nD < 0 ? 0 : m->nD > 8 ? 8 : m->nD;
    p_u32(&w, (uint32_t)nd);
    for (int k = 0; k < nd; k++) p_f64(&w, m->D[k]);
    for (int k = 0; k < 9; k++) p_f64(&w, m->K[k]);
    for (int k = 0; k < 9; k++) p_f64(&w, m->R[k]);
    for (int k = 0; k < 12; k++) p_f64(&w, m->P[k]);
    for (int k = 0; k < 6; k++) p_u32(&w, 0);   /* binning_x, binning_y, roi x, y, height, width */
    p_u8(&w, 0);                                /* roi.do_rectify */
    return w_end(&w);
}

sooc_status sooc_ros_encode_tf(sooc_ros_buf *b, sooc_msg_encoding enc, const sooc_ros_transform *tf, int n) {
    wc w;
    sooc_status st = w_begin(&w, b, enc, NULL);
    if (st) return st;
    p_u32(&w, (uint32_t)n);
    for (int i = 0; i < n; i++) {
        p_header(&w, &tf[i].header);
        p_str(&w, tf[i].child);
        for (int k = 0; k < 3; k++) p_f64(&w, tf[i].t[k]);
        for (int k = 0; k < 4; k++) p_f64(&w, tf[i].q[k]);
    }
    return w_end(&w);
}
