/* Per-object NeRF finetuning by EM (include/sooc3d/train.h, docs/finetune.md).
 *
 * Layout of the work: views are turned into rays once (direction in the
 * view's gravity-aligned frame G, colour, Euclidean depth, and the set of the
 * view's components whose locality boxes the ray crosses). A unit's step
 * draws a batch of its rays, makes one surface and one air sample per ray,
 * evaluates every (sample, crossing component) pair inside the component's
 * box with that component's decoder (rows grouped per component, one GEMM
 * chain per component), computes ℓ per ray and, for the unit's own rows, the
 * gradient, which goes back through the unit's decoder copy to its weights
 * and z. Adam then updates them. Nothing is allocated per step once the
 * workspace has grown to the batch size. */
#include "finetune/finetune_impl.h"

#include <math.h>
#include <string.h>

void sooc_finetune_params_default(sooc_finetune_params *p) {
    memset(p, 0, sizeof *p);
    p->iterations = 300;
    p->rays = 512;
    p->lr = 1e-3f;
    p->lr_z = 1e-3f;
    p->lr_final = 1.0f;
    p->layout = 1;
    p->max_obj = SOOC_COGMAP_K_MAX - 1;
    p->seed = 1;
}

float sooc_finetune_lr_scale(const sooc_finetune_params *p, int it) {
    float f = p->lr_final, T = (float)(p->iterations > 0 ? p->iterations : 1);
    return f + (1.0f - f) * 0.5f * (1.0f + cosf(3.14159265f * (float)it / T));
}

/* ------------------------------------------------------------ components */

void sooc_ft_comp_bias(sooc_ft_comp *c) { sooc_mdl_own_bias(c->w, &c->rel, c->z, c->bias); }

static int find_comp(const sooc_finetune *ft, sooc_finetune_kind kind, uint64_t id, int32_t bi, int32_t bj) {
    for (int i = 0; i < ft->ncomp; i++) {
        const sooc_ft_comp *c = &ft->comp[i];
        if (c->kind == kind && (kind == SOOC_FT_OBJECT ? c->id == id : (c->bi == bi && c->bj == bj))) return i;
    }
    return -1;
}

/* The component of an entry / block, created on first sight from the map's
 * payload (a finetuned decoder) or the model's decoder and the posterior mean. */
static sooc_status get_comp(sooc_finetune *ft, sooc_finetune_kind kind, uint64_t id, int32_t bi, int32_t bj, int *out) {
    int i = find_comp(ft, kind, id, bi, bj);
    if (i >= 0) {
        *out = i;
        return SOOC_OK;
    }
    const sooc_model *m = ft->m;
    if (ft->ncomp % 16 == 0) {
        sooc_ft_comp *nc = sooc_realloc(ft->comp, (size_t)(ft->ncomp + 16) * sizeof *nc);
        if (!nc) return SOOC_ENOMEM;
        ft->comp = nc;
    }
    sooc_ft_comp *c = &ft->comp[ft->ncomp];
    memset(c, 0, sizeof *c);
    c->kind = kind, c->id = id, c->bi = bi, c->bj = bj;
    c->net = kind == SOOC_FT_OBJECT ? &m->dobj : &m->dlay;
    sooc_mdl_dec_rel(c->net, &c->rel);
    c->nw = sooc_mdl_dec_count(c->net);
    c->w = sooc_malloc(c->nw * sizeof(float));
    c->bias = sooc_malloc((size_t)c->net->H * sizeof(float));
    if (!c->w || !c->bias) {
        sooc_free(c->w);
        sooc_free(c->bias);
        return SOOC_ENOMEM;
    }
    size_t npl = 0;
    const float *pl = kind == SOOC_FT_OBJECT ? sooc_cogmap_payload_get(ft->map, id, &npl)
                                             : sooc_cogmap_block_payload_get(ft->map, bi, bj, &npl);
    int dz = c->net->dz;
    if (pl && sooc_mdl_ft_payload_ok(c->net, kind == SOOC_FT_OBJECT ? MDL_FT_OBJ : MDL_FT_LAY, pl, npl)) {
        memcpy(c->w, mdl_ft_payload_w(c->net, pl), c->nw * sizeof(float));
        memcpy(c->z, mdl_ft_payload_z(pl), (size_t)dz * sizeof(float));
    } else {
        memcpy(c->w, m->p + c->net->W1x, c->nw * sizeof(float));
        if (kind == SOOC_FT_OBJECT) {
            sooc_cogmap_entry e;
            sooc_status st = sooc_cogmap_get(ft->map, id, &e);
            if (st) {
                sooc_free(c->w);
                sooc_free(c->bias);
                return st;
            }
            memcpy(c->z, e.what_mu, (size_t)dz * sizeof(float));
        } else {
            float lv[SOOC_COGMAP_DIM_MAX];
            if (sooc_cogmap_layout_get(ft->map, bi, bj, c->z, lv) != SOOC_OK) {
                sooc_clearerr();
                memcpy(c->z, m->p + m->prior_lay, (size_t)dz * sizeof(float));
            }
        }
    }
    sooc_ft_comp_bias(c);
    *out = ft->ncomp++;
    return SOOC_OK;
}

/* ------------------------------------------------------------ create */

