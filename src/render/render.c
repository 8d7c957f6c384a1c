/* Dense volume renderer: see include/sooc3d/render.h for the exact rules. */
#include "sooc3d/render.h"

#include <math.h>
#include <string.h>

#ifdef SOOC_HAVE_OPENMP
#include <omp.h>
#endif

#define COMP_EPS 1e-8f
#define BOX_PAD 1e-5

void sooc_render_opts_default(sooc_render_opts *o) {
    memset(o, 0, sizeof *o);
    o->n_coarse = 96;
    o->n_fine = 32;
    o->t_near = 0.1;
    o->d_clip = 8.0;
    o->cull = 1;
    o->chunk_rays = 16;
}

void sooc_render_box_object(sooc_render_box *b, double px, double pz, double yaw, double h,
                            double R_h, double H_b) {
    double R[9], t[3] = {px, -h, pz};
    sooc_m3_rot_y(R, yaw);
    memset(b, 0, sizeof *b);
    b->enabled = 1;
    sooc_se3_from_rt(b->T_fb, R, t);
    b->lo[0] = -R_h; b->lo[1] = 0.0; b->lo[2] = -R_h;
    b->hi[0] = R_h;  b->hi[1] = H_b; b->hi[2] = R_h;
}

void sooc_render_box_aabb(sooc_render_box *b, const double lo[3], const double hi[3]) {
    memset(b, 0, sizeof *b);
    b->enabled = 1;
    sooc_se3_identity(b->T_fb);
    for (int i = 0; i < 3; i++) { b->lo[i] = lo[i]; b->hi[i] = hi[i]; }
}

int sooc_render_ray_box(const sooc_render_box *b, const double o[3], const double r[3],
                        double zmin, double zmax, double *z0, double *z1) {
    /* Ray in box-local coordinates: p_b = R^T (p_f - t). */
    double R[9], t[3], d[3], ol[3], rl[3];
    sooc_se3_to_rt(R, t, b->T_fb);
    sooc_v3_sub(d, o, t);
    sooc_m3_tmulv(ol, R, d);
    sooc_m3_tmulv(rl, R, r);
    double a = zmin, c = zmax;
    for (int i = 0; i < 3; i++) {
        double lo = b->lo[i] - BOX_PAD, hi = b->hi[i] + BOX_PAD;
        if (fabs(rl[i]) < 1e-300) {
            if (ol[i] < lo || ol[i] > hi) return 0;
            continue;
        }
        double ta = (lo - ol[i]) / rl[i], tb = (hi - ol[i]) / rl[i];
        if (ta > tb) { double s = ta; ta = tb; tb = s; }
        if (ta > a) a = ta;
        if (tb < c) c = tb;
        if (a > c) return 0;
    }
    *z0 = a;
    *z1 = c;
    return 1;
}

void sooc_render_out_free(sooc_render_out *o) {
    if (!o) return;
    sooc_free(o->rgb);
    sooc_free(o->depth);
    sooc_free(o->alpha);
    sooc_free(o->label);
    sooc_free(o->seg);
    sooc_free(o->comp_rgb);
    sooc_free(o->comp_alpha);
    sooc_free(o->uncert);
    sooc_free(o->rgb_mean);
    memset(o, 0, sizeof *o);
}

/* (Re)allocate a buffer of n bytes if missing or if the image size changed. */
static sooc_status ensure(void **p, size_t n, int realloc_needed) {
    if (*p && !realloc_needed) return SOOC_OK;
    sooc_free(*p);
    *p = sooc_malloc(n);
    return *p ? SOOC_OK : SOOC_ENOMEM;
}

