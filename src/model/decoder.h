/* Layer 1 of src/model (docs/model.md "Layers"): the decoder (decoder.c:
 * the fused object/layout NeRF decode and likelihood; dec_rays.c: rays;
 * dec_kl.c: KL terms; dec_own.c:
 * a decoder on its own weights; field.c: the render.h field). Includes only
 * layer 0. Internal interface of src/model (docs/architecture.md "Layers"):
 * the modules above it see it through step.h; not a public API. */
#ifndef SOOC3D_MODEL_DECODER_H
#define SOOC3D_MODEL_DECODER_H

#include "model/weights.h"

#include <math.h>
#include <string.h>

/* Rays of one view in G_t (origin at the camera centre). P = 2 N points:
 * point 2r = surface sample, 2r + 1 = air sample. */
typedef struct sooc_view_rays {
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
} sooc_view_rays;

/* Noise of one decode, shared with the reference. */
typedef struct sooc_dec_noise {
    float eps_where[SOOC_MODEL_K_MAX][3];
    float eps_what[SOOC_MODEL_K_MAX][SOOC_MODEL_D_MAX];
    float logistic[SOOC_MODEL_K_MAX];
    float eps_lay[SOOC_MODEL_D_MAX];
} sooc_dec_noise;

/* Workspace of the fused decoder (sized for P points and K slots at create). */
struct sooc_dec_ws {
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
    float *ll_cf;                 /* N x (K+1): the aux inputs' colour posterior (sooc_mdl_aux_post_ray) */
    float *lt;                    /* N x 3 per-ray likelihood terms (surface density, colour, air) */
    int *lr_pt;                   /* layout row -> point */
    float *tbuf;                  /* nthr x (dec_np + (K+1) H + 3K) thread-private grads */
    size_t dec_np;                /* decoder parameters: slab offsets [0, dec_np) */
    int nthr;
    float *slot_bias;             /* (K+1) x H */
    float *wt;                    /* nwt: transposed decoder weights for the backward GEMMs */
    size_t nwt;
    float *g_bias;                /* (K+1) x H */
    const sooc_view_rays *lpe_vr;      /* the rays whose layout rows' PE (nrl rows) l_pe holds */
    int lpe_nrl;
};
typedef struct sooc_dec_ws sooc_dec_ws;

/* One decode: inputs, outputs. */
typedef struct sooc_dec_call {
    const sooc_view_rays *rays;
    int nslot;                    /* active object slots (<= K)                 */
    const float *lam;             /* nslot x NL                                 */
    const float *lam0;            /* nslot x NL prior (NULL: no KL, query view) */
    const float *lay, *lay0;      /* 2 d_l (lay0 NULL: no layout KL)            */
    const sooc_dec_noise *noise;
    float tau, beta_kl, sigma_c;
    const uint8_t *hard;          /* per slot: 0 relaxed, 1 straight-through hard, 2 forced one */
    float wgrad;                  /* scale of decoder weight gradients (0: none)               */
    const float *zw_sg;           /* TEST ONLY (nslot x 3): forward multiplies σ̂ by
                                     w_g(Π(zw) x) / w_g(Π(zw_sg) x), i.e. the Gaussian trick
                                     written as a forward, for finite-difference checks        */
    int backward;                 /* 0: forward only                                           */
    int same_rays;                /* 1: the rays have not changed since the previous decode on this
                                     workspace (the next iteration of the same view): the layout
                                     rows' positional encoding is kept                          */
    int aux_post;                 /* 1: also the aux inputs' colour posterior (w->ll_cf, per
                                     surface ray; sooc_mdl_aux_post_ray) during the composition      */
    /* outputs */
    double loss, nll, nll_d, nll_c, kl;
    float *g_lam, *g_lam0, *g_lay, *g_lay0;   /* ACCUMULATED (+=) when non-NULL; UNWEIGHTED */
    /* samples (outputs, for aux inputs) */
    float zw[SOOC_MODEL_K_MAX][3], zwhat[SOOC_MODEL_K_MAX][SOOC_MODEL_D_MAX];
    float zp[SOOC_MODEL_K_MAX], zp_soft[SOOC_MODEL_K_MAX], zlay[SOOC_MODEL_D_MAX];
} sooc_dec_call;

/* The decoder's part of a workspace (sized for the model's ray grid and K). */
sooc_status sooc_mdl_dec_ws_create(const sooc_model *m, sooc_dec_ws **out);
void sooc_mdl_dec_ws_destroy(sooc_dec_ws *w);   /* NULL-safe */

void sooc_mdl_sample_noise(const sooc_model *m, sooc_rng *r, sooc_dec_noise *n);
/* One decode on workspace x (its model, its decoder scratch and pool). */
sooc_status sooc_mdl_decode(sooc_model_ws *x, sooc_dec_call *c);
/* KL between two slot posteriors (accumulates gradients when non-NULL). */
double sooc_mdl_kl_slot(const sooc_model_config *cfg, const float *lam, const float *lam0, float beta,
                   float *g_lam, float *g_lam0);
double sooc_mdl_kl_gauss(int n, const float *mu, const float *rho, const float *mu0, const float *rho0,
                    float rmin, float rmax, float beta, float *gmu, float *grho, float *gmu0,
                    float *grho0);
