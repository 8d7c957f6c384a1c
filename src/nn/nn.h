/*
 * sooc3d nn: the float32 numerics engine (tensors, layers, autodiff, Adam,
 * parameter slabs, checkpoints). See docs/engine.md for the design, the
 * measurements behind it and the test strategy.
 *
 * An internal interface header of src/nn (docs/architecture.md "Headers"):
 * src/model, src/train, the tests and benchmarks include it as "nn/nn.h";
 * it is not installed and not part of the public API.
 *
 * Three layers, use whichever fits:
 *
 *  1. Kernel pairs (llm.c style), on raw row-major float arrays:
 *       sooc_nn_<op>_forward (out, saved..., in, weights, sizes)
 *       sooc_nn_<op>_backward(din, dweights, dout, saved, in, weights, sizes)
 *     Backward ACCUMULATES (+=) into every gradient pointer; any gradient
 *     pointer may be NULL to skip that gradient. Shapes are in comments,
 *     dimension letters: N points/rows, K slots, C channels, B batch (slots
 *     for images), H/W height/width, I/O/G LSTM input/hidden sizes.
 *     No allocation: callers pass scratch buffers whose size is given by a
 *     *_floats() helper.
 *
 *  2. A tape (sooc_nn_tape) over arena tensors (sooc_nn_tensor): eager
 *     forward ops `sooc_nn_<op>(tape, ...)` compute immediately and record a
 *     node; sooc_nn_tape_backward() replays the nodes in reverse. Errors are
 *     sticky: once an op fails (arena full, shape mismatch), every later op
 *     returns NULL and sooc_nn_tape_status() reports the first error.
 *     sooc_nn_tape_grad() takes the gradient of an intermediate loss over a
 *     tape segment into separate buffers without disturbing the final
 *     backward. The model does not run on the tape (it runs on the kernel
 *     pairs of layers 1 and 3); the tape is the reference the engine's
 *     gradient and PyTorch tests build composite networks with
 *     (tests/nn/test_nn_grad.c, test_nn_ref.c, test_nn_state.c).
 *
 *  3. The kernels the model runs (nn/nn_kern.h): the GEMM, the task
 *     pool and the decoder MLP layers as forward / backward pairs.
 *
 * Memory: parameters, gradients and Adam moments live in one sooc_nn_params
 * slab each (named views); activations live in a sooc_nn_arena (bump
 * allocator, reset per step). Nothing here calls malloc during a step.
 *
 * Threads: OpenMP loops only over outputs each iteration owns, so results
 * are bitwise identical with OpenMP on or off and for any thread count
 * (the nn_kern.h kernels are serial; callers split rows). All parallelism
 * here is OpenMP: the engine puts
 * OpenBLAS in single-thread mode on first use (process-global, see
 * sooc_nn_blas_set_threads) and splits large sgemms into a fixed number of
 * M/N blocks (never K), so no output element's summation order depends on
 * the thread count: results are bitwise identical with OpenMP on or off.
 *
 * Thread safety: kernels are reentrant. A tape/arena/params object must be
 * used by one thread at a time.
 */
#ifndef SOOC3D_NN_H
#define SOOC3D_NN_H

#include <stddef.h>
#include <stdint.h>
#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SOOC_NN_MAX_DIMS 4

/* ============================================================ activations */

/* Elementwise functions; also the fused activation of linear/conv/MLP.
 * Formulas (x input, y output):
 *   RELU     y = max(x, 0)             dy/dx = [x > 0]   (0 at the kink)
 *   ELU      y = x>0 ? x : exp(x)-1    dy/dx = x>0 ? 1 : y+1   (alpha = 1)
 *   SIGMOID  y = 1/(1+exp(-x))         dy/dx = y(1-y)
 *   SOFTPLUS y = log(1+exp(x))         dy/dx = sigmoid(x)  (beta 1; x>20: y=x, like torch)
 *   EXP, LOG, SQUARE (y = x^2), TANH.
 * Fused activations (linear/conv/MLP) must be computable from y alone:
 * NONE, RELU, ELU, SIGMOID, TANH. */