static sooc_status out_prepare(sooc_render_out *out, int W, int H, int nc, int comps, int soft) {
    int size_changed = out->width != W || out->height != H;
    int changed = size_changed || out->n_comp != nc;
    size_t P = (size_t)W * H;
    if (changed) {   /* buffers whose size depends on the component count */
        sooc_free(out->seg); out->seg = NULL;
        sooc_free(out->comp_rgb); out->comp_rgb = NULL;
        sooc_free(out->comp_alpha); out->comp_alpha = NULL;
    }
    if (size_changed) {
        sooc_free(out->uncert); out->uncert = NULL;
        sooc_free(out->rgb_mean); out->rgb_mean = NULL;
    }
    sooc_status s = SOOC_OK;
    s = s ? s : ensure((void **)&out->rgb, P * 3 * sizeof(float), size_changed);
    s = s ? s : ensure((void **)&out->depth, P * sizeof(float), size_changed);
    s = s ? s : ensure((void **)&out->alpha, P * sizeof(float), size_changed);
    s = s ? s : ensure((void **)&out->label, P * sizeof(int16_t), size_changed);
    if (soft) s = s ? s : ensure((void **)&out->seg, P * nc * sizeof(float), 0);
    if (comps) {
        s = s ? s : ensure((void **)&out->comp_rgb, P * nc * 3 * sizeof(float), 0);
        s = s ? s : ensure((void **)&out->comp_alpha, P * nc * sizeof(float), 0);
    }
    out->width = W;
    out->height = H;
    out->n_comp = nc;
    if (s) return sooc_seterr(s, "render: out of memory for %dx%d output (%d components)", W, H, nc);
    return SOOC_OK;
}

/* Per-worker scratch, allocated once per render call. C rays, Ns samples. */
typedef struct scratch {
    float *z;          /* C*Ns planar depths; [0,nc) coarse, [nc,Ns) fine (each sorted)   */
    int *order;        /* C*Ns merged order of sample slots                                */
    float *sh;         /* C*Ns*N sigma_hat                                                 */
    float *col;        /* C*Ns*N*3 colour                                                  */
    float *pts;        /* C*Nmax*3 gathered points                                         */
    int *gidx;         /* C*Nmax gathered sample slots (ray*Ns + slot)                     */
    float *gs, *gc;    /* eval outputs                                                     */
    double *r;         /* C*3 ray directions (field frame, planar-depth scaled)            */
    double *rn;        /* C ray |r|                                                        */
    double *bz;        /* C*N*2 box intervals (z0, z1), z0 > z1 = miss                      */
    float *w;          /* C*Ns weights (coarse pass)                                       */
    double *cdf;       /* n_coarse + 2                                                     */
} scratch;

static void scratch_free(scratch *s) {
    sooc_free(s->z); sooc_free(s->order); sooc_free(s->sh); sooc_free(s->col);
    sooc_free(s->pts); sooc_free(s->gidx); sooc_free(s->gs); sooc_free(s->gc);
    sooc_free(s->r); sooc_free(s->rn); sooc_free(s->bz); sooc_free(s->w); sooc_free(s->cdf);
    memset(s, 0, sizeof *s);
}

static sooc_status scratch_alloc(scratch *s, int C, int Ns, int Nmax, int N, int n_coarse) {
    memset(s, 0, sizeof *s);
    size_t cs = (size_t)C * Ns, cm = (size_t)C * Nmax;
    s->z = sooc_malloc(cs * sizeof(float));
    s->order = sooc_malloc(cs * sizeof(int));
    s->sh = sooc_malloc(cs * N * sizeof(float));
    s->col = sooc_malloc(cs * N * 3 * sizeof(float));
    s->pts = sooc_malloc(cm * 3 * sizeof(float));
    s->gidx = sooc_malloc(cm * sizeof(int));
    s->gs = sooc_malloc(cm * sizeof(float));
    s->gc = sooc_malloc(cm * 3 * sizeof(float));
    s->r = sooc_malloc((size_t)C * 3 * sizeof(double));
    s->rn = sooc_malloc((size_t)C * sizeof(double));
    s->bz = sooc_malloc((size_t)C * N * 2 * sizeof(double));
    s->w = sooc_malloc(cs * sizeof(float));
    s->cdf = sooc_malloc(((size_t)n_coarse + 2) * sizeof(double));
    if (!s->z || !s->order || !s->sh || !s->col || !s->pts || !s->gidx || !s->gs || !s->gc ||
        !s->r || !s->rn || !s->bz || !s->w || !s->cdf) {
        scratch_free(s);
        return SOOC_ENOMEM;
    }
    return SOOC_OK;
}

typedef struct ctx {
    const sooc_field *f;
    const sooc_intrinsics *K;
    const sooc_render_opts *o;
    double R_fc[9], o_f[3];    /* camera rotation and centre in the field frame */
    int W, H, N, Ns, nc, nf, C, Nmax;
    sooc_render_out *out;
} ctx;