sooc_status sooc_finetune_create(sooc_finetune **out, sooc_model *m, sooc_cogmap *map, const sooc_finetune_params *pp) {
    *out = NULL;
    if (!m || !map) return sooc_seterr(SOOC_EINVAL, "finetune: missing model or map");
    if (sooc_model_is_global(m))
        return sooc_seterr(SOOC_EUNSUPPORTED, "finetune: the global-frame baseline has no per-object decoders");
    sooc_finetune_params p;
    if (pp) p = *pp;
    else sooc_finetune_params_default(&p);
    if (p.iterations < 0 || p.rays < 0 || !(p.lr >= 0) || !(p.lr_z >= 0) || !(p.sigma_c >= 0) ||
        !(p.lr_final >= 0 && p.lr_final <= 1))
        return sooc_seterr(SOOC_EINVAL, "finetune: bad parameters (iterations %d, rays %d, lr %g, lr_z %g, lr_final %g)",
                           p.iterations, p.rays, p.lr, p.lr_z, p.lr_final);
    if (p.max_obj <= 0 || p.max_obj > SOOC_COGMAP_K_MAX - 1) p.max_obj = SOOC_COGMAP_K_MAX - 1;
    if (p.max_obj > SOOC_RENDER_MAX_COMP - 1) p.max_obj = SOOC_RENDER_MAX_COMP - 1;
    if (sooc_cogmap_dim(map) != m->cfg.d_what)
        return sooc_seterr(SOOC_EINVAL, "finetune: map latent dim %d, model d_what %d", sooc_cogmap_dim(map),
                           m->cfg.d_what);
    sooc_finetune *ft = sooc_calloc(1, sizeof *ft);
    if (!ft) return SOOC_ENOMEM;
    ft->m = m, ft->map = map, ft->p = p;
    ft->sigma_c = p.sigma_c > 0 ? p.sigma_c : m->cfg.sigma_c;
    *out = ft;
    return SOOC_OK;
}

static void free_ws(sooc_finetune *ft) {
    float **f[] = {&ft->pts, &ft->Wa, &ft->pe, &ft->a1, &ft->a2, &ft->a3, &ft->ac, &ft->sig, &ft->col,
                   &ft->gsig, &ft->gcol, &ft->gA, &ft->gB, &ft->gC};
    for (size_t i = 0; i < sizeof f / sizeof *f; i++) sooc_free(*f[i]), *f[i] = NULL;
    int **g[] = {&ft->pt_row0, &ft->pt_nrow, &ft->row_comp, &ft->row_pos, &ft->row_pt};
    for (size_t i = 0; i < sizeof g / sizeof *g; i++) sooc_free(*g[i]), *g[i] = NULL;
    ft->cap_pts = ft->cap_rows = 0;
}

void sooc_finetune_destroy(sooc_finetune *ft) {
    if (!ft) return;
    free_ws(ft);
    for (int i = 0; i < ft->ncomp; i++) {
        sooc_free(ft->comp[i].w);
        sooc_free(ft->comp[i].bias);
        sooc_free(ft->comp[i].rays);
    }
    sooc_free(ft->comp);
    sooc_free(ft->views);
    sooc_free(ft->dir);
    sooc_free(ft->rgb);
    sooc_free(ft->depth);
    sooc_free(ft->surf);
    sooc_free(ft->rview);
    sooc_free(ft->mask);
    sooc_free(ft->units);
    sooc_free(ft->cnt);
    sooc_free(ft->off);
    sooc_free(ft->gw);
    sooc_free(ft->gbias);
    sooc_free(ft->am);
    sooc_free(ft->av);
    sooc_free(ft);
}

/* ------------------------------------------------------------ views */

/* Does the ray t dir, t in [t0, t1], cross the object box of pose (px, pz, th)?
 * Slab test in the object's frame (its locality box). */
static int ray_crosses(const sooc_model_config *c, const float dir[3], float t0, float t1, const float pose[3], float h) {
    float o[3] = {0, 0, 0}, ol[3], e[3] = {dir[0], dir[1], dir[2]}, el[3];
    sooc_mdl_pi(o, pose[0], pose[1], pose[2], h, ol);
    float cth = cosf(pose[2]), sth = sinf(pose[2]);
    el[0] = cth * e[0] - sth * e[2];
    el[1] = e[1];
    el[2] = sth * e[0] + cth * e[2];
    float lo[3] = {-c->box_rh, 0, -c->box_rh}, hi[3] = {c->box_rh, c->box_hb, c->box_rh};
    for (int a = 0; a < 3; a++) {
        if (fabsf(el[a]) < 1e-12f) {
            if (ol[a] < lo[a] || ol[a] > hi[a]) return 0;
            continue;
        }
        float ta = (lo[a] - ol[a]) / el[a], tb = (hi[a] - ol[a]) / el[a];
        if (ta > tb) {
            float t = ta;
            ta = tb, tb = t;
        }
        if (ta > t0) t0 = ta;
        if (tb < t1) t1 = tb;
        if (t0 > t1) return 0;
    }
    return 1;
}

static sooc_status grow_rays(sooc_finetune *ft, size_t need) {
    if (need <= ft->cap_r) return SOOC_OK;
    size_t nc = ft->cap_r ? ft->cap_r : 16384;
    while (nc < need) nc *= 2;
    float *d = sooc_realloc(ft->dir, nc * 3 * sizeof(float));
    if (d) ft->dir = d;
    float *r = sooc_realloc(ft->rgb, nc * 3 * sizeof(float));
    if (r) ft->rgb = r;
    float *z = sooc_realloc(ft->depth, nc * sizeof(float));
    if (z) ft->depth = z;
    uint8_t *s = sooc_realloc(ft->surf, nc);
    if (s) ft->surf = s;
    uint32_t *v = sooc_realloc(ft->rview, nc * sizeof(uint32_t));
    if (v) ft->rview = v;
    uint64_t *mk = sooc_realloc(ft->mask, nc * sizeof(uint64_t));
    if (mk) ft->mask = mk;
    if (!d || !r || !z || !s || !v || !mk) return SOOC_ENOMEM;
    ft->cap_r = nc;
    return SOOC_OK;
}

