/*
 * The tape: eager forward ops on arena tensors, recorded as nodes, replayed
 * in reverse by sooc_nn_tape_backward (accumulating) or over a segment into
 * temporary gradient buffers by sooc_nn_tape_grad (docs/engine.md §3).
 *
 * Errors are sticky: the first failure is stored in the tape; every later op
 * returns NULL without doing anything.
 */
#include "nn_impl.h"
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

typedef enum node_op {
    OP_LINEAR, OP_SLOT_BIAS, OP_UNARY, OP_BINARY, OP_AFFINE, OP_CONCAT, OP_SLICE, OP_GATHER,
    OP_SCATTER, OP_SUM, OP_LAYERNORM, OP_POSENC, OP_RESHAPE
} node_op;

#define NODE_MAX_IN 8

typedef struct node {
    node_op op;
    int n_in;
    sooc_nn_tensor *in[NODE_MAX_IN];
    sooc_nn_tensor *out[2];
    float *saved[2];
    void *aux;
    int64_t ia[6];
    float fa[2];
} node;

struct sooc_nn_tape {
    sooc_nn_arena *arena;
    node *nodes;
    int n, cap;
    sooc_status status;
    char msg[256];
};

static atomic_uint g_epoch = 1;

sooc_status sooc_nn_tape_create(sooc_nn_tape **out, sooc_nn_arena *arena, int max_nodes) {
    *out = NULL;
    if (max_nodes < 1) return sooc_seterr(SOOC_EINVAL, "nn tape: max_nodes must be >= 1");
    sooc_nn_tape *t = sooc_calloc(1, sizeof *t);
    if (!t) return SOOC_ENOMEM;
    t->nodes = sooc_calloc((size_t)max_nodes, sizeof(node));
    if (!t->nodes) { sooc_free(t); return SOOC_ENOMEM; }
    t->arena = arena;
    t->cap = max_nodes;
    *out = t;
    return SOOC_OK;
}

void sooc_nn_tape_destroy(sooc_nn_tape *t) {
    if (!t) return;
    sooc_free(t->nodes);
    sooc_free(t);
}

void sooc_nn_tape_reset(sooc_nn_tape *t) {
    t->n = 0;
    t->status = SOOC_OK;
    t->msg[0] = 0;
}

sooc_status sooc_nn_tape_status(const sooc_nn_tape *t) { return t->status; }
const char *sooc_nn_tape_errmsg(const sooc_nn_tape *t) { return t->msg; }
int sooc_nn_tape_mark(const sooc_nn_tape *t) { return t->n; }

void sooc_nn_tape_cut(sooc_nn_tape *t, int mark) {
    SOOC_ASSERT(mark >= 0 && mark <= t->n);
    t->n = mark;
}

static void *fail(sooc_nn_tape *t, sooc_status s, const char *fmt, const char *a) {
    if (!t->status) {
        if (fmt) sooc_seterr(s, fmt, a ? a : "");
        t->status = s;
        snprintf(t->msg, sizeof t->msg, "%s", sooc_errmsg());
    }
    return NULL;
}

static sooc_nn_tensor *new_tensor(sooc_nn_tape *t, float *data, int ndim, const int64_t *shape,
                                  int req) {
    if (t->status) return NULL;
    if (ndim < 1 || ndim > SOOC_NN_MAX_DIMS)
        return fail(t, SOOC_EINVAL, "nn tape: bad ndim%s", "");
    sooc_nn_tensor *x = sooc_nn_arena_alloc(t->arena, sizeof *x);
    if (!x) return fail(t, SOOC_ENOMEM, NULL, NULL);
    memset(x, 0, sizeof *x);
    x->ndim = ndim;
    x->n = 1;
    for (int d = 0; d < ndim; d++) {
        if (shape[d] < 0) return fail(t, SOOC_EINVAL, "nn tape: negative dim%s", "");
        x->shape[d] = shape[d];
        x->n *= shape[d];
    }
    x->requires_grad = req;
    if (!data) {
        data = sooc_nn_arena_floats(t->arena, (size_t)x->n);
        if (!data) return fail(t, SOOC_ENOMEM, NULL, NULL);
    }
    x->data = data;
    return x;
}

sooc_nn_tensor *sooc_nn_tensor_new(sooc_nn_tape *t, float *data, int ndim, const int64_t *shape,
                                   int requires_grad) {
    return new_tensor(t, data, ndim, shape, requires_grad);
}