/* Evaluate every component at sample slots [s0, s1) of the n rays of the chunk. */
static void eval_samples(const ctx *c, scratch *s, int worker, int nray, int s0, int s1) {
    const sooc_field *f = c->f;
    int N = c->N, Ns = c->Ns;
    for (int k = 0; k < N; k++) {
        int use_box = c->o->cull && f->boxes && f->boxes[k].enabled;
        int g = 0;
        for (int i = 0; i < nray; i++) {
            double z0 = -1e300, z1 = 1e300;
            if (use_box) {
                z0 = s->bz[((size_t)i * N + k) * 2];
                z1 = s->bz[((size_t)i * N + k) * 2 + 1];
            }
            const double *r = s->r + 3 * i;
            for (int j = s0; j < s1; j++) {
                size_t slot = (size_t)i * Ns + j;
                double z = s->z[slot];
                if (z < z0 || z > z1) {
                    s->sh[slot * N + k] = 0.f;
                    s->col[(slot * N + k) * 3 + 0] = 0.f;
                    s->col[(slot * N + k) * 3 + 1] = 0.f;
                    s->col[(slot * N + k) * 3 + 2] = 0.f;
                    continue;
                }
                s->pts[3 * g + 0] = (float)(c->o_f[0] + z * r[0]);
                s->pts[3 * g + 1] = (float)(c->o_f[1] + z * r[1]);
                s->pts[3 * g + 2] = (float)(c->o_f[2] + z * r[2]);
                s->gidx[g] = (int)slot;
                g++;
            }
        }
        if (g == 0) continue;
        f->eval(f->user, worker, k, s->pts, g, s->gs, s->gc);
        for (int q = 0; q < g; q++) {
            size_t slot = (size_t)s->gidx[q];
            s->sh[slot * N + k] = s->gs[q];
            s->col[(slot * N + k) * 3 + 0] = s->gc[3 * q + 0];
            s->col[(slot * N + k) * 3 + 1] = s->gc[3 * q + 1];
            s->col[(slot * N + k) * 3 + 2] = s->gc[3 * q + 2];
        }
    }
}

/* Composition at one sample: returns Sbar; fills colour c (if non-NULL). */
static inline float compose(const float *sh, const float *col, int N, float *c) {
    float S = COMP_EPS, S2 = 0.f;
    for (int k = 0; k < N; k++) { S += sh[k]; S2 += sh[k] * sh[k]; }
    if (c) {
        float inv = 1.f / S, c0 = 0.f, c1 = 0.f, c2 = 0.f;
        for (int k = 0; k < N; k++) {
            float p = sh[k] * inv;
            c0 += p * col[3 * k]; c1 += p * col[3 * k + 1]; c2 += p * col[3 * k + 2];
        }
        c[0] = c0; c[1] = c1; c[2] = c2;
    }
    return S2 / S;
}

/* Coarse weights of ray i over the coarse slots [0, nc). */
static void coarse_weights(const ctx *c, scratch *s, int i) {
    int N = c->N, Ns = c->Ns, nc = c->nc;
    double T = 1.0, rn = s->rn[i];
    const float *z = s->z + (size_t)i * Ns;
    for (int j = 0; j < nc; j++) {
        size_t slot = (size_t)i * Ns + j;
        float Sb = compose(s->sh + slot * N, NULL, N, NULL);
        double zn = j + 1 < nc ? z[j + 1] : c->o->d_clip;
        double delta = (zn - z[j]) * rn;
        if (delta < 0) delta = 0;
        double a = 1.0 - exp(-(double)c->f->sigma_max * Sb * delta);
        s->w[slot] = (float)(T * a);
        T *= 1.0 - a;
    }
}

/* Importance samples of ray i into slots [nc, Ns): piecewise-constant pdf on
 * the gaps g = 0..nc, gap g = [z_{g-1}, z_g] with z_{-1} = t_near and
 * z_nc = d_clip. The weight w_j of sample j goes 75 % to the gap preceding it
 * (where a surface first seen at z_j lies) and 25 % to the gap following it:
 * gap g gets 0.75 w_g + 0.25 w_{g-1}. */
