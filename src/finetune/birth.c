/* Births before finetuning (include/sooc3d/train.h "births").
 *
 * Every view is rendered from the map as it stands (the dense renderer, the
 * model's field). A pixel is unexplained when its sensor depth is valid and
 * inside the clip, the rendering puts the surface more than `depth_margin`
 * behind it, and its point lies between `min_height` and the object box's
 * height above the floor: something stands there that no entry draws. Its
 * world point goes into a list. The points are binned on a floor grid; cells
 * with at least `min_cell` points are joined into 8-connected clusters; a
 * cluster wider than an object box is cut into box-sized tiles. A cluster or
 * tile seen by `min_views` views with `min_pixels` points, whose centre is
 * not within `dup_radius` of an entry, becomes a new entry at the mean of its
 * points, yaw 0, with the mean of the model's slot priors as its z^what; the
 * finetuning that follows fits its decoder copy like any other entry's, and
 * sooc_birth_prune afterwards removes any entry (born or not) whose finetuned
 * density reaches the surface level nowhere (objgeom EMPTY): it explains
 * nothing. */
#include "finetune/finetune_impl.h"
#include "model/weights.h"
#include "sooc3d/core.h"
#include "sooc3d/mapper.h"
#include "sooc3d/render.h"

#include <math.h>
#include <string.h>

void sooc_birth_params_default(sooc_birth_params *p) {
    memset(p, 0, sizeof *p);
    p->depth_margin = 0.15f;
    p->min_height = 0.05f;
    p->cell = 0.1f;
    p->min_cell = 3;
    p->min_pixels = 40;
    p->min_views = 2;
    p->dup_radius = 0.15f;
    p->max_births = 32;
    p->n_coarse = 64;
    p->n_fine = 16;
}

typedef struct bpt {
    float x, z;
    uint32_t view;
} bpt;

struct sooc_birth {
    sooc_model *m;
    sooc_cogmap *map;
    sooc_birth_params p;
    int threads;
    bpt *pts;
    size_t n, cap;
    int nv;
    sooc_render_out rout;
};

sooc_status sooc_birth_create(sooc_birth **out, sooc_model *m, sooc_cogmap *map, const sooc_birth_params *pp,
                              int threads) {
    *out = NULL;
    if (!m || !map) return sooc_seterr(SOOC_EINVAL, "birth: missing model or map");
    if (sooc_model_is_global(m))
        return sooc_seterr(SOOC_EUNSUPPORTED, "birth: the global-frame baseline has no per-object entries");
    sooc_birth_params p;
    if (pp) p = *pp;
    else sooc_birth_params_default(&p);
    if (!(p.depth_margin > 0) || !(p.min_height >= 0) || !(p.cell > 0) || p.min_cell < 1 || p.min_pixels < 1 ||
        p.min_views < 1 || !(p.dup_radius >= 0) || p.max_births < 0 || p.n_coarse < 2 || p.n_fine < 0)
        return sooc_seterr(SOOC_EINVAL,
                           "birth: bad parameters (margin %g, min height %g, cell %g, min cell %d, min pixels %d, "
                           "min views %d, dup radius %g, max %d, samples %d,%d)",
                           p.depth_margin, p.min_height, p.cell, p.min_cell, p.min_pixels, p.min_views, p.dup_radius,
                           p.max_births, p.n_coarse, p.n_fine);
    sooc_birth *b = sooc_calloc(1, sizeof *b);
    if (!b) return SOOC_ENOMEM;
    b->m = m, b->map = map, b->p = p, b->threads = threads;
    *out = b;
    return SOOC_OK;
}

void sooc_birth_destroy(sooc_birth *b) {
    if (!b) return;
    sooc_render_out_free(&b->rout);
    sooc_free(b->pts);
    sooc_free(b);
}

size_t sooc_birth_n_points(const sooc_birth *b) { return b->n; }