sooc_nn_tensor *sooc_nn_tensor_zeros(sooc_nn_tape *t, int ndim, const int64_t *shape,
                                     int requires_grad) {
    sooc_nn_tensor *x = new_tensor(t, NULL, ndim, shape, requires_grad);
    if (x) memset(x->data, 0, (size_t)x->n * sizeof(float));
    return x;
}

static float *ensure_grad(sooc_nn_tape *t, sooc_nn_tensor *x) {
    if (!x->grad) {
        x->grad = sooc_nn_arena_zeros(t->arena, (size_t)x->n);
        if (!x->grad) fail(t, SOOC_ENOMEM, NULL, NULL);
    }
    return x->grad;
}

/* gradient pointer for input x if it needs one, else NULL */
static float *gin(sooc_nn_tape *t, sooc_nn_tensor *x) {
    if (!x || !x->requires_grad) return NULL;
    return ensure_grad(t, x);
}

static node *push(sooc_nn_tape *t, node_op op, sooc_nn_tensor *out, int n_in, ...);

static int any_req(sooc_nn_tensor *const *xs, int n) {
    for (int i = 0; i < n; i++)
        if (xs[i] && xs[i]->requires_grad) return 1;
    return 0;
}

#include <stdarg.h>
static node *push(sooc_nn_tape *t, node_op op, sooc_nn_tensor *out, int n_in, ...) {
    if (t->n >= t->cap) return fail(t, SOOC_ENOMEM, "nn tape: node capacity exhausted%s", "");
    node *nd = &t->nodes[t->n++];
    memset(nd, 0, sizeof *nd);
    nd->op = op;
    nd->out[0] = out;
    nd->n_in = n_in;
    va_list ap;
    va_start(ap, n_in);
    for (int i = 0; i < n_in; i++) nd->in[i] = va_arg(ap, sooc_nn_tensor *);
    va_end(ap);
    out->requires_grad = any_req(nd->in, n_in);
    return nd;
}

#define CHECK_IN(x) do { if (t->status) return NULL; if (!(x)) return fail(t, SOOC_EINVAL, "nn tape: NULL input%s", ""); } while (0)
#define SHAPE_FAIL(what) fail(t, SOOC_EINVAL, "nn tape: shape mismatch in %s", what)

/* rows of a tensor viewed as [rows, last] */
static int64_t rows_of(const sooc_nn_tensor *x) {
    return x->shape[x->ndim - 1] ? x->n / x->shape[x->ndim - 1] : 0;
}

/* ------------------------------------------------------------ ops */

sooc_nn_tensor *sooc_nn_linear(sooc_nn_tape *t, sooc_nn_tensor *x, sooc_nn_tensor *w,
                               sooc_nn_tensor *b, sooc_nn_act act) {
    CHECK_IN(x); CHECK_IN(w);
    int64_t I = x->shape[x->ndim - 1];
    if (w->ndim != 2 || w->shape[1] != I || (b && b->n != w->shape[0])) return SHAPE_FAIL("linear");
    int64_t shp[SOOC_NN_MAX_DIMS];
    memcpy(shp, x->shape, sizeof shp);
    shp[x->ndim - 1] = w->shape[0];
    sooc_nn_tensor *y = new_tensor(t, NULL, x->ndim, shp, 0);
    if (!y) return NULL;
    sooc_nn_linear_forward(y->data, x->data, w->data, b ? b->data : NULL, rows_of(x), (int)I,
                           (int)w->shape[0], act);
    node *nd = push(t, OP_LINEAR, y, 3, x, w, b);
    if (!nd) return NULL;
    nd->ia[0] = act;
    return y;
}

sooc_nn_tensor *sooc_nn_slot_bias(sooc_nn_tape *t, sooc_nn_tensor *x, sooc_nn_tensor *b) {
    CHECK_IN(x); CHECK_IN(b);
    if (x->ndim != 3 || b->ndim != 2 || b->shape[0] != x->shape[0] || b->shape[1] != x->shape[2])
        return SHAPE_FAIL("slot_bias");
    sooc_nn_tensor *y = new_tensor(t, NULL, 3, x->shape, 0);
    if (!y) return NULL;
    sooc_nn_slot_bias_forward(y->data, x->data, b->data, (int)x->shape[0], x->shape[1],
                              (int)x->shape[2]);
    return push(t, OP_SLOT_BIAS, y, 2, x, b) ? y : NULL;
}