static void fine_samples(const ctx *c, scratch *s, int i, uint64_t pix) {
    int nc = c->nc, nf = c->nf, Ns = c->Ns;
    const float *z = s->z + (size_t)i * Ns;
    const float *w = s->w + (size_t)i * Ns;
    double *cdf = s->cdf;   /* nc + 1 gaps -> cdf[0..nc+1] */
    double tot = 0.0;
    cdf[0] = 0.0;
    for (int g = 0; g <= nc; g++) {
        double wg = (g < nc ? 0.75 * w[g] : 0.0) + (g > 0 ? 0.25 * w[g - 1] : 0.0);
        tot += wg;
        cdf[g + 1] = tot;
    }
    sooc_rng rng;
    if (c->o->jitter) sooc_rng_seed(&rng, c->o->seed ^ 0x5bd1e995u, pix);
    float *zf = s->z + (size_t)i * Ns + nc;
    double t0 = c->o->t_near, t1 = c->o->d_clip;
    if (tot <= 1e-12) {   /* empty ray: spread the fine samples uniformly */
        for (int j = 0; j < nf; j++) {
            double u = (j + (c->o->jitter ? sooc_rng_uniform(&rng) : 0.5)) / nf;
            zf[j] = (float)(t0 + u * (t1 - t0));
        }
        return;
    }
    int g = 0;
    for (int j = 0; j < nf; j++) {
        double u = (j + (c->o->jitter ? sooc_rng_uniform(&rng) : 0.5)) / nf * tot;
        while (g < nc && cdf[g + 1] < u) g++;
        double a = g > 0 ? z[g - 1] : t0, b = g < nc ? z[g] : t1;
        double wg = cdf[g + 1] - cdf[g];
        double fr = wg > 0 ? (u - cdf[g]) / wg : 0.5;
        if (fr < 0) fr = 0;
        if (fr > 1) fr = 1;
        zf[j] = (float)(a + fr * (b - a));
    }
}

/* Final compositing of ray i into pixel p. */
static void composite(const ctx *c, scratch *s, int i, size_t p) {
    int N = c->N, Ns = c->Ns, nc = c->nc, n = c->nc + c->nf;
    const float *z = s->z + (size_t)i * Ns;
    int *ord = s->order + (size_t)i * Ns;
    /* merge the two sorted runs [0, nc) and [nc, n) (stable: coarse first on ties) */
    int a = 0, b = nc, m = 0;
    while (a < nc && b < n) ord[m++] = z[b] < z[a] ? b++ : a++;
    while (a < nc) ord[m++] = a++;
    while (b < n) ord[m++] = b++;

    sooc_render_out *out = c->out;
    double rn = s->rn[i], T = 1.0, A = 0.0, D = 0.0, rgb[3] = {0, 0, 0};
    double seg[SOOC_RENDER_MAX_COMP];
    double Tk[SOOC_RENDER_MAX_COMP], ck[SOOC_RENDER_MAX_COMP][3], Ak[SOOC_RENDER_MAX_COMP];
    for (int k = 0; k < N; k++) {
        seg[k] = 0.0; Tk[k] = 1.0; Ak[k] = 0.0; ck[k][0] = ck[k][1] = ck[k][2] = 0.0;
    }
    int comps = c->o->components;
    float sig_max = c->f->sigma_max;
    for (int q = 0; q < n; q++) {
        int j = ord[q];
        size_t slot = (size_t)i * Ns + j;
        const float *sh = s->sh + slot * N, *col = s->col + slot * N * 3;
        float cc[3];
        float Sb = compose(sh, col, N, cc);
        double zn = q + 1 < n ? z[ord[q + 1]] : c->o->d_clip;
        double delta = (zn - z[j]) * rn;
        if (delta < 0) delta = 0;
        double al = 1.0 - exp(-(double)sig_max * Sb * delta);
        double w = T * al;
        T *= 1.0 - al;
        A += w;
        D += w * z[j];
        rgb[0] += w * cc[0]; rgb[1] += w * cc[1]; rgb[2] += w * cc[2];
        if (Sb > 0.f && w > 0.0) {
            float S = COMP_EPS;
            for (int k = 0; k < N; k++) S += sh[k];
            double ws = w / ((double)Sb * S);   /* sbar_k / Sbar = sh_k^2 / (S Sbar) */
            for (int k = 0; k < N; k++) seg[k] += ws * (double)sh[k] * sh[k];
        }
        if (comps) {
            float S = COMP_EPS;
            for (int k = 0; k < N; k++) S += sh[k];
            for (int k = 0; k < N; k++) {
                double sb = (double)sh[k] * sh[k] / S;
                if (sb <= 0.0) continue;
                double ak = 1.0 - exp(-(double)sig_max * sb * delta);
                double wk = Tk[k] * ak;
                Tk[k] *= 1.0 - ak;
                Ak[k] += wk;
                ck[k][0] += wk * col[3 * k]; ck[k][1] += wk * col[3 * k + 1];
                ck[k][2] += wk * col[3 * k + 2];
            }
        }
    }
    const float *bg = c->o->bg_rgb;
    for (int ch = 0; ch < 3; ch++) out->rgb[3 * p + ch] = (float)(rgb[ch] + (1.0 - A) * bg[ch]);
    out->depth[p] = (float)(D + (1.0 - A) * c->o->d_clip);
    out->alpha[p] = (float)A;
    int best = SOOC_RENDER_LABEL_NONE;
    if (A >= 0.5) {
        double bv = -1.0;
        for (int k = 0; k < N; k++)
            if (seg[k] > bv) { bv = seg[k]; best = k; }
    }
    out->label[p] = (int16_t)best;
    size_t P = (size_t)c->W * c->H;
    if (out->seg && c->o->soft_seg)
        for (int k = 0; k < N; k++) out->seg[p * N + k] = (float)seg[k];
    if (comps) {
        for (int k = 0; k < N; k++) {
            out->comp_alpha[k * P + p] = (float)Ak[k];
            for (int ch = 0; ch < 3; ch++) out->comp_rgb[(k * P + p) * 3 + ch] = (float)ck[k][ch];
        }
    }
}

