/* Internal structures of the model module (not a public API; tests include it). */
#ifndef SOOC3D_MODEL_INTERNAL_H
#define SOOC3D_MODEL_INTERNAL_H

#include "sooc3d/model.h"
#include "sooc3d/geom.h"
#include "sooc3d/nn_kern.h"

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

typedef struct dec_net {          /* offsets into the slab */
    size_t W1x, W1z, b1, W2, b2, W3, b3, Wd, bd, Wc1, bc1, Wc2, bc2;
    int din, dz, H, Hc, nfreq;
} dec_net;

typedef struct ref_net {
    size_t cw[4], cb[4], fcW, fcb, Wx, Wh, lb, hW, hb;
    int cin, ch[4], nflat, fc, hid, nvec, nout;
} ref_net;

/* Rays of one view in G_t (origin at the camera centre). P = 2 N points:
 * point 2r = surface sample, 2r + 1 = air sample. */
typedef struct view_rays {
    int N, gw, gh;                /* N = gw * gh, ray r <-> grid cell (r / gw, r % gw) */
    float *dir;                   /* N x 3 unit direction in G                         */
    float *rgb;                   /* N x 3 observed colour in [0, 1]                   */
    float *depth;                 /* N Euclidean depth (valid rays)                    */
    uint8_t *surf;                /* N 1 = surface visible (d <= d_clip)               */
    uint8_t *unk;                 /* N 1 = depth unknown (invalid_depth UNKNOWN and no
                                     valid depth): no surface, no air sample, no colour */
    float *W;                     /* N air-sample importance weight                    */
    float *pts;                   /* 2N x 3 points in G                                */
    float h, pitch;               /* camera height, pitch                              */
    float blk[3];                 /* active layout block origin in G (x, -h, z)        */
} view_rays;

/* Noise of one decode, shared with the reference. */
typedef struct dec_noise {
    float eps_where[SOOC_MODEL_K_MAX][3];
    float eps_what[SOOC_MODEL_K_MAX][SOOC_MODEL_D_MAX];
    float logistic[SOOC_MODEL_K_MAX];
    float eps_lay[SOOC_MODEL_D_MAX];
} dec_noise;

/* Workspace of the fused decoder (sized for P points and K slots at create). */
typedef struct dec_ws {
    int Pmax, Kmax;
    /* object rows */
    int nro; int *ro_pt, *ro_slot; int cnt[SOOC_MODEL_K_MAX + 1];
    float *o_pe, *o_a1, *o_a2, *o_a3, *o_ac, *o_sig, *o_col, *o_xk, *o_gf;
    /* layout rows (one per point) */
    float *l_pe, *l_a1, *l_a2, *l_a3, *l_ac, *l_sig, *l_col;
    /* backward scratch */
    float *gA, *gB, *gC, *gpe;
    /* dense per point x component (comp 0 = layout, 1..K objects) */
    float *sh, *ct, *gsh, *gct; int *rowof;
    float *S, *Sb, *cc;           /* per point */
    float *ll;                    /* per ray log-lik (ell_c + ell_d) */
    float *ll_cf;                 /* N x (K+1) counterfactual ell - ell_{-k} */
    int *lr_pt;                   /* layout row -> point */
    float *tbuf;                  /* nthr x (dec_np + (K+1) H + 3K) thread-private grads */
    size_t dec_np;                /* decoder parameters: slab offsets [0, dec_np) */
    int nthr;
    float *slot_bias;             /* (K+1) x H */
    float *wt;                    /* nwt: transposed decoder weights for the backward GEMMs */
    size_t nwt;
    float *g_bias;                /* (K+1) x H */
} dec_ws;