sooc_nn_tensor *sooc_nn_unary(sooc_nn_tape *t, sooc_nn_act f, sooc_nn_tensor *x) {
    CHECK_IN(x);
    sooc_nn_tensor *y = new_tensor(t, NULL, x->ndim, x->shape, 0);
    if (!y) return NULL;
    sooc_nn_unary_forward(f, y->data, x->data, x->n);
    node *nd = push(t, OP_UNARY, y, 1, x);
    if (!nd) return NULL;
    nd->ia[0] = f;
    return y;
}

static void pad_shape(const sooc_nn_tensor *x, int nd, int64_t *s) {
    int off = nd - x->ndim;
    for (int d = 0; d < nd; d++) s[d] = d < off ? 1 : x->shape[d - off];
}

sooc_nn_tensor *sooc_nn_binary(sooc_nn_tape *t, sooc_nn_binop op, sooc_nn_tensor *a,
                               sooc_nn_tensor *b) {
    CHECK_IN(a); CHECK_IN(b);
    int nd = a->ndim > b->ndim ? a->ndim : b->ndim;
    int64_t sa[SOOC_NN_MAX_DIMS], sb[SOOC_NN_MAX_DIMS], so[SOOC_NN_MAX_DIMS];
    pad_shape(a, nd, sa);
    pad_shape(b, nd, sb);
    for (int d = 0; d < nd; d++) {
        if (sa[d] != sb[d] && sa[d] != 1 && sb[d] != 1) return SHAPE_FAIL("binary broadcast");
        so[d] = sa[d] > sb[d] ? sa[d] : sb[d];
    }
    sooc_nn_tensor *y = new_tensor(t, NULL, nd, so, 0);
    if (!y) return NULL;
    sooc_nn_binary_forward(op, y->data, a->data, sa, b->data, sb, nd);
    node *n = push(t, OP_BINARY, y, 2, a, b);
    if (!n) return NULL;
    n->ia[0] = op;
    return y;
}

sooc_nn_tensor *sooc_nn_affine(sooc_nn_tape *t, sooc_nn_tensor *x, float s, float c) {
    CHECK_IN(x);
    sooc_nn_tensor *y = new_tensor(t, NULL, x->ndim, x->shape, 0);
    if (!y) return NULL;
    for (int64_t i = 0; i < x->n; i++) y->data[i] = x->data[i] * s + c;
    node *nd = push(t, OP_AFFINE, y, 1, x);
    if (!nd) return NULL;
    nd->fa[0] = s;
    return y;
}

static int norm_axis(int axis, int ndim) { return axis < 0 ? axis + ndim : axis; }

static void outer_inner(const sooc_nn_tensor *x, int axis, int64_t *outer, int64_t *inner) {
    *outer = 1;
    *inner = 1;
    for (int d = 0; d < axis; d++) *outer *= x->shape[d];
    for (int d = axis + 1; d < x->ndim; d++) *inner *= x->shape[d];
}

sooc_nn_tensor *sooc_nn_concat(sooc_nn_tape *t, sooc_nn_tensor *const *xs, int n, int axis) {
    if (t->status) return NULL;
    if (n < 1 || n > NODE_MAX_IN) return fail(t, SOOC_EINVAL, "nn tape: concat of 1..8 tensors%s", "");
    for (int i = 0; i < n; i++) CHECK_IN(xs[i]);
    int nd = xs[0]->ndim;
    axis = norm_axis(axis, nd);
    if (axis < 0 || axis >= nd) return SHAPE_FAIL("concat axis");
    int64_t shp[SOOC_NN_MAX_DIMS];
    memcpy(shp, xs[0]->shape, sizeof shp);
    shp[axis] = 0;
    for (int i = 0; i < n; i++) {
        if (xs[i]->ndim != nd) return SHAPE_FAIL("concat");
        for (int d = 0; d < nd; d++)
            if (d != axis && xs[i]->shape[d] != xs[0]->shape[d]) return SHAPE_FAIL("concat");
        shp[axis] += xs[i]->shape[axis];
    }
    sooc_nn_tensor *y = new_tensor(t, NULL, nd, shp, 0);
    if (!y) return NULL;
    int64_t outer, inner, c[NODE_MAX_IN];
    const float *ins[NODE_MAX_IN];
    outer_inner(y, axis, &outer, &inner);
    for (int i = 0; i < n; i++) { c[i] = xs[i]->shape[axis]; ins[i] = xs[i]->data; }
    sooc_nn_concat_forward(y->data, ins, c, n, outer, inner);
    node *no = push(t, OP_CONCAT, y, 0);
    if (!no) return NULL;
    no->n_in = n;
    for (int i = 0; i < n; i++) no->in[i] = xs[i];
    y->requires_grad = any_req(no->in, n);
    no->ia[0] = axis;
    return y;
}