static void render_chunk(const ctx *c, scratch *s, int worker, size_t p0, int nray) {
    int N = c->N, Ns = c->Ns, nc = c->nc;
    const sooc_render_opts *o = c->o;
    double t0 = o->t_near, t1 = o->d_clip, dz = (t1 - t0) / nc;
    for (int i = 0; i < nray; i++) {
        size_t p = p0 + (size_t)i;
        int u = (int)(p % (size_t)c->W), v = (int)(p / (size_t)c->W);
        double rc[3] = {(u + 0.5 - c->K->cx) / c->K->fx, (v + 0.5 - c->K->cy) / c->K->fy, 1.0};
        double *r = s->r + 3 * i;
        sooc_m3_mulv(r, c->R_fc, rc);
        s->rn[i] = sooc_v3_norm(r);
        sooc_rng rng;
        if (o->jitter) sooc_rng_seed(&rng, o->seed, (uint64_t)p);
        float *z = s->z + (size_t)i * Ns;
        for (int j = 0; j < nc; j++)
            z[j] = (float)(t0 + (j + (o->jitter ? sooc_rng_uniform(&rng) : 0.5)) * dz);
        if (o->cull && c->f->boxes) {
            for (int k = 0; k < N; k++) {
                double *bz = s->bz + ((size_t)i * N + k) * 2;
                if (!c->f->boxes[k].enabled) { bz[0] = -1e300; bz[1] = 1e300; continue; }
                if (!sooc_render_ray_box(&c->f->boxes[k], c->o_f, r, t0, t1, &bz[0], &bz[1])) {
                    bz[0] = 1.0; bz[1] = -1.0;   /* empty interval */
                }
            }
        }
    }
    eval_samples(c, s, worker, nray, 0, nc);
    if (c->nf > 0) {
        for (int i = 0; i < nray; i++) {
            coarse_weights(c, s, i);
            fine_samples(c, s, i, (uint64_t)(p0 + (size_t)i));
        }
        eval_samples(c, s, worker, nray, nc, Ns);
    }
    for (int i = 0; i < nray; i++) composite(c, s, i, p0 + (size_t)i);
}