/* One decode: inputs, outputs. */
typedef struct dec_call {
    const view_rays *rays;
    int nslot;                    /* active object slots (<= K)                 */
    const float *lam;             /* nslot x NL                                 */
    const float *lam0;            /* nslot x NL prior (NULL: no KL, query view) */
    const float *lay, *lay0;      /* 2 d_l (lay0 NULL: no layout KL)            */
    const dec_noise *noise;
    float tau, beta_kl, sigma_c;
    const uint8_t *hard;          /* per slot: 0 relaxed, 1 straight-through hard, 2 forced one */
    float wgrad;                  /* scale of decoder weight gradients (0: none)               */
    const float *zw_sg;           /* TEST ONLY (nslot x 3): forward multiplies σ̂ by
                                     w_g(Π(zw) x) / w_g(Π(zw_sg) x), i.e. the Gaussian trick
                                     written as a forward, for finite-difference checks        */
    int backward;                 /* 0: forward only                                           */
    /* outputs */
    double loss, nll, nll_d, nll_c, kl;
    float *g_lam, *g_lam0, *g_lay, *g_lay0;   /* ACCUMULATED (+=) when non-NULL; UNWEIGHTED */
    /* samples (outputs, for aux inputs) */
    float zw[SOOC_MODEL_K_MAX][3], zwhat[SOOC_MODEL_K_MAX][SOOC_MODEL_D_MAX];
    float zp[SOOC_MODEL_K_MAX], zp_soft[SOOC_MODEL_K_MAX], zlay[SOOC_MODEL_D_MAX];
} dec_call;

/* Refinement activations for one (view, iteration), B items. */
typedef struct ref_act {
    int B;
    int nsh;                      /* leading input channels shared by every item, stored for
                                     item 0 only (the backward fills the other copies); 0 = none */
    float *x0;                    /* B x cin x gh x gw  (stored as [c][b][hw]) */
    float *y[4];                  /* conv outputs [c][b][hw] (post-ELU)        */
    float *flat, *f;              /* B x nflat, B x fc (post-ELU)              */
    float *xin;                   /* B x (fc + nvec)                           */
    float *gates;                 /* B x 4H post-nonlinearity (i, f, g, o)     */
    float *c_prev, *h_prev, *c, *h; /* B x H                                   */
} ref_act;

typedef struct ref_ws {           /* scratch for conv forward/backward */
    float *cols, *gcols, *gy[4], *gflat, *gf, *gx, *gg, *gh;
    size_t ncols;                 /* floats in cols (and gcols): per-thread slices in the forward */
    float *ysh;                   /* 2 x ysh_ch x (gw gh / 4): first-conv share of the shared channels */
    int ysh_ch;
    float *gconv;                 /* ngconv: the second item block's conv weight gradients (backward) */
    size_t ngconv;
} ref_ws;

struct sooc_model {
    sooc_model_config cfg;
    int NL;
    float *p, *g;
    size_t np;
    sooc_model_tensor t[MDL_MAXT];
    int nt;
    dec_net dobj, dlay;
    ref_net robj, rlay;
    size_t prior, prior_lay;      /* K x NL, 2 d_l */
    int threads;
    dec_ws ws;
    ref_ws rws;
    void *step;                   /* training-step state (step.c) */
    sooc_nn_pool *pool;           /* task pool of the inference passes (kern.c), made on first use */
};

/* model.c */
sooc_status mdl_alloc_ws(sooc_model *m);
void mdl_free_ws(sooc_model *m);

/* model.c: config.unit_m at the cognitive map's boundary. n slot posteriors λ
 * (flat cogmap.h layout, stride NL) in a G frame: metres -> model units
 * (x, z divided by unit_m, rho_t less 2 ln unit_m) and back. No-ops at
 * unit_m = 1 (bit-identical). */
void mdl_lam_from_m(const sooc_model_config *c, float *lam, int n, int NL);
void mdl_lam_to_m(const sooc_model_config *c, float *lam, int n, int NL);

/* decoder.c */
void mdl_sample_noise(const sooc_model *m, sooc_rng *r, dec_noise *n);
sooc_status mdl_decode(sooc_model *m, dec_call *c);
/* KL between two slot posteriors (accumulates gradients when non-NULL). */
double mdl_kl_slot(const sooc_model_config *cfg, const float *lam, const float *lam0, float beta,
                   float *g_lam, float *g_lam0);
double mdl_kl_gauss(int n, const float *mu, const float *rho, const float *mu0, const float *rho0,
                    float rmin, float rmax, float beta, float *gmu, float *grho, float *gmu0,
                    float *grho0);
/* Rays of a frame: stratified grid with offset (ox, oy), samples from rng. */
sooc_status mdl_make_rays(const sooc_model *m, const sooc_frame *f, int ox, int oy, sooc_rng *r,
                          view_rays *vr, const double T_wg[16], double h, double pitch,
                          const double blk_local[2]);
sooc_status mdl_rays_alloc(view_rays *vr, int gw, int gh);
void mdl_rays_free(view_rays *vr);
/* Gaussian-trick density on a single point (exposed for tests):
 * value = sig * zp; adds dL/dxk for upstream g into gxk (3). */