sooc_status sooc_finetune_add_view(sooc_finetune *ft, const sooc_frame *f) {
    const sooc_model *m = ft->m;
    const sooc_model_config *c = &m->cfg;
    if (ft->built) return sooc_seterr(SOOC_EINVAL, "finetune: views must be added before the first unit runs");
    if (!f || !f->rgb || !f->has_pose)
        return sooc_seterr(SOOC_EINVAL, "finetune: frame %lld has no colour or no pose", f ? (long long)f->index : -1LL);
    if (f->width != c->img_w || f->height != c->img_h)
        return sooc_seterr(SOOC_EINVAL, "finetune: frame %lld is %dx%d, the model's resolution is %dx%d",
                           (long long)f->index, f->width, f->height, c->img_w, c->img_h);
    double T_wg[16], T_gw[16], h, pitch, roll;
    sooc_status st = sooc_gframe(f->T_wc, T_wg, &h, &pitch, &roll);
    if (st) return sooc_adderr(st, "finetune: frame %lld", (long long)f->index);
    double u = c->unit_m;
    float iu = 1.0f / c->unit_m;
    sooc_cogmap_camera cam;
    memset(&cam, 0, sizeof cam);
    memcpy(cam.T_wc, f->T_wc, sizeof cam.T_wc);
    cam.K = f->K;
    cam.K.width = f->width, cam.K.height = f->height;
    cam.t_near = c->t_near * u, cam.d_clip = c->d_clip * u, cam.R_h = c->box_rh * u, cam.H_b = c->box_hb * u;
    cam.mode = SOOC_INVIEW_CORNERS;
    sooc_cogmap_slot slots[SOOC_COGMAP_K_MAX];
    int nret = 0;
    sooc_floor_frame gf;
    if ((st = sooc_cogmap_query(ft->map, &cam, ft->p.max_obj, slots, &nret, &gf, NULL)))
        return sooc_adderr(st, "finetune: frame %lld", (long long)f->index);
    int32_t bi = 0, bj = 0;
    double blk[2] = {0, 0};
    if ((st = sooc_cogmap_active_block(ft->map, f->T_wc, cam.d_clip, &bi, &bj, blk)))
        return sooc_adderr(st, "finetune: frame %lld", (long long)f->index);
    if (ft->nv == ft->cap_v) {
        int nc = ft->cap_v ? 2 * ft->cap_v : 32;
        sooc_ft_view *nvw = sooc_realloc(ft->views, (size_t)nc * sizeof *nvw);
        if (!nvw) return SOOC_ENOMEM;
        ft->views = nvw, ft->cap_v = nc;
    }
    sooc_ft_view *v = &ft->views[ft->nv];
    memset(v, 0, sizeof *v);
    v->h = (float)h * iu;
    v->blk[0] = (float)blk[0] * iu, v->blk[1] = (float)-h * iu, v->blk[2] = (float)blk[1] * iu;
    if ((st = get_comp(ft, SOOC_FT_LAYOUT, 0, bi, bj, &v->lay))) return st;
    for (int i = 0; i < nret; i++) {
        sooc_mdl_lam_from_m(c, slots[i].lam, 1, SOOC_LAM_SIZE(c->d_what));
        if ((st = get_comp(ft, SOOC_FT_OBJECT, slots[i].id, 0, 0, &v->comp[v->nc]))) return st;
        v->pose[v->nc][0] = slots[i].lam[0], v->pose[v->nc][1] = slots[i].lam[1], v->pose[v->nc][2] = slots[i].lam[2];
        v->nc++;
    }
    /* rays: every pixel (docs/finetune.md), as sooc_mdl_make_rays reads them */
    size_t npx = (size_t)f->width * f->height;
    if ((st = grow_rays(ft, ft->nr + npx))) return st;
    double Rwg[9], Rwc[9], tt[3], Rgc[9], RwgT[9];
    sooc_se3_inverse(T_gw, T_wg);
    sooc_se3_to_rt(Rwg, tt, T_wg);
    sooc_se3_to_rt(Rwc, tt, f->T_wc);
    sooc_m3_transpose(RwgT, Rwg);
    sooc_m3_mul(Rgc, RwgT, Rwc);
    int unk_mode = c->invalid_depth == SOOC_INVALID_DEPTH_UNKNOWN;
    float sup_h = ft->p.support_m * iu;
    for (int y = 0; y < f->height; y++)
        for (int x = 0; x < f->width; x++) {
            size_t pix = (size_t)y * f->width + x;
            double dc[3], dg[3];
            double uz = sooc_cam_ray(&f->K, x, y, dc);
            sooc_m3_mulv(dg, Rgc, dc);
            float zd = f->depth ? f->depth[pix] : 0.0f;
            int valid = (f->valid ? f->valid[pix] != 0 : 1) && zd > 0 && isfinite(zd);
            float d = valid ? (float)(zd / uz) * iu : 0.0f;
            int surf = valid && d <= c->d_clip && d > c->t_near;
            int unk = unk_mode && !surf && !(valid && d > c->d_clip);
            if (unk) continue;   /* a hole says nothing about the ray */
            size_t r = ft->nr;
            for (int a = 0; a < 3; a++) {
                ft->dir[r * 3 + a] = (float)dg[a];
                ft->rgb[r * 3 + a] = f->rgb[pix * 3 + a] * (1.0f / 255.0f);
            }
            ft->depth[r] = surf ? d : 0.0f;
            /* 2: the surface lies on the support plane (G: camera at the origin, plane at y = -h) */
            ft->surf[r] = (uint8_t)(surf ? (sup_h > 0 && v->h + d * (float)dg[1] < sup_h ? 2 : 1) : 0);
            ft->rview[r] = (uint32_t)ft->nv;
            float t1 = surf ? d + c->delta_s : c->d_clip;
            uint64_t mk = 0;
            int nx = 0;
            for (int k = 0; k < v->nc; k++)
                if (ray_crosses(c, ft->dir + r * 3, c->t_near * 0.5f, t1, v->pose[k], v->h)) mk |= 1ULL << k, nx++;
            if (nx > ft->max_cross) ft->max_cross = nx;
            ft->mask[r] = mk;
            ft->nr++;
        }
    ft->nv++;
    return SOOC_OK;
}

