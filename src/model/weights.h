/* Layer 0 of src/model (docs/model.md "Layers"): configuration and weights
 * (model.c) and the kernels every layer above runs on (kern.c: the GEMM
 * aliases, the task pool of a workspace). Includes no other model header.
 * Internal interface of src/model (docs/architecture.md "Layers"): src/finetune
 * includes it; not installed, not a public API. */
#ifndef SOOC3D_MODEL_WEIGHTS_H
#define SOOC3D_MODEL_WEIGHTS_H

#include "sooc3d/model.h"
#include "sooc3d/core.h"
#include "nn/nn_kern.h"

#define MDL_NL(d) (6 + 2 * (d))   /* λ size per slot */
/* Parallel regions only pay off with enough rows: with fewer, thread start-up
 * and barriers dominate (badly so on a loaded 2-core machine). */
#define MDL_PAR_ROWS 1024
#ifdef SOOC_HAVE_OPENMP
#define MDL_OMP(x) _Pragma(#x)
#else
#define MDL_OMP(x)
#endif
#define MDL_MAXT 64               /* tensors */

/* Phase timers (compiled out by default; build with -DMDL_PROFILE to read
 * where an update's time goes: bench_keyframe prints them). */
enum { MDL_PR_DEC_PREP, MDL_PR_DEC_FWD, MDL_PR_DEC_COMP, MDL_PR_DEC_BWD, MDL_PR_DEC_RED, MDL_PR_AUX,
       MDL_PR_CONV0, MDL_PR_CONV1, MDL_PR_CONV2, MDL_PR_CONV3, MDL_PR_FC, MDL_PR_GATES, MDL_PR_LSTM, MDL_PR_HEAD,
       MDL_PR_N };
#ifdef MDL_PROFILE
extern double mdl_prof[MDL_PR_N];
#define MDL_PT(v) double v = sooc_seconds()
#define MDL_PACC(i, v) (mdl_prof[i] += sooc_seconds() - (v), (v) = sooc_seconds())
#else
#define MDL_PT(v) ((void)0)
#define MDL_PACC(i, v) ((void)0)
#endif

typedef struct sooc_dec_net {          /* offsets into the slab */
    size_t W1x, W1z, b1, W2, b2, W3, b3, Wd, bd, Wc1, bc1, Wc2, bc2;
    int din, dz, H, Hc, nfreq;
} sooc_dec_net;

typedef struct sooc_ref_net {
    size_t cw[4], cb[4], fcW, fcb, Wx, Wh, lb, hW, hb;
    int cin, ch[4], nflat, fc, hid, nvec, nout;
} sooc_ref_net;

/* The weights: configuration, the parameter slab and its gradient, the
 * tensor table and the networks' offsets. No workspace, no thread pool, no
 * step state: those are the runner's (struct sooc_model_ws below). */
struct sooc_model {
    sooc_model_config cfg;
    int NL;
    float *p, *g;
    size_t np;
    sooc_model_tensor t[MDL_MAXT];
    int nt;
    sooc_dec_net dobj, dlay;
    sooc_ref_net robj, rlay;
    size_t prior, prior_lay;      /* K x NL, 2 d_l */
    int threads;                  /* sooc_model_set_threads: the thread count a workspace's pool uses */
};

/* A runner's workspace (sooc_model_ws_create, in the step layer: workspace.c).
 * Whoever runs the model (the mapper, the global baseline, the trainer, tests)
 * creates one per model and thread of control and passes it down the layers;
 * each layer touches only its own part, whose type its own header defines:
 * the pool here (kern.c), `dec` the decoder's (decoder.h), `ref` the
 * refinement's (refine.h), `step` the training step's (step.h, made on the
 * first step). */
struct sooc_dec_ws;
struct sooc_ref_ws;
struct sooc_step_state;
struct sooc_model_ws {
    sooc_model *m;                /* the model it was made for (not owned) */
    sooc_nn_pool *pool;           /* kern.c: made on first use, remade when m->threads changes */
    struct sooc_dec_ws *dec;
    struct sooc_ref_ws *ref;
    struct sooc_step_state *step;
};

/* model.c */
/* config.unit_m at the cognitive map's boundary. n slot posteriors λ
 * (flat cogmap.h layout, stride NL) in a G frame: metres -> model units
 * (x, z divided by unit_m, rho_t less 2 ln unit_m) and back. No-ops at
 * unit_m = 1 (bit-identical). */
void sooc_mdl_lam_from_m(const sooc_model_config *c, float *lam, int n, int NL);
void sooc_mdl_lam_to_m(const sooc_model_config *c, float *lam, int n, int NL);

/* Image channels of a refinement net's input (its first conv's width in
 * the slab): 26 for objects, 25 for the layout (refine.c builds them). */
int sooc_mdl_aux_channels(int layout);

/* The engine's GEMM (src/nn/gemm.c, nn/nn_kern.h) under the model's old names:
 * C[M x N] = init + A[M x K] B[K x N], all row-major (leading dimensions
 * lda, ldb, ldc), init = C (acc != 0), else the row vector bias (N; NULL: 0);
 * then the epilogue ep: MDL_EP_RELU max(0, .), MDL_EP_MASK zero where
 * mask[i ldm + j] <= 0 (ReLU backward on a post-activation). AVX2/FMA when the
 * CPU has it (SOOC_NO_AVX2 set in the environment forces the portable path). */
enum { MDL_EP_NONE = SOOC_NN_EP_NONE, MDL_EP_RELU = SOOC_NN_EP_RELU, MDL_EP_MASK = SOOC_NN_EP_MASK };
static inline void mdl_gemm(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc,
                            const float *bias, int acc, int ep, const float *mask, int ldm) {
    sooc_nn_gemm(M, N, K, A, lda, B, ldb, C, ldc, bias, acc, ep, mask, ldm);
}
static inline int mdl_kern_avx2(void) { return sooc_nn_gemm_avx2(); }
/* kern.c: the task pool (sooc_nn_pool) of a workspace. sooc_mdl_par_run runs fn(ctx, t, tid) for t = 0..n-1, the
 * caller being tid 0 and up to sooc_mdl_par_threads(w) - 1 helpers the others (tid < sooc_mdl_par_threads(w));
 * tasks are claimed one at a time and the caller waits only for claimed tasks. A task's
 * result must not depend on tid. sooc_mdl_par_threads makes w's pool (w->m->threads) if needed. */
typedef sooc_nn_task_fn sooc_mdl_task_fn;
int sooc_mdl_par_threads(sooc_model_ws *w);
void sooc_mdl_par_run(sooc_model_ws *w, int n, sooc_mdl_task_fn fn, void *ctx);
void sooc_mdl_pool_free(sooc_model_ws *w);

#endif
