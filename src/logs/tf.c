/* A TF buffer built from a log's /tf and /tf_static: a tree of frames, each
 * with its pose in its parent over time, and lookups between any two
 * connected frames (through their lowest common ancestor). */
#include "logseq_impl.h"
#include "logs_impl.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

typedef struct tf_sample {
    int64_t t;
    double p[3], q[4];
} tf_sample;

typedef struct tf_frame {
    char name[128];
    int parent;                /* -1: a root */
    int is_static;
    tf_sample *s;
    size_t n, cap;
} tf_frame;

struct sooc_logs_tf {
    tf_frame *f;
    int n, cap;
    int64_t count, reparented;
};

sooc_status sooc_logs_tf_create(sooc_logs_tf **out) {
    *out = sooc_calloc(1, sizeof **out);
    return *out ? SOOC_OK : SOOC_ENOMEM;
}

void sooc_logs_tf_free(sooc_logs_tf *tf) {
    if (!tf) return;
    for (int i = 0; i < tf->n; i++) sooc_free(tf->f[i].s);
    sooc_free(tf->f);
    sooc_free(tf);
}

static const char *strip(const char *name) { return name[0] == '/' ? name + 1 : name; }   /* ROS 1 "/map" = "map" */

static int find(const sooc_logs_tf *tf, const char *name) {
    name = strip(name);
    for (int i = 0; i < tf->n; i++)
        if (!strcmp(tf->f[i].name, name)) return i;
    return -1;
}

static int intern(sooc_logs_tf *tf, const char *name) {
    int i = find(tf, name);
    if (i >= 0) return i;
    if (tf->n == tf->cap) {
        int cap = tf->cap ? tf->cap * 2 : 16;
        tf_frame *f = sooc_realloc(tf->f, sizeof *f * (size_t)cap);
        if (!f) return -1;
        tf->f = f;
        tf->cap = cap;
    }
    tf_frame *f = &tf->f[tf->n];
    memset(f, 0, sizeof *f);
    snprintf(f->name, sizeof f->name, "%s", strip(name));
    f->parent = -1;
    return tf->n++;
}

sooc_status sooc_logs_tf_add(sooc_logs_tf *tf, const sooc_ros_transform *t, int is_static) {
    int c = intern(tf, t->child), p = intern(tf, t->header.frame_id);
    if (c < 0 || p < 0) return sooc_seterr(SOOC_ENOMEM, "tf: out of memory");
    if (c == p || !t->child[0]) return SOOC_OK;
    tf_frame *f = &tf->f[c];
    if (f->parent >= 0 && f->parent != p) {
        tf->reparented++;
        return SOOC_OK;
    }
    for (int a = p; a >= 0; a = tf->f[a].parent)   /* a loop would make lookups endless */
        if (a == c) {
            tf->reparented++;
            return SOOC_OK;
        }
    f->parent = p;
    if (is_static) {
        f->is_static = 1;
        f->n = 0;
    } else if (f->is_static) {
        return SOOC_OK;
    }
    if (f->n == f->cap) {
        size_t cap = f->cap ? f->cap * 2 : 16;
        tf_sample *s = sooc_realloc(f->s, sizeof *s * cap);
        if (!s) return sooc_seterr(SOOC_ENOMEM, "tf: out of memory");
        f->s = s;
        f->cap = cap;
    }
    tf_sample *s = &f->s[f->n++];
    s->t = t->header.stamp_ns;
    memcpy(s->p, t->t, sizeof s->p);
    memcpy(s->q, t->q, sizeof s->q);
    tf->count++;
    return SOOC_OK;
}

static int cmp_sample(const void *a, const void *b) {
    const tf_sample *x = a, *y = b;
    return x->t < y->t ? -1 : x->t > y->t;
}

void sooc_logs_tf_finish(sooc_logs_tf *tf) {
    for (int i = 0; i < tf->n; i++)
        if (tf->f[i].n > 1) qsort(tf->f[i].s, tf->f[i].n, sizeof(tf_sample), cmp_sample);
}

int64_t sooc_logs_tf_count(const sooc_logs_tf *tf) { return tf->count; }
int sooc_logs_tf_has_frame(const sooc_logs_tf *tf, const char *name) { return find(tf, name) >= 0; }

void sooc_logs_tf_frame_list(const sooc_logs_tf *tf, char *buf, size_t cap) {
    size_t m = 0;
    if (cap) buf[0] = 0;
    for (int i = 0; i < tf->n && m + 1 < cap; i++) {
        int k = snprintf(buf + m, cap - m, "%s%s", i ? ", " : "", tf->f[i].name);
        if (k < 0 || (size_t)k >= cap - m) break;
        m += (size_t)k;
    }
    if (!tf->n) snprintf(buf, cap, "none");
}