/* ------------------------------------------------------------ units */

static int cmp_unit(const void *a, const void *b, void *ctx) {
    const sooc_finetune *ft = ctx;
    const sooc_ft_comp *x = &ft->comp[*(const int *)a], *y = &ft->comp[*(const int *)b];
    if (x->kind != y->kind) return x->kind < y->kind ? -1 : 1;
    if (x->kind == SOOC_FT_OBJECT) return x->id < y->id ? -1 : x->id > y->id;
    if (x->bi != y->bi) return x->bi < y->bi ? -1 : 1;
    return x->bj < y->bj ? -1 : x->bj > y->bj;
}

/* insertion sort with a context (few units) */
static void sort_units(sooc_finetune *ft) {
    for (int i = 1; i < ft->nunits; i++)
        for (int j = i; j > 0 && cmp_unit(&ft->units[j - 1], &ft->units[j], ft) > 0; j--) {
            int t = ft->units[j];
            ft->units[j] = ft->units[j - 1], ft->units[j - 1] = t;
        }
}

/* Build the components' ray lists (done by the first unit call). */
static sooc_status sooc_ft_build(sooc_finetune *ft) {
    if (ft->built) return SOOC_OK;
    for (int i = 0; i < ft->ncomp; i++) ft->comp[i].nrays = 0;
    /* count, then fill */
    for (int pass = 0; pass < 2; pass++) {
        for (size_t r = 0; r < ft->nr; r++) {
            const sooc_ft_view *v = &ft->views[ft->rview[r]];
            sooc_ft_comp *lc = &ft->comp[v->lay];
            if (pass) lc->rays[lc->nrays] = (uint32_t)r;
            lc->nrays++;
            for (uint64_t mk = ft->mask[r]; mk; mk &= mk - 1) {
                sooc_ft_comp *oc = &ft->comp[v->comp[__builtin_ctzll(mk)]];
                if (pass) oc->rays[oc->nrays] = (uint32_t)r;
                oc->nrays++;
            }
        }
        if (!pass)
            for (int i = 0; i < ft->ncomp; i++) {
                sooc_ft_comp *c = &ft->comp[i];
                c->rays = sooc_malloc((c->nrays ? c->nrays : 1) * sizeof(uint32_t));
                if (!c->rays) return SOOC_ENOMEM;
                c->nrays = 0;
            }
    }
    /* views per component */
    for (int i = 0; i < ft->ncomp; i++) {
        sooc_ft_comp *c = &ft->comp[i];
        uint32_t last = UINT32_MAX;
        for (size_t k = 0; k < c->nrays; k++)
            if (ft->rview[c->rays[k]] != last) last = ft->rview[c->rays[k]], c->n_views++;
    }
    ft->units = sooc_malloc((size_t)(ft->ncomp ? ft->ncomp : 1) * sizeof(int));
    ft->cnt = sooc_calloc((size_t)ft->ncomp + 1, sizeof(int));
    ft->off = sooc_calloc((size_t)ft->ncomp + 1, sizeof(int));
    size_t maxw = 0;
    int H = ft->m->cfg.dec_width;
    for (int i = 0; i < ft->ncomp; i++)
        if (ft->comp[i].nw > maxw) maxw = ft->comp[i].nw;
    ft->gw = sooc_malloc((maxw + 1) * sizeof(float));
    ft->gbias = sooc_malloc((size_t)H * sizeof(float));
    ft->am = sooc_malloc((maxw + SOOC_MODEL_D_MAX) * sizeof(float));
    ft->av = sooc_malloc((maxw + SOOC_MODEL_D_MAX) * sizeof(float));
    if (!ft->units || !ft->cnt || !ft->off || !ft->gw || !ft->gbias || !ft->am || !ft->av) return SOOC_ENOMEM;
    ft->nunits = 0;
    for (int i = 0; i < ft->ncomp; i++) {
        const sooc_ft_comp *c = &ft->comp[i];
        if (!c->nrays || (c->kind == SOOC_FT_LAYOUT && (!ft->p.layout || !ft->m->cfg.d_layout))) continue;
        ft->units[ft->nunits++] = i;
    }
    sort_units(ft);
    ft->built = 1;
    return SOOC_OK;
}

int sooc_finetune_n_units(const sooc_finetune *ft) {
    if (!ft->built && sooc_ft_build((sooc_finetune *)ft)) return 0;
    return ft->nunits;
}

sooc_status sooc_finetune_unit_get(const sooc_finetune *ft, int u, sooc_finetune_unit *out) {
    if (u < 0 || u >= sooc_finetune_n_units(ft)) return sooc_seterr(SOOC_EINVAL, "finetune: no unit %d", u);
    const sooc_ft_comp *c = &ft->comp[ft->units[u]];
    out->kind = c->kind, out->id = c->id, out->bi = c->bi, out->bj = c->bj;
    out->n_views = c->n_views, out->n_rays = c->nrays;
    return SOOC_OK;
}