sooc_nn_tensor *sooc_nn_slice(sooc_nn_tape *t, sooc_nn_tensor *x, int axis, int64_t start,
                              int64_t len) {
    CHECK_IN(x);
    axis = norm_axis(axis, x->ndim);
    if (axis < 0 || axis >= x->ndim || start < 0 || len < 0 || start + len > x->shape[axis])
        return SHAPE_FAIL("slice");
    int64_t shp[SOOC_NN_MAX_DIMS];
    memcpy(shp, x->shape, sizeof shp);
    shp[axis] = len;
    sooc_nn_tensor *y = new_tensor(t, NULL, x->ndim, shp, 0);
    if (!y) return NULL;
    int64_t outer, inner;
    outer_inner(x, axis, &outer, &inner);
    sooc_nn_slice_forward(y->data, x->data, outer, x->shape[axis], inner, start, len);
    node *nd = push(t, OP_SLICE, y, 1, x);
    if (!nd) return NULL;
    nd->ia[0] = axis;
    nd->ia[1] = start;
    nd->ia[2] = len;
    return y;
}

static int32_t *copy_idx(sooc_nn_tape *t, const int32_t *idx, int64_t N) {
    int32_t *c = sooc_nn_arena_alloc(t->arena, (size_t)(N ? N : 1) * sizeof(int32_t));
    if (!c) return fail(t, SOOC_ENOMEM, NULL, NULL);
    memcpy(c, idx, (size_t)N * sizeof(int32_t));
    return c;
}

/* gather (out row n = x row idx[n]; N rows out of M) and scatter-add (out row
 * idx[n] += x row n; M rows from N): the same index check, index copy, output
 * and node. The node keeps ia = {N, M, C}. */
static sooc_nn_tensor *index_op(sooc_nn_tape *t, int op, sooc_nn_tensor *x, const int32_t *idx, int64_t N,
                                int64_t M) {
    int gather = op == OP_GATHER;
    int64_t rows_in = x->shape[0], C = rows_in ? x->n / rows_in : 0;
    for (int64_t i = 0; i < N; i++)
        if (idx[i] < 0 || idx[i] >= M)
            return fail(t, SOOC_EINVAL, "nn tape: %s index out of range", gather ? "gather" : "scatter");
    int64_t shp[SOOC_NN_MAX_DIMS];
    memcpy(shp, x->shape, sizeof shp);
    shp[0] = gather ? N : M;
    int32_t *ci = copy_idx(t, idx, N);
    sooc_nn_tensor *y = ci ? new_tensor(t, NULL, x->ndim, shp, 0) : NULL;
    if (!y) return NULL;
    if (gather) sooc_nn_gather_forward(y->data, x->data, ci, N, M, C);
    else sooc_nn_scatter_add_forward(y->data, x->data, ci, N, M, C);
    node *nd = push(t, op, y, 1, x);
    if (!nd) return NULL;
    nd->aux = ci;
    nd->ia[0] = N; nd->ia[1] = M; nd->ia[2] = C;
    return y;
}

sooc_nn_tensor *sooc_nn_gather(sooc_nn_tape *t, sooc_nn_tensor *x, const int32_t *idx,
                               int64_t N) {
    CHECK_IN(x);
    return index_op(t, OP_GATHER, x, idx, N, x->shape[0]);
}

sooc_nn_tensor *sooc_nn_scatter_add(sooc_nn_tape *t, sooc_nn_tensor *src, const int32_t *idx,
                                    int64_t M) {
    CHECK_IN(src);
    return index_op(t, OP_SCATTER, src, idx, src->shape[0], M);
}