static void to_T(double T[16], const double p[3], const double q[4]) {
    double R[9];
    sooc_quat_to_m3(R, q);
    sooc_se3_from_rt(T, R, p);
}

/* Pose of frame i in its parent at t. */
static sooc_status edge(const sooc_logs_tf *tf, int i, int64_t t, int64_t tol, double T[16]) {
    const tf_frame *f = &tf->f[i];
    const char *pn = tf->f[f->parent].name;
    if (!f->n) return sooc_seterr(SOOC_ENOTFOUND, "tf: no transform %s -> %s", pn, f->name);
    if (f->is_static || f->n == 1) {
        if (f->is_static || logs_tgap(t, f->s[0].t) <= tol) {
            to_T(T, f->s[0].p, f->s[0].q);
            return SOOC_OK;
        }
    } else {
        size_t lo = 0, hi = f->n;   /* first sample with t_s >= t */
        while (lo < hi) {
            size_t mid = (lo + hi) / 2;
            if (f->s[mid].t < t) lo = mid + 1;
            else hi = mid;
        }
        if (lo < f->n && f->s[lo].t == t) {
            to_T(T, f->s[lo].p, f->s[lo].q);
            return SOOC_OK;
        }
        if (lo > 0 && lo < f->n) {
            const tf_sample *a = &f->s[lo - 1], *b = &f->s[lo];
            double w = ((double)t - (double)a->t) / ((double)b->t - (double)a->t), p[3], q[4];
            for (int k = 0; k < 3; k++) p[k] = a->p[k] + w * (b->p[k] - a->p[k]);
            sooc_quat_slerp(q, a->q, b->q, w);
            to_T(T, p, q);
            return SOOC_OK;
        }
        const tf_sample *s = lo == 0 ? &f->s[0] : &f->s[f->n - 1];
        if (logs_tgap(t, s->t) <= tol) {
            to_T(T, s->p, s->q);
            return SOOC_OK;
        }
    }
    return sooc_seterr(SOOC_ENOTFOUND, "tf: %s -> %s has no transform within %.3f s of t = %.6f s (it spans %.6f .. %.6f s)",
                       pn, f->name, (double)tol * 1e-9, (double)t * 1e-9, (double)f->s[0].t * 1e-9,
                       (double)f->s[f->n - 1].t * 1e-9);
}

/* T_anc_i: the pose of frame i in its ancestor anc. */
static sooc_status chain(const sooc_logs_tf *tf, int anc, int i, int64_t t, int64_t tol, double T[16]) {
    sooc_se3_identity(T);
    for (int c = i; c != anc; c = tf->f[c].parent) {
        double E[16], tmp[16];
        sooc_status st = edge(tf, c, t, tol, E);
        if (st) return st;
        sooc_se3_mul(tmp, E, T);
        memcpy(T, tmp, sizeof tmp);
    }
    return SOOC_OK;
}

static int common_ancestor(const sooc_logs_tf *tf, int a, int b) {
    for (int x = a; x >= 0; x = tf->f[x].parent)
        for (int y = b; y >= 0; y = tf->f[y].parent)
            if (x == y) return x;
    return -1;
}

sooc_status sooc_logs_tf_lookup(const sooc_logs_tf *tf, const char *parent, const char *child, int64_t t, int64_t tol_ns,
                           double T[16]) {
    int p = find(tf, parent), c = find(tf, child);
    if (p < 0 || c < 0) {
        char list[512];
        sooc_logs_tf_frame_list(tf, list, sizeof list);
        return sooc_seterr(SOOC_ENOTFOUND, "tf: no frame '%s' (frames: %s)", p < 0 ? parent : child, list);
    }
    int a = common_ancestor(tf, p, c);
    if (a < 0) return sooc_seterr(SOOC_ENOTFOUND, "tf: frames '%s' and '%s' are not connected", parent, child);
    double Tap[16], Tac[16], Tpa[16];
    sooc_status st = chain(tf, a, p, t, tol_ns, Tap);
    if (!st) st = chain(tf, a, c, t, tol_ns, Tac);
    if (st) return st;
    sooc_se3_inverse(Tpa, Tap);
    sooc_se3_mul(T, Tpa, Tac);
    return SOOC_OK;
}

const char *sooc_logs_tf_root(const sooc_logs_tf *tf, const char *frame) {
    int i = find(tf, frame);
    if (i < 0) return NULL;
    while (tf->f[i].parent >= 0) i = tf->f[i].parent;
    return tf->f[i].name;
}