/* ------------------------------------------------------------ objective */

static sooc_status grow_ws(sooc_finetune *ft, size_t npts) {
    const sooc_model_config *c = &ft->m->cfg;
    size_t nrows = npts * (size_t)(2 + ft->max_cross);
    if (npts <= ft->cap_pts && nrows <= ft->cap_rows) return SOOC_OK;
    free_ws(ft);
    int H = c->dec_width, Hc = c->dec_color_width;
    int din = ft->m->dobj.din > ft->m->dlay.din ? ft->m->dobj.din : ft->m->dlay.din;
    ft->pts = sooc_malloc(npts * 3 * sizeof(float));
    ft->Wa = sooc_malloc(npts * sizeof(float));
    ft->pt_row0 = sooc_malloc(npts * sizeof(int));
    ft->pt_nrow = sooc_malloc(npts * sizeof(int));
    ft->row_comp = sooc_malloc(nrows * sizeof(int));
    ft->row_pos = sooc_malloc(nrows * sizeof(int));
    ft->row_pt = sooc_malloc(nrows * sizeof(int));
    ft->pe = sooc_malloc(nrows * din * sizeof(float));
    ft->a1 = sooc_malloc(nrows * H * sizeof(float));
    ft->a2 = sooc_malloc(nrows * H * sizeof(float));
    ft->a3 = sooc_malloc(nrows * H * sizeof(float));
    ft->ac = sooc_malloc(nrows * Hc * sizeof(float));
    ft->sig = sooc_malloc(nrows * sizeof(float));
    ft->col = sooc_malloc(nrows * 3 * sizeof(float));
    ft->gsig = sooc_malloc(nrows * sizeof(float));
    ft->gcol = sooc_malloc(nrows * 3 * sizeof(float));
    ft->gA = sooc_malloc(nrows * H * sizeof(float));
    ft->gB = sooc_malloc(nrows * H * sizeof(float));
    ft->gC = sooc_malloc(nrows * Hc * sizeof(float));
    if (!ft->pts || !ft->Wa || !ft->pt_row0 || !ft->pt_nrow || !ft->row_comp || !ft->row_pos || !ft->row_pt ||
        !ft->pe || !ft->a1 || !ft->a2 || !ft->a3 || !ft->ac || !ft->sig || !ft->col || !ft->gsig || !ft->gcol ||
        !ft->gA || !ft->gB || !ft->gC) {
        free_ws(ft);
        return SOOC_ENOMEM;
    }
    ft->cap_pts = npts, ft->cap_rows = nrows;
    return SOOC_OK;
}

static inline int in_box(const sooc_model_config *c, const float xk[3]) {
    return fabsf(xk[0]) <= c->box_rh && fabsf(xk[2]) <= c->box_rh && xk[1] >= 0 && xk[1] <= c->box_hb;
}

/* Local coordinates of point x (G) for component slot k of view v (k < 0:
 * the layout), written as the decoder's positional encoding. 0 if outside. */
static int local_pe(const sooc_finetune *ft, const sooc_ft_view *v, int k, const float x[3], float *pe) {
    const sooc_model_config *c = &ft->m->cfg;
    if (k < 0) {
        float xl[3] = {x[0] - v->blk[0], x[1] - v->blk[1], x[2] - v->blk[2]};
        sooc_mdl_pe_row(xl, 1.0f / c->block_size, ft->m->dlay.nfreq, pe);
        return 1;
    }
    float xk[3];
    sooc_mdl_pi(x, v->pose[k][0], v->pose[k][1], v->pose[k][2], v->h, xk);
    if (!in_box(c, xk)) return 0;
    sooc_mdl_pe_row(xk, 1.0f / c->box_rh, ft->m->dobj.nfreq, pe);
    return 1;
}