sooc_status sooc_birth_add_view(sooc_birth *b, const sooc_frame *f) {
    const sooc_model_config *c = &b->m->cfg;
    if (!f || !f->depth || !f->has_pose)
        return sooc_seterr(SOOC_EINVAL, "birth: frame %lld has no depth or no pose", f ? (long long)f->index : -1LL);
    float u = c->unit_m;
    sooc_intrinsics K = f->K;
    K.width = f->width, K.height = f->height;
    sooc_render_opts ro;
    sooc_render_opts_default(&ro);
    ro.n_coarse = b->p.n_coarse, ro.n_fine = b->p.n_fine;
    ro.t_near = c->t_near * u, ro.d_clip = c->d_clip * u;
    ro.threads = b->threads;
    sooc_model_field *fld = NULL;
    sooc_status st = sooc_model_field_create(&fld, b->m, b->map, f->T_wc, &K, SOOC_RENDER_MAX_COMP - 1, NULL);
    if (st) return sooc_adderr(st, "birth: frame %lld", (long long)f->index);
    double T_fc[16];
    sooc_model_field_T_fc(fld, T_fc);
    st = sooc_render_view(sooc_model_field_get(fld), &K, T_fc, &ro, &b->rout);
    sooc_model_field_destroy(fld);
    if (st) return sooc_adderr(st, "birth: rendering frame %lld", (long long)f->index);
    double margin = (double)b->p.depth_margin * u, ymin = (double)b->p.min_height * u, ymax = (double)c->box_hb * u;
    double dmin = (double)c->t_near * u, dmax = (double)c->d_clip * u;
    for (int y = 0; y < f->height; y++)
        for (int x = 0; x < f->width; x++) {
            size_t pix = (size_t)y * f->width + x;
            float zd = f->depth[pix];
            if ((f->valid && !f->valid[pix]) || !(zd > dmin && zd <= dmax)) continue;
            if (!((double)b->rout.depth[pix] > zd + margin)) continue;
            double dc[3];
            double uz = sooc_cam_ray(&K, x, y, dc), s = zd / uz;
            double pc[3] = {dc[0] * s, dc[1] * s, dc[2] * s}, pw[3];
            sooc_se3_apply(pw, f->T_wc, pc);
            if (pw[1] < ymin || pw[1] > ymax) continue;
            if (b->n == b->cap) {
                size_t nc = b->cap ? 2 * b->cap : 4096;
                bpt *np = sooc_realloc(b->pts, nc * sizeof *np);
                if (!np) return SOOC_ENOMEM;
                b->pts = np, b->cap = nc;
            }
            b->pts[b->n++] = (bpt){(float)pw[0], (float)pw[2], (uint32_t)b->nv};
        }
    b->nv++;
    return SOOC_OK;
}

/* Statistics of one candidate (a cluster, or a tile of one). */
typedef struct bcand {
    double sx, sz;
    float x0, x1, z0, z1;
    int n, views;
    uint32_t last_view;
} bcand;

static void cand_add(bcand *c, const bpt *p) {
    if (!c->n) c->x0 = c->x1 = p->x, c->z0 = c->z1 = p->z, c->last_view = UINT32_MAX;
    c->sx += p->x, c->sz += p->z, c->n++;
    if (p->x < c->x0) c->x0 = p->x;
    if (p->x > c->x1) c->x1 = p->x;
    if (p->z < c->z0) c->z0 = p->z;
    if (p->z > c->z1) c->z1 = p->z;
    if (p->view != c->last_view) c->last_view = p->view, c->views++;   /* points come in view order */
}

/* The entry of a birth at (X, Z): yaw 0, the mean of the slot priors' z^what
 * and spreads (in metres), presence well above the threshold. */
static void birth_entry(const sooc_model *m, double X, double Z, int views, sooc_cogmap_entry *e) {
    const sooc_model_config *c = &m->cfg;
    int d = c->d_what, K = c->K, NL = m->NL;
    memset(e, 0, sizeof *e);
    e->X = X, e->Z = Z, e->Theta = 0;
    e->dim = d;
    double rt = 0, rth = 0;
    for (int k = 0; k < K; k++) {
        const float *l = m->p + m->prior + (size_t)k * NL;
        rt += l[SOOC_LAM_RHO_T], rth += l[SOOC_LAM_RHO_TH];
        for (int i = 0; i < d; i++) {
            e->what_mu[i] += l[SOOC_LAM_WHAT_MU + i] / (float)K;
            e->what_logvar[i] += l[SOOC_LAM_WHAT_LV(d) + i] / (float)K;
        }
    }
    e->rho_t = (float)(rt / K + 2.0 * log((double)c->unit_m));
    e->rho_theta = (float)(rth / K);
    e->pres_logit = 2.0f;
    e->obs_count = (uint32_t)views;
    e->last_view = -1;
}

