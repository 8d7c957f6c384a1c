/* Internals of the finetuning module (src/finetune; tests include it). */
#ifndef SOOC3D_FINETUNE_IMPL_H
#define SOOC3D_FINETUNE_IMPL_H

#include "model/dec_own.h"
#include "sooc3d/train.h"

/* One component: an object (map entry) or a layout block. */
typedef struct sooc_ft_comp {
    sooc_finetune_kind kind;
    uint64_t id;
    int32_t bi, bj;
    const sooc_dec_net *net;   /* the model's net (object or layout)          */
    sooc_dec_net rel;          /* offsets relative to w                       */
    size_t nw;            /* weights                                     */
    float *w;             /* own weights (slab)                          */
    float z[SOOC_MODEL_D_MAX];
    float *bias;          /* H: b1 + z W1z                               */
    uint32_t *rays;       /* rays crossing it (global ray indices)       */
    size_t nrays;
    int n_views;
} sooc_ft_comp;

typedef struct sooc_ft_view {
    float h;              /* camera height (model units)                 */
    float blk[3];         /* active layout block origin in G             */
    int lay;              /* component index of its layout block         */
    int nc;               /* object components in view                   */
    int comp[SOOC_COGMAP_K_MAX];
    float pose[SOOC_COGMAP_K_MAX][3];   /* px, pz, th in G (model units) */
} sooc_ft_view;

struct sooc_finetune {
    sooc_model *m;
    sooc_cogmap *map;
    sooc_finetune_params p;
    float sigma_c;
    /* views and rays */
    sooc_ft_view *views;
    int nv, cap_v;
    size_t nr, cap_r;
    float *dir, *rgb, *depth;   /* per ray: 3, 3, 1 (depth model units, Euclidean) */
    uint8_t *surf;              /* 1 surface ray, 2 surface ray on the support plane
                                   (p.support_m), 0 free (beyond clip)             */
    uint32_t *rview;            /* view of the ray                                 */
    uint64_t *mask;             /* view components (bit i = views[v].comp[i]) crossed */
    int max_cross;
    /* components */
    sooc_ft_comp *comp;
    int ncomp, nobj;
    int built;                  /* units built (views frozen)                      */
    int *units;                 /* unit -> component                               */
    int nunits;
    /* workspace (grown to the largest batch) */
    size_t cap_pts, cap_rows;
    float *pts, *Wa;            /* 2 n x 3 points, n air weights                   */
    int *pt_row0, *pt_nrow;     /* rows of a point in point order                  */
    int *row_comp, *row_pos, *row_pt;
    int *cnt, *off;             /* per component                                   */
    float *pe, *a1, *a2, *a3, *ac, *sig, *col, *gsig, *gcol, *gA, *gB, *gC;
    float *gw, gz[SOOC_MODEL_D_MAX], *gbias;
    float *am, *av;             /* Adam moments (weights then z)                   */
};

/* Σ ℓ over rays[0..n) with samples from `seed` (per ray: seed and the ray's
 * index, so a ray's samples do not depend on the batch); if u >= 0, the
 * gradient of Σ ℓ with respect to component u's weights (gw, rel layout) and
 * z (gz) is ACCUMULATED. Uses the components' current weights. */
sooc_status sooc_ft_objective(sooc_finetune *ft, int u, const uint32_t *rays, size_t n, uint64_t seed, float *gw,
                         float *gz, double *ll);
/* Recompute component c's layer-1 bias from its weights and z. */
void sooc_ft_comp_bias(sooc_ft_comp *c);

#endif