sooc_status sooc_ft_objective(sooc_finetune *ft, int u, const uint32_t *rays, size_t n, uint64_t seed, float *gw,
                         float *gz, double *ll_out) {
    const sooc_model *m = ft->m;
    const sooc_model_config *c = &m->cfg;
    sooc_status st = sooc_ft_build(ft);
    if (st) return st;
    if ((st = grow_ws(ft, 2 * n))) return st;
    int H = c->dec_width, Hc = c->dec_color_width;
    int dinmax = m->dobj.din > m->dlay.din ? m->dobj.din : m->dlay.din;
    float cut = c->air_cut;
    /* 1. samples: point 2i = surface, 2i + 1 = air */
    for (size_t i = 0; i < n; i++) {
        uint32_t r = rays[i];
        sooc_rng rng;
        sooc_rng_seed(&rng, seed, 0x66740000ULL + r);
        const float *d = ft->dir + (size_t)r * 3;
        float *ps = ft->pts + i * 6, *pa = ps + 3, ta;
        if (ft->surf[r]) {
            float dep = ft->depth[r];
            float es = c->delta_s * sooc_rng_uniformf(&rng);
            /* on the support plane the sample lies in front of the surface, where an
             * object standing there would have its density */
            if (ft->surf[r] == 2) es = -es;
            for (int a = 0; a < 3; a++) ps[a] = (dep + es) * d[a];
            int near = sooc_rng_uniformf(&rng) < 0.5f;
            float U = sooc_rng_uniformf(&rng);
            if (near) ta = dep * (cut + (1 - cut) * U), ft->Wa[i] = 2 * (1 - cut) * dep;
            else ta = dep * cut * U, ft->Wa[i] = 2 * cut * dep;
        } else {
            for (int a = 0; a < 3; a++) ps[a] = 0;
            ta = c->d_clip * sooc_rng_uniformf(&rng);
            ft->Wa[i] = c->d_clip;
        }
        for (int a = 0; a < 3; a++) pa[a] = ta * d[a];
    }
    /* 2. rows in point order: (point, component); components with no rows skip */
    size_t nrow = 0;
    int nc = ft->ncomp;
    memset(ft->cnt, 0, (size_t)(nc + 1) * sizeof(int));
    float pe_tmp[3 + 6 * 16];
    for (size_t p = 0; p < 2 * n; p++) {
        uint32_t r = rays[p / 2];
        int air = (int)(p & 1);
        ft->pt_row0[p] = (int)nrow, ft->pt_nrow[p] = 0;
        if (!air && !ft->surf[r]) continue;   /* free ray: air sample only */
        const sooc_ft_view *v = &ft->views[ft->rview[r]];
        const float *x = ft->pts + p * 3;
        /* layout first, then the crossed objects */
        ft->row_comp[nrow] = v->lay, ft->row_pt[nrow] = (int)p, nrow++, ft->cnt[v->lay]++, ft->pt_nrow[p]++;
        for (uint64_t mk = ft->mask[r]; mk; mk &= mk - 1) {
            int k = __builtin_ctzll(mk);
            if (!local_pe(ft, v, k, x, pe_tmp)) continue;
            ft->row_comp[nrow] = v->comp[k], ft->row_pt[nrow] = (int)p, nrow++;
            ft->cnt[v->comp[k]]++, ft->pt_nrow[p]++;
        }
    }
    SOOC_ASSERT(nrow <= ft->cap_rows);
    ft->off[0] = 0;
    for (int k = 0; k < nc; k++) ft->off[k + 1] = ft->off[k] + ft->cnt[k];
    for (int k = 0; k < nc; k++) ft->cnt[k] = 0;
    for (size_t i = 0; i < nrow; i++) {
        int k = ft->row_comp[i];
        int pos = ft->off[k] + ft->cnt[k]++;
        ft->row_pos[i] = pos;
        uint32_t r = rays[ft->row_pt[i] / 2];
        const sooc_ft_view *v = &ft->views[ft->rview[r]];
        int slot = -1;
        if (k != v->lay)
            for (int j = 0; j < v->nc; j++)
                if (v->comp[j] == k) {
                    slot = j;
                    break;
                }
        local_pe(ft, v, slot, ft->pts + (size_t)ft->row_pt[i] * 3, ft->pe + (size_t)pos * dinmax);
    }
    /* 3. forward per component (pe rows have stride dinmax: compact to din first) */
    for (int k = 0; k < nc; k++) {
        int R = ft->off[k + 1] - ft->off[k];
        if (!R) continue;
        sooc_ft_comp *cp = &ft->comp[k];
        int din = cp->net->din, o = ft->off[k];
        float *pe = ft->pe + (size_t)o * dinmax;
        if (din != dinmax)
            for (int i = 0; i < R; i++) memmove(pe + (size_t)i * din, pe + (size_t)i * dinmax, din * sizeof(float));
        sooc_mdl_own_forward(cp->w, &cp->rel, R, pe, cp->bias, ft->a1 + (size_t)o * H, ft->a2 + (size_t)o * H,
                        ft->a3 + (size_t)o * H, ft->ac + (size_t)o * Hc, ft->sig + o, ft->col + (size_t)o * 3);
    }
    /* 4. per ray: ℓ and the gradient at the unit's rows */
    if (u >= 0) {
        int o = ft->off[u], R = ft->off[u + 1] - o;
        memset(ft->gsig + o, 0, (size_t)R * sizeof(float));
        memset(ft->gcol + (size_t)o * 3, 0, (size_t)R * 3 * sizeof(float));
    }
    double ll = 0;
    float smax = c->sigma_max, eps_s = c->eps_sigma_rel * c->sigma_max, isc2 = 1.0f / (ft->sigma_c * ft->sigma_c);
    for (size_t i = 0; i < n; i++) {
        uint32_t r = rays[i];
        /* air sample: -W smax Σ̄(x_a) */
        {
            size_t p = 2 * i + 1;
            double S = 1e-8, Q2 = 0;
            for (int j = 0; j < ft->pt_nrow[p]; j++) {
                float s = ft->sig[ft->row_pos[ft->pt_row0[p] + j]];
                S += s, Q2 += (double)s * s;
            }
            double W = ft->Wa[i];
            ll -= W * smax * Q2 / S;
            if (u >= 0)
                for (int j = 0; j < ft->pt_nrow[p]; j++) {
                    int row = ft->pt_row0[p] + j;
                    if (ft->row_comp[row] != u) continue;
                    float s = ft->sig[ft->row_pos[row]];
                    ft->gsig[ft->row_pos[row]] += (float)(-W * smax * (2 * s / S - Q2 / (S * S)));
                }
        }
        if (!ft->surf[r]) continue;
        size_t p = 2 * i;
        const float *C = ft->rgb + (size_t)r * 3;
        if (ft->surf[r] == 2) {
            /* on the support plane: log(smax σ̂_lay + ε) + log N_lay - Wb smax Σ_obj σ̂_k(x_s), Wb = δ_s */
            for (int j = 0; j < ft->pt_nrow[p]; j++) {
                int row = ft->pt_row0[p] + j, pos = ft->row_pos[row];
                float s = ft->sig[pos];
                int mine = u >= 0 && ft->row_comp[row] == u;
                if (j == 0) {   /* the layout's row comes first */
                    const float *cc = ft->col + (size_t)pos * 3;
                    float d0 = C[0] - cc[0], d1 = C[1] - cc[1], d2 = C[2] - cc[2];
                    ll += log(smax * (double)s + eps_s) - 0.5 * (d0 * d0 + d1 * d1 + d2 * d2) * isc2;
                    if (!mine) continue;
                    ft->gsig[pos] += (float)(smax / (smax * (double)s + eps_s));
                    for (int a = 0; a < 3; a++) ft->gcol[(size_t)pos * 3 + a] += (C[a] - cc[a]) * isc2;
                } else {
                    ll -= c->delta_s * smax * (double)s;
                    if (mine) ft->gsig[pos] += -c->delta_s * smax;
                }
            }
            continue;
        }
        double S = 1e-8, Q2 = 0, lmax = -INFINITY;
        float lN[SOOC_COGMAP_K_MAX + 1];
        int nrp = ft->pt_nrow[p];
        for (int j = 0; j < nrp; j++) {
            int pos = ft->row_pos[ft->pt_row0[p] + j];
            float s = ft->sig[pos];
            const float *cc = ft->col + (size_t)pos * 3;
            float d0 = C[0] - cc[0], d1 = C[1] - cc[1], d2 = C[2] - cc[2];
            lN[j] = -0.5f * (d0 * d0 + d1 * d1 + d2 * d2) * isc2;
            S += s, Q2 += (double)s * s;
            if (s > 0 && lN[j] > lmax) lmax = lN[j];
        }
        double Sb = Q2 / S;
        ll += log(smax * Sb + eps_s);
        /* mixture term log Σ_k (σ̂_k² / Q2) N_k (the Gaussian's constant is dropped) */
        double A = 0;
        for (int j = 0; j < nrp; j++) {
            float s = ft->sig[ft->row_pos[ft->pt_row0[p] + j]];
            A += (double)s * s * exp(lN[j] - lmax);
        }
        if (Q2 > 1e-30 && A > 0) ll += log(A / Q2) + lmax;
        if (u < 0) continue;
        for (int j = 0; j < nrp; j++) {
            int row = ft->pt_row0[p] + j;
            if (ft->row_comp[row] != u) continue;
            int pos = ft->row_pos[row];
            double s = ft->sig[pos];
            /* d log(smax Σ̄ + ε)/dσ̂_u, Σ̄ = Q2 / S */
            double g = smax / (smax * Sb + eps_s) * (2 * s / S - Q2 / (S * S));
            if (Q2 > 1e-30 && A > 0) {
                double eN = exp(lN[j] - lmax);
                double gam = s * s * eN / A;   /* E-step responsibility γ_u (no gradient) */
                g += 2 * s * eN / A - 2 * s / Q2;
                const float *cc = ft->col + (size_t)pos * 3;
                for (int a = 0; a < 3; a++) ft->gcol[(size_t)pos * 3 + a] += (float)(gam * (C[a] - cc[a]) * isc2);
            }
            ft->gsig[pos] += (float)g;
        }
    }
    *ll_out = ll;
    if (u < 0) return SOOC_OK;
    /* 5. backward through the unit's decoder copy */
    sooc_ft_comp *cu = &ft->comp[u];
    int o = ft->off[u], R = ft->off[u + 1] - o;
    if (!R) return SOOC_OK;
    memset(ft->gbias, 0, (size_t)H * sizeof(float));
    sooc_mdl_own_backward(cu->w, &cu->rel, R, ft->pe + (size_t)o * dinmax, ft->a1 + (size_t)o * H, ft->a2 + (size_t)o * H,
                     ft->a3 + (size_t)o * H, ft->ac + (size_t)o * Hc, ft->sig + o, ft->col + (size_t)o * 3,
                     ft->gsig + o, ft->gcol + (size_t)o * 3, ft->gA, ft->gB, ft->gC, gw, ft->gbias);
    sooc_mdl_own_bias_backward(cu->w, &cu->rel, cu->z, ft->gbias, gw, gz);
    return SOOC_OK;
}