typedef enum sooc_nn_act {
    SOOC_NN_ACT_NONE = 0,
    SOOC_NN_ACT_RELU,
    SOOC_NN_ACT_ELU,
    SOOC_NN_ACT_SIGMOID,
    SOOC_NN_ACT_SOFTPLUS,
    SOOC_NN_ACT_EXP,
    SOOC_NN_ACT_LOG,
    SOOC_NN_ACT_SQUARE,
    SOOC_NN_ACT_TANH
} sooc_nn_act;

/* Binary elementwise ops with numpy broadcasting. */
typedef enum sooc_nn_binop {
    SOOC_NN_ADD = 0, SOOC_NN_SUB, SOOC_NN_MUL, SOOC_NN_DIV
} sooc_nn_binop;

/* ============================================================ kernel pairs */

/* y[N] = f(x[N]).  backward: dx[N] += dy * f'(x) (uses x and/or y). */
void sooc_nn_unary_forward(sooc_nn_act f, float *y, const float *x, int64_t n);
void sooc_nn_unary_backward(sooc_nn_act f, float *dx, const float *dy, const float *x,
                            const float *y, int64_t n);

/* out = a (op) b with numpy broadcasting. Shapes are given padded to the same
 * `ndim` (<= 4); each dim of a and b is either equal to the output dim or 1.
 * out_shape[d] = max(ashape[d], bshape[d]). backward reduces over broadcast
 * dims: da[ashape] += ..., db[bshape] += ... (either may be NULL). */
void sooc_nn_binary_forward(sooc_nn_binop op, float *out, const float *a, const int64_t *ashape,
                            const float *b, const int64_t *bshape, int ndim);
void sooc_nn_binary_backward(sooc_nn_binop op, float *da, float *db, const float *dout,
                             const float *a, const int64_t *ashape, const float *b,
                             const int64_t *bshape, int ndim);

/* Dense layer, torch layout (I = Ci, O = Co):
 *   y[N,O] = act(x[N,I] w[O,I]^T + b[O]) (b may be NULL).
 * backward: dy[N,O] is OVERWRITTEN with the pre-activation gradient when
 * act != NONE; then dx[N,I] += dz w, dw[O,I] += dz^T x, db[O] += sum_n dz.
 * y is the forward output (needed for act' ). Uses sgemm (OpenBLAS threads). */
void sooc_nn_linear_forward(float *y, const float *x, const float *w, const float *b,
                            int64_t N, int Ci, int Co, sooc_nn_act act);
void sooc_nn_linear_backward(float *dx, float *dw, float *db, float *dy, const float *x,
                             const float *y, const float *w, int64_t N, int Ci, int Co,
                             sooc_nn_act act);

/* dz = dy * act'(y) in place (act in NONE/RELU/ELU/SIGMOID/TANH). */
void sooc_nn_act_backward_inplace(sooc_nn_act act, float *dy, const float *y, int64_t n);

/* Per-slot bias broadcast over points: y[K,N,C] = x[K,N,C] + b[K,C].
 * backward: dx += dy, db[k,c] += sum_n dy[k,n,c]. y may alias x. */
void sooc_nn_slot_bias_forward(float *y, const float *x, const float *b, int K, int64_t N, int C);
void sooc_nn_slot_bias_backward(float *dx, float *db, const float *dy, int K, int64_t N, int C);

/* Concatenate n_in tensors viewed as [outer, c[i], inner] along the middle
 * axis: out[outer, sum c, inner]. backward: din[i] += matching block of dout
 * (din[i] may be NULL). */
void sooc_nn_concat_forward(float *out, const float *const *in, const int64_t *c, int n_in,
                            int64_t outer, int64_t inner);
void sooc_nn_concat_backward(float *const *din, const float *dout, const int64_t *c, int n_in,
                             int64_t outer, int64_t inner);

/* out[outer, len, inner] = in[outer, start:start+len, inner] of in[outer, C, inner]. */
void sooc_nn_slice_forward(float *out, const float *in, int64_t outer, int64_t C, int64_t inner,
                           int64_t start, int64_t len);