static sooc_status check_args(const sooc_field *f, const sooc_intrinsics *K, const sooc_render_opts *o) {
    if (!f || !f->eval) return sooc_seterr(SOOC_EINVAL, "render: field has no eval callback");
    if (f->n_comp < 1 || f->n_comp > SOOC_RENDER_MAX_COMP)
        return sooc_seterr(SOOC_EINVAL, "render: n_comp = %d outside [1, %d]", f->n_comp,
                           SOOC_RENDER_MAX_COMP);
    if (!(f->sigma_max > 0.f) || !isfinite(f->sigma_max))
        return sooc_seterr(SOOC_EINVAL, "render: sigma_max = %g must be positive", f->sigma_max);
    if (!K || K->width <= 0 || K->height <= 0 || !(K->fx > 0) || !(K->fy > 0))
        return sooc_seterr(SOOC_EINVAL, "render: bad intrinsics");
    if (o->n_coarse < 1 || o->n_fine < 0 || o->n_coarse + o->n_fine > 4096)
        return sooc_seterr(SOOC_EINVAL, "render: n_coarse = %d, n_fine = %d out of range",
                           o->n_coarse, o->n_fine);
    if (!(o->t_near >= 0) || !(o->d_clip > o->t_near) || !isfinite(o->d_clip))
        return sooc_seterr(SOOC_EINVAL, "render: need 0 <= t_near < d_clip (got %g, %g)",
                           o->t_near, o->d_clip);
    if (o->chunk_rays < 1 || o->chunk_rays > 4096)
        return sooc_seterr(SOOC_EINVAL, "render: chunk_rays = %d out of [1, 4096]", o->chunk_rays);
    return SOOC_OK;
}

sooc_status sooc_render_view(const sooc_field *f, const sooc_intrinsics *K, const double T_fc[16],
                             const sooc_render_opts *opts, sooc_render_out *out) {
    sooc_render_opts od;
    if (!opts) { sooc_render_opts_default(&od); opts = &od; }
    sooc_status st = check_args(f, K, opts);
    if (st) return st;
    ctx c;
    memset(&c, 0, sizeof c);
    c.f = f; c.K = K; c.o = opts; c.out = out;
    c.W = K->width; c.H = K->height; c.N = f->n_comp;
    c.nc = opts->n_coarse; c.nf = opts->n_fine; c.Ns = c.nc + c.nf;
    c.C = opts->chunk_rays;
    c.Nmax = c.nc > c.nf ? c.nc : c.nf;
    sooc_se3_to_rt(c.R_fc, c.o_f, T_fc);
    st = out_prepare(out, c.W, c.H, c.N, opts->components, opts->soft_seg);
    if (st) return st;

    int nt = 1;
#ifdef SOOC_HAVE_OPENMP
    nt = opts->threads > 0 ? opts->threads : omp_get_max_threads();
#endif
    if (nt < 1) nt = 1;
    size_t P = (size_t)c.W * c.H;
    size_t n_chunks = (P + (size_t)c.C - 1) / (size_t)c.C;
    if ((size_t)nt > n_chunks) nt = (int)n_chunks;
    if (f->prepare) {
        st = f->prepare(f->user, nt, c.C * c.Nmax);
        if (st) return sooc_adderr(st, "render: field prepare");
    }
    scratch *sc = sooc_calloc((size_t)nt, sizeof(scratch));
    if (!sc) return sooc_seterr(SOOC_ENOMEM, "render: out of memory (scratch)");
    for (int t = 0; t < nt; t++) {
        if (scratch_alloc(&sc[t], c.C, c.Ns, c.Nmax, c.N, c.nc)) {
            for (int u = 0; u < t; u++) scratch_free(&sc[u]);
            sooc_free(sc);
            return sooc_seterr(SOOC_ENOMEM, "render: out of memory (per-worker scratch)");
        }
    }
#ifdef SOOC_HAVE_OPENMP
#pragma omp parallel num_threads(nt)
    {
        int w = omp_get_thread_num();
#pragma omp for schedule(dynamic, 1)
        for (long ch = 0; ch < (long)n_chunks; ch++) {
            size_t p0 = (size_t)ch * (size_t)c.C;
            int nray = (int)((P - p0) < (size_t)c.C ? (P - p0) : (size_t)c.C);
            render_chunk(&c, &sc[w], w, p0, nray);
        }
    }
#else
    for (size_t ch = 0; ch < n_chunks; ch++) {
        size_t p0 = ch * (size_t)c.C;
        int nray = (int)((P - p0) < (size_t)c.C ? (P - p0) : (size_t)c.C);
        render_chunk(&c, &sc[0], 0, p0, nray);
    }
#endif
    for (int t = 0; t < nt; t++) scratch_free(&sc[t]);
    sooc_free(sc);
    return SOOC_OK;
}