/* ------------------------------------------------------------ units: run */

sooc_status sooc_finetune_unit_payload(const sooc_finetune *ft, int u, const float **v, size_t *n) {
    if (u < 0 || u >= ft->nunits) return sooc_seterr(SOOC_EINVAL, "finetune: no unit %d", u);
    const sooc_ft_comp *c = &ft->comp[ft->units[u]];
    *v = c->kind == SOOC_FT_OBJECT ? sooc_cogmap_payload_get(ft->map, c->id, n)
                                   : sooc_cogmap_block_payload_get(ft->map, c->bi, c->bj, n);
    if (!*v) return sooc_seterr(SOOC_ENOTFOUND, "finetune: unit %d has no payload in the map yet", u);
    return SOOC_OK;
}

sooc_status sooc_finetune_unit_run(sooc_finetune *ft, int u, sooc_finetune_progress_fn cb, void *user, int every,
                                   sooc_finetune_result *res) {
    sooc_finetune_result rl;
    if (!res) res = &rl;
    memset(res, 0, sizeof *res);
    sooc_status st = sooc_ft_build(ft);
    if (st) return st;
    if (u < 0 || u >= ft->nunits) return sooc_seterr(SOOC_EINVAL, "finetune: no unit %d", u);
    int k = ft->units[u];
    sooc_ft_comp *c = &ft->comp[k];
    size_t nw = c->nw;
    int dz = c->net->dz, iters = ft->p.iterations;
    size_t B = ft->p.rays > 0 && (size_t)ft->p.rays < c->nrays ? (size_t)ft->p.rays : c->nrays;
    uint32_t *batch = sooc_malloc((B ? B : 1) * sizeof(uint32_t));
    if (!batch) return SOOC_ENOMEM;
    memset(ft->am, 0, (nw + dz) * sizeof(float));
    memset(ft->av, 0, (nw + dz) * sizeof(float));
    sooc_rng rng;
    sooc_rng_seed(&rng, ft->p.seed, 0x6674ULL + (uint64_t)k * 7919ULL + (c->kind == SOOC_FT_OBJECT ? c->id : 0));
    const float b1 = 0.9f, b2 = 0.999f, eps = 1e-8f;
    double t0 = sooc_seconds(), ema = 0, first = 0, last = 0;
    int nfirst = 0, nlast = 0, win = iters / 10 > 0 ? iters / 10 : 1;
    for (int it = 0; it < iters; it++) {
        if (B == c->nrays) memcpy(batch, c->rays, B * sizeof(uint32_t));
        else
            for (size_t i = 0; i < B; i++) batch[i] = c->rays[sooc_rng_below(&rng, (uint32_t)c->nrays)];
        uint64_t sseed = ft->p.fixed_samples ? ft->p.seed : sooc_rng_u64(&rng);
        memset(ft->gw, 0, nw * sizeof(float));
        float gz[SOOC_MODEL_D_MAX] = {0};
        double ll = 0;
        if ((st = sooc_ft_objective(ft, k, batch, B, sseed, ft->gw, gz, &ll))) break;
        double loss = -ll / (double)(B ? B : 1);
        if (!isfinite(loss)) {
            st = sooc_seterr(SOOC_ENUMERIC, "finetune: non-finite likelihood at step %d of unit %d", it, u);
            break;
        }
        if (it < win) first += loss, nfirst++;
        if (it >= iters - win) last += loss, nlast++;
        ema = it ? 0.9 * ema + 0.1 * loss : loss;
        /* Adam ascent on ℓ (mean over the batch) */
        float ib = 1.0f / (float)(B ? B : 1);
        float bc1 = 1.0f - powf(b1, (float)(it + 1)), bc2 = 1.0f - powf(b2, (float)(it + 1));
        float sch = sooc_finetune_lr_scale(&ft->p, it), lr_w = ft->p.lr * sch, lr_zz = ft->p.lr_z * sch;
        for (size_t i = 0; i < nw + (size_t)dz; i++) {
            float g = -(i < nw ? ft->gw[i] : gz[i - nw]) * ib;
            float *mm = &ft->am[i], *vv = &ft->av[i];
            *mm = b1 * *mm + (1 - b1) * g;
            *vv = b2 * *vv + (1 - b2) * g * g;
            float step = (i < nw ? lr_w : lr_zz) * (*mm / bc1) / (sqrtf(*vv / bc2) + eps);
            if (i < nw) c->w[i] -= step;
            else c->z[i - nw] -= step;
        }
        sooc_ft_comp_bias(c);
        res->steps = it + 1;
        if (cb && every > 0 && ((it + 1) % every == 0 || it + 1 == iters)) {
            double el = sooc_seconds() - t0;
            sooc_finetune_progress pr = {u, ft->nunits, it + 1, iters, ema, (it + 1) / (el > 0 ? el : 1e-9), 0};
            pr.eta_s = (iters - it - 1) / (pr.steps_per_s > 0 ? pr.steps_per_s : 1e-9);
            if (cb(user, &pr)) {
                st = sooc_seterr(SOOC_EINTERRUPTED, "finetune: stopped during unit %d", u);
                break;
            }
        }
    }
    sooc_free(batch);
    res->seconds = sooc_seconds() - t0;
    res->loss_first = nfirst ? first / nfirst : 0;
    res->loss_last = nlast ? last / nlast : 0;
    if (st) return st;
    /* the finished unit's decoder goes into the map */
    size_t np = sooc_mdl_ft_payload_size(c->net);
    float *pl = sooc_malloc(np * sizeof(float));
    if (!pl) return SOOC_ENOMEM;
    sooc_mdl_ft_payload_pack(c->net, c->kind == SOOC_FT_OBJECT ? MDL_FT_OBJ : MDL_FT_LAY, c->z, c->w, pl);
    st = c->kind == SOOC_FT_OBJECT ? sooc_cogmap_payload_set(ft->map, c->id, pl, np)
                                   : sooc_cogmap_block_payload_set(ft->map, c->bi, c->bj, pl, np);
    sooc_free(pl);
    return st;
}

sooc_status sooc_finetune_run_all(sooc_finetune *ft, sooc_finetune_progress_fn cb, void *user, int every) {
    int n = sooc_finetune_n_units(ft);
    for (int u = 0; u < n; u++) {
        sooc_status st = sooc_finetune_unit_run(ft, u, cb, user, every, NULL);
        if (st) return st;
    }
    return SOOC_OK;
}

sooc_status sooc_finetune_loglik(sooc_finetune *ft, uint64_t seed, double *ll, size_t *n_rays) {
    sooc_status st = sooc_ft_build(ft);
    if (st) return st;
    *ll = 0;
    uint32_t chunk[1024];
    for (size_t r0 = 0; r0 < ft->nr; r0 += 1024) {
        size_t nb = ft->nr - r0 < 1024 ? ft->nr - r0 : 1024;
        for (size_t i = 0; i < nb; i++) chunk[i] = (uint32_t)(r0 + i);
        double l = 0;
        if ((st = sooc_ft_objective(ft, -1, chunk, nb, seed, NULL, NULL, &l))) return st;
        *ll += l;
    }
    if (n_rays) *n_rays = ft->nr;
    return SOOC_OK;
}
