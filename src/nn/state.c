/*
 * Arena, parameter slabs, Adam/AdamW, gradient clipping, LR schedules.
 */
#include "nn_impl.h"
#include <math.h>
#include <stdio.h>
#include <string.h>

/* ---------------------------------------------------------------- arena */

sooc_status sooc_nn_arena_init(sooc_nn_arena *a, size_t cap_bytes) {
    memset(a, 0, sizeof *a);
    cap_bytes = (cap_bytes + 63) & ~(size_t)63;
    a->base = sooc_malloc(cap_bytes ? cap_bytes : 64);
    if (!a->base) return sooc_seterr(SOOC_ENOMEM, "nn arena: cannot allocate %zu bytes", cap_bytes);
    a->cap = cap_bytes;
    return SOOC_OK;
}

void sooc_nn_arena_deinit(sooc_nn_arena *a) {
    if (!a) return;
    sooc_free(a->base);
    memset(a, 0, sizeof *a);
}

void sooc_nn_arena_reset(sooc_nn_arena *a) { a->used = 0; }

void sooc_nn_arena_rewind(sooc_nn_arena *a, size_t mark) {
    SOOC_ASSERT(mark <= a->used);
    a->used = mark;
}

void *sooc_nn_arena_alloc(sooc_nn_arena *a, size_t nbytes) {
    size_t n = (nbytes + 63) & ~(size_t)63;
    if (n < nbytes || n > a->cap - a->used) {
        sooc_seterr(SOOC_ENOMEM, "nn arena full: need %zu bytes, %zu of %zu used", nbytes,
                    a->used, a->cap);
        return NULL;
    }
    void *p = a->base + a->used;
    a->used += n;
    if (a->used > a->peak) a->peak = a->used;
    return p;
}

float *sooc_nn_arena_floats(sooc_nn_arena *a, size_t n) {
    if (n > SIZE_MAX / sizeof(float)) return NULL;
    return sooc_nn_arena_alloc(a, n * sizeof(float));
}

float *sooc_nn_arena_zeros(sooc_nn_arena *a, size_t n) {
    float *p = sooc_nn_arena_floats(a, n);
    if (p) memset(p, 0, n * sizeof(float));
    return p;
}

/* --------------------------------------------------------------- params */

void sooc_nn_params_init(sooc_nn_params *p) { memset(p, 0, sizeof *p); }

void sooc_nn_params_deinit(sooc_nn_params *p) {
    if (!p) return;
    sooc_free(p->views);
    sooc_free(p->w);
    sooc_free(p->g);
    sooc_free(p->m);
    sooc_free(p->v);
    memset(p, 0, sizeof *p);
}

int sooc_nn_params_add(sooc_nn_params *p, const char *name, int ndim, const int64_t *shape) {
    if (p->w) return sooc_seterr(SOOC_EINVAL, "nn params: add '%s' after alloc", name);
    if (!name || !*name || strlen(name) >= sizeof p->views[0].name)
        return sooc_seterr(SOOC_EINVAL, "nn params: bad view name");
    if (ndim < 1 || ndim > SOOC_NN_MAX_DIMS)
        return sooc_seterr(SOOC_EINVAL, "nn params: '%s': ndim %d out of range", name, ndim);
    if (sooc_nn_params_find(p, name) >= 0)
        return sooc_seterr(SOOC_EINVAL, "nn params: duplicate view '%s'", name);
    size_t n = 1;
    for (int d = 0; d < ndim; d++) {
        if (shape[d] < 1 || shape[d] > (1 << 30))
            return sooc_seterr(SOOC_EINVAL, "nn params: '%s': bad dim %d", name, d);
        n *= (size_t)shape[d];
        if (n > ((size_t)1 << 34))
            return sooc_seterr(SOOC_EINVAL, "nn params: '%s' too large", name);
    }
    if (p->n_views == p->cap_views) {
        int nc = p->cap_views ? 2 * p->cap_views : 16;
        sooc_nn_param_view *nv = sooc_realloc(p->views, (size_t)nc * sizeof *nv);
        if (!nv) return SOOC_ENOMEM;
        p->views = nv;
        p->cap_views = nc;
    }
    sooc_nn_param_view *v = &p->views[p->n_views];
    memset(v, 0, sizeof *v);
    snprintf(v->name, sizeof v->name, "%s", name);
    v->ndim = ndim;
    for (int d = 0; d < ndim; d++) v->shape[d] = shape[d];
    v->n = n;
    v->offset = p->n_total;
    v->lr_mult = v->wd_mult = 1.f;
    p->n_total += (n + 15) & ~(size_t)15; /* 64-byte aligned views */
    return p->n_views++;
}