void mdl_gauss_backward(float g, float sig, float zp, const float xk[3], float s, float gxk[3]);
/* Π: G point -> object-local; and its backward to (px, pz, th). */
void mdl_pi(const float x[3], float px, float pz, float th, float h, float xk[3]);
/* Π with cos/sin of θ precomputed (hot loops). */
static inline void mdl_pi_cs(const float x[3], float px, float pz, float c, float s, float h, float xk[3]) {
    float vx = x[0] - px, vz = x[2] - pz;
    xk[0] = c * vx - s * vz;
    xk[1] = x[1] + h;
    xk[2] = s * vx + c * vz;
}
void mdl_pi_backward(const float xk[3], float th, const float gxk[3], float gw[3]);

void mdl_pe_row(const float *x, float inv, int nf, float *out);
/* Layers 2.. of a decoder on R rows (serial), layer-1 pre-activation in a1. */
void mdl_mlp_tail_forward(const sooc_model *m, const dec_net *n, int R, float *a1, float *a2, float *a3, float *ac,
                          float *sig, float *col);

/* The engine's GEMM (src/nn/gemm.c, sooc3d/nn_kern.h) under the model's old names:
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
/* kern.c: the task pool (sooc_nn_pool). mdl_par_run runs fn(ctx, t, tid) for t = 0..n-1, the caller being
 * tid 0 and up to mdl_par_threads(m) - 1 helpers the others (tid < mdl_par_threads(m));
 * tasks are claimed one at a time and the caller waits only for claimed tasks. A task's
 * result must not depend on tid. mdl_par_threads makes the pool (m->threads) if needed. */
typedef sooc_nn_task_fn mdl_task_fn;
int mdl_par_threads(sooc_model *m);
void mdl_par_run(sooc_model *m, int n, mdl_task_fn fn, void *ctx);
void mdl_pool_free(sooc_model *m);

/* refine.c */
int mdl_aux_channels(int layout);
/* Build the refinement inputs of every object slot (and the layout) after a
 * decode with backward: images img[c][b][hw] for B = nslot (objects) and 1
 * (layout), vector inputs vec [B x nvec]. */
void mdl_aux_inputs(sooc_model *m, const dec_call *c, const float *g_lam, const float *g_lay,
                    float *img_o, float *vec_o, float *img_l, float *vec_l);
sooc_status mdl_ref_act_alloc(const ref_net *n, int B, int gw, int gh, ref_act *a);
void mdl_ref_act_free(ref_act *a);
/* forward: a->x0 (and a->nsh) and the vector part of a->xin must be filled; h_prev/c_prev too. out: B x nout */
void mdl_ref_forward(sooc_model *m, const ref_net *n, ref_act *a, int gw, int gh, float *out);
/* The conv stack's last map flattened (average-pooled to 2 x 2 above a 32 x 32
 * ray grid) for the FC layer, and its backward (writes gy3). */
void mdl_ref_flatten(const ref_net *n, const float *y3, int B, int gw, int gh, float *flat);
void mdl_ref_flatten_backward(const ref_net *n, const float *gflat, int B, int gw, int gh, float *gy3);
/* Two nets' forwards in one parallel pass (the object and the layout refinement: their
 * items split across the threads together). n1 / a1 / out1 NULL: one net. */
void mdl_ref_forward2(sooc_model *m, const ref_net *n0, ref_act *a0, float *out0, const ref_net *n1, ref_act *a1,
                      float *out1, int gw, int gh);
/* Leading object-image aux channels that are the same for every slot (colour, depth,
 * beyond-clip flag, ray direction): mdl_aux_inputs writes them for slot 0 only. */
#define MDL_AUX_NSH 8
/* backward: gout B x nout; dh/dc: in = from the next iteration, out = to the previous.
 * gvec (B x nvec) receives d/d(vector inputs) (+=). Weight grads accumulated. */
void mdl_ref_backward(sooc_model *m, const ref_net *n, ref_act *a, int gw, int gh,
                      const float *gout, float *dh, float *dc, float *gvec);

/* step.c */
void mdl_step_free(sooc_model *m);

/* global.c (the global-frame baseline, docs/baseline.md) */
void mdl_global_init_priors(sooc_model *m);
/* World-frame λ of map entry id (field.c, global branch). */
void mdl_global_world_lam(const sooc_cogmap *map, uint64_t id, float *lam);

#endif