static sooc_nn_tensor *reduce(sooc_nn_tape *t, sooc_nn_tensor *x, int axis, int mean) {
    CHECK_IN(x);
    int64_t outer, C, inner, shp[SOOC_NN_MAX_DIMS];
    int nd;
    if (axis == SOOC_NN_ALL) {
        outer = 1; C = x->n; inner = 1; nd = 1; shp[0] = 1;
    } else {
        axis = norm_axis(axis, x->ndim);
        if (axis < 0 || axis >= x->ndim) return SHAPE_FAIL("reduce axis");
        outer_inner(x, axis, &outer, &inner);
        C = x->shape[axis];
        nd = 0;
        for (int d = 0; d < x->ndim; d++)
            if (d != axis) shp[nd++] = x->shape[d];
        if (nd == 0) { nd = 1; shp[0] = 1; }
    }
    sooc_nn_tensor *y = new_tensor(t, NULL, nd, shp, 0);
    if (!y) return NULL;
    sooc_nn_sum_forward(y->data, x->data, outer, C, inner, mean);
    node *no = push(t, OP_SUM, y, 1, x);
    if (!no) return NULL;
    no->ia[0] = outer; no->ia[1] = C; no->ia[2] = inner; no->ia[3] = mean;
    return y;
}

sooc_nn_tensor *sooc_nn_sum(sooc_nn_tape *t, sooc_nn_tensor *x, int axis) { return reduce(t, x, axis, 0); }
sooc_nn_tensor *sooc_nn_mean(sooc_nn_tape *t, sooc_nn_tensor *x, int axis) { return reduce(t, x, axis, 1); }

sooc_nn_tensor *sooc_nn_layernorm(sooc_nn_tape *t, sooc_nn_tensor *x, sooc_nn_tensor *w,
                                  sooc_nn_tensor *b, float eps) {
    CHECK_IN(x);
    int64_t C = x->shape[x->ndim - 1], N = rows_of(x);
    if ((w && w->n != C) || (b && b->n != C)) return SHAPE_FAIL("layernorm");
    sooc_nn_tensor *y = new_tensor(t, NULL, x->ndim, x->shape, 0);
    float *ms = y ? sooc_nn_arena_floats(t->arena, 2 * (size_t)N) : NULL;
    if (!ms) return fail(t, SOOC_ENOMEM, NULL, NULL);
    sooc_nn_layernorm_forward(y->data, ms, ms + N, x->data, w ? w->data : NULL,
                              b ? b->data : NULL, N, C, eps);
    node *nd = push(t, OP_LAYERNORM, y, 3, x, w, b);
    if (!nd) return NULL;
    nd->saved[0] = ms;
    nd->saved[1] = ms + N;
    return y;
}

sooc_nn_tensor *sooc_nn_posenc(sooc_nn_tape *t, sooc_nn_tensor *x, int F) {
    CHECK_IN(x);
    if (x->ndim != 2 || F < 0 || F > 20) return SHAPE_FAIL("posenc");
    int64_t shp[2] = {x->shape[0], sooc_nn_posenc_dim(x->shape[1], F)};
    sooc_nn_tensor *y = new_tensor(t, NULL, 2, shp, 0);
    if (!y) return NULL;
    sooc_nn_posenc_forward(y->data, x->data, x->shape[0], (int)x->shape[1], F);
    node *nd = push(t, OP_POSENC, y, 1, x);
    if (!nd) return NULL;
    nd->ia[0] = F;
    return y;
}

sooc_nn_tensor *sooc_nn_reshape(sooc_nn_tape *t, sooc_nn_tensor *x, int ndim,
                                const int64_t *shape) {
    CHECK_IN(x);
    int64_t n = 1;
    for (int d = 0; d < ndim && d < SOOC_NN_MAX_DIMS; d++) n *= shape[d];
    if (n != x->n) return SHAPE_FAIL("reshape");
    sooc_nn_tensor *y = new_tensor(t, x->data, ndim, shape, 0);
    if (!y) return NULL;
    return push(t, OP_RESHAPE, y, 1, x) ? y : NULL;
}

sooc_nn_tensor *sooc_nn_stop_grad(sooc_nn_tape *t, sooc_nn_tensor *x) {
    CHECK_IN(x);
    return new_tensor(t, x->data, x->ndim, x->shape, 0);
}

/* ------------------------------------------------------------ backward */