void sooc_nn_slice_backward(float *din, const float *dout, int64_t outer, int64_t C,
                            int64_t inner, int64_t start, int64_t len);

/* Row gather: out[N,C] = in[idx[n], :] of in[M,C]. idx values must be in
 * [0, M) (checked with SOOC_ASSERT). backward: din[idx[n]] += dout[n]
 * (serial over n: deterministic). */
void sooc_nn_gather_forward(float *out, const float *in, const int32_t *idx, int64_t N,
                            int64_t M, int64_t C);
void sooc_nn_gather_backward(float *din, const float *dout, const int32_t *idx, int64_t N,
                             int64_t M, int64_t C);

/* Row scatter-add: out[M,C] = 0; out[idx[n]] += src[n] for n in order.
 * backward: dsrc[n] += dout[idx[n]]. */
void sooc_nn_scatter_add_forward(float *out, const float *src, const int32_t *idx, int64_t N,
                                 int64_t M, int64_t C);
void sooc_nn_scatter_add_backward(float *dsrc, const float *dout, const int32_t *idx, int64_t N,
                                  int64_t M, int64_t C);

/* Sum (mean if `mean`) over the middle axis: out[outer, inner] from
 * in[outer, C, inner]. Accumulates in double, in index order. */
void sooc_nn_sum_forward(float *out, const float *in, int64_t outer, int64_t C, int64_t inner,
                         int mean);
void sooc_nn_sum_backward(float *din, const float *dout, int64_t outer, int64_t C,
                          int64_t inner, int mean);

/* Layer norm over the last axis of x[N,C]:
 *   y = (x - mean) * rstd * w + b, rstd = 1/sqrt(var + eps) (biased var).
 * w, b may be NULL (non-learnable; MulMON "LN"). mean[N], rstd[N] are saved. */
void sooc_nn_layernorm_forward(float *y, float *mean, float *rstd, const float *x,
                               const float *w, const float *b, int64_t N, int64_t C, float eps);
void sooc_nn_layernorm_backward(float *dx, float *dw, float *db, const float *dy,
                                const float *x, const float *mean, const float *rstd,
                                const float *w, int64_t N, int64_t C);

/* Sinusoidal positional encoding (no pi):
 *   y[n] = [x, sin(2^0 x), cos(2^0 x), sin(2^1 x), cos(2^1 x), ...,
 *           sin(2^(F-1) x), cos(2^(F-1) x)]
 * where each entry is a D-vector: y[N, D*(1+2F)] from x[N,D].
 * D=3, F=5 gives the decoder's 33 inputs. backward: dx[N,D] += ... (uses y). */
static inline int64_t sooc_nn_posenc_dim(int64_t D, int F) { return D * (1 + 2 * (int64_t)F); }
void sooc_nn_posenc_forward(float *y, const float *x, int64_t N, int D, int F);
void sooc_nn_posenc_backward(float *dx, const float *dy, const float *y, int64_t N, int D, int F);

/* The refinement network's conv 3x3 stride 2 and LSTM cell, in the model's
 * layouts, are the pairs of nn/nn_refine.h. */

/* ================================================================== arena */

/* One big 64-byte aligned buffer with bump allocation. reset() rewinds it;
 * pointers handed out before are invalid afterwards. Not thread-safe. */
typedef struct sooc_nn_arena {
    unsigned char *base;
    size_t cap, used, peak;
} sooc_nn_arena;

sooc_status sooc_nn_arena_init(sooc_nn_arena *a, size_t cap_bytes);
void sooc_nn_arena_deinit(sooc_nn_arena *a);                 /* NULL-safe */
void sooc_nn_arena_reset(sooc_nn_arena *a);
static inline size_t sooc_nn_arena_mark(const sooc_nn_arena *a) { return a->used; }
void sooc_nn_arena_rewind(sooc_nn_arena *a, size_t mark);
/* n bytes rounded up to 64; NULL + SOOC_ENOMEM message when full. */
void *sooc_nn_arena_alloc(sooc_nn_arena *a, size_t nbytes);
float *sooc_nn_arena_floats(sooc_nn_arena *a, size_t n);     /* uninitialised */
float *sooc_nn_arena_zeros(sooc_nn_arena *a, size_t n);