sooc_status sooc_nn_params_alloc(sooc_nn_params *p) {
    if (p->w) return sooc_seterr(SOOC_EINVAL, "nn params: already allocated");
    size_t n = p->n_total ? p->n_total : 16;
    p->w = sooc_calloc(n, sizeof(float));
    p->g = sooc_calloc(n, sizeof(float));
    p->m = sooc_calloc(n, sizeof(float));
    p->v = sooc_calloc(n, sizeof(float));
    if (!p->w || !p->g || !p->m || !p->v) {
        sooc_free(p->w); sooc_free(p->g); sooc_free(p->m); sooc_free(p->v);
        p->w = p->g = p->m = p->v = NULL;
        return sooc_seterr(SOOC_ENOMEM, "nn params: cannot allocate 4 x %zu floats", n);
    }
    for (int i = 0; i < p->n_views; i++) {
        sooc_nn_param_view *v = &p->views[i];
        sooc_nn_tensor *t = &v->t;
        memset(t, 0, sizeof *t);
        t->data = p->w + v->offset;
        t->grad = p->g + v->offset;
        t->ndim = v->ndim;
        for (int d = 0; d < v->ndim; d++) t->shape[d] = v->shape[d];
        t->n = (int64_t)v->n;
        t->requires_grad = 1;
        t->is_param = 1;
        t->name = v->name;
    }
    p->adam_t = 0;
    return SOOC_OK;
}

sooc_nn_tensor *sooc_nn_params_tensor(sooc_nn_params *p, int index) {
    SOOC_ASSERT(p->w && index >= 0 && index < p->n_views);
    return &p->views[index].t;
}

int sooc_nn_params_find(const sooc_nn_params *p, const char *name) {
    for (int i = 0; i < p->n_views; i++)
        if (strcmp(p->views[i].name, name) == 0) return i;
    return -1;
}

void sooc_nn_params_zero_grad(sooc_nn_params *p) {
    if (p->g) memset(p->g, 0, p->n_total * sizeof(float));
}

void sooc_nn_init_uniform(float *w, size_t n, float bound, sooc_rng *rng) {
    for (size_t i = 0; i < n; i++) w[i] = (2.f * sooc_rng_uniformf(rng) - 1.f) * bound;
}

/* ------------------------------------------------------------ optimizer */

sooc_nn_adam_cfg sooc_nn_adam_default(void) {
    sooc_nn_adam_cfg c = {0.9f, 0.999f, 1e-8f, 0.f, 0};
    return c;
}

sooc_status sooc_nn_adam_step(sooc_nn_params *p, const sooc_nn_adam_cfg *cfg, float lr) {
    SOOC_ASSERT(p->w);
    for (size_t i = 0; i < p->n_total; i++)
        if (!isfinite(p->g[i]))
            return sooc_seterr(SOOC_ENUMERIC, "nn adam: non-finite gradient at slab index %zu", i);
    p->adam_t++;
    double t = (double)p->adam_t;
    /* torch.optim.Adam: step_size = lr / bc1; denom = sqrt(v)/sqrt(bc2) + eps */
    float bc1 = (float)(1.0 - pow(cfg->beta1, t));
    float bc2s = (float)sqrt(1.0 - pow(cfg->beta2, t));
    float b1 = cfg->beta1, b2 = cfg->beta2;
    for (int iv = 0; iv < p->n_views; iv++) {
        const sooc_nn_param_view *v = &p->views[iv];
        float vlr = lr * v->lr_mult, wd = cfg->weight_decay * v->wd_mult;
        float step = vlr / bc1;
        float *w = p->w + v->offset, *g = p->g + v->offset, *m = p->m + v->offset,
              *s = p->v + v->offset;
        int64_t n = (int64_t)v->n;
#pragma omp parallel for schedule(static) if (n > SOOC_NN_PAR_MIN)
        for (int64_t i = 0; i < n; i++) {
            float gi = g[i];
            if (cfg->adamw) w[i] *= 1.f - vlr * wd;
            else gi += wd * w[i];
            m[i] = b1 * m[i] + (1.f - b1) * gi;
            s[i] = b2 * s[i] + (1.f - b2) * gi * gi;
            float denom = sqrtf(s[i]) / bc2s + cfg->eps;
            w[i] -= step * m[i] / denom;
        }
    }
    return SOOC_OK;
}

double sooc_nn_grad_norm(const sooc_nn_params *p) {
    double s = 0.0;
    for (int iv = 0; iv < p->n_views; iv++) {
        const float *g = p->g + p->views[iv].offset;
        for (size_t i = 0; i < p->views[iv].n; i++) s += (double)g[i] * g[i];
    }
    return sqrt(s);
}

double sooc_nn_clip_grad_norm(sooc_nn_params *p, double max_norm) {
    double norm = sooc_nn_grad_norm(p);
    double coef = max_norm / (norm + 1e-6);
    if (coef < 1.0) {
        float c = (float)coef;
        for (size_t i = 0; i < p->n_total; i++) p->g[i] *= c;
    }
    return norm;
}

float sooc_nn_schedule_lr(const sooc_nn_schedule *s, int64_t step) {
    if (step < 0) step = 0;
    if (s->warmup > 0 && step < s->warmup) return s->lr * (float)(step + 1) / (float)s->warmup;
    if (s->decay == SOOC_NN_DECAY_CONST || s->total <= s->warmup) return s->lr;
    double u = (double)(step - s->warmup) / (double)(s->total - s->warmup);
    if (u > 1.0) u = 1.0;
    double f = s->final_frac;
    double k = s->decay == SOOC_NN_DECAY_LINEAR ? 1.0 - u : 0.5 * (1.0 + cos(M_PI * u));
    return (float)(s->lr * (f + (1.0 - f) * k));
}