static void node_backward(sooc_nn_tape *t, node *nd) {
    sooc_nn_tensor *y = nd->out[0];
    int reached = y->grad || (nd->out[1] && nd->out[1]->grad);
    if (!reached) return; /* nothing reached it */
    sooc_nn_tensor **in = nd->in;
    sooc_nn_arena *A = t->arena;
    switch (nd->op) {
    case OP_LINEAR: {
        float *dx = gin(t, in[0]), *dw = gin(t, in[1]), *db = gin(t, in[2]);
        if (t->status) return;
        int64_t I = in[0]->shape[in[0]->ndim - 1], O = in[1]->shape[0];
        sooc_nn_act act = (sooc_nn_act)nd->ia[0];
        size_t mk = sooc_nn_arena_mark(A);
        float *dz = y->grad;
        if (act != SOOC_NN_ACT_NONE) { /* keep y->grad intact (it may be a wrt result) */
            dz = sooc_nn_arena_floats(A, (size_t)y->n);
            if (!dz) { fail(t, SOOC_ENOMEM, NULL, NULL); return; }
            memcpy(dz, y->grad, (size_t)y->n * sizeof(float));
        }
        sooc_nn_linear_backward(dx, dw, db, dz, in[0]->data, y->data, in[1]->data, rows_of(in[0]),
                                (int)I, (int)O, act);
        sooc_nn_arena_rewind(A, mk);
        break;
    }
    case OP_SLOT_BIAS: {
        float *dx = gin(t, in[0]), *db = gin(t, in[1]);
        if (t->status) return;
        sooc_nn_slot_bias_backward(dx, db, y->grad, (int)y->shape[0], y->shape[1], (int)y->shape[2]);
        break;
    }
    case OP_UNARY: {
        float *dx = gin(t, in[0]);
        if (!t->status) sooc_nn_unary_backward((sooc_nn_act)nd->ia[0], dx, y->grad, in[0]->data, y->data, y->n);
        break;
    }
    case OP_BINARY: {
        float *da = gin(t, in[0]), *db = gin(t, in[1]);
        if (t->status) return;
        int64_t sa[SOOC_NN_MAX_DIMS], sb[SOOC_NN_MAX_DIMS];
        pad_shape(in[0], y->ndim, sa);
        pad_shape(in[1], y->ndim, sb);
        sooc_nn_binary_backward((sooc_nn_binop)nd->ia[0], da, db, y->grad, in[0]->data, sa,
                                in[1]->data, sb, y->ndim);
        break;
    }
    case OP_AFFINE: {
        float *dx = gin(t, in[0]);
        if (dx) for (int64_t i = 0; i < y->n; i++) dx[i] += nd->fa[0] * y->grad[i];
        break;
    }
    case OP_CONCAT: {
        float *din[NODE_MAX_IN];
        int64_t c[NODE_MAX_IN], outer, inner;
        for (int i = 0; i < nd->n_in; i++) { din[i] = gin(t, in[i]); c[i] = in[i]->shape[nd->ia[0]]; }
        if (t->status) return;
        outer_inner(y, (int)nd->ia[0], &outer, &inner);
        sooc_nn_concat_backward(din, y->grad, c, nd->n_in, outer, inner);
        break;
    }
    case OP_SLICE: {
        float *dx = gin(t, in[0]);
        if (!dx) return;
        int64_t outer, inner;
        outer_inner(in[0], (int)nd->ia[0], &outer, &inner);
        sooc_nn_slice_backward(dx, y->grad, outer, in[0]->shape[nd->ia[0]], inner, nd->ia[1], nd->ia[2]);
        break;
    }
    case OP_GATHER: {
        float *dx = gin(t, in[0]);
        if (dx) sooc_nn_gather_backward(dx, y->grad, nd->aux, nd->ia[0], nd->ia[1], nd->ia[2]);
        break;
    }
    case OP_SCATTER: {
        float *dx = gin(t, in[0]);
        if (dx) sooc_nn_scatter_add_backward(dx, y->grad, nd->aux, nd->ia[0], nd->ia[1], nd->ia[2]);
        break;
    }
    case OP_SUM: {
        float *dx = gin(t, in[0]);
        if (dx) sooc_nn_sum_backward(dx, y->grad, nd->ia[0], nd->ia[1], nd->ia[2], (int)nd->ia[3]);
        break;
    }
    case OP_LAYERNORM: {
        float *dx = gin(t, in[0]), *dw = gin(t, in[1]), *db = gin(t, in[2]);
        if (t->status) return;
        int64_t C = y->shape[y->ndim - 1];
        sooc_nn_layernorm_backward(dx, dw, db, y->grad, in[0]->data, nd->saved[0], nd->saved[1],
                                   in[1] ? in[1]->data : NULL, rows_of(y), C);
        break;
    }
    case OP_POSENC: {
        float *dx = gin(t, in[0]);
        if (dx) sooc_nn_posenc_backward(dx, y->grad, y->data, in[0]->shape[0], (int)in[0]->shape[1], (int)nd->ia[0]);
        break;
    }
    case OP_RESHAPE: {
        float *dx = gin(t, in[0]);
        if (dx) for (int64_t i = 0; i < y->n; i++) dx[i] += y->grad[i];
        break;
    }
    }
}