static int near_entry(const sooc_cogmap_entry *ent, size_t n, double X, double Z, double r) {
    for (size_t i = 0; i < n; i++)
        if ((ent[i].X - X) * (ent[i].X - X) + (ent[i].Z - Z) * (ent[i].Z - Z) < r * r) return 1;
    return 0;
}

sooc_status sooc_birth_run(sooc_birth *b, uint64_t *ids, int cap, int *n_born) {
    *n_born = 0;
    if (!b->n) return SOOC_OK;
    const sooc_model_config *c = &b->m->cfg;
    double u = c->unit_m, cs = (double)b->p.cell * u, tile = (double)c->box_rh * u * 2.0 * 0.9;
    float x0 = b->pts[0].x, x1 = x0, z0 = b->pts[0].z, z1 = z0;
    for (size_t i = 1; i < b->n; i++) {
        const bpt *p = &b->pts[i];
        x0 = fminf(x0, p->x), x1 = fmaxf(x1, p->x), z0 = fminf(z0, p->z), z1 = fmaxf(z1, p->z);
    }
    /* a grid no larger than 4M cells: coarser cells on a huge map */
    while (((x1 - x0) / cs + 3) * ((z1 - z0) / cs + 3) > 4e6) cs *= 2;
    int gw = (int)((x1 - x0) / cs) + 3, gh = (int)((z1 - z0) / cs) + 3;
    size_t ng = (size_t)gw * gh;
    int *cnt = sooc_calloc(ng, sizeof(int)), *lab = sooc_malloc(ng * sizeof(int));
    int *stack = sooc_malloc(ng * sizeof(int));
    sooc_cogmap_entry *ent = NULL;
    bcand *cl = NULL, *tl = NULL;
    sooc_status st = SOOC_OK;
    if (!cnt || !lab || !stack) {
        st = SOOC_ENOMEM;
        goto done;
    }
#define CELL(p) ((size_t)((int)(((p)->z - z0) / cs) + 1) * gw + (size_t)((int)(((p)->x - x0) / cs) + 1))
    for (size_t i = 0; i < b->n; i++) cnt[CELL(&b->pts[i])]++;
    /* 8-connected components of the cells with enough points */
    int ncl = 0;
    for (size_t g = 0; g < ng; g++) lab[g] = -1;
    for (size_t g = 0; g < ng; g++) {
        if (lab[g] >= 0 || cnt[g] < b->p.min_cell) continue;
        int sp = 0;
        stack[sp++] = (int)g, lab[g] = ncl;
        while (sp) {
            int q = stack[--sp], qx = q % gw, qz = q / gw;
            for (int dz = -1; dz <= 1; dz++)
                for (int dx = -1; dx <= 1; dx++) {
                    int nx = qx + dx, nz = qz + dz;
                    if (nx < 0 || nz < 0 || nx >= gw || nz >= gh) continue;
                    size_t r = (size_t)nz * gw + nx;
                    if (lab[r] >= 0 || cnt[r] < b->p.min_cell) continue;
                    lab[r] = ncl, stack[sp++] = (int)r;
                }
        }
        ncl++;
    }
    if (!ncl) goto done;
    cl = sooc_calloc((size_t)ncl, sizeof *cl);
    if (!cl) {
        st = SOOC_ENOMEM;
        goto done;
    }
    for (size_t i = 0; i < b->n; i++) {
        int l = lab[CELL(&b->pts[i])];
        if (l >= 0) cand_add(&cl[l], &b->pts[i]);
    }
    size_t ne = 0;
    if ((st = sooc_cogmap_entries(b->map, NULL, 0, &ne))) goto done;
    ent = sooc_malloc((ne + (size_t)b->p.max_births + 1) * sizeof *ent);
    if (!ent) {
        st = SOOC_ENOMEM;
        goto done;
    }
    if ((st = sooc_cogmap_entries(b->map, ent, ne, &ne))) goto done;
    double dup = (double)b->p.dup_radius * u;
    for (int k = 0; k < ncl && *n_born < b->p.max_births; k++) {
        bcand *q = &cl[k];
        if (q->n < b->p.min_pixels) continue;
        /* a cluster wider than an object box: box-sized tiles */
        int tx = (int)((q->x1 - q->x0) / tile) + 1, tz = (int)((q->z1 - q->z0) / tile) + 1, nt = tx * tz;
        if (nt > 1) {
            sooc_free(tl);
            tl = sooc_calloc((size_t)nt, sizeof *tl);
            if (!tl) {
                st = SOOC_ENOMEM;
                goto done;
            }
            for (size_t i = 0; i < b->n; i++) {
                const bpt *p = &b->pts[i];
                if (lab[CELL(p)] != k) continue;
                int ix = (int)((p->x - q->x0) / tile), iz = (int)((p->z - q->z0) / tile);
                cand_add(&tl[(iz < tz ? iz : tz - 1) * tx + (ix < tx ? ix : tx - 1)], p);
            }
        }
        for (int t = 0; t < nt && *n_born < b->p.max_births; t++) {
            const bcand *s = nt > 1 ? &tl[t] : q;
            if (s->n < b->p.min_pixels || s->views < b->p.min_views) continue;
            double X = s->sx / s->n, Z = s->sz / s->n;
            if (near_entry(ent, ne, X, Z, dup)) continue;
            sooc_cogmap_entry e;
            birth_entry(b->m, X, Z, s->views, &e);
            uint64_t id = 0;
            if ((st = sooc_cogmap_insert(b->map, &e, &id))) goto done;
            e.id = id;
            ent[ne++] = e;
            if (ids && *n_born < cap) ids[*n_born] = id;
            (*n_born)++;
        }
    }
#undef CELL
done:
    sooc_free(cnt);
    sooc_free(lab);
    sooc_free(stack);
    sooc_free(cl);
    sooc_free(tl);
    sooc_free(ent);
    return st;
}

