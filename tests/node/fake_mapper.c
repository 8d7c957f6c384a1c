/* A tiny stand-in for the model's mapper (tests and bench only): every
 * keyframe registers one new object 1.5 m in front of the camera on the
 * floor, re-observes the object registered before it, and every 5th
 * keyframe removes the oldest remaining object. Deterministic. */
#include "sooc3d/mapper.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define FAKE_W 32
#define FAKE_H 24
#define FAKE_DIM 8

struct sooc3d_mapper {
    sooc_map_entry *e;
    size_t n, cap;
    uint64_t next_id, updates;
    double delay_ms;
};

void sooc3d_mapper_params_default(sooc3d_mapper_params *p) { memset(p, 0, sizeof *p); }

sooc_status sooc3d_mapper_create(sooc3d_mapper **out, const sooc3d_mapper_params *p) {
    (void)p;
    sooc3d_mapper *m = sooc_calloc(1, sizeof *m);
    if (!m) return SOOC_ENOMEM;
    m->next_id = 1;
    const char *d = getenv("SOOC_FAKE_MAPPER_DELAY_MS");
    m->delay_ms = d ? atof(d) : 0.0;
    *out = m;
    return SOOC_OK;
}

void sooc3d_mapper_destroy(sooc3d_mapper *m) {
    if (!m) return;
    sooc_free(m->e);
    sooc_free(m);
}

void sooc3d_mapper_input_size(const sooc3d_mapper *m, int *w, int *h) {
    (void)m;
    *w = FAKE_W;
    *h = FAKE_H;
}

static sooc_status push(sooc3d_mapper *m, const sooc_map_entry *e) {
    if (m->n == m->cap) {
        size_t nc = m->cap ? 2 * m->cap : 16;
        void *q = sooc_realloc(m->e, nc * sizeof *m->e);
        if (!q) return SOOC_ENOMEM;
        m->e = q;
        m->cap = nc;
    }
    m->e[m->n++] = *e;
    return SOOC_OK;
}

sooc_status sooc3d_mapper_update(sooc3d_mapper *m, const sooc_frame *f, sooc3d_update_stats *st) {
    if (!f->has_pose) return sooc_seterr(SOOC_EINVAL, "fake mapper: frame without pose");
    if (f->width != FAKE_W || f->height != FAKE_H)
        return sooc_seterr(SOOC_EINVAL, "fake mapper: frame is %dx%d, want %dx%d", f->width, f->height, FAKE_W,
                           FAKE_H);
    if (m->delay_ms > 0) {
        double t0 = sooc_seconds();
        while ((sooc_seconds() - t0) * 1e3 < m->delay_ms) {
        }
    }
    m->updates++;
    if (st) memset(st, 0, sizeof *st);
    /* re-observe the newest object */
    if (m->n) {
        sooc_map_entry *l = &m->e[m->n - 1];
        l->obs_count++;
        l->last_seen_ns = f->t_ns;
        l->sigma_t *= 0.9;
        if (st) st->n_retrieved = 1;
    }
    /* a new object 1.5 m ahead of the camera, on the floor */
    sooc_map_entry e;
    memset(&e, 0, sizeof e);
    e.id = m->next_id++;
    double fwd[3] = {f->T_wc[2], f->T_wc[6], f->T_wc[10]};
    double nrm = sqrt(fwd[0] * fwd[0] + fwd[2] * fwd[2]);
    if (nrm < 1e-9) nrm = 1;
    e.x = f->T_wc[3] + 1.5 * fwd[0] / nrm;
    e.z = f->T_wc[11] + 1.5 * fwd[2] / nrm;
    e.yaw = 0.1 * (double)e.id;
    e.sigma_t = 0.2;
    e.sigma_yaw = 0.3;
    e.presence_logit = 2.0f;
    e.presence = 1.0f / (1.0f + expf(-2.0f));
    e.latent_dim = FAKE_DIM;
    for (int i = 0; i < FAKE_DIM; i++) {
        e.what_mu[i] = (float)e.id + 0.01f * (float)i;
        e.what_logvar[i] = -1.0f;
    }
    e.extent[0] = 0.4f;
    e.extent[1] = 0.8f;
    e.extent[2] = 0.5f;
    e.first_seen_ns = e.last_seen_ns = f->t_ns;
    e.obs_count = 1;
    sooc_status s = push(m, &e);
    if (s) return s;
    if (st) { st->n_registered = 1; st->n_new = 1; }
    if (m->updates % 5 == 0 && m->n > 1) {
        memmove(m->e, m->e + 1, (m->n - 1) * sizeof *m->e);
        m->n--;
        if (st) st->n_removed = 1;
    }
    return SOOC_OK;
}

sooc_status sooc3d_mapper_entries(const sooc3d_mapper *m, sooc_map_entry *out, size_t cap, size_t *n) {
    *n = m->n;
    if (out)
        for (size_t i = 0; i < m->n && i < cap; i++) out[i] = m->e[i];
    return SOOC_OK;
}

sooc_status sooc3d_mapper_load_entries(sooc3d_mapper *m, const sooc_map_entry *e, size_t n) {
    m->n = 0;
    for (size_t i = 0; i < n; i++) {
        sooc_status s = push(m, &e[i]);
        if (s) return s;
        if (e[i].id >= m->next_id) m->next_id = e[i].id + 1;
    }
    return SOOC_OK;
}