/* Rays of a frame: stratified grid with offset (ox, oy), samples from rng. */
sooc_status sooc_mdl_make_rays(const sooc_model *m, const sooc_frame *f, int ox, int oy, sooc_rng *r,
                          sooc_view_rays *vr, const double T_wg[16], double h, double pitch,
                          const double blk_local[2]);
sooc_status sooc_mdl_rays_alloc(sooc_view_rays *vr, int gw, int gh);
void sooc_mdl_rays_free(sooc_view_rays *vr);
/* Gaussian-trick density on a single point (exposed for tests):
 * value = sig * zp; adds dL/dxk for upstream g into gxk (3). */
void sooc_mdl_gauss_backward(float g, float sig, float zp, const float xk[3], float s, float gxk[3]);
/* Π: G point -> object-local; and its backward to (px, pz, th). */
void sooc_mdl_pi(const float x[3], float px, float pz, float th, float h, float xk[3]);
/* Π with cos/sin of θ precomputed (hot loops). */
static inline void mdl_pi_cs(const float x[3], float px, float pz, float c, float s, float h, float xk[3]) {
    float vx = x[0] - px, vz = x[2] - pz;
    xk[0] = c * vx - s * vz;
    xk[1] = x[1] + h;
    xk[2] = s * vx + c * vz;
}
void sooc_mdl_pi_backward(const float xk[3], float th, const float gxk[3], float gw[3]);

void sooc_mdl_pe_row(const float *x, float inv, int nf, float *out);

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define MDL_HAVE_AVX2_PATHS 1
#define MDL_TGT_AVX2 __attribute__((target("avx2")))   /* no FMA: float operations round as in C */

/* sooc_nn_logf_pos on 8 lanes (its operations in its order, no FMA: bitwise equal) for
 * normal x > 0; the caller redoes the other lanes with logf. */
static MDL_TGT_AVX2 inline __m256 mdl_logf_pos8(__m256 x) {
    __m256i ix = _mm256_castps_si256(x);
    __m256i e = _mm256_sub_epi32(_mm256_srli_epi32(ix, 23), _mm256_set1_epi32(127));
    ix = _mm256_or_si256(_mm256_and_si256(ix, _mm256_set1_epi32(0x007fffff)), _mm256_set1_epi32(0x3f800000));
    __m256 mt = _mm256_castsi256_ps(ix);
    __m256 big = _mm256_cmp_ps(mt, _mm256_set1_ps(1.41421356237f), _CMP_GT_OQ);
    mt = _mm256_blendv_ps(mt, _mm256_mul_ps(mt, _mm256_set1_ps(0.5f)), big);
    e = _mm256_sub_epi32(e, _mm256_castps_si256(big));   /* mask -1: e + 1 */
    __m256 f = _mm256_sub_ps(mt, _mm256_set1_ps(1.0f)), z = _mm256_mul_ps(f, f), fe = _mm256_cvtepi32_ps(e);
    __m256 y = _mm256_set1_ps(7.0376836292e-2f);
    y = _mm256_sub_ps(_mm256_mul_ps(y, f), _mm256_set1_ps(1.1514610310e-1f));
    y = _mm256_add_ps(_mm256_mul_ps(y, f), _mm256_set1_ps(1.1676998740e-1f));
    y = _mm256_sub_ps(_mm256_mul_ps(y, f), _mm256_set1_ps(1.2420140846e-1f));
    y = _mm256_add_ps(_mm256_mul_ps(y, f), _mm256_set1_ps(1.4249322787e-1f));
    y = _mm256_sub_ps(_mm256_mul_ps(y, f), _mm256_set1_ps(1.6668057665e-1f));
    y = _mm256_add_ps(_mm256_mul_ps(y, f), _mm256_set1_ps(2.0000714765e-1f));
    y = _mm256_sub_ps(_mm256_mul_ps(y, f), _mm256_set1_ps(2.4999993993e-1f));
    y = _mm256_add_ps(_mm256_mul_ps(y, f), _mm256_set1_ps(3.3333331174e-1f));
    y = _mm256_mul_ps(_mm256_mul_ps(y, f), z);
    y = _mm256_add_ps(y, _mm256_mul_ps(_mm256_set1_ps(-2.12194440e-4f), fe));
    y = _mm256_add_ps(y, _mm256_mul_ps(_mm256_set1_ps(-0.5f), z));
    return _mm256_add_ps(_mm256_add_ps(f, y), _mm256_mul_ps(_mm256_set1_ps(0.693359375f), fe));
}

#endif

/* The aux inputs' colour-likelihood posterior of surface ray rr after a composition:
 * softmax_k [log pi_k + log N(C; c_k, sigma_C^2)] into w->ll_cf row rr (C components;
 * is2 = 1 / sigma_C^2). */
void sooc_mdl_aux_post_ray(sooc_dec_ws *w, const sooc_view_rays *vr, int rr, int C, float is2);
/* Layers 2.. of a decoder on R rows (serial), layer-1 pre-activation in a1. */
void sooc_mdl_mlp_tail_forward(const sooc_model *m, const sooc_dec_net *n, int R, float *a1, float *a2, float *a3, float *ac,
                          float *sig, float *col);

#endif