/* ================================================================= tensor */

/* A contiguous row-major float32 tensor. `data` and `grad` point into an
 * arena, a params slab or caller memory; the struct never owns them.
 * grad is NULL until a backward pass needs it (params: the slab's view). */
typedef struct sooc_nn_tensor {
    float *data;
    float *grad;
    int64_t shape[SOOC_NN_MAX_DIMS];
    int ndim;
    int64_t n;            /* number of elements */
    int requires_grad;    /* gradient flows into this tensor             */
    int is_param;         /* a view of a sooc_nn_params slab             */
    /* internal (tape bookkeeping) */
    float *grad_main;
    uint32_t epoch;
    const char *name;
} sooc_nn_tensor;

/* ================================================================ params */

/* Parameters, gradients and Adam moments as four flat slabs with the same
 * layout. Register views (name, shape) first, then sooc_nn_params_alloc();
 * each view starts on a 64-byte boundary. View tensors are stable for the
 * lifetime of the object (use sooc_nn_params_tensor()). */
typedef struct sooc_nn_param_view {
    char name[64];
    int ndim;
    int64_t shape[SOOC_NN_MAX_DIMS];
    size_t offset, n;         /* in floats */
    float lr_mult, wd_mult;   /* per-view optimizer multipliers (default 1) */
    sooc_nn_tensor t;         /* data/grad point into w/g after alloc */
} sooc_nn_param_view;

typedef struct sooc_nn_params {
    sooc_nn_param_view *views;
    int n_views, cap_views;
    size_t n_total;           /* floats per slab, including alignment padding */
    float *w, *g, *m, *v;     /* slabs (NULL before alloc) */
    int64_t adam_t;           /* Adam steps taken */
} sooc_nn_params;

void sooc_nn_params_init(sooc_nn_params *p);
void sooc_nn_params_deinit(sooc_nn_params *p);              /* NULL-safe */
/* Register a view; returns its index (>= 0) or a negative status. Names must
 * be unique and < 64 chars. Not allowed after alloc. */
int sooc_nn_params_add(sooc_nn_params *p, const char *name, int ndim, const int64_t *shape);
/* Allocate the 4 slabs, zeroed. */
sooc_status sooc_nn_params_alloc(sooc_nn_params *p);
sooc_nn_tensor *sooc_nn_params_tensor(sooc_nn_params *p, int index);
/* Index of a view by name, or -1. */
int sooc_nn_params_find(const sooc_nn_params *p, const char *name);
void sooc_nn_params_zero_grad(sooc_nn_params *p);
/* torch default Linear/Conv init: U(-1/sqrt(fan_in), 1/sqrt(fan_in)). */
void sooc_nn_init_uniform(float *w, size_t n, float bound, sooc_rng *rng);

/* ============================================================= optimizer */

typedef struct sooc_nn_adam_cfg {
    float beta1, beta2, eps;
    float weight_decay;   /* Adam: L2 added to the gradient; AdamW: decoupled */
    int adamw;            /* 0 = Adam (torch.optim.Adam), 1 = AdamW */
} sooc_nn_adam_cfg;

/* beta (0.9, 0.999), eps 1e-8, no weight decay, Adam. */
sooc_nn_adam_cfg sooc_nn_adam_default(void);
/* One step over all views with learning rate lr (times each view's
 * lr_mult; weight decay times wd_mult). Increments p->adam_t first; bias
 * correction as torch. Gradients are not zeroed. Non-finite gradient ->
 * SOOC_ENUMERIC, nothing updated. */
sooc_status sooc_nn_adam_step(sooc_nn_params *p, const sooc_nn_adam_cfg *cfg, float lr);
/* Global L2 norm of the gradient slab (double accumulation, fixed order). */
double sooc_nn_grad_norm(const sooc_nn_params *p);
/* torch.nn.utils.clip_grad_norm_: if norm > max_norm scale grads by
 * max_norm/(norm+1e-6). Returns the norm before clipping. */