/* ---- uncertainty ---- */

typedef struct fields_user { const sooc_field *fields; } fields_user;
static sooc_status fields_get(void *user, int m, sooc_field *f) {
    *f = ((fields_user *)user)->fields[m];
    return SOOC_OK;
}

sooc_status sooc_render_uncertainty(const sooc_field_sampler *smp, int M, const sooc_intrinsics *K,
                                    const double T_fc[16], const sooc_render_opts *opts,
                                    sooc_render_out *out) {
    if (!smp || !smp->get) return sooc_seterr(SOOC_EINVAL, "render: uncertainty needs a sampler");
    if (M < 2) return sooc_seterr(SOOC_EINVAL, "render: uncertainty needs M >= 2 (got %d)", M);
    if (!K || K->width <= 0 || K->height <= 0) return sooc_seterr(SOOC_EINVAL, "render: bad intrinsics");
    sooc_render_opts o;
    if (opts) o = *opts; else sooc_render_opts_default(&o);
    o.components = 0;
    o.soft_seg = 0;
    size_t P = (size_t)K->width * K->height;
    if (out->width != K->width || out->height != K->height) {
        sooc_render_out_free(out);   /* other buffers are sized by the next render_view */
        out->width = K->width;
        out->height = K->height;
    }
    sooc_status st = SOOC_OK;
    st = st ? st : ensure((void **)&out->uncert, P * sizeof(float), 0);
    st = st ? st : ensure((void **)&out->rgb_mean, P * 3 * sizeof(float), 0);
    double *mean = sooc_calloc(P * 3, sizeof(double)), *m2 = sooc_calloc(P * 3, sizeof(double));
    if (st || !mean || !m2) {
        sooc_free(mean); sooc_free(m2);
        return sooc_seterr(SOOC_ENOMEM, "render: out of memory (uncertainty)");
    }
    sooc_render_out tmp;
    memset(&tmp, 0, sizeof tmp);
    uint64_t seed0 = o.seed;
    for (int m = 0; m < M && !st; m++) {
        sooc_field f;
        memset(&f, 0, sizeof f);
        st = smp->get(smp->user, m, &f);
        if (st) { st = sooc_adderr(st, "render: posterior sample %d", m); break; }
        o.seed = seed0 + (uint64_t)m * 0x9E3779B97F4A7C15ull;
        st = sooc_render_view(&f, K, T_fc, &o, &tmp);
        if (smp->release) smp->release(smp->user, m, &f);
        if (st) break;
        for (size_t i = 0; i < P * 3; i++) {   /* Welford */
            double x = tmp.rgb[i], d = x - mean[i];
            mean[i] += d / (m + 1);
            m2[i] += d * (x - mean[i]);
        }
    }
    if (!st) {
        for (size_t p = 0; p < P; p++) {
            double v = 0.0;
            for (int ch = 0; ch < 3; ch++) {
                v += m2[3 * p + ch] / M;
                out->rgb_mean[3 * p + ch] = (float)mean[3 * p + ch];
            }
            out->uncert[p] = (float)v;
        }
    }
    sooc_render_out_free(&tmp);
    sooc_free(mean);
    sooc_free(m2);
    return st;
}

sooc_status sooc_render_uncertainty_fields(const sooc_field *fields, int M, const sooc_intrinsics *K,
                                           const double T_fc[16], const sooc_render_opts *o,
                                           sooc_render_out *out) {
    if (!fields) return sooc_seterr(SOOC_EINVAL, "render: uncertainty: no fields");
    fields_user u = {fields};
    sooc_field_sampler s = {fields_get, NULL, &u};
    return sooc_render_uncertainty(&s, M, K, T_fc, o, out);
}