sooc_status sooc_birth_prune(sooc_model *m, sooc_cogmap *map, uint64_t *ids, int *n, int *n_pruned) {
    *n_pruned = 0;
    sooc_objgeom_opts o;
    sooc_objgeom_opts_default(&o);
    int k = 0;
    for (int i = 0; i < *n; i++) {
        sooc_objgeom_box b;
        sooc_status st = sooc_objgeom_entry_box(m, map, ids[i], &o, &b);
        if (st == SOOC_ENOTFOUND) {   /* gone, or no field reaches it: keep what is there */
            sooc_clearerr();
            if (sooc_cogmap_get(map, ids[i], &(sooc_cogmap_entry){0}) == SOOC_OK) ids[k++] = ids[i];
            else sooc_clearerr();
            continue;
        }
        if (st) return st;
        if (b.flags & SOOC_GEOM_EMPTY) {
            if ((st = sooc_cogmap_remove(map, ids[i]))) return st;
            (*n_pruned)++;
        } else {
            ids[k++] = ids[i];
        }
    }
    *n = k;
    return SOOC_OK;
}

sooc_status sooc_birth_prune_all(sooc_model *m, sooc_cogmap *map, uint64_t **removed, int *n_pruned) {
    *n_pruned = 0;
    if (removed) *removed = NULL;
    size_t n = 0;
    sooc_status st = sooc_cogmap_entries(map, NULL, 0, &n);
    if (st || !n) return st;
    sooc_cogmap_entry *e = sooc_malloc(n * sizeof *e);
    uint64_t *ids = sooc_malloc(n * sizeof *ids), *gone = sooc_malloc(n * sizeof *gone);
    if (!e || !ids || !gone) st = SOOC_ENOMEM;
    if (!st) st = sooc_cogmap_entries(map, e, n, &n);
    for (size_t i = 0; !st && i < n; i++) ids[i] = e[i].id;
    int k = (int)n;
    if (!st) st = sooc_birth_prune(m, map, ids, &k, n_pruned);
    if (!st && removed) {   /* the ids that are no longer there, in id order */
        int j = 0, g = 0;
        for (size_t i = 0; i < n; i++)
            if (j < k && ids[j] == e[i].id) j++;
            else gone[g++] = e[i].id;
        *removed = gone, gone = NULL;
    }
    sooc_free(e);
    sooc_free(ids);
    sooc_free(gone);
    return st;
}