double sooc_nn_clip_grad_norm(sooc_nn_params *p, double max_norm);

typedef enum sooc_nn_decay { SOOC_NN_DECAY_CONST = 0, SOOC_NN_DECAY_LINEAR, SOOC_NN_DECAY_COSINE } sooc_nn_decay;
typedef struct sooc_nn_schedule {
    float lr;              /* peak learning rate */
    int64_t warmup;        /* steps of linear warm-up from lr/warmup to lr */
    int64_t total;         /* total steps (decay ends here) */
    float final_frac;      /* lr at step `total` = lr * final_frac */
    sooc_nn_decay decay;
} sooc_nn_schedule;
/* lr for 0-based step: warm-up lr*(step+1)/warmup for step < warmup, then
 * decay from lr to lr*final_frac over [warmup, total]; clamped after total. */
float sooc_nn_schedule_lr(const sooc_nn_schedule *s, int64_t step);

/* =================================================================== tape */

typedef struct sooc_nn_tape sooc_nn_tape;

/* A tape records up to max_nodes ops; tensors, saved activations and
 * gradients come from `arena` (not owned). */
sooc_status sooc_nn_tape_create(sooc_nn_tape **out, sooc_nn_arena *arena, int max_nodes);
void sooc_nn_tape_destroy(sooc_nn_tape *t);                  /* NULL-safe */
/* Forget all nodes and clear the sticky error. Does NOT reset the arena
 * (do that yourself, usually right after). */
void sooc_nn_tape_reset(sooc_nn_tape *t);
/* First error since reset (SOOC_OK if none); message via sooc_errmsg() at
 * the time of failure, also kept in the tape: */
sooc_status sooc_nn_tape_status(const sooc_nn_tape *t);
const char *sooc_nn_tape_errmsg(const sooc_nn_tape *t);

/* Leaf tensors. `data` NULL allocates (uninitialised / zeroed) in the arena,
 * otherwise wraps caller memory (not copied; must outlive the tape use). */
sooc_nn_tensor *sooc_nn_tensor_new(sooc_nn_tape *t, float *data, int ndim, const int64_t *shape,
                                   int requires_grad);
sooc_nn_tensor *sooc_nn_tensor_zeros(sooc_nn_tape *t, int ndim, const int64_t *shape,
                                     int requires_grad);

/* Recorded ops (all return NULL on error, see sticky status). Output
 * requires grad iff an input does. Shapes: */
/* x[N,I], w[O,I], b[O] or NULL -> [N,O] (x may have more leading dims, flattened) */
sooc_nn_tensor *sooc_nn_linear(sooc_nn_tape *t, sooc_nn_tensor *x, sooc_nn_tensor *w,
                               sooc_nn_tensor *b, sooc_nn_act act);
/* x[K,N,C] + b[K,C] */
sooc_nn_tensor *sooc_nn_slot_bias(sooc_nn_tape *t, sooc_nn_tensor *x, sooc_nn_tensor *b);
sooc_nn_tensor *sooc_nn_unary(sooc_nn_tape *t, sooc_nn_act f, sooc_nn_tensor *x);
/* numpy broadcasting, ndim right-aligned */
sooc_nn_tensor *sooc_nn_binary(sooc_nn_tape *t, sooc_nn_binop op, sooc_nn_tensor *a,
                               sooc_nn_tensor *b);
/* y = x * s + c (scalars) */
sooc_nn_tensor *sooc_nn_affine(sooc_nn_tape *t, sooc_nn_tensor *x, float s, float c);
/* along `axis` (negative counts from the end) */
sooc_nn_tensor *sooc_nn_concat(sooc_nn_tape *t, sooc_nn_tensor *const *xs, int n, int axis);
sooc_nn_tensor *sooc_nn_slice(sooc_nn_tape *t, sooc_nn_tensor *x, int axis, int64_t start,
                              int64_t len);