sooc_status sooc_nn_tape_seed(sooc_nn_tape *t, sooc_nn_tensor *x, const float *g, float scale) {
    if (t->status) return t->status;
    float *d = ensure_grad(t, x);
    if (!d) return t->status;
    for (int64_t i = 0; i < x->n; i++) d[i] += scale * (g ? g[i] : 1.f);
    return SOOC_OK;
}

sooc_status sooc_nn_tape_backward(sooc_nn_tape *t) {
    for (int i = t->n - 1; i >= 0 && !t->status; i--) node_backward(t, &t->nodes[i]);
    return t->status;
}

/* swap every tensor touched by nodes [mark, n) to a temporary gradient */
static void seg_swap(sooc_nn_tape *t, int mark, uint32_t ep) {
    for (int i = mark; i < t->n; i++) {
        node *nd = &t->nodes[i];
        sooc_nn_tensor *ts[NODE_MAX_IN + 2];
        int k = 0;
        for (int j = 0; j < nd->n_in; j++) ts[k++] = nd->in[j];
        ts[k++] = nd->out[0];
        ts[k++] = nd->out[1];
        for (int j = 0; j < k; j++) {
            sooc_nn_tensor *x = ts[j];
            if (!x || x->epoch == ep) continue;
            x->epoch = ep;
            x->grad_main = x->grad;
            x->grad = NULL;
        }
    }
}

sooc_status sooc_nn_tape_grad(sooc_nn_tape *t, int mark, sooc_nn_tensor *loss,
                              const float *loss_grad, sooc_nn_tensor *const *wrt,
                              float *const *dwrt, int n_wrt, float param_scale) {
    if (t->status) return t->status;
    SOOC_ASSERT(mark >= 0 && mark <= t->n);
    uint32_t ep = atomic_fetch_add(&g_epoch, 1u) + 1u;
    seg_swap(t, mark, ep);
    int loss_swapped = loss->epoch == ep;
    if (!loss_swapped) { /* loss not produced in segment: nothing flows */
        loss->epoch = ep;
        loss->grad_main = loss->grad;
        loss->grad = NULL;
    }
    if (!sooc_nn_tape_seed(t, loss, loss_grad, 1.f))
        for (int i = t->n - 1; i >= mark && !t->status; i--) node_backward(t, &t->nodes[i]);
    if (!t->status) {
        for (int i = 0; i < n_wrt; i++) {
            sooc_nn_tensor *x = wrt[i];
            if (x->epoch == ep && x->grad) memcpy(dwrt[i], x->grad, (size_t)x->n * sizeof(float));
            else memset(dwrt[i], 0, (size_t)x->n * sizeof(float));
        }
    }
    /* restore main gradients; fold parameter gradients in */
    for (int i = mark; i <= t->n; i++) {
        sooc_nn_tensor *ts[NODE_MAX_IN + 2];
        int k = 0;
        if (i == t->n) ts[k++] = loss;
        else {
            node *nd = &t->nodes[i];
            for (int j = 0; j < nd->n_in; j++) ts[k++] = nd->in[j];
            ts[k++] = nd->out[0];
            ts[k++] = nd->out[1];
        }
        for (int j = 0; j < k; j++) {
            sooc_nn_tensor *x = ts[j];
            if (!x || x->epoch != ep) continue;
            x->epoch = ep + 0x80000000u; /* restored */
            if (x->is_param && x->grad && param_scale != 0.f && !t->status)
                for (int64_t e = 0; e < x->n; e++) x->grad_main[e] += param_scale * x->grad[e];
            x->grad = x->grad_main;
            x->grad_main = NULL;
        }
    }
    return t->status;
}