/* x[M,C...] rows gathered: [N, C...]; idx copied into the arena */
sooc_nn_tensor *sooc_nn_gather(sooc_nn_tape *t, sooc_nn_tensor *x, const int32_t *idx,
                               int64_t N);
/* src[N,C...] scatter-added into M rows: [M, C...] */
sooc_nn_tensor *sooc_nn_scatter_add(sooc_nn_tape *t, sooc_nn_tensor *src, const int32_t *idx,
                                    int64_t M);
/* Reduce over `axis`, removing it; axis = SOOC_NN_ALL reduces everything to shape [1]. */
#define SOOC_NN_ALL 99
sooc_nn_tensor *sooc_nn_sum(sooc_nn_tape *t, sooc_nn_tensor *x, int axis);
sooc_nn_tensor *sooc_nn_mean(sooc_nn_tape *t, sooc_nn_tensor *x, int axis);
/* layer norm over the last axis; w, b: [C] or NULL */
sooc_nn_tensor *sooc_nn_layernorm(sooc_nn_tape *t, sooc_nn_tensor *x, sooc_nn_tensor *w,
                                  sooc_nn_tensor *b, float eps);
/* x[N,D] -> [N, D(1+2F)] */
sooc_nn_tensor *sooc_nn_posenc(sooc_nn_tape *t, sooc_nn_tensor *x, int F);
/* same data, new shape (copy-free forward; backward adds the gradient) */
sooc_nn_tensor *sooc_nn_reshape(sooc_nn_tape *t, sooc_nn_tensor *x, int ndim,
                                const int64_t *shape);
/* identity forward (shares data), no gradient flows back */
sooc_nn_tensor *sooc_nn_stop_grad(sooc_nn_tape *t, sooc_nn_tensor *x);

/* ---------------------------------------------------------- backward */

/* Add `scale * g` (g NULL: ones) into x's gradient (allocating it). Use it to
 * seed the final backward, possibly at several tensors. */
sooc_status sooc_nn_tape_seed(sooc_nn_tape *t, sooc_nn_tensor *x, const float *g, float scale);
/* Run all recorded nodes in reverse, accumulating (+=) into the grad of every
 * tensor that requires grad (params: into the params g slab). */
sooc_status sooc_nn_tape_backward(sooc_nn_tape *t);

/* Node index to delimit a segment for sooc_nn_tape_grad / _cut. */
int sooc_nn_tape_mark(const sooc_nn_tape *t);

/* Local gradient of an intermediate scalar-or-seeded `loss` over the nodes
 * recorded since `mark`, into separate buffers, leaving every tensor's main
 * gradient untouched:
 *   - dwrt[i][wrt[i]->n] = d loss / d wrt[i]  (OVERWRITTEN; loss seeded with
 *     `loss_grad` if non-NULL (loss->n floats), else ones);
 *   - if param_scale != 0, every parameter gradient reached in the segment
 *     is accumulated into the params g slab as param_scale * d loss/d param
 *     (exactly: computed in a temporary buffer, then scaled and added).
 * Temporaries come from the arena. The results are plain arrays: wrap them
 * with sooc_nn_tensor_new(..., requires_grad = 0) to feed them back as
 * stop-gradient inputs. The later sooc_nn_tape_backward still traverses the
 * segment (correct, since its main grads are untouched); call
 * sooc_nn_tape_cut(t, mark) first if the segment should not be revisited. */
sooc_status sooc_nn_tape_grad(sooc_nn_tape *t, int mark, sooc_nn_tensor *loss,
                              const float *loss_grad, sooc_nn_tensor *const *wrt,
                              float *const *dwrt, int n_wrt, float param_scale);
/* Drop the nodes recorded since `mark` (their outputs stay valid as data
 * but do not propagate gradient). */
void sooc_nn_tape_cut(sooc_nn_tape *t, int mark);

/* Set OpenBLAS threads and return the previous count. The nn kernels reset
 * it to 1 on their next call (they parallelise with OpenMP themselves); use
 * this only around your own large BLAS calls. */
int sooc_nn_blas_set_threads(int n);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_NN_H */
